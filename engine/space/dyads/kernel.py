"""The closed form's sample loops compiled (numba), with numpy as the fallback and the reference.

A dense closed-form exploration places 10^5 samples and checks them: in numpy every dyad step
is some twenty passes over the samples, and the small placements of the checks (a golden
search calls :func:`engine.space.dyads.chain.place` sixty times on a few angles) pay the overhead of
each numpy call. :mod:`engine.space.dyads._numba` runs the same loops compiled: the placement, the
step gaps of a walk and the length check, each bitwise the numpy code it replaces (same
operations in the same order, the trigonometry computed by numpy), so an answer never depends
on which path ran.

The choice: environment variable ``LINKAGE_DYADS_KERNEL`` = ``numba`` (default; numpy when
numba cannot be imported) or ``numpy``. The kernels are loaded on first use (numba caches the
machine code on disk: about a second to import numba and load it; a few seconds to compile
where the cache is cold, which :func:`prepare` at a worker's start-up keeps out of requests).
"""

from __future__ import annotations

import os
import threading
from types import ModuleType

#: Environment variable choosing the closed form's path: ``numba`` or ``numpy``.
KERNEL_ENV = "LINKAGE_DYADS_KERNEL"

_module: ModuleType | None = None
_tried = False
_lock = threading.Lock()

#: Why the kernels could not be loaded (None when loaded, not tried, or numba is missing).
failure: str | None = None


def kernels() -> ModuleType | None:
    """The compiled kernels (:mod:`engine.space.dyads._numba`) when chosen and loadable, else None
    (the numpy path). The first call loads them (and waits)."""
    if os.environ.get(KERNEL_ENV, "numba").strip().lower() == "numpy":
        return None
    if _module is None and not _tried:
        load()
    return _module


def prepare() -> bool:
    """Load the kernels unless numpy is chosen (before a worker's first request): True when
    the compiled path is in use."""
    return kernels() is not None


def load() -> bool:
    """Import and compile the kernels (once per process); True when they are ready."""
    global _module, _tried, failure
    with _lock:
        if not _tried:
            try:
                _module = _compile()
            except ImportError:  # numba missing: numpy is the path
                _module = None
            except Exception as err:  # noqa: BLE001 -- any failure leaves numpy in charge
                _module = None
                failure = f"{type(err).__name__}: {err}"
            _tried = True
    return _module is not None


def _after_fork() -> None:
    """A forked child gets a lock of its own (a thread of the parent may hold the old one)."""
    global _lock
    _lock = threading.Lock()


os.register_at_fork(after_in_child=_after_fork)


def _compile() -> ModuleType:
    """The kernel module, every kernel compiled for the one signature it is called with."""
    import numpy as np

    from engine.space.dyads import _numba

    f8, i8, f8x2 = np.zeros(1), np.zeros(1, dtype=np.int64), np.zeros((1, 2))
    _numba.place(f8, f8, 1.0, np.ones((1, 1)), np.zeros((0, 1), bool), i8, i8, i8,
                 np.ones((1, 6)), f8x2, 0, 0, i8, i8, f8x2, np.zeros((1, 1)), np.zeros((1, 1)))
    _numba.long_gaps(f8x2, 1.0, i8)
    _numba.within_lengths(f8x2, f8x2, i8, np.zeros((1, 2), dtype=np.int64), f8, f8)
    _numba.golden_signed_nu(f8, f8, f8, i8, np.ones((1, 1)), 1, 0.5, i8, i8, i8,
                            np.ones((1, 6)), f8x2, 0, 0, 1.0, np.zeros(1))
    _numba.near_segments(f8x2, np.zeros(2), 1.0, i8)
    return _numba
