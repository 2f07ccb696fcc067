"""How long a job's large answer takes to reach its client once the worker is done.

    .venv/bin/python bench/bench_job_result.py [--n 30] [--step 0.01]

A configuration-space job of the ``kl-chain`` preset (``n`` rotors, ``step_max`` small enough
for a large answer: some 55 MB of JSON for the defaults) runs on a one-worker embedded cluster
through :class:`service.tasks.JobManager`, as ``POST /v1/jobs`` runs it. Measured, in the
service process: from the worker's last progress report (its answer serialised) to the job
``done`` (the answer moved and kept), then what ``GET /v1/jobs/{id}`` serialises (the job with
its result) and what ``GET /v1/jobs/{id}/result`` sends.

Issue 31 keeps the answer as the worker's JSON (``serialise.RawJSON``) instead of parsing it
in the service. On the shared 2-core machine (load about 10), 55.5 MB answer, two runs each:
last report -> done 4.2-4.4 s before, 0.13-0.19 s after; ``GET`` the job 0.32-0.66 s before,
0.04-0.11 s after; ``GET`` the result 0.37-1.07 s before, under 1 ms after.
"""

from __future__ import annotations

import argparse
import time

from engine.catalogue.presets import build_preset
from service import mappers, serialise
from service.config import Settings
from service.schemas.space import SpaceRequest
from service.tasks import JobManager


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--n", type=int, default=30)
    parser.add_argument("--step", type=float, default=0.01)
    args = parser.parse_args()
    settings = Settings().replace(dask_workers=1, job_time_limit_s=600.0)
    linkage = mappers.linkage_out(build_preset("kl-chain", {"n": args.n}))
    body = SpaceRequest.model_validate({
        "linkage": linkage.model_dump(mode="json", exclude_none=True),
        "options": {"max_points": 200_000, "step_max": args.step, "max_components": 4,
                    "angles": 8, "random_starts": 0}})
    manager = JobManager(settings)
    try:
        manager.client().wait_for_workers(1, timeout=120)
        job = manager.submit("analysis/configuration-space", body)
        reported = None
        while job.status not in ("done", "failed", "cancelled"):
            if reported is None and job.done[0] >= 1.0:
                reported = time.perf_counter()  # the worker's last report: its answer is made
            time.sleep(0.001)
        done = time.perf_counter()
        assert job.status == "done", job.error
        start = time.perf_counter()
        page = serialise.dumps(mappers.job_out(job, manager.expires(job)))
        get_job = time.perf_counter() - start
        start = time.perf_counter()
        raw = getattr(serialise, "RawJSON", ())  # () before issue 31: the bench runs on both
        result = (job.result.data if isinstance(job.result, raw)
                  else serialise.dumps(job.result))
        get_result = time.perf_counter() - start
        moved = float("nan") if reported is None else done - reported
        print(f"answer {len(result) / 1e6:.1f} MB; worker's last report -> job done "
              f"{moved:.3f} s; GET job serialises {len(page) / 1e6:.1f} MB in {get_job:.3f} s; "
              f"GET result {get_result:.3f} s")
    finally:
        manager.close()


if __name__ == "__main__":
    main()
