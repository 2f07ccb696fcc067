"""Large answers from the engine workers to the client (service/workers.py, issue 15): an
answer of at least ``SPILL_MIN_BYTES`` comes back from its worker through a file the service
hands to the request, not pebble's pipe; the file is kept for the next request once its
request is answered, removed at once when the worker was stopped at the time limit, and every
file is gone when the pool closes.

References: the same job serialised in-process by :func:`service.serialise.dumps` (the bytes
every answer had before), and the directory the files live in, which must end up empty."""

from __future__ import annotations

import asyncio
import json
from pathlib import Path
from typing import Any

import pytest

from engine.catalogue.presets import build_preset
from service import jobs, serialise, workers
from service import spill as spill_files
from service.config import Settings, get_settings
from service.main import create_app
from service.mappers import linkage_out
from service.schemas.common import AnalysisRequest
from service.schemas.space import SpaceRequest
from tests.conftest import start_ready
from tests.service.test_hardening import (
    OVERRUN_PATH,
    assert_problem,
    client_for,
    overrun_body,
)

SPACE = "/v1/analysis/configuration-space"
# the closed form, dense: ~35,000 points, some 3 MB of compact JSON and 5 MB of default JSON
DENSE = {"step_max": 2.5e-4, "max_points": 200_000}


def _linkage(name: str, **params: float) -> dict[str, Any]:
    return linkage_out(build_preset(name, params)).model_dump(mode="json", by_alias=True)


@pytest.fixture(scope="module")
def crank_rocker() -> dict[str, Any]:
    return _linkage("four-bar", L1=0.5, L2=1.2, L3=1.0)


@pytest.mark.parametrize("points", [None, "compact"])
def test_a_large_answer_is_written_to_the_spill_file(tmp_path, crank_rocker, points):
    settings = get_settings()
    body = SpaceRequest.model_validate(
        {"linkage": crank_rocker, "options": {**DENSE, "points": points}})
    expected = serialise.dumps(jobs.configuration_space(body, settings))
    assert len(expected) >= spill_files.SPILL_MIN_BYTES, "too small to test the spill"
    spill = tmp_path / "answer.json"
    spill.touch()
    size = workers._as_json(jobs.configuration_space, body, settings, str(spill))
    assert size == len(expected)
    assert spill.read_bytes() == expected
    assert workers._read_spill(str(spill), len(expected)) == expected


def test_without_its_file_a_large_answer_comes_back_as_bytes(tmp_path, crank_rocker):
    """The service removed the file (it stopped waiting): the worker makes no new one."""
    settings = get_settings()
    body = SpaceRequest.model_validate(
        {"linkage": crank_rocker, "options": {**DENSE, "points": "compact"}})
    gone = tmp_path / "removed.json"
    answer = workers._as_json(jobs.configuration_space, body, settings, str(gone))
    assert answer == serialise.dumps(jobs.configuration_space(body, settings))
    assert not gone.exists()


def test_a_small_answer_comes_back_as_bytes(tmp_path, crank_rocker):
    settings = get_settings()
    body = AnalysisRequest.model_validate({"linkage": crank_rocker})
    spill = tmp_path / "answer.json"
    spill.touch()
    answer = workers._as_json(jobs.rigidity, body, settings, str(spill))
    assert answer == serialise.dumps(jobs.rigidity(body, settings))
    assert spill.read_bytes() == b""


def test_a_cut_answer_is_a_worker_failure(tmp_path):
    spill = tmp_path / "answer.json"
    spill.write_bytes(b"{}")
    with pytest.raises(workers.WorkerFailed):
        workers._read_spill(str(spill), 3)


@pytest.mark.slow
def test_answers_through_a_worker_reuse_one_file(tmp_path, monkeypatch, crank_rocker):
    """Default and compact answers of a real worker are the in-process ones; one after the
    other they cross in one file, which is gone when the pool closes."""
    monkeypatch.setattr(spill_files, "spill_dir", lambda: str(tmp_path))
    app = start_ready(create_app(Settings(workers=1, time_limit_s=120)))
    settings = get_settings()
    files = []

    async def scenario() -> list[Any]:
        answers = []
        async with client_for(app) as c:
            for points in (None, "compact"):
                answers.append(await c.post(SPACE, json={
                    "linkage": crank_rocker, "options": {**DENSE, "points": points}}))
                files.append(sorted(Path(tmp_path).iterdir()))
        return answers

    try:
        answers = asyncio.run(scenario())
    finally:
        app.state.engine_pool.close()
    for r, points in zip(answers, (None, "compact"), strict=True):
        assert r.status_code == 200, r.text
        assert r.headers["content-type"].startswith("application/json")
        assert int(r.headers["content-length"]) == len(r.content) >= spill_files.SPILL_MIN_BYTES
        body = SpaceRequest.model_validate(
            {"linkage": crank_rocker, "options": {**DENSE, "points": points}})
        expected = json.loads(serialise.dumps(jobs.configuration_space(body, settings)))
        got = r.json()
        assert got["components"] == expected["components"]
        assert got.keys() == expected.keys()
    assert len(files[0]) == 1 and files[1] == files[0]  # kept, and taken again
    assert list(Path(tmp_path).iterdir()) == []


def test_spill_files_are_kept_within_bounds(tmp_path, monkeypatch):
    monkeypatch.setattr(spill_files, "spill_dir", lambda: str(tmp_path))
    files = spill_files.SpillFiles(keep=1)
    a, b = files.take(), files.take()
    assert a != b and Path(a).parent == Path(b).parent == tmp_path
    assert oct(Path(a).stat().st_mode & 0o777) == oct(0o600)
    files.give_back(a, reuse=True)
    files.give_back(b, reuse=True)  # no room: removed
    assert sorted(tmp_path.iterdir()) == [Path(a)]
    assert files.take() == a
    with open(a, "wb") as f:  # too large to keep
        f.truncate(spill_files.SPILL_KEEP_MAX_BYTES + 1)
    files.give_back(a, reuse=True)
    c = files.take()
    files.give_back(c, reuse=False)  # its worker may still write: removed
    assert list(tmp_path.iterdir()) == []
    d = files.take()
    files.give_back(d, reuse=True)
    files.close()
    assert list(tmp_path.iterdir()) == []


@pytest.mark.slow
def test_a_request_stopped_at_the_time_limit_leaves_no_file(tmp_path, monkeypatch):
    monkeypatch.setattr(spill_files, "spill_dir", lambda: str(tmp_path))
    app = start_ready(create_app(Settings(workers=1, time_limit_s=1.5)))

    async def scenario() -> Any:
        async with client_for(app) as c:
            return await c.post(OVERRUN_PATH, json=overrun_body())

    try:
        slow = asyncio.run(scenario())
        assert_problem(slow, 504, "time-limit")
        assert list(Path(tmp_path).iterdir()) == []  # removed at once, not kept
    finally:
        app.state.engine_pool.close()


def _faults_of_a_second_array() -> int:
    """Minor page faults of filling a 20 MB array after one of the same size was freed."""
    import resource

    import numpy as np

    first = np.ones(2_500_000)
    del first
    before = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
    second = np.ones(2_500_000)
    faults = resource.getrusage(resource.RUSAGE_SELF).ru_minflt - before
    del second
    return faults


@pytest.mark.slow
def test_a_worker_reuses_freed_memory():
    """tune_malloc in every worker: an array of 20 MB freed and allocated again is filled
    in memory the worker kept (no page faults; with glibc's defaults the second array is
    mapped or the heap grown afresh: hundreds to thousands of faults)."""
    if not workers.tune_malloc():
        pytest.skip("no glibc mallopt here")
    pool = workers.EnginePool(1, 4)
    try:
        faults = asyncio.run(pool.run(60, _faults_of_a_second_array))
    finally:
        pool.close()
    assert faults < 100, faults
