"""Anytime answers through HTTP (issue 11, item 2): a search that is merely large answers 200
with what it found before the time limit, ``search.complete: false`` and ``search.reason``; the
search time is ``LINKAGE_SEARCH_TIME_S`` or ``options.time_budget_s``, within the time limit.

These apps have short limits of their own (the session app of ``conftest`` is generous), so that
the deadlines, not the sizes, decide when the answers come."""

from __future__ import annotations

import time
from collections.abc import Iterator
from typing import Any

import pytest

from service.config import SEARCH_SHARE, Settings
from service.main import create_app
from tests.conftest import ApiClient

TIME_LIMIT_S = 12.0
SEARCH_S = 1.0


@pytest.fixture(scope="module")
def api() -> Iterator[ApiClient]:
    app = create_app(Settings.from_env().replace(time_limit_s=TIME_LIMIT_S,
                                                 search_time_s=SEARCH_S))
    client = ApiClient(app)
    yield client
    client.close()
    app.state.engine_pool.close()


def huge_chain(api: ApiClient) -> dict[str, Any]:
    """A 60-rotor chain (2^59 components) for the general tracer: no search finishes it."""
    return api.get("/v1/presets/kl-chain?n=60").json()


def timed_post(api: ApiClient, path: str, body: dict[str, Any]) -> tuple[Any, float]:
    t0 = time.monotonic()
    r = api.post(path, json=body)
    return r, time.monotonic() - t0


@pytest.mark.slow
def test_a_huge_exploration_answers_200_incomplete_before_the_limit(api):
    body = {"linkage": huge_chain(api), "options": {"max_components": 1000}}
    r, took = timed_post(api, "/v1/analysis/configuration-space", body)
    assert r.status_code == 200, r.text
    search = r.json()["search"]
    # stopped by whichever bound it meets first: its deadline, or (tracing fast enough) the
    # answer's budget of values, which only a search that is merely large reaches
    assert search["complete"] is False and search["reason"] in ("time", "budget")
    if search["reason"] == "budget":
        assert search["answer_size_reached"] is True and search["answer_values_max"] > 0
    else:
        assert "answer_size_reached" not in search
    assert search["time_budget_s"] == SEARCH_S
    assert r.json()["components"], "what was found comes back"
    assert took < TIME_LIMIT_S


def test_a_huge_search_answers_200_incomplete_where_nothing_derives_it(api):
    """The chain rules prove that the 60-rotor chain has no critical point: that answer is
    complete however much of the curves the deadline left untraced; its components are not."""
    body = {"linkage": huge_chain(api), "options": {"max_components": 1000}}
    r, took = timed_post(api, "/v1/analysis/critical-points", body)
    assert r.status_code == 200, r.text
    search = r.json()["search"]
    assert search["complete"] is True and search["argument"] == "derived"
    assert r.json()["critical_points"] == [] and "no critical point" in search["argument_detail"]
    assert took < TIME_LIMIT_S
    r, took = timed_post(api, "/v1/analysis/configuration-space", body)
    assert r.status_code == 200, r.text
    search = r.json()["search"]
    assert search["complete"] is False and search["reason"] in ("time", "budget")
    assert took < TIME_LIMIT_S


def test_a_fine_slice_answers_200_with_regions_left_unexplored(api):
    # (a linkage without a closed form: the three-rotor's map is drawn in well under 0.5 s)
    linkage = api.get("/v1/presets/rotor-chain-3d?n=2").json()
    body = {"linkage": linkage, "axes": [{"bar": "r0b", "min": 1.3, "max": 1.9},
                                         {"bar": "l0", "min": 1.2, "max": 1.8}],
            "options": {"resolution": 200, "seeds_per_axis": 12, "time_budget_s": 0.5}}
    r, took = timed_post(api, "/v1/analysis/critical-values", body)
    assert r.status_code == 200, r.text
    got = r.json()
    assert got["search"]["complete"] is False and got["search"]["reason"] == "time"
    assert got["search"]["regions_explored"] == sum(g["components"] is not None
                                                   for g in got["regions"])
    assert took < TIME_LIMIT_S


def test_the_time_budget_is_the_requests_within_the_limit(api):
    linkage = api.get("/v1/presets/four-bar").json()
    for asked, granted in [(0.25, 0.25), (1e4, SEARCH_SHARE * TIME_LIMIT_S)]:
        r = api.post("/v1/analysis/critical-points",
                     json={"linkage": linkage, "options": {"time_budget_s": asked}})
        assert r.status_code == 200, r.text
        search = r.json()["search"]
        assert search["time_budget_s"] == granted
        # The four-bar's three branch points took 80 ms through HTTP at load 4: 0.25 s asked
        # may end before them on a loaded machine (incomplete at load 12, the deadline counted
        # from the request's arrival), cut by time; the 9 s granted is ample anywhere.
        if asked == granted:
            assert search["complete"] is (search["reason"] is None)
            assert search["reason"] in (None, "time")
        else:
            assert search["complete"] is True and search["reason"] is None


@pytest.mark.parametrize("bad", [0, -1, "2", None, 1e6])
def test_a_bad_time_budget_is_a_422_naming_it(api, bad):
    linkage = api.get("/v1/presets/four-bar").json()
    r = api.post("/v1/analysis/configuration-space",
                 json={"linkage": linkage, "options": {"time_budget_s": bad}})
    if bad is None:  # null is the default
        assert r.status_code == 200, r.text
        return
    assert r.status_code == 422, r.text
    assert r.headers["content-type"].startswith("application/problem+json")
    assert r.json()["errors"][0]["loc"][-2:] == ["options", "time_budget_s"]


def test_robustness_and_design_report_their_search(api):
    linkage = api.get("/v1/presets/four-bar").json()
    r = api.post("/v1/analysis/robustness",
                 json={"linkage": linkage, "method": "multistart",
                       "options": {"time_budget_s": 0.3}})
    assert r.status_code == 200, r.text
    search = r.json()["search"]
    assert search["time_budget_s"] == 0.3 and search["complete"] in (True, False)
    if not search["complete"]:
        assert search["reason"] == "time"
    r = api.post("/v1/design/splitting",
                 json={"linkage": linkage, "targets": [{"branch_point": 0, "sign": 1}],
                       "adjustable": ["L2", "L3"]})
    assert r.status_code == 200, r.text
    assert r.json()["search"]["complete"] is True and r.json()["search"]["reason"] is None
