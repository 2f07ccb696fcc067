"""numba's cache of the kernel follows every file of the kernel (engine/space/_trace_numba/
cache.py): numba itself invalidates a function's cache only when the function's own file
changes."""

from __future__ import annotations

import importlib.util
import os
import subprocess
import sys
from pathlib import Path

import pytest

from engine.space._trace_numba.cache import MARK, flush_if_changed, sources_digest

ROOT = Path(__file__).resolve().parents[4]


class _Cache:
    """What flush_if_changed uses of numba's cache of a function."""

    def __init__(self, path: Path) -> None:
        self.cache_path = str(path)
        self.flushed = 0

    def flush(self) -> None:
        self.flushed += 1


class _Dispatcher:
    def __init__(self, path: Path) -> None:
        self._cache = _Cache(path)


def test_a_change_in_any_file_of_the_package_flushes_every_cache(tmp_path: Path) -> None:
    src, cache = tmp_path / "src", tmp_path / "cache"
    src.mkdir()
    (src / "a.py").write_text("x = 1\n")
    (src / "b.py").write_text("y = 2\n")
    funcs = [_Dispatcher(cache), _Dispatcher(cache), object()]  # (no cache: left alone)
    assert flush_if_changed(src, funcs)  # no mark yet: whatever is cached is of unknown files
    assert (cache / MARK).read_text() == sources_digest(src)
    assert not flush_if_changed(src, funcs)  # the same files: the cache stands
    (src / "b.py").write_text("y = 3\n")  # a callee's file (the caller's is unchanged)
    assert flush_if_changed(src, funcs)
    assert [f._cache.flushed for f in funcs[:2]] == [2, 2]
    (src / "c.py").write_text("")  # a new file counts too
    assert sources_digest(src) != (cache / MARK).read_text()


def test_without_a_cache_nothing_happens(tmp_path: Path) -> None:
    (tmp_path / "a.py").write_text("")
    assert not flush_if_changed(tmp_path, [object()])


_SCRIPT = """
import numpy as np
from engine.space._trace_numba import _band_lu_from
ab = np.array([[0.0, 1.0], [2.0, 3.0], [4.0, 0.0]])
_band_lu_from(ab, 2, 1, 0, np.empty(2, dtype=np.int64), 0)
print(sum(_band_lu_from.stats.cache_hits.values()), sum(_band_lu_from.stats.cache_misses.values()))
"""


@pytest.mark.slow
@pytest.mark.skipif(importlib.util.find_spec("numba") is None, reason="numba not installed")
def test_numba_compiles_again_after_a_kernel_file_changed(tmp_path: Path) -> None:
    """In real processes with a cache of their own: compiled once, then loaded from the cache,
    then compiled again once the mark says that the kernel's files are other ones."""
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path)}

    def hits_misses() -> list[str]:
        out = subprocess.run([sys.executable, "-c", _SCRIPT], env=env, cwd=ROOT,
                             capture_output=True, text=True, check=True, timeout=300)
        return out.stdout.split()

    assert hits_misses() == ["0", "1"]  # compiled
    assert hits_misses() == ["1", "0"]  # from the cache
    (mark,) = tmp_path.rglob(MARK)
    mark.write_text("the digest of other files")
    assert hits_misses() == ["0", "1"]  # compiled again
    assert hits_misses() == ["1", "0"]
