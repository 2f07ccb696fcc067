"""Bulk construction of many small objects with the cyclic garbage collector paused.

Mapping a large linkage (a 10,000-rotor chain: 20,000 vertices, 20,000 bars) to or from models
creates some 10^5 small containers. Every such allocation counts towards a collection, and the
older generations are rescanned as they grow, so the collector costs several times the
construction itself (unpickling that chain's request: about 0.11 s with the collector paused,
0.3-0.6 s with it running). None of these objects forms a reference cycle, so nothing is lost
by pausing the collector while they are built; it runs again afterwards as usual.
"""

from __future__ import annotations

import gc
from collections.abc import Iterator
from contextlib import contextmanager


@contextmanager
def gc_paused() -> Iterator[None]:
    """Pause the cyclic garbage collector for the block (restored as it was, also nested)."""
    was_enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if was_enabled:
            gc.enable()
