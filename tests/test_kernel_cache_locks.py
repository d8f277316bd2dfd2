"""Processes that share a kernel cache compile each kernel signature once between them
(morphlab.kernels._jit: lock files per signature, and per kernel around its cache index).

Two fresh processes call the same kernel at the same moment (a file barrier) on an empty
cache; the kernel takes about a second to compile, far longer than the processes' start
skew after the barrier, so without the locks both compile it (seen: one cache miss in each
process). With them, one compiles and the other loads the compiled code.
"""

import json
import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest

#: A kernel whose compilation takes about a second (a hundred branches).
_MODULE = "\n".join(
    ["from morphlab.kernels._jit import kernel", "", "", "@kernel", "def heavy(x):",
     "    s = x[0] * 0.0", "    for i in range(x.shape[0]):", "        v = x[i]"]
    + [f"        if v.real > {k}.0:\n            s += v * {k}.5\n        else:\n"
       f"            s -= v / {k + 1}.0" for k in range(1, 100)]
    + ["    return s", ""])

#: One process: wait for the others at the barrier, call ``heavy`` on each dtype, report.
_CHILD = textwrap.dedent("""
    import json, os, sys, time
    import numpy as np
    me, n, folder = sys.argv[1], int(sys.argv[2]), sys.argv[3]
    if os.environ.get("SLOW_INDEX"):  # between reading and writing the index, wait for the
        from numba.core import caching  # others to get there too (3 s at most)
        save_index = caching.IndexDataCacheFile._save_index
        def slow(self, overloads):
            open(os.path.join(folder, "saving." + me), "w").close()
            t0 = time.monotonic()
            while (sum(f.startswith("saving.") for f in os.listdir(folder)) < n
                   and time.monotonic() - t0 < 3.0):
                time.sleep(0.005)
            save_index(self, overloads)
        caching.IndexDataCacheFile._save_index = slow
    import lockmod
    dtypes = sys.argv[4].split(",")
    open(os.path.join(folder, "ready." + me), "w").close()
    while sum(f.startswith("ready.") for f in os.listdir(folder)) < n:
        time.sleep(0.005)
    values = [complex(lockmod.heavy(np.arange(1.0, 4.0).astype(d))) for d in dtypes]
    print(json.dumps({"misses": sum(lockmod.heavy.stats.cache_misses.values()),
                      "hits": sum(lockmod.heavy.stats.cache_hits.values()),
                      "values": [[v.real, v.imag] for v in values]}))
""")


def _run(tmp_path, jobs: list[str], slow_index: bool = False) -> list[dict]:
    """Start one process per entry of ``jobs`` (its dtypes, comma-separated) at once
    (``slow_index``: each waits between reading and writing a cache index until all the
    others have read it too, or 3 s)."""
    barrier = tmp_path / f"barrier{len(list(tmp_path.glob('barrier*')))}"
    barrier.mkdir()
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "cache"),
               PYTHONPATH=os.pathsep.join([str(tmp_path), os.environ.get("PYTHONPATH", "")]),
               SLOW_INDEX="1" if slow_index else "")
    procs = [subprocess.Popen([sys.executable, "-c", _CHILD, str(i), str(len(jobs)),
                               str(barrier), dtypes], env=env, stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE, text=True)
             for i, dtypes in enumerate(jobs)]
    out = []
    for p in procs:
        stdout, stderr = p.communicate(timeout=300)
        assert p.returncode == 0, stderr
        out.append(json.loads(stdout.strip().splitlines()[-1]))
    return out


@pytest.mark.slow
@pytest.mark.skipif(sys.platform == "win32", reason="no flock: no locks across processes")
def test_two_processes_compile_a_signature_once(tmp_path):
    (tmp_path / "lockmod.py").write_text(_MODULE)
    a, b = _run(tmp_path, ["float64", "float64"])
    # exactly one of the two compiled (a miss), the other loaded its code (a hit)
    assert sorted([a["misses"], b["misses"]]) == [0, 1]
    assert sorted([a["hits"], b["hits"]]) == [0, 1]
    assert a["values"] == b["values"]


@pytest.mark.slow
@pytest.mark.skipif(sys.platform == "win32", reason="no flock: no locks across processes")
def test_signatures_added_at_once_all_stay_in_the_cache(tmp_path):
    """Two processes add different signatures of one kernel at once: the cache index keeps
    both (a third process loads both, compiling nothing), each with its own code. Numba
    reads, extends and writes the index; the two processes here wait for each other between
    reading and writing it, so that without the index's lock both read it empty and one
    overwrites the other's entry (seen: the third process then compiles again). With the
    lock the second reads the index only after the first has written it (its wait times out
    after 3 s)."""
    (tmp_path / "lockmod.py").write_text(_MODULE)
    real, cplx = _run(tmp_path, ["float64", "complex128"], slow_index=True)
    assert real["misses"] == 1 and cplx["misses"] == 1  # different signatures: both compile
    (both,) = _run(tmp_path, ["float64,complex128"])
    assert both["misses"] == 0 and both["hits"] == 2
    assert both["values"] == real["values"] + cplx["values"]
    x = np.arange(1.0, 4.0)
    assert both["values"][0][0] == pytest.approx(_reference(x), rel=1e-14)


def _reference(x: np.ndarray) -> float:
    """``heavy`` in Python (its result is a sum of a hundred branches per entry)."""
    s = 0.0
    for v in x:
        for k in range(1, 100):
            s = s + v * (k + 0.5) if v > k else s - v / (k + 1.0)
    return s
