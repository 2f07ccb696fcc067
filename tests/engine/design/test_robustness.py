"""Robustness margins against closed forms computed here, independently of the engine: the
four-bar's collinearity planes ``a +- L1 +- L2 +- L3 = 0`` (Grashof's critical lengths) and the
slider-crank's branch point ``crank = rod``; degenerate (zero-length) configurations are never
reported; the multistart agrees with the exact closed form where both apply; deadlines stop it."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from scipy.optimize import minimize

from engine.catalogue.presets import build_preset
from engine.design.dyad_margin import project_on_plane
from engine.design.robustness import min_critical_length, robustness
from engine.model.budget import Deadline
from engine.model.constraints import Constraints
from engine.model.errors import InvalidRequest
from engine.model.linkage import BarSpec, Linkage, VertexSpec, build_linkage
from engine.model.tolerances import Tolerances, scaled_tolerances
from engine.space.configuration_space import SpaceOptions

FAST = SpaceOptions(angles=24, random_starts=4)


def exact_margin(l1: float, l2: float, l3: float, adjustable: list[int]) -> float:
    """Distance from (L1, L2, L3) to the nearest plane a +- L1 +- L2 +- L3 = 0 (a = 1) moving
    only the adjustable lengths: |signed sum| / |normal restricted to them|."""
    best = np.inf
    for signs in itertools.product((1, -1), repeat=3):
        s = 1 + signs[0] * l1 + signs[1] * l2 + signs[2] * l3
        best = min(best, abs(s) / np.linalg.norm(np.array(signs)[adjustable]))
    return float(best)


def cases(count: int, seed: int):
    rng = np.random.default_rng(seed)
    out = []
    while len(out) < count:
        lengths = rng.uniform(0.6, 1.8, 3)
        if exact_margin(*lengths, [0, 1, 2]) < min(lengths):  # the planes are nearest
            out.append(tuple(float(x) for x in lengths))
    return out


@pytest.mark.parametrize("lengths", cases(5, 31), ids=lambda x: "-".join(f"{v:.3f}" for v in x))
@pytest.mark.parametrize(
    ("adjustable", "index"), [(None, [0, 1, 2]), (["L2"], [1]), (["L1", "L3"], [0, 2])]
)
def test_four_bar_margin_is_the_distance_to_the_nearest_collinearity_plane(
    lengths, adjustable, index
):
    l1, l2, l3 = lengths
    lk = build_preset("four-bar", {"L1": l1, "L2": l2, "L3": l3})
    res = robustness(lk, adjustable, options=FAST)
    assert res.success
    assert res.margin == pytest.approx(exact_margin(l1, l2, l3, index), abs=1e-7)
    # the nearest lengths are critical: collinear configuration, lengths consistent
    pos = lk.positions_of(res.critical_u)
    assert np.allclose(pos[:, 1], 0.0, atol=1e-6)
    changed = [b for b in lk.bar_ids if adjustable is not None and b not in adjustable]
    for bar in changed:
        k = lk.bar_ids.index(bar)
        assert res.nearest[k] == pytest.approx(lk.lengths[k], abs=1e-9)
    assert np.linalg.norm(res.nearest - lk.lengths) == pytest.approx(res.margin, abs=1e-7)


def test_bad_adjustable():
    lk = build_preset("four-bar", {"L2": 1.2})
    with pytest.raises(InvalidRequest) as info:
        robustness(lk, ["nope"])
    assert info.value.loc == ("adjustable", 0)


# -- independent references ------------------------------------------------------------------


def four_bar(a: float, l1: float, l2: float, l3: float, theta: float = 1.1,
             turn: float = 0.0, shift: tuple[float, float] = (0.0, 0.0)) -> Linkage:
    """Pins ``p1``, ``p2`` at distance ``a`` (rotated by ``turn``, shifted), crank ``L1`` from
    ``p1`` at ``theta`` (the first angle from there where it assembles), coupler ``L2``,
    rocker ``L3`` to ``p2``."""
    rot = np.array([[np.cos(turn), -np.sin(turn)], [np.sin(turn), np.cos(turn)]])
    for t in theta + np.linspace(0.0, 2 * np.pi, 721):
        pa = l1 * np.array([np.cos(t), np.sin(t)])
        d = np.array([a, 0.0]) - pa
        dist = float(np.hypot(*d))
        along = (dist**2 + l2**2 - l3**2) / (2 * dist)
        h2 = l2**2 - along**2
        if h2 >= 0:
            pb = pa + along * d / dist + np.sqrt(h2) * np.array([-d[1], d[0]]) / dist
            break
    else:
        raise AssertionError("does not assemble")
    pts = {k: rot @ p + np.array(shift) for k, p in
           {"p1": np.zeros(2), "p2": np.array([a, 0.0]), "A": pa, "B": pb}.items()}
    return build_linkage(2, [VertexSpec("p1", tuple(pts["p1"]), True),
                             VertexSpec("p2", tuple(pts["p2"]), True),
                             VertexSpec("A", tuple(pts["A"])), VertexSpec("B", tuple(pts["B"]))],
                         [BarSpec("L1", ("p1", "A"), l1), BarSpec("L2", ("A", "B"), l2),
                          BarSpec("L3", ("p2", "B"), l3)])


def grashof_margin(a: float, lengths: np.ndarray, adjustable: list[int], shortest: float) -> float:
    """Distance from ``lengths`` = (L1, L2, L3) to the union of the planes
    ``s1 L1 + s2 L2 + s3 L3 = a`` (every sign), moving only the adjustable lengths and keeping
    every length >= ``shortest``: per plane a small constrained least-squares problem solved by
    SciPy (not the engine's KKT solver)."""
    best = np.inf
    adj = np.array(adjustable)
    for signs in itertools.product((1.0, -1.0), repeat=3):
        n = np.array(signs)
        rhs = a - float(np.delete(n, adj) @ np.delete(lengths, adj))
        x0 = lengths[adj]
        res = minimize(lambda x, x0=x0: float((x - x0) @ (x - x0)), np.maximum(x0, shortest),
                       method="SLSQP", bounds=[(shortest, None)] * len(adj),
                       constraints=[{"type": "eq",
                                     "fun": lambda x, n=n, rhs=rhs: n[adj] @ x - rhs}],
                       options={"ftol": 1e-15, "maxiter": 100})
        if res.success and abs(n[adj] @ res.x - rhs) < 1e-9:
            best = min(best, float(np.linalg.norm(res.x - x0)))
    return best


def assert_critical(lk: Linkage, nearest: np.ndarray, u: np.ndarray, shortest: float) -> None:
    """``u`` has every bar at its ``nearest`` length, none shorter than ``shortest``, and a
    self-stress (the smallest singular value of J vanishes relative to the largest)."""
    at = lk.with_lengths(nearest)
    got = at.bar_lengths(at.positions_of(u))[lk.active]
    assert np.allclose(got, nearest[lk.active], atol=1e-6)
    assert got.min() >= shortest * (1 - 1e-9)
    sv = np.linalg.svd(Constraints(at).jacobian(u, sparse=False), compute_uv=False)
    assert sv[-1] <= 1e-6 * sv[0]


def slider_crank(crank: float = 0.7, rod: float = 1.6, theta: float = 0.9) -> Linkage:
    """Crank from pin ``O`` to ``B``, rod from ``B`` to ``P`` sliding along x."""
    b = crank * np.array([np.cos(theta), np.sin(theta)])
    px = b[0] + np.sqrt(rod**2 - b[1] ** 2)
    return build_linkage(2, [VertexSpec("O", (0.0, 0.0), True), VertexSpec("B", tuple(b)),
                             VertexSpec("P", (px, 0.0), (False, True))],
                         [BarSpec("crank", ("O", "B"), crank), BarSpec("rod", ("B", "P"), rod)])


SUBSETS = [None, ["L1"], ["L2"], ["L3"], ["L1", "L2"], ["L2", "L3"], ["L1", "L3"]]


def random_four_bars(count: int, seed: int) -> list[tuple[float, ...]]:
    rng = np.random.default_rng(seed)
    out: list[tuple[float, ...]] = []
    while len(out) < count:
        a, l1, l2, l3 = rng.uniform(0.3, 2.0, 4)
        try:
            four_bar(a, l1, l2, l3)
        except AssertionError:
            continue
        out.append((float(a), float(l1), float(l2), float(l3), float(rng.uniform(0, 2 * np.pi))))
    return out


# -- the closed form: four-bars ------------------------------------------------------------


@pytest.mark.parametrize("params", random_four_bars(12, 5),
                         ids=lambda p: "-".join(f"{v:.2f}" for v in p))
@pytest.mark.parametrize("adjustable", SUBSETS, ids=lambda a: "+".join(a or ["all"]))
def test_random_four_bars_against_the_collinearity_planes(params, adjustable):
    a, l1, l2, l3, turn = params
    lk = four_bar(a, l1, l2, l3, turn=turn, shift=(0.3, -1.7))
    tol = Tolerances()
    shortest = min_critical_length(tol)
    res = robustness(lk, adjustable, tol)
    index = [0, 1, 2] if adjustable is None else [["L1", "L2", "L3"].index(b) for b in adjustable]
    expected = grashof_margin(a, np.array([l1, l2, l3]), index, shortest)
    assert res.method == "closed-form" and res.guarantee == "exact"
    assert res.search["complete"] is True and res.search["reason"] is None
    assert res.success == bool(np.isfinite(expected))
    if not res.success:
        return
    assert res.margin == pytest.approx(expected, abs=1e-7)
    fixed = [k for k, b in enumerate(lk.bar_ids) if adjustable is not None and b not in adjustable]
    assert np.allclose(res.nearest[fixed], lk.lengths[fixed], atol=0)
    assert np.linalg.norm(res.nearest - lk.lengths) == pytest.approx(res.margin, abs=1e-9)
    assert_critical(lk, res.nearest, res.critical_u, shortest)


@pytest.mark.parametrize("lengths", [(1.0, 1.0, 1.0, 1.0), (2.0, 1.0, 2.0, 1.0),
                                     (1.0, 1.0, 0.6, 0.6), (1.3, 0.8, 1.3, 0.8)])
def test_critical_four_bars_have_margin_zero(lengths):
    """Parallelogram, kite, equilateral: critical lengths (a plane through them)."""
    lk = four_bar(*lengths)
    res = robustness(lk)
    assert res.success and res.margin == pytest.approx(0.0, abs=1e-12)
    assert_critical(lk, res.nearest, res.critical_u, min_critical_length(Tolerances()))


def test_a_short_crank_is_not_shrunk_to_nothing():
    """Only the crank may change and it is short: shrinking it to zero would be the nearest
    "critical" change (a rigid triangle), but that bar is degenerate; the nearest critical
    value is L1 = 1 (a + L1 = L2 + L3)."""
    lk = four_bar(1.0, 0.05, 1.0, 1.0)
    res = robustness(lk, ["L1"])
    assert res.margin == pytest.approx(0.95, abs=1e-9)
    assert res.nearest[0] == pytest.approx(1.0, abs=1e-9)


@pytest.mark.parametrize("seed", range(40))
def test_projection_on_a_plane_in_a_box_matches_scipy(seed):
    rng = np.random.default_rng(seed)
    k = int(rng.integers(1, 5))
    x0 = rng.uniform(0.0, 2.0, k)
    normal = rng.choice([-1.0, 1.0], k) * rng.uniform(0.2, 1.5, k)
    rhs = float(rng.uniform(-2.0, 3.0))
    lower = np.full(k, 0.1)
    got = project_on_plane(x0, normal, rhs, lower)
    res = minimize(lambda x: float((x - x0) @ (x - x0)), np.maximum(x0, lower), method="SLSQP",
                   bounds=[(0.1, None)] * k,
                   constraints=[{"type": "eq", "fun": lambda x: normal @ x - rhs}],
                   options={"ftol": 1e-15, "maxiter": 500})
    feasible = res.success and abs(normal @ res.x - rhs) < 1e-9
    if got is None:
        assert not feasible
        return
    assert normal @ got == pytest.approx(rhs, abs=1e-12) and np.all(got >= lower)
    if feasible:
        assert np.linalg.norm(got - x0) == pytest.approx(np.linalg.norm(res.x - x0), abs=1e-7)


# -- the multistart: slider-crank, agreement, deadlines ------------------------------------


@pytest.mark.parametrize(("adjustable", "expected"), [
    (None, (1.6 - 0.7) / np.sqrt(2)),  # to crank = rod along (1, -1)
    (["rod"], 0.9),  # rod = crank = 0.7
    (["crank"], 0.9),  # crank = rod = 1.6
])
def test_slider_crank_margin_is_the_branch_point_crank_equals_rod(adjustable, expected):
    """Crank 0.7, rod 1.6 sliding on the line through the pin: J^T sigma = 0 needs the rod
    vertical and the crank on the same vertical line, i.e. the slider at the pin and
    crank = rod (or a zero-length bar, which is degenerate)."""
    lk = slider_crank()
    tol = Tolerances()
    res = robustness(lk, adjustable, tol)
    assert res.success and res.method == "multistart"
    assert res.guarantee == "upper-bound" and res.exact_margin is None
    # incomplete without an argument, and the answer says what it does establish (issue 30)
    assert not res.search.complete and res.search.argument is None
    assert res.search.argument_detail.startswith("an upper bound: the best local minimum")
    assert res.guarantee_detail.startswith("best local minimum over")
    # every start ran, but a multistart's margin is an upper bound: no argument, never complete
    assert res.search["complete"] is False and res.search["reason"] == "searched"
    assert res.search["argument"] is None
    assert res.margin == pytest.approx(expected, abs=1e-7)
    assert res.nearest[0] == pytest.approx(res.nearest[1], abs=1e-7)
    assert_critical(lk, res.nearest, res.critical_u, min_critical_length(tol))


def offset_slider_crank(crank: float, rod: float, offset: float, theta: float = 0.9) -> Linkage:
    """Crank from pin ``O`` at the origin, rod to ``P`` sliding along the line ``y = offset``."""
    b = crank * np.array([np.cos(theta), np.sin(theta)])
    px = b[0] + np.sqrt(rod**2 - (b[1] - offset) ** 2)
    return build_linkage(2, [VertexSpec("O", (0.0, 0.0), True), VertexSpec("B", tuple(b)),
                             VertexSpec("P", (px, offset), (False, True))],
                         [BarSpec("crank", ("O", "B"), crank), BarSpec("rod", ("B", "P"), rod)])


def offset_slider_margin(crank: float, rod: float, offset: float, adjustable: list[int]) -> float:
    """J^T sigma = 0 needs B_x = P_x (the rod's force has no x part) and then B_x = 0 (the
    crank's): slider right above or below the pin, so crank - rod = +-offset or
    crank + rod = |offset|. Distance to the nearest of these lines moving the adjustable
    lengths, by brute force on a fine grid of each line (independent of any solver)."""
    x0 = np.array([crank, rod])
    best = np.inf
    t = np.linspace(1e-6, 5.0, 500_001)
    for line in ((1.0, -offset), (1.0, offset)):  # crank = rod + c
        pts = np.column_stack([t + line[1], t])
        pts = pts[pts[:, 0] > 0]
        fixed = [k for k in (0, 1) if k not in adjustable]
        if fixed:
            k = fixed[0]
            pts = pts[np.abs(pts[:, k] - x0[k]) < 1e-5]
            if not len(pts):
                continue
            pts[:, k] = x0[k]
        best = min(best, float(np.min(np.linalg.norm(pts - x0, axis=1))))
    # crank + rod = |offset| lies farther than |offset| from lengths both above |offset|
    assert crank > abs(offset) and rod > abs(offset)
    return best


@pytest.mark.parametrize("offset", [0.3, -0.3])
@pytest.mark.parametrize("adjustable", [None, ["rod"], ["crank"]],
                         ids=lambda a: "+".join(a or ["both"]))
@pytest.mark.slow
def test_offset_slider_crank_margin(offset, adjustable):
    lk = offset_slider_crank(0.7, 1.6, offset)
    index = [0, 1] if adjustable is None else [["crank", "rod"].index(b) for b in adjustable]
    expected = offset_slider_margin(0.7, 1.6, offset, index)
    res = robustness(lk, adjustable)
    assert res.success and res.method == "multistart"
    assert res.margin == pytest.approx(expected, abs=2e-5)  # the reference's grid step
    assert_critical(lk, res.nearest, res.critical_u, min_critical_length(Tolerances()))


def test_closed_form_declines_a_slider_crank():
    with pytest.raises(InvalidRequest) as info:
        robustness(slider_crank(), method="closed-form")
    assert info.value.loc == ("method",)
    with pytest.raises(InvalidRequest):
        robustness(slider_crank(), method="newton")


@pytest.mark.parametrize("params", random_four_bars(3, 11),
                         ids=lambda p: "-".join(f"{v:.2f}" for v in p))
@pytest.mark.parametrize("adjustable", [None, ["L2"], ["L1", "L3"]],
                         ids=lambda a: "+".join(a or ["all"]))
def test_multistart_agrees_with_the_closed_form(params, adjustable):
    a, l1, l2, l3, turn = params
    lk = four_bar(a, l1, l2, l3, turn=turn)
    exact = robustness(lk, adjustable)
    general = robustness(lk, adjustable, options=FAST, method="multistart")
    assert exact.method == "closed-form" and general.method == "multistart"
    assert exact.guarantee == "exact" and general.guarantee == "upper-bound"
    assert general.margin == pytest.approx(exact.margin, abs=1e-7)
    assert general.exact_margin == exact.margin and general.success
    assert_critical(lk, general.nearest, general.critical_u, min_critical_length(Tolerances()))


def test_an_expired_deadline_answers_at_once_marked_incomplete():
    res = robustness(slider_crank(), deadline=Deadline.after(0.0))
    assert not res.success and res.margin == np.inf
    assert res.search["complete"] is False and res.search["reason"] == "time"
    assert res.search["starts_run"] == 0


def test_a_deadline_mid_search_keeps_the_best_so_far():
    runs = {"n": 0}

    def count_local_searches(fraction: float, message: str) -> None:
        runs["n"] += "local searches" in message

    def stop_after_two_local_searches() -> bool:
        return runs["n"] > 2

    res = robustness(slider_crank(), deadline=Deadline(stop=stop_after_two_local_searches,
                                                       progress=count_local_searches))
    assert res.search["complete"] is False and res.search["reason"] == "time"
    assert 0 < res.search["starts_run"] < res.search["starts_planned"]
    if res.success:  # whatever was found is a true critical configuration, never a short bar
        assert res.margin >= (1.6 - 0.7) / np.sqrt(2) - 1e-7
        assert_critical(slider_crank(), res.nearest, res.critical_u,
                        min_critical_length(Tolerances()))


def test_closed_form_whatever_the_order_of_ends_and_with_a_ground_bar():
    """The same four-bar written with every bar's ends reversed, vertices in another order and
    the ground drawn as a bar between the pins (inactive): the same exact margin."""
    lk = four_bar(1.3, 0.6, 1.4, 0.9, turn=0.4)
    pos = {v: lk.positions[k] for k, v in enumerate(["p1", "p2", "A", "B"])}
    other = build_linkage(2, [VertexSpec("B", tuple(pos["B"])), VertexSpec("A", tuple(pos["A"])),
                              VertexSpec("p2", tuple(pos["p2"]), True),
                              VertexSpec("p1", tuple(pos["p1"]), True)],
                          [BarSpec("g", ("p2", "p1")), BarSpec("L3", ("B", "p2"), 0.9),
                           BarSpec("L2", ("B", "A"), 1.4), BarSpec("L1", ("A", "p1"), 0.6)])
    for adjustable in (None, ["L1"], ["L2", "L3"]):
        a = robustness(lk, adjustable)
        b = robustness(other, adjustable)
        assert b.method == "closed-form"
        assert b.margin == pytest.approx(a.margin, abs=1e-12)
        assert_critical(other, b.nearest, b.critical_u, min_critical_length(Tolerances()))
    with pytest.raises(InvalidRequest):
        robustness(other, ["g"])  # the ground is the pins' distance


def four_bar_margin(a: float, l1: float, l2: float, l3: float, adjustable: list[int]) -> float:
    """Grashof's critical values: the four-bar is critical exactly where
    ``a = s1 L1 + s2 L2 + s3 L3`` for some signs (the ``a +- b = c +- d`` conditions, all
    joints on a line); the margin is the distance to the nearest of these planes moving the
    adjustable lengths, ``|a - s . L| / |s restricted to them|``, over the planes whose foot of
    the perpendicular keeps every length positive. A plane whose foot does not is farther than
    its unbounded distance; the test's cases have every such distance beyond the margin, so
    that the bounds play no part (asserted)."""
    lengths = np.array([l1, l2, l3])
    valid, blocked = [np.inf], [np.inf]
    for signs in itertools.product((1.0, -1.0), repeat=3):
        s = np.array(signs)
        n = np.zeros(3)
        n[adjustable] = s[adjustable]
        dist = abs(a - s @ lengths) / float(np.linalg.norm(n))
        foot = lengths + (a - s @ lengths) / (n @ n) * n
        (valid if foot.min() > 0 else blocked).append(dist)
    assert min(valid) <= min(blocked)
    return min(valid)


#: (a, L1, L2, L3, turn, adjustable): two four-bars, every bar or one adjustable (the issue saw
#: 4.002 for 2.092 on a four-bar scaled by 3.95; 3.95 is among the scales below)
SCALED = [(1.3, 0.9, 1.5, 0.8, 0.4, [0, 1, 2]), (1.0, 1.2, 0.7, 1.05, 2.0, [1])]


@pytest.mark.slow
@pytest.mark.parametrize("case", SCALED, ids=["far", "near"])
def test_multistart_is_scale_invariant_and_meets_the_closed_form(case):
    """The same four-bar drawn at scales 1e-3..1e3 (tolerances scaled as the service does):
    the multistart's margin divided by the scale is the Grashof margin computed here at every
    scale, it says it is an upper bound, and it carries the exact margin it was compared with."""
    a, l1, l2, l3, turn, adj = case
    expected = four_bar_margin(a, l1, l2, l3, adj)
    names = [["L1", "L2", "L3"][k] for k in adj]
    got = []
    for scale in (1e-3, 1e-1, 1.0, 3.95, 1e2, 1e3):
        lk = four_bar(a * scale, l1 * scale, l2 * scale, l3 * scale, turn=turn,
                      shift=(0.3 * scale, -0.2 * scale))
        tol = scaled_tolerances(float(np.median(lk.lengths)))
        res = robustness(lk, names, tol, options=FAST, method="multistart")
        assert res.method == "multistart" and res.guarantee == "upper-bound"
        assert res.success, res.message
        assert res.margin / scale == pytest.approx(expected, rel=1e-7)
        assert res.exact_margin is not None
        assert res.exact_margin / scale == pytest.approx(expected, rel=1e-9)
        assert_critical(lk, res.nearest, res.critical_u, min_critical_length(tol))
        got.append(res.margin / scale)
    assert np.ptp(got) <= 1e-9 * expected
