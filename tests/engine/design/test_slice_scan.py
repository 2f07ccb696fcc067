"""Every critical value on a scanline (engine/design/slice_scan.py) against closed forms."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from engine.catalogue.presets import build_preset
from engine.design.slice_scan import ScanDirection, scan_paths
from tests.engine.design.slice_references import three_rotor_residual


def _bars(lk):  # noqa: ANN001, ANN202 - test helper
    return {name: k for k, name in enumerate(lk.bar_ids)}


@pytest.mark.parametrize("held", [0.55, 1.2, 1.7])
def test_a_four_bar_scanline_has_every_critical_value(held):
    """Four-bar (a = L1 = 1), L2 held, L3 free: the critical values are the positive
    ``|1 +- 1 +- L2|`` (the four-bar straight), each found, and nothing else."""
    lk = build_preset("four-bar", {"L2": 1.2})
    b = _bars(lk)
    scan = ScanDirection(lk, b["L3"], b["L2"], 0, 1.2, 4.0)
    assert scan.paths == scan_paths(lk) == 2**2 * 3**2
    line = scan.at_value(held)
    assert line.success, line.message
    expected = {round(abs(1 + s1 * 1 + s2 * held), 9)
                for s1, s2 in itertools.product((1, -1), repeat=2)} - {0.0}
    found = {round(float(v), 9) for v in line.starts[:, -1] if v > 1e-6}
    assert found == expected
    assert np.all(line.starts[:, -2] == held)
    # each start is a critical configuration: J^T sigma = 0 with |sigma| = 1
    from engine.model.constraints import Constraints  # noqa: PLC0415 - only here
    for x in line.starts:
        lengths = lk.lengths.copy()
        lengths[b["L2"]], lengths[b["L3"]] = x[-2:]
        cons = Constraints(lk.with_lengths(lengths))
        u, sig = x[:cons.n_free], x[cons.n_free:cons.n_free + cons.n_constraints]
        assert np.abs(cons.jacobian(u, sparse=False).T @ sig).max() < 1e-8
        assert np.allclose(cons.squared_lengths(u), lengths[cons.bars] ** 2, atol=1e-8)


@pytest.mark.slow
def test_a_three_rotor_scanline_has_the_arc_where_both_dyads_are_straight():
    """Three-rotor, L1 held at 0.6, L2 free: the critical values in [0.6, 1.4] are the line
    L2 = 1 and where the arc of both dyads straight crosses (L2 = 0.98 here): every value found is
    on the closed-form set, and the arc's crossing is among them."""
    lk = build_preset("three-rotor")
    b = _bars(lk)
    scan = ScanDirection(lk, b["L2"], b["L1"], 0, 1.0, 1.4)
    line = scan.at_value(0.6)
    assert line.success, line.message
    raw = [float(v) for v in line.starts[:, -1] if 0.6 <= v <= 1.4]
    for v in raw:
        assert three_rotor_residual(0.6, v) < 1e-7, v
    values = {round(v, 6) for v in raw}
    # the arc L1 = d1 - 1, L2 = d3 - 1 at L1 = 0.6: d1 = 1.6 fixes B (two mirror points)
    arc = {round(float(np.linalg.norm(bp - np.array([1.0, 1.0]))) - 1.0, 6)
           for bp in _circle_points(1.6)}
    assert arc & values, (arc, values)
    assert 1.0 in values


def _circle_points(d1: float) -> list[np.ndarray]:
    from tests.engine.design.slice_references import P1, P2, R2, circle_points  # noqa: PLC0415
    return circle_points(P1, d1, P2, R2)


@pytest.mark.slow
def test_a_sweep_finds_where_the_three_rotor_curves_enter_the_box():
    """Three-rotor, L1 swept from 0.6 to 1.4 with L2 in [0.6, 1.4]: the curves that enter the
    box through its bottom or top edge between the two ends (the arc where both dyads are
    straight enters at L1 = 0.98, the corner curves at 0.717 and 1.283, closed forms below) are
    each met by a point the sweep reports, and every point it reports in the box is critical (on
    the closed-form set)."""
    from tests.engine.design.slice_references import P1, P2, P3, R2, circle_points  # noqa: PLC0415

    lk = build_preset("three-rotor")
    b = _bars(lk)
    scan = ScanDirection(lk, b["L2"], b["L1"], 0, 1.0, 1.4)
    line = scan.sweep(0.6, 1.4, 0.6, 1.4, 0.8 / 48)
    assert line.success, line.message
    for l1, l2 in line.starts[:, -2:]:
        if 0.6 <= l2 <= 1.4:  # (the edges' critical values outside the box too, L2 = 0 among them)
            assert three_rotor_residual(l1, l2) < 1e-3, (l1, l2)  # (points of the bent path)
    # where the bottom edge L2 = 0.6 is critical: |P3 B| = 1.6 or 0.4, L1 = |P1 B| -+ 1
    entries = []
    for d3 in (1.6, 0.4):
        for bp in circle_points(P3, d3, P2, R2):
            d1 = float(np.linalg.norm(bp - P1))
            entries += [v for v in (d1 - 1.0, 1.0 - d1, d1 + 1.0) if 0.6 < v < 1.4]
    assert entries
    for e in entries:
        near = np.abs(line.starts[:, -2] - e) <= 2 * 0.8 / 48
        assert near.any(), (e, line.starts[:, -2:])
