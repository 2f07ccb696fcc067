"""How the cones of a two-degree-of-freedom configuration space resolve under a length change,
and what that does to the topology; checked by re-meshing the perturbed linkages.

**One cone.** At a critical point with one self-stress ``sigma`` and ``D + 1 = 3`` zero modes,
the perturbed space near the point is the quadric ``(c - dc)^T Q (c - dc) = Delta`` (the conic
of :mod:`.splitting` with one more zero mode; ``Delta = 4 sum sigma_a L_a dL_a`` to first order,
:func:`.splitting.conic_delta`). With ``Q`` indefinite, two eigenvalues share a sign ``s``: the
quadric is a hyperboloid of *one sheet* (an annulus: the cone's two nappes joined by a neck)
where ``sign(Delta) = s``, of *two sheets* (two discs, the nappes parted) where
``sign(Delta) = -s``.

**Topology.** Replacing a cone's neighbourhood (two discs sharing their centre, Euler
characteristic 1) by an annulus (0) or two discs (2) changes the Euler characteristic of the
space by ``2 sheets - 3``: -1 or +1. So the perturbed spaces at ``+dL`` and ``-dL`` (where every
resolved cone has the other number of sheets) differ by::

    chi(+dL) - chi(-dL) = 2 sum_cones (2 sheets(+dL) - 3)

which the answer predicts and then checks by meshing both perturbed linkages
(:func:`engine.space.surfaces.explore.explore_surfaces`).

**Every cone.** The cones are found by homotopy, not only near a mesh: a critical point solves
``f(u) = 0, J(u)^T lambda = 0`` for a nonzero ``lambda``; with a random ``r`` and one more
unknown ``t`` the square system ``f = 0, J^T lambda = t r, a . lambda = 1`` has the critical
points as its solutions with ``t = 0`` (the others are critical points of the height
``r . u``). It is bihomogeneous in ``(u, (lambda, t))`` with the Lagrange system's structure,
so its linear product has ``2^E C(M, E)`` paths (240 for a pentagon).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from engine.design.splitting import conic_delta
from engine.local.critical import CriticalPoint, classify, refine_critical
from engine.model.budget import NEVER, Deadline, granted
from engine.model.constraints import Constraints
from engine.model.linkage import Linkage
from engine.model.report import SearchReport
from engine.model.tolerances import Tolerances
from engine.space.homotopy import REGULAR, SINGULAR, track
from engine.space.linear_product import LinearProduct, Structure, bezout
from engine.space.surfaces.explore import SurfaceOptions, explore_surfaces, require_two_dof
from engine.space.witnesses import FAR_REACH, SINGULAR_IMAG_TOL, _reach, bar_quadrics

#: ``|t|`` (``|r| = 1``) below which an end is a critical-point candidate (a singular end is
#: only within about ``sqrt(T_END)`` of its point: 4e-4 on a pentagon's cone; refinement by
#: Newton then decides).
T_TOL = 1e-2


@dataclass(frozen=True)
class ConeResolution:
    """One cone: ``delta`` (with ``delta_error``), ``sign`` (0: undecided), the number of
    ``sheets`` it resolves into (1 or 2; 0 where undecided or not a cone) and the change of
    the Euler characteristic ``euler_change`` (``2 sheets - 3``)."""

    point: CriticalPoint
    delta: float
    delta_error: float
    sign: int
    sheets: int
    euler_change: int


@dataclass(frozen=True)
class SurfaceSplit:
    """The cones, the predicted ``chi(+dL) - chi(-dL)`` (None where a cone is undecided) and
    the re-meshed Euler characteristics and Betti numbers (over Q, summed over components) at
    ``+dL`` and ``-dL`` with whether the prediction holds; ``complete`` when the cone search's
    homotopy ended and both re-meshings were complete; ``search`` the report (``proved`` when
    complete and verified)."""

    cones: list[ConeResolution]
    predicted_euler_difference: int | None
    euler: tuple[int | None, int | None]
    betti: tuple[tuple[int, int, int] | None, tuple[int, int, int] | None]
    verified: bool
    complete: bool
    message: str
    search: SearchReport


def find_cones(linkage: Linkage, tol: Tolerances, rng: np.random.Generator,
               deadline: Deadline = NEVER) -> tuple[list[CriticalPoint], bool]:
    """Every critical point (module docstring), refined and classified; and whether every path
    of the homotopy ended."""
    cons = Constraints(linkage)
    quad, scale, centre = bar_quadrics(linkage, cons)
    e, m = cons.n_constraints, cons.n_free
    r = rng.normal(size=m)
    r /= np.linalg.norm(r)
    a = rng.normal(size=e)

    def system(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        xu, mu, t = x[:, :m + 1], x[:, m + 1:m + 1 + e], x[:, -1]
        g = np.einsum("amn,pn->pam", quad, xu)  # (N, E, M + 1)
        x0 = x[:, 0]
        f = np.concatenate([np.einsum("pam,pm->pa", g, xu),
                            2 * np.einsum("pa,pam->pm", mu, g[:, :, 1:]) - (t * x0)[:, None] * r,
                            (mu @ a - x0)[:, None]], axis=1)
        jac = np.zeros((len(x), e + m + 1, m + e + 2), dtype=complex)
        jac[:, :e, :m + 1] = 2 * g
        jac[:, e:e + m, :m + 1] = 2 * np.einsum("pa,amn->pmn", mu, quad[:, 1:, :])
        jac[:, e:e + m, 0] -= t[:, None] * r
        jac[:, e:e + m, m + 1:m + 1 + e] = 2 * g[:, :, 1:].transpose(0, 2, 1)
        jac[:, e:e + m, -1] = -x0[:, None] * r
        jac[:, -1, m + 1:m + 1 + e] = a
        jac[:, -1, 0] = -1
        return f, jac

    structure = Structure((np.arange(1, m + 1), np.arange(m + 1, m + e + 2)),
                          np.array([[2, 0]] * e + [[1, 1]] * m + [[0, 1]]))
    total = np.array([2] * (e + m) + [1])
    assert bezout(structure) > 0
    res = track(system, total, rng, deadline, far=FAR_REACH * _reach(linkage, cons, scale),
                start=LinearProduct(structure, total, rng))
    x0 = res.ends[:, 0]
    y = res.ends[:, 1:m + 1] / np.where(np.abs(x0) > 0, x0, np.inf)[:, None]
    t = res.ends[:, -1] / np.where(np.abs(x0) > 0, x0, np.inf)
    ok = np.isin(res.state, (REGULAR, SINGULAR)) & np.isfinite(y).all(axis=1)
    near_real = np.linalg.norm(y.imag, axis=1) <= SINGULAR_IMAG_TOL * np.maximum(
        np.linalg.norm(y, axis=1), 1.0)
    cand = ok & near_real & (np.abs(t) <= T_TOL)
    found: list[CriticalPoint] = []
    same = 1e-6 * float(np.median(linkage.lengths[cons.bars]))
    for u0 in centre + scale * y[cand].real:
        ref = refine_critical(cons, u0, tol)
        if not ref.critical or any(np.linalg.norm(cp.u - ref.u) <= same for cp in found):
            continue
        found.append(CriticalPoint(ref.u, classify(linkage, ref.u, tol), ref.length_residual,
                                   ref.stress_residual))
    # in the order of their coordinates (rounded well above the refinement's error), not of
    # the homotopy's paths: the cones' numbers, which a design names, do not depend on the seed
    key = np.round(np.array([cp.u for cp in found]).reshape(len(found), m) / same, 0)
    order = np.lexsort(key.T[::-1]) if len(found) else np.zeros(0, dtype=np.int64)
    return [found[int(k)] for k in order], res.success


def is_cone(cp: CriticalPoint) -> bool:
    """One self-stress and ``Q`` indefinite on three zero modes: a cone of the surface."""
    q = cp.analysis.q_eigenvalues
    return (cp.analysis.self_stress is not None and q is not None and len(q) == 3
            and bool(q.max() > 0 > q.min()))


def cone_sign(cp: CriticalPoint, sheets: int) -> int:
    """The sign of ``Delta`` that resolves the cone ``cp`` into ``sheets`` (1 or 2) sheets:
    the sign two of ``Q``'s eigenvalues share for one sheet, the other for two."""
    q = cp.analysis.q_eigenvalues
    assert q is not None
    pair = 1 if int((q > 0).sum()) == 2 else -1
    return pair if sheets == 1 else -pair


def resolve_cone(linkage: Linkage, cp: CriticalPoint, d_l: np.ndarray) -> ConeResolution:
    """Sheets and Euler change of one critical point under ``dL`` (module docstring)."""
    if not is_cone(cp):
        return ConeResolution(cp, 0.0, 0.0, 0, 0, 0)
    delta, _, _, error = conic_delta(linkage, cp, d_l)
    sign = int(np.sign(delta)) if abs(delta) > error else 0
    if sign == 0:
        return ConeResolution(cp, delta, error, 0, 0, 0)
    sheets = 1 if sign == cone_sign(cp, 1) else 2
    return ConeResolution(cp, delta, error, sign, sheets, 2 * sheets - 3)


def split_surface(linkage: Linkage, d_l: np.ndarray, tol: Tolerances | None = None,
                  options: SurfaceOptions | None = None, deadline: Deadline = NEVER,
                  seed: int = 0) -> SurfaceSplit:
    """Cones of ``linkage`` (``D = 2``), how each resolves under ``dL`` (E,), the predicted
    ``chi(+dL) - chi(-dL)`` and its check by meshing the linkage at ``L + dL`` and ``L - dL``.
    """
    tol = tol or Tolerances()
    cons = Constraints(linkage)
    require_two_dof(linkage, cons)
    cps, ended = find_cones(linkage, tol, np.random.default_rng(seed), deadline.fraction(0.3))
    return remesh_split(linkage, [cp for cp in cps if is_cone(cp)], ended, d_l, tol, options,
                        deadline)


def remesh_split(linkage: Linkage, cps: list[CriticalPoint], ended: bool, d_l: np.ndarray,
                 tol: Tolerances, options: SurfaceOptions | None = None,
                 deadline: Deadline = NEVER) -> SurfaceSplit:
    """How the cones ``cps`` (found by :func:`find_cones`; ``ended``: every path of its
    homotopy ended) resolve under ``dL``, the predicted ``chi(+dL) - chi(-dL)`` and its check
    by meshing the linkage at ``L + dL`` and ``L - dL`` (:func:`split_surface`)."""
    cones = [resolve_cone(linkage, cp, d_l) for cp in cps]
    decided = all(c.sign != 0 for c in cones)
    predicted = 2 * sum(c.euler_change for c in cones) if decided else None
    eulers: list[int | None] = []
    bettis: list[tuple[int, int, int] | None] = []
    complete = ended
    for k, sign in enumerate((1.0, -1.0)):
        if deadline.expired():
            eulers.append(None)
            bettis.append(None)
            complete = False
            continue
        at = linkage.with_lengths(linkage.lengths + sign * d_l)
        out = explore_surfaces(at, tol, options, deadline=deadline.fraction(0.5 if k == 0
                                                                            else 1.0),
                               start_on_space=False)
        complete &= bool(out.search.complete)
        homs = [c.homology for c in out.components]
        if not homs or any(h is None for h in homs):
            eulers.append(None)
            bettis.append(None)
            continue
        eulers.append(int(sum(h.euler for h in homs if h is not None)))
        b = np.sum([h.betti_q for h in homs if h is not None], axis=0)
        bettis.append((int(b[0]), int(b[1]), int(b[2])))
    verified = (predicted is not None and eulers[0] is not None and eulers[1] is not None
                and eulers[0] - eulers[1] == predicted)
    message = ("the re-meshed Euler characteristics differ as predicted" if verified else
               "a cone's Delta is within its error: no prediction" if predicted is None else
               "the re-meshing did not finish" if None in eulers else
               "the re-meshed Euler characteristics differ from the prediction")
    report = SearchReport(
        {"method": "cone homotopy and re-meshing", "cones": len(cones),
         "cone_homotopy_ended": ended, "verified": verified},
        timed_out=deadline.expired(), unresolved=not verified,
        time_budget_s=granted(deadline),
        argument="proved" if complete and verified else None,
        argument_detail=(f"the {len(cones)} cones found by homotopy (every path ended) resolve "
                         "as predicted: the complete re-meshings at L + dL and L - dL differ in "
                         "Euler characteristic by the predicted amount")
        if complete and verified else None)
    return SurfaceSplit(cones, predicted, (eulers[0], eulers[1]), (bettis[0], bettis[1]),
                        verified, complete, message, report)
