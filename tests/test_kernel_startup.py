"""The first compilation is announced once, and the cache lives where the user says."""

import os
import subprocess
import sys

from morphlab.jit import cache


def test_announced_once_on_a_cold_cache(monkeypatch, capsys):
    monkeypatch.setattr(cache, "_announced", False)
    monkeypatch.setattr(cache, "kernels_cached", lambda: False)
    cache.announce_compilation()
    cache.announce_compilation()
    err = capsys.readouterr().err
    assert err.count("compiling the numerical kernels once") == 1
    assert str(cache.kernel_cache_dir()) in err


def test_silent_on_a_warm_cache(monkeypatch, capsys):
    monkeypatch.setattr(cache, "_announced", False)
    monkeypatch.setattr(cache, "kernels_cached", lambda: True)
    cache.announce_compilation()
    assert capsys.readouterr().err == ""


def test_numba_cache_dir_is_respected(tmp_path):
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path))
    out = subprocess.run([sys.executable, "-c", "from morphlab.jit.cache import "
                          "kernel_cache_dir; print(kernel_cache_dir())"], env=env,
                         capture_output=True, text=True, check=True).stdout
    assert out.strip().startswith(str(tmp_path))
