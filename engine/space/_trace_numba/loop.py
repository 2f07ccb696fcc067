"""The compiled tracer's loop (:mod:`engine.space._trace_numba`): :func:`run`, the committed
passes of engine.space.trace.trace_curve; the steps of a pass are in :mod:`.steps`.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from engine.model.tolerances import POLISH_TANGENT_MOVE
from engine.space._trace_numba.band import _band_solve
from engine.space._trace_numba.factor import _DECLINE, _OK, _SINGULAR, _factor_into
from engine.space._trace_numba.steps import _correct
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
def run(u, t, t_in, u_prev, u0, fp, ip, fixed, gi, gj, lengths, targets, rows, cols, sign,
        axes, entry_i, entry_j, col_pos, entry_rank, entry_col, keys, row_rank, sign_perm,
        out_pts, out_tan, out_sign, out_logdet):
    """Committed passes of engine.space.trace.trace_curve (see engine.space.trace_kernel.advance).

    ``u_prev``: the point before ``u`` (tangent ``t_in``), for the predictor's cubic
    (engine.space.trace.predict) when ``has_prev``;
    ``fp = [h, arc, close_after, h_max, h_min, collapse, strain_tol, residual_atol, cos_turn,
    h_cross]``,
    ``ip = [sign, budget, tried, close, dense, band_max_work, deadline_every, checked,
    cross_ahead, has_prev]``; the state entries of ``u, t, t_in, u_prev, fp, ip`` are updated
    in place. Returns (points committed, event)."""
    h = fp[0]
    arc = fp[1]
    close_after = fp[2]
    h_max = fp[3]
    h_min = fp[4]
    collapse = fp[5]
    strain_tol = fp[6]
    atol = fp[7]
    cos_turn = fp[8]
    h_cross = fp[9]
    sgn = ip[0]
    budget = ip[1]
    tried = ip[2] != 0
    close = ip[3] != 0
    dense = ip[4] != 0
    band_max_work = ip[5]
    every = ip[6]
    checked = ip[7]
    cross_ahead = ip[8] != 0
    has_prev = ip[9] != 0
    m = u.shape[0]
    ea = lengths.shape[0]
    cap = out_pts.shape[0]
    vals = np.empty(rows.shape[0])
    lay = np.full(4, -1, dtype=np.int64)
    lay_pos = np.empty(rows.shape[0], dtype=np.int64)
    lay_rp = np.zeros(0, dtype=np.int64)
    sq = np.empty(ea)
    e1 = np.zeros(m)
    e1[0] = 1.0
    count = 0
    event = _EV_FULL
    tw = np.zeros(m)
    s3 = 0
    l3 = 0.0
    step = 0.0
    # work arrays of every pass, allocated once: [v, fixed], [w, fixed] (the corrector's
    # iterate), [u, fixed] of a factorisation, the corrector's right-hand side and the band
    # rows of its entries on the dense path, the tangent's solve, and the empty arrays of the
    # dense factorisation
    nf = fixed.shape[0]
    ext_v = np.empty(m + nf)
    ext_w = np.empty(m + nf)
    ext_f = np.empty(m + nf)
    ext_v[m:] = fixed
    ext_w[m:] = fixed
    ext_f[m:] = fixed
    v = ext_v[:m]
    rhs = np.empty(m)
    pos_dense = np.arange(1, ea + 1)
    ybuf = np.empty(m)
    wpre = np.empty(m)  # the corrected point before the polish
    empty_i = np.zeros(0, dtype=np.int64)
    empty_f = np.zeros(0)
    st, ab, piv, kl, ku, _s, _l, rp, y0, dv, gam = _factor_into(
        u, t_in, dense, band_max_work, fixed, gi, gj, rows, cols, sign, axes, entry_i, entry_j,
        col_pos, entry_rank, entry_col, keys, row_rank, sign_perm, vals, lay, lay_pos, lay_rp,
        ext_f, empty_i, empty_f)
    lay_rp = rp
    ab3, piv3, kl3, ku3, rp3, y03, dv3, gam3 = ab, piv, kl, ku, rp, y0, dv, gam
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
        # --- one attempt (engine.space.trace._attempt) ---
        for c in range(m):
            v[c] = u[c] + h * t[c]
        if has_prev:  # engine.space.trace.predict: the cubic through u_prev and u
            h0 = math.sqrt(_dist2(u, u_prev))
            if h0 > 0.0:
                r = h / h0
                a3 = r * r * (3.0 + 2.0 * r)
                b3 = h0 * r * r * (1.0 + r)
                for c in range(m):
                    v[c] = v[c] + a3 * (u_prev[c] - u[c] + h0 * t[c]) + b3 * (t_in[c] - t[c])
        _squared_lengths_ext(ext_v, gi, gj, sq)
        shrink = _strained(sq, lengths, strain_tol)
        decline = False
        w = v
        ok = False
        iters = 0
        if not shrink:
            w, ok, iters = _correct(v, ab, piv, kl, ku, rp, col_pos, y0, dv, gam, dense, atol,
                                    False, fixed, gi, gj, lengths, targets, sq, True, ext_w,
                                    rhs, pos_dense)
            if not ok:
                st2, ab2, piv2, kl2, ku2, _s2, _l2, rp2, y02, dv2, gam2 = _factor_into(
                    v, t, dense, band_max_work, fixed, gi, gj, rows, cols, sign, axes,
                    entry_i, entry_j, col_pos, entry_rank, entry_col, keys, row_rank, sign_perm,
                    vals, lay, lay_pos, lay_rp, ext_f, empty_i, empty_f)
                lay_rp = rp2
                if st2 == _DECLINE:
                    decline = True
                elif st2 == _SINGULAR:
                    w, ok, iters = v, False, 0
                else:
                    w, ok, iters = _correct(v, ab2, piv2, kl2, ku2, rp2, col_pos, y02, dv2,
                                            gam2, dense, atol, False, fixed, gi, gj, lengths,
                                            targets, sq, False, ext_w, rhs, pos_dense)
            if not decline:
                if not ok or math.sqrt(_dist2(w, v)) > 0.5 * h:
                    shrink = True
        if decline:
            event = _EV_PASS
            break
        if not shrink:
            st3, ab3, piv3, kl3, ku3, s3, l3, rp3, y03, dv3, gam3 = _factor_into(
                w, t, dense, band_max_work, fixed, gi, gj, rows, cols, sign, axes, entry_i,
                entry_j, col_pos, entry_rank, entry_col, keys, row_rank, sign_perm, vals, lay,
                lay_pos, lay_rp, ext_f, empty_i, empty_f)
            lay_rp = rp3
            if st3 == _DECLINE:
                event = _EV_PASS
                break
            if st3 == _SINGULAR:
                shrink = True
            else:
                # the polish (engine.space.trace._attempt): Newton with the factorisation at w to
                # CORRECT_TIGHT * atol (sq holds the squared lengths at w); the tangent
                # factorised again at the polished point where it moved w by more than
                # POLISH_TANGENT_MOVE of the step
                for c in range(m):
                    wpre[c] = w[c]
                w, ok, _it = _correct(w, ab3, piv3, kl3, ku3, rp3, col_pos, y03, dv3, gam3,
                                      dense, atol, True, fixed, gi, gj, lengths, targets, sq,
                                      True, ext_w, rhs, pos_dense)
                shrink = not ok
                if ok and math.sqrt(_dist2(w, wpre)) > POLISH_TANGENT_MOVE * h:
                    st3, ab3, piv3, kl3, ku3, s3, l3, rp3, y03, dv3, gam3 = _factor_into(
                        w, t, dense, band_max_work, fixed, gi, gj, rows, cols, sign, axes,
                        entry_i, entry_j, col_pos, entry_rank, entry_col, keys, row_rank,
                        sign_perm, vals, lay, lay_pos, lay_rp, ext_f, empty_i, empty_f)
                    lay_rp = rp3
                    if st3 == _DECLINE:
                        event = _EV_PASS
                        break
                    shrink = st3 == _SINGULAR
            if not shrink:
                y = ybuf
                if dense:  # _solve's dense path, into ybuf
                    for c in range(m):
                        y[c] = e1[c]
                    _band_solve(ab3, m, kl3, ku3, piv3, y)
                else:  # BorderedFactor.solve_first: B0^{-1} e_1 / gamma, already known
                    for c in range(m):
                        y[c] = y03[c] / gam3
                ny = math.sqrt(_dot(y, y))
                if not np.isfinite(ny) or ny == 0.0:
                    shrink = True
                else:
                    for c in range(m):
                        tw[c] = y[c] / ny
                    if _dot(tw, t) < cos_turn:
                        shrink = True
                    elif not (s3 == sgn or sgn == 0):
                        if h > h_cross:
                            shrink = True  # as engine.space.trace._attempt
                        else:
                            event = _EV_PASS  # a crossing: the Python loop decides
                            break
        if not shrink:
            step = math.sqrt(_dist2(w, u))
            if step > h_max:
                shrink = True
        if shrink:
            budget = nb
            h *= 0.5
            has_prev = False  # the tangent predicts from here on (engine.space.trace.trace_curve)
            continue
        arc_new = arc + step
        if close and arc_new > close_after:
            # segment_distance(u, w, u0) <= 0.5 h_max: the Python loop tests the closing
            if _segment_distance(u, w, u0) <= 0.5 * h_max:
                event = _EV_PASS
                break
        # commit
        budget = nb
        out_pts[count] = w
        out_tan[count] = tw
        out_sign[count] = s3
        out_logdet[count] = l3
        count += 1
        arc = arc_new
        for c in range(m):
            u_prev[c] = u[c]
            t_in[c] = t[c]
            u[c] = w[c]
            t[c] = tw[c]
        has_prev = True
        ab, piv, kl, ku, rp, y0, dv, gam = ab3, piv3, kl3, ku3, rp3, y03, dv3, gam3
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
