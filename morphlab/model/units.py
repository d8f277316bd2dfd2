"""Consistent unit systems, for the plausibility check of a model's data
(:func:`morphlab.compile.checks.check_units`).

morphlab computes in whatever consistent units a model is given in. A model may say which
ones (``model.units = "mm-t-s"`` or ``= ml.units.MM_T_S``): its materials, gravity and masses
are then checked against physical ranges in those units, and a value far outside them is an
error that names the item. Without a declaration, the check looks for a unit system in which
gravity and every beam's material are plausible together, and warns when there is none.
``model.units = "nondimensional"`` turns the check off (a model in scaled variables).

Each system is given by its units of length, time and mass in SI; force, stress and density
follow (a consistent system: force = mass length / time²).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import ModelError
from .bodies import Beam, RigidBody

#: Standard gravity [m/s²] (CGPM 1901).
STANDARD_GRAVITY = 9.80665


@dataclass(frozen=True)
class UnitSystem:
    """A consistent system of units.

    Attributes
    ----------
    name : str
        Its short name, e.g. ``"mm-t-s"``.
    length, time, mass : float
        Its units of length [m], time [s] and mass [kg].
    units : str
        The units by name (length, mass, time, force, stress), for messages.
    """

    name: str
    length: float
    time: float
    mass: float
    units: str

    def __str__(self) -> str:
        return f"{self.name} ({self.units})"

    @property
    def velocity(self) -> float:
        """The unit of velocity [m/s]."""
        return self.length / self.time

    @property
    def acceleration(self) -> float:
        """The unit of acceleration [m/s²]."""
        return self.length / self.time**2

    @property
    def density(self) -> float:
        """The unit of density [kg/m³]."""
        return self.mass / self.length**3

    @property
    def gravity(self) -> float:
        """Standard gravity in this system's units of acceleration."""
        return STANDARD_GRAVITY / self.acceleration


SI = UnitSystem("m-kg-s", 1.0, 1.0, 1.0, "m, kg, s, N, Pa")
MM_T_S = UnitSystem("mm-t-s", 1e-3, 1.0, 1e3, "mm, t, s, N, MPa")
MM_KG_MS = UnitSystem("mm-kg-ms", 1e-3, 1e-3, 1.0, "mm, kg, ms, kN, GPa")
MM_G_MS = UnitSystem("mm-g-ms", 1e-3, 1e-3, 1e-3, "mm, g, ms, N, MPa")
MM_KG_S = UnitSystem("mm-kg-s", 1e-3, 1.0, 1.0, "mm, kg, s, mN, kPa")
CM_G_S = UnitSystem("cm-g-s", 1e-2, 1.0, 1e-3, "cm, g, s, dyn, Ba")
M_T_S = UnitSystem("m-t-s", 1.0, 1.0, 1e3, "m, t, s, kN, kPa")
#: inch, pound-force, second: mass in lbf s²/in (4.4482216152605 N / 0.0254 m/s² in kg)
IN_LBF_S = UnitSystem("in-lbf-s", 0.0254, 1.0, 4.4482216152605 / 0.0254,
                      "in, lbf s²/in, s, lbf, psi")

#: The systems a model's units are looked for among, in this order.
SYSTEMS = (SI, MM_T_S, MM_KG_MS, MM_G_MS, MM_KG_S, CM_G_S, M_T_S, IN_LBF_S)
#: ``model.units`` of a model in scaled variables: not checked.
NONDIMENSIONAL = "nondimensional"

# Physical ranges (SI) of what a model's data are checked against, wide on purpose: a unit
# mistake moves a value by a factor of 25 (inch) to 1e12 (density in kg/m³ for t/mm³).
#: Densities of structural solids [kg/m³]: from rigid foams (~15-30) to osmium (22 590).
DENSITY_RANGE = (10.0, 2.5e4)
#: Bar wave speeds sqrt(E/rho) of solids [m/s]: from soft elastomers (~20-50: E ~ 1 MPa,
#: rho ~ 1100 kg/m³) to diamond (~17 000: E ~ 1.05e12 Pa, rho = 3510 kg/m³).
WAVE_SPEED_RANGE = (10.0, 2.0e4)
#: Gravitational accelerations [m/s²] a model may use: the Moon's 1.62 to Jupiter's 24.8, with
#: margin (a centrifuge or a test rig may use more).
GRAVITY_RANGE = (1.0, 100.0)
#: The densest element, osmium [kg/m³]: a bound on a rigid body's mass for its size.
DENSEST = 2.26e4


def of(value) -> UnitSystem | str | None:
    """``value`` as a unit system: a :class:`UnitSystem`, one's name (``"mm-t-s"``), None
    (not declared) or :data:`NONDIMENSIONAL`; anything else is a :class:`ModelError` naming
    the valid names."""
    if value is None or isinstance(value, UnitSystem):
        return value
    if isinstance(value, str):
        if value == NONDIMENSIONAL:
            return value
        for s in SYSTEMS:
            if s.name == value:
                return s
    names = ", ".join(repr(s.name) for s in SYSTEMS)
    raise ModelError(f"model units must be a morphlab.units.UnitSystem, one of {names}, "
                     f"{NONDIMENSIONAL!r} (not checked) or None (inferred), got {value!r}")


# ---------------------------------------------------------------------------- plausibility
#: A value this many times beyond its physical range, in the units a model declares, is an
#: error rather than a warning.
UNITS_CERTAIN = 10.0


def plausibility(model, t_end: float | None = None, length_scale: float = 1.0) -> list[str]:
    """What in ``model`` looks like a unit mistake, as messages that name the item; raises
    :class:`ModelError` where the model declares its units and a value lies more than
    :data:`UNITS_CERTAIN` times outside its physical range in them.

    * **materials and gravity**: every beam's bar wave speed ``sqrt(E/rho)`` (and its
      density, when its section is given by thickness and width) and the magnitude of
      gravity, in SI for each system of :data:`SYSTEMS`, against :data:`WAVE_SPEED_RANGE`,
      :data:`DENSITY_RANGE` and :data:`GRAVITY_RANGE`. The wave speed is a length over a
      time and gravity a length over a time squared, so together they fix the model's units
      of length and time. A model that declares its units (``model.units``) is checked in
      them; one that does not is reported when no system fits all of these at once (E in Pa
      and rho in kg/m³ with gravity in mm/s², or gravity 9.81 with a material in MPa and
      t/mm³).
    * **rigid-body masses**, when the unit of mass is known (declared, or left by the beams'
      densities): a body heavier than a ball of osmium three times its size (the larger of
      its radius of gyration and the distance to its joints and loads) could be (a mass in
      kg with lengths in mm). Bodies smaller than 1e-3 of ``length_scale`` are points: not
      checked.
    * **angles**: a rigid body's initial angle beyond a full turn, a rotational spring's rest
      angle or a drive's angle at rest at ``t_end`` beyond a full turn and a whole number of
      15 degrees: degrees where radians are meant.

    ``model.units = "nondimensional"`` skips the first two (a model in scaled variables).
    """
    declared = of(getattr(model, "units", None))
    found: list[str] = []
    if declared != NONDIMENSIONAL:
        evidence = _unit_evidence(model)
        if isinstance(declared, UnitSystem):
            found += _check_declared(model, declared, evidence)
            masses_in = [declared]
        else:
            fits = [s for s in SYSTEMS if all(e.fits(s) for e in evidence)]
            if evidence and not fits:
                found.append(_no_system(model, evidence))
            densities = any(e.density is not None for e in evidence)
            masses_in = fits if densities else []
        if masses_in:
            found += _rigid_masses(model, min(masses_in, key=lambda u: u.mass), length_scale)
    return found + _angles(model, t_end)


class _Evidence:
    """One item of a model whose value fixes (part of) its units: gravity or a beam."""

    def __init__(self, what: str, acceleration=None, speed=None, density=None):
        self.what = what
        self.acceleration, self.speed, self.density = acceleration, speed, density

    def ranges(self, u) -> list[tuple[str, str, float, tuple]]:
        """``(quantity, SI unit, value in SI, its physical range)`` of this item in units
        ``u``."""
        out = []
        if self.acceleration is not None:
            out.append(("magnitude", "m/s²", self.acceleration * u.acceleration, GRAVITY_RANGE))
        for c in self.speed or ():
            out.append(("wave speed sqrt(E/rho)", "m/s", c * u.velocity, WAVE_SPEED_RANGE))
        for r in self.density or ():
            out.append(("density", "kg/m³", r * u.density, DENSITY_RANGE))
        return out

    def excess(self, u) -> float:
        """How many times the farthest value lies outside its range in units ``u`` (1:
        inside)."""
        return max([max(lo / v if v > 0 else np.inf, v / hi, 1.0)
                    for _, _, v, (lo, hi) in self.ranges(u)] or [1.0])

    def fits(self, u) -> bool:
        return self.excess(u) <= 1.0

    def describe(self, u) -> str:
        """The values outside their ranges in units ``u``, for a message."""
        return ", ".join(f"{q} {v:.3g} {unit} (expected {lo:g} to {hi:g})"
                         for q, unit, v, (lo, hi) in self.ranges(u) if not lo <= v <= hi)


def _unit_evidence(model) -> list[_Evidence]:
    out = []
    g = float(np.hypot(*np.real(np.asarray(model.gravity, dtype=complex))))
    if g > 0:
        out.append(_Evidence(f"gravity {g:.4g}", acceleration=g))
    for b in model.bodies:
        if not isinstance(b, Beam):
            continue
        E = np.unique(np.atleast_1d(np.real(np.asarray(b.E))))
        rho = np.unique(np.atleast_1d(np.real(np.asarray(b.rho))))
        c = np.unique(np.sqrt(np.atleast_1d(np.real(np.asarray(b.E / b.rho)))))
        shown = f"beam {b.name!r} (E {_few(E)}, rho {_few(rho)})"
        out.append(_Evidence(shown, speed=np.unique([c.min(), c.max()]),
                             density=np.unique([rho.min(), rho.max()])
                             if b.thickness is not None else None))
    return out


def _few(values) -> str:
    return f"{values[0]:.3g}" if values.size == 1 else f"{values.min():.3g}..{values.max():.3g}"


def _check_declared(model, u, evidence) -> list[str]:
    """Each item outside its range in the declared units ``u``: raise beyond
    :data:`UNITS_CERTAIN` times the range, else a message."""
    certain, doubtful = [], []
    for e in evidence:
        x = e.excess(u)
        if x > 1.0:
            other = [s.name for s in SYSTEMS if e.fits(s)]
            hint = f"; it fits {', '.join(other)}" if other else ""
            text = f"{e.what}: {e.describe(u)} in {u}{hint}"
            (certain if x > UNITS_CERTAIN else doubtful).append(text)
    if certain:
        raise ModelError(f"model {model.name!r} declares its units {u.name!r}, but "
                         + "; ".join(certain) + ": check the units of these items")
    return [f"model {model.name!r} ({u.name}): {t}" for t in doubtful]


def _no_system(model, evidence) -> str:
    """The message for data that fit no one unit system: what fits where, and what is off in
    the (at most two) systems that fit most items."""
    parts = []
    for e in evidence:
        where = [s.name for s in SYSTEMS if e.fits(s)]
        parts.append(f"{e.what} fits {', '.join(where) if where else 'none of them'}")
    score = {s: sum(not e.fits(s) for e in evidence) for s in SYSTEMS}
    best = sorted(SYSTEMS, key=lambda s: score[s])[:2]
    off = [f"in {s.name}, " + "; ".join(f"{e.what.split(' (')[0]} has {e.describe(s)}"
                                        for e in evidence if not e.fits(s)) for s in best]
    names = ", ".join(s.name for s in SYSTEMS)
    return (f"model {model.name!r}: no consistent unit system ({names}) fits all its data: "
            + "; ".join(parts) + ". " + "; ".join(off)
            + ". Check the units of these items (E in MPa with rho in t/mm³ and gravity "
            "9810 mm/s², or E in Pa with rho in kg/m³ and gravity 9.81 m/s²), or declare the "
            "model's (model.units = 'mm-t-s', see morphlab.units; 'nondimensional' for scaled "
            "variables)")


def _attachments(model, body) -> list[np.ndarray]:
    """The points at which joints, loads and springs act on ``body``."""
    out = []
    for item in (*model.joints, *model.forces, *model.torques, *model.springs):
        for side, point in (("a", "at"), ("b", "at"), ("body", "at"), ("a", "at_a"),
                            ("b", "at_b")):
            if getattr(item, side, None) is body and getattr(item, point, None) is not None:
                out.append(np.real(np.asarray(getattr(item, point), dtype=complex)))
    return out


def _rigid_masses(model, u, length_scale: float) -> list[str]:
    """Rigid bodies heavier, in units ``u``, than osmium could make them
    (:func:`plausibility`)."""
    out = []
    for b in model.bodies:
        if not isinstance(b, RigidBody):
            continue
        m, inertia = float(np.real(b.mass)), float(np.real(b.inertia))
        c = np.real(np.asarray(b.position, dtype=complex))
        reach = [float(np.hypot(*(p - c))) for p in _attachments(model, b)]
        radius = max([np.sqrt(inertia / m), *reach])
        if radius <= 1e-3 * length_scale:  # a point: nothing to compare with
            continue
        bound = DENSEST * 4.0 / 3.0 * np.pi * (3.0 * radius * u.length) ** 3
        if m * u.mass > bound:
            length, mass = u.units.split(", ")[:2]
            out.append(f"rigid body {b.name!r}: mass {m:.3g} is {m * u.mass:.3g} kg in {u}, "
                       f"more than a ball of osmium three times its size (radius of gyration "
                       f"and joints within {radius:.3g} {length}) could weigh ({bound:.3g} kg): "
                       f"a mass in kg with lengths in mm? ({u.name}: mass in {mass})")
    return out


def _round_degrees(x: float) -> bool:
    """More than a full turn and a whole number of 15 degrees (90, 180, 45, ...)."""
    return abs(x) > 2 * np.pi and abs(x / 15.0 - round(x / 15.0)) < 1e-9


def _angles(model, t_end) -> list[str]:
    out = []
    for b in model.bodies:
        a = float(np.real(getattr(b, "angle", 0.0)))
        if isinstance(b, RigidBody) and abs(a) > 2 * np.pi:
            out.append(f"rigid body {b.name!r}: initial angle {a:g} is more than a full turn: "
                       f"angles are in radians (degrees? {a:g}° = {np.radians(a):.6g} rad)")
    for s in model.springs:
        r = float(np.real(getattr(s, "rest_angle", 0.0) or 0.0))
        if _round_degrees(r):
            out.append(f"rotational spring {s.name!r}: rest angle {r:g} is more than a full "
                       f"turn: angles are in radians (degrees? {r:g}° = {np.radians(r):.6g} rad)")
    if t_end is None:
        return out
    for j in model.joints:
        prof = getattr(j, "profile", None)
        if prof is None or not hasattr(prof, "d1"):
            continue
        try:
            a, rate = float(np.real(prof.value(t_end))), float(np.real(prof.d1(t_end)))
        except Exception:  # a user's profile: it reports its own failures during the run
            continue
        if _round_degrees(a) and abs(rate) * max(abs(t_end), 1e-300) <= 1e-9 * abs(a):
            out.append(f"drive {j.name!r}: its angle comes to rest at {a:g} by t={t_end:g}, "
                       f"more than a full turn: angles are in radians (degrees? {a:g}° = "
                       f"{np.radians(a):.6g} rad)")
    return out


__all__ = ["CM_G_S", "DENSEST", "DENSITY_RANGE", "GRAVITY_RANGE", "IN_LBF_S", "MM_G_MS",
           "MM_KG_MS", "MM_KG_S", "MM_T_S", "M_T_S", "NONDIMENSIONAL", "SI", "STANDARD_GRAVITY",
           "SYSTEMS", "UNITS_CERTAIN", "UnitSystem", "WAVE_SPEED_RANGE", "of", "plausibility"]
