"""The whole configuration space of a one-degree-of-freedom linkage.

1. **Seeds** (:mod:`engine.assembly`): every assembly at swept rotor angles, random projections.
2. **Curves**: from every seed that is not on a curve already traced, trace until the curve
   closes (:func:`engine.trace.trace_curve`).
3. **Critical points**: candidates where the augmented determinant changes sign along a curve,
   at deep minima of ``|det|`` along it, and from seeded multistart; each refined on the
   augmented system (:mod:`engine.critical`), deduplicated and classified to second order.
   Points of a non-isolated critical set are merged into one degenerate entry per stress
   support: they are never counted.
4. **Segments** (critical lengths): from every branch point along each of its four rays, trace
   until the next critical point. Components are the connected pieces of the graph of critical
   points and segments (walked as an Eulerian circuit, so consecutive points stay within the
   step bound), plus the closed curves that meet no critical point.

Planar dyad chains (a rotor and circle-circle dyads) first try the closed form of
:mod:`engine.dyads`: every component sampled in one vectorised pass, with a certificate that no
critical point exists; it declines (and the steps above run) at or near critical lengths.
With ``SpaceOptions.critical_closed_form`` (default), :func:`find_critical_points` of such a chain
refines closed-form candidates instead of tracing (:func:`engine.dyads.critical_candidates`:
wherever that certificate is in doubt) and answers only when every candidate refines to a
critical point and none is degenerate; otherwise the steps above run.
"""

from __future__ import annotations

import itertools
import re
from collections.abc import Iterable
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial import cKDTree

from engine.assembly import iter_seeds, projected_random_starts, rotors
from engine.batched import BATCH_MAX_FREE, BatchedConstraints
from engine.budget import (
    NEVER,
    REASON_BUDGET,
    REASON_DEGENERATE,
    REASON_TIME,
    REASON_UNRESOLVED,
    Deadline,
)
from engine.chain_count import chain_components
from engine.constraints import Constraints
from engine.critical import CriticalPoint, NearMiss, classify, refine_critical, singular_gap
from engine.dyads import closed_form_space, critical_candidates
from engine.errors import InvalidLinkage, InvalidRequest
from engine.linkage import Linkage
from engine.rigidity import first_order
from engine.tolerances import Tolerances
from engine.trace import (
    STOP_TIME,
    Curve,
    TraceOptions,
    correct,
    polyline_distance,
    segment_distance,
    trace_curve,
)

#: Above this many free coordinates the critical-point search uses only candidates along the
#: traced curves (no random multistart on the augmented system).
MULTISTART_MAX_FREE = 64
#: Smallest ``step_max`` accepted, relative to the median bar length.
MIN_STEP_MAX_REL = 1e-6


#: Above this many free coordinates the zero mode at a seed comes from the sparse first-order
#: method (measured faster than the dense SVD from about 100 rotors of a chain).
SPARSE_SEED_RIGIDITY_MIN_FREE = 128

#: Why a traced curve stopped, when that was a count running out (see ``trace_curve``).
BUDGET_STOPS = re.compile(r"max points|step budget")

#: Seeds tested together against the traced curves (small linkages, see ``trace_all``).
SEED_CHUNK = 128


@dataclass(frozen=True)
class SpaceOptions:
    """Controls of the exploration (every cost is bounded by these)."""

    trace: TraceOptions = field(default_factory=TraceOptions)
    angles: int = 60
    assembly_budget: int = 16
    max_swept_rotors: int = 4
    random_starts: int = 12
    max_components: int = 32
    seed: int = 0
    #: Try the closed form of :mod:`engine.dyads` first (planar dyad chains away from critical
    #: lengths); False always runs the general tracer (the tests cross-check the two).
    closed_form: bool = True
    #: :func:`find_critical_points` of planar dyad chains from the closed-form candidates of
    #: :func:`engine.dyads.critical_candidates` (no tracing), where they are beyond doubt
    #: (critical points are in one canonical order whichever path finds them; the report then
    #: has no seeds or traced curves). Needs ``closed_form`` too; False always traces.
    critical_closed_form: bool = True
    #: With ``critical_closed_form``, where the closed form certifies that there is no critical
    #: point, take the near misses from its walks instead of tracing the curves (several times
    #: faster; it may miss one of a mirror pair of closest approaches, which seeds of a
    #: critical-value slice do not need; False: the general search's near misses).
    near_misses_closed_form: bool = False


@dataclass(frozen=True)
class Segment:
    """A branch of the configuration space from one critical point to another (or back).

    ``start``/``end`` index critical points; ``start_ray``/``end_ray`` number the rays as in the
    second-order tangents (``+t0, -t0, +t1, -t1`` = 0..3), -1 where not a branch point.
    """

    start: int
    start_ray: int
    end: int
    end_ray: int
    points: np.ndarray


@dataclass(frozen=True)
class Component:
    """A connected component: its walk (n, M); closed walks repeat the first point at the end."""

    points: np.ndarray
    closed: bool
    through_start: bool
    critical_points: list[int]
    segments: list[int]


@dataclass(frozen=True)
class SpaceResult:
    """Outcome of :func:`explore`."""

    components: list[Component]
    critical_points: list[CriticalPoint]
    segments: list[Segment]
    near_misses: list[NearMiss]
    search: dict[str, object]
    degenerate: bool


def rays(cp: CriticalPoint) -> np.ndarray:
    """The four rays ``+t0, -t0, +t1, -t1`` (4, M) of a branch point."""
    t = cp.analysis.tangents
    return np.array([t[0], -t[0], t[1], -t[1]])


def _require_one_dof(linkage: Linkage, cons: Constraints) -> None:
    if cons.n_free - cons.n_constraints != 1 or not linkage.anything_fixed:
        raise InvalidLinkage(
            "tracing needs one degree of freedom (M - E = 1 with something fixed); this linkage "
            f"has M = {cons.n_free}, E = {cons.n_constraints}"
            + ("" if linkage.anything_fixed else " and nothing fixed"),
            loc=("bars",),
        )


class _Explorer:
    def __init__(self, linkage: Linkage, tol: Tolerances, options: SpaceOptions,
                 deadline: Deadline = NEVER) -> None:
        self.linkage = linkage
        self.deadline = deadline
        #: the deadline stopped some part of the search (its answer is then incomplete)
        self.timed_out = False
        self.cons = Constraints(linkage)
        _require_one_dof(linkage, self.cons)
        self.tol = tol
        self.opt = options
        self.h_max = options.trace.resolved_step_max(self.cons)
        self.scale = float(np.median(linkage.lengths[self.cons.bars]))
        if self.h_max < MIN_STEP_MAX_REL * self.scale:
            raise InvalidRequest(
                f"step_max = {self.h_max:g} is below {MIN_STEP_MAX_REL:g} of the median bar "
                f"length ({self.scale:g}): a curve would need more points than any budget",
                loc=("options", "step_max"),
            )
        self.curves: list[Curve] = []
        self.tree: cKDTree | None = None
        self.tree_owner: np.ndarray = np.zeros(0, dtype=int)
        self.tree_first: np.ndarray = np.zeros(0, dtype=int)
        self.report: dict[str, object] = {}
        self.batched = BatchedConstraints(self.cons) if self.cons.n_free <= BATCH_MAX_FREE \
            else None

    # -- deadline -------------------------------------------------------------------------
    def out_of_time(self) -> bool:
        """True (and remembered) once the deadline has passed: the search stops there."""
        if not self.timed_out and self.deadline.expired():
            self.timed_out = True
        return self.timed_out

    def _trace(self, u: np.ndarray, t: np.ndarray, close: bool = True) -> Curve:
        curve = trace_curve(self.cons, u, t, self.tol, self.opt.trace, close=close,
                            deadline=self.deadline)
        self.timed_out = self.timed_out or curve.stop == STOP_TIME
        return curve

    def completion(self, degenerate: bool, segments_complete: bool = True) -> dict[str, object]:
        """``complete`` and, when not, the ``reason``: ``"time"`` (the deadline stopped the
        search), ``"budget"`` (a count ran out: components, assemblies, points of a curve),
        ``"degenerate"`` (a critical point that is not isolated) or ``"unresolved"`` (a curve
        or segment that stopped open for a numerical reason, e.g. near a split branch point)."""
        budget = bool(self.report.get("component_budget_reached")
                      or self.report.get("assemblies_truncated")
                      or any(BUDGET_STOPS.search(c.stop) for c in self.curves))
        unresolved = bool(self.report.get("open_curves", 0)) or not segments_complete
        reason = (REASON_TIME if self.timed_out else REASON_BUDGET if budget
                  else REASON_DEGENERATE if degenerate
                  else REASON_UNRESOLVED if unresolved else None)
        return {"complete": reason is None, "reason": reason}

    # -- curves ---------------------------------------------------------------------------
    def _rebuild_tree(self) -> None:
        pts = [np.array(c.points) for c in self.curves]
        self.tree = cKDTree(np.vstack(pts))
        self.tree_owner = np.concatenate([np.full(len(p), k) for k, p in enumerate(pts)])
        # index of each curve's first point in the tree: a point's offset in its curve
        self.tree_first = np.concatenate([[0], np.cumsum([len(p) for p in pts])[:-1]])

    def _tree_point(self, i: int) -> tuple[Curve, int]:
        """The curve owning tree point ``i`` and the point's index along it."""
        owner = int(self.tree_owner[i])
        return self.curves[owner], int(i) - int(self.tree_first[owner])

    def on_traced(self, u: np.ndarray) -> bool:
        """True when ``u`` lies on a traced curve: near its polyline, and the hyperplane
        correction from the nearest curve point towards ``u`` lands on ``u``."""
        if self.tree is None:
            return False
        dist, idx = self.tree.query(u, k=min(4, self.tree.n))
        for d, i in zip(np.atleast_1d(dist), np.atleast_1d(idx), strict=True):
            if d > self.h_max:
                continue
            curve, offset = self._tree_point(int(i))
            p, t = curve.points[offset], curve.tangents[offset]
            v = p + ((u - p) @ t) * t
            w, ok, _ = correct(self.cons, v, t, self.tol)
            if ok and np.linalg.norm(w - u) <= 1e-6 * self.scale:
                return True
        return False

    def trace_from(self, u: np.ndarray) -> Curve | None:
        # The zero mode at a seed: on large linkages by the engine's sparse method (shift-invert
        # Lanczos, same rank rule), a dense SVD costs O(M^3) per traced curve (0.1-0.2 s at
        # M = 200 to 400, more than tracing the curve).
        rig = first_order(self.linkage.with_positions(self.linkage.positions_of(u)), self.tol,
                          sparse=True if self.cons.n_free > SPARSE_SEED_RIGIDITY_MIN_FREE
                          else None)
        if rig.critical or rig.zero_modes.shape[0] != 1:
            return None
        curve = self._trace(u, rig.zero_modes[0])
        if curve.stop != "closed":
            back = self._trace(u, -rig.zero_modes[0], close=False)
            curve = Curve(
                points=back.points[::-1][:-1] + curve.points,
                tangents=[-t for t in back.tangents[::-1][:-1]] + curve.tangents,
                signs=back.signs[::-1][:-1] + curve.signs,
                logdets=back.logdets[::-1][:-1] + curve.logdets,
                stop=f"open ({back.stop}; {curve.stop})",
            )
        return curve

    def on_curve(self, us: np.ndarray, curve: Curve) -> np.ndarray:
        """:meth:`on_traced` for a stack of points (K, M) against one curve, vectorised (small
        linkages): each point is tested from its 4 nearest points of ``curve`` within the step
        bound (a superset of the tests :meth:`on_traced` makes for that curve), and a point
        counts as on the curve only when a hyperplane correction lands on it."""
        assert self.batched is not None  # only called for small linkages
        pts = np.array(curve.points)
        tans = np.array(curve.tangents)
        k = min(4, len(pts))
        dist, idx = cKDTree(pts).query(us, k=k)
        dist, idx = dist.reshape(len(us), k), idx.reshape(len(us), k)
        on = np.zeros(len(us), dtype=bool)
        for r in range(k):  # nearest curve point first; the next only where that one failed
            which = np.flatnonzero(~on & (dist[:, r] <= self.h_max))
            if not len(which):
                continue
            p, t = pts[idx[which, r]], tans[idx[which, r]]
            u = us[which]
            v = p + np.einsum("ij,ij->i", u - p, t)[:, None] * t
            w, ok = self.batched.correct(v, t, self.tol)
            on[which[ok & (np.linalg.norm(w - u, axis=1) <= 1e-6 * self.scale)]] = True
        return on

    def trace_all(self, start: np.ndarray | None) -> None:
        # Seeds are generated on demand: once the component budget is reached the rest (on long
        # chains the costly random projections) is never computed; the report then counts the
        # seeds generated up to that point.
        found = iter_seeds(
            self.linkage, self.tol, self.report, self.opt.angles, self.opt.assembly_budget,
            self.opt.random_starts, self.opt.seed, self.opt.max_swept_rotors,
        )
        truncated = False
        first = [start] if start is not None else []
        # Small linkages: every seed is generated (they are cheap) and tested in chunks, each
        # against every curve traced so far in one batch per curve (``tested`` counts the
        # curves a seed has been tested against), so a seed reached in the loop below is tested
        # against every traced curve. Large ones take seeds lazily and test them one by one.
        batch = self.batched is not None
        points: Iterable[np.ndarray] = list(itertools.chain(first, found)) if batch \
            else itertools.chain(first, found)
        stack = np.array(points) if batch else np.zeros((0, self.cons.n_free))
        batch = batch and len(stack) > 0
        covered = np.zeros(len(stack), dtype=bool)
        tested = np.zeros(len(stack), dtype=int)
        for n, u in enumerate(points):
            if self.out_of_time():
                break
            # progress: seeds tested (all known for small linkages) or components traced
            done = max(n / len(stack) if batch else 0.0,
                       len(self.curves) / self.opt.max_components)
            self.deadline.report(0.6 * done, "tracing the components")
            if batch and not covered[n] and tested[n] < len(self.curves):
                chunk = np.arange(n, min(len(stack), n + SEED_CHUNK))
                for c in range(int(tested[chunk].min()), len(self.curves)):
                    sel = chunk[~covered[chunk] & (tested[chunk] <= c)]
                    if len(sel):
                        covered[sel[self.on_curve(stack[sel], self.curves[c])]] = True
                tested[chunk] = len(self.curves)
            if (covered[n] if batch else self.on_traced(u)):
                continue
            if len(self.curves) >= self.opt.max_components:
                truncated = True
                break
            curve = self.trace_from(u)
            if curve is None:
                continue
            self.curves.append(curve)
            self._rebuild_tree()
        self.report["curves_traced"] = len(self.curves)
        self.report["component_budget_reached"] = truncated
        self.report["open_curves"] = sum(c.stop != "closed" for c in self.curves)

    # -- critical points ------------------------------------------------------------------
    def candidates(self) -> list[np.ndarray]:
        starts: list[np.ndarray] = []
        for curve in self.curves:
            pts = np.array(curve.points)
            signs = np.array(curve.signs)
            flips = np.flatnonzero(signs[1:] * signs[:-1] < 0)
            starts += [0.5 * (pts[i] + pts[i + 1]) for i in flips]
            logd = np.array(curve.logdets)
            if len(logd) >= 3:
                deep = np.median(logd) - np.log(30.0)
                mins = np.flatnonzero(
                    (logd[1:-1] <= logd[:-2]) & (logd[1:-1] <= logd[2:]) & (logd[1:-1] < deep)
                ) + 1
                starts += [pts[i] for i in mins]
            if len(logd):  # the closest approach of every curve, however shallow
                starts.append(pts[int(np.argmin(logd))])
        # Seeded multistart from random points projected onto the constraints (close to where
        # critical points live); only for small linkages, where it is cheap: larger ones rely on
        # the candidates along the traced curves.
        starts_used = self.opt.random_starts if self.cons.n_free <= MULTISTART_MAX_FREE else 0
        rng = np.random.default_rng(self.opt.seed + 1)
        starts += projected_random_starts(self.linkage, self.tol, starts_used, rng)
        self.report["critical_multistart"] = starts_used
        return starts

    def critical_points(self) -> tuple[list[CriticalPoint], list[NearMiss], bool]:
        candidates = self.candidates()
        self.report["critical_candidates"] = len(candidates)
        exact, misses, degenerate, _ = self.resolve(candidates)
        return exact, misses, degenerate

    def resolve(
        self, candidates: Iterable[np.ndarray]
    ) -> tuple[list[CriticalPoint], list[NearMiss], bool, int]:
        """Refine every candidate on the augmented system; deduplicate, classify and merge the
        critical points (near misses only against traced curves): ``(critical points, near
        misses, degenerate, how many candidates did not refine to a critical point)``."""
        exact: list[CriticalPoint] = []
        misses: list[NearMiss] = []
        failed = 0
        for u0 in candidates:
            if self.out_of_time():
                break
            ref = refine_critical(self.cons, u0, self.tol)
            failed += not ref.critical
            if ref.critical:
                if any(np.linalg.norm(ref.u - c.u) <= 1e-6 * self.scale for c in exact):
                    continue
                analysis = classify(self.linkage, ref.u, self.tol)
                exact.append(CriticalPoint(ref.u, analysis, ref.length_residual,
                                           ref.stress_residual))
            elif self.tree is not None:
                _, i = self.tree.query(ref.u)
                curve, offset = self._tree_point(int(i))
                on = curve.points[offset]
                misses.append(NearMiss(on, singular_gap(self.cons, on),
                                       float(np.linalg.norm(on - ref.u)),
                                       ref.length_residual, ref.u, ref.sigma))
        exact, degenerate = _merge_non_isolated(exact)
        # One canonical order, whichever path found them (closed-form candidates, traced
        # curves, multistart): every endpoint numbers the critical points alike, so a
        # branch_point index from one answer means the same point in another.
        exact.sort(key=lambda c: tuple(np.round(c.u / self.scale, 5)))
        misses = _dedupe_misses(misses, self.scale)
        return exact, misses, degenerate, failed

    # -- segments -------------------------------------------------------------------------
    def segments(self, crit: list[CriticalPoint]) -> tuple[list[Segment], bool]:
        out: list[Segment] = []
        seen: set[frozenset[tuple[int, int]]] = set()
        complete = True
        h0 = 0.05 * self.h_max
        capture = 0.05 * self.h_max
        centres = [c.u for c in crit]
        for i, cp in enumerate(crit):
            if cp.kind != "branch":
                continue
            self.deadline.report(0.8 + 0.2 * i / len(crit), "tracing the segments")
            for r, ray in enumerate(rays(cp)):
                if any((i, r) in key for key in seen):
                    continue
                if self.out_of_time():
                    complete = False
                    break
                v = cp.u + h0 * ray
                w, ok, _ = correct(self.cons, v, ray, self.tol)
                if not ok:
                    complete = False
                    continue

                def stop(a: np.ndarray, b: np.ndarray, t: np.ndarray, _i: int = i,
                         _w: np.ndarray = w) -> str | None:
                    for j, c in enumerate(centres):
                        if j == _i and np.linalg.norm(b - _w) < 2 * h0:
                            continue
                        if segment_distance(a, b, c) <= capture:
                            return f"critical:{j}"
                    return None

                curve = trace_curve(self.cons, w, ray, self.tol, self.opt.trace, stop=stop,
                                    close=False, deadline=self.deadline)
                self.timed_out = self.timed_out or curve.stop == STOP_TIME
                if not curve.stop.startswith("critical:"):
                    complete = False
                    continue
                j = int(curve.stop.split(":")[1])
                end_ray = _arrival_ray(crit[j], curve.points[-2] if len(curve.points) > 1
                                       else curve.points[-1])
                key = frozenset({(i, r), (j, end_ray)})
                if key in seen:
                    continue
                seen.add(key)
                pts = np.vstack([cp.u, np.array(curve.points[:-1]), crit[j].u])
                out.append(Segment(i, r, j, end_ray, pts))
        return out, complete


def _arrival_ray(cp: CriticalPoint, near: np.ndarray) -> int:
    if cp.kind != "branch":
        return -1
    d = near - cp.u
    return int(np.argmax(rays(cp) @ (d / max(np.linalg.norm(d), 1e-300))))


def _merge_non_isolated(points: list[CriticalPoint]) -> tuple[list[CriticalPoint], bool]:
    """Keep isolated critical points; merge points of non-isolated sets into one entry per
    stress support (the set is a continuum: any count of its points would be wrong)."""
    kept: list[CriticalPoint] = []
    supports: set[tuple[int, ...]] = set()
    degenerate = False
    for cp in points:
        reason = cp.analysis.reason or ""
        if cp.kind == "degenerate" and "non-isolated" in reason:
            degenerate = True
            stress = cp.analysis.self_stress
            support = tuple(np.flatnonzero(np.abs(stress) > 1e-6).tolist()) if stress is not None \
                else ()
            if support in supports:
                continue
            supports.add(support)
        elif cp.kind == "degenerate":
            degenerate = True
        kept.append(cp)
    return kept, degenerate


def _dedupe_misses(misses: list[NearMiss], scale: float) -> list[NearMiss]:
    misses = sorted(misses, key=lambda m: m.length_gap)
    out: list[NearMiss] = []
    for m in misses:
        if all(np.linalg.norm(m.critical_u - o.critical_u) > 1e-4 * scale for o in out):
            out.append(m)
    return out


def _euler_walks(n_nodes: int, segs: list[Segment]) -> list[list[tuple[int, bool]]]:
    """Walks covering every segment once (Hierholzer per connected piece): (segment, reversed)."""
    adj: dict[int, list[int]] = {k: [] for k in range(n_nodes)}
    for s, seg in enumerate(segs):
        adj[seg.start].append(s)
        if seg.end != seg.start:
            adj[seg.end].append(s)
        else:
            adj[seg.start].append(s)
    used = [False] * len(segs)
    walks: list[list[tuple[int, bool]]] = []
    for s0 in range(len(segs)):
        if used[s0]:
            continue
        odd = [v for v in adj if len(adj[v]) % 2 == 1]
        start = segs[s0].start if not odd else odd[0]
        stack: list[tuple[int, int, bool]] = [(start, -1, False)]
        path: list[tuple[int, bool]] = []
        while stack:
            node, via, rev = stack[-1]
            nxt = next((s for s in adj[node] if not used[s]), None)
            if nxt is None:
                stack.pop()
                if via >= 0:
                    path.append((via, rev))
                continue
            used[nxt] = True
            seg = segs[nxt]
            forward = seg.start == node
            stack.append((seg.end if forward else seg.start, nxt, not forward))
        if path:
            walks.append(path[::-1])
    return walks


@dataclass(frozen=True)
class CriticalSearch:
    """Outcome of :func:`find_critical_points`: :class:`SpaceResult` without the components
    and segments."""

    critical_points: list[CriticalPoint]
    near_misses: list[NearMiss]
    search: dict[str, object]
    degenerate: bool


def find_critical_points(
    linkage: Linkage,
    tolerances: Tolerances | None = None,
    options: SpaceOptions | None = None,
    start_on_space: bool = True,
    deadline: Deadline | None = None,
) -> CriticalSearch:
    """Critical points and near misses of a 1-DOF linkage, as :func:`explore` finds them,
    without building the segments and components.

    The critical points come from the traced curves (sign changes and deep minima of the
    augmented determinant, closest approaches) and the multistart, exactly as in
    :func:`explore`; the segments only connect critical points already found (a ray traced
    from a branch point crosses any other critical point on its way and goes on to a known
    one), so they add nothing to the search: its ``complete`` here is that of the curves
    (component budget, assemblies, no open curve) and of the classification (not degenerate).

    Examples
    --------
    >>> from engine.presets import build_preset
    >>> res = find_critical_points(build_preset("four-bar", {"L2": 1.0}))
    >>> len(res.critical_points), res.search["complete"]
    (3, True)
    """
    tol = tolerances or Tolerances()
    opt = options or SpaceOptions()
    ex = _Explorer(linkage, tol, opt, deadline or NEVER)
    start = linkage.coordinates() if start_on_space else None
    if opt.closed_form and opt.critical_closed_form:
        fast = _closed_form_critical(ex)
        if fast is not None:
            return fast
        if opt.near_misses_closed_form and ex.report.get("closed_form") == NO_CANDIDATE:
            # certified: no critical point; the near misses from the closed form's walks (as
            # explore finds them), instead of tracing the curves
            space = _closed_form(ex, start, near_misses=True)
            if space is not None:
                return CriticalSearch([], space.near_misses, space.search, False)
    if opt.critical_closed_form:
        ex.report["method"] = "tracer"
        ex.report.setdefault("closed_form", "off")
    ex.trace_all(start)
    crit, misses, degenerate = ex.critical_points()
    search = dict(ex.report)
    search.update(
        {
            "critical_points_found": len(crit),
            "step_max": ex.h_max,
            "strain_tol": opt.trace.strain_tol,
            **ex.completion(degenerate),
        }
    )
    return CriticalSearch(crit, misses if not crit else [], search, degenerate)


def explore(
    linkage: Linkage,
    tolerances: Tolerances | None = None,
    options: SpaceOptions | None = None,
    start_on_space: bool = True,
    near_misses: bool = True,
    deadline: Deadline | None = None,
) -> SpaceResult:
    """Components, critical points, segments and near misses of a 1-DOF linkage (on its
    configuration space: see :func:`engine.constraints.on_constraints`).

    ``near_misses=False`` says the caller does not need the near misses: where the closed form
    of :mod:`engine.dyads` certifies that no critical point exists, or the rules of
    :mod:`engine.chain_count` prove it for a rotor chain, the critical-point search (which
    finds the near misses, and would find no critical point) is then skipped.

    Examples
    --------
    >>> from engine.presets import build_preset
    >>> res = explore(build_preset("four-bar", {"L2": 1.2}))
    >>> len(res.components), len(res.critical_points)
    (1, 0)
    """
    tol = tolerances or Tolerances()
    opt = options or SpaceOptions()
    ex = _Explorer(linkage, tol, opt, deadline or NEVER)
    # With start_on_space=False the given positions need not satisfy the lengths (e.g. lengths
    # changed for a map): only the seeds are used, and none means an empty configuration space.
    start = linkage.coordinates() if start_on_space else None
    # -- closed-form path (engine.dyads); None: not a dyad chain, or at/near critical lengths --
    if opt.closed_form:
        fast = _closed_form(ex, start, near_misses)
        if fast is not None:
            return fast
    # -- general path ---------------------------------------------------------------------
    ex.report.setdefault("method", "tracer")
    ex.report.setdefault("closed_form", "off")
    ex.trace_all(start)
    count = chain_components(linkage)
    if count is not None and not near_misses:
        # The chain rules prove that there is no critical point (engine.chain_count): the
        # search would only find near misses, which the caller does not want. On long chains
        # it is most of the cost (dense refinements on 2n unknowns).
        crit: list[CriticalPoint] = []
        misses: list[NearMiss] = []
        degenerate = False
        ex.report["critical_search"] = f"skipped: {count.rule} proves no critical point"
    else:
        crit, misses, degenerate = ex.critical_points()
    # Segments need every critical point classified; with a degenerate one the traced curves
    # themselves are the answer (they may pass through critical points).
    segs, seg_complete = ex.segments(crit) if not degenerate else ([], False)
    components: list[Component] = []
    capture = 0.05 * ex.h_max

    def touching(curve: Curve) -> list[int]:
        pts = np.array(curve.points)
        return [k for k, c in enumerate(crit)
                if np.min(np.linalg.norm(pts - c.u, axis=1)) <= ex.h_max]

    for curve in ex.curves:
        near = touching(curve)
        if near and not degenerate:
            continue  # covered by the segments
        pts = np.array(curve.points)
        closed = curve.stop == "closed"
        if closed:
            pts = np.vstack([pts, pts[:1]])
        components.append(Component(pts, closed, False, near, []))
    for walk in _euler_walks(len(crit), segs):
        pieces = [segs[s].points[::-1] if rev else segs[s].points for s, rev in walk]
        pts = np.vstack([pieces[0]] + [p[1:] for p in pieces[1:]])
        nodes = sorted({segs[s].start for s, _ in walk} | {segs[s].end for s, _ in walk})
        closed = bool(np.linalg.norm(pts[0] - pts[-1]) <= capture)
        components.append(Component(pts, closed, False, nodes, [s for s, _ in walk]))
    on_segments = {n for c in components for n in c.critical_points}
    for k, cp in enumerate(crit):
        if k not in on_segments and cp.kind == "rigid":
            components.append(Component(cp.u[None, :], True, False, [k], []))
    _mark_through_start(components, start, ex.h_max)
    search = dict(ex.report)
    if count is not None:
        # the true total for rotor chains (four-bar decomposition), also when the budget of
        # traced components is far below it (a 100-rotor spinner chain has 2^99)
        search["components_total"] = count.components
        search["components_total_rule"] = count.rule
    search.update(
        {
            "critical_points_found": len(crit),
            "segments_complete": seg_complete,
            "step_max": ex.h_max,
            "strain_tol": opt.trace.strain_tol,
            **ex.completion(degenerate, seg_complete),
        }
    )
    return SpaceResult(components, crit, segs, misses if not crit else [], search, degenerate)


# -- closed-form path ------------------------------------------------------------------------


def _mark_through_start(components: list[Component], start: np.ndarray | None,
                        h_max: float) -> None:
    """Flag the component that passes through ``start`` (nearest walk, within ``h_max``)."""
    if start is None or not components:
        return
    dist = [polyline_distance(c.points, start) for c in components]
    best = int(np.argmin(dist))
    if dist[best] <= h_max:
        c = components[best]
        components[best] = Component(c.points, c.closed, True, c.critical_points, c.segments)


#: The critical-point search on closed-form walks looks at most this many points per walk
#: (the tracer's own density at the default step bound is far below it).
SEARCH_POINTS = 2000


def _walk_curve(cons: Constraints, walk: np.ndarray) -> Curve:
    """A closed walk (n, M; first point repeated) as a traced :class:`Curve`: unit tangents
    along the walk, ``det([t; J])`` signs and ``log|det|``, computed for all points at once.

    The tangent is the generalised cross product of ``J``'s rows, ``c_k = (-1)^k det(J without
    column k)``; then ``det([c; J]) = |c|^2``, so with ``t = o c / |c|`` (``o = +-1`` orienting
    ``t`` along the walk) ``det([t; J]) = o |c|``."""
    pts = walk[:-1]
    stride = max(1, int(np.ceil(len(pts) / SEARCH_POINTS)))
    pts = pts[::stride]
    lk = cons.linkage
    pos = np.empty((len(pts), *lk.positions.shape))
    pos[:] = lk.positions
    pos[:, ~lk.fixed] = pts
    r, c, s, ax = cons._pattern
    bars = cons.linkage.ends[cons.bars]
    diff = pos[:, bars[:, 0]] - pos[:, bars[:, 1]]  # (n, Ea, d)
    jac = np.zeros((len(pts), cons.n_constraints, cons.n_free))
    jac[:, r, c] = 2.0 * s * diff[:, r, ax]
    m = cons.n_free
    cof = np.empty((len(pts), m))
    for k in range(m):  # M small determinants per point, each vectorised over the points
        cols = np.r_[0:k, k + 1:m]
        cof[:, k] = (-1) ** k * np.linalg.det(jac[:, :, cols])
    ahead = np.roll(pts, -1, axis=0) - np.roll(pts, 1, axis=0)
    orient = np.where(np.einsum("ij,ij->i", cof, ahead) >= 0, 1, -1)
    norm = np.linalg.norm(cof, axis=1)
    tangents = orient[:, None] * cof / np.maximum(norm, 1e-300)[:, None]
    return Curve(points=list(pts), tangents=list(tangents), signs=orient.tolist(),
                 logdets=np.log(np.maximum(norm, 1e-300)).tolist(), stop="closed")


def _closed_form(ex: _Explorer, start: np.ndarray | None, near_misses: bool) -> SpaceResult | None:
    """The answer of :func:`explore` from :func:`engine.dyads.closed_form_space`, or None
    (the general path runs; ``search["closed_form"]`` then says why the closed form declined).

    With ``near_misses`` the usual critical-point search runs on the closed-form walks (for the
    near misses); should it find a critical point the closed form's certificate is contradicted
    and the general path answers instead."""
    lk, opt = ex.linkage, ex.opt
    try:
        cf = closed_form_space(lk, ex.tol, ex.h_max, opt.trace.max_points)
    except (ArithmeticError, ValueError, MemoryError) as exc:  # a safety net: never worse
        ex.report["method"] = "tracer"                          # than the general path
        ex.report["closed_form"] = f"declined: {type(exc).__name__}: {exc}"
        return None
    if cf.components is None:
        ex.report["method"] = "tracer"
        ex.report["closed_form"] = cf.report["closed_form"]
        return None
    free = ~np.asarray(lk.fixed)
    walks = [c[:, free] for c in cf.components]
    if start is not None:  # as the tracer, which starts there: the given one first
        walks.sort(key=lambda w: polyline_distance(w, start) > ex.h_max)
    truncated = len(walks) > opt.max_components
    walks = walks[: opt.max_components]
    report: dict[str, object] = {
        "method": "closed form",
        "closed_form": "used",
        "closed_form_rotor": cf.report["rotor"],
        "closed_form_sheets": cf.report["sheets"],
        "closed_form_folds": cf.report["folds"],
        "closed_form_samples": cf.report["samples"],
        "closed_form_margin": cf.report["margin"],
        "rotor_sweeps": [cf.report["rotor"]],
        "angles_per_rotor": cf.report["samples"],
        "assembly_budget_per_angle": cf.report["sheets"],
        "assemblies_truncated": False,
        "random_starts": 0,
        "random_starts_projected": 0,
        "seeds": 0,
        "curves_traced": 0,
        "component_budget_reached": truncated,
        "open_curves": 0,
    }
    misses: list[NearMiss] = []
    if near_misses:
        ex.curves = [_walk_curve(ex.cons, w) for w in walks]
        if ex.curves:
            ex._rebuild_tree()
        crit, misses, degenerate = ex.critical_points()
        if crit or degenerate:
            ex.curves, ex.tree = [], None
            ex.report = {"method": "tracer", "closed_form": "declined: the critical-point "
                         "search found a critical point"}
            return None
        report["critical_multistart"] = ex.report["critical_multistart"]
        report["critical_candidates"] = ex.report["critical_candidates"]
    else:
        report["critical_multistart"] = 0
        report["critical_candidates"] = 0
    components = [Component(w, True, False, [], []) for w in walks]
    _mark_through_start(components, start, ex.h_max)
    count = chain_components(lk)
    if count is not None:  # as in the general path
        report["components_total"] = count.components
        report["components_total_rule"] = count.rule
    report.update({
        "critical_points_found": 0,
        "segments_complete": True,
        "step_max": ex.h_max,
        "strain_tol": opt.trace.strain_tol,
        "complete": not (truncated or ex.timed_out),
        "reason": REASON_TIME if ex.timed_out else REASON_BUDGET if truncated else None,
    })
    return SpaceResult(components, [], [], misses, report, False)


#: ``search["closed_form"]`` of :func:`_closed_form_critical` when the closed form certifies that
#: there is no critical point (the near misses then come from the closed-form walks).
NO_CANDIDATE = ("declined: no candidate (no critical point); the near misses come from the "
                "closed-form walks or the general search")


def _closed_form_critical(ex: _Explorer) -> CriticalSearch | None:
    """:func:`find_critical_points` from the closed-form candidates of
    :func:`engine.dyads.critical_candidates`, or None (the general path runs;
    ``search["closed_form"]`` then says why).

    Every candidate is refined, deduplicated and classified as in the general search. The
    answer is given only when it is beyond doubt: at least one candidate, every candidate
    refines to a critical point (a start that does not is a near miss, i.e. lengths near but
    not at critical values, or a failed refinement: the general search decides), and no
    critical point is degenerate (non-isolated sets are merged by the general search). With no
    candidate at all the certificate holds (no critical point) but the near misses come from
    the general search, which then runs."""
    try:
        cc = critical_candidates(ex.linkage, ex.tol)
    except (ArithmeticError, ValueError, MemoryError) as exc:  # a safety net, as in explore
        ex.report["closed_form"] = f"declined: {type(exc).__name__}: {exc}"
        return None
    if cc.points is None:
        ex.report["closed_form"] = cc.report["closed_form"]
        return None
    if not len(cc.points):
        ex.report["closed_form"] = NO_CANDIDATE
        return None
    crit, _, degenerate, failed = ex.resolve(list(cc.points))
    if failed or degenerate or not crit:
        why = (f"{failed} of {len(cc.points)} candidates did not refine to a critical point"
               if failed else "a degenerate critical point" if degenerate
               else "no critical point")
        ex.report["closed_form"] = f"declined: {why}"
        return None
    search: dict[str, object] = {
        "method": "closed-form candidates",
        "closed_form": "used",
        "closed_form_rotor": cc.report["rotor"],
        "closed_form_sheets": cc.report["sheets"],
        "closed_form_samples": cc.report["samples"],
        "closed_form_margin": cc.report["margin"],
        "closed_form_extrema": cc.report.get("extrema_within_margin", 0),
        "closed_form_doubtful_folds": cc.report.get("doubtful_folds", 0),
        "critical_candidates": len(cc.points),
        "critical_multistart": 0,
        "curves_traced": 0,
        "assemblies_truncated": False,
        "component_budget_reached": False,
        "open_curves": 0,
        "critical_points_found": len(crit),
        "step_max": ex.h_max,
        "strain_tol": ex.opt.trace.strain_tol,
        # every sheet of the rotor's whole turn was searched: complete as the general search is
        # when its curves cover the space and no critical point is degenerate
        "complete": True,
        "reason": None,
    }
    return CriticalSearch(crit, [], search, False)


# -- end of closed-form path -----------------------------------------------------------------


def rotor_angles(linkage: Linkage, points: np.ndarray) -> dict[str, np.ndarray]:
    """Unwrapped angle of every rotor (bar with exactly one fully fixed end) along ``points``
    (n, M): ``atan2`` of the vector from the fixed end to the moving end (planar only)."""
    if linkage.dimension != 2:
        return {}
    out: dict[str, np.ndarray] = {}
    full = np.asarray(linkage.fixed.all(axis=1), dtype=bool)
    pos = positions_along(linkage, points)
    for k in rotors(linkage):
        i, j = (int(x) for x in linkage.ends[k])
        pin, tip = (i, j) if full[i] else (j, i)
        vec = pos[:, tip] - pos[:, pin]
        out[linkage.bar_ids[k]] = np.unwrap(np.arctan2(vec[:, 1], vec[:, 0]))
    return out


def positions_along(linkage: Linkage, points: np.ndarray) -> np.ndarray:
    """Vertex positions (n, V, d) of free coordinates ``points`` (n, M), all at once."""
    pts = np.asarray(points, dtype=float).reshape(len(points), -1)
    pos = np.empty((len(pts), *linkage.positions.shape))
    pos[:] = linkage.positions
    pos[:, ~linkage.fixed] = pts
    return pos


def winding(angles: np.ndarray, closed: bool) -> int | None:
    """Net number of turns of an unwrapped angle along a closed walk (None when open)."""
    if not closed or len(angles) < 2:
        return None
    return int(np.rint((angles[-1] - angles[0]) / (2 * np.pi)))
