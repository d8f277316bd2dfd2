"""Figures of models, motions, stresses, shape errors, sensitivities, timings, energy
and optimization histories.

Every function returns a :class:`matplotlib.figure.Figure` and never calls ``plt.show``. Without
an ``ax`` argument the figure is a bare :class:`~matplotlib.figure.Figure` (not registered with
pyplot, so there is nothing to close); with ``ax`` the drawing goes into that axes and its
figure is returned. Inputs may be complex (complex-step runs): their real parts are drawn.

Units
-----
The library is unit-agnostic; axis labels use the morphing model's units by default
(:data:`DEFAULT_UNITS`: mm, s, MPa, N, N mm). Pass ``units={"length": "m", ...}`` to change
any of them.

Colour maps
-----------
Figures must stay readable when printed in grey:

* sequential data (times of the snapshots, stress magnitudes) use ``viridis``/``cividis``, whose
  lightness changes monotonically;
* signed data (stress, sensitivities) use the diverging ``RdBu_r`` with limits symmetric about
  zero, so white is zero. Red and blue of equal magnitude have about the same grey value, so
  the sign is also drawn with black contour lines: solid for positive levels, dashed for
  negative levels and a thicker solid line at zero;
* bars and lines of several series differ in hatching, marker and line style as well as in
  colour.
"""

from ._common import DEFAULT_UNITS, arc_coordinate
from .animation import animate
from .charts import (
    node_sensitivities,
    profile_comparison,
    sensitivity_map,
    stress_map,
    timing_bars,
    timing_curves,
)
from .drawing import model
from .optimization import design_path, optimization_history
from .run import energy, snapshots

__all__ = [
    "DEFAULT_UNITS", "animate", "arc_coordinate", "design_path", "energy", "model",
    "node_sensitivities", "optimization_history", "profile_comparison", "sensitivity_map",
    "snapshots", "stress_map", "timing_bars", "timing_curves",
]
