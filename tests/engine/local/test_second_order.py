"""Second-order analysis against independently found critical points and independent projection."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from engine.catalogue.presets import build_preset
from engine.local.rigidity import first_order
from engine.local.second_order import second_order
from engine.model.linkage import BarSpec, VertexSpec, build_linkage
from tests.strategies import nearest_solution


def four_bar_critical_configurations(a: float, l1: float, l2: float, l3: float):
    """Critical configurations of the planar four-bar, found without the engine.

    A four-bar (pins (0,0), (a,0); tips A, B) is critical exactly when all four joints are
    collinear (the classical result; the paper's critical configuration set y_A = y_B = 0).
    Enumerate the collinear assemblies: A = (+-l1, 0), B = (a +- l3, 0) with |B - A| = l2.
    """
    found = []
    for xa, xb in itertools.product((l1, -l1), (a + l3, a - l3)):
        if abs(abs(xb - xa) - l2) < 1e-12:
            found.append(((xa, 0.0), (xb, 0.0)))
    return found


def at(linkage, **where):
    pos = np.array(linkage.positions)
    for vid, p in where.items():
        pos[linkage.vertex_ids.index(vid)] = p
    return linkage.with_positions(pos)


def correction(linkage, direction: np.ndarray, h: float) -> float:
    """Distance from ``u_c + h * direction`` to the configuration space (independent SLSQP)."""
    u = linkage.coordinates() + h * direction
    return float(np.linalg.norm(nearest_solution(linkage, u) - u))


EQUILATERAL = build_preset("four-bar")
CRITICAL = four_bar_critical_configurations(1.0, 1.0, 1.0, 1.0)


def test_equilateral_four_bar_has_three_collinear_critical_configurations():
    assert len(CRITICAL) == 3
    for pa, pb in CRITICAL:
        lk = at(EQUILATERAL, A=pa, B=pb)
        assert np.allclose(lk.bar_lengths(), 1.0)


@pytest.mark.parametrize("config", CRITICAL, ids=[f"A={a[0]:+g},B={b[0]:+g}" for a, b in CRITICAL])
@pytest.mark.slow
def test_equilateral_four_bar_critical_points_are_branch_points(config):
    lk = at(EQUILATERAL, A=config[0], B=config[1])
    res = second_order(lk)
    assert res.rigidity.critical
    assert res.rigidity.self_stresses.shape[0] == 1
    assert res.zero_modes.shape[0] == 2
    assert res.kind == "branch", res.reason
    assert res.q_eigenvalues[0] > 0 > res.q_eigenvalues[1]
    assert res.tangents.shape == (2, lk.n_free)
    # each tangent solves c^T Q c = 0 and is a unit zero mode
    for c, t in zip(res.tangent_coefficients, res.tangents, strict=True):
        assert abs(c @ res.q @ c) <= 1e-10
        assert abs(np.linalg.norm(t) - 1) <= 1e-12
    # each tangent is tangent to the configuration space: the correction after a step h is O(h^2)
    for t in res.tangents:
        for sign in (1.0, -1.0):
            c1, c2 = correction(lk, sign * t, 2e-2), correction(lk, sign * t, 1e-2)
            assert c1 <= 2.0 * (2e-2) ** 2 and c2 <= 2.0 * (1e-2) ** 2
            assert 3.0 <= c1 / c2 <= 5.0, (c1, c2)
    # negative control: a zero mode that is not a branch direction needs an O(h) correction
    off = res.zero_modes[0]
    c1, c2 = correction(lk, off, 2e-2), correction(lk, off, 1e-2)
    assert c1 > 10 * (2e-2) ** 2 and 1.5 <= c1 / c2 <= 2.5


def test_equilateral_four_bar_generic_configuration_is_regular():
    for theta in (np.pi / 3, 1.0, 2.5, 4.0):
        res = second_order(build_preset("four-bar", {"theta": theta}))
        assert res.kind == "regular"
        assert res.zero_modes.shape[0] == 1
        assert res.self_stress is None and res.rigidity.self_stresses.shape[0] == 0


@pytest.mark.parametrize("dim", [2, 3])
def test_straight_two_bar_chain_is_rigid(dim):
    origin, mid, end = np.zeros(dim), np.eye(dim)[0], 2 * np.eye(dim)[0]
    lk = build_linkage(
        dim,
        [VertexSpec("P", origin.tolist(), True), VertexSpec("A", mid.tolist()),
         VertexSpec("Q", end.tolist(), True)],
        [BarSpec("a", ("P", "A")), BarSpec("b", ("A", "Q"))],
    )
    res = second_order(lk)
    assert res.rigidity.critical
    assert res.kind == "rigid"
    assert res.zero_modes.shape[0] == dim - 1
    assert np.all(res.q_eigenvalues > 0)
    # closed form: sigma = (1, 1)/sqrt(2), Hess(l^2) = 2 I on A for each bar -> Q = 2 sqrt(2) I
    np.testing.assert_allclose(res.q_eigenvalues, 2 * np.sqrt(2))
    # a bent chain is regular
    bent = at(lk, A=(mid + 0.3 * np.eye(dim)[1]).tolist())
    assert second_order(bent).kind == "regular"


def test_collinear_three_rotor_is_degenerate_not_a_count():
    """Pins on a line, all lengths equal, rotor 2 folded onto pin 1: rotor 1 spins freely along
    a whole circle of critical configurations (non-isolated critical set)."""
    lk = build_preset("three-rotor", {"phi": 0.0})
    lk = at(lk, B=(0.0, 0.0), A=(0.6, 0.8), C=(1.0, 0.0))
    assert np.allclose(lk.bar_lengths(), 1.0)
    res = second_order(lk)
    assert res.kind == "degenerate"
    assert "non-isolated" in res.reason
    # and along that circle every point is critical (independent check of the claim)
    for angle in (0.3, 1.1, 2.0):
        moved = at(lk, A=(np.cos(angle), np.sin(angle)))
        assert first_order(moved).critical


def test_several_self_stresses_are_degenerate():
    lk = build_linkage(
        2,
        [VertexSpec("P", [0, 0], True), VertexSpec("A", [1, 0]), VertexSpec("Q", [2, 0], True),
         VertexSpec("R", [3, 0], True)],
        [BarSpec("a", ("P", "A")), BarSpec("b", ("A", "Q")), BarSpec("c", ("A", "R"))],
    )
    res = second_order(lk)
    assert res.kind == "degenerate" and "2 self-stresses" in res.reason


def test_straight_three_bar_chain_matches_closed_form():
    """P-A-B-Q straight between two pins: one stress (1, 1, 1)/sqrt(3); on the y-velocities of
    A and B, Q = (2/sqrt(3)) [[2, -1], [-1, 2]] with eigenvalues 6/sqrt(3) and 2/sqrt(3): rigid."""
    lk = build_linkage(
        2,
        [VertexSpec("P", [0, 0], True), VertexSpec("A", [1, 0]), VertexSpec("B", [2, 0]),
         VertexSpec("Q", [3, 0], True)],
        [BarSpec("a", ("P", "A")), BarSpec("b", ("A", "B")), BarSpec("c", ("B", "Q"))],
    )
    res = second_order(lk)
    assert res.kind == "rigid"
    np.testing.assert_allclose(res.self_stress, np.ones(3) / np.sqrt(3))
    np.testing.assert_allclose(res.q_eigenvalues, [6 / np.sqrt(3), 2 / np.sqrt(3)])
    np.testing.assert_allclose(np.abs(res.zero_modes[0]), [0, 1, 0, 1] / np.sqrt(2), atol=1e-12)


def test_doubled_bar_cancelling_stress_is_not_called_rigid():
    """sigma = (1, -1)/sqrt(2) on a doubled bar makes H_sigma = 0: Q vanishes identically and
    the (mobile) four-bar must be degenerate, never 'rigid'."""
    fb = build_preset("four-bar")
    pos = fb.positions
    lk = build_linkage(
        2,
        [VertexSpec("P1", [0, 0], True), VertexSpec("P2", [1, 0], True),
         VertexSpec("A", pos[2].tolist()), VertexSpec("B", pos[3].tolist())],
        [BarSpec("L1", ("P1", "A")), BarSpec("L1b", ("P1", "A")), BarSpec("L2", ("A", "B")),
         BarSpec("L3", ("P2", "B"))],
    )
    res = second_order(lk)
    assert res.kind == "degenerate", (res.kind, res.q_eigenvalues)
    assert "non-isolated" in res.reason


@pytest.mark.parametrize("sparse", [False, True])
def test_second_order_is_deterministic(sparse):
    lk = at(EQUILATERAL, A=(-1.0, 0.0), B=(0.0, 0.0))
    ref = second_order(lk, sparse=sparse)
    for _ in range(5):
        again = second_order(lk, sparse=sparse)
        np.testing.assert_array_equal(again.self_stress, ref.self_stress)
        np.testing.assert_array_equal(again.q_eigenvalues, ref.q_eigenvalues)
