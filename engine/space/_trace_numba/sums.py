"""Constraints and small reductions of the compiled tracer (:mod:`engine.space._trace_numba`).

Squared bar lengths and the Jacobian's values from the gathers of
:class:`engine.model.constraints.Constraints` (straight into the band storage of :mod:`.band`
for the bordered factorisation), and the reductions of the corrector and the step control (dot
products and distances in partial sums, residual and strain tests without a branch per bar).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


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
    """engine.space.curve.segment_distance: from ``target`` to the segment ``[a, b]``."""
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
