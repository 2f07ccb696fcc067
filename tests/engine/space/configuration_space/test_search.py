"""Whole configuration spaces against the classical four-bar rules, the paper's examples, and an
independent critical-point search."""

from __future__ import annotations

import itertools
from dataclasses import replace

import numpy as np
import pytest
from scipy.optimize import least_squares

from engine.catalogue.presets import build_preset
from engine.model.constraints import Constraints
from engine.model.linkage import BarSpec, VertexSpec, build_linkage
from engine.model.tolerances import CORRECT_TIGHT, Tolerances
from engine.space.configuration_space import SpaceOptions, explore, rotor_angles, winding
from engine.space.trace import correct

TOL = Tolerances()
FAST = SpaceOptions(angles=24, random_starts=4)


def random_four_bars(count: int, seed: int = 2026):
    """Seeded length sets (a = 1) that assemble and stay away from every critical value:
    every signed sum a +- L1 +- L2 +- L3 is at least 0.05 from zero."""
    rng = np.random.default_rng(seed)
    out = []
    while len(out) < count:
        l1, l2, l3 = rng.uniform(0.3, 2.2, 3)
        sums = [abs(1 + s1 * l1 + s2 * l2 + s3 * l3)
                for s1, s2, s3 in itertools.product((1, -1), repeat=3)]
        if min(sums) < 0.05:
            continue
        links = sorted([1.0, l1, l2, l3])
        if links[3] >= links[0] + links[1] + links[2]:
            continue  # does not assemble
        out.append((float(l1), float(l2), float(l3)))
    return out


def classical(l1: float, l2: float, l3: float):
    """Grashof: components, and which rotors turn fully (crank conditions)."""
    links = {"a": 1.0, "L1": l1, "L2": l2, "L3": l3}
    shortest_len, longest_len = min(links.values()), max(links.values())
    p_q = sum(links.values()) - shortest_len - longest_len
    if shortest_len + longest_len >= p_q:
        return 1, {"L1": False, "L3": False}
    shortest = min(links, key=links.get)
    full = {
        "a": {"L1": True, "L3": True},  # double crank
        "L1": {"L1": True, "L3": False},  # crank-rocker
        "L3": {"L1": False, "L3": True},
        "L2": {"L1": False, "L3": False},  # double rocker
    }[shortest]
    return 2, full


@pytest.mark.parametrize(
    "lengths", random_four_bars(200), ids=lambda x: "-".join(f"{v:.3f}" for v in x)
)
def test_four_bar_components_and_cranks_follow_grashof(lengths):
    l1, l2, l3 = lengths
    lk = build_preset("four-bar", {"L1": l1, "L2": l2, "L3": l3})
    res = explore(lk, TOL, FAST)
    count, cranks = classical(l1, l2, l3)
    assert res.search["complete"]
    assert not res.critical_points
    assert len(res.components) == count
    assert sum(c.through_start for c in res.components) == 1
    cons = Constraints(lk)
    step_max = FAST.trace.resolved_step_max(cons)
    for comp in res.components:
        assert comp.closed
        assert max(cons.max_residual(u) for u in comp.points) <= TOL.residual_atol
        assert np.max(np.linalg.norm(np.diff(comp.points, axis=0), axis=1)) <= step_max
        for bar, angles in rotor_angles(lk, comp.points).items():
            turns = winding(angles, comp.closed)
            assert (abs(turns) == 1) if cranks[bar] else (turns == 0), (bar, turns)


def equilateral(l2: float = 1.0):
    return build_preset("four-bar", {"L2": l2})


def test_equilateral_four_bar_three_branch_points_and_segments():
    res = explore(equilateral(), TOL, FAST)
    assert [cp.kind for cp in res.critical_points] == ["branch"] * 3
    # each critical point's four rays start or end exactly one segment
    ends = [(s.start, s.start_ray) for s in res.segments]
    ends += [(s.end, s.end_ray) for s in res.segments]
    assert sorted(ends) == [(k, r) for k in range(3) for r in range(4)]
    assert len(res.segments) == 6
    for s in res.segments:  # segments join distinct branch points (the three circles)
        assert s.start != s.end
    assert len(res.components) == 1 and res.components[0].closed
    # the critical points are the collinear configurations
    for cp in res.critical_points:
        pos = equilateral().positions_of(cp.u)
        assert np.allclose(pos[:, 1], 0.0, atol=1e-9)


@pytest.mark.parametrize(("sign", "count"), [(1, 1), (-1, 2)])
def test_equilateral_four_bar_perturbed(sign, count):
    """Paper: L2 = a(1 + e) gives one component, L2 = a(1 - e) two."""
    res = explore(equilateral(1 + sign * 0.05), TOL, FAST)
    assert len(res.components) == count and not res.critical_points
    assert res.search["complete"]


def augmented_residual(lk, x):
    """Independent residual of the critical-point system: bar by bar, in a different scaling."""
    m = lk.n_free
    u, s = x[:m], x[m:]
    pos = lk.positions_of(u)
    free = ~lk.fixed
    rows, force = [], np.zeros_like(pos)
    for k, (i, j) in enumerate(lk.ends):
        d = pos[i] - pos[j]
        rows.append(d @ d - lk.lengths[k] ** 2)
        force[i] += s[k] * d
        force[j] -= s[k] * d
    return np.concatenate([rows, force[free], [s @ s - 1]])


def augmented_jacobian(lk, x):
    """The Jacobian of :func:`augmented_residual` (rows: lengths, forces at the free
    coordinates, the stress norm; columns: ``u``, ``s``), bar by bar like it."""
    m = lk.n_free
    u, s = x[:m], x[m:]
    pos = lk.positions_of(u)
    n_v, dim = pos.shape
    free = (~lk.fixed).ravel()
    e = len(lk.ends)
    lengths = np.zeros((e, n_v * dim))
    force_pos = np.zeros((n_v * dim, n_v * dim))
    force_s = np.zeros((n_v * dim, e))
    eye = np.eye(dim)
    for k, (i, j) in enumerate(lk.ends):
        d = pos[i] - pos[j]
        si, sj = slice(i * dim, (i + 1) * dim), slice(j * dim, (j + 1) * dim)
        lengths[k, si] += 2 * d
        lengths[k, sj] -= 2 * d
        force_pos[si, si] += s[k] * eye
        force_pos[si, sj] -= s[k] * eye
        force_pos[sj, si] -= s[k] * eye
        force_pos[sj, sj] += s[k] * eye
        force_s[si, k] += d
        force_s[sj, k] -= d
    return np.vstack([
        np.hstack([lengths[:, free], np.zeros((e, e))]),
        np.hstack([force_pos[free][:, free], force_s[free]]),
        np.concatenate([np.zeros(m), 2 * s])[None, :],
    ])


def test_the_augmented_jacobian_is_the_residuals():
    """The reference's Jacobian against central differences of the reference's residual."""
    rng = np.random.default_rng(3)
    for lk in (build_preset("three-rotor"), build_preset("four-bar", {"L2": 1.3})):
        for _ in range(3):
            x = np.concatenate([lk.coordinates() + rng.normal(size=lk.n_free),
                                rng.normal(size=lk.n_bars)])
            h = 1e-6
            fd = np.array([(augmented_residual(lk, x + h * e) - augmented_residual(lk, x - h * e))
                           / (2 * h) for e in np.eye(x.size)]).T
            assert np.allclose(augmented_jacobian(lk, x), fd, atol=1e-7)


def independent_critical_points(lk, starts: int, seed: int) -> list[np.ndarray]:
    rng = np.random.default_rng(seed)
    found: list[np.ndarray] = []
    m, e = lk.n_free, lk.n_bars
    for _ in range(starts):
        x0 = np.concatenate([lk.coordinates() + rng.normal(size=m), rng.normal(size=e)])
        res = least_squares(lambda x: augmented_residual(lk, x), x0, method="lm", xtol=1e-15,
                            ftol=1e-15, gtol=1e-15, max_nfev=4000,
                            jac=lambda x: augmented_jacobian(lk, x))
        if np.max(np.abs(res.fun)) < 1e-10:
            u = res.x[:m]
            if all(np.linalg.norm(u - f) > 1e-6 for f in found):
                found.append(u)
    return found


@pytest.mark.slow
def test_three_rotor_twelve_branch_points_cross_checked():
    lk = build_preset("three-rotor")
    res = explore(lk, TOL, FAST)
    ours = [cp.u for cp in res.critical_points]
    assert len(ours) == 12 and all(cp.kind == "branch" for cp in res.critical_points)
    theirs = independent_critical_points(lk, starts=300, seed=7)
    assert len(theirs) == 12
    for u in theirs:
        assert min(np.linalg.norm(u - v) for v in ours) < 1e-6
    # the paper's pairing: branch points split together in pairs (identical splitting gradient)
    assert len(res.segments) == 24


@pytest.mark.slow
def test_collinear_three_rotor_is_degenerate():
    lk = build_preset("three-rotor", {"phi": 0.0})
    res = explore(lk, TOL, FAST)
    assert res.degenerate and not res.search["complete"]
    kinds = [cp.kind for cp in res.critical_points]
    assert "degenerate" in kinds
    reasons = [cp.analysis.reason for cp in res.critical_points if cp.kind == "degenerate"]
    assert any("non-isolated" in (r or "") for r in reasons)
    # the traced branches are still returned (and every point keeps the lengths)
    assert res.components and not res.segments
    cons = Constraints(lk)
    for comp in res.components:
        assert max(cons.max_residual(u) for u in comp.points) <= TOL.residual_atol


def test_three_dimensional_linkage_is_traced_and_closed():
    """A spatial one-degree-of-freedom linkage: A on the circle of two spheres about P1, P2;
    B at fixed distances from A, P3 and P4 (not coplanar with the rest)."""
    lk = build_linkage(
        3,
        [VertexSpec("P1", [0, 0, 0], True), VertexSpec("P2", [0, 0, 1], True),
         VertexSpec("P3", [2, 0, 0], True), VertexSpec("P4", [2, 1, 0.5], True),
         VertexSpec("A", [0.8, 0.2, 0.5]), VertexSpec("B", [1.6, 0.9, 0.9])],
        [BarSpec("a1", ("P1", "A")), BarSpec("a2", ("P2", "A")), BarSpec("c", ("A", "B")),
         BarSpec("b3", ("P3", "B")), BarSpec("b4", ("P4", "B"))],
    )
    res = explore(lk, TOL, SpaceOptions(random_starts=8))
    assert res.components
    cons = Constraints(lk)
    through = [c for c in res.components if c.through_start]
    assert len(through) == 1 and through[0].closed
    for comp in res.components:
        assert max(cons.max_residual(u) for u in comp.points) <= TOL.residual_atol
    assert np.linalg.norm(through[0].points[0] - through[0].points[-1]) == 0.0


@pytest.mark.parametrize("eps", [1e-3, 1e-5, 1e-6, 1e-7, 1e-8])
@pytest.mark.parametrize(("sign", "count"), [(1, 1), (-1, 2)])
def test_near_critical_four_bar_does_not_jump_branches(eps, sign, count):
    """Within ~sqrt(eps) of a split branch point the two arcs nearly touch; a predictor allowed
    1% strain could land on the other arc. The sign of the augmented determinant guards it.
    At 1e-7 and 1e-8 the neck is ~1e-4 across while the Jacobian's smallest singular value is
    ~1e-4: the corrector converges well below ``residual_atol`` (``CORRECT_TIGHT``), else its
    points sit ~1e-5 off the curve and the tracer crawled for minutes and stopped open."""
    res = explore(equilateral(1 + sign * eps), TOL, FAST)
    assert res.search["complete"]
    assert len(res.components) == count and not res.critical_points


@pytest.mark.parametrize("eps", [3e-9])
@pytest.mark.slow
def test_very_near_critical_four_bar_is_right_or_flagged(eps):
    """Closer still, the tracer may not resolve the split: then the search must say it is not
    complete; a count it calls complete must be the right one."""
    for sign, count in ((1, 1), (-1, 2)):
        res = explore(equilateral(1 + sign * eps), TOL, FAST)
        if res.search["complete"]:
            assert len(res.components) == count


def test_the_corrector_converges_below_the_residual_tolerance_near_a_neck():
    """Near critical lengths a point within ``residual_atol`` can still be ``residual_atol / s``
    off the curve (``s`` the Jacobian's smallest singular value, ~1e-4 here): the corrector
    goes on to ``CORRECT_TIGHT * residual_atol``."""
    lk = equilateral(1 - 1e-8)
    cons = Constraints(lk)
    points = explore(lk, TOL, FAST).components[0].points
    for i in range(0, len(points) - 1, max(1, len(points) // 20)):
        t = points[i + 1] - points[i]
        t /= np.linalg.norm(t)
        off = 1e-6 * np.random.default_rng(i).normal(size=t.size)
        w, ok, _ = correct(cons, points[i] + off, t, TOL)
        assert ok and cons.max_residual(w) <= CORRECT_TIGHT * TOL.residual_atol


@pytest.mark.parametrize(("sign", "count"), [(1, 1), (-1, 2)])
def test_near_critical_four_bar_with_default_options_counts_each_component_once(sign, count):
    """1e-7 from critical lengths, with the default options, a seed lay on a curve whose other
    arc (the split branch point's) passed nearer than the seed's own arc: the nearest curve
    points all belonged to the wrong pass, the seed was traced again and the same component
    came out twice with ``complete: true``. The closest point of every pass is now tested."""
    lk = equilateral(1 + sign * 1e-7)
    res = explore(lk, TOL, SpaceOptions())
    assert res.search["complete"]
    assert len(res.components) == count == res.search["components_total"]


def test_a_count_that_disagrees_with_the_chain_rule_is_unresolved(monkeypatch):
    """Fault injection: with a membership test that never recognises a traced curve, every seed
    is traced again; the four-bar rule's independent count then disagrees and the answer must
    say so instead of reporting a confident count."""
    from engine.space.configuration_space import explorer

    monkeypatch.setattr(explorer.Explorer, "on_traced", lambda self, u: False)
    monkeypatch.setattr(explorer.Explorer, "on_curve",
                        lambda self, us, curve: np.zeros(len(us), dtype=bool))
    res = explore(build_preset("four-bar", {"L2": 1.2}), TOL,
                  replace(FAST, closed_form=False, max_components=1000))
    assert len(res.components) != res.search["components_total"]
    assert not res.search["complete"] and res.search["reason"] == "unresolved"
    assert "components_disagree" in res.search


@pytest.mark.parametrize("preset, params", [("kl-chain", {"n": 12}),
                                            ("four-bar", {"L2": 1.2})])
def test_a_budget_of_values_stops_the_search_for_size_and_keeps_what_was_found(preset, params):
    # the answer's values (points x vertices), counted here from the components themselves
    lk = build_preset(preset, params)
    v = lk.n_vertices
    full = explore(lk, TOL, FAST, near_misses=False)
    full_values = v * sum(len(c.points) for c in full.components)
    budget = full_values // 4
    res = explore(lk, TOL, replace(FAST, max_values=budget), near_misses=False)
    values = v * sum(len(c.points) for c in res.components)
    assert 0 < values <= budget
    assert res.search.reason == "budget" and not res.search.complete
    assert res.search.details["answer_size_reached"] is True
    assert res.search.details["answer_values_max"] == budget
    # a budget the whole answer fits in changes nothing
    roomy = explore(lk, TOL, replace(FAST, max_values=2 * full_values), near_misses=False)
    assert "answer_size_reached" not in roomy.search.details
    assert [len(c.points) for c in roomy.components] == [len(c.points) for c in full.components]
    assert roomy.search.reason == full.search.reason


def test_a_closed_form_answer_keeps_the_values_the_time_left_maps():
    # the crank-rocker, dense: ~35000 points of 4 vertices, above a budget of 50000 values, made
    # in a moment: the time left maps them, and the closed form answers in full
    from engine.model.budget import ANSWER_SECONDS_PER_VALUE, Deadline
    from engine.space.trace import TraceOptions

    lk = build_preset("four-bar", {"L1": 0.5, "L2": 1.2, "L3": 1.0})
    opt = SpaceOptions(trace=TraceOptions(step_max=2.5e-4, max_points=200_000),
                       max_values=50_000)
    deadline = Deadline.after(4.0)
    res = explore(lk, TOL, opt, near_misses=False, deadline=deadline)
    values = lk.n_vertices * sum(len(c.points) for c in res.components)
    assert res.search.details["method"] == "closed form" and res.search.complete
    assert 50_000 < values <= (4.0 + 0.5) / ANSWER_SECONDS_PER_VALUE
