"""Prestress stability and second-order rigidity: every certificate checked independently.

The checks below never use the engine's Jacobian, Hessian, stresses or flexes: squared lengths
are evaluated from positions here, their Jacobian and Hessians by central differences (exact up
to rounding for quadratics), the stress and flex spaces by ``scipy.linalg.null_space``, the rigid
motions from their definition. A stress certificate must be a self-stress whose energy is
positive definite on *our* basis of the non-trivial flexes; a dual certificate must be PSD,
non-zero, written on genuine non-trivial flexes and orthogonal to the energy of *our* basis of
self-stresses; a second-order flex must solve ``J p'' = -(p'^T H_a p')_a``.
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg as sla
from hypothesis import given, settings
from hypothesis import strategies as st

from engine.catalogue.presets import build_preset
from engine.local.prestress import decide, prestress
from engine.local.rigidity import first_order
from engine.local.second_order import second_order
from engine.model.linkage import BarSpec, VertexSpec, build_linkage
from engine.model.tolerances import Tolerances

TOL = 1e-7


# -- independent references ------------------------------------------------------------------

def squared_lengths(lk, u):
    pos = np.array(lk.positions, dtype=float)
    pos[~lk.fixed] = u
    active = np.flatnonzero(lk.active)
    d = pos[lk.ends[active, 0]] - pos[lk.ends[active, 1]]
    return (d * d).sum(axis=1)


def jacobian_fd(lk, h=1e-6):
    u = lk.coordinates()
    cols = []
    for i in range(u.size):
        e = np.zeros(u.size)
        e[i] = h
        cols.append((squared_lengths(lk, u + e) - squared_lengths(lk, u - e)) / (2 * h))
    return np.array(cols).T  # (Ea, M)


def hessians_fd(lk, h=1e-3):
    """Hess(l_a^2) for every active bar, (Ea, M, M), by central differences."""
    u = lk.coordinates()
    m = u.size
    out = np.zeros((int(lk.active.sum()), m, m))
    eye = np.eye(m) * h
    for i in range(m):
        for j in range(m):
            f = (squared_lengths(lk, u + eye[i] + eye[j]) - squared_lengths(lk, u + eye[i] - eye[j])
                 - squared_lengths(lk, u - eye[i] + eye[j])
                 + squared_lengths(lk, u - eye[i] - eye[j]))
            out[:, i, j] = f / (4 * h * h)
    return out


def rigid_motions(lk):
    if lk.fixed.any():
        return np.zeros((0, lk.n_free))
    pos = np.array(lk.positions, dtype=float)
    v, d = pos.shape
    gens = [np.tile(np.eye(d)[k], (v, 1)) for k in range(d)]
    pairs = [(0, 1)] if d == 2 else [(0, 1), (1, 2), (0, 2)]
    for a, b in pairs:
        w = np.zeros((v, d))
        w[:, a], w[:, b] = -pos[:, b], pos[:, a]
        gens.append(w)
    return sla.orth(np.array([g.ravel() for g in gens]).T).T


def reference(lk):
    """(J, H (Ea, M, M), our non-trivial flex basis F (k, M), our stress basis W (s, Ea), T)."""
    jac = jacobian_fd(lk)
    scale = np.abs(jac).max()
    flex_all = sla.null_space(jac, rcond=1e-9 * scale / np.linalg.norm(jac, 2)).T
    triv = rigid_motions(lk)
    if triv.shape[0]:
        proj = flex_all - (flex_all @ triv.T) @ triv
        u, s, vt = np.linalg.svd(proj, full_matrices=False)
        flex = vt[s > 0.5]
    else:
        flex = flex_all
    stresses = sla.null_space(jac.T, rcond=1e-9).T
    return jac, hessians_fd(lk), flex, stresses, triv


def energy(hess, stress_active):
    return np.einsum("a,aij->ij", stress_active, hess)


def check_certificate(lk, pre):
    """Check whichever certificate ``pre`` carries, against the references only."""
    jac, hess, flex, stresses, triv = reference(lk)
    active = np.flatnonzero(lk.active)
    k = flex.shape[0]
    assert pre.flexes.shape[0] == k, "the engine and the reference disagree on the flex count"
    if pre.prestress_stable:
        sigma = pre.stress[active]
        assert np.all(pre.stress[~lk.active] == 0)
        assert np.linalg.norm(sigma @ jac) <= TOL * np.abs(jac).max() * max(1, len(sigma))
        if k:
            assert abs(np.linalg.norm(pre.stress) - 1) <= 1e-9
            q = flex @ energy(hess, sigma) @ flex.T
            lam = np.linalg.eigvalsh(0.5 * (q + q.T))
            assert lam[0] > 1e-6 * 4 * np.abs(sigma).sum(), lam
            np.testing.assert_allclose(lam[0], pre.min_eigenvalue, rtol=1e-5)
        assert pre.second_order_rigid is True
        return
    if pre.prestress_stable is False:
        f = pre.flexes
        # genuine, orthonormal, non-trivial flexes
        assert np.linalg.norm(jac @ f.T) <= TOL * np.abs(jac).max()
        np.testing.assert_allclose(f @ f.T, np.eye(k), atol=1e-9)
        if triv.shape[0]:
            assert np.abs(f @ triv.T).max() <= 1e-8
        x = pre.dual
        lam = np.linalg.eigvalsh(x)
        assert lam[0] >= -1e-9 and abs(np.trace(x) - 1) <= 1e-9
        for w in stresses:
            qk = f @ energy(hess, w) @ f.T
            assert abs(np.sum(qk * x)) <= 1e-6 * 4 * np.abs(w).sum(), np.sum(qk * x)
    if pre.second_order_rigid is False:
        p1, p2 = pre.second_order_flex, pre.second_order_acceleration
        assert abs(np.linalg.norm(p1) - 1) <= 1e-9
        assert np.linalg.norm(jac @ p1) <= TOL * np.abs(jac).max()
        if triv.shape[0]:
            assert np.linalg.norm(p1 - (p1 @ triv.T) @ triv) >= 0.5  # not a rigid motion
        rhs = -np.einsum("i,aij,j->a", p1, hess, p1)
        assert np.linalg.norm(jac @ p2 - rhs) <= 1e-6 * (1 + np.linalg.norm(rhs))


# -- frameworks ------------------------------------------------------------------------------

def braced_line(dim):
    """P-A-B-Q on the x-axis with extra bars P-B and A-Q: 3 stresses, dim - 1 flexes per free
    vertex."""
    z = [0.0] * (dim - 1)
    vertices = [VertexSpec("P", [0.0] + z, True), VertexSpec("A", [1.0] + z),
                VertexSpec("B", [2.0] + z), VertexSpec("Q", [3.0] + z, True)]
    ends = [("P", "A"), ("A", "B"), ("B", "Q"), ("P", "B"), ("A", "Q")]
    return build_linkage(dim, vertices, [BarSpec(f"b{i}", e) for i, e in enumerate(ends)])


def star_with_dangling_rotor(dim):
    """A collinear star (stable part) beside a free rotor C (flexes with no stress)."""
    z = [0.0] * (dim - 1)
    vertices = [VertexSpec("A", [1.0] + z)]
    vertices += [VertexSpec(f"P{i}", [x] + z, True) for i, x in enumerate((0.0, 2.0, 3.0))]
    vertices += [VertexSpec("O", [5.0] + z, True), VertexSpec("C", [5.6, 0.8] + z[1:])]
    bars = [BarSpec(f"a{i}", ("A", f"P{i}")) for i in range(3)]
    bars.append(BarSpec("c", ("O", "C")))
    if dim == 3:  # a second pin makes C a hinge in 3D: one flex
        vertices.append(VertexSpec("O2", [5.0, 0.0, 1.0], True))
        bars.append(BarSpec("c2", ("O2", "C")))
    return build_linkage(dim, vertices, bars)


def star(dim, pins=(0.0, 2.0, 3.0)):
    """Free vertex A joined to pins on the x-axis (collinear: several stresses)."""
    z = [0.0] * (dim - 1)
    vertices = [VertexSpec("A", [1.0] + z)]
    vertices += [VertexSpec(f"P{i}", [x] + z, True) for i, x in enumerate(pins)]
    bars = [BarSpec(f"a{i}", ("A", f"P{i}")) for i in range(len(pins))]
    return build_linkage(dim, vertices, bars)


def folded_four_bar():
    lk = build_preset("four-bar")
    pos = np.array(lk.positions)
    pos[lk.vertex_ids.index("A")] = (1.0, 0.0)
    pos[lk.vertex_ids.index("B")] = (2.0, 0.0)
    return lk.with_positions(pos)


CASES = {
    # one stress
    "three-prism (2D, s=1, k=1, stable)": (lambda: build_preset("three-prism"), True, True),
    "k33-conic (2D, s=1, k=1, stable)": (lambda: build_preset("k33-conic"), True, True),
    "braced-free-chain 3D (s=1, k=4, stable)": (
        lambda: build_linkage(3, [VertexSpec("P", [0, 0, 0], True), VertexSpec("A", [1, 0, 0]),
                                  VertexSpec("B", [2, 0, 0]), VertexSpec("Q", [3, 0, 0], True)],
                              [BarSpec("a", ("P", "A")), BarSpec("b", ("A", "B")),
                               BarSpec("c", ("B", "Q"))]),
        True, True),
    "folded four-bar (2D, s=1, k=2, branch)": (folded_four_bar, False, False),
    "bricard-line (3D, s=1, k=1, flexible)": (lambda: build_preset("bricard-line"), False, False),
    "bricard-plane (3D, s=1, k=1, flexible)": (lambda: build_preset("bricard-plane"), False,
                                               False),
    "three-prism-flexible (2D, flexible)": (lambda: build_preset("three-prism-flexible"), False,
                                            False),
    # several stresses, one flex
    "star (2D, s=2, k=1)": (lambda: star(2), True, True),
    "cn-symmetric-four-regular 8 (2D, s=4, k=1)": (
        lambda: build_preset("cn-symmetric-four-regular"), True, True),
    # several of both
    "braced line (2D, s=3, k=2)": (lambda: braced_line(2), True, True),
    "braced line (3D, s=3, k=4)": (lambda: braced_line(3), True, True),
    "star (3D, s=2, k=2)": (lambda: star(3), True, True),
    "star beside a rotor (2D, s=2, k=2)": (lambda: star_with_dangling_rotor(2), False, False),
    "star beside a hinge (3D, s=2, k=3)": (lambda: star_with_dangling_rotor(3), False, False),
    "cn-symmetric-four-regular 10 (2D)": (
        lambda: build_preset("cn-symmetric-four-regular", {"n": 10}), True, True),
}


@pytest.mark.parametrize("name", list(CASES))
def test_certificates_check_independently(name):
    make, stable, rigid = CASES[name]
    lk = make()
    pre = second_order(lk).prestress
    assert pre.success, pre.message
    assert (pre.prestress_stable, pre.second_order_rigid) == (stable, rigid), pre.reason
    check_certificate(lk, pre)


def test_cases_cover_the_issue_matrix():
    """One stress, several stresses with one flex, several of both; 2D and 3D (counted here)."""
    seen = set()
    for make, _, _ in CASES.values():
        lk = make()
        rig = first_order(lk)
        s, k = rig.self_stresses.shape[0], rig.dof
        kind = "one-stress" if s == 1 else ("one-flex" if k == 1 else "both")
        seen.add((kind, lk.dimension))
    assert {(k, d) for k in ("one-stress", "one-flex", "both") for d in (2, 3)} - {
        ("one-flex", 3)} <= seen
    # 3D with several stresses and one flex: the star with pins on a line and one free axis
    lk = build_linkage(3, [VertexSpec("A", [1, 0, 0], [False, False, True])]
                       + [VertexSpec(f"P{i}", [x, 0, 0], True) for i, x in enumerate((0, 2, 3))],
                       [BarSpec(f"a{i}", ("A", f"P{i}")) for i in range(3)])
    rig = first_order(lk)
    assert (rig.self_stresses.shape[0], rig.dof) == (2, 1)
    pre = prestress(lk, rig)
    assert pre.prestress_stable is True
    check_certificate(lk, pre)


FLEXIBLE = [
    ("bricard-line", {}), ("bricard-line", {"x2": 0.7, "y2": 1.6, "z2": 0.4}),
    ("bricard-plane", {}), ("bricard-plane", {"y0": 1.3, "z1": -1.5, "x4": 0.8}),
    ("three-prism-flexible", {}), ("three-prism-flexible", {"dx": -1.0, "dy": 2.0}),
    ("k33-dixon", {}), ("four-bar", {}), ("kl-chain", {"n": 6}), ("rotor-chain-3d", {}),
]


@pytest.mark.parametrize(("name", "params"), FLEXIBLE)
def test_flexible_frameworks_are_never_prestress_stable(name, params):
    lk = build_preset(name, params)
    pre = second_order(lk).prestress
    assert pre.prestress_stable is False and pre.second_order_rigid is False
    check_certificate(lk, pre)


@pytest.mark.parametrize(("name", "params"), [
    ("tetrahedron", {}), ("octahedron", {}), ("three-prism", {"twist": 0.4}),
    ("k33-conic", {"rx": 2.0, "ry": 2.0}),  # a circle is a conic too: still one stress
])
def test_first_order_rigid_frameworks_are_prestress_stable(name, params):
    lk = build_preset(name, params)
    rig = first_order(lk)
    pre = second_order(lk).prestress
    assert pre.prestress_stable is True and pre.second_order_rigid is True
    if rig.dof == 0:
        assert pre.method == "first-order"
    check_certificate(lk, pre)


def test_rigid_motions_are_quotiented_out():
    """The free tetrahedron has 6 rigid motions and no other flex: stable, not 'flexible'."""
    lk = build_preset("tetrahedron")
    rig = first_order(lk)
    assert rig.trivial_motions == 6 and rig.dof == 0
    assert prestress(lk, rig).prestress_stable is True


# -- the decision on forms alone: cases no small framework above reaches ---------------------

def forms(*mats):
    q = np.array(mats, dtype=float)
    return q, 4.0 * np.ones(len(mats))


def test_not_stable_but_second_order_rigid_on_two_flexes():
    """x^2 - y^2 and 2xy: no definite combination (trace 0), no common real zero."""
    q, scales = forms([[1, 0], [0, -1]], [[0, 1], [1, 0]])
    d = decide(q, scales, Tolerances())
    assert (d.stable, d.rigid) == (False, True)
    x = d.dual
    assert np.linalg.eigvalsh(x)[0] >= -1e-9 and abs(np.trace(x) - 1) <= 1e-9
    assert np.abs(np.einsum("sij,ij->s", q, x)).max() <= 1e-8


def test_undecided_is_said_not_guessed():
    """x^2 - y^2, 2xy, x^2 + y^2 - z^2: not stable, no common real zero, but k = 3 and s = 3 is
    beyond the exact cases: second-order rigidity must be None with the reason saying so."""
    q, scales = forms(np.diag([1, -1, 0]), [[0, 1, 0], [1, 0, 0], [0, 0, 0]], np.diag([1, 1, -1]))
    d = decide(q, scales, Tolerances())
    assert d.stable is False and d.rigid is None and "undecided" in d.reason
    assert np.abs(np.einsum("sij,ij->s", q, d.dual)).max() <= 1e-8


def test_common_zero_found_on_three_flexes():
    """x^2 - y^2 and 2 x z vanish together on (0, 0, 1): not second-order rigid."""
    q, scales = forms(np.diag([1, -1, 0]), [[0, 0, 1], [0, 0, 0], [1, 0, 0]])
    d = decide(q, scales, Tolerances())
    assert (d.stable, d.rigid) == (False, False)
    c = d.witness
    assert np.abs(np.einsum("i,sij,j->s", c, q, c)).max() <= 1e-6 * 4


def test_stable_combination_on_random_forms():
    """Forms built around a known definite combination: the SDP must find one."""
    rng = np.random.default_rng(7)
    k, s = 5, 4
    mats = rng.standard_normal((s, k, k))
    mats = mats + mats.transpose(0, 2, 1)
    target = np.eye(k) * 3.0
    mats[0] = target - mats[1:].sum(axis=0) * 0.1
    q = mats
    scales = 4.0 * np.abs(q).sum(axis=(1, 2))
    d = decide(q, scales, Tolerances())
    assert d.stable is True
    combined = np.einsum("s,sij->ij", d.omega, q)
    assert np.linalg.eigvalsh(combined)[0] > 0
    np.testing.assert_allclose(np.linalg.norm(d.omega), 1.0)


def test_connelly_whiteley_second_order_rigid_but_not_prestress_stable():
    """Connelly and Whiteley (1996), the example PyRigi lists as ``SecondOrderRigid``: a 3D
    framework (vertices 1 and 5, 3 and 6 coincide) with two stresses and two flexes, proved
    second-order rigid but not prestress stable. Decided exactly here (two flexes)."""
    pts = [(0, 0, 0), (0, 1, 0), (0, 0, 1), (1, 0, 0), (1, 1, 0), (0, 1, 0), (1, 0, 0)]
    edges = [(0, 1), (0, 2), (0, 3), (0, 5), (0, 6), (1, 2), (1, 4), (1, 6), (2, 3), (2, 4),
             (3, 4), (3, 5), (4, 5), (4, 6), (5, 6)]
    lk = build_linkage(3, [VertexSpec(f"v{i}", list(p)) for i, p in enumerate(pts)],
                       [BarSpec(f"e{i}", (f"v{a}", f"v{b}")) for i, (a, b) in enumerate(edges)])
    rig = first_order(lk)
    assert (rig.self_stresses.shape[0], rig.dof) == (2, 2)
    pre = prestress(lk, rig)
    assert (pre.prestress_stable, pre.second_order_rigid) == (False, True), pre.reason
    check_certificate(lk, pre)


# -- properties ------------------------------------------------------------------------------


@settings(max_examples=25, deadline=None)
@given(st.integers(2, 6), st.integers(2, 5), st.integers(0, 2**31 - 1), st.booleans())
def test_decide_returns_a_certificate_that_checks(k, s, seed, feasible):
    """Random forms: planted definite combination (must be found) or trace-zero forms (no
    definite combination can exist: <Q_k, I/k> = 0). Either way the certificate checks."""
    rng = np.random.default_rng(seed)
    q = rng.standard_normal((s, k, k))
    q = q + q.transpose(0, 2, 1)
    if feasible:
        q[0] = 3.0 * k * np.eye(k) - 0.1 * q[1:].sum(axis=0)
    else:
        q -= np.einsum("sii->s", q)[:, None, None] * np.eye(k) / k
    scales = 4.0 * np.abs(q).sum(axis=(1, 2))
    d = decide(q, scales, Tolerances())
    assert d.success
    assert d.stable is feasible
    if feasible:
        combined = np.einsum("s,sij->ij", d.omega, q)
        assert np.linalg.eigvalsh(combined)[0] > 1e-6 * np.abs(d.omega) @ scales
        assert d.rigid is True
    else:
        assert np.linalg.eigvalsh(d.dual)[0] >= -1e-12 and abs(np.trace(d.dual) - 1) < 1e-9
        assert np.all(np.abs(np.einsum("sij,ij->s", q, d.dual)) <= 1e-6 * scales)
        if d.rigid is False:
            c = d.witness
            assert np.all(np.abs(np.einsum("i,sij,j->s", c, q, c)) <= 1e-6 * scales)
