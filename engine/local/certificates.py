"""Prestress stability and second-order rigidity decided on the stress forms alone, with the
certificates that back each answer (Connelly-Whiteley; used by :mod:`engine.local.prestress`).

The value that decides is ``t* = max lambda_min(sum_k omega_k Q_k)`` over unit ``omega``
(``t* >= 0``; stable iff ``t* > 0``). A stress certificate proves ``t* >= lambda_min`` of its
combination; a dual certificate ``X`` (PSD, trace 1) proves ``t* <= |(<Q_k, X>)_k|``, and so does
a common near-zero ``c`` of the forms (``X = c c^T``). Relative to ``scales`` (bounds on
``|Q_k|``), with ``err`` the rounding scale of the forms (:func:`rounding_error`, plus the error
the caller knows the forms carry):

- ``t*`` proved above ``q_rtol``: prestress stable (True);
- ``t*`` proved at most ``err`` (the forms are not definite to rounding): not stable (False);
- otherwise the answer is within ``q_rtol`` of the boundary: ``None`` with the reason and the
  bracket of ``t*`` (a smaller ``q_rtol`` may decide it).

Second-order rigidity likewise: a common zero within ``err`` is a second-order flex (False), no
common zero within ``q_rtol`` on two flexes is rigid (True), a common zero between the two is
``None``.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import clarabel
import numpy as np
import scipy.sparse as sp
from scipy.optimize import least_squares

from engine.model.errors import LimitExceeded
from engine.model.tolerances import DUAL_RANGE_RTOL, Tolerances

#: Largest number of non-trivial flexes for which the SDP is set up (the PSD block is k x k;
#: an interior-point step costs about k^6 / 8 flops through the k(k+1)/2 svec coordinates).
MAX_FLEXES = 40
#: Largest number of self-stresses for which the ``Q_k`` are formed and the SDP is solved.
MAX_STRESSES = 400
#: Wall-clock limit handed to the conic solver.
SOLVER_SECONDS = 5.0
#: Wall-clock limit of the search for a common zero of the forms.
SEARCH_SECONDS = 1.0
#: Random starts of the local search for a common real zero of the ``Q_k``.
SEARCH_STARTS = 8
#: Seed of that search (answers are reproducible).
SEARCH_SEED = 20261123


@dataclass(frozen=True)
class Decision:
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


def rounding_error(k: int, s: int) -> float:
    """Rounding scale, relative to ``scales``, of the quantities :func:`decide` compares: an
    eigenvalue of a ``k x k`` combination of ``s`` forms (``eigh`` is backward stable to about
    ``k eps |A|``, the combination adds ``s eps``) and ``<Q_k, X>`` (``k^2`` products,
    ``gamma_{k^2} = k^2 eps``, with ``|X|_F <= tr X = 1``)."""
    eps = float(np.finfo(float).eps)
    return (k * k + k + s) * eps


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


def _energies(c: np.ndarray, q: np.ndarray, scales: np.ndarray) -> np.ndarray:
    """``|c^T Q_k c| / scale_k`` (s,) for a unit ``c``."""
    return np.abs(np.einsum("i,kij,j->k", c, q, c)) / scales


def _binary_common_zero(q: np.ndarray, scales: np.ndarray) -> tuple[float, np.ndarray]:
    """k = 2: the unit ``c`` that comes nearest to a common zero of the forms, and its largest
    relative energy. The candidates are the (at most two) real root lines of the largest form
    (any line when it vanishes): a common zero lies on them, so this is exact up to rounding."""
    size = np.array([np.linalg.norm(qk) for qk in q]) / scales
    form = q[int(np.argmax(size))]
    if float(size.max()) == 0.0:
        return 0.0, np.array([1.0, 0.0])
    a, b, c = form[0, 0], form[0, 1], form[1, 1]
    # a x^2 + 2 b x y + c y^2 on the unit circle, x = cos(phi), y = sin(phi):
    # (a + c)/2 + (a - c)/2 cos(2 phi) + b sin(2 phi) = 0
    mid, amp = 0.5 * (a + c), np.hypot(0.5 * (a - c), b)
    if amp == 0.0:  # a multiple of the identity: definite, no root line
        return float("inf"), np.array([1.0, 0.0])
    ratio = float(np.clip(-mid / amp, -1.0, 1.0))
    base = np.arctan2(b, 0.5 * (a - c))
    best, best_c = float("inf"), np.array([1.0, 0.0])
    for sgn in (1.0, -1.0):
        phi = 0.5 * (base + sgn * np.arccos(ratio))
        cand = np.array([np.cos(phi), np.sin(phi)])
        value = float(_energies(cand, q, scales).max())
        if value < best:
            best, best_c = value, cand
    return best, best_c


def _search_common_zero(
    q: np.ndarray, scales: np.ndarray, err: float, start: np.ndarray
) -> tuple[float, np.ndarray | None]:
    """Seeded local search (Gauss-Newton from :data:`SEARCH_STARTS` starts, at most
    :data:`SEARCH_SECONDS`) for a unit ``c`` with small ``|c^T q_k c| / scale_k``; returns the
    smallest largest relative energy found and its ``c`` (stops early once it is within
    ``err``). Finding a small one proves a near common zero; not finding one proves nothing."""
    k = q.shape[1]
    qs = q / scales[:, None, None]  # (s, k, k), |qs_k| <= 1
    rng = np.random.default_rng(SEARCH_SEED)
    starts = [start] + [rng.standard_normal(k) for _ in range(SEARCH_STARTS - 1)]
    stop = time.monotonic() + SEARCH_SECONDS

    def residual(c: np.ndarray) -> np.ndarray:  # energies, and |c|^2 - 1
        return np.append(np.einsum("i,kij,j->k", c, qs, c), c @ c - 1.0)

    def jacobian(c: np.ndarray) -> np.ndarray:  # (s + 1, k)
        return np.vstack([2.0 * qs @ c, 2.0 * c])

    best, best_c = float("inf"), None
    for c0 in starts:
        if time.monotonic() > stop or np.linalg.norm(c0) == 0.0:
            continue
        fit = least_squares(residual, c0 / np.linalg.norm(c0), jac=jacobian, max_nfev=100,
                            xtol=1e-15, ftol=1e-15, gtol=1e-15)
        c = fit.x / np.linalg.norm(fit.x)
        value = float(np.abs(np.einsum("i,kij,j->k", c, qs, c)).max())
        if value < best:
            best, best_c = value, c
        if best <= err:
            break
    return best, best_c


def _polish_dual(q: np.ndarray, scales: np.ndarray, dual: np.ndarray) -> np.ndarray:
    """The nearest ``Y`` (Frobenius) to ``dual`` on its range with ``<Q_k, Y> = 0`` and
    ``tr Y = 1``, when it is still PSD (else ``dual``): the conic solver stops at its own
    tolerance (about 1e-8), this linear correction brings a certificate that exists on that
    range down to rounding."""
    mu, vec = np.linalg.eigh(dual)
    keep = mu > DUAL_RANGE_RTOL * max(float(mu[-1]), 0.0)
    r = int(keep.sum())
    if r == 0:
        return dual
    basis = vec[:, keep]  # (k, r)
    reduced = np.einsum("ia,sij,jb->sab", basis, q / scales[:, None, None], basis)
    rows = np.vstack([_svec(reduced), _svec(np.eye(r))[None, :]])  # (s + 1, r(r+1)/2)
    target = np.zeros(rows.shape[0])
    target[-1] = 1.0
    y0 = _svec(basis.T @ dual @ basis)
    y = y0 - np.linalg.lstsq(rows, rows @ y0 - target, rcond=None)[0]
    polished = basis @ _smat(y, r) @ basis.T
    polished = 0.5 * (polished + polished.T)
    if np.linalg.eigvalsh(polished)[0] < -np.finfo(float).eps * r:
        return dual
    return polished


def decide(
    q: np.ndarray, scales: np.ndarray, tol: Tolerances, form_error: float = 0.0
) -> Decision:
    """Decide prestress stability and second-order rigidity from the forms alone.

    Parameters
    ----------
    q : (s, k, k) float64
        ``Q_k`` on an orthonormal basis of the non-trivial flexes, ``k >= 1``, ``s >= 1``.
    scales : (s,) float64
        ``4 |w_k|_1``, a bound on ``|Q_k|`` free of cancellation; eigenvalues and inner products
        below ``tol.q_rtol`` times it count as zero.
    form_error : float
        The error the forms carry, relative to ``scales`` (0 for forms known exactly); with
        :func:`rounding_error` it is the scale below which a value is zero.

    Examples
    --------
    >>> d = decide(np.array([[[1.0, 0.0], [0.0, -1.0]], [[0.0, 1.0], [1.0, 0.0]]]),
    ...            np.array([4.0, 4.0]), Tolerances())
    >>> d.stable, d.rigid
    (False, True)
    """
    s, k, _ = q.shape
    err = rounding_error(k, s) + form_error
    if k == 1 or s == 1:
        return _closed_form(q, scales, tol, err)
    if k > MAX_FLEXES or s > MAX_STRESSES:
        raise LimitExceeded(
            f"the SDP is limited to {MAX_FLEXES} flexes and {MAX_STRESSES} stresses", loc=()
        )
    norm = float(np.max(scales))
    omega, dual, status, usable = _solve_lmi(q / norm)
    if not usable:
        return Decision(None, None, f"the conic solver stopped with status {status}: undecided",
                        None, None, None, None, None, "sdp", False, status)
    # Every claim is checked with numpy against q_rtol, whatever the solver reported.
    lower = 0.0  # t* >= lower (relative): omega = 0 gives 0
    if np.linalg.norm(omega) > 0:
        omega = omega / np.linalg.norm(omega)
        combined = np.einsum("s,sij->ij", omega, q)
        lam_min = float(np.linalg.eigvalsh(combined)[0])
        weight = float(np.abs(omega) @ scales)
        if lam_min > tol.q_rtol * weight:
            return Decision(
                True, True,
                f"prestress stable: the combined stress of {s} self-stresses has energy at least "
                f"{lam_min:.3g} on every unit non-trivial flex ({k} flexes); hence second-order "
                "rigid (and rigid)",
                omega, lam_min, None, None, None, "sdp", True, "",
            )
        lower = max(lam_min / weight, 0.0)
    lam, vec = np.linalg.eigh(0.5 * (dual + dual.T))
    lam = np.clip(lam, 0.0, None)
    if lam.sum() <= 0:
        return Decision(None, None, "the conic solver returned no dual certificate: undecided",
                        None, None, None, None, None, "sdp", False, status)
    dual = _polish_dual(q, scales, (vec * lam) @ vec.T / lam.sum())
    lam, vec = np.linalg.eigh(dual)
    residual = float(np.max(np.abs(np.einsum("sij,ij->s", q, dual)) / scales))
    if lower > err:
        return Decision(
            None, None,
            f"borderline: a combined stress has energy {lower:.3g} (relative) on every unit "
            f"flex, above the rounding scale {err:.2g} but not above q_rtol = {tol.q_rtol:g}: "
            "the answer is within q_rtol of the boundary (prestress stable if that energy is "
            "real; a smaller q_rtol decides): undecided",
            None, None, dual, residual, None, "sdp", False, "borderline",
        )
    return _not_stable(q, scales, tol, err, dual, residual, lam, vec)


def _not_stable(
    q: np.ndarray, scales: np.ndarray, tol: Tolerances, err: float, dual: np.ndarray,
    residual: float, lam: np.ndarray, vec: np.ndarray,
) -> Decision:
    """No combined stress is definite beyond rounding; ``dual`` (k, k) bounds ``t*`` by
    ``residual`` (relative), ``lam`` and ``vec`` its eigen-decomposition. Not stable where that
    bound, or a common zero of the forms, is within rounding; then: is there a second-order
    flex?"""
    s, k, _ = q.shape
    witness: np.ndarray | None
    if k == 2:
        zero, witness = _binary_common_zero(q, scales)
    else:
        zero, witness = _search_common_zero(q, scales, err, vec[:, -1])
    if residual > err and zero <= err and witness is not None:
        dual, residual = np.outer(witness, witness), zero  # the common zero is the certificate
    if residual > err:
        bound = min(residual, zero)
        within = bound <= tol.q_rtol
        return Decision(
            None, None,
            (f"borderline: no combined stress is definite beyond rounding ({err:.2g}), but the "
             f"best certificate that none is bounds the stability margin only by {bound:.3g} "
             f"(relative), not to rounding: within q_rtol = {tol.q_rtol:g} of the boundary, "
             "undecided" if within else
             f"borderline: no combined stress is definite beyond q_rtol and the dual residual "
             f"{residual:.3g} exceeds q_rtol = {tol.q_rtol:g}: undecided"),
            None, None, dual, residual, None, "sdp", False, "borderline",
        )
    if zero <= err and witness is not None:
        return Decision(
            False, False,
            "not prestress stable (dual certificate) and not second-order rigid: "
            "second_order_flex is a non-trivial flex with zero energy under every self-stress, "
            "so it extends to a second-order flex",
            None, None, dual, residual, witness, "sdp", True, "",
        )
    if k == 2 and zero > tol.q_rtol:
        return Decision(
            False, True,
            "not prestress stable (dual certificate); second-order rigid: no flex is a common "
            "zero of the stress energies (decided exactly on the two flexes)",
            None, None, dual, residual, None, "sdp", True, "",
        )
    if zero <= tol.q_rtol:
        why = (f"second-order rigidity borderline: a flex has energy at most {zero:.3g} "
               f"(relative) under every self-stress, above rounding ({err:.2g}) but within "
               f"q_rtol = {tol.q_rtol:g}: undecided")
    else:
        why = (f"second-order rigidity undecided: no flex with zero energy under all {s} "
               f"self-stresses was found on the {k} flexes, and none is proved not to exist")
    rank = int(np.sum(lam > tol.rank_rtol * lam[-1]))
    return Decision(False, None, f"not prestress stable (dual certificate of rank {rank}); {why}",
                    None, None, dual, residual, None, "sdp", True, "")


def count(n: int, noun: str) -> str:
    return f"{n} {noun}" if n == 1 else f"{n} {noun}es"


def _borderline(what: str, value: float, err: float, tol: Tolerances, method: str) -> Decision:
    return Decision(
        None, None,
        f"borderline: {what} {value:.3g} (relative), above the rounding scale {err:.2g} but not "
        f"above q_rtol = {tol.q_rtol:g}: within q_rtol of the boundary, prestress stability and "
        "second-order rigidity undecided (a smaller q_rtol decides)",
        None, None, None, None, None, method, False, "borderline",
    )


def _closed_form(q: np.ndarray, scales: np.ndarray, tol: Tolerances, err: float) -> Decision:
    """One flex or one stress: prestress stability and second-order rigidity coincide."""
    s, k, _ = q.shape
    if k == 1:
        vals = q[:, 0, 0]
        norm = float(np.linalg.norm(vals))
        # the best unit omega is vals / |vals|, with energy |vals| on the flex
        weight = float(np.abs(vals / norm) @ scales) if norm > 0 else float(np.max(scales))
        if norm > tol.q_rtol * weight:
            return Decision(
                True, True,
                f"prestress stable: one non-trivial flex and {count(s, 'self-stress')}; the "
                f"combined stress has energy {norm:.3g} on it, hence second-order rigid",
                vals / norm, norm, None, None, None, "closed-form", True, "",
            )
        if norm > err * weight:
            return _borderline("the only flex has energy", norm / weight, err, tol,
                               "closed-form")
        return Decision(
            False, False,
            f"not prestress stable and not second-order rigid: the only non-trivial flex has "
            f"zero energy under {count(s, 'self-stress')}, so it extends to second order "
            "(higher-order analysis decides rigidity)",
            None, None, np.ones((1, 1)), float(np.max(np.abs(vals) / scales)),
            np.ones(1), "closed-form", True, "",
        )
    lam, vec = np.linalg.eigh(q[0])  # ascending
    thr, zero = tol.q_rtol * scales[0], err * scales[0]
    # definite either way: omega = +1 or -1 (a stress and its negative are both stresses)
    for sign, smallest in ((1.0, float(lam[0])), (-1.0, float(-lam[-1]))):
        if smallest > thr:
            return Decision(
                True, True,
                f"prestress stable: one self-stress whose Q is definite on the {k} flexes "
                f"(smallest |eigenvalue| {smallest:.3g}), hence second-order rigid",
                np.array([sign]), smallest, None, None, None, "closed-form", True, "",
            )
    margin = max(float(lam[0]), float(-lam[-1]))
    if margin > zero:
        return _borderline("Q is definite on the flexes with smallest |eigenvalue|",
                           margin / scales[0], err, tol, "closed-form")
    # Q is singular to rounding, or indefinite beyond it: a real zero of c^T Q c exists
    small = np.flatnonzero(np.abs(lam) <= zero)
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
    return Decision(
        False, False,
        f"not prestress stable and not second-order rigid: one self-stress and {why}; "
        "second_order_flex has zero energy, so it extends to a second-order flex",
        None, None, dual, residual, c, "closed-form", True, "",
    )
