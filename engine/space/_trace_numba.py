"""numba kernels of :mod:`engine.space.trace_kernel` (imported only when the compiled path runs).

Every function mirrors a piece of :mod:`engine.space.trace` and :mod:`engine.model.lu`; the names
say
which. Matrices are in LAPACK band storage: ``ab[kl + ku + i - j, j] = A[i, j]`` with ``kl``
extra leading rows for the fill of partial pivoting.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from engine.model.tolerances import CORRECT_TIGHT, POLISH_TANGENT_MOVE

# status of a factorisation
_OK = 0
_SINGULAR = 1  # what Factor.ok = False means on the dense path (the Python loop shrinks)
_DECLINE = 2  # the Python path would take another method (SuperLU, direct sparse LU)

_EV_FULL = 0
_EV_PASS = 1
_EV_DEADLINE = 2


@njit(cache=True)
def _extended(u, fixed):
    """``[u, fixed coordinates]``: the gathers of a bar's ends index into it."""
    m = u.shape[0]
    ext = np.empty(m + fixed.shape[0])
    ext[:m] = u
    ext[m:] = fixed
    return ext


@njit(cache=True)
def _squared_lengths(u, fixed, gi, gj, out):
    """Constraints.squared_lengths."""
    _squared_lengths_ext(_extended(u, fixed), gi, gj, out)


@njit(cache=True)
def _squared_lengths_ext(ext, gi, gj, out):
    """:func:`_squared_lengths` of ``ext = [u, fixed]`` (in the plane without the loop over
    the axes: the same sums)."""
    ea, dim = gi.shape
    if dim == 2:
        for a in range(ea):
            d0 = ext[gi[a, 0]] - ext[gj[a, 0]]
            d1 = ext[gi[a, 1]] - ext[gj[a, 1]]
            out[a] = 0.0 + d0 * d0 + d1 * d1
        return
    for a in range(ea):
        s = 0.0
        for x in range(dim):
            df = ext[gi[a, x]] - ext[gj[a, x]]
            s += df * df
        out[a] = s


@njit(cache=True)
def _jac_values(u, fixed, gi, gj, rows, sign, axes, out):
    """Constraints.jacobian_values."""
    _jac_values_ext(_extended(u, fixed), gi, gj, rows, sign, axes, out)


@njit(cache=True)
def _jac_values_ext(ext, gi, gj, rows, sign, axes, out):
    """:func:`_jac_values` of ``ext = [u, fixed]``."""
    for e in range(rows.shape[0]):
        a = rows[e]
        x = axes[e]
        out[e] = 2.0 * sign[e] * (ext[gi[a, x]] - ext[gj[a, x]])


@njit(cache=True, boundscheck=False)
def _band_values(flat, ext, entry_i, entry_j, sign, pos):
    """Constraints.jacobian_values straight into the band: ``flat`` the band's storage in
    one row, ``pos`` the flat index of each entry, ``entry_i, entry_j`` the indices into
    ``ext = [u, fixed]`` of the coordinates whose difference it is (one gather each instead
    of the bar's and the axis' and then the gather's)."""
    for e in range(pos.shape[0]):
        flat[pos[e]] = 2.0 * sign[e] * (ext[entry_i[e]] - ext[entry_j[e]])


@njit(cache=True, boundscheck=False, inline="always")
def _dot(a, b):
    """``a . b`` in four partial sums (the additions are not one chain of dependencies).

    This and the other small reductions below are inlined (``inline="always"``) where
    :func:`run` and :func:`_correct` use them: as calls they made the kernel on a small
    dense linkage (the crank-rocker's curve) about 1.7 times slower."""
    m = a.shape[0]
    s0 = 0.0
    s1 = 0.0
    s2 = 0.0
    s3 = 0.0
    c = 0
    while c + 4 <= m:
        s0 += a[c] * b[c]
        s1 += a[c + 1] * b[c + 1]
        s2 += a[c + 2] * b[c + 2]
        s3 += a[c + 3] * b[c + 3]
        c += 4
    while c < m:
        s0 += a[c] * b[c]
        c += 1
    return (s0 + s1) + (s2 + s3)


@njit(cache=True, boundscheck=False, inline="always")
def _dist2(a, b):
    """``|a - b|^2`` in four partial sums."""
    m = a.shape[0]
    s0 = 0.0
    s1 = 0.0
    s2 = 0.0
    s3 = 0.0
    c = 0
    while c + 4 <= m:
        d0 = a[c] - b[c]
        d1 = a[c + 1] - b[c + 1]
        d2 = a[c + 2] - b[c + 2]
        d3 = a[c + 3] - b[c + 3]
        s0 += d0 * d0
        s1 += d1 * d1
        s2 += d2 * d2
        s3 += d3 * d3
        c += 4
    while c < m:
        d0 = a[c] - b[c]
        s0 += d0 * d0
        c += 1
    return (s0 + s1) + (s2 + s3)


@njit(cache=True, boundscheck=False, inline="always")
def _segment_distance(a, b, target):
    """engine.space.trace.segment_distance: from ``target`` to the segment ``[a, b]``."""
    m = a.shape[0]
    ab = _dist2(b, a)
    n0 = 0.0
    n1 = 0.0
    c = 0
    while c + 2 <= m:
        n0 += (target[c] - a[c]) * (b[c] - a[c])
        n1 += (target[c + 1] - a[c + 1]) * (b[c + 1] - a[c + 1])
        c += 2
    if c < m:
        n0 += (target[c] - a[c]) * (b[c] - a[c])
    num = n0 + n1
    s = 0.0 if ab == 0.0 else min(1.0, max(0.0, num / ab))
    g0 = 0.0
    g1 = 0.0
    c = 0
    while c + 2 <= m:
        e0 = a[c] + s * (b[c] - a[c]) - target[c]
        e1 = a[c + 1] + s * (b[c + 1] - a[c + 1]) - target[c + 1]
        g0 += e0 * e0
        g1 += e1 * e1
        c += 2
    if c < m:
        e0 = a[c] + s * (b[c] - a[c]) - target[c]
        g0 += e0 * e0
    return math.sqrt(g0 + g1)


@njit(cache=True, boundscheck=False)
def _diagonal(ab, off, piv, n):
    """After the LU: the number of sign flips (negative pivots and row interchanges) and
    ``log|det|``, the diagonal replaced by the reciprocals of the pivots and every row of
    ``U`` off the diagonal scaled by it (``U = D U'``, ``U'`` unit upper triangular: the back
    substitution of :func:`_band_solve` then has one product on its chain of dependencies per
    column instead of two); flips -1 when a pivot is not finite. One logarithm per block of
    the product instead of one per pivot (which would cost about what the band LU does)."""
    flips = 0
    out = 0.0
    prod = 1.0
    for j in range(n):
        a = ab[off, j]
        if not np.isfinite(a):
            return -1, 0.0
        # (no branch on the signs: they are data, and a mispredicted branch costs more)
        flips += int(a < 0) + int(piv[j] != j)
        a = abs(a)
        if a > 1e100 or a < 1e-100:
            out += math.log(a)
        else:
            prod *= a
            if prod > 1e100 or prod < 1e-100:
                out += math.log(prod)
                prod = 1.0
        r = 1.0 / ab[off, j]
        ab[off, j] = r
        if off == 4 and j + 4 < n:  # a chain's band (kl = ku = 2), unrolled
            ab[3, j + 1] *= r
            ab[2, j + 2] *= r
            ab[1, j + 3] *= r
            ab[0, j + 4] *= r
        else:
            for c in range(j + 1, min(j + off, n - 1) + 1):
                ab[off + j - c, c] *= r
    return flips, out + math.log(prod)


@njit(cache=True)
def _band_lu(ab, n, kl, ku, piv):
    """gbtrf without blocking: True unless a pivot is exactly zero. A chain's band
    (``kl = ku = 2``) goes through :func:`_band_lu22` up to its last few columns."""
    j0 = 0
    if kl == 2 and ku == 2:
        j0 = _band_lu22(ab, n, piv)
        if j0 < 0:
            return False
    return _band_lu_from(ab, n, kl, ku, piv, j0)


@njit(cache=True, fastmath={"contract"}, boundscheck=False)
def _band_lu22(ab, n, piv):
    """:func:`_band_lu_from` for ``kl = ku = 2`` on the columns ``j < n - 4`` (where every
    column has both multipliers and four columns to its right): the same operations in the
    same order, with the active window (rows ``j .. j + 2``, columns ``j .. j + 4``) held in
    registers and shifted one column on, so that a column's updates are not stored and
    reloaded by the next (the elimination is a chain of dependencies), the row interchange
    as selects (no data-dependent branch). Returns the next column, -1 at a zero pivot
    (``ab`` then as the loop leaves it)."""
    if n <= 4:
        return 0
    # x{r}{c} = A[j + r, j + c] = ab[4 + r - c, j + c]
    x00, x01, x02, x03, x04 = ab[4, 0], ab[3, 1], ab[2, 2], ab[1, 3], ab[0, 4]
    x10, x11, x12, x13, x14 = ab[5, 0], ab[4, 1], ab[3, 2], ab[2, 3], ab[1, 4]
    x20, x21, x22, x23, x24 = ab[6, 0], ab[5, 1], ab[4, 2], ab[3, 3], ab[2, 4]
    j = 0
    while j < n - 4:
        p = 0
        best = abs(x00)
        pv = x00
        if abs(x10) > best:
            best = abs(x10)
            p = 1
            pv = x10
        if abs(x20) > best:
            p = 2
            pv = x20
        piv[j] = j + p
        if pv == 0.0:
            _flush22(ab, n, j, x00, x01, x02, x03, x04, x10, x11, x12, x13, x14,
                     x20, x21, x22, x23, x24)
            return -1
        s1 = p == 1
        s2 = p == 2
        t0, t1, t2, t3, t4 = x00, x01, x02, x03, x04
        x00 = x10 if s1 else (x20 if s2 else x00)
        x01 = x11 if s1 else (x21 if s2 else x01)
        x02 = x12 if s1 else (x22 if s2 else x02)
        x03 = x13 if s1 else (x23 if s2 else x03)
        x04 = x14 if s1 else (x24 if s2 else x04)
        x10, x11, x12, x13, x14 = (t0 if s1 else x10), (t1 if s1 else x11), \
            (t2 if s1 else x12), (t3 if s1 else x13), (t4 if s1 else x14)
        x20, x21, x22, x23, x24 = (t0 if s2 else x20), (t1 if s2 else x21), \
            (t2 if s2 else x22), (t3 if s2 else x23), (t4 if s2 else x24)
        ab[4, j] = x00
        ab[3, j + 1] = x01
        ab[2, j + 2] = x02
        ab[1, j + 3] = x03
        ab[0, j + 4] = x04
        rpiv = 1.0 / x00
        l1 = x10 * rpiv
        l2 = x20 * rpiv
        ab[5, j] = l1
        ab[6, j] = l2
        if x01 != 0.0:
            x11 -= l1 * x01
            x21 -= l2 * x01
        if x02 != 0.0:
            x12 -= l1 * x02
            x22 -= l2 * x02
        if x03 != 0.0:
            x13 -= l1 * x03
            x23 -= l2 * x03
        if x04 != 0.0:
            x14 -= l1 * x04
            x24 -= l2 * x04
        # one column on: rows j + 1, j + 2 stay in registers, row j + 3 comes in
        x00, x01, x02, x03 = x11, x12, x13, x14
        x10, x11, x12, x13 = x21, x22, x23, x24
        x20, x21, x22, x23 = ab[6, j + 1], ab[5, j + 2], ab[4, j + 3], ab[3, j + 4]
        if j + 5 < n:
            x04, x14, x24 = ab[0, j + 5], ab[1, j + 5], ab[2, j + 5]
        else:
            x04, x14, x24 = 0.0, 0.0, 0.0
        j += 1
    _flush22(ab, n, j, x00, x01, x02, x03, x04, x10, x11, x12, x13, x14,
             x20, x21, x22, x23, x24)
    return j


@njit(cache=True, boundscheck=False, inline="always")
def _flush22(ab, n, j, x00, x01, x02, x03, x04, x10, x11, x12, x13, x14,
             x20, x21, x22, x23, x24):
    """Store the window of :func:`_band_lu22` at column ``j`` back into ``ab``."""
    ab[4, j], ab[3, j + 1], ab[2, j + 2], ab[1, j + 3] = x00, x01, x02, x03
    ab[5, j], ab[4, j + 1], ab[3, j + 2], ab[2, j + 3] = x10, x11, x12, x13
    ab[6, j], ab[5, j + 1], ab[4, j + 2], ab[3, j + 3] = x20, x21, x22, x23
    if j + 4 < n:
        ab[0, j + 4], ab[1, j + 4], ab[2, j + 4] = x04, x14, x24


@njit(cache=True, fastmath={"contract"})
def _band_lu_from(ab, n, kl, ku, piv, j0):
    """gbtf2 from column ``j0`` on (the columns before it done)."""
    off = kl + ku
    for j in range(j0, n):
        km = min(kl, n - 1 - j)
        p = j
        best = abs(ab[off, j])
        for i in range(1, km + 1):
            v = abs(ab[off + i, j])
            if v > best:
                best = v
                p = j + i
        piv[j] = p
        if ab[off + p - j, j] == 0.0:
            return False
        last = min(j + kl + ku, n - 1)
        if p != j:
            for c in range(j, last + 1):
                tmp = ab[off + j - c, c]
                ab[off + j - c, c] = ab[off + p - c, c]
                ab[off + p - c, c] = tmp
        rpiv = 1.0 / ab[off, j]  # as gbtf2: scaled by the reciprocal of the pivot
        for i in range(1, km + 1):
            ab[off + i, j] *= rpiv
        for c in range(j + 1, last + 1):
            f = ab[off + j - c, c]
            if f != 0.0:
                for i in range(1, km + 1):
                    ab[off + j + i - c, c] -= ab[off + i, j] * f
    return True


@njit(cache=True)
def _band_solve(ab, n, kl, ku, piv, b):
    """gbtrs (in place), on a factorisation whose diagonal holds the reciprocals of the
    pivots and whose ``U`` is scaled by them (:func:`_diagonal`): ``x = U'^{-1} D^{-1}
    L^{-1} P b``, no division and one product per column on the back substitution's chain of
    dependencies. A chain's band (``kl = ku = 2``) goes through
    :func:`_band_solve22`."""
    if kl == 2 and ku == 2:
        _band_solve22(ab, n, piv, b)
    else:
        _band_solve_any(ab, n, kl, ku, piv, b)


@njit(cache=True, fastmath={"contract"})
def _band_solve_any(ab, n, kl, ku, piv, b):
    """:func:`_band_solve` for any band."""
    off = kl + ku
    for j in range(n):
        km = min(kl, n - 1 - j)
        p = piv[j]
        if p != j:
            tmp = b[j]
            b[j] = b[p]
            b[p] = tmp
        bj = b[j]
        if bj != 0.0:
            for i in range(1, km + 1):
                b[j + i] -= ab[off + i, j] * bj
        b[j] = bj * ab[off, j]  # D^{-1}: off the back substitution's chain
    for j in range(n - 1, -1, -1):
        bj = b[j]
        if bj != 0.0:
            for i in range(max(0, j - off), j):
                b[i] -= ab[off + i - j, j] * bj


@njit(cache=True, fastmath={"contract"}, boundscheck=False)
def _band_solve22(ab, n, piv, b):
    """:func:`_band_solve` for ``kl = ku = 2`` with the window of ``b`` that a column touches
    held in registers (the substitutions are chains of dependencies: no store and reload of
    ``b`` on them) and the row interchange as selects: the same operations in the same order
    (a zero entry of ``b`` is not skipped: its products are exact zeros, the factors finite)."""
    # forward, L: b0, b1, b2 = b[j], b[j + 1], b[j + 2]
    b0 = b[0] if n > 0 else 0.0
    b1 = b[1] if n > 1 else 0.0
    b2 = b[2] if n > 2 else 0.0
    for j in range(n):
        p = piv[j] - j
        t = b0
        b0 = b1 if p == 1 else (b2 if p == 2 else b0)
        b1 = t if p == 1 else b1
        b2 = t if p == 2 else b2
        b[j] = b0 * ab[4, j]  # D^{-1}: off the back substitution's chain
        if j + 1 < n:
            b1 -= ab[5, j] * b0
        if j + 2 < n:
            b2 -= ab[6, j] * b0
        b0 = b1
        b1 = b2
        b2 = b[j + 3] if j + 3 < n else 0.0
    # backward, U' (unit diagonal, rows scaled by _diagonal): r0..r4 = b[j], ..., b[j - 4]
    r0 = b[n - 1] if n > 0 else 0.0
    r1 = b[n - 2] if n > 1 else 0.0
    r2 = b[n - 3] if n > 2 else 0.0
    r3 = b[n - 4] if n > 3 else 0.0
    r4 = b[n - 5] if n > 4 else 0.0
    for j in range(n - 1, -1, -1):
        x = r0
        b[j] = x
        r1 -= ab[3, j] * x
        r2 -= ab[2, j] * x
        r3 -= ab[1, j] * x
        r4 -= ab[0, j] * x
        r0 = r1
        r1 = r2
        r2 = r3
        r3 = r4
        r4 = b[j - 5] if j >= 5 else 0.0


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
    # k = argmax |row| (the first largest, as np.argmax)
    k = 0
    big = abs(row[0])
    for c in range(1, m):
        if abs(row[c]) > big:
            big = abs(row[c])
            k = c
    ck = col_pos[k]
    nnz = rows.shape[0]
    if lay[0] == k:
        kl = lay[1]
        ku = lay[2]
        ins = lay[3]
        row_pos = lay_rp
    else:
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


@njit(cache=True, inline="always")
def _within(sq, lengths, atol, tight):
    """``(max |sqrt(sq) - L| <= atol, ... <= tight)`` (a NaN is within neither) as counts of
    the bars outside: no data-dependent branch, so the loop vectorises."""
    over_a = 0
    over_t = 0
    for a in range(lengths.shape[0]):
        r = abs(math.sqrt(sq[a]) - lengths[a])
        over_a += not (r <= atol)
        over_t += not (r <= tight)
    return over_a == 0, over_t == 0


@njit(cache=True, inline="always")
def _strained(sq, lengths, strain_tol):
    """``max |sqrt(sq) - L| / L > strain_tol`` (a NaN strains), without a branch per bar."""
    over = 0
    for a in range(lengths.shape[0]):
        over += not (abs(math.sqrt(sq[a]) - lengths[a]) / lengths[a] <= strain_tol)
    return over > 0


@njit(cache=True, boundscheck=False, inline="always")
def _gap(sq, targets, pos, rhs):
    """``rhs[pos] = -(sq - targets)``; returns ``|sq - targets|^2`` (four partial sums: the
    additions are not one chain of dependencies)."""
    ea = sq.shape[0]
    s0 = 0.0
    s1 = 0.0
    s2 = 0.0
    s3 = 0.0
    a = 0
    while a + 4 <= ea:
        g0 = sq[a] - targets[a]
        g1 = sq[a + 1] - targets[a + 1]
        g2 = sq[a + 2] - targets[a + 2]
        g3 = sq[a + 3] - targets[a + 3]
        rhs[pos[a]] = -g0
        rhs[pos[a + 1]] = -g1
        rhs[pos[a + 2]] = -g2
        rhs[pos[a + 3]] = -g3
        s0 += g0 * g0
        s1 += g1 * g1
        s2 += g2 * g2
        s3 += g3 * g3
        a += 4
    while a < ea:
        g0 = sq[a] - targets[a]
        rhs[pos[a]] = -g0
        s0 += g0 * g0
        a += 1
    return (s0 + s1) + (s2 + s3)


@njit(cache=True, boundscheck=False, inline="always")
def _dot_gather(d, b, col_pos):
    """``sum_c d[c] b[col_pos[c]]`` in four partial sums."""
    m = d.shape[0]
    s0 = 0.0
    s1 = 0.0
    s2 = 0.0
    s3 = 0.0
    c = 0
    while c + 4 <= m:
        s0 += d[c] * b[col_pos[c]]
        s1 += d[c + 1] * b[col_pos[c + 1]]
        s2 += d[c + 2] * b[col_pos[c + 2]]
        s3 += d[c + 3] * b[col_pos[c + 3]]
        c += 4
    while c < m:
        s0 += d[c] * b[col_pos[c]]
        c += 1
    return (s0 + s1) + (s2 + s3)


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
