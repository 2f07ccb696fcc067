"""Exact robustness margins of one-loop planar dyad chains, from their closed-form critical
conditions.

A planar dyad chain (:func:`engine.space.dyads.chain_of`) places every free vertex from a rotor's
tip,
each dyad ``j`` putting its vertex at radii ``ra_j``, ``rb_j`` from two placed centres. A
self-stress ends at the last stressed dyad: its vertex is balanced only if its two bars lie on
one line, and the equal and opposite forces that the dyad then puts on its centres along that
line are balanced by the rest only if the centre distance ``d_j = |a_j - b_j|`` is stationary
along the motion of the chain before it. So the critical lengths of dyad ``j`` are::

    ra_j + rb_j = d*    or    |ra_j - rb_j| = d*,    d* a stationary value of d_j

With one dyad the chain before it is the rotor alone (radius ``r`` about pin ``p``): a centre
on the rotor's tip sits on a circle about ``p``, so ``d`` is stationary exactly where the tip is
on the line from ``p`` to the other centre ``c`` (a pin at distance ``D = |c - p|``):
``d* = D + r`` or ``|D - r|``. (A dyad between two pins has ``d = D`` throughout.) Written as
one equation per choice of signs, the critical value set is the union of the hyperplane pieces::

    s_r r + s_a ra + s_b rb = D,    s in {-1, +1}^3,  every length >= the shortest bar

and every point of every piece is critical (all vertices on the line ``p c``, which the signs
lay out). The margin is then the distance, in the adjustable lengths, to the nearest piece: per
plane a separable quadratic programme (project onto the plane, lengths bounded below), solved
exactly from its KKT conditions. Chains of more dyads have ``d*`` as the stationary values of a
function on the configuration space of the chain before it, in general not linear in the
lengths: they are left to the multistart (:func:`engine.design.robustness.robustness`).
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

from engine.model.linkage import Linkage
from engine.space.chain_count import GENERIC_RTOL, gated_chain
from engine.space.dyads import Chain, chain_of


@dataclass(frozen=True)
class ExactMargin:
    """The nearest critical lengths: ``margin``, ``nearest`` (E,) all bars, ``critical_u``
    (M,) a critical configuration there, and how many hyperplanes were ``planes`` tried."""

    margin: float
    nearest: np.ndarray
    critical_u: np.ndarray
    planes: int


def _bar(linkage: Linkage, i: int, j: int) -> int:
    """Index of the active bar between vertices ``i`` and ``j``."""
    ends = linkage.ends
    hit = np.flatnonzero(linkage.active & (
        ((ends[:, 0] == i) & (ends[:, 1] == j)) | ((ends[:, 0] == j) & (ends[:, 1] == i))))
    return int(hit[0])


@dataclass(frozen=True)
class CriticalPlanes:
    """The critical value set of a one-dyad planar chain: the pieces
    ``normals[p] . lengths[bars] = dist`` (every length at least the shortest critical bar).

    ``bars`` (3,) are the rotor and the dyad's two bars ``(r, ra, rb)``; ``normals`` (P, 3) of
    +-1 (0 for the rotor where the dyad's centres are both pins: P = 4, else 8)."""

    bars: np.ndarray
    normals: np.ndarray
    dist: float


def critical_planes(linkage: Linkage) -> tuple[Chain, CriticalPlanes] | None:
    """The chain and the critical hyperplanes of a one-dyad planar chain (see the module
    docstring), or None when the linkage is not one.

    >>> from engine.catalogue.presets import build_preset
    >>> _, pl = critical_planes(build_preset("four-bar"))
    >>> pl.normals.shape, pl.dist
    ((8, 3), 1.0)
    """
    ch = chain_of(linkage)
    if ch is None or ch.k != 1:
        return None
    v, a, b = int(ch.vertex[0]), int(ch.a[0]), int(ch.b[0])
    bars = np.array([ch.rotor, _bar(linkage, v, a), _bar(linkage, v, b)])  # r, ra, rb
    pins = np.asarray(linkage.positions, dtype=float)
    if ch.tip in (a, b):
        c = b if a == ch.tip else a
        dist = float(np.linalg.norm(pins[c] - pins[ch.pin]))
        signs_r: tuple[float, ...] = (1.0, -1.0)
    else:  # both centres pins: d is their distance, the rotor plays no part
        dist = float(np.linalg.norm(pins[a] - pins[b]))
        signs_r = (0.0,)
    normals = np.array(list(itertools.product(signs_r, (1.0, -1.0), (1.0, -1.0))))
    return ch, CriticalPlanes(bars, normals, dist)


def gate_planes(linkage: Linkage) -> CriticalPlanes | None:
    """The critical hyperplanes of a rotor chain with the paper's gate in the lengths of the
    gate's bars ``(D, L2, L1)``: ``+-D +-L2 +-L1 = r_g`` (the gate four-bar flat), or None
    where that is not the whole critical value set in those lengths: not such a chain, the
    chain not driven from the gate rotor (its cells then have critical configurations of their
    own) or the slider's line off the gate's pin (the slider's two positions meet at
    ``D`` = its offset).

    With the chain driven from the gate rotor every other tip is balanced only with no stress
    on its bars (its two bars are never on one line), tip by tip inwards, so a self-stress
    lives on the gate rotor and the gate four-bar alone: that four-bar is flat (see
    :mod:`engine.space.chain_count`).

    >>> from engine.catalogue.presets import build_preset
    >>> pl = gate_planes(build_preset("gated-kl-chain", {"n": 3, "gate": 1}))
    >>> pl.normals.shape, pl.dist
    ((8, 3), 1.5)
    """
    parts = gated_chain(linkage)
    if parts is None or not parts.chain_driven or \
            parts.slider_offset > GENERIC_RTOL * max(parts.sides):
        return None
    ids = {b: k for k, b in enumerate(linkage.bar_ids)}
    bars = np.array([ids[b] for b in parts.gate_bars])  # D, L2, L1
    normals = np.array(list(itertools.product((1.0, -1.0), repeat=3)))
    return CriticalPlanes(bars, normals, parts.sides[1])


def project_on_plane(
    x0: np.ndarray, normal: np.ndarray, rhs: float, lower: np.ndarray
) -> np.ndarray | None:
    """The point of ``{x : normal . x = rhs, x >= lower}`` nearest to ``x0`` (Euclidean), or
    None when the set is empty.

    KKT: ``x(lam) = max(lower, x0 - lam * normal)``, and ``g(lam) = normal . x(lam)`` is
    continuous, piecewise linear and non-increasing; ``g = rhs`` is solved exactly on the piece
    between two consecutive breakpoints (where a coordinate meets its bound), or beyond the
    outermost ones where only the coordinates that are never clamped there move.

    >>> project_on_plane(np.array([1.0, 1.0]), np.array([1.0, 1.0]), 1.0, np.zeros(2))
    array([0.5, 0.5])
    """
    act = normal != 0
    if not act.any():
        return np.maximum(x0, lower) if rhs == 0.0 else None

    def x_of(lam: float) -> np.ndarray:
        return np.maximum(lower, x0 - lam * normal)

    bps = np.sort((x0 - lower)[act] / normal[act])  # x0_i - lam n_i = lower_i
    vals = np.array([float(normal @ x_of(float(t))) for t in bps])  # non-increasing
    if vals[0] >= rhs >= vals[-1]:
        k = int(np.flatnonzero(vals >= rhs)[-1])
        if k == len(bps) - 1 or vals[k] == vals[k + 1]:
            return x_of(float(bps[k]))
        lam = bps[k] + (vals[k] - rhs) * (bps[k + 1] - bps[k]) / (vals[k] - vals[k + 1])
        return x_of(float(lam))
    # left of every breakpoint the coordinates with normal > 0 move, right of them those < 0
    side, moving = (0, normal > 0) if rhs > vals[0] else (-1, normal < 0)
    slope = -float(normal[moving] @ normal[moving])
    if slope == 0.0:
        return None
    return x_of(float(bps[side] + (rhs - vals[side]) / slope))


def exact_margin(
    linkage: Linkage, adjustable: np.ndarray, min_length: float, length_atol: float
) -> ExactMargin | None:
    """Exact margin of a one-dyad planar chain (see the module docstring), or None when the
    linkage is not one.

    Parameters
    ----------
    linkage : Linkage
    adjustable : (E,) bool
        Bars whose lengths may change (over all bars; inactive ones never are).
    min_length : float
        Shortest bar of a critical configuration: shorter ones are degenerate, not critical.
    length_atol : float
        The constructed critical configuration must have every bar within this of the nearest
        lengths (a check of the construction; None when it fails).

    Returns
    -------
    ExactMargin or None
        ``margin`` is ``inf`` (with ``nearest`` the given lengths) when no piece is reachable.
    """
    found = critical_planes(linkage)
    if found is None:
        return None
    ch, pl = found
    bars, dist = pl.bars, pl.dist
    x_now = linkage.lengths[bars].astype(float)
    adj = np.asarray(adjustable, dtype=bool)[bars]
    best: tuple[float, np.ndarray, np.ndarray] | None = None
    planes = 0
    for normal in pl.normals:  # at most 8 planes
        planes += 1
        rhs = dist - float(normal[~adj] @ x_now[~adj])
        lower = np.full(int(adj.sum()), min_length)
        if np.any(x_now[~adj & (normal != 0)] < min_length):
            continue
        x_adj = project_on_plane(x_now[adj], normal[adj], rhs, lower)
        if x_adj is None:
            continue
        x = x_now.copy()
        x[adj] = x_adj
        gap = float(np.linalg.norm(x_adj - x_now[adj]))
        if best is None or gap < best[0]:
            best = (gap, x, normal)
    nearest = np.array(linkage.lengths, dtype=float)
    if best is None:
        return ExactMargin(np.inf, nearest, linkage.coordinates(), planes)
    gap, x, normal = best
    nearest[bars] = x
    u = _critical_configuration(linkage, ch, x, normal, length_atol, nearest)
    if u is None:
        return None
    return ExactMargin(gap, nearest, u, planes)


def _critical_configuration(
    linkage: Linkage, ch: Chain, x: np.ndarray, normal: np.ndarray, length_atol: float,
    nearest: np.ndarray,
) -> np.ndarray | None:
    """The critical configuration of plane ``normal . (r, ra, rb) = D`` at lengths ``x``:
    every vertex on the line from the rotor's pin ``p`` to the pin centre ``c``, each bar laid
    along it in the direction of its sign (``c - p = sum s_i x_i e``). None when a bar misses
    its length by more than ``length_atol`` (a check of the construction)."""
    pos = np.array(linkage.positions, dtype=float)
    a, b = int(ch.a[0]), int(ch.b[0])
    if ch.tip in (a, b):
        c = b if a == ch.tip else a
        first = 1 if a == ch.tip else 2  # the dyad's bar at the tip
        delta = pos[c] - pos[ch.pin]
        norm = float(np.hypot(*delta))
        e = delta / norm if norm > 0 else np.array([1.0, 0.0])
        pos[ch.tip] = pos[ch.pin] + normal[0] * x[0] * e
        pos[ch.vertex[0]] = pos[ch.tip] + normal[first] * x[first] * e
    else:  # both centres pins: the dyad lies on their line, the rotor where it is
        delta = pos[b] - pos[a]
        e = delta / float(np.hypot(*delta))
        pos[ch.vertex[0]] = pos[a] + normal[1] * x[1] * e
    error = np.max(np.abs(linkage.bar_lengths(pos)[linkage.active] - nearest[linkage.active]))
    if not error <= length_atol:
        return None
    return linkage.coordinates(pos)
