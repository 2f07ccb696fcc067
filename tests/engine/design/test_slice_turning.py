"""The turning points of a slice's curves (issue 23, item 3) against finite differences and the
four-bar's closed-form critical lines, and the traced four-bar slice they prove complete."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from engine.catalogue.presets import build_preset
from engine.design.critical_values import critical_value_slice
from engine.design.slice_regions import _polyline_distance
from engine.design.slice_turning import TurningSystem, turning_paths, turning_points
from engine.model.constraints import Constraints

SIGNS = list(itertools.product((1, -1), repeat=3))
BASE = {"a": 1.0, "L1": 1.0, "L2": 1.2, "L3": 1.0}


def _four_bar_line_residual(l2: float, l3: float) -> float:
    """min over signs of |a +- L1 +- L2 +- L3| (the four-bar's collinear configurations)."""
    return min(abs(BASE["a"] + e1 * BASE["L1"] + e2 * l2 + e3 * l3) for e1, e2, e3 in SIGNS)


def _three_rotor_system() -> tuple[TurningSystem, int]:
    lk = build_preset("three-rotor")
    cons = Constraints(lk)
    act = [int(b) for b in cons.bars]
    rows = (act.index(lk.bar_ids.index("L1")), act.index(lk.bar_ids.index("L2")))
    return TurningSystem(lk, cons, rows, np.random.default_rng(1)), cons.n_free


def test_the_turning_system_s_jacobian_is_its_derivative():
    """Central differences (step 1e-6) at random complex points: the SVD-based gradients and
    Hessians of the determinants and the bordered determinant's derivative."""
    system, m = _three_rotor_system()
    rng = np.random.default_rng(2)
    x = rng.normal(size=(3, m + 1)) + 1j * rng.normal(size=(3, m + 1))
    _, jac = system(x)
    h = 1e-6
    fd = np.stack([(system(x + h * e)[0] - system(x - h * e)[0]) / (2 * h)
                   for e in np.eye(m + 1)], axis=2)
    assert np.abs(fd - jac).max() <= 1e-6 * np.abs(jac).max()


def test_the_last_equation_is_the_bordered_jacobian_s_determinant():
    """``T`` is the determinant of the first equations' derivatives in ``y`` (by central
    differences) bordered by the gradient of ``ell``; the determinant rows are ``det [J; c]``
    with ``J`` the quadrics' derivatives (by differences as well)."""
    system, m = _three_rotor_system()
    rng = np.random.default_rng(3)
    x = rng.normal(size=(2, m + 1)) + 1j * rng.normal(size=(2, m + 1))
    values, _ = system(x)
    h = 1e-5
    fd = np.stack([(system(x + h * e)[0] - system(x - h * e)[0]) / (2 * h)
                   for e in np.eye(m + 1)], axis=2)  # (N, M, M + 1)
    base = system.base
    for k in range(len(x)):
        ell_row = 2.0 * system.ell[1:, :] @ x[k]
        bordered = np.vstack([fd[k, :m - 1, 1:], ell_row])
        assert abs(np.linalg.det(bordered) - values[k, -1]) <= 1e-6 * abs(values[k, -1])
        grads = np.array([2.0 * (q @ x[k])[1:] for q in base.quad])  # (E, M)
        for j in range(2):
            ref = np.linalg.det(np.vstack([grads, system.c[j]]))
            assert abs(ref - values[k, m - 3 + j]) <= 1e-9 * max(abs(ref), 1.0)


def test_paths_of_the_turning_homotopy():
    assert turning_paths(build_preset("four-bar")) == 2 * 9 * 6
    assert turning_paths(build_preset("three-rotor")) == 8 * 25 * 12


@pytest.mark.parametrize("box", [((0.5, 1.5), (0.5, 1.5)), ((0.3, 2.2), (0.3, 2.2))])
def test_four_bar_turning_points_are_on_its_critical_lines(box):
    """Every turning point found is a critical value (on a line a +- L1 +- L2 +- L3 = 0) with
    lengths in the box, and a critical configuration (its stress is a self-stress of the
    linkage at its lengths); the lines L2 + L3 = const crossing the box are the only ones a
    generic ``ell`` (positive weights) turns on, so some lie on one of them."""
    lk = build_preset("four-bar", {"L2": BASE["L2"]})
    b = np.array(box)
    found = turning_points(lk, (1, 2), b)
    assert found.success and found.paths == 108
    for x in found.starts:
        u, sigma, p = x[:4], x[4:7], x[7:]
        assert np.all(p >= b[:, 0] - 1e-9) and np.all(p <= b[:, 1] + 1e-9)
        assert _four_bar_line_residual(*p) <= 1e-8, p
        lengths = lk.lengths.copy()
        lengths[1], lengths[2] = p
        jac = Constraints(lk.with_lengths(lengths)).jacobian(u, sparse=False)
        assert np.linalg.norm(sigma @ jac) <= 1e-8
    # (the four-bar's sum lines in (L2, L3): L2 + L3 = a + L1 = 2 and = L1 - a + ... crossing
    # the box; ell = a L2^2 + b L3^2 is stationary on such a line at one point)
    assert len(found.starts) >= 1


@pytest.mark.slow
def test_a_traced_four_bar_slice_is_proved():
    """The four-bar traced (not its closed form) over (L2, L3) in [0.5, 1.5]^2: the sweeps and
    the turning points prove every curve found, every region's count is exact: complete with
    ``argument: proved``; every curve is on a Grashof line and every Grashof line in the box
    is drawn, and every region's count is the Grashof rule's."""
    lk = build_preset("four-bar", {"L2": BASE["L2"]})
    box = np.array([[0.5, 1.5], [0.5, 1.5]])
    res = critical_value_slice(lk, [("L2", 0.5, 1.5), ("L3", 0.5, 1.5)], resolution=16,
                               method="traced")
    s = res.search
    assert s["complete"] and s["argument"] == "proved", s["argument_detail"]
    assert s["turning_complete"] and s["turning_paths"] == 108
    assert s["turning_points_traced"] == s["turning_points"] >= 1
    for curve in res.curves:
        for l2, l3 in curve:
            assert _four_bar_line_residual(l2, l3) <= 1e-6
    xs = np.linspace(0.5, 1.5, 300)[1:-1]
    for e1, e2, e3 in SIGNS:
        const = BASE["a"] + e1 * BASE["L1"]
        ys = -(const + e2 * xs) / e3
        inside = (ys > 0.5 + 1e-3) & (ys < 1.5 - 1e-3)
        if inside.any():
            pts = np.column_stack([xs[inside], ys[inside]])
            dist = np.min([_polyline_distance(pts, c) for c in res.curves], axis=0)
            assert dist.max() <= 1e-6, (e1, e2, e3)
    for region in res.regions:
        links = sorted([BASE["a"], BASE["L1"], *region.point])
        assert region.components == (2 if links[0] + links[3] < links[1] + links[2] else 1)
    assert np.all(box[:, 0] <= np.concatenate(res.curves).min(axis=0) + 1e-12)


def test_a_slice_whose_turning_homotopy_exceeds_the_bound_says_so():
    """The three-rotor's 2,400 paths exceed the default bound of 512: with complete sweeps the
    report says the turning points were not solved for, and the slice stays searched."""
    from engine.design.slice_argument import _slice_argument
    from engine.design.slice_scan import Scan, Scanline
    from engine.design.slice_turning import TurningFound

    lines = [Scanline(k, 1.0, np.zeros((0, 13)), 400, True, "") for k in range(2)]
    scan = Scan(lines, 2, 400, "", 0.1)
    turning = TurningFound(2400, None, 0, "2,400 paths exceed the bound of 512")
    assert not turning.complete and turning.details()["turning_paths"] == 0
    argument, detail = _slice_argument(None, [], scan, 0, turning)
    assert argument is None
    assert "not solved for (2,400 paths exceed the bound of 512)" in detail


def test_the_module_example_holds():
    import doctest

    import engine.design.slice_turning

    assert doctest.testmod(engine.design.slice_turning).failed == 0
