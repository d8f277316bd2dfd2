"""The package's layers: every module imports only its own stage or earlier ones.

Stages in data-flow order (import order):

    kernels < jit < errors < model < compile < results < solve < sensitivity < warmup
            < plots, io < studies < morphing < bench, cli

``results`` comes before ``solve`` because the solver fills a Result. ``bench`` and
``morphing`` (the benchmark tools and the paper's application) are imported by no core
module. ``warmup`` compiles the kernels through the solver and the sensitivities only, so
the studies can warm up each worker process of a sweep. Every import is read from the
source with ``ast``, those inside functions included.
"""

from __future__ import annotations

import ast
import pathlib

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]
STAGES = ["kernels", "jit", ("errors", "_version"), "model", "compile", "results", "solve",
          "sensitivity", "warmup", ("plots", "io"), "studies", "morphing", ("bench", "cli")]
RANK = {}
for rank, stage in enumerate(STAGES):
    for name in (stage if isinstance(stage, tuple) else (stage,)):
        RANK[name] = rank


def _modules():
    """(dotted name, path) of every module of the installed tree."""
    for path in sorted((ROOT / "morphlab").rglob("*.py")):
        rel = path.relative_to(ROOT / "morphlab").with_suffix("")
        yield "morphlab." + ".".join(rel.parts), path


def _stage(dotted: str) -> str | None:
    """Stage of a module of morphlab (None for the package's ``__init__`` itself)."""
    parts = dotted.split(".")
    if parts[0] != "morphlab" or len(parts) < 2 or parts[1] == "__init__":
        return None
    return parts[1]


def _imports(dotted: str, path: pathlib.Path):
    """Absolute names of every morphlab module ``path`` imports, with line numbers."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    package = dotted.split(".")
    if path.name != "__init__.py":
        package = package[:-1]
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.startswith("morphlab"):
                    yield alias.name, node.lineno
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package[: len(package) - (node.level - 1)]
                mod = ".".join(base + ([node.module] if node.module else []))
            else:
                mod = node.module or ""
            if not mod.startswith("morphlab"):
                continue
            if node.module is None or mod == "morphlab":  # from . import a, b: submodules
                for alias in node.names:
                    yield f"{mod}.{alias.name}", node.lineno
            else:
                yield mod, node.lineno


def _violations():
    bad = []
    for dotted, path in _modules():
        own = _stage(dotted)
        if own is None:
            continue
        for target, line in _imports(dotted, path):
            other = _stage(target)
            if other == own:
                continue
            if other is None or other not in RANK:
                # the package's top level (``import morphlab``, ``from .. import name``): it
                # imports every core stage, so only the application and the tools may use it
                if RANK[own] < RANK["morphing"]:
                    bad.append(f"{path.relative_to(ROOT)}:{line} ({own}) imports the package "
                               f"top level ({target})")
                continue
            if RANK[other] > RANK[own]:
                bad.append(f"{path.relative_to(ROOT)}:{line} ({own}) imports {target} ({other})")
    return bad


def test_every_import_points_to_an_earlier_stage():
    assert _violations() == []


def test_the_layer_check_sees_an_upward_import(tmp_path, monkeypatch):
    """The check must be able to fail: a model module importing the solver is reported."""
    fake = tmp_path / "morphlab" / "model"
    fake.mkdir(parents=True)
    (fake / "bad.py").write_text("def f():\n    from ..solve import stepper\n")
    monkeypatch.setattr(__import__(__name__), "ROOT", tmp_path)
    assert _violations() == ["morphlab/model/bad.py:2 (model) imports morphlab.solve (solve)"]


def test_the_layer_check_sees_the_package_top_level(tmp_path, monkeypatch):
    """A core module reading a name from the package's top level (which imports every stage)
    is reported; the application may."""
    for stage, text in (("io", "from .. import __version__\n"), ("morphing", "import morphlab\n")):
        (tmp_path / "morphlab" / stage).mkdir(parents=True)
        (tmp_path / "morphlab" / stage / "m.py").write_text(text)
    monkeypatch.setattr(__import__(__name__), "ROOT", tmp_path)
    assert _violations() == ["morphlab/io/m.py:1 (io) imports the package top level "
                             "(morphlab.__version__)"]


def test_kernels_import_nothing_of_morphlab():
    for dotted, path in _modules():
        if dotted.startswith("morphlab.kernels."):
            names = [t for t, _ in _imports(dotted, path) if not t.startswith("morphlab.kernels")]
            assert names == [], path


@pytest.mark.parametrize("stage", sorted(RANK))
def test_every_stage_is_a_folder_or_module(stage):
    base = ROOT / "morphlab" / stage
    assert base.is_dir() or base.with_suffix(".py").is_file(), stage


def test_every_package_is_installed():
    """pyproject.toml finds the packages of the tree (``[tool.setuptools.packages.find]``),
    so a wheel (``pip install .``, not only the editable install) carries all of them."""
    tomllib = pytest.importorskip("tomllib")  # Python 3.11+

    import setuptools

    config = tomllib.loads((ROOT / "pyproject.toml").read_text())
    find = config["tool"]["setuptools"]["packages"]["find"]
    listed = set(setuptools.find_packages(str(ROOT), include=find["include"]))
    found = {"morphlab." + ".".join(p.parent.relative_to(ROOT / "morphlab").parts)
             for p in (ROOT / "morphlab").rglob("__init__.py")}
    found = {name.rstrip(".") for name in found}
    assert found == listed, f"missing: {sorted(found - listed)}, stale: {sorted(listed - found)}"
