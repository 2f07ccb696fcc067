"""Sweep points per second on 1 and 2 workers of the embedded Dask cluster, and the gated grid.

    .venv/bin/python bench/bench_sweep.py [--repeat 3] [--json bench/results/sweep.json]
    .venv/bin/python bench/bench_sweep.py --gated [--steps 20] [--repo DIR] [--json ...]

Two sweeps, each run as a job by :class:`service.tasks.JobManager` exactly as ``POST
/v1/sweeps`` runs it (chunks on the workers, progress events, rows gathered and summarised):

* ``four-bar grid``: 400 points of a four-bar grid over L1 and L2, components only (the closed
  form: milliseconds per point, so this measures the overhead of the job machinery too);
* ``gated chain MC``: 24 Monte Carlo samples of the gate length D of a 3-rotor gated chain,
  components and windings (traced until the chain rules gave these rows: about half a second
  a point then, milliseconds now).

The cluster is started and warmed up before timing (its start-up is not part of a sweep). Best
of ``--repeat`` wall-clock runs, from submission to the finished job; the machine is shared, so
timings are noisy.

``--gated``: the issue's sweep, a ``--steps`` x ``--steps`` grid of the gated 4-rotor chain
(gate 2) over (L2, D) in [0.5, 5]^2 with components and windings, timed in this process
(:func:`engine.design.sweep.run_points`) and through HTTP (``POST /v1/sweeps`` to a uvicorn
process with its embedded 2-worker cluster, polled to the end; the cluster is warmed up by one
small sweep first). ``--repo DIR`` serves (and runs in-process) another checkout's code, e.g.
the tree before a change (``git archive``); a smaller grid stands for the 20 x 20 one where
the old code is slow (``per_point`` times 400 is then an extrapolation, and says so).
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from functools import partial
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent))
from harness import Table, best_of  # noqa: E402

from service import mappers, tasks
from service.config import Settings
from service.schemas.jobs import SweepRequest

SWEEPS: dict[str, dict[str, Any]] = {
    "four-bar grid": {
        "preset": {"name": "four-bar"},
        "grid": {"L1": {"min": 0.4, "max": 1.7, "steps": 20},
                 "L2": {"min": 0.35, "max": 3.35, "steps": 20}},
    },
    "gated chain MC": {
        "preset": {"name": "gated-kl-chain", "parameters": {"n": 3, "gate": 1}},
        "samples": {"D": {"mean": 2.5, "sd": 0.25}}, "count": 24, "seed": 0,
        "compute": ["components", "windings"],
        "options": {"max_components": 2, "angles": 12, "random_starts": 2},
    },
}


def run(manager: tasks.JobManager, body: dict[str, Any]) -> int:
    req = SweepRequest.model_validate(body)
    sweep = mappers.sweep_in(req, manager.settings.limits)
    job = manager.submit_sweep(sweep, sweep.names)
    while not job.finished_state:
        time.sleep(0.01)
    assert job.status == "done", job.error
    return int(job.result["summary"]["points"])


def gated_body(steps: int) -> dict[str, Any]:
    """The issue's gated sweep on a ``steps`` x ``steps`` grid."""
    return {"preset": {"name": "gated-kl-chain", "parameters": {"n": 4, "gate": 2}},
            "grid": {"L2": {"min": 0.5, "max": 5.0, "steps": steps},
                     "D": {"min": 0.5, "max": 5.0, "steps": steps}},
            "compute": ["components", "windings"]}


def run_http(url: str, body: dict[str, Any]) -> int:
    import httpx

    with httpx.Client(base_url=url, timeout=30.0) as client:
        r = client.post("/v1/sweeps", json=body)
        assert r.status_code == 202, r.text
        where = r.headers["location"]
        while (job := client.get(where).json())["status"] in ("queued", "running"):
            time.sleep(0.05)
        assert job["status"] == "done", job
        return int(job["result"]["summary"]["points"])


def in_process(repo: Path | None, body: dict[str, Any]) -> float:
    """Seconds of the sweep's points in one plain process (``repo``'s code)."""
    import json
    import subprocess

    code = ("import json, sys, time; from service import mappers; from service.config import "
            "Settings; from service.schemas.jobs import SweepRequest; "
            "from engine.design.sweep import run_points; from engine.space import trace_kernel; "
            "trace_kernel.prepare(); "
            "s = mappers.sweep_in(SweepRequest.model_validate(json.loads(sys.argv[1])), "
            "Settings().limits); t = time.perf_counter(); "
            "run_points(s.family, s.points, s.compute, s.tolerances, s.options); "
            "print(time.perf_counter() - t)")
    out = subprocess.run([sys.executable, "-c", code, json.dumps(body)], capture_output=True,
                         text=True, check=True, cwd=repo or Path(__file__).resolve().parents[1])
    return float(out.stdout.strip().splitlines()[-1])


def gated(args: argparse.Namespace) -> Table:
    from harness import served_process

    table = Table(f"gated 4-rotor chain, {args.steps} x {args.steps} (L2, D), components + "
                  f"windings ({'code of ' + str(args.repo) if args.repo else 'this tree'})")
    body = gated_body(args.steps)
    n = args.steps ** 2
    seconds = min(in_process(args.repo, body) for _ in range(args.repeat))
    table.record("in process (one core)", seconds, f"{n} points", per_point=seconds / n,
                 for_400_points=seconds / n * 400, extrapolated=n < 400)
    with served_process(repo=args.repo, env={"LINKAGE_DASK_WORKERS": "2"},
                        timeout=180.0) as url:
        run_http(url, gated_body(2))  # warm-up: starts the embedded cluster
        seconds, points = best_of(partial(run_http, url, body), args.repeat)
        table.record("HTTP, embedded cluster of 2 workers", seconds, f"{points} points",
                     per_point=seconds / points, for_400_points=seconds / points * 400,
                     extrapolated=points < 400)
    return table


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--json", type=Path)
    ap.add_argument("--gated", action="store_true", help="the gated (L2, D) grid only")
    ap.add_argument("--steps", type=int, default=20)
    ap.add_argument("--repo", type=Path, help="the checkout whose code is timed")
    args = ap.parse_args()
    if args.gated:
        table = gated(args)
        if args.json:
            table.save(args.json, load_average=os.getloadavg())
        return
    table = Table("sweep points per second, embedded LocalCluster (1 thread per worker)")
    for workers in (1, 2):
        manager = tasks.JobManager(Settings().replace(dask_workers=workers))
        try:
            manager.client().wait_for_workers(workers)
            run(manager, {**SWEEPS["four-bar grid"],
                          "grid": {"L2": {"min": 0.5, "max": 1.5, "steps": 4}}})  # warm-up
            for name, body in SWEEPS.items():
                seconds, points = best_of(partial(run, manager, body), args.repeat)
                table.record(f"{name}, {workers} worker(s)", seconds, f"{points} points",
                             points_per_s=points / seconds, workers=workers)
        finally:
            manager.close()
    if args.json:
        table.save(args.json)


if __name__ == "__main__":
    main()
