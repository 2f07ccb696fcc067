"""The steps of the compiled tracer's pass (:mod:`engine.space._trace_numba`), each a piece of
engine.space.trace._attempt that :func:`engine.space._trace_numba.loop.run` calls in turn.
"""

from __future__ import annotations

import math
from collections import namedtuple

import numpy as np
from numba import njit

from engine.model.tolerances import CORRECT_TIGHT, POLISH_TANGENT_MOVE
from engine.space._trace_numba.band import _band_solve
from engine.space._trace_numba.factor import _OK, _SINGULAR, _factor_into
from engine.space._trace_numba.sums import (
    _dist2,
    _dot,
    _dot_gather,
    _gap,
    _squared_lengths_ext,
    _within,
)

#: What a factorisation of a pass reads (:func:`_factor_at`): the linkage's arrays as
#: :func:`engine.space._trace_numba.factor._factor_into` takes them and its work arrays
Factoring = namedtuple(
    "Factoring", "dense band_max_work fixed gi gj rows cols sign axes entry_i entry_j col_pos "
    "entry_rank entry_col keys row_rank sign_perm vals lay lay_pos ext empty_i empty_f")

#: What the corrector of a pass reads (:func:`_correct_with`): the arrays and work arrays of
#: :func:`_correct` (``sq`` the squared lengths at its last point)
Correcting = namedtuple(
    "Correcting", "col_pos dense atol fixed gi gj lengths targets sq ext rhs pos_dense")

#: A factorisation of ``[row; J]`` as :func:`_correct` and :func:`_tangent` use it (the middle
#: of what :func:`engine.space._trace_numba.factor._factor_into` returns)
Fac = namedtuple("Fac", "ab piv kl ku row_pos y0 d gamma")


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


@njit(cache=True, inline="always")
def _predict(v, u, t, u_prev, t_in, h, has_prev):
    """engine.space.curve.predict into ``v``: ``u + h t``, and with the point before ``u``
    (``has_prev``; its tangent ``t_in``) the cubic through both."""
    m = u.shape[0]
    for c in range(m):
        v[c] = u[c] + h * t[c]
    if has_prev:  # the cubic through u_prev and u
        h0 = math.sqrt(_dist2(u, u_prev))
        if h0 > 0.0:
            r = h / h0
            a3 = r * r * (3.0 + 2.0 * r)
            b3 = h0 * r * r * (1.0 + r)
            for c in range(m):
                v[c] = v[c] + a3 * (u_prev[c] - u[c] + h0 * t[c]) + b3 * (t_in[c] - t[c])


@njit(cache=True, inline="always")
def _factor_at(x, row, fd, lay_rp):
    """:func:`engine.space._trace_numba.factor._factor_into` of ``[row; J(x)]`` with what
    ``fd`` (:data:`Factoring`) holds and the band rows ``lay_rp`` of the last layout:
    ``(status, Fac, sign, logdet)``."""
    st, ab, piv, kl, ku, sgn, logdet, rp, y0, d, gamma = _factor_into(
        x, row, fd.dense, fd.band_max_work, fd.fixed, fd.gi, fd.gj, fd.rows, fd.cols, fd.sign,
        fd.axes, fd.entry_i, fd.entry_j, fd.col_pos, fd.entry_rank, fd.entry_col, fd.keys,
        fd.row_rank, fd.sign_perm, fd.vals, fd.lay, fd.lay_pos, lay_rp, fd.ext, fd.empty_i,
        fd.empty_f)
    return st, Fac(ab, piv, kl, ku, rp, y0, d, gamma), sgn, logdet


@njit(cache=True, inline="always")
def _correct_with(v, fac, tight_goal, sq_ready, cd):
    """:func:`_correct` from ``v`` with the factorisation ``fac`` (:data:`Fac`) and what ``cd``
    (:data:`Correcting`) holds: (w, ok, iterations that reached ``atol``)."""
    return _correct(v, fac.ab, fac.piv, fac.kl, fac.ku, fac.row_pos, cd.col_pos, fac.y0, fac.d,
                    fac.gamma, cd.dense, cd.atol, tight_goal, cd.fixed, cd.gi, cd.gj, cd.lengths,
                    cd.targets, cd.sq, sq_ready, cd.ext, cd.rhs, cd.pos_dense)


@njit(cache=True, inline="always")
def _corrected(v, t, fac, fd, cd, lay_rp):
    """The corrector of a pass (engine.space.trace._attempt): chord Newton from the predicted
    point ``v`` with the factorisation ``fac`` at the last point, to ``residual_atol`` (the
    squared lengths at ``v`` are in ``cd.sq``), and where that fails full Newton with a
    factorisation at ``v``. Returns (status, w, ok, iterations that reached ``atol``,
    lay_rp): status ``_DECLINE`` where that factorisation is not the Python loop's,
    ``_SINGULAR`` where it is singular (``ok`` False: the step shrinks)."""
    st = _OK
    w, ok, iters = _correct_with(v, fac, False, True, cd)
    if not ok:
        st, fac2, _s2, _l2 = _factor_at(v, t, fd, lay_rp)
        lay_rp = fac2.row_pos
        if st == _SINGULAR:
            w, ok, iters = v, False, 0
        elif st == _OK:
            w, ok, iters = _correct_with(v, fac2, False, False, cd)
    return st, w, ok, iters, lay_rp


@njit(cache=True, inline="always")
def _polished(w, t, h, fd, cd, lay_rp, wpre):
    """The factorisation of ``[t; J(w)]`` at the corrected point ``w`` (the tangent's) and the
    polish with it (engine.space.trace._attempt): Newton to ``CORRECT_TIGHT * residual_atol``
    (the squared lengths at ``w`` are in ``cd.sq``), the factorisation made again at the
    polished point where the polish moved ``w`` by more than ``POLISH_TANGENT_MOVE`` of the
    step ``h`` (``wpre``: work array for the point before the polish). Returns (status, Fac,
    sign, logdet, the polished point): status ``_SINGULAR`` also where the polish fails (the
    step shrinks either way), ``_DECLINE`` where a factorisation is not the Python loop's."""
    st, fac3, s3, l3 = _factor_at(w, t, fd, lay_rp)
    if st == _OK:
        for c in range(w.shape[0]):
            wpre[c] = w[c]
        w, ok, _it = _correct_with(w, fac3, True, True, cd)
        if not ok:
            st = _SINGULAR
        elif math.sqrt(_dist2(w, wpre)) > POLISH_TANGENT_MOVE * h:
            st, fac3, s3, l3 = _factor_at(w, t, fd, fac3.row_pos)
    return st, fac3, s3, l3, w


@njit(cache=True, inline="always")
def _tangent(fac, dense, e1, y, tw):
    """The unit tangent of the factorisation ``fac`` (:data:`Fac`) of ``[t; J]`` into ``tw``
    (``y``: work array): ``[t; J]^{-1} e_1`` normalised (engine.space.trace.tangent_at); False
    where it is zero or not finite."""
    m = y.shape[0]
    if dense:  # _solve's dense path, into y
        for c in range(m):
            y[c] = e1[c]
        _band_solve(fac.ab, m, fac.kl, fac.ku, fac.piv, y)
    else:  # BorderedFactor.solve_first: B0^{-1} e_1 / gamma, already known
        for c in range(m):
            y[c] = fac.y0[c] / fac.gamma
    ny = math.sqrt(_dot(y, y))
    ok = np.isfinite(ny) and ny != 0.0
    if ok:
        for c in range(m):
            tw[c] = y[c] / ny
    return ok
