"""How the splitting figure of :mod:`service.figures` is drawn: one panel per branch point, its
unperturbed rays and the perturbed curves, on a matplotlib ``Figure`` (object-oriented API only),
each element with the SVG id that :mod:`service.figures` documents.
"""

from __future__ import annotations

import math

import numpy as np
from matplotlib.figure import Figure
from matplotlib.lines import Line2D

from service.figure_drawing import _figure
from service.schemas import space
from service.schemas import splitting as splitting_schemas


def _coefficients(vector: dict[str, list[float]], modes: list[dict[str, list[float]]]
                  ) -> np.ndarray:
    """A per-vertex vector on the zero modes (orthonormal, so by inner products)."""
    ids = list(vector)
    flat = np.concatenate([np.asarray(vector[i]) for i in ids])
    return np.array([flat @ np.concatenate([np.asarray(m[i]) for i in ids]) for m in modes])


#: Seconds to lay out and save one panel of the splitting figure (a branch point), and the
#: figure's own (title, legend), measured on the shared test machine (three-rotor, twelve panels:
#: 0.07 s per panel drawn and 0.3 s saved unloaded, 6 to 16 s for the twelve under load),
#: conservative: the panels drawn are those that fit the time left (:func:`panels_in_time`).
PANEL_SECONDS = 0.5
FIGURE_SECONDS = 0.2


def panels_in_time(seconds: float) -> int:
    """Panels of the splitting figure drawn and saved in ``seconds`` (at least one)."""
    return max(1, int((seconds - FIGURE_SECONDS) / PANEL_SECONDS))


def _draw_splitting(body: splitting_schemas.SplittingRequest,
                    ans: splitting_schemas.SplittingResponse,
                    points: list[space.CriticalPointOut],
                    panels_max: int | None = None) -> Figure:
    """One panel per branch point, the first ``panels_max`` of them (None: all); the title
    says how many were left out."""
    found = ans.branch_points
    branches = found if panels_max is None else found[:max(1, panels_max)]
    cols = min(3, max(1, len(branches)))
    rows = max(1, math.ceil(len(branches) / cols))
    fig = _figure(3.2 * cols + 1.6, 3.2 * rows + 0.6)
    change = ", ".join(f"d{bar} = {v:+.3g}" for bar, v in body.perturbation.items())
    left_out = len(found) - len(branches)
    title = fig.suptitle(f"Splitting of the branch points under {change or 'no change'}" + (
        f"\n(first {len(branches)} of {len(found)} branch points drawn: {left_out} panels "
        "left out to answer within the time budget)" if left_out else "") + (
        "" if ans.search.complete else
        f"\n(search incomplete: {ans.search.reason}; branch points may be missing)"))
    if left_out:
        title.set_gid(f"panels-left-out-{left_out}")  # (the text is drawn as paths)
    if not branches:
        ax = fig.add_subplot()
        ax.set_axis_off()
        ax.text(0.5, 0.5, f"no branch point among the {ans.critical_points_found} critical "
                "points found", ha="center", va="center")
        return fig
    by_index = {p.index: p for p in points}
    ray_colours = ["#1f77b4", "#1f77b4", "#ff7f0e", "#ff7f0e"]
    for n, b in enumerate(branches):
        ax = fig.add_subplot(rows, cols, n + 1)
        cp = by_index[b.index]
        lam = np.asarray(cp.q_eigenvalues or [1.0, -1.0])  # (2,), lam[0] > 0 > lam[1]
        t = np.array([_coefficients(v, cp.zero_modes) for v in cp.tangents])  # (2, 2)
        rays = np.array([t[0], -t[0], t[1], -t[1]])  # numbered 0..3 as in the answer
        rays /= np.linalg.norm(rays, axis=1, keepdims=True)
        shift = np.asarray(b.shift)
        gap = math.sqrt(abs(b.delta) / min(abs(lam[0]), abs(lam[1]))) if b.delta else 0.0
        reach = 4.0 * max(gap, float(np.linalg.norm(shift)), 1e-12)
        for r, d in enumerate(rays):
            ax.plot([0, reach * d[0]], [0, reach * d[1]], ls="--", lw=1.2,
                    color=ray_colours[r], gid=f"ray-{b.index}-{r}")
            ax.annotate(f"ray {r}", 0.85 * reach * d, fontsize=8, color=ray_colours[r],
                        ha="center", va="bottom")
        s = np.linspace(-3.0, 3.0, 121)
        if b.delta != 0 and lam[0] > 0 > lam[1]:
            a0, a1 = math.sqrt(abs(b.delta) / lam[0]), math.sqrt(abs(b.delta) / -lam[1])
            for side in (1.0, -1.0):
                if b.delta > 0:  # opens along the first zero mode: c_1 = +-a0 cosh s
                    pts = np.stack([side * a0 * np.cosh(s), a1 * np.sinh(s)], axis=1)
                else:
                    pts = np.stack([a0 * np.sinh(s), side * a1 * np.cosh(s)], axis=1)
                pts = pts + shift
                pts = pts[np.linalg.norm(pts, axis=1) <= reach]
                end = pts[-1] - shift
                joined = sorted(int(np.argmax(rays @ p)) for p in (pts[0] - shift, end))
                ax.plot(pts[:, 0], pts[:, 1], color="#2ca02c", lw=2.2,
                        gid=f"split-{b.index}-{joined[0]}-{joined[1]}")
        ax.plot(0, 0, marker="X", ms=9, mfc="#d62728", mec="white", ls="none")
        ax.set_aspect("equal")
        ax.set_xlim(-reach, reach)
        ax.set_ylim(-reach, reach)
        ax.set_xlabel("c₁ (zero mode 0)")
        ax.set_ylabel("c₂ (zero mode 1)")
        pairs = " and ".join(f"{i}–{j}" for i, j in b.connects) or "none (Δ = 0)"
        ax.set_title(f"branch point {b.index}: Δ = {b.delta:+.3g}\njoins rays {pairs}",
                     fontsize=9)
    fig.legend(handles=[
        Line2D([], [], ls="--", color="#1f77b4", label="rays ±t0 (unperturbed)"),
        Line2D([], [], ls="--", color="#ff7f0e", label="rays ±t1 (unperturbed)"),
        Line2D([], [], color="#2ca02c", lw=2.2, label="perturbed: (c−dc)ᵀQ(c−dc) = Δ"),
        Line2D([], [], marker="X", mfc="#d62728", mec="white", ls="none", ms=9,
               label="branch point"),
    ], loc="outside lower center", ncols=2)
    return fig
