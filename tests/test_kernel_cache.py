"""The kernel cache is dropped when any kernel source changes (Numba itself checks only the
file that defines a function, not the files of the kernels it calls)."""

from morphlab.kernels import _drop_stale_cache


def test_cache_is_kept_while_sources_are_unchanged_and_dropped_after_an_edit(tmp_path):
    (tmp_path / "a.py").write_text("x = 1\n")
    (tmp_path / "b.py").write_text("y = 2\n")
    cache = tmp_path / "__pycache__"
    cache.mkdir()
    (cache / "a.f-1.py311.nbi").write_text("old")
    _drop_stale_cache(str(tmp_path))  # no stamp yet: the cache's origin is unknown
    assert not (cache / "a.f-1.py311.nbi").exists()
    (cache / "a.f-1.py311.nbi").write_text("new")
    (cache / "a.f-1.py311.1.nbc").write_text("new")
    (cache / "a.cpython-311.pyc").write_text("bytecode")
    _drop_stale_cache(str(tmp_path))
    assert (cache / "a.f-1.py311.nbi").exists() and (cache / "a.f-1.py311.1.nbc").exists()
    (tmp_path / "b.py").write_text("y = 3\n")  # an edit of another kernel file
    _drop_stale_cache(str(tmp_path))
    assert not (cache / "a.f-1.py311.nbi").exists()
    assert not (cache / "a.f-1.py311.1.nbc").exists()
    assert (cache / "a.cpython-311.pyc").exists()  # Python's own bytecode is left alone
