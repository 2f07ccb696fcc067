"""Predictor-corrector tracing of one-degree-of-freedom configuration spaces.

Along a curve ``l(u) = L`` (``M - E = 1``) the unit tangent ``t`` solves ``[t_prev; J] t = e_1``
(normalised): one LU factorisation of ``J`` augmented by the previous tangent gives the tangent
with a continued orientation, and ``det([t_prev; J])`` whose sign flips when the path crosses a
critical point (a branch point passed along a smooth branch: the tangent form ``t(u)`` reverses
there, paper Appendix B). The predictor steps along the cubic through the last two points and
their tangents (:func:`predict`; along ``t`` at the start); the corrector is Newton in a
hyperplane through the predicted point, first reusing the same factorisation (chord Newton)
down to ``residual_atol``, then with the factorisation at the corrected point, which the next
tangent needs anyway, down to ``CORRECT_TIGHT * residual_atol`` (:func:`_attempt`). Steps adapt
so that the predictor's largest bar strain stays below ``strain_tol``, the corrected residual
below ``residual_atol``, and no step exceeds ``step_max``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
import scipy.sparse as sp

from engine.local.critical import refine_critical, singular_gap
from engine.model.budget import NEVER, Deadline
from engine.model.constraints import Constraints
from engine.model.lu import BandLU, BorderedFactor, Factor
from engine.model.tolerances import CORRECT_TIGHT, POLISH_TANGENT_MOVE, Tolerances
from engine.space import trace_kernel
from engine.space.curve import (
    Curve,
    StopCheck,
    TraceOptions,
    _Limits,
    _limits,
    closest_on_segment,
    distances_to_segment,
    polyline_distance,
    predict,
    segment_distance,
    segments_distance,
)

# the curve, its options and its geometry live in engine.space.curve; named here too, where
# the tracer's callers have always found them
__all__ = [
    "Curve", "StopCheck", "TangentInfo", "TraceOptions", "closest_on_segment", "correct",
    "distances_to_segment", "factor_augmented", "polyline_distance", "predict",
    "segment_distance", "segments_distance", "tangent_at", "trace_curve",
]

#: The tracer looks at its deadline every this many passes of its loop.
DEADLINE_EVERY = 16

#: With a ``stop`` check the compiled kernel hands back at most this many points at first, then
#: twice as many each call up to ``STOP_CHUNK_MAX``: the check runs on the points handed back,
#: so a curve it stops early is not traced on to the kernel's buffer (tens of thousands of
#: points) first.
STOP_CHUNK_MIN = 32
STOP_CHUNK_MAX = 4096

#: ``Curve.stop`` of a trace that its deadline ended.
STOP_TIME = "time"

#: A step below this fraction of ``step_max`` has collapsed: the tracer looks for a critical
#: point just ahead (within ten times this) to cross.
STEP_COLLAPSE = 1e-3


#: Above this many free coordinates the augmented matrix is factorised with sparse LU (for LU,
#: unlike SVD, sparse wins early: the Jacobians of chains are banded).
SPARSE_LU_MIN_FREE = 48

#: Band LU of ``[e_k; J]`` while its work per column ``kl (kl + ku)`` stays below this (a chain
#: has kl, ku of about 3); wider bands go to SuperLU.
BAND_MAX_WORK = 256


def augmented(cons: Constraints, u: np.ndarray, row: np.ndarray) -> np.ndarray | sp.spmatrix:
    """``[row; J(u)]``, (M, M) for a one-degree-of-freedom linkage (sparse: CSC)."""
    return cons.bordered_jacobian(u, row, sparse=cons.n_free > SPARSE_LU_MIN_FREE)


def factor_augmented(
    cons: Constraints, u: np.ndarray, row: np.ndarray
) -> Factor | BorderedFactor:
    """LU of ``[row; J(u)]``: dense for small linkages; sparse through ``[e_k; J]`` and a
    rank-one update (:class:`engine.model.lu.BorderedFactor`: the dense row would fill a direct
    sparse
    LU), ``[e_k; J]`` factorised as a band matrix when a fixed reordering makes it narrow
    (chains) and by SuperLU otherwise; the direct sparse LU if ``[e_k; J]`` is singular."""
    if cons.n_free <= SPARSE_LU_MIN_FREE:
        return Factor(augmented(cons, u, row))
    k = int(np.argmax(np.abs(row)))
    band = cons.unit_bordered_band(u, k, BAND_MAX_WORK)
    base = BandLU(*band) if band is not None else Factor(cons.unit_bordered_jacobian(u, k))
    fac = BorderedFactor(base, k, row)
    return fac if fac.ok else Factor(augmented(cons, u, row))


@dataclass(frozen=True)
class TangentInfo:
    """Unit tangent at ``u`` oriented along ``t_prev``, and ``det([t_prev; J])``."""

    tangent: np.ndarray
    sign: int
    logdet: float
    factor: Factor | BorderedFactor


def tangent_at(cons: Constraints, u: np.ndarray, t_prev: np.ndarray) -> TangentInfo | None:
    """Tangent continued from ``t_prev``; None where ``[t_prev; J]`` is singular (at a
    critical point, or with ``t_prev`` orthogonal to the curve)."""
    fac = factor_augmented(cons, u, t_prev)
    if not fac.ok:
        return None
    y = fac.solve_first()
    norm = float(np.linalg.norm(y))
    if not np.isfinite(norm) or norm == 0.0:
        return None
    return TangentInfo(y / norm, fac.sign, fac.logdet, fac)


def correct(
    cons: Constraints,
    v: np.ndarray,
    t: np.ndarray,
    tol: Tolerances,
    factor: Factor | BorderedFactor | None = None,
    max_iter: int = 12,
    tight: bool = True,
) -> tuple[np.ndarray, bool, int]:
    """Newton in the hyperplane ``{w : t.(w - v) = 0}`` onto ``l(w) = L``.

    Solves ``[t; J] dw = [0; -(l^2 - L^2)]``; with ``factor`` (of ``[r; J]`` at a nearby
    point, ``r`` close to ``t``: the iterates then stay in the hyperplane orthogonal to ``r``)
    the iteration is chord Newton (no refactorisation), otherwise it refactors at ``v`` once.
    Returns the point (converged to ``CORRECT_TIGHT * residual_atol`` where rounding allows;
    with ``tight=False`` only to ``residual_atol``: the tracer's step then polishes it with
    the factorisation at the point that it makes for the tangent anyway, see
    :func:`_attempt`), whether ``max|l - L| <= residual_atol``, and the iterations that
    reached ``residual_atol`` (what the step control looks at).
    """
    fac = factor if factor is not None else factor_augmented(cons, v, t)
    if not fac.ok:
        return v, False, 0
    w = v.copy()
    prev = np.inf
    lengths = cons.linkage.lengths[cons.bars]
    goal = CORRECT_TIGHT * tol.residual_atol if tight else tol.residual_atol
    within: int | None = None  # the iterations that reached residual_atol (the step control's)
    for it in range(1, max_iter + 1):
        sq = cons.squared_lengths(w)  # once per iteration: both the residual and g use it
        g = sq - cons.targets
        res = float(np.max(np.abs(np.sqrt(sq) - lengths))) if sq.size else 0.0
        if within is None and res <= tol.residual_atol:
            within = it - 1
        if res <= goal:
            return w, True, it - 1 if within is None else within
        norm = float(np.linalg.norm(g))
        if norm > 0.7 * prev:  # not contracting: within residual_atol (the rounding floor of
            # large coordinates) the point stands, else the caller shrinks the step
            return w, res <= tol.residual_atol, it if within is None else within
        prev = norm
        w = w + fac.solve(np.concatenate([[0.0], -g]))
    return w, cons.max_residual(w) <= tol.residual_atol, max_iter if within is None else within


class _Step(NamedTuple):
    """An accepted step: the new point, its tangent information, the corrector's iterations,
    and the critical point crossed on the way (None for a regular step)."""

    w: np.ndarray
    info: TangentInfo
    iters: int
    crossed: np.ndarray | None = None


#: What a step attempt gives: a step, SHRINK (halve the step and try again) or a reason to stop.
SHRINK = "shrink"


def trace_curve(
    cons: Constraints,
    u0: np.ndarray,
    t0: np.ndarray,
    tol: Tolerances,
    options: TraceOptions,
    stop: StopCheck | None = None,
    close: bool = True,
    min_arc_to_close: float | None = None,
    deadline: Deadline = NEVER,
) -> Curve:
    """Trace from ``u0`` (on the constraints) in direction ``t0`` until the curve closes,
    ``stop`` says so, the budget runs out, the step underflows, or ``deadline`` expires
    (``stop = "time"``).

    The step is halved when the predictor's strain exceeds ``strain_tol``, the corrector
    fails, or the tangent turns by more than ``max_turn``; it grows by 1.5 after easy steps.
    Critical points on the way are crossed along the incoming tangent (:func:`_attempt`,
    :func:`_cross_ahead`).
    """
    lim = _limits(cons, u0, options)
    curve = Curve()
    info = tangent_at(cons, u0, t0 / np.linalg.norm(t0))
    if info is None:
        curve.append(u0, t0 / np.linalg.norm(t0), 0, -np.inf)
        curve.stop = "singular start"
        return curve
    u, t, sign, fac = u0, info.tangent, info.sign, info.factor
    t_in = t0 / np.linalg.norm(t0)  # the row of ``fac``: the tangent before ``u``
    # the point before ``u`` on the curve (its tangent is ``t_in``): the predictor's cubic
    # (:func:`predict`); None at the start, after a crossing and after a failed attempt from
    # ``u`` (the tangent predicts)
    u_prev: np.ndarray | None = None
    curve.append(u, t, info.sign, info.logdet)
    h, arc, budget = 0.25 * lim.h_max, 0.0, lim.passes
    close_after = 4 * lim.h_max if min_arc_to_close is None else min_arc_to_close
    tried_at_u = False  # whether a collapsed step looked for a critical point ahead of u
    compiled = trace_kernel.enabled()
    # a deadline that can never expire is never looked at (no hand-back every 16 passes)
    watch = deadline.at != float("inf") or deadline.stop is not None
    chunk = STOP_CHUNK_MIN
    while len(curve.points) < options.max_points:
        if compiled:
            # the regular passes in compiled code; it hands back the pass it cannot finish
            # as this loop would (then run below) or a due deadline check
            adv, chunk = _compiled_passes(
                cons, curve, u, t, t_in, u_prev, sign, h, arc, budget, tried_at_u, u0=u0,
                close=close, close_after=close_after, lim=lim, options=options, tol=tol,
                stop=stop, deadline=deadline, watch=watch, chunk=chunk)
            if adv is None:
                return curve
            u, t, t_in, sign, u_prev = adv.u, adv.t, adv.t_in, adv.sign, adv.u_prev
            h, arc, budget, tried_at_u = adv.h, adv.arc, adv.budget, adv.tried
            if adv.event == trace_kernel.EV_FULL:
                continue
            fac = factor_augmented(cons, u, t_in)
        budget -= 1
        ended = _ended(budget, h, lim, deadline)
        if ended is not None:
            curve.stop = ended
            return curve
        step: _Step | str | None = None
        if h < STEP_COLLAPSE * lim.h_max and not tried_at_u and cons.n_free <= 600:
            tried_at_u = True
            step = _cross_ahead(cons, u, t, tol, lim.h_max, options.max_turn, lim.h_cross, deadline)
        if step is None:
            step = _attempt(cons, u, t, h, fac, sign, tol, options, lim, u_prev, t_in)
        if step == SHRINK or (isinstance(step, _Step)
                              and np.linalg.norm(step.w - u) > lim.h_max):
            h *= 0.5
            # the cubic predicts once from a point: where its step failed the tangent does
            # (near critical points the tangent turns within a step, and the cubic's
            # curvature, taken from the last step, would only lead the next ones astray)
            u_prev = None
            continue
        if isinstance(step, str):
            curve.stop = step
            return curve
        u_prev = u
        if step.crossed is not None:  # keep the critical point, with the incoming tangent
            _append_crossing(curve, step.crossed, t, step.info.sign)
            u_prev = None
            arc += float(np.linalg.norm(step.crossed - u))
            u = step.crossed
            h = float(np.linalg.norm(step.w - u))
        w, nxt = step.w, step.info
        arc += float(np.linalg.norm(w - u))
        curve.append(w, nxt.tangent, nxt.sign, nxt.logdet)
        reason = stop(u, w, nxt.tangent) if stop is not None else None
        if reason is None and close and arc > close_after and \
                _closes(cons, u, w, nxt.tangent, u0, tol, lim):
            reason = "closed"
        if reason is not None:
            curve.stop = reason
            return curve
        u, t_in, t, fac, sign = w, t, nxt.tangent, nxt.factor, nxt.sign
        tried_at_u = False
        h = min(lim.h_max, h * (1.5 if step.iters <= 3 else 1.0))
    curve.stop = "max points"
    return curve


def _ended(budget: int, h: float, lim: _Limits, deadline: Deadline) -> str | None:
    """Why :func:`trace_curve`'s loop stops before a pass (``budget``: the passes left after
    it), or None: the pass budget spent, the deadline (looked at every
    :data:`DEADLINE_EVERY` passes), the step ``h`` below the smallest."""
    return ("step budget" if budget < 0
            else STOP_TIME if budget % DEADLINE_EVERY == 0 and deadline.expired()
            else "step underflow" if h < lim.h_min else None)


def _closes(cons: Constraints, u: np.ndarray, w: np.ndarray, t: np.ndarray, u0: np.ndarray,
            tol: Tolerances, lim: _Limits) -> bool:
    """The step from ``u`` to ``w`` (tangent ``t`` at ``w``) passes by the start ``u0`` and
    the curve really goes through it (:func:`_lands_on`): the curve has closed."""
    return segment_distance(u, w, u0) <= 0.5 * lim.h_max and \
        _lands_on(cons, u, w, t, u0, tol, 1e-5 * lim.h_max)


def _compiled_passes(
    cons: Constraints, curve: Curve, u: np.ndarray, t: np.ndarray, t_in: np.ndarray,
    u_prev: np.ndarray | None, sign: int, h: float, arc: float, budget: int, tried_at_u: bool,
    *, u0: np.ndarray, close: bool, close_after: float, lim: _Limits, options: TraceOptions,
    tol: Tolerances, stop: StopCheck | None, deadline: Deadline, watch: bool, chunk: int,
) -> tuple[trace_kernel.Advance | None, int]:
    """:func:`trace_curve`'s regular passes from the state ``(u, t, t_in, u_prev, sign, h, arc,
    budget, tried_at_u)`` in compiled code (:func:`engine.space.trace_kernel.advance`), its
    points added to ``curve``, its deadline checks made, until it hands back a pass it cannot
    finish as the Python loop would or its buffer is full: the kernel's last answer (the state
    after it, and why it returned) and the next chunk of a stop check, or None when the trace
    has ended (``curve.stop`` says why: the stop check or the deadline)."""
    checked = -1
    while True:
        room = options.max_points - len(curve.points)
        if stop is not None:
            room, chunk = min(room, chunk), min(2 * chunk, STOP_CHUNK_MAX)
        adv = trace_kernel.advance(
            cons, cons.n_free <= SPARSE_LU_MIN_FREE, u, t, t_in, sign, h, arc, budget,
            tried_at_u, room, u_prev=u_prev, u0=u0, close=close,
            close_after=close_after, h_max=lim.h_max, h_min=lim.h_min,
            collapse=STEP_COLLAPSE * lim.h_max, strain_tol=options.strain_tol,
            residual_atol=tol.residual_atol, cos_turn=float(np.cos(options.max_turn)),
            h_cross=lim.h_cross, band_max_work=BAND_MAX_WORK,
            deadline_every=DEADLINE_EVERY if watch else 0, checked=checked,
            cross_ahead=cons.n_free <= 600)
        if stop is None:
            curve.extend(adv.points, adv.tangents, adv.signs, adv.logdets)
        else:  # the stop check on every committed point, as in trace_curve's loop
            prev = u
            for k in range(len(adv.points)):
                w = adv.points[k]
                curve.append(w, adv.tangents[k], int(adv.signs[k]),
                             float(adv.logdets[k]))
                reason = stop(prev, w, adv.tangents[k])
                if reason is not None:
                    curve.stop = reason
                    return None, chunk
                prev = w
        u, t, t_in, sign, u_prev = adv.u, adv.t, adv.t_in, adv.sign, adv.u_prev
        h, arc, budget, tried_at_u = adv.h, adv.arc, adv.budget, adv.tried
        if adv.event != trace_kernel.EV_DEADLINE:
            return adv, chunk
        if deadline.expired():
            curve.stop = STOP_TIME
            return None, chunk
        checked = budget - 1


def _attempt(
    cons: Constraints, u: np.ndarray, t: np.ndarray, h: float,
    fac: Factor | BorderedFactor, sign: int, tol: Tolerances, options: TraceOptions,
    lim: _Limits, u_prev: np.ndarray | None = None, t_prev: np.ndarray | None = None,
) -> _Step | str:
    """One predictor-corrector step of size ``h`` from ``u`` along ``t``: the step,
    :data:`SHRINK`, or a reason to stop.

    The predictor is :func:`predict` (the cubic through ``u_prev``, ``u`` with their
    tangents ``t_prev``, ``t`` when ``u_prev`` is given). The chord corrector (the
    factorisation ``fac`` at ``u``) runs only until the residual is within ``residual_atol``
    (what the step control counts); the factorisation of ``[t; J(w)]`` at the corrected point
    ``w``, made for the tangent anyway, then polishes ``w`` to ``CORRECT_TIGHT *
    residual_atol`` by Newton (quadratic: one step from ``residual_atol``, where the chord's
    linear rate took about two; it iterates on if one step does not reach it, so the accuracy
    is the chord's run to the end). The point's tangent, sign and ``log|det|`` are those of
    that factorisation at ``w`` while the polish moved the point by at most
    :data:`~engine.model.tolerances.POLISH_TANGENT_MOVE` of the step (it moves it by
    ``~residual_atol / s``, ``s`` the Jacobian's smallest singular value: the tangent is then
    off by about that fraction of the step's own turn, far below any test made on it), else
    (near critical lengths, where ``s`` is small and the tangent turns fast) those of a
    factorisation at the polished point.

    A sign change of ``det([t; J])`` between neighbours means the corrector landed on another
    branch (near a split branch point the arcs are ``~sqrt(dL)`` apart), or the step crosses a
    true critical point: the step shrinks until it is tiny; then the crossing is accepted only
    at a truly critical point (exact branch points at critical lengths), else the trace stops
    open (the search is then incomplete)."""
    lengths = cons.linkage.lengths[cons.bars]
    v = predict(u, t, h, u_prev, t if t_prev is None else t_prev)
    strain = float(np.max(np.abs(np.sqrt(cons.squared_lengths(v)) - lengths) / lengths))
    if strain > options.strain_tol:
        return SHRINK
    w, ok, iters = correct(cons, v, t, tol, factor=fac, tight=False)
    if not ok:
        w, ok, iters = correct(cons, v, t, tol, tight=False)
    if not ok or np.linalg.norm(w - v) > 0.5 * h:
        return SHRINK
    at_w = tangent_at(cons, w, t)
    if at_w is None:
        return SHRINK
    polished, ok, _ = correct(cons, w, t, tol, factor=at_w.factor)  # Newton at w
    if not ok:
        return SHRINK
    if np.linalg.norm(polished - w) > POLISH_TANGENT_MOVE * h:  # near critical lengths
        at_w = tangent_at(cons, polished, t)
        if at_w is None:
            return SHRINK
    w = polished
    if at_w.tangent @ t < np.cos(options.max_turn):
        return SHRINK
    if at_w.sign == sign or sign == 0:
        return _Step(w, at_w, iters)
    if h > lim.h_cross:
        return SHRINK
    # (no dense SVD for large linkages: their crossings are accepted as critical)
    if cons.n_free <= 600 and singular_gap(cons, w) > 1e-5:
        return "unresolved near-critical point"
    # ``w`` sits on the critical point, where the tangent of ``[t; J]`` is any vector of the
    # two-dimensional kernel: keep it with the incoming tangent and jump clear of it along
    # that tangent (see ``_jump``).
    past = _jump(cons, w, t, tol, lim.h_max, options.max_turn, lim.h_cross)
    if past is None:
        return "unresolved branch crossing"
    return _Step(past[0], past[1], 0, crossed=w)


def _append_crossing(curve: Curve, c: np.ndarray, t: np.ndarray, sign: int) -> None:
    """Record the critical point ``c`` crossed with tangent ``t``: the determinant vanishes
    there (``log|det| = -inf``), and ``sign`` is the one beyond it."""
    curve.append(c, t, sign, -np.inf)


def _cross_ahead(
    cons: Constraints,
    u: np.ndarray,
    t: np.ndarray,
    tol: Tolerances,
    h_max: float,
    max_turn: float,
    h_min: float,
    deadline: Deadline = NEVER,
) -> _Step | None:
    """After the step collapsed: the critical point just ahead of ``u`` (within
    ``10 STEP_COLLAPSE h_max``, in the direction of ``t``) crossed to the point beyond it on
    the same branch, or None (no critical point there: a near miss, which the tracer passes
    with small steps; or ``deadline`` has passed: the refinement is dense, O(M^3)).

    Near an exact branch point the corrector's own residual acts as a length perturbation of
    ``~residual_atol``, which splits the crossing into a tiny hyperbola
    (``~sqrt(residual_atol L)`` across) whose arc turns onto the other branch in steps that
    each pass the turn test: locating the critical point and jumping across it keeps the
    branch."""
    if deadline.expired():
        return None
    ref = refine_critical(cons, u, tol)
    ahead = ref.u - u
    dist = float(np.linalg.norm(ahead))
    if not ref.critical or dist > 10 * STEP_COLLAPSE * h_max or ahead @ t < 0.5 * dist:
        return None
    past = _jump(cons, ref.u, t, tol, h_max, max_turn, h_min)
    return None if past is None else _Step(past[0], past[1], 0, crossed=ref.u)


def _jump(
    cons: Constraints,
    w: np.ndarray,
    t: np.ndarray,
    tol: Tolerances,
    h_max: float,
    max_turn: float,
    h_min: float,
) -> tuple[np.ndarray, TangentInfo] | None:
    """Continue the branch arriving at the critical point ``w`` with tangent ``t``: the point
    beyond it (and its tangent) where a hyperplane correction from ``w + H t`` lands, with the
    largest ``H <= h_max / 4`` that keeps the landing within ``H / 2`` of the prediction and the
    new tangent within ``max_turn`` of ``t``; None when no step down to ``h_min`` does.

    At a step ``H`` from a branch point the other branch (crossing at an angle ``a``) is about
    ``H sin a`` from the predicted point, the own branch only ``O(H^2)`` (its curvature), so the
    correction stays on the branch it arrived on for every step below ``~ sin a`` times the
    curvature radius."""
    step = 0.25 * h_max
    while step >= h_min:
        v = w + step * t
        land, ok, _ = correct(cons, v, t, tol)
        if ok and np.linalg.norm(land - v) <= 0.5 * step:
            nxt = tangent_at(cons, land, t)
            if nxt is not None and nxt.tangent @ t >= np.cos(max_turn):
                return land, nxt
        step *= 0.5
    return None


def _lands_on(
    cons: Constraints,
    a: np.ndarray,
    b: np.ndarray,
    t: np.ndarray,
    target: np.ndarray,
    tol: Tolerances,
    radius: float,
) -> bool:
    """True when the curve through the segment ``[a, b]`` (tangent ``t``) really passes through
    ``target``: correcting from the segment's closest point, in the hyperplane through
    ``target`` orthogonal to ``t``, lands on ``target``. Near a split branch point another arc
    can pass close by; the correction then lands on that arc instead."""
    p = closest_on_segment(a, b, target)
    w, ok, _ = correct(cons, p + ((target - p) @ t) * t, t, tol)
    return ok and float(np.linalg.norm(w - target)) <= radius
