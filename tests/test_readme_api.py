"""The README's API table and set-up say what the code does: the sensitivity method's default,
every response with a gradient for the adjoint, how to run the notebooks and the extra that
installs Jupyter for it."""

import inspect
import pathlib
import re

import pytest

import morphlab as ml

ROOT = pathlib.Path(__file__).resolve().parents[1]
README = (ROOT / "README.md").read_text(encoding="utf-8")


def _row(call: str) -> str:
    """The API table's row whose first cell starts with ``call``."""
    rows = [line for line in README.splitlines() if line.startswith(f"| `{call}")]
    assert len(rows) == 1, call
    return rows[0]


def test_the_sensitivity_row_gives_the_default_method():
    default = inspect.signature(ml.sensitivities).parameters["method"].default
    assert f'method="{default}"' in _row("ml.sensitivities")


def test_every_response_with_a_vjp_is_listed():
    """Every response factory of ml.responses that has a vjp (so the adjoint takes it) is
    named in the table's ml.responses row: before, reaction was missing."""
    factories = sorted(name for name, obj in vars(ml.responses).items()
                       if isinstance(obj, type) and callable(getattr(obj, "vjp", None))
                       and not name.startswith("_"))
    assert {"ks_max_stress", "reaction", "peak_reaction"} <= set(factories)
    row = _row("ml.responses")
    missing = [f for f in factories if not re.search(rf"`{f}[`(]", row)]
    assert missing == []


def test_the_notebooks_extra_installs_jupyter_and_the_readme_says_how_to_run_them():
    tomllib = pytest.importorskip("tomllib")  # Python 3.11+
    extras = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"][
        "optional-dependencies"]
    names = {re.split(r"[<>=\[ ]", d)[0] for d in extras["notebooks"]}
    assert {"jupyterlab", "nbconvert", "ipykernel"} <= names
    notebooks = README[README.index("## Notebooks"):README.index("## Limits")]
    assert 'pip install -e ".[notebooks]"' in notebooks
    assert "jupyter nbconvert --to notebook --execute" in notebooks
    for path in sorted((ROOT / "notebooks").glob("*.ipynb")):  # every notebook is described
        assert path.stem in notebooks, path.name
