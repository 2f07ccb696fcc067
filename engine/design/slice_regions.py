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

from engine.design.region_labels import RegionLabel, label_region, label_signature
from engine.design.slice_curves import Axis
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


def _signature(linkage: Linkage, lengths: np.ndarray, options: SpaceOptions,
               tol: Tolerances, deadline: Deadline = NEVER, axes: tuple[str, ...] = ()
               ) -> tuple[int, str, Argument | None, RegionLabel]:
    at = linkage.with_lengths(lengths)
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


def _regions(
    linkage: Linkage,
    ax: tuple[Axis, Axis],
    box: np.ndarray,
    curves: list[np.ndarray],
    resolution: int,
    opt: SpaceOptions,
    tol: Tolerances,
    deadline: Deadline = NEVER,
) -> list[Region]:
    n = resolution
    span = box[:, 1] - box[:, 0]
    blocked = _blocked_cells(curves, box, n)
    labels, count = ndimage.label(~blocked)
    dist = ndimage.distance_transform_edt(~blocked)
    out = []
    for k in range(1, count + 1):
        cells = labels == k
        idx = np.unravel_index(int(np.argmax(np.where(cells, dist, -1))), cells.shape)
        point = box[:, 0] + span * (np.array(idx) + 0.5) / n
        lengths = linkage.lengths.copy()
        lengths[ax[0].bar], lengths[ax[1].bar] = point
        where = (float(point[0]), float(point[1]))
        if deadline.expired():
            out.append(Region(where, None, "not explored (time)", int(cells.sum())))
            continue
        deadline.report(0.6 + 0.4 * k / count, "critical values: exploring the regions")
        comps, sig, argument, label = _signature(linkage, lengths, opt, tol, deadline,
                                                 (linkage.bar_ids[ax[0].bar],
                                                  linkage.bar_ids[ax[1].bar]))
        out.append(Region(where, comps, sig, int(cells.sum()), argument, label))
    return out
