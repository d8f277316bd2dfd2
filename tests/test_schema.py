"""The compiled arrays are declared once (morphlab.kernels.schema): every list the library
keeps of them agrees with the declarations, and a model with every kind of item compiles into
tables of the declared shapes whose design data the flat design vector lays out exactly."""

import pickle
import sys

import numpy as np
import pytest

import morphlab as ml
import morphlab.model as mm
from morphlab.compile.builder import _COMPILERS
from morphlab.compile.design import layout, owners
from morphlab.kernels import assemble
from morphlab.kernels.schema import DESIGN, KINDS, PATTERN, TIME, TOPOLOGY
from morphlab.kernels.system import KIND_NAMES, TIMED_NAMES, SystemArrays, Times


def every_kind():
    """A model with every kind of item."""
    m = ml.Model(gravity=(0.0, -9.81e3), name="every kind")
    nodes = np.stack([np.linspace(0.0, 60.0, 5), np.zeros(5)], axis=1)
    beam = m.add_beam(nodes, E=7e4, rho=2.7e-9, thickness=2.0, width=10.0, name="beam")
    link = m.add_rigid_body(mass=1e-4, inertia=0.1, position=(80.0, 0.0), name="link")
    disk = m.add_rigid_body(mass=1e-4, inertia=0.1, position=(0.0, 40.0), name="disk")
    slider = m.add_rigid_body(mass=1e-4, inertia=0.1, position=(100.0, 0.0), name="slider")
    m.add_revolute(m.ground, beam, at=(0.0, 0.0), name="pin")
    m.add_drive(beam, angle=ml.Ramp(0.0, 0.01) * 0.1, name="motor")
    m.add_weld(beam, link, at=(60.0, 0.0), name="weld")
    m.add_revolute(m.ground, disk, at=(0.0, 40.0), name="axle")
    m.add_gear(beam, disk, ratio=2.0, at_a=(0.0, 0.0), name="gear")
    m.add_prismatic(m.ground, slider, at=(100.0, 0.0), axis=(1.0, 0.0), name="guide")
    m.add_fix(link, at=(80.0, 0.0), dofs="y", name="rest")
    m.add_spring("s", link, slider, at_a=(80.0, 0.0), at_b=(100.0, 0.0), stiffness=1.0)
    m.add_rotational_spring("r", "axle", stiffness=10.0)
    m.add_force(beam, at=(30.0, 0.0), force=(0.0, -1.0), name="F")
    m.add_force(link, at=(80.0, 0.0), force=(0.5, 0.0), follower=True, name="Ff")
    m.add_torque(disk, 1.0, name="T")
    m.add_line_load("q", beam, q=(0.0, -0.01))
    m.add_pressure("p", beam, 0.001)
    return m


def test_the_containers_are_generated_from_the_kinds():
    assert SystemArrays._fields == ("gravity",) + KIND_NAMES
    assert tuple(KINDS) == KIND_NAMES == tuple(assemble.POS)
    assert Times._fields == TIMED_NAMES == tuple(k for k in KINDS if KINDS[k].times)
    for name, kind in KINDS.items():
        assert kind.arrays._fields == tuple(f.name for f in kind.fields if f.role != TIME)
        if kind.by_role(PATTERN):
            assert kind.coordinates is not None, name  # the pattern knows its entries
        if "con" in kind.fields_by_name:
            assert kind.reactions is not None, name  # a constraint kind's reactions


def test_each_kinds_named_tuples_are_found_by_module_and_name():
    """Numba's disk cache and pickle find a type by its module and name: ``register`` binds
    every kind's tuples in its kernel module (a tuple found nowhere fails the cache's load)."""
    for name, kind in KINDS.items():
        for tuple_type in (kind.arrays, kind.times):
            if tuple_type is not None:
                module = sys.modules[tuple_type.__module__]
                assert module.__name__.startswith("morphlab.kernels."), name
                assert getattr(module, tuple_type.__name__) is tuple_type, name
        table = kind.arrays(*range(len(kind.arrays._fields)))
        assert pickle.loads(pickle.dumps(table)) == table


def test_every_item_class_has_a_compile_function():
    # abstract (their kinds derive from them), and the ground: it has no DOFs to compile
    bases = (mm.Body, mm.Joint, mm.Load, mm.Ground)
    items = [cls for cls in vars(mm).values() if isinstance(cls, type)
             and issubclass(cls, mm.Item) and cls.collection and cls not in bases]
    assert len(items) >= 15
    for cls in items:
        assert any(base in _COMPILERS for base in cls.__mro__), cls.__name__


@pytest.fixture(scope="module")
def system():
    return ml.compile_model(every_kind())


def test_a_model_with_every_kind_fills_every_table_in_its_declared_shapes(system):
    for name, kind in KINDS.items():
        table = system.table(name)
        assert table is not None and table[0].shape[0] > 0, name
        for f in kind.fields:
            if f.role == TIME:
                continue
            a = getattr(table, f.name)
            assert a.shape[1:] == f.shape, (name, f.name)
            assert a.dtype == (np.float64 if f.dtype == "float" else np.int64), (name, f.name)
            if f.role in (TOPOLOGY, PATTERN):
                assert a.min(initial=0) >= -1, (name, f.name)


def test_the_design_vector_lays_out_every_design_field_once(system):
    """Every design field is a view of the flat vector, the slots tile it without gap or
    overlap, and each position maps back to its field and item."""
    slots = layout(system.arrays)
    assert slots[0].start == 0 and slots[-1].start + slots[-1].n * slots[-1].size == \
        system.design.size
    for a, b in zip(slots, slots[1:]):
        assert b.start == a.start + a.n * a.size
    for s in slots[1:]:
        view = getattr(system.table(s.kind), s.field)
        assert np.shares_memory(view, system.design), (s.kind, s.field)
    fields = {(s.kind, s.field) for s in slots[1:]}
    assert fields == {(k, f.name) for k, kind in KINDS.items() for f in kind.by_role(DESIGN)}
    last = slots[-1]
    pos = np.array([last.start + last.size * (last.n - 1)])
    assert owners(system.arrays, pos) == [(last.kind, last.field, np.array([last.n - 1]))] or \
        owners(system.arrays, pos)[0][2].tolist() == [last.n - 1]


def test_the_model_with_every_kind_runs(system):
    res = ml.simulate(system, t_end=0.004, dt=1e-3)
    assert res.status in ("ok", "warning") and np.all(np.isfinite(res.q))
