"""Simulation results: stacked histories, accessors by name, energy, statistics.

Every accessor is written with NumPy operations that keep complex values (``cos``, ``sin``,
products, sums), so the response functions built on them can be differentiated by complex step.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..compile.system import System, time_table
from ..errors import ModelError
from ..kernels.assemble import residual
from ..kernels.ffrf import scratch
from ..kernels.forces import measures as spring_measures
from ..kernels.schema import KINDS
from ..kernels.system import parts_of_kinds
from ..kernels.types import Level, Weights
from ..model import Beam, RigidBody
from . import reactions
from .kinematics import kinematics


@dataclass
class Result:
    """Histories of one run.

    Attributes
    ----------
    t : (n_t,)
        Times [s].
    q, v, a : (n_t, n_dof)
        Generalized coordinates, velocities, accelerations.
    lam : (n_t, n_con)
        Lagrange multipliers (constraint forces/torques of each row).
    newton_iterations : (n_t,) int
        Newton iterations (= factorizations) of each step; 1 for the initial solve.
    q, v, a, lam may be None: the histories a run did not keep (``simulate(store=...)``).
    constraint_violation, velocity_violation : (n_t,)
        ``max |Phi|`` and ``max |Phi'|`` after each step.
    status, message : str
        ``"ok"``, ``"warning"`` (a check of the finished run failed: ``findings``),
        ``"failed"`` or ``"interrupted"``, and a readable sentence.
    findings : list of Finding
        What the run's own checks found doubtful (:mod:`morphlab.results.checks`).
    analysis : str
        ``"dynamic"`` (:func:`morphlab.simulate`) or ``"static"`` (:func:`morphlab.static`: an
        equilibrium path, ``t`` the load parameter).

    Notes
    -----
    Accuracy of the first steps: ``a``, ``lam`` and what is read off them (:meth:`reaction`,
    :meth:`drive_torque`) carry a transient of first order in the step over the first ~20
    steps of a run, from the constraint stabilization; positions and velocities do not. On a
    driven link it is 7.4e-5 of the peak drive torque at dt = 1e-4 s (rho_inf 0.8; 2.0e-4 at
    rho_inf 0.5), halving with dt, against 2e-8 afterwards; ``stabilization=0`` removes it
    (``docs/accuracy.md``).
    """

    system: System
    settings: object
    t: np.ndarray
    q: np.ndarray
    v: np.ndarray
    a: np.ndarray
    lam: np.ndarray
    newton_iterations: np.ndarray
    constraint_violation: np.ndarray
    velocity_violation: np.ndarray
    status: str = "ok"
    message: str = ""
    n_factorizations: int = 0
    wall_time: float = 0.0
    scale: float = 1.0
    step_reductions: list = field(default_factory=list)
    energy_cache: dict | None = field(default=None, repr=False, compare=False)
    kinematics_cache: dict | None = field(default=None, repr=False, compare=False)
    findings: list = field(default_factory=list)
    newton_log: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)), repr=False)
    newton_log_offsets: np.ndarray = field(default_factory=lambda: np.zeros(1, np.int64),
                                           repr=False)
    analysis: str = "dynamic"

    def __repr__(self) -> str:
        """A few lines for a notebook: run, status, sizes, key figures (not the arrays)."""
        s = self.system
        kept = " ".join(k for k in ("q", "v", "a", "lam") if getattr(self, k) is not None)
        t = self.t
        span = f"t {t[0]:.4g}..{t[-1]:.4g}" if t.size else "no steps"
        what = "static equilibrium path" if self.analysis == "static" else "simulation"
        phi = (f", max |Phi| {self.constraint_violation.max():.3g}"
               if self.constraint_violation.size else "")
        msg = self.message if len(self.message) <= 120 else self.message[:117] + "..."
        return (f"<Result {what} of {getattr(s.model, 'name', '?')!r}: {self.status} "
                f"({msg}); {self.n_t} times, {span}; n_dof {s.n_dof}, n_con {s.n_con}; "
                f"histories {kept or 'none'} {(self.n_t, s.n_dof)}{phi}; "
                f"{len(self.findings)} findings; wall {self.wall_time:.3g} s>")

    @property
    def newton_history(self) -> list:
        """``(|R|, position correction)`` of every Newton iteration of every step after the
        initial solve: a list over the steps of lists of pairs (from the compact
        ``newton_log`` (k, 2), whose rows of step ``n`` are
        ``newton_log_offsets[n]:newton_log_offsets[n + 1]``)."""
        off = self.newton_log_offsets
        return [[tuple(r) for r in self.newton_log[off[n]:off[n + 1]].tolist()]
                for n in range(1, off.size - 1)]

    # ---- coordinates by name
    @property
    def n_t(self) -> int:
        return self.t.shape[0]

    def dof(self, name: str) -> np.ndarray:
        """History of the coordinate called ``name`` (e.g. ``"link.theta"``), (n_t,)."""
        try:
            i = self.system.dof_names.index(name)
        except ValueError:
            raise ModelError(f"no coordinate {name!r}; e.g. {self.system.dof_names[:4]}") from None
        return self.q[:, i]

    def reference(self, body: str):
        """``(R (n_t, 2), theta (n_t,))`` of a body's reference frame (a beam's first
        frame)."""
        info = self.system.body(body)
        return self.q[:, info.ref[:2]], self.q[:, info.ref[2]]

    def _nodal(self, body: str, arr: np.ndarray):
        info = self.system.body(body)
        if info.kind != "beam":
            raise ModelError(f"body {body!r} is not a beam")
        nd = info.node_dofs
        out = np.zeros((arr.shape[0],) + nd.shape, dtype=arr.dtype)
        mask = nd >= 0
        out[:, mask] = arr[:, nd[mask]]
        return info, out

    def node_positions(self, body: str, times=None) -> np.ndarray:
        """Global node positions of a beam, (n_t, n_nodes, 2).

        ``times`` (an index, slice or index array of the time axis) picks the times first:
        ``node_positions(body, -1)`` is ``node_positions(body)[-1]``, (n_nodes, 2), without
        computing the other times (a response at one time, evaluated once per design
        variable on the complex histories of a sensitivity run)."""
        q = self.q if times is None else self.q[times]
        one = q.ndim == 1
        q = q[None] if one else q
        info, w = self._nodal(body, q)
        Rx, Ry, th = _frames_of_nodes(info, q)
        c, s = np.cos(th), np.sin(th)
        ux = info.X[None, :, 0] + w[:, :, 0]
        uy = info.X[None, :, 1] + w[:, :, 1]
        pos = np.stack([Rx + c * ux - s * uy, Ry + s * ux + c * uy], axis=-1)
        return pos[0] if one else pos

    def node_rotations(self, body: str) -> np.ndarray:
        """Absolute rotation ``theta + phi_k`` of every node of a beam relative to its initial
        value, (n_t, n_nodes)."""
        info, w = self._nodal(body, self.q)
        _, _, th = _frames_of_nodes(info, self.q)
        angle0 = info.angle0 if info.node_angle0 is None else info.node_angle0[None, :]
        return th - angle0 + w[:, :, 2]

    def chord_deflection(self, body: str) -> np.ndarray:
        """Transverse deflection of every node of a beam from the straight line (chord)
        through its two end nodes, at every time, (n_t, n_nodes) [length units].

        Positive to the left of the chord's direction (first node towards last). An initially
        curved beam has a nonzero value at ``t[0]``; subtract it for the change. The chord
        moves with the beam, so rigid motion of the whole beam gives no deflection.
        Complex-safe (a response may use it).
        """
        P = self.node_positions(body)
        d = P[:, -1, :] - P[:, 0, :]
        length = np.sqrt(d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1])
        r = P - P[:, :1, :]
        return (d[:, None, 0] * r[:, :, 1] - d[:, None, 1] * r[:, :, 0]) / length[:, None]

    def deformation(self, body: str) -> np.ndarray:
        """Nodal deformation ``(u, v, phi)`` of a beam, each node in the frame that holds it
        (a node shared by two frames: the one that starts there), (n_t, n_nodes, 3)."""
        return self._nodal(body, self.q)[1]

    def point_positions(self, body: str, at) -> np.ndarray:
        """Trajectory of the material point initially at ``at`` (a node on a beam), (n_t, 2)."""
        b = self.system.model.body(body)
        info = self.system.body(body)
        R, th = self.reference(body)
        if isinstance(b, Beam):
            k, dist = b.nearest_node(at)
            if dist > 1e-6 * max(self.system.length_scale, 1.0):
                raise ModelError(f"point {tuple(np.real(at))} is not at a node of beam {body!r} "
                                 f"(nearest node {k} at distance {dist:.3g})")
            return self.node_positions(body)[:, k, :]
        if not isinstance(b, RigidBody):
            raise ModelError(f"body {body!r} has no material points")
        c0, s0 = np.cos(info.angle0), np.sin(info.angle0)
        d = np.asarray(at) - b.position
        u0 = np.array([c0 * d[0] + s0 * d[1], -s0 * d[0] + c0 * d[1]])
        c, s = np.cos(th), np.sin(th)
        return np.stack([R[:, 0] + c * u0[0] - s * u0[1], R[:, 1] + s * u0[0] + c * u0[1]],
                        axis=-1)

    def stress(self, body: str) -> np.ndarray:
        """Normal stress at both ends and both outer fibres of every element of a beam,
        (n_t, n_elements, 2 ends, 2 fibres) [MPa in the morphing units].

        Fibre 0 lies left of the element direction (node k -> k+1), fibre 1 right of it.
        """
        info = self.system.body(body)
        if info.kind != "beam":
            raise ModelError(f"body {body!r} is not a beam; stress is defined for beams")
        sl = info.elements
        ed = self.system.arrays.elements.dofs[sl]
        B = self.system.arrays.elements.B[sl]
        n_e = B.shape[0]
        d = self.q.T[np.maximum(ed, 0)]  # (n_elem, 6, n_t): rows of q^T, one temporary
        d[ed < 0] = 0.0
        s = np.matmul(B.reshape(n_e, 4, 6), d)  # (n_elem, 4, n_t), per element one product
        return s.reshape(n_e, 2, 2, -1).transpose(3, 0, 1, 2)

    # ---- joint reactions and drives (morphlab.results.reactions)
    def reaction(self, name: str, frame: str | None = None) -> np.ndarray:
        """Force ``F_x, F_y`` and moment joint ``name`` transmits to the body it holds, (n_t, 3):
        the action of ``a`` on ``b`` (of the ground on ``body`` for a fix or drive), global or
        in the frame of the body called ``frame`` (:mod:`morphlab.results.reactions`)."""
        return reactions.reaction(self, name, frame)

    def drive_torque(self, name: str) -> np.ndarray:
        """Torque the drive ``name`` applies to its body [force·length], (n_t,)."""
        return reactions.drive_torque(self, name)

    def drive_power(self, name: str) -> np.ndarray:
        """Power the drive ``name`` delivers (torque times angular rate), (n_t,)."""
        return reactions.drive_power(self, name)

    def spring(self, name: str) -> dict:
        """Histories of the spring-damper ``name`` (n_t,) each: ``stretch`` (length minus rest
        length [length], or relative rotation minus rest angle [rad]), its ``rate`` and the
        ``force`` (tension, or moment) ``k stretch + c rate + f0``. Complex-safe: usable in a
        response."""
        s = self.system
        names = s.names.get("springs", [])
        if name not in names:
            known = ", ".join(repr(n) for n in names) or "none"
            raise ModelError(f"no spring-damper {name!r} in the model (spring-dampers: {known})")
        i = names.index(name)
        meas = _spring_histories(s, self)[:, i]
        k, c, s0, f0 = s.table("springs").par[i]
        stretch = meas[:, 0] - s0
        return {"stretch": stretch, "rate": meas[:, 1], "force": k * stretch + c * meas[:, 1] + f0}

    # ---- energy
    @property
    def energy(self) -> dict:
        """Energy balance over time: ``kinetic``, ``strain``, ``gravity`` (potential),
        ``spring`` (potential of the spring-dampers), ``damping`` (dissipated by the beams'
        and the spring-dampers' damping), ``load_work`` (of applied forces, line loads and
        torques), ``drive_work`` (of the drives), ``work`` (both), and ``total`` = kinetic +
        strain + gravity + spring; each (n_t,). ``total - work + damping`` is constant up to
        the integrator's error (computed once, on first access)."""
        if self.energy_cache is None:
            self.energy_cache = energy(self)
        return self.energy_cache

    @property
    def kinematics(self) -> dict:
        """Kinematic accuracy of every beam's floating frames over the run, by beam name
        (:class:`~morphlab.results.kinematics.BeamKinematics`; computed on first access)."""
        if self.kinematics_cache is None:
            self.kinematics_cache = kinematics(self)
        return self.kinematics_cache

    def summary(self) -> str:
        """One paragraph with the run's statistics and the beams' kinematic accuracy. Numbers
        are in the model's own units (``model.units`` when the model names them, else "model
        units")."""
        units = getattr(self.system.model, "units", None)
        where = f"in {units}" if units else "in model units"
        it = self.newton_iterations[1:]
        newton = (f"Newton iterations per step {it.mean() if it.size else 0:.2f} "
                  f"(max {it.max() if it.size else 0}), {self.n_factorizations} factorizations")
        phi = self.constraint_violation.max() if self.constraint_violation.size else 0.0
        if self.analysis == "static":
            steps = self.n_t - 1
            head = (f"static equilibrium path of {steps} load step{'s' if steps != 1 else ''} "
                    f"up to t={self.t[-1]:.6g} (loads and drives taken at t)" if self.n_t
                    else "static equilibrium: no step")
            stats = f"{newton}, max |Phi| {phi:.3g}"
        else:
            head = f"{self.n_t - 1} steps of {self.settings.h:.3g} (time unit of the model)"
            stats = (f"{newton}, max |Phi| {phi:.3g}, max |Phi'| "
                     f"{self.velocity_violation.max() if self.velocity_violation.size else 0:.3g}")
        checks = "".join(f"; check {f.check} at {f.where}: {f.message}"
                         for f in self.findings[:3])
        more = f"; {len(self.findings) - 3} more findings" if len(self.findings) > 3 else ""
        kin = "".join(f"; beam {k!r}: {v.frames} frame(s), element rotation <= "
                      f"{v.rotation.max():.3g} rad, kinematic error ~{v.estimate:.3g} "
                      f"({v.relative:.2g} of its length)" for k, v in self.kinematics.items())
        return (f"{self.status}: {self.message}; {head}, {stats} ({where}), "
                f"wall {self.wall_time:.3g} s{kin}{checks}{more}")


def _frames_of_nodes(info, q: np.ndarray):
    """``(R_x, R_y, theta)`` of the frame holding each node of a beam at the times of ``q``
    (n_t, n_dof): (n_t, 1) each for a single frame, (n_t, n_nodes) for several."""
    if info.n_frames == 1:
        return q[:, info.ref[0], None], q[:, info.ref[1], None], q[:, info.ref[2], None]
    nr = info.node_ref
    return q[:, nr[:, 0]], q[:, nr[:, 1]], q[:, nr[:, 2]]


def energy(res: Result) -> dict:
    """Kinetic, strain, gravitational and spring energy, damping dissipation and external
    work (:attr:`Result.energy`)."""
    if res.q is None or res.v is None:
        raise ModelError("the energy needs the histories of q and v: run with store "
                         "including 'q' and 'v'")
    s = res.system
    A = s.arrays
    n, n_dof = s.n, s.n_dof
    zeros_c = np.zeros(s.n_con, dtype=s.dtype)
    n_t = res.n_t
    kin = np.zeros(n_t)
    strain = np.zeros(n_t)
    grav = np.zeros(n_t)
    power_ext = np.zeros(n_t)
    power_damp = np.zeros(n_t)
    E = A.elements
    ed = E.dofs
    beta = A.bodies.damp[E.body]
    T = time_table(s, res.t) if n_t else None
    W = scratch(s.count("flex"), np.zeros(1, dtype=s.dtype))
    inertia = parts_of_kinds(A, ("bodies", "flex", "elements"))
    loads = parts_of_kinds(A, [k for k, kind in KINDS.items() if kind.work])
    w_inertia = Weights(1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0)
    w_loads = Weights(0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 0.0, 0.0)
    zero = np.zeros(n_dof, dtype=s.dtype)
    for i in range(n_t):
        q, v = np.ascontiguousarray(res.q[i]), np.ascontiguousarray(res.v[i])
        # M v through the inertia term of the residual kernel (the acceleration slot holds v)
        R = np.zeros(n, dtype=s.dtype)
        residual(A, Level(q, zero, v, zeros_c), w_inertia, T, 0, i, inertia, n_dof, R, W)
        kin[i] = 0.5 * np.real(v @ R[:n_dof])
        d = np.where(ed >= 0, q[np.maximum(ed, 0)], 0.0)
        dv = np.where(ed >= 0, v[np.maximum(ed, 0)], 0.0)
        strain[i] = 0.5 * np.real(np.sum(d * np.einsum("eij,ej->ei", E.K, d)))
        power_damp[i] = np.real(np.sum(beta[:, None] * dv * np.einsum("eij,ej->ei", E.K, dv)))
        # external power: -Q_ext . v of the kinds that are loads (their residual is -Q_ext)
        Rl = np.zeros(n, dtype=s.dtype)
        residual(A, Level(q, v, zero, zeros_c), w_loads, T, 0, i, loads, n_dof, Rl, W)
        power_ext[i] = -np.real(v @ Rl[:n_dof])
        grav[i] = _gravity_potential(s, q)
    spring, power_spring = _spring_energy(s, res)
    work = _cumulative(power_ext, res.t)
    diss = _cumulative(power_damp + power_spring, res.t)
    drive = _cumulative(reactions.drive_power_total(res), res.t)
    return {"kinetic": kin, "strain": strain, "gravity": grav, "spring": spring,
            "damping": diss, "load_work": work, "drive_work": drive, "work": work + drive,
            "total": kin + strain + grav + spring}


def _gravity_potential(s: System, q) -> float:
    """``-sum m g . r_cm`` over the bodies, ``r_cm = R + A c_u / m`` (real parts)."""
    B, Fx = s.arrays.bodies, s.arrays.flex
    out = 0.0
    for b in range(B.ref.shape[0]):
        ref = B.ref[b]
        m = np.real(B.scal[b, 0])
        cu = np.real(B.scal[b, 1:3]).astype(float)
        f0, f1 = B.flex[b]
        if f1 > f0:
            cu = cu + np.real(Fx.IS[f0:f1].T @ q[Fx.dof[f0:f1]])
        th = np.real(q[ref[2]])
        Acu = np.array([np.cos(th) * cu[0] - np.sin(th) * cu[1],
                        np.sin(th) * cu[0] + np.cos(th) * cu[1]])
        r = np.real(q[ref[:2]]) * m + Acu
        out -= float(np.real(s.arrays.gravity) @ r)
    return out


def _spring_histories(s: System, res: Result) -> np.ndarray:
    """The measure ``s`` and rate ``s'`` of every spring-damper at every time,
    (n_t, n_spring, 2) (``kernels.forces.measures``)."""
    if res.q is None or res.v is None:
        raise ModelError("the spring-dampers need the histories of q and v: run with store "
                         "including 'q' and 'v'")
    dt = np.result_type(s.dtype, res.q.dtype, res.v.dtype)
    out = np.zeros((res.n_t, s.count("springs"), 2), dtype=dt)
    if out.size:
        spring_measures(s.arrays_as(dt).springs, np.ascontiguousarray(res.q, dtype=dt),
                        np.ascontiguousarray(res.v, dtype=dt), out)
    return out


def _spring_energy(s: System, res: Result) -> tuple[np.ndarray, np.ndarray]:
    """Potential ``k (x^2)/2 + f0 x`` (``x = s - s0``) of the spring-dampers summed, and the
    power ``c s'^2`` their dampers dissipate, at every time (real parts, (n_t,) each)."""
    n_t, n_s = res.n_t, s.count("springs")
    if n_s == 0 or n_t == 0:
        return np.zeros(n_t), np.zeros(n_t)
    out = _spring_histories(s, res)
    k, c, s0, f0 = np.real(s.table("springs").par).T
    x = np.real(out[..., 0]) - s0
    return (np.sum(0.5 * k * x * x + f0 * x, axis=1),
            np.sum(c * np.real(out[..., 1]) ** 2, axis=1))


def _cumulative(power: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Trapezoidal integral of ``power`` from ``t[0]`` to every time."""
    return np.concatenate([[0.0], np.cumsum(0.5 * (power[1:] + power[:-1]) * np.diff(t))])
