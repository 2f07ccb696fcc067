"""How each figure of :mod:`service.figures` is drawn: the linkage, the configuration space,
and the critical values on matplotlib ``Figure`` objects (the object-oriented API only), each
element with the SVG id that :mod:`service.figures` documents (the splitting figure:
:mod:`service.figure_splitting`).
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Sequence

import matplotlib as mpl
import numpy as np
from matplotlib.axes import Axes
from matplotlib.collections import LineCollection
from matplotlib.colors import ListedColormap
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Patch, Rectangle
from scipy import ndimage

from service.mappers.common import decimal_digits
from service.schemas import common as c
from service.schemas import critical_values as cv_schemas
from service.schemas import space

_KIND_MARKERS = {
    "branch": ("X", "#d62728", "branch point"),
    "rigid": ("o", "#111111", "rigid point"),
    "degenerate": ("s", "#ff7f0e", "degenerate point"),
}
_TENSION, _COMPRESSION = "#d62728", "#1f77b4"


# -- shared ------------------------------------------------------------------------------------



def _figure(width: float, height: float) -> Figure:
    return Figure(figsize=(width, height), layout="constrained")


def _fixed_axes(vertex: c.Vertex, dim: int) -> list[bool]:
    return [vertex.fixed] * dim if isinstance(vertex.fixed, bool) else list(vertex.fixed)


def _rotors(linkage: c.Linkage) -> dict[str, tuple[str, str]]:
    """Bars with exactly one fully pinned end: ``{bar_id: (pinned end, moving end)}``, in the
    order of the request (the engine's ``angles`` use the same bars and direction)."""
    pinned = {v.id for v in linkage.vertices if all(_fixed_axes(v, linkage.dimension))}
    out = {}
    for bar in linkage.bars:
        a, b = bar.ends
        if (a in pinned) != (b in pinned):
            out[bar.id] = (a, b) if a in pinned else (b, a)
    return out


def _bar_length(linkage: c.Linkage, bar: c.Bar) -> float:
    if bar.length is not None:
        return float(bar.length)
    pos = {v.id: np.asarray(v.position, dtype=float) for v in linkage.vertices}
    return float(np.linalg.norm(pos[bar.ends[0]] - pos[bar.ends[1]]))


def _pi_ticks(ax: Axes) -> None:
    ticks = np.linspace(-np.pi, np.pi, 5)
    names = ["−π", "−π/2", "0", "π/2", "π"]
    ax.set_xticks(ticks, names)
    ax.set_yticks(ticks, names)


# -- linkage -----------------------------------------------------------------------------------


def _draw_linkage(linkage: c.Linkage, ans: object, show: Sequence[str]) -> Figure:
    conf: dict[str, list[float]] = ans.configuration  # type: ignore[attr-defined]
    ids = [v.id for v in linkage.vertices]
    xy = np.array([conf[i][:2] for i in ids])  # (V, 2): 3D linkages in their x-y projection
    index = {vid: k for k, vid in enumerate(ids)}
    ends = np.array([[index[b.ends[0]], index[b.ends[1]]] for b in linkage.bars],
                    dtype=int).reshape(-1, 2)  # (E, 2)
    given = np.array([np.nan if b.length is None else b.length for b in linkage.bars])
    pos = np.array([v.position for v in linkage.vertices], dtype=float)  # (V, d) as given
    lengths = np.where(np.isnan(given), np.linalg.norm(pos[ends[:, 0]] - pos[ends[:, 1]],
                                                       axis=1), given)
    scale = float(np.median(lengths)) if len(lengths) else 1.0
    fig = _figure(6.4, 5.0)
    ax = fig.add_subplot()
    ax.set_aspect("equal")
    ax.set_xlabel("x")
    ax.set_ylabel("y")
    handles: list[object] = []
    stress = getattr(ans, "self_stress", None) if "self_stress" in show else None
    named = len(linkage.bars) <= NAMED_BARS_MAX
    _draw_bars(ax, linkage, xy[ends], stress, named)
    if stress is not None:
        # A self-stress is defined up to its overall sign: the colours tell the bars that
        # pull from those that push, not which of the two is tension.
        handles += [Line2D([], [], color=_TENSION, lw=3, label="self-stress σ > 0"),
                    Line2D([], [], color=_COMPRESSION, lw=3, label="self-stress σ < 0 "
                           "(opposite sign: one pulls, the other pushes)")]
    kinds = _draw_vertices(ax, linkage, xy, scale, named)
    for kind, label in (("pin", "pin"), ("slider", "slider (dashed: its axis)"),
                        ("vertex", "joint")):
        if kinds[kind]:
            marker, face, _ = _VERTEX_STYLE[kind]
            handles.append(Line2D([], [], marker=marker, mfc=face, mec="#111111", ls="none",
                                  ms=8, label=label))
    arrows: list[tuple[str, str, list[dict[str, list[float]]]]] = []
    if "zero_modes" in show:
        arrows.append(("zero-mode", "zero mode", list(ans.zero_modes)))  # type: ignore[attr-defined]
    if "tangents" in show:
        arrows.append(("tangent", "branch tangent", list(getattr(ans, "tangents", []))))
    tips = [xy]
    palette = iter(["#2ca02c", "#17becf", "#e377c2", "#bcbd22", "#8c564b", "#7f7f7f"])
    for prefix, label, vectors in arrows:
        for j, vec in enumerate(vectors):
            arr = np.array([vec[i][:2] for i in ids])  # (V, 2)
            top = float(np.max(np.linalg.norm(arr, axis=1))) or 1.0
            arr = arr * (0.4 * scale / top)
            colour = next(palette, "#7f7f7f")
            moving = np.linalg.norm(arr, axis=1) > 1e-12
            tips.append(xy + arr)
            ax.quiver(xy[moving, 0], xy[moving, 1], arr[moving, 0], arr[moving, 1],
                      angles="xy", scale_units="xy", scale=1, color=colour, width=0.006,
                      zorder=3, gid=f"{prefix}-{j}")
            handles.append(Line2D([], [], color=colour, lw=2, label=f"{label} {j}"))
    notes = []
    if "self_stress" in show and stress is None:
        notes.append("no self-stress: the configuration is not critical")
    if "tangents" in show and not getattr(ans, "tangents", []):
        notes.append("no branch tangents: not a branch point")
    point_kind = getattr(ans, "kind", None)
    title = "Linkage" + (f" ({point_kind} configuration)" if point_kind else "")
    if linkage.dimension == 3:
        title += ", x-y projection"
    if not named:
        notes.append(f"{len(linkage.bars)} bars, {len(ids)} joints: drawn without their names")
    ax.set_title(title + ("\n" + "; ".join(notes) if notes else ""))
    ax.margins(0.15)
    ax.update_datalim(np.concatenate(tips))  # quiver's arrows do not widen the view
    ax.autoscale_view()
    (x0, x1), (y0, y1) = ax.get_xlim(), ax.get_ylim()
    # as tall as the drawing needs at the figure's width (equal aspect), plus title and legend
    fig.set_size_inches(6.4, float(np.clip(5.6 * (y1 - y0) / (x1 - x0), 1.8, 7.0)) + 1.6)
    fig.legend(handles=handles, loc="outside lower center", ncols=3)
    return fig


#: Most bars drawn one artist each, with their SVG ids ``bar-<k>``, ``pin-<k>``, ... and names;
#: a larger linkage's bars are one ``LineCollection`` (``bars``) and its joints one marker
#: artist per kind (``pins``, ``sliders``, ``vertices``), without names (300 names are
#: unreadable, and laying out their text took seconds).
NAMED_BARS_MAX = 40
_VERTEX_STYLE = {"pin": ("^", "#111111", 10), "slider": ("s", "#9467bd", 10),
                 "vertex": ("o", "white", 8)}
_PLURAL = {"pin": "pins", "slider": "sliders", "vertex": "vertices"}


def _draw_bars(ax: Axes, linkage: c.Linkage, segments: np.ndarray,
               stress: dict[str, float] | None, named: bool) -> None:
    """The bars ``segments`` (E, 2, 2), coloured and widened by the self-stress where shown:
    one artist and name each when ``named``, else one collection."""
    colours = np.full(len(segments), "#555555", dtype=object)
    widths = np.full(len(segments), 2.5)
    if stress is not None and len(segments):
        s = np.array([stress[b.id] for b in linkage.bars])
        colours = np.where(s > 0, _TENSION, np.where(s < 0, _COMPRESSION, "#999999"))
        widths = 1.0 + 5.0 * np.abs(s) / (np.max(np.abs(s)) or 1.0)
    if not named:
        ax.add_collection(LineCollection(list(segments), colors=list(colours),
                                         linewidths=widths, capstyle="round", zorder=2,
                                         gid="bars"))
        return
    for k, bar in enumerate(linkage.bars):
        (p, q) = segments[k]
        ax.plot(*zip(p, q, strict=True), color=colours[k], lw=widths[k],
                solid_capstyle="round", zorder=2, gid=f"bar-{k}")
        text = ax.annotate(bar.id, (p + q) / 2, xytext=(3, 3), textcoords="offset points",
                           color="#333333", fontsize=8)
        text.set_in_layout(False)  # (inside the axes: the layout need not measure it)


def _draw_vertices(ax: Axes, linkage: c.Linkage, xy: np.ndarray, scale: float, named: bool
                   ) -> dict[str, int]:
    """Pins, sliders (with the dashed line they slide along) and joints; their number by
    kind. One marker artist and name each when ``named``, else one artist per kind."""
    masks = [_fixed_axes(v, linkage.dimension) for v in linkage.vertices]
    kind_of = ["pin" if all(m) else "slider" if any(m) else "vertex" for m in masks]
    for kind, (marker, face, size) in _VERTEX_STYLE.items():
        at = [k for k, x in enumerate(kind_of) if x == kind]
        if at and not named:
            ax.plot(xy[at, 0], xy[at, 1], marker=marker, ms=size / 2, mfc=face, mec="#111111",
                    zorder=4, ls="none", gid=_PLURAL[kind])
        for k in at if named else []:
            ax.plot(*xy[k], marker=marker, ms=size, mfc=face, mec="#111111", zorder=4,
                    ls="none", gid=f"{kind}-{k}")
            text = ax.annotate(linkage.vertices[k].id, xy[k], xytext=(-10, -12),
                               textcoords="offset points", fontsize=8)
            text.set_in_layout(False)
    for k in (k for k, x in enumerate(kind_of) if x == "slider"):
        free = np.array([0.0 if f else 1.0 for f in masks[k][:2]])
        if free.any():  # the line along which it slides (its free axes, in x-y)
            seg = np.array([xy[k] - free * scale, xy[k] + free * scale])
            ax.plot(seg[:, 0], seg[:, 1], ls="--", color="#9467bd", lw=1, zorder=1,
                    gid=f"slider-axis-{k}")
    return {kind: kind_of.count(kind) for kind in _VERTEX_STYLE}


# -- configuration space -----------------------------------------------------------------------

#: Most components named one by one in the legend (beyond: one entry for all).
LEGEND_COMPONENTS_MAX = 10


def _angle(conf: dict[str, list[float]], ends: tuple[str, str]) -> float:
    p, q = np.asarray(conf[ends[0]]), np.asarray(conf[ends[1]])
    return float(math.atan2(q[1] - p[1], q[0] - p[0]))


def _wrap(a: np.ndarray) -> np.ndarray:
    return (a + np.pi) % (2 * np.pi) - np.pi


def _torus_pieces(x: np.ndarray, y: np.ndarray) -> Iterator[tuple[np.ndarray, np.ndarray]]:
    """Unwrapped angles -> pieces in the square [-pi, pi)^2 (cut where the walk wraps)."""
    wx, wy = _wrap(x), _wrap(y)
    cuts = np.flatnonzero((np.abs(np.diff(wx)) > np.pi) | (np.abs(np.diff(wy)) > np.pi)) + 1
    for idx in np.split(np.arange(len(x)), cuts):
        if len(idx):
            yield wx[idx], wy[idx]


def _passages(walk: np.ndarray, closed: bool, targets: list[tuple[int, np.ndarray]]
              ) -> list[tuple[int, int]]:
    """Where the walk (n, D) passes through each critical configuration: ``(point index,
    critical index)`` sorted along the walk, one per contiguous close approach."""
    steps = np.linalg.norm(np.diff(walk, axis=0), axis=1)
    radius = 2.0 * float(steps.max()) if steps.size else 0.0
    found = []
    for k, target in targets:
        near = np.linalg.norm(walk - target, axis=1) <= radius
        runs = np.split(np.arange(len(walk)), np.flatnonzero(np.diff(near.astype(int))) + 1)
        runs = [r for r in runs if near[r[0]]]
        if closed and len(runs) > 1 and runs[0][0] == 0 and runs[-1][-1] == len(walk) - 1:
            runs = [np.concatenate([runs[-1], runs[0]]), *runs[1:-1]]  # one run across the end
        for r in runs:
            found.append((int(r[np.argmin(np.linalg.norm(walk[r] - target, axis=1))]), k))
    return sorted(set(found))


def _draw_space(ans: space.SpaceResponse, axes: list[str],
                rotors: dict[str, tuple[str, str]]) -> Figure:
    fig = _figure(6.0, 6.6)
    ax = fig.add_subplot()
    ax.set_aspect("equal")
    pad = 0.08  # markers on the edges of the square stay whole
    ax.set_xlim(-np.pi - pad, np.pi + pad)
    ax.set_ylim(-np.pi - pad, np.pi + pad)
    ax.add_patch(Rectangle((-np.pi, -np.pi), 2 * np.pi, 2 * np.pi, fill=False, lw=0.8,
                           ec="#888888", ls=":"))
    _pi_ticks(ax)
    ax.set_xlabel(f"angle of rotor {axes[0]} (rad)")
    ax.set_ylabel(f"angle of rotor {axes[1]} (rad)")
    ax.grid(color="#e5e5e5", lw=0.6)
    colours = mpl.colormaps["tab10"].colors  # type: ignore[attr-defined]
    handles: list[object] = []
    crit_xy = {cp.index: (_wrap(np.array(_angle(cp.configuration, rotors[axes[0]]))),
                          _wrap(np.array(_angle(cp.configuration, rotors[axes[1]]))))
               for cp in ans.critical_points}
    remaining = [(s.from_, s.to) for s in ans.segments]
    labelled = 0
    for k, comp in enumerate(ans.components):
        colour = colours[k % len(colours)]
        # the figure asks for the per-vertex lists (never options.points = "compact")
        assert isinstance(comp.angles, dict) and isinstance(comp.positions, dict)
        x, y = np.asarray(comp.angles[axes[0]]), np.asarray(comp.angles[axes[1]])
        for p, (px, py) in enumerate(_torus_pieces(x, y)):
            ax.plot(px, py, color=colour, lw=1.8, zorder=2, gid=f"component-{k}-{p}")
        if len(ans.components) <= LEGEND_COMPONENTS_MAX:
            handles.append(Line2D([], [], color=colour, lw=2, label=f"component {k} "
                                  f"({'closed' if comp.closed else 'open'})"))
        # The segments: the walk cut where it passes through critical points, each piece
        # labelled with the critical points it joins (as in the answer's ``segments``).
        ids = list(comp.positions)
        walk = np.concatenate([np.asarray(comp.positions[v]) for v in ids], axis=1)
        targets = [(cp.index, np.concatenate([np.asarray(cp.configuration[v]) for v in ids]))
                   for cp in ans.critical_points if cp.index in comp.critical_points]
        cuts = _passages(walk, comp.closed, targets)
        pieces = list(zip(cuts, cuts[1:], strict=False))
        if comp.closed and len(cuts) > 1:
            pieces.append((cuts[-1], (cuts[0][0] + len(walk) - 1, cuts[0][1])))
        for (i, a), (j, b) in pieces:
            pair = next((p for p in remaining if p in ((a, b), (b, a))), None)
            if pair is None:
                continue
            remaining.remove(pair)
            mid = ((i + j) // 2) % len(walk)
            ax.annotate(f"{pair[0]}–{pair[1]}", (_wrap(x[mid]), _wrap(y[mid])),
                        xytext=(4, 4), textcoords="offset points", fontsize=7,
                        color=colour, gid=f"segment-{labelled}")
            labelled += 1
    if len(ans.components) > LEGEND_COMPONENTS_MAX:  # (a legend of 32 entries: unreadable)
        closed = sum(comp.closed for comp in ans.components)
        handles.insert(0, Line2D([], [], color=colours[0], lw=2, label=(
            f"components 0-{len(ans.components) - 1} ({closed} closed), colours repeating")))
    seen = set()
    for cp in ans.critical_points:
        marker, colour, label = _KIND_MARKERS.get(cp.kind, ("D", "#7f7f7f", cp.kind))
        px, py = crit_xy[cp.index]
        ax.plot(px, py, marker=marker, ms=10, mfc=colour, mec="white", ls="none", zorder=4,
                gid=f"critical-{cp.kind}-{cp.index}")
        ax.annotate(str(cp.index), (px, py), xytext=(6, -10), textcoords="offset points",
                    fontsize=8, fontweight="bold")
        if cp.kind not in seen:
            seen.add(cp.kind)
            handles.append(Line2D([], [], marker=marker, mfc=colour, mec="white", ms=9,
                                  ls="none", label=label))
    if labelled:
        handles.append(Line2D([], [], ls="none", label="i–j: segment between critical points"))
    m = len(ans.critical_points)
    ax.set_title(f"Configuration space: {_components_text(ans)}, "
                 f"{m} critical point{'s' * (m != 1)}"
                 + ("" if ans.search.complete else f" (search incomplete: {ans.search.reason})"))
    if handles:
        fig.legend(handles=handles, loc="outside lower center", ncols=2)
    return fig


def _components_text(ans: space.SpaceResponse) -> str:
    """The count as it is known: the rules' exact total beside the traced ones where they
    differ, ``>= n`` where the search is incomplete without a total (a lower bound)."""
    n = len(ans.components)
    total = (ans.search.model_extra or {}).get("components_total")
    if total is not None and str(total) != str(n):
        return f"{total} components ({n} traced)"
    if total is None and not ans.search.complete:
        return f">= {n} component{'s' * (n != 1)}"
    return f"{n} component{'s' * (n != 1)}"


def _signs_text(signs: Sequence[int]) -> str:
    return "(" + ",".join("+" if x > 0 else "-" if x < 0 else "0" for x in signs) + ")"


def region_text(r: cv_schemas.RegionOut) -> str:
    """A region's label on the map: its count (``>=`` a lower bound), the tau signs of its
    first four-bar cell (the gate's on a gated chain, as Fig. 5b) and gated or not."""
    if r.components is None:
        return "?"
    lines = [("" if r.components_exact is not False else ">=") + str(r.components)]
    if r.tau_signs:
        lines.append(_signs_text(r.tau_signs[0].signs))
    if r.gated is not None:
        lines.append("gated" if r.gated else "ungated")
    return "\n".join(lines)


#: Shades of gated and ungated regions (the paper's Fig. 5b: blue gated, red ungated).
GATED_SHADES = {True: "#cfe3f5", False: "#f6d0d8", None: "#e6e6e6"}


# -- critical values ---------------------------------------------------------------------------


def _legend_text(kind: str) -> str:
    if not kind.isdigit():
        return {"gated": "gated: no rotor completes a turn",
                "ungated": "ungated: the rotors turn fully"}.get(kind, "gated undecided")
    m = int(kind)
    return f"{m} component{'s' * (m != 1)}" + (" (empty)" if m == 0 else "")


def _region_raster(box: np.ndarray, curves: list[np.ndarray], n: int) -> np.ndarray:
    """Label (n, n) of the cells of the box between the curves (cells on a curve take the
    label of the nearest free cell), indexed [i along axis 0, j along axis 1]."""
    span = box[:, 1] - box[:, 0]
    blocked = np.zeros((n, n), dtype=bool)
    for curve in curves:
        seg = np.diff(curve, axis=0)
        steps = np.maximum(1, np.ceil(3 * n * np.max(np.abs(seg) / span, axis=1))).astype(int)
        for a, d, s in zip(curve[:-1], seg, steps, strict=True):
            pts = a + np.linspace(0.0, 1.0, s + 1)[:, None] * d
            ij = np.clip(((pts - box[:, 0]) / span * n).astype(int), 0, n - 1)
            blocked[ij[:, 0], ij[:, 1]] = True
    labels, _ = ndimage.label(~blocked)
    if blocked.any() and not blocked.all():
        _, (ii, jj) = ndimage.distance_transform_edt(blocked, return_indices=True)
        labels = labels[ii, jj]
    return labels


#: Digits of a region's count drawn as they are; longer counts (a 20000-rotor chain's region
#: has 2^19999 components: 6,020 digits, which ``int`` and ``str`` refuse) as a magnitude.
LABEL_DIGITS_MAX = 18


def _count_label(count: int | str | None) -> str:
    """A region's count for its label and legend: its digits, or ``about 10^k``."""
    digits = count if isinstance(count, str) else decimal_digits(int(count or 0))
    return digits if len(digits) <= LABEL_DIGITS_MAX else f"about 10^{len(digits) - 1}"


def _draw_critical_values(body: cv_schemas.CriticalValuesRequest,
                          ans: cv_schemas.CriticalValuesResponse) -> Figure:
    box = np.array([[a.min, a.max] for a in body.axes])
    fig = _figure(6.0, 6.0)
    ax = fig.add_subplot()
    ax.set_xlabel(f"length of bar {body.axes[0].bar}")
    ax.set_ylabel(f"length of bar {body.axes[1].bar}")
    curves = [np.asarray(cv, dtype=float).reshape(-1, 2) for cv in ans.curves]
    n = 240
    labels = _region_raster(box, [cv for cv in curves if len(cv) >= 2], n)
    gate_map = any(r.gated is not None for r in ans.regions)
    # a region's class: gated or not on a gate's map (the paper's colours), else its count
    def kind(r: cv_schemas.RegionOut) -> str:
        if gate_map and r.components not in (0, "0"):
            return {True: "gated", False: "ungated", None: "undecided"}[r.gated]
        return _count_label(r.components)

    counts = sorted({kind(r) for r in ans.regions if r.components is not None},
                    key=lambda c: (not c.isdigit(), int(c) if c.isdigit() else 0, c))
    shades = ["#f2f2f2", "#cfe3f5", "#f7d9b9", "#d5ecd0", "#e8d5f0", "#f6d0d8"]
    colour_of = {m: (GATED_SHADES[{"gated": True, "ungated": False}.get(m)]
                     if not m.isdigit() else "#f2f2f2" if m == "0"
                     else shades[min(k + 1, len(shades) - 1)])
                 for k, m in enumerate(counts)}
    cell = np.full((n, n), -1, dtype=int)  # index into counts, -1: no region sampled here
    span = box[:, 1] - box[:, 0]
    spots = []  # where each region's label goes: its drawn cell farthest from its edges
    for r in ans.regions:
        i, j = np.clip(((np.asarray(r.point) - box[:, 0]) / span * n).astype(int), 0, n - 1)
        mine = labels == labels[i, j]
        if r.components is not None:  # (None: not explored in time, left white)
            cell[mine] = counts.index(kind(r))
        depth = ndimage.distance_transform_edt(np.pad(mine, 1))[1:-1, 1:-1]
        ij = np.unravel_index(int(np.argmax(depth)), depth.shape)
        spots.append(box[:, 0] + span * (np.array(ij) + 0.5) / n)
    if counts:
        cmap = ListedColormap(["white"] + [colour_of[m] for m in counts])
        ax.imshow((cell + 1).T, origin="lower", extent=(*box[0], *box[1]), cmap=cmap,
                  vmin=-0.5, vmax=len(counts) + 0.5, interpolation="nearest", aspect="auto",
                  gid="cv-regions")
    for k, cv in enumerate(curves):
        ax.plot(cv[:, 0], cv[:, 1], color="#111111", lw=1.6, gid=f"cv-curve-{k}")
    for k, r in enumerate(ans.regions):
        label = region_text(r)
        ax.annotate(label, spots[k], ha="center", va="center",
                    fontsize=10 if "\n" not in label else 7,
                    fontweight="bold", gid=f"region-{k}-{r.components}",
                    bbox={"boxstyle": "circle,pad=0.25" if "\n" not in label
                          else "round,pad=0.25", "fc": "white", "ec": "#888888", "lw": 0.6})
    bars = {b.id: b for b in body.linkage.bars}
    here = [_bar_length(body.linkage, bars[a.bar]) for a in body.axes if a.bar in bars]
    handles: list[object] = [Line2D([], [], color="#111111", lw=1.6,
                                    label="critical values")]
    if len(here) == 2 and all(box[k, 0] <= here[k] <= box[k, 1] for k in range(2)):
        ax.plot(*here, marker="*", ms=13, mfc="#ffd92f", mec="#111111", ls="none", zorder=5,
                gid="current-lengths")
        handles.append(Line2D([], [], marker="*", mfc="#ffd92f", mec="#111111", ms=11,
                              ls="none", label="the linkage's lengths"))
    handles += [Patch(fc=colour_of[m], ec="#888888", label=_legend_text(m)) for m in counts]
    if any(r.tau_signs for r in ans.regions):
        first = next(r.tau_signs[0] for r in ans.regions if r.tau_signs)
        handles.append(Line2D([], [], ls="none", label=f"(tau1,tau2,tau3) of the {first.cell} "
                              "four-bar" if first.cell == "gate" else
                              f"(tau1,tau2,tau3) of the four-bar {first.cell}"))
    if any(r.components_exact is False for r in ans.regions):
        handles.append(Line2D([], [], ls="none", label=">= n: a lower bound (n traced)"))
    ax.set_xlim(*box[0])
    ax.set_ylim(*box[1])
    ax.set_title(f"Critical values: {len(curves)} curve{'s' * (len(curves) != 1)}, "
                 f"{len(ans.regions)} region{'s' * (len(ans.regions) != 1)}"
                 + ("" if ans.search.complete else
                    f"\nincomplete ({ans.search.reason}): curves or regions may be missing"))
    fig.legend(handles=handles, loc="outside lower center", ncols=2 if gate_map else 3)
    return fig
