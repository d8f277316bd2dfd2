"""Libraries kept as LLVM IR (morphlab.kernels._jit._Library): an inner kernel's library gets
no machine code of its own, is cached as bitcode and linked from the cache by a kernel a later
process compiles; a kernel Python calls gets machine code and computes what Numba's own
libraries compute, bit for bit, also over a cache Numba's libraries filled.
"""

import json
import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from morphlab.kernels import _jit

_MODULE = textwrap.dedent('''
    import numba
    import numpy as np
    from morphlab.kernels._jit import inner, kernel


    @inner
    def scaled(x, c):
        out = np.empty_like(x)
        for i in range(x.shape[0]):
            out[i] = c * x[i] + np.sin(x[i])
        return out


    @inner
    def checked(x):
        if x.shape[0] == 0:
            raise ValueError("checked: an empty array")
        return scaled(x, 2.0)


    @kernel
    def first(x):
        return checked(x).sum()


    @kernel
    def second(x):
        return scaled(x, 3.0)[-1]


    @inner
    def via_python(x):
        with numba.objmode(y="float64"):  # lifted out: compiled to run in object mode
            y = float(np.sum(x))
        return 2.0 * y


    @kernel
    def third(x):
        return via_python(x) + 1.0


    @numba.njit(parallel=True)  # a user's parallel function, its loop body a gufunc
    def squares(x):
        s = 0.0
        for i in numba.prange(x.shape[0]):
            s += x[i] * x[i]
        return s


    @inner
    def shifted_squares(x):
        return squares(x) + 1.0


    @kernel
    def fourth(x):
        return 2.0 * shifted_squares(x)
''')

#: One process: import the module, call the kernels named, report values and cache use.
_CHILD = textwrap.dedent("""
    import json, sys
    import numpy as np
    import irmod
    from morphlab.kernels import _jit
    x = np.linspace(0.1, 1.3, 7)
    out = {"ir_only": _jit.IR_ONLY}
    for name in sys.argv[1].split(","):
        out[name] = float(getattr(irmod, name)(x)).hex()
    for name in ("scaled", "checked", "first", "second", "via_python", "third"):
        d = getattr(irmod, name)
        out[name + ".hits"] = sum(d.stats.cache_hits.values())
        out[name + ".misses"] = sum(d.stats.cache_misses.values())
    print(json.dumps(out))
""")


@pytest.fixture()
def irmod(tmp_path, monkeypatch):
    (tmp_path / "irmod.py").write_text(_MODULE)
    monkeypatch.syspath_prepend(str(tmp_path))
    sys.modules.pop("irmod", None)
    import irmod

    yield irmod
    sys.modules.pop("irmod", None)


def test_an_inner_kernel_has_no_machine_code_and_its_caller_runs_it(irmod):
    if not _jit.IR_ONLY:
        pytest.skip("IR-only libraries are off (MORPHLAB_INNER_IR_ONLY=0 or another Numba)")
    x = np.linspace(0.1, 1.3, 7)
    assert irmod.first(x) == pytest.approx(np.sum(2.0 * x + np.sin(x)), rel=1e-15)
    z = x + 0.5j  # dtype-generic: the complex signature links its own IR
    assert irmod.first(z) == pytest.approx(np.sum(2.0 * z + np.sin(z)), rel=1e-15)
    for d in (irmod.scaled, irmod.checked):
        for cres in d.overloads.values():
            assert cres.library._ir_only and not cres.library._compiled, d
    for cres in irmod.first.overloads.values():
        assert not cres.library._ir_only and cres.library._compiled
    # an inner kernel's exception crosses its caller's module as before
    with pytest.raises(ValueError, match="checked: an empty array"):
        irmod.first(np.empty(0))
    # an object-mode block in an inner kernel: the block itself is machine code, called
    # through a pointer, and finds the inner kernel's environment
    assert irmod.third(x) == 2.0 * np.sum(x) + 1.0
    # a parallel loop's body is called through a pointer as well
    assert irmod.fourth(x) == pytest.approx(2.0 * (np.sum(x * x) + 1.0), rel=1e-14)
    assert irmod.via_python.overloads[irmod.via_python.signatures[0]].library._ir_only


def _child(tmp_path, cache, calls: str, ir_only: bool = True) -> dict:
    env = {**os.environ, "NUMBA_CACHE_DIR": str(cache),
           "PYTHONPATH": os.pathsep.join([str(tmp_path), os.environ.get("PYTHONPATH", "")]),
           "MORPHLAB_INNER_IR_ONLY": "1" if ir_only else "0"}
    out = subprocess.run([sys.executable, "-c", _CHILD, calls], env=env, capture_output=True,
                         text=True, timeout=300, cwd=tmp_path)
    assert out.returncode == 0, out.stderr[-3000:]
    return json.loads(out.stdout.strip().splitlines()[-1])


@pytest.mark.slow
def test_a_later_process_links_the_cached_ir_into_a_new_kernel(tmp_path):
    (tmp_path / "irmod.py").write_text(_MODULE)
    cache = tmp_path / "cache"
    a = _child(tmp_path, cache, "first,third")
    if not a["ir_only"]:
        pytest.skip("IR-only libraries are off in this environment")
    assert a["scaled.misses"] == 1 and a["first.misses"] == 1
    b = _child(tmp_path, cache, "second,first,third")
    assert b["scaled.hits"] == 1 and b["scaled.misses"] == 0  # the bitcode, loaded
    assert b["second.misses"] == 1 and b["first.hits"] == 1 and b["third.hits"] == 1
    ref = _child(tmp_path, tmp_path / "ref", "second,first,third", ir_only=False)
    assert not ref["ir_only"]
    assert (b["first"], b["second"], b["third"]) == (a["first"], ref["second"], a["third"])
    assert (b["first"], b["third"]) == (ref["first"], ref["third"])  # the same bits


@pytest.mark.slow
def test_a_cache_filled_by_numbas_own_libraries_is_linked_as_well(tmp_path):
    """A cache written without IR-only libraries (an older morphlab) holds inner kernels as
    object code with their IR beside it: a new kernel links that IR."""
    (tmp_path / "irmod.py").write_text(_MODULE)
    cache = tmp_path / "cache"
    a = _child(tmp_path, cache, "first", ir_only=False)
    b = _child(tmp_path, cache, "second")
    assert b["scaled.hits"] == 1 and b["scaled.misses"] == 0
    ref = _child(tmp_path, tmp_path / "ref", "second", ir_only=False)
    assert not a["ir_only"] and b["second"] == ref["second"]


@pytest.mark.slow
def test_the_quickstart_computes_the_same_bits_either_way(tmp_path):
    """The README quickstart's run and its direct sensitivities, compiled in two fresh caches
    with and without IR-only libraries: equal to the last bit."""
    code = textwrap.dedent("""
        import json
        import numpy as np
        from morphlab.bench import scenarios
        ns = {}
        exec(scenarios.QUICKSTART.replace("print(res.summary())", ""), ns)
        exec(scenarios.QUICKSTART_SENSITIVITY.replace("{method}", "direct")
             .replace("print(sens.values, sens.gradients)", ""), ns)
        g = ns["sens"].gradients["ks_stress"]
        out = [*ns["tip"].ravel(), *ns["sigma"].ravel(), *(g[k] for k in sorted(g))]
        print(json.dumps([float(v).hex() for v in out]))
    """)
    runs = []
    for flag in ("1", "0"):
        env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / flag),
               "MORPHLAB_INNER_IR_ONLY": flag}
        out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True,
                             text=True, timeout=900)
        assert out.returncode == 0, out.stderr[-3000:]
        runs.append(json.loads(out.stdout.strip().splitlines()[-1]))
    assert len(runs[0]) > 1000 and runs[0] == runs[1]
