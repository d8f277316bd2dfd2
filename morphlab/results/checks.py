"""The checks a finished run reads off its own histories, so that a doubtful result never
reads "ok".

* **constraint drift**: the largest position-level violation of the joints, against
  ``constraint_tol`` times the model size (the acceleration-level constraints drift; the
  stabilization keeps the drift at the Newton tolerance in a sound run). A violation beyond
  :data:`FAILURE_FACTOR` times that limit fails the run
  (:class:`~morphlab.errors.ConstraintViolationError`);
* **unbounded growth**: a beam's deformation that grows by orders of magnitude towards the end
  of the run (a divergence, e.g. a single linear floating frame spun above its first bending
  frequency);
* **implausible units**: a beam deformed by a large part of its own size, or stresses above
  the material's Young's modulus (a modulus in Pa with lengths in mm, say).
* **kinematic accuracy**: a beam whose floating frames turn too little with it, so that the
  linear kinematics of a frame err by more than ``kinematic_tol`` of the beam's length
  (:mod:`morphlab.results.kinematics`); the message says how many frames, or with one frame
  per element how many elements, bring the estimate below it (the error falls as the inverse
  square of either).

Each finding names the check, where (joint, beam) and when; the run's status becomes
``"warning"``, an :class:`~morphlab.errors.AccuracyWarning` is emitted at the user's line, or,
with ``checks="raise"``, an :class:`~morphlab.errors.AccuracyError` carries the result. The
defaults and their measurements: ``docs/accuracy.md`` and ``docs/frames.md``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import (
    AccuracyError,
    AccuracyWarning,
    ConstraintViolationError,
    KinematicAccuracyWarning,
    ModelError,
    warn,
)

#: A beam deformed by more than this part of its size is reported (the linear floating frame is
#: meant for small deformations relative to it).
DEFORMATION_TOL = 0.3
#: Growth of a beam's deformation between the first 80 % of a run and its last 20 % above
#: which the run is reported as diverging (and the deformation must exceed 1e-3 of the size).
GROWTH_TOL = 1e3
#: A joint violated by more than this many times ``constraint_tol`` times the model size (1 % of
#: the size at the default 1e-3) fails the run. Measured on the four-bar of the tests without
#: stabilization (docs/accuracy.md): the drift grows smoothly, through 0.7 % of the size at
#: 0.5 s, until Newton fails at about 10 %; a sound run holds its joints to ~1e-6 of the size.
#: At 1 % the joints are open by more than the elastic deflections a flexible mechanism is
#: usually simulated for, so its deformations and stresses no longer belong to the mechanism
#: that was modelled.
FAILURE_FACTOR = 10.0
#: Default of ``kinematic_tol``: the largest estimated kinematic error accepted, relative to
#: a beam's length. The estimate is within 0.8-1.2 of the measured error in large-rotation
#: statics (docs/frames.md, "Calibration"); 1e-3 keeps converged meshes quiet (16 elements
#: bent to 60 degrees: 1.8e-4) and flags coarse ones and the paper's single frame (2e-3).
KINEMATIC_TOL = 1e-3
CHECK_MODES = ("warn", "raise", "off")


@dataclass(frozen=True)
class Finding:
    """One doubtful aspect of a result: which check, where, its value against its limit, and
    a sentence for the user."""

    check: str
    where: str
    value: float
    limit: float
    message: str
    #: the finding fails the run (a joint violated beyond FAILURE_FACTOR times its limit), at
    #: this time index (the first step beyond)
    failed: bool = False
    step: int | None = None


def assess(result, constraint_tol: float, kinematic_tol: float | None = None) -> list[Finding]:
    """The findings of every check on ``result`` (empty: nothing doubtful); the kinematic
    accuracy is checked when ``kinematic_tol`` is given."""
    if result.n_t == 0:
        return []
    found = [_drift(result, constraint_tol), *_beams(result)]
    if kinematic_tol is not None:
        found += kinematic_findings(result, kinematic_tol)
    return [f for f in found if f is not None]


def kinematic_findings(result, tol: float) -> list[Finding]:
    """A "kinematic accuracy" finding for every beam whose estimated kinematic error exceeds
    ``tol`` times its length; its message says how far to refine (:func:`refinement`)."""
    out = []
    for name, kin in result.kinematics.items():
        if not kin.relative > tol:
            continue
        n_el = result.system.model.body(name).n_elements
        out.append(Finding(
            "kinematic accuracy", repr(name), kin.relative, tol,
            f"beam {name!r}: estimated kinematic error {kin.estimate:.3g} at t={kin.time:.6g} "
            f"({kin.relative:.2g} of its length, kinematic_tol {tol:.2g}): its elements turn "
            f"up to {kin.rotation.max():.3g} rad relative to their {kin.frames} floating "
            f"frame(s); {refinement(kin, tol, n_el)}"))
    return out


def refinement(kin, tol: float, n_elements: int) -> str:
    """What brings the kinematic error of a beam below ``tol``, by the inverse-square law of
    the estimate in the number of frames (one frame per element: in the number of elements;
    docs/frames.md): more frames while the elements allow, else a finer mesh."""
    need = kin.suggested_frames(tol)
    if kin.frames >= n_elements:
        return (f"refine the mesh to about {need} elements (now {n_elements}; with one frame "
                "per element the error falls as 1/elements^2)")
    if need <= n_elements:
        return (f"use add_beam(..., frames={need}, reference='chord') (the error falls as "
                "1/frames^2)")
    return (f"use add_beam(..., frames='element') and refine the mesh to about {need} elements "
            f"(now {n_elements}; the error falls as 1/frames^2)")


def _drift(result, tol: float) -> Finding | None:
    system = result.system
    if system.n_con == 0 or not result.constraint_violation.size:
        return None
    size = system.length_scale
    viol = result.constraint_violation
    k = int(np.argmax(viol))
    worst = float(viol[k])
    if worst <= tol * size:
        return None
    where = _worst_row(result, k)
    failed = worst > FAILURE_FACTOR * tol * size
    first = int(np.argmax(viol > FAILURE_FACTOR * tol * size)) if failed else None
    text = (f"joint {where} is violated by {worst:.3g} at t={result.t[k]:.6g} "
            f"({worst / size:.2g} of the model size, tolerance {tol:.1g})")
    if failed:
        text += (f"; beyond {FAILURE_FACTOR:g} times the tolerance from t={result.t[first]:.6g} "
                 f"(step {first}) on, so the run failed: the bodies it joins are apart and the "
                 "run describes another mechanism")
    return Finding("constraint drift", where, worst, tol * size,
                   text + "; use a smaller dt, keep the stabilization on (stabilization=0.5, "
                   "the default) or check the joints and loads (a mechanism driven through a "
                   "dead point, an overloaded flexible link)", failed, first)


def _worst_row(result, k: int) -> str:
    """The joint of the row violated most at time index ``k`` (its name, or '?')."""
    if result.q is None:
        return "?"
    system = result.system
    phi, _ = system.constraint_violation(np.real(result.q[k]), np.zeros(system.n_dof),
                                         float(result.t[k]))
    i = int(np.argmax(np.abs(np.real(phi))))
    return repr(system.con_joint[i])


def _beams(result):
    """Growth and plausibility of every beam (needs the history of q), computed over chunks
    of times so that a long run of a large model needs no copy of its histories."""
    if result.q is None:
        return
    system = result.system
    for name, info in system.bodies.items():
        if info.kind != "beam":
            continue
        body = system.model.body(name)
        amp, sigma = _extremes(result, info)
        yield _growth(result, name, amp, body.size)
        yield _deformation(result, name, amp, body.size)
        yield _stress(name, sigma, body)


def _extremes(result, info, chunk: int = 256) -> tuple[np.ndarray, float]:
    """Largest node deflection of a beam in its frame at every time (n_t,) and the largest
    stress magnitude of the run."""
    system = result.system
    nd = info.node_dofs[:, :2]
    ed = system.arrays.elements.dofs[info.elements]
    B = np.real(system.arrays.elements.B[info.elements]).reshape(ed.shape[0], 4, 6)
    amp = np.zeros(result.n_t)
    sigma = 0.0
    for k0 in range(0, result.n_t, chunk):
        q = np.real(result.q[k0:k0 + chunk])
        w = np.where(nd >= 0, q[:, np.maximum(nd, 0)], 0.0)  # (k, n_nodes, 2)
        amp[k0:k0 + chunk] = np.sqrt(np.max(np.sum(w * w, axis=2), axis=1))
        d = np.where(ed >= 0, q[:, np.maximum(ed, 0)], 0.0)  # (k, n_elem, 6)
        sigma = max(sigma, float(np.max(np.abs(np.einsum("enj,kej->ken", B, d)), initial=0.0)))
    return amp, sigma


def _growth(result, name, amp, size) -> Finding | None:
    n = amp.size
    if n < 10:
        return None
    early, late = float(np.max(amp[: int(0.8 * n)])), float(np.max(amp[int(0.8 * n):]))
    if late <= 1e-3 * size or late <= GROWTH_TOL * max(early, 1e-300):
        return None
    return Finding("unbounded growth", repr(name), late / max(early, 1e-300), GROWTH_TOL,
                   f"the deformation of beam {name!r} grows from {early:.3g} to {late:.3g} in "
                   "the last fifth of the run: the solution diverges (a single floating frame "
                   "spun or loaded beyond its validity? try add_beam(..., frames=...))")


def _deformation(result, name, amp, size) -> Finding | None:
    k = int(np.argmax(amp))
    if amp[k] <= DEFORMATION_TOL * size:
        return None
    return Finding("implausible deformation", repr(name), float(amp[k] / size),
                   DEFORMATION_TOL,
                   f"beam {name!r} is deformed by {amp[k]:.3g} ({amp[k] / size:.0%} of its size "
                   f"{size:.3g}) at t={result.t[k]:.6g} relative to its frame: check the units "
                   "(E, density and lengths consistent?) and the loads")


def _stress(name, sigma, body) -> Finding | None:
    E = float(np.min(np.real(np.asarray(body.E))))
    if sigma <= E:
        return None
    return Finding("implausible stress", repr(name), float(sigma / E), 1.0,
                   f"the stress in beam {name!r} reaches {sigma:.3g}, above its Young's "
                   f"modulus {E:.3g}: check the units (E in MPa with lengths in mm, say)")


def report_findings(result, findings: list[Finding], mode: str) -> None:
    """Apply the findings to ``result``: status ``"warning"`` and the findings listed, and an
    :class:`AccuracyWarning` each at the user's line (``mode="warn"``) or an
    :class:`AccuracyError` (``"raise"``). A finding that fails the run (a joint violated far
    beyond its tolerance) raises :class:`ConstraintViolationError` with status ``"failed"``
    in either mode; ``"off"`` reports nothing."""
    if mode not in CHECK_MODES:
        raise ModelError(f"checks must be one of {CHECK_MODES}, got {mode!r}")
    result.findings = list(findings)
    if not findings or mode == "off":
        return
    result.status = "warning"
    result.message += "; " + "; ".join(f"{f.check} ({f.where})" for f in findings)
    failed = [f for f in findings if f.failed]
    if failed:
        result.status = "failed"
        k = failed[0].step
        raise ConstraintViolationError("; ".join(f.message for f in findings), result=result,
                                       time=float(result.t[k]), step=k)
    if mode == "raise":
        raise AccuracyError("; ".join(f.message for f in findings), result=result,
                            time=float(result.t[-1]), step=result.n_t - 1)
    for f in findings:
        kind = KinematicAccuracyWarning if f.check == "kinematic accuracy" else AccuracyWarning
        warn(kind(f.message))


def check_kinematic_tol(value) -> float | None:
    """``value`` as a kinematic tolerance: None (off) or a number in (0, 1)."""
    if value is None:
        return None
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.number)) \
            or not 0 < float(np.real(value)) < 1 or isinstance(value, complex):
        raise ModelError(f"kinematic_tol must be None (off) or a number in (0, 1) (relative to "
                         f"a beam's length), got {value!r}")
    return float(value)
