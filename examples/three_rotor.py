"""Figs. 2 and 4 of the paper: the three-rotor with r1 = r2 = r3 = L1 = L2 = a has twelve branch
points, paired by the two four-bars it contains (Sec. II A: the pairs coincide in the (theta1,
theta2) or (theta2, theta3) projection and split together); raising r1 to 1.05 a and then
lowering L1 to 0.9 a switches how exactly one pair splits, which changes the topology of the
configuration space; the design endpoint finds such a perturbation from the targets, and
cannot split the two points of a pair apart with (r1, L1, L2).

    python examples/three_rotor.py [--url http://127.0.0.1:8000] [--out figures]
"""

from __future__ import annotations

from itertools import combinations

import numpy as np
from _paper import start
from linkage_client import CriticalPoint, Labelled

RED = {"r1": 1.05}               # the red dot of Fig. 4a
BLUE = {"r1": 1.05, "L1": 0.9}   # the blue dot


def angle(q: Labelled, pin: str, tip: str) -> float:
    d = q[tip] - q[pin]
    return float(np.arctan2(d[1], d[0]))


def same_angle(x: float, y: float) -> bool:
    return abs(np.angle(np.exp(1j * (x - y)))) < 1e-6


def pairs(points: list[CriticalPoint]) -> list[tuple[int, int]]:
    """Branch points that coincide in the projection onto the four-bar they are branch points
    of: (theta1, theta2) for P1-A-B-P2 (the self-stress loads r1), else (theta2, theta3)."""
    th = [[angle(p.configuration, f"P{k}", tip) for k, tip in ((1, "A"), (2, "B"), (3, "C"))]
          for p in points]
    first = [p.self_stress is not None and abs(p.self_stress["r1"]) > 1e-9 for p in points]
    return [(i, j) for i, j in combinations(range(len(points)), 2)
            if first[i] == first[j] and same_angle(th[i][1], th[j][1])
            and same_angle(th[i][0 if first[i] else 2], th[j][0 if first[i] else 2])]


def taus(r1: float, l1: float, r2: float = 1.0, a: float = 1.0) -> np.ndarray:
    """tau of the four-bar P1-A-B-P2 (crank r1, coupler L1, rocker r2, ground a)."""
    return np.array([a - r1 + l1 - r2, a - r1 - l1 + r2, l1 + r2 - a - r1])


def main() -> int:
    client, report = start("Figs. 2 and 4: the three-rotor and its programming", __doc__)
    rotor = client.get_preset_three_rotor()
    found = client.find_critical_points(rotor)
    points = found.critical_points
    report.check("branch points at r1 = r2 = r3 = L1 = L2 = a", 12,
                 f"{len(points)} ({sum(p.kind == 'branch' for p in points)} branch; "
                 f"complete: {found.search.complete})",
                 len(points) == 12 and all(p.kind == "branch" for p in points)
                 and found.search.complete)
    space = client.explore_configuration_space(rotor)
    report.check("segments between them (4 rays each)", "12 x 4 / 2 = 24",
                 len(space.segments), len(space.segments) == 24)
    paired = pairs(points)
    covered = sorted(i for pair in paired for i in pair)
    report.check("pairs coinciding in a projection", 6, f"{len(paired)}: {paired}",
                 len(paired) == 6 and covered == list(range(12)))
    stresses = [p.self_stress.array if p.self_stress is not None else np.zeros(5)
                for p in points]
    parallel = all(abs(abs(float(stresses[i] @ stresses[j])) - 1) < 1e-9 for i, j in paired)
    report.check("a pair's self-stresses (splitting gradients)", "identical",
                 "parallel" if parallel else "not parallel", parallel)

    red = client.predict_splitting(rotor, {"r1": RED["r1"] - 1}).branch_points
    blue = client.predict_splitting(
        rotor, {k: v - 1 for k, v in BLUE.items()}).branch_points
    split = [b.index for b in red if b.resolved]
    loads_r1 = [i for i, p in enumerate(points)
                if p.self_stress is not None and abs(p.self_stress["r1"]) > 1e-9]
    # r1 carries no stress at the branch points of the four-bar P2-B-C-P3: they stay critical
    report.check("r1 = 1.05 a splits the points stressing r1", "6 (pairs with r1, L1)",
                 f"{len(split)}: {split}", split == loads_r1 and len(split) == 6)
    switched = [r.index for r, b in zip(red, blue, strict=True)
                if r.resolved and b.resolved and r.sign != b.sign]
    report.check("L1 = 0.9 a switches how branch points split", "one pair (4, 6)",
                 f"{switched}", len(switched) == 2 and tuple(switched) in paired)
    # the switched pair is where tau2 of P1-A-B-P2 vanishes (A, B right of their pins)
    flips = np.sign(taus(RED["r1"], 1.0)) != np.sign(taus(BLUE["r1"], BLUE["L1"]))
    at = [(round(angle(points[i].configuration, "P1", "A"), 9),
           round(angle(points[i].configuration, "P2", "B"), 9)) for i in switched]
    report.check("the pair switched is tau2's (theta1 = theta2 = 0)", "closed form: tau2",
                 f"tau flipped {flips.astype(int).tolist()}, (theta1, theta2) {at}",
                 flips.tolist() == [False, True, False] and all(t == (0.0, 0.0) for t in at))

    counts = {}
    for name, lengths in (("red", RED), ("blue", BLUE)):
        s = client.explore_configuration_space(client.get_preset_three_rotor(**lengths))
        counts[name] = (len(s.components), len(s.critical_points), s.search.complete)
        report.figure(f"fig4b-three-rotor-{name}.svg", client.draw_configuration_space(
            client.get_preset_three_rotor(**lengths)))
    report.check("topology from red to blue", "changes",
                 f"{counts['red'][0]} -> {counts['blue'][0]} components "
                 f"(complete: {counts['red'][2]}, {counts['blue'][2]})",
                 counts["red"][0] != counts["blue"][0] and counts["red"][2]
                 and counts["blue"][2])
    report.note(f"the paper calls the red configuration space smooth; here {counts['red'][1]} "
                "critical points are left at r1 = 1.05 a (and at the blue dot): the branch "
                "points of the four-bar P2-B-C-P3 carry no stress on r1 or L1, and that "
                "four-bar keeps r2 = L2 = r3 = a, so no change of r1 and L1 can split them "
                "(moving L2 too would).")

    i, j = switched
    targets = [{"branch_point": b.index, "sign": b.sign} for b in blue if b.resolved]
    design = client.design_splitting(rotor, targets, ["r1", "L1", "L2"])
    report.check("design: the blue pattern from its targets", "feasible",
                 f"feasible {design.feasible}, verified {design.verified}, "
                 f"{ {k: float(f'{v:.2g}') for k, v in design.perturbation.items()} }",
                 design.feasible and design.verified is True)
    apart = client.design_splitting(rotor, [{"branch_point": i, "sign": 1},
                                            {"branch_point": j, "sign": -1}],
                                    ["r1", "L1", "L2"])
    report.check("design: the pair split apart with (r1, L1, L2)", "not possible",
                 f"feasible {apart.feasible}, conflicts "
                 f"{[c.branch_points for c in apart.conflicts]}",
                 not apart.feasible and [c.branch_points for c in apart.conflicts] == [[i, j]])
    report.figure("fig2c-three-rotor-critical.svg", client.draw_configuration_space(rotor))
    return report.finish()


if __name__ == "__main__":
    raise SystemExit(main())
