"""Fig. 5 of the paper: the gated Kane-Lubensky chain (r = l = 3a/2, L1 = 2a). The slice of the
critical value set in (L2, D) has six regions (Fig. 5b), bounded by the lines where one tau of
the gate's four-bar (ground D, crank r, coupler L2, rocker L1) vanishes; at L2 = 2a,
D = 5a/2 the unit cell has two critical points (Fig. 5d), and D < 5a/2 lets every rotor turn
(ungated) while D > 5a/2 stops them all (gated).

    python examples/gated_chain.py [--url http://127.0.0.1:8000] [--out figures]
"""

from __future__ import annotations

from typing import Any

import numpy as np
from _paper import sign, start
from linkage_client import Client

R, L1 = 1.5, 2.0
AXES = [{"bar": "L2", "min": 1.0, "max": 3.0}, {"bar": "D", "min": 1.0, "max": 3.5}]
#: the slice's search budget: its regions are explored chains, seconds on a loaded machine
MAP_OPTIONS = {"time_budget_s": 20}
QUICK = {"max_components": 2, "angles": 12, "random_starts": 2}
SCAN = (2.3, 2.45, 2.49, 2.51, 2.55, 2.7)  # D around 5a/2 (not on it: critical there)


def taus(l2: Any, d: Any) -> tuple[Any, Any, Any]:
    """tau of the gate four-bar (ground D, crank r, coupler L2, rocker L1)."""
    return (d - R + l2 - L1, d - R - l2 + L1, l2 + L1 - d - R)


def crank_turns(l2: float, d: float) -> bool:
    """Grashof's rule: the crank r turns fully when s + l < p + q and the shortest link is
    the crank or the ground D."""
    sides = {"r": R, "D": d, "L2": l2, "L1": L1}
    s, *_, big = sorted(sides.values())
    shortest = min(sides, key=sides.__getitem__)
    return s + big < sum(sides.values()) - s - big and shortest in ("r", "D")


def turning(client: Client, n: int, gate: int, **lengths: float) -> set[int]:
    """|winding| of every chain rotor r0..r{n-1} on the traced components."""
    chain = client.get_preset("gated-kl-chain", n=n, gate=gate, **lengths)
    space = client.explore_configuration_space(chain, options=QUICK)
    return {abs(w) for comp in space.components for k, w in comp.winding.items()
            if k.startswith("r") and w is not None}


def lines_distance(curve: np.ndarray) -> float:
    """Distance of each (L2, D) to the nearest of the lines tau_i = 0."""
    l2, d = curve[:, 0], curve[:, 1]
    return float(np.max(np.min([np.abs(t) for t in taus(l2, d)], axis=0)) / np.sqrt(2))


def main() -> int:
    client, report = start("Fig. 5: the gated Kane-Lubensky chain", __doc__)
    chain = client.get_preset("gated-kl-chain", n=4, gate=2)
    m = client.map_critical_values(chain, AXES, options=MAP_OPTIONS)
    report.check("regions of the (L2, D) slice", 6, len(m.regions), len(m.regions) == 6)
    worst = max(lines_distance(c) for c in m.curves)
    report.check("curves on the gate's tau_i = 0", "3 lines",
                 f"{len(m.curves)} curves, largest distance {worst:.1e}",
                 len(m.curves) == 3 and worst < 1e-6)
    wrong, labels = [], []
    for region in m.regions:
        l2, d = (float(x) for x in region.point)
        stopped = turning(client, 4, 2, L2=l2, D=d) == {0}
        labels.append("".join(sign(t) for t in taus(l2, d)) + (" gated" if stopped else " open"))
        if stopped == crank_turns(l2, d):
            wrong.append((round(l2, 3), round(d, 3)))
    report.check("gated where Grashof stops the gate's crank", "each region",
                 f"{len(m.regions) - len(wrong)} of {len(m.regions)}: {', '.join(labels)}",
                 not wrong and bool(m.regions))
    report.figure("fig5b-gate-slice.svg",
                  client.draw_critical_values(chain, AXES, options=MAP_OPTIONS))

    cell = client.get_preset("gated-kl-chain", n=2, gate=1, L2=2.0, D=2.5)
    found = client.find_critical_points(cell, options={"time_budget_s": 20})
    below = [p for p in found.critical_points
             if p.configuration["G"][1] < p.configuration["P1"][1]]
    report.check("critical points of a unit cell at L2 = 2a, D = 5a/2", 2,
                 f"{len(below)} with G below the chain ({len(found.critical_points)} with its "
                 f"mirror image; complete: {found.search.complete})",
                 len(below) == 2 and found.search.complete)
    report.figure("fig5d-unit-cell-critical.svg", client.draw_configuration_space(cell))

    turns = {d: turning(client, 6, 3, D=d) for d in SCAN}
    ungated = [d for d in SCAN if turns[d] == {1}]
    gated = [d for d in SCAN if turns[d] == {0}]
    bracket = (max(ungated, default=float("nan")), min(gated, default=float("nan")))
    report.check("threshold in D (6 rotors, gate on rotor 3)", "5a/2",
                 f"between {bracket[0]} (every rotor turns) and {bracket[1]} (none)",
                 len(ungated) + len(gated) == len(SCAN) and bracket[0] < 2.5 < bracket[1]
                 and max(ungated) < min(gated))
    report.figure("fig5a-gated-chain.svg", client.draw_linkage(
        client.get_preset("gated-kl-chain", n=6, gate=3, D=2.7), show=["zero_modes"]))
    return report.finish()


if __name__ == "__main__":
    raise SystemExit(main())
