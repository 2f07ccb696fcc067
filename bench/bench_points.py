"""Configuration points per second: a crank-rocker four-bar, ours against pylinkage 1.3.

    .venv/bin/python bench/bench_points.py [--repeat 3] [--json bench/results/points.json]

pylinkage simulates one branch (one assembly mode) by stepping its crank, in plain Python (no
numba here), and detects no branch point. Ours answers POST /v1/analysis/configuration-space:
every component (both assembly modes), with the certificate that no critical point exists (the
closed form of ``engine.space.dyads``), consecutive points no farther apart than ``step_max``. The
same four-bar everywhere: pins (0, 0) and (1, 0), crank L1 = 0.5, coupler L2 = 1.2, rocker
L3 = 1. Best of ``--repeat`` wall-clock runs (``time.perf_counter``); the machine is shared, so
timings are noisy.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from dataclasses import replace
from pathlib import Path

import httpx

sys.path.insert(0, str(Path(__file__).resolve().parent))
from harness import Table, best_of, served  # noqa: E402

from engine.catalogue.presets import build_preset
from engine.space.configuration_space import SpaceOptions, explore
from engine.space.trace import TraceOptions
from service import mappers

LENGTHS = {"L1": 0.5, "L2": 1.2, "L3": 1.0}
ENDPOINT = "/v1/analysis/configuration-space"


def pylinkage_points(n: int, fast: bool = False) -> int:
    """``n`` crank steps of pylinkage's four-bar (one full turn, one branch)."""
    from pylinkage.actuators import Crank
    from pylinkage.components import Ground
    from pylinkage.dyads import RRRDyad
    from pylinkage.simulation import Linkage

    o1, o2 = Ground(0.0, 0.0, name="O1"), Ground(1.0, 0.0, name="O2")
    crank = Crank(anchor=o1, radius=LENGTHS["L1"], angular_velocity=2 * math.pi / n)
    rocker = RRRDyad(crank.output, o2, distance1=LENGTHS["L2"], distance2=LENGTHS["L3"])
    linkage = Linkage([o1, o2, crank, rocker], name="crank-rocker")
    if fast:
        return len(linkage.step_fast(iterations=n))
    return sum(1 for _ in linkage.step(iterations=n))


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--json", type=Path, default=Path("bench/results/points.json"))
    parser.add_argument("--step-max", type=float, default=7.5e-5,
                        help="options.step_max of the dense request (about 120k points)")
    args = parser.parse_args()
    table = Table("Configuration points per second, crank-rocker four-bar (L1=0.5, L2=1.2, L3=1)")
    lk = build_preset("four-bar", LENGTHS)
    n_peer = 100_000

    t, n = best_of(lambda: pylinkage_points(n_peer), args.repeat)
    peer_rate = n / t
    table.record("pylinkage 1.3 Linkage.step, one branch", t, f"{n} points",
                 points_per_s=peer_rate)
    t, n = best_of(lambda: pylinkage_points(n_peer, fast=True), args.repeat)
    table.record("pylinkage 1.3 Linkage.step_fast (no numba), one branch", t, f"{n} points",
                 points_per_s=n / t)

    dense = SpaceOptions(trace=TraceOptions(step_max=args.step_max, max_points=200_000))

    def ours(opt: SpaceOptions, near: bool) -> int:
        res = explore(lk, options=opt, near_misses=near)
        assert res.search["complete"] and not res.critical_points
        return sum(len(c.points) for c in res.components)

    for label, opt, near in (
        ("ours engine, closed form, as the endpoint (no near misses)", dense, False),
        ("ours engine, closed form, with the near-miss search", dense, True),
        ("ours engine, default options (step_max 0.1), as the endpoint", SpaceOptions(), False),
    ):
        t, n = best_of(lambda o=opt, m=near: ours(o, m), args.repeat)
        table.record(label, t, f"{n} points, all 2 components", points_per_s=n / t,
                     ratio_vs_pylinkage=n / t / peer_rate)
    tracer = replace(dense, closed_form=False,
                     trace=TraceOptions(step_max=2e-3, max_points=200_000))
    t, n = best_of(lambda: ours(tracer, True), 1)
    table.record("general tracer (closed_form=False), step_max 2e-3", t,
                 f"{n} points, all 2 components", points_per_s=n / t,
                 ratio_vs_pylinkage=n / t / peer_rate)

    linkage = mappers.linkage_out(lk).model_dump(mode="json", by_alias=True)
    with served() as url, httpx.Client(base_url=url, timeout=120) as client:
        for label, options in (
            (f"step_max {args.step_max:g}", {"step_max": args.step_max, "max_points": 200_000}),
            ("default options", {}),
        ):
            body = {"linkage": linkage, "options": options}

            def received(b: dict = body) -> bytes:  # type: ignore[type-arg]
                r = client.post(ENDPOINT, json=b)
                r.raise_for_status()
                return r.content

            def parsed(b: dict = body) -> int:  # type: ignore[type-arg]
                comps = json.loads(received(b))["components"]
                return sum(len(next(iter(c["positions"].values()))) for c in comps)

            n = parsed()  # also warms the worker
            t, raw = best_of(received, args.repeat)
            table.record(f"ours through HTTP, {label}: answer received", t,
                         f"{n} points, all 2 components, {len(raw) / 1e6:.1f} MB JSON",
                         points_per_s=n / t, ratio_vs_pylinkage=n / t / peer_rate)
            t, n = best_of(parsed, args.repeat)
            table.record(f"ours through HTTP, {label}: + client json.loads", t,
                         f"{n} points, all 2 components", points_per_s=n / t,
                         ratio_vs_pylinkage=n / t / peer_rate)
    table.save(args.json)


if __name__ == "__main__":
    main()
