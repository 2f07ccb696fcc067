"""Critical value slices against the classical four-bar conditions, and the gate."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from scipy import ndimage

from engine.catalogue.presets import build_preset
from engine.design.critical_values import critical_value_slice
from engine.design.slice_curves import Axis, _System
from engine.design.slice_regions import _blocked_cells, _polyline_distance
from engine.space.configuration_space import SpaceOptions, explore
from tests.engine.design.slice_references import (
    ThreeRotor,
    distance_to_curves,
    gate_lines,
    gate_rotor_turns,
    points_inside,
)
from tests.load import Timer

SIGNS = list(itertools.product((1, -1), repeat=3))


def plane_residual(point: dict[str, float]) -> float:
    """min over sign patterns of |a + e1 L1 + e2 L2 + e3 L3| (a = 1): zero on the four-bar's
    critical value set (collinear configurations)."""
    return min(abs(point["a"] + e1 * point["L1"] + e2 * point["L2"] + e3 * point["L3"])
               for e1, e2, e3 in SIGNS)


def grashof_components(lengths: dict[str, float]) -> int:
    links = sorted(lengths.values())
    return 2 if links[0] + links[3] < links[1] + links[2] else 1


def four_bar_components(lengths: dict[str, float]) -> int:
    links = sorted(lengths.values())
    if links[3] >= links[0] + links[1] + links[2]:
        return 0  # does not assemble
    return grashof_components(lengths)


@pytest.mark.parametrize(
    ("x", "y", "x_range"),
    # The (L1, L2) box avoids its nearly rigid corner (L1 small, L2 near a + L1 + L3), where
    # the seed explorations of tiny configuration spaces are slow (a known cost issue, not a
    # correctness one: see the CHANGELOG).
    [("L2", "L3", (0.3, 3.6)), ("L1", "L2", (0.4, 2.0))],
    ids=["L2-L3 (with the empty region beyond L2 = 2 + L3)", "L1-L2"],
)
def test_four_bar_slice(x, y, x_range):
    base = {"a": 1.0, "L1": 1.0, "L2": 1.2, "L3": 1.0}
    lk = build_preset("four-bar", {k: v for k, v in base.items() if k != "a"})
    box = {x: x_range, y: (0.3, 2.2)}
    x_max = x_range[1]
    res = critical_value_slice(lk, [(x, *box[x]), (y, *box[y])], resolution=32,
                               options=SpaceOptions(angles=24, random_starts=4))
    assert res.curves
    # 1. every curve point is a critical value: on a plane a +- L1 +- L2 +- L3 = 0
    for curve in res.curves:
        for px, py in curve:
            assert plane_residual({**base, x: px, y: py}) <= 1e-6
    # 2. the curves cover every such line inside the box
    for e1, e2, e3 in SIGNS:
        coef = dict(zip(("L1", "L2", "L3"), (e1, e2, e3), strict=True))
        const = 1.0 + sum(coef[k] * base[k] for k in ("L1", "L2", "L3") if k not in (x, y))
        # const + coef[x] * X + coef[y] * Y = 0 -> Y = -(const + coef[x] X) / coef[y]
        xs = np.linspace(*box[x], 400)[1:-1]
        ys = -(const + coef[x] * xs) / coef[y]
        inside = (ys > box[y][0] + 1e-3) & (ys < box[y][1] - 1e-3)
        if not inside.any():
            continue
        pts = np.column_stack([xs[inside], ys[inside]])
        dist = np.min([_polyline_distance(pts, c) for c in res.curves], axis=0)
        assert np.max(dist) <= 1e-6, (e1, e2, e3)
    # 3. every region's component count follows the classical rule
    assert len(res.regions) >= 3
    for region in res.regions:
        lengths = {**base, x: region.point[0], y: region.point[1]}
        assert region.components == four_bar_components(lengths), (region, lengths)
    if x_max > 3:  # the boundary of the empty configuration space is a curve of the slice
        assert any(r.components == 0 for r in res.regions)


def gate_turns(l2: float, d: float, r: float = 1.5, l1: float = 2.0) -> int:
    """Classical: the gate rotor (crank r of the four-bar with ground D, coupler L2, rocker L1)
    turns fully iff the four-bar is Grashof and the crank or the ground is shortest."""
    links = {"D": d, "r": r, "L2": l2, "L1": l1}
    values = sorted(links.values())
    grashof = values[0] + values[3] < values[1] + values[2]
    return int(grashof and min(links, key=links.get) in ("r", "D"))


@pytest.mark.slow
def test_gate_slice_matches_the_gate_four_bar():
    """Paper: r = l = 3a/2, L1 = 2a; slice in (L2, D)."""
    lk = build_preset("gated-kl-chain", {"n": 4, "gate": 2})
    res = critical_value_slice(lk, [("L2", 1.0, 3.0), ("D", 1.0, 3.5)], resolution=16,
                               options=SpaceOptions(angles=12, random_starts=2, max_components=4))
    for curve in res.curves:
        for l2, d in curve:
            residual = min(abs(d + e1 * 1.5 + e2 * l2 + e3 * 2.0) for e1, e2, e3 in SIGNS)
            assert residual <= 1e-6
    assert len(res.curves) == 3
    assert len(res.regions) == 6
    for region in res.regions:
        expected = gate_turns(*region.point)
        turns = {int(t.split(":")[1]) for t in region.signature.split("turns=")[1].split(",")
                 if t.startswith("r")}
        assert turns == {expected}, region


def test_the_slice_system_reuses_the_jacobian_only_at_the_same_point():
    """``G`` and ``DG`` of one system asked along a sequence of points (one changed in place,
    as least squares may do) equal those of a fresh system at each point."""
    lk = build_preset("gated-kl-chain", {"n": 4, "gate": 2})
    axes = (Axis(lk.bar_ids.index("L2"), 1.0, 3.0), Axis(lk.bar_ids.index("D"), 1.0, 3.5))
    sys = _System(lk, axes)
    rng = np.random.default_rng(3)
    x = rng.normal(size=sys.n)
    for k in range(6):
        if k % 2:
            x[rng.integers(sys.m)] += 1e-3  # in place: same array, another u
        else:
            x = rng.normal(size=sys.n)
        fresh = _System(lk, axes)
        for first, second in (("g", "dg"), ("dg", "g")):
            for name in (first, second):
                np.testing.assert_array_equal(getattr(sys, name)(x), getattr(fresh, name)(x))


@pytest.mark.slow
def test_a_traced_slice_has_one_topology_per_region():
    """Three-rotor traced (``method="traced"``), (L1, L2) in [0.5, 2]^2: away from the curves every
    region has the component count of its sample point at three more of its cells. A curve
    missed inside a region (as a seeding that skipped the seeds of regions already explored
    did here: 8 of 11 curves) leaves a region with two counts."""
    lk = build_preset("three-rotor")
    box = np.array([[0.5, 2.0], [0.5, 2.0]])
    n = 16
    opt = SpaceOptions(angles=12, random_starts=2, max_components=4)
    res = critical_value_slice(lk, [("L1", 0.5, 2.0), ("L2", 0.5, 2.0)], resolution=n,
                               options=opt, method="traced")
    # traced: nothing was cut short, but only a search (issue 23, item 3 is open)
    assert not res.search["complete"] and res.search["reason"] == "searched"
    free = ~_blocked_cells(res.curves, box, n)
    labels, count = ndimage.label(free)
    # one region per piece of the raster, or several pieces the finer raster joins; regions
    # thinner than a cell have no cell
    assert count >= sum(r.cells > 0 for r in res.regions)
    dist = ndimage.distance_transform_edt(free)
    bars = (lk.bar_ids.index("L1"), lk.bar_ids.index("L2"))
    for region in (r for r in res.regions if r.cells > 0):
        cell = tuple(((np.array(region.point) - box[:, 0]) / (box[:, 1] - box[:, 0]) * n)
                     .astype(int))
        inner = np.argwhere((labels == labels[cell]) & (dist >= 2))
        for i, j in inner[np.linspace(0, len(inner) - 1, min(3, len(inner))).astype(int)]:
            lengths = lk.lengths.copy()
            lengths[bars[0]], lengths[bars[1]] = box[:, 0] + (box[:, 1] - box[:, 0]) * (
                np.array([i, j]) + 0.5) / n
            at = lk.with_lengths(lengths)
            comps = explore(at, options=opt, start_on_space=False, near_misses=False).components
            assert len(comps) == region.components, (region, (i, j))


def _inside_points(res, box: np.ndarray, n: int, region, count: int = 3) -> list[np.ndarray]:  # noqa: ANN001
    """The region's sample and up to ``count`` of its cells at least two cells from every curve
    (a region thinner than a cell: its sample only)."""
    points = [np.array(region.point)]
    if region.cells == 0:
        return points
    free = ~_blocked_cells(res.curves, box, n)
    labels, _ = ndimage.label(free)
    dist = ndimage.distance_transform_edt(free)
    span = box[:, 1] - box[:, 0]
    cell = tuple(np.clip(((points[0] - box[:, 0]) / span * n).astype(int), 0, n - 1))
    inner = np.argwhere((labels == labels[cell]) & (dist >= 2))
    for i, j in inner[np.linspace(0, len(inner) - 1, min(count, len(inner))).astype(int)]:
        points.append(box[:, 0] + span * (np.array([i, j]) + 0.5) / n)
    return points


def _covered(res, pieces: list[np.ndarray], box: np.ndarray, atol: float) -> None:  # noqa: ANN001
    """Every point of the closed-form pieces strictly inside the box is within ``atol`` of a
    curve of the slice."""
    for piece in pieces:
        inside = np.all((piece > box[:, 0] + 1e-3) & (piece < box[:, 1] - 1e-3), axis=1)
        if not inside.any():
            continue
        pts = piece[inside][:: max(1, int(inside.sum()) // 400)]
        dist = np.min([_polyline_distance(pts, c) for c in res.curves], axis=0)
        assert dist.max() <= atol, pts[np.argmax(dist)]


@pytest.mark.parametrize(("axes", "box"), [
    (("L1", "L2"), ((0.6, 1.4), (0.6, 1.4))),  # issue 23's box
    (("r1", "r2"), ((0.8, 1.2), (0.8, 1.2))),  # the preset matrix's: the first two free bars
])
def test_the_three_rotor_slice_has_its_closed_form_critical_set(axes, box):
    """Issue 23: the default three-rotor's maps have the lines where one dyad straightens with
    the middle rotor (a flat four-bar cell, where the other dyad assembles) and the curves
    where both dyads are straight (over (L1, L2) the arc from (0.98, 0.6) to (0.6, 0.98), where
    a component is born at a rigid point, was missed: one region held 3 and 4 components).
    Every curve point is on the critical set written in the test, every critical point that
    its scanlines find is drawn, every region's count is the dense sampling's at its sample and
    at four more of its cells, and the map is complete: derived, from its closed form."""
    lk = build_preset("three-rotor")
    n = 48
    b = np.array(box)
    res = critical_value_slice(lk, [(axes[0], *box[0]), (axes[1], *box[1])], resolution=n)
    ref = ThreeRotor()
    for curve in res.curves:
        assert ref.residuals(axes, curve).max() <= 1e-9
    expected = ref.scanned(axes, b)
    assert distance_to_curves(expected, res.curves).max() <= 1e-3
    for region in res.regions:
        points = [np.array(region.point)] + points_inside(res.curves, b, n,
                                                          np.array(region.point))
        for q in points:
            assert region.components == ref.components(dict(zip(axes, q, strict=True))), \
                (region, q)
    s = res.search
    assert s["complete"] and s["argument"] == "derived" and s["method"] == "closed form"
    assert "both of its dyads are straight" in s["argument_detail"]
    if axes == ("L1", "L2"):
        assert {3, 4} <= {r.components for r in res.regions}


def test_a_three_rotor_map_critical_on_a_piece_of_the_plane_says_degenerate():
    """The preset's lengths hold its cell r2-L2-r3 flat whatever r1 and L1 are: the map of
    (r1, L1) has no curves to draw (the critical lengths fill the part of the box where the
    first dyad reaches the flat cell's tip), and answers at once that it is degenerate (it was
    traced to the end of its budget)."""
    from engine.model.budget import Deadline

    lk = build_preset("three-rotor")
    res = critical_value_slice(lk, [("r1", 0.5, 1.5), ("L1", 0.5, 1.5)], resolution=8,
                               deadline=Deadline.after(4.0))
    s = res.search
    assert not s["complete"] and s["reason"] == "degenerate" and not res.curves
    assert "r2-L2-r3 is flat at every length" in s["argument_detail"]
    # (B at (1, 1) with the cell flat: the first dyad reaches it where |r1 - L1| <= sqrt(2))
    assert all(r.components is not None for r in res.regions)


@pytest.mark.slow
@pytest.mark.parametrize(("box", "empty"), [
    (((1.0, 3.0), (1.0, 3.5)), False),
    (((0.5, 3.0), (1.0, 5.0)), True),  # with the line D = L2 + 3.5 beyond which it is empty
], ids=["default box", "with the empty region"])
def test_the_gate_slice_has_its_closed_form_lines(box, empty):
    """The gated chain (n = 4, gate 2) over (L2, D): its critical values are the gate four-bar's
    straight lines D = +-r +-L2 +-L1 (the chain's dyads never straighten), the last of which
    bounds the region where the space is empty; every curve point is on one, every line in the
    box is drawn, and the gate rotor's turning in every region is the dense sampling's at its
    sample and at three more of its cells (0 components where the gate does not assemble)."""
    lk = build_preset("gated-kl-chain", {"n": 4, "gate": 2})
    n = 48
    b = np.array(box)
    res = critical_value_slice(lk, [("L2", *box[0]), ("D", *box[1])], resolution=n,
                               options=SpaceOptions(angles=12, random_starts=2,
                                                    max_components=4))
    lines = gate_lines()
    for curve in res.curves:
        for l2, d in curve:
            assert min(abs(d - (k * l2 + c)) for k, c in lines) <= 1e-6, (l2, d)
    xs = np.linspace(*box[0], 400)
    _covered(res, [np.column_stack([xs, k * xs + c]) for k, c in lines], b, 1e-6)
    kinds = set()
    for region in res.regions:
        for q in _inside_points(res, b, n, region):
            expected = gate_rotor_turns(*q)
            kinds.add(expected)
            if expected is None:
                assert region.components == 0, (region, q)
                continue
            turns = {int(t.split(":")[1]) for t in
                     region.signature.split("turns=")[1].split(",") if t.startswith("r2")}
            assert turns == {expected}, (region, q)
    assert (None in kinds) == empty and {0, 1} <= kinds


def test_a_four_bar_map_keeps_a_region_thinner_than_a_cell():
    """Four-bar a = 1, L1 = 1.01 over (L2, L3) in [0.3, 2.2]^2 at 48 cells (0.04 each): the
    lines L3 = L2 +- 0.01 (a +- L1 +- L2 +- L3 = 0) bound a strip 0.014 wide where the four-bar
    is Grashof (2 components, 1 on either side for L2 > 1): it is a region of the map, with
    every region's count the classical rule's."""
    base = {"a": 1.0, "L1": 1.01, "L2": 1.2, "L3": 1.0}
    lk = build_preset("four-bar", {"L1": 1.01, "L2": 1.2})
    res = critical_value_slice(lk, [("L2", 0.3, 2.2), ("L3", 0.3, 2.2)], resolution=48)
    for region in res.regions:
        lengths = {**base, "L2": region.point[0], "L3": region.point[1]}
        assert region.components == four_bar_components(lengths), region
    # the strip beyond L2 = 1.01 (below it other lines cross it and it is non-Grashof)
    strip = [r for r in res.regions if abs(r.point[1] - r.point[0]) < 0.01 and r.point[0] > 1.1]
    assert strip and all(r.components == 2 and r.cells == 0 for r in strip)
    assert res.search["complete"] and res.search["thin_unresolved"] == 0


def test_moving_starts_onto_the_critical_set_stops_at_the_deadline():
    """Moving a slice's starts onto ``G = 0`` (a dense ``lstsq`` per Gauss-Newton step and a
    dense SVD per least-squares evaluation: seconds for a 100-rotor chain) looks at the
    deadline on every step: once it has passed, the starts come back as they were (off
    ``G = 0``, so the tracing leaves them out), and a least squares it ends midway gives its
    start back."""
    from engine.design.critical_values import _validate
    from engine.design.slice_curves import (
        _least_squares_onto,
        _onto_solutions,
        _onto_solutions_batch,
    )
    from engine.model.budget import Deadline

    lk = build_preset("four-bar", {"L2": 1.2})
    ax = _validate(lk, [("L2", 0.5, 1.5), ("L3", 0.5, 1.5)])
    sys = _System(lk, ax)
    rng = np.random.default_rng(1)
    x0s = rng.normal(size=(3, sys.n))
    gone = Deadline.after(0.0)
    np.testing.assert_array_equal(_onto_solutions(sys, x0s[0], deadline=gone), x0s[0])
    np.testing.assert_array_equal(_onto_solutions_batch(sys, x0s, deadline=gone), x0s)
    calls = []

    def stop() -> bool:  # the deadline passes at the third evaluation
        calls.append(1)
        return len(calls) > 2

    got = _least_squares_onto(sys, x0s[0], Deadline.after(None, stop=stop))
    np.testing.assert_array_equal(got, x0s[0])
    assert len(calls) == 3


@pytest.mark.slow
def test_a_100_rotor_chain_s_map_answers_within_its_budget():
    """The Kane-Lubensky chain of 100 rotors over +-20 % of its first two free bars (the
    preset matrix's request): traced, its starts took 10 s of dense algebra past a 4 s
    deadline; now the traced map stops at its deadline, and the default method draws the
    first four-bar's flat planes and counts the regions by the chain rules (complete)."""

    from engine.model.budget import Deadline

    lk = build_preset("kl-chain", {"n": 100})
    free = np.flatnonzero(lk.active)  # (the bars with a free end, in request order)
    axes = [(lk.bar_ids[k], 0.8 * lk.lengths[k], 1.2 * lk.lengths[k]) for k in free[:2]]
    with Timer() as t:
        s = critical_value_slice(lk, axes, deadline=Deadline.after(4.0), method="traced")
    # test_bounded's margin of 2 s of an idle machine's work after the deadline, scaled by the
    # load measured around the call (tests/load.py)
    assert t.within(4.0, 2.0), f"answered after {t}"
    assert s.search["complete"] is False and s.search["reason"] == "time"
    s = critical_value_slice(lk, axes, deadline=Deadline.after(4.0))
    assert s.search["complete"] and s.search["argument"] == "derived"
    assert s.search["method"] == "closed form" and len(s.curves) == 3
    assert sorted(r.components for r in s.regions) == [2**98] * 3 + [2**99]


@pytest.mark.parametrize("seconds", [None, 0.0])
def test_two_degrees_of_freedom_are_refused_before_any_time_is_spent(seconds):
    """A map needs one degree of freedom: the pentagon (D = 2) is refused naming the linkage's
    bars, also when the deadline has already passed (it answered 200 with regions 'not
    explored (time)' then)."""
    from engine.model.budget import Deadline
    from engine.model.errors import InvalidLinkage

    lk = build_preset("pentagon")
    with pytest.raises(InvalidLinkage) as err:
        critical_value_slice(lk, [("L1", 0.8, 1.2), ("L2", 0.8, 1.2)], resolution=8,
                             deadline=Deadline.after(seconds))
    assert err.value.loc == ("bars",) and "one degree of freedom" in err.value.message
