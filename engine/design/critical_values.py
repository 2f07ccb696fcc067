"""Slices of the critical value set in two lengths, and the regions they separate.

With two bar lengths ``p = (L_x, L_y)`` free, the critical configurations solve::

    G(u, sigma, p) = [ (l^2(u) - L(p)^2) / s ;  J(u)^T sigma / s ;  |sigma|^2 - 1 ] = 0

``E + M + 1`` equations in ``M + E + 2`` unknowns: a one-dimensional solution set whose
projection on ``p`` is the slice (paper, Sec. III B). It is traced by pseudo-arclength
continuation (tangent from one factorisation of ``[DG; tau_prev]``, hyperplane Newton corrector)
until it leaves the box or closes. Seeds: every critical configuration on the box's edges and
wherever a curve turns or enters the box between them (a sweep of each axis in steps of one
raster cell), each found by homotopy (:mod:`.slice_scan`), so that every curve crossing the box
but a closed one smaller than a cell is traced;
where the homotopy's paths exceed ``options.homotopy_paths_max``, at a grid of sample lengths,
every critical configuration the exploration reaches (critical points, and the nearest critical
configurations of the near misses), projected onto ``G = 0`` from the sample lengths. The
boundaries where the configuration space becomes empty are critical values too (a component
shrinks to a rigid point) and are found the same way.

Regions: the box is rasterised at ``resolution``; cells crossed by a curve separate the rest,
which is split into 4-connected regions; each region is sampled at the cell farthest from every
curve and explored there: its number of components (0 where empty) and a ``signature``
(component count and the sorted rotor windings) tell topologies apart. Regions thinner than a
cell, between curves running close, are found in a finer raster (:mod:`.slice_regions`).

What is proved is said in the report: a slice is complete only with every curve and every
region's count exact. Its curves are every one with the closed form's curves, or with the
sweeps complete and every turning point of a curve in the box (:mod:`.slice_turning`: a
closed curve born and gone within one sweep step holds one) solved for by homotopy and lying
on a traced curve (``argument: proved``); otherwise a traced slice names its sweeps, its
turning points and its exact regions, and stays ``searched``.

This module seeds the curves and puts the slice together; ``G`` and its continuation are in
:mod:`.slice_curves`, the regions and the polyline helpers in :mod:`.slice_regions`.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from engine.design.chain_curves import flat_everywhere, two_cell_curves
from engine.design.chain_planes import chain_planes
from engine.design.dyad_margin import CriticalPlanes, critical_planes, gate_planes
from engine.design.slice_argument import _scan_details, _slice_argument
from engine.design.slice_curves import Axis, _continue, _onto_solutions_batch, _System, _tangent
from engine.design.slice_regions import (
    Region,
    _clip,
    _merge_coincident,
    _on_polyline,
    _regions,
)
from engine.design.slice_scan import Scan, ScanDirection, Scanline, scan_paths
from engine.design.slice_turning import TurningFound, turning_paths, turning_points
from engine.design.spherical_curves import SPHERICAL_CURVES, spherical_curves
from engine.design.spherical_radii import radius_curves
from engine.local.critical import refine_critical
from engine.model.budget import (
    NEVER,
    REASON_TIME,
    Deadline,
    granted,
)
from engine.model.constraints import Constraints
from engine.model.errors import InvalidRequest
from engine.model.linkage import Linkage, changeable_bar
from engine.model.report import SearchReport, count_text
from engine.model.tolerances import MIN_CRITICAL_LENGTH_ATOL, Tolerances
from engine.space.chain_count import gated_chain
from engine.space.configuration_space import SpaceOptions, find_critical_points
from engine.space.configuration_space.results import require_one_dof

#: Where in its grid cell each seed length sits, per axis: irrational and different on the two
#: axes, so that the seed grid avoids the symmetric lengths (``L_x = L_y``, ...) on which
#: critical values of symmetric linkages lie (a seed at critical lengths is the slowest and least
#: robust exploration there is; its neighbours seed the same curves from regular lengths).
GRID_OFFSET = np.array([0.5 + (np.sqrt(2.0) - 1.0) / 10.0, 0.5 - (np.sqrt(5.0) - 2.0) / 10.0])

#: A seed this close to a traced polyline (relative to the tracing step), going its way, lies on
#: that curve: a chord of a circle of radius ``R`` is within ``h^2 / (8 R)`` of it, so a curve
#: whose radius of curvature is above ``1 / (8 KNOWN_REL)`` steps is recognised.
KNOWN_REL = 0.05
#: Sine of the angle below which a seed's direction is a traced polyline's.
SAME_WAY = 0.2

#: Point budget of one curve in a seed exploration.
SEED_MAX_POINTS = 2000

#: Methods of :func:`critical_value_slice`: ``"auto"`` draws the curves of one-dyad planar
#: chains (the four-bar family), of a gated chain in its gate's lengths, of rotor chains
#: whose cells cannot combine (:mod:`.chain_planes`), of three-rotors (:mod:`.chain_curves`) and
#: of spherical four-bars (:mod:`.spherical_curves`, :mod:`.spherical_radii`)
#: from their closed forms and traces the rest;
#: ``"traced"`` always seeds and traces (the tests cross-check the two).
SLICE_METHODS = ("auto", "traced")
#: The explorations' options when a request gives none (fewer angles and random starts than a
#: configuration-space search: a slice explores one linkage per seed and per region).
SLICE_OPTIONS = SpaceOptions(angles=24, random_starts=4)


@dataclass(frozen=True)
class Slice:
    curves: list[np.ndarray]  # each (n, 2)
    regions: list[Region]
    search: SearchReport


def _validate(linkage: Linkage, axes: list[tuple[str, float, float]]) -> tuple[Axis, Axis]:
    if len(axes) != 2:
        raise InvalidRequest("give exactly two axes", loc=("axes",))
    out = []
    for k, (bar, lo, hi) in enumerate(axes):
        j = changeable_bar(linkage, bar, ("axes", k, "bar"))
        if not (0 < lo < hi and np.isfinite(hi)):
            raise InvalidRequest("need 0 < min < max", loc=("axes", k))
        out.append(Axis(j, float(lo), float(hi)))
    if out[0].bar == out[1].bar:
        raise InvalidRequest("the two axes name the same bar", loc=("axes", 1, "bar"))
    return out[0], out[1]


def _trace_from_seeds(tracing: _CurveTracing, grid: list[np.ndarray], per_column: int,
                      dl: Deadline) -> None:
    """Trace the curves reached from the seed lengths ``grid``. One column of seed lengths at a
    time: the explorations first, then all their starts onto G = 0 in one batch (a pure
    function of each start), then taken in seed order (the same curves as seed by seed; a
    deadline still leaves the earlier columns' curves)."""
    for col in range(0, len(grid), per_column):
        starts = []
        for k in range(col, min(col + per_column, len(grid))):
            if dl.expired():
                tracing.timed_out = True
                break
            dl.report(0.3 + 0.3 * k / len(grid), "critical values: tracing the curves")
            starts.append(tracing.starts_at(grid[k]))
        tracing.take(starts)
        if tracing.timed_out and dl.expired():
            break


def critical_value_slice(
    linkage: Linkage,
    axes: list[tuple[str, float, float]],
    resolution: int = 48,
    seeds_per_axis: int = 5,
    tolerances: Tolerances | None = None,
    options: SpaceOptions | None = None,
    max_curve_points: int = 4000,
    deadline: Deadline | None = None,
    *,
    method: str = "auto",
) -> Slice:
    """Curves of the critical value set in the plane of two lengths, and its regions.

    Once ``deadline`` has passed the seeding and tracing stop, and regions not yet explored
    have ``components = None``; ``search["complete"]`` is then False with ``reason "time"``.

    ``method="auto"`` takes the curves from closed-form critical lines where they are known
    (one-dyad planar chains; a gated chain in its gate's lengths; rotor chains whose four-bar
    cells cannot combine in the box; three-rotors; spherical four-bars:
    :func:`_closed_form_curves`), sampled at
    the tracing step; ``"traced"`` (and every other linkage) seeds and traces them.
    ``search["method"]`` says which (``"closed form"`` or ``"traced"``).

    Examples
    --------
    >>> from engine.catalogue.presets import build_preset
    >>> s = critical_value_slice(build_preset("four-bar", {"L2": 1.2}),
    ...                          [("L2", 0.5, 1.5), ("L3", 0.5, 1.5)], resolution=16)
    >>> len(s.regions) >= 2
    True
    """
    if method not in SLICE_METHODS:
        raise InvalidRequest(f"unknown method {method!r}: one of {', '.join(SLICE_METHODS)}",
                             loc=("method",))
    tol = tolerances or Tolerances()
    opt = options or SLICE_OPTIONS
    dl = deadline or NEVER
    ax = _validate(linkage, axes)
    # before any time is spent: a deadline must never turn "needs one degree of freedom" (a
    # 422) into a 200 with regions not explored
    require_one_dof(linkage, Constraints(linkage))
    box = np.array([[ax[0].lo, ax[0].hi], [ax[1].lo, ax[1].hi]])
    span = box[:, 1] - box[:, 0]
    h_max = float(min(span)) / resolution
    closed = _closed_form_curves(linkage, ax, box, h_max, tol) if method == "auto" else None
    lines, planes_of = closed if closed is not None else (None, "")
    # (a three-rotor's cell flat whatever the axes: critical lengths fill part of the box)
    everywhere = None if closed is not None or method != "auto" else \
        flat_everywhere(linkage, (ax[0].bar, ax[1].bar))
    lines = [] if everywhere is not None else lines
    scan: Scan | None = None
    turning: TurningFound | None = None
    open_curves = 0
    if lines is not None:
        raw, seeds, timed_out = lines, 0, False
        grid: list[np.ndarray] = []
    else:
        tracing = _CurveTracing(linkage, ax, box, h_max, tol, opt, max_curve_points, dl)
        scan = _scan(tracing, opt.homotopy_paths_max, opt.seed)
        turning = _turning(tracing, opt.homotopy_paths_max, opt.seed) if scan.complete else None
        # Seed lengths only where the sweeps did not all solve: their explorations find what
        # they find, and add nothing to the sweeps' argument.
        grid = [] if scan.complete else [
            box[:, 0] + span * (np.array([i, j]) + GRID_OFFSET) / seeds_per_axis
            for i in range(seeds_per_axis) for j in range(seeds_per_axis)]
        _trace_from_seeds(tracing, grid, seeds_per_axis, dl)
        raw = [_clip(c[:, -2:], box) for c in tracing.curves]
        open_curves = tracing.open_curves
        seeds, timed_out = tracing.seeds_tried, tracing.timed_out
    curves = _merge_coincident([c for c in raw if len(c) >= 2], KNOWN_REL * h_max)
    regions, thin_unresolved = _regions(linkage, ax, box, curves, resolution, opt, tol, dl)
    timed_out = timed_out or any(r.components is None for r in regions)
    search = SearchReport({
        "method": "closed form" if lines is not None else "traced",
        "seed_lengths": len(grid),
        "seed_configurations": seeds,
        "curves": len(curves),
        "step": h_max,
        "resolution": resolution,
        "regions_explored": sum(r.components is not None for r in regions),
        "regions_exact": sum(r.argument is not None for r in regions),
        "regions_thin": sum(r.cells == 0 for r in regions),
        "thin_unresolved": thin_unresolved,
        **_scan_details(scan),
        **(turning.details() if turning is not None else {}),
    }, timed_out=timed_out, degenerate=everywhere is not None, time_budget_s=granted(dl))
    search = search.with_argument(*_slice_argument(
        lines, regions, scan, thin_unresolved, turning, open_curves, planes_of)) \
        if everywhere is None else search.with_argument(None, everywhere)
    return Slice(curves, regions, search)


def _scan(tracing: _CurveTracing, paths_max: int, seed: int) -> Scan:
    """For each axis held in turn: every critical configuration on the box's two edges across
    it, and where a curve turns or enters the box in between (:meth:`engine.design.slice_scan.
    ScanDirection.sweep`, steps of at most the tracing step ``h_max``), each found by homotopy
    where its paths are within ``paths_max``; the curves through them traced
    (:meth:`_CurveTracing.take`). Every connected piece of a curve in the box meets one of
    these (its point of least ``L_x`` is on the left edge, or where it enters through the top or
    bottom edge, or where it turns; a segment ``L_x = const``, where the linkage without the
    other bar is critical, is a curve like any other for the sweep of ``L_y``) unless it is
    born and gone within one step of both sweeps."""
    box, ax, dl = tracing.box, tracing.ax, tracing.deadline
    paths = scan_paths(tracing.linkage)
    planned = 2
    if paths > paths_max:
        return Scan([], planned, 0,
                    f"{count_text(paths)} paths per sweep exceed the bound of {paths_max}",
                    tracing.h_max)
    lines: list[Scanline] = []
    for fixed in range(2):
        lo, hi = (float(v) for v in box[fixed])
        if dl.expired():
            tracing.timed_out = True
            return Scan(lines, planned, paths, "the deadline stopped the sweeps", tracing.h_max)
        dl.report(0.3 * fixed, "critical values: sweeping the box")
        direction = ScanDirection(tracing.linkage, ax[1 - fixed].bar, ax[fixed].bar, fixed,
                                  0.5 * (lo + hi), float(box[1 - fixed, 1]), seed=seed + fixed,
                                  deadline=dl)
        line = direction.sweep(lo, hi, float(box[1 - fixed, 0]), float(box[1 - fixed, 1]),
                               tracing.h_max, dl)
        lines.append(line)
        tracing.take([line.starts])
    failed = [f"{tracing.linkage.bar_ids[ax[s.fixed].bar]}: {s.message}"
              for s in lines if not s.success]
    return Scan(lines, planned, paths, "; ".join(failed), tracing.h_max)


def _turning(tracing: _CurveTracing, paths_max: int, seed: int) -> TurningFound:
    """The turning points of the slice's curves in the box (:func:`engine.design.
    slice_turning.turning_points`, when its paths are within ``paths_max``), the curves
    through them traced; then which of them lie on a traced curve."""
    paths = turning_paths(tracing.linkage)
    if paths > paths_max:
        return TurningFound(paths, None, 0,
                             f"{count_text(paths)} paths exceed the bound of {paths_max}")
    dl = tracing.deadline
    if dl.expired():
        tracing.timed_out = True
        return TurningFound(paths, None, 0, "the deadline passed before them")
    dl.report(0.3, "critical values: the curves' turning points")
    bars = (tracing.ax[0].bar, tracing.ax[1].bar)
    found = turning_points(tracing.linkage, bars, tracing.box, seed=seed, deadline=dl)
    tracing.take([found.starts])
    atol = KNOWN_REL * tracing.h_max
    on = sum(any(_on_polyline(x[-2:], None, c[:, -2:], atol) for c in tracing.curves
                 if len(c) >= 2) for x in found.starts)
    return TurningFound(found.paths, found, on, found.message)


def _closed_form_curves(
    linkage: Linkage, ax: tuple[Axis, Axis], box: np.ndarray, step: float, tol: Tolerances,
) -> tuple[list[np.ndarray], str] | None:
    """The slice's curves where the critical value set is known in closed form, and what they
    are (a phrase: "every critical curve in the box is ..."): every critical hyperplane
    ``n . (x_1, x_2, x_3) = D`` (of a one-dyad planar chain, :func:`engine.design.dyad_margin.
    critical_planes`; of the gate four-bar, :func:`~engine.design.dyad_margin.gate_planes`; of
    the flat cells of a rotor chain, :func:`engine.design.chain_planes.chain_planes`, a gated
    chain's whose gate rotor cranks the gate four-bar too) met with the plane of the two axes
    (the other lengths as given) is a line; its piece inside the box (lengths at least the
    shortest critical bar) sampled at most ``step`` apart. A three-rotor
    whose cells' alignments combine in the box: the flat cells' lines where the other cell
    assembles and the curves where both dyads are straight (:func:`engine.design.chain_curves.
    two_cell_curves`). None when no closed form applies (or a plane holds the whole box: every
    length there critical)."""
    found = critical_planes(linkage)
    gate = gate_planes(linkage) if found is None else None
    # (those planes are the whole critical value set in their own three lengths only)
    mine = [pl for pl in ([found[1]] if found is not None else []) + ([gate] if gate else [])
            if all(a.bar in pl.bars for a in ax)]
    planes: list[CriticalPlanes] | None
    bars = (ax[0].bar, ax[1].bar)
    if mine or found is not None:
        planes = mine or None
        what = "the one-dyad chain" if found is not None else "the gate four-bar"
    else:  # (a gated chain in its chain's lengths too: the gate cranking, never restricting)
        planes = chain_planes(linkage, bars, box)
        what = ("a four-bar cell of the rotor chain flat (no two cells' alignments combine in "
                "the box" + ("; the gate rotor cranks the gate four-bar, whose rocker's two "
                             "places never meet: the gate neither restricts the chain nor "
                             "carries a self-stress)" if gated_chain(linkage) else ")"))
    if planes is None:
        if found is not None or gate is not None:
            return None
        shortest = MIN_CRITICAL_LENGTH_ATOL * tol.residual_atol
        sphere = spherical_curves(linkage, bars, box, step, shortest)
        sphere = radius_curves(linkage, bars, box, step, shortest) if sphere is None else sphere
        if sphere is not None:
            return sphere, SPHERICAL_CURVES
        two = two_cell_curves(linkage, bars, box, step, shortest)
        if two is None:
            return None
        return two, ("a line of a flat four-bar cell of the three-rotor where the other cell "
                     "assembles, or a curve where both of its dyads are straight (closed form: "
                     "three circles through the middle tip)")
    curves: list[np.ndarray] = []
    for pl in planes:
        lines = _plane_lines(linkage, pl, ax, box, step, tol)
        if lines is None:
            return None
        curves += lines
    return curves, f"a critical hyperplane of {what} (closed form) met with the plane"


def _plane_lines(linkage: Linkage, pl: CriticalPlanes, ax: tuple[Axis, Axis], box: np.ndarray,
                 step: float, tol: Tolerances) -> list[np.ndarray] | None:
    """The pieces in the box of the planes ``pl`` met with the plane of the two axes (None: a
    plane holds the whole box)."""
    shortest = MIN_CRITICAL_LENGTH_ATOL * tol.residual_atol
    lo = np.maximum(box[:, 0], shortest)
    at = [np.flatnonzero(pl.bars == a.bar) for a in ax]  # each axis's column (or none)
    fixed = np.array([k for k in range(len(pl.bars)) if not any(k in c for c in at)], dtype=int)
    others = linkage.lengths[pl.bars[fixed]].astype(float)
    curves = []
    for normal in pl.normals:  # at most 8 planes
        if np.any((normal[fixed] != 0) & (others < shortest)):
            continue  # a fixed bar would be degenerate: no critical configuration there
        n = np.array([float(normal[c[0]]) if len(c) else 0.0 for c in at])
        c = pl.dist - float(normal[fixed] @ others)
        if not n.any():  # (a plane of fixed lengths only: all of the box, or none of it)
            if abs(c) <= MIN_CRITICAL_LENGTH_ATOL * tol.residual_atol:
                return None
            continue
        # the line n . p = c, as p0 + t d with |d| = 1, cut to the box (slab by slab)
        p0 = n * c / float(n @ n)
        d = np.array([-n[1], n[0]]) / float(np.hypot(*n))
        t_lo, t_hi = -np.inf, np.inf
        for m in range(2):  # the two axes of the box
            if d[m] == 0.0:
                if not lo[m] <= p0[m] <= box[m, 1]:
                    t_lo, t_hi = np.inf, -np.inf
                continue
            ta, tb = sorted(((lo[m] - p0[m]) / d[m], (box[m, 1] - p0[m]) / d[m]))
            t_lo, t_hi = max(t_lo, ta), min(t_hi, tb)
        if not t_hi > t_lo:
            continue
        t = np.linspace(t_lo, t_hi, int(np.ceil((t_hi - t_lo) / step)) + 1)
        curves.append(np.clip(p0[None, :] + t[:, None] * d[None, :], lo, box[:, 1]))
    return curves


class _CurveTracing:
    """The curves of a slice traced so far (in ``(u, sigma, p)`` space), and how they are
    seeded: from the critical points and near misses of a seed's lengths, each moved onto the
    solution set ``G = 0`` and followed both ways unless a curve already traced has it."""

    def __init__(self, linkage: Linkage, ax: tuple[Axis, Axis], box: np.ndarray, h_max: float,
                 tol: Tolerances, opt: SpaceOptions, max_curve_points: int,
                 deadline: Deadline) -> None:
        self.linkage, self.ax, self.box, self.h_max = linkage, ax, box, h_max
        self.tol, self.max_curve_points, self.deadline = tol, max_curve_points, deadline
        self.sys = _System(linkage, ax)
        self.span = float(max(box[:, 1] - box[:, 0]))
        self.curves: list[np.ndarray] = []
        self.seeds_tried = self.seeds_used = 0
        self.open_curves = 0  # curves stopped by the point budget or a step underflow
        self.timed_out = False
        # A seed exploration need not be complete (it only has to reach critical configurations
        # near its lengths), so its curves get a point budget: one that fails to close (as near
        # a branch point at critical lengths) must not cost a full trace budget.
        self.seed_opt = replace(
            opt, max_components=min(opt.max_components, 8), near_misses_closed_form=True,
            trace=replace(opt.trace, max_points=min(opt.trace.max_points, SEED_MAX_POINTS)),
        )

    def known(self, x: np.ndarray) -> bool:
        """The seed's lengths lie on a curve already traced, going the same way there (other
        assemblies of the same critical sheet project onto the same curve of the slice). A
        traced polyline is a chord of its curve (within ``KNOWN_REL`` of a step of it); a
        curve that only crosses it there has another direction, and is traced."""
        p = x[-2:]
        t = _tangent(self.sys, x, np.random.default_rng(0).normal(size=self.sys.n))
        d = None if t is None else t[-2:]
        if t is not None and np.linalg.norm(t[-2:]) <= 1e-3 * np.linalg.norm(t):
            d = None  # (a cusp of the projection: its direction is no guide)
        atol = KNOWN_REL * self.h_max
        return any(_on_polyline(p, d, c[:, -2:], atol, SAME_WAY) for c in self.curves
                   if len(c) >= 2)  # (a curve the deadline cut to one point: no segment)

    def starts_at(self, p0: np.ndarray) -> np.ndarray:
        """The starts (K, M + E + 2) of the seed lengths ``p0``: every critical point (refined,
        with its stress) and near miss that the exploration at ``p0`` reaches, at ``p0``."""
        lengths = self.linkage.lengths.copy()
        lengths[self.ax[0].bar], lengths[self.ax[1].bar] = p0
        at = self.linkage.with_lengths(lengths)
        # Only the critical configurations are needed here: no segments, no components.
        res = find_critical_points(at, self.tol, self.seed_opt, start_on_space=False,
                                   deadline=self.deadline)
        cons = Constraints(at)
        starts: list[np.ndarray] = []
        found: list[tuple[np.ndarray, np.ndarray | None]] = (
            [(cp.u, None) for cp in res.critical_points]
            + [(m.critical_u, m.critical_sigma) for m in res.near_misses]
        )
        for u0, s0 in found:
            if self.deadline.expired():
                self.timed_out = True
                break
            if s0 is None:  # (a near miss's configuration is refined already, with its stress)
                ref = refine_critical(cons, u0, self.tol)
                u0, s0 = ref.u, ref.sigma
            starts.append(np.concatenate([u0, s0, p0]))
        return np.array(starts, dtype=float).reshape(-1, self.sys.n)

    def take(self, starts: list[np.ndarray]) -> None:
        """Every new curve through the starts of some seed lengths (:meth:`starts_at`, one
        array per seed, in seed order): all of them moved onto ``G = 0`` at once, then each
        followed unless a curve traced before it (from this or an earlier seed) has it."""
        if not starts or not sum(len(s) for s in starts):
            return
        if self.deadline.expired():  # (not even moved onto G = 0: seconds of dense algebra)
            self.timed_out = True
            return
        xs = _onto_solutions_batch(self.sys, np.concatenate(starts), deadline=self.deadline)
        for x in xs:
            if self.deadline.expired():  # (every start left would be followed a little)
                self.timed_out = True
                return
            self.seeds_tried += 1
            if np.max(np.abs(self.sys.g(x))) > 1e-9 or self.known(x):
                continue
            if np.any(x[-2:] < self.box[:, 0] - self.h_max) or \
                    np.any(x[-2:] > self.box[:, 1] + self.h_max):
                continue
            self.seeds_used += 1
            self.follow(x)

    def follow(self, x: np.ndarray) -> None:
        """The curve through ``x``, both ways (closed: once round)."""
        t = _tangent(self.sys, x, np.random.default_rng(self.seeds_used).normal(size=self.sys.n))
        if t is None:
            return
        args = (self.box, self.h_max, self.max_curve_points, self.deadline)
        fwd, stop_f = _continue(self.sys, x, t, *args)
        if stop_f == "closed":
            self.curves.append(np.array(fwd + [fwd[0]]))
            return
        back, stop_b = _continue(self.sys, x, -t, *args)
        self.curves.append(np.array(back[::-1] + fwd[1:]))
        self.timed_out = self.timed_out or REASON_TIME in (stop_f, stop_b)
        self.open_curves += any(s in ("budget", "step underflow") for s in (stop_f, stop_b))
