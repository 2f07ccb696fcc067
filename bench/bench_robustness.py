"""Benchmarks of the robustness margin (run on demand): the closed form against the multistart.

    .venv/bin/python bench/bench_robustness.py [--repeat 3] [--json bench/results/robustness.json]

Rows: the four-bar (L2 = 1.2, and the equal-length four-bar, which is itself critical) by the
closed form (``method="auto"``) and by the multistart (``method="multistart"``, what every
linkage got before the closed form); the slider-crank of issue 11 (crank 0.7 from a pin, rod
1.6 to a slider on the line through the pin), which only the multistart answers.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from harness import Table, best_of_cpu

from engine.catalogue.presets import build_preset
from engine.design.robustness import robustness
from engine.model.linkage import BarSpec, Linkage, VertexSpec, build_linkage


def slider_crank(crank: float = 0.7, rod: float = 1.6, theta: float = 0.9) -> Linkage:
    b = crank * np.array([np.cos(theta), np.sin(theta)])
    px = b[0] + np.sqrt(rod**2 - b[1] ** 2)
    return build_linkage(2, [VertexSpec("O", (0.0, 0.0), True), VertexSpec("B", tuple(b)),
                             VertexSpec("P", (px, 0.0), (False, True))],
                         [BarSpec("crank", ("O", "B"), crank), BarSpec("rod", ("B", "P"), rod)])



def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--json", type=Path, default=Path("bench/results/robustness.json"))
    args = parser.parse_args()
    table = Table("robustness margins")
    cases = [
        ("four-bar L2=1.2, all bars", build_preset("four-bar", {"L2": 1.2}), None),
        ("four-bar L2=1.2, L2 only", build_preset("four-bar", {"L2": 1.2}), ["L2"]),
        ("equal-length four-bar, all bars", build_preset("four-bar", {}), None),
    ]
    for name, lk, adj in cases:
        for method in ("auto", "multistart"):
            t, cpu, m = best_of_cpu(lambda lk=lk, adj=adj, method=method: robustness(
                lk, adj, method=method), args.repeat)
            table.record(f"{name}: {m.method}", t, f"margin {m.margin:.6f} ({m.guarantee})",
                         cpu=cpu)
    sc = slider_crank()
    for adj, exact in ((None, 0.9 / np.sqrt(2)), (["rod"], 0.9)):
        t, cpu, m = best_of_cpu(lambda adj=adj: robustness(sc, adj), args.repeat)
        table.record(f"slider-crank, {'+'.join(adj or ['both bars'])}: {m.method}", t,
                     f"margin {m.margin:.6f} (exact {exact:.6f}; {m.guarantee})", cpu=cpu)
    table.save(args.json)


if __name__ == "__main__":
    main()
