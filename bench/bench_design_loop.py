"""The design loop of issue 15 (run on demand): maps, margins and the critical-point search,
before (the path replaced, where it is still selectable) and after.

    .venv/bin/python bench/bench_design_loop.py [--repeat 1] [--no-before]
        [--json bench/results/design_loop.json]

Rows (CPU time of this process, ``time.process_time``, and wall-clock; on a shared machine the
CPU time is the steadier number; run with ``OPENBLAS_NUM_THREADS=1`` as the issue's table). The
rows with the defaults a request gets (options and the service's 4 s search budget) come first
and say whether the answer is complete (issue 30); a row with other options says so in its name
(the same cells through HTTP: ``bench/bench_matrix.py``):

* gate slice (L2, D), 4-rotor gated chain (``gated-kl-chain`` n=4, gate=2), resolution 48;
* four-bar slice (L2, L3) in [0.3, 2.2]^2, resolution 200: ``method="traced"`` (before) and
  the closed-form lines of one-dyad chains (``"auto"``, after);
* robustness margin, four-bar L2 = 1.2, all bars adjustable: ``method="multistart"`` (before)
  and ``"auto"`` (the closed form, after);
* critical-point search with near misses, 100-rotor KL chain (budget 4 components, as in
  ``bench_space.py``: the curves traced first, untimed): every candidate refined by MINPACK's
  dense ``lmder`` (before) and by the sparse Levenberg-Marquardt (after).
"""

from __future__ import annotations

import argparse
import os
import platform
from collections.abc import Callable
from pathlib import Path
from typing import Any

from harness import Table, best_of_cpu

import engine.local.critical as critical
from engine.catalogue.presets import build_preset
from engine.design.critical_values import critical_value_slice
from engine.design.robustness import robustness
from engine.model.budget import Deadline
from engine.model.tolerances import Tolerances
from engine.space.configuration_space import Explorer, SpaceOptions, find_critical_points
from engine.space.configuration_space.critical_search import critical_points

#: The service's default search budget (``LINKAGE_SEARCH_TIME_S``).
DEFAULT_BUDGET_S = 4.0


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--repeat", type=int, default=1)
    parser.add_argument("--no-before", action="store_true", help="only the paths in use")
    parser.add_argument("--json", type=Path, default=Path("bench/results/design_loop.json"))
    args = parser.parse_args()
    table = Table("design loop (issue 15): maps, margins, critical-point search")
    before = not args.no_before

    def row(name: str, fn: Callable[[], Any], detail: Callable[[Any], str], **extra: Any) -> None:
        wall, cpu, out = best_of_cpu(fn, args.repeat)
        table.record(name, wall, detail(out), cpu=cpu, **extra)

    gated = build_preset("gated-kl-chain", {"n": 4, "gate": 2})
    gate_axes = [("L2", 1.0, 3.0), ("D", 1.0, 3.5)]
    # what a request gets (issue 30): the default options and the service's default search
    # budget (LINKAGE_SEARCH_TIME_S, 4 s)
    row("gate slice (L2, D), 4-rotor gated chain, resolution 48, defaults",
        lambda: critical_value_slice(gated, gate_axes, resolution=48,
                                     deadline=Deadline.after(DEFAULT_BUDGET_S)),
        lambda s: f"{len(s.curves)} curves, {len(s.regions)} regions, {s.search['method']}, "
                  f"complete {s.search['complete']} ({s.search['reason']})",
        when="after")
    gate_opt = SpaceOptions(angles=12, random_starts=2, max_components=4)
    row("gate slice, NOT the defaults: angles=12, random_starts=2, max_components=4",
        lambda: critical_value_slice(gated, gate_axes, resolution=48, options=gate_opt),
        lambda s: f"{len(s.curves)} curves, {len(s.regions)} regions, {s.search['method']}, "
                  f"complete {s.search['complete']} ({s.search['reason']})",
        when="after")

    four_bar = build_preset("four-bar", {"L2": 1.2})
    axes = [("L2", 0.3, 2.2), ("L3", 0.3, 2.2)]
    for method, when in (("traced", "before"), ("auto", "after")):
        if when == "before" and not before:
            continue
        row(f"four-bar slice (L2, L3), resolution 200 ({method})",
            lambda m=method: critical_value_slice(four_bar, axes, resolution=200, method=m),
            lambda s: f"{len(s.curves)} curves, {len(s.regions)} regions, {s.search['method']}",
            when=when)

    for method, when in (("multistart", "before"), ("auto", "after")):
        if when == "before" and not before:
            continue
        row(f"robustness margin, four-bar, all bars adjustable ({method})",
            lambda m=method: robustness(four_bar, method=m),
            lambda r: f"margin {r.margin:.9f}, {r.method} ({r.guarantee})", when=when)

    kl = build_preset("kl-chain", {"n": 100})
    row("critical-point search, 100-rotor chain, defaults",
        lambda: find_critical_points(kl, deadline=Deadline.after(DEFAULT_BUDGET_S)),
        lambda r: f"{len(r.critical_points)} critical points, {len(r.near_misses)} near misses, "
                  f"complete {r.search['complete']} ({r.search['argument']})", when="after")
    ex = Explorer(kl, Tolerances(), SpaceOptions(max_components=4))
    ex.trace_all(kl.coordinates())  # the curves, as an exploration traces them: not timed
    sparse_from = critical.SPARSE_REFINE_MIN_UNKNOWNS
    for threshold, label, when in ((10**9, "MINPACK lmder", "before"),
                                   (sparse_from, "sparse LM", "after")):
        if when == "before" and not before:
            continue
        critical.SPARSE_REFINE_MIN_UNKNOWNS = threshold
        try:
            row(f"near-miss refinement, 100-rotor chain, NOT the defaults: max_components=4, "
                f"curves traced first untimed ({label})",
                lambda: critical_points(ex),
                lambda r: f"{ex.report['critical_candidates']} candidates, {len(r[0])} critical "
                          f"points, {len(r[1])} near misses, length gaps "
                          f"{sorted(round(m.length_gap, 8) for m in r[1])}", when=when)
        finally:
            critical.SPARSE_REFINE_MIN_UNKNOWNS = sparse_from
    table.save(args.json, machine=f"{platform.processor() or platform.machine()}, "
               f"{os.cpu_count()} cores, load {os.getloadavg()[0]:.2f}",
               blas_threads=os.environ.get("OPENBLAS_NUM_THREADS"))


if __name__ == "__main__":
    main()
