"""The regions of a slice (for :mod:`.critical_values`): the curves in the plane of the two lengths.

The box is rasterised at ``resolution``; cells crossed by a curve separate the rest, which is
split into 4-connected regions; each region is sampled at the cell farthest from every curve and
explored there: its number of components (0 where empty) and a ``signature`` (component count
and the sorted rotor windings) tell topologies apart. The polyline helpers (distance, clipping to
the box, coincident curves) serve the tracing too.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from engine.design.region_labels import (
    RegionLabel,
    derived_label,
    label_region,
    label_signature,
)
from engine.design.slice_curves import Axis
from engine.design.sweep_rules import derive
from engine.model.budget import NEVER, Argument, Deadline
from engine.model.linkage import Linkage
from engine.model.tolerances import CELL_EDGE_TOL, NORM_FLOOR, Tolerances
from engine.space.configuration_space import SpaceOptions, explore


@dataclass(frozen=True)
class Region:
    point: tuple[float, float]
    components: int | None  # None: not explored before the deadline
    signature: str
    cells: int
    #: what proves ``components`` exact (the exploration's argument: "derived" or "proved");
    #: None: a lower bound (or not explored)
    argument: Argument | None = None
    #: tau signs of the four-bar cells, gated, winding patterns (:mod:`.region_labels`)
    label: RegionLabel | None = None


#: Seconds per bar of the chain rules' derivation of a region's label (``derive`` and
#: ``derived_label``, vectorised over the cells: 40,000 bars in 0.3-0.5 s), doubled.
DERIVE_SECONDS_PER_BAR = 2.5e-5


def _signature(linkage: Linkage, lengths: np.ndarray, options: SpaceOptions,
               tol: Tolerances, deadline: Deadline = NEVER, axes: tuple[str, ...] = ()
               ) -> tuple[int, str, Argument | None, RegionLabel]:
    at = linkage.with_lengths(lengths)
    # where the chain rules give the count and every component's rotor turns, nothing is traced
    # (a gated chain's region took 0.4-0.7 s of exploration, 6 regions most of a 4 s budget)
    # (about 0.5 s for 20,000 rotors: only when it fits in the time left)
    fits = DERIVE_SECONDS_PER_BAR * at.n_bars <= deadline.remaining()
    row = derive(at) if fits else None
    derived = None if row is None else derived_label(at, row, axes)
    if derived is not None:
        signature, argument = label_signature(derived, None)
        return derived.components, signature, argument, derived
    # the components only: no near misses (where the closed form or the chain rules certify
    # that there is no critical point, the critical-point search is then skipped)
    res = explore(at, tol, options, start_on_space=False, near_misses=False, deadline=deadline)
    label = label_region(at, res, axes)
    signature, argument = label_signature(label, res)
    return label.components, signature, argument, label


def _polyline_distance(points: np.ndarray, line: np.ndarray) -> np.ndarray:
    """Distance of each point (n, 2) to the polyline ``line`` (m, 2)."""
    a, b = line[:-1], line[1:]
    ab = b - a
    denom = np.maximum(np.einsum("ij,ij->i", ab, ab), NORM_FLOOR)
    rel = points[:, None, :] - a[None, :, :]
    s = np.clip(np.einsum("kij,ij->ki", rel, ab) / denom, 0.0, 1.0)
    foot = a[None, :, :] + s[:, :, None] * ab[None, :, :]
    return np.min(np.linalg.norm(points[:, None, :] - foot, axis=2), axis=1)


def _on_polyline(p: np.ndarray, d: np.ndarray | None, line: np.ndarray, atol: float,
                 same_way: float = 0.2) -> bool:
    """``p`` (2,) lies within ``atol`` of a segment of ``line`` (m, 2) that runs along ``d``
    (2,; ``|sin|`` of the angle at most ``same_way``; None: any segment)."""
    a, b = line[:-1], line[1:]
    ab = b - a
    denom = np.maximum(np.einsum("ij,ij->i", ab, ab), NORM_FLOOR)
    s = np.clip(np.einsum("ij,ij->i", p - a, ab) / denom, 0.0, 1.0)
    near = np.linalg.norm(a + s[:, None] * ab - p, axis=1) <= atol
    if d is None or not near.any():
        return bool(near.any())
    seg = ab[near] / np.sqrt(denom[near])[:, None]
    sine = np.abs(seg[:, 0] * d[1] - seg[:, 1] * d[0]) / max(float(np.linalg.norm(d)), 1e-300)
    return bool((sine <= same_way).any())


def _merge_coincident(curves: list[np.ndarray], atol: float) -> list[np.ndarray]:
    """Drop a curve lying on another one: two sheets of the critical value set can project onto
    the same line of the slice (a self-intersection of the set); the slice draws it once."""
    kept: list[np.ndarray] = []
    for c in sorted(curves, key=len, reverse=True):
        if not any(np.all(_polyline_distance(c, k) <= atol) for k in kept):
            kept.append(c)
    return kept


def _clip(points: np.ndarray, box: np.ndarray) -> np.ndarray:
    """The part of a polyline inside the box, cut exactly where it crosses the boundary (the
    crossing point is interpolated on the segment that crosses; the traced curve ends one
    step outside the box)."""
    lo, hi = box[:, 0], box[:, 1]

    def inside(q: np.ndarray) -> bool:
        return bool(np.all(q >= lo - 1e-12) and np.all(q <= hi + 1e-12))

    def crossing(a: np.ndarray, b: np.ndarray) -> np.ndarray:
        # largest s in [0, 1] keeping a + s (b - a) in the box (a inside)
        s = 1.0
        d = b - a
        for k in range(2):
            if d[k] > 0:
                s = min(s, (hi[k] - a[k]) / d[k])
            elif d[k] < 0:
                s = min(s, (lo[k] - a[k]) / d[k])
        return a + max(s, 0.0) * d

    out: list[np.ndarray] = []
    for k, q in enumerate(points):
        if inside(q):
            if k > 0 and not inside(points[k - 1]) and not out:
                out.append(crossing(q, points[k - 1]))
            out.append(q)
        elif out and inside(points[k - 1]):
            out.append(crossing(points[k - 1], q))
            break
    return np.array(out).reshape(-1, 2)


def _blocked_cells(curves: list[np.ndarray], box: np.ndarray, n: int) -> np.ndarray:
    """The (n, n) raster cells the curves cross: every segment sampled at a quarter of a cell
    (``steps + 1`` points ``a + s (b - a)``, ``s = 0, 1/steps, .., 1``), all segments at once;
    a sample on a cell's edge (within ``CELL_EDGE_TOL`` cells) blocks the cells on both sides."""
    blocked = np.zeros((n, n), dtype=bool)
    if not curves:
        return blocked
    span = box[:, 1] - box[:, 0]
    a = np.concatenate([c[:-1] for c in curves])  # (S, 2) segment starts
    b = np.concatenate([c[1:] for c in curves])
    steps = (np.ceil(4 * np.max(np.abs(b - a) / span, axis=1) * n)).astype(int) + 1  # (S,)
    seg = np.repeat(np.arange(len(a)), steps + 1)
    first = np.concatenate([[0], np.cumsum(steps + 1)[:-1]])
    s = (np.arange(len(seg)) - first[seg]) / steps[seg]  # (N,) in [0, 1] per segment
    q = (a[seg] + s[:, None] * (b[seg] - a[seg]) - box[:, 0]) / span * n
    # a sample within CELL_EDGE_TOL of a cell's edge blocks the cells on both sides (at a
    # corner all four): no cell depends on how the sample was rounded
    lo = np.clip(np.floor(q - CELL_EDGE_TOL).astype(int), 0, n - 1)
    hi = np.clip(np.floor(q + CELL_EDGE_TOL).astype(int), 0, n - 1)
    for i in (lo[:, 0], hi[:, 0]):
        for j in (lo[:, 1], hi[:, 1]):
            blocked[i, j] = True
    return blocked


#: Curves closer than this many raster cells, running alike (``|sin|`` of their angle at most
#: ``THIN_SAME_WAY``) and not meeting there, may hold a region the raster loses between them.
THIN_CELLS = 1.5
THIN_SAME_WAY = 0.3
#: The finer raster (``THIN_REFINE`` times the resolution, at most ``THIN_FINE_MAX`` cells a
#: side) that thin regions are looked for in.
THIN_REFINE = 8
THIN_FINE_MAX = 1600


def _close_pairs(curves: list[np.ndarray], cell: float, deadline: Deadline = NEVER
                 ) -> list[np.ndarray]:
    """Points (2,) midway between two curves (or two parts of one) that run alike closer than
    ``THIN_CELLS`` cells without crossing: one per run of such samples along a curve."""
    out: list[np.ndarray] = []
    reach = THIN_CELLS * cell
    lo = [c.min(axis=0) - reach for c in curves]
    hi = [c.max(axis=0) + reach for c in curves]
    for i, c in enumerate(curves):
        d_c = np.gradient(c, axis=0) if len(c) >= 2 else np.zeros_like(c)
        d_c /= np.maximum(np.linalg.norm(d_c, axis=1, keepdims=True), NORM_FLOOR)
        for j in range(i, len(curves)):
            if deadline.expired():
                return out
            if len(c) < 2 or len(curves[j]) < 2 or np.any(lo[j] > hi[i]) or \
                    np.any(lo[i] > hi[j]):
                continue
            near, foot, u = _nearest_segments(c, curves[j], reach if j == i else None)
            close = np.flatnonzero((near < reach) & (np.abs(u[:, 0] * d_c[:, 1] - u[:, 1]
                                                           * d_c[:, 0]) <= THIN_SAME_WAY))
            off = c - foot
            side = np.sign(u[:, 0] * off[:, 1] - u[:, 1] * off[:, 0])
            for run in np.split(close, np.flatnonzero(np.diff(close) > 1) + 1):
                if len(run) and len(set(side[run].tolist()) - {0.0}) == 1:  # (crossing: no strip)
                    k = run[len(run) // 2]
                    out.append(0.5 * (c[k] + foot[k]))
    return out


def _nearest_segments(points: np.ndarray, line: np.ndarray, skip: float | None,
                      chunk: int = 256) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """For each point (n, 2): the distance to the nearest segment of ``line`` (m, 2), the
    nearest point on it and the segment's unit direction, in chunks of points (memory
    ``chunk * m``). ``skip``: ``points`` is ``line`` itself, and segments within ``3 skip``
    along it are left out."""
    a, b = line[:-1], line[1:]
    ab = b - a
    denom = np.maximum(np.einsum("ij,ij->i", ab, ab), NORM_FLOOR)
    step = float(np.median(np.sqrt(denom)))
    near = np.full(len(points), np.inf)
    foot = np.zeros_like(points)
    unit = np.zeros_like(points)
    for s0 in range(0, len(points), chunk):
        pts = points[s0:s0 + chunk]
        rel = pts[:, None, :] - a[None]
        s = np.clip(np.einsum("kij,ij->ki", rel, ab) / denom, 0.0, 1.0)
        f = a[None] + s[:, :, None] * ab[None]
        dist = np.linalg.norm(pts[:, None, :] - f, axis=2)
        if skip is not None:
            along = np.abs(np.arange(s0, s0 + len(pts))[:, None] - np.arange(len(ab))[None])
            dist = np.where(along * step > 3 * skip, dist, np.inf)
        seg = np.argmin(dist, axis=1)
        rows = np.arange(len(pts))
        near[s0:s0 + len(pts)] = dist[rows, seg]
        foot[s0:s0 + len(pts)] = f[rows, seg]
        unit[s0:s0 + len(pts)] = ab[seg] / np.sqrt(denom[seg])[:, None]
    return near, foot, unit


def _thin_points(curves: list[np.ndarray], box: np.ndarray, n: int, free: np.ndarray,
                 deadline: Deadline = NEVER) -> tuple[list[np.ndarray], int]:
    """Sample points of the regions narrower than a raster cell, and how many places where
    curves run closer than a cell of the finer raster remain unresolved. In the raster
    ``THIN_REFINE`` times finer (at most ``THIN_FINE_MAX`` cells a side), every piece of free
    cells (4-connected, as the raster's: a diagonal step may cross a curve) that holds no free
    cell of the coarse raster (``free``, (n, n)) is a thin region (a strip between close
    curves, a corner cut off by a curve), sampled at its cell
    farthest from the curves; a point midway between two curves that run alike closer than
    ``THIN_CELLS`` cells (:func:`_close_pairs`) on a blocked fine cell is unresolved."""
    if not curves:
        return [], 0
    span = box[:, 1] - box[:, 0]
    k = max(2, min(THIN_REFINE, THIN_FINE_MAX // n))
    fine_free = ~_blocked_cells(curves, box, k * n)
    labels, count = ndimage.label(fine_free)
    coarse = np.repeat(np.repeat(free, k, axis=0), k, axis=1)
    wide = np.zeros(count + 1, dtype=bool)
    wide[np.unique(labels[coarse & fine_free])] = True
    wide[0] = True
    points = []
    thin = np.flatnonzero(~wide)
    if len(thin):
        dist = ndimage.distance_transform_edt(fine_free)
        best = ndimage.maximum_position(dist, labels, thin)
        points = [box[:, 0] + span * (np.array(ij) + 0.5) / (k * n) for ij in best]
    pairs = _close_pairs(curves, float(max(span)) / n, deadline)
    cells = [tuple(np.clip(((q - box[:, 0]) / span * k * n).astype(int), 0, k * n - 1))
             for q in pairs]
    return points, sum(int(labels[c]) == 0 for c in cells)


def _regions(
    linkage: Linkage,
    ax: tuple[Axis, Axis],
    box: np.ndarray,
    curves: list[np.ndarray],
    resolution: int,
    opt: SpaceOptions,
    tol: Tolerances,
    deadline: Deadline = NEVER,
) -> tuple[list[Region], int]:
    """The regions (the raster's, then those thinner than a cell, with ``cells = 0``) and
    how many places where curves run closer than a cell of the finer raster are unresolved."""
    n = resolution
    span = box[:, 1] - box[:, 0]
    blocked = _blocked_cells(curves, box, n)
    labels, count = ndimage.label(~blocked)
    dist = ndimage.distance_transform_edt(~blocked)
    # pieces of the raster that the finer raster joins are one region (a strip about a cell
    # wide breaks into cells at the raster; between the same curves it is one region)
    k = max(2, min(THIN_REFINE, THIN_FINE_MAX // n))
    fine = ndimage.label(~_blocked_cells(curves, box, k * n))[0] if curves else None
    group: dict[int, list[int]] = {}
    keys = np.zeros(count)
    if fine is not None and count:  # each piece's fine label (at its cells' centres)
        centre = fine[k // 2::k, k // 2::k]  # (n, n)
        keys = np.asarray(ndimage.maximum(centre, labels, np.arange(1, count + 1)))
    for r in range(1, count + 1):
        group.setdefault(int(keys[r - 1]) or -r, []).append(r)
    samples = []
    for members in group.values():
        cells = np.isin(labels, members)
        idx = np.unravel_index(int(np.argmax(np.where(cells, dist, -1))), cells.shape)
        samples.append((box[:, 0] + span * (np.array(idx) + 0.5) / n, int(cells.sum())))
    thin, unresolved = _thin_points(curves, box, n, ~blocked, deadline)
    samples += [(q, 0) for q in thin]
    out = []
    for k, (point, size) in enumerate(samples):
        lengths = linkage.lengths.copy()
        lengths[ax[0].bar], lengths[ax[1].bar] = point
        where = (float(point[0]), float(point[1]))
        if deadline.expired():
            out.append(Region(where, None, "not explored (time)", size))
            continue
        deadline.report(0.6 + 0.4 * (k + 1) / len(samples),
                        "critical values: exploring the regions")
        comps, sig, argument, label = _signature(linkage, lengths, opt, tol, deadline,
                                                 (linkage.bar_ids[ax[0].bar],
                                                  linkage.bar_ids[ax[1].bar]))
        out.append(Region(where, comps, sig, size, argument, label))
    return out, unresolved
