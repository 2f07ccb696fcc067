"""The whole configuration space of a two-degree-of-freedom linkage (``M - E = 2``, something
fixed): every compact component as a triangulated surface with its topology.

1. **Seeds**: the critical points of a generic height ``c . u`` (:mod:`.morse`: the Lagrange
   system's real solutions, all of them found by homotopy when its paths -- ``2^E C(M, E)``
   from the linear-product start, else ``2^(M + E)`` from the total degree's -- are within
   ``homotopy_paths_max``: then every compact component holds one), the given
   configuration and projected random starts. Where the homotopy exceeds its bound or fails,
   a five-bar chain (planar, or spherical with ``4,608`` paths) is seeded by the derived
   argument of :mod:`.five_bar` (24 paths over its crank angles), which also gives every
   critical point of the linkage.
2. **Meshes**: from every seed that no mesh covers yet, march a triangulation
   (:mod:`.mesh`), within the triangle budget and the deadline.
3. **Topology** per component (:mod:`.homology`): Euler characteristic, orientability, Betti
   numbers over Z/2 and Q, the genus of a closed surface; the manifold checks (every edge in two
   triangles, every vertex link a cycle) and the geometric ones (every triangle positive in its
   vertices' tangent frames, its plane within ``TANGENT_ANGLE_MAX`` of theirs).
4. **Morse check**: the critical points of the height (the homotopy's, else the PL critical
   vertices of the meshes refined by Newton) with their indices; on each component their
   alternating sum must equal the Euler characteristic.
5. **Critical points of the linkage** (rank-deficient ``J``): refined from the mesh vertices
   where ``J`` is nearest to losing rank, classified to second order (``Q`` on the three zero
   modes: its signature says cone or isolated point). Where the meshes come near one, every
   critical point is found by the cone homotopy (:func:`.cones.find_cones`) and the components
   through the cones are meshed again from fans around their apexes (:mod:`.cones`), which
   become mesh vertices (``apexes``) whose links are two cycles; the Morse check adds each
   apex's term (:func:`.cones.cone_morse_term`). A critical point that is no cone (an isolated
   point, two self-stresses) or a cone not meshed through leaves the answer incomplete
   (``degenerate``).

The answer is complete only when every mesh closed as a 2-manifold (but at its apexes), passed
the geometric and Morse checks, every critical point of the linkage is a cone it passes through
(found by a cone homotopy whose every path ended), and the homotopy proved the seeds
(``argument = "proved"``) or the five-bar chain's argument derived them (``"derived"``);
otherwise ``search.reason`` says what is missing.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from engine.local.critical import CriticalPoint, classify, refine_critical
from engine.model.budget import NEVER, Deadline, granted
from engine.model.constraints import Constraints
from engine.model.linkage import Linkage
from engine.model.report import SearchReport
from engine.model.tolerances import SAME_POINT_REL, Tolerances
from engine.space.surfaces.cones import cone_fans, cone_morse_term, find_cones, is_cone
from engine.space.surfaces.five_bar import ChainSeeds, chain_seeds, five_bar_chain
from engine.space.surfaces.geometry import Surface, finer_step, require_two_dof
from engine.space.surfaces.homology import (
    Homology,
    manifold_defects,
    surface_homology,
)
from engine.space.surfaces.mesh import Mesh, components, geometry_checks, march
from engine.space.surfaces.morse import (
    HeightCritical,
    HeightWitnesses,
    assign,
    classify_points,
    generic_height,
    height_witnesses,
    pl_critical_vertices,
    ring,
)
from engine.space.witnesses import PATHS_MAX

#: Largest angle (radians) between a mesh edge and the tangent planes at its ends: it grows as
#: the step times the surface's curvature (the equilateral pentagon: 36 degrees at
#: ``step_rel = 0.25``); beyond it the mesh cuts across the surface (a thin part, a tight
#: bend), and the component is meshed again with a shorter step.
TANGENT_ANGLE_MAX = np.deg2rad(45.0)
#: Times a component is meshed again at most.
REMESH_MAX = 2
#: Mesh vertices where ``s_min / s_max`` of ``J`` is below this are refined as possible
#: critical points of the linkage.
NEAR_CRITICAL_GAP = 0.02
#: At most this many such vertices are refined (the smallest gaps first).
NEAR_CRITICAL_MAX = 8


@dataclass(frozen=True)
class SurfaceOptions:
    """Controls of the surface search (every cost is bounded by these and the deadline)."""

    #: Edge length of the triangles, relative to the median bar length.
    step_rel: float = 0.25
    #: Budget of triangles over all components.
    max_triangles: int = 20_000
    #: Projected random starts (seeds besides the height's critical points).
    random_starts: int = 12
    #: Largest path count of the homotopy (the linear product's ``2^E C(M, E)``, 240 for a
    #: pentagon with one bar pinned; the total degree's ``2^(M + E)``, 1024, is the fallback
    #: where it fits); 0 skips it.
    homotopy_paths_max: int = PATHS_MAX
    seed: int = 0


@dataclass(frozen=True)
class SurfaceComponent:
    """One meshed component: ``vertices`` (N, M), ``triangles`` (T, 3), ``closed``, its
    ``homology`` (None without triangles), ``defects`` (:func:`.homology.manifold_defects`),
    ``inverted`` (triangles negative in two of their vertices' frames),
    ``tangent_angle_max`` (radians: the largest angle of an edge off its ends' tangent planes),
    the height's critical points on it (indices into :attr:`SurfaceResult.height_critical`),
    ``morse_sum`` (their alternating sum) and ``morse_agrees``, and the linkage's critical
    points on it (indices into :attr:`SurfaceResult.critical_points`) with ``apexes``, the mesh
    vertices at its cones (their links are two cycles: ``defects`` counts them as pinched)."""

    vertices: np.ndarray
    triangles: np.ndarray
    closed: bool
    homology: Homology | None
    defects: dict[str, int]
    inverted: int
    tangent_angle_max: float
    height_critical: list[int]
    morse_sum: int | None
    morse_agrees: bool
    critical_points: list[int]
    message: str
    apexes: np.ndarray


@dataclass(frozen=True)
class SurfaceResult:
    """Outcome of :func:`explore_surfaces`: the components, the height ``c`` (M,) of the
    Morse check with its critical points (``component`` (K,): the component each lies on, -1
    none), the linkage's critical points and the search report."""

    components: list[SurfaceComponent]
    height: np.ndarray
    height_critical: HeightCritical
    height_component: np.ndarray
    critical_points: list[CriticalPoint]
    search: SearchReport


def _seeds(surface: Surface, start: np.ndarray | None, witnesses: np.ndarray,
           rng: np.random.Generator, count: int, deadline: Deadline,
           derived: np.ndarray | None = None) -> list[np.ndarray]:
    """The height's critical points, the given configuration, the ``derived`` seeds (after
    the configuration: where one component holds both, its mesh grows from the same point with
    or without them), projected random starts."""
    seeds = list(witnesses)
    if start is not None:
        seeds.append(start)
    seeds += list(derived if derived is not None else [])
    scale = float(np.median(surface.linkage.lengths[surface.cons.bars]))
    base = surface.linkage.coordinates()
    for _ in range(count):
        if deadline.expired():
            break
        u, ok = surface.project(base + scale * rng.normal(size=surface.n))
        if ok:
            seeds.append(u)
    return seeds


def _linkage_critical(surface: Surface, meshes: list[Mesh], tol: Tolerances
                      ) -> tuple[list[CriticalPoint], list[int]]:
    """Critical points of the linkage refined from the mesh vertices of smallest gap, and
    the mesh each lies on."""
    cands = [(float(m.gaps[v]), k, int(v)) for k, m in enumerate(meshes)
             for v in np.flatnonzero(m.gaps < NEAR_CRITICAL_GAP)]
    cands.sort()
    same = SAME_POINT_REL * float(np.median(surface.linkage.lengths[surface.cons.bars])) * 1e3
    found: list[CriticalPoint] = []
    where: list[int] = []
    for _, k, v in cands[:NEAR_CRITICAL_MAX]:
        ref = refine_critical(surface.cons, meshes[k].vertices[v], tol)
        if not ref.critical:
            continue
        if any(np.linalg.norm(cp.u - ref.u) <= same for cp in found):
            continue
        found.append(CriticalPoint(ref.u, classify(surface.linkage, ref.u, tol),
                                   ref.length_residual, ref.stress_residual))
        where.append(k)
    return found, where


def _mesh(surface: Surface, seed: np.ndarray, step: float, left: int, dl: Deadline
          ) -> tuple[Mesh, tuple[int, float], bool]:
    """March from ``seed``; where its first hexagon does not project or the closed mesh fails
    the geometric checks, march again with a shorter step (:func:`.geometry.finer_step`, at
    most ``REMESH_MAX`` times) while the budget and the deadline allow. The mesh, its checks
    (folded triangles, largest edge angle) and whether the budget stopped a march."""
    mesh = march(surface, seed, step, left, dl)
    if not len(mesh.triangles) and surface.frame(seed).gap >= NEAR_CRITICAL_GAP:  # no apex
        step = finer_step(surface, step, seed[None], None, np.inf)
        mesh = march(surface, seed, step, left, dl)
    check = geometry_checks(mesh)
    for _ in range(REMESH_MAX):
        if not mesh.closed or not (check[0] or check[1] > TANGENT_ANGLE_MAX) or dl.expired():
            break
        if len(mesh.gaps) and float(mesh.gaps.min()) < NEAR_CRITICAL_GAP:
            break  # near a cone of the linkage: no step makes the surface smooth there
        step = finer_step(surface, step, mesh.vertices, mesh.frames,
                          left / max(len(mesh.triangles), 1))
        finer = march(surface, seed, step, left, dl)
        if not finer.closed:
            return mesh, check, "budget" in finer.message
        mesh, check = finer, geometry_checks(finer)
    return mesh, check, "budget" in mesh.message


def _component(mesh: Mesh, check: tuple[int, float], crit: HeightCritical, owner: np.ndarray,
               k: int, critical: list[int], cone_terms: int) -> SurfaceComponent:
    """One component's topology and checks; ``cone_terms``: what its cones' apexes add to the
    Morse count (:func:`.cones.cone_morse_term`)."""
    hom = surface_homology(mesh.triangles) if len(mesh.triangles) else None
    defects = manifold_defects(mesh.triangles)
    inverted, angle = check
    mine = [int(i) for i in np.flatnonzero(owner == k)]
    idx = crit.index[mine]
    morse = None if (idx < 0).any() else int(sum((-1) ** int(i) for i in idx)) + cone_terms
    agrees = hom is not None and morse is not None and morse == hom.euler
    return SurfaceComponent(mesh.vertices, mesh.triangles, mesh.closed, hom, defects, inverted,
                            angle, mine, morse, agrees, critical, mesh.message, mesh.apexes)


def search_height(n_free: int, options: SurfaceOptions | None = None) -> np.ndarray:
    """The height of :func:`explore_surfaces` with ``options`` (:func:`.morse.generic_height`),
    whose critical points a caller may find beforehand (the same seeds)."""
    return generic_height(n_free, (options or SurfaceOptions()).seed)[0]


def explore_surfaces(linkage: Linkage, tolerances: Tolerances | None = None,
                     options: SurfaceOptions | None = None, start_on_space: bool = True,
                     deadline: Deadline | None = None,
                     cones: tuple[list[CriticalPoint], bool] | None = None,
                     meshes: list[Mesh] | None = None,
                     witnesses: tuple[np.ndarray, HeightWitnesses] | None = None,
                     chain: ChainSeeds | None = None) -> SurfaceResult:
    """Every compact component of a ``D = 2`` configuration space as a triangulated surface
    with its topology (module docstring); ``cones``: the critical points and whether every
    path ended, where :func:`.cones.find_cones` has run already for this linkage; ``meshes``:
    closed meshes of this linkage's surface made otherwise (:func:`.transport.transport`),
    checked as marched ones are, the seeds they cover not marched again; ``witnesses``: a
    height ``c`` (M,) and its critical points on this surface found by a homotopy elsewhere
    (:func:`engine.design.surface_homotopy.line_witnesses`), used instead of solving its
    Lagrange system here; ``chain``: a five-bar chain's seeds of this linkage
    (:func:`.five_bar.chain_seeds`) where they were derived already.

    Examples
    --------
    >>> from engine.model.linkage import build_linkage, VertexSpec, BarSpec
    >>> vs = [VertexSpec("P", (0, 0, 0), True), VertexSpec("A", (1, 0, 0))]
    >>> res = explore_surfaces(build_linkage(3, vs, [BarSpec("r", ("P", "A"))]))
    >>> [c.homology.betti_q for c in res.components], res.search["complete"]
    ([(1, 0, 1)], True)
    """
    tol = tolerances or Tolerances()
    opt = options or SurfaceOptions()
    dl = deadline or NEVER
    cons = Constraints(linkage)
    require_two_dof(linkage, cons)
    surface = Surface(linkage, cons, tol.residual_atol)
    c, rng = generic_height(cons.n_free, opt.seed)
    wit: HeightWitnesses | None
    if witnesses is not None:
        c, wit = witnesses
    else:
        wit = height_witnesses(surface, c, rng, dl.fraction(0.6), opt.homotopy_paths_max) \
            if opt.homotopy_paths_max > 0 else None
    five = five_bar_chain(linkage, cons) if wit is None or not wit.success else None
    derived = None if five is None else chain if chain is not None else chain_seeds(
        surface, five, rng, dl.fraction(0.3))
    if derived is not None and cones is None:  # every critical point: no cone homotopy
        refs = [refine_critical(cons, u, tol) for u in derived.critical]
        cones = ([CriticalPoint(r.u, classify(linkage, r.u, tol), r.length_residual,
                                r.stress_residual) for r in refs], derived.success)
    scale = float(np.median(linkage.lengths[cons.bars]))
    step = opt.step_rel * scale
    start = linkage.coordinates() if start_on_space else None
    seeds = _seeds(surface, start, wit.critical.points if wit else np.zeros((0, cons.n_free)),
                   rng, opt.random_starts, dl, derived.seeds if derived else None)
    # cones known already: mesh through them first, then from the seeds no mesh covers
    # the cone homotopy within the default bound, or the larger one the options allow
    paths_max = max(opt.homotopy_paths_max, PATHS_MAX)
    cone_pass = _through_cones(surface, tol, [], [], step, opt.max_triangles, rng, dl, cones,
                               paths_max) \
        if cones is not None and any(is_cone(cp) for cp in cones[0]) else None
    given = list(meshes or [])
    first = given + ([] if cone_pass is None else cone_pass.meshes)
    marched, checks, budget_hit = _mesh_seeds(
        surface, seeds, step, opt.max_triangles - sum(len(m.triangles) for m in first), dl,
        [m.vertices for m in first])
    meshes, checks = given + marched, [geometry_checks(m) for m in given] + checks
    critical, where = _linkage_critical(surface, meshes, tol)
    # near a cone, or failing the geometric checks at every step tried (a narrow cone's
    # tube may keep its vertices' gaps above NEAR_CRITICAL_GAP): look for the cones
    if cone_pass is None and (critical or any(
            len(m.gaps) and float(m.gaps.min()) < NEAR_CRITICAL_GAP for m in meshes) or any(
            k[0] or k[1] > TANGENT_ANGLE_MAX for k in checks)):
        cone_pass = _through_cones(surface, tol, meshes, checks, step, opt.max_triangles, rng,
                                   dl, cones, paths_max)
        if cone_pass is not None:  # it keeps what it does not replace
            meshes, checks = [], []
            # the budget spent on the meshes it replaced (finer and finer through a cone)
            # does not count; a kept mesh stopped by it does
            budget_hit = any("budget" in m.message for m in cone_pass.meshes)
    if cone_pass is not None:
        meshes, checks = cone_pass.meshes + meshes, cone_pass.checks + checks
        critical, where = cone_pass.critical, cone_pass.where
        budget_hit |= cone_pass.budget
    proved = wit is not None and wit.success
    # without the homotopy: the PL critical vertices of the closed meshes and their
    # neighbours, refined by Newton within a trust region of half a step
    crit = wit.critical if proved and wit is not None else classify_points(
        surface, c, np.vstack([np.zeros((0, cons.n_free))] + [
            m.vertices[ring(m.triangles, pl_critical_vertices(m.vertices, m.triangles,
                                                              m.vertices @ c)[0])]
            for m in meshes if m.closed]), 0.5 * step)
    owner = assign(crit.points, [m.vertices for m in meshes], 2.0 * step)
    comps = [_component(m, checks[k], crit, owner, k,
                        [j for j, w in enumerate(where) if w == k],
                        sum(cone_morse_term(critical[j], c) for j, w in enumerate(where)
                            if w == k and is_cone(critical[j])))
             for k, m in enumerate(meshes)]
    return SurfaceResult(comps, c, crit, owner, critical,
                         _report(wit, comps, owner, critical, dl, budget_hit, step, cone_pass,
                                 derived))


@dataclass(frozen=True)
class _ConePass:
    """The meshes after meshing through the cones (those of the other components kept), their
    checks, every critical point of the linkage (:func:`.cones.find_cones`), the mesh each
    lies on (-1: none), whether every path of the cone search ended and whether the triangle
    budget stopped the march."""

    meshes: list[Mesh]
    checks: list[tuple[int, float]]
    critical: list[CriticalPoint]
    where: list[int]
    ended: bool
    budget: bool


def _mesh_seeds(surface: Surface, seeds: list[np.ndarray], step: float, max_triangles: int,
                dl: Deadline, covered: list[np.ndarray] | None = None
                ) -> tuple[list[Mesh], list[tuple[int, float]], bool]:
    """A mesh from every seed that no mesh (nor the vertices ``covered``) covers yet, within
    the budget and the deadline: the meshes, their checks and whether the budget stopped one."""
    meshes: list[Mesh] = []
    checks: list[tuple[int, float]] = []
    trees: list[cKDTree] = [cKDTree(v) for v in covered or [] if len(v)]
    budget_hit = False
    for seed in seeds:
        if dl.expired():
            break
        if any(t.query(seed)[0] <= step for t in trees):
            continue
        left = max_triangles - sum(len(m.triangles) for m in meshes)
        if left <= 0:
            budget_hit = True
            break
        mesh, check, hit = _mesh(surface, seed, step, left, dl)
        budget_hit |= hit
        meshes.append(mesh)
        checks.append(check)
        trees.append(cKDTree(mesh.vertices))
    return meshes, checks, budget_hit


def _through_cones(surface: Surface, tol: Tolerances, meshes: list[Mesh],
                   checks: list[tuple[int, float]], step: float, max_triangles: int,
                   rng: np.random.Generator, dl: Deadline,
                   known: tuple[list[CriticalPoint], bool] | None = None,
                   paths_max: int | None = None) -> _ConePass | None:
    """Mesh the components through the linkage's cones (:mod:`.cones`): find every critical
    point by homotopy, march from fans around every cone's apex at once, part the result into
    components and keep the first meshes of the other components (most of whose vertices are
    over a step from the new ones); ``known``: the critical points found already;
    ``paths_max``: the homotopy's bound (over it no path runs: no cone found, the search not
    ended). None where there is no cone or a fan does not project."""
    found, ended = known or find_cones(surface.linkage, tol, rng, dl.fraction(0.5), paths_max)
    cones = [cp for cp in found if is_cone(cp)]
    fans = [cone_fans(surface, cp, step) for cp in cones]
    if not cones or any(fan is None for fan in fans) or dl.expired():
        return None
    mesh = march(surface, None, step, max_triangles, dl,
                 fans=[fan for fan in fans if fan is not None])
    parts = components(mesh)
    tree = cKDTree(mesh.vertices)
    kept = [k for k, m in enumerate(meshes) if float(np.median(tree.query(m.vertices)[0])) > step]
    out = [meshes[k] for k in kept] + parts
    same = SAME_POINT_REL * float(np.median(surface.linkage.lengths[surface.cons.bars])) * 1e3
    where = []
    for cp in found:
        d = [float(cKDTree(m.vertices).query(cp.u)[0]) if len(m.vertices) else np.inf
             for m in out]
        where.append(int(np.argmin(d)) if d and min(d) <= same else -1)
    return _ConePass(out, [checks[k] for k in kept] + [geometry_checks(p) for p in parts],
                     found, where, ended, "budget" in mesh.message)


def _sound(c: SurfaceComponent) -> bool:
    """Closed, a 2-manifold but at its apexes (each pinched once), no fold, close to the
    tangent planes, and the Morse check agrees."""
    d = c.defects
    return (c.closed and d["open_edges"] == d["branched_edges"] == d["repeated_triangles"] == 0
            and d["pinched_vertices"] == len(c.apexes) and c.inverted == 0
            and c.tangent_angle_max <= TANGENT_ANGLE_MAX and c.morse_agrees)


def _report(wit: HeightWitnesses | None, comps: list[SurfaceComponent],
            owner: np.ndarray, critical: list[CriticalPoint], dl: Deadline, budget_hit: bool,
            step: float, cone_pass: _ConePass | None, derived: ChainSeeds | None = None
            ) -> SearchReport:
    """The search report: complete only with the homotopy's proof (or the five-bar chain's
    derived seeds), every surface closed and sound, every critical point of the height on one,
    and every critical point of the linkage a cone found by the cone homotopy (or the chain's
    argument; every path ended) and meshed through."""
    ended = cone_pass is None or cone_pass.ended
    proved = wit is not None and wit.success and ended
    by_chain = not proved and derived is not None and derived.success and ended
    paths = wit.paths if wit is not None else 0
    sound = all(_sound(c) for c in comps)
    meshed = cone_pass is not None and all(w >= 0 for w in cone_pass.where)
    degenerate = bool(critical) and not (meshed and all(is_cone(cp) for cp in critical))
    missed = int((owner < 0).sum())
    details: dict[str, object] = {
        "method": "marching", "dof": 2, "step": step, "components_meshed": len(comps),
        "triangles": int(sum(len(c.triangles) for c in comps)),
        "height_critical_points": len(owner), "height_critical_unplaced": missed,
        "homotopy": wit.message if wit is not None else "skipped",
        "homotopy_paths": paths,
        "homotopy_start": wit.start if wit is not None and wit.counts else None,
        "morse_agrees": all(c.morse_agrees for c in comps),
        "cones": sum(len(c.apexes) for c in comps),
        "cone_homotopy_ended": None if cone_pass is None else cone_pass.ended,
        "five_bar_chain": None if derived is None else derived.message,
    }
    detail = ("every compact component holds a maximum of a generic height: the "
              f"{paths} paths of the Lagrange system's homotopy (from a "
              f"{wit.start if wit is not None else ''} start) found its {len(owner)} real "
              "critical points, each on a meshed closed surface whose Morse sum equals its "
              "Euler characteristic" + (
                  f"; the {len(critical)} critical points of the linkage, all found by the "
                  "cone homotopy (every path ended), are cones the meshes pass through, their "
                  "apexes counted by stratified Morse theory" if cone_pass is not None
                  else "")) if proved else derived.detail if by_chain and derived else None
    return SearchReport(details, timed_out=dl.expired(), budget=budget_hit,
                        degenerate=degenerate, unresolved=not sound or missed > 0,
                        time_budget_s=granted(dl),
                        argument="proved" if proved else "derived" if by_chain else None,
                        argument_detail=detail)
