"""First-order analysis: invariants, a second method that must agree, trivial motions, and the
tangent form against explicit minors."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings

from engine.catalogue.presets import build_preset
from engine.local.rigidity import first_order
from engine.model.constraints import Constraints
from engine.model.linkage import BarSpec, VertexSpec, build_linkage
from tests.strategies import random_linkages

SETTINGS = settings(max_examples=60, deadline=None, derandomize=True)


def check_invariants(linkage, rig):
    cons = Constraints(linkage)
    jac = cons.jacobian(linkage.coordinates(), sparse=False)
    scale = max(1.0, np.linalg.norm(jac, 2)) if jac.size else 1.0
    m = cons.n_free
    for z in rig.zero_modes:
        assert np.linalg.norm(jac @ z) <= 1e-8 * scale
    for t in rig.trivial_basis:
        assert np.linalg.norm(jac @ t) <= 1e-8 * scale
    for s in rig.self_stresses:
        assert np.linalg.norm(s[cons.bars] @ jac) <= 1e-8 * scale
        assert np.all(s[~linkage.active] == 0)
    # rank-nullity: rank + nontrivial zero modes + trivial motions = M
    assert rig.rank + rig.dof + rig.trivial_motions == m
    # left null space: E_a - rank stresses
    assert rig.self_stresses.shape[0] == cons.n_constraints - rig.rank
    basis = np.vstack([rig.zero_modes, rig.trivial_basis])
    if basis.size:
        np.testing.assert_allclose(basis @ basis.T, np.eye(len(basis)), atol=1e-8)
    if rig.self_stresses.size:
        s = rig.self_stresses
        np.testing.assert_allclose(s @ s.T, np.eye(len(s)), atol=1e-8)


def same_subspace(a: np.ndarray, b: np.ndarray) -> bool:
    if a.shape != b.shape:
        return False
    if a.size == 0:
        return True
    return bool(np.linalg.norm(a.T @ (a @ b.T) - b.T, 2) < 1e-6)


@SETTINGS
@given(random_linkages())
def test_invariants_on_random_linkages(linkage):
    check_invariants(linkage, first_order(linkage))


@SETTINGS
@given(random_linkages(max_vertices=6))
def test_sparse_method_agrees_with_dense(linkage):
    dense = first_order(linkage, sparse=False)
    sparse = first_order(linkage, sparse=True)
    check_invariants(linkage, sparse)
    assert (sparse.rank, sparse.dof, sparse.trivial_motions) == (
        dense.rank,
        dense.dof,
        dense.trivial_motions,
    )
    assert same_subspace(sparse.zero_modes, dense.zero_modes)
    assert same_subspace(sparse.self_stresses, dense.self_stresses)


def equilateral_collinear():
    base = build_preset("four-bar")
    pos = np.array(base.positions)
    pos[2], pos[3] = (-1.0, 0.0), (0.0, 0.0)
    return base.with_positions(pos)


@pytest.mark.parametrize(
    "linkage",
    [
        build_preset("kl-chain", {"n": 60}),
        build_preset("gated-kl-chain", {"n": 30, "gate": 12}),
        build_preset("three-rotor"),
        equilateral_collinear(),
    ],
    ids=["kl-chain-60", "gated-30", "three-rotor", "four-bar-critical"],
)
def test_sparse_method_agrees_on_catalogue(linkage):
    dense = first_order(linkage, sparse=False)
    sparse = first_order(linkage, sparse=True)
    check_invariants(linkage, dense)
    check_invariants(linkage, sparse)
    assert (sparse.rank, sparse.dof, sparse.critical) == (dense.rank, dense.dof, dense.critical)
    assert same_subspace(sparse.zero_modes, dense.zero_modes)
    assert same_subspace(sparse.self_stresses, dense.self_stresses)
    # the smallest singular values agree
    np.testing.assert_allclose(
        np.sort(sparse.singular_values)[:2], np.sort(dense.singular_values)[:2], atol=1e-9
    )


def test_free_triangle_has_only_trivial_motions():
    lk = build_linkage(
        2,
        [VertexSpec("a", [0, 0]), VertexSpec("b", [1, 0]), VertexSpec("c", [0.3, 0.8])],
        [BarSpec("ab", "ab"), BarSpec("bc", "bc"), BarSpec("ca", "ca")],
    )
    rig = first_order(lk)
    assert (rig.trivial_motions, rig.dof, rig.expected_dof, rig.rank) == (3, 0, 0, 3)
    assert rig.self_stresses.shape[0] == 0 and not rig.critical
    check_invariants(lk, rig)


def test_free_tetrahedron_has_only_trivial_motions():
    pts = [[0, 0, 0], [1, 0, 0], [0.2, 0.9, 0], [0.3, 0.3, 0.8]]
    names = "abcd"
    lk = build_linkage(
        3,
        [VertexSpec(n, p) for n, p in zip(names, pts, strict=True)],
        [BarSpec(a + b, (a, b)) for i, a in enumerate(names) for b in names[i + 1 :]],
    )
    rig = first_order(lk)
    assert (rig.trivial_motions, rig.dof, rig.rank) == (6, 0, 6)
    assert rig.self_stresses.shape[0] == 0 and not rig.critical
    check_invariants(lk, rig)


def test_degenerate_rigid_motions():
    # collinear in 3D: rotation about the line moves nothing -> 5 trivial motions
    lk = build_linkage(
        3,
        [VertexSpec("a", [0, 0, 0]), VertexSpec("b", [1, 0, 0]), VertexSpec("c", [3, 0, 0])],
        [BarSpec("ab", "ab"), BarSpec("bc", "bc")],
    )
    rig = first_order(lk)
    assert rig.trivial_motions == 5
    check_invariants(lk, rig)
    # a collinear free triangle in 2D: 3 trivial motions, one flex, one self-stress
    tri = build_linkage(
        2,
        [VertexSpec("a", [0, 0]), VertexSpec("b", [1, 0]), VertexSpec("c", [3, 0])],
        [BarSpec("ab", "ab"), BarSpec("bc", "bc"), BarSpec("ca", "ca")],
    )
    rig = first_order(tri)
    assert (rig.trivial_motions, rig.dof, rig.self_stresses.shape[0]) == (3, 1, 1)
    assert rig.critical
    check_invariants(tri, rig)


def explicit_minor_tangent(jac: np.ndarray) -> np.ndarray:
    """t_i = det([e_i; J]) from explicit determinants (reference only; tiny M)."""
    m = jac.shape[1]
    return np.array([np.linalg.det(np.vstack([np.eye(m)[i], jac])) for i in range(m)])


@SETTINGS
@given(random_linkages(min_vertices=3, max_vertices=6, dof=1))
def test_tangent_form_equals_explicit_minors(linkage):
    cons = Constraints(linkage)
    assert cons.n_free - cons.n_constraints == 1 and linkage.anything_fixed
    jac = cons.jacobian(linkage.coordinates(), sparse=False)
    reference = explicit_minor_tangent(jac)
    for sparse in (False, True):
        tf = first_order(linkage, sparse=sparse).tangent_form
        assert tf is not None
        if tf.orientation == 0:
            assert np.linalg.norm(reference) <= 1e-8 * max(1.0, np.linalg.norm(jac)) ** len(jac)
            continue
        value = tf.direction * 10**tf.log10_magnitude
        np.testing.assert_allclose(value, reference, rtol=1e-7, atol=1e-9 * np.abs(reference).max())
        assert np.linalg.norm(jac @ tf.direction) <= 1e-9 * max(1.0, np.linalg.norm(jac))


def test_tangent_form_vanishes_at_critical_points_and_flips_across():
    """On the equilateral four-bar parallelogram branch, the tangent form is nonzero away from
    the branch points and vanishes there (paper, Appendix B)."""
    crit = first_order(equilateral_collinear())
    assert crit.critical and crit.tangent_form is not None and crit.tangent_form.orientation == 0
    for theta in (0.3, 1.5, 2.9, -1.0):
        lk = build_preset("four-bar", {"theta": theta})
        tf = first_order(lk).tangent_form
        assert tf is not None and tf.orientation in (-1, 1) and tf.log10_magnitude > -3


def straight_chain(n: int):
    names = ["P"] + [f"v{k}" for k in range(n)] + ["Q"]
    vertices = [
        VertexSpec(name, [float(k), 0.0], name in ("P", "Q")) for k, name in enumerate(names)
    ]
    bars = [BarSpec(f"b{k}", (names[k], names[k + 1])) for k in range(n + 1)]
    return build_linkage(2, vertices, bars)


def fan_of_rotors(n: int, seed: int = 1):
    angles = np.random.default_rng(seed).uniform(0, 2 * np.pi, n)
    vertices = [VertexSpec("P", [0.0, 0.0], True)] + [
        VertexSpec(f"t{k}", [float(np.cos(a)), float(np.sin(a))]) for k, a in enumerate(angles)
    ]
    return build_linkage(2, vertices, [BarSpec(f"r{k}", ("P", f"t{k}")) for k in range(n)])


@pytest.mark.parametrize(
    "linkage",
    [straight_chain(20), fan_of_rotors(350)],
    ids=["straight-chain-20 (20-fold null space)", "350-rotor fan (M=700, sparse by default)"],
)
def test_sparse_method_finds_repeated_zero_eigenvalues(linkage):
    """Lanczos alone finds one copy of a repeated eigenvalue; deflation must find them all."""
    dense = first_order(linkage, sparse=False)
    sparse = first_order(linkage, sparse=True)
    check_invariants(linkage, sparse)
    assert (sparse.rank, sparse.dof, sparse.critical, sparse.self_stresses.shape[0]) == (
        dense.rank, dense.dof, dense.critical, dense.self_stresses.shape[0],
    )
    assert same_subspace(sparse.self_stresses, dense.self_stresses)


def test_sparse_method_with_a_zero_jacobian():
    vertices = [VertexSpec(f"v{k}", [0.0, 0.0]) for k in range(302)]
    bars = [BarSpec(f"b{k}", (f"v{k}", f"v{k + 1}"), 1.0) for k in range(301)]
    rig = first_order(build_linkage(2, vertices, bars), sparse=True)
    assert rig.rank == 0 and rig.dof + rig.trivial_motions == 604


def test_sparse_answers_are_deterministic():
    lk = equilateral_collinear()
    first = first_order(lk, sparse=True)
    for _ in range(5):
        again = first_order(lk, sparse=True)
        np.testing.assert_array_equal(again.self_stresses, first.self_stresses)
        np.testing.assert_array_equal(again.zero_modes, first.zero_modes)
