"""The factorisation step of the compiled tracer (:mod:`engine.space._trace_numba`): ``[row; J]``
(engine.space.trace.factor_augmented) by the band LU of :mod:`.band`, dense with full
bandwidth or through ``[e_k; J]`` and a rank-one update (engine.model.lu.BorderedFactor), and
solves with it.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from engine.space._trace_numba.band import _band_lu, _band_solve, _diagonal
from engine.space._trace_numba.sums import _band_values, _dot, _jac_values_ext

# status of a factorisation
_OK = 0
_SINGULAR = 1  # what Factor.ok = False means on the dense path (the Python loop shrinks)
_DECLINE = 2  # the Python path would take another method (SuperLU, direct sparse LU)


@njit(cache=True)
def _factor(u, row, dense, band_max_work, fixed, gi, gj, rows, cols, sign, axes, entry_i,
            entry_j, col_pos, entry_rank, entry_col, keys, row_rank, sign_perm, vals, lay,
            lay_pos, lay_rp):
    """:func:`_factor_into` with work arrays of its own."""
    m = u.shape[0]
    ext = np.empty(m + fixed.shape[0])
    ext[m:] = fixed
    return _factor_into(u, row, dense, band_max_work, fixed, gi, gj, rows, cols, sign, axes,
                        entry_i, entry_j, col_pos, entry_rank, entry_col, keys, row_rank,
                        sign_perm, vals, lay, lay_pos, lay_rp, ext, np.zeros(0, dtype=np.int64),
                        np.zeros(0))


@njit(cache=True)
def _factor_into(u, row, dense, band_max_work, fixed, gi, gj, rows, cols, sign, axes, entry_i,
                 entry_j, col_pos, entry_rank, entry_col, keys, row_rank, sign_perm, vals, lay,
                 lay_pos, lay_rp, ext, empty_i, empty_f):
    """engine.space.trace.factor_augmented of ``[row; J(u)]``: (status, ab, piv, kl, ku, sign,
    logdet, row_pos, y0, d, gamma). Dense: LU of ``[row; J]`` itself (full bandwidth);
    otherwise the band LU of the reordered ``[e_k; J]`` and the rank-one update
    (engine.model.lu.BorderedFactor).

    The band layout of the last ``k`` is kept (``k`` changes rarely along a curve): ``lay =
    [k, kl, ku, ins]``, ``lay_pos`` the flat index in the band (band row times ``m`` plus
    column) of each entry, ``lay_rp`` the band row of each row (a new array whenever ``k``
    changes: a factorisation keeps the one it was made with).

    Work arrays from the caller: ``ext`` (M + F,) with the fixed coordinates after ``M``
    (``[u, fixed]`` is written into it), ``empty_i`` and ``empty_f`` empty (returned where a
    path has no such array)."""
    m = u.shape[0]
    ext[:m] = u
    if dense:
        return _factor_dense(ext, row, gi, gj, rows, cols, sign, axes, vals, empty_i, empty_f)
    # k = argmax |row| (the first largest, as np.argmax)
    k = 0
    big = abs(row[0])
    for c in range(1, m):
        if abs(row[c]) > big:
            big = abs(row[c])
            k = c
    ck = col_pos[k]
    kl, ku, ins, row_pos = _band_layout(k, ck, m, keys, entry_rank, entry_col, row_rank, lay,
                                        lay_pos, lay_rp)
    if kl * (kl + ku) > band_max_work:
        return _DECLINE, np.zeros((1, 1)), empty_i, kl, ku, 0, -np.inf, row_pos, empty_f, \
            empty_f, 1.0
    off = kl + ku
    ab = np.zeros((2 * kl + ku + 1, m))
    _band_values(ab.reshape(-1), ext, entry_i, entry_j, sign, lay_pos)
    ab[off + ins - ck, ck] = 1.0
    piv = np.empty(m, dtype=np.int64)
    if not _band_lu(ab, m, kl, ku, piv):
        return _DECLINE, ab, piv, kl, ku, 0, -np.inf, row_pos, empty_f, empty_f, 1.0
    flips, logdet = _diagonal(ab, off, piv, m)
    if flips < 0:
        return _DECLINE, ab, piv, kl, ku, 0, -np.inf, row_pos, empty_f, empty_f, 1.0
    base_sign = (-1 if flips % 2 else 1) * sign_perm * (-1 if ins % 2 else 1)
    # y0 = B0^{-1} e_1 (in the original order), d = row - e_k, gamma = 1 + d.y0
    b = np.zeros(m)
    b[row_pos[0]] = 1.0
    _band_solve(ab, m, kl, ku, piv, b)
    y0 = np.empty(m)
    for c in range(m):
        y0[c] = b[col_pos[c]]
    d = row.copy()
    d[k] -= 1.0
    gamma = 1.0 + _dot(d, y0)
    if gamma == 0.0 or not np.isfinite(gamma):
        return _DECLINE, ab, piv, kl, ku, 0, -np.inf, row_pos, y0, d, gamma
    sgn = base_sign * (1 if gamma > 0 else -1)
    return _OK, ab, piv, kl, ku, sgn, logdet + math.log(abs(gamma)), row_pos, y0, d, gamma



@njit(cache=True, inline="always")
def _factor_dense(ext, row, gi, gj, rows, cols, sign, axes, vals, empty_i, empty_f):
    """:func:`_factor_into`'s dense path: the LU of ``[row; J]`` itself with full bandwidth
    (``ext = [u, fixed]``)."""
    m = row.shape[0]
    _jac_values_ext(ext, gi, gj, rows, sign, axes, vals)
    kl = m - 1
    ku = m - 1
    off = kl + ku
    ab = np.zeros((2 * kl + ku + 1, m))
    for c in range(m):
        ab[off - c, c] = row[c]  # row 0
    for e in range(rows.shape[0]):
        i = rows[e] + 1
        c = cols[e]
        ab[off + i - c, c] = vals[e]
    piv = np.empty(m, dtype=np.int64)
    if not _band_lu(ab, m, kl, ku, piv):
        return _SINGULAR, ab, piv, kl, ku, 0, -np.inf, empty_i, empty_f, empty_f, 1.0
    flips, logdet = _diagonal(ab, off, piv, m)
    if flips < 0:
        return _SINGULAR, ab, piv, kl, ku, 0, -np.inf, empty_i, empty_f, empty_f, 1.0
    sgn = -1 if flips % 2 else 1
    return _OK, ab, piv, kl, ku, sgn, logdet, empty_i, empty_f, empty_f, 1.0


@njit(cache=True, inline="always")
def _band_layout(k, ck, m, keys, entry_rank, entry_col, row_rank, lay, lay_pos, lay_rp):
    """The band layout of ``[e_k; J]`` (column ``ck`` of the unit row in the band order):
    ``(kl, ku, ins, row_pos)``, kept in ``lay = [k, kl, ku, ins]`` and ``lay_pos`` (the flat
    index of each entry in the band) for the next factorisation; ``row_pos`` (the band row of
    each row) is ``lay_rp`` while ``k`` is the kept one, else a new array."""
    if lay[0] == k:
        return lay[1], lay[2], lay[3], lay_rp
    nnz = entry_rank.shape[0]
    ins = np.searchsorted(keys, ck, side="right")
    kl = max(ins - ck, 0)
    ku = max(ck - ins, 0)
    for e in range(nnz):
        r = entry_rank[e]
        diff = r + (1 if r >= ins else 0) - entry_col[e]
        if diff > kl:
            kl = diff
        if -diff > ku:
            ku = -diff
    for e in range(nnz):  # flat index into the band: (band row) * m + column
        r = entry_rank[e]
        lay_pos[e] = (kl + ku + r + (1 if r >= ins else 0) - entry_col[e]) * m \
            + entry_col[e]
    row_pos = np.empty(m, dtype=np.int64)
    row_pos[0] = ins
    for a in range(row_rank.shape[0]):
        r = row_rank[a]
        row_pos[a + 1] = r + (1 if r >= ins else 0)
    lay[0] = k
    lay[1] = kl
    lay[2] = ku
    lay[3] = ins
    return kl, ku, ins, row_pos


@njit(cache=True)
def _solve(ab, piv, kl, ku, row_pos, col_pos, y0, d, gamma, dense, rhs):
    """Factor.solve / BorderedFactor.solve: ``[row; J]^{-1} rhs`` (a new array)."""
    m = rhs.shape[0]
    if dense:
        x = rhs.copy()
        _band_solve(ab, m, kl, ku, piv, x)
        return x
    b = np.empty(m)
    for i in range(m):
        b[row_pos[i]] = rhs[i]
    _band_solve(ab, m, kl, ku, piv, b)
    x = np.empty(m)
    for c in range(m):
        x[c] = b[col_pos[c]]
    s = 0.0
    for c in range(m):
        s += d[c] * x[c]
    s /= gamma
    for c in range(m):
        x[c] -= y0[c] * s
    return x
