"""Design length changes that split chosen branch points with chosen signs (paper, Sec. III C).

To first order ``Delta_i = g_i . dL`` with ``g_i = 4 sigma_i L`` (see
:mod:`engine.design.splitting`).
Asking ``sign_i Delta_i >= margin |g_i|`` for every target and minimising the largest change
``max_j |dL_j|`` over the adjustable bars is a linear programme (HiGHS via
``scipy.optimize.linprog``). Targets whose gradients are parallel on the adjustable bars are
tied: they split together, and asking them for opposite signs is a conflict.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import linprog

from engine.design.splitting import linear_delta_gradient, retraced_pairing, split
from engine.local.critical import CriticalPoint
from engine.model.budget import NEVER, Deadline
from engine.model.errors import InvalidRequest
from engine.model.linkage import Linkage, changeable_bar
from engine.model.tolerances import Tolerances


@dataclass(frozen=True)
class Target:
    branch_point: int
    sign: int


@dataclass(frozen=True)
class Conflict:
    branch_points: list[int]
    reason: str


@dataclass(frozen=True)
class DesignResult:
    """``perturbation`` (E,) is zero off the adjustable bars; ``success``/``message`` report the
    solver; ``feasible`` is False with ``conflicts`` when no change satisfies every target."""

    feasible: bool
    perturbation: np.ndarray
    largest_change: float
    conflicts: list[Conflict]
    success: bool
    message: str


def check_request(linkage: Linkage, targets: list[Target], adjustable: list[str]) -> np.ndarray:
    """Validate what needs no exploration (call it before exploring, so that a bad request is
    refused at once): targets given with signs +-1, adjustable bars known, changeable and
    distinct. Returns the indices of the adjustable bars."""
    if not targets:
        raise InvalidRequest("give at least one target", loc=("targets",))
    if not adjustable:
        raise InvalidRequest("give at least one adjustable bar", loc=("adjustable",))
    idx = [changeable_bar(linkage, bar, ("adjustable", k)) for k, bar in enumerate(adjustable)]
    if len(set(idx)) != len(idx):
        raise InvalidRequest("adjustable bars repeat", loc=("adjustable",))
    for k, t in enumerate(targets):
        if t.sign not in (-1, 1):
            raise InvalidRequest("sign must be 1 or -1", loc=("targets", k, "sign"))
    return np.array(idx)


def _validate(
    linkage: Linkage, crit: list[CriticalPoint], targets: list[Target], adjustable: list[str]
) -> np.ndarray:
    idx = check_request(linkage, targets, adjustable)
    for k, t in enumerate(targets):
        if not 0 <= t.branch_point < len(crit):
            raise InvalidRequest(
                f"no critical point {t.branch_point} (found {len(crit)})",
                loc=("targets", k, "branch_point"),
            )
        if crit[t.branch_point].kind != "branch":
            raise InvalidRequest(
                f"critical point {t.branch_point} is {crit[t.branch_point].kind}, not a branch "
                "point", loc=("targets", k, "branch_point"),
            )
    return idx


def _conflicts(rows: np.ndarray, targets: list[Target]) -> list[Conflict]:
    """Pairs of targets whose signed gradients point in opposite directions (tied), and
    targets that the adjustable bars cannot move at all."""
    out: list[Conflict] = []
    norms = np.linalg.norm(rows, axis=1)
    for a in range(len(targets)):
        if norms[a] <= 1e-12:
            out.append(Conflict([targets[a].branch_point],
                                "the adjustable bars do not change how this point splits"))
    for a in range(len(targets)):
        for b in range(a + 1, len(targets)):
            if norms[a] <= 1e-12 or norms[b] <= 1e-12:
                continue
            cos = float(rows[a] @ rows[b] / (norms[a] * norms[b]))
            if cos < -1 + 1e-9:
                out.append(Conflict(
                    [targets[a].branch_point, targets[b].branch_point],
                    "tied: on the adjustable bars these points split together, so they cannot "
                    "take these signs at once",
                ))
    return out


def design(
    linkage: Linkage,
    crit: list[CriticalPoint],
    targets: list[Target],
    adjustable: list[str],
    margin: float,
    max_change: float | None = None,
) -> DesignResult:
    """Smallest largest change of the adjustable bars giving every target its sign with
    ``sign * Delta >= margin * |g|`` (``margin`` in length units)."""
    if not (np.isfinite(margin) and margin > 0):
        raise InvalidRequest(f"margin must be a positive number, got {margin!r}", loc=("margin",))
    if max_change is not None and not (np.isfinite(max_change) and max_change > 0):
        raise InvalidRequest(
            f"max_change must be a positive number, got {max_change!r}", loc=("max_change",)
        )
    idx = _validate(linkage, crit, targets, adjustable)
    grads = np.array([linear_delta_gradient(linkage, crit[t.branch_point])[idx] for t in targets])
    signs = np.array([t.sign for t in targets], dtype=float)
    rows = signs[:, None] * grads
    k = len(idx)
    conflicts = _conflicts(rows, targets)
    zero = np.zeros(linkage.n_bars)
    if conflicts:
        return DesignResult(False, zero, 0.0, conflicts, True, "conflicting targets")
    # variables x = (dL_1..dL_k, t): minimise t, -t <= dL_j <= t, rows . dL >= margin |row|
    cost = np.zeros(k + 1)
    cost[-1] = 1.0
    a_ub = np.vstack([
        np.hstack([-rows, np.zeros((len(targets), 1))]),
        np.hstack([np.eye(k), -np.ones((k, 1))]),
        np.hstack([-np.eye(k), -np.ones((k, 1))]),
    ])
    b_ub = np.concatenate([-margin * np.linalg.norm(rows, axis=1), np.zeros(2 * k)])
    bounds = [(None, None)] * k + [(0, max_change)]
    res = linprog(cost, A_ub=a_ub, b_ub=b_ub, bounds=bounds, method="highs")
    if res.status == 2:  # infeasible
        reason = "no change of the adjustable bars gives all these signs together"
        if max_change is not None:
            reason += f" within max_change = {max_change:g}"
        return DesignResult(False, zero, 0.0,
                            [Conflict([t.branch_point for t in targets], reason)], True,
                            res.message)
    if res.status != 0:
        return DesignResult(False, zero, 0.0, [], False, res.message)
    d_l = zero.copy()
    d_l[idx] = res.x[:k]
    return DesignResult(True, d_l, float(res.x[-1]), [], True, res.message)


@dataclass(frozen=True)
class Check:
    """Prediction and re-traced answer for one target of a design.

    ``sign`` is 0 (undecided, ``connects`` empty) where ``|delta| <= delta_error`` (see
    :func:`engine.design.splitting.delta_error`): such a check never agrees.
    """

    branch_point: int
    sign: int
    delta: float
    connects: list[tuple[int, int]]
    traced: list[tuple[int, int]] | None
    #: not re-traced: the deadline had passed (``traced`` is then None, and says nothing)
    skipped: bool = False
    delta_error: float = 0.0

    @property
    def agrees(self) -> bool:
        return self.sign != 0 and self.traced is not None and self.traced == self.connects


def verify(
    linkage: Linkage,
    crit: list[CriticalPoint],
    targets: list[Target],
    d_l: np.ndarray,
    tol: Tolerances,
    deadline: Deadline = NEVER,
) -> list[Check]:
    """Predict (Appendix A, second order) and re-trace the perturbed linkage at each target
    (once ``deadline`` has passed the remaining targets are predicted only: ``skipped``)."""
    perturbed = linkage.with_lengths(linkage.lengths + d_l)
    scale = float(np.median(linkage.lengths[linkage.active]))
    out = []
    for t in targets:
        cp = crit[t.branch_point]
        s = split(linkage, t.branch_point, cp, d_l)
        assert cp.analysis.q_eigenvalues is not None  # targets are branch points (validated)
        lam = float(np.abs(cp.analysis.q_eigenvalues).min())
        if deadline.expired():
            out.append(Check(t.branch_point, s.sign, s.delta, s.connects, None, skipped=True,
                             delta_error=s.delta_error))
            continue
        radius = float(np.clip(4 * np.sqrt(abs(s.delta) / lam), 0.05 * scale, 0.3 * scale))
        traced = retraced_pairing(perturbed, cp, radius, tol)
        out.append(Check(t.branch_point, s.sign, s.delta, s.connects, traced,
                         delta_error=s.delta_error))
    return out
