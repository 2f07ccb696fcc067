"""Fig. 3 of the paper: the four-bar's critical value set (a = +-L1 +-L2 +-L3, the collinear
configurations) divides the lengths into 2^3 = 8 volumes, labelled by the signs of
tau1 = a - L1 + L2 - L3, tau2 = a - L1 - L2 + L3, tau3 = L2 + L3 - a - L1 (Sec. I E); a
Grashof four-bar (tau1 tau2 tau3 > 0) has two components, the others one.

Two slices in (L2, L3), at L1 = 0.6 a and L1 = 1.5 a, each cut six of the eight volumes (their
tau1 + tau2 = 2 (a - L1) fixes a sign between them); together they meet all eight.

    python examples/four_bar_map.py [--url http://127.0.0.1:8000] [--out figures]
"""

from __future__ import annotations

import itertools

import numpy as np
from _paper import sign, start

A = 1.0
BOX = (0.3, 3.0)  # no corner of the box on a plane: no region thinner than the raster
SLICES = (0.6, 1.5)


def taus(l1: float, l2: float, l3: float) -> tuple[float, float, float]:
    return (A - l1 + l2 - l3, A - l1 - l2 + l3, l2 + l3 - A - l1)


def assembles(l1: float, l2: float, l3: float) -> bool:
    """A closed quadrilateral exists: its longest side is shorter than the other three."""
    sides = (A, l1, l2, l3)
    return 2 * max(sides) < sum(sides)


def plane_distance(l1: float, points: np.ndarray) -> np.ndarray:
    """Distance of each (L2, L3) to the nearest plane a = +-L1 +-L2 +-L3 (divided by sqrt 3)."""
    return np.min([np.abs(s1 * l1 + s2 * points[:, 0] + s3 * points[:, 1] - A)
                   for s1, s2, s3 in itertools.product((1, -1), repeat=3)], axis=0) / np.sqrt(3)


def raster_regions(l1: float, n: int = 601) -> int:
    """Regions of the slice from the closed form: the cells of the seven planes' arrangement
    met with the box are convex, so each is one distinct sign vector on a fine grid."""
    g = np.linspace(*BOX, n)
    l2, l3 = np.meshgrid(g, g)
    planes = [s1 * l1 + s2 * l2 + s3 * l3 - A
              for s1, s2, s3 in itertools.product((1, -1), repeat=3)]
    codes = np.stack([p > 0 for p in planes], axis=-1).reshape(-1, 8)
    return len({tuple(c) for c in codes})


def main() -> int:
    client, report = start("Fig. 3: the four-bar's critical value set and its eight volumes",
                           __doc__)
    axes = [{"bar": "L2", "min": BOX[0], "max": BOX[1]},
            {"bar": "L3", "min": BOX[0], "max": BOX[1]}]
    labels: dict[str, int] = {}
    for l1 in SLICES:
        four_bar = client.get_preset_four_bar(L1=l1, theta=1.0)
        m = client.map_critical_values(four_bar, axes)
        worst = max(float(np.max(plane_distance(l1, c))) for c in m.curves)
        report.check(f"L1 = {l1}: curves on a = +-L1 +-L2 +-L3", "distance 0",
                     f"{len(m.curves)} curves, largest distance {worst:.1e}", worst < 1e-6)
        expected = raster_regions(l1)
        report.check(f"L1 = {l1}: regions in the box", f"closed form: {expected}",
                     f"{len(m.regions)} (complete: {m.search.complete})",
                     len(m.regions) == expected and m.search.complete)
        wrong = []
        for region in m.regions:
            l2, l3 = (float(x) for x in region.point)
            t = taus(l1, l2, l3)
            grashof = t[0] * t[1] * t[2] > 0
            want = (2 if grashof else 1) if assembles(l1, l2, l3) else 0
            if region.components != want:
                wrong.append((round(l2, 3), round(l3, 3), region.components, want))
            if want:
                label = "".join(sign(x) for x in t)
                labels[label] = region.components or 0
        report.check(f"L1 = {l1}: components (Grashof 2, else 1; 0 where none)",
                     "each region", f"{len(m.regions) - len(wrong)} of {len(m.regions)} agree"
                     + (f", not {wrong}" if wrong else ""), not wrong)
        report.figure(f"fig3-four-bar-slice-L1-{l1}.svg",
                      client.draw_critical_values(four_bar, axes))
    report.check("volumes met (sign patterns of tau)", 8,
                 f"{len(labels)}: " + " ".join(f"{k}:{v}" for k, v in sorted(labels.items())),
                 len(labels) == 8)
    return report.finish()


if __name__ == "__main__":
    raise SystemExit(main())
