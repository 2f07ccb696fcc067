"""Problems raised as exceptions carrying their fields, and the bounded retries on 503."""

from __future__ import annotations

import asyncio
import email.utils
import time
from collections.abc import Iterator
from typing import Any

import httpx
import pytest
from linkage_client import AsyncClient, Client, ProblemError, RetryPolicy
from linkage_client._http import retry_after

from service.config import Settings
from service.main import create_app
from tests.conftest import start_ready
from tests.service.test_hardening import OVERRUN_PATH, WORKER_RIGIDITY, overrun_body


def test_invalid_linkage_problem_names_the_field(sync: Client) -> None:
    body = {"vertices": [{"id": "P", "position": [0, 0], "fixed": True},
                         {"id": "A", "position": [1, 0]}],
            "bars": [{"id": "r", "ends": ["P", "X"]}]}
    with pytest.raises(ProblemError) as err:
        sync.analyse_rigidity(body)
    p = err.value
    assert (p.status, p.kind, p.type) == (422, "invalid-linkage", "/problems/invalid-linkage")
    assert p.title == "Invalid linkage" and "unknown vertex 'X'" in p.detail
    assert p.errors[0].loc == ("body", "linkage", "bars", 0, "ends", 1)
    assert p.body["status"] == 422 and p.retry_after is None
    assert str(p).startswith("422 Invalid linkage")


def test_schema_problem_and_preset_problems(sync: Client) -> None:
    with pytest.raises(ProblemError) as err:
        sync.analyse_second_order({"vertices": [{"id": "A", "position": [0, "x"]}]})
    assert err.value.kind == "validation-error"
    assert err.value.errors[0].loc[:4] == ("body", "linkage", "vertices", 0)
    with pytest.raises(ProblemError) as err:
        sync.get_preset("nope")
    assert (err.value.status, err.value.kind) == (404, "unknown-preset")
    with pytest.raises(ProblemError) as err:
        sync.get_preset_four_bar(L2=50)  # does not close
    assert err.value.status == 422 and err.value.kind == "invalid-parameter"
    assert sync.get_health().status == "ok"  # the service keeps answering


def test_retry_after_forms() -> None:
    def response(value: str | None) -> httpx.Response:
        return httpx.Response(503, headers={} if value is None else {"retry-after": value})

    assert retry_after(response("3")) == 3.0
    assert retry_after(response(None)) is None and retry_after(response("soon")) is None
    later = email.utils.formatdate(time.time() + 30, usegmt=True)
    assert 25 < (retry_after(response(later)) or 0) <= 30
    policy = RetryPolicy(retries=2, max_wait_s=5, total_wait_s=6)
    assert policy.wait_for(response("2"), 0, 0.0) == 2.0
    assert policy.wait_for(response("2"), 2, 0.0) is None  # out of retries
    assert policy.wait_for(response("9"), 0, 0.0) is None  # longer than one wait may be
    assert policy.wait_for(response("2"), 1, 5.0) is None  # longer than all waits may be
    assert policy.wait_for(response(None), 0, 0.0) is None
    assert policy.wait_for(httpx.Response(500, headers={"retry-after": "1"}), 0, 0.0) is None


# A real busy service: one engine worker, a queue of one, and a request that overruns the
# time limit (tests/service/test_hardening.py's configuration-space figure as a 24.7-Mpx PNG
# after a search that runs to its whole budget: 504 at the limit of 1.5 s).
TIME_LIMIT_S = 1.5


@pytest.fixture(scope="module")
def busy_app() -> Iterator[Any]:
    app = start_ready(create_app(Settings(workers=1, time_limit_s=TIME_LIMIT_S, max_queue=1)))
    yield app
    app.state.engine_pool.close()


async def busy_then(busy_app: Any, retry: RetryPolicy) -> tuple[Any, float, int]:
    """Keeps the one worker busy, then asks a worker's rigidity (WORKER_RIGIDITY: no search,
    so no deadline's work stretched past the 1.5 s limit on a loaded machine, where a
    four-bar's critical points were a 504): (answer or problem, seconds, the slow request's
    status)."""
    transport = httpx.ASGITransport(app=busy_app, raise_app_exceptions=False)
    async with AsyncClient(base_url="http://testserver", transport=transport,
                           retry=retry) as client, httpx.AsyncClient(
            base_url="http://testserver", transport=transport, timeout=60) as raw:
        slow = asyncio.create_task(raw.post(OVERRUN_PATH, json=overrun_body()))
        deadline = time.monotonic() + 60
        while busy_app.state.engine_pool.admitted < 1:  # the slow one holds the only place
            assert time.monotonic() < deadline and not slow.done()
            await asyncio.sleep(0.05)
        start = time.monotonic()
        try:
            answer: Any = await client.analyse_rigidity(WORKER_RIGIDITY["linkage"])
        except ProblemError as err:
            answer = err
        waited = time.monotonic() - start
        return answer, waited, (await slow).status_code


@pytest.mark.slow
def test_busy_without_retries_raises_the_503_with_retry_after(busy_app: Any) -> None:
    answer, _, slow = asyncio.run(busy_then(busy_app, RetryPolicy(retries=0)))
    assert isinstance(answer, ProblemError)
    assert (answer.status, answer.kind) == (503, "busy")
    assert answer.retry_after is not None and answer.retry_after >= 1
    assert slow == 504


@pytest.mark.slow
def test_busy_is_retried_after_retry_after_until_answered(busy_app: Any) -> None:
    answer, waited, slow = asyncio.run(busy_then(busy_app, RetryPolicy(retries=20,
                                                                      max_wait_s=5,
                                                                      total_wait_s=30)))
    assert slow == 504
    # answered once the worker was free: every vertical motion of a free vertex on the line
    assert len(answer.zero_modes) == 32 - 2
    assert waited >= 1.0  # at least one Retry-After was waited for
