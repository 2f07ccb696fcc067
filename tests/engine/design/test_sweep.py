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
