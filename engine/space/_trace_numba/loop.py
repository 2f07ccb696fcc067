"""The compiled tracer's loop (:mod:`engine.space._trace_numba`): :func:`run`, the committed
passes of engine.space.trace.trace_curve; the steps of a pass are in :mod:`.steps`.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from engine.space._trace_numba.factor import _DECLINE, _OK
from engine.space._trace_numba.steps import (
    Correcting,
    Factoring,
    _corrected,
    _factor_at,
    _polished,
    _predict,
    _tangent,
)
from engine.space._trace_numba.sums import (
    _dist2,
    _dot,
    _segment_distance,
    _squared_lengths_ext,
    _strained,
)

_EV_FULL = 0
_EV_PASS = 1
_EV_DEADLINE = 2


@njit(cache=True)
def _extended_work(fixed, m):
    """A work array ``[x, fixed]`` (M + F,) for points ``x`` of ``M`` free coordinates."""
    ext = np.empty(m + fixed.shape[0])
    ext[m:] = fixed
    return ext


@njit(cache=True)
def _work(m, dense, band_max_work, atol, fixed, gi, gj, lengths, targets, rows, cols, sign,
          axes, entry_i, entry_j, col_pos, entry_rank, entry_col, keys, row_rank, sign_perm):
    """The work arrays of every pass of :func:`run`, allocated once, with the arrays they go
    with: those of the factorisations (:data:`.steps.Factoring`: ``[u, fixed]`` of a
    factorisation, the Jacobian's values, the band layout, the empty arrays of the dense
    path), the corrector's (:data:`.steps.Correcting`: ``[w, fixed]``, its iterate; the squared
    lengths, its right-hand side and the band rows of its entries on the dense path), and
    ``[v, fixed]`` of the predicted point."""
    fd = Factoring(dense, band_max_work, fixed, gi, gj, rows, cols, sign, axes, entry_i,
                   entry_j, col_pos, entry_rank, entry_col, keys, row_rank, sign_perm,
                   np.empty(rows.shape[0]), np.full(4, -1, dtype=np.int64),
                   np.empty(rows.shape[0], dtype=np.int64), _extended_work(fixed, m),
                   np.zeros(0, dtype=np.int64), np.zeros(0))
    cd = Correcting(col_pos, dense, atol, fixed, gi, gj, lengths, targets,
                    np.empty(lengths.shape[0]), _extended_work(fixed, m), np.empty(m),
                    np.arange(1, lengths.shape[0] + 1))
    return fd, cd, _extended_work(fixed, m)


@njit(cache=True, inline="always")
def _commit(k, w, tw, s3, l3, u, t, t_in, u_prev, out_pts, out_tan, out_sign, out_logdet):
    """Commit the pass to ``w`` (tangent ``tw``, sign and ``log|det|`` ``s3``, ``l3``): its
    row ``k`` of the output, and ``u``, ``t`` move on to ``u_prev``, ``t_in``."""
    out_pts[k] = w
    out_tan[k] = tw
    out_sign[k] = s3
    out_logdet[k] = l3
    for c in range(u.shape[0]):
        u_prev[c] = u[c]
        t_in[c] = t[c]
        u[c] = w[c]
        t[c] = tw[c]


@njit(cache=True)
def run(u, t, t_in, u_prev, u0, fp, ip, fixed, gi, gj, lengths, targets, rows, cols, sign,
        axes, entry_i, entry_j, col_pos, entry_rank, entry_col, keys, row_rank, sign_perm,
        out_pts, out_tan, out_sign, out_logdet):
    """Committed passes of engine.space.trace.trace_curve (see engine.space.trace_kernel.advance).

    ``u_prev``: the point before ``u`` (tangent ``t_in``), for the predictor's cubic
    (engine.space.curve.predict) when ``has_prev``;
    ``fp = [h, arc, close_after, h_max, h_min, collapse, strain_tol, residual_atol, cos_turn,
    h_cross]``,
    ``ip = [sign, budget, tried, close, dense, band_max_work, deadline_every, checked,
    cross_ahead, has_prev]``; the state entries of ``u, t, t_in, u_prev, fp, ip`` are updated
    in place. Returns (points committed, event).

    A pass (engine.space.trace._attempt) is the steps of :mod:`.steps`: predict, strain test,
    correct, factorise at the corrected point and polish, tangent, turn and sign tests; then
    the step control and the closing test, and the commit."""
    h, arc, close_after, h_max, h_min = fp[0], fp[1], fp[2], fp[3], fp[4]
    collapse, strain_tol, cos_turn, h_cross = fp[5], fp[6], fp[8], fp[9]
    sgn, budget, tried, close, dense = ip[0], ip[1], ip[2] != 0, ip[3] != 0, ip[4] != 0
    every, checked, cross_ahead, has_prev = ip[6], ip[7], ip[8] != 0, ip[9] != 0
    m = u.shape[0]
    cap = out_pts.shape[0]
    fd, cd, ext_v = _work(m, dense, ip[5], fp[7], fixed, gi, gj, lengths, targets, rows, cols,
                          sign, axes, entry_i, entry_j, col_pos, entry_rank, entry_col, keys,
                          row_rank, sign_perm)
    v = ext_v[:m]
    e1 = np.zeros(m)
    e1[0] = 1.0
    ybuf = np.empty(m)
    wpre = np.empty(m)
    tw = np.zeros(m)
    count = 0
    event = _EV_FULL
    step = 0.0
    st, fac, s3, l3 = _factor_at(u, t_in, fd, np.zeros(0, dtype=np.int64))
    lay_rp = fac.row_pos
    fac3 = fac
    if st != _OK:
        event = _EV_PASS
    while st == _OK and count < cap:
        nb = budget - 1
        if nb < 0 or h < h_min or (cross_ahead and h < collapse and not tried):
            event = _EV_PASS
            break
        if every > 0 and nb % every == 0 and nb != checked:
            event = _EV_DEADLINE
            break
        _predict(v, u, t, u_prev, t_in, h, has_prev)
        _squared_lengths_ext(ext_v, gi, gj, cd.sq)
        shrink = _strained(cd.sq, lengths, strain_tol)
        w = v
        iters = 0
        if not shrink:
            st2, w, ok, iters, lay_rp = _corrected(v, t, fac, fd, cd, lay_rp)
            if st2 == _DECLINE:
                event = _EV_PASS
                break
            shrink = not ok or math.sqrt(_dist2(w, v)) > 0.5 * h
        if not shrink:
            st3, fac3, s3, l3, w = _polished(w, t, h, fd, cd, lay_rp, wpre)
            lay_rp = fac3.row_pos
            if st3 == _DECLINE:
                event = _EV_PASS
                break
            shrink = st3 != _OK or not _tangent(fac3, dense, e1, ybuf, tw) or \
                _dot(tw, t) < cos_turn
            if not shrink and not (s3 == sgn or sgn == 0):
                if h > h_cross:
                    shrink = True  # as engine.space.trace._attempt
                else:
                    event = _EV_PASS  # a crossing: the Python loop decides
                    break
        if not shrink:
            step = math.sqrt(_dist2(w, u))
            shrink = step > h_max
        if shrink:
            budget = nb
            h *= 0.5
            has_prev = False  # the tangent predicts from here on (engine.space.trace.trace_curve)
            continue
        # segment_distance(u, w, u0) <= 0.5 h_max: the Python loop tests the closing
        if close and arc + step > close_after and _segment_distance(u, w, u0) <= 0.5 * h_max:
            event = _EV_PASS
            break
        _commit(count, w, tw, s3, l3, u, t, t_in, u_prev, out_pts, out_tan, out_sign, out_logdet)
        budget = nb
        count += 1
        arc = arc + step
        has_prev = True
        fac = fac3
        sgn = s3
        tried = False
        h = min(h_max, h * (1.5 if iters <= 3 else 1.0))
    fp[0] = h
    fp[1] = arc
    ip[0] = sgn
    ip[1] = budget
    ip[2] = 1 if tried else 0
    ip[9] = 1 if has_prev else 0
    return count, event
