"""Service throughput over loopback: requests per second and p50/p99 latency of a four-bar
rigidity request with concurrent clients, for several server settings (run on demand).

    .venv/bin/python bench/bench_service.py [--requests 2000] [--clients 1 8 32]
                                            [--json bench/results/service.json]

Each configuration starts a real ``uvicorn service.main:app`` process on a free loopback port
(``--workers`` uvicorn processes, ``LINKAGE_WORKERS`` engine workers each), warms it up, then
sends a bounded number of requests from ``clients`` concurrent keep-alive connections (asyncio +
httpx, in this process). The load generator shares the machine with the server: on a 2-core
machine it takes a good part of one core, so the numbers are a lower bound of what a remote
client would see. A second row per configuration posts a 100-rotor chain (an engine-worker
request) to show the cost of the process hop.
"""

from __future__ import annotations

import argparse
import asyncio
import os
import statistics
import time
from pathlib import Path
from typing import Any

import httpx
from harness import Table, served_process  # bench/ is on sys.path when run as a script


async def load(url: str, path: str, body: Any, requests: int, clients: int
               ) -> tuple[float, list[float], int]:
    """``requests`` POSTs from ``clients`` connections: wall time, latencies, failures."""
    latencies: list[float] = []
    failures = 0
    queue: asyncio.Queue[int] = asyncio.Queue()
    for k in range(requests):
        queue.put_nowait(k)
    limits = httpx.Limits(max_connections=clients, max_keepalive_connections=clients)
    async with httpx.AsyncClient(base_url=url, limits=limits, timeout=120) as client:

        async def worker() -> None:
            nonlocal failures
            while True:
                try:
                    queue.get_nowait()
                except asyncio.QueueEmpty:
                    return
                t0 = time.perf_counter()
                r = await client.post(path, json=body)
                latencies.append(time.perf_counter() - t0)
                failures += r.status_code != 200

        t0 = time.perf_counter()
        await asyncio.gather(*(worker() for _ in range(clients)))
        wall = time.perf_counter() - t0
    return wall, latencies, failures


def percentile(values: list[float], q: float) -> float:
    return statistics.quantiles(values, n=100, method="inclusive")[q - 1] if len(values) > 1 \
        else values[0]


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--requests", type=int, default=2000)
    parser.add_argument("--clients", type=int, nargs="+", default=[1, 8, 32])
    parser.add_argument("--configs", nargs="+", default=["1x1", "1x2", "2x1"],
                        help="uvicorn workers x engine workers per uvicorn process")
    parser.add_argument("--uvicorn-args", default="",
                        help='more uvicorn options, e.g. "--loop asyncio --http h11"')
    parser.add_argument("--json", type=Path, default=Path("bench/results/service.json"))
    args = parser.parse_args()

    table = Table(f"service throughput over loopback ({os.cpu_count()} cores) "
                  f"{args.uvicorn_args}".strip())
    for config in args.configs:
        uv, eng = (int(x) for x in config.split("x"))
        extra = ["--workers", str(uv), "--no-access-log", *args.uvicorn_args.split()]
        with served_process(extra, env={"LINKAGE_WORKERS": str(eng)}, timeout=120) as url:
            four_bar = httpx.get(url + "/v1/presets/four-bar", params={"theta": 0.5}).json()
            chain = httpx.get(url + "/v1/presets/kl-chain", params={"n": 100}).json()
            cases = [("four-bar rigidity", {"linkage": four_bar}, args.requests),
                     ("100-rotor chain rigidity (engine worker)", {"linkage": chain},
                      max(50, args.requests // 10))]
            for name, body, n in cases:
                asyncio.run(load(url, "/v1/analysis/rigidity", body, 50, 4))  # warm-up
                for clients in args.clients:
                    wall, lat, failed = asyncio.run(
                        load(url, "/v1/analysis/rigidity", body, n, clients))
                    table.record(
                        f"{name}, uvicorn {uv} x engine {eng}, {clients} clients", wall,
                        f"{n} requests, {failed} failed",
                        rps=n / wall, p50_ms=1e3 * percentile(lat, 50),
                        p99_ms=1e3 * percentile(lat, 99))
    table.save(args.json)


if __name__ == "__main__":
    main()
