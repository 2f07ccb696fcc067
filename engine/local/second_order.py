"""Second-order analysis at a critical point with one self-stress (paper, Sec. II B).

``Q = Z H_sigma Z^T`` with ``H_sigma = sum_a sigma_a Hess(l_a^2)`` and ``Z`` (k, M) an
orthonormal basis of the nontrivial zero modes. Note: the main text's ``Q`` has no factor 1/2;
Appendix A's carries one. We use the main text's.

- ``Q`` definite: ``rigid`` (the critical point is isolated, second-order rigid);
- ``Q`` indefinite and nonsingular: ``branch``; the branch tangents are the real solutions of
  ``c^T Q c = 0``;
- several self-stresses, singular ``Q`` or a non-isolated critical set: ``degenerate`` with a
  ``reason``.

Whatever the kind, ``prestress`` (:mod:`engine.local.prestress`) decides prestress stability and
second-order rigidity for any number of stresses and flexes, with certificates.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np

from engine.local.prestress import PrestressResult, prestress
from engine.local.rigidity import RigidityResult, first_order, plan_first_order
from engine.model.budget import NEVER, Deadline, OutOfTime
from engine.model.constraints import DENSE_MAX_FREE, Constraints, project
from engine.model.linkage import Linkage
from engine.model.memory import check_memory
from engine.model.tolerances import Tolerances
from engine.model.vectors import normalise_sign

Kind = Literal["regular", "branch", "rigid", "degenerate"]


@dataclass(frozen=True)
class SecondOrderResult:
    """Outcome of :func:`second_order`.

    Attributes
    ----------
    kind : {"regular", "branch", "rigid", "degenerate"}
    reason : str or None
        Why the point is degenerate.
    self_stress : (E,) float64 or None
        The unit self-stress over all bars.
    zero_modes : (k, M) float64
        Orthonormal zero modes; at a critical point with one stress they are the eigenvectors
        of ``Q``, so ``q`` is diagonal, ordered by decreasing eigenvalue.
    q : (k, k) float64 or None
        ``Q`` in the basis ``zero_modes``.
    q_eigenvalues : (k,) float64 or None
        Descending.
    tangents : (n, M) float64
        Unit branch directions (lines: ``+t`` and ``-t`` are the two rays of each).
    tangent_coefficients : (n, k) float64
        The same directions as coefficients ``c`` on ``zero_modes``.
    rigidity : RigidityResult
        The first-order analysis it builds on.
    prestress : PrestressResult
        Prestress stability and second-order rigidity with their certificates.
    """

    kind: Kind
    reason: str | None
    self_stress: np.ndarray | None
    zero_modes: np.ndarray
    q: np.ndarray | None
    q_eigenvalues: np.ndarray | None
    tangents: np.ndarray
    tangent_coefficients: np.ndarray
    rigidity: RigidityResult
    prestress: PrestressResult


def _stays_critical(
    linkage: Linkage, direction: np.ndarray, tol: Tolerances, scale: float, sparse: bool | None
) -> bool:
    """True when stepping along ``direction`` and projecting back lands on critical points
    again, for two step sizes and both signs: evidence of a non-isolated critical set."""
    u0 = linkage.coordinates()
    for h in (1e-2 * scale, 1e-3 * scale):
        for sgn in (1.0, -1.0):
            moved = linkage.with_positions(linkage.positions_of(u0 + sgn * h * direction))
            proj = project(moved, tol)
            if not proj.success:
                return False
            rig = first_order(linkage.with_positions(proj.positions), tol, sparse=sparse)
            if not rig.critical:
                return False
    return True


def _in_time(deadline: Deadline, what: str) -> None:
    if deadline.expired():
        raise OutOfTime(f"the deadline passed before {what}")


def branch_coefficients(eigenvalues: np.ndarray) -> np.ndarray:
    """Real solutions ``c`` (unit, (n, k)) of ``sum_n lam_n c_n^2 = 0`` in the eigenbasis.

    For each pair of a positive eigenvalue ``lam_p`` and a negative one ``lam_m``,
    ``c = e_p / sqrt(lam_p) +- e_m / sqrt(-lam_m)`` (normalised). For ``k = 2`` these are the
    two lines of the cone; for ``k > 2`` they are generators spanning it.
    """
    k = len(eigenvalues)
    pos = np.flatnonzero(eigenvalues > 0)
    neg = np.flatnonzero(eigenvalues < 0)
    out = []
    for p in pos:
        for n in neg:
            for sgn in (1.0, -1.0):
                c = np.zeros(k)
                c[p] = 1.0 / np.sqrt(eigenvalues[p])
                c[n] = sgn / np.sqrt(-eigenvalues[n])
                out.append(c / np.linalg.norm(c))
    return np.array(out).reshape(-1, k)


def second_order_memory(linkage: Linkage, sparse: bool | None = None) -> tuple[int, str]:
    """Estimated peak bytes of :func:`second_order` (and what they are for), before any work:
    the first-order analysis (whose answer holds the same zero modes), then for
    ``k >= M - E_a + 1`` zero modes at a critical point ``H_sigma Z^T`` (M, k) and the
    ``Q``-eigenbasis (k, M) twice, plus ``H_sigma`` (M, M) where it is dense."""
    plan = plan_first_order(linkage, sparse)
    m, ea = linkage.n_free, int(np.count_nonzero(linkage.active))
    k = max(0, m - ea) + 1
    dense_hessian = 8 * m * m if (m <= DENSE_MAX_FREE if sparse is None else not sparse) else 0
    extra = 8 * (3 * k * m + 2 * k * k) + dense_hessian
    return plan.memory + extra, plan.what.replace("first-order", "second-order")


def second_order(
    linkage: Linkage, tolerances: Tolerances | None = None, sparse: bool | None = None,
    deadline: Deadline = NEVER,
) -> SecondOrderResult:
    """Classify the configuration (taken as given, see ``on_constraints``) to second order.

    ``deadline``: checked by the first-order analysis and between the steps after it
    (:class:`~engine.model.budget.OutOfTime` once it has passed).

    Examples
    --------
    >>> from engine.model.linkage import BarSpec, VertexSpec, build_linkage
    >>> lk = build_linkage(2, [VertexSpec("P", [0, 0], True), VertexSpec("A", [1, 0]),
    ...                        VertexSpec("Q", [2, 0], True)],
    ...                    [BarSpec("a", ["P", "A"]), BarSpec("b", ["A", "Q"])])
    >>> second_order(lk).kind
    'rigid'
    """
    tol = tolerances or Tolerances()
    check_memory(*second_order_memory(linkage, sparse))
    rig = first_order(linkage, tol, sparse=sparse, deadline=deadline)
    _in_time(deadline, "the prestress analysis")
    pre = prestress(linkage, rig, tol)
    _in_time(deadline, "the second-order classification")

    if not rig.critical:
        return _result(rig, pre, "regular")
    n_stress = rig.self_stresses.shape[0]
    if n_stress != 1:
        return _result(
            rig,
            pre,
            "degenerate",
            f"{n_stress} self-stresses: the second-order condition is a system of "
            f"{n_stress} quadratic equations, not classified by kind (see prestress_stable and "
            "second_order_rigid)",
        )
    if rig.dof == 0:
        return _result(rig, pre, "degenerate", "critical with no nontrivial zero mode")

    cons = Constraints(linkage)
    sigma_full, modes, q_diag, lam = _q_eigenbasis(cons, rig, sparse)
    fields = {"self_stress": sigma_full, "zero_modes": modes, "q": q_diag, "q_eigenvalues": lam}

    # ||Hess(l_a^2)||_2 = 4, so 4 sum|sigma_a| bounds ||H_sigma|| without the cancellation a
    # norm of H_sigma itself would suffer (e.g. sigma = (1, -1)/sqrt(2) on a doubled bar).
    q_scale = 4.0 * float(np.abs(sigma_full).sum())
    singular = np.abs(lam) <= tol.q_rtol * q_scale
    if singular.any():
        reason = _singular_reason(linkage, cons, modes, singular, tol, sparse)
        return _result(rig, pre, "degenerate", reason, **fields)
    if np.all(lam > 0) or np.all(lam < 0):
        return _result(rig, pre, "rigid", **fields)
    coeffs = branch_coefficients(lam)
    tangents = coeffs @ modes
    flips = np.sign(np.sum(normalise_sign(tangents) * tangents, axis=1))
    return _result(
        rig,
        pre,
        "branch",
        tangents=tangents * flips[:, None],
        tangent_coefficients=coeffs * flips[:, None],
        **fields,
    )


def _result(
    rig: RigidityResult, pre: PrestressResult, kind: Kind, reason: str | None = None, /,
    **kw: object,
) -> SecondOrderResult:
    """A :class:`SecondOrderResult` of ``kind``: the fields in ``kw`` over the defaults (no
    stress, no ``Q``, no tangents, the first-order zero modes)."""
    base: dict[str, object] = {
        "self_stress": None,
        "zero_modes": normalise_sign(rig.zero_modes),
        "q": None,
        "q_eigenvalues": None,
        "tangents": np.zeros((0, rig.n_free)),
        "tangent_coefficients": np.zeros((0, rig.dof)),
    }
    base.update(kw)
    return SecondOrderResult(
        kind=kind, reason=reason, rigidity=rig, prestress=pre, **base  # type: ignore[arg-type]
    )


def _q_eigenbasis(
    cons: Constraints, rig: RigidityResult, sparse: bool | None
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """At a critical point with one self-stress: the unit stress ``sigma`` (E,), the zero
    modes in ``Q``'s eigenbasis (k, M), ``Q`` in that basis (k, k) and its diagonal (k,),
    ordered by decreasing eigenvalue."""
    sigma_full = normalise_sign(rig.self_stresses)[0]
    hess = cons.stress_hessian(sigma_full[cons.bars], sparse=sparse)
    z = rig.zero_modes  # (k, M)
    hz = hess @ z.T  # (M, k)
    q = z @ hz
    q = 0.5 * (q + q.T)
    lam, vec = np.linalg.eigh(q)
    order = np.argsort(lam)[::-1]
    lam, vec = lam[order], vec[:, order]
    modes = normalise_sign(vec.T @ z)  # Q-eigenbasis, signs by convention
    q_diag = modes @ (hess @ modes.T)
    q_diag = 0.5 * (q_diag + q_diag.T)
    lam = np.diag(q_diag).copy()
    return sigma_full, modes, q_diag, lam


def _singular_reason(
    linkage: Linkage,
    cons: Constraints,
    modes: np.ndarray,
    singular: np.ndarray,
    tol: Tolerances,
    sparse: bool | None,
) -> str:
    """Why a ``Q`` singular on the ``modes`` marked ``singular`` leaves the point degenerate."""
    scale = float(np.median(linkage.lengths[cons.bars]))
    if any(
        _stays_critical(linkage, modes[k], tol, scale, sparse)
        for k in np.flatnonzero(singular)
    ):
        return (
            "non-isolated critical set: the configuration stays critical along a zero mode "
            "on which Q vanishes"
        )
    return "Q is singular on the zero modes: higher-order analysis is needed"
