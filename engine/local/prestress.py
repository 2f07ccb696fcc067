"""Prestress stability and second-order rigidity with certificates (Connelly-Whiteley).

Notation (README): ``Z`` (k, M) an orthonormal basis of the non-trivial flexes (zero modes
orthogonal to the rigid motions), ``W`` (s, E) an orthonormal basis of the self-stresses and
``Q_k = Z H_{w_k} Z^T`` (k, k) the stress energy of ``w_k`` on the flexes, with
``H_w = sum_a w_a Hess(l_a^2)``. ``H_w`` vanishes on the rigid motions of an unpinned framework
(``Omega p = 0`` and ``Omega 1 = 0``), so working on ``Z`` is working on the quotient by them.

- **Prestress stable**: some ``omega`` makes ``sum_k omega_k Q_k`` positive definite. This is an
  LMI, solved as the SDP ``max t`` s.t. ``sum_k omega_k Q_k - t I >= 0``, ``|omega|_2 <= 1``;
  its optimum ``t*`` is >= 0 (``omega = 0``) and by duality equals
  ``min |(<Q_k, X>)_k|_2`` over ``X >= 0, tr X = 1``. So either a combined stress certifies
  stability (its ``Q`` has a positive smallest eigenvalue) or ``t* = 0`` and the dual ``X``
  (PSD, trace 1, ``<Q_k, X> = 0`` for every ``k``) certifies that none exists.
- **Second-order rigid**: no non-trivial flex ``c`` has ``c^T Q_k c = 0`` for every ``k`` (such a
  ``c`` is exactly a flex that extends to a second-order flex ``(p', p'')``). Prestress stable
  implies second-order rigid. Decided exactly when ``k <= 2`` or ``s = 1``; otherwise a rank-one
  dual or a seeded local search may exhibit a second-order flex, and if neither does the answer
  is ``None`` (undecided: in general this is a system of ``s`` real quadratic equations).

The SDP is solved by Clarabel (an interior-point conic solver with a native PSD cone), bounded
by :data:`MAX_FLEXES`, :data:`MAX_STRESSES` and :data:`SOLVER_SECONDS`.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import clarabel
import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from scipy.optimize import least_squares

from engine.local.rigidity import RigidityResult
from engine.model.constraints import Constraints
from engine.model.errors import LimitExceeded
from engine.model.linkage import Linkage
from engine.model.tolerances import Tolerances
from engine.model.vectors import normalise_sign

#: Largest number of non-trivial flexes for which the SDP is set up (the PSD block is k x k;
#: an interior-point step costs about k^6 / 8 flops through the k(k+1)/2 svec coordinates).
MAX_FLEXES = 40
#: Largest number of self-stresses for which the ``Q_k`` are formed and the SDP is solved.
MAX_STRESSES = 400
#: Wall-clock limit handed to the conic solver.
SOLVER_SECONDS = 5.0
#: Largest linkage whose second-order acceleration is solved densely (sparse LSQR above).
DENSE_ACCELERATION_MAX_FREE = 2000
#: Wall-clock limit of that search.
SEARCH_SECONDS = 1.0
#: Random starts of the local search for a common real zero of the ``Q_k``.
SEARCH_STARTS = 8
#: Seed of that search (answers are reproducible).
SEARCH_SEED = 20261123


@dataclass(frozen=True)
class PrestressResult:
    """Outcome of :func:`prestress` / :func:`decide`.

    Attributes
    ----------
    prestress_stable : bool or None
        None when undecided (too large, solver failure, or borderline against ``q_rtol``).
    second_order_rigid : bool or None
    reason : str
        What the certificates prove, and which case is undecided.
    coefficients : (s,) float64 or None
        ``omega`` on the stress basis (unit 2-norm) when stable.
    stress : (E,) float64 or None
        The combined self-stress ``W^T omega`` over all bars when stable (0 on inert bars).
    min_eigenvalue : float or None
        Smallest eigenvalue of the combined ``Q`` (positive when stable; None without flexes).
    dual : (k, k) float64 or None
        The dual certificate ``X`` (PSD, trace 1) in the basis ``flexes`` when not stable.
    dual_residual : float or None
        ``max_k |<Q_k, X>| / scale_k`` (compare with ``q_rtol``).
    flexes : (k, M) float64
        The basis in which ``Q_k`` and ``dual`` are written.
    second_order_flex : (M,) float64 or None
        A unit non-trivial flex ``p'`` that extends to second order, when one was found.
    second_order_acceleration : (M,) float64 or None
        A ``p''`` with ``J p'' = -(p'^T Hess(l_a^2) p')_a`` (least squares, minimal norm).
    method : str
        ``"first-order"``, ``"closed-form"`` or ``"sdp"``.
    success : bool
        False when the solver did not produce a usable answer (see ``message``).
    message : str
    """

    prestress_stable: bool | None
    second_order_rigid: bool | None
    reason: str
    coefficients: np.ndarray | None
    stress: np.ndarray | None
    min_eigenvalue: float | None
    dual: np.ndarray | None
    dual_residual: float | None
    flexes: np.ndarray
    second_order_flex: np.ndarray | None
    second_order_acceleration: np.ndarray | None
    method: str
    success: bool
    message: str


@dataclass(frozen=True)
class _Decision:
    """The decision on the matrices alone (no linkage): see :func:`decide`."""

    stable: bool | None
    rigid: bool | None
    reason: str
    omega: np.ndarray | None
    min_eigenvalue: float | None
    dual: np.ndarray | None
    dual_residual: float | None
    witness: np.ndarray | None  # (k,) coefficients of a second-order flex on the basis
    method: str
    success: bool
    message: str


def flex_differences(linkage: Linkage, bars: np.ndarray, flexes: np.ndarray) -> np.ndarray:
    """``p'_i - p'_j`` of each flex on each bar, (k, E_a, d); fixed coordinates move by 0."""
    k = flexes.shape[0]
    full = np.zeros((k, linkage.fixed.size))
    full[:, ~linkage.fixed.ravel()] = flexes
    vel = full.reshape(k, linkage.n_vertices, linkage.dimension)  # (k, V, d)
    ends = linkage.ends[bars]
    return vel[:, ends[:, 0]] - vel[:, ends[:, 1]]


def stress_forms(
    linkage: Linkage, flexes: np.ndarray, stresses: np.ndarray
) -> np.ndarray:
    """``Q_k = Z H_{w_k} Z^T`` for each stress, (s, k, k), without forming ``H``.

    ``flexes`` (k, M); ``stresses`` (s, E) over all bars. Uses
    ``x^T Hess(l_a^2) y = 2 (x_i - x_j) . (y_i - y_j)``.
    """
    bars = np.flatnonzero(linkage.active)
    diff = flex_differences(linkage, bars, flexes)  # (k, Ea, d)
    gram = 2.0 * np.einsum("iad,jad->aij", diff, diff)  # (Ea, k, k)
    return np.einsum("sa,aij->sij", stresses[:, bars], gram)


def _svec(mat: np.ndarray) -> np.ndarray:
    """Clarabel's PSD-triangle vectorisation: upper triangle by columns, off-diagonals times
    sqrt(2), so that ``svec(A) . svec(B) = <A, B>``."""
    k = mat.shape[-1]
    iu, ju = np.triu_indices(k)
    order = np.lexsort((iu, ju))  # by column, then row
    iu, ju = iu[order], ju[order]
    scale = np.where(iu == ju, 1.0, np.sqrt(2.0))
    return mat[..., iu, ju] * scale


def _smat(vec: np.ndarray, k: int) -> np.ndarray:
    iu, ju = np.triu_indices(k)
    order = np.lexsort((iu, ju))
    iu, ju = iu[order], ju[order]
    scale = np.where(iu == ju, 1.0, 1.0 / np.sqrt(2.0))
    out = np.zeros((k, k))
    out[iu, ju] = vec * scale
    out[ju, iu] = vec * scale
    return out


def _solve_lmi(q: np.ndarray) -> tuple[np.ndarray, np.ndarray, str, bool]:
    """``max t`` s.t. ``sum omega_k q_k - t I >= 0``, ``|omega| <= 1``. Returns ``omega``,
    the dual ``X`` (trace 1), the solver status and whether it is usable.

    Only the span of the forms matters: with ``svec(q) = U S W^T`` (thin SVD, rank r), the
    best ``omega`` lies in the span of ``U`` and ``|omega| = |U^T omega|``, so the SDP is solved
    on the r forms ``S W^T`` (at most ``k(k+1)/2`` of them, however many stresses there are)."""
    _, k, _ = q.shape
    n_tri = k * (k + 1) // 2
    u_mat, sing, wt = np.linalg.svd(_svec(q), full_matrices=False)
    rank = max(1, int(np.sum(sing > 1e-12 * sing[0]))) if sing.size and sing[0] > 0 else 1
    svq = sing[:rank, None] * wt[:rank]  # (r, n_tri)
    s = rank
    # x = (omega, t); the slacks are (1, omega) in the SOC and svec(sum omega Q - t I) in PSD
    a_soc = sp.hstack([sp.vstack([sp.csr_matrix((1, s)), -sp.identity(s)]),
                       sp.csr_matrix((s + 1, 1))])
    a_psd = sp.csr_matrix(np.hstack([-svq.T, _svec(np.eye(k))[:, None]]))
    a_mat = sp.vstack([a_soc, a_psd]).tocsc()
    b = np.zeros(s + 1 + n_tri)
    b[0] = 1.0
    cost = np.zeros(s + 1)
    cost[-1] = -1.0
    settings = clarabel.DefaultSettings()
    settings.verbose = False
    settings.time_limit = SOLVER_SECONDS
    solver = clarabel.DefaultSolver(
        sp.csc_matrix((s + 1, s + 1)), cost, a_mat, b,
        [clarabel.SecondOrderConeT(s + 1), clarabel.PSDTriangleConeT(k)], settings,
    )
    sol = solver.solve()
    status = str(sol.status)
    usable = status.endswith("Solved") or status.endswith("AlmostSolved")
    x = np.asarray(sol.x)
    z = np.asarray(sol.z)
    return u_mat[:, :rank] @ x[:s], _smat(z[s + 1:], k), status, usable


def _binary_common_zero(q: np.ndarray, thr: np.ndarray) -> tuple[bool, np.ndarray | None]:
    """k = 2: is there a unit ``c`` with ``c^T q_k c = 0`` for all ``k``? Exact up to ``thr``:
    the candidates are the (at most two) real root lines of the largest form, or any line when
    every form vanishes."""
    size = np.array([np.linalg.norm(qk) / t for qk, t in zip(q, thr, strict=True)])
    if np.all(size <= 1.0):
        return True, np.array([1.0, 0.0])
    form = q[int(np.argmax(size))]
    a, b, c = form[0, 0], form[0, 1], form[1, 1]
    # a x^2 + 2 b x y + c y^2 on the unit circle, x = cos(phi), y = sin(phi):
    # (a + c)/2 + (a - c)/2 cos(2 phi) + b sin(2 phi) = 0
    mid, amp = 0.5 * (a + c), np.hypot(0.5 * (a - c), b)
    if amp == 0.0:
        return False, None
    cands = []
    ratio = float(np.clip(-mid / amp, -1.0, 1.0))
    base = np.arctan2(b, 0.5 * (a - c))
    for sgn in (1.0, -1.0):
        phi = 0.5 * (base + sgn * np.arccos(ratio))
        cands.append(np.array([np.cos(phi), np.sin(phi)]))
    for cand in cands:
        vals = np.einsum("i,kij,j->k", cand, q, cand)
        if np.all(np.abs(vals) <= thr):
            return True, cand
    return False, None


def _search_common_zero(
    q: np.ndarray, scales: np.ndarray, tol: Tolerances, start: np.ndarray
) -> np.ndarray | None:
    """Seeded local search (Gauss-Newton from :data:`SEARCH_STARTS` starts, at most
    :data:`SEARCH_SECONDS`) for a unit ``c`` with ``|c^T q_k c| <= q_rtol scale_k`` for all ``k``.
    Finding one proves a second-order flex; not finding one proves nothing."""
    k = q.shape[1]
    qs = q / scales[:, None, None]  # (s, k, k), |qs_k| <= 1
    rng = np.random.default_rng(SEARCH_SEED)
    starts = [start] + [rng.standard_normal(k) for _ in range(SEARCH_STARTS - 1)]
    stop = time.monotonic() + SEARCH_SECONDS

    def residual(c: np.ndarray) -> np.ndarray:  # energies, and |c|^2 - 1
        return np.append(np.einsum("i,kij,j->k", c, qs, c), c @ c - 1.0)

    def jacobian(c: np.ndarray) -> np.ndarray:  # (s + 1, k)
        return np.vstack([2.0 * qs @ c, 2.0 * c])

    for c0 in starts:
        if time.monotonic() > stop or np.linalg.norm(c0) == 0.0:
            continue
        fit = least_squares(residual, c0 / np.linalg.norm(c0), jac=jacobian, max_nfev=100)
        c = fit.x / np.linalg.norm(fit.x)
        if np.all(np.abs(np.einsum("i,kij,j->k", c, qs, c)) <= tol.q_rtol):
            return c
    return None


def decide(q: np.ndarray, scales: np.ndarray, tol: Tolerances) -> _Decision:
    """Decide prestress stability and second-order rigidity from the forms alone.

    Parameters
    ----------
    q : (s, k, k) float64
        ``Q_k`` on an orthonormal basis of the non-trivial flexes, ``k >= 1``, ``s >= 1``.
    scales : (s,) float64
        ``4 |w_k|_1``, a bound on ``|Q_k|`` free of cancellation; eigenvalues and inner products
        below ``tol.q_rtol`` times it count as zero.

    Examples
    --------
    >>> d = decide(np.array([[[1.0, 0.0], [0.0, -1.0]], [[0.0, 1.0], [1.0, 0.0]]]),
    ...            np.array([4.0, 4.0]), Tolerances())
    >>> d.stable, d.rigid
    (False, True)
    """
    s, k, _ = q.shape
    if k == 1 or s == 1:
        return _closed_form(q, scales, tol)
    if k > MAX_FLEXES or s > MAX_STRESSES:
        raise LimitExceeded(
            f"the SDP is limited to {MAX_FLEXES} flexes and {MAX_STRESSES} stresses", loc=()
        )
    norm = float(np.max(scales))
    omega, dual, status, usable = _solve_lmi(q / norm)
    if not usable:
        return _Decision(None, None, f"the conic solver stopped with status {status}: undecided",
                         None, None, None, None, None, "sdp", False, status)
    # Every claim is checked with numpy against q_rtol, whatever the solver reported.
    if np.linalg.norm(omega) > 0:
        omega = omega / np.linalg.norm(omega)
        combined = np.einsum("s,sij->ij", omega, q)
        lam_min = float(np.linalg.eigvalsh(combined)[0])
        if lam_min > tol.q_rtol * float(np.abs(omega) @ scales):
            return _Decision(
                True, True,
                f"prestress stable: the combined stress of {s} self-stresses has energy at least "
                f"{lam_min:.3g} on every unit non-trivial flex ({k} flexes); hence second-order "
                "rigid (and rigid)",
                omega, lam_min, None, None, None, "sdp", True, "",
            )
    lam, vec = np.linalg.eigh(0.5 * (dual + dual.T))
    lam = np.clip(lam, 0.0, None)
    if lam.sum() <= 0:
        return _Decision(None, None, "the conic solver returned no dual certificate: undecided",
                         None, None, None, None, None, "sdp", False, status)
    dual = (vec * lam) @ vec.T / lam.sum()
    inner = np.einsum("sij,ij->s", q, dual)
    residual = float(np.max(np.abs(inner) / scales))
    if residual > tol.q_rtol:
        return _Decision(
            None, None,
            f"borderline: no combined stress is definite beyond q_rtol and the dual residual "
            f"{residual:.3g} exceeds q_rtol = {tol.q_rtol:g}: undecided",
            None, None, dual, residual, None, "sdp", False, "borderline",
        )
    return _not_stable(q, scales, tol, dual, residual, lam, vec)


def _not_stable(
    q: np.ndarray,
    scales: np.ndarray,
    tol: Tolerances,
    dual: np.ndarray,
    residual: float,
    lam: np.ndarray,
    vec: np.ndarray,
) -> _Decision:
    """Not prestress stable (``dual`` (k, k) is a checked certificate, ``lam`` and ``vec`` the
    eigen-decomposition it was built from): is there a second-order flex?"""
    s, k, _ = q.shape
    thr = tol.q_rtol * scales  # (s,)
    if k == 2:
        found, witness = _binary_common_zero(q, thr)
        rigid_reason = (
            "not prestress stable (dual certificate); second-order rigid: no flex is a common "
            "zero of the stress energies (decided exactly on the two flexes)"
        )
    else:
        witness = _search_common_zero(q, scales, tol, vec[:, -1])
        found = witness is not None
        rigid_reason = (
            f"not prestress stable (dual certificate of rank "
            f"{int(np.sum(lam > tol.rank_rtol * lam[-1]))});"
            f" second-order rigidity undecided: no flex with zero energy under all {s} "
            f"self-stresses was found on the {k} flexes, and none is proved not to exist"
        )
    if found:
        return _Decision(
            False, False,
            "not prestress stable (dual certificate) and not second-order rigid: "
            "second_order_flex is a non-trivial flex with zero energy under every self-stress, "
            "so it extends to a second-order flex",
            None, None, dual, residual, witness, "sdp", True, "",
        )
    return _Decision(False, True if k == 2 else None, rigid_reason, None, None, dual, residual,
                     None, "sdp", True, "")


def _count(n: int, noun: str) -> str:
    return f"{n} {noun}" if n == 1 else f"{n} {noun}es"


def _closed_form(q: np.ndarray, scales: np.ndarray, tol: Tolerances) -> _Decision:
    """One flex or one stress: prestress stability and second-order rigidity coincide."""
    s, k, _ = q.shape
    thr = tol.q_rtol * scales
    if k == 1:
        vals = q[:, 0, 0]
        norm = float(np.linalg.norm(vals))
        # the best unit omega is vals / |vals|, with energy |vals| on the flex
        if norm > 0 and norm > tol.q_rtol * float(np.abs(vals / norm) @ scales):
            return _Decision(
                True, True,
                f"prestress stable: one non-trivial flex and {_count(s, 'self-stress')}; the "
                f"combined stress has energy {norm:.3g} on it, hence second-order rigid",
                vals / norm, norm, None, None, None, "closed-form", True, "",
            )
        return _Decision(
            False, False,
            f"not prestress stable and not second-order rigid: the only non-trivial flex has "
            f"zero energy under {_count(s, 'self-stress')}, so it extends to second order "
            "(higher-order analysis decides rigidity)",
            None, None, np.ones((1, 1)), float(np.max(np.abs(vals) / scales)),
            np.ones(1), "closed-form", True, "",
        )
    lam, vec = np.linalg.eigh(q[0])  # ascending
    # definite either way: omega = +1 or -1 (a stress and its negative are both stresses)
    for sign, smallest in ((1.0, float(lam[0])), (-1.0, float(-lam[-1]))):
        if smallest > thr[0]:
            return _Decision(
                True, True,
                f"prestress stable: one self-stress whose Q is definite on the {k} flexes "
                f"(smallest |eigenvalue| {smallest:.3g}), hence second-order rigid",
                np.array([sign]), smallest, None, None, None, "closed-form", True, "",
            )
    # Q is semidefinite-singular or indefinite: a real zero of c^T Q c exists
    small = np.flatnonzero(np.abs(lam) <= thr[0])
    if small.size:
        c = vec[:, small[0]]
        why = "Q is singular on the flexes"
    else:
        lp, ln = int(np.argmax(lam)), int(np.argmin(lam))
        c = vec[:, lp] / np.sqrt(lam[lp]) + vec[:, ln] / np.sqrt(-lam[ln])
        c = c / np.linalg.norm(c)
        why = "Q is indefinite on the flexes"
    dual = np.outer(c, c)
    residual = float(abs(c @ q[0] @ c) / scales[0])
    return _Decision(
        False, False,
        f"not prestress stable and not second-order rigid: one self-stress and {why}; "
        "second_order_flex has zero energy, so it extends to a second-order flex",
        None, None, dual, residual, c, "closed-form", True, "",
    )


def prestress(linkage: Linkage, rig: RigidityResult, tolerances: Tolerances | None = None
              ) -> PrestressResult:
    """Prestress stability and second-order rigidity of ``linkage`` at its configuration.

    ``rig`` is the first-order analysis of the same configuration (:func:`engine.local.rigidity.
    first_order`); its ``zero_modes`` are the flexes, orthogonal to the rigid motions.

    Examples
    --------
    >>> from engine.model.linkage import BarSpec, VertexSpec, build_linkage
    >>> from engine.local.rigidity import first_order
    >>> lk = build_linkage(2, [VertexSpec("P", [0, 0], True), VertexSpec("A", [1, 0]),
    ...                        VertexSpec("Q", [2, 0], True), VertexSpec("R", [3, 0], True)],
    ...                    [BarSpec("a", ["P", "A"]), BarSpec("b", ["A", "Q"]),
    ...                     BarSpec("c", ["A", "R"])])
    >>> res = prestress(lk, first_order(lk))
    >>> res.prestress_stable, res.second_order_rigid
    (True, True)
    """
    tol = tolerances or Tolerances()
    # the reporting sign convention is applied here, before Q_k and X are written in this basis
    flexes = normalise_sign(rig.zero_modes)  # (k, M)
    stresses = rig.self_stresses  # (s, E)
    k, s = flexes.shape[0], stresses.shape[0]
    if k == 0:
        dec = _Decision(
            True, True, "first-order rigid: no non-trivial flex, so every self-stress (even 0) "
            "certifies prestress stability", np.zeros(s), None, None, None, None, "first-order",
            True, "",
        )
        return _from_decision(linkage, stresses, flexes, dec)
    if s == 0:
        dec = _Decision(
            False, False, "no self-stress: the bars are independent and every flex "
            f"({_count(k, 'flex')}) extends to a real motion (the framework flexes here)",
            None, None, np.diag(np.eye(k)[0]), 0.0, np.eye(k)[0], "first-order", True, "",
        )
        return _from_decision(linkage, stresses, flexes, dec)
    if k > 1 and s > 1 and (k > MAX_FLEXES or s > MAX_STRESSES):
        # refuse before forming the Q_k (E k^2 s work); the closed forms stay cheap
        dec = _Decision(
            None, None,
            f"{k} flexes and {s} self-stresses exceed the SDP limits ({MAX_FLEXES} flexes, "
            f"{MAX_STRESSES} stresses): prestress stability and second-order rigidity undecided",
            None, None, None, None, None, "sdp", False, "too large",
        )
        return _from_decision(linkage, stresses, flexes, dec)
    q = stress_forms(linkage, flexes, stresses)  # (s, k, k)
    q = 0.5 * (q + np.transpose(q, (0, 2, 1)))
    scales = 4.0 * np.abs(stresses).sum(axis=1)
    return _from_decision(linkage, stresses, flexes, decide(q, scales, tol))


def _acceleration(linkage: Linkage, flex: np.ndarray) -> np.ndarray:
    """Minimal-norm ``p''`` with ``J p'' = -(p'^T Hess(l_a^2) p')_a`` (least squares)."""
    cons = Constraints(linkage)
    diff = flex_differences(linkage, cons.bars, flex[None, :])[0]  # (Ea, d)
    rhs = -2.0 * np.einsum("ad,ad->a", diff, diff)
    u = linkage.coordinates()
    if linkage.n_free <= DENSE_ACCELERATION_MAX_FREE:
        return np.linalg.lstsq(np.asarray(cons.jacobian(u, sparse=False)), rhs, rcond=None)[0]
    # p'' = J^T y with J J^T y = rhs: the minimal-norm solution, one sparse LU of the (E, E)
    # banded-like J J^T. A shift of eps-size keeps it invertible at a critical point, where
    # rhs is orthogonal to the self-stresses (the witness has zero energy) and J^T removes the
    # stress components of y.
    jac = sp.csr_matrix(cons.jacobian(u, sparse=True))
    gram = (jac @ jac.T).tocsc()
    shift = 1e-13 * float(abs(gram).max()) if gram.nnz else 1.0
    y = spla.spsolve(gram + shift * sp.identity(gram.shape[0], format="csc"), rhs)
    return np.asarray(jac.T @ y)


def _from_decision(
    linkage: Linkage, stresses: np.ndarray, flexes: np.ndarray, dec: _Decision
) -> PrestressResult:
    stress = None if dec.omega is None else dec.omega @ stresses
    flex = acc = None
    if dec.witness is not None:
        flex = dec.witness @ flexes
        flex = flex / np.linalg.norm(flex)
        acc = _acceleration(linkage, flex)
    return PrestressResult(
        prestress_stable=dec.stable,
        second_order_rigid=dec.rigid,
        reason=dec.reason,
        coefficients=dec.omega,
        stress=stress,
        min_eigenvalue=dec.min_eigenvalue,
        dual=dec.dual,
        dual_residual=dec.dual_residual,
        flexes=flexes,
        second_order_flex=flex,
        second_order_acceleration=acc,
        method=dec.method,
        success=dec.success,
        message=dec.message,
    )
