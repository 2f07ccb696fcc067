"""The steps of the compiled tracer's pass (:mod:`engine.space._trace_numba`), each a piece of
engine.space.trace._attempt that :func:`engine.space._trace_numba.loop.run` calls in turn.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from engine.model.tolerances import CORRECT_TIGHT
from engine.space._trace_numba.band import _band_solve
from engine.space._trace_numba.sums import _dot_gather, _gap, _squared_lengths_ext, _within


@njit(cache=True)
def _correct(v, ab, piv, kl, ku, row_pos, col_pos, y0, d, gamma, dense, atol, tight_goal,
             fixed, gi, gj, lengths, targets, sq, sq_ready, ext, rhs, pos_dense):
    """engine.space.trace.correct with a factorisation (max_iter 12, to ``CORRECT_TIGHT * atol``,
    or to ``atol`` where ``tight_goal`` is False): (w, ok, iterations that reached ``atol``).
    ``sq_ready``: ``sq`` already holds the squared lengths at ``v``. Work arrays from the
    caller: ``ext`` (M + F,) with the fixed coordinates after ``M`` (``w`` is its first
    ``M`` entries: a view, valid until the next call with the same ``ext``), ``rhs``
    (M,) and, for the dense path, ``pos_dense = [1, ..., E]`` (the band row of each bar's
    right-hand side entry)."""
    m = v.shape[0]
    ext[:m] = v  # w is ext[:m]: the gathers read it without a copy per iteration
    w = ext[:m]
    rhs[:] = 0.0
    prev = np.inf
    # the band row of each bar's right-hand side entry (dense: the row after the first,
    # ``pos_dense = [1, ..., E]`` from the caller)
    pos = pos_dense if dense else row_pos[1:]
    tight = CORRECT_TIGHT * atol if tight_goal else atol
    within = -1  # the iterations that reached atol (what the step control looks at)
    for it in range(1, 13):
        if it > 1 or not sq_ready:
            _squared_lengths_ext(ext, gi, gj, sq)
        ok_atol, ok_tight = _within(sq, lengths, atol, tight)
        if within < 0 and ok_atol:
            within = it - 1
        if ok_tight:
            return w, True, it - 1 if within < 0 else within
        # -(l^2 - L^2) straight into the right-hand side (band order), and its norm
        norm = math.sqrt(_gap(sq, targets, pos, rhs))
        if norm > 0.7 * prev or norm != norm:
            return w, ok_atol, it if within < 0 else within
        prev = norm
        if dense:
            rhs[0] = 0.0
            _band_solve(ab, m, kl, ku, piv, rhs)  # _solve's dense path, in place
            for c in range(m):
                w[c] += rhs[c]
        else:  # _solve fused: the right-hand side already in the band order, one buffer
            rhs[row_pos[0]] = 0.0
            _band_solve(ab, m, kl, ku, piv, rhs)
            s = _dot_gather(d, rhs, col_pos) / gamma
            for c in range(m):
                w[c] += rhs[col_pos[c]] - y0[c] * s
    _squared_lengths_ext(ext, gi, gj, sq)
    return w, _within(sq, lengths, atol, atol)[0], 12 if within < 0 else within
