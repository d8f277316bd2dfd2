"""``compile_model(..., like=system)`` reuses the Newton pattern of a system of the same
topology (the perturbed designs of a sensitivity run) and builds its own otherwise."""

import numpy as np

import morphlab as ml
from morphlab.compile.compile import _PATTERN_KEYS

mo = ml.morphing


def test_pattern_of_a_perturbed_design_equals_a_fresh_one():
    sys0 = ml.compile_model(mo.build(mo.DEFAULTS))
    p = dict(mo.DEFAULTS, t_w=mo.DEFAULTS["t_w"] + 1e-30j)
    reused = ml.compile_model(mo.build(p), like=sys0)
    fresh = ml.compile_model(mo.build(p))
    for k in _PATTERN_KEYS:
        np.testing.assert_array_equal(getattr(reused, k), getattr(fresh, k))
        assert getattr(reused, k) is getattr(sys0, k)  # shared, not rebuilt
    np.testing.assert_array_equal(reused.elem_K, fresh.elem_K)


def test_other_topology_builds_its_own_pattern():
    sys0 = ml.compile_model(mo.build(mo.DEFAULTS))
    other = ml.compile_model(mo.build(mo.DEFAULTS, n_elements=60), like=sys0)
    fresh = ml.compile_model(mo.build(mo.DEFAULTS, n_elements=60))
    assert other.indices is not sys0.indices
    for k in _PATTERN_KEYS:
        np.testing.assert_array_equal(getattr(other, k), getattr(fresh, k))
