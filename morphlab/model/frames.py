"""Floating frames of a beam: how its elements are split into groups and where each group's
frame sits.

A beam of ``n`` elements carries ``k`` floating frames (``1 <= k <= n``): consecutive groups of
elements, each a linear FFRF substructure with its own reference coordinates and reference
condition, joined to its neighbour at the shared node by a rigid connection (``docs/frames.md``).
This module holds the integer bookkeeping only (which elements, which node is the origin, which
nodal DOFs the reference condition removes); the compile step computes the geometry.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from ..errors import ModelError

#: the frame choices of :func:`frame_specs` (``docs/frames.md``)
REFERENCES = ("first", "middle", "chord")
#: default spelling of "one frame per element" and the default reference
DEFAULT_FRAMES = "element"
DEFAULT_REFERENCE = "chord"


@dataclass(frozen=True)
class FrameSpec:
    """One floating frame of a beam.

    Attributes
    ----------
    first, last : int
        First and last node of the group (its elements are ``first .. last - 1``).
    origin : int
        Node at the frame's origin.
    axis : (int, int)
        The frame's x axis points from node ``axis[0]`` to node ``axis[1]``.
    removed : tuple of (node, component)
        Nodal DOFs the reference condition removes (component 0 = u, 1 = v, 2 = phi).
    """

    first: int
    last: int
    origin: int
    axis: tuple
    removed: tuple


def _is_int(x) -> bool:
    return isinstance(x, (int, np.integer)) and not isinstance(x, (bool, np.bool_))


def resolve(frames, reference, reference_node, n_elem: int, owner: str):
    """Validated ``(k, reference, reference_node)`` of a beam of ``n_elem`` elements.

    ``reference_node=r`` (an int) is the single tangent frame at node ``r``: ``frames`` must
    then be None or 1 and ``reference`` None. Otherwise ``frames`` is an int in
    ``[1, n_elem]`` or ``"element"`` (default), ``reference`` one of :data:`REFERENCES`
    (default ``"chord"``); the returned ``reference_node`` is None.
    """
    n_node = n_elem + 1
    if reference_node is not None:
        if not (_is_int(reference_node) and -n_node <= reference_node < n_node):
            raise ModelError(f"{owner}: reference_node must be a node index in "
                             f"[0, {n_node - 1}] or None, got {reference_node!r}")
        if not (frames is None or (_is_int(frames) and frames == 1)):
            raise ModelError(f"{owner}: reference_node={reference_node!r} is a single tangent "
                             f"frame; it cannot be combined with frames={frames!r} (use "
                             "frames and reference instead)")
        if reference is not None:
            raise ModelError(f"{owner}: give reference_node or reference, not both "
                             f"(reference={reference!r})")
        return 1, None, int(reference_node) % n_node
    frames = DEFAULT_FRAMES if frames is None else frames
    reference = DEFAULT_REFERENCE if reference is None else reference
    if isinstance(frames, str) and frames == "element":
        k = n_elem
    elif _is_int(frames) and 1 <= frames <= n_elem:
        k = int(frames)
    else:
        raise ModelError(f"{owner}: frames must be an integer in [1, {n_elem}] (the number of "
                         f"elements) or 'element' (one frame per element), got {frames!r}")
    if not (isinstance(reference, str) and reference in REFERENCES):
        raise ModelError(f"{owner}: reference must be one of {', '.join(map(repr, REFERENCES))},"
                         f" got {reference!r}")
    return k, reference, None


def frame_offsets(n_elem: int, k: int) -> np.ndarray:
    """First element of each of ``k`` groups of consecutive elements, and ``n_elem`` last,
    (k + 1,) int64: sizes as equal as possible, the longer groups first."""
    base, extra = divmod(n_elem, k)
    sizes = [base + 1] * extra + [base] * (k - extra)
    return np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)


def _tangent_axis(node: int, last_node: int) -> tuple:
    """Along the element that starts at ``node`` (the one that ends there for the last)."""
    return (node, node + 1) if node < last_node else (node - 1, node)


@lru_cache(maxsize=64)
def frame_specs(n_elem: int, k: int, reference: str | None,
                reference_node: int | None) -> tuple[FrameSpec, ...]:
    """The :class:`FrameSpec` of each frame of a beam (see :func:`resolve` for the
    arguments). Kept for the last layouts: the perturbed designs of a sensitivity run
    rebuild the same beams again and again."""
    if reference_node is not None:
        r = reference_node
        return (FrameSpec(0, n_elem, r, _tangent_axis(r, n_elem), ((r, 0), (r, 1), (r, 2))),)
    off = frame_offsets(n_elem, k)
    specs = []
    for f in range(k):
        s, e = int(off[f]), int(off[f + 1])
        if reference == "chord":
            specs.append(FrameSpec(s, e, s, (s, e), ((s, 0), (s, 1), (e, 1))))
        else:
            o = s if reference == "first" else s + (e - s) // 2
            specs.append(FrameSpec(s, e, o, (o, o + 1), ((o, 0), (o, 1), (o, 2))))
    return tuple(specs)


def holding_frame(offsets: np.ndarray, node: int) -> int:
    """Index of the frame that holds ``node``: a node shared by two frames belongs to the
    frame that starts there (the last node to the last frame)."""
    k = offsets.size - 1
    return min(int(np.searchsorted(offsets, node, side="right")) - 1, k - 1)


def drive_node(beam) -> int:
    """Node a drive or torque without ``at`` acts on: the beam's ``reference_node``, else 0."""
    return 0 if beam.reference_node is None else beam.reference_node


def specs_of(beam) -> tuple[FrameSpec, ...]:
    """The :class:`FrameSpec` of each frame of ``beam`` (a :class:`~morphlab.model.Beam`)."""
    return frame_specs(beam.n_elements, beam.frames, beam.reference, beam.reference_node)
