"""The closed form of planar dyad chains (engine.space.dyads) against the general tracer.

Each case runs :func:`explore` twice: closed form first (``search["method"] == "closed form"``)
and with ``closed_form=False`` (seeds, predictor-corrector tracing, critical-point search). They
must agree on the number of components, on every rotor's winding per component, on the point
sets themselves (every point of either walk lies within the step bound of the other's matching
component), and on the critical points (none); and every closed-form point keeps every bar
within ``residual_atol``. At and near critical lengths the closed form must decline.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from scipy.spatial import cKDTree

from engine.catalogue.presets import build_preset, circle_intersection
from engine.model.constraints import Constraints
from engine.model.linkage import BarSpec, VertexSpec, build_linkage
from engine.model.tolerances import Tolerances
from engine.space.configuration_space import SpaceOptions, explore, rotor_angles, winding
from engine.space.dyads import chain_of, closed_form_space
from tests.engine.space.configuration_space.test_search import classical, random_four_bars

TOL = Tolerances()
FAST = SpaceOptions(angles=24, random_starts=4)
TRACER = replace(FAST, closed_form=False)


def windings(lk, res) -> list[tuple[tuple[str, int | None], ...]]:
    out = []
    for comp in res.components:
        turns = {b: winding(a, comp.closed) for b, a in rotor_angles(lk, comp.points).items()}
        out.append(tuple(sorted((b, None if w is None else abs(w)) for b, w in turns.items())))
    return sorted(out, key=str)


def match(a, b, radius: float) -> list[int]:
    """For each component of ``b``, the one component of ``a`` all its points lie near."""
    pts = np.vstack([c.points for c in a.components])
    owner = np.concatenate([np.full(len(c.points), k) for k, c in enumerate(a.components)])
    tree = cKDTree(pts)
    out = []
    for comp in b.components:
        dist, idx = tree.query(comp.points)
        assert np.max(dist) <= radius
        owners = set(owner[idx].tolist())
        assert len(owners) == 1, owners
        out.append(owners.pop())
    return out


def cross_check(lk, options: SpaceOptions = FAST):
    """Closed form and tracer on ``lk``; asserts everything they must share; returns both."""
    fast = explore(lk, TOL, options)
    assert fast.search["method"] == "closed form", fast.search.get("closed_form")
    slow = explore(lk, TOL, replace(options, closed_form=False))
    assert slow.search["method"] == "tracer" and slow.search["closed_form"] == "off"
    assert fast.search["complete"] and slow.search["complete"]
    assert not fast.critical_points and not slow.critical_points
    assert len(fast.components) == len(slow.components)
    cons = Constraints(lk)
    h = options.trace.resolved_step_max(cons)
    for comp in fast.components:
        assert comp.closed and np.array_equal(comp.points[0], comp.points[-1])
        pos = lk.positions_of(comp.points[0])
        assert np.all(pos[lk.fixed.all(axis=1)] == lk.positions[lk.fixed.all(axis=1)])
        assert max(cons.max_residual(u) for u in comp.points) <= TOL.residual_atol
        assert np.max(np.linalg.norm(np.diff(comp.points, axis=0), axis=1)) <= h
    # the same point sets, component for component (a bijection)
    assert sorted(match(fast, slow, h)) == list(range(len(fast.components)))
    assert sorted(match(slow, fast, h)) == list(range(len(slow.components)))
    assert windings(lk, fast) == windings(lk, slow)
    assert sum(c.through_start for c in fast.components) == 1
    assert [c.through_start for c in fast.components] == [
        slow.components[k].through_start for k in match(slow, fast, h)
    ]
    return fast, slow


@pytest.mark.parametrize(
    "lengths", random_four_bars(200), ids=lambda x: "-".join(f"{v:.3f}" for v in x)
)
def test_random_four_bars_closed_form_agrees_with_tracer(lengths):
    l1, l2, l3 = lengths
    lk = build_preset("four-bar", {"L1": l1, "L2": l2, "L3": l3})
    fast, _ = cross_check(lk)
    count, cranks = classical(l1, l2, l3)
    assert len(fast.components) == count
    for comp in fast.components:
        for bar, angles in rotor_angles(lk, comp.points).items():
            turns = winding(angles, comp.closed)
            assert (abs(turns) == 1) if cranks[bar] else (turns == 0), (bar, turns)


def test_crank_rocker_dense_sampling_and_no_near_miss_search():
    """A dense request (step bound 1e-3): the step bound holds, and skipping the near-miss
    search changes nothing else."""
    lk = build_preset("four-bar", {"L1": 0.5, "L2": 1.2, "L3": 1.0})
    opt = replace(FAST, trace=replace(FAST.trace, step_max=1e-3, max_points=100_000))
    full = explore(lk, TOL, opt)
    lean = explore(lk, TOL, opt, near_misses=False)
    assert full.search["method"] == lean.search["method"] == "closed form"
    assert full.near_misses and not lean.near_misses
    assert len(full.components) == len(lean.components) == 2
    for a, b in zip(full.components, lean.components, strict=True):
        assert np.array_equal(a.points, b.points) and a.through_start == b.through_start
        assert np.max(np.linalg.norm(np.diff(a.points, axis=0), axis=1)) <= 1e-3
    cross_check(lk, replace(opt, trace=replace(opt.trace, step_max=1e-2)))


@pytest.mark.slow
def test_max_points_and_max_components_budgets():
    lk = build_preset("four-bar", {"L1": 0.5, "L2": 1.2, "L3": 1.0})
    tiny = replace(FAST, trace=replace(FAST.trace, step_max=1e-4, max_points=1000))
    res = explore(lk, TOL, tiny)  # the closed form declines; the tracer runs out of points
    assert "max_points" in str(res.search["closed_form"]) and not res.search["complete"]
    one = explore(lk, TOL, replace(FAST, max_components=1))
    assert one.search["method"] == "closed form"
    assert len(one.components) == 1 and not one.search["complete"]
    assert one.components[0].through_start  # the budget keeps the component of the start


def equilateral(l2: float = 1.0):
    return build_preset("four-bar", {"L2": l2})


def test_equilateral_four_bar_declines_and_tracer_finds_three_branch_points():
    assert closed_form_space(equilateral(), TOL, 0.1, 20_000).components is None
    res = explore(equilateral(), TOL, FAST)
    assert str(res.search["closed_form"]).startswith("declined")
    assert [cp.kind for cp in res.critical_points] == ["branch"] * 3
    assert len(res.segments) == 6


@pytest.mark.parametrize("eps", [1e-1, 1e-2, 1e-3, 1e-4, 1e-5, 1e-6, 1e-8, 1e-10])
@pytest.mark.parametrize(("sign", "count"), [(1, 1), (-1, 2)])
@pytest.mark.slow
def test_near_critical_equilateral_closed_form_right_or_declines(eps, sign, count):
    """Near critical lengths the closed form either answers right (and agrees with the tracer)
    or declines. Well away from them it answers; within its margin (``nu = sin^2`` of a dyad's
    angle below 1e-5 where it is extreme or folds: here L2 within ~1e-3 of a = 1) it declines."""
    lk = equilateral(1 + sign * eps)
    res = explore(lk, TOL, FAST)
    if res.search.get("method") == "closed form":
        assert eps > 1e-6
        assert len(res.components) == count and not res.critical_points
        cross_check(lk)
    else:
        assert eps < 1e-2
        assert str(res.search["closed_form"]).startswith("declined")


def test_three_rotor_at_critical_lengths_declines():
    lk = build_preset("three-rotor")
    assert chain_of(lk) is not None  # a dyad chain, but with twelve branch points
    res = explore(lk, TOL, FAST)
    assert str(res.search["closed_form"]).startswith("declined")
    assert len(res.critical_points) == 12


def three_rotors(count: int, seed: int = 11):
    """Three-rotors with random lengths (two dyads on the middle rotor) that assemble at the
    preset angle or after it, and are left to the closed form (away from critical lengths)."""
    rng = np.random.default_rng(seed)
    out = []
    while len(out) < count:
        p = dict(zip(("r1", "r2", "r3", "L1", "L2"), rng.uniform(0.5, 1.8, 5).tolist(),
                     strict=True))
        p["phi"] = float(rng.uniform(0.2, 2.8))
        try:
            lk = build_preset("three-rotor", p)
        except Exception:  # noqa: BLE001  (does not assemble)
            continue
        if closed_form_space(lk, TOL, 0.1, 20_000).components is None:
            continue
        out.append(p)
    return out


@pytest.mark.parametrize("params", three_rotors(12), ids=lambda p: f"phi{p['phi']:.2f}")
def test_three_rotors_closed_form_agrees_with_tracer(params):
    lk = build_preset("three-rotor", params)
    assert chain_of(lk).k == 2
    cross_check(lk)


def six_bar(lengths: dict[str, float], theta: float):
    """A chained six-bar: rotor r (P1-A); dyad B on A (c1) and P2 (b2); dyad C on B (c2) and
    P3 (b3): C's circles move with B, which folds with the four-bar P1-A-B-P2. None when it
    does not assemble at ``theta``."""
    p1, p2, p3 = np.zeros(2), np.array([1.0, 0.0]), np.array([1.6, 0.9])
    a = lengths["r"] * np.array([np.cos(theta), np.sin(theta)])
    b = circle_intersection(a, lengths["c1"], p2, lengths["b2"], 1.0)
    if b is None:
        return None
    c = circle_intersection(b, lengths["c2"], p3, lengths["b3"], 1.0)
    if c is None:
        return None
    return build_linkage(
        2,
        [VertexSpec("P1", p1.tolist(), True), VertexSpec("P2", p2.tolist(), True),
         VertexSpec("P3", p3.tolist(), True), VertexSpec("A", a.tolist()),
         VertexSpec("B", b.tolist()), VertexSpec("C", c.tolist())],
        [BarSpec("r", ("P1", "A"), lengths["r"]), BarSpec("c1", ("A", "B"), lengths["c1"]),
         BarSpec("b2", ("P2", "B"), lengths["b2"]), BarSpec("c2", ("B", "C"), lengths["c2"]),
         BarSpec("b3", ("P3", "C"), lengths["b3"])],
    )


def six_bars(count: int, seed: int = 5):
    rng = np.random.default_rng(seed)
    out = []
    while len(out) < count:
        lengths = dict(zip(("r", "c1", "b2", "c2", "b3"), rng.uniform(0.3, 1.8, 5).tolist(),
                           strict=True))
        theta = float(rng.uniform(0, 2 * np.pi))
        lk = six_bar(lengths, theta)
        if lk is None or closed_form_space(lk, TOL, 0.1, 20_000).components is None:
            continue
        out.append((lengths, theta))
    return out


@pytest.mark.parametrize("case", six_bars(16), ids=lambda c: f"r{c[0]['r']:.2f}")
def test_chained_six_bars_closed_form_agrees_with_tracer(case):
    lengths, theta = case
    lk = six_bar(lengths, theta)
    ch = chain_of(lk)
    assert ch is not None and ch.k == 2
    cross_check(lk)


def test_linkages_that_are_not_dyad_chains_are_declined():
    # a slider (gated chain), a spatial linkage, and a chain too long for 2^k sheets
    assert chain_of(build_preset("gated-kl-chain", {"n": 6, "gate": 3, "D": 2.0})) is None
    assert chain_of(build_preset("kl-chain", {"n": 12})) is None
    lk = build_linkage(
        3,
        [VertexSpec("P1", [0, 0, 0], True), VertexSpec("P2", [0, 0, 1], True),
         VertexSpec("A", [0.8, 0.2, 0.5])],
        [BarSpec("a1", ("P1", "A")), BarSpec("a2", ("P2", "A"))],
    )
    assert chain_of(lk) is None


def test_placing_in_blocks_changes_no_bit(monkeypatch):
    """:func:`engine.space.dyads.chain.place` works in blocks of PLACE_BLOCK samples; every
    operation
    is elementwise, so the positions, ``nu`` and ``d2`` are bitwise those of one block."""
    from engine.space.dyads import chain as chain_module

    rng = np.random.default_rng(3)
    for lk in (build_preset("four-bar", {"L1": 0.5, "L2": 1.2, "L3": 1.0}),
               six_bar(*six_bars(1)[0])):
        ch = chain_of(lk)
        n = 5000
        theta = rng.uniform(-np.pi, np.pi, n)
        signs = rng.choice([-1, 1], size=(n, ch.k))
        flat = rng.random((n, ch.k)) < 0.01
        whole = chain_module.place(ch, theta, signs, flat)
        monkeypatch.setattr(chain_module, "PLACE_BLOCK", 777)
        blocks = chain_module.place(ch, theta, signs, flat)
        one_sheet = chain_module.place(ch, theta, signs[:1])
        monkeypatch.undo()
        for a, b in zip(whole, blocks, strict=True):
            assert np.array_equal(a, b, equal_nan=True)
        same = chain_module.place(ch, theta, np.repeat(signs[:1], n, axis=0))
        for a, b in zip(same, one_sheet, strict=True):
            assert np.array_equal(a, b, equal_nan=True)


def test_walk_distance_is_the_polyline_distance():
    """The distance from the start to a closed-form walk, measured on the segments near it only,
    is the distance to the whole polyline (engine.space.trace.polyline_distance), on random walks
    with their step bound and targets near and far."""
    from engine.space.configuration_space.closed_form import walk_distance
    from engine.space.trace import polyline_distance

    rng = np.random.default_rng(8)
    for _ in range(200):
        m = int(rng.integers(2, 7))
        n = int(rng.integers(2, 400))
        steps = rng.normal(size=(n - 1, m))
        steps *= rng.uniform(0.0, 1.0, (n - 1, 1)) / np.linalg.norm(steps, axis=1, keepdims=True)
        walk = np.concatenate([rng.normal(size=(1, m)), steps]).cumsum(axis=0)
        gap = float(np.max(np.linalg.norm(np.diff(walk, axis=0), axis=1)))
        target = walk[int(rng.integers(n))] + rng.normal(size=m) * rng.choice([1e-3, 0.3, 10.0])
        exact = polyline_distance(walk, target)
        assert abs(walk_distance(walk, target, gap) - exact) <= 1e-12 * max(1.0, exact)
