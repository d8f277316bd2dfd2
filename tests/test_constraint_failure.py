"""A joint violated far beyond its tolerance (more than FAILURE_FACTOR = 10 times
``constraint_tol``, 1 % of the model size at the default) is a failed run: a typed error with
the time and step where it went beyond and the whole run, not status "warning"."""

import warnings

import numpy as np
import pytest
from models import flexible_mechanism

import morphlab as ml
from morphlab.results.checks import FAILURE_FACTOR

# the four-bar of the tests without stabilization at a coarse step: its joints drift
# smoothly, 0.7 % of its size (59.7 mm) by 0.5 s, ~2 % by 0.8 s; Newton fails at 0.915 s
DRIFT = dict(dt=5e-3, stabilization=0.0)


def test_a_joint_drifting_far_beyond_its_tolerance_fails_the_run():
    """Run to 0.8 s: the error names the joint, its time and step are the first beyond 1 %
    of the size, and it carries the whole run (status "failed", the finding). Before: status
    "warning" and a warning."""
    with pytest.raises(ml.errors.ConstraintViolationError, match=r"joint '\w' is violated by "
                       r".*beyond 10 times the tolerance") as err:
        ml.simulate(flexible_mechanism(), t_end=0.8, **DRIFT)
    e = err.value
    assert isinstance(e, ml.SolverError) and isinstance(e, ml.errors.AccuracyError)
    res = e.result
    assert res.status == "failed" and res.n_t == 161  # every step computed is kept
    limit = FAILURE_FACTOR * res.settings.constraint_tol * res.system.length_scale
    viol = res.constraint_violation
    assert viol[e.step] > limit and np.all(viol[:e.step] <= limit)
    assert e.time == pytest.approx(res.t[e.step]) and 0.5 < e.time < 0.8
    assert [f.check for f in res.findings] == ["constraint drift"] and res.findings[0].failed


def test_a_moderate_drift_stays_a_warning_and_off_means_off():
    """0.7 % of the size at 0.5 s (between the tolerance and ten times it): a warning; with
    checks='off' nothing, even for the far drift."""
    with pytest.warns(ml.errors.AccuracyWarning, match=r"joint '\w' is violated by"):
        res = ml.simulate(flexible_mechanism(), t_end=0.5, **DRIFT)
    assert res.status == "warning" and not res.findings[0].failed
    with warnings.catch_warnings():
        warnings.simplefilter("error", ml.errors.MorphlabWarning)
        res = ml.simulate(flexible_mechanism(), t_end=0.8, checks="off", **DRIFT)
    assert res.status == "ok"


def test_a_far_drift_fails_with_checks_raise_too():
    with pytest.raises(ml.errors.ConstraintViolationError):
        ml.simulate(flexible_mechanism(), t_end=0.8, checks="raise", **DRIFT)
