"""Why a search is complete: the witness points of :mod:`engine.space.witnesses` gathered for a
search, and the argument its answer names.

``derived``: the rules of :mod:`engine.space.chain_count` count the components of a rotor chain
(and prove it has no critical point), and exactly that many were traced; or a closed form
(:mod:`.closed_form`). ``proved``: every real solution of the witness system was found (every
path of its homotopy ended), every real regular one lies on a traced curve, and every singular
one near the reals refined to a critical point of the answer. Otherwise there is no argument
and the answer is incomplete with reason ``searched``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from engine.local.critical import CriticalPoint
from engine.model.budget import ARGUMENT_DERIVED, ARGUMENT_PROVED, Argument
from engine.model.constraints import project
from engine.model.report import count_text
from engine.space.chain_count import ChainCount
from engine.space.configuration_space.explorer import Explorer
from engine.space.witnesses import Witnesses, witness_points

#: Share of the remaining time the homotopy may take (the tracing and the critical-point search
#: need the rest).
WITNESS_SHARE = 0.6
#: A singular end counts as resolved when a critical point of the answer lies this close
#: (relative to the median bar length; the end is within about ``sqrt(T_END)`` of its solution).
RESOLVED_REL = 1e-3


@dataclass(frozen=True)
class Proof:
    """Witness points for a search: the regular ones projected onto the constraints (seeds of
    the tracer), the singular ones (starts of the critical-point refinement)."""

    witnesses: Witnesses
    seeds: np.ndarray  # (K, M) on the constraints
    critical_starts: np.ndarray  # (S, M)
    unprojected: int  # regular real ends whose projection failed


def gather(ex: Explorer) -> Proof | None:
    """The witness points of ``ex``'s linkage, or None where the method does not apply (the
    option is off); the report's ``homotopy`` says what was done or why not."""
    paths_max = ex.opt.homotopy_paths_max
    if paths_max <= 0:
        ex.report["homotopy"] = "off"
        return None
    w = witness_points(ex.linkage, ex.cons, seed=ex.opt.seed,
                       deadline=ex.deadline.fraction(WITNESS_SHARE), paths_max=paths_max)
    ex.report["homotopy"] = {"paths": w.paths, **w.counts, "success": w.success,
                             "message": w.message}
    if not w.paths or not w.success:
        return Proof(w, np.zeros((0, ex.cons.n_free)), w.critical_starts, 0)
    seeds, lost = [], 0
    for u in w.seeds:
        lk = ex.linkage.with_positions(ex.linkage.positions_of(u))
        res = project(lk, ex.tol)
        if res.success:
            seeds.append(lk.with_positions(res.positions).coordinates())
        else:
            lost += 1
    return Proof(w, np.array(seeds, dtype=float).reshape(-1, ex.cons.n_free),
                 w.critical_starts, lost)


def unresolved_starts(ex: Explorer, proof: Proof, crit: list[CriticalPoint]) -> int:
    """Singular ends near the reals with no critical point of the answer near them."""
    if not len(proof.critical_starts):
        return 0
    if not crit:
        return len(proof.critical_starts)
    found = np.array([c.u for c in crit])
    dist = np.linalg.norm(proof.critical_starts[:, None, :] - found[None], axis=2).min(axis=1)
    return int((dist > RESOLVED_REL * ex.scale).sum())


def uncovered_seeds(ex: Explorer, proof: Proof) -> int:
    """Real regular ends that lie on no traced curve."""
    return sum(not ex.on_traced(u) for u in proof.seeds)


def argument(ex: Explorer, proof: Proof | None, crit: list[CriticalPoint],
             count: ChainCount | None = None, traced: int | None = None,
             components: bool = True) -> tuple[Argument | None, str | None]:
    """The argument of a search that ran to its end (or ``(None, why not)``): ``components``
    False for the critical-point search, which needs no seed on every component."""
    if count is not None and not crit and (traced == count.components or not components):
        return ARGUMENT_DERIVED, (
            f"{count.rule}: {count_text(count.components)} components and no critical point"
            + (f"; {traced} traced" if components else ""))
    if proof is None:
        return None, None
    w = proof.witnesses
    if not w.paths or not w.success:
        return None, f"homotopy: {w.message}"
    why = []
    if components and proof.unprojected:
        why.append(f"{proof.unprojected} real solutions did not project onto the constraints")
    if components and (off := uncovered_seeds(ex, proof)):
        why.append(f"{off} real solutions lie on no traced curve")
    if unresolved := unresolved_starts(ex, proof, crit):
        why.append(f"{unresolved} singular solutions refined to no critical point")
    if why:
        return None, "homotopy: " + "; ".join(why)
    c = w.counts
    what = ("a point on every compact component (a height's extremum) and every critical point"
            if components else "every critical point")
    return ARGUMENT_PROVED, (
        f"{what} among the real solutions of f = 0, det[J; c] = 0 for a random c; all "
        f"{w.paths} paths of its total-degree homotopy ended ({c['regular']} regular, "
        f"{c['singular']} singular, {c['far']} towards infinity or beyond reach); "
        f"{c['real']} real regular solutions on the traced curves, "
        f"{c['critical_candidates']} singular ones near the reals refined to the "
        f"{len(crit)} critical points")


def proved_so_far(ex: Explorer, proof: Proof | None, crit: list[CriticalPoint],
                  count: ChainCount | None, degenerate: bool, complete: bool,
                  components: int | None = None, agreed: bool = True
                  ) -> dict[str, dict[str, object]]:
    """What an answer proves even when it is incomplete (issue 23, item 5): for the critical
    points and (``components`` traced, None for the critical-point search) the components,
    ``{"count": N, "exact": bool}``: exactly N where the answer is complete or an argument
    covers that part alone (the homotopy proves the critical points complete while tracing ran
    out of time; the chain rules count the components whatever was traced), else at least N
    (what was found: each critical point and traced component is one)."""
    crit_exact = complete or (
        not degenerate and argument(ex, proof, crit, count, components=False)[0] is not None)
    out: dict[str, dict[str, object]] = {
        "critical_points": {"count": len(crit), "exact": bool(crit_exact)}}
    if components is not None:
        if count is not None and agreed:
            out["components"] = {"count": count.components, "exact": True}
        else:
            out["components"] = {"count": components, "exact": bool(complete)}
    return out
