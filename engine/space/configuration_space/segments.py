"""Segments between critical points (traced along the rays of each branch point) and the
components they make (Eulerian walks of the graph of critical points and segments).
"""

from __future__ import annotations

import numpy as np

from engine.local.critical import CriticalPoint
from engine.model.tolerances import NORM_FLOOR
from engine.space.configuration_space.explorer import Explorer
from engine.space.configuration_space.results import Component, Segment, rays
from engine.space.trace import (
    STOP_TIME,
    Curve,
    correct,
    distances_to_segment,
    polyline_distance,
    trace_curve,
)


def trace_segments(ex: Explorer, crit: list[CriticalPoint]) -> tuple[list[Segment], bool]:
    """From every branch point along each of its four rays, trace until the next critical point
    (each pair of rays joined once): the segments, and whether every ray arrived."""
    out: list[Segment] = []
    seen: set[frozenset[tuple[int, int]]] = set()
    complete = True
    h0 = 0.05 * ex.h_max
    capture = 0.05 * ex.h_max
    centres = np.array([c.u for c in crit])
    for i, cp in enumerate(crit):
        if cp.kind != "branch":
            continue
        ex.deadline.report(0.8 + 0.2 * i / len(crit), "tracing the segments")
        for r, ray in enumerate(rays(cp)):
            if any((i, r) in key for key in seen):
                continue
            if ex.out_of_time() or ex.size_reached():
                complete = False
                break
            v = cp.u + h0 * ray
            w, ok, _ = correct(ex.cons, v, ray, ex.tol)
            if not ok:
                complete = False
                continue

            def stop(a: np.ndarray, b: np.ndarray, t: np.ndarray, _i: int = i,
                     _w: np.ndarray = w) -> str | None:
                j = captured(a, b, centres, capture, _i, _w, 2 * h0)
                return None if j is None else f"critical:{j}"

            curve = trace_curve(ex.cons, w, ray, ex.tol, ex.trace_options(), stop=stop,
                                close=False, deadline=ex.deadline)
            ex.timed_out = ex.timed_out or curve.stop == STOP_TIME
            ex.spend(len(curve.points) + 1)
            if not curve.stop.startswith("critical:"):
                complete = False
                continue
            j = int(curve.stop.split(":")[1])
            end_ray = _arrival_ray(crit[j], curve.points[-2] if len(curve.points) > 1
                                   else curve.points[-1], curve.tangents[-1])
            key = frozenset({(i, r), (j, end_ray)})
            if key in seen:
                continue
            seen.add(key)
            pts = np.vstack([cp.u, np.array(curve.points[:-1]), crit[j].u])
            out.append(Segment(i, r, j, end_ray, pts))
    return out, complete


def captured(a: np.ndarray, b: np.ndarray, centres: np.ndarray, capture: float, own: int,
             start: np.ndarray, leave: float) -> int | None:
    """The first critical point (row of ``centres``) within ``capture`` of the step ``[a, b]``,
    or None; the ray's own point ``own`` only once ``b`` is ``leave`` or more from the ray's
    ``start``. One vectorised pass over the centres (a step of a segment's tracing)."""
    near = distances_to_segment(a, b, centres) <= capture
    if near[own] and np.linalg.norm(b - start) < leave:
        near[own] = False
    hits = np.flatnonzero(near)
    return int(hits[0]) if len(hits) else None


def _arrival_ray(cp: CriticalPoint, near: np.ndarray, heading: np.ndarray | None = None) -> int:
    """The ray of branch point ``cp`` a segment arrives on: the one pointing back towards its
    last point ``near`` before capture or, with the segment's unit ``heading`` there, back
    along it (the curve's own tangent: the point may lie a step away, where a branch that
    crosses the other at a small angle has already curved towards the wrong ray)."""
    if cp.kind != "branch":
        return -1
    d = near - cp.u if heading is None else -np.asarray(heading, dtype=float)
    return int(np.argmax(rays(cp) @ (d / max(np.linalg.norm(d), NORM_FLOOR))))


def euler_walks(n_nodes: int, segs: list[Segment]) -> list[list[tuple[int, bool]]]:
    """Walks covering every segment once (Hierholzer per connected piece): (segment, reversed)."""
    adj: dict[int, list[int]] = {k: [] for k in range(n_nodes)}
    for s, seg in enumerate(segs):
        adj[seg.start].append(s)
        if seg.end != seg.start:
            adj[seg.end].append(s)
        else:
            adj[seg.start].append(s)
    used = [False] * len(segs)
    walks: list[list[tuple[int, bool]]] = []
    for s0 in range(len(segs)):
        if used[s0]:
            continue
        odd = [v for v in adj if len(adj[v]) % 2 == 1]
        start = segs[s0].start if not odd else odd[0]
        stack: list[tuple[int, int, bool]] = [(start, -1, False)]
        path: list[tuple[int, bool]] = []
        while stack:
            node, via, rev = stack[-1]
            nxt = next((s for s in adj[node] if not used[s]), None)
            if nxt is None:
                stack.pop()
                if via >= 0:
                    path.append((via, rev))
                continue
            used[nxt] = True
            seg = segs[nxt]
            forward = seg.start == node
            stack.append((seg.end if forward else seg.start, nxt, not forward))
        if path:
            walks.append(path[::-1])
    return walks


def mark_through_start(components: list[Component], start: np.ndarray | None,
                        h_max: float) -> None:
    """Flag the component that passes through ``start`` (nearest walk, within ``h_max``)."""
    if start is None or not components:
        return
    dist = [polyline_distance(c.points, start) for c in components]
    best = int(np.argmin(dist))
    if dist[best] <= h_max:
        c = components[best]
        components[best] = Component(c.points, c.closed, True, c.critical_points, c.segments)


def assemble_components(
    ex: Explorer, crit: list[CriticalPoint], segs: list[Segment], degenerate: bool
) -> list[Component]:
    """The components: traced curves that meet no critical point (all of them when a critical
    point is degenerate: the segments are not traced then), the Eulerian walks of the graph of
    critical points and segments, and rigid critical points on no segment (isolated points)."""
    components: list[Component] = []
    capture = 0.05 * ex.h_max

    def touching(curve: Curve) -> list[int]:
        pts = curve.array("points")
        return [k for k, c in enumerate(crit)
                if np.min(np.linalg.norm(pts - c.u, axis=1)) <= ex.h_max]

    for curve in ex.curves:
        near = touching(curve)
        if near and not degenerate:
            continue  # covered by the segments
        pts = curve.array("points").copy()  # the component's own array (writeable)
        closed = curve.stop == "closed"
        if closed:
            pts = np.vstack([pts, pts[:1]])
        components.append(Component(pts, closed, False, near, []))
    for walk in euler_walks(len(crit), segs):
        pieces = [segs[s].points[::-1] if rev else segs[s].points for s, rev in walk]
        pts = np.vstack([pieces[0]] + [p[1:] for p in pieces[1:]])
        nodes = sorted({segs[s].start for s, _ in walk} | {segs[s].end for s, _ in walk})
        closed = bool(np.linalg.norm(pts[0] - pts[-1]) <= capture)
        components.append(Component(pts, closed, False, nodes, [s for s, _ in walk]))
    on_segments = {n for c in components for n in c.critical_points}
    for k, cp in enumerate(crit):
        if k not in on_segments and cp.kind == "rigid":
            components.append(Component(cp.u[None, :], True, False, [k], []))
    return components
