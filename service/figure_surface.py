"""The configuration-space figure of a two-degree-of-freedom planar linkage: each surface of the
answer in the direction angles of three bars, drawn in 3D (matplotlib's ``mplot3d``, projected
in a fixed view), the height's critical points and the linkage's own critical points marked.

Angles live on a circle: a triangle whose vertices' angles of one bar differ by more than pi
crosses the cut at +-pi and is left out (the surface is drawn in the cube ``[-pi, pi]^3``, the
torus cut open). SVG ids: ``surface-<k>`` (the triangles of surface ``k``),
``height-critical-<i>`` (the Morse check's points, coloured by index), ``critical-<kind>-<i>``
(the linkage's critical points).
"""

from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure
from mpl_toolkits.mplot3d.art3d import Poly3DCollection

from engine.model.errors import InvalidRequest
from service.figure_drawing import _fixed_axes
from service.schemas import common as c
from service.schemas.space import SpaceResponse

#: Colours of the height's critical points by index (minimum, saddle, maximum; degenerate).
INDEX_COLOURS = {0: "#1f77b4", 1: "#2ca02c", 2: "#d62728", -1: "#7f7f7f"}
#: The view: elevation and azimuth in degrees.
VIEW = (24.0, -58.0)


def degrees_of_freedom(linkage: c.Linkage) -> int:
    """``M - E``: free coordinates less the bars with a moving end (a bar between two pinned
    vertices constrains nothing)."""
    d = linkage.dimension
    free = {v.id: [not f for f in _fixed_axes(v, d)] for v in linkage.vertices}
    m = sum(sum(f) for f in free.values())
    e = sum(1 for b in linkage.bars if any(any(free[v]) for v in b.ends if v in free))
    return m - e


def surface_axes(linkage: c.Linkage, axes: list[str] | None) -> list[tuple[str, str, str]]:
    """Three bars whose direction angles are the axes: ``(bar_id, end_a, end_b)``; default the
    first three bars with a moving end. A 422 naming ``axes`` where one is not such a bar or
    there are not three."""
    d = linkage.dimension
    pinned = {v.id for v in linkage.vertices if all(_fixed_axes(v, d))}
    moving = {b.id: (b.ends[0], b.ends[1]) for b in linkage.bars
              if not set(b.ends) <= pinned}
    if axes is None:
        if len(moving) < 3:
            raise InvalidRequest(f"the linkage has {len(moving)} bar(s) with a moving end; the "
                                 "surface figure needs three for its axes", loc=("axes",))
        return [(b, *moving[b]) for b in list(moving)[:3]]
    if len(axes) != 3:
        raise InvalidRequest("a two-degree-of-freedom linkage's figure takes three axes (bars "
                             "whose direction angles are drawn)", loc=("axes",))
    for k, bar in enumerate(axes):
        if bar not in moving:
            raise InvalidRequest(f"{bar!r} is not a bar with a moving end; such bars: "
                                 f"{', '.join(moving) or 'none'}", loc=("axes", k))
    if len(set(axes)) < 3:
        raise InvalidRequest("the three axes must be different bars", loc=("axes",))
    return [(b, *moving[b]) for b in axes]


def angles(positions: dict[str, list[list[float]]],
           axes: list[tuple[str, str, str]]) -> np.ndarray:
    """Direction angles (N, 3) of the axis bars at each of N mesh vertices."""
    cols = []
    for _, a, b in axes:
        pa, pb = np.asarray(positions[a], dtype=float), np.asarray(positions[b], dtype=float)
        diff = pb - pa
        cols.append(np.arctan2(diff[:, 1], diff[:, 0]))
    return np.stack(cols, axis=1)


def uncut(theta: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """The triangles (T, 3) none of whose angles jumps across +-pi."""
    if not len(triangles):
        return triangles.reshape(0, 3)
    t = theta[triangles]  # (T, 3, 3)
    span = t.max(axis=1) - t.min(axis=1)
    return triangles[(span <= np.pi).all(axis=1)]


def _point_angles(config: dict[str, list[float]], axes: list[tuple[str, str, str]]
                  ) -> np.ndarray:
    return angles({k: [v] for k, v in config.items()}, axes)[0]


def draw_surfaces(ans: SpaceResponse, axes: list[tuple[str, str, str]]) -> Figure:
    """The figure (module docstring)."""
    fig = Figure(figsize=(6.4, 5.6))
    ax = fig.add_subplot(projection="3d")
    # markers over the surface wherever they are (mplot3d's depth order would hide most)
    ax.computed_zorder = False
    light = np.array([0.3, -0.5, 0.8])
    light /= np.linalg.norm(light)
    for k, surf in enumerate(ans.surfaces or []):
        if not isinstance(surf.positions, dict):
            continue  # (the figure asks for per-vertex lists)
        theta = angles(surf.positions, axes)
        tri = uncut(theta, np.asarray(surf.triangles, dtype=np.int64).reshape(-1, 3))
        polys = theta[tri]  # (T, 3, 3)
        normal = np.cross(polys[:, 1] - polys[:, 0], polys[:, 2] - polys[:, 0])
        normal /= np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-300)
        shade = 0.45 + 0.5 * np.abs(normal @ light)
        base = np.array([0.55, 0.65, 0.85]) if surf.closed else np.array([0.85, 0.65, 0.5])
        colours = np.clip(shade[:, None] * base[None], 0.0, 1.0)
        coll = Poly3DCollection(list(polys), facecolors=colours, edgecolors="none",
                                linewidths=0.0)
        coll.set_gid(f"surface-{k}")
        ax.add_collection3d(coll)
    for i, h in enumerate(ans.height_critical_points or []):
        p = _point_angles(h.configuration, axes)
        ax.scatter(*p, s=18, color=INDEX_COLOURS.get(h.index, "#7f7f7f"), depthshade=False,
                   gid=f"height-critical-{i}", zorder=5)
    for cp in ans.critical_points:
        p = _point_angles(cp.configuration, axes)
        ax.scatter(*p, s=40, marker="x", color="black", depthshade=False,
                   gid=f"critical-{cp.kind}-{cp.index}", zorder=6)
    for setter in (ax.set_xlim, ax.set_ylim, ax.set_zlim):
        setter(-np.pi, np.pi)
    names = [f"angle of {b} ({a}->{e})" for b, a, e in axes]
    ax.set_xlabel(names[0])
    ax.set_ylabel(names[1])
    ax.set_zlabel(names[2])
    ax.view_init(*VIEW)
    genus = [s.genus for s in ans.surfaces or []]
    ax.set_title(f"configuration space: {len(genus)} surface(s), genus {genus}; "
                 "height critical points by index (blue min, green saddle, red max), "
                 "linkage critical points x" + ("" if ans.search.complete else
                                                 f" (search incomplete: {ans.search.reason})"),
                 fontsize=8, wrap=True)
    return fig
