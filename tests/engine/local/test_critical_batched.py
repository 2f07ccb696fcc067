"""The batched critical-point refinement (engine/local/critical_batched.py) against the one-start
MINPACK refinement it replaces in the critical-point search: the system itself, the refinement
from the same starts, and whole searches and slices through either path (random and catalogue
linkages)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import least_squares

from engine.catalogue.presets import build_preset
from engine.local import critical_batched
from engine.local.critical import AugmentedSystem, refine_critical
from engine.local.critical_batched import batched_system, refine_critical_batch, start_stresses
from engine.model.constraints import Constraints
from engine.model.tolerances import Tolerances
from engine.space.configuration_space import SpaceOptions, explore, find_critical_points

TOL = Tolerances()


def _random_four_bar(seed: int) -> tuple[str, dict[str, float]]:
    rng = np.random.default_rng(seed)
    return "four-bar", dict(zip(("L1", "L2", "L3"), rng.uniform(0.4, 1.8, 3), strict=True))


def _random_three_rotor(seed: int) -> tuple[str, dict[str, float]]:
    """The three-rotor with its lengths scaled at random (as a map's sample lengths do)."""
    return "three-rotor", {"seed": seed}


def _build(name: str, params: dict[str, float]):
    if name == "three-rotor" and "seed" in params:
        lk = build_preset("three-rotor")
        rng = np.random.default_rng(int(params["seed"]))
        return lk.with_lengths(lk.lengths * rng.uniform(0.8, 1.25, len(lk.lengths)))
    return build_preset(name, params)


LINKAGES = [
    ("four-bar", {}),  # equilateral: critical lengths (exact critical points)
    ("four-bar", {"L2": 1.2}),
    ("four-bar", {"L1": 1.4, "L2": 0.6, "L3": 1.3}),
    _random_four_bar(1),
    _random_four_bar(2),
    ("three-rotor", {}),
    _random_three_rotor(3),
    ("kl-chain", {"n": 6}),
    ("gated-kl-chain", {"n": 4, "gate": 2}),
]
IDS = [f"{n}-{'-'.join(f'{k}{v:.3g}' for k, v in p.items())}" for n, p in LINKAGES]


def _starts(lk, seed: int) -> np.ndarray:
    """Candidates of the critical-point search (along traced curves, and its multistart)."""
    from engine.space.configuration_space import Explorer
    from engine.space.configuration_space.critical_search import candidates

    ex = Explorer(lk, TOL, SpaceOptions(max_components=4, random_starts=4, seed=seed,
                                        closed_form=False))
    ex.trace_all(lk.coordinates())
    return np.array(candidates(ex))


@pytest.mark.parametrize(("name", "params"), LINKAGES, ids=IDS)
def test_batched_system_is_the_augmented_system(name, params):
    """``F``, ``dF/dx`` (the affine map and the direct blocks) equal those of
    :class:`engine.local.critical.AugmentedSystem`; the second-order term is the difference of the
    Hessian of ``|F|^2 / 2`` (central differences of its gradient) and ``A^T A``."""
    cons = Constraints(_build(name, params))
    system, ref = batched_system(cons), AugmentedSystem(cons)
    rng = np.random.default_rng(7)
    xs = np.concatenate([cons.linkage.coordinates() + 0.3 * rng.normal(size=(4, cons.n_free)),
                         rng.normal(size=(4, cons.n_constraints))], axis=1)
    f, a = system.residual(xs), system.jacobian(xs)
    np.testing.assert_allclose(a, system.jacobian_direct(xs), rtol=0, atol=1e-13)
    curv = system.second_order(f)
    np.testing.assert_allclose(curv, system.second_order_direct(f), rtol=0, atol=1e-13)
    np.testing.assert_allclose(system.jacobians(xs[:, :cons.n_free]),
                               [cons.jacobian(x[:cons.n_free], sparse=False) for x in xs],
                               rtol=0, atol=1e-13)
    h = 1e-6
    for k, x in enumerate(xs):
        np.testing.assert_allclose(f[k], ref.residual(x), rtol=0, atol=1e-13)
        np.testing.assert_allclose(a[k], ref.jacobian(x), rtol=0, atol=1e-13)

        def grad(y):
            return ref.jacobian(y).T @ ref.residual(y)

        eye = np.eye(len(x))
        hess = np.array([(grad(x + h * e) - grad(x - h * e)) / (2 * h) for e in eye])
        full = a[k].T @ a[k] + curv[k]
        assert np.max(np.abs(hess - full)) <= 1e-6 * max(1.0, float(np.max(np.abs(full))))


@pytest.mark.parametrize(("name", "params"), LINKAGES, ids=IDS)
def test_batched_refinement_is_minpacks(name, params):
    """From the same starts: the same verdict; the same critical point and stress (critical
    lengths); for a near miss the same local minimum of ``|F|`` that MINPACK reaches when it
    runs to convergence (within its budget of 100 evaluations it may still creep along a
    flat valley, some 1e-5 to 1e-3 short on a floppy chain), reached here to rounding."""
    lk = _build(name, params)
    cons = Constraints(lk)
    scale = float(np.median(lk.lengths[cons.bars]))
    m = cons.n_free
    starts = _starts(lk, 2)
    assert len(starts) >= 4
    batch = refine_critical_batch(cons, starts, TOL)
    sigma0 = start_stresses(cons, starts)
    x0s = np.concatenate([starts, sigma0], axis=1)
    raw, finished = critical_batched.levenberg_marquardt(batched_system(cons), x0s)
    assert finished.all()
    ref_sys = AugmentedSystem(cons)

    def cost(x):
        f = ref_sys.residual(x)
        return float(f @ f)

    same_minimum = 0
    for k, (u0, new) in enumerate(zip(starts, batch, strict=True)):
        assert new is not None
        np.testing.assert_allclose(raw[k, :m], new.u, rtol=0, atol=0)
        old = refine_critical(cons, u0, TOL)
        assert old.critical == new.critical, k
        np.testing.assert_allclose(sigma0[k], np.linalg.svd(cons.jacobian(u0, sparse=False))[0]
                                   [:, -1], rtol=0, atol=1e-12)
        if old.critical:
            assert np.linalg.norm(old.u - new.u) <= 1e-6 * scale
            assert np.linalg.norm(old.sigma - new.sigma) <= 1e-6
            assert new.length_residual <= TOL.residual_atol
            same_minimum += 1
            continue
        # a near miss: MINPACK within its budget, and run to convergence, from the same start
        kw = {"jac": ref_sys.jacobian, "method": "lm", "xtol": 1e-15, "ftol": 1e-15,
              "gtol": 1e-15}
        budget = least_squares(ref_sys.residual, x0s[k], max_nfev=100, **kw)
        far = least_squares(ref_sys.residual, x0s[k], max_nfev=5000, **kw)
        # never a worse point than MINPACK's own answer within its budget
        assert cost(raw[k]) <= cost(budget.x) * (1 + 1e-12)
        if np.linalg.norm(far.x[:m] - new.u) <= 1e-5 * scale:
            same_minimum += 1
            assert abs(new.length_residual - old.length_residual) <= 1e-3 * scale
        else:
            # another basin (a far start): a local minimum all the same, as deep or deeper
            grad = ref_sys.jacobian(raw[k]).T @ ref_sys.residual(raw[k])
            assert np.linalg.norm(grad) <= 1e-8
    assert same_minimum >= len(starts) - 1


def _one_at_a_time(monkeypatch, converged: bool = False):
    """The path the batch replaces: MINPACK from one start at a time; ``converged``: run to
    convergence (5000 evaluations) instead of its budget of 100."""
    import engine.local.critical as critical

    monkeypatch.setattr(critical_batched, "REFINE_BATCH_MAX_FREE", -1)
    if converged:
        monkeypatch.setattr(critical, "REFINE_MAX_NFEV", 5000)


def _same_near_misses(fast, slow, scale: float, exact: bool) -> None:
    """``exact``: against MINPACK run to convergence, the same list (count, gaps and
    configurations). Else against MINPACK within its budget of 100 evaluations, which stops
    short of a minimum (1e-5 to 1e-2 of the scale on floppy linkages) so that two starts into
    the same minimum can stay apart by more than the deduplication distance: every near miss
    of either path has one of the other near it with nearly the same gap (the same minima,
    up to those duplicates)."""
    if exact:  # one to one (mirror pairs have equal gaps: matched by configuration)
        assert len(fast) == len(slow)
        matched = set()
        for a in fast:
            k = int(np.argmin([np.linalg.norm(a.critical_u - b.critical_u) for b in slow]))
            b = slow[k]
            matched.add(k)
            assert np.linalg.norm(a.critical_u - b.critical_u) <= 1e-5 * scale
            assert abs(a.length_gap - b.length_gap) <= 1e-6 * scale
            assert a.distance == pytest.approx(b.distance, abs=1e-5 * scale)
        assert len(matched) == len(slow)
        return
    assert bool(fast) == bool(slow)
    for one, other in ((fast, slow), (slow, fast)):
        for a in one:
            near = min(other, key=lambda b: float(np.linalg.norm(a.critical_u - b.critical_u)))
            assert np.linalg.norm(a.critical_u - near.critical_u) <= 5e-2 * scale
            assert abs(a.length_gap - near.length_gap) <= 1e-3 * scale


def _same_critical_points(fast, slow, scale: float) -> None:
    assert len(fast) == len(slow)
    for a, b in zip(fast, slow, strict=True):  # one canonical order
        assert a.kind == b.kind
        assert np.linalg.norm(a.u - b.u) <= 1e-7 * scale
        sa, sb = a.analysis.self_stress, b.analysis.self_stress
        if sa is not None and sb is not None:  # the same stress, up to its sign
            assert min(np.linalg.norm(sa - sb), np.linalg.norm(sa + sb)) <= 1e-6


#: Linkages whose near misses are isolated minima of |F| (no flat valley of a floppy chain):
#: MINPACK run to convergence finds exactly the batch's near misses.
ISOLATED = [lk for lk in LINKAGES if lk[0] != "kl-chain"]


@pytest.mark.parametrize("converged", [False, True], ids=["budget", "converged"])
@pytest.mark.parametrize(("name", "params"), LINKAGES, ids=IDS)
def test_explore_through_the_batched_refinement(name, params, converged, monkeypatch):
    """The whole exploration (general tracer, near misses on) refining one candidate at a time
    (MINPACK, within its budget or to convergence) and all at once: the same components, the
    same critical points (positions, kinds, stresses, in the same order), the same near
    misses (see :func:`_same_near_misses`)."""
    if converged and (name, params) not in ISOLATED:
        pytest.skip("a flat valley: where MINPACK stops on it depends on its path")
    lk = _build(name, params)
    scale = float(np.median(lk.lengths))
    opt = SpaceOptions(closed_form=False, angles=24, random_starts=4, max_components=8)
    fast = explore(lk, TOL, opt)
    _one_at_a_time(monkeypatch, converged)
    slow = explore(lk, TOL, opt)
    _same_critical_points(fast.critical_points, slow.critical_points, scale)
    _same_near_misses(fast.near_misses, slow.near_misses, scale, converged)
    assert fast.degenerate == slow.degenerate
    assert len(fast.components) == len(slow.components)
    for a, b in zip(fast.components, slow.components, strict=True):
        assert a.closed == b.closed and a.critical_points == b.critical_points
        assert a.points.shape == b.points.shape
        np.testing.assert_allclose(a.points, b.points, rtol=0, atol=1e-6 * scale)
    assert len(fast.segments) == len(slow.segments)
    assert fast.search.complete == slow.search.complete
    for key in ("curves_traced", "critical_candidates", "critical_points_found"):
        assert fast.search[key] == slow.search[key]


@pytest.mark.parametrize(("name", "params"), LINKAGES[:7], ids=IDS[:7])
def test_find_critical_points_through_the_batched_refinement(name, params, monkeypatch):
    lk = _build(name, params)
    scale = float(np.median(lk.lengths))
    opt = SpaceOptions(critical_closed_form=False, angles=24, random_starts=6)
    fast = find_critical_points(lk, TOL, opt)
    _one_at_a_time(monkeypatch, converged=True)
    slow = find_critical_points(lk, TOL, opt)
    _same_critical_points(fast.critical_points, slow.critical_points, scale)
    _same_near_misses(fast.near_misses, slow.near_misses, scale, exact=True)
    assert fast.search.complete == slow.search.complete


def test_the_batched_refinement_stops_at_the_deadline():
    """A deadline already past: no start is refined (None), none is made up."""
    from engine.model.budget import Deadline

    lk = build_preset("four-bar", {"L2": 1.2})
    cons = Constraints(lk)
    starts = _starts(lk, 0)
    out = refine_critical_batch(cons, starts, TOL, deadline=Deadline.after(0.0))
    assert all(r is None for r in out) and len(out) == len(starts)
    assert refine_critical_batch(cons, starts[:0], TOL) == []


@pytest.mark.slow
@pytest.mark.parametrize(("name", "params", "axes"), [
    # bars of the chain's cells, not of its gate: the gate's lengths (D, L2, L1) are drawn in
    # closed form (test_gate_slice_is_closed_form_and_complete below), without any refinement
    ("gated-kl-chain", {"n": 4, "gate": 2}, [("l1", 1.0, 2.5), ("r1", 1.0, 2.5)]),
    ("three-rotor", {}, [("L1", 0.5, 2.0), ("L2", 0.5, 2.0)]),
])
def test_slice_through_the_batched_refinement(name, params, axes, monkeypatch):
    """A traced critical-value slice seeded through either refinement: the same curves (within
    a small fraction of the step) and the same regions (points, counts, signatures)."""
    from engine.design.critical_values import critical_value_slice
    from engine.design.slice_regions import _polyline_distance

    lk = build_preset(name, params)
    opt = SpaceOptions(angles=12, random_starts=2, max_components=4)
    fast = critical_value_slice(lk, axes, resolution=16, options=opt)
    _one_at_a_time(monkeypatch)
    slow = critical_value_slice(lk, axes, resolution=16, options=opt)
    # traced curves: no argument proves every curve found, neither path claims it
    assert fast.search["reason"] == slow.search["reason"] == "searched"
    assert len(fast.curves) == len(slow.curves)
    step = float(fast.search["step"])
    for one, other in ((fast.curves, slow.curves), (slow.curves, fast.curves)):
        for c in one:
            assert np.max(np.min([_polyline_distance(c, k) for k in other], axis=0)) \
                <= 1e-3 * step
    assert [(r.point, r.components, r.signature, r.cells) for r in fast.regions] == \
        [(r.point, r.components, r.signature, r.cells) for r in slow.regions]


def test_gate_slice_is_closed_form_and_complete(monkeypatch):
    """The gated chain driven from its gate rotor, in its gate's lengths: the curves are the
    gate four-bar's critical lines (closed form), no start is refined, and with every region's
    count exact the slice is complete by a derived argument."""
    from engine.design.critical_values import critical_value_slice

    def refined(*args, **kwargs):
        raise AssertionError("a closed-form slice refines no start")

    monkeypatch.setattr(critical_batched, "refine_critical_batch", refined)
    lk = build_preset("gated-kl-chain", {"n": 4, "gate": 2})
    opt = SpaceOptions(angles=12, random_starts=2, max_components=4)
    s = critical_value_slice(lk, [("L2", 1.0, 3.0), ("D", 1.0, 3.5)], resolution=16, options=opt)
    assert s.search["method"] == "closed form"
    assert s.search["complete"] is True and s.search["reason"] is None
    assert s.search["argument"] == "derived"
    assert s.curves and all(r.components is not None for r in s.regions)


@pytest.mark.parametrize(("name", "params", "axes"), [
    ("four-bar", {"L2": 1.2}, [("L2", 0.3, 2.2), ("L3", 0.3, 2.2)]),
    ("three-rotor", {}, [("L1", 0.5, 2.0), ("L2", 0.5, 2.0)]),
    ("gated-kl-chain", {"n": 4, "gate": 2}, [("L2", 1.0, 3.0), ("D", 1.0, 3.5)]),
])
def test_onto_the_critical_set_batched_is_one_at_a_time(name, params, axes):
    """The seeds of a slice (near misses and critical points at sample lengths, as
    ``_CurveTracing.starts_at`` makes them) moved onto ``G = 0`` all at once and one at a time:
    the same points (the same Gauss-Newton iteration, and the same fallback)."""
    from engine.design.critical_values import _validate
    from engine.design.slice_curves import (
        _BatchedSystem,
        _onto_solutions,
        _onto_solutions_batch,
        _System,
    )

    lk = build_preset(name, params)
    ax = _validate(lk, axes)
    sys = _System(lk, ax)
    rng = np.random.default_rng(4)
    x0s = []
    for _ in range(3):
        p0 = np.array([rng.uniform(a.lo, a.hi) for a in ax])
        lengths = lk.lengths.copy()
        lengths[ax[0].bar], lengths[ax[1].bar] = p0
        res = find_critical_points(lk.with_lengths(lengths), TOL,
                                   SpaceOptions(angles=12, random_starts=2, max_components=4),
                                   start_on_space=False)
        x0s += [np.concatenate([m.critical_u, m.critical_sigma, p0]) for m in res.near_misses]
    assert len(x0s) >= 2
    x0s = np.array(x0s)
    batched = _BatchedSystem(sys)
    np.testing.assert_allclose(batched.g(x0s), [sys.g(x) for x in x0s], rtol=0, atol=1e-13)
    np.testing.assert_allclose(batched.dg(x0s), [sys.dg(x) for x in x0s], rtol=0, atol=1e-13)
    fast = _onto_solutions_batch(sys, x0s)
    for x0, x in zip(x0s, fast, strict=True):
        ref = _onto_solutions(sys, x0)
        on_ref, on_new = (np.max(np.abs(sys.g(y))) <= 1e-9 for y in (ref, x))
        assert on_ref == on_new
        if on_ref:
            assert np.linalg.norm(x - ref) <= 1e-7 * (1.0 + np.linalg.norm(ref))


@pytest.mark.parametrize(("name", "params"), LINKAGES, ids=IDS)
def test_seed_assemblies_checked_at_once_are_the_ones_checked_one_by_one(name, params):
    """``iter_seeds`` checks every assembly of an angle in one expression: the same seeds, in
    the same order, as the check of each one's coordinates by ``Constraints.max_residual``."""
    from engine.space.assembly import assemblies_at, dyad_plan, iter_seeds, rotors

    lk = _build(name, params)
    cons = Constraints(lk)
    angles, budget = 12, 16
    got = list(iter_seeds(lk, TOL, {}, angles, budget, 0, 0, 4))
    offset = (np.sqrt(5) - 1) / 2
    grid = 2 * np.pi * (np.arange(angles) + offset) / angles
    cands = rotors(lk)
    if len(cands) > 4:
        pick = np.linspace(0, len(cands) - 1, 4).round().astype(int)
        cands = [cands[k] for k in sorted(set(pick.tolist()))]
    ref = []
    for rotor in cands:
        plan = dyad_plan(lk, rotor)
        if plan is None:
            continue
        for angle in grid:
            for pos in assemblies_at(lk, rotor, plan, float(angle), budget)[0]:
                u = lk.coordinates(pos)
                if cons.max_residual(u) <= max(1e3 * TOL.residual_atol, 1e-7):
                    ref.append(u)
    assert len(got) == len(ref) > 0
    np.testing.assert_array_equal(np.array(got), np.array(ref))


@pytest.mark.parametrize(("name", "params"), LINKAGES, ids=IDS)
def test_projections_at_once_are_the_projections_one_by_one(name, params, monkeypatch):
    """``project_many`` (the random starts of small linkages, all at once) against
    ``project`` from each start: the same verdicts and the same points."""
    from engine.model.batched import project_many
    from engine.model.constraints import project

    lk = _build(name, params)
    cons = Constraints(lk)
    scale = float(np.median(lk.lengths[cons.bars]))
    rng = np.random.default_rng(8)
    us = lk.coordinates() + scale * rng.normal(size=(24, cons.n_free))
    got, ok = project_many(cons, us, TOL)
    agree = 0
    for u0, u, success in zip(us, got, ok, strict=True):
        ref = project(lk.with_positions(lk.positions_of(u0)), TOL)
        assert ref.success == success
        if success:
            agree += np.linalg.norm(lk.coordinates(ref.positions) - u) <= 1e-9 * scale
    # (rounding: an SVD against lstsq's may tip one near-tie decision of the line search)
    assert agree >= ok.sum() - 1


@pytest.mark.parametrize("scale", [2.0**-40, 1e-12, 1e-6, 1e6, 1e12, 2.0**40])
def test_batched_refinement_is_scale_free(scale):
    """The equilateral four-bar drawn at any scale has the same three branch points (scaled):
    far from unit lengths the batched refinement works in units of a power of two near the
    median length (at 1e12 the lengths' rounding had hidden the stress rows, and one branch
    point stopped 1e-8 short of critical and was classified "regular")."""
    from engine.model.tolerances import scaled_tolerances

    unit_lk = build_preset("four-bar")
    lk = unit_lk.with_positions(unit_lk.positions * scale).with_lengths(unit_lk.lengths * scale)
    assert critical_batched.unit_length(Constraints(unit_lk)) == 1.0
    unit = find_critical_points(unit_lk, TOL, SpaceOptions(random_starts=4))
    got = find_critical_points(lk, scaled_tolerances(scale), SpaceOptions(random_starts=4))
    assert got.search.complete
    assert [cp.analysis.kind for cp in got.critical_points] == ["branch"] * 3
    expected = sorted(tuple(np.round(cp.u, 6)) for cp in unit.critical_points)
    found = sorted(tuple(np.round(cp.u / scale, 6)) for cp in got.critical_points)
    np.testing.assert_allclose(found, expected, atol=1e-6)
    cons = Constraints(lk)
    for cp in got.critical_points:
        sv = np.linalg.svd(cons.jacobian(cp.u, sparse=False), compute_uv=False)
        assert sv[-1] <= 1e-2 * TOL.rank_rtol * sv[0]  # well inside the rank test


def _halving_loop(batch, u, step, cost):
    """The backtracking that ``project_many`` ran before :func:`engine.model.batched.backtrack`:
    one batch of the rows still looking per ``t = 1, 1/2, ...`` (> 1e-10)."""
    targets = batch.lengths**2
    new_u = np.full_like(u, np.nan)
    new_g = np.full((len(u), len(targets)), np.nan)
    new_cost = np.full(len(u), np.inf)
    pending = np.ones(len(u), dtype=bool)
    t = 1.0
    while t > 1e-10 and pending.any():
        rows = np.flatnonzero(pending)
        trial = u[rows] + t * step[rows]
        g_trial = batch.squared_lengths(trial) - targets
        c_trial = np.einsum("ka,ka->k", g_trial, g_trial)
        hit = c_trial < cost[rows]
        new_u[rows[hit]], new_g[rows[hit]] = trial[hit], g_trial[hit]
        new_cost[rows[hit]] = c_trial[hit]
        pending[rows[hit]] = False
        t *= 0.5
    return new_u, new_g, new_cost


@pytest.mark.parametrize(("name", "params"),
                         LINKAGES + [("rotor-chain-3d", {}), ("kl-chain", {"n": 10})],
                         ids=IDS + ["rotor-chain-3d", "kl-chain-n10"])
def test_backtracking_and_line_searches_at_once_are_the_loops_bit_for_bit(name, params):
    """``engine.model.batched.backtrack`` (every halving of every row in one batch, replayed) gives
    bit for bit what one batch per halving gave; ``engine.model.batched.line_searches`` what
    ``engine.model.constraints._line_search`` gives for each step: rows that hit at once, late, or
    never (a cost nothing beats), single rows and many."""
    from engine.model.batched import BatchedConstraints, backtrack, line_searches
    from engine.model.constraints import _line_search

    lk = _build(name, params)
    cons = Constraints(lk)
    batch = BatchedConstraints(cons)
    rng = np.random.default_rng(21)
    scale = float(np.median(lk.lengths[cons.bars]))
    for rows in (1, 2, 7, 24):
        for spread in (0.05, 0.5, 2.0):
            u = lk.coordinates() + spread * scale * rng.normal(size=(rows, cons.n_free))
            step = spread * scale * rng.normal(size=u.shape)
            g = batch.squared_lengths(u) - batch.lengths**2
            cost = np.einsum("ka,ka->k", g, g)
            cost[::3] *= 1e-6  # rows that must halve far, or never find a lower cost
            got, ref = backtrack(batch, u, step, cost), _halving_loop(batch, u, step, cost)
            for a, b in zip(got, ref, strict=True):
                np.testing.assert_array_equal(a, b)
            for r in range(rows):
                steps = [step[r], -step[r], 1e-3 * step[r]]
                fast = line_searches(cons, batch, u[r], steps, float(cost[r]))
                for s, res in zip(steps, fast, strict=True):
                    slow = _line_search(cons, u[r], s, cost[r])
                    assert (res is None) == (slow is None)
                    if res is not None and slow is not None:
                        np.testing.assert_array_equal(res[0], slow[0])
                        np.testing.assert_array_equal(res[1], slow[1])
                        assert res[2] == slow[2]


@pytest.mark.parametrize(("name", "params"), LINKAGES + [("rotor-chain-3d", {})],
                         ids=IDS + ["rotor-chain-3d"])
def test_projections_are_those_of_the_halving_loop(name, params, monkeypatch):
    """``project_many`` with the batched backtracking and line searches projects every start
    to bit for bit the point it reached with the loops they replace."""
    import engine.model.batched as batched
    from engine.model.constraints import _line_search

    lk = _build(name, params)
    cons = Constraints(lk)
    scale = float(np.median(lk.lengths[cons.bars]))
    for seed in (0, 1, 8):
        us = lk.coordinates() + scale * np.random.default_rng(seed).normal(size=(24, cons.n_free))
        fast = batched.project_many(cons, us, TOL)
        with monkeypatch.context() as m:
            m.setattr(batched, "backtrack", _halving_loop)
            m.setattr(batched, "line_searches", lambda cons, batch, u, steps, cost: [
                _line_search(cons, u, s, cost) for s in steps])
            slow = batched.project_many(cons, us, TOL)
        np.testing.assert_array_equal(fast[0], slow[0])
        np.testing.assert_array_equal(fast[1], slow[1])
