"""numba's cache of the kernel kept in step with all of the kernel's files.

numba invalidates the cached machine code of a function when the function's own file changes,
not when a file of a function it calls does (a documented limitation of numba's caching):
with the kernel in several files, :func:`engine.space._trace_numba.loop.run` would be loaded
from its cache with the old code of a step changed in :mod:`.steps`. So the package keeps one
digest of all its files beside numba's cache and empties the cache of every compiled function
of the package when the digest differs (:func:`flush_if_changed`, called when the package is
imported, before anything is compiled or loaded).
"""

from __future__ import annotations

import hashlib
from collections.abc import Iterable
from pathlib import Path
from typing import Any

#: The file beside numba's cache files holding the digest they were made from.
MARK = "trace_numba.sources"


def sources_digest(root: Path) -> str:
    """sha256 of the package's files (names and contents, in name order)."""
    h = hashlib.sha256()
    for path in sorted(root.glob("*.py")):
        h.update(path.name.encode())
        h.update(path.read_bytes())
    return h.hexdigest()


def flush_if_changed(root: Path, dispatchers: Iterable[Any]) -> bool:
    """Empty the numba cache of every dispatcher when the package's files are not those the
    cache was made from; True when it did. Without a cache (or a writable one) nothing
    happens: numba then compiles in memory."""
    caches = [c for d in dispatchers if (c := getattr(d, "_cache", None)) is not None
              and hasattr(c, "cache_path") and hasattr(c, "flush")]
    if not caches:
        return False
    digest = sources_digest(root)
    mark = Path(caches[0].cache_path) / MARK
    try:
        if mark.is_file() and mark.read_text() == digest:
            return False
        for cache in caches:
            cache.flush()
        mark.parent.mkdir(parents=True, exist_ok=True)
        mark.write_text(digest)
    except OSError:  # a read-only cache: numba's own invalidation is all there is
        return False
    return True
