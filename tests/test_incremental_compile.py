"""The incremental compile of a perturbed design (``compile_model(m, like=nominal)`` with a
nominal compiled ``record=True``) gives the same System as a full compile. With
``incremental.ROUND_OFF = 0`` bit for bit: every array with the same dtype, shape and bytes,
every BodyInfo, name table and number equal. With the default, frames whose inputs a complex
``build`` reproduces only to round-off are copied from the nominal: the real parts then agree to
1e-15 of each array's largest entry (a few ulp; ``ROUND_OFF`` is 4 eps on the inputs) and the
imaginary parts, which carry the complex-step derivatives, bit for bit. Checked for every kind
of design variable — a thickness per element group, a node moved, a link point, a torque,
Young's modulus, the damping — by complex step and by a real step, on a multi-frame coupler
(one frame per element, three frames, one frame) and on the morphing model's two skins.
"""

import dataclasses

import numpy as np
import pytest

import morphlab as ml
from morphlab.compile import incremental
from tests.models import E_AL, RHO_AL, straight_nodes

mo = ml.morphing


def assert_same(a, b, path="system", rtol=0.0):
    """Field by field; floating arrays compared by their bytes (a signed zero counts), or with
    ``rtol``: real parts to ``rtol`` of the largest entry, imaginary parts by their bytes."""
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        a, b = np.asarray(a), np.asarray(b)
        assert (a.dtype, a.shape) == (b.dtype, b.shape), path
        if rtol and a.dtype.kind in "fc" and a.size:
            assert np.imag(a).tobytes() == np.imag(b).tobytes(), path
            ra, rb = np.real(a), np.real(b)
            assert np.array_equal(np.isnan(ra), np.isnan(rb)), path  # NaN: no reaction
            ok = ~np.isnan(rb)
            if ok.any():
                scale = np.abs(rb[ok]).max()
                assert np.all(np.abs(ra[ok] - rb[ok]) <= rtol * scale), path
        else:
            assert a.tobytes() == b.tobytes(), path
    elif dataclasses.is_dataclass(a) and not isinstance(a, type):
        assert type(a) is type(b), path
        for f in dataclasses.fields(a):
            if f.name != "model":
                assert_same(getattr(a, f.name), getattr(b, f.name), f"{path}.{f.name}", rtol)
    elif isinstance(a, dict):
        assert list(a) == list(b), path
        for k in a:
            assert_same(a[k], b[k], f"{path}[{k!r}]", rtol)
    elif isinstance(a, (list, tuple)):
        assert len(a) == len(b), path
        for i, (x, y) in enumerate(zip(a, b)):
            assert_same(x, y, f"{path}[{i}]", rtol)
    elif isinstance(a, (float, complex, np.floating, np.complexfloating)):
        assert type(a) is type(b), path
        assert_same(np.asarray(a), np.asarray(b), path, rtol)
    else:  # ints, names, slices, dtypes, profiles
        assert a == b, path


def coupler_model(p, frames="element"):
    """A four-bar with a 12-element coupler: thickness per group of 4 elements ``t0..t2``, the
    y of node 5 moved by ``dy5`` and of node 0 (where the crank holds it) by ``dy0``, the
    coupler's modulus ``E`` and damping ``beta``, the torque ``Mt``."""
    n_elem = 12
    m = ml.Model(gravity=(0.0, -9.81e3), name="four-bar")
    crank = m.add_rigid_body(mass=2e-4, inertia=0.2, position=(0.0, 10.0), angle=np.pi / 2,
                             name="crank")
    nodes = straight_nodes(n_elem, length=60.0, origin=(0.0, 20.0), angle=0.1).astype(
        np.result_type(*p.values(), float))
    nodes[5, 1] += p["dy5"]
    nodes[0, 1] += p["dy0"]
    t = np.repeat(np.array([p["t0"], p["t1"], p["t2"]]), 4)
    coupler = m.add_beam(nodes, E=p["E"], rho=RHO_AL, thickness=t, width=10.0,
                         damping=p["beta"], frames=frames,
                         reference="first" if frames == 1 else "chord", name="coupler")
    end = nodes[-1].real
    rocker = m.add_rigid_body(mass=3e-4, inertia=0.3, position=(end[0], end[1] / 2),
                              angle=np.pi / 2, name="rocker")
    m.add_revolute(m.ground, crank, at=(0.0, 0.0), name="A")
    m.add_revolute(crank, coupler, at=(nodes[0, 0], nodes[0, 1]), name="B")
    m.add_revolute(coupler, rocker, at=tuple(end), name="C")
    m.add_revolute(rocker, m.ground, at=(end[0], 0.0), name="D")
    m.add_torque(crank, p["Mt"], profile=ml.SmoothStep(0.0, 0.05), name="Mt")
    m.add_force(coupler, at=tuple(nodes[8].real), force=(0.0, -2.0),
                profile=ml.SmoothStep(0.0, 0.05), name="F")
    return m


P_COUPLER = {"t0": 2.0, "t1": 2.2, "t2": 1.8, "dy5": 0.0, "dy0": 0.0, "E": E_AL,
             "beta": 1e-4, "Mt": 50.0}


def _check_every_variable(build, p0, rtol):
    """Every variable, complex and real step: the incremental compile against a full one
    (round-off ``rtol`` on the real parts, 0: bit for bit)."""
    sys0 = ml.compile_model(build(p0), record=True)
    assert incremental.record_of(sys0)
    for name in p0:
        for delta in (1e-30j, 1e-6 * (abs(p0[name]) or 1.0)):
            p = dict(p0)
            p[name] = p0[name] + delta
            model = build(p)
            dtype = np.complex128 if isinstance(delta, complex) else np.float64
            assert_same(ml.compile_model(model, dtype=dtype),
                        ml.compile_model(model, dtype=dtype, like=sys0), f"{name}+{delta!r}",
                        rtol)


# a few ulp on the inputs of a copied frame stay a few ulp in its matrices and invariants
RTOL = 1e-15


@pytest.fixture(params=["bits", "round-off"])
def rtol(request, monkeypatch):
    if request.param == "bits":
        monkeypatch.setattr(incremental, "ROUND_OFF", 0.0)
        return 0.0
    return RTOL


@pytest.mark.parametrize("frames", ["element", 3, 1])
def test_coupler_every_variable_kind(frames, rtol):
    _check_every_variable(lambda p: coupler_model(p, frames), P_COUPLER, rtol)


@pytest.mark.parametrize("skin", ["accurate", "paper"])
def test_morphing_model_every_variable(skin, rtol):
    _check_every_variable(lambda p: mo.build(p, skin=skin), {**mo.DEFAULTS, **mo.GEOMETRY},
                          rtol)


def test_only_the_changed_frames_are_compiled(monkeypatch):
    """A thickness of one group has its 4 frames' numbers formed anew and nothing compiled
    (their DOFs, elements and joints are the nominal's), a node moved recompiles the 2 frames
    holding it; the rest is copied (counted by wrapping the frame compile and the rewrite),
    and only the rewritten rows are formed afresh."""
    from morphlab.compile import bodies

    sys0 = ml.compile_model(coupler_model(P_COUPLER), record=True)
    calls, rewrites = [], []
    real, real_rewrite = bodies._compile_frame, incremental.rewrite
    monkeypatch.setattr(bodies, "_compile_frame",
                        lambda body, spec, name, *rest: calls.append(name)
                        or real(body, spec, name, *rest))
    monkeypatch.setattr(incremental, "rewrite",
                        lambda b, rec, f, values: rewrites.append(f)
                        or real_rewrite(b, rec, f, values))
    for name, compiled, rewritten in (
            ("t1", [], [4, 5, 6, 7]), ("dy5", ["coupler#4", "coupler#5"], []), ("Mt", [], [])):
        calls.clear()
        rewrites.clear()
        p = dict(P_COUPLER, **{name: P_COUPLER[name] + 1e-30j})
        sys_p = ml.compile_model(coupler_model(p), like=sys0)
        assert (calls, rewrites) == (compiled, rewritten), name
        if name == "t1":
            fresh = incremental.fresh_rows(sys_p)
            frames = sys0.bodies["coupler"].index + np.arange(4, 8)  # t1's group
            elems = np.flatnonzero(np.isin(sys0.elem_body, frames))
            assert np.array_equal(fresh["elem_K"], elems)
            assert fresh["elem_dofs"].size == 0  # the structure is copied
            assert not any(sys0.con_names[r].startswith("coupler.frame")
                           for r in fresh["con_u0"])  # so are the frame joints


def test_without_a_record_or_another_layout_compiles_in_full():
    sys0 = ml.compile_model(coupler_model(P_COUPLER))  # no record
    assert incremental.record_of(sys0) is None
    p = dict(P_COUPLER, t1=2.2 + 1e-30j)
    assert_same(ml.compile_model(coupler_model(p)), ml.compile_model(coupler_model(p), like=sys0))
    rec0 = ml.compile_model(coupler_model(P_COUPLER, 3), record=True)
    assert_same(ml.compile_model(coupler_model(p, 4)),
                ml.compile_model(coupler_model(p, 4), like=rec0))
