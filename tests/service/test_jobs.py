"""Jobs and sweeps on real Dask clusters: an embedded LocalCluster (shared by this module) and a
separately started ``dask scheduler`` with two ``dask worker`` processes on loopback."""

from __future__ import annotations

import csv
import io
import itertools
import json
import os
import re
import signal
import socket
import subprocess
import sys
import time
from collections import Counter
from collections.abc import Iterator
from datetime import datetime, timedelta
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from distributed import Client
from fastapi.testclient import TestClient

from service.config import Settings
from service.main import create_app
from service.tasks import Job, JobManager

pytestmark = pytest.mark.dask

#: Generous: the machine is shared; a finished job answers at once.
WAIT_S = 120.0
#: The gated chain small enough for tests (as in tests/engine/design/test_gate.py).
QUICK = {"max_components": 2, "angles": 12, "random_starts": 2}
GATED = {"name": "gated-kl-chain", "parameters": {"n": 3, "gate": 1}}


def grashof(sides: list[float]) -> int:
    """Components of a generic planar four-bar (classical rule; 0: does not assemble)."""
    s = sorted(sides)
    if s[3] >= s[0] + s[1] + s[2]:
        return 0
    return 2 if s[0] + s[3] < s[1] + s[2] else 1


def generic(sides: list[float]) -> bool:
    """No configuration with the four joints on a line (no signed sum of the sides vanishes)."""
    return all(abs(np.dot(signs, sides)) > 1e-6
               for signs in itertools.product((1, -1), repeat=4) if signs[0] == 1)


def settings(**changes: Any) -> Settings:
    # small clusters for a 2-core machine: 2 workers, 1 thread each; 1 engine process
    return Settings().replace(workers=1, dask_workers=2, **changes)


@pytest.fixture(scope="module")
def api() -> Iterator[TestClient]:
    with TestClient(create_app(settings())) as c:
        yield c


def dask_client(api: TestClient) -> Client:
    return api.app.state.jobs.client()  # type: ignore[attr-defined]


def wait(api: TestClient, location: str, until: tuple[str, ...] = ("done", "failed",
         "cancelled"), seen: list[float] | None = None) -> dict[str, Any]:
    deadline = time.monotonic() + WAIT_S
    while time.monotonic() < deadline:
        job = api.get(location).json()
        if seen is not None:
            seen.append(job["progress"]["fraction"])
        if job["status"] in until:
            return job
        time.sleep(0.05)
    raise AssertionError(f"job {location} not {until} after {WAIT_S} s: {job}")


RFC3339 = re.compile(r"^\d{4}-\d\d-\d\dT\d\d:\d\d:\d\d(\.\d+)?(Z|[+-]\d\d:\d\d)$")


def when(text: str) -> datetime:
    """A job's time: RFC 3339 (the grammar written out above), in UTC."""
    assert RFC3339.match(text), text
    moment = datetime.fromisoformat(text.replace("Z", "+00:00"))
    assert moment.utcoffset() == timedelta(0)
    return moment


def four_bar(api: TestClient) -> dict[str, Any]:
    return api.get("/v1/presets/four-bar").json()


def gated_sweep(seed: int, count: int, critical: bool = False) -> dict[str, Any]:
    """Monte Carlo samples of the gated chain's D; its rows come from the chain rules (no
    trace), unless ``critical`` asks for the critical points, which the tracer searches
    (about half a second a point: a sweep that runs long enough to be stopped)."""
    compute = ["components", "critical", "windings"] if critical else ["components", "windings"]
    return {"preset": GATED, "samples": {"D": {"mean": 2.5, "sd": 0.25}}, "count": count,
            "seed": seed, "compute": compute, "options": QUICK}


def run_sweep(api: TestClient, body: dict[str, Any],
              seen: list[float] | None = None) -> dict[str, Any]:
    r = api.post("/v1/sweeps", json=body)
    assert r.status_code == 202, r.text
    assert r.headers["location"] == f"/v1/jobs/{r.json()['id']}"
    job = wait(api, r.headers["location"], seen=seen)
    assert job["status"] == "done", job
    return job


@pytest.fixture(scope="module")
def grid_job(api: TestClient) -> tuple[dict[str, Any], list[float]]:
    """A four-bar grid over two bars, with every progress value seen while polling."""
    body = {"linkage": four_bar(api),
            "grid": {"L1": {"min": 0.4, "max": 1.7, "steps": 4},
                     "L2": {"min": 0.35, "max": 3.35, "steps": 5}},
            "compute": ["components", "critical"]}
    seen: list[float] = []
    return run_sweep(api, body, seen), seen


def test_grid_rows_agree_with_grashof(grid_job):
    job, _ = grid_job
    rows = job["result"]["rows"]
    assert len(rows) == 20
    assert {(r["lengths"]["L1"], r["lengths"]["L2"]) for r in rows} == {
        (float(a), float(b)) for a in np.linspace(0.4, 1.7, 4) for b in np.linspace(0.35, 3.35, 5)}
    for row in rows:
        sides = [1.0, row["lengths"]["L1"], row["lengths"]["L2"], 1.0]  # a = L3 = 1
        assert generic(sides)
        assert row["components"] == grashof(sides), row
        assert row["critical_points"] == 0 and row["error"] is None
    assert {r["components"] for r in rows} == {0, 1, 2}  # the grid crosses every regime


def test_grid_summary_agrees_with_rows(grid_job):
    job, _ = grid_job
    rows, summary = job["result"]["rows"], job["result"]["summary"]
    assert summary["points"] == len(rows)
    assert summary["topologies"] == {
        f"components={k}": v for k, v in Counter(r["components"] for r in rows).items()}
    assert summary["critical"] == 0 and summary["errors"] == 0 and summary["incomplete"] == 0
    assert summary["fraction_gated"] is None and summary["smallest_margin"] is None


def test_grid_csv_parses(api, grid_job):
    job, _ = grid_job
    r = api.get(f"/v1/jobs/{job['id']}/result", headers={"accept": "text/csv"})
    assert r.status_code == 200 and r.headers["content-type"].startswith("text/csv")
    table = list(csv.DictReader(io.StringIO(r.text)))
    rows = job["result"]["rows"]
    assert len(table) == len(rows)
    for line, row in zip(table, rows, strict=True):
        assert float(line["L1"]) == row["lengths"]["L1"]
        assert float(line["L2"]) == row["lengths"]["L2"]
        assert int(line["components"]) == row["components"]
    assert api.get(f"/v1/jobs/{job['id']}/result").json() == job["result"]


def tau_signs(a: float, l1: float, l2: float, l3: float) -> list[int]:
    """The paper's Eq. 16 for ground ``a``, input ``l1``, coupler ``l2``, output ``l3``."""
    taus = (a - l1 + l2 - l3, a - l1 - l2 + l3, l2 + l3 - a - l1)
    assert min(abs(t) for t in taus) > 1e-6  # off the critical lines
    return [int(np.sign(t)) for t in taus]


def test_grid_rows_carry_their_cells_tau_signs_in_json_and_csv(api, grid_job):
    """The four-bar's one cell on every row (its bars say which rotor is the input), with the
    signs computed here from the point's lengths; the CSV's tau_signs column says the same."""
    job, _ = grid_job
    rows = job["result"]["rows"]
    for row in rows:
        length = {"L1": row["lengths"]["L1"], "L2": row["lengths"]["L2"], "L3": 1.0}
        (cell,) = row["tau_signs"]
        inp, coupler, out = cell["bars"]
        assert coupler == "L2" and {inp, out} == {"L1", "L3"}
        assert cell["sides"] == pytest.approx([1.0, length[inp], length["L2"], length[out]])
        assert cell["signs"] == tau_signs(1.0, length[inp], length["L2"], length[out]), row
    r = api.get(f"/v1/jobs/{job['id']}/result", headers={"accept": "text/csv"})
    table = list(csv.DictReader(io.StringIO(r.text)))
    for line, row in zip(table, rows, strict=True):
        (cell,) = row["tau_signs"]
        assert line["tau_signs"] == f"{cell['cell']}:" + ",".join(map(str, cell["signs"]))


def test_gated_grid_rows_carry_the_gate_four_bars_tau_signs(api):
    """The gated chain's (L2, D) grid through HTTP: each row's one cell is the gate four-bar
    (ground D, input the gate rotor r = 1.5, coupler L2, output L1 = 2), its signs as computed
    here; gated exactly where they say the gate rotor is no crank (not (+,+,+) nor (-,-,+))."""
    body = {"preset": GATED, "compute": ["components", "windings"],
            "grid": {"L2": {"min": 0.55, "max": 4.95, "steps": 5},
                     "D": {"min": 0.55, "max": 4.95, "steps": 5}}}
    rows = run_sweep(api, body)["result"]["rows"]
    for row in rows:
        l2, d = row["lengths"]["L2"], row["lengths"]["D"]
        (cell,) = row["tau_signs"]
        assert cell["cell"] == "gate" and cell["bars"] == ["r1", "L2", "L1"]
        assert cell["signs"] == tau_signs(d, 1.5, l2, 2.0), row
        if row["components"]:
            assert row["gated"] is (cell["signs"] not in ([1, 1, 1], [-1, -1, 1])), row


def test_progress_is_monotone_and_reaches_one(grid_job):
    job, seen = grid_job
    assert seen == sorted(seen) and seen[-1] == 1.0
    assert all(0.0 <= f <= 1.0 for f in seen)
    assert job["progress"] == {"fraction": 1.0, "message": "done"}
    assert when(job["started"]) <= when(job["finished"]) < when(job["expires"])


@pytest.fixture(scope="module")
def embedded_gated(api: TestClient) -> dict[str, Any]:
    return run_sweep(api, gated_sweep(seed=7, count=6))["result"]


def test_monte_carlo_gated_chain_reproducible_with_its_seed(api, embedded_gated):
    again = run_sweep(api, gated_sweep(seed=7, count=6))["result"]
    assert again == embedded_gated
    drawn = np.random.default_rng(7).normal(2.5, 0.25, size=6)
    assert [r["lengths"]["D"] for r in again["rows"]] == pytest.approx(drawn.tolist(), abs=0)
    # the paper's gate: gated (no rotor turns) for D > 5a/2, every chain rotor turns below
    for row in again["rows"]:
        d = row["lengths"]["D"]
        if abs(d - 2.5) > 0.05:
            assert row["gated"] is (d > 2.5), row
    summary = again["summary"]
    assert summary["gated"] == sum(r["gated"] for r in again["rows"])
    assert summary["fraction_gated"] == pytest.approx(summary["gated"] / 6)


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@pytest.fixture(scope="module")
def external_scheduler() -> Iterator[str]:
    """``dask scheduler`` and two ``dask worker`` processes on loopback, stopped at the end."""
    port = free_port()
    address = f"tcp://127.0.0.1:{port}"
    dask = [sys.executable, "-m", "dask"]
    quiet = {"stdout": subprocess.DEVNULL, "stderr": subprocess.DEVNULL}
    procs = [subprocess.Popen([*dask, "scheduler", "--host", "127.0.0.1", "--port", str(port),
                               "--no-dashboard"], **quiet)]
    try:
        for _ in range(2):
            procs.append(subprocess.Popen([*dask, "worker", address, "--host", "127.0.0.1",
                                           "--nthreads", "1", "--no-dashboard"], **quiet))
        with Client(address, timeout=60, set_as_default=False) as client:
            client.wait_for_workers(2, timeout=90)
        yield address
    finally:
        for p in reversed(procs):
            p.terminate()
        for p in reversed(procs):
            try:
                p.wait(timeout=20)
            except subprocess.TimeoutExpired:
                p.kill()


@pytest.mark.process
def test_external_cluster_gives_the_same_result(external_scheduler, embedded_gated):
    with TestClient(create_app(settings(dask_scheduler=external_scheduler))) as ext:
        result = run_sweep(ext, gated_sweep(seed=7, count=6))["result"]
        workers = dask_client(ext).scheduler_info()["workers"]
    assert len(workers) == 2
    assert result == embedded_gated


@pytest.mark.process
def test_command_line_run_with_a_scheduler_answers_as_in_process(external_scheduler, tmp_path):
    """``run --scheduler`` goes through Dask (the service's job path); without it, in-process:
    the same answer but for the search's time budget (the job's own limit)."""
    script = Path(sys.executable).with_name("linkage-topology")
    args = [str(script), "run", "analysis/critical-points", "--preset", "four-bar", "--param",
            "L2=1", "--no-progress"]
    answers = []
    for extra in (["--scheduler", external_scheduler], []):
        proc = subprocess.run([*args, *extra], capture_output=True, text=True, timeout=WAIT_S,
                              cwd=tmp_path)
        assert proc.returncode == 0, proc.stderr
        answer = json.loads(proc.stdout)
        answer["search"].pop("time_budget_s")
        answers.append(answer)
    assert answers[0] == answers[1]
    assert sorted(p["kind"] for p in answers[0]["critical_points"]) == ["branch"] * 3


def test_unreachable_scheduler_answers_503_and_the_service_keeps_answering(monkeypatch):
    monkeypatch.setattr("service.cluster.CONNECT_TIMEOUT_S", 1.0)
    nobody = f"tcp://127.0.0.1:{free_port()}"
    with TestClient(create_app(settings(dask_scheduler=nobody))) as c:
        body = {"preset": {"name": "four-bar"}, "grid": {"L2": {"min": 1, "max": 2, "steps": 2}}}
        r = c.post("/v1/sweeps", json=body)
        assert r.status_code == 503 and r.json()["type"] == "/problems/cluster-unavailable"
        assert nobody in r.json()["detail"] and r.headers["retry-after"] == "5"
        assert c.get("/health").status_code == 200


def executing(api: TestClient) -> int:
    """Tasks running on the embedded cluster's workers right now (asked of the workers, not
    the scheduler: a cancelled task leaves the scheduler at once but runs on until it stops)."""
    counts = dask_client(api).run(lambda dask_worker: dask_worker.state.executing_count)
    return sum(counts.values())


def start_slow_sweep(api: TestClient) -> str:
    """A sweep of many gated-chain points (~0.5 s each), returned once it is running."""
    r = api.post("/v1/sweeps", json=gated_sweep(seed=1, count=60, critical=True))
    assert r.status_code == 202
    location = r.headers["location"]
    job = wait(api, location, until=("running",))
    assert job["progress"]["fraction"] < 1.0
    return location


def test_cancelled_job_stops_its_tasks(api):
    location = start_slow_sweep(api)
    assert executing(api) > 0
    stop_by = time.monotonic() + WAIT_S
    while api.get(location).json()["progress"]["fraction"] == 0.0:  # a few points done
        assert time.monotonic() < stop_by
        time.sleep(0.05)
    r = api.delete(location)
    assert r.status_code == 200 and r.json()["status"] == "cancelled"
    stop_by = time.monotonic() + 20
    while executing(api) and time.monotonic() < stop_by:
        time.sleep(0.1)
    assert executing(api) == 0  # 60 points would take far longer than this
    frozen = settled(api, location)
    assert frozen["status"] == "cancelled" and frozen["partial"] is True
    # the rows the stopped tasks had finished: points of the sweep, not all of them
    assert frozen["result"]["partial"] is True
    rows = frozen["result"]["rows"]
    assert 1 <= len(rows) < 60
    assert_rows_of_the_gated_sample(rows, seed=1, count=60)
    assert api.get(f"{location}/result").json() == frozen["result"]


def settled(api: TestClient, location: str) -> dict[str, Any]:
    """The job once it has stopped changing (stopped tasks' rows arrive after the cancel)."""
    last = api.get(location).json()
    for _ in range(100):
        time.sleep(0.3)
        now = api.get(location).json()
        if now == last:
            return now
        last = now
    raise AssertionError(f"job {location} keeps changing: {last}")


def assert_rows_of_the_gated_sample(rows: list[dict[str, Any]], seed: int, count: int) -> None:
    """Each row is a distinct point of :func:`gated_sweep`'s sample (drawn here as the README
    says: ``np.random.default_rng(seed)``, mean 2.5, sd 0.25) with a count of components."""
    sample = 2.5 + 0.25 * np.random.default_rng(seed).standard_normal(count)
    index = [int(np.argmin(abs(sample - row["lengths"]["D"]))) for row in rows]
    assert all(abs(sample[i] - row["lengths"]["D"]) < 1e-12
               for i, row in zip(index, rows, strict=True))
    assert len(set(index)) == len(rows)
    assert all(row["error"] is not None or row["components"] >= 0 for row in rows)


def long_exploration(api: TestClient) -> dict[str, Any]:
    """The general tracer on a 40-rotor chain: its 2^39 components take far beyond any test."""
    chain = api.get("/v1/presets/kl-chain?n=40").json()
    return {"operation": "analysis/configuration-space",
            "body": {"linkage": chain, "options": {"max_components": 1000}}}


def test_analysis_job_progress_comes_from_the_engine_and_cancel_stops_it(api):
    r = api.post("/v1/jobs", json=long_exploration(api))
    assert r.status_code == 202
    location = r.headers["location"]
    seen: list[float] = []
    messages: set[str] = set()
    stop_by = time.monotonic() + WAIT_S
    while time.monotonic() < stop_by:  # until the engine has reported from inside its search
        job = api.get(location).json()
        seen.append(job["progress"]["fraction"])
        messages.add(job["progress"]["message"])
        if "tracing the components" in messages and 0 < seen[-1] < 1:
            break
        time.sleep(0.05)
    assert "tracing the components" in messages, messages
    assert seen == sorted(seen) and 0 < seen[-1] < 1
    assert executing(api) > 0
    r = api.delete(location)
    assert r.status_code == 200 and r.json()["status"] == "cancelled"
    stop_by = time.monotonic() + 20
    while executing(api) and time.monotonic() < stop_by:
        time.sleep(0.1)
    assert executing(api) == 0  # the engine saw the cancel flag through its deadline


def test_error_paths_answer_problems(api, grid_job):
    r = api.post("/v1/jobs", json={"operation": "analysis/nope", "body": {}})
    assert r.status_code == 422 and r.json()["errors"][0]["loc"] == ["body", "operation"]
    r = api.post("/v1/jobs", json={"operation": "analysis/rigidity",
                                   "body": {"linkage": {"vertices": []}}})
    assert r.status_code == 422
    assert r.json()["errors"][0]["loc"] == ["body", "body", "linkage", "vertices"]
    r = api.post("/v1/sweeps", json={"linkage": four_bar(api),
                                     "grid": {"L9": {"min": 1, "max": 2, "steps": 2}}})
    assert r.status_code == 422 and r.json()["errors"][0]["loc"] == ["body", "grid", "L9"]
    r = api.post("/v1/sweeps", json={"preset": {"name": "four-bar"},
                                     "grid": {"L2": {"min": 1, "max": 2, "steps": 2}},
                                     "samples": {"L2": {"mean": 1, "sd": 0.1}}, "count": 3})
    assert r.status_code == 422 and r.headers["content-type"] == "application/problem+json"
    r = api.get("/v1/jobs/nope")
    assert r.status_code == 404 and r.json()["type"] == "/problems/unknown-job"
    assert api.delete("/v1/jobs/nope").status_code == 404


def test_analysis_job_answers_as_the_endpoint(api):
    body = {"linkage": four_bar(api)}
    r = api.post("/v1/jobs", json={"operation": "analysis/critical-points", "body": body})
    assert r.status_code == 202
    location = r.headers["location"]
    r409 = api.get(f"{location}/result")
    job = wait(api, location)
    assert job["status"] == "done" and job["progress"]["fraction"] == 1.0
    if r409.status_code != 200:  # asked before it was done
        assert r409.status_code == 409
    direct = api.post("/v1/analysis/critical-points", json=body).json()
    # the one difference: the search's time, the job's own limit instead of the request's
    assert job["result"]["search"].pop("time_budget_s") > direct["search"].pop("time_budget_s")
    assert job["result"] == direct
    r = api.get(f"{location}/result", headers={"accept": "text/csv"})
    assert r.status_code == 406


def test_time_limit_fails_the_job_and_finished_jobs_expire(api):
    manager = api.app.state.jobs
    kept = manager.settings
    manager.settings = kept.replace(job_time_limit_s=1.0, job_ttl_s=1.0)
    try:
        r = api.post("/v1/jobs", json={"operation": "sweeps", "body": gated_sweep(
            seed=2, count=2000, critical=True)})
        assert r.status_code == 202
        job = wait(api, r.headers["location"])
        assert job["status"] == "failed" and job["error"]["title"] == "Time limit exceeded"
        assert 0.0 < job["progress"]["fraction"] < 1.0
        job = settled(api, r.headers["location"])
        # the points finished within the limit are kept, marked partial
        assert job["partial"] is True and job["result"]["partial"] is True
        rows = job["result"]["rows"]
        assert 1 <= len(rows) < 2000 and job["result"]["summary"]["points"] == len(rows)
        assert_rows_of_the_gated_sample(rows, seed=2, count=2000)
        assert (when(job["expires"]) - when(job["finished"])).total_seconds() \
            == pytest.approx(1.0)
        time.sleep(1.2)
        r = api.get(r.headers["location"])
        assert r.status_code == 404 and "LINKAGE_JOB_TTL_S" in r.json()["detail"]
    finally:
        manager.settings = kept


def test_finished_jobs_kept_are_bounded():
    """At most 10 x LINKAGE_MAX_JOBS finished jobs are kept, the newest (no cluster needed)."""
    manager = JobManager(settings(max_jobs=2))
    for k in range(25):
        job = Job(f"j{k}", "sweeps", end_wall=time.time() + 60, sizes=[1], done=[1.0])
        job.status, job.finished = "done", time.time() + k  # finished in this order
        manager._jobs[job.id] = job
    manager._purge()
    assert sorted(manager._jobs, key=lambda i: int(i[1:])) == [f"j{k}" for k in range(5, 25)]


def test_operations_are_listed(api):
    ops = {o["operation"]: o["request"] for o in api.get("/v1/jobs/operations").json()}
    assert ops["analysis/configuration-space"] == "SpaceRequest"
    assert ops["sweeps"] == "SweepRequest"


def test_a_task_whose_worker_dies_runs_again_and_the_job_completes(api):
    """After the other tests of the shared cluster: it kills one of its workers while it runs
    a chunk of a sweep; the chunk runs again on the other worker (once), and every row is
    there (the worker's nanny starts a new one, which the end of this test waits for)."""
    location = start_slow_sweep(api)
    client = dask_client(api)
    job_id = location.rsplit("/", 1)[1]
    busy = [w for w, keys in client.processing().items()
            if any(job_id in str(k) for k in keys)]
    pids = client.run(os.getpid, workers=busy[:1])
    os.kill(next(iter(pids.values())), signal.SIGKILL)
    job = wait(api, location)
    assert job["status"] == "done", job
    assert job["partial"] is False and len(job["result"]["rows"]) == 60
    assert_rows_of_the_gated_sample(job["result"]["rows"], seed=1, count=60)
    assert api.get("/health").status_code == 200
    client.wait_for_workers(2, timeout=60)
    small = {"preset": {"name": "four-bar"}, "grid": {"L2": {"min": 0.5, "max": 1.5, "steps": 2}}}
    assert [r["components"] for r in run_sweep(api, small)["result"]["rows"]] == [2, 1]


@pytest.mark.process
def test_command_line_preset_sweep_to_csv(tmp_path: Path):
    out = tmp_path / "sweep.csv"
    script = Path(sys.executable).with_name("linkage-topology")
    proc = subprocess.run(
        [str(script), "sweep", "--preset", "four-bar", "--grid", "L2=0.35:3.35:5",
         "--no-progress", "--workers", "1", "-o", str(out)],
        capture_output=True, text=True, timeout=WAIT_S, cwd=tmp_path,
    )
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout == ""  # no progress bar
    table = list(csv.DictReader(io.StringIO(out.read_text())))
    assert [float(r["L2"]) for r in table] == [0.35, 1.1, 1.85, 2.6, 3.35]
    for r in table:
        assert int(r["components"]) == grashof([1.0, 1.0, float(r["L2"]), 1.0])


def test_jobs_are_listed_without_their_results(api):
    before = time.time()
    r = api.post("/v1/jobs", json={"operation": "analysis/rigidity",
                                   "body": {"linkage": four_bar(api)}})
    job = wait(api, r.headers["location"])
    listed = api.get("/v1/jobs")
    assert listed.status_code == 200
    jobs = listed.json()
    assert [j["id"] for j in jobs].count(job["id"]) == 1
    mine = next(j for j in jobs if j["id"] == job["id"])
    assert "result" not in mine and mine == {k: v for k, v in job.items() if k != "result"}
    assert when(mine["created"]).timestamp() >= before - 1.0  # the clock the job was made with
    created = [when(j["created"]) for j in jobs]
    assert created == sorted(created)  # oldest first
    done = api.get("/v1/jobs", params={"status": "done"}).json()
    assert job["id"] in {j["id"] for j in done} and {j["status"] for j in done} == {"done"}
    bad = api.get("/v1/jobs", params={"status": "finished"})
    assert bad.status_code == 422 and bad.json()["errors"][0]["loc"] == ["query", "status"]


def test_figure_runs_as_a_job_and_answers_the_endpoints_svg(api):
    body = {"linkage": four_bar(api), "show": ["zero_modes"]}
    r = api.post("/v1/jobs", json={"operation": "figures/linkage", "body": body})
    assert r.status_code == 202, r.text
    job = wait(api, r.headers["location"])
    assert job["status"] == "done", job
    direct = api.post("/v1/figures/linkage", json=body)
    result = api.get(f"{r.headers['location']}/result")
    assert result.headers["content-type"] == "image/svg+xml"
    assert result.content == direct.content and job["result"] == direct.text
    ops = {o["operation"] for o in api.get("/v1/jobs/operations").json()}
    assert {"figures/linkage", "figures/configuration-space", "figures/critical-values",
            "figures/splitting"} <= ops


def test_a_figure_job_in_another_format_answers_its_bytes(api):
    """A PNG or DXF figure job: its JSON result a data: URL (RFC 2397), /result the bytes
    the endpoint answers, with the format's media type."""
    import base64

    for fmt, media_type in (("png", "image/png"), ("dxf", "image/vnd.dxf")):
        body = {"linkage": four_bar(api), "format": fmt, "dpi": 40}
        r = api.post("/v1/jobs", json={"operation": "figures/linkage", "body": body})
        assert r.status_code == 202, r.text
        job = wait(api, r.headers["location"])
        assert job["status"] == "done", job
        head, data = job["result"].split(",", 1)
        assert head == f"data:{media_type};base64"
        result = api.get(f"{r.headers['location']}/result")
        assert result.headers["content-type"] == media_type
        assert result.content == base64.b64decode(data)
        direct = api.post("/v1/figures/linkage", json=body).content
        if fmt == "png":
            assert result.content == direct
        else:  # a DXF carries its time of writing and random GUIDs: the same entities
            import io

            import ezdxf

            def entities(data: bytes) -> list[tuple[str, str, str]]:
                msp = ezdxf.read(io.StringIO(data.decode())).modelspace()
                return sorted((e.dxftype(), e.dxf.layer, str(e.dxfattribs())) for e in msp)

            assert entities(result.content) == entities(direct)
