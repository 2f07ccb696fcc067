"""Robustness margin: the smallest change of the adjustable lengths that reaches a critical value.

Fabrication tolerance of a design: how far (Euclidean norm over the adjustable bars) its lengths
sit from the critical value set, where the topology of the configuration space can change.

Method: over critical configurations ``(u, sigma)`` minimise ``sum_{a adjustable}
(l_a(u) - L_a)^2`` subject to ``J(u)^T sigma = 0``, ``|sigma|^2 = 1`` and ``l_b(u) = L_b`` for
the other bars (SLSQP with analytic derivatives). Starts: every critical configuration the
exploration reaches (critical points, the critical configurations of the near misses, and
seeded multistart refinements of the augmented system from random points projected onto the
constraints). Each run is a local minimum; the answer is the best over all starts. It is the
global minimum when some start lies in the basin of the nearest sheet of the critical value
set; the starts sample every sheet that the critical-point search meets (for the four-bar, all
eight collinearity planes, which the tests check against the exact distances).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import minimize

from engine.assembly import projected_random_starts
from engine.configuration_space import SpaceOptions, find_critical_points
from engine.constraints import Constraints
from engine.critical import refine_critical
from engine.errors import InvalidRequest
from engine.linkage import Linkage, changeable_bar
from engine.tolerances import Tolerances


@dataclass(frozen=True)
class Margin:
    """``margin`` (length units), the ``nearest`` critical lengths (E,), and the critical
    configuration ``critical_u`` (M,) there; ``starts``/``converged`` count the local runs."""

    margin: float
    nearest: np.ndarray
    critical_u: np.ndarray
    starts: int
    converged: int
    success: bool
    message: str


def _adjustable_mask(linkage: Linkage, adjustable: list[str] | None) -> np.ndarray:
    act = np.flatnonzero(linkage.active)
    if adjustable is None:
        return np.ones(len(act), dtype=bool)
    mask = np.zeros(len(act), dtype=bool)
    for k, bar in enumerate(adjustable):
        j = changeable_bar(linkage, bar, ("adjustable", k))
        mask[int(np.flatnonzero(act == j)[0])] = True
    if not mask.any():
        raise InvalidRequest("give at least one adjustable bar", loc=("adjustable",))
    return mask


def _local(
    cons: Constraints, adj: np.ndarray, u0: np.ndarray, s0: np.ndarray, tol: Tolerances
) -> tuple[float, np.ndarray, np.ndarray] | None:
    m, e = cons.n_free, cons.n_constraints
    target = cons.linkage.lengths[cons.bars]
    scale = float(np.median(target))

    def lengths(u: np.ndarray) -> np.ndarray:
        return np.sqrt(np.maximum(cons.squared_lengths(u), 1e-300))

    def objective(x: np.ndarray) -> tuple[float, np.ndarray]:
        u = x[:m]
        ln = lengths(u)
        diff = (ln - target)[adj]
        jac = cons.jacobian(u, sparse=False)
        grad_u = ((diff / ln[adj])[:, None] * jac[adj]).sum(axis=0)  # d l / du = J / (2 l)
        return float(diff @ diff), np.concatenate([grad_u, np.zeros(e)])

    def eq(x: np.ndarray) -> np.ndarray:
        u, s = x[:m], x[m:]
        jac = cons.jacobian(u, sparse=False)
        return np.concatenate([(lengths(u) - target)[~adj], jac.T @ s / (2 * scale), [s @ s - 1]])

    def eq_jac(x: np.ndarray) -> np.ndarray:
        u, s = x[:m], x[m:]
        jac = cons.jacobian(u, sparse=False)
        ln = lengths(u)
        fixed_rows = np.hstack([jac[~adj] / (2 * ln[~adj])[:, None], np.zeros(((~adj).sum(), e))])
        stress_rows = np.hstack([cons.stress_hessian(s, sparse=False), jac.T]) / (2 * scale)
        norm_row = np.concatenate([np.zeros(m), 2 * s])[None, :]
        return np.vstack([fixed_rows, stress_rows, norm_row])

    res = minimize(
        objective, np.concatenate([u0, s0]), jac=True, method="SLSQP",
        constraints=[{"type": "eq", "fun": eq, "jac": eq_jac}],
        options={"maxiter": 300, "ftol": 1e-16},
    )
    if np.max(np.abs(eq(res.x))) > 1e3 * tol.residual_atol:
        return None
    u = res.x[:m]
    return float(np.sqrt(max(res.fun, 0.0))), lengths(u), u


def robustness(
    linkage: Linkage,
    adjustable: list[str] | None = None,
    tolerances: Tolerances | None = None,
    options: SpaceOptions | None = None,
    extra_starts: int = 24,
) -> Margin:
    """Smallest Euclidean change of the adjustable lengths that reaches a critical value.

    Examples
    --------
    >>> from engine.presets import build_preset
    >>> r = robustness(build_preset("four-bar", {"L2": 1.2}), ["L2"])
    >>> round(r.margin, 6)  # the nearest critical value is L2 = a + L1 - L3 = 1
    0.2
    """
    tol = tolerances or Tolerances()
    cons = Constraints(linkage)
    adj = _adjustable_mask(linkage, adjustable)
    space = find_critical_points(linkage, tol, options or SpaceOptions())  # no segments needed
    starts = [cp.u for cp in space.critical_points] + [m.critical_u for m in space.near_misses]
    rng = np.random.default_rng(1234)
    for u0 in projected_random_starts(linkage, tol, extra_starts, rng):
        starts.append(refine_critical(cons, u0, tol).u)
    best: tuple[float, np.ndarray, np.ndarray] | None = None
    converged = 0
    for u0 in starts:
        jac = cons.jacobian(u0, sparse=False)
        s0 = np.linalg.svd(jac)[0][:, -1]
        found = _local(cons, adj, u0, s0, tol)
        if found is None:
            continue
        converged += 1
        if best is None or found[0] < best[0]:
            best = found
    nearest = np.array(linkage.lengths, dtype=float)
    if best is None:
        return Margin(np.inf, nearest, linkage.coordinates(), len(starts), 0, False,
                      "no local search converged to a critical configuration")
    nearest[cons.bars] = best[1]
    return Margin(best[0], nearest, best[2], len(starts), converged, True, "best over starts")
