"""Jobs and sweeps through the client on a real embedded Dask cluster (as in
tests/service/test_jobs.py): progress, results as models, CSV, cancel, timeouts, problems."""

from __future__ import annotations

import asyncio
import csv
import io
import itertools
from collections.abc import Iterator
from typing import Any

import httpx
import numpy as np
import pytest
from fastapi.testclient import TestClient
from linkage_client import (
    AsyncClient,
    Client,
    Job,
    JobCancelled,
    JobTimeout,
    ProblemError,
    SpaceResult,
    TextBar,
)

from service.config import Settings
from service.main import create_app

pytestmark = pytest.mark.dask

QUICK = {"max_components": 2, "angles": 12, "random_starts": 2}
GATED = {"n": 3, "gate": 1}


def grashof(sides: list[float]) -> int:
    """Components of a generic planar four-bar (classical rule; 0: does not assemble)."""
    s = sorted(sides)
    if s[3] >= s[0] + s[1] + s[2]:
        return 0
    return 2 if s[0] + s[3] < s[1] + s[2] else 1


def generic(sides: list[float]) -> bool:
    return all(abs(np.dot(signs, sides)) > 1e-6
               for signs in itertools.product((1, -1), repeat=4) if signs[0] == 1)


@pytest.fixture(scope="module")
def app() -> Iterator[Any]:
    # small clusters for a 2-core machine: 2 Dask workers, 1 engine process
    with TestClient(create_app(Settings().replace(workers=1, dask_workers=2))) as http:
        yield http


@pytest.fixture(scope="module")
def jobs(app: TestClient) -> Client:
    return Client(http=app)


def test_grid_sweep_with_a_progress_callback_agrees_with_grashof(jobs: Client) -> None:
    seen: list[Job] = []
    result = jobs.sweep(linkage=jobs.get_preset_four_bar(),
                        grid={"L1": {"min": 0.4, "max": 1.7, "steps": 4},
                              "L2": {"min": 0.35, "max": 3.35, "steps": 5}},
                        compute=["components", "critical"], progress=seen.append,
                        timeout_s=120)
    assert len(result.rows) == 20 and result.summary.points == 20
    for row in result.rows:
        sides = [1.0, row.lengths["L1"], row.lengths["L2"], 1.0]
        if generic(sides):
            assert row.components == grashof(sides), row
    fractions = [j.progress.fraction for j in seen]
    assert fractions == sorted(fractions) and seen[-1].status == "done" and fractions[-1] == 1
    assert len({(j.status, j.progress.fraction, j.progress.message) for j in seen}) == len(seen)
    assert result.column("L1").shape == (20,) and np.isfinite(result.column("components")).all()


def test_job_result_as_the_operation_model_and_as_csv(jobs: Client) -> None:
    four = jobs.get_preset_four_bar(L2=0.9)
    space = jobs.run_job("analysis/configuration-space",
                         {"linkage": four.to_json(), "options": {**QUICK, "points": "compact"}},
                         timeout_s=120)
    assert isinstance(space, SpaceResult) and len(space.components) == 2
    assert space.components[0].positions.array.shape[1:] == (4, 2)
    sweep = jobs.create_sweep(preset="four-bar", grid={"L2": {"min": 0.5, "max": 2.5,
                                                               "steps": 3}})
    done = jobs.wait(sweep, timeout_s=120)
    rows = list(csv.DictReader(io.StringIO(jobs.get_job_result(done.id, csv=True))))
    assert [float(r["L2"]) for r in rows] == [0.5, 1.5, 2.5]
    assert jobs.get_job_result(done.id) == done.result


def slow_sweep(client: Client) -> Job:
    """Many gated-chain points with their critical points (the tracer's search, about half a
    second each, 2,000 of them; components and windings alone come from the chain rules in
    microseconds): far longer than any test waits."""
    return client.create_sweep(preset="gated-kl-chain", parameters=GATED,
                               samples={"D": {"mean": 2.5, "sd": 0.25}}, count=2000, seed=1,
                               compute=["components", "critical", "windings"], options=QUICK)


def test_timeout_cancels_the_job_and_a_text_bar_draws(jobs: Client) -> None:
    stream = io.StringIO()
    job = slow_sweep(jobs)
    with pytest.raises(ProblemError) as err:
        jobs.get_job_result(job.id)
    assert (err.value.status, err.value.kind) == (409, "job-not-done")
    with pytest.raises(JobTimeout) as timeout:
        jobs.wait(job, timeout_s=1.0, progress=TextBar(stream))
    assert timeout.value.job.status == "cancelled"
    assert jobs.get_job(job.id).status == "cancelled"
    assert "[" in stream.getvalue() and "%" in stream.getvalue()
    with pytest.raises(JobCancelled):  # waiting on a cancelled job says so
        jobs.wait(job.id)


def test_cancel_job_and_failed_problem(jobs: Client) -> None:
    job = slow_sweep(jobs)
    cancelled = jobs.cancel_job(job.id)
    assert cancelled.status == "cancelled" and cancelled.done
    with pytest.raises(ProblemError) as err:
        jobs.create_job("analysis/rigidity", {"linkage": {"vertices": []}})
    assert err.value.errors[0].loc == ("body", "body", "linkage", "vertices")


def test_async_job_cancelled_with_its_task(app: TestClient) -> None:
    """Cancelling the awaiting task cancels the job on the service; a second job runs to its
    answer with progress through the async client."""

    async def scenario() -> tuple[str, str, Any, list[float]]:
        transport = httpx.ASGITransport(app=app.app, raise_app_exceptions=False)
        async with AsyncClient(base_url="http://testserver", transport=transport) as client:
            job = await client.create_sweep(
                preset="gated-kl-chain", parameters=GATED, samples={"D": {"mean": 2.5,
                                                                           "sd": 0.25}},
                count=2000, seed=2, compute=["components", "critical"], options=QUICK)
            waiting = asyncio.create_task(client.wait(job, poll_s=0.1))
            await asyncio.sleep(1.0)
            waiting.cancel()
            with pytest.raises(asyncio.CancelledError):
                await waiting
            status = (await client.get_job(job.id)).status
            seen: list[float] = []
            result = await client.run_job(
                "analysis/critical-points",
                {"linkage": (await client.get_preset_four_bar()).to_json(),
                 "options": QUICK}, progress=lambda j: seen.append(j.progress.fraction),
                timeout_s=120)
            return job.id, status, result, seen

    _, status, result, seen = asyncio.run(scenario())
    assert status == "cancelled"
    assert [cp.kind for cp in result.critical_points] == ["branch"] * 3
    assert seen and seen[-1] == 1.0 and seen == sorted(seen)
    assert app.get("/health").status_code == 200
