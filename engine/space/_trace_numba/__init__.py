"""numba kernels of :mod:`engine.space.trace_kernel` (imported only when the compiled path runs).

Every function mirrors a piece of :mod:`engine.space.trace` and :mod:`engine.model.lu`; the names
say which. The rooms: :mod:`.sums` (squared lengths, the Jacobian's values, the small
reductions), :mod:`.band` (the band LU and solve), :mod:`.factor` (the factorisation of
``[row; J]`` and its solve), :mod:`.steps` (the steps of a pass: predict, correct, polish,
tangent) and :mod:`.loop` (:func:`run`, the committed passes); :mod:`.cache` keeps numba's
cache in step with all of them. Matrices are in LAPACK band storage: ``ab[kl + ku + i - j, j]
= A[i, j]`` with ``kl`` extra leading rows for the fill of partial pivoting.
"""

from pathlib import Path

from numba.core.dispatcher import Dispatcher

from engine.space._trace_numba import band, factor, loop, steps, sums
from engine.space._trace_numba.band import (
    _band_lu,
    _band_lu_from,
    _band_solve,
    _band_solve_any,
    _diagonal,
)
from engine.space._trace_numba.cache import flush_if_changed
from engine.space._trace_numba.factor import _factor, _factor_into, _solve
from engine.space._trace_numba.loop import run
from engine.space._trace_numba.sums import (
    _band_values,
    _dist2,
    _dot,
    _dot_gather,
    _gap,
    _segment_distance,
    _strained,
    _within,
)

# before anything is compiled or loaded from numba's cache: a cache made from other files is
# emptied (see .cache)
flush_if_changed(Path(__file__).parent,
                 [f for mod in (band, factor, loop, steps, sums) for f in vars(mod).values()
                  if isinstance(f, Dispatcher) and f.py_func.__module__ == mod.__name__])

# run is what the tracer calls (engine.space.trace_kernel); the rest is named here for the
# tests, which check each piece against its reference
__all__ = [
    "_band_lu",
    "_band_lu_from",
    "_band_solve",
    "_band_solve_any",
    "_band_values",
    "_diagonal",
    "_dist2",
    "_dot",
    "_dot_gather",
    "_factor",
    "_factor_into",
    "_gap",
    "_segment_distance",
    "_solve",
    "_strained",
    "_within",
    "run",
]
