"""Analyses without a search (rigidity, second order) that would not finish within the request's
time limit stop before it, with a 422 ``too-costly`` naming the linkage, instead of the 504 at the
limit: straight Kane-Lubensky chains (every pin, rotor and coupler on one line) have thousands of
zero modes and self-stresses. A straight chain the methods can do answers 200 with the counts of
a straight chain."""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from service.config import Settings
from service.main import create_app
from tests.conftest import ApiClient
from tests.load import Timer

#: The app's request time limit: the analyses get half of it (service.jobs.ANALYSIS_SHARE).
LIMIT_S = 6.0
#: Seconds past the limit an answer may come, on an idle machine: scaled by the machine's
#: slowdown measured around the request (tests.load.stretch, as in test_bounded.py).
MARGIN_S = 2.0


@pytest.fixture(scope="module")
def api() -> Iterator[ApiClient]:
    app = create_app(Settings.from_env().replace(time_limit_s=LIMIT_S, workers=1))
    # a ready service, as an orchestrator routes to it (/health/ready): ApiClient starts the
    # pool (tests.conftest.start_ready), else the worker's start-up inside the first request
    # would count as time waited for a worker (503 busy instead of 422 too-costly)
    client = ApiClient(app)
    yield client
    client.close()
    app.state.engine_pool.close()


def straight(api: ApiClient, n: int) -> dict:
    return api.get(f"/v1/presets/kl-chain?n={n}&theta=0&a=1&l=1&r=1.5").json()


@pytest.mark.slow
@pytest.mark.parametrize(("path", "n"), [("/v1/analysis/rigidity", 20000),
                                         ("/v1/analysis/second-order", 5000)])
def test_an_analysis_too_costly_for_the_time_limit_is_a_422_before_it(api, path, n):
    body = {"linkage": straight(api, n)}
    with Timer(api.app) as took:
        r = api.post(path, json=body)
    assert r.status_code == 422, r.text[:300]
    assert r.headers["content-type"].startswith("application/problem+json")
    problem = r.json()
    assert problem["type"] == "/problems/too-costly"
    assert problem["errors"][0]["loc"] == ["body", "linkage"]
    # stopped at half the limit, plus the unit of work under way (estimated before it starts)
    # and the answer, with the margin of tests/service/test_bounded.py for a loaded machine
    assert took.within(LIMIT_S, MARGIN_S), took
    # the connection serves the next request
    assert api.get("/health/live").status_code == 200


def test_a_straight_chain_within_reach_answers(api):
    n = 150  # 2n free coordinates (the tips), 2n - 1 bars
    r = api.post("/v1/analysis/rigidity", json={"linkage": straight(api, n)})
    assert r.status_code == 200, r.text[:300]
    answer = r.json()
    # on a line only the tips' x coordinates are constrained: rank n, so n zero modes (the y
    # coordinates) and 2n - 1 - n = n - 1 self-stresses
    assert len(answer["self_stresses"]) == n - 1
    assert len(answer["zero_modes"]) == n
