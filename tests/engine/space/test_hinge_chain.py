"""3D hinged rotor chains derived from their cells (engine.space.hinge_chain and the answers of
engine.space.configuration_space.hinge): every ``complete`` answer against references written
here or in tests/engine/space/test_witnesses.py, never the engine's code: components from dense
sampling of the first rotor's angle with closed-form circle-sphere intersections, critical
points from the stationary points of a cell's squared distance (Newton on central differences)
or from the closed-form farthest point of a circle, completed through the other cells."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import cKDTree

from engine.catalogue.presets import build_preset
from engine.model.budget import Deadline
from engine.model.errors import EngineError
from engine.space.configuration_space import explore, find_critical_points
from engine.space.hinge_chain import cell_matrix, derive, folds, hinge_chain
from engine.space.hinge_sheets import hinge_count
from tests.engine.space.test_witnesses import (
    circle_sphere,
    circles_of,
    hinge_circle,
    on_circle,
    reference_components,
    reference_sheets,
    rotor_chain,
)

SAMPLES = 20000


# -- references --------------------------------------------------------------------------------
def squared_distance(c1, c2, x: np.ndarray) -> float:
    return float(np.sum((on_circle(c1, np.array(x[0])) - on_circle(c2, np.array(x[1]))) ** 2))


def stationary(c1, c2) -> list[tuple[np.ndarray, float, float]]:
    """Stationary points of the squared distance between two circles (angles, value, Hessian
    determinant): Newton on central differences from a 16 x 16 grid, deduplicated."""
    out: list[tuple[np.ndarray, float, float]] = []
    e = 1e-5
    grid = np.linspace(0, 2 * np.pi, 16, endpoint=False)
    for s in grid:
        for t in grid:
            x = np.array([s, t])
            for _ in range(40):
                def f(y):
                    return squared_distance(c1, c2, y)
                g = np.array([(f(x + e * k) - f(x - e * k)) / (2 * e) for k in np.eye(2)])
                h = np.array([[(f(x + e * k + e * m) - f(x + e * k - e * m)
                                - f(x - e * k + e * m) + f(x - e * k - e * m)) / (4 * e * e)
                               for m in np.eye(2)] for k in np.eye(2)])
                if abs(np.linalg.det(h)) < 1e-12:
                    break
                x = x - np.clip(np.linalg.solve(h, g), -0.3, 0.3)
            if np.linalg.norm(g) < 1e-7 and not any(
                    np.abs(np.angle(np.exp(1j * (x - y)))).max() < 1e-5 for y, _, _ in out):
                out.append((np.mod(x, 2 * np.pi), f(x), float(np.linalg.det(h))))
    return out


def completions(circles, lengths, first: int, tips: list[np.ndarray]) -> np.ndarray:
    """Every configuration (K, n, 3) with tips ``first, first + 1, ...`` given: the other tips
    from circle-sphere intersections outwards, both points each (a double one once)."""
    rows = [list(tips)]
    for j in range(first + len(tips), len(circles)):  # outwards to the right
        rows = [r + [p[0]] for r in rows
                for p in _both(circles[j], r[-1], lengths[j - 1])]
    for j in range(first - 1, -1, -1):  # and to the left
        rows = [[p[0]] + r for r in rows for p in _both(circles[j], r[0], lengths[j])]
    return np.array(rows, dtype=float).reshape(-1, len(circles), 3)


def _both(circle, centre: np.ndarray, length: float) -> list[np.ndarray]:
    pts = [p for p in circle_sphere(circle, centre[None], length) if np.isfinite(p).all()]
    if len(pts) == 2 and np.linalg.norm(pts[0] - pts[1]) < 1e-7:
        pts = pts[:1]
    return pts


def farthest(circle, point: np.ndarray) -> float:
    """Angle of the point of ``circle`` farthest from ``point`` (closed form)."""
    c, _, e1, e2 = circle
    return float(np.arctan2((c - point) @ e2, (c - point) @ e1)) + np.pi


def chain_at(lk, lengths: list[float], tips: np.ndarray):
    """The linkage with couplers ``lengths`` at tip positions ``tips`` (n, 3)."""
    _, _, tip_index = circles_of(lk)
    lens = np.array(lk.lengths, dtype=float)
    for j, value in enumerate(lengths):
        lens[list(lk.bar_ids).index(f"l{j}")] = value
    pos = np.asarray(lk.positions, dtype=float).copy()
    pos[tip_index] = tips
    return lk.with_positions(pos).with_lengths(lens)


def regular_start(circles, lengths: list[float]) -> np.ndarray | None:
    """A configuration (n, 3) of the sampled sheets, or None where there is none."""
    sheets = reference_sheets(circles, lengths, 720)
    ok = np.argwhere(np.isfinite(sheets).all(axis=(2, 3)))
    return None if not len(ok) else sheets[tuple(ok[len(ok) // 3])]


def assert_components_as_sampled(lk, res, touch: float = 0.0) -> None:
    """Components as the reference counts them, and every sampled configuration on one; an
    isolated point of the space (a rigid critical point) is a component the samples meet only
    where one lands on it (then the reference counts it too)."""
    circles, lengths, tips = circles_of(lk)
    sheets = reference_sheets(circles, lengths, SAMPLES)
    cloud = sheets[np.isfinite(sheets).all(axis=(2, 3))]
    cloud = cloud.reshape(len(cloud), 3 * len(tips))
    if not len(cloud):  # no sample on the space: it is its isolated points
        assert len(res.components) == sum(c.kind == "rigid" for c in res.critical_points)
        assert all(len(c.points) == 1 for c in res.components)
        return
    rigid = np.array([lk.positions_of(c.u)[tips].ravel() for c in res.critical_points
                      if c.kind == "rigid"]).reshape(-1, cloud.shape[1])
    unseen = int((cKDTree(cloud).query(rigid)[0] > 1e-6).sum()) if len(rigid) else 0
    assert len(res.components) == reference_components(sheets, touch) + unseen
    walk = np.vstack([lk.positions_of(u)[tips].ravel()[None] for c in res.components
                      for u in c.points])
    dist, _ = cKDTree(walk).query(cloud)
    assert dist.max() <= res.search["step_max"]


def assert_critical_as_expected(lk, res, expected: np.ndarray) -> None:
    _, _, tips = circles_of(lk)
    found = np.array([lk.positions_of(c.u)[tips] for c in res.critical_points])
    found = found.reshape(-1, 3 * len(tips))
    want = expected.reshape(len(expected), -1)
    assert len(found) == len(want)
    if len(want):
        assert cKDTree(found).query(want)[0].max() < 1e-5


# -- the cells ---------------------------------------------------------------------------------
def test_the_cell_matrix_is_the_squared_distance_less_the_length():
    rng = np.random.default_rng(0)
    for _ in range(20):
        circles = []
        for _ in range(2):
            a = rng.normal(size=3)
            b = a + rng.normal(size=3)
            circles.append(hinge_circle(a, b, *(1.2 * np.linalg.norm(b - a),) * 2))
        length = rng.uniform(0.5, 3)
        m = cell_matrix(circles[0][0], circles[0][1], np.stack(circles[0][2:]),
                        circles[1][0], circles[1][1], np.stack(circles[1][2:]), length)
        s, t = rng.uniform(0, 2 * np.pi, size=2)
        x, y = np.array([1, np.cos(s), np.sin(s)]), np.array([1, np.cos(t), np.sin(t)])
        want = np.sum((on_circle(circles[0], np.array(s)) - on_circle(circles[1], np.array(t)))
                      ** 2) - length**2
        assert x @ m @ y == pytest.approx(want, abs=1e-10)


@pytest.mark.parametrize("params", [{"n": 3, "tilt": 1.4, "h": 0.3}, {"n": 3, "l": 2.5},
                                    {"n": 3, "r": 1.0, "l": 0.8}])
def test_the_folds_are_where_the_sampled_sheets_end(params):
    # b-folds of cell k: where, over theta_k, the circle-sphere points of tip k + 1 appear or
    # vanish (sign changes of their existence on a dense grid)
    lk = build_preset("rotor-chain-3d", params)
    chain = hinge_chain(lk)
    circles, lengths, _ = circles_of(lk)
    phi = np.linspace(0, 2 * np.pi, 200000, endpoint=False)
    for k in range(chain.n - 1):
        pts = circle_sphere(circles[k + 1], on_circle(circles[k], phi), lengths[k])[0]
        exists = np.isfinite(pts).all(axis=1)
        changes = int(np.count_nonzero(exists != np.roll(exists, 1)))
        found = folds(chain.cells[k], "b", tol=1e-5)
        assert found is not None and len(found) == changes
        # and the tips there are at distance l_k: configurations of the cell
        for t0, t1 in found:
            d = np.linalg.norm(on_circle(circles[k], np.array(t0)) - on_circle(circles[k + 1],
                                                                                np.array(t1)))
            assert d == pytest.approx(lengths[k], abs=1e-7)


def test_only_hinged_chains_are_recognised():
    assert hinge_chain(build_preset("rotor-chain-3d", {"n": 5})).n == 5
    for name in ("four-bar", "three-rotor", "tetrahedron", "octahedron"):
        assert hinge_chain(build_preset(name)) is None


# -- components and critical points against the references ------------------------------------
@pytest.mark.parametrize("params", [
    {"n": 3}, {"n": 3, "tilt": 0.9, "h": 0.8}, {"n": 3, "tilt": 1.4, "h": 0.3},
    {"n": 3, "tilt": 2.2, "h": 1.1}, {"n": 3, "l": 2.5}, {"n": 4, "tilt": 0.7},
    {"n": 4, "tilt": 1.4, "h": 0.3}, {"n": 4, "r": 1.0, "l": 0.8}, {"n": 6},
    {"n": 6, "tilt": 1.1, "h": 0.4},
])
def test_presets_against_dense_sampling(params):
    lk = build_preset("rotor-chain-3d", params)
    res = explore(lk)
    assert res.search["complete"], res.search
    assert res.search["argument"] == "derived"
    assert_components_as_sampled(lk, res)
    assert res.critical_points == []
    crit = find_critical_points(lk)
    assert crit.search["complete"] and crit.critical_points == []


def random_chain(rng: np.random.Generator, n: int):
    axes, hinge, tips = [], [], []
    for k in range(n):
        a = rng.normal(size=3) + [1.5 * k, 0, 0]
        b = a + rng.normal(size=3)
        ra, rb = rng.uniform(0.8, 1.5, size=2) * np.linalg.norm(b - a)
        axes.append((a, b))
        hinge.append((ra, rb))
        tips.append(on_circle(hinge_circle(a, b, ra, rb), rng.uniform(0, 2 * np.pi)))
    return rotor_chain(axes, hinge, np.array(tips))


@pytest.mark.parametrize("seed", range(8))
def test_random_hinged_chains_against_dense_sampling(seed):
    rng = np.random.default_rng(100 + seed)
    lk = random_chain(rng, 3 + seed % 3)
    res = explore(lk)
    assert res.search["complete"], res.search
    assert res.search["argument"] == "derived"
    assert_components_as_sampled(lk, res)
    assert res.critical_points == []


CELL_TUNED = [({"n": 3}, 1), ({"n": 3}, 0), ({"n": 3, "tilt": 1.4, "h": 0.3}, 1),
              ({"n": 4, "tilt": 0.7}, 1), ({"n": 4, "tilt": 0.7}, 2)]


@pytest.mark.parametrize(("params", "cell"), CELL_TUNED)
def test_a_coupler_at_a_stationary_distance_of_its_cell(params, cell):
    """l_cell at each stationary value of its two circles' squared distance (the cell alone is
    then critical there): the critical points are its completions through the other cells; a
    saddle is a branch point where sheets cross, an extremum whose cell is only that point makes
    every completion an isolated point (a component each)."""
    base = build_preset("rotor-chain-3d", params)
    circles, lengths, _ = circles_of(base)
    tried = 0
    points = stationary(circles[cell], circles[cell + 1])
    values = sorted(v for _, v, _ in points)
    for value in [v for k, v in enumerate(values) if k == 0 or v - values[k - 1] > 1e-8]:
        at = [(x, det) for x, v, det in points if abs(v - value) < 1e-8]  # (mirror pairs)
        det = at[0][1]
        lengths_at = list(lengths)
        lengths_at[cell] = float(np.sqrt(value))
        expected = np.concatenate([completions(
            circles, lengths_at, cell, [on_circle(circles[cell], np.array(x[0])),
                                        on_circle(circles[cell + 1], np.array(x[1]))])
            for x, _ in at])
        start = regular_start(circles, lengths_at)
        isolated = start is None
        if isolated and not len(expected):
            continue  # (an extremum in a mirror-pair's list, or no completion)
        lk = chain_at(base, lengths_at, start if start is not None else expected[0])
        res = explore(lk)
        assert res.search["complete"], (value, res.search)
        assert res.search["argument"] == "derived"
        assert_critical_as_expected(lk, res, expected)
        kinds = [c.kind for c in res.critical_points]
        if det < 0:  # a saddle: sheets cross
            assert set(kinds) == {"branch"}
        else:  # an extremum: the cell is locally that point
            assert set(kinds) == {"rigid"}
        if isolated:  # the whole space is the completions, each rigid
            assert len(res.components) == len(expected)
        else:
            assert_components_as_sampled(lk, res, touch=0.05)
        crit = find_critical_points(lk)
        assert crit.search["complete"] and crit.search["argument"] == "derived"
        assert_critical_as_expected(lk, crit, expected)
        tried += 1
    assert tried >= 3


def extremes(circle, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Squared distances (K,) from points ``q`` (K, 3) to the nearest and the farthest point of
    ``circle``: ``|w|^2 + rho^2 -+ 2 rho |w in the plane|`` with ``w = q - centre``."""
    c, rho, e1, e2 = circle
    w = q - c
    planar = np.hypot(w @ e1, w @ e2)
    return np.sum(w * w, axis=1) + rho**2 - 2 * rho * planar, \
        np.sum(w * w, axis=1) + rho**2 + 2 * rho * planar


def extreme_point(circle, q: np.ndarray, far: bool) -> np.ndarray:
    c, _, e1, e2 = circle
    angle = np.arctan2((q - c) @ e2, (q - c) @ e1) + (np.pi if far else 0.0)
    return on_circle(circle, np.array(angle))


def run_reference(circles, lengths) -> np.ndarray:
    """Configurations where tip 1 sees both its neighbours' circles at an extreme distance
    equal to their coupler (cells 0 and 1 fold: a_0 = b_1 = 0): zeros of the extreme-distance
    curves over tip 1's angle (dense grid, then brentq), both checked, then completed."""
    from scipy.optimize import brentq

    grid = np.linspace(0, 2 * np.pi, 20001)
    out = []
    for first in (0, 1):  # nearest, farthest from circle 0
        def g(t, first=first):
            return extremes(circles[0], on_circle(circles[1], np.atleast_1d(t)))[first][0] \
                - lengths[0] ** 2
        values = extremes(circles[0], on_circle(circles[1], grid))[first] - lengths[0] ** 2
        for k in np.flatnonzero(np.sign(values[1:]) != np.sign(values[:-1])):
            t = brentq(g, grid[k], grid[k + 1], xtol=1e-14)
            tip1 = on_circle(circles[1], np.array(t))
            near2, far2 = (v[0] for v in extremes(circles[2], tip1[None]))
            for second, value in ((0, near2), (1, far2)):
                if abs(value - lengths[1] ** 2) < 1e-6:
                    tips = [extreme_point(circles[0], tip1, bool(first)), tip1,
                            extreme_point(circles[2], tip1, bool(second))]
                    out.append(completions(circles, lengths, 0, tips))
    return np.concatenate(out) if out else np.zeros((0, len(circles), 3))


@pytest.mark.parametrize(("params", "theta1"), [({"n": 3}, 0.7), ({"n": 3, "tilt": 1.4}, 2.0),
                                                ({"n": 4, "tilt": 0.7}, -1.0)])
def test_a_stress_on_a_run_of_two_cells(params, theta1):
    """Tip 1 at a chosen angle, l_0 its farthest distance from circle 0 (cell 0 folds:
    a_0 = 0) and l_1 its farthest from circle 2 (cell 1 folds: b_1 = 0): a self-stress on
    couplers 0 and 1 there, which no single cell explains; the reference finds every such
    configuration (a mirror image too, where the chain has one)."""
    base = build_preset("rotor-chain-3d", params)
    circles, lengths, _ = circles_of(base)
    tip1 = on_circle(circles[1], np.array(theta1))
    tip0 = extreme_point(circles[0], tip1, True)
    tip2 = extreme_point(circles[2], tip1, True)
    lengths_at = [float(np.linalg.norm(tip0 - tip1)), float(np.linalg.norm(tip2 - tip1)),
                  *lengths[2:]]
    expected = run_reference(circles, lengths_at)
    assert len(expected) >= 1
    start = regular_start(circles, lengths_at)
    lk = chain_at(base, lengths_at, start if start is not None else expected[0])
    crit = find_critical_points(lk)
    assert crit.search["complete"] and crit.search["argument"] == "derived", crit.search
    assert_critical_as_expected(lk, crit, expected)
    res = explore(lk)
    assert res.search["proved"]["critical_points"] == {"count": len(expected), "exact": True}
    if res.search["complete"]:
        assert_components_as_sampled(lk, res, touch=0.05)


# -- what is not derived says so ---------------------------------------------------------------
def test_a_cell_of_folds_is_degenerate_and_never_complete():
    """Two equal coaxial hinges at the coupler's length apart: cell 0 is the circle
    theta_0 = theta_1, every point of it a fold (a continuum of critical points)."""
    z = np.array([0.0, 0.0, 1.0])
    axes = [(np.array([0.0, 0, -1]), np.array([0.0, 0, 1])),
            (np.array([0.0, 0, 0]), np.array([0.0, 0, 2])),
            (np.array([2.0, 0, 0]), np.array([2.0, 1, 0]))]
    hinge = [(np.sqrt(2), np.sqrt(2))] * 3
    tips = np.array([[1.0, 0, 0], [1.0, 0, 1], [2.0 + 0.8, 0.5, 0.6]])
    lk = rotor_chain(axes, hinge, tips)
    del z
    d = derive(hinge_chain(lk))
    assert d.degenerate is not None and not d.critical_done
    try:
        res = find_critical_points(lk)
    except EngineError:
        return  # (refused as not one degree of freedom: no claim made)
    assert not res.search["complete"]


def test_beyond_the_bound_the_derivation_says_what_it_did_not_finish():
    lk = build_preset("rotor-chain-3d", {"n": 4, "tilt": 1.4, "h": 0.3})
    d = derive(hinge_chain(lk), points_max=10)
    assert d.stopped is not None and not d.seeds_done
    late = derive(hinge_chain(lk), deadline=Deadline.after(0.0))
    assert late.stopped is not None and "deadline" in late.stopped
    res = explore(lk, deadline=Deadline.after(0.0))
    assert not res.search["complete"]


@pytest.mark.parametrize("n", [10, 20])
def test_long_chains_are_counted_whatever_is_shown(n):
    lk = build_preset("rotor-chain-3d", {"n": n})
    assert hinge_count(lk).components == 2 ** (n - 1)
    crit = find_critical_points(lk)
    assert crit.search["complete"] and crit.critical_points == []
    res = explore(lk, near_misses=False)
    assert res.search["proved"] == {"critical_points": {"count": 0, "exact": True},
                                    "components": {"count": 2 ** (n - 1), "exact": True}}
    assert len(res.components) == 32  # (the default budget of components shown)


def test_a_long_chain_whose_cells_turn_keeps_its_critical_points_proved():
    """Eighteen rotors whose cells turn: the runs are walked (no critical point), the seeds
    would pass the walk's bound: critical points exact, components at least what was traced."""
    lk = build_preset("rotor-chain-3d", {"n": 18, "tilt": 1.4, "h": 0.3})
    res = explore(lk, near_misses=False, deadline=Deadline.after(4.0))
    assert not res.search["complete"]
    assert "seeds" in res.search["hinge_chain"]["stopped"]
    assert res.search["proved"]["critical_points"] == {"count": 0, "exact": True}
    assert res.search["proved"]["components"]["exact"] is False
