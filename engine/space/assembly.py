"""Seeds for the search of every component: assemblies at swept rotor angles, random starts.

For planar linkages that decompose into dyads (each remaining vertex placed from two placed
neighbours, circle-circle, or a slider from one, line-circle), fixing one rotor's angle makes
the linkage rigid and *every* assembly at that angle is enumerated in closed form (both
intersections at each step, pruned where circles miss). Other linkages get random starts
projected onto the constraint set.
"""

from __future__ import annotations

import heapq
import math
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

from engine.model.batched import BATCH_MAX_FREE, project_many
from engine.model.budget import NEVER, Deadline
from engine.model.constraints import Constraints, project
from engine.model.linkage import Linkage
from engine.model.tolerances import Tolerances


@dataclass(frozen=True)
class Step:
    """Place ``vertex`` from placed neighbours ``a`` (and ``b``) with bar lengths ``ra``, ``rb``;
    ``axis`` is the free axis of a slider (then only ``a`` is used)."""

    vertex: int
    a: int
    ra: float
    b: int = -1
    rb: float = 0.0
    axis: int = -1


def rotors(linkage: Linkage) -> list[int]:
    """Bars with exactly one fully fixed end (indices)."""
    full = np.asarray(linkage.fixed.all(axis=1), dtype=bool)
    ends = linkage.ends
    return [k for k in range(linkage.n_bars) if full[ends[k, 0]] != full[ends[k, 1]]]


def dyad_plan(linkage: Linkage, rotor: int) -> list[Step] | None:
    """Order in which the vertices are placed once ``rotor``'s tip is, or None.

    At every step the vertex placed is the one of lowest index that can be (two placed
    neighbours, or one for a slider), from its first placed neighbours in bar order. A vertex
    that can be placed stays so, so the candidates wait in a heap: O((V + E) log V), where
    scanning the unplaced vertices at every step cost O(V^2) (seconds at a few thousand
    vertices, before any deadline is looked at)."""
    if linkage.dimension != 2:
        return None
    full = np.asarray(linkage.fixed.all(axis=1), dtype=bool)
    placed = full.copy()
    pin, tip = linkage.ends[rotor]
    if not full[pin]:
        pin, tip = tip, pin
    placed[int(tip)] = True
    nbrs: dict[int, list[tuple[int, float]]] = {v: [] for v in range(linkage.n_vertices)}
    for (i, j), length in zip(linkage.ends.tolist(), linkage.lengths.tolist(), strict=True):
        nbrs[i].append((j, length))
        nbrs[j].append((i, length))
    n_free_axes = (~np.asarray(linkage.fixed, dtype=bool)).sum(axis=1)
    free_axis = np.argmax(~np.asarray(linkage.fixed, dtype=bool), axis=1)
    # placed neighbours (bars to them, with multiplicity) each vertex needs: 2, 1 on a slider
    need = np.where(n_free_axes == 1, 1, 2)
    known = np.zeros(linkage.n_vertices, dtype=int)
    ready: list[int] = []

    def mark(v: int) -> None:
        for w, _ in nbrs[v]:
            if not placed[w]:
                known[w] += 1
                if known[w] == need[w]:
                    heapq.heappush(ready, w)

    for v in np.flatnonzero(placed).tolist():
        mark(v)
    plan: list[Step] = []
    for _ in range(int((~placed).sum())):
        if not ready:
            return None
        v = heapq.heappop(ready)
        first = [(w, ln) for w, ln in nbrs[v] if placed[w]][:2]
        if n_free_axes[v] == 2:
            plan.append(Step(v, first[0][0], first[0][1], first[1][0], first[1][1]))
        else:
            plan.append(Step(v, first[0][0], first[0][1], axis=int(free_axis[v])))
        placed[v] = True
        mark(v)
    return plan


def _candidates(step: Step, pos: np.ndarray) -> list[tuple[float, float]]:
    """Where ``step`` may put its vertex given the positions ``pos`` (V, 2): both
    intersections, first root first (none where the circles miss). Python floats: a node of
    the depth-first enumeration costs microseconds, not numpy's per-call overhead."""
    if step.axis >= 0:  # slider: the line through pos[v] along axis meets a circle
        base = pos[step.vertex].tolist()
        other = 1 - step.axis
        centre = pos[step.a].tolist()
        disc = step.ra**2 - (base[other] - centre[other]) ** 2
        if disc < 0:
            return []
        out = []
        for sgn in (1.0, -1.0):
            p = list(base)
            p[step.axis] = centre[step.axis] + sgn * math.sqrt(disc)
            out.append((p[0], p[1]))
        return out
    (x0, y0), (x1, y1) = pos[step.a].tolist(), pos[step.b].tolist()
    dx, dy = x1 - x0, y1 - y0
    dist = float(np.hypot(dx, dy))  # (numpy's: math.hypot may differ in the last bit)
    if dist == 0.0:
        return []
    along = (dist**2 + step.ra**2 - step.rb**2) / (2 * dist)
    h2 = step.ra**2 - along**2
    if h2 < 0:
        return []
    ex, ey = dx / dist, dy / dist
    h = math.sqrt(h2)
    return [(x0 + along * ex - sgn * h * ey, y0 + along * ey + sgn * h * ex)
            for sgn in (1.0, -1.0)]


#: Nodes (partial assemblies) :func:`assemblies_at` visits at most, per assembly asked for and
#: per level of the plan: a tree whose branches fail deep (one part of the linkage assembles in
#: 2^k ways before another part fails) is cut there, its answer marked truncated.
NODES_PER_ASSEMBLY_LEVEL = 8
#: The enumeration looks at its deadline every this many nodes.
DEADLINE_EVERY_NODES = 256


def node_budget(plan: list[Step], budget: int) -> int:
    """Nodes :func:`assemblies_at` visits at most for ``budget`` assemblies of ``plan``:
    :data:`NODES_PER_ASSEMBLY_LEVEL` per assembly and level (a tree without dead ends needs at
    most ``len(plan) + 1`` per assembly)."""
    return NODES_PER_ASSEMBLY_LEVEL * max(int(budget), 1) * (len(plan) + 1)


def assemblies_at(
    linkage: Linkage, rotor: int, plan: list[Step], angle: float, budget: int,
    deadline: Deadline = NEVER,
) -> tuple[list[np.ndarray], bool]:
    """Every assembly (positions (V, 2)) with ``rotor`` at ``angle``; and whether the
    enumeration was cut short: by the budget of assemblies, by that of nodes
    (:func:`node_budget`) or by ``deadline``.

    Depth-first, on one array of positions: a node's children are computed from the positions
    of its ancestors, which no node visited in between overwrites (they are all its
    descendants), so a node costs O(1), not a copy of the V positions."""
    pin, tip = (int(x) for x in linkage.ends[rotor])
    if not linkage.fixed[pin].all():
        pin, tip = tip, pin
    pos = np.array(linkage.positions, dtype=float)
    length = float(linkage.lengths[rotor])
    pos[tip] = pos[pin] + length * np.array([np.cos(angle), np.sin(angle)])
    out: list[np.ndarray] = []
    # (depth, the position of the vertex plan[depth - 1] places; None at the root)
    stack: list[tuple[int, tuple[float, float] | None]] = [(0, None)]
    cap = node_budget(plan, budget)
    nodes = 0
    while stack:
        if nodes >= cap or (nodes % DEADLINE_EVERY_NODES == 0 and deadline.expired()):
            return out, True
        nodes += 1
        depth, where = stack.pop()
        if where is not None:
            pos[plan[depth - 1].vertex] = where
        if depth == len(plan):
            out.append(pos.copy())
            if len(out) >= budget:
                return out, bool(stack)
            continue
        stack += [(depth + 1, cand) for cand in _candidates(plan[depth], pos)]
    return out, False


def _level_roots(step: Step, pos: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`_candidates` for every partial assembly of ``pos`` (N, V, 2) at once: where both
    roots exist (N,), the first roots and the second (N, 2), the same arithmetic array-wise."""
    if step.axis >= 0:
        other = 1 - step.axis
        off = pos[:, step.vertex, other] - pos[:, step.a, other]
        disc = step.ra**2 - off**2
        keep = disc >= 0
        root = np.sqrt(np.where(keep, disc, 0.0))
        first = pos[:, step.vertex].copy()
        second = first.copy()
        first[:, step.axis] = pos[:, step.a, step.axis] + 1.0 * root
        second[:, step.axis] = pos[:, step.a, step.axis] + -1.0 * root
        return keep, first, second
    c0, c1 = pos[:, step.a], pos[:, step.b]
    delta = c1 - c0
    dist = np.hypot(delta[:, 0], delta[:, 1])
    nonzero = dist != 0.0
    safe = np.where(nonzero, dist, 1.0)
    along = (safe**2 + step.ra**2 - step.rb**2) / (2 * safe)
    h2 = step.ra**2 - along**2
    keep = nonzero & (h2 >= 0)
    e = delta / safe[:, None]
    normal = np.stack([-e[:, 1], e[:, 0]], axis=1)
    mid = c0 + along[:, None] * e
    root = np.sqrt(np.where(keep, h2, 0.0))
    return keep, mid + (1.0 * root)[:, None] * normal, mid + (-1.0 * root)[:, None] * normal


#: Partial assemblies held at once by :func:`assemblies_at_angles` (all angles, one level of the
#: plan); past it, the angles with the largest trees are left to :func:`assemblies_at`.
MAX_BATCHED_ASSEMBLIES = 1 << 16
#: Coordinates :func:`assemblies_at_angles` copies at most over the whole plan (each level
#: copies its partial assemblies' V positions): fewer assemblies per level on long plans of
#: large linkages, whose angles are left to :func:`assemblies_at` (O(1) a node) instead.
MAX_BATCHED_WORK = 1 << 26


def assemblies_at_angles(
    linkage: Linkage, rotor: int, plan: list[Step], angles: np.ndarray, budget: int,
    deadline: Deadline = NEVER,
) -> list[tuple[list[np.ndarray], bool]]:
    """:func:`assemblies_at` at every angle of ``angles`` at once: the same assemblies (the same
    arithmetic, array-wise), in the same order, with the same truncation flags.

    The plan is walked level by level over all angles' partial assemblies at once; children
    are listed second intersection first, which is the order in which :func:`assemblies_at`'s
    depth-first stack finds them, so every level lists its nodes in depth-first order. The
    budget keeps an angle's first ``budget`` assemblies; its flag is that of the depth-first
    search, which stops with its stack not empty exactly when some node of the tree (a later
    assembly or a dead end) comes after the last one kept: a right sibling of one of its
    ancestors. Angles whose trees would hold more than :data:`MAX_BATCHED_ASSEMBLIES` nodes in
    all on one level (fewer on long plans, :data:`MAX_BATCHED_WORK`), or more nodes than
    :func:`node_budget` in all, are left to :func:`assemblies_at` itself. Once ``deadline``
    has passed, every angle not yet enumerated answers no assembly, cut short.
    """
    angles = np.asarray(angles, dtype=float).reshape(-1)
    n_angles = len(angles)
    pin, tip = (int(x) for x in linkage.ends[rotor])
    if not linkage.fixed[pin].all():
        pin, tip = tip, pin
    base = np.array(linkage.positions, dtype=float)
    length = float(linkage.lengths[rotor])
    pos = np.repeat(base[None], n_angles, axis=0)  # (N, V, 2)
    pos[:, tip] = base[pin] + length * np.stack([np.cos(angles), np.sin(angles)], axis=1)
    owner = np.arange(n_angles)  # the angle of each partial assembly
    scalar = np.zeros(n_angles, dtype=bool)  # angles left to assemblies_at
    seen = np.ones(n_angles, dtype=int)  # each angle's nodes so far (the root)
    cap = node_budget(plan, budget)
    most = min(MAX_BATCHED_ASSEMBLIES, MAX_BATCHED_WORK // (2 * len(base) * max(len(plan), 1)))
    # per level below the root: each node's owner and the index of its parent one level up
    owners: list[np.ndarray] = []
    parents: list[np.ndarray] = []
    for step in plan:
        if not len(owner):
            break  # every tree is done (dead ends) or left to assemblies_at
        if deadline.expired():
            return [([], True)] * n_angles
        keep, first, second = _level_roots(step, pos)
        rows = np.flatnonzero(keep)
        size = np.bincount(owner[rows], minlength=n_angles)
        seen += 2 * size
        # trees past the node budget: the depth-first search cuts them where it does
        scalar |= seen > cap
        if 2 * len(rows) > most:
            # the largest trees go to the depth-first search; the others stay batched
            scalar |= size > (most // 2) // n_angles
        rows = rows[~scalar[owner[rows]]]
        # children in depth-first order: each parent's second intersection, then its first
        children = np.repeat(pos[rows], 2, axis=0)
        children[0::2, step.vertex] = second[rows]
        children[1::2, step.vertex] = first[rows]
        pos, owner = children, np.repeat(owner[rows], 2)
        owners.append(owner)
        parents.append(np.repeat(rows, 2))
    count = np.bincount(owner, minlength=n_angles)
    starts = np.concatenate([[0], np.cumsum(count)])
    # the last node of every angle on every level (-1: none)
    lasts = []
    for own in owners:
        last = np.full(n_angles, -1)
        last[own] = np.arange(len(own))  # the last write per angle wins: its last node
        lasts.append(last)
    out: list[tuple[list[np.ndarray], bool]] = []
    for k in range(n_angles):
        if scalar[k]:
            out.append(assemblies_at(linkage, rotor, plan, float(angles[k]), budget, deadline))
            continue
        stop = starts[k] + min(int(count[k]), budget)
        truncated = False
        if count[k] >= budget > 0:
            node = int(stop) - 1  # the last assembly kept, then its ancestors
            for level in range(len(plan) - 1, -1, -1):
                if lasts[level][k] > node:
                    truncated = True
                    break
                node = int(parents[level][node])
        out.append((list(pos[starts[k]:stop]), truncated))
    return out


def iter_projected_random_starts(
    linkage: Linkage, tol: Tolerances, count: int, rng: np.random.Generator,
    deadline: Deadline = NEVER,
) -> Iterator[np.ndarray]:
    """The projections of :func:`projected_random_starts`, one at a time (large linkages: one
    projection each, until ``deadline``)."""
    cons = Constraints(linkage)
    scale = float(np.median(linkage.lengths[cons.bars])) if cons.n_constraints else 1.0
    free = ~linkage.fixed
    if 0 < cons.n_free <= BATCH_MAX_FREE and count > 1:
        # small linkages: every start drawn (the same draws, in order) and projected at once
        base = linkage.coordinates()
        us = np.array([base + scale * rng.normal(size=int(free.sum())) for _ in range(count)])
        projected, ok = project_many(cons, us, tol)
        for k in np.flatnonzero(ok):
            yield projected[k]
        return
    for _ in range(count):
        if deadline.expired():
            return
        pos = np.array(linkage.positions, dtype=float)
        pos[free] += scale * rng.normal(size=int(free.sum()))
        res = project(linkage.with_positions(pos), tol, deadline=deadline)
        if res.success:
            yield linkage.coordinates(res.positions)


def projected_random_starts(
    linkage: Linkage, tol: Tolerances, count: int, rng: np.random.Generator,
    deadline: Deadline = NEVER,
) -> list[np.ndarray]:
    """``count`` random perturbations of the given positions (scale: the median bar length),
    each projected onto the constraints; only the projections that succeed are returned (those
    made before ``deadline``)."""
    return list(iter_projected_random_starts(linkage, tol, count, rng, deadline))


#: ``report["seeding"]`` of a seed generation that the deadline stopped.
STOPPED_BY_TIME = "stopped: time"
#: Bytes of assemblies a rotor sweep holds at once (:func:`iter_seeds` enumerates its angles in
#: chunks of at most this many assemblies' coordinates, ``budget`` per angle).
SWEEP_CHUNK_BYTES = 1 << 26


@dataclass(frozen=True)
class Seeds:
    """Points of the configuration space to start traces from, and what was done."""

    points: list[np.ndarray]
    report: dict[str, object]


def iter_seeds(
    linkage: Linkage,
    tol: Tolerances,
    report: dict[str, object],
    angles: int = 90,
    budget: int = 64,
    random_starts: int = 16,
    seed: int = 0,
    max_rotors: int = 4,
    *,
    with_random: bool = True,
    deadline: Deadline = NEVER,
) -> Iterator[np.ndarray]:
    """The seeds of :func:`seeds`, in the same order, generated on demand.

    A consumer that stops early (the explorer stops at its component budget) does not pay for
    the seeds it never looks at: on long chains the random projections are by far the most
    expensive part (dense least squares from far-off starts, most of which fail). ``report``
    is filled as generation proceeds; its counts describe the seeds generated so far.
    ``with_random=False``: the rotor sweeps' seeds only; :func:`iter_random_seeds` (same
    ``report``, ``random_starts`` and ``seed``) then gives the rest, when it is wanted.
    Once ``deadline`` has passed no more seeds are generated and ``report["seeding"]`` is
    ``"stopped: time"``.
    """
    cons = Constraints(linkage)
    ends = linkage.ends[cons.bars]
    targets = linkage.lengths[cons.bars]
    free = ~np.asarray(linkage.fixed, dtype=bool)
    base_values = int(np.asarray(linkage.positions).size)  # one assembly's coordinates
    swept: list[str] = []
    offset = (np.sqrt(5) - 1) / 2  # irrational offset: avoid symmetric (often critical) angles
    grid = 2 * np.pi * (np.arange(angles) + offset) / angles
    candidates = rotors(linkage)
    if len(candidates) > max_rotors:
        pick = np.linspace(0, len(candidates) - 1, max_rotors).round().astype(int)
        candidates = [candidates[k] for k in sorted(set(pick.tolist()))]
    counts = {"seeds": 0, "random_starts_projected": 0}
    report.update({
        "rotor_sweeps": swept,
        "angles_per_rotor": 0,
        "assembly_budget_per_angle": budget,
        "assemblies_truncated": False,
        "random_starts": random_starts,
        **counts,
    })
    for rotor in candidates:
        if deadline.expired():
            report["seeding"] = STOPPED_BY_TIME
            return
        plan = dyad_plan(linkage, rotor)
        if plan is None:
            continue
        swept.append(linkage.bar_ids[rotor])
        report["angles_per_rotor"] = angles
        # the angles' assemblies enumerated a chunk of angles at once (the same ones, in the
        # same order, as assemblies_at angle by angle) and checked at once (the same residual
        # as cons.max_residual of their coordinates, one vectorised expression); a chunk holds
        # at most SWEEP_CHUNK_BYTES of assemblies (a 20,000-rotor chain's 90 angles x 64
        # assemblies held 3.7 GB at once), and the report still follows the consumer angle by
        # angle
        chunk = max(1, SWEEP_CHUNK_BYTES // max(1, 8 * budget * base_values))
        for first in range(0, len(grid), chunk):
            swept_angles = assemblies_at_angles(linkage, rotor, plan, grid[first:first + chunk],
                                                budget, deadline)
            if deadline.expired():  # (the sweep may be cut anywhere: its seeds are not used)
                report["seeding"] = STOPPED_BY_TIME
                return
            yield from _good_seeds(swept_angles, ends, targets, free, tol, report, counts)
    if with_random:
        yield from iter_random_seeds(linkage, tol, report, random_starts, seed, deadline)


def _good_seeds(swept_angles: list[tuple[list[np.ndarray], bool]], ends: np.ndarray,
                targets: np.ndarray, free: np.ndarray, tol: Tolerances,
                report: dict[str, object], counts: dict[str, int]) -> Iterator[np.ndarray]:
    """The free coordinates of the assemblies of ``swept_angles`` (one chunk of a rotor's
    angles) whose bars have their lengths, angle by angle, counted in ``report``."""
    everything = [a for found, _ in swept_angles for a in found]
    if everything:
        stack = np.array(everything, dtype=float)  # (F, V, d)
        vec = stack[:, ends[:, 0]] - stack[:, ends[:, 1]]
        res = np.max(np.abs(np.sqrt(np.einsum("kij,kij->ki", vec, vec)) - targets), axis=1,
                     initial=0.0)
        good = res <= max(1e3 * tol.residual_atol, 1e-7)
        us = stack[:, free]
    start = 0
    for found, cut in swept_angles:
        if cut:
            report["assemblies_truncated"] = True
        stop = start + len(found)
        for k in range(start, stop):
            if good[k]:
                counts["seeds"] += 1
                report.update(counts)
                yield us[k]
        start = stop


def iter_random_seeds(
    linkage: Linkage,
    tol: Tolerances,
    report: dict[str, object],
    random_starts: int = 16,
    seed: int = 0,
    deadline: Deadline = NEVER,
) -> Iterator[np.ndarray]:
    """The seeds that end :func:`iter_seeds`, after its rotor sweeps: the random projections,
    counted on in ``report`` (as filled by ``iter_seeds(..., with_random=False)``), until
    ``deadline``."""
    # The random projections come last, drawn from one generator in order: stopping early
    # never changes the seeds that were generated.
    rng = np.random.default_rng(seed)
    counts = {k: v if isinstance(v := report.get(k), int) else 0
              for k in ("seeds", "random_starts_projected")}
    for u in iter_projected_random_starts(linkage, tol, random_starts, rng, deadline):
        counts["seeds"] += 1
        counts["random_starts_projected"] += 1
        report.update(counts)
        yield u
    if deadline.expired():  # (conservatively: it may have cut the last projections)
        report["seeding"] = STOPPED_BY_TIME


def seeds(
    linkage: Linkage,
    tol: Tolerances,
    angles: int = 90,
    budget: int = 64,
    random_starts: int = 16,
    seed: int = 0,
    max_rotors: int = 4,
) -> Seeds:
    """Seeds from rotor sweeps (dyad-decomposable planar linkages, at most ``max_rotors``
    rotors, spread along the bar list) and random projections."""
    report: dict[str, object] = {}
    points = list(
        iter_seeds(linkage, tol, report, angles, budget, random_starts, seed, max_rotors)
    )
    return Seeds(points, report)
