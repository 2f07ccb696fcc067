"""The performance shortcuts against the slow or reference paths they replace."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from scipy.optimize import least_squares

from engine.catalogue.presets import build_preset
from engine.design.critical_values import GRID_OFFSET, _validate
from engine.design.slice_curves import _onto_solutions, _System
from engine.local.critical import AugmentedSystem
from engine.model.batched import BatchedConstraints
from engine.model.constraints import Constraints
from engine.model.hessian import dense_stress_hessian
from engine.model.tolerances import Tolerances
from engine.space.assembly import seeds
from engine.space.configuration_space import (
    SpaceOptions,
    _Explorer,
    explore,
    find_critical_points,
)
from engine.space.trace import correct

TOL = Tolerances()
FAST = SpaceOptions(angles=24, random_starts=4)
LINKAGES = {
    "four-bar": ("four-bar", {"L2": 1.2}),
    "equilateral four-bar": ("four-bar", {}),
    "three-rotor": ("three-rotor", {}),
    "gated chain": ("gated-kl-chain", {"n": 4, "gate": 2}),
    "kl-chain 6": ("kl-chain", {"n": 6}),
}


@pytest.mark.parametrize("name", list(LINKAGES))
def test_dense_stress_hessian_equals_the_sparse_assembly(name):
    cons = Constraints(build_preset(*LINKAGES[name]))
    rng = np.random.default_rng(5)
    for _ in range(3):
        sigma = rng.normal(size=cons.n_constraints)
        ref = cons.stress_hessian(sigma, sparse=True).toarray()
        assert np.allclose(dense_stress_hessian(cons, sigma), ref, rtol=0, atol=1e-14)


@pytest.mark.parametrize("name", list(LINKAGES))
def test_batched_constraints_and_correction_match_the_scalar_ones(name):
    lk = build_preset(*LINKAGES[name])
    cons = Constraints(lk)
    batch = BatchedConstraints(cons)
    rng = np.random.default_rng(11)
    u0 = lk.coordinates()
    us = u0 + 0.02 * rng.normal(size=(12, cons.n_free))
    ts = rng.normal(size=us.shape)
    ts /= np.linalg.norm(ts, axis=1)[:, None]
    assert np.allclose(batch.squared_lengths(us), [cons.squared_lengths(u) for u in us])
    assert np.allclose(batch.jacobians(us), [cons.jacobian(u, sparse=False) for u in us])
    w, ok = batch.correct(us, ts, TOL)
    for k in range(len(us)):
        w1, ok1, _ = correct(cons, us[k], ts[k], TOL)
        assert ok[k] == ok1
        if ok1:
            assert np.allclose(w[k], w1, atol=1e-10)


@pytest.mark.parametrize("name", ["four-bar", "three-rotor", "gated chain"])
@pytest.mark.slow
def test_batched_seed_test_agrees_with_on_traced(name):
    """Every seed the batch marks as on a curve is on it by the one-at-a-time test too, and
    the seeds the batch leaves are (almost all) off every traced curve."""
    lk = build_preset(*LINKAGES[name])
    ex = _Explorer(lk, TOL, FAST)
    ex.trace_all(lk.coordinates())
    found = seeds(lk, TOL, FAST.angles, FAST.assembly_budget, FAST.random_starts, FAST.seed,
                  FAST.max_swept_rotors)
    stack = np.array(found.points)
    batch = np.zeros(len(stack), dtype=bool)
    for curve in ex.curves:
        batch |= ex.on_curve(stack, curve)
    single = np.array([ex.on_traced(u) for u in stack])
    assert np.all(single <= batch)  # nothing the reference finds is missed
    assert batch.sum() >= 0.95 * len(stack)  # and nearly every seed is on a traced curve


@pytest.mark.parametrize("name", ["four-bar", "equilateral four-bar", "three-rotor",
                                  "gated chain"])
@pytest.mark.slow
def test_find_critical_points_equals_explore(name):
    lk = build_preset(*LINKAGES[name])
    # explore's closed form (engine.space.dyads) searches along its own walks; the tracer's curves
    # are what find_critical_points searches, so compare with explore on those
    full = explore(lk, TOL, replace(FAST, closed_form=False))
    # (the closed-form candidates are cross-checked in tests/engine/space/dyads/test_candidates.py)
    fast = find_critical_points(lk, TOL, replace(FAST, critical_closed_form=False))
    assert len(fast.critical_points) == len(full.critical_points)
    for a, b in zip(fast.critical_points, full.critical_points, strict=True):
        assert np.allclose(a.u, b.u, atol=1e-12) and a.kind == b.kind
    assert fast.degenerate == full.degenerate
    if full.search["complete"]:
        assert fast.search["complete"]
    if "near_misses_from" in fast.search:
        # the chain rules prove that there is no critical point (the gated chain driven from
        # its gate): only the component through the given configuration is traced, and the
        # near misses lie on it, the one explore traces from there too (issue 30)
        assert fast.search["curves_traced"] == 1 and fast.near_misses
        (own,) = [c for c in full.components if c.through_start]
        for m in fast.near_misses:
            assert np.linalg.norm(own.points - m.u, axis=1).min() <= 1e-9
        return
    assert len(fast.near_misses) == len(full.near_misses)
    for a, b in zip(fast.near_misses, full.near_misses, strict=True):
        assert np.allclose(a.critical_u, b.critical_u, atol=1e-12)
    for key in ("curves_traced", "critical_candidates", "critical_points_found", "seeds"):
        assert fast.search[key] == full.search[key]


def test_three_rotor_critical_points_fast_path():
    """The critical-points endpoint's path finds the 12 branch points (cross-checked against an
    independent multistart in configuration_space/test_search.py)."""
    res = find_critical_points(build_preset("three-rotor"), TOL)
    assert len(res.critical_points) == 12
    assert all(cp.kind == "branch" for cp in res.critical_points)
    assert res.search["complete"] and not res.degenerate


def test_newton_onto_the_critical_set_agrees_with_least_squares():
    """From near misses of a four-bar, the minimum-norm Newton projection and the trust-region
    least squares it replaces both land on G = 0, on the same critical plane."""
    lk = build_preset("four-bar", {"L2": 1.2})
    axes = _validate(lk, [("L2", 0.3, 2.2), ("L3", 0.3, 2.2)])
    sys = _System(lk, axes)
    res = find_critical_points(lk, TOL, FAST)
    assert res.near_misses
    for m in res.near_misses:
        x0 = np.concatenate([m.critical_u, m.critical_sigma, lk.lengths[[a.bar for a in axes]]])
        x = _onto_solutions(sys, x0)
        ref = least_squares(sys.g, x0, jac=sys.dg, method="trf", xtol=1e-15, ftol=1e-15,
                            gtol=1e-15, max_nfev=200).x
        assert np.max(np.abs(sys.g(x))) <= 1e-12
        assert np.max(np.abs(sys.g(ref))) <= 1e-9
        # both on a plane a +- L1 +- L2 +- L3 = 0 (a = L1 = 1)
        for p in (x[-2:], ref[-2:]):
            assert min(abs(1 + e1 + e2 * p[0] + e3 * p[1])
                       for e1 in (1, -1) for e2 in (1, -1) for e3 in (1, -1)) <= 1e-9


def test_seed_grid_avoids_the_diagonal():
    """In a box with equal ranges the critical values of symmetric linkages lie on L_x = L_y
    (the four-bar with a = L1 in its (L2, L3) slice): no seed of the offset grid is there."""
    n = 5
    frac = (np.arange(n) + GRID_OFFSET[:, None]) / n  # (2, n): seed fractions per axis
    assert np.min(np.abs(frac[0][:, None] - frac[1][None, :])) > 1e-3
    assert np.all((frac > 0) & (frac < 1))


@pytest.mark.parametrize("name", list(LINKAGES))
def test_augmented_system_equals_its_definition(name):
    """F and dF of the refinement against the expressions of the module docstring, built from
    the reference Constraints methods (sparse Hessian assembly)."""
    lk = build_preset(*LINKAGES[name])
    cons = Constraints(lk)
    sys = AugmentedSystem(cons)
    m, e = cons.n_free, cons.n_constraints
    lengths = lk.lengths[cons.bars]
    scale = 2.0 * float(np.median(lengths))
    rng = np.random.default_rng(3)
    for _ in range(3):
        u = lk.coordinates() + 0.1 * rng.normal(size=m)
        s = rng.normal(size=e)
        x = np.concatenate([u, s])
        jac = cons.jacobian(u, sparse=False)
        f_ref = np.concatenate([(cons.squared_lengths(u) - cons.targets) / (2 * lengths),
                                jac.T @ s / scale, [s @ s - 1.0]])
        hess = cons.stress_hessian(s, sparse=True).toarray()
        d_ref = np.vstack([
            np.hstack([jac / (2 * lengths)[:, None], np.zeros((e, e))]),
            np.hstack([hess / scale, jac.T / scale]),
            np.concatenate([np.zeros(m), 2 * s])[None, :],
        ])
        assert np.allclose(sys.residual(x), f_ref, rtol=1e-13, atol=1e-13)
        assert np.allclose(sys.jacobian(x), d_ref, rtol=1e-13, atol=1e-13)
        # and the Jacobian is the derivative of the residual (central differences)
        h = 1e-6
        fd = np.column_stack([(sys.residual(x + h * ei) - sys.residual(x - h * ei)) / (2 * h)
                              for ei in np.eye(m + e)])
        assert np.allclose(sys.jacobian(x), fd, atol=1e-6)


@pytest.mark.parametrize("name", ["four-bar", "equilateral four-bar", "three-rotor",
                                  "kl-chain 6"])
def test_batched_seed_loop_traces_what_the_one_at_a_time_loop_traces(name):
    lk = build_preset(*LINKAGES[name])
    opt = SpaceOptions(angles=24, random_starts=4, max_components=4 if "kl" in name else 32)
    runs = []
    for batched in (True, False):
        ex = _Explorer(lk, TOL, opt)
        if not batched:
            ex.batched = None  # the reference: on_traced for one seed at a time
        ex.trace_all(lk.coordinates())
        runs.append(ex)
    fast, ref = runs
    assert fast.batched is not None
    assert len(fast.curves) == len(ref.curves)
    # Small linkages generate every seed up front; the one-at-a-time loop generates them on
    # demand and stops at the component budget, so then it has generated fewer.
    lazy = {"seeds", "rotor_sweeps", "random_starts_projected"}
    same = set(ref.report) - (lazy if ref.report["component_budget_reached"] else set())
    assert {k: fast.report[k] for k in same} == {k: ref.report[k] for k in same}
    assert set(fast.report) == set(ref.report)
    assert ref.report["seeds"] <= fast.report["seeds"]
    for a, b in zip(fast.curves, ref.curves, strict=True):
        assert a.stop == b.stop and len(a.points) == len(b.points)
        assert np.allclose(a.points[0], b.points[0])


class _NoCache(dict):
    """A curve-array cache that never keeps anything: every test rebuilds its arrays."""

    def __setitem__(self, key, value):
        pass


@pytest.mark.parametrize("name", ["four-bar", "three-rotor", "gated chain", "kl-chain 6"])
def test_the_curve_array_cache_changes_no_membership_test(name):
    """on_curve with each traced curve's arrays and k-d tree built once (the explorer's cache)
    marks the same seeds, and the seed loop traces the same curves, as with them rebuilt for
    every call."""
    lk = build_preset(*LINKAGES[name])
    opt = SpaceOptions(angles=24, random_starts=4, max_components=4 if "kl" in name else 32)
    runs = []
    for cached in (True, False):
        ex = _Explorer(lk, TOL, opt)
        if not cached:
            ex._curve_arrays = _NoCache()
        ex.trace_all(lk.coordinates())
        runs.append(ex)
    fast, ref = runs
    assert fast._curve_arrays and not ref._curve_arrays
    assert fast.report == ref.report
    assert len(fast.curves) == len(ref.curves) > 0
    for a, b in zip(fast.curves, ref.curves, strict=True):
        assert a.stop == b.stop
        assert np.array_equal(np.array(a.points), np.array(b.points))
    stack = np.array(seeds(lk, TOL, opt.angles, opt.assembly_budget, opt.random_starts,
                           opt.seed, opt.max_swept_rotors).points)
    for curve in fast.curves:
        first = fast.on_curve(stack, curve)
        again = fast.on_curve(stack, curve)  # from the cache
        assert np.array_equal(first, ref.on_curve(stack, curve))
        assert np.array_equal(again, first)


@pytest.mark.parametrize("name", list(LINKAGES))
@pytest.mark.parametrize("budget", [4, 32])
def test_random_seeds_appended_when_reached_trace_what_all_seeds_up_front_trace(
        name, budget, monkeypatch):
    """The small linkages' seed loop with the random projections appended only when the loop
    reaches them, against the loop over every seed generated up front (as it was): the same
    curves, point for point; the same report, but for the counts of the seeds generated when
    the component budget stops the loop before the random ones (then never projected)."""
    import engine.space.configuration_space.explorer as explorer_module
    from engine.space import assembly

    lk = build_preset(*LINKAGES[name])
    opt = SpaceOptions(angles=24, random_starts=4, max_components=budget)
    fast = _Explorer(lk, TOL, opt)
    fast.trace_all(lk.coordinates())
    assert fast.batched is not None

    def everything(*args, with_random=True, **kw):
        return assembly.iter_seeds(*args, with_random=True, **kw)

    def nothing(*args):
        return iter(())

    monkeypatch.setattr(explorer_module, "iter_seeds", everything)
    monkeypatch.setattr(explorer_module, "iter_random_seeds", nothing)
    ref = _Explorer(lk, TOL, opt)
    ref.trace_all(lk.coordinates())
    assert ref.report["random_starts_projected"] > 0
    assert len(fast.curves) == len(ref.curves) > 0
    for a, b in zip(fast.curves, ref.curves, strict=True):
        assert a.stop == b.stop
        assert np.array_equal(np.array(a.points), np.array(b.points))
    counts = {"seeds", "random_starts_projected"}
    same = set(ref.report) - (counts if ref.report["component_budget_reached"] else set())
    assert {k: fast.report[k] for k in same} == {k: ref.report[k] for k in same}
    assert set(fast.report) == set(ref.report)
    if ref.report["component_budget_reached"]:
        skipped = ref.report["random_starts_projected"] - fast.report["random_starts_projected"]
        assert fast.report["seeds"] == ref.report["seeds"] - skipped
    # and the explorations: the same critical points and components
    for search in (explore, find_critical_points):
        monkeypatch.undo()
        one = search(lk, TOL, replace(opt, closed_form=False))
        monkeypatch.setattr(explorer_module, "iter_seeds", everything)
        monkeypatch.setattr(explorer_module, "iter_random_seeds", nothing)
        two = search(lk, TOL, replace(opt, closed_form=False))
        assert len(one.critical_points) == len(two.critical_points)
        for p, q in zip(one.critical_points, two.critical_points, strict=True):
            assert np.array_equal(p.u, q.u) and p.kind == q.kind
        if search is explore:
            assert len(one.components) == len(two.components)


@pytest.mark.parametrize("name", list(LINKAGES))
def test_the_seed_loop_builds_the_tree_of_its_curves_once(name, monkeypatch):
    """The seed loop never builds the k-d tree of all traced curves, neither small linkages'
    (on_curve keeps a tree per curve) nor the one-at-a-time loop of large ones (on_traced asks
    each curve's tree up to FOREST_MAX curves): it is built once, when first read, and it is
    the same tree for both loops."""
    lk = build_preset(*LINKAGES[name])
    opt = SpaceOptions(angles=24, random_starts=4, max_components=4)
    builds = {}
    fresh = _Explorer._fresh_tree

    def counted(self):
        if self._tree_stale and self.curves:  # a build, not a read of the built tree
            builds[id(self)] = builds.get(id(self), 0) + 1
        fresh(self)

    monkeypatch.setattr(_Explorer, "_fresh_tree", counted)
    fast, ref = _Explorer(lk, TOL, opt), _Explorer(lk, TOL, opt)
    ref.batched = None
    for ex in (fast, ref):
        ex.trace_all(lk.coordinates())
    assert id(fast) not in builds and id(ref) not in builds
    assert len(ref.curves) == len(fast.curves) > 0
    assert np.array_equal(fast.tree_owner, ref.tree_owner)
    assert np.array_equal(fast.tree_first, ref.tree_first)
    assert np.array_equal(fast.tree.data, ref.tree.data)
    assert builds[id(fast)] == builds[id(ref)] == 1


def _on_curve_full_query(ex, us, curve):
    """Explorer.on_curve as it was: the 16 nearest curve points however far, pass minima of
    every row, every rank of neighbour."""
    from scipy.spatial import cKDTree

    from engine.model.tolerances import SAME_POINT_REL
    from engine.space.configuration_space.explorer import NEAREST, pass_minima

    pts, tans = np.array(curve.points), np.array(curve.tangents)
    k = min(NEAREST, len(pts))
    dist, idx = cKDTree(pts).query(us, k=k)
    dist, idx = dist.reshape(len(us), k), idx.reshape(len(us), k)
    candidate = (dist <= ex.h_max) & pass_minima(pts, us, idx)
    on = np.zeros(len(us), dtype=bool)
    for r in range(k):
        which = np.flatnonzero(~on & candidate[:, r])
        if not len(which):
            continue
        p, t = pts[idx[which, r]], tans[idx[which, r]]
        u = us[which]
        v = p + np.einsum("ij,ij->i", u - p, t)[:, None] * t
        w, ok = ex.batched.correct(v, t, ex.tol)
        on[which[ok & (np.linalg.norm(w - u, axis=1) <= SAME_POINT_REL * ex.scale)]] = True
    return on


@pytest.mark.parametrize("name", list(LINKAGES))
def test_the_bounded_curve_query_marks_what_the_full_query_marks(name, monkeypatch):
    """on_curve's k-d tree query stops at (a little beyond) the step bound, and only rows and
    ranks of neighbours with a candidate are looked at: the same points are on each curve as
    with the 16 nearest points looked up however far and every row and rank tested (the code
    it replaces), for the seeds, for points at about the step bound from the curves and for
    points of the curves between their traced points."""
    import engine.space.configuration_space.explorer as explorer_module

    lk = build_preset(*LINKAGES[name])
    opt = SpaceOptions(angles=24, random_starts=4, max_components=4)
    ex = _Explorer(lk, TOL, opt)
    ex.trace_all(lk.coordinates())
    assert ex.curves
    rng = np.random.default_rng(7)
    stack = np.array(seeds(lk, TOL, opt.angles, opt.assembly_budget, opt.random_starts,
                           opt.seed, opt.max_swept_rotors).points)
    pts = np.vstack([np.array(c.points) for c in ex.curves])
    pick = pts[rng.integers(0, len(pts), 200)]
    away = rng.normal(size=pick.shape)
    away /= np.linalg.norm(away, axis=1, keepdims=True)
    near = pick + ex.h_max * rng.uniform(0.9, 1.1, (len(pick), 1)) * away
    on_it = pick + 1e-3 * ex.h_max * away  # (projected or not: some land, some do not)
    # points of the curves between their traced points (up to a step from the nearest)
    between = []
    for c in ex.curves:
        a, b, t = np.array(c.points[:-1]), np.array(c.points[1:]), np.array(c.tangents[:-1])
        w, ok = ex.batched.correct(a + rng.uniform(0.2, 0.8, (len(a), 1)) * (b - a), t, TOL)
        between.append(w[ok])
    us = np.vstack([stack, near, on_it, pts[::7], *between])
    fast = [ex.on_curve(us, c) for c in ex.curves]
    ref = [_on_curve_full_query(ex, us, c) for c in ex.curves]
    for a, b in zip(fast, ref, strict=True):
        assert np.array_equal(a, b)
    monkeypatch.setattr(explorer_module, "QUERY_BOUND_REL", np.inf)
    for c, b in zip(ex.curves, ref, strict=True):
        assert np.array_equal(ex.on_curve(us, c), b)
    assert any(a.any() for a in ref) and not all(a.all() for a in ref)
def test_a_curves_arrays_are_its_lists_converted():
    """``Curve.array``: ``np.array`` of the field, read-only, built once, rebuilt when the
    field grows or is replaced by another list."""
    lk = build_preset("four-bar", {"L2": 1.2})
    ex = _Explorer(lk, TOL, FAST)
    curve = ex.trace_from(lk.coordinates())
    assert curve is not None and len(curve.points) > 10
    for name in ("points", "tangents", "signs", "logdets"):
        arr = curve.array(name)
        assert np.array_equal(arr, np.array(getattr(curve, name)))
        assert not arr.flags.writeable
        assert curve.array(name) is arr  # built once
    before = curve.array("points")
    curve.append(curve.points[0] + 1.0, curve.tangents[0], 1, 0.0)
    grown = curve.array("points")
    assert len(grown) == len(before) + 1
    assert np.array_equal(grown, np.array(curve.points))
    curve.points = curve.points[:5]
    assert np.array_equal(curve.array("points"), np.array(curve.points[:5]))


def _eager_tree(ex) -> None:
    """The explorer's tree as it was built before it became lazy: at once, from the lists."""
    from scipy.spatial import cKDTree

    pts = [np.array(c.points) for c in ex.curves]
    ex.tree = cKDTree(np.vstack(pts))
    ex._tree_owner = np.concatenate([np.full(len(p), k) for k, p in enumerate(pts)])
    ex._tree_first = np.concatenate([[0], np.cumsum([len(p) for p in pts])[:-1]])


def _random_four_bars(count: int, seed: int) -> list[tuple[str, dict[str, float]]]:
    rng = np.random.default_rng(seed)
    out: list[tuple[str, dict[str, float]]] = []
    while len(out) < count:
        l1, l2, l3 = (float(x) for x in rng.uniform(0.3, 2.2, 3))
        links = sorted([1.0, l1, l2, l3])
        if links[3] < links[0] + links[1] + links[2]:
            out.append(("four-bar", {"L1": l1, "L2": l2, "L3": l3}))
    return out


@pytest.mark.parametrize("case", [LINKAGES[k] for k in ("four-bar", "equilateral four-bar",
                                                        "three-rotor", "kl-chain 6")]
                         + _random_four_bars(3, seed=151))
def test_the_lazy_tree_and_curve_arrays_change_no_exploration(case, monkeypatch):
    """The explorer's k-d tree built when first read (and the curves' arrays built once)
    gives the same tree, and the same exploration (components, critical points, segments,
    near misses, report), as the tree built from the lists after every traced curve."""
    import engine.space.configuration_space.explorer as explorer_module

    lk = build_preset(*case)
    opt = SpaceOptions(closed_form=False, angles=24, random_starts=4,
                       max_components=4 if "kl" in case[0] else 32)
    ex = _Explorer(lk, TOL, opt)
    ex.trace_all(lk.coordinates())
    lazy = (ex.tree.data.copy(), ex.tree_owner.copy(), ex.tree_first.copy())
    _eager_tree(ex)
    assert np.array_equal(lazy[0], ex.tree.data)
    assert np.array_equal(lazy[1], ex.tree_owner)
    assert np.array_equal(lazy[2], ex.tree_first)
    fast = explore(lk, TOL, opt)
    monkeypatch.setattr(explorer_module.Explorer, "_rebuild_tree", _eager_tree)
    ref = explore(lk, TOL, opt)
    assert fast.search == ref.search
    assert len(fast.components) == len(ref.components)
    for a, b in zip(fast.components, ref.components, strict=True):
        assert np.array_equal(a.points, b.points)
        assert (a.closed, a.through_start, a.critical_points, a.segments) == \
            (b.closed, b.through_start, b.critical_points, b.segments)
    assert [(c.kind, c.u.tolist()) for c in fast.critical_points] == \
        [(c.kind, c.u.tolist()) for c in ref.critical_points]
    assert [(s.start, s.start_ray, s.end, s.end_ray, s.points.tolist()) for s in fast.segments] \
        == [(s.start, s.start_ray, s.end, s.end_ray, s.points.tolist()) for s in ref.segments]
    assert [(m.u.tolist(), m.critical_u.tolist()) for m in fast.near_misses] == \
        [(m.u.tolist(), m.critical_u.tolist()) for m in ref.near_misses]


def _tree_nearest(ex, us):
    """The nearest traced points from the k-d tree of all curves, one query per point (before
    ``nearest_points``)."""
    out = []
    for u in np.asarray(us).reshape(-1, ex.cons.n_free):
        _, i = ex.tree.query(u)
        out.append(ex._tree_point(int(i)))
    return out


@pytest.mark.parametrize("case", [LINKAGES[k] for k in ("four-bar", "equilateral four-bar",
                                                        "three-rotor", "gated chain",
                                                        "kl-chain 6")]
                         + _random_four_bars(3, seed=152))
def test_bounded_neighbour_search_and_per_curve_nearest_change_nothing(case, monkeypatch):
    """``on_curve`` asking its k-d tree only for neighbours within ``QUERY_BOUND_REL h_max`` marks
    the same points as with every one of the ``NEAREST`` nearest (an unbounded query), for
    seeds and for points scattered near and far from the curves; ``nearest_points`` from each
    curve's own tree, all points at once, are the tree of all curves' nearest points one by
    one; whole explorations are the same with the unbounded queries and the tree of all
    curves queried point by point."""
    import engine.space.configuration_space.explorer as explorer_module

    lk = build_preset(*case)
    opt = SpaceOptions(closed_form=False, angles=24, random_starts=4,
                       max_components=4 if "kl" in case[0] else 32)
    ex = _Explorer(lk, TOL, opt)
    ex.trace_all(lk.coordinates())
    assert ex.curves
    rng = np.random.default_rng(9)
    stack = np.array(seeds(lk, TOL, opt.angles, opt.assembly_budget, opt.random_starts,
                           opt.seed, opt.max_swept_rotors).points)
    pts = np.vstack([c.array("points") for c in ex.curves])
    picks = pts[rng.integers(0, len(pts), 64)]
    probes = [stack] + [picks + s * ex.h_max * rng.normal(size=picks.shape)
                        for s in (0.0, 0.01, 0.5, 1.0, 3.0)]
    for us in probes:
        for curve in ex.curves:
            bounded = ex.on_curve(us, curve)
            with monkeypatch.context() as m:
                m.setattr(explorer_module, "QUERY_BOUND_REL", np.inf)
                assert np.array_equal(bounded, ex.on_curve(us, curve))
        for rows in (us[:1], us[:32]):
            got, ref = ex.nearest_points(rows), _tree_nearest(ex, rows)
            assert len(got) == len(ref) == len(rows)
            for row, a, b in zip(rows, got, ref, strict=True):
                # the same curve point, or (a tie) another exactly as near: a critical point
                # that two curves both pass through, refined to the same point from both
                # sides (the three-rotor's (1, 0, 2, 0, 2, 1) to 1e-38), where the per-curve
                # trees keep the first curve and the tree of all curves any of them
                assert (a[0] is b[0] and a[1] == b[1]) or \
                    np.linalg.norm(a[0].points[a[1]] - row) == \
                    np.linalg.norm(b[0].points[b[1]] - row)
    fast = explore(lk, TOL, opt)
    monkeypatch.setattr(explorer_module, "QUERY_BOUND_REL", np.inf)
    monkeypatch.setattr(explorer_module.Explorer, "nearest_points", _tree_nearest)
    ref = explore(lk, TOL, opt)
    assert fast.search == ref.search
    assert len(fast.components) == len(ref.components)
    for a, b in zip(fast.components, ref.components, strict=True):
        assert np.array_equal(a.points, b.points)
        assert (a.closed, a.critical_points, a.segments) == (b.closed, b.critical_points,
                                                              b.segments)
    assert [(c.kind, c.u.tolist()) for c in fast.critical_points] == \
        [(c.kind, c.u.tolist()) for c in ref.critical_points]
    assert [(s.start, s.end, s.points.tolist()) for s in fast.segments] == \
        [(s.start, s.end, s.points.tolist()) for s in ref.segments]
    assert [(m.u.tolist(), m.critical_u.tolist()) for m in fast.near_misses] == \
        [(m.u.tolist(), m.critical_u.tolist()) for m in ref.near_misses]


@pytest.mark.parametrize("path", ["numba", "numpy"])
@pytest.mark.parametrize("case", [("four-bar", {"L2": 1.2}), ("four-bar", {}),
                                  ("three-rotor", {}), ("kl-chain", {"n": 6})]
                         + _random_four_bars(2, seed=153))
def test_curve_arrays_joined_from_blocks_are_the_lists_converted(case, path, monkeypatch):
    """``Curve.array`` joins the blocks the tracer added (the compiled kernel's chunks, the
    Python loop's single points, crossed critical points) instead of converting the lists
    row by row: bit for bit the same arrays, same dtypes, on the traced curves of
    explorations (closed and open, with and without crossings) and the segments' curves;
    and after a list is changed behind its back, the conversion of the list."""
    import engine.space.trace as trace_module
    from engine.space import trace_kernel

    monkeypatch.setenv(trace_kernel.KERNEL_ENV, path)
    if path == "numba":
        assert trace_kernel.load()
    lk = build_preset(*case)
    opt = SpaceOptions(closed_form=False, angles=24, random_starts=4,
                       max_components=4 if "kl" in case[0] else 32)
    curves: list = []
    original = trace_module.trace_curve

    def keep(*args, **kwargs):
        curve = original(*args, **kwargs)
        curves.append(curve)
        return curve

    monkeypatch.setattr("engine.space.configuration_space.explorer.trace_curve", keep)
    monkeypatch.setattr("engine.space.configuration_space.segments.trace_curve", keep)
    explore(lk, TOL, opt)
    assert curves
    for curve in curves:
        for name in ("points", "tangents", "signs", "logdets"):
            ref = np.array(getattr(curve, name))
            got = curve.array(name)
            assert got.dtype == ref.dtype and got.shape == ref.shape
            np.testing.assert_array_equal(got, ref)
    curve = curves[0]
    curve.points.append(curve.points[0] + 1.0)  # behind the blocks' back
    np.testing.assert_array_equal(curve.array("points"), np.array(curve.points))


@pytest.mark.parametrize("case", [LINKAGES[k] for k in ("three-rotor", "gated chain",
                                                        "kl-chain 6")]
                         + [("kl-chain", {"n": 20})])
def test_per_curve_trees_of_on_traced_change_nothing(case, monkeypatch):
    """``on_traced`` asking each curve's own k-d tree (up to ``FOREST_MAX`` curves: the tree of
    all curves was rebuilt after every traced curve, 40 % of a 100-rotor chain's search, issue
    30) marks the same points as the tree of all curves, for seeds and for points scattered
    near and far from the curves; the one-at-a-time seed loop of a chain of 20 rotors (40 free
    coordinates, beyond the batched loop) traces the same exploration with either."""
    import engine.space.configuration_space.explorer as explorer_module

    lk = build_preset(*case)
    opt = SpaceOptions(closed_form=False, angles=24, random_starts=4, max_components=6)
    ex = _Explorer(lk, TOL, opt)
    ex.trace_all(lk.coordinates())
    assert ex.curves and len(ex.curves) <= explorer_module.FOREST_MAX
    rng = np.random.default_rng(11)
    stack = np.array(seeds(lk, TOL, opt.angles, opt.assembly_budget, opt.random_starts,
                           opt.seed, opt.max_swept_rotors).points)[:200]
    pts = np.vstack([c.array("points") for c in ex.curves])
    picks = pts[rng.integers(0, len(pts), 32)]
    probes = np.vstack([stack] + [picks + s * ex.h_max * rng.normal(size=picks.shape)
                                  for s in (0.0, 0.01, 0.5, 1.0, 3.0)])
    forest = [ex.on_traced(u) for u in probes]
    monkeypatch.setattr(explorer_module, "FOREST_MAX", 0)
    assert forest == [ex.on_traced(u) for u in probes]
    assert any(forest) and not all(forest)
    ref = explore(lk, TOL, opt)
    monkeypatch.undo()
    fast = explore(lk, TOL, opt)
    assert fast.search == ref.search
    assert len(fast.components) == len(ref.components)
    for a, b in zip(fast.components, ref.components, strict=True):
        assert np.array_equal(a.points, b.points)
    assert [(m.u.tolist(), m.critical_u.tolist()) for m in fast.near_misses] == \
        [(m.u.tolist(), m.critical_u.tolist()) for m in ref.near_misses]
