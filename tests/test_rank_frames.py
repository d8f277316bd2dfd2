"""The rank test of the constraint Jacobian with the frame joints of beams eliminated.

``constraint_rank`` eliminates the three rows joining each pair of neighbouring frames against
the reference coordinates of the later frame (block Gaussian elimination: the rank is kept)
and takes the SVD of what is left. The reference here is the SVD of the whole scaled Jacobian,
dense, as ``constraint_rank`` did before: the ranks must agree, on valid and on redundant
models and away from the initial configuration, and the rows named dependent must be the same.
"""

import numpy as np
import pytest
from models import E_AL, RHO_AL, flexible_mechanism, straight_nodes

import morphlab as ml
import morphlab.compile.compile as compile_module
from morphlab.compile import constraint_rank
from morphlab.compile.checks import (
    RANK_RTOL,
    _eliminate_frames,
    _frame_joints,
    _reduced_jacobian,
    _scaled_jacobian,
)


def _dense(system, q=None):
    """(rank, rows with a share in the null space of J^T) from the dense scaled Jacobian."""
    Js = _scaled_jacobian(system, q).toarray()
    U, sigma, _ = np.linalg.svd(Js, full_matrices=True)
    rank = int(np.sum(sigma > RANK_RTOL * sigma[0]))
    null = U[:, rank:]
    return rank, set(np.flatnonzero(np.sqrt(np.sum(null * null, axis=1)) > 1e-6))


@pytest.mark.parametrize("frames", [dict(), dict(frames=3), dict(frames=3, reference="middle"),
                                    dict(frames=4, reference="first")])
def test_rank_of_a_closed_loop_with_frames_is_that_of_the_whole_jacobian(frames):
    system = ml.compile_model(flexible_mechanism(n_elem=8, **frames))
    rng = np.random.default_rng(4)
    # the initial configuration, and one far from it (angles, lever arms and nodal rotations
    # of every frame perturbed: the Jacobian depends on q only)
    for q in (system.q0, system.q0 + 0.3 * rng.standard_normal(system.n_dof)):
        rank, dep, _ = constraint_rank(system, q)
        assert (rank, set(np.flatnonzero(dep > 1e-6))) == _dense(system, q) == (system.n_con,
                                                                                 set())


def _beam_with_supports(names):
    m = ml.Model(gravity=(0.0, 0.0), name="supported")
    nodes = straight_nodes(12, length=120.0, angle=0.2)
    b = m.add_beam(nodes, E=E_AL, rho=RHO_AL, thickness=2.0, width=10.0, frames=4,
                   reference="middle", name="beam")
    m.add_fix(b, at=tuple(nodes[0]), dofs="xyr", name="clamp")
    for name in names:  # supports at a node of the third frame
        m.add_fix(b, at=tuple(nodes[7]), dofs="y", name=name)
    return m


def test_repeated_supports_inside_a_later_frame_are_named(monkeypatch):
    # two y-supports at the same node of the third frame: one of them repeats the other
    with pytest.raises(ml.ModelError, match="redundant") as err:
        ml.compile_model(_beam_with_supports(["s1", "s2"]))
    listed = str(err.value).split("Linearly dependent rows:")[1].split("(joints")[0]
    assert sorted(listed.replace("'", "").replace(" ", "").split(",")) == ["s1.y", "s2.y"]
    # the same system compiled without the check: the reduced and the dense rank agree, and
    # so do the rows they name
    monkeypatch.setattr(compile_module, "check_rank", lambda system: None)
    system = ml.compile_model(_beam_with_supports(["s1", "s2"]))
    rank, dep, _ = constraint_rank(system)
    names = {system.con_names[i] for i in np.flatnonzero(dep > 1e-6)}
    dense_rank, dense_rows = _dense(system)
    assert rank == dense_rank == system.n_con - 1
    assert names == {system.con_names[i] for i in dense_rows} == {"s1.y", "s2.y"}


def test_one_support_in_a_later_frame_has_full_rank():
    system = ml.compile_model(_beam_with_supports(["s1"]))
    assert constraint_rank(system)[0] == _dense(system)[0] == system.n_con


def test_the_svd_covers_the_joints_only():
    # a frame per element: 3 (n_el - 1) frame rows are eliminated, the SVD has the clamp's 3
    m = ml.Model(gravity=(0.0, 0.0))
    b = m.add_beam(straight_nodes(200, length=1000.0), E=E_AL, rho=RHO_AL, thickness=2.0,
                   width=10.0, name="beam")
    m.add_fix(b, at=(0.0, 0.0), dofs="xyr", name="clamp")
    system = ml.compile_model(m)
    S, rows, n_f = _reduced_jacobian(system)
    assert (n_f, S.shape[0], rows.size) == (3 * 199, 3, 3)
    assert constraint_rank(system)[0] == system.n_con == 3 * 199 + 3


@pytest.mark.parametrize("frames", [dict(), dict(frames=3, reference="middle")])
def test_reduced_rows_are_the_joints_on_motions_that_keep_the_frames_joined(frames):
    # what the elimination means: for a motion x whose frame coordinates x_c follow the other
    # coordinates x_o so that the frame joints hold (J_f x = 0, solved densely here), the
    # other rows give J_u x = S x_o
    system = ml.compile_model(flexible_mechanism(n_elem=8, **frames))
    q = system.q0 + 0.2 * np.random.default_rng(5).standard_normal(system.n_dof)
    Js = _scaled_jacobian(system, q).toarray()
    F, C = _frame_joints(system)
    U = np.setdiff1d(np.arange(system.n_con), F)
    O = np.setdiff1d(np.arange(system.n_dof), C)
    rng = np.random.default_rng(6)
    x = np.zeros(system.n_dof)
    x[O] = rng.standard_normal(O.size)
    x[C] = np.linalg.solve(Js[np.ix_(F, C)], -Js[np.ix_(F, O)] @ x[O])
    np.testing.assert_allclose(Js[F] @ x, 0.0, atol=1e-12)
    S, rows, cols, n_f = _eliminate_frames(system, q)
    assert n_f == F.size and np.array_equal(rows, U) and np.array_equal(cols, O)
    np.testing.assert_allclose(S @ x[O], Js[U] @ x, rtol=0,
                               atol=1e-12 * np.abs(Js[U]).max() * np.abs(x).max())
