"""Design for two degrees of freedom: a length change that resolves chosen cones into chosen
numbers of sheets, with the predicted change of the topology, checked by re-meshing.

A cone (one self-stress, ``Q`` indefinite on three zero modes) resolves into a hyperboloid of
one sheet where ``Delta`` has the sign two of ``Q``'s eigenvalues share, of two sheets where it
has the other (:mod:`.surface_splitting`). So asking a cone for a number of sheets is asking
``Delta`` for a sign, and ``Delta = 4 sum sigma_a L_a dL_a`` to first order is linear in
``dL``: the smallest largest change giving every target its sign with a margin is the linear
programme of :func:`engine.design.design.design`, whose conflicts (tied cones asked for
opposite signs, bars that do not move a cone) carry over.

The answer predicts how every cone (asked or not) resolves at ``L + dL``, the change of the
Euler characteristic from the critical space (``sum (2 sheets - 3)``) and
``chi(L + dL) - chi(L - dL) = 2 sum (2 sheets - 3)``, and checks them by meshing both perturbed
linkages (:func:`.surface_splitting.remesh_split`); a target is met when its cone resolves
into the sheets asked for.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from engine.design.design import DesignResult, Target, check_request, design
from engine.design.surface_critical import CriticalSearch, critical_search
from engine.design.surface_homotopy import line_witnesses
from engine.design.surface_splitting import SurfaceSplit, cone_sign, one_homotopy, remesh_split
from engine.local.critical import CriticalPoint
from engine.model.budget import NEVER, Deadline, granted
from engine.model.constraints import Constraints
from engine.model.errors import InvalidRequest
from engine.model.linkage import Linkage
from engine.model.report import SearchReport
from engine.model.tolerances import Tolerances
from engine.space.surfaces.cones import is_cone
from engine.space.surfaces.explore import SurfaceOptions, require_two_dof, search_height

#: Share of the deadline the cone search may use (the rest meshes the two perturbed spaces).
CONE_SHARE = 0.3
#: Default margin, relative to the median bar length: the perturbed spaces must be meshed, and
#: a cone's neck (of radius about ``sqrt(|Delta| / |Q|)``) must be wide against the mesh's step.
#: On the pentagon at (2, 1, 1, 1, 1) changes of 0.02 re-mesh to Farber and Schuetz's topology
#: but not every re-meshing is proved; at 0.05 they are, after meshing the necks again with
#: finer steps (10-13 s CPU for the whole design); at 0.08 the first meshes pass (5 s).
MARGIN_REL = 0.08


@dataclass(frozen=True)
class ConeTarget:
    """Cone number ``cone`` (in the order of :func:`engine.space.surfaces.cones.find_cones`, as the
    splitting answer lists them) asked for ``sheets`` (1 or 2) or, where ``sheets`` is 0, for
    the sign ``sign`` (+-1) of its ``Delta``."""

    cone: int
    sheets: int = 0
    sign: int = 0


@dataclass(frozen=True)
class SurfaceDesign:
    """The linear programme's ``result``, the ``cones`` found, the signs asked of them
    (``signs`` (T,)), the resolution at ``L + dL`` with its re-meshed check (``split``: None
    where infeasible or the deadline passed first), ``euler_change`` (the predicted
    ``chi(L + dL) - chi(L)``: None where a cone is undecided or infeasible) and ``targets_met``
    (every target's cone resolves as asked; None without a ``split``), whether every path of
    the cone search ended (``cones_ended``) and the report (the re-meshing's where there is
    one, else the cone search's)."""

    result: DesignResult
    cones: list[CriticalPoint]
    signs: np.ndarray
    split: SurfaceSplit | None
    euler_change: int | None
    targets_met: bool | None
    cones_ended: bool
    search: SearchReport


def check_targets(targets: list[ConeTarget]) -> None:
    """Each target gives ``sheets`` (1 or 2) or ``sign`` (+-1), not both and not neither
    (:class:`InvalidRequest` naming the field)."""
    for k, t in enumerate(targets):
        if t.sheets and t.sign:
            raise InvalidRequest("give sheets or sign, not both", loc=("targets", k, "sheets"))
        if t.sheets not in (0, 1, 2):
            raise InvalidRequest("sheets must be 1 or 2", loc=("targets", k, "sheets"))
        if not t.sheets and t.sign not in (-1, 1):
            raise InvalidRequest("give sheets (1 or 2) or sign (1 or -1)",
                                 loc=("targets", k, "sheets"))


def _unfound(cones: list[CriticalPoint], targets: list[ConeTarget], bars: int,
             deadline: Deadline, how: CriticalSearch) -> SurfaceDesign:
    """The answer where the cone search stopped (its deadline, or its path bound before any
    path ran) before finding a target's cone: no design, and a report saying why (not a
    refusal: the cone may exist)."""
    missing = next(t.cone for t in targets if not 0 <= t.cone < len(cones))
    message = f"{how.message}: {len(cones)} cones found, no cone {missing} to design for"
    result = DesignResult(False, np.zeros(bars), 0.0, [], False, message)
    report = SearchReport({"method": how.method, "cones": len(cones),
                           "cone_search_paths": how.paths,
                           "cone_homotopy_ended": False}, timed_out=deadline.expired(),
                          unresolved=True, time_budget_s=granted(deadline),
                          argument_detail="no proof: " + message)
    return SurfaceDesign(result, cones, np.zeros(0, dtype=np.int64), None, None, None, False,
                         report)


def design_surface(linkage: Linkage, targets: list[ConeTarget], adjustable: list[str],
                   margin: float, max_change: float | None = None,
                   tol: Tolerances | None = None, options: SurfaceOptions | None = None,
                   deadline: Deadline = NEVER, seed: int = 0) -> SurfaceDesign:
    """Smallest largest change of the ``adjustable`` bars resolving each target cone as asked
    (``sign * Delta >= margin * |dDelta/dL|``), and its check by re-meshing (module
    docstring).

    Examples
    --------
    The pentagon with its bar P0 P1 pinned, at lengths (2, 1, 1, 1, 1), has four cones (its
    collinear configurations); ask the first for two sheets by changing ``b2``:

    >>> from engine.model.linkage import build_linkage, VertexSpec, BarSpec
    >>> pts = {"P0": (0, 0), "P1": (2, 0), "A": (2.5, 0.8), "B": (1.6, 1.3), "C": (0.7, 0.7)}
    >>> vs = [VertexSpec(k, p, k in ("P0", "P1")) for k, p in pts.items()]
    >>> ends = [("P0", "P1"), ("P1", "A"), ("A", "B"), ("B", "C"), ("C", "P0")]
    >>> bs = [BarSpec(f"b{i}", e, x) for i, (e, x) in enumerate(zip(ends, (2, 1, 1, 1, 1)))]
    >>> out = design_surface(build_linkage(2, vs, bs), [ConeTarget(0, sheets=2)], ["b2"], 1e-3)
    >>> len(out.cones), out.split.cones[0].sheets, out.targets_met, out.split.verified
    (4, 2, True, True)
    """
    tol = tol or Tolerances()
    cons = Constraints(linkage)
    require_two_dof(linkage, cons)
    check_targets(targets)
    check_request(linkage, [Target(t.cone, 1) for t in targets], adjustable)
    paths_max = (options or SurfaceOptions()).homotopy_paths_max
    how = critical_search(linkage, tol, paths_max, np.random.default_rng(seed),
                          deadline.fraction(CONE_SHARE))
    found, ended = how.found, how.ended
    cones = [cp for cp in found if is_cone(cp)]
    for k, t in enumerate(targets):
        if not 0 <= t.cone < len(cones) and ended:
            raise InvalidRequest(f"no cone {t.cone} (found {len(cones)})",
                                 loc=("targets", k, "branch_point"))
    if any(not 0 <= t.cone < len(cones) for t in targets):
        return _unfound(cones, targets, len(linkage.lengths), deadline, how)
    signs = np.array([t.sign if not t.sheets else cone_sign(cones[t.cone], t.sheets)
                      for t in targets], dtype=np.int64)
    result = design(linkage, cones, [Target(t.cone, int(s)) for t, s in zip(targets, signs,
                                                                            strict=True)],
                    adjustable, margin, max_change)
    if not result.feasible or deadline.expired():
        report = SearchReport({"method": how.method, "cones": len(cones),
                               "cone_search_paths": how.paths,
                               "cone_homotopy_ended": ended}, timed_out=deadline.expired(),
                              unresolved=not ended, time_budget_s=granted(deadline))
        return SurfaceDesign(result, cones, signs, None, None, None, ended, report)
    line = line_witnesses(linkage, result.perturbation, tol, np.random.default_rng(seed + 1),
                          deadline.fraction(CONE_SHARE), at=(1.0, -1.0),
                          height=search_height(cons.n_free, options)) \
        if one_homotopy(cons, options) else None
    split = remesh_split(linkage, cones, ended, result.perturbation, tol, options, deadline,
                         found=found, witnesses=None if line is None else {
                             w: (line.height, h) for w, h in line.heights.items()}, how=how)
    decided = all(c.sign != 0 for c in split.cones)
    change = sum(c.euler_change for c in split.cones) if decided else None
    met = all(split.cones[t.cone].sign == s for t, s in zip(targets, signs, strict=True))
    return SurfaceDesign(result, cones, signs, split, change, met, ended, split.search)
