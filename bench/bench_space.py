"""Benchmarks of the configuration-space engine (run on demand, not in the test suite).

    .venv/bin/python bench/bench_space.py [--repeat 3] [--json bench/results/space.json]

Best of ``--repeat`` wall-clock runs (``time.perf_counter``), engine only (no HTTP).
"""

from __future__ import annotations

import argparse
import json
import time
from collections.abc import Callable
from pathlib import Path

from engine.configuration_space import SpaceOptions, explore, find_critical_points
from engine.constraints import Constraints
from engine.presets import build_preset
from engine.rigidity import first_order
from engine.tolerances import Tolerances
from engine.trace import TraceOptions, trace_curve


def best_of(fn: Callable[[], object], repeat: int) -> tuple[float, object]:
    best, out = float("inf"), None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return best, out


def kl_component(n: int) -> int:
    lk = build_preset("kl-chain", {"n": n})
    cons = Constraints(lk)
    z = first_order(lk).zero_modes[0]
    curve = trace_curve(cons, lk.coordinates(), z, Tolerances(), TraceOptions())
    assert curve.stop == "closed"
    return len(curve.points)


def critical_points_http(repeat: int) -> tuple[float, dict]:
    """Best-of time of POST /v1/analysis/critical-points for the three-rotor through the real
    service (uvicorn on a loopback port, worker processes as deployed), after one warm-up."""
    import httpx
    from harness import served

    with served() as url, httpx.Client(base_url=url, timeout=120.0) as client:
        linkage = client.get("/v1/presets/three-rotor").json()
        body = {"linkage": linkage}
        client.post("/v1/analysis/critical-points", json=body).raise_for_status()  # warm-up

        def once() -> dict:
            r = client.post("/v1/analysis/critical-points", json=body)
            r.raise_for_status()
            return dict(r.json())

        return best_of(once, repeat)


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--json", type=Path, default=Path("bench/results/space.json"))
    args = parser.parse_args()
    rows = []

    def record(name: str, seconds: float, detail: str) -> None:
        rows.append({"benchmark": name, "seconds": seconds, "detail": detail})
        print(f"{name:<58} {seconds:9.3f} s   {detail}")

    for label, params in (("four-bar crank-rocker (L1=0.5, L2=1.2, L3=1)",
                           {"L1": 0.5, "L2": 1.2, "L3": 1.0}),
                          ("four-bar equilateral (3 branch points)", {})):
        t, res = best_of(lambda p=params: explore(build_preset("four-bar", p)), args.repeat)
        pts = sum(len(c.points) for c in res.components)
        record(f"configuration space, {label}", t,
               f"{len(res.components)} components, {pts} points, "
               f"{len(res.critical_points)} critical points")
    t, res = best_of(lambda: explore(build_preset("three-rotor")), args.repeat)
    record("configuration space, three-rotor (all lengths a)", t,
           f"{len(res.critical_points)} critical points, {len(res.segments)} segments")
    t, crit = best_of(lambda: find_critical_points(build_preset("three-rotor")), args.repeat)
    record("all critical points, three-rotor (engine)", t,
           f"{len(crit.critical_points)} critical points")
    t, body = critical_points_http(args.repeat)
    record("all critical points, three-rotor (HTTP, POST critical-points)", t,
           f"{len(body['critical_points'])} critical points")
    for n in (50, 100, 200):
        t, pts = best_of(lambda n=n: kl_component(n), args.repeat)
        record(f"component through the start, {n}-rotor KL chain", t, f"{pts} points")
    t, res = best_of(
        lambda: explore(
            build_preset("kl-chain", {"n": 100}), options=SpaceOptions(max_components=4)
        ),
        1,
    )
    record("explore 100-rotor KL chain, budget 4 components", t,
           f"{len(res.components)} components traced of 2^99; complete={res.search['complete']}")
    args.json.parent.mkdir(parents=True, exist_ok=True)
    args.json.write_text(json.dumps(rows, indent=2) + "\n")


if __name__ == "__main__":
    main()
