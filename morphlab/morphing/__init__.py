"""The paper's application: the morphing leading edge of a high-performance sailplane (§4).

``ml.morphing`` is :mod:`morphlab.morphing.leading_edge` (the parametric model, its settings and
responses, and :func:`study`); :mod:`.airfoil` holds the CST geometry and the target shapes,
:mod:`.geometry` the skin's nodes, the design variables and the mechanism's clearance
(re-exported by :mod:`.leading_edge`), :mod:`.design` how the mechanism was designed,
:mod:`.paper` the model-agnostic study that writes the tables, figures and JSON. Nothing in
the core library imports this package.
"""

from . import airfoil
from .leading_edge import *  # noqa: F403 - the model's public names (leading_edge.__all__)
from .leading_edge import __all__ as _model_names
from .leading_edge import _assemble, _crosses, _distance_to_polyline, _inside  # noqa: F401

__all__ = ["airfoil", *_model_names]
