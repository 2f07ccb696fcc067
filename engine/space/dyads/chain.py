"""Planar dyad chains: the chain of a linkage, its placement on every sheet, the detection
grid shared by the closed form and the candidates, and the folds on it.

See :mod:`engine.space.dyads` for the sheets, the folds and the certificate of no critical point.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from functools import cached_property
from types import ModuleType
from typing import NamedTuple

import numpy as np

from engine.model.linkage import Linkage
from engine.model.tolerances import SAME_POINT_REL, Tolerances
from engine.space.assembly import dyad_plan, rotors
from engine.space.dyads import kernel

#: More dyads than this (2^k sheets) are left to the general tracer.
MAX_DYADS = 6
#: Angle samples of the detection grid (per sheet).
DETECT_SAMPLES = 4096
#: Samples of the dense check inside a fold's grid cell.
FOLD_CELL_SAMPLES = 33


class Decline(Exception):
    """A check of the closed form is within its margin: the general engine answers instead."""


@dataclass(frozen=True)
class Chain:
    """A rotor and the dyads that place every other free vertex (arrays over the ``k`` dyads)."""

    rotor: int
    pin: int
    tip: int
    radius: float
    vertex: np.ndarray
    a: np.ndarray
    b: np.ndarray
    ra: np.ndarray
    rb: np.ndarray
    base: np.ndarray  # (V, 2) positions of the pins (free vertices overwritten)
    pins: np.ndarray  # (P,) the vertices that no step places (neither the tip nor a dyad's)

    @property
    def k(self) -> int:
        return len(self.vertex)

    @cached_property
    def columns(self) -> np.ndarray:
        """(V,) the column of each vertex's x in the free coordinates (its y next), -1 for
        a pin (the compiled placement's layout of a walk)."""
        free = np.ones(len(self.base), bool)
        free[self.pins] = False
        return np.where(free, 2 * np.cumsum(free) - 2, -1).astype(np.int64)

    @cached_property
    def all_columns(self) -> np.ndarray:
        """(V,) the columns of :func:`place`'s positions (n, V, 2) seen as (n, 2V)."""
        return 2 * np.arange(len(self.base), dtype=np.int64)

    @cached_property
    def free_flat(self) -> np.ndarray:
        """(M,) the free coordinates' indices in the flattened positions (2V,)."""
        free = np.ones((len(self.base), 2), bool)
        free[self.pins] = False
        return np.flatnonzero(free)

    @cached_property
    def no_flat(self) -> np.ndarray:
        """(0, k) bool: no dyad forced flat (the compiled placement's "none")."""
        return np.zeros((0, self.k), bool)

    @cached_property
    def consts(self) -> np.ndarray:
        """Per dyad (k, 6): ``(ra + rb)^2``, ``(ra - rb)^2``, ``ra * ra``, ``rb * rb``,
        ``4 ra^2 rb^2`` and 0, each by the expression :func:`_place` evaluates (the compiled
        kernel's constants)."""
        out = np.zeros((self.k, 6))
        for j in range(self.k):
            ra, rb = self.ra[j], self.rb[j]
            out[j, :5] = ((ra + rb) ** 2, (ra - rb) ** 2, ra * ra, rb * rb,
                          4.0 * ra * ra * rb * rb)
        return out


def chain_of(linkage: Linkage) -> Chain | None:
    """The first rotor whose dyad plan places every free vertex with exactly the active bars
    (circle-circle steps only, no sliders, at most :data:`MAX_DYADS` dyads), or None
    (:func:`chains_of`'s first)."""
    return next(chains_of(linkage), None)


def chains_of(linkage: Linkage) -> Iterator[Chain]:
    """Every rotor's chain, in bar order, whose dyad plan places every free vertex with exactly
    the active bars (circle-circle steps only, no sliders, at most :data:`MAX_DYADS` dyads).

    Such a plan places every free vertex but the rotor's tip, one dyad each, with two active
    bars each and the rotor: a linkage with more free vertices or another count of active bars
    has none, decided in O(V + E) before any plan is made (a plan per rotor of a long chain
    cost seconds before the search's deadline was first looked at)."""
    if linkage.dimension != 2:
        return
    fixed = np.asarray(linkage.fixed)
    full: np.ndarray = np.asarray(fixed.all(axis=1), dtype=bool)
    if not np.all(full | ~fixed.any(axis=1)):
        return  # sliders: left to the general engine
    dyads = int((~full).sum()) - 1
    if not 0 <= dyads <= MAX_DYADS or int(np.count_nonzero(linkage.active)) != 2 * dyads + 1:
        return
    active = Counter(tuple(sorted((int(i), int(j)))) for i, j in linkage.ends[linkage.active])
    for rotor in rotors(linkage):
        plan = dyad_plan(linkage, rotor)
        if plan is None or len(plan) > MAX_DYADS or any(s.axis >= 0 or s.b < 0 for s in plan):
            continue
        pin, tip = (int(x) for x in linkage.ends[rotor])
        if not full[pin]:
            pin, tip = tip, pin
        used = Counter([tuple(sorted((pin, tip)))])
        for s in plan:
            used[tuple(sorted((s.vertex, s.a)))] += 1
            used[tuple(sorted((s.vertex, s.b)))] += 1
        if used != active:
            continue  # an extra or missing bar: not a plain dyad chain
        yield Chain(
            rotor=rotor, pin=pin, tip=tip, radius=float(linkage.lengths[rotor]),
            vertex=np.array([s.vertex for s in plan], dtype=int),
            a=np.array([s.a for s in plan], dtype=int),
            b=np.array([s.b for s in plan], dtype=int),
            ra=np.array([s.ra for s in plan]), rb=np.array([s.rb for s in plan]),
            base=np.array(linkage.positions, dtype=float),
            pins=np.setdiff1d(np.arange(linkage.n_vertices),
                              [tip, *(s.vertex for s in plan)]),
        )


#: Samples placed per block: every temporary of a block (64 KB per array) stays in the cache,
#: where arrays of all the samples at once (a dense walk: 10^5) would each be fresh memory.
PLACE_BLOCK = 8192


def place(
    ch: Chain, theta: np.ndarray, signs: np.ndarray, flat: np.ndarray | None = None,
    given: dict[int, np.ndarray] | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Positions (n, V, 2), ``nu`` (n, k) and squared centre distances (n, k) at angles
    ``theta`` (n,) on sheets ``signs`` (n, k) of +-1 (or (1, k): one sheet for every angle).

    ``flat`` (n, k) bool forces a dyad's vertex onto its centres' line (its fold point, so that
    the two sheets that meet there give bitwise the same configuration). ``given = {j: v}``
    puts dyad ``j``'s vertex at ``v`` (n, 2) instead (a point of the circle it is free on where
    its centres coincide). Where ``nu < 0`` the
    vertex is put on the line too; the caller masks those samples (the loop runs over the ``k``
    dyads, at most :data:`MAX_DYADS`, each vectorised over the samples of a block of
    :data:`PLACE_BLOCK`: every operation is elementwise, so blocks change no bit).
    """
    n = len(theta)
    compiled = kernel.kernels() if given is None else None
    if compiled is not None:
        pos = np.empty((n, len(ch.base), 2))
        nu = np.empty((n, ch.k))
        d2 = np.empty((n, ch.k))
        _place_compiled(compiled, ch, theta, signs, flat, pos.reshape(n, 2 * len(ch.base)),
                        ch.all_columns,
                        nu, d2)
        return pos, nu, d2
    if n <= PLACE_BLOCK:
        return _place(ch, theta, signs, flat, given)
    pos = np.empty((n, len(ch.base), 2))
    nu = np.empty((n, ch.k))
    d2 = np.empty((n, ch.k))
    per_sample = len(signs) == n
    for lo in range(0, n, PLACE_BLOCK):
        part = slice(lo, lo + PLACE_BLOCK)
        pos[part], nu[part], d2[part] = _place(
            ch, theta[part], signs[part] if per_sample else signs,
            None if flat is None else flat[part],
            None if given is None else {j: v[part] for j, v in given.items()})
    return pos, nu, d2


def place_free(
    ch: Chain, theta: np.ndarray, signs: np.ndarray, flat: np.ndarray | None = None,
) -> np.ndarray:
    """The free coordinates (n, M) of :func:`place` (the columns of ``positions[:, free]``:
    the pins left out), without ``nu`` and ``d2``; compiled, the pins are never written."""
    n = len(theta)
    compiled = kernel.kernels()
    if compiled is None:
        return place(ch, theta, signs, flat)[0].reshape(n, 2 * len(ch.base))[:, ch.free_flat]
    out = np.empty((n, len(ch.free_flat)))
    none = np.empty((0, ch.k))
    _place_compiled(compiled, ch, theta, signs, flat, out, ch.columns, none, none)
    return out


def _place_compiled(
    compiled: ModuleType, ch: Chain, theta: np.ndarray, signs: np.ndarray,
    flat: np.ndarray | None, out: np.ndarray, cols: np.ndarray, nu: np.ndarray,
    d2: np.ndarray,
) -> None:
    """:func:`place` by the compiled kernel into ``out`` (n, C) at columns ``cols`` (V,),
    bitwise :func:`_place`: the trigonometry and the dyads' constants by numpy, the rest the
    same operations in the same order."""
    theta = np.asarray(theta, dtype=float)
    compiled.place(np.cos(theta), np.sin(theta), ch.radius,
                   np.ascontiguousarray(signs, dtype=float),
                   ch.no_flat if flat is None else np.ascontiguousarray(flat, dtype=bool),
                   ch.vertex, ch.a, ch.b, ch.consts, ch.base, ch.pin, ch.tip, ch.pins, cols,
                   out, nu, d2)


def _place(
    ch: Chain, theta: np.ndarray, signs: np.ndarray, flat: np.ndarray | None,
    given: dict[int, np.ndarray] | None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`place` on one block."""
    n = len(theta)
    # Coordinates as two (V, n) planes: every dyad step reads and writes contiguous rows (the
    # (n, V, 2) layout strides by V * 16 bytes); interleaved once at the end. The arithmetic
    # is the same, term by term, so the positions are bitwise those of the interleaved layout.
    xs = np.empty((len(ch.base), n))
    ys = np.empty((len(ch.base), n))
    xs[ch.pins] = ch.base[ch.pins, :1]  # every other row is written below
    ys[ch.pins] = ch.base[ch.pins, 1:]
    xs[ch.tip] = ch.base[ch.pin, 0] + ch.radius * np.cos(theta)
    ys[ch.tip] = ch.base[ch.pin, 1] + ch.radius * np.sin(theta)
    nu = np.empty((n, ch.k))
    d2 = np.empty((n, ch.k))
    with np.errstate(divide="ignore", invalid="ignore"):
        for j in range(ch.k):
            ra, rb = ch.ra[j], ch.rb[j]
            cx, cy = xs[ch.a[j]], ys[ch.a[j]]
            dx = xs[ch.b[j]] - cx
            dy = ys[ch.b[j]] - cy
            dd = dx**2 + dy**2
            # 4 d^2 h^2 = ((ra + rb)^2 - d^2)(d^2 - (ra - rb)^2) = 4 ra^2 rb^2 sin^2(angle at
            # v): a product of differences (no cancellation in the quartic) and no division.
            quad = ((ra + rb) ** 2 - dd) * (dd - (ra - rb) ** 2)
            inv = 0.5 / dd
            along = (dd + ra * ra - rb * rb) * inv
            hh = np.sqrt(np.maximum(quad, 0.0)) * inv * signs[:, j]
            if flat is not None:
                hh = np.where(flat[:, j], 0.0, hh)
            if given is not None and j in given:
                xs[ch.vertex[j]] = given[j][:, 0]
                ys[ch.vertex[j]] = given[j][:, 1]
            else:
                xs[ch.vertex[j]] = cx + along * dx - hh * dy
                ys[ch.vertex[j]] = cy + along * dy + hh * dx
            nu[:, j] = quad / (4.0 * ra * ra * rb * rb)
            d2[:, j] = dd
    pos = np.stack((xs.T, ys.T), axis=2)  # (n, V, 2), C order: one interleaving pass
    return pos, nu, d2


def sheets_of(k: int) -> np.ndarray:
    """All ``2^k`` sign vectors (S, k), ``+1`` first (the first root of
    :func:`engine.space.assembly.assemblies_at`)."""
    s = np.arange(2**k)[:, None] >> np.arange(k)[None, :]
    return 1 - 2 * (s & 1)


#: The golden section's ratio, ``(sqrt(5) - 1) / 2`` (one value for :func:`golden_arg` and
#: the compiled search of :func:`engine.space.dyads.closed_form.extremum_minima`).
GOLDEN_RATIO = float((np.sqrt(5.0) - 1.0) / 2.0)


def golden(
    f: Callable[[np.ndarray], np.ndarray], lo: np.ndarray, hi: np.ndarray, iters: int = 60
) -> np.ndarray:
    """Vectorised golden-section minimisation of ``f`` (arrays in, arrays out) on each
    ``[lo, hi]``; returns the smallest value seen per bracket (ends included)."""
    return golden_arg(f, lo, hi, iters)[0]


def golden_arg(
    f: Callable[[np.ndarray], np.ndarray], lo: np.ndarray, hi: np.ndarray, iters: int = 60
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_golden` with the argument of the smallest value seen: ``(value, argument)``."""
    g = GOLDEN_RATIO
    a, b = lo.copy(), hi.copy()
    c, d = b - g * (b - a), a + g * (b - a)
    fa, fb, fc, fd = f(a), f(b), f(c), f(d)
    best = np.minimum(fa, fb)
    arg = np.where(fa <= fb, a, b)

    def keep(x: np.ndarray, fx: np.ndarray) -> None:
        nonlocal best, arg
        better = fx < best
        best, arg = np.where(better, fx, best), np.where(better, x, arg)

    keep(c, fc)
    keep(d, fd)
    for _ in range(iters):
        left = fc < fd
        b = np.where(left, d, b)
        a = np.where(left, a, c)
        c_new = b - g * (b - a)
        d_new = a + g * (b - a)
        c, d = np.where(left, c_new, d), np.where(left, c, d_new)
        x_new = np.where(left, c, d)
        fc_new = f(x_new)
        fc, fd = np.where(left, fc_new, fd), np.where(left, fc, fc_new)
        keep(x_new, fc_new)
    return best, arg


class Extrema(NamedTuple):
    mask: np.ndarray
    prev_nu: np.ndarray
    next_nu: np.ndarray
    prev_ok: np.ndarray
    next_ok: np.ndarray


def discrete_extrema(nu: np.ndarray, prefix: np.ndarray, axis: int) -> Extrema:
    """Samples (along the periodic ``axis`` of the angle grid) where ``nu`` is a discrete
    minimum of a positive run or a maximum of a negative run, with the neighbours' values and
    whether they are defined (``prefix``); at the end of a prefix run only one neighbour exists,
    so one-sided extrema count too."""
    prev_nu, next_nu = np.roll(nu, 1, axis=axis), np.roll(nu, -1, axis=axis)
    prev_ok, next_ok = np.roll(prefix, 1, axis=axis), np.roll(prefix, -1, axis=axis)
    pos_min = (nu > 0) & (nu <= prev_nu) & (nu <= next_nu)
    neg_max = (nu < 0) & (nu >= prev_nu) & (nu >= next_nu)
    pos_min |= (nu > 0) & ((~prev_ok & (nu <= next_nu)) | (~next_ok & (nu <= prev_nu)))
    neg_max |= (nu < 0) & ((~prev_ok & (nu >= next_nu)) | (~next_ok & (nu >= prev_nu)))
    return Extrema(pos_min | neg_max, prev_nu, next_nu, prev_ok, next_ok)


@dataclass(frozen=True)
class Sampled:
    """Every sheet of a dyad chain on the detection grid (shared by the closed form and the
    critical-point candidates, so both see the same grid): ``nu`` and ``d2`` (sheets, n, k),
    ``prefix[s, i, j]`` (dyads before ``j`` assembled, so ``nu_j`` is defined there), the margin
    ``tau`` and the report so far; ``problem`` says why the closed form cannot be used."""

    k: int
    scale: float
    tau: float
    n: int
    dth: float
    grid: np.ndarray
    sheets: np.ndarray
    nu: np.ndarray
    d2: np.ndarray
    pos_nu: np.ndarray
    prefix: np.ndarray
    report: dict[str, object]
    problem: str | None


def sample_sheets(linkage: Linkage, ch: Chain, tol: Tolerances, samples: int) -> Sampled:
    k = ch.k
    scale = float(np.median(linkage.lengths[linkage.active]))
    tau = float(np.clip(1e4 * tol.residual_atol / scale, 1e-10, 1e-3))
    n = int(samples)
    dth = 2 * np.pi / n
    offset = (np.sqrt(5) - 1) / 2  # irrational offset: symmetric angles are often special
    grid = dth * (np.arange(n) + offset)
    sheets = sheets_of(k)
    n_sheets = len(sheets)
    report: dict[str, object] = {
        "rotor": linkage.bar_ids[ch.rotor], "dyads": k, "sheets": n_sheets,
        "samples": n, "margin": tau,
    }
    _, nu, d2 = place(ch, np.tile(grid, n_sheets), np.repeat(sheets, n, axis=0))
    nu = nu.reshape(n_sheets, n, k)
    d2 = d2.reshape(n_sheets, n, k)
    pos_nu = nu > 0
    prefix = np.concatenate(
        [np.ones((n_sheets, n, 1), bool), np.cumprod(pos_nu, axis=2)[:, :, :-1].astype(bool)],
        axis=2,
    )
    problem = None
    if not (np.isfinite(scale) and np.all(np.isfinite(nu)) and np.all(np.isfinite(d2))):
        problem = "non-finite values (coordinates or lengths too large)"
    elif np.any(prefix & (d2 <= (SAME_POINT_REL * scale) ** 2)):
        # centres that coincide make a dyad's vertex free on a circle
        problem = "a dyad's centres (nearly) coincide"
    return Sampled(k, scale, tau, n, dth, grid, sheets, nu, d2, pos_nu, prefix, report, problem)


def bisect_folds(
    nu_at: Callable[[np.ndarray], np.ndarray], lo: np.ndarray, hi: np.ndarray, dyad: np.ndarray
) -> np.ndarray:
    """The fold angle in each bracket: the last angle where ``nu`` of ``dyad`` is positive,
    bisected to the last bit from ``lo`` (inside: positive) and ``hi`` (outside);
    ``nu_at(theta)`` gives ``nu`` (n, k) at the angles."""
    rows = np.arange(len(lo))
    lo, hi = lo.copy(), hi.copy()
    for _ in range(64):
        mid = 0.5 * (lo + hi)
        inside = nu_at(mid)[rows, dyad] > 0
        lo, hi = np.where(inside, mid, lo), np.where(inside, hi, mid)
    return lo


@dataclass(frozen=True)
class Folds:
    """Every fold of a sampled chain: where a sheet's run of assembled samples ends.

    ``ends`` lists ``(sheet, inside index, outside index, -1 at a run's start / +1 at its end)``;
    per fold (arrays): ``sheet``, ``inside``, ``direction``, the ``dyad`` that stops assembling,
    its angle ``star``, the ``slope`` of that dyad's ``nu`` there (transversality), and the
    fold's grid cell sampled densely: angles ``cell`` (F, FOLD_CELL_SAMPLES) and every dyad's
    ``nu`` there ``cell_nu`` (F, FOLD_CELL_SAMPLES, k; the fold's own dyad flat at the fold)."""

    ends: list[tuple[int, int, int, int]]
    sheet: np.ndarray
    inside: np.ndarray
    direction: np.ndarray
    dyad: np.ndarray
    star: np.ndarray
    slope: np.ndarray
    cell: np.ndarray
    cell_nu: np.ndarray


def run_ends(valid: np.ndarray) -> list[tuple[int, int, int, int]]:
    """``(sheet, inside, outside, -1 | +1)`` of every run of ``valid`` (S, n) samples (periodic)."""
    n = valid.shape[1]
    ends: list[tuple[int, int, int, int]] = []
    for s in range(len(valid)):
        v = valid[s]
        up = np.flatnonzero(v & ~np.roll(v, 1))  # run starts: outside is i - 1
        down = np.flatnonzero(v & ~np.roll(v, -1))  # run ends: outside is i + 1
        ends += [(s, int(i), (int(i) - 1) % n, -1) for i in up]
        ends += [(s, int(i), (int(i) + 1) % n, +1) for i in down]
    return ends


def locate_folds(ch: Chain, sm: Sampled) -> Folds | None:
    """The folds of every sheet (None where every sheet turns fully: no fold)."""
    ends = run_ends(np.asarray(sm.pos_nu.all(axis=2), dtype=bool))
    if not ends:
        return None
    e = np.array(ends)
    es, ein, eout, edir = e[:, 0], e[:, 1], e[:, 2], e[:, 3]
    jf = np.argmax(~sm.pos_nu[es, eout], axis=1)  # the first dyad that fails outside
    f_signs = sm.sheets[es]
    rows = np.arange(len(es))

    def nu_at(theta: np.ndarray) -> np.ndarray:
        return place(ch, theta, f_signs)[1]

    # the outside angle, unwrapped next to the inside one
    star = bisect_folds(nu_at, sm.grid[ein], sm.grid[ein] + edir * sm.dth, jf)
    h = 1e-3 * sm.dth
    slope = np.abs(nu_at(star + h)[rows, jf] - nu_at(star - h)[rows, jf]) / (2 * h)
    # the fold's grid cell, densely (the vertex moves like sqrt(theta - theta*) there, faster
    # than the grid resolves)
    sig = np.linspace(0.0, 1.0, FOLD_CELL_SAMPLES)
    cell = star[:, None] + (sm.grid[ein] - star)[:, None] * sig[None, :] ** 2
    rep_flat = np.zeros((cell.size, ch.k), bool)
    rep_flat[::FOLD_CELL_SAMPLES][rows, jf] = True  # sigma = 0 is the fold itself
    _, cell_nu, _ = place(ch, cell.ravel(), np.repeat(f_signs, FOLD_CELL_SAMPLES, axis=0),
                          rep_flat)
    return Folds(ends, es, ein, edir, jf, star, slope, cell,
                 cell_nu.reshape(len(es), FOLD_CELL_SAMPLES, ch.k))
