"""Sweeps in the engine: points, per-point answers against the classical rules, progress, stop."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from engine.catalogue.presets import build_preset
from engine.design.sweep import (
    BarFamily,
    GridAxis,
    PresetFamily,
    SampleAxis,
    grid_points,
    run_points,
    sample_points,
    summarize,
)
from engine.model.budget import Deadline
from engine.model.linkage import BarSpec, VertexSpec, build_linkage
from engine.space.configuration_space import SpaceOptions, explore


def grashof(sides: list[float]) -> int:
    """Components of a generic planar four-bar from its four sides (classical rule)."""
    s = sorted(sides)
    if s[3] >= s[0] + s[1] + s[2]:
        return 0
    return 2 if s[0] + s[3] < s[1] + s[2] else 1


def generic(sides: list[float]) -> bool:
    return all(abs(np.dot(signs, sides)) > 1e-6
               for signs in itertools.product((1, -1), repeat=4) if signs[0] == 1)


def test_grid_points_cover_the_grid_last_axis_fastest():
    pts = grid_points([GridAxis("a", 1.0, 2.0, 3), GridAxis("b", 0.0, 1.0, 2)])
    assert pts.shape == (6, 2)
    assert pts[:, 0].tolist() == [1.0, 1.0, 1.5, 1.5, 2.0, 2.0]
    assert pts[:, 1].tolist() == [0.0, 1.0] * 3


def test_samples_reproducible_with_their_seed():
    axes = [SampleAxis("D", 2.5, 0.2), SampleAxis("L1", 2.0, 0.01)]
    a, b = sample_points(axes, 50, 3), sample_points(axes, 50, 3)
    assert np.array_equal(a, b)
    assert not np.array_equal(a, sample_points(axes, 50, 4))
    ref = np.random.default_rng(3).normal([2.5, 2.0], [0.2, 0.01], size=(50, 2))
    assert np.allclose(a, ref)


@pytest.mark.parametrize("family", ["bars", "preset"])
def test_four_bar_rows_follow_grashof(family):
    """Both families (bars of a linkage re-lengthened; the preset rebuilt) agree with the rule,
    including points where the lengths assemble nowhere."""
    lk = build_preset("four-bar")
    fam = BarFamily(lk, ("L1", "L2")) if family == "bars" else PresetFamily(
        "four-bar", {}, ("L1", "L2"))
    pts = grid_points([GridAxis("L1", 0.4, 1.7, 3), GridAxis("L2", 0.35, 3.35, 4)])
    rows = run_points(fam, pts)
    assert len(rows) == len(pts)
    for row in rows:
        sides = [1.0, row.values[0], row.values[1], 1.0]
        assert generic(sides)
        assert row.components == grashof(sides), row


def test_progress_reports_points_done_and_stop_ends_early():
    fam = PresetFamily("four-bar", {}, ("L2",))
    pts = grid_points([GridAxis("L2", 0.5, 2.5, 5)])
    seen: list[float] = []
    rows = run_points(fam, pts, deadline=Deadline.after(None, progress=lambda f, m: seen.append(f)))
    assert len(rows) == 5 and seen == [0.2, 0.4, 0.6, 0.8, 1.0]
    stopped = run_points(fam, pts, deadline=Deadline.after(None, stop=lambda: len(seen) >= 7,
                                                            progress=lambda f, m: seen.append(f)))
    assert len(stopped) == 2


def test_summary_counts_the_rows():
    fam = PresetFamily("four-bar", {}, ("L2",))
    rows = run_points(fam, grid_points([GridAxis("L2", 0.5, 3.5, 4)]))
    s = summarize(rows)
    assert s.points == 4 and s.errors == 0 and s.margin is None
    assert s.topologies == {"components=0": 1, "components=1": 2, "components=2": 1}


def test_margin_is_the_distance_to_the_nearest_critical_lengths():
    """L2 = 1.2 (L1 = L3 = a = 1): the nearest critical value is L2 = 1; L2 = 3.5: empty."""
    fam = PresetFamily("four-bar", {}, ("L2",))
    rows = run_points(fam, np.array([[1.2], [3.5]]), ("components", "margin"))
    s = summarize(rows)
    assert rows[1].components == 0 and rows[1].margin is None
    assert s.margin == pytest.approx(0.2, abs=1e-6) and s.margin_at == (1.2,)


def test_a_bad_point_is_a_row_error_not_an_exception():
    fam = BarFamily(build_preset("four-bar"), ("L2",))
    rows = run_points(fam, np.array([[-0.5], [1.5]]))
    assert rows[0].error is not None and rows[0].components is None
    assert rows[1].components == 1
    assert summarize(rows).errors == 1


def test_a_linkage_of_two_degrees_of_freedom_gives_row_errors():
    """A free two-bar arm on a pin moves with two degrees of freedom: no configuration-space
    exploration applies, and every row says why instead of the sweep failing."""
    arm = build_linkage(2, [VertexSpec("P", (0.0, 0.0), True), VertexSpec("A", (1.0, 0.0)),
                            VertexSpec("B", (2.0, 0.0))],
                        [BarSpec("L1", ("P", "A")), BarSpec("L2", ("A", "B"))])
    rows = run_points(BarFamily(arm, ("L2",)), np.array([[1.0], [1.5]]))
    assert [r.components for r in rows] == [None, None]
    assert all(r.error and "degree" in r.error for r in rows), rows


# -- rows against single explorations; gated that does not rest on the trace ---------------


def traced_turns(lk, comp) -> dict[str, int]:
    """Turns of every rotor along a traced component: atan2 of the rotor vectors at its
    points, unwrapped (computed here from the positions, not by the engine's kinematics)."""
    pos = np.repeat(lk.positions[None], len(comp.points), axis=0)
    pos[:, ~lk.fixed] = np.asarray(comp.points)
    fixed = lk.fixed.all(axis=1)
    out = {}
    for k, (i, j) in enumerate(lk.ends):
        if fixed[i] == fixed[j]:
            continue
        pin, tip = (i, j) if fixed[i] else (j, i)
        vec = pos[:, tip] - pos[:, pin]
        angle = np.unwrap(np.arctan2(vec[:, 1], vec[:, 0]))
        out[lk.bar_ids[k]] = abs(int(np.rint((angle[-1] - angle[0]) / (2 * np.pi))))
    return out


@pytest.mark.slow
def test_gated_rows_equal_single_explorations_across_the_critical_line():
    """The 3-rotor gated chain at L2 = 2 on both sides of D = 5/2 (ungated 16 components,
    gated 8), at a Grashof double rocker (L2 = 1: gated, 16) and on the line itself (no rule:
    the row is the exploration's, its count a lower bound unless an argument proves it): the
    sweep's rows against explorations of the same points (every component traced there)."""
    fam = PresetFamily("gated-kl-chain", {"n": 3, "gate": 1}, ("L2", "D"))
    pts = np.array([[2.0, 2.3], [2.0, 2.7], [1.0, 2.0], [2.0, 2.5]])
    rows = run_points(fam, pts, ("components", "windings"))
    for row, values in zip(rows, pts, strict=True):
        lk = fam.at(values)
        res = explore(lk, near_misses=False)
        turning = [traced_turns(lk, c) for c in res.components]
        assert all(c.closed for c in res.components)
        if tuple(values) != (2.0, 2.5):  # derived: the trace finds exactly the rule's count
            assert row.complete and row.argument == "derived"
            assert row.components == len(res.components)
            assert row.gated is all(not any(t.values()) for t in turning)
            assert set(row.windings) == {",".join(f"{b}:{w}" for b, w in t.items())
                                         for t in turning}
            if res.search.complete:
                assert res.search.argument == row.argument
        else:  # no rule on the critical line: the row is the exploration's
            assert row.complete is res.search.complete
            assert row.argument == res.search.argument
            assert row.components == len(res.components)
            turns_any = any(any(t.values()) for t in turning)
            assert row.gated is (False if turns_any else (True if row.complete else None))
    assert [(r.components, r.gated) for r in rows[:3]] == [(16, False), (8, True), (16, True)]


@pytest.mark.slow
@pytest.mark.parametrize("D,gated,count", [(2.0, False, 16), (3.0, True, 8)])
def test_gated_is_right_where_the_tracer_stops_short(D, gated, count):
    """A component budget of 2 stops the tracer far below the count (asked for the critical
    points, the point is explored): ``gated`` and the count still come from the rules."""
    fam = PresetFamily("gated-kl-chain", {"n": 3, "gate": 1}, ("D",))
    opt = SpaceOptions(max_components=2)
    (row,) = run_points(fam, np.array([[D]]), ("components", "critical", "windings"),
                        options=opt)
    assert row.error is None and row.critical_points == 0
    assert (row.components, row.complete, row.gated) == (count, True, gated)


@pytest.mark.slow
def test_without_a_rule_a_cut_trace_never_says_gated():
    """A gated chain whose cells are not driven from the gate rotor (r = 0.6, l = 1.2): no rule
    decides; with one component traced the row may say False (a traced rotor turns) or None
    (undecided), never True, and its count is a lower bound."""
    fam = PresetFamily("gated-kl-chain", {"n": 3, "gate": 1, "r": 0.6, "l": 1.2, "L1": 1.0,
                                          "L2": 1.0, "D": 1.0}, ("D",))
    (row,) = run_points(fam, np.array([[1.0]]), ("components", "windings"),
                        options=SpaceOptions(max_components=1))
    assert row.error is None and row.complete is False and row.argument is None
    assert row.gated is not True and row.gated_reason
    if row.gated is None:
        assert row.gated_reason.startswith("undecided")


def test_a_gated_grid_is_derived_wherever_it_assembles():
    """A 20 x 20 gated 10-rotor grid with windings: every row that assembles is derived."""
    fam = PresetFamily("gated-kl-chain", {}, ("L2", "D"))
    pts = grid_points([GridAxis("L2", 0.5, 5.0, 20), GridAxis("D", 0.5, 5.0, 20)])
    rows = run_points(fam, pts, ("components", "windings"))
    for row in rows:
        if row.components:
            assert row.argument == "derived" and row.components in (1024, 2048)
            assert row.gated is (row.windings == ((",".join(
                f"r{k}:0" for k in range(10)) + ",D:0"),))


@pytest.mark.parametrize("name,params,names,values", [
    ("gated-kl-chain", {"n": 3, "gate": 1}, ("L2", "D"), (0.5, 4.5)),  # 4.5 > 0.5 + 1.5 + 2
    ("four-bar", {}, ("L2",), (3.5,)),  # 3.5 > 1 + 1 + 1
])
def test_a_point_whose_four_bar_cannot_close_is_proved_empty(name, params, names, values):
    """The preset assembles nowhere, and its bars at these lengths include a four-bar whose
    longest side exceeds the other three together: 0 components, derived, nothing gated."""
    (row,) = run_points(PresetFamily(name, params, names), np.array([values]),
                        ("components", "windings"))
    assert (row.components, row.complete, row.argument) == (0, True, "derived")
    assert row.windings == () and row.gated is None and "no configuration" in row.gated_reason


def test_an_empty_point_without_a_rule_stays_a_lower_bound():
    """Swept parameters that are not bars (the chain's rotor length r): no rule sees the
    lengths, and a preset that assembles at none of its sampled angles is a search, not a
    proof."""
    fam = PresetFamily("gated-kl-chain", {"n": 3, "gate": 1, "D": 4.5, "L2": 0.5}, ("r",))
    (row,) = run_points(fam, np.array([[1.5]]), ("components", "windings"))
    assert (row.components, row.complete, row.argument, row.gated) == (0, False, None, None)


def test_bars_and_preset_families_give_the_same_derived_rows():
    """The gated chain's (L2, D) grid as the preset rebuilt and as its bars re-lengthened (off
    the configuration space): the rules see the same cells, so the rows agree."""
    lk = build_preset("gated-kl-chain", {"n": 3, "gate": 1})
    pts = grid_points([GridAxis("L2", 0.5, 5.0, 6), GridAxis("D", 0.5, 5.0, 6)])
    want = ("components", "windings")
    by_preset = run_points(PresetFamily("gated-kl-chain", {"n": 3, "gate": 1}, ("L2", "D")),
                           pts, want)
    by_bars = run_points(BarFamily(lk, ("L2", "D")), pts, want)
    for a, b in zip(by_preset, by_bars, strict=True):
        assert (a.components, a.complete, a.windings, a.gated) == \
            (b.components, b.complete, b.windings, b.gated), (a, b)
        assert a.argument == b.argument == "derived"


def tau_signs(a: float, l1: float, l2: float, l3: float) -> tuple[int, int, int]:
    """The paper's Eq. 16 (after McCarthy) for a four-bar with ground ``a``, input ``l1``,
    coupler ``l2``, output ``l3``: the signs of tau_1 = a - l1 + l2 - l3, tau_2 = a - l1 - l2 +
    l3, tau_3 = l2 + l3 - a - l1 (the test's points are off every critical line)."""
    taus = (a - l1 + l2 - l3, a - l1 - l2 + l3, l2 + l3 - a - l1)
    assert min(abs(t) for t in taus) > 1e-6
    return tuple(int(np.sign(t)) for t in taus)  # type: ignore[return-value]


def test_gated_rows_carry_the_gate_four_bars_tau_signs():
    """The gated chain's (L2, D) grid: every row carries the gate four-bar's signs (ground D,
    input the gate rotor r, coupler L2, output L1) computed here from the point's lengths, and
    no chain cell (no swept bar is a side of one); the signs tell the gated rows apart as the
    Grashof type does: gated exactly where the gate rotor is no crank."""
    r, l1 = 1.5, 2.0
    pts = grid_points([GridAxis("L2", 0.55, 4.95, 9), GridAxis("D", 0.55, 4.95, 9)])
    rows = run_points(PresetFamily("gated-kl-chain", {"n": 3, "gate": 1}, ("L2", "D")), pts,
                      ("components", "windings"))
    seen = set()
    for row in rows:
        l2, d = row.values
        assert row.tau_signs is not None and len(row.tau_signs) == 1, row
        (cell,) = row.tau_signs
        assert cell.name == "gate" and cell.bars == ("r1", "L2", "L1") and cell.ground == "D"
        assert cell.sides == pytest.approx((d, r, l2, l1), rel=1e-12)
        assert cell.signs == tau_signs(d, r, l2, l1), row
        seen.add(cell.signs)
        if row.components:  # the input turns fully iff (+,+,+) or (-,-,+)
            assert row.gated is (cell.signs not in ((1, 1, 1), (-1, -1, 1))), row
    assert len(seen) >= 5  # the grid crosses the lines of every tau


def test_rows_carry_the_signs_of_every_cell_a_swept_name_sets():
    """A four-bar's bars swept: its one cell, oriented as its bars say (input, coupler,
    output); a chain's pin spacing ``a`` (a parameter, not a bar) sets every cell; one rotor
    of a chain given as bars: the two cells it is a side of; a slider-crank: no cell."""
    lk = build_preset("four-bar", {})
    pts = np.array([[0.4, 2.3], [1.6, 0.7], [0.6, 1.3]])
    for row in run_points(BarFamily(lk, ("L1", "L2")), pts, ("components",)):
        (cell,) = row.tau_signs
        length = dict(zip(("L1", "L3"), (row.values[0], 1.0), strict=True))
        inp, coupler, out = cell.bars
        assert coupler == "L2" and {inp, out} == {"L1", "L3"}
        assert cell.signs == tau_signs(1.0, length[inp], row.values[1], length[out]), row
    rows = run_points(PresetFamily("kl-chain", {"n": 4, "r": 1.5, "l": 1.5}, ("a",)),
                      np.array([[1.0], [1.8], [0.4]]), ("components",))
    for row in rows:
        a = row.values[0]
        assert [c.name for c in row.tau_signs] == ["r0-l0-r1", "r1-l1-r2", "r2-l2-r3"]
        assert all(c.signs == tau_signs(a, 1.5, 1.5, 1.5) for c in row.tau_signs), row
    chain = build_preset("kl-chain", {"n": 4})
    (row,) = run_points(BarFamily(chain, ("r1",)), np.array([[1.3]]), ("components",))
    assert [c.name for c in row.tau_signs] == ["r0-l0-r1", "r1-l1-r2"]
    first, second = row.tau_signs
    assert first.signs == tau_signs(1.0, 1.5, 1.5, 1.3)
    assert second.signs == tau_signs(1.0, 1.3, 1.5, 1.5)
    crank = build_linkage(2, [VertexSpec("O", [0.0, 0.0], True), VertexSpec("B", [0.0, 0.7]),
                              VertexSpec("P", [1.44, 0.0], [False, True])],
                          [BarSpec("crank", ("O", "B")), BarSpec("rod", ("B", "P"))])
    (row,) = run_points(BarFamily(crank, ("rod",)), np.array([[1.6]]), ("components",))
    assert row.tau_signs is None
