"""Fig. 1 of the paper: the equilateral four-bar (a = L1 = L2 = L3 = 1) has three branch points,
each with one self-stress and two zero modes; L2 slightly above a splits them into one
component, slightly below into two, the hyperbolas of each branch point in the opposite pair of
quadrants (Sec. I C; the splitting quantity Delta of Appendix A).

    python examples/four_bar.py [--url http://127.0.0.1:8000] [--out figures]
"""

from __future__ import annotations

import numpy as np
from _paper import start

DL = 0.01  # the perturbation of L2 (the paper: "slightly")


def collinear_stress(xa: float, xb: float, a: float = 1.0) -> np.ndarray:
    """The self-stress of bars (L1, L2, L3) when P1 = 0, A = xa, B = xb, P2 = a lie on a line:
    equilibrium at A, s1 xa + s2 (xa - xb) = 0, and at B, s2 (xb - xa) + s3 (xb - a) = 0; unit
    norm (its overall sign is a convention; only |sigma| is compared)."""
    s2 = 1.0
    s = np.array([-s2 * (xa - xb) / xa, s2, -s2 * (xb - xa) / (xb - a)])
    return s / np.linalg.norm(s)


def main() -> int:
    client, report = start("Fig. 1: the equilateral four-bar", __doc__)
    four_bar = client.get_preset_four_bar()  # a = L1 = L2 = L3 = 1
    found = client.find_critical_points(four_bar)
    points = found.critical_points
    report.check("branch points at L1 = L2 = L3 = a", 3,
                 f"{len(points)} ({', '.join(p.kind for p in points)}; complete: "
                 f"{found.search.complete})",
                 len(points) == 3 and all(p.kind == "branch" for p in points)
                 and found.search.complete)
    report.check("self-stresses and zero modes at each", "1 and 2",
                 ", ".join(f"{int(p.self_stress is not None)} and {len(p.zero_modes)}"
                           for p in points),
                 all(p.self_stress is not None and len(p.zero_modes) == 2 for p in points))
    signs = [np.sign(p.q_eigenvalues if p.q_eigenvalues is not None else []) for p in points]
    report.check("Q indefinite at each (a cone)", "one + and one - eigenvalue",
                 [s.astype(int).tolist() for s in signs],
                 all(sorted(s.tolist()) == [-1.0, 1.0] for s in signs))
    heights = max(float(np.max(np.abs(p.configuration.array[:, 1]))) for p in points)
    report.check("critical configurations collinear (y = 0)", "y2 = y3 = 0",
                 f"max |y| = {heights:.1e}", heights < 1e-9)

    counts = {}
    for l2 in (1 + DL, 1 - DL):
        space = client.explore_configuration_space(client.get_preset_four_bar(L2=l2))
        counts[l2] = (len(space.components), len(space.critical_points), space.search.complete)
    for l2, paper in ((1 + DL, 1), (1 - DL, 2)):
        n, crit, complete = counts[l2]
        report.check(f"components at L2 = {l2:g}", paper,
                     f"{n} ({crit} critical points, complete: {complete})",
                     n == paper and crit == 0 and complete)

    up = client.predict_splitting(four_bar, {"L2": DL}).branch_points
    down = client.predict_splitting(four_bar, {"L2": -DL}).branch_points
    opposite = [sorted(map(tuple, u.connects)) != sorted(map(tuple, d.connects))
                and u.sign == -d.sign != 0 for u, d in zip(up, down, strict=True)]
    report.check("dL2 = +-0.01 joins opposite ray pairs", "at all 3",
                 f"at {sum(opposite)} of {len(up)}", len(up) == 3 and all(opposite))
    # Appendix A: Delta = 4 sum_a sigma_a L_a dL_a to first order, sigma from equilibrium
    worst = 0.0
    for split, p in zip(up, points, strict=True):
        xa, xb = p.configuration["A"][0], p.configuration["B"][0]
        linear = 4 * abs(collinear_stress(xa, xb)[1]) * 1.0 * DL
        worst = max(worst, abs(abs(split.delta) - linear))
    report.check("|Delta| - 4 |sigma_L2| L2 dL2 (second order)", f"O(dL^2) = {DL**2:g}",
                 f"{worst:.1e}", worst < 10 * DL**2)

    report.figure("fig1b-four-bar-critical.svg", client.draw_configuration_space(four_bar))
    for l2, colour in ((1 + DL, "red"), (1 - DL, "blue")):
        report.figure(f"fig1b-four-bar-L2-{l2:g}-{colour}.svg",
                      client.draw_configuration_space(client.get_preset_four_bar(L2=l2)))
    report.figure("fig1-splitting-dL2.svg", client.draw_splitting(four_bar, {"L2": DL}))
    return report.finish()


if __name__ == "__main__":
    raise SystemExit(main())
