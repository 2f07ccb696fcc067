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

The decision on the forms, with its certificates, is :func:`engine.local.certificates.decide`
(the SDP by Clarabel, bounded by ``MAX_FLEXES``, ``MAX_STRESSES`` and ``SOLVER_SECONDS``): an
answer within ``q_rtol`` of the boundary (stability margin ``t*`` above the rounding scale of the
forms but not above ``q_rtol``) is ``None`` with the reason, never a definite False. The forms'
own rounding scale comes from the first-order analysis (:func:`form_error`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from engine.local.certificates import MAX_FLEXES, MAX_STRESSES, Decision, count, decide
from engine.local.rigidity import RigidityResult
from engine.model.constraints import Constraints
from engine.model.linkage import Linkage
from engine.model.tolerances import Tolerances
from engine.model.vectors import normalise_sign

#: Largest linkage whose second-order acceleration is solved densely (sparse LSQR above).
DENSE_ACCELERATION_MAX_FREE = 2000

__all__ = ["MAX_FLEXES", "MAX_STRESSES", "PrestressResult", "decide", "form_error", "prestress",
           "stress_forms"]


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
        dec = Decision(
            True, True, "first-order rigid: no non-trivial flex, so every self-stress (even 0) "
            "certifies prestress stability", np.zeros(s), None, None, None, None, "first-order",
            True, "",
        )
        return _from_decision(linkage, stresses, flexes, dec)
    if s == 0:
        dec = Decision(
            False, False, "no self-stress: the bars are independent and every flex "
            f"({count(k, 'flex')}) extends to a real motion (the framework flexes here)",
            None, None, np.diag(np.eye(k)[0]), 0.0, np.eye(k)[0], "first-order", True, "",
        )
        return _from_decision(linkage, stresses, flexes, dec)
    if k > 1 and s > 1 and (k > MAX_FLEXES or s > MAX_STRESSES):
        # refuse before forming the Q_k (E k^2 s work); the closed forms stay cheap
        dec = Decision(
            None, None,
            f"{k} flexes and {s} self-stresses exceed the SDP limits ({MAX_FLEXES} flexes, "
            f"{MAX_STRESSES} stresses): prestress stability and second-order rigidity undecided",
            None, None, None, None, None, "sdp", False, "too large",
        )
        return _from_decision(linkage, stresses, flexes, dec)
    q = stress_forms(linkage, flexes, stresses)  # (s, k, k)
    q = 0.5 * (q + np.transpose(q, (0, 2, 1)))
    scales = 4.0 * np.abs(stresses).sum(axis=1)
    return _from_decision(linkage, stresses, flexes, decide(q, scales, tol, form_error(rig)))


def form_error(rig: RigidityResult) -> float:
    """The error of the forms ``Q_k`` relative to their scales ``4 |w_k|_1``, from the flexes
    and stresses they are made of.

    Both are null spaces of ``J`` (Ea, M) computed in float64: by Wedin's theorem each is off by
    an angle ``e <= max(Ea, M) eps s_max / s_gap``, ``s_gap`` the smallest singular value
    counted in the rank (at least ``rank_rtol s_max`` by that count, where the sparse method
    does not report it). A flex error moves ``Q_k = Z H Z^T`` by ``2 e |H|``, a stress error
    moves ``H_w`` by ``4 |dw|_1 <= 4 sqrt(Ea) e |w|_2``, and ``|H_w| <= 4 |w|_1`` with
    ``|w|_1 >= |w|_2``: in all ``(2 + sqrt(Ea)) e``.
    """
    sv = rig.singular_values
    if rig.rank == 0 or sv.size == 0 or sv[0] <= 0:
        return 0.0
    s_max = float(sv[0])
    if rig.singular_values_complete and rig.rank <= sv.size:
        s_gap = float(sv[rig.rank - 1])
    else:
        s_gap = rig.tolerances.rank_rtol * s_max
    eps = float(np.finfo(float).eps)
    angle = max(rig.n_constraints, rig.n_free) * eps * s_max / max(s_gap, eps * s_max)
    return (2.0 + float(np.sqrt(rig.n_constraints))) * angle


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
    linkage: Linkage, stresses: np.ndarray, flexes: np.ndarray, dec: Decision
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
