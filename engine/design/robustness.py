"""Robustness margin: the smallest change of the adjustable lengths that reaches a critical value.

Fabrication tolerance of a design: how far (Euclidean norm over the adjustable bars) its lengths
sit from the critical value set, where the topology of the configuration space can change.
A configuration with a bar shorter than :func:`min_critical_length` is degenerate (the service
refuses such bars as input), not critical: it is never a critical value here.

Two methods, and each result says which one answered and what it guarantees (``guarantee``):

- ``"closed-form"`` (guarantee ``"exact"``): spherical four-bars over one or two of their chords
  (:mod:`engine.design.spherical_margin`: the nearest arc equality in closed form or by a
  certified branch and bound along it, the flat triangles where the rest assembles), and
  one-loop planar dyad chains (the four-bar family,
  any pin geometry), whose critical value set is a union of hyperplane pieces derived in
  :mod:`engine.design.dyad_margin`; the margin is the exact distance to the nearest piece.
- ``"multistart"`` (guarantee ``"upper-bound"``: a critical value lies at this distance, found
  and checked, and a nearer one may have been missed; the best local minimum over the starts
  that converged). It runs on the linkage scaled to unit median length (and ``residual_atol``
  with it) and scales its answer back, so that the same linkage drawn at any scale gets the same
  margin in its units. Where the closed form applies too, the multistart is compared with it:
  ``exact_margin`` reports the exact value beside the multistart's. Over
  critical configurations ``(u, sigma)`` minimise ``sum_{a adjustable} (l_a(u) - L_a)^2``
  subject to ``J(u)^T sigma = 0``, ``sum_i (sigma_i l_i)^2 = s^2`` (the stress normalised by
  the forces it exerts, ``s`` the median length: a stress on a vanishing bar cannot satisfy
  it), ``l_b(u) = L_b`` for the other bars and ``l_a(u) >= min_critical_length`` (SLSQP with
  analytic derivatives, after a least-squares step onto the constraints). Starts: every
  critical configuration the exploration reaches (critical points and the critical
  configurations of the near misses), seeded random points refined on the augmented system,
  and seeded random points off the constraints (the local search moves the lengths, so these
  reach critical configurations that exist only at other lengths, e.g. the slider-crank's
  branch point). It is the global minimum when some start lies in the basin of the nearest
  sheet of the critical value set.
  With a :class:`engine.model.budget.Deadline` the starts stop when it expires and the best so far
  is
  returned with ``search.complete`` False and ``search.reason`` ``"time"``.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Literal

import numpy as np
from scipy.optimize import OptimizeResult, least_squares, minimize

from engine.design.dyad_margin import ExactMargin, exact_margin
from engine.design.spherical_margin import SPHERICAL_PIECES, spherical_margin
from engine.local.critical import refine_critical
from engine.model.budget import ARGUMENT_DERIVED, NEVER, Deadline, granted
from engine.model.constraints import Constraints
from engine.model.errors import InvalidRequest
from engine.model.hessian import dense_stress_hessian
from engine.model.linkage import Linkage, changeable_bar
from engine.model.report import SearchReport
from engine.model.tolerances import MIN_CRITICAL_LENGTH_ATOL, NORM_FLOOR, Tolerances
from engine.space.assembly import iter_projected_random_starts
from engine.space.configuration_space import SpaceOptions, find_critical_points

#: A local search whose start, moved onto the critical set, has a bar shorter than this
#: (relative to the median length) is abandoned: it is in a degenerate configuration's basin.
DEGENERATE_START_REL = 1e-3

#: A local search whose objective has not changed over this many iterations is ended.
STALL_ITERATIONS = 10

#: What the closed forms' pieces are, in the answer's message and argument.
DYAD_PIECES = "critical hyperplanes of a one-loop dyad chain"

#: Methods of :func:`robustness`: ``"auto"`` takes the closed form where it applies.
METHODS = ("auto", "closed-form", "multistart")


def min_critical_length(tol: Tolerances) -> float:
    """Shortest bar a reported critical configuration may have (``1e3 * residual_atol``)."""
    return MIN_CRITICAL_LENGTH_ATOL * tol.residual_atol


@dataclass(frozen=True)
class Margin:
    """``margin`` (length units), the ``nearest`` critical lengths (E,), and the critical
    configuration ``critical_u`` (M,) there; ``starts``/``converged`` count the local runs.

    ``method`` is ``"closed-form"`` or ``"multistart"``; ``guarantee`` says what the margin is:
    ``"exact"`` (the closed form) or ``"upper-bound"`` (the multistart found a critical value at
    this distance; a nearer one may exist), with ``guarantee_detail`` saying how it was found;
    ``exact_margin`` is the closed form's margin where one exists beside a multistart (None
    otherwise); ``search`` is the :class:`engine.model.report.SearchReport` of the starts
    (``complete``, and ``reason`` ``"time"`` when a deadline stopped them)."""

    margin: float
    nearest: np.ndarray
    critical_u: np.ndarray
    starts: int
    converged: int
    success: bool
    message: str
    method: Literal["closed-form", "multistart"] = "multistart"
    guarantee: Literal["exact", "upper-bound"] = "upper-bound"
    search: SearchReport = field(default_factory=SearchReport)
    guarantee_detail: str = ""
    exact_margin: float | None = None


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


class _MarginProblem:
    """The local margin problem over ``x = (u, sigma)`` (M + E,): the objective, the equality
    and inequality constraints and their Jacobians, for SLSQP and the least-squares step.

    ``adj`` (E,) bool marks the adjustable bars among the active ones."""

    def __init__(self, cons: Constraints, adj: np.ndarray, tol: Tolerances) -> None:
        self.cons = cons
        self.adj = adj
        self.m, self.e = cons.n_free, cons.n_constraints
        self.target = cons.linkage.lengths[cons.bars]
        self.scale = float(np.median(self.target))
        self.shortest = min_critical_length(tol)
        # SLSQP asks for the objective, the constraints and their Jacobians at the same point:
        # lengths and J are computed once per point
        self._memo: dict[bytes, tuple[np.ndarray, np.ndarray]] = {}

    def at(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        memo = self._memo
        key = u.tobytes()
        if key not in memo:
            memo.clear()
            memo[key] = (np.sqrt(np.maximum(self.cons.squared_lengths(u), NORM_FLOOR)),
                         self.cons.jacobian(u, sparse=False))
        return memo[key]

    def lengths(self, u: np.ndarray) -> np.ndarray:
        return self.at(u)[0]

    def objective(self, x: np.ndarray) -> tuple[float, np.ndarray]:
        m, adj = self.m, self.adj
        u = x[:m]
        ln, jac = self.at(u)
        diff = (ln - self.target)[adj]
        grad_u = ((diff / ln[adj])[:, None] * jac[adj]).sum(axis=0)  # d l / du = J / (2 l)
        return float(diff @ diff), np.concatenate([grad_u, np.zeros(self.e)])

    # The stress is normalised by the forces it exerts, sum_i (sigma_i l_i)^2 = scale^2, not by
    # |sigma| = 1: a unit stress on a bar of length zero would balance trivially (its row of J
    # vanishes), which made every zero-length bar a spurious critical configuration; with
    # the forces normalised a vanishing bar would need an unbounded stress, so degenerate
    # configurations are no solutions at all.
    def eq(self, x: np.ndarray) -> np.ndarray:
        m, adj, scale = self.m, self.adj, self.scale
        u, s = x[:m], x[m:]
        ln, jac = self.at(u)
        force = float((s * ln) @ (s * ln)) / scale**2
        return np.concatenate([(ln - self.target)[~adj], jac.T @ s / (2 * scale), [force - 1]])

    def eq_jac(self, x: np.ndarray) -> np.ndarray:
        m, e, adj, scale = self.m, self.e, self.adj, self.scale
        u, s = x[:m], x[m:]
        ln, jac = self.at(u)
        fixed_rows = np.hstack([jac[~adj] / (2 * ln[~adj])[:, None], np.zeros(((~adj).sum(), e))])
        stress_rows = np.hstack([dense_stress_hessian(self.cons, s), jac.T]) / (2 * scale)
        norm_row = np.concatenate([(s * s) @ jac, 2 * s * ln * ln])[None, :] / scale**2
        return np.vstack([fixed_rows, stress_rows, norm_row])

    # adjustable bars stay longer than the shortest critical bar (the others keep their length)
    def ineq(self, x: np.ndarray) -> np.ndarray:
        return (self.lengths(x[:self.m]) - self.shortest)[self.adj] / self.scale

    def ineq_jac(self, x: np.ndarray) -> np.ndarray:
        adj = self.adj
        ln, jac = self.at(x[:self.m])
        rows = jac[adj] / (2 * ln[adj])[:, None] / self.scale
        return np.hstack([rows, np.zeros((int(adj.sum()), self.e))])


def _slsqp(problem: _MarginProblem, x0: np.ndarray, deadline: Deadline) -> OptimizeResult:
    """SLSQP on ``problem`` from ``x0``, ended early by the deadline or a stalled objective."""
    scale = problem.scale
    history: list[float] = []

    def stop(xk: np.ndarray) -> None:
        # the deadline ends a run too (its iterate is checked like any other); so does a
        # run whose objective has stopped changing (SLSQP can cycle there to its limit)
        history.append(problem.objective(xk)[0])
        if deadline.expired() or (len(history) > STALL_ITERATIONS and np.ptp(
                history[-STALL_ITERATIONS:]) <= 1e-15 * scale**2):
            raise StopIteration

    return minimize(
        problem.objective, x0, jac=True, method="SLSQP", callback=stop,
        constraints=[{"type": "eq", "fun": problem.eq, "jac": problem.eq_jac},
                     {"type": "ineq", "fun": problem.ineq, "jac": problem.ineq_jac}],
        options={"maxiter": 150, "ftol": 1e-14 * scale**2},
    )


class _OutOfTime(Exception):
    """The deadline passed inside a local search's least squares."""


def _local(
    cons: Constraints, adj: np.ndarray, u0: np.ndarray, s0: np.ndarray, tol: Tolerances,
    deadline: Deadline = NEVER,
) -> tuple[float, np.ndarray, np.ndarray] | None:
    problem = _MarginProblem(cons, adj, tol)
    m, scale, lengths, eq = problem.m, problem.scale, problem.lengths, problem.eq

    # Onto the critical set first (least squares, the adjustable lengths free): cheap, and a
    # start that lands on a degenerate configuration (a bar shrunk to nearly nothing) is in
    # that configuration's basin, where SLSQP spends its whole iteration budget for nothing.
    s0 = s0 * scale / max(float(np.linalg.norm(s0 * lengths(u0))), NORM_FLOOR)

    def eq_in_time(x: np.ndarray) -> np.ndarray:
        # (each evaluation: the deadline ends the least squares too, as it ends SLSQP)
        if deadline.expired():
            raise _OutOfTime
        return eq(x)

    # a run that diverges (the stress growing without bound) overflows; it is rejected below
    with np.errstate(over="ignore", invalid="ignore"):
        try:
            pre = least_squares(eq_in_time, np.concatenate([u0, s0]), jac=problem.eq_jac,
                                method="trf", xtol=1e-12, ftol=1e-12, gtol=1e-12, max_nfev=15)
        except ValueError:  # not finite at the start
            return None
        except _OutOfTime:
            return None
        if not np.all(np.isfinite(pre.x)) or (
                np.min(lengths(pre.x[:m])) < DEGENERATE_START_REL * scale):
            return None
        res = _slsqp(problem, pre.x, deadline)
        if not (np.all(np.isfinite(res.x)) and np.isfinite(res.fun)) or not (
                np.max(np.abs(eq(res.x))) <= 1e3 * tol.residual_atol):
            return None
    u = res.x[:m]
    if np.min(lengths(u)) < problem.shortest:
        return None  # a degenerate configuration, not a critical one
    return float(np.sqrt(max(res.fun, 0.0))), lengths(u), u


def robustness(
    linkage: Linkage,
    adjustable: list[str] | None = None,
    tolerances: Tolerances | None = None,
    options: SpaceOptions | None = None,
    extra_starts: int = 24,
    *,
    method: str = "auto",
    deadline: Deadline | None = None,
) -> Margin:
    """Smallest Euclidean change of the adjustable lengths that reaches a critical value.

    Parameters
    ----------
    linkage : Linkage
        One degree of freedom, something fixed.
    adjustable : list of bar ids, optional
        Bars whose lengths may change (default: every bar with a free end).
    tolerances : Tolerances, optional
    options : SpaceOptions, optional
        Of the critical-point search that seeds the multistart; ``closed_form=False`` always
        runs the multistart.
    extra_starts : int
        Random starts of each kind (projected and refined on the augmented system; free points
        off the constraints) besides the critical configurations found.
    method : {"auto", "closed-form", "multistart"}
        ``"auto"`` takes the closed form where it applies (one-loop planar dyad chains,
        spherical four-bars over one or two chords), else
        the multistart; ``"closed-form"`` raises :class:`InvalidRequest` where it does not apply.
    deadline : Deadline, optional
        When it expires the multistart stops and returns the best margin so far, with
        ``search.complete`` False and ``search.reason`` ``"time"``.

    Examples
    --------
    >>> from engine.catalogue.presets import build_preset
    >>> r = robustness(build_preset("four-bar", {"L2": 1.2}), ["L2"])
    >>> round(r.margin, 6), r.method, r.guarantee  # nearest critical value: L2 = a + L1 - L3 = 1
    (0.2, 'closed-form', 'exact')
    """
    if method not in METHODS:
        raise InvalidRequest(f"unknown method {method!r}: one of {', '.join(METHODS)}",
                             loc=("method",))
    tol = tolerances or Tolerances()
    opt = options or SpaceOptions()
    cons = Constraints(linkage)
    adj = _adjustable_mask(linkage, adjustable)
    exact, what = None, DYAD_PIECES
    if opt.closed_form:
        adj_all = np.zeros(linkage.n_bars, dtype=bool)
        adj_all[cons.bars[adj]] = True
        exact = exact_margin(linkage, adj_all, min_critical_length(tol), 1e3 * tol.residual_atol)
        if exact is None:  # (a spherical four-bar over one or two of its chords)
            exact = spherical_margin(linkage, adj_all, min_critical_length(tol),
                                     deadline or NEVER)
            what = SPHERICAL_PIECES if exact is not None else what
    if method != "multistart" and exact is not None:
        found = bool(np.isfinite(exact.margin))
        return Margin(
            exact.margin, exact.nearest, exact.critical_u, 0, 0, found,
            f"nearest of {exact.planes} {what}"
            if found else "no critical value is reachable by the adjustable bars",
            method="closed-form", guarantee="exact",
            search=SearchReport({"planes": exact.planes}, time_budget_s=_granted(deadline),
                                argument=ARGUMENT_DERIVED,
                                argument_detail=f"the nearest of the {exact.planes} {what}, "
                                "in closed form"),
            guarantee_detail="the distance to the nearest critical hyperplane (closed form)"
            if what == DYAD_PIECES else f"the distance to the nearest of the {what}",
        )
    if method == "closed-form":
        raise InvalidRequest("the closed form applies to one-loop planar dyad chains (a rotor "
                             "and one dyad, no sliders) and to spherical four-bars over one "
                             "or two chords only", loc=("method",))
    scale = float(np.median(linkage.lengths[cons.bars]))
    unit = linkage.with_positions(np.asarray(linkage.positions) / scale).with_lengths(
        linkage.lengths / scale)
    unit_tol = replace(tol, residual_atol=tol.residual_atol / scale)
    res = _multistart(unit, Constraints(unit), adj, unit_tol, opt, extra_starts,
                      deadline or NEVER)
    return _compared(replace(res, margin=res.margin * scale, nearest=res.nearest * scale,
                             critical_u=res.critical_u * scale), exact, tol)


def _compared(res: Margin, exact: ExactMargin | None, tol: Tolerances) -> Margin:
    """The multistart's answer beside the closed form's, where there is one."""
    if exact is None:
        return res
    gap = res.margin - exact.margin
    # both are distances to critical lengths located to about 1e3 residual_atol
    same = bool(np.isfinite(res.margin) and abs(gap) <= 1e3 * tol.residual_atol) or (
        not np.isfinite(res.margin) and not np.isfinite(exact.margin))
    if same:
        verdict = "equals the exact margin of the closed form"
    elif gap > 0:
        verdict = (f"exceeds the exact margin {exact.margin:.6g} of the closed form: the starts "
                   "missed the nearest critical sheet")
    else:
        verdict = (f"is below the exact margin {exact.margin:.6g} of the closed form by "
                   f"{-gap:.3g}: its critical configuration is not a critical value of the "
                   "closed form")
    return replace(res, exact_margin=float(exact.margin),
                   message=f"{res.message}; the multistart's margin {verdict}",
                   success=res.success and same)


def _multistart(
    linkage: Linkage, cons: Constraints, adj: np.ndarray, tol: Tolerances, opt: SpaceOptions,
    extra_starts: int, deadline: Deadline,
) -> Margin:
    """The multistart of the module docstring, stopped by ``deadline``."""
    starts: list[np.ndarray] = []
    cp_complete: object = None
    cut = deadline.expired()  # some planned start was never made or never run
    if not cut:
        # no segments needed; half the time at most, the rest is for the local searches
        space = find_critical_points(linkage, tol, opt, deadline=deadline.fraction(0.5))
        cp_complete = space.search.complete
        starts += [cp.u for cp in space.critical_points]
        starts += [m.critical_u for m in space.near_misses]
    rng = np.random.default_rng(1234 + opt.seed)
    planned = len(starts) + 2 * extra_starts
    cut = cut or deadline.expired()
    if not cut:
        for u0 in iter_projected_random_starts(linkage, tol, extra_starts, rng, deadline):
            starts.append(refine_critical(cons, u0, tol).u)
            if deadline.expired():
                cut = True
                break
    # Random points off the constraints too: at the given lengths the nearest critical
    # configuration is often a degenerate one (a bar shrunk to a point), whose basin the
    # refined starts share; the local search from a free point moves the lengths as it goes
    # and reaches the critical configurations that exist only at other lengths.
    scale = float(np.median(linkage.lengths[cons.bars]))
    free = ~np.asarray(linkage.fixed, dtype=bool)
    for _ in range(extra_starts):
        pos = np.array(linkage.positions, dtype=float)
        pos[free] += scale * rng.normal(size=int(free.sum()))
        starts.append(linkage.coordinates(pos))
    best: tuple[float, np.ndarray, np.ndarray] | None = None
    converged = run = 0
    for u0 in starts:
        if deadline.expired():
            cut = True
            break
        run += 1
        deadline.report(run / max(planned, 1), "robustness: local searches")
        jac = cons.jacobian(u0, sparse=False)
        s0 = np.linalg.svd(jac)[0][:, -1]
        found = _local(cons, adj, u0, s0, tol, deadline)
        if found is None:
            continue
        converged += 1
        if best is None or found[0] < best[0]:
            best = found
    # the deadline may also have ended the last run part-way (conservatively: incomplete)
    complete = not (cut or deadline.expired())
    detail = f"best local minimum over {converged} converged of {run} starts"
    # no argument: what the answer establishes, and why it is not more (issue 30)
    search = SearchReport({"starts_planned": planned, "starts_run": run,
                           "critical_points_complete": cp_complete},
                          timed_out=not complete, time_budget_s=_granted(deadline),
                          argument_detail=f"an upper bound: the {detail} of the multistart; "
                          "no argument bounds the margin from below (a nearer critical value "
                          "may lie where no start led)")
    nearest = np.array(linkage.lengths, dtype=float)
    if best is None:
        return Margin(np.inf, nearest, linkage.coordinates(), run, 0, False,
                      "no local search converged to a non-degenerate critical configuration",
                      method="multistart", search=search, guarantee_detail=detail)
    nearest[cons.bars] = best[1]
    message = "best over starts" if complete else "best over the starts run before the deadline"
    return Margin(best[0], nearest, best[2], run, converged, True, message,
                  method="multistart", search=search, guarantee_detail=detail)


def _granted(deadline: Deadline | None) -> float | None:
    """``time_budget_s`` for the report, when the search had a deadline."""
    return granted(deadline) if deadline is not None else None
