"""What a first use runs, as the ``compile`` and ``startup`` cases run it in a fresh process.

* the README's quickstart: its first result (:data:`QUICKSTART`, the README's lines verbatim:
  ``tests/test_bench.py`` checks them against README.md) and then its first
  ``sensitivities`` with one method (:data:`QUICKSTART_SENSITIVITY`);
* a model with every kind of item (:func:`every_item_model`);
* the main command, ``morphlab morphing --out DIR``.

:func:`run` executes one scenario in phases and returns the CPU and wall time of each phase.
"""

from __future__ import annotations

import time

#: The README quickstart up to its first result (model, run, summary, read-outs).
QUICKSTART = '''\
import numpy as np
import morphlab as ml

m = ml.Model(gravity=(0.0, -9.81e3))
crank = m.add_rigid_body(mass=2e-4, inertia=0.2, position=(0.0, 10.0), angle=np.pi / 2,
                         name="crank")
nodes = np.stack([np.linspace(0.0, 60.0, 9), np.full(9, 20.0)], axis=1)
beam = m.add_beam(nodes, E=70000.0, rho=2.7e-9, thickness=2.0, width=10.0, damping=1e-4,
                  name="coupler")
m.add_revolute(m.ground, crank, at=(0.0, 0.0), name="A")
m.add_revolute(crank, beam, at=(0.0, 20.0), name="B")
m.add_torque(crank, 30.0, profile=ml.SmoothStep(0.0, 0.02), name="Mt")

res = ml.simulate(m, t_end=0.05, dt=1e-3, rho_inf=0.8)
print(res.summary())
tip = res.node_positions("coupler")[:, -1]        # (n_t, 2) [mm]
sigma = res.stress("coupler")                      # (n_t, n_elem, 2 ends, 2 fibres) [MPa]
'''

#: The README quickstart's sensitivities (``{method}`` replaces the README's "direct").
QUICKSTART_SENSITIVITY = '''\
def build(p):                                      # the same model as a function of a design
    mm = ml.Model(gravity=(0.0, -9.81e3))
    c = mm.add_rigid_body(mass=2e-4, inertia=0.2, position=(0.0, 10.0), angle=np.pi / 2,
                          name="crank")
    b = mm.add_beam(nodes, E=70000.0, rho=2.7e-9, thickness=p["t"], width=10.0,
                    damping=1e-4, name="coupler")
    mm.add_revolute(mm.ground, c, at=(0.0, 0.0))
    mm.add_revolute(c, b, at=(0.0, 20.0))
    mm.add_torque(c, p["M"], profile=ml.SmoothStep(0.0, 0.02))
    return mm

sens = ml.sensitivities(build, {"t": 2.0, "M": 30.0},
                        {"ks_stress": ml.responses.ks_max_stress("coupler")},
                        t_end=0.05, dt=1e-3, method="{method}")
print(sens.values, sens.gradients)                 # d(KS stress)/dt [MPa/mm], /dM [MPa/(N mm)]
'''

#: The sensitivity methods whose first use is measured (method string of the README call).
METHODS = ("direct", "adjoint", "complex-step", "direct-fd")

#: Scenario names: the quickstart's first result, its first sensitivities per method, the
#: every-item model, the main command.
SCENARIOS = ("quickstart", *METHODS, "every-item", "main-command")

#: Item kinds :func:`every_item_model` holds when the library has them (probed).
OPTIONAL_KINDS = {"gear": "add_gear", "pressure": "add_pressure"}


def every_item_model():
    """A small mechanism with one item of every kind the library has (units mm, t, s, N).

    A driven hub (revolute to the ground and an angle drive) carries a welded flexible arm;
    a spring joins the arm's tip to a slider on a prismatic guide, which carries a pendulum
    on a revolute with a rotational spring; a second beam is clamped by a fix and carries a
    line load (and a follower pressure when the library has one). A force pushes the slider,
    a torque turns the pendulum, gravity acts on all. When the library has a gear joint it
    couples the pendulum to a second wheel (:data:`OPTIONAL_KINDS`).

    Returns
    -------
    (Model, list of str)
        The model and the item kinds it holds.
    """
    import numpy as np

    import morphlab as ml

    m = ml.Model(gravity=(0.0, -9.81e3), name="every item")
    kinds = ["rigid body", "beam"]
    hub = m.add_rigid_body(mass=1e-4, inertia=0.05, position=(0.0, 0.0), name="hub")
    arm_nodes = np.stack([np.linspace(0.0, 40.0, 5), np.zeros(5)], axis=1)
    arm = m.add_beam(arm_nodes, E=70000.0, rho=2.7e-9, thickness=2.0, width=10.0,
                     damping=1e-4, name="arm")
    slider = m.add_rigid_body(mass=2e-4, inertia=0.1, position=(60.0, 0.0), name="slider")
    pendulum = m.add_rigid_body(mass=1e-4, inertia=0.05, position=(60.0, -10.0),
                                name="pendulum")
    strip_nodes = np.stack([np.linspace(0.0, 50.0, 6), np.full(6, -40.0)], axis=1)
    strip = m.add_beam(strip_nodes, E=70000.0, rho=2.7e-9, thickness=1.5, width=10.0,
                       damping=1e-4, name="strip")
    ramp = ml.SmoothStep(0.0, 0.01)
    m.add_revolute(m.ground, hub, at=(0.0, 0.0), name="pivot")
    m.add_drive(hub, angle=0.05 * ramp, name="motor")
    m.add_weld(hub, arm, at=(0.0, 0.0), name="root")
    m.add_prismatic(m.ground, slider, at=(60.0, 0.0), axis=(1.0, 0.0), name="guide")
    hinge = m.add_revolute(slider, pendulum, at=(60.0, 0.0), name="hinge")
    m.add_fix(strip, at=(0.0, -40.0), dofs="xyr", name="clamp")
    m.add_force(slider, at=(60.0, 0.0), force=(-2.0, 0.0), profile=ramp, name="push")
    m.add_torque(pendulum, 5.0, profile=ramp, name="turn")
    m.add_spring("link", arm, slider, at_a=(40.0, 0.0), at_b=(60.0, 0.0), stiffness=20.0,
                 damping=0.02)
    m.add_rotational_spring("hinge_spring", hinge, stiffness=50.0, damping=0.05)
    m.add_line_load("wind", strip, q=(0.0, -0.01), profile=ramp)
    kinds += ["revolute", "drive", "weld", "prismatic", "fix", "force", "torque", "spring",
              "rotational spring", "line load"]
    if hasattr(ml.Model, "add_pressure"):
        m.add_pressure("gust", strip, 1e-3, profile=ramp)
        kinds.append("pressure")
    if hasattr(ml.Model, "add_gear"):
        wheel = m.add_rigid_body(mass=1e-4, inertia=0.05, position=(60.0, -30.0), name="wheel")
        m.add_revolute(m.ground, wheel, at=(60.0, -30.0), name="axle")
        m.add_gear(pendulum, wheel, ratio=2.0, name="gear")
        kinds.append("gear")
    return m, kinds


def _phase(fn) -> dict:
    """Run ``fn`` and return its process CPU and wall seconds."""
    c0, w0 = time.process_time(), time.perf_counter()
    fn()
    return {"cpu_s": time.process_time() - c0, "wall_s": time.perf_counter() - w0}


def run(scenario: str, *, out_dir: str | None = None, quick: bool = False,
        recorder=None) -> dict:
    """Run ``scenario`` (one of :data:`SCENARIOS`) in this process, phase by phase.

    Parameters
    ----------
    scenario : str
    out_dir : str, optional
        Output folder of the main command (required for ``"main-command"``).
    quick : bool
        The main command with ``--quick`` (a coarser time step, Table 2 timed once).
    recorder : CompileRecorder, optional
        Its ``phase`` is set to the name of the phase running.

    Returns
    -------
    dict
        ``{"phases": {name: {"cpu_s", "wall_s"}}, "kinds": [...]}`` (kinds: the every-item
        model's item kinds).
    """
    from .record import BenchError

    if scenario not in SCENARIOS:
        raise BenchError(f"unknown scenario {scenario!r}; choose from {', '.join(SCENARIOS)}")
    phases, out = {}, {}
    scope: dict = {}

    def phase(name, fn):
        if recorder is not None:
            recorder.phase = name
        phases[name] = _phase(fn)

    if scenario == "main-command":
        if out_dir is None:
            raise BenchError("the main-command scenario needs an output folder")
        from ..cli import main

        argv = ["morphing", "--out", out_dir] + (["--quick"] if quick else [])
        status = {}
        phase("main-command", lambda: status.setdefault("code", main(argv)))
        if status["code"] != 0:
            raise RuntimeError(f"morphlab {' '.join(argv)} exited with status {status['code']}")
        out["argv"] = ["morphlab", *argv]
    elif scenario == "every-item":
        import morphlab as ml

        def first():
            model, kinds = every_item_model()
            out["kinds"] = kinds
            ml.simulate(model, t_end=0.02, dt=1e-3)

        phase("every-item", first)
    else:
        phase("quickstart", lambda: exec(QUICKSTART, scope))
        if scenario != "quickstart":
            code = QUICKSTART_SENSITIVITY.replace("{method}", scenario)
            phase(scenario, lambda: exec(code, scope))
    return {"phases": phases, **out}
