"""Messages for a user's first hour: a static model with an unsupported body names the body,
``io.save`` with its arguments swapped says the order, the command-line help is plain text
with its defaults."""

import numpy as np
import pytest

import morphlab as ml
from morphlab import cli


def _model():
    """A clamped strip (held), a rigid body with nothing on it, and one hinged off its centre
    (free to swing about the hinge under gravity)."""
    m = ml.Model(gravity=(0.0, -9.81e3), name="parts")
    nodes = np.stack([np.linspace(0.0, 100.0, 5), np.zeros(5)], axis=1)
    b = m.add_beam(nodes, E=7e4, rho=2.7e-9, thickness=2.0, width=10.0, name="strip")
    m.add_fix(b, at=(0.0, 0.0), dofs="xyr", name="clamp")
    m.add_rigid_body(mass=1e-4, inertia=1.0, position=(200.0, 0.0), name="loose")
    h = m.add_rigid_body(mass=1e-4, inertia=1.0, position=(300.0, 0.0), name="hinged")
    m.add_revolute(m.ground, h, at=(250.0, 0.0), name="h")
    return m


def test_static_names_the_bodies_nothing_holds():
    """The loose body is free in x, y and theta; the hinged one swings (y and theta move
    together about the hinge, x not); the clamped strip is not named. Before: a bare
    SingularMatrixError about the saddle-point matrix."""
    with pytest.raises(ml.SingularMatrixError) as err:
        ml.static(_model())
    msg = str(err.value)
    assert "body 'loose' (loose.x, loose.y, loose.theta)" in msg
    assert "body 'hinged' (hinged.y, hinged.theta)" in msg
    assert "strip" not in msg.split("(singular")[0]
    assert err.value.result is not None and err.value.result.status == "failed"


def test_save_with_swapped_arguments_says_the_order(tmp_path):
    m = ml.Model(name="pendulum")
    bob = m.add_rigid_body(mass=1e-3, inertia=1.0, position=(10.0, 0.0), name="bob")
    m.add_revolute(m.ground, bob, at=(0.0, 0.0))
    res = ml.simulate(m, t_end=1e-3, dt=5e-4)
    path = tmp_path / "run.npz"
    with pytest.raises(ml.FormatError, match=r"save\(result, path\): the result comes first"):
        ml.io.save(str(path), res)
    assert not path.exists()
    ml.io.save(res, path)  # the right order works
    assert ml.io.load(path).n_t == res.n_t


@pytest.mark.parametrize("argv", [["--help"], ["morphing", "--help"], ["warmup", "--help"]])
def test_cli_help_is_plain_text_with_defaults(argv, capsys):
    with pytest.raises(SystemExit) as exit_:
        cli.main(argv)
    assert exit_.value.code == 0
    text = capsys.readouterr().out
    assert "``" not in text and ":func:" not in text
    if argv[0] == "morphing":
        assert "(default: morphing-out)" in text
        assert "(default: False)" not in text  # on/off flags carry no default
