"""morphlab's entry points run with one BLAS thread and give the user's setting back
(morphlab/jit/threads.py): inside a run every BLAS library loaded reports one thread, after
it (also after a failure) the threads it had."""

import pytest

import morphlab as ml
from morphlab.jit.threads import _blas_libraries, blas_threads, one_blas_thread


@pytest.fixture
def two_threads():
    """Every BLAS library at two threads (whatever the machine's default), restored after."""
    libs = _blas_libraries()
    assert libs, "NumPy's BLAS should be found"
    before = [lc.get_num_threads() for lc in libs]
    for lc in libs:
        lc.set_num_threads(2)
    yield
    for lc, n in zip(libs, before):
        lc.set_num_threads(n)


def _pendulum():
    m = ml.Model()
    b = m.add_rigid_body(mass=1e-3, inertia=1.0, position=(10.0, 0.0), name="link")
    m.add_revolute(m.ground, b, at=(0.0, 0.0), name="pin")
    return m


def test_a_run_has_one_blas_thread_and_restores_the_users(two_threads):
    seen = []
    ml.simulate(_pendulum(), t_end=0.003, dt=0.001, observer=lambda info: seen.append(
        blas_threads()))
    assert seen and all(set(s) == {1} for s in seen)
    assert set(blas_threads()) == {2}


def test_nested_uses_restore_once_and_a_failure_restores_too(two_threads):
    with one_blas_thread():
        with one_blas_thread():
            assert set(blas_threads()) == {1}
        assert set(blas_threads()) == {1}  # the outer block still runs
    assert set(blas_threads()) == {2}
    with pytest.raises(RuntimeError, match="inside"):
        with one_blas_thread():
            raise RuntimeError("failed inside the block")
    assert set(blas_threads()) == {2}
