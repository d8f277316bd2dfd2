"""The compile record (morphlab.compile.record): a design compiled ``like`` a nominal copies
the beams whose inputs did not change, and the copy is the compile's own output bit for bit."""

import numpy as np
import pytest

import morphlab as ml
from morphlab.kernels.schema import KINDS
from morphlab.morphing import leading_edge as le


def _assert_identical(a, b):
    """Every array and name list of two systems equal (NaN where both are NaN)."""
    assert a.dof_names == b.dof_names and a.con_names == b.con_names
    assert a.con_joint == b.con_joint and a.names == b.names
    for f in ("design", "q0", "v0", "con_sign", "con_side", "con_kind", "con_item", "indices",
              "indptr"):
        np.testing.assert_array_equal(getattr(a, f), getattr(b, f), err_msg=f)
    for k in KINDS:
        ta, tb = a.table(k), b.table(k)
        assert (ta is None) == (tb is None), k
        if ta is not None:
            for f in ta._fields:
                np.testing.assert_array_equal(getattr(ta, f), getattr(tb, f), err_msg=(k, f))
    for k in a.time_base:
        np.testing.assert_array_equal(a.time_base[k], b.time_base[k], err_msg=k)
        assert [i for i, _ in a.time_profiles[k]] == [i for i, _ in b.time_profiles[k]]


@pytest.fixture(scope="module")
def nominal():
    return ml.compile_model(le.build(le.DEFAULTS))


@pytest.mark.parametrize("variable", list(le.DEFAULTS))
def test_a_perturbed_design_compiled_like_the_nominal_is_its_own_compile(nominal, variable):
    """Complex-step designs of each of the study's variables: the skin is copied exactly when
    the variable leaves it alone (the torque, the mechanism's points), compiled when it changes
    it (its thickness, its modulus), and either way the system equals a compile from scratch."""
    p = dict(le.DEFAULTS)
    p[variable] = p[variable] + 1e-30j
    fresh = ml.compile_model(le.build(p))
    like = ml.compile_model(le.build(p), like=nominal)
    _assert_identical(like, fresh)
    copied = like.record["skin"] is nominal.record["skin"]
    assert copied == (variable not in ("t_w", "E")), variable
    # a section variable (the thickness, the modulus) keeps the skin's layout: its rows are
    # copied with the element data computed again, and its record holds the new inputs
    section = like.record["skin"].info is nominal.record["skin"].info
    assert section, variable
    assert like.record["skin"].inputs["E"] == p["E"]
    # a design that changes sections alone is a copy of the nominal system (its body table
    # shared), not a compile
    assert (like.bodies is nominal.bodies) == (variable in ("t_w", "E")), variable


def test_a_thickness_of_a_few_elements_is_a_section_copy_and_exact():
    """One thickness variable of a few elements of a many-frame skin (the gradient bench's
    problem): a section copy, equal to a compile from scratch bit for bit; its record serves a
    further design compiled like it."""
    from morphlab.bench.variables import problem

    build, p0, _ = problem(20, n_elements=60)
    nominal = ml.compile_model(build(p0))
    name = next(k for k in p0 if k.startswith("t"))
    p = dict(p0)
    p[name] = p[name] + 1e-30j
    like = ml.compile_model(build(p), like=nominal)
    assert like.record["skin"].info is nominal.record["skin"].info
    assert like.bodies is nominal.bodies  # a copy of the nominal system
    _assert_identical(like, ml.compile_model(build(p)))
    other = [k for k in p0 if k.startswith("t")][-1]
    q = dict(p)
    q[other] = q[other] * 1.01 + 2e-30j  # a further section change, like the perturbed design
    again = ml.compile_model(build(q), like=like)
    assert again.record["skin"].info is nominal.record["skin"].info
    _assert_identical(again, ml.compile_model(build(q)))
    # a real design is not copied from a complex one (its imaginary parts would be dropped)
    assert ml.compile_model(build(p0), like=like).record["skin"].info \
        is not like.record["skin"].info


def test_a_moved_node_compiles_the_beam_again(nominal):
    """Node positions are not a section: the frames, their angles and joints move, so the skin
    is compiled (not copied), and the system equals a compile from scratch."""
    moved = le.build(le.DEFAULTS)
    skin = next(b for b in moved.bodies if b.name == "skin")
    skin.nodes = skin.nodes.copy()
    skin.nodes[3] = skin.nodes[3] + np.array([1e-3, -2e-3])
    like = ml.compile_model(moved, like=nominal)
    assert like.record["skin"].info is not nominal.record["skin"].info
    _assert_identical(like, ml.compile_model(moved))


def test_a_beam_after_a_changed_item_is_compiled(nominal):
    """The record applies only where the builder stands as it stood: a model with one more
    body before the skin (its DOFs shift) compiles the skin again, correctly."""
    extra = le.build(le.DEFAULTS)
    first = extra.add_rigid_body(mass=1e-6, inertia=1e-3, position=(0.0, 0.0), name="first")
    extra.bodies.remove(first)
    extra.bodies.insert(0, first)  # compiled before the skin: the skin's DOFs shift by 3
    extra.add_fix(first, at=(0.0, 0.0), dofs="xyr", name="held")
    like = ml.compile_model(extra, like=nominal)
    assert like.record["skin"] is not nominal.record["skin"]
    _assert_identical(like, ml.compile_model(extra))


@pytest.mark.parametrize("step", [1e-30j, 1e-6], ids=["complex-step", "difference"])
def test_a_copied_beam_of_a_model_started_by_a_drive_takes_the_velocities_anew(step):
    """A model whose initial velocities are computed from a drive moving at ``t = 0`` (least
    kinetic energy, which the beam's mass enters): a perturbed design compiled like it copies
    the beam's rows, not the velocities computed for the nominal, and equals its own compile
    (the copy of those velocities left the other bodies at rest: a perturbed run of a
    complex-step or finite-difference gradient started from another state)."""
    from tests.models import flexible_mechanism

    def build(t):
        m = flexible_mechanism()
        next(b for b in m.bodies if b.name == "coupler").thickness = t
        m.add_drive(m.bodies[0], speed=10.0, name="motor")
        return m

    nominal = ml.compile_model(build(2.0))
    assert np.count_nonzero(nominal.v0) > 3  # the drive moves the mechanism at t = 0
    for t in (2.0, 2.0 + step):  # the beam copied as it is; its section computed again
        like = ml.compile_model(build(t), like=nominal)
        assert like.record["coupler"].info is nominal.record["coupler"].info
        assert like.bodies is not nominal.bodies  # compiled: its velocities computed anew
        _assert_identical(like, ml.compile_model(build(t)))


def test_a_changed_gravity_is_compiled_not_copied(nominal):
    """The gravity enters every body's load: a design with another gravity (and a new skin
    thickness) is compiled, not copied, and equals its own compile."""
    p = dict(le.DEFAULTS, t_w=le.DEFAULTS["t_w"] + 1e-30j)
    model = le.build(p)
    model.gravity = model.gravity + np.array([0.0, -1.0])
    like = ml.compile_model(model, like=nominal)
    assert like.bodies is not nominal.bodies
    _assert_identical(like, ml.compile_model(model))
    assert not np.array_equal(like.arrays.gravity, nominal.arrays.gravity)
