"""Band LU and solve of the compiled tracer (:mod:`engine.space._trace_numba`), as LAPACK's
``gbtrf``/``gbtrs`` without blocking.

Matrices are in LAPACK band storage: ``ab[kl + ku + i - j, j] = A[i, j]`` with ``kl`` extra
leading rows for the fill of partial pivoting. A chain's band (``kl = ku = 2``) has unrolled
kernels of its own (:func:`_band_lu22`, :func:`_band_solve22`), checked bit for bit against
the loops for any band.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


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
