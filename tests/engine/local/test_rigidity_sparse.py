"""The sparse first-order method (default above ``FIRST_ORDER_DENSE_MAX_FREE``) against the dense
SVD on a catalogue near and above the size threshold: generic and critical Kane-Lubensky chains,
repeated null spaces, random sparse linkages; the sparse tangent form against the dense one; and
large chains, where only invariants can be checked."""

from __future__ import annotations

import numpy as np
import pytest

from engine.catalogue.presets import build_preset
from engine.local.rigidity import FIRST_ORDER_DENSE_MAX_FREE, first_order
from engine.model.budget import Deadline, OutOfTime
from engine.model.constraints import Constraints
from engine.model.linkage import BarSpec, Linkage, VertexSpec, build_linkage
from engine.model.lu import Factor, parity
from tests.engine.local.test_rigidity import check_invariants, same_subspace
from tests.load import Timer


def straight_kl_chain(n: int) -> Linkage:
    """KL chain with ``l = a`` at ``theta = 0``: pins, rotors and couplers on one line, so only
    the x coordinates are constrained: ``n - 1`` self-stresses and ``n`` zero modes."""
    return build_preset("kl-chain", {"n": n, "theta": 0.0, "l": 1.0, "a": 1.0})


def straight_chain(n: int) -> Linkage:
    """Pins P, Q and ``n`` free vertices on a line: one self-stress, ``n`` zero modes."""
    names = ["P"] + [f"v{k}" for k in range(n)] + ["Q"]
    vertices = [VertexSpec(v, [float(k), 0.0], v in ("P", "Q")) for k, v in enumerate(names)]
    bars = [BarSpec(f"b{k}", (names[k], names[k + 1])) for k in range(n + 1)]
    return build_linkage(2, vertices, bars)


def random_sparse_linkage(n_vertices: int, seed: int, dead_point: bool = False) -> Linkage:
    """Random planar linkage: vertices scattered in a square, each joined to its nearest
    neighbours, a few pins. With ``dead_point``, a pinned straight pair A-B-C is added (B free):
    exactly one extra self-stress and one extra zero mode."""
    rng = np.random.default_rng(seed)
    pos = rng.uniform(0, 10, size=(n_vertices, 2))
    pinned = set(rng.choice(n_vertices, size=max(3, n_vertices // 15), replace=False).tolist())
    vertices = [VertexSpec(f"v{k}", pos[k].tolist(), k in pinned) for k in range(n_vertices)]
    dist = np.linalg.norm(pos[:, None] - pos[None], axis=2)
    pairs = set()
    for i in range(n_vertices):
        for j in np.argsort(dist[i])[1 : 1 + int(rng.integers(1, 4))]:
            pairs.add((min(i, int(j)), max(i, int(j))))
    bars = [BarSpec(f"b{k}", (f"v{i}", f"v{j}")) for k, (i, j) in enumerate(sorted(pairs))]
    if dead_point:
        vertices += [VertexSpec("A", [20.0, 0.0], True), VertexSpec("B", [21.0, 0.5]),
                     VertexSpec("C", [23.0, 1.5], True)]
        bars += [BarSpec("AB", ("A", "B")), BarSpec("BC", ("B", "C"))]
    return build_linkage(2, vertices, bars)


def free_strip(n: int, d: int = 2) -> Linkage:
    """A free triangulated strip (nothing fixed): rigid in 2D, so only the 3 trivial motions;
    in 3D it also folds along its diagonals."""
    rng = np.random.default_rng(n)
    pos = [[k / 2, float(k % 2)] + ([float(rng.uniform(-0.1, 0.1))] if d == 3 else [])
           for k in range(n)]
    vertices = [VertexSpec(f"v{k}", p) for k, p in enumerate(pos)]
    bars = [BarSpec(f"b{k}-{k + j}", (f"v{k}", f"v{k + j}")) for j in (1, 2)
            for k in range(n - j)]
    return build_linkage(d, vertices, bars)


CATALOGUE = {
    "free strip-110 (2D, trivial motions only)": lambda: free_strip(110),
    "free strip-80 (3D, M=240)": lambda: free_strip(80, d=3),
    "kl-chain-110 (M=220, generic)": lambda: build_preset("kl-chain", {"n": 110}),
    "kl-chain-300 (M=600)": lambda: build_preset("kl-chain", {"n": 300}),
    "straight kl-chain-110 (109 stresses, 110 zero modes)": lambda: straight_kl_chain(110),
    "straight chain-120 (1 stress, 120 zero modes)": lambda: straight_chain(120),
    "gated-kl-chain-110": lambda: build_preset("gated-kl-chain", {"n": 110, "gate": 40}),
    **{f"random sparse, seed {s}": (lambda s=s: random_sparse_linkage(115, s)) for s in range(4)},
    **{f"random sparse with a dead point, seed {s}": (
        lambda s=s: random_sparse_linkage(105, s, dead_point=True)) for s in range(4, 6)},
}


@pytest.mark.parametrize("make", CATALOGUE.values(), ids=CATALOGUE.keys())
def test_sparse_agrees_with_dense_near_the_threshold(make):
    linkage = make()
    dense = first_order(linkage, sparse=False)
    sparse = first_order(linkage, sparse=True)
    assert sparse.method == "sparse-eigsh" and dense.method == "dense-svd"
    check_invariants(linkage, dense)
    check_invariants(linkage, sparse)
    assert (sparse.rank, sparse.dof, sparse.critical, sparse.trivial_motions) == (
        dense.rank, dense.dof, dense.critical, dense.trivial_motions,
    )
    assert sparse.self_stresses.shape == dense.self_stresses.shape
    assert same_subspace(sparse.zero_modes, dense.zero_modes)
    assert same_subspace(sparse.self_stresses, dense.self_stresses)
    # the smallest singular values that the sparse method reports agree with the SVD
    small = np.sort(sparse.singular_values)[:2]
    np.testing.assert_allclose(small, np.sort(dense.singular_values)[:2], atol=1e-9)
    np.testing.assert_allclose(sparse.singular_values[0], dense.singular_values[0], rtol=0.05)


def test_catalogue_covers_both_sides_of_the_default():
    sizes = [Constraints(make()).n_free for make in CATALOGUE.values()]
    # near the default threshold, on both sides of it (both methods are forced in the test)
    assert min(sizes) <= FIRST_ORDER_DENSE_MAX_FREE < max(sizes)
    assert first_order(build_preset("kl-chain", {"n": 110})).method == "sparse-eigsh"
    assert first_order(build_preset("kl-chain", {"n": 64})).method == "dense-svd"


@pytest.mark.parametrize("make", [
    lambda: build_preset("kl-chain", {"n": 150}),
    lambda: build_preset("kl-chain", {"n": 130, "theta": 0.7, "r": 1.3, "l": 1.4}),
    lambda: build_preset("gated-kl-chain", {"n": 120, "gate": 60}),
], ids=["kl-chain-150", "kl-chain-130 other lengths", "gated-120"])
def test_sparse_tangent_form_equals_dense(make):
    """The sparse path uses ``[e_k; J]`` instead of ``[w; J]``: the same ``t``."""
    linkage = make()
    dense = first_order(linkage, sparse=False).tangent_form
    sparse = first_order(linkage, sparse=True).tangent_form
    assert dense is not None and sparse is not None
    assert sparse.orientation == dense.orientation != 0
    np.testing.assert_allclose(sparse.direction, dense.direction, atol=1e-9)
    assert abs(sparse.log10_magnitude - dense.log10_magnitude) < 1e-9 * abs(
        dense.log10_magnitude
    ) + 1e-9


def test_sparse_tangent_form_vanishes_at_a_critical_chain():
    """The straight KL chain has M - E_a = 1 and is critical (rank < E_a): t = 0."""
    rig = first_order(straight_kl_chain(110), sparse=True)
    assert rig.critical and rig.n_free - rig.n_constraints == 1
    assert rig.tangent_form is not None and rig.tangent_form.orientation == 0
    assert rig.tangent_form.log10_magnitude == -np.inf


@pytest.mark.parametrize("n", [2000, 5000])
def test_large_chains_by_invariants(n):
    """Too large for the dense SVD: zero mode, self-stresses and tangent form by their
    defining properties, with the sparse Jacobian."""
    linkage = build_preset("kl-chain", {"n": n})
    rig = first_order(linkage)
    cons = Constraints(linkage)
    jac = cons.jacobian(linkage.coordinates(), sparse=True)
    assert rig.method == "sparse-eigsh"
    assert (rig.rank, rig.dof, rig.self_stresses.shape[0]) == (2 * n - 1, 1, 0)
    assert not rig.critical
    z = rig.zero_modes[0]
    assert abs(np.linalg.norm(z) - 1) < 1e-12
    s_max = rig.singular_values[0]
    assert np.linalg.norm(jac @ z) <= 1e-12 * s_max
    tf = rig.tangent_form
    assert tf is not None and tf.orientation != 0 and np.isfinite(tf.log10_magnitude)
    assert np.linalg.norm(jac @ tf.direction) <= 1e-10 * s_max
    assert abs(abs(tf.direction @ z) - 1) < 1e-10  # t is along the zero mode
    assert tf.orientation == int(np.sign(tf.direction @ z))
    # the smallest nonzero singular value really is one: ||J^T s|| for its left vector ~ s
    assert rig.singular_values[-1] > 1e3 * 1e-8 * s_max


def test_sparse_tangent_form_sign_is_det_of_w_and_j():
    """orientation = sign det([w; J]) for the reported zero mode w, checked with a dense LU at a
    size where the sparse path is the default."""
    linkage = build_preset("kl-chain", {"n": 120, "theta": 0.4})
    rig = first_order(linkage)
    jac = Constraints(linkage).jacobian(linkage.coordinates(), sparse=False)
    fac = Factor(np.vstack([rig.zero_modes[0], jac]))
    assert rig.tangent_form is not None and rig.method == "sparse-eigsh"
    assert fac.sign == rig.tangent_form.orientation
    np.testing.assert_allclose(
        rig.tangent_form.log10_magnitude, fac.logdet / np.log(10), rtol=1e-10
    )


def _parity_by_cycles(perm: np.ndarray) -> int:
    seen = np.zeros(len(perm), dtype=bool)
    cycles = 0
    for start in range(len(perm)):
        if not seen[start]:
            cycles += 1
            j = start
            while not seen[j]:
                seen[j] = True
                j = perm[j]
    return -1 if (len(perm) - cycles) % 2 else 1


@pytest.mark.parametrize("n", [0, 1, 2, 3, 7, 64, 1000])
def test_parity_matches_cycle_count(n):
    rng = np.random.default_rng(n)
    for _ in range(30):
        perm = rng.permutation(n)
        assert parity(perm) == _parity_by_cycles(perm)
    if n >= 2:  # one transposition flips the sign
        perm = np.arange(n)
        perm[[0, n - 1]] = perm[[n - 1, 0]]
        assert parity(perm) == -1


def test_the_sparse_method_stops_at_its_deadline():
    # the Lanczos rounds check the deadline at every operator application: a search's zero
    # mode at a seed (a 100-rotor chain of parallelograms: one eigsh took 1.5 s) stops with
    # OutOfTime instead of running past the search's deadline; without one it answers
    chain = build_preset("kl-chain", {"n": 100, "a": 1.0, "l": 1.0, "r": 1.5})
    with pytest.raises(OutOfTime):
        first_order(chain, sparse=True, deadline=Deadline.after(0.0))
    res = first_order(chain, sparse=True, deadline=Deadline.after(60.0))
    assert res.dof == 1 and not res.critical
    check_invariants(chain, res)


@pytest.mark.parametrize("n", [150])
def test_a_large_null_space_goes_to_the_dense_svd(n):
    # a straight chain (pins, rotors and couplers on one line): n zero modes and n - 1
    # self-stresses, far more than 5 % of M: the sparse method (chosen by default above
    # 200 free coordinates) hands over to the dense SVD (a straight 150-rotor chain took 22 s
    # of Lanczos rounds; now about 0.1 s), whose answer is checked by its invariants and
    # against the counts of the straight chain
    chain = straight_kl_chain(n)
    res = first_order(chain)
    assert res.method.startswith("dense-svd")
    assert (res.dof, res.self_stresses.shape[0]) == (n, n - 1)
    check_invariants(chain, res)


def test_a_dense_svd_that_would_not_end_in_time_is_not_started():
    chain = straight_kl_chain(1000)  # M = 2000: a dense SVD of about 10 s or more
    with Timer() as t, pytest.raises(OutOfTime):
        first_order(chain, deadline=Deadline.after(1.0))
    # the sparse rounds before it stop at the deadline; 4 s of an idle machine's work after it
    # (scaled by the load: tests/load.py), far below the SVD's 10 s
    assert t.within(1.0, 4.0), t


def test_a_round_of_the_completion_that_would_not_end_in_time_is_not_started():
    # 20,000 straight rotors: too large for the dense fallback; the block inverse iteration's
    # next round is estimated before it starts
    chain = straight_kl_chain(20000)
    with pytest.raises(OutOfTime):
        first_order(chain, sparse=True, deadline=Deadline.after(2.0))
