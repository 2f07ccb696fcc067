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

**Every cone** is found by one homotopy along ``L + w dL`` with the heights' critical points
at ``w = +-1`` (:func:`engine.design.surface_homotopy.line_witnesses`) where its paths are
within ``homotopy_paths_max``; otherwise by :func:`engine.design.surface_critical.
critical_search`: a five-bar chain's cones are derived from the critical points of
``|A - C|^2`` on its band's edge (24 paths; the re-meshings at ``L +- dL`` are then seeded by
the chain's argument too, and the answer is ``derived``), any other linkage's by the cone
homotopy within the bound (over it none runs, and the answer says so).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from engine.design.splitting import conic_delta
from engine.design.surface_critical import CriticalSearch, critical_search
from engine.design.surface_homotopy import line_witnesses
from engine.local.critical import CriticalPoint
from engine.model.budget import NEVER, Deadline, granted
from engine.model.constraints import Constraints
from engine.model.linkage import Linkage
from engine.model.report import SearchReport
from engine.model.tolerances import Tolerances
from engine.space.linear_product import bezout
from engine.space.surfaces.cones import cone_structure, is_cone, resolve_apexes
from engine.space.surfaces.explore import (
    SurfaceOptions,
    SurfaceResult,
    explore_surfaces,
    require_two_dof,
    search_height,
)
from engine.space.surfaces.geometry import Surface
from engine.space.surfaces.homology import Homology, surface_homology
from engine.space.surfaces.mesh import Mesh
from engine.space.surfaces.morse import HeightWitnesses
from engine.space.surfaces.transport import transport

#: Share of the deadline the homotopy of the cones and the heights may use (the rest meshes).
LINE_SHARE = 0.4


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
    rng = np.random.default_rng(seed)
    if not one_homotopy(cons, options):
        got = critical_search(linkage, tol, (options or SurfaceOptions()).homotopy_paths_max,
                              rng, deadline.fraction(0.3))
        return remesh_split(linkage, [cp for cp in got.found if is_cone(cp)], got.ended, d_l,
                            tol, options, deadline, found=got.found, how=got)
    line = line_witnesses(linkage, d_l, tol, rng, deadline.fraction(LINE_SHARE),
                          height=search_height(cons.n_free, options))
    return remesh_split(linkage, [cp for cp in line.cones if is_cone(cp)], line.ended, d_l,
                        tol, options, deadline, found=line.cones,
                        witnesses={w: (line.height, h) for w, h in line.heights.items()})


def one_homotopy(cons: Constraints, options: SurfaceOptions | None) -> bool:
    """Whether the cones at ``L`` and the heights' critical points at ``L +- dL`` come from one
    homotopy (:func:`engine.design.surface_homotopy.line_witnesses`): where the options let
    the surfaces' homotopy run its ``2^E C(M, E)`` paths."""
    structure, _ = cone_structure(cons.n_constraints, cons.n_free)
    return bezout(structure) <= (options or SurfaceOptions()).homotopy_paths_max


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
                  options: SurfaceOptions | None, deadline: Deadline,
                  how: CriticalSearch | None = None
                  ) -> tuple[Betti | None, tuple[Betti | None, Betti | None]]:
    """The critical space's Betti numbers over Q, and those predicted at ``L + dL`` and
    ``L - dL``: its surfaces meshed through the cones (complete), each apex resolved as its
    cone resolves (:func:`engine.space.surfaces.cones.resolve_apexes`; the other number of
    sheets at ``L - dL``; ``found``: every critical point the cone search found, cones or not,
    and whether its every path ended, where it ran already; ``how``: that search, whose
    five-bar chain's seeds then seed the mesh). None where the mesh is incomplete or a cone
    undecided."""
    none: tuple[Betti | None, tuple[Betti | None, Betti | None]] = (None, (None, None))
    if not cones or any(c.sign == 0 for c in cones):
        return none
    out = explore_surfaces(linkage, tol, options, deadline=deadline, start_on_space=False,
                           cones=found, chain=None if how is None else how.chain)
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


def _remesh_sides(linkage: Linkage, d_l: np.ndarray, tol: Tolerances,
                  options: SurfaceOptions | None, deadline: Deadline, smooth: bool,
                  witnesses: dict[float, tuple[np.ndarray, HeightWitnesses]]
                  ) -> tuple[list[int | None], list[Betti | None], bool, bool]:
    """The Euler characteristics and Betti numbers of the complete meshes at ``L + dL`` and
    ``L - dL`` (None where incomplete or out of time), whether both are complete, and whether
    ``L - dL``'s meshes were moved from ``L + dL``'s. With no cone at ``L`` (``smooth``) the
    two spaces are alike, and ``L + dL``'s closed meshes are moved onto ``L - dL``
    (:func:`engine.space.surfaces.transport.transport`) instead of marching anew: the answer
    at ``L - dL`` judges them (its own height homotopy, fold, tangent and Morse checks), and
    where they fail it marches. ``witnesses``: the heights' critical points by side (``1.0``,
    ``-1.0``) where they are known."""
    eulers: list[int | None] = []
    bettis: list[Betti | None] = []
    complete, moved = True, False
    given: list[Mesh] | None = None
    for k, sign in enumerate((1.0, -1.0)):
        if deadline.expired():
            eulers.append(None)
            bettis.append(None)
            complete = False
            continue
        at = linkage.with_lengths(linkage.lengths + sign * d_l)
        dl = deadline.fraction(0.5 if k == 0 else 1.0)
        out = explore_surfaces(at, tol, options, deadline=dl, start_on_space=False,
                               meshes=given, witnesses=witnesses.get(sign))
        if given is not None and not out.search.complete and not dl.expired():
            out = explore_surfaces(at, tol, options, deadline=dl, start_on_space=False,
                                   witnesses=witnesses.get(sign))
        elif given is not None:
            moved = bool(out.search.complete)
        if k == 0 and smooth and out.search.complete:
            given = _moved(at.with_lengths(linkage.lengths - d_l), out, tol)
        complete &= bool(out.search.complete)
        euler, betti = _summed([c.homology for c in out.components])
        eulers.append(euler)
        bettis.append(betti)
    return eulers, bettis, complete, moved


def _moved(at: Linkage, out: SurfaceResult, tol: Tolerances) -> list[Mesh] | None:
    """``out``'s closed meshes (no apexes) moved onto ``at``'s surface; None where one cannot
    be."""
    surface = Surface(at, Constraints(at), tol.residual_atol)
    step = float(out.search["step"])
    moved = [transport(surface, c.vertices, c.triangles, step) for c in out.components
             if c.closed and not len(c.apexes)]
    if len(moved) != len(out.components) or any(m is None for m in moved):
        return None
    return [m for m in moved if m is not None]


def _why_not(ended: bool, complete: bool, verified: bool, message: str,
             how: CriticalSearch | None = None) -> str:
    """The sentence of why a surface splitting has no argument (what it did establish);
    ``how``: the critical-point search where it was not the cones' homotopy along the line."""
    search = how.message if how is not None and how.message else \
        "the cones' homotopy did not end on every path"
    why = [] if ended else [f"{search}, so a cone may be missing"]
    if ended and not complete:
        why.append("a re-meshing at L + dL or L - dL is incomplete")
    return "no proof: " + "; ".join([*why, message])


def _found_by(how: CriticalSearch | None, n: int) -> str:
    """How the ``n`` cones were found, in the words of the answer's argument."""
    cones = "the cone" if n == 1 else f"the {n} cones"
    if how is not None and how.argument == "derived":
        return (f"{cones}, derived as every critical point of the linkage by the "
                f"five-bar chain's argument ({how.detail}),")
    return f"{cones} found by homotopy (every path ended)"


def remesh_split(linkage: Linkage, cps: list[CriticalPoint], ended: bool, d_l: np.ndarray,
                 tol: Tolerances, options: SurfaceOptions | None = None,
                 deadline: Deadline = NEVER, found: list[CriticalPoint] | None = None,
                 witnesses: dict[float, tuple[np.ndarray, HeightWitnesses]] | None = None,
                 how: CriticalSearch | None = None) -> SurfaceSplit:
    """How the cones ``cps`` (found by a homotopy or ``how``,
    :func:`engine.design.surface_critical.critical_search`; ``ended``: its argument holds, every
    critical point found) resolve under ``dL``, the predicted ``chi(+dL) - chi(-dL)`` and Betti
    numbers (:func:`predict_betti`) and their check by meshing the linkage at ``L + dL`` and
    ``L - dL`` (:func:`split_surface`); ``found``: every critical point the search found
    (the cones among them), which the critical space's meshing then need not search again;
    ``witnesses``: the height and its critical points at ``L + w dL`` for ``w = +-1``
    (:func:`engine.design.surface_homotopy.line_witnesses`), which the re-meshings then need
    not solve for; the answer's argument is ``how``'s (``derived`` for a five-bar chain),
    else ``proved``."""
    cones = [resolve_cone(linkage, cp, d_l) for cp in cps]
    decided = all(c.sign != 0 for c in cones)
    predicted = 2 * sum(c.euler_change for c in cones) if decided else None
    critical, predicted_betti = predict_betti(
        linkage, cones, None if found is None else (found, ended), tol, options,
        deadline.fraction(1 / 3), how)
    eulers, bettis, complete, moved = _remesh_sides(linkage, d_l, tol, options, deadline,
                                                     not cps, witnesses or {})
    complete &= ended
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
        {"method": f"{how.method if how else 'cone homotopy'} and re-meshing",
         "cones": len(cones), "cone_homotopy_ended": ended,
         "cone_search_paths": how.paths if how else None, "verified": verified,
         "betti_verified": betti_agrees, "minus_side_mesh": "moved" if moved else "marched"},
        timed_out=deadline.expired(), unresolved=not verified,
        time_budget_s=granted(deadline),
        argument=(how.argument if how else "proved") if complete and verified else None,
        argument_detail=(f"{_found_by(how, len(cones))} "
                         f"{'resolves' if len(cones) == 1 else 'resolve'} as predicted: the "
                         "complete re-meshings at L + dL and L - dL differ in Euler "
                         "characteristic by the predicted amount" + (
                             " (L - dL's meshes moved from L + dL's and checked as marched "
                             "ones: folds, tangent planes, the Morse count of its own height "
                             "homotopy)" if moved else "") + (
                             ", and their Betti numbers are those of the critical space's mesh "
                             "with each apex resolved" if betti_agrees else ""))
        if complete and verified else _why_not(ended, complete, verified, message, how))
    return SurfaceSplit(cones, predicted, (eulers[0], eulers[1]), (bettis[0], bettis[1]),
                        verified, complete, message, report, critical, predicted_betti)
