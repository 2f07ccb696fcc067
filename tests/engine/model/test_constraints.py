"""Constraint map, analytic Jacobian and stress-Hessian against finite differences; projection."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from engine.local.rigidity import first_order
from engine.model.constraints import Constraints, on_constraints, project
from engine.model.errors import NoNearbySolution
from engine.model.linkage import BarSpec, VertexSpec, build_linkage
from engine.model.tolerances import Tolerances
from tests.strategies import (
    random_linkages,
    squared_lengths_jacobian_reference,
    squared_lengths_reference,
)

SETTINGS = settings(max_examples=60, deadline=None, derandomize=True)


def central_difference(fun, u: np.ndarray, h: float = 1e-6) -> np.ndarray:
    cols = []
    for k in range(u.size):
        e = np.zeros_like(u)
        e[k] = h
        cols.append((fun(u + e) - fun(u - e)) / (2 * h))
    return np.array(cols).T


@SETTINGS
@given(random_linkages())
def test_squared_lengths_match_reference(linkage):
    cons = Constraints(linkage)
    u = linkage.coordinates()
    np.testing.assert_allclose(
        cons.squared_lengths(u), squared_lengths_reference(linkage, u), rtol=1e-12, atol=1e-12
    )


@SETTINGS
@given(random_linkages())
def test_jacobian_matches_central_differences(linkage):
    cons = Constraints(linkage)
    u = linkage.coordinates()
    if u.size == 0:
        return
    fd = central_difference(lambda x: squared_lengths_reference(linkage, x), u).reshape(
        cons.n_constraints, cons.n_free
    )
    dense = cons.jacobian(u, sparse=False)
    sparse = cons.jacobian(u, sparse=True).toarray()
    np.testing.assert_allclose(dense, fd, atol=1e-7)
    np.testing.assert_array_equal(dense, sparse)
    # the tests' own reference Jacobian (nearest_solution's SLSQP constraint), bar by bar
    np.testing.assert_allclose(squared_lengths_jacobian_reference(linkage, u), fd, atol=1e-7)


@SETTINGS
@given(random_linkages(), st.integers(0, 2**32 - 1))
def test_stress_hessian_matches_central_differences(linkage, seed):
    cons = Constraints(linkage)
    u = linkage.coordinates()
    if u.size == 0:
        return
    sigma = np.random.default_rng(seed).normal(size=cons.n_constraints)
    # Hess(sigma . f) = d/du (J^T sigma), differentiated numerically from the reference f.
    grad = lambda x: central_difference(  # noqa: E731
        lambda y: np.atleast_1d(sigma @ squared_lengths_reference(linkage, y)), x, h=1e-5
    ).ravel()
    fd = central_difference(grad, u, h=1e-4)
    analytic = cons.stress_hessian(sigma, sparse=False)
    np.testing.assert_allclose(analytic, fd, atol=1e-5 * max(1.0, np.abs(sigma).sum()))
    np.testing.assert_allclose(cons.stress_hessian(sigma, sparse=True).toarray(), analytic)
    np.testing.assert_allclose(analytic, analytic.T)


def test_inert_bar_between_pins_is_not_a_constraint():
    lk = build_linkage(
        2,
        [VertexSpec("P", [0, 0], True), VertexSpec("Q", [2, 0], True), VertexSpec("A", [1, 1])],
        [BarSpec("g", ("P", "Q")), BarSpec("a", ("P", "A")), BarSpec("b", ("A", "Q"))],
    )
    cons = Constraints(lk)
    assert cons.n_constraints == 2
    assert list(cons.bars) == [1, 2]
    rig = first_order(lk)
    assert rig.self_stresses.shape == (0, 3) and not rig.critical


@SETTINGS
@given(random_linkages(min_vertices=4), st.integers(0, 2**32 - 1))
def test_projection_lands_on_constraints_and_moves_orthogonally(linkage, seed):
    """Perturb the positions, project back: the residual is below residual_atol and the
    displacement is orthogonal to the tangent space at the solution to second order (the
    first-order condition of the nearest point)."""
    rng = np.random.default_rng(seed)
    u0 = linkage.coordinates()
    eps = 1e-3
    start = linkage.with_positions(linkage.positions_of(u0 + eps * rng.normal(size=u0.size)))
    tol = Tolerances()
    res = project(start, tol)
    rig = first_order(linkage, tol)
    if rig.critical or rig.dof + rig.trivial_motions == 0:
        return  # nearest-point geometry is only first-order clean at regular points
    assert res.success, res.message
    assert res.residual <= tol.residual_atol
    moved = start.coordinates(res.positions) - start.coordinates()
    at = first_order(linkage.with_positions(res.positions), tol)
    tangent = np.vstack([at.zero_modes, at.trivial_basis])
    assert np.linalg.norm(tangent @ moved) <= 50 * np.linalg.norm(moved) ** 2 + 1e-12


def test_projection_from_the_paper_example_positions():
    """API.md example positions (0.309, 0.951) are 5.9e-5 off the unit circle: projected."""
    lk = build_linkage(
        2,
        [VertexSpec("P1", [0, 0], True), VertexSpec("A", [0.309, 0.951])],
        [BarSpec("r1", ("P1", "A"), 1.0)],
    )
    at, res = on_constraints(lk)
    assert res.input_residual > 1e-5
    assert res.residual <= 1e-9
    assert abs(np.linalg.norm(at.positions[1]) - 1.0) <= 1e-9
    # nearest point on a circle: radial projection
    np.testing.assert_allclose(at.positions[1], np.array([0.309, 0.951]) / np.hypot(0.309, 0.951))


def test_projection_separates_coincident_ends():
    """At coincident ends J's row is zero; the projection still finds the nearest solution
    (each end moves half the length, total displacement L / sqrt(2))."""
    lk = build_linkage(
        2, [VertexSpec("a", [0, 0]), VertexSpec("b", [0, 0])], [BarSpec("ab", ("a", "b"), 1.0)]
    )
    res = project(lk)
    assert res.success
    assert abs(np.linalg.norm(res.positions[0] - res.positions[1]) - 1.0) <= 1e-9
    assert abs(res.distance - 1 / np.sqrt(2)) <= 1e-5


def test_infeasible_lengths_fail_clearly():
    lk = build_linkage(
        2,
        [VertexSpec("P", [0, 0], True), VertexSpec("Q", [10, 0], True), VertexSpec("A", [5, 1])],
        [BarSpec("a", ("P", "A"), 1.0), BarSpec("b", ("A", "Q"), 1.0)],
    )
    res = project(lk)
    assert not res.success and res.residual > 1.0
    with pytest.raises(NoNearbySolution, match="not near any configuration") as info:
        on_constraints(lk)
    assert info.value.loc == ("vertices",)


@pytest.mark.parametrize("offset", [0.0, 1e-8, 1e-5])
@pytest.mark.parametrize("l2", [1.001, 0.999, 1.01])
def test_projection_from_a_critical_configuration_with_perturbed_lengths(offset, l2):
    """At a branch point with perturbed lengths, J^T g = 0: plain Gauss-Newton is stationary.
    The projection must still land on the configuration space, near the nearest solution
    (independent SLSQP reference)."""
    from engine.catalogue.presets import build_preset
    from tests.strategies import nearest_solution

    fb = build_preset("four-bar")
    pos = np.array(fb.positions)
    pos[2], pos[3] = (-1.0, 0.0), (0.0, offset)
    lk = fb.with_positions(pos).with_lengths([1.0, l2, 1.0])
    res = project(lk)
    assert res.success, res.message
    reference = np.linalg.norm(nearest_solution(lk, lk.coordinates()) - lk.coordinates())
    assert res.distance <= 1.01 * reference
