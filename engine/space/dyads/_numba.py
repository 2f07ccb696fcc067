"""numba kernels of :mod:`engine.space.dyads.kernel` (imported only when the compiled path runs).

Each kernel is the numpy code it replaces (named in its docstring) written as one loop over the
samples, with the same operations in the same order on the same operands: IEEE arithmetic,
no fused multiply-add (numba contracts only under ``fastmath``) and the trigonometry left to
numpy, so the answers are bitwise those of the numpy path. ``error_model="numpy"``: a
division by zero gives inf or nan as in numpy instead of raising.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True, error_model="numpy")
def place(cos_t, sin_t, radius, signs, flat, vertex, a, b, consts, base, pin, tip, pins, cols,
          out, nu, d2):
    """:func:`engine.space.dyads.chain._place` (``given`` None) into ``out`` (n, C): vertex ``v`` in
    columns ``cols[v]``, ``cols[v] + 1`` (or, ``cols[v] < 0``, not written and read from
    ``base``: a pin of the free walk). ``cos_t``, ``sin_t`` (n,) numpy's trigonometry of the
    angles, ``signs`` (n or 1, k) float, ``flat`` (n, k) bool or (0, k) for none, ``consts``
    (k, 6) per dyad (:attr:`engine.space.dyads.chain.Chain.consts`); fills ``nu`` and ``d2`` (n, k)
    unless they are (0, k). Dyad by dyad, each a loop over the samples with its indices and
    constants fixed (numpy's passes, fused)."""
    n = cos_t.shape[0]
    per_sample = signs.shape[0] > 1
    has_flat = flat.shape[0] > 0
    want_nu = nu.shape[0] > 0
    for p in range(pins.shape[0]):
        c = cols[pins[p]]
        if c >= 0:
            x = base[pins[p], 0]
            y = base[pins[p], 1]
            for i in range(n):
                out[i, c] = x
                out[i, c + 1] = y
    ct = cols[tip]
    px = base[pin, 0]
    py = base[pin, 1]
    for i in range(n):
        out[i, ct] = px + radius * cos_t[i]
        out[i, ct + 1] = py + radius * sin_t[i]
    for j in range(vertex.shape[0]):
        ca, cb, cv = cols[a[j]], cols[b[j]], cols[vertex[j]]
        ax, ay = base[a[j], 0], base[a[j], 1]
        bx, by = base[b[j], 0], base[b[j], 1]
        sum2, diff2, ra2, rb2, denom = (consts[j, 0], consts[j, 1], consts[j, 2],
                                        consts[j, 3], consts[j, 4])
        sign = signs[0, j] if signs.shape[0] > 0 else 1.0  # no sample: no sheet
        for i in range(n):
            cx = out[i, ca] if ca >= 0 else ax
            cy = out[i, ca + 1] if ca >= 0 else ay
            dx = (out[i, cb] if cb >= 0 else bx) - cx
            dy = (out[i, cb + 1] if cb >= 0 else by) - cy
            dd = dx * dx + dy * dy
            quad = (sum2 - dd) * (dd - diff2)
            inv = 0.5 / dd
            along = (dd + ra2 - rb2) * inv
            # np.maximum(quad, 0.0): a nan stays nan
            root = quad if (quad > 0.0 or quad != quad) else 0.0
            hh = math.sqrt(root) * inv * (signs[i, j] if per_sample else sign)
            if has_flat and flat[i, j]:
                hh = 0.0
            out[i, cv] = cx + along * dx - hh * dy
            out[i, cv + 1] = cy + along * dy + hh * dx
            if want_nu:
                nu[i, j] = quad / denom
                d2[i, j] = dd


@njit(cache=True, error_model="numpy")
def long_gaps(walk, limit, out):
    """:func:`engine.space.dyads.closed_form.long_gaps`: the ``i`` (in ``out``, how many returned)
    whose step from sample ``i`` to ``i + 1`` of ``walk`` (n, M) is longer than ``limit``
    (the squares summed column by column, then the square root)."""
    count = 0
    for i in range(walk.shape[0] - 1):
        s = 0.0
        for c in range(walk.shape[1]):
            d = walk[i + 1, c] - walk[i, c]
            s = d * d if c == 0 else s + d * d
        if math.sqrt(s) > limit:
            out[count] = i
            count += 1
    return count


@njit(cache=True, error_model="numpy")
def within_lengths(walk, base, cols, ends, low, high):
    """:func:`engine.space.dyads.closed_form.within_lengths`: every sample of ``walk`` (n, M; vertex
    ``v`` in columns ``cols[v]``, ``cols[v] + 1``, or at ``base[v]`` where ``cols[v] < 0``)
    with every bar's squared length ``dx * dx + dy * dy`` in ``[low, high]`` (per bar); a nan
    fails."""
    for e in range(ends.shape[0]):
        ci, cj = cols[ends[e, 0]], cols[ends[e, 1]]
        xi, yi = base[ends[e, 0], 0], base[ends[e, 0], 1]
        xj, yj = base[ends[e, 1], 0], base[ends[e, 1], 1]
        lo = low[e]
        hi = high[e]
        for s in range(walk.shape[0]):
            dx = (walk[s, ci] if ci >= 0 else xi) - (walk[s, cj] if cj >= 0 else xj)
            dy = (walk[s, ci + 1] if ci >= 0 else yi) - (walk[s, cj + 1] if cj >= 0 else yj)
            q = dx * dx + dy * dy
            if not (lo <= q and q <= hi):
                return False
    return True


@njit(cache=True, error_model="numpy")
def _signed_nu(t, sgn, dyad, signs, row, vertex, a, b, consts, base, pin, tip, radius, xs, ys):
    """``sgn * nu`` of dyad ``dyad`` at angle ``t`` on the sheet ``signs[row]`` (the dyads
    before it placed in ``xs``, ``ys``: the arithmetic of :func:`place`, math's trigonometry)."""
    xs[tip] = base[pin, 0] + radius * math.cos(t)
    ys[tip] = base[pin, 1] + radius * math.sin(t)
    quad = 0.0
    for j in range(dyad + 1):
        cx = xs[a[j]]
        cy = ys[a[j]]
        dx = xs[b[j]] - cx
        dy = ys[b[j]] - cy
        dd = dx * dx + dy * dy
        quad = (consts[j, 0] - dd) * (dd - consts[j, 1])
        if j == dyad:
            break
        inv = 0.5 / dd
        along = (dd + consts[j, 2] - consts[j, 3]) * inv
        root = quad if (quad > 0.0 or quad != quad) else 0.0
        hh = math.sqrt(root) * inv * signs[row, j]
        xs[vertex[j]] = cx + along * dx - hh * dy
        ys[vertex[j]] = cy + along * dy + hh * dx
    return sgn * (quad / consts[dyad, 4])


@njit(cache=True, error_model="numpy")
def golden_signed_nu(lo, hi, sgn, dyad, signs, iters, g, vertex, a, b, consts, base, pin,
                     tip, radius, best):
    """:func:`engine.space.dyads.chain.golden` of ``sgn[r] * nu`` of dyad ``dyad[r]`` on the sheet
    ``signs[r]`` over ``[lo[r], hi[r]]`` (the extrema check of
    :func:`engine.space.dyads.closed_form._check_extrema`): the same steps and comparisons, so the
    same answer to the rounding of the trigonometry (math's here, numpy's there). Fills
    ``best`` (m,), the smallest value seen per bracket (nan where numpy's would be)."""
    xs = base[:, 0].copy()
    ys = base[:, 1].copy()
    for r in range(lo.shape[0]):
        s, jj = sgn[r], dyad[r]
        aa, bb = lo[r], hi[r]
        c = bb - g * (bb - aa)
        d = aa + g * (bb - aa)
        fa = _signed_nu(aa, s, jj, signs, r, vertex, a, b, consts, base, pin, tip, radius,
                        xs, ys)
        fb = _signed_nu(bb, s, jj, signs, r, vertex, a, b, consts, base, pin, tip, radius,
                        xs, ys)
        fc = _signed_nu(c, s, jj, signs, r, vertex, a, b, consts, base, pin, tip, radius,
                        xs, ys)
        fd = _signed_nu(d, s, jj, signs, r, vertex, a, b, consts, base, pin, tip, radius,
                        xs, ys)
        # np.minimum: a nan wins; then keep(x, fx) replaces only where fx < best
        low = fa if (fa != fa or not fb < fa) else fb
        if fb != fb:
            low = fb
        if fc < low:
            low = fc
        if fd < low:
            low = fd
        for _ in range(iters):
            left = fc < fd
            if left:
                bb = d
            else:
                aa = c
            c_new = bb - g * (bb - aa)
            d_new = aa + g * (bb - aa)
            if left:
                c, d = c_new, c
                x_new = c
            else:
                c, d = d, d_new
                x_new = d
            f_new = _signed_nu(x_new, s, jj, signs, r, vertex, a, b, consts, base, pin, tip,
                               radius, xs, ys)
            if left:
                fd = fc
                fc = f_new
            else:
                fc = fd
                fd = f_new
            if f_new < low:
                low = f_new
        best[r] = low


@njit(cache=True, error_model="numpy")
def near_segments(walk, target, gap, out):
    """:func:`engine.space.configuration_space.closed_form.walk_distance`'s choice of segments: the
    ``k`` (in ``out``, how many returned) whose point ``k`` or ``k + 1`` of ``walk`` (n, M) is
    within ``(d + gap / 2) (1 + 1e-9)`` of ``target`` (``d`` the distance to the nearest point;
    squares summed column by column). A nan point makes ``d`` nan (numpy's min): none."""
    n, m = walk.shape
    d2 = np.empty(n)
    best = np.inf
    for i in range(n):
        s = 0.0
        for c in range(m):
            d = walk[i, c] - target[c]
            s = d * d if c == 0 else s + d * d
        d2[i] = s
        if best == best and (s != s or s < best):  # numpy's min: a nan wins
            best = s
    reach = (math.sqrt(best) + 0.5 * gap) * (1.0 + 1e-9)
    limit = reach * reach
    count = 0
    for k in range(n - 1):
        if d2[k] <= limit or d2[k + 1] <= limit:
            out[count] = k
            count += 1
    return count
