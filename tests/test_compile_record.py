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
