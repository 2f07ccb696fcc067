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

**Betti numbers.** The Euler characteristic follows from the cones alone; the Betti numbers
need the whole space. The critical space is meshed through its cones (each apex a vertex whose
link is two cycles) and each apex is resolved in the complex as its cone resolves: split in two
(two sheets) or its star replaced by a tube between the two cycles (one sheet,
:func:`engine.space.surfaces.cones.resolve_apexes`); the complex's homology is the prediction
at ``L + dL`` (and, with the other number of sheets everywhere, at ``L - dL``), checked by the
re-meshing too.

**Every cone** is found by the homotopy of :func:`engine.space.surfaces.cones.find_cones`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from engine.design.splitting import conic_delta
from engine.local.critical import CriticalPoint
from engine.model.budget import NEVER, Deadline, granted
from engine.model.constraints import Constraints
from engine.model.linkage import Linkage
from engine.model.report import SearchReport
from engine.model.tolerances import Tolerances
from engine.space.surfaces.cones import find_cones, is_cone, resolve_apexes
from engine.space.surfaces.explore import SurfaceOptions, explore_surfaces, require_two_dof
from engine.space.surfaces.homology import Homology, surface_homology


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
    complete and verified); the critical space's Betti numbers and those predicted at ``+dL``
    and ``-dL`` from its mesh (:func:`predict_betti`; None where it is incomplete)."""

    cones: list[ConeResolution]
    predicted_euler_difference: int | None
    euler: tuple[int | None, int | None]
    betti: tuple[tuple[int, int, int] | None, tuple[int, int, int] | None]
    verified: bool
    complete: bool
    message: str
    search: SearchReport
    critical_betti: tuple[int, int, int] | None = None
    predicted_betti: tuple[tuple[int, int, int] | None, tuple[int, int, int] | None] = (None,
                                                                                          None)


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
                        deadline, found=cps)


Betti = tuple[int, int, int]


def _summed(homs: list[Homology | None]) -> tuple[int | None, Betti | None]:
    """Euler characteristic and Betti numbers over Q summed over components (None without
    them)."""
    if not homs or any(h is None for h in homs):
        return None, None
    b = np.sum([h.betti_q for h in homs if h is not None], axis=0)
    return int(sum(h.euler for h in homs if h is not None)), (int(b[0]), int(b[1]), int(b[2]))


def predict_betti(linkage: Linkage, cones: list[ConeResolution],
                  found: tuple[list[CriticalPoint], bool] | None, tol: Tolerances,
                  options: SurfaceOptions | None, deadline: Deadline
                  ) -> tuple[Betti | None, tuple[Betti | None, Betti | None]]:
    """The critical space's Betti numbers over Q, and those predicted at ``L + dL`` and
    ``L - dL``: its surfaces meshed through the cones (complete), each apex resolved as its
    cone resolves (:func:`engine.space.surfaces.cones.resolve_apexes`; the other number of
    sheets at ``L - dL``; ``found``: every critical point the cone search found, cones or not,
    and whether its every path ended, where it ran already). None where the mesh is incomplete
    or a cone undecided."""
    none: tuple[Betti | None, tuple[Betti | None, Betti | None]] = (None, (None, None))
    if not cones or any(c.sign == 0 for c in cones):
        return none
    out = explore_surfaces(linkage, tol, options, deadline=deadline, start_on_space=False,
                           cones=found)
    if not out.search.complete:
        return none
    apex_at = np.array([c.point.u for c in cones])
    sides: list[list[Homology | None]] = [[], []]
    for comp in out.components:
        near = [int(np.argmin(np.linalg.norm(apex_at - comp.vertices[a], axis=1)))
                for a in comp.apexes]
        sheets = np.array([cones[k].sheets for k in near], dtype=np.int64)
        for side, n in enumerate((sheets, 3 - sheets)):
            _, tri = resolve_apexes(comp.vertices, comp.triangles, comp.apexes, n)
            sides[side].append(surface_homology(tri))
    critical = _summed([c.homology for c in out.components])[1]
    return critical, (_summed(sides[0])[1], _summed(sides[1])[1])


def _why_not(ended: bool, complete: bool, verified: bool, message: str) -> str:
    """The sentence of why a surface splitting has no argument (what it did establish)."""
    why = [] if ended else ["the cones' homotopy did not end on every path, so a cone may be "
                            "missing"]
    if ended and not complete:
        why.append("a re-meshing at L + dL or L - dL is incomplete")
    return "no proof: " + "; ".join([*why, message])


def remesh_split(linkage: Linkage, cps: list[CriticalPoint], ended: bool, d_l: np.ndarray,
                 tol: Tolerances, options: SurfaceOptions | None = None,
                 deadline: Deadline = NEVER, found: list[CriticalPoint] | None = None
                 ) -> SurfaceSplit:
    """How the cones ``cps`` (found by :func:`find_cones`; ``ended``: every path of its
    homotopy ended) resolve under ``dL``, the predicted ``chi(+dL) - chi(-dL)`` and Betti
    numbers (:func:`predict_betti`) and their check by meshing the linkage at ``L + dL`` and
    ``L - dL`` (:func:`split_surface`); ``found``: every critical point the search found
    (the cones among them), which the critical space's meshing then need not search again."""
    cones = [resolve_cone(linkage, cp, d_l) for cp in cps]
    decided = all(c.sign != 0 for c in cones)
    predicted = 2 * sum(c.euler_change for c in cones) if decided else None
    critical, predicted_betti = predict_betti(
        linkage, cones, None if found is None else (found, ended), tol, options,
        deadline.fraction(1 / 3))
    eulers: list[int | None] = []
    bettis: list[Betti | None] = []
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
        euler, betti = _summed([c.homology for c in out.components])
        eulers.append(euler)
        bettis.append(betti)
    betti_agrees = None not in predicted_betti and list(predicted_betti) == bettis
    verified = (predicted is not None and eulers[0] is not None and eulers[1] is not None
                and eulers[0] - eulers[1] == predicted
                and (betti_agrees or None in predicted_betti))
    message = ("the re-meshed Euler characteristics differ as predicted" + (
               " and the Betti numbers are those predicted" if betti_agrees else
               " (no Betti numbers predicted: the critical space's mesh is incomplete)")
               if verified else
               "a cone's Delta is within its error: no prediction" if predicted is None else
               "the re-meshing did not finish" if None in eulers else
               "the re-meshed topology differs from the prediction")
    report = SearchReport(
        {"method": "cone homotopy and re-meshing", "cones": len(cones),
         "cone_homotopy_ended": ended, "verified": verified, "betti_verified": betti_agrees},
        timed_out=deadline.expired(), unresolved=not verified,
        time_budget_s=granted(deadline),
        argument="proved" if complete and verified else None,
        argument_detail=(f"the {len(cones)} cones found by homotopy (every path ended) resolve "
                         "as predicted: the complete re-meshings at L + dL and L - dL differ in "
                         "Euler characteristic by the predicted amount" + (
                             ", and their Betti numbers are those of the critical space's mesh "
                             "with each apex resolved" if betti_agrees else ""))
        if complete and verified else _why_not(ended, complete, verified, message))
    return SurfaceSplit(cones, predicted, (eulers[0], eulers[1]), (bettis[0], bettis[1]),
                        verified, complete, message, report, critical, predicted_betti)
