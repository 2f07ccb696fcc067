"""Memory-bounded engine workers (issue 11, item 4): the cost of a first- or second-order
analysis is known before it is spent, a worker cannot allocate beyond
``LINKAGE_WORKER_MEMORY_MB``, and neither kind of refusal is a 500 or stops the service.

Each test builds its own application with one real worker process (as
tests/service/test_hardening.py does) and talks to it in-process over the ASGI transport.
"""

from __future__ import annotations

import asyncio
import os
import signal
import time
from pathlib import Path
from typing import Any

import httpx
import numpy as np
import pytest

from bench.bench_memory import floppy_chain
from service.config import Settings, default_worker_memory_mb, machine_memory_mb
from service.main import create_app
from service.schemas.common import AnalysisRequest
from service.workers import WORKER_NICE, EnginePool, MemoryLimit, WorkerFailed
from tests.service.test_hardening import (
    OVERRUN_PATH,
    assert_problem,
    busy_body,
    client_for,
    collinear,
    overrun_body,
)

# An application with its own worker process per test: seconds each.
pytestmark = pytest.mark.slow

# A warm worker's data segment is about 230 MB: this leaves it a few hundred MB to work with.
SMALL_WORKER_MB = 640


def worker_peak_mb(pid: int) -> float:
    """High-water resident size (``VmHWM``) of a process, in MB."""
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmHWM:"):
            return int(line.split()[1]) / 1024
    raise AssertionError("no VmHWM")


@pytest.fixture(scope="module")
def four_bar() -> dict[str, Any]:
    from engine.catalogue.presets import build_preset
    from service.mappers import linkage_out

    return linkage_out(build_preset("four-bar")).model_dump(mode="json")


def run(app: Any, requests: list[tuple[str, dict[str, Any]]]) -> list[httpx.Response]:
    async def scenario() -> list[httpx.Response]:
        async with client_for(app) as c:
            return [await c.post(url, json=body) for url, body in requests]

    return asyncio.run(scenario())


@pytest.mark.parametrize("route", ["/v1/analysis/rigidity", "/v1/analysis/second-order"])
def test_a_memory_bounded_worker_refuses_the_floppy_50000_vertex_chain(route, four_bar):
    app = create_app(Settings(workers=1, time_limit_s=60, worker_memory_mb=SMALL_WORKER_MB))
    chain = floppy_chain(49_998)  # 50,000 vertices: the size limit
    try:
        refused, after, again = run(app, [
            (route, {"linkage": chain}),
            ("/v1/analysis/critical-points", {"linkage": four_bar}),  # in the worker
            (route, {"linkage": chain}),
        ])
        (pid,) = app.state.engine_pool.worker_pids()
        peak = worker_peak_mb(pid)
    finally:
        app.state.engine_pool.close()
    body = assert_problem(refused, 422, "limit-exceeded")
    assert "49997 independent zero modes" in body["detail"]
    assert "(2000)" in body["detail"] and "(4000)" in body["detail"]  # the limits it meets
    assert body["errors"][0]["loc"] == ["body", "linkage"]
    assert after.status_code == 200, after.text
    assert len(after.json()["critical_points"]) == 3
    assert again.status_code == 422  # the same answer, not a crash the second time
    assert peak < SMALL_WORKER_MB


def test_the_floppy_8000_vertex_chain_answers_without_holding_gigabytes(four_bar):
    # default memory limit: the refusal comes from the estimate, not from hitting the limit
    app = create_app(Settings(workers=1, time_limit_s=60))
    try:
        rig, sec, after = run(app, [
            ("/v1/analysis/rigidity", {"linkage": floppy_chain(8000)}),
            ("/v1/analysis/second-order", {"linkage": floppy_chain(8000)}),
            ("/v1/analysis/critical-points", {"linkage": four_bar}),
        ])
        (pid,) = app.state.engine_pool.worker_pids()
        peak = worker_peak_mb(pid)
    finally:
        app.state.engine_pool.close()
    for r in (rig, sec):
        body = assert_problem(r, 422, "limit-exceeded")
        assert "7999 independent zero modes" in body["detail"]
    assert after.status_code == 200, after.text
    assert peak < 400, f"the worker held {peak:.0f} MB"  # it held 2.1 GB for 30 s before


@pytest.mark.parametrize("route", ["/v1/analysis/rigidity", "/v1/analysis/second-order"])
def test_an_analysis_beyond_the_worker_memory_is_refused_before_it_starts(route, four_bar):
    # 2,000 free vertices: the dense SVD can answer (M = 4000), but the answer alone holds
    # 8 million numbers, more than a 640 MB worker can hold
    app = create_app(Settings(workers=1, time_limit_s=60, worker_memory_mb=SMALL_WORKER_MB))
    try:
        refused, after = run(app, [
            (route, {"linkage": floppy_chain(2000)}),
            ("/v1/analysis/critical-points", {"linkage": four_bar}),
        ])
        (pid,) = app.state.engine_pool.worker_pids()
        peak = worker_peak_mb(pid)
    finally:
        app.state.engine_pool.close()
    body = assert_problem(refused, 422, "memory-limit")
    assert "LINKAGE_WORKER_MEMORY_MB" in body["detail"]
    assert "dense-svd, M = 4000 free coordinates, E = 2001 bars" in body["detail"]
    assert after.status_code == 200, after.text
    assert peak < SMALL_WORKER_MB


def test_a_floppy_chain_within_the_limits_is_answered(four_bar):
    """300 free vertices: 299 zero modes, answered by the dense SVD (the default for such
    large null spaces) within a small worker."""
    app = create_app(Settings(workers=1, time_limit_s=60, worker_memory_mb=SMALL_WORKER_MB))
    try:
        (r,) = run(app, [("/v1/analysis/rigidity", {"linkage": floppy_chain(300)})])
    finally:
        app.state.engine_pool.close()
    assert r.status_code == 200, r.text
    body = r.json()
    assert body["dof"] == 299 and len(body["zero_modes"]) == 299
    assert body["method"] == "dense-svd"


def _loaded(name: str) -> bool:
    import sys

    return name in sys.modules


def test_a_worker_starts_with_the_figures_imported():
    """The forkserver imports the figures (matplotlib) once: a worker's first figure request
    does not pay the import (1-3 s on a loaded 2-core machine, issue 30)."""
    pool = EnginePool(1, 4)
    try:
        pool.start()
        assert asyncio.run(pool.run(30, _loaded, "service.figures"))
        assert asyncio.run(pool.run(30, _loaded, "matplotlib.figure"))
    finally:
        pool.close()


def _allocate(n_bytes: int) -> int:
    return int(np.ones(n_bytes // 8).size)


def _kernels_in_this_process() -> tuple[bool, bool, int]:
    """Whether the tracer's and the closed form's compiled kernels are loaded here, without
    loading them (the modules' state, read before anything calls ``prepare``)."""
    from engine.space import trace_kernel
    from engine.space.dyads import kernel as dyads_kernel

    return (trace_kernel._kernel is not None, dyads_kernel._module is not None, os.getpid())


def test_workers_and_their_replacements_start_with_the_kernels_loaded():
    """The forkserver loads the kernels (service.warm) and each worker forked from it,
    a replacement of a killed one too, has them before its first task (issue 28: half a
    second of a core per worker at start-up, which the start-up no longer waits for)."""
    pool = EnginePool(1, 4, watch_interval_s=None)
    try:
        pool.start()
        tracer, dyads, first = asyncio.run(pool.run(30, _kernels_in_this_process))
        assert tracer and dyads
        # and below the service's priority, so that its event loop comes first
        assert (os.getpriority(os.PRIO_PROCESS, first)
                == os.getpriority(os.PRIO_PROCESS, 0) + WORKER_NICE)
        kill([first])
        deadline = time.monotonic() + 30
        while True:  # the next task is served by a replacement
            try:
                tracer, dyads, pid = asyncio.run(pool.run(30, _kernels_in_this_process))
                break
            except WorkerFailed:
                assert time.monotonic() < deadline
                time.sleep(0.1)
        assert pid != first and tracer and dyads
    finally:
        pool.close()


def test_a_memory_error_in_a_worker_is_a_422_and_the_worker_keeps_serving():
    pool = EnginePool(1, 4, memory_mb=SMALL_WORKER_MB)
    try:
        pool.start()
        (before,) = pool.worker_pids()
        with pytest.raises(MemoryLimit) as err:
            asyncio.run(pool.run(30, _allocate, 2 * SMALL_WORKER_MB * 2**20))
        assert err.value.status == 422 and err.value.kind == "memory-limit"
        assert f"LINKAGE_WORKER_MEMORY_MB = {SMALL_WORKER_MB}" in err.value.detail
        assert asyncio.run(pool.run(30, _allocate, 8 * 2**20)) == 2**20
        assert pool.worker_pids() == [before]  # the same worker, not a replacement
    finally:
        pool.close()


def test_a_memory_error_in_the_service_process_is_a_503(four_bar, monkeypatch):
    from service import jobs

    def out_of_memory(*args: Any) -> Any:
        raise MemoryError("simulated")

    # a small linkage is analysed in the service's thread pool, not in a worker
    monkeypatch.setattr(jobs, "rigidity", out_of_memory)
    app = create_app(Settings(workers=1))
    try:
        failed, after = run(app, [("/v1/analysis/rigidity", {"linkage": four_bar}),
                                  ("/v1/analysis/second-order", {"linkage": four_bar})])
    finally:
        app.state.engine_pool.close()
    assert_problem(failed, 503, "out-of-memory")
    assert failed.headers["retry-after"]
    assert after.status_code == 200, after.text


def test_worker_memory_setting(monkeypatch):
    monkeypatch.setenv("LINKAGE_WORKERS", "2")
    monkeypatch.delenv("LINKAGE_WORKER_MEMORY_MB", raising=False)
    derived = Settings.from_env()
    assert derived.worker_memory_mb is None
    assert derived.worker_memory == default_worker_memory_mb(2)
    assert 512 <= derived.worker_memory <= max(512, machine_memory_mb() * 3 // 8)
    monkeypatch.setenv("LINKAGE_WORKER_MEMORY_MB", "1500")
    assert Settings.from_env().worker_memory == 1500
    for bad in ("0", "100", "lots"):
        monkeypatch.setenv("LINKAGE_WORKER_MEMORY_MB", bad)
        with pytest.raises(ValueError, match="LINKAGE_WORKER_MEMORY_MB|invalid literal"):
            Settings.from_env()


# --- worker deaths in every state (issue 28, item 1) -------------------------------------------
# pebble 5 declares a pool broken for good when a worker dies while no task runs: every later
# request answered 500 ("Unexpected error within the Pool") until the service was restarted.


def cpu_ticks(pid: int) -> int:
    """User plus system CPU time of a process so far, in clock ticks (``/proc/<pid>/stat``)."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return int(fields[11]) + int(fields[12])


def busy_and_idle(pids: list[int]) -> tuple[int, int]:
    """Of two workers, the one using the CPU and the one that is not."""
    before = {pid: cpu_ticks(pid) for pid in pids}
    time.sleep(0.5)
    used = sorted(pids, key=lambda pid: cpu_ticks(pid) - before[pid])
    return used[1], used[0]


def answered(responses: list[httpx.Response]) -> None:
    """Each a 200, or a 503 with ``Retry-After`` while the pool is replaced (then 200s)."""
    codes = [r.status_code for r in responses]
    assert codes[-1] == 200, responses[-1].text
    for r in responses:
        if r.status_code == 503:
            assert r.headers["retry-after"], r.text
            assert r.headers["content-type"].startswith("application/problem+json")
        else:
            assert r.status_code == 200, r.text


async def critical_points(c: httpx.AsyncClient, four_bar: dict[str, Any],
                          times: int = 3) -> list[httpx.Response]:
    out = []
    for _ in range(times):
        out.append(await c.post("/v1/analysis/critical-points", json={"linkage": four_bar}))
        if out[-1].status_code == 503:
            await asyncio.sleep(float(out[-1].headers["retry-after"]))
    return out


def kill(pids: list[int]) -> None:
    for pid in pids:
        os.kill(pid, signal.SIGKILL)  # as the out-of-memory killer would


@pytest.mark.parametrize("watchdog", [True, False])
def test_an_idle_worker_killed_before_any_request_is_replaced(four_bar, watchdog):
    app = create_app(Settings(workers=1, time_limit_s=30))
    pool = app.state.engine_pool = EnginePool(
        1, 8, watch_interval_s=0.5 if watchdog else None)

    async def scenario() -> tuple[list[httpx.Response], httpx.Response, httpx.Response]:
        async with client_for(app) as c:
            pool.start()
            victims = pool.worker_pids()
            kill(victims)
            # pebble notices the death within its 0.1 s loop, the watchdog replaces the pool
            # within its 0.5 s, on an idle machine (fixed sleeps of 0.3 and 1.0 s were too
            # short at load 10: /health/ready still answered 200 before pebble noticed)
            deadline = time.monotonic() + 60
            while not (pool.replacements and pool.ready if watchdog else pool.broken):
                assert time.monotonic() < deadline
                await asyncio.sleep(0.05)
            if watchdog:
                not_ready = None
            else:  # nothing replaces it before a request: the pool is reported broken
                not_ready = await c.get("/health/ready")
            answers = await critical_points(c, four_bar)
            return answers, not_ready, await c.get("/health/ready")

    try:
        answers, not_ready, ready = asyncio.run(scenario())
        after = pool.worker_pids()
    finally:
        pool.close()
    answered(answers)
    assert len(answers[-1].json()["critical_points"]) == 3
    if not_ready is not None:
        body = assert_problem(not_ready, 503, "not-ready")
        assert "being replaced" in body["detail"] and not_ready.headers["retry-after"] == "1"
    assert ready.status_code == 200, ready.text
    assert ready.json()["workers"] == 1
    assert len(after) == 1 and pool.replacements == 1


def test_a_worker_killed_between_requests_is_replaced(four_bar):
    app = create_app(Settings(workers=2, time_limit_s=30))
    pool = app.state.engine_pool

    async def scenario() -> tuple[list[httpx.Response], list[httpx.Response]]:
        async with client_for(app) as c:
            first = await critical_points(c, four_bar, times=2)
            pool.start()  # the watchdog, as the lifespan starts it
            kill(pool.worker_pids())  # both idle, between requests
            await asyncio.sleep(0.3)
            return first, await critical_points(c, four_bar, times=4)

    try:
        first, then = asyncio.run(scenario())
        after = pool.worker_pids()
    finally:
        pool.close()
    assert [r.status_code for r in first] == [200, 200]
    answered(then)
    assert len(after) == 2 and pool.replacements >= 1


def test_an_idle_worker_killed_beside_a_busy_one(four_bar):
    """The busy worker's request finishes (at its time limit); the idle one is replaced by
    pebble itself (a task was running) and later requests are served."""
    app = create_app(Settings(workers=2, time_limit_s=1.5))
    pool = app.state.engine_pool

    async def scenario() -> tuple[httpx.Response, list[httpx.Response], int]:
        async with client_for(app) as c:
            pool.start()
            slow = asyncio.create_task(c.post(OVERRUN_PATH, json=overrun_body()))
            await asyncio.sleep(0.5)
            busy, idle = busy_and_idle(pool.worker_pids())
            kill([idle])
            small = await critical_points(c, four_bar)
            done = await slow
            for _ in range(50):  # the time limit's replacement starting
                if len(pool.worker_pids()) == 2:
                    break
                await asyncio.sleep(0.1)
            return done, small, busy

    try:
        slow, small, busy = asyncio.run(scenario())
        after = pool.worker_pids()
    finally:
        pool.close()
    # its own worker was never touched: stopped at the time limit, not failed
    assert_problem(slow, 504, "time-limit")
    answered(small)
    assert len(after) == 2 and busy not in after


def test_a_busy_worker_killed_fails_its_request_and_the_next_is_served(four_bar):
    app = create_app(Settings(workers=1, time_limit_s=30))
    pool = app.state.engine_pool

    async def scenario() -> tuple[httpx.Response, list[httpx.Response], httpx.Response]:
        async with client_for(app) as c:
            pool.start()
            slow = asyncio.create_task(c.post(
                "/v1/analysis/configuration-space", json=busy_body(20.0)))
            await asyncio.sleep(1.0)
            kill(pool.worker_pids())
            failed = await slow
            return failed, await critical_points(c, four_bar), await c.get("/health/ready")

    try:
        failed, small, ready = asyncio.run(scenario())
    finally:
        pool.close()
    assert_problem(failed, 503, "worker-failed")
    assert failed.headers["retry-after"] == "1"
    answered(small)
    assert ready.status_code == 200, ready.text


def test_small_requests_have_a_lane_of_their_own():
    """Small requests (answered in the service's thread pool) are admitted apart from the
    workers' queue: a full engine queue does not refuse them, and beyond LINKAGE_MAX_QUEUE of
    their own they are a 503 busy with Retry-After (no workers are started here)."""
    from service.workers import Busy

    pool = EnginePool(1, 2)
    pool.admitted = pool.max_queue  # every engine slot taken
    with pool.light_lane(30), pool.light_lane(30):
        assert pool.light_admitted == 2
        with pytest.raises(Busy) as err, pool.light_lane(30):
            pass
    assert err.value.status == 503 and err.value.retry_after == 1
    assert "LINKAGE_MAX_QUEUE = 2" in err.value.detail
    assert pool.light_admitted == 0
    with pool.light_lane(30):  # free again
        assert pool.light_admitted == 1


def test_a_script_importing_the_app_starts_workers(tmp_path):
    """A script whose ``__main__`` imports ``service.main`` (benchmarks, examples) has its
    workers import that script again while they bootstrap: the app's early start of the
    forkserver must do nothing there (it failed the workers, replaced for ever, before)."""
    import subprocess
    import sys

    script = tmp_path / "script.py"
    script.write_text(
        "import asyncio, os\n"
        "import service.main\n"
        "from service.workers import EnginePool\n"
        "if __name__ == '__main__':\n"
        "    pool = EnginePool(1, 2, watch_interval_s=None)\n"
        "    pool.start()\n"
        "    print('worker', asyncio.run(pool.run(60, os.getpid)) != os.getpid(),\n"
        "          pool.replacements)\n"
        "    pool.close()\n")
    root = Path(__file__).resolve().parents[2]
    out = subprocess.run([sys.executable, str(script)], cwd=root, capture_output=True,
                         text=True, timeout=300, env={**os.environ, "PYTHONPATH": str(root)})
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.split()[-3:] == ["worker", "True", "0"], out.stdout
    assert "RuntimeError" not in out.stderr, out.stderr[-2000:]


def test_the_analysis_routes_need_no_thread_for_their_dependencies():
    """FastAPI runs a plain-function dependency in the thread pool: two thread hand-offs per
    request, most of a small request's time on a loaded machine (bench/bench_lanes.py). The
    analysis routes' dependencies (their settings) are coroutines, run on the event loop."""
    import inspect

    from fastapi.routing import APIRoute

    def calls(dependant: Any) -> list[Any]:
        out = []
        for sub in dependant.dependencies:
            out += [sub.call, *calls(sub)]
        return out

    from service.routers import analysis

    routes = [r for r in analysis.router.routes if isinstance(r, APIRoute)]
    assert len(routes) >= 7
    for route in routes:
        found = calls(route.dependant)
        assert found, route.path  # the settings
        assert all(inspect.iscoroutinefunction(call) for call in found), (route.path, found)


def test_a_tiny_first_order_request_is_answered_on_the_event_loop(monkeypatch):
    """A four-bar's rigidity (INLINE_MAX_VERTICES) is answered without the thread pool; a
    larger light one still goes through it."""
    import threading

    from fastapi.testclient import TestClient

    from service import jobs, workers

    threads: list[str] = []
    original = jobs.rigidity

    def spy(body: Any, settings: Settings) -> Any:
        threads.append(threading.current_thread().name)
        return original(body, settings)

    monkeypatch.setattr(jobs, "rigidity", spy)
    client = TestClient(create_app(Settings(workers=1)))  # not entered: no workers started
    four_bar = client.get("/v1/presets/four-bar").json()
    chain = client.get("/v1/presets/kl-chain?n=12").json()
    assert len(chain["vertices"]) > workers.INLINE_MAX_VERTICES
    assert jobs.is_light(AnalysisRequest.model_validate({"linkage": chain}))
    for linkage in (four_bar, chain):
        assert client.post("/v1/analysis/rigidity", json={"linkage": linkage}).status_code == 200
    loop_thread, pool_thread = threads
    assert "AnyIO" not in loop_thread and "AnyIO" in pool_thread, threads


@pytest.mark.parametrize(("n", "bars", "pinned", "fixed", "light", "light_second"), [
    # M = 2 (n - pinned) free coordinates counted by hand, E = bars
    (4, 3, 2, None, True, True),        # the four-bar's sizes: M 4, E 3, M E 12
    (32, 88, 0, None, True, False),     # M 64, E 88: 11,840 numbers, below 12,288
    (32, 96, 0, None, False, False),    # M 64, E 96: 13,312 numbers
    (8, 8, 0, None, True, True),        # M 16, E 8: M E = 128, the largest second order taken
    (8, 9, 0, None, True, False),       # M 16, E 9: M E = 144
    (8, 15, 0, [True, False], True, True),  # a slider per vertex: M 8, E 15, M E = 120
])
def test_the_light_lane_takes_a_request_by_its_estimated_worst_cost(
        n, bars, pinned, fixed, light, light_second):
    """Zero modes and self-stresses of at most M^2 + E^2 numbers (``LIGHT_MAX_NUMBERS``) and,
    for second order, ``M E`` at most ``LIGHT_SECOND_ORDER_MAX_PRODUCT``; sizes counted here
    from the request by hand, not by the service's counter."""
    from service import jobs, workers

    linkage = collinear(n, bars, pinned)
    if fixed is not None:
        for v in linkage["vertices"]:
            v["fixed"] = fixed
    body = AnalysisRequest.model_validate({"linkage": linkage})
    free = sum(2 - (sum(v["fixed"]) if isinstance(v["fixed"], list) else 2 * v["fixed"])
               for v in linkage["vertices"])
    assert jobs.free_coordinates(body.linkage) == free
    assert jobs.is_light(body) is (free**2 + bars**2 <= workers.LIGHT_MAX_NUMBERS) is light
    assert jobs.is_light(body, second_order=True) is light_second


def test_a_request_beyond_the_estimate_is_answered_by_a_worker(monkeypatch):
    """A collinear linkage of 32 vertices and 96 bars (estimated 13,312 numbers) is answered by
    an engine worker; one of 88 bars (11,840) by the service's own process."""
    scheduled: list[Any] = []
    original = EnginePool.run

    async def counted(self: EnginePool, time_limit: float, fn: Any, *args: Any) -> Any:
        scheduled.append(args[0])  # the job run by service.workers._as_json
        return await original(self, time_limit, fn, *args)

    monkeypatch.setattr(EnginePool, "run", counted)
    app = create_app(Settings(workers=1))
    heavy, light = run(app, [("/v1/analysis/rigidity", {"linkage": collinear(32, 96)}),
                             ("/v1/analysis/rigidity", {"linkage": collinear(32, 88)})])
    assert heavy.status_code == 200, heavy.text
    assert light.status_code == 200, light.text
    assert [fn.__name__ for fn in scheduled] == ["rigidity"]  # the heavy one only
    # the same analysis wherever it ran: on a line of n free vertices whose path of bars spans
    # it, every vertical motion is a first-order flex, n - 2 of them beyond the trivial ones
    assert len(heavy.json()["zero_modes"]) == len(light.json()["zero_modes"]) == 32 - 2


def test_time_lost_in_the_queue_is_a_503_not_a_too_costly_422():
    """An analysis that would not end in the time left (the engine's OutOfTime) is the input's
    fault (422) when it started at once, the queue's (503 busy, Retry-After) when it waited for
    a worker more than QUEUE_SHARE of the time limit; the 503 crosses the process boundary with
    its Retry-After (pickled as a worker's exception is)."""
    import pickle

    from engine.model.budget import OutOfTime
    from service import workers

    settings = Settings(time_limit_s=10.0)
    err = OutOfTime("a dense SVD takes about 9 s, more than the 2.0 s left")
    assert workers._queued_too_long(err, settings, 0.5) is err  # 0.5 s < 0.1 * 10 s
    busy = workers._queued_too_long(err, settings, 3.2)
    assert isinstance(busy, workers.Busy) and busy.status == 503
    assert "waited 3.2 s" in busy.detail and busy.retry_after == 3
    back = pickle.loads(pickle.dumps(busy))
    assert (type(back), back.detail, back.retry_after) == (workers.Busy, busy.detail, 3)


def test_only_a_request_that_finds_every_worker_taken_counts_its_wait(monkeypatch, four_bar):
    """The time from the hand-over to a worker counts as queueing (for the 503 above) only
    where every worker was taken then, or the pool not ready: a request handed to a free
    worker that starts late on a loaded machine lost no time in a queue (it answered 503
    "waited for an engine worker" instead of its 422 too-costly)."""
    handed: list[tuple[str, float | None]] = []
    original = EnginePool.run

    async def recorded(self: EnginePool, time_limit: float, fn: Any, *args: Any) -> Any:
        handed.append((args[0].__name__, args[-1]))  # _as_json's job and its queued_at
        return await original(self, time_limit, fn, *args)

    monkeypatch.setattr(EnginePool, "run", recorded)
    app = create_app(Settings(workers=1, time_limit_s=30))
    pool = app.state.engine_pool

    async def scenario() -> list[httpx.Response]:
        async with client_for(app) as c:
            alone = await c.post("/v1/analysis/critical-points", json={"linkage": four_bar})
            slow = asyncio.create_task(
                c.post("/v1/analysis/configuration-space", json=busy_body(2.0)))
            deadline = time.monotonic() + 60
            while pool.admitted < 1:  # the slow one holds the only worker
                assert time.monotonic() < deadline and not slow.done()
                await asyncio.sleep(0.01)
            behind = await c.post("/v1/analysis/critical-points", json={"linkage": four_bar})
            return [alone, await slow, behind]

    pool.start()
    try:
        responses = asyncio.run(scenario())
    finally:
        pool.close()
    assert [r.status_code for r in responses] == [200, 200, 200]
    (job, alone), (_, slow), (_, behind) = handed
    assert job == "critical_points" and alone is None and slow is None
    assert isinstance(behind, float)  # handed over while the slow one held the worker
