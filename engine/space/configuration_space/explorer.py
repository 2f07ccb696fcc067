"""The search state: constraints, the curves traced from the seeds (with a k-d tree of their
points), the report and the deadline.
"""

from __future__ import annotations

import itertools
import re
from collections.abc import Iterator
from dataclasses import replace

import numpy as np
from scipy.spatial import cKDTree

from engine.local.rigidity import first_order
from engine.model.batched import BATCH_MAX_FREE, BatchedConstraints
from engine.model.budget import (
    ANSWER_SECONDS_PER_VALUE,
    ANSWER_TIME_S,
    NEVER,
    Argument,
    Deadline,
    OutOfTime,
    granted,
)
from engine.model.constraints import Constraints
from engine.model.errors import InvalidRequest
from engine.model.linkage import Linkage
from engine.model.report import SearchReport
from engine.model.tolerances import SAME_POINT_REL, Tolerances
from engine.space.assembly import STOPPED_BY_TIME, iter_random_seeds, iter_seeds
from engine.space.configuration_space.results import (
    MIN_STEP_MAX_REL,
    SpaceOptions,
    require_one_dof,
)
from engine.space.trace import (
    STOP_TIME,
    Curve,
    TraceOptions,
    correct,
    trace_curve,
)

#: Above this many free coordinates the zero mode at a seed comes from the sparse first-order
#: method (measured faster than the dense SVD from about 100 rotors of a chain).
SPARSE_SEED_RIGIDITY_MIN_FREE = 128
#: Seconds per free coordinate of that sparse zero mode (shift-invert Lanczos), measured on
#: the shared test machine (3.1 s at M = 40000, a 20000-rotor chain, at load 10 on 2 cores),
#: rounded up: a seed whose zero mode would not fit the time left is not traced.
SPARSE_SEED_SECONDS_PER_FREE = 1e-4


#: Why a traced curve stopped, when that was a count running out (see ``trace_curve``).
BUDGET_STOPS = re.compile(r"max points|step budget")


#: A seed this close (relative to the median bar length) to an isolated point of the space is
#: that point (see ``Explorer.trace_all``).
ISOLATED_REL = 1e-3

#: Seeds tested together against the traced curves (small linkages, see ``trace_all``).
SEED_CHUNK = 128

#: Nearest curve points looked at when testing whether a point lies on traced curves; of
#: these, only the closest point of each pass of a curve near the point is tested.
NEAREST = 16

#: Up to this many traced curves :meth:`Explorer.on_traced` asks each curve's own k-d tree
#: instead of the tree of all curves (rebuilt after every new curve).
FOREST_MAX = 64

#: The k-d tree query of :meth:`Explorer.on_curve` looks this far (relative to the step bound,
#: beyond which no point is a candidate), a little further so that rounding in the tree's
#: distance test drops no neighbour at the bound.
QUERY_BOUND_REL = 1.25


def pass_minima(points: np.ndarray, us: np.ndarray, idx: np.ndarray,
                first: np.ndarray | int = 0, last: np.ndarray | int | None = None) -> np.ndarray:
    """Which of the nearest curve points ``idx`` (K, k) of ``us`` (K, M) are the closest point
    of their pass: no farther from their row of ``us`` than their neighbours along the curve in
    ``points`` (n, M) that runs from index ``first`` to ``last`` (default: all of ``points``;
    arrays like ``idx`` where ``points`` holds several curves). Where a curve folds back near
    itself (the two arcs of a split branch point) the nearest points can all lie on the pass a
    point is not on; testing one point per pass finds the pass it is on.

    A point's own distance is computed here, by the same arithmetic as its neighbours', not
    taken from the k-d tree that found it: at a curve's ends the neighbour is the point itself,
    and the tree's distance differs from ``np.linalg.norm``'s in the last bit, so the nearest
    point (the end of a closed curve, near its seam) was rejected about half the time; a seed
    there counted as on no traced curve and its component was traced twice (a gated 3-rotor
    chain: 18 components traced where there are 16)."""
    last = len(points) - 1 if last is None else last
    here = np.linalg.norm(points[idx] - us[:, None, :], axis=2)
    before = np.linalg.norm(points[np.maximum(idx - 1, first)] - us[:, None, :], axis=2)
    after = np.linalg.norm(points[np.minimum(idx + 1, last)] - us[:, None, :], axis=2)
    return (here <= before) & (here <= after)


class Explorer:
    """The state of one search: the linkage's constraints, the curves traced so far (with a
    k-d tree of their points), the search report and the deadline."""

    def __init__(self, linkage: Linkage, tol: Tolerances, options: SpaceOptions,
                 deadline: Deadline = NEVER) -> None:
        self.linkage = linkage
        self.deadline = deadline
        #: the deadline stopped some part of the search (its answer is then incomplete)
        self.timed_out = False
        self.cons = Constraints(linkage)
        require_one_dof(linkage, self.cons)
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
        self._tree: cKDTree | None = None
        self._tree_owner: np.ndarray = np.zeros(0, dtype=int)
        self._tree_first: np.ndarray = np.zeros(0, dtype=int)
        #: the k-d tree of every curve's points is built when first read after the curves
        #: changed (small linkages test seeds against each curve's own tree: the search may
        #: never read it, or only once all curves are traced)
        self._tree_stale = False
        self.report: dict[str, object] = {}
        self.batched = BatchedConstraints(self.cons) if self.cons.n_free <= BATCH_MAX_FREE \
            else None
        #: per traced curve (by identity; the curve is held so its id stays its own): its
        #: points and tangents as arrays and their k-d tree, built once for every seed chunk
        #: :meth:`on_curve` tests against it
        self._curve_arrays: dict[int, tuple[Curve, np.ndarray, np.ndarray, cKDTree]] = {}
        #: points the answer may still carry (``options.max_values`` over the vertex count;
        #: None: no budget), spent by every traced curve and segment
        self.points_left: int | None = None if options.max_values is None else \
            max(0, options.max_values // max(1, len(linkage.vertex_ids)))

    def trace_options(self) -> TraceOptions:
        """The trace options of the next curve or segment: ``max_points`` no more than the
        points the answer may still carry."""
        if self.points_left is None or self.points_left >= self.opt.trace.max_points:
            return self.opt.trace
        return replace(self.opt.trace, max_points=max(1, self.points_left))

    def spend(self, points: int) -> None:
        """``points`` more in the answer; once its budget of values is spent the search
        stops for size (``answer_size_reached``: reason ``budget``)."""
        if self.points_left is None:
            return
        self.points_left -= points
        if self.points_left <= 1:
            self.report["answer_size_reached"] = True
            self.report["answer_values_max"] = self.opt.max_values

    def values_in_time(self) -> int | None:
        """The values an answer made now may carry (None: no budget): its budget, or what
        maps in the time left and ``ANSWER_TIME_S`` past the deadline where that is more (a
        closed form's walks, made in a moment; traced curves keep to the budget, since
        tracing spends the time left)."""
        if self.opt.max_values is None:
            return None
        left = self.deadline.remaining()
        if left == float("inf"):
            return self.opt.max_values
        return max(self.opt.max_values, int((left + ANSWER_TIME_S) / ANSWER_SECONDS_PER_VALUE))

    def size_reached(self) -> bool:
        """True once the answer's budget of values is spent (nothing more is traced)."""
        return bool(self.report.get("answer_size_reached"))

    def out_of_time(self) -> bool:
        """True (and remembered) once the deadline has passed: the search stops there."""
        if not self.timed_out and self.deadline.expired():
            self.timed_out = True
        return self.timed_out

    def _trace(self, u: np.ndarray, t: np.ndarray, close: bool = True) -> Curve:
        curve = trace_curve(self.cons, u, t, self.tol, self.trace_options(), close=close,
                            deadline=self.deadline)
        self.timed_out = self.timed_out or curve.stop == STOP_TIME
        self.spend(len(curve.points) + 1)  # (+1: a closed walk repeats its first point)
        return curve

    def finish(self, degenerate: bool, segments_done: bool = True, agreed: bool = True,
               argument: tuple[Argument | None, str | None] = (None, None),
               curves_needed: bool = True, seeds_needed: bool = True,
               **details: object) -> SearchReport:
        """The report of the search: what was done (``self.report`` and ``details``), and the
        flags that decide whether it is complete (:class:`engine.model.report.SearchReport`);
        ``agreed`` False: an independent count disagrees with what was traced (unresolved);
        ``argument``: what proves that nothing was missed, and the sentence that says so
        (:func:`engine.space.configuration_space.proof.argument`); ``curves_needed`` False: the
        argument does not rest on the traced curves (critical points proved by the homotopy or
        the chain rules), so budgets, open curves and the deadline while tracing do not make
        the answer incomplete; ``seeds_needed`` False: the argument counts the components
        and that many were traced (the chain rules), so seeds left untried (the component and
        assembly budgets) do not either."""
        if argument[0] is not None and not curves_needed:
            return SearchReport({**self.report, **details}, degenerate=degenerate,
                                time_budget_s=granted(self.deadline), argument=argument[0],
                                argument_detail=argument[1])
        budget = bool((seeds_needed and (self.report.get("component_budget_reached")
                                         or self.report.get("assemblies_truncated")))
                      or self.size_reached()
                      or any(BUDGET_STOPS.search(c.stop) for c in self.curves))
        unresolved = bool(self.report.get("open_curves", 0)) or not segments_done or not agreed
        return SearchReport({**self.report, **details}, timed_out=self.timed_out, budget=budget,
                            degenerate=degenerate, unresolved=unresolved,
                            time_budget_s=granted(self.deadline), argument=argument[0],
                            argument_detail=argument[1])

    def _rebuild_tree(self) -> None:
        """The curves changed: the tree is rebuilt when next read."""
        self._tree_stale = True

    def _fresh_tree(self) -> None:
        if not self._tree_stale:
            return
        self._tree_stale = False
        if not self.curves:
            self._tree = None
            return
        pts = [c.array("points") for c in self.curves]
        self._tree = cKDTree(np.vstack(pts))
        self._tree_owner = np.concatenate([np.full(len(p), k) for k, p in enumerate(pts)])
        # index of each curve's first point in the tree: a point's offset in its curve
        self._tree_first = np.concatenate([[0], np.cumsum([len(p) for p in pts])[:-1]])

    @property
    def tree(self) -> cKDTree | None:
        """The k-d tree of the points of every traced curve (None before the first)."""
        self._fresh_tree()
        return self._tree

    @tree.setter
    def tree(self, value: cKDTree | None) -> None:
        self._tree, self._tree_stale = value, False

    @property
    def tree_owner(self) -> np.ndarray:
        """The curve owning each point of :attr:`tree`."""
        self._fresh_tree()
        return self._tree_owner

    @property
    def tree_first(self) -> np.ndarray:
        """Index in :attr:`tree` of each curve's first point."""
        self._fresh_tree()
        return self._tree_first

    def _tree_point(self, i: int) -> tuple[Curve, int]:
        """The curve owning tree point ``i`` and the point's index along it."""
        owner = int(self.tree_owner[i])
        return self.curves[owner], int(i) - int(self.tree_first[owner])

    def on_traced(self, u: np.ndarray) -> bool:
        """True when ``u`` lies on a traced curve: near its polyline, and the hyperplane
        correction from the closest point of some pass of a curve near ``u`` (among its
        ``NEAREST`` nearest curve points) towards ``u`` lands on ``u``."""
        near = self._nearest_traced(u)
        if near is None:
            return False
        dist, owner, offset = near
        keep = dist <= self.h_max
        dist, owner, offset = dist[keep], owner[keep], offset[keep]
        if not len(dist):
            return False
        tested = np.zeros(len(dist), dtype=bool)
        for k in np.unique(owner):  # (pass minima along each curve's own points)
            mine = owner == k
            pts = self._curve_cache(self.curves[int(k)])[1]
            tested[mine] = pass_minima(pts, u[None], offset[mine][None])[0]
        for k, i in zip(owner[tested], offset[tested], strict=True):
            curve = self.curves[int(k)]
            p, t = curve.points[int(i)], curve.tangents[int(i)]
            v = p + ((u - p) @ t) * t
            w, ok, _ = correct(self.cons, v, t, self.tol)
            if ok and np.linalg.norm(w - u) <= SAME_POINT_REL * self.scale:
                return True
        return False

    def _nearest_traced(self, u: np.ndarray
                        ) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
        """The ``NEAREST`` traced points nearest to ``u`` (distances ascending, as the tree of
        all curves gives them; those beyond ``QUERY_BOUND_REL h_max`` may be left out): their
        distances, curves and offsets along them, None before any curve. Up to
        :data:`FOREST_MAX` curves each curve's own tree is asked (built once per curve): the
        tree of all curves is rebuilt after every traced curve, which on long chains (10^4
        points of 200 coordinates per curve) cost more than the tracing."""
        if not self.curves:
            return None
        if len(self.curves) > FOREST_MAX:
            tree = self.tree
            assert tree is not None
            dist, idx = tree.query(u, k=min(NEAREST, tree.n))
            idx = np.atleast_1d(idx)
            owner = self.tree_owner[idx]
            return np.atleast_1d(dist), owner, idx - self.tree_first[owner]
        found = []
        bound = QUERY_BOUND_REL * self.h_max
        for k, curve in enumerate(self.curves):
            tree = self._curve_cache(curve)[3]
            dist, idx = tree.query(u, k=min(NEAREST, tree.n), distance_upper_bound=bound)
            dist, idx = np.atleast_1d(dist), np.atleast_1d(idx)
            near = np.isfinite(dist)
            found.append((dist[near], np.full(int(near.sum()), k), idx[near]))
        dist = np.concatenate([f[0] for f in found])
        order = np.argsort(dist, kind="stable")[:NEAREST]  # (ties: the first curve first)
        return (dist[order], np.concatenate([f[1] for f in found])[order],
                np.concatenate([f[2] for f in found])[order])

    def trace_from(self, u: np.ndarray) -> Curve | None:
        # The zero mode at a seed: on large linkages by the engine's sparse method (shift-invert
        # Lanczos, same rank rule), a dense SVD costs O(M^3) per traced curve (0.1-0.2 s at
        # M = 200 to 400, more than tracing the curve).
        sparse = self.cons.n_free > SPARSE_SEED_RIGIDITY_MIN_FREE
        if sparse and self.cons.n_free * SPARSE_SEED_SECONDS_PER_FREE > self.deadline.remaining():
            self.timed_out = True  # (the zero mode alone would run past the deadline)
            return None
        try:
            rig = first_order(self.linkage.with_positions(self.linkage.positions_of(u)),
                              self.tol, sparse=True if sparse else None, deadline=self.deadline)
        except OutOfTime:
            self.timed_out = True
            return None
        if rig.critical or rig.zero_modes.shape[0] != 1:
            return None
        curve = self._trace(u, rig.zero_modes[0])
        if curve.stop != "closed" and not self.size_reached() and not self.out_of_time():
            back = self._trace(u, -rig.zero_modes[0], close=False)
            curve = Curve(
                points=back.points[::-1][:-1] + curve.points,
                tangents=[-t for t in back.tangents[::-1][:-1]] + curve.tangents,
                signs=back.signs[::-1][:-1] + curve.signs,
                logdets=back.logdets[::-1][:-1] + curve.logdets,
                stop=f"open ({back.stop}; {curve.stop})",
            )
        return curve

    def _curve_cache(self, curve: Curve) -> tuple[Curve, np.ndarray, np.ndarray, cKDTree]:
        """``curve``, its points and tangents as arrays and the k-d tree of its points (built
        once per curve, again only if it grew)."""
        cached = self._curve_arrays.get(id(curve))
        if cached is None or cached[0] is not curve or len(cached[1]) != len(curve.points):
            pts = curve.array("points")
            cached = (curve, pts, curve.array("tangents"), cKDTree(pts))
            self._curve_arrays[id(curve)] = cached
        return cached

    def nearest_points(self, us: np.ndarray) -> list[tuple[Curve, int]] | None:
        """The traced curve point nearest to each row of ``us`` (K, M): its curve and its
        index along it (None before any curve), all rows in one query per tree. Small
        linkages, and up to :data:`FOREST_MAX` curves, ask each curve's own k-d tree
        (:meth:`on_curve` and :meth:`on_traced` have built them), so the tree of all curves is
        never built; more curves of a large linkage :attr:`tree`."""
        us = np.asarray(us, dtype=float).reshape(-1, self.cons.n_free)
        if self.batched is None and len(self.curves) > FOREST_MAX:
            tree = self.tree
            if tree is None:
                return None
            _, idx = tree.query(us)
            return [self._tree_point(int(i)) for i in np.atleast_1d(idx)]
        if not self.curves:
            return None
        best = np.full(len(us), np.inf)
        owner = np.zeros(len(us), dtype=int)
        where = np.zeros(len(us), dtype=int)
        for k, curve in enumerate(self.curves):
            d, i = self._curve_cache(curve)[3].query(us)
            closer = np.atleast_1d(d) < best  # (the first curve on a tie)
            best[closer] = np.atleast_1d(d)[closer]
            owner[closer], where[closer] = k, np.atleast_1d(i)[closer]
        return [(self.curves[int(k)], int(i)) for k, i in zip(owner, where, strict=True)]

    def on_curve(self, us: np.ndarray, curve: Curve) -> np.ndarray:
        """:meth:`on_traced` for a stack of points (K, M) against one curve, vectorised (small
        linkages): each point is tested from the closest point of each pass of ``curve`` among
        its ``NEAREST`` nearest within the step bound (:func:`pass_minima`), and a point
        counts as on the curve only when a hyperplane correction lands on it."""
        assert self.batched is not None  # only called for small linkages
        _, pts, tans, tree = self._curve_cache(curve)
        k = min(NEAREST, len(pts))
        # Only neighbours within the step bound can be candidates: the query looks no further
        # (most seeds are far from a given curve, and the pruned search is an order of
        # magnitude faster); those it finds are the same nearest ones, in the same order, and
        # the rest (none, distance inf) are no candidates either way.
        dist, idx = tree.query(us, k=k, distance_upper_bound=QUERY_BOUND_REL * self.h_max)
        dist, idx = dist.reshape(len(us), k), idx.reshape(len(us), k)
        near = dist <= self.h_max
        idx = np.where(near, idx, 0)  # (missing neighbours are numbered len(pts))
        candidate = np.zeros_like(near)
        close = np.flatnonzero(near.any(axis=1))  # (pass minima row by row: only these)
        candidate[close] = near[close] & pass_minima(pts, us[close], idx[close])
        on = np.zeros(len(us), dtype=bool)
        # nearest pass first; the next only where that one failed
        for r in np.flatnonzero(candidate.any(axis=0)):
            which = np.flatnonzero(~on & candidate[:, r])
            if not len(which):
                continue
            p, t = pts[idx[which, r]], tans[idx[which, r]]
            u = us[which]
            v = p + np.einsum("ij,ij->i", u - p, t)[:, None] * t
            w, ok = self.batched.correct(v, t, self.tol)
            on[which[ok & (np.linalg.norm(w - u, axis=1) <= SAME_POINT_REL * self.scale)]] = True
        return on

    def trace_all(self, start: np.ndarray | None, extra: np.ndarray | None = None,
                  isolated: np.ndarray | None = None, sweeps: bool = True) -> None:
        """Trace a curve from every seed not on a curve already traced: ``start``, then
        ``extra`` (K, M) (e.g. the witness points of a proof), then the rotor sweeps and the
        random projections of :mod:`engine.space.assembly`. Seeds within ``ISOLATED_REL`` of
        a point of ``isolated`` (L, M) (rigid critical points: isolated points of the space,
        where no curve passes) are skipped: the tracer would crawl around rounding there.
        ``sweeps`` False: ``start`` and ``extra`` alone (a proof's seeds meet every component)."""
        # Seeds are generated on demand: once the component budget is reached the rest (on long
        # chains the costly random projections) is never computed; the report then counts the
        # seeds generated up to that point.
        batch = self.batched is not None
        found: Iterator[np.ndarray] = iter_seeds(
            self.linkage, self.tol, self.report, self.opt.angles, self.opt.assembly_budget,
            self.opt.random_starts, self.opt.seed, self.opt.max_swept_rotors,
            with_random=not batch, deadline=self.deadline,
        ) if sweeps else iter(())
        truncated = False
        first = [start] if start is not None else []
        first += [] if extra is None else list(extra)
        # Small linkages: the rotor sweeps' seeds are generated up front (they are cheap) and
        # tested in chunks, each against every curve traced so far in one batch per curve
        # (``tested`` counts the curves a seed has been tested against), so a seed reached in
        # the loop below is tested against every traced curve; the random projections (the
        # costly seeds, last in order) are appended when the loop reaches them, as the lazy
        # path generates them. Large ones take seeds lazily and test them one by one.
        m = self.cons.n_free
        stack = np.array(list(itertools.chain(first, found)) if batch else [],
                         dtype=float).reshape(-1, m)
        tail = iter_random_seeds(self.linkage, self.tol, self.report, self.opt.random_starts,
                                 self.opt.seed, self.deadline) if batch and sweeps else None
        covered = np.zeros(len(stack), dtype=bool)
        tested = np.zeros(len(stack), dtype=int)

        def points() -> Iterator[tuple[int, np.ndarray]]:
            nonlocal stack, covered, tested, tail
            if not batch:
                yield from enumerate(itertools.chain(first, found))
                return
            n = 0
            while True:
                if n == len(stack) and tail is not None:
                    more = np.array(list(tail), dtype=float).reshape(-1, m)
                    tail = None
                    stack = np.concatenate([stack, more])
                    covered = np.concatenate([covered, np.zeros(len(more), dtype=bool)])
                    tested = np.concatenate([tested, np.zeros(len(more), dtype=int)])
                if n >= len(stack):
                    return
                yield n, stack[n]
                n += 1

        for n, u in points():
            if self.out_of_time() or self.size_reached():
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
            if isolated is not None and len(isolated) and np.linalg.norm(
                    isolated - u, axis=1).min() <= ISOLATED_REL * self.scale:
                continue
            if len(self.curves) >= self.opt.max_components:
                truncated = True
                break
            curve = self.trace_from(u)
            if curve is None:
                continue
            self.curves.append(curve)
            self._rebuild_tree()  # (lazy: built when next read; on_curve has a tree per curve)
        if self.report.get("seeding") == STOPPED_BY_TIME:
            self.timed_out = True  # seeds the deadline kept from being made
        self.report["curves_traced"] = len(self.curves)
        self.report["component_budget_reached"] = truncated
        self.report["open_curves"] = sum(c.stop != "closed" for c in self.curves)
