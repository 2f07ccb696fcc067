"""Sweep points per second on 1 and 2 workers of the embedded Dask cluster.

    .venv/bin/python bench/bench_sweep.py [--repeat 3] [--json bench/results/sweep.json]

Two sweeps, each run as a job by :class:`service.tasks.JobManager` exactly as ``POST
/v1/sweeps`` runs it (chunks on the workers, progress events, rows gathered and summarised):

* ``four-bar grid``: 400 points of a four-bar grid over L1 and L2, components only (the closed
  form: milliseconds per point, so this measures the overhead of the job machinery too);
* ``gated chain MC``: 24 Monte Carlo samples of the gate length D of a 3-rotor gated chain,
  components and windings (traced: about half a second per point).

The cluster is started and warmed up before timing (its start-up is not part of a sweep). Best
of ``--repeat`` wall-clock runs, from submission to the finished job; the machine is shared, so
timings are noisy.
"""

from __future__ import annotations

import argparse
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


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--json", type=Path)
    args = ap.parse_args()
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
