"""Kinematic accuracy of the beams' floating frames, read off a finished run.

A linear floating frame measures an element's deformation in the frame's coordinates: an
element that turns by ``phi`` relative to its frame is stretched, in the linear kinematics, by
about ``l phi^2 / 2`` without resisting it (the second-order shortening ``int v'^2/2 dx`` is
missing), and the work of the axial force through that stretch -- the geometric stiffness -- is
missing too. Both shrink as ``1/k^2`` with the number ``k`` of frames (``docs/frames.md``).

Per beam and frame, at every time of the run:

* ``rotation``: the largest RMS rotation of an element relative to its frame,
  ``sqrt(mean over the element of v'(x)^2)`` [rad], ``v`` the element's transverse
  displacement in the frame (cubic Hermite, integrated exactly by 3-point Gauss);
* ``stretch``: the spurious stretch ``sum_e l_e phi_e^2 / 2`` [length];
* ``geometric``: the axial work through that stretch over the strain energy,
  ``|sum_e N_e l_e phi_e^2 / 2| / U``, times the beam's largest elastic deflection [length]:
  the deflection error of the missing geometric stiffness (for a connecting rod the stretch
  alone underestimates the error by an order of magnitude).

The beam's ``estimate`` [length] is the largest over the run of the sum of its frames'
stretches plus its geometric term; :func:`finding` turns it into a run check against
``kinematic_tol`` times the beam's length.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..model import Beam

# 3-point Gauss on [0, 1]: exact for v'^2 (degree 4)
_XI = 0.5 + 0.5 * np.array([-np.sqrt(0.6), 0.0, np.sqrt(0.6)])
_W = np.array([5.0, 8.0, 5.0]) / 18.0


@dataclass(frozen=True)
class BeamKinematics:
    """Kinematic accuracy of one beam over a run.

    Attributes
    ----------
    beam : str
        The beam's name.
    frames : int
        Number of floating frames of the beam (element groups, each with its own frame).
    rotation : (frames,)
        Largest RMS element rotation relative to its frame, per frame [rad].
    stretch : (frames,)
        Largest spurious stretch ``sum l phi^2/2`` of each frame [length].
    geometric : float
        The geometric-stiffness term at the time of the largest estimate [length].
    estimate : float
        Largest ``sum(stretch) + geometric`` at one time [length].
    length : float
        Undeformed length of the beam [length].
    time : float
        Time of the largest estimate [s].
    """

    beam: str
    frames: int
    rotation: np.ndarray
    stretch: np.ndarray
    geometric: float
    estimate: float
    length: float
    time: float

    @property
    def relative(self) -> float:
        """``estimate / length``."""
        return self.estimate / self.length

    def suggested_frames(self, tol: float) -> int:
        """Frames that bring ``relative`` to ``tol`` by the ``1/k^2`` law (may exceed the
        number of elements: then refine the mesh too)."""
        k = int(np.ceil(self.frames * np.sqrt(max(self.relative / tol, 1.0))))
        return k


def kinematics(result) -> dict[str, BeamKinematics]:
    """:class:`BeamKinematics` of every beam of ``result`` (empty without the history of q)."""
    if result.q is None or result.n_t == 0:
        return {}
    out = {}
    for body in result.system.model.bodies:
        if isinstance(body, Beam):
            out[body.name] = _beam(result, body)
    return out


def _geometry(system, info, body: Beam):
    """Per element of the beam: length, direction (cos, sin) in its frame, its frame's index
    (0 .. frames - 1), axial stiffness EA."""
    X = np.real(np.asarray(body.nodes))
    d = np.diff(X, axis=0)
    ell = np.sqrt(np.sum(d * d, axis=1))
    kb = system.arrays.elements.body[info.elements]
    frame = kb - kb[0]
    th0 = np.real(system.q0[system.arrays.bodies.ref[kb, 2]])
    alpha = np.arctan2(d[:, 1], d[:, 0]) - th0
    EA = np.real(np.broadcast_to(np.asarray(body.E * body.area), ell.shape))
    return ell, np.cos(alpha), np.sin(alpha), frame, EA


def _beam(result, body: Beam, chunk: int = 256) -> BeamKinematics:
    system = result.system
    info = system.body(body.name)
    ell, ca, sa, frame, EA = _geometry(system, info, body)
    k = int(frame[-1]) + 1
    ed = system.arrays.elements.dofs[info.elements]
    K = np.real(system.arrays.elements.K[info.elements])
    nd = info.node_dofs[:, :2]
    rot = np.zeros(k)
    stretch = np.zeros(k)
    best = (-1.0, 0.0, 0)
    for k0 in range(0, result.n_t, chunk):
        q = np.real(result.q[k0:k0 + chunk])
        de = np.where(ed >= 0, q[:, np.maximum(ed, 0)], 0.0)  # (m, n_e, 6)
        wa = -sa * de[..., 0] + ca * de[..., 1]
        wb = -sa * de[..., 3] + ca * de[..., 4]
        xi = _XI[:, None, None]
        slope = ((6 * xi * xi - 6 * xi) * ((wa - wb) / ell)[None] + (1 - 4 * xi + 3 * xi * xi)
                 * de[None, ..., 2] + (3 * xi * xi - 2 * xi) * de[None, ..., 5])
        phi2 = np.einsum("g,gme->me", _W, slope * slope)  # mean of v'^2 per element
        s_e = 0.5 * ell * phi2
        N = EA / ell * (ca * (de[..., 3] - de[..., 0]) + sa * (de[..., 4] - de[..., 1]))
        U = 0.5 * np.einsum("mei,eij,mej->m", de, K, de)
        work = np.abs(np.sum(N * s_e, axis=1))
        w = np.where(nd >= 0, q[:, np.maximum(nd, 0)], 0.0)
        amp = np.sqrt(np.max(np.sum(w * w, axis=2), axis=1))
        geo = np.where(U > 0, work / np.where(U > 0, U, 1.0), 0.0) * amp
        per_frame = np.zeros((q.shape[0], k))
        np.add.at(per_frame, (slice(None), frame), s_e)
        rms = np.zeros((q.shape[0], k))
        np.maximum.at(rms, (slice(None), frame), np.sqrt(phi2))
        rot = np.maximum(rot, rms.max(axis=0))
        stretch = np.maximum(stretch, per_frame.max(axis=0))
        total = per_frame.sum(axis=1) + geo
        i = int(np.argmax(total))
        if total[i] > best[0]:
            best = (float(total[i]), float(geo[i]), k0 + i)
    geo_max = best[1]
    return BeamKinematics(body.name, k, rot, stretch, geo_max, max(best[0], 0.0),
                          float(np.sum(ell)), float(result.t[best[2]]))
