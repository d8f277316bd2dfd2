"""``compile_model(..., like=system)`` reuses the Newton pattern of a system of the same
topology (the perturbed designs of a sensitivity run) and builds its own otherwise."""

import numpy as np

import morphlab as ml
from morphlab.kernels.schema import KINDS, PATTERN

mo = ml.morphing


def test_pattern_of_a_perturbed_design_equals_a_fresh_one():
    sys0 = ml.compile_model(mo.build(mo.DEFAULTS))
    p = dict(mo.DEFAULTS, t_w=mo.DEFAULTS["t_w"] + 1e-30j)
    reused = ml.compile_model(mo.build(p), like=sys0)
    fresh = ml.compile_model(mo.build(p))
    for kind, f in _pattern_fields(sys0):
        a, b = getattr(reused.table(kind), f), getattr(fresh.table(kind), f)
        np.testing.assert_array_equal(a, b)
        assert a is getattr(sys0.table(kind), f)  # shared, not rebuilt
    assert reused.indices is sys0.indices
    np.testing.assert_array_equal(reused.arrays.elements.K, fresh.arrays.elements.K)


def test_other_topology_builds_its_own_pattern():
    sys0 = ml.compile_model(mo.build(mo.DEFAULTS))
    other = ml.compile_model(mo.build(mo.DEFAULTS, n_elements=60), like=sys0)
    fresh = ml.compile_model(mo.build(mo.DEFAULTS, n_elements=60))
    assert other.indices is not sys0.indices
    np.testing.assert_array_equal(other.indices, fresh.indices)
    for kind, f in _pattern_fields(fresh):
        np.testing.assert_array_equal(getattr(other.table(kind), f),
                                      getattr(fresh.table(kind), f))


def _pattern_fields(system):
    """``(kind, field)`` of every pattern field of the system's kinds."""
    return [(name, f.name) for name, kind in KINDS.items() if system.table(name) is not None
            for f in kind.by_role(PATTERN)]
