"""Liveness and readiness (issue 28, item 1): ``/health`` and ``/health/live`` answer as soon
as the process does; ``/health/ready`` only once the engine workers have started, and not while
the worker pool is broken (tests/service/test_workers.py kills workers in every state)."""

import asyncio

import pytest

from service.config import Settings
from service.main import create_app
from tests.service.test_hardening import assert_problem, client_for


def test_health(client):
    r = client.get("/health")
    assert r.status_code == 200
    assert r.json()["status"] == "ok"


def test_live(client):
    r = client.get("/health/live")
    assert r.status_code == 200
    assert r.json()["status"] == "ok" and r.json()["version"]


@pytest.mark.slow
def test_ready_only_once_the_workers_have_started():
    app = create_app(Settings(workers=1))
    pool = app.state.engine_pool

    async def scenario() -> tuple[object, ...]:
        async with client_for(app) as c:
            before = await c.get("/health/ready")
            live = await c.get("/health/live")
            await asyncio.to_thread(pool.start)
            return before, live, await c.get("/health/ready")

    try:
        before, live, after = asyncio.run(scenario())
    finally:
        pool.close()
    body = assert_problem(before, 503, "not-ready")
    assert "starting" in body["detail"] and before.headers["retry-after"] == "1"
    assert live.status_code == 200
    assert after.status_code == 200, after.text
    assert after.json() == {"status": "ready", "version": after.json()["version"], "workers": 1}


@pytest.mark.process
def test_the_port_answers_at_once_and_ready_follows_the_kernels(tmp_path):
    """A real uvicorn with numba's cache cold (a fresh NUMBA_CACHE_DIR: the kernels compile,
    tens of seconds): /health/live answers while they compile, /health/ready is 503 until the
    log says they are loaded and the workers started, then 200."""
    import os
    import subprocess
    import sys
    import time

    import httpx

    from tests.service.test_uvicorn_process import HOST, ROOT, free_port, stop

    port = free_port()
    env = {**os.environ, "PYTHONUNBUFFERED": "1", "NUMBA_CACHE_DIR": str(tmp_path / "numba"),
           "LINKAGE_WORKERS": "1"}
    log_path = tmp_path / "uvicorn.log"
    with log_path.open("wb") as log:
        proc = subprocess.Popen(
            [sys.executable, "-m", "uvicorn", "service.main:app", "--host", HOST, "--port",
             str(port)], cwd=ROOT, env=env, stdin=subprocess.DEVNULL, stdout=log, stderr=log)
    try:
        with httpx.Client(base_url=f"http://{HOST}:{port}", trust_env=False,
                          timeout=5.0) as c:
            t0 = time.monotonic()
            live = None
            while live is None:
                assert proc.poll() is None and time.monotonic() - t0 < 60, log_path.read_text()
                try:
                    live = c.get("/health/live")
                except httpx.TransportError:
                    time.sleep(0.05)
            t_live = time.monotonic() - t0
            assert live.status_code == 200
            early = c.get("/health/ready")
            early_log = log_path.read_text()
            while (ready := c.get("/health/ready")).status_code != 200:
                assert ready.status_code == 503 and ready.headers["retry-after"] == "1"
                assert time.monotonic() - t0 < 300, log_path.read_text()
                time.sleep(0.2)
            t_ready = time.monotonic() - t0
    finally:
        stop(proc)
    text = log_path.read_text()
    assert "start-up: starting 1 engine workers" in text
    assert "start-up: the workers' forkserver" in text  # each step, in the order taken
    assert text.index("has imported the engine") < text.index("start-up: kernels loaded in") \
        < text.index("start-up: ready in")
    assert "tracer compiled" in text and "closed form compiled" in text
    # asked while the kernels compiled (a cold compile takes tens of seconds)
    assert "kernels loaded" not in early_log, early_log
    assert early.status_code == 503 and early.json()["type"] == "/problems/not-ready"
    assert ready.json()["workers"] == 1
    print(f"live after {t_live:.1f} s, ready after {t_ready:.1f} s (cold numba cache)")


def test_the_service_process_starts_without_the_figures_and_dask():
    """The service's own start-up imports neither matplotlib and ezdxf (the figures are drawn in
    the workers, whose forkserver has them) nor Dask (loaded by the first job): 0.7-0.9 s of a
    core on the way to /health/live. A fresh interpreter, as uvicorn starts one; the
    forkserver's own launch is left out (its imports are another process's)."""
    import subprocess
    import sys

    from tests.service.test_uvicorn_process import ROOT

    code = ("import sys; import service.forkserver as f; f.start = lambda: None; "
            "import service.main; "
            "print(' '.join(m for m in ('matplotlib', 'ezdxf', 'distributed', 'dask', "
            "'service.figures', 'service.cluster') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True,
                         text=True, timeout=120, check=True)
    assert out.stdout.strip() == "", out.stdout


def test_a_figure_and_a_job_load_what_they_need_on_first_use():
    """The figure route hands the worker a reference by name (service.operations.draw), which
    the worker resolves to service.figures; a job manager imports Dask with its first job."""
    import inspect
    import pickle
    from functools import partial

    from service import figures, operations
    from service.routers import figures as figure_routes
    from service.tasks import JobManager

    source = inspect.getsource(figure_routes)
    names = ("linkage_figure", "configuration_space_figure", "critical_values_figure",
             "splitting_figure")
    for name in names:  # each route's name is a figure of service.figures
        assert f'"{name}"' in source and callable(getattr(figures, name))
    fn = pickle.loads(pickle.dumps(partial(operations.draw, "linkage_figure")))
    assert fn.func is operations.draw and fn.args == ("linkage_figure",)
    manager = JobManager(Settings(dask_workers=1))
    assert manager._current() is None  # no connection, nothing imported for it
    manager.close()  # closing a manager that ran no job connects to nothing
    assert manager._connection is None
