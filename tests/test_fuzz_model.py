"""Fuzzing the model API: random bad values must be refused with a MorphlabError (never a raw
TypeError/ValueError/IndexError/ZeroDivisionError from NumPy, never a silently accepted
model), and random valid values must be accepted and compile.

The generator is seeded, so a failure names a case that can be replayed.
"""

import numpy as np
import pytest

import morphlab as ml

SEED = 20260611
N_BAD = 400
N_GOOD = 60

NAN, INF = float("nan"), float("inf")


def _positive_bad(rng):
    """A value that is not a finite positive scalar."""
    return [NAN, INF, -INF, 0.0, -rng.uniform(1e-9, 1e9), -0.0, "1.0", "abc", None, True,
            [1.0], (1.0, 2.0), np.ones((2, 2)), complex(NAN, 0.0), complex(1.0, INF), object(),
            np.array([]), {}][rng.integers(18)]


def _scalar_bad(rng):
    """A value that is not a finite scalar (signs and zero are fine here)."""
    return [NAN, INF, -INF, "0", None, False, [0.0], np.zeros(2), object(), complex(0.0, NAN),
            (), np.array(["a"])][rng.integers(12)]


def _point_bad(rng):
    """A value that is not a finite pair (x, y)."""
    x = float(rng.normal())
    return [(NAN, x), (x, INF), (-INF, -INF), (x,), (x, x, x), np.ones((2, 2)), "xy", None, x,
            [x, [x, x]], ("a", "b"), (True, x), object(), [], complex(x, 0.0),
            (complex(x, NAN), x)][rng.integers(16)]


def _dofs_bad(rng):
    return ["", "xx", "z", "XY", "xyrr", None, 0, ["x"], "x y", b"x", "ry ", 1.5][rng.integers(12)]


def _nodes_bad(rng):
    n = int(rng.integers(2, 7))
    X = np.cumsum(rng.uniform(1.0, 10.0, size=(n, 2)), axis=0)
    k = int(rng.integers(n))
    choice = int(rng.integers(10))
    if choice == 0:
        X[k, rng.integers(2)] = NAN
    elif choice == 1:
        X[k, rng.integers(2)] = -INF
    elif choice == 2:
        X = X[:1]  # one node
    elif choice == 3:
        X = X[:, 0]  # (n,)
    elif choice == 4:
        X = np.hstack([X, X[:, :1]])  # (n, 3)
    elif choice == 5:
        X[min(k + 1, n - 1)] = X[min(k, n - 2)]  # coincident consecutive nodes
    elif choice == 6:
        return X.astype(str)
    elif choice == 7:
        return None
    elif choice == 8:
        return [list(X[0]), [X[1, 0]]]  # ragged
    else:
        return np.empty((0, 2))
    return X


def _valid_nodes(rng, n=None):
    n = int(rng.integers(2, 9)) if n is None else n
    steps = rng.uniform(0.5, 30.0, size=n - 1)
    angles = np.cumsum(rng.uniform(-0.6, 0.6, size=n - 1)) + rng.uniform(-np.pi, np.pi)
    X = np.zeros((n, 2))
    X[1:] = np.cumsum(np.stack([steps * np.cos(angles), steps * np.sin(angles)], axis=1), axis=0)
    return X + rng.uniform(-100.0, 100.0, size=2)


def _beam_kwargs(rng):
    kw = dict(E=float(10 ** rng.uniform(2, 6)), rho=float(10 ** rng.uniform(-10, -7)),
              damping=float(rng.choice([0.0, 10 ** rng.uniform(-6, -2)])),
              reference_node=0)
    if rng.random() < 0.5:
        kw.update(thickness=float(rng.uniform(0.1, 5.0)), width=float(rng.uniform(1.0, 50.0)))
    else:
        kw.update(area=float(rng.uniform(0.1, 50.0)), second_moment=float(rng.uniform(0.01, 50.0)),
                  fibre=float(rng.uniform(0.1, 3.0)))
    return kw


def _rigid_kwargs(rng):
    return dict(mass=float(10 ** rng.uniform(-6, 0)), inertia=float(10 ** rng.uniform(-3, 2)),
                position=tuple(rng.uniform(-100.0, 100.0, size=2)),
                angle=float(rng.uniform(-np.pi, np.pi)))


def _base(rng):
    """A valid model with one beam and one rigid body to attach things to."""
    m = ml.Model(gravity=tuple(rng.normal(size=2) * 1e3), name="fuzz")
    X = _valid_nodes(rng)
    beam = m.add_beam(X, name="beam", **_beam_kwargs(rng))
    body = m.add_rigid_body(name="body", **_rigid_kwargs(rng))
    return m, beam, body, X


def _off_node_point(rng, X):
    """A finite point clearly away from every node of X (farther than the beam's size)."""
    size = float(np.ptp(X, axis=0).max())
    return tuple(X[int(rng.integers(len(X)))] + (2 * size + 1.0) * np.array([1.0, 0.5]))


def _bad_case(rng):
    """(description, call) of one randomized invalid use of the model API."""
    m, beam, body, X = _base(rng)
    node = tuple(X[int(rng.integers(len(X)))])
    target = int(rng.integers(11))
    if target == 0:  # add_beam with one bad parameter
        kw = _beam_kwargs(rng)
        nodes = _valid_nodes(rng)
        key = str(rng.choice(["E", "rho", "section", "damping", "reference_node", "nodes",
                              "frames", "reference"]))
        if key == "nodes":
            nodes = _nodes_bad(rng)
            val = nodes
        elif key == "section":
            k2 = "thickness" if "thickness" in kw else str(rng.choice(["area", "second_moment",
                                                                      "fibre"]))
            kw[k2] = val = _positive_bad(rng)
            if val is None and k2 == "fibre":
                kw[k2] = val = -1.0  # fibre=None is valid (no stress output)
            key = k2
        elif key == "damping":
            val = _scalar_bad(rng) if rng.random() < 0.7 else -float(rng.uniform(1e-9, 1.0))
            kw[key] = val
        elif key == "reference_node":
            val = [-100, 100, 1.5, "0", True, np.nan][int(rng.integers(6))]
            kw[key] = val
        elif key == "frames":  # None is valid (the default); nodes have 2 to 6 elements
            val = [0, -1, 10**6, 1.5, "2", True, np.nan, "elements"][int(rng.integers(8))]
            kw.pop("reference_node")
            kw[key] = val
        elif key == "reference":
            val = ["last", "", "Chord", 1, True][int(rng.integers(5))]
            kw.pop("reference_node")
            kw[key] = val
        else:
            kw[key] = val = _positive_bad(rng)
        return f"add_beam {key}={val!r}", m, lambda: m.add_beam(nodes, name="new", **kw)
    if target == 1:  # add_rigid_body
        kw = _rigid_kwargs(rng)
        key = str(rng.choice(["mass", "inertia", "position", "angle", "velocity",
                              "angular_velocity", "name"]))
        if key in ("mass", "inertia"):
            kw[key] = val = _positive_bad(rng)
        elif key in ("position", "velocity"):
            kw[key] = val = _point_bad(rng)
        elif key == "name":
            kw[key] = val = ["", "body", "ground", 3, ("a",)][int(rng.integers(5))]
        else:
            kw[key] = val = _scalar_bad(rng)
        kw.setdefault("name", "new")
        return f"add_rigid_body {key}={val!r}", m, lambda: m.add_rigid_body(**kw)
    if target == 2:  # add_fix
        if rng.random() < 0.5:
            val = _dofs_bad(rng)
            return f"add_fix dofs={val!r}", m, lambda: m.add_fix(beam, at=node, dofs=val)
        val = _point_bad(rng) if rng.random() < 0.6 else _off_node_point(rng, X)
        return f"add_fix at={val!r}", m, lambda: m.add_fix(beam, at=val)
    if target == 3:  # add_revolute: bad point, off-node point, bad bodies
        choice = int(rng.integers(3))
        if choice == 0:
            val = _point_bad(rng)
            return (f"add_revolute at={val!r}", m,
                    lambda: m.add_revolute(body, m.ground, at=val))
        if choice == 1:
            val = _off_node_point(rng, X)
            return f"add_revolute off-node at={val}", m, lambda: m.add_revolute(beam, body, at=val)
        val = [None, 3, "nobody", body, 1.5][int(rng.integers(5))]
        other = body if val is not body else body  # body to itself when val is body
        return f"add_revolute a={val!r}", m, lambda: m.add_revolute(val, other, at=node)
    if target == 4:  # add_weld with bad point
        val = _point_bad(rng) if rng.random() < 0.7 else _off_node_point(rng, X)
        return f"add_weld at={val!r}", m, lambda: m.add_weld(beam, body, at=val)
    if target == 5:  # add_force
        key = str(rng.choice(["force", "at", "profile", "body"]))
        if key == "force":
            val = _point_bad(rng)
            return f"add_force force={val!r}", m, lambda: m.add_force(beam, at=node, force=val)
        if key == "at":
            val = _point_bad(rng) if rng.random() < 0.6 else _off_node_point(rng, X)
            return f"add_force at={val!r}", m, lambda: m.add_force(beam, at=val, force=(1.0, 0.0))
        if key == "profile":
            val = [NAN, INF, "ramp", True, object(), [1.0], lambda t: 1.0 / t,
                   lambda t: "x", ml.Constant(NAN)][int(rng.integers(9))]
            return (f"add_force profile={val!r}", m,
                    lambda: m.add_force(body, at=(0.0, 0.0), force=(1.0, 0.0), profile=val))
        val = [m.ground, None, "ground", 7][int(rng.integers(4))]
        return f"add_force body={val!r}", m, lambda: m.add_force(val, at=node, force=(1.0, 0.0))
    if target == 6:  # add_torque
        if rng.random() < 0.6:
            val = _scalar_bad(rng)
            return f"add_torque magnitude={val!r}", m, lambda: m.add_torque(body, val)
        val = _point_bad(rng) if rng.random() < 0.5 else _off_node_point(rng, X)
        return f"add_torque at={val!r}", m, lambda: m.add_torque(beam, 1.0, at=val)
    if target == 7:  # add_drive
        val = [NAN, 0.5, lambda t: 1.0 + t, lambda t: None, "x", True,
               ml.Constant(INF)][int(rng.integers(7))]
        return f"add_drive angle={val!r}", m, lambda: m.add_drive(body, angle=val)
    if target == 8:  # Model(gravity=...)
        val = _point_bad(rng)
        return f"Model gravity={val!r}", None, lambda: ml.Model(gravity=val)
    if target == 9:  # duplicate names
        kind = int(rng.integers(3))
        if kind == 0:
            return "duplicate body", m, lambda: m.add_rigid_body(name="beam", **_rigid_kwargs(rng))
        m.add_fix(beam, at=tuple(X[0]), dofs="x", name="J")
        if kind == 1:
            return "duplicate joint", m, lambda: m.add_revolute(body, m.ground, at=(0, 0), name="J")
        m.add_torque(body, 1.0, name="T")
        return "duplicate load", m, lambda: m.add_force(body, at=(0, 0), force=(1, 0), name="T")
    # a body that belongs to another model
    other = ml.Model(name="other")
    foreign = other.add_rigid_body(name="foreign", **_rigid_kwargs(rng))
    if rng.random() < 0.5:
        return "add_body foreign", m, lambda: m.add_body(foreign)
    return "joint to a foreign body", m, lambda: m.add_revolute(m.ground, foreign, at=(0, 0))


def _counts(m):
    if m is None:
        return None
    return (len(m.bodies), len(m.joints), len(m.forces), len(m.torques))


def test_random_bad_values_are_refused_with_a_morphlab_error():
    rng = np.random.default_rng(SEED)
    failures = []
    for case in range(N_BAD):
        desc, model, call = _bad_case(rng)
        before = _counts(model)
        try:
            out = call()
        except ml.MorphlabError as exc:
            if not str(exc):
                failures.append(f"case {case} {desc}: empty message")
            if _counts(model) != before:
                failures.append(f"case {case} {desc}: model changed although refused")
            continue
        except Exception as exc:  # noqa: BLE001 - this is what the test is looking for
            failures.append(f"case {case} {desc}: raw {type(exc).__name__}: {exc}")
            continue
        failures.append(f"case {case} {desc}: accepted ({out!r})")
    assert not failures, "\n".join(failures[:20])


def test_random_valid_models_are_accepted_and_compile():
    rng = np.random.default_rng(SEED + 1)
    for _ in range(N_GOOD):
        m, beam, body, X = _base(rng)
        # a tree: the beam held at its reference node by a random subset of x, y, r; the
        # rigid body pinned to a random node (any point of a rigid body is material) and
        # optionally driven; loads at random nodes. No row can repeat another.
        dofs = "".join(c for c in "xyr" if rng.random() < 0.6) or "y"
        m.add_fix(beam, at=tuple(X[0]), dofs=str("".join(rng.permutation(list(dofs)))))
        k = int(rng.integers(len(X)))
        m.add_revolute(beam, body, at=tuple(X[k]))
        driven = rng.random() < 0.5
        if driven:
            m.add_drive(body, angle=ml.SmoothStep(0.0, float(rng.uniform(0.01, 1.0))))
        m.add_force(beam, at=tuple(X[int(rng.integers(len(X)))]),
                    force=tuple(rng.normal(size=2)), profile=ml.Ramp(0.0, 1.0))
        m.add_force(body, at=tuple(rng.uniform(-200, 200, size=2)), force=(0.0, -1.0))
        m.add_torque(beam, float(rng.normal()), at=tuple(X[-1]))
        m.add_torque(body, float(rng.normal()), profile=ml.Sine(float(rng.uniform(1, 100))))
        system = ml.compile_model(m)
        # reference count: the fix's letters, two revolute rows, one drive row
        assert system.n_con == len(dofs) + 2 + int(driven)
        assert system.n_dof == 3 * len(X) + 3  # 3 reference + 3 (n - 1) nodal + 3 rigid


@pytest.mark.parametrize("value", [1, 2.5, np.float32(3.0), np.int64(4), complex(2.0, 1e-30)])
def test_numeric_types_are_accepted(value):
    # plain ints, NumPy scalars and complex-step perturbed values are valid numbers
    m = ml.Model(gravity=(0, -value))
    b = m.add_rigid_body(mass=value, inertia=value, position=(value, 0), angle=value,
                         name="b")
    m.add_revolute(m.ground, b, at=(0, 0))
    m.add_torque(b, value)
    m.add_force(b, at=(0, value), force=(value, 0))
    m.add_beam([[0, 0], [value, 0]], E=value, rho=value, thickness=value, width=value,
               damping=value, name="s")
    assert ml.compile_model(m).n_con == 2
