"""Cheap requests while heavy ones saturate the engine workers (issue 28): latency of
``/health`` and of a four-bar rigidity request (the in-process lane) beside clients that keep
every worker busy with configuration spaces that run to the time limit (run on demand,
bounded in time and requests, loopback only).

    .venv/bin/python bench/bench_lanes.py [--seconds 20] [--heavy 4] [--cheap 8] [--medium 2]
                                          [--json bench/results/lanes.json] [--max-p99-ms 100]
                                          [--repo ../other-checkout]

A real ``uvicorn service.main:app`` process (``LINKAGE_WORKERS`` 2, ``LINKAGE_TIME_LIMIT_S``
5) on a free loopback port, asked once ``/health/ready`` answers. ``--heavy`` clients post a
300-rotor chain's configuration space (it always meets the time limit: 504) in a loop,
``--cheap`` clients alternate ``/health`` and the four-bar's rigidity, ``--medium`` clients post
the rigidity of a flat 3D linkage (48 vertices, 144 bars: small by its counts, but its zero
modes and self-stresses make it 0.1-0.7 s of work, which the light lane must leave to the
workers: ``service.jobs.is_light``); every request must get
an HTTP answer (a transport error is a lost request and fails the run); with ``--max-p99-ms``
the cheap requests' p99 must be under it too. The engine workers run at a lower priority
(``service.workers.WORKER_NICE``) than the service process, whose event loop and small
requests' lane therefore come first on a machine the workers saturate; the load generator
shares the machine with the server, and so does any other work running (the load average is
reported: the priority orders the service's own processes, not anyone else's).
"""

from __future__ import annotations

import argparse
import asyncio
import os
import statistics
import time
from collections import Counter
from pathlib import Path
from typing import Any

import httpx
import numpy as np
from harness import Table, served_process  # bench/ is on sys.path when run as a script


def flat_linkage(vertices: int = 48, bars: int = 144, seed: int = 0) -> dict[str, Any]:
    """A 3D linkage with every vertex in the plane z = 0 (seeded): each vertex's motion out of
    the plane is a first-order flex, so its answer holds some 10^4-10^5 numbers."""
    rng = np.random.default_rng(seed)
    pos = np.column_stack([rng.normal(size=(vertices, 2)), np.zeros(vertices)])
    pairs = {(i, i + 1) for i in range(vertices - 1)}
    while len(pairs) < bars:
        i, j = sorted(int(x) for x in rng.choice(vertices, 2, replace=False))
        pairs.add((i, j))
    return {"dimension": 3,
            "vertices": [{"id": f"v{i}", "position": p.tolist(), "fixed": i < 3}
                         for i, p in enumerate(pos)],
            "bars": [{"id": f"b{k}", "ends": [f"v{i}", f"v{j}"]}
                     for k, (i, j) in enumerate(sorted(pairs))]}


def percentile(values: list[float], q: float) -> float:
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, int(q * len(ordered)))]


async def run(url: str, seconds: float, heavy: int, cheap: int,
              medium: int = 0) -> dict[str, Any]:
    latencies: dict[str, list[float]] = {"health": [], "rigidity": [], "medium": [],
                                         "heavy": []}
    statuses: Counter[tuple[str, int]] = Counter()
    lost: list[str] = []
    async with httpx.AsyncClient(base_url=url, timeout=120, trust_env=False) as c:
        deadline = time.monotonic() + 120
        while (await c.get("/health/ready")).status_code != 200:
            assert time.monotonic() < deadline, "not ready after 120 s"
            await asyncio.sleep(0.2)
        chain = (await c.get("/v1/presets/kl-chain?n=300")).json()
        four_bar = (await c.get("/v1/presets/four-bar")).json()
        heavy_body = {"linkage": chain, "options": {"max_components": 1000}}
        medium_body = {"linkage": flat_linkage()}
        stop = time.monotonic() + seconds

        async def client(kind: str, k: int) -> None:
            n = 0
            while time.monotonic() < stop:
                if kind == "heavy":
                    name, call = "heavy", c.post("/v1/analysis/configuration-space",
                                                 json=heavy_body)
                elif kind == "medium":
                    name, call = "medium", c.post("/v1/analysis/rigidity", json=medium_body)
                elif (n + k) % 2:
                    name, call = "health", c.get("/health")
                else:
                    name, call = "rigidity", c.post("/v1/analysis/rigidity",
                                                    json={"linkage": four_bar})
                n += 1
                t0 = time.perf_counter()
                try:
                    r = await call
                except httpx.TransportError as err:
                    lost.append(f"{name}: {type(err).__name__}")
                    continue
                latencies[name].append(time.perf_counter() - t0)
                statuses[(name, r.status_code)] += 1
                if kind != "heavy":
                    await asyncio.sleep(0.02)

        await asyncio.gather(*[client("heavy", k) for k in range(heavy)],
                             *[client("cheap", k) for k in range(cheap)],
                             *[client("medium", k) for k in range(medium)])
        exposition = (await c.get("/metrics")).text
    return {"latencies": latencies, "statuses": statuses, "lost": lost,
            "server": server_side(exposition)}


ROUTES = {"health": "/health", "rigidity": "/v1/analysis/rigidity"}


def server_side(exposition: str) -> dict[str, dict[str, float]]:
    """Per cheap route, the fraction of requests the service itself answered within 5, 10, 25,
    50 and 100 ms (its latency histogram, from the request's first byte in the middleware to
    the last of its answer): what the client saw beyond that waited outside the application
    (the kernel's scheduler, the HTTP parser, the load generator itself)."""
    out: dict[str, dict[str, float]] = {}
    for name, route in ROUTES.items():
        counts: dict[str, float] = {}
        for line in exposition.splitlines():
            if (line.startswith("linkage_request_duration_seconds_bucket{")
                    and f'route="{route}"' in line):
                le = line.split('le="', 1)[1].split('"', 1)[0]
                counts[le] = float(line.rsplit(" ", 1)[1])
        total = counts.get("+Inf", 0.0)
        if total:
            out[name] = {f"<{float(le) * 1e3:g} ms": counts[le] / total
                         for le in ("0.005", "0.01", "0.025", "0.05", "0.1") if le in counts}
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seconds", type=float, default=20.0)
    parser.add_argument("--heavy", type=int, default=4)
    parser.add_argument("--cheap", type=int, default=8)
    parser.add_argument("--medium", type=int, default=2)
    parser.add_argument("--json", type=Path)
    parser.add_argument("--repo", type=Path, default=None,
                        help="serve this checkout instead (another version, for alternated runs)")
    parser.add_argument("--max-p99-ms", type=float, default=None,
                        help="fail when a cheap request's p99 is above this")
    args = parser.parse_args()
    env = {"LINKAGE_WORKERS": "2", "LINKAGE_TIME_LIMIT_S": "5"}
    with served_process(env=env, timeout=120, repo=args.repo) as url:
        out = asyncio.run(run(url, args.seconds, args.heavy, args.cheap, args.medium))
    table = Table(f"cheap requests beside {args.heavy} heavy and {args.medium} medium clients "
                  "on 2 engine workers, "
                  f"{args.seconds:g} s, load average {os.getloadavg()[0]:.1f}")
    for name, values in out["latencies"].items():
        if not values:
            continue
        codes = {code: n for (kind, code), n in out["statuses"].items() if kind == name}
        table.record(f"{name} p99", percentile(values, 0.99), f"{len(values)} requests",
                     p50=statistics.median(values), max=max(values), statuses=str(codes))
    for name, fractions in out["server"].items():
        print(f"{name} answered by the service within: "
              + ", ".join(f"{k} {100 * v:.1f} %" for k, v in fractions.items()))
    if args.json:
        table.save(args.json, load_average=os.getloadavg(), server_side=out["server"])
    assert not out["lost"], f"lost requests: {out['lost'][:10]}"
    if args.max_p99_ms is not None:
        for name in ("health", "rigidity"):
            p99 = 1e3 * percentile(out["latencies"][name], 0.99)
            assert p99 < args.max_p99_ms, f"{name} p99 {p99:.0f} ms >= {args.max_p99_ms:g} ms"


if __name__ == "__main__":
    main()
