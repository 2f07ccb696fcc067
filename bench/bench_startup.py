"""Start-up time (issue 28, item 5): the README's command (``uvicorn service.main:app
--http service.protocol:GuardedH11Protocol`` on loopback), timed from the process's start to
the first ``/health/live`` 200 and to the first ``/health/ready`` 200 (run on demand; warm
install: numba's cache is filled by the first run, which is reported apart).

    .venv/bin/python bench/bench_startup.py [--repeats 3] [--repo ../other-checkout]
                                            [--json bench/results/startup.json]

Each run is a fresh process (``LINKAGE_WORKERS`` 2, as on the 2-core machine), polled every
20 ms, then stopped; the load average is reported beside (the start-up imports and the
forkserver's kernel loading compete for the cores with whatever else runs).
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import time
from pathlib import Path

import httpx
import psutil
from harness import Table, free_port  # bench/ is on sys.path when run as a script


def cpu_seconds(pid: int) -> tuple[float, float]:
    """CPU seconds (user + system) used so far by the process ``pid`` and by its descendants
    alive now (the forkserver and the workers)."""
    proc = psutil.Process(pid)
    own = sum(proc.cpu_times()[:2])
    children = 0.0
    for child in proc.children(recursive=True):
        try:
            children += sum(child.cpu_times()[:2])
        except psutil.NoSuchProcess:
            pass
    return own, children


def one_start(repo: Path, timeout: float = 300.0) -> tuple[float, float, float, float]:
    """Seconds from ``Popen`` to the first ``/health/live`` 200 and to ``/health/ready`` 200,
    and the CPU seconds the service process and its children had used when ready (what the
    start-up costs whatever the load: on an idle 2-core machine the two run side by side)."""
    port = free_port()
    start = time.perf_counter()
    proc = subprocess.Popen(
        [sys.executable, "-m", "uvicorn", "service.main:app", "--host", "127.0.0.1", "--port",
         str(port), "--http", "service.protocol:GuardedH11Protocol", "--log-level", "warning"],
        cwd=repo, env={**os.environ, "LINKAGE_WORKERS": "2"},
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    live = ready = None
    cpu = (float("nan"), float("nan"))
    try:
        with httpx.Client(base_url=f"http://127.0.0.1:{port}", timeout=2.0,
                          trust_env=False) as c:
            while ready is None:
                assert proc.poll() is None, "the server stopped"
                assert time.perf_counter() - start < timeout, "not ready in time"
                try:
                    if live is None and c.get("/health/live").status_code == 200:
                        live = time.perf_counter() - start
                    if live is not None and c.get("/health/ready").status_code == 200:
                        ready = time.perf_counter() - start
                        cpu = cpu_seconds(proc.pid)
                except httpx.TransportError:
                    pass
                time.sleep(0.02)
    finally:
        proc.terminate()
        try:
            proc.wait(30)
        except subprocess.TimeoutExpired:
            proc.kill()
    assert live is not None and ready is not None
    return live, ready, *cpu


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--repo", type=Path, default=Path(__file__).resolve().parents[1])
    parser.add_argument("--json", type=Path)
    args = parser.parse_args()
    table = Table(f"start-up of the README's command, {args.repeats} runs after one that "
                  f"fills numba's cache, load average {os.getloadavg()[0]:.1f}")
    first = one_start(args.repo)
    table.record("first run (cache filled if cold): ready", first[1], f"live {first[0]:.2f} s")
    for k in range(args.repeats):
        live, ready, own, children = one_start(args.repo)
        table.record(f"run {k + 1}: ready", ready, f"live {live:.2f} s",
                     cpu_service=own, cpu_children=children, load=os.getloadavg()[0])
    if args.json:
        table.save(args.json, load_average=os.getloadavg())


if __name__ == "__main__":
    main()
