"""Geometry of the morphing leading edge: materials, the skin's nodes and target, the
design variables with the bell crank's points, and whether the mechanism stays inside the skin.

The model built from it is :mod:`morphlab.morphing.leading_edge` (which re-exports these
names); how the numbers were found is :mod:`morphlab.morphing.design`.

Units: mm, t, s, N, N·mm, MPa.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from ..errors import ModelError
from . import airfoil

__all__ = [
    "SPAN_MM", "RHO_AL", "E_AL", "YIELD_MPA", "N_ELEMENTS", "DROOP_MM", "C_NODE", "E_NODE",
    "LINK_SECTION_MM2", "DESIGN_DELTA", "CRANK_SENSE", "DEFAULTS", "GEOMETRY", "undeformed",
    "target",
    "mechanism_clearance",
]

#: Span of the planar wing section [mm] (the skin's out-of-plane width).
SPAN_MM = 1000.0
#: Density of aluminium [t/mm³].
RHO_AL = 2.7e-9
#: Young's modulus of aluminium [MPa].
E_AL = 70000.0
#: Yield (0.2 % proof) stress of 6061-T6, the minimum of EN 755-2 for extrusions [MPa].
YIELD_MPA = 240.0
#: Skin elements of the paper's mesh.
N_ELEMENTS = 30
#: Nose droop of the low-speed target [mm].
DROOP_MM = airfoil.DEFAULT_DROOP_MM
#: Skin node (of the 30-element mesh) where link_C acts: upper surface, x = 99.2 mm.
C_NODE = 4
#: Skin node (of the 30-element mesh) where link_E acts: lower surface, x = 79.3 mm.
E_NODE = 24
#: Cross-section of the rigid links, a 10 mm x 10 mm aluminium bar [mm²].
LINK_SECTION_MM2 = 100.0
#: Crank rotation of the design from the undeformed to the morphed state [rad].
DESIGN_DELTA = 0.575
#: Sense in which the torque turns the crank: +1 counter-clockwise, -1 clockwise (the torque
#: ``M_t`` is a magnitude; the model applies ``CRANK_SENSE * M_t``).
CRANK_SENSE = 1

#: Design variables of the paper's sensitivity study (Table 1): skin wall thickness [mm],
#: actuation torque [N·mm], pivot A [mm], Young's modulus of the skin [MPa].
DEFAULTS: dict[str, float] = {
    "t_w": 2.0,
    "M_t": 1.0e4,
    "x_A": 104.5,
    "y_A": -4.01,
    "E": E_AL,
}
#: Further geometry that ``build`` accepts in ``p`` (not in the paper's study): the bell-crank
#: points B and D [mm].
GEOMETRY: dict[str, float] = {
    "x_B": 102.59,
    "y_B": -12.76,
    "x_D": 132.11,
    "y_D": -8.89,
}


def _check_elements(n_elements: int) -> int:
    if not (isinstance(n_elements, (int, np.integer)) and n_elements >= 8):
        raise ModelError(f"n_elements must be an integer >= 8, got {n_elements!r}")
    return int(n_elements)


def _attachment(node: int, n_elements: int) -> int:
    """Node of an n-element skin at the arc-length position of ``node`` of the 30-element
    mesh: the same material point when n is a multiple of 30, else the nearest node."""
    return int(round(node * n_elements / N_ELEMENTS))


@lru_cache(maxsize=8)
def _nodes(n_elements: int, droop: float) -> tuple[np.ndarray, np.ndarray]:
    d = airfoil.target_nodes(droop=droop, n_nodes=n_elements + 1)
    und, tgt = d["undeformed"], d["target"]
    und.setflags(write=False)
    tgt.setflags(write=False)
    return und, tgt


def undeformed(n_elements: int = N_ELEMENTS) -> np.ndarray:
    """Undeformed skin nodes, F first, G last, (n_elements + 1, 2) [mm]."""
    return _nodes(_check_elements(n_elements), DROOP_MM)[0].copy()


def target(p: dict | None = None, n_elements: int = N_ELEMENTS) -> np.ndarray:
    """Target (drooped) skin nodes, node k the image of undeformed node k, (n + 1, 2) [mm].

    ``p`` is accepted for a uniform signature; the target does not depend on the design
    variables.
    """
    return _nodes(_check_elements(n_elements), DROOP_MM)[1].copy()


def _design(p: dict | None) -> dict:
    q = {**DEFAULTS, **GEOMETRY}
    if p:
        unknown = set(p) - set(q)
        if unknown:
            raise ModelError(f"unknown design variables {sorted(unknown)}; known: {sorted(q)}")
        q.update(p)
    return q


# ------------------------------------------------------------------------------- geometry checks
def _inside(points: np.ndarray, poly: np.ndarray) -> np.ndarray:
    """Even-odd ray casting: True for points inside the closed polygon ``poly`` (m, 2)."""
    x, y = points[:, 0:1], points[:, 1:2]
    a, b = poly, np.roll(poly, -1, axis=0)
    straddle = (a[None, :, 1] > y) != (b[None, :, 1] > y)
    with np.errstate(divide="ignore", invalid="ignore"):
        xc = a[None, :, 0] + (y - a[None, :, 1]) * (b[None, :, 0] - a[None, :, 0]) / (
            b[None, :, 1] - a[None, :, 1])
    return np.sum(straddle & (x < xc), axis=1) % 2 == 1


def _distance_to_polyline(points: np.ndarray, line: np.ndarray) -> np.ndarray:
    a, b = line[:-1], line[1:]
    ab = b - a
    ap = points[:, None, :] - a[None]
    t = np.clip(np.sum(ap * ab, axis=-1) / np.sum(ab * ab, axis=-1), 0.0, 1.0)
    d = ap - t[..., None] * ab[None]
    return np.min(np.sqrt(np.sum(d * d, axis=-1)), axis=1)


def _crosses(P, Q, a, b) -> np.ndarray:
    """Whether segment P-Q properly crosses each segment a_i-b_i."""
    def orient(u, v, w):
        return (v[..., 0] - u[..., 0]) * (w[..., 1] - u[..., 1]) - (
            v[..., 1] - u[..., 1]) * (w[..., 0] - u[..., 0])

    d1, d2 = orient(P, Q, a), orient(P, Q, b)
    d3, d4 = orient(a, b, P), orient(a, b, Q)
    return (d1 * d2 < 0) & (d3 * d4 < 0)


def mechanism_clearance(result, p: dict | None = None, *, tip_fraction: float = 0.1,
                        nodes: tuple[int, int] = (C_NODE, E_NODE)) -> dict:
    """How far the mechanism stays inside the skin over a run.

    Parameters
    ----------
    result : Result
        A run of ``build(p)`` (real).
    p : dict, optional
        The design the run was built from (default: the defaults).
    tip_fraction : float
        Part of each link next to its skin node left out of the link clearance (the link
        meets the skin there).
    nodes : (int, int)
        C and E as nodes of the 30-element mesh.

    Returns
    -------
    dict
        ``"joints"``: smallest signed distance [mm] of A, B, D from the skin contour (closed by
        the segment G -> F; positive inside) over all time steps; ``"links"``: the same for 20
        points on each link's remaining length; ``"crossings"``: number of (time step, link,
        skin element) crossings, the elements next to the link's own node excepted.
    """
    q = _design(p)
    n_nodes = result.node_positions("skin").shape[1]
    c_node, e_node = (_attachment(k, n_nodes - 1) for k in nodes)
    skin = np.real(result.node_positions("skin"))
    A = np.array([np.real(q["x_A"]), np.real(q["y_A"])])
    B0 = np.array([np.real(q["x_B"]), np.real(q["y_B"])])
    D0 = np.array([np.real(q["x_D"]), np.real(q["y_D"])])
    B = np.real(result.point_positions("crank", B0))
    D = np.real(result.point_positions("arm", D0))
    s = np.linspace(0.0, 1.0 - tip_fraction, 20)[:, None]
    joints, links, crossings = np.inf, np.inf, 0
    for i in range(result.n_t):
        S = skin[i]
        for pts, which in ((np.array([A, B[i], D[i]]), "j"),
                           (B[i] + s * (S[c_node] - B[i]), "l"),
                           (D[i] + s * (S[e_node] - D[i]), "l")):
            d = _distance_to_polyline(pts, np.vstack([S, S[:1]]))
            d = np.where(_inside(pts, S), d, -d)
            if which == "j":
                joints = min(joints, float(d.min()))
            else:
                links = min(links, float(d.min()))
        for P, node in ((B[i], c_node), (D[i], e_node)):
            keep = np.ones(n_nodes - 1, dtype=bool)
            keep[max(node - 1, 0):node + 1] = False
            hit = _crosses(P, S[node], S[:-1][keep], S[1:][keep])
            crossings += int(np.sum(hit))
    return {"joints": joints, "links": links, "crossings": crossings}
