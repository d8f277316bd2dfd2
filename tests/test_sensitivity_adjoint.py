"""The discrete adjoint against the direct method and the whole-run complex step.

The adjoint is the exact transpose of the direct recursion (docs/theory.md §7): on the same
runs the two must agree to round-off, whatever the variable (section, material, load, mass,
a shape variable that moves the initial configuration and a beam's nodes in its frame) and the
scheme (the paper's weighting adds an old-level share to every step). The responses here carry
their own ``vjp``, written out in this file, so the test exercises the sweep itself: a node
position at the final time (state terms at one time and a term through the beam's node table),
a constraint multiplier at one time and the time average of another (a term at every time).
"""

import numpy as np
import pytest
from test_sensitivity_direct import CASES, RUN, responses_for

import morphlab as ml
from morphlab.results.gradients import ResponseVJP
from morphlab.sensitivity import beside
from morphlab.sensitivity.units import BODY_KINDS

RUN_STEPS = round(RUN["t_end"] / RUN["dt"])


class NodeY:
    """y of a beam node at the final time: ``R_y + sin(th) (X_x + w_x) + cos(th) (X_y + w_y)``
    (``R, th`` of the frame that holds the node)."""

    def __init__(self, body, node):
        self.body, self.node = body, node

    def __call__(self, res):
        return res.node_positions(self.body, -1)[self.node, 1]

    def vjp(self, res):
        info = res.system.body(self.body)
        ref = info.node_ref[self.node]  # the frame that holds the node
        q = np.real(res.q[-1])
        th = q[ref[2]]
        c, s = np.cos(th), np.sin(th)
        X = np.real(info.X[self.node])
        nd = info.node_dofs[self.node]
        wx, wy = (q[d] if d >= 0 else 0.0 for d in nd[:2])
        g = np.zeros(res.system.n_dof)
        g[ref[1]] = 1.0
        g[ref[2]] = c * (X[0] + wx) - s * (X[1] + wy)
        for d, val in zip(nd[:2], (s, c)):
            if d >= 0:
                g[d] = val
        dX = np.zeros(np.shape(info.X))
        dX[self.node] = (s, c)
        return ResponseVJP(np.real(self(res)), terms={res.n_t - 1: {"q": g}},
                           data={f"body:{self.body}:X": dX})


class Multiplier:
    """A constraint multiplier at one time, or its time average (``mean=True``)."""

    def __init__(self, row, mean=False):
        self.row, self.mean = row, mean

    def _i(self, res):
        return res.system.con_names.index(self.row)

    def __call__(self, res):
        lam = res.lam[:, self._i(res)]
        return np.mean(lam) if self.mean else lam[-1]

    def vjp(self, res):
        e = np.zeros(res.system.n_con)
        e[self._i(res)] = 1.0
        value = np.real(self(res))
        if self.mean:
            return ResponseVJP(value, stream=lambda ns: {"lam": np.tile(e / res.n_t,
                                                                         (ns.size, 1))})
        return ResponseVJP(value, terms={res.n_t - 1: {"lam": e}})


def adjoint_responses(name):
    build, p0, _ = responses_for(name)
    body, joint = ("beam", "pivot") if name == "pendulum" else ("coupler", "D")
    n_nodes = build(p0).body(body).n_nodes
    return build, p0, {"node_y": NodeY(body, n_nodes - 1),
                       "reaction": Multiplier(f"{joint}.y"),
                       "mean_reaction": Multiplier(f"{joint}.x", mean=True)}


@pytest.mark.parametrize("scheme", ["arnold-bruls", "paper"])
@pytest.mark.parametrize("name", CASES)
def test_adjoint_equals_direct(name, scheme):
    """Both solve the same linear recursion with the same factors, forwards and transposed:
    agreement to round-off of the recursion (measured <= 4e-12 relative); 1e-10 asserted."""
    build, p0, resp = adjoint_responses(name)
    d = ml.sensitivities(build, p0, resp, method="direct", scheme=scheme, **RUN)
    a = ml.sensitivities(build, p0, resp, method="adjoint", scheme=scheme, **RUN)
    assert a.method == "adjoint" and a.values == d.values
    for r in resp:
        scale = max(abs(g) for g in d.gradients[r].values())
        for v in p0:
            assert abs(a.gradients[r][v] - d.gradients[r][v]) <= 1e-10 * scale, (r, v)


@pytest.mark.parametrize("scheme", ["arnold-bruls", "paper"])
def test_every_sweep_of_a_run_takes_one_signature(monkeypatch, scheme):
    """The compiled sweep is called for the recorded steps, the initial solve (solved from
    Python) and the probe of the rows the variables touch (a shape variable: ``x_D``); all
    with arguments of the same Numba types, so a run compiles one sweep. The old level's
    weights are passed as an argument (None without an old level, which prunes its code):
    the initial solve's scheme has none, and a sweep given its None would compile a second
    time. A step solved from Python with a compiled factor is solved in the sweep too; one
    with SuperLU's factor is begun by the sweep (``stop``) and solved in between: no kernel
    of its own is called from Python."""
    import numba

    import morphlab.sensitivity.adjoint as sa

    build, p0, resp = adjoint_responses("mechanism")
    real = sa.kadj.sweep
    seen, seen_args = [], []

    def spy(*args):
        seen.append(tuple(numba.typeof(x) for x in args))
        seen_args.append(args)
        return real(*args)

    compiled = []
    real_step = sa._python_step

    def step(a, st, *args):
        compiled.append(st.factor.compiled)
        return real_step(a, st, *args)

    monkeypatch.setattr(sa.kadj, "sweep", spy)
    monkeypatch.setattr(sa, "_python_step", step)
    ml.sensitivities(build, p0, resp, method="adjoint", scheme=scheme, **RUN)
    assert len(seen) >= 3  # the probe, the recorded steps, the initial solve
    assert len(set(seen)) == 1
    # steps solved from Python: the initial solve (SuperLU's factor) and compiled factors
    # after a new row order, which the sweep solves with
    assert True in compiled and False in compiled
    stops = [args for args in seen_args if args[12] != -1]  # begun for a solve from Python
    assert len(stops) == compiled.count(False)
    assert all(args[11] == -1 and args[8] == args[9] == args[12] for args in stops)
    has_old = scheme == "paper"
    assert isinstance(seen[0][-1], numba.types.NoneType) != has_old


def test_the_sensitivity_entries_are_given_only_what_they_read(monkeypatch):
    """A kernel Python calls unboxes every array it is given, about 6 ms of compile each
    (``morphlab/kernels/_jit.py``). With linear variables alone (no perturbed path), the
    reuse variant and no old level: the adjoint's shares get of the system the bodies' kinds
    alone, no time values and the record's states; its sweep and the direct method's chunk no
    system, time values, old level's weights or bodies' scratch; the pseudo-load data none of
    the perturbed path's. The gradients of the two methods agree as above (1e-10). Fails if
    any of them is passed whole again."""
    import morphlab.sensitivity.adjoint as sa
    import morphlab.sensitivity.direct as sd

    build, p0, resp = adjoint_responses("mechanism")
    chosen = ["E", "t", "m_crank", "M"]  # a material, a section, a mass, a load: linear
    calls = {"sweep": [], "shares": [], "chunk": []}
    real = {"sweep": sa.kadj.sweep, "shares": sa.kadj.shares, "chunk": sd.chunk}

    def spy(name):
        def call(*args):
            calls[name].append(args)
            return real[name](*args)
        return call

    for k in ("sweep", "shares"):
        monkeypatch.setattr(sa.kadj, k, spy(k))
    monkeypatch.setattr(sd, "chunk", spy("chunk"))
    a = ml.sensitivities(build, p0, resp, method="adjoint", variables=chosen, **RUN)
    d = ml.sensitivities(build, p0, resp, method="direct", variables=chosen, **RUN)
    for r in resp:
        scale = max(abs(g) for g in d.gradients[r].values())
        for v in chosen:
            assert abs(a.gradients[r][v] - d.gradients[r][v]) <= 1e-10 * scale, (r, v)
    assert all(calls.values())
    bodies = set(BODY_KINDS)
    perturbed = ("MN", "DN", "VN", "D0", "TN", "tn", "pert", "WN")
    for sh, M, T, _sc, K, *_ in calls["shares"]:
        assert all(getattr(sh.ps, f) is None for f in perturbed)
        assert all(getattr(sh.column, f) is None for f in ("RN", "R0", "XN", "XO"))
        assert {k for k in M._fields if k != "gravity" and getattr(M, k) is not None} <= bodies
        assert T is None
        assert all(getattr(K, f) is None for f in ("LU", "piv", "Lx", "Ux", "Ud", "D"))
    for M, T, *_, st, _MU in (c[:8] for c in calls["sweep"]):
        assert M is None and T is None and st.W is None
    for dd, M, T, *rest in calls["chunk"]:
        assert M is None and T is None and rest[-1] is None
        assert all(getattr(dd.ps, f) is None for f in perturbed)


def test_adjoint_equals_the_whole_run_complex_step():
    """Against the reference without truncation error, the exact variant: as tight as the
    direct method is (tests/test_sensitivity_direct.py: 1e-8 of each response's gradient
    scale)."""
    build, p0, resp = adjoint_responses("mechanism")
    a = ml.sensitivities(build, p0, resp, method=ml.Adjoint(reuse=False), **RUN)
    cs = ml.sensitivities(build, p0, resp, method="complex-step", **RUN)
    for r in resp:
        scale = max(abs(g) for g in cs.gradients[r].values())
        for v in p0:
            assert abs(a.gradients[r][v] - cs.gradients[r][v]) <= 1e-8 * scale, (r, v)


def test_a_response_without_vjp_is_refused_by_name():
    build, p0, resp = adjoint_responses("pendulum")
    resp = dict(resp, plain=lambda r: r.q[-1, 0])
    with pytest.raises(ml.SensitivityError, match="'plain'.*vjp.*method='direct'"):
        ml.sensitivities(build, p0, resp, method="adjoint", **RUN)


def test_adjoint_has_no_history_derivatives():
    build, p0, resp = adjoint_responses("pendulum")
    a = ml.sensitivities(build, p0, resp, method="adjoint", **RUN)
    with pytest.raises(ml.SensitivityError, match="method='direct'"):
        a.derivative(lambda r: r.q)


@pytest.mark.parametrize("name", CASES)
def test_checkpointed_sweep_gives_the_same_gradients(name):
    """A memory budget of a few steps: the forward run keeps checkpoints only, the sweep
    recomputes each segment from its checkpoint. On dense factors (the pendulum, 22 unknowns)
    the recomputed steps are the original ones bit for bit and only the order in which the
    blocks' contributions are summed differs: round-off of ~30 steps' sums, 1e-13 of the
    gradient's scale asserted; on sparse ones (the four-bar, 35) the recomputation starts its
    own SuperLU row orders, so its states agree to the Newton tolerance and the gradients to
    ~1e-10 (measured below 1e-12); 1e-9 asserted."""
    from morphlab.sensitivity import Adjoint

    build, p0, resp = adjoint_responses(name)
    full = ml.sensitivities(build, p0, resp, method="adjoint", **RUN)
    small = ml.sensitivities(build, p0, resp, method=Adjoint(memory=30_000), **RUN)
    assert full.stats["segment_steps"] is None and 1 <= small.stats["segment_steps"] < 10
    for r in resp:
        scale = max(abs(g) for g in full.gradients[r].values())
        for v in p0:
            diff = abs(small.gradients[r][v] - full.gradients[r][v])
            assert diff <= (1e-13 if name == "pendulum" else 1e-9) * scale, (r, v, diff)


def test_auto_chooses_by_variables_per_response_and_vjp(monkeypatch):
    """On one usable core: more than ``crossover`` variables per response and every response
    with a vjp: the adjoint; a response without one, or fewer variables per response: direct.
    The default crossover (0.15, measured) takes the adjoint for this model's 6 variables and
    3 responses and for one variable with them, the direct method for one variable with 9
    responses."""
    monkeypatch.setattr(beside, "usable_cores", lambda: 1)
    build, p0, resp = adjoint_responses("pendulum")
    per = len(p0) / len(resp)
    eager = ml.Auto(crossover=0.5 * per)
    assert ml.sensitivities(build, p0, resp, method=eager, **RUN).method == "adjoint"
    plain = dict(resp, plain=lambda r: r.q[-1, 0])
    assert ml.sensitivities(build, p0, plain, method=eager, **RUN).method == "direct"
    few = ml.sensitivities(build, p0, resp, method=ml.Auto(crossover=2.0 * per), **RUN)
    assert few.method == "direct"
    assert per == 2 and ml.Auto().crossover == 0.15
    assert ml.sensitivities(build, p0, resp, **RUN).method == "adjoint"  # the default: auto
    one = {"t": p0["t"]}
    one_build = lambda p: build({**p0, **p})  # noqa: E731
    assert ml.sensitivities(one_build, one, resp, **RUN).method == "adjoint"
    nine = {f"{k}_{i}": f for i in range(3) for k, f in resp.items()}
    assert ml.sensitivities(one_build, one, nine, **RUN).method == "direct"


def test_auto_takes_the_direct_method_beside_the_primal_up_to_its_variables(monkeypatch):
    """With two usable cores the direct method's work runs beside the primal: the direct
    method up to ``beside_variables`` variables (24, measured), the adjoint beyond, and the
    adjoint where the direct method may not use the thread (``overlap=False``) or the
    process only one core. The choice is read from the model and the cores: the same for
    every call on one machine."""
    monkeypatch.setattr(beside, "usable_cores", lambda: 2)
    build, p0, resp = adjoint_responses("pendulum")  # 6 variables, 3 responses, with vjps

    class Seen:  # what choose() reads of a setup: the variables and the responses
        def __init__(self, n_x):
            self.names = [f"x{i}" for i in range(n_x)]
            self.responses = resp

    auto = ml.Auto()
    assert auto.beside_variables == 24
    assert auto.choose(Seen(6)).name == "direct" and auto.choose(Seen(24)).name == "direct"
    assert auto.choose(Seen(25)).name == "adjoint"
    no_thread = ml.Auto(direct=ml.Direct(overlap=False))
    assert no_thread.choose(Seen(6)).name == "adjoint"
    monkeypatch.setattr(beside, "usable_cores", lambda: 1)
    assert auto.choose(Seen(6)).name == "adjoint"
    assert ml.sensitivities(build, p0, resp, **RUN).method == "adjoint"
    monkeypatch.setattr(beside, "usable_cores", lambda: 2)
    assert ml.sensitivities(build, p0, resp, **RUN).method == "direct"  # the default: auto


@pytest.mark.parametrize("name", CASES)
def test_library_responses_have_exact_vjps(name):
    """The response factories of ml.responses carry their own vjp: the adjoint with them
    equals the direct method (which differentiates the same responses by complex step over
    perturbed histories) to round-off. The pendulum's displacement is of a beam node, the
    four-bar's of a rigid body point (its initial position moves with x_D)."""
    build, p0, lib = responses_for(name)
    body = "beam" if name == "pendulum" else "coupler"
    resp = {k: lib[k] for k in ("displacement", "ks_stress", "rms_error")}
    resp["ks_relative"] = ml.responses.ks_max_stress(body)
    resp["max_error"] = ml.responses.max_error(body, lib["rms_error"].target)
    if name == "mechanism":
        resp["rocker_point"] = ml.responses.point_displacement("rocker", (65.0, 0.0), 0)
    d = ml.sensitivities(build, p0, resp, method="direct", **RUN)
    a = ml.sensitivities(build, p0, resp, method="adjoint", **RUN)
    for r in resp:
        assert a.values[r] == pytest.approx(d.values[r], rel=1e-13)
        scale = max(abs(g) for g in d.gradients[r].values())
        for v in p0:
            assert abs(a.gradients[r][v] - d.gradients[r][v]) <= 1e-10 * scale, (r, v)


@pytest.mark.parametrize(("n_elements", "scheme"), [(30, "paper"), (120, "arnold-bruls")])
def test_adjoint_equals_direct_with_a_thickness_per_element(n_elements, scheme):
    """The morphing skin with one thickness variable per element (30 and 120 of them) and the
    bell-crank points B, D (shape variables: they move joints and rigid bodies), the study's
    three responses over a shortened run: every gradient of the adjoint equals the direct
    method's to ``TOL`` of the response's largest gradient (the same recursion transposed).
    The round-off floor grows with the skin's condition: on the 120-element skin each method
    lies 1e-11 to 1.4e-9 from the whole-run complex step (converged to a Newton tolerance of
    1e-13), whatever the refinement (1 or 2 sweeps), and the two differ by up to 1.2e-10
    (measured): 1e-9 asserted there, 1e-10 on the 30-element skin (measured 6e-12)."""
    tol = 1e-10 if n_elements <= 30 else 1e-9
    from morphlab.bench.variables import LINK_POINTS, problem
    from morphlab.morphing import leading_edge as le

    build, p0, resp = problem(n_elements + len(LINK_POINTS), n_elements)
    run = dict(le.SETTINGS, t_end=0.03, scheme=scheme)
    d = ml.sensitivities(build, p0, resp, method="direct", **run)
    a = ml.sensitivities(build, p0, resp, method="adjoint", **run)
    assert len(p0) == n_elements + 4
    for r in resp:
        scale = max(abs(g) for g in d.gradients[r].values())
        worst = max(abs(a.gradients[r][v] - d.gradients[r][v]) for v in p0)
        assert worst <= tol * scale, (r, worst / scale)


def test_a_new_row_order_while_a_segment_is_recomputed(monkeypatch):
    """A pivot refused while the sweep recomputes a segment (the sparse factors get a new row
    order, of other sizes in general): the segment goes on in a record of the new order's
    sizes and patterns. Every recomputed chunk is cut after two steps with a refusal, so that
    each segment runs under several row orders; the gradients stay those of the full record
    within the checkpointed sweep's bound (1e-9 of the scale, the test above)."""
    import morphlab.sensitivity.adjoint_record as sa
    from morphlab.kernels.newton import PIVOT_REFUSED
    from morphlab.sensitivity import Adjoint

    real = sa.run_steps
    refused = []

    def cut(M, T, P, sc, csc, F, opts, work, H, k, k1, K):
        stop = min(k1, k + 2)
        out = real(M, T, P, sc, csc, F, opts, work, H, k, stop, K)
        if out[0] == stop < k1:
            refused.append(stop)
            return (out[0], PIVOT_REFUSED) + tuple(out[2:])
        return out

    build, p0, resp = adjoint_responses("mechanism")
    full = ml.sensitivities(build, p0, resp, method="adjoint", **RUN)
    monkeypatch.setattr(sa, "run_steps", cut)
    small = ml.sensitivities(build, p0, resp, method=Adjoint(memory=200_000), **RUN)
    assert 3 <= small.stats["segment_steps"] < 10 and len(refused) >= 5
    for r in resp:
        scale = max(abs(g) for g in full.gradients[r].values())
        for v in p0:
            diff = abs(small.gradients[r][v] - full.gradients[r][v])
            assert diff <= 1e-9 * scale, (r, v, diff)


def test_a_thickness_per_element_of_one_frame_keeps_the_direct_methods_digits():
    """The flexible pendulum of the Exudyn comparison (32 elements in one floating frame, a
    thickness each, 1000 steps), exact variants: the adjoint takes these variables' shares
    from the bodies' data gradient, which must not lose digits the direct method keeps.
    Summed over the steps before being contracted with ``dK``, the stiffness entries would
    (the elements' rigid motions in the frame cancel in ``dK q``: 3e-11 measured); per
    variable and step they agree with the direct method to 4e-13 and with the whole-run
    complex step to the direct method's 2e-13 (measured). 2e-12 of the largest gradient
    asserted."""
    from morphlab.bench import exudyn as pendulum
    from morphlab.bench.gradients import PendulumBuild

    build = PendulumBuild(32)
    p0 = {f"t{k}": pendulum.THICKNESS for k in range(32)}
    resp = {"tip_y": ml.responses.point_displacement("strip", (pendulum.LENGTH, 0.0), 1)}
    run = dict(t_end=pendulum.T_END, dt=pendulum.T_END / pendulum.N_STEPS,
               rho_inf=pendulum.RHO_INF)
    d = ml.sensitivities(build, p0, resp, method=ml.Direct(reuse=False), **run).gradients
    a = ml.sensitivities(build, p0, resp, method=ml.Adjoint(reuse=False), **run).gradients
    scale = max(abs(g) for g in d["tip_y"].values())
    worst = max(abs(a["tip_y"][v] - d["tip_y"][v]) for v in p0)
    assert worst <= 2e-12 * scale, worst / scale


def _threads_of_builds(build):
    """``build`` that notes the thread of each call with a complex (perturbed) design."""
    import threading

    seen = []

    def traced(p):
        if any(np.iscomplexobj(v) for v in p.values()):
            seen.append(threading.current_thread().name)
        return build(p)

    return traced, seen


@pytest.mark.parametrize("name", CASES)
def test_design_data_formed_beside_the_primal_give_the_same_bits(name):
    """The variables' changes and pseudo-load data formed in the worker thread while the
    primal's compiled steps run (``sensitivity/beside.py``) or in the caller's thread after
    them: the same calls on the same data, so the same values and gradients bit for bit; and
    the perturbed designs were really built in the worker thread in the first case."""
    from morphlab.sensitivity import Adjoint

    build, p0, resp = adjoint_responses(name)
    runs = {}
    for overlap in (True, False):
        traced, seen = _threads_of_builds(build)
        runs[overlap] = ml.sensitivities(traced, p0, resp, method=Adjoint(overlap=overlap),
                                         **RUN)
        where = {"morphlab-beside" if t.startswith("morphlab-beside") else t for t in seen}
        assert len(seen) == len(p0) and where == ({"morphlab-beside"} if overlap else
                                                  {"MainThread"}), (overlap, seen)
    assert runs[True].values == runs[False].values
    for r in resp:
        assert runs[True].gradients[r] == runs[False].gradients[r], r


def test_design_shares_formed_beside_the_sweep_give_the_same_bits(monkeypatch):
    """The design's shares of each block of swept steps (``kernels/adjoint.py: shares``) run
    in the worker thread while the sweep goes on with the next block, or in the caller's
    thread: block after block in the order of the sweep, so the same gradients bit for bit.
    Blocks of 4 steps here (30 steps: several blocks besides the steps solved from Python),
    and every block's shares (all but the probe's) in the worker thread with ``overlap``."""
    import threading

    import morphlab.sensitivity.adjoint as sa
    from morphlab.sensitivity import Adjoint

    build, p0, resp = adjoint_responses("mechanism")
    real = sa.kadj.shares
    monkeypatch.setattr(sa, "_block", lambda *args: 4)
    runs = {}
    for overlap in (True, False):
        where = []

        def spy(*args, where=where):
            where.append((threading.current_thread().name, args[-2], args[-1]))
            return real(*args)

        monkeypatch.setattr(sa.kadj, "shares", spy)
        runs[overlap] = ml.sensitivities(build, p0, resp, method=Adjoint(overlap=overlap),
                                         **RUN)
        probe, blocks = where[0], where[1:]
        assert probe[0] == "MainThread"
        assert sum(hi - lo + 1 for _, hi, lo in blocks) == RUN_STEPS + 1  # every step once
        assert max(hi - lo + 1 for _, hi, lo in blocks) == 4 and len(blocks) >= 8
        threads = {t.split("_")[0] for t, _, _ in blocks}
        assert threads == ({"morphlab-beside"} if overlap else {"MainThread"}), threads
    for r in resp:
        assert runs[True].gradients[r] == runs[False].gradients[r], r


def test_a_failure_beside_the_primal_stops_the_run_at_a_chunk_boundary():
    """A variable ``build`` does not use, found in the worker thread: the SensitivityError is
    raised from the primal run at the chunk boundary after the worker failed (the hook's
    ``after_chunk`` in the traceback), not after the whole run. 3000 steps in chunks of one
    step (``chunk_seconds=0``): the worker has the whole run to fail in."""
    import traceback

    from morphlab.sensitivity import Adjoint

    build, p0, resp = adjoint_responses("pendulum")
    with pytest.raises(ml.SensitivityError, match="'unused' is not used by build") as err:
        ml.sensitivities(build, dict(p0, unused=1.0), resp, method=Adjoint(overlap=True),
                         t_end=3.0, dt=1e-3, chunk_seconds=0.0)
    frames = [f.name for f in traceback.extract_tb(err.value.__traceback__)]
    assert frames.index("integrate") < frames.index("after_chunk") < frames.index("changes"), \
        frames


@pytest.mark.parametrize("overlap", [True, False])
def test_the_design_work_sees_the_callers_numpy_error_state(overlap):
    """The perturbed designs are built under the caller's ``np.errstate`` in the worker
    thread as in the caller's (a thread does not inherit NumPy's error state by itself)."""
    from morphlab.sensitivity import Adjoint

    build, p0, resp = adjoint_responses("pendulum")
    seen = []

    def traced(p):
        if any(np.iscomplexobj(v) for v in p.values()):
            seen.append(np.geterr()["divide"])
        return build(p)

    with np.errstate(divide="raise"):
        ml.sensitivities(traced, p0, resp, method=Adjoint(overlap=overlap), **RUN)
    assert seen == ["raise"] * len(p0)


def test_overlap_is_a_boolean_or_none():
    from morphlab.sensitivity import Adjoint

    with pytest.raises(ml.SensitivityError, match="overlap must be True, False or None"):
        Adjoint(overlap="yes")
