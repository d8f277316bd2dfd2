"""The motion of a run as an animated GIF."""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np
from matplotlib import colormaps
from matplotlib.figure import Figure
from matplotlib.patches import Polygon

from ..errors import ModelError
from ._common import _SEQUENTIAL, _check_result, _units
from ._sliders import _block
from .motion import (
    _checked_outlines,
    _mark_ground_joints,
    _slider_tracks,
    _spring_tracks,
    _time_indices,
)


def _check_gif(path, fps, n_frames) -> Path:
    path = Path(path)
    if path.suffix.lower() != ".gif":
        raise ModelError(f"animate writes GIF files; the path must end in .gif, got {path.name!r}")
    if not isinstance(n_frames, (int, np.integer)) or n_frames < 1:
        raise ModelError(f"n_frames must be a positive integer, got {n_frames!r}")
    if not (np.isfinite(fps) and fps > 0):
        raise ModelError(f"fps must be positive, got {fps!r}")
    return path


def _frame_axes(fig: Figure, outlines, tgt, u: dict):
    """Axes whose limits hold every outline of the run and the target at every frame."""
    ax = fig.add_subplot()
    allxy = np.concatenate([xy.reshape(-1, 2) for _, xy, _, _ in outlines]
                           + ([tgt] if tgt is not None else []))
    lo, hi = allxy.min(axis=0), allxy.max(axis=0)
    pad = 0.05 * max(float(np.max(hi - lo)), 1e-12)
    ax.set_xlim(lo[0] - pad, hi[0] + pad)
    ax.set_ylim(lo[1] - pad, hi[1] + pad)
    ax.set_aspect("equal", adjustable="box")
    ax.set_xlabel(f"x [{u['length']}]")
    ax.set_ylabel(f"y [{u['length']}]")
    if tgt is not None:
        ax.plot(tgt[:, 0], tgt[:, 1], "--", color="0.5", linewidth=1.2, label="target")
        ax.legend(loc="best", fontsize=8)
    return ax


class _Frames:
    """The artists of the animation, moved to the state of one step at a time."""

    def __init__(self, ax, result, outlines):
        self.outlines = outlines
        self.sym, tracks = _slider_tracks(result)
        self.sliders = []
        for _j, P, d, ends in tracks:
            (guide,) = ax.plot(ends[0, :, 0], ends[0, :, 1], "-", color="0.5", linewidth=1.0)
            block = Polygon(_block(P[0], d[0], self.sym), closed=True, facecolor="white",
                            edgecolor="k", linewidth=1.0, zorder=4)
            ax.add_patch(block)
            self.sliders.append((guide, block, P, d, ends))
        self.springs = []
        for _sp, Z in _spring_tracks(result, outlines):
            (ln,) = ax.plot(Z[0, :, 0], Z[0, :, 1], "-", color="tab:green", linewidth=1.0)
            self.springs.append((ln, Z))
        colours = itertools.cycle(colormaps[_SEQUENTIAL](np.linspace(0.0, 0.7, 4)))
        self.lines = []
        for _, xy, _, _ in outlines:
            (ln,) = ax.plot([], [], "-", color=next(colours), linewidth=2.0,
                            marker="o" if xy.shape[1] == 1 else None)
            self.lines.append(ln)

    def show(self, k: int) -> None:
        for ln, (_, xy, closed, _) in zip(self.lines, self.outlines):
            P = np.vstack([xy[k], xy[k][:1]]) if closed else xy[k]
            ln.set_data(P[:, 0], P[:, 1])
        for guide, block, P, d, ends in self.sliders:
            guide.set_data(ends[k, :, 0], ends[k, :, 1])
            block.set_xy(_block(P[k], d[k], self.sym))
        for ln, Z in self.springs:
            ln.set_data(Z[k, :, 0], Z[k, :, 1])


def animate(result, path, fps=20, n_frames=60, target=None, *, dpi=80, units=None,
            magnify: float = 1.0) -> Path:
    """Write the motion of a run as an animated GIF.

    Parameters
    ----------
    result : Result
    path : str or Path
        Output file; must end in ``.gif``.
    fps : float
        Frames per second of the GIF.
    n_frames : int
        Number of frames, taken at evenly spaced steps (at most one per step).
    target : array_like, shape (n_nodes, 2), optional
        Target node positions drawn dashed in every frame [length].
    dpi : float
        Resolution of the frames (the figure is 5 x 4 inches).
    units : dict, optional
        Overrides of :data:`DEFAULT_UNITS`.
    magnify : float
        Scale of the beams' deformation relative to their chord motion (as in
        :func:`~morphlab.plots.snapshots`).

    Returns
    -------
    Path
        ``path``.

    Notes
    -----
    Frames are drawn with the same outlines as :func:`~morphlab.plots.snapshots` and written by
    :class:`matplotlib.animation.PillowWriter` (Pillow is a dependency of matplotlib).
    """

    from matplotlib.animation import PillowWriter

    u = _units(units)
    _check_result(result)
    path = _check_gif(path, fps, n_frames)
    magnify, outlines, tgt = _checked_outlines(result, magnify, target)
    t = np.real(result.t)
    idx = _time_indices(result, None, int(n_frames))

    fig = Figure(figsize=(5.0, 4.0), layout="constrained")
    ax = _frame_axes(fig, outlines, tgt, u)
    _mark_ground_joints(ax, result.system.model)
    frames = _Frames(ax, result, outlines)
    title = ax.set_title("")
    writer = PillowWriter(fps=fps)
    with writer.saving(fig, str(path), dpi):
        for k in idx:
            frames.show(k)
            title.set_text(f"t = {t[k]:.4g} {u['time']}" + (
                f", deformation x{magnify:g}" if magnify != 1.0 else ""))
            writer.grab_frame()
    return path
