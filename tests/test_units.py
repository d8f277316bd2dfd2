"""The plausibility check of a model's units (morphlab.model.units.plausibility, run by
simulate and static before they start): unit mistakes are named, consistent models in the
common unit systems are quiet, a declared unit system makes the check an error."""

import warnings

import numpy as np
import pytest

import morphlab as ml
from morphlab.errors import UnitsWarning


def rod(E=70000.0, rho=2.7e-9, g=9.81e3, L=300.0, units=None, mass=None, inertia=0.2,
        angle=0.0, section=None, name="rig"):
    """A clamped aluminium rod (thickness 2, width 10 by default) in the mm-t-s units (N,
    MPa) unless told otherwise; ``mass``: a rigid body pinned at its tip, its centre 10
    length units beyond."""
    m = ml.Model(gravity=(0.0, -g), name=name)
    nodes = np.stack([np.linspace(0.0, L, 7), np.zeros(7)], axis=1)
    sec = section or dict(thickness=2.0 * L / 300.0, width=10.0 * L / 300.0)
    r = m.add_beam(nodes, E=E, rho=rho, name="rod", **sec)
    m.add_fix(r, at=(0.0, 0.0), name="clamp")
    if mass is not None:
        b = m.add_rigid_body(mass=mass, inertia=inertia, position=(L + 10.0 * L / 300.0, 0.0),
                             angle=angle, name="crank")
        m.add_revolute(r, b, at=(L, 0.0), name="pin")
    if units is not None:
        m.units = units
    return m


def found(model, t_end=0.01):
    """The units warnings of a short run of ``model`` (their messages)."""
    with warnings.catch_warnings(record=True) as rec:
        warnings.simplefilter("always")
        ml.simulate(model, t_end=t_end, dt=t_end / 2, checks="off")
    return [str(w.message) for w in rec if issubclass(w.category, UnitsWarning)]


@pytest.mark.parametrize("case", ["mm-t-s", "SI", "mm-kg-ms", "mm-g-ms", "in-lbf-s",
                                  "SI section", "mm-t-s heavy crank"])
def test_consistent_models_in_common_units_are_quiet(case):
    """Aluminium (E 70 GPa, rho 2700 kg/m^3) and steel, with gravity, in the units people
    use, converted by hand; the spin-up beam's section trick (area 1, E = EA, rho = rho A) in
    SI; a crank of 0.2 kg with a radius of gyration of 32 mm."""
    model = {
        "mm-t-s": lambda: rod(),
        "SI": lambda: rod(E=2.1e11, rho=7850.0, g=9.81, L=0.3),
        "mm-kg-ms": lambda: rod(E=70.0, rho=2.7e-6, g=9.81e-3),
        "mm-g-ms": lambda: rod(E=70000.0, rho=2.7e-3, g=9.81e-3),
        "in-lbf-s": lambda: rod(E=1.015e7, rho=2.53e-4, g=386.1, L=12.0),
        "SI section": lambda: rod(E=2.8e7, rho=1.2, g=0.0, L=10.0,
                                  section=dict(area=1.0, second_moment=5e-4)),
        "mm-t-s heavy crank": lambda: rod(mass=2e-4),
    }[case]()
    assert found(model, 0.01 if case not in ("mm-kg-ms", "mm-g-ms") else 10.0) == []


def test_pascals_and_kilograms_per_cubic_metre_with_millimetres():
    """E = 70e9 (Pa) and rho = 2700 (kg/m^3) with lengths in mm and gravity 9810 mm/s^2:
    the wave speed sqrt(E/rho) = 5090 is 5.09 m/s in mm-s units (solids: 10 to 2e4) and the
    density 2.7e15 kg/m^3, while gravity fits only mm-s units: the warning names both."""
    (msg,) = found(rod(E=70e9, rho=2700.0))
    assert "beam 'rod'" in msg and "gravity 9810" in msg and "fits m-kg-s" in msg
    assert "wave speed sqrt(E/rho) 5.09 m/s" in msg


def test_gravity_in_metres_with_a_model_in_millimetres():
    """gravity 9.81 with the mm-t-s aluminium: 0.00981 m/s^2 in mm-t-s."""
    (msg,) = found(rod(g=9.81))
    assert "gravity 9.81 fits m-kg-s" in msg and "beam 'rod'" in msg and "fits mm-t-s" in msg
    assert "0.00981 m/s²" in msg


def test_mass_in_kilograms_with_millimetres():
    """A crank of 0.2 given in kg in a mm-t-s model is 200 kg, more than a ball of osmium
    three times its size (joints within 10 mm: 2.56 kg) could weigh; the same crank in t
    (2e-4) is quiet (test above)."""
    (msg,) = found(rod(mass=0.2))
    assert msg.startswith("rigid body 'crank': mass 0.2 is 200 kg in mm-t-s")


@pytest.mark.parametrize("where", ["body", "spring", "drive"])
def test_angles_in_degrees(where):
    """angle=90 on a rigid body, a rotational spring's rest angle of 180, a drive that
    turns to 90 and stops: each named."""
    m = rod(mass=2e-4, angle=90.0 if where == "body" else 0.0)
    if where == "spring":
        m.add_rotational_spring("coil", "pin", stiffness=1.0, rest_angle=180.0)
        expect = "rotational spring 'coil': rest angle 180"
    elif where == "drive":
        m.add_drive("crank", angle=90.0 * ml.SmoothStep(0.0, 4e-3), name="motor")
        expect = "drive 'motor': its angle comes to rest at 90"
    else:
        expect = "rigid body 'crank': initial angle 90"
    with warnings.catch_warnings(record=True) as rec:
        warnings.simplefilter("always")
        try:
            ml.simulate(m, t_end=0.01, dt=5e-3, checks="off")
        except ml.SolverError:
            pass  # the warning comes before the run
    msgs = [str(w.message) for w in rec if issubclass(w.category, UnitsWarning)]
    assert len(msgs) == 1 and msgs[0].startswith(expect), msgs
    assert ("3.14159 rad" if where == "spring" else "1.5708 rad") in msgs[0]


def test_a_declared_unit_system_makes_a_mistake_an_error():
    """Declared mm-t-s: E in Pa is an error naming the beam (the density is 1e11 times its
    range); declared SI for the mm-t-s rod too; the right declaration is quiet, and
    'nondimensional' switches the material check off."""
    with pytest.raises(ml.ModelError, match=r"declares its units 'mm-t-s'.*beam 'rod'.*fits "
                                            r"m-kg-s"):
        ml.simulate(rod(E=70e9, rho=2700.0, units="mm-t-s"), t_end=0.01, dt=5e-3)
    with pytest.raises(ml.ModelError, match="declares its units 'm-kg-s'.*gravity 9810"):
        ml.static(rod(units=ml.units.SI))
    assert found(rod(units=ml.units.MM_T_S)) == []
    assert found(rod(E=1.0, rho=1.0, g=0.0, units="nondimensional"), 100.0) == []
    assert len(found(rod(E=1.0, rho=1.0, g=0.0), 100.0)) == 1  # undeclared: named


def test_an_unknown_unit_system_is_refused():
    with pytest.raises(ml.ModelError, match="model units must be .*'mm-t-s'"):
        ml.simulate(rod(units="mm"), t_end=0.01, dt=5e-3)


def test_unit_systems_are_consistent():
    """Each system's standard gravity and stress unit against the textbook values."""
    u = ml.units
    assert u.MM_T_S.gravity == pytest.approx(9806.65)
    assert u.IN_LBF_S.gravity == pytest.approx(386.09, rel=1e-4)  # in/s^2
    assert u.MM_KG_MS.mass / (u.MM_KG_MS.length * u.MM_KG_MS.time**2) == pytest.approx(1e9)
    assert u.MM_T_S.mass / (u.MM_T_S.length * u.MM_T_S.time**2) == pytest.approx(1e6)
    psi = 4.4482216152605 / 0.0254**2  # lbf/in^2 in Pa
    assert u.IN_LBF_S.mass / (u.IN_LBF_S.length * u.IN_LBF_S.time**2) == pytest.approx(psi)


def test_declared_units_travel_with_a_saved_result(tmp_path):
    """The declaration is stored and read back (the summary names the units); a user's own
    system keeps its fields."""
    res = ml.simulate(rod(units="mm-t-s"), t_end=0.01, dt=5e-3)
    ml.io.save(res, tmp_path / "a.npz")
    back = ml.io.load(tmp_path / "a.npz")
    assert back.system.model.units is ml.units.MM_T_S
    assert "in mm-t-s (mm, t, s, N, MPa)" in back.summary()
    own = ml.units.UnitSystem("dm-kg-s", 0.1, 1.0, 1.0, "dm, kg, s, dN, ...")
    res = ml.simulate(rod(E=7e8, rho=2.7, g=98.1, L=3.0, units=own), t_end=0.01, dt=5e-3)
    ml.io.save(res, tmp_path / "b.npz")
    assert ml.io.load(tmp_path / "b.npz").system.model.units == own
