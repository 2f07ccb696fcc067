"""TikZ of the linkage and configuration-space figures: a ``tikzpicture`` a paper includes with
``\\input`` (needs ``\\usepackage{tikz}`` only, no TikZ library), drawn from the same answers
as the SVG (:mod:`service.figures`), with the same elements as the SVG (bars, pins, sliders and
their axes, joints, labels, zero modes or tangents; components on the torus, critical points by
kind), each preceded by a ``%`` comment naming it as the SVG's id does (``% bar-0 L1``).

Coordinates are the linkage's own (lengths in its units, scaled by the picture's ``x``/``y``)
and the rotor angles in radians; marks and labels have fixed sizes (mm, ``\\footnotesize``).
A component's walk is thinned to at most :data:`MAX_POINTS` points (every k-th, ends kept) so
that TeX's memory is never the limit.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence

import numpy as np

from service.figure_drawing import _angle, _bar_length, _fixed_axes, _torus_pieces, _wrap
from service.schemas import common as c
from service.schemas import space

#: The most points of one component's walk written (a figure of 10^5 points is thinned).
MAX_POINTS = 4000
#: Width of the drawing in cm (the picture's unit is set so that it is this wide).
WIDTH_CM = 8.0
#: Colours of components and arrows (xcolor expressions: TikZ loads xcolor).
PALETTE = ("blue!80!black", "orange!90!black", "green!55!black", "red!80!black", "violet",
           "brown", "magenta!80!black", "gray", "olive", "cyan!70!black")
#: Colours of zero modes and tangents (none of them the self-stress's red or blue).
ARROWS = ("green!55!black", "cyan!70!black", "magenta!80!black", "olive", "brown", "gray")
_TEX_SPECIAL = {"\\": r"\textbackslash{}", "{": r"\{", "}": r"\}", "$": r"\$", "&": r"\&",
                "#": r"\#", "^": r"\^{}", "_": r"\_", "%": r"\%", "~": r"\~{}"}
_HEAD = ("% {what}: TikZ written by the linkage topology service (POST /v1/figures/{path}).\n"
         "% In a LaTeX document with \\usepackage{{tikz}} (no library needed): "
         "\\input{{this file}}.\n")


def tex(text: str) -> str:
    """``text`` with TeX's special characters escaped (an id in a node or a comment).

    Examples
    --------
    >>> tex("L_1 & 50%")
    'L\\\\_1 \\\\& 50\\\\%'
    """
    return "".join(_TEX_SPECIAL.get(ch, ch) for ch in text)


def _num(x: float) -> str:
    return f"{x:.5g}" if abs(x) >= 1e-9 else "0"


def _pt(p: Iterable[float]) -> str:
    return "(" + ",".join(_num(float(v)) for v in p) + ")"


def _picture(unit: float, styles: Sequence[str], body: list[str], what: str, path: str) -> bytes:
    opts = ",\n  ".join([f"x={_num(unit)}cm", f"y={_num(unit)}cm", *styles])
    text = (_HEAD.format(what=what, path=path) + f"\\begin{{tikzpicture}}[\n  {opts}]\n"
            + "\n".join(body) + "\n\\end{tikzpicture}\n")
    return text.encode("utf-8")


# -- linkage -----------------------------------------------------------------------------------


def _marks(kind: str, p: np.ndarray, k: int) -> list[str]:
    at = _pt(p)
    if kind == "pin":  # a filled triangle on the joint
        return [f"% pin-{k}", f"\\fill[black] {at} ++(-1.2mm,-1mm) -- ++(2.4mm,0) "
                "-- ++(-1.2mm,2.1mm) -- cycle;"]
    if kind == "slider":
        return [f"% slider-{k}", f"\\filldraw[fill=violet!60, draw=black] {at} "
                "++(-1mm,-1mm) rectangle ++(2mm,2mm);"]
    return [f"% vertex-{k}", f"\\filldraw[fill=white, draw=black] {at} circle[radius=0.9mm];"]


def linkage(lk: c.Linkage, ans: object, show: Sequence[str]) -> bytes:
    """The linkage at the answer's configuration (x-y projection of a 3D one) as TikZ."""
    conf: dict[str, list[float]] = ans.configuration  # type: ignore[attr-defined]
    ids = [v.id for v in lk.vertices]
    xy = np.array([conf[i][:2] for i in ids])  # (V, 2)
    index = {vid: k for k, vid in enumerate(ids)}
    lengths = [_bar_length(lk, b) for b in lk.bars]
    scale = float(np.median(lengths)) if lengths else 1.0
    span = float(np.ptp(xy[:, 0])) if len(xy) else 0.0
    unit = WIDTH_CM / max(span, scale)
    body: list[str] = []
    stress = getattr(ans, "self_stress", None) if "self_stress" in show else None
    top = max((abs(v) for v in stress.values()), default=0.0) if stress else 0.0
    for k, bar in enumerate(lk.bars):
        p, q = xy[index[bar.ends[0]]], xy[index[bar.ends[1]]]
        style = "bar"
        if stress is not None and top > 0:
            s = stress[bar.id]
            colour = "red!80!black" if s > 0 else "blue!80!black" if s < 0 else "gray"
            style += f", draw={colour}, line width={_num(0.6 + 2.4 * abs(s) / top)}pt"
        body += [f"% bar-{k} {tex(bar.id)}",
                 f"\\draw[{style}] {_pt(p)} -- {_pt(q)} node[midway, idlabel] {{{tex(bar.id)}}};"]
    arrows: list[tuple[str, list[dict[str, list[float]]]]] = []
    if "zero_modes" in show:
        arrows.append(("zero-mode", list(ans.zero_modes)))  # type: ignore[attr-defined]
    if "tangents" in show:
        arrows.append(("tangent", list(getattr(ans, "tangents", []))))
    colours = iter(ARROWS)
    for prefix, vectors in arrows:
        for j, vec in enumerate(vectors):
            arr = np.array([vec[i][:2] for i in ids])  # (V, 2)
            arr = arr * (0.4 * scale / (float(np.max(np.linalg.norm(arr, axis=1))) or 1.0))
            colour = next(colours, "gray")
            body.append(f"% {prefix}-{j}")
            body += [f"\\draw[arrow, draw={colour}] {_pt(p)} -- ++{_pt(d)};"
                     for p, d in zip(xy, arr, strict=True) if np.linalg.norm(d) > 1e-12]
    for k, v in enumerate(lk.vertices):
        mask = _fixed_axes(v, lk.dimension)
        kind = "pin" if all(mask) else "slider" if any(mask) else "vertex"
        if kind == "slider":  # the line along which it slides (its free axes, in x-y)
            free = np.array([0.0 if f else 1.0 for f in mask[:2]])
            if free.any():
                body += [f"% slider-axis-{k}", f"\\draw[dashed, violet] {_pt(xy[k] - free * scale)}"
                         f" -- {_pt(xy[k] + free * scale)};"]
        body += _marks(kind, xy[k], k)
        body.append(f"\\node[idlabel, below left] at {_pt(xy[k])} {{{tex(v.id)}}};")
    styles = ["bar/.style={line width=1.6pt, line cap=round, draw=black!70}",
              "idlabel/.style={font=\\footnotesize, above left, inner sep=1.5pt}",
              "arrow/.style={->, thick}"]
    what = "Linkage" + (" (x-y projection)" if lk.dimension == 3 else "")
    return _picture(unit, styles, body, what, "linkage")


# -- configuration space -----------------------------------------------------------------------


def _thin(x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """At most :data:`MAX_POINTS` points of a walk: every k-th, the last one kept."""
    step = math.ceil(len(x) / MAX_POINTS)
    if step <= 1:
        return x, y
    keep = np.unique(np.append(np.arange(0, len(x), step), len(x) - 1))
    return x[keep], y[keep]


def _critical_mark(kind: str, at: str) -> str:
    if kind == "branch":  # a cross
        return (f"\\draw[red!80!black, very thick] {at} ++(-1.2mm,-1.2mm) -- ++(2.4mm,2.4mm) "
                f"{at} ++(-1.2mm,1.2mm) -- ++(2.4mm,-2.4mm);")
    if kind == "degenerate":
        return f"\\fill[orange] {at} ++(-1.1mm,-1.1mm) rectangle ++(2.2mm,2.2mm);"
    return f"\\fill[black] {at} circle[radius=1.1mm];"


def configuration_space(ans: space.SpaceResponse, axes: list[str],
                        rotors: dict[str, tuple[str, str]]) -> bytes:
    """The components in the angles of the rotors ``axes`` on the square [-pi, pi)^2 (the
    torus cut open), critical points marked by kind and numbered, as TikZ."""
    pi = math.pi
    body = [f"\\draw[gray, dotted] {_pt((-pi, -pi))} rectangle {_pt((pi, pi))};"]
    for k, name in enumerate(("$-\\pi$", "$-\\pi/2$", "$0$", "$\\pi/2$", "$\\pi$")):
        t = -pi + k * pi / 2
        body += [f"\\draw[gray] {_pt((t, -pi))} -- ++(0,-1mm) node[below, tick] {{{name}}};",
                 f"\\draw[gray] {_pt((-pi, t))} -- ++(-1mm,0) node[left, tick] {{{name}}};"]
    body += [f"\\node[below=6mm] at {_pt((0, -pi))} {{angle of rotor {tex(axes[0])} (rad)}};",
             f"\\node[left=9mm, rotate=90, anchor=south] at {_pt((-pi, 0))} "
             f"{{angle of rotor {tex(axes[1])} (rad)}};"]
    for k, comp in enumerate(ans.components):
        colour = PALETTE[k % len(PALETTE)]
        assert isinstance(comp.angles, dict)  # the figure asks for the per-vertex lists
        x, y = np.asarray(comp.angles[axes[0]]), np.asarray(comp.angles[axes[1]])
        x, y = _thin(x, y)
        for p, (px, py) in enumerate(_torus_pieces(x, y)):
            points = " ".join(_pt(q) for q in zip(px, py, strict=True))
            body += [f"% component-{k}-{p} ({'closed' if comp.closed else 'open'})",
                     f"\\draw[component, draw={colour}] plot coordinates {{{points}}};"]
    for cp in ans.critical_points:
        at = _pt([float(_wrap(np.array(_angle(cp.configuration, rotors[a])))) for a in axes])
        body += [f"% critical-{cp.kind}-{cp.index}", _critical_mark(cp.kind, at),
                 f"\\node[tick, below right] at {at} {{\\textbf{{{cp.index}}}}};"]
    n, m = len(ans.components), len(ans.critical_points)
    title = (f"Configuration space: {n} component{'s' * (n != 1)}, {m} critical "
             f"point{'s' * (m != 1)}"
             + ("" if ans.search.complete else f" (search incomplete: {ans.search.reason})"))
    body.append(f"\\node[above=2mm] at {_pt((0, pi))} {{{tex(title)}}};")
    styles = ["component/.style={line width=1.2pt, line join=round}",
              "tick/.style={font=\\footnotesize}"]
    return _picture(WIDTH_CM / (2 * pi), styles, body, "Configuration space",
                    "configuration-space")

