"""Fuzzing that reaches the engine (issue 28): every POST operation gets generated *valid*
requests, built around random one-degree-of-freedom linkages (``one_dof_linkage_bodies`` of
``tests/strategies.py``: generic positions, the lengths as drawn), and each must be answered
(2xx, or only the refusals listed in ``REFUSALS``, which depend on what the linkage turns out
to be), with a status code, content type and body that conform to the OpenAPI schema
(schemathesis's checks). Jobs and sweeps go through a real Dask cluster and their ids through
``GET`` and ``DELETE /v1/jobs/{job_id}``.

Bounded: ``FUZZ_VALID_EXAMPLES`` (10 unless the environment says otherwise) requests per
operation, some 150 in all; the jobs test takes a fifth of that.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable, Iterator
from typing import Any

import hypothesis
import pytest
import schemathesis
from hypothesis import strategies as st

from service.config import Settings
from service.main import create_app
from tests.service.test_fuzz_openapi import CHECKS
from tests.strategies import one_dof_linkage_bodies

pytestmark = pytest.mark.fuzz

EXAMPLES = int(os.environ.get("FUZZ_VALID_EXAMPLES", "10"))
#: Seconds a search may take: small linkages, and the answers are what is checked.
BUDGET = 1.0

app = create_app(Settings(max_vertices=12, max_bars=24, time_limit_s=120.0, workers=2))
schema = schemathesis.openapi.from_asgi("/openapi.json", app)

Body = dict[str, Any]
Draw = Callable[[st.SearchStrategy[Any]], Any]


def _bars(linkage: Body) -> list[str]:
    return [b["id"] for b in linkage["bars"]]


def _length(linkage: Body, bar: str) -> float:
    pos = {v["id"]: v["position"] for v in linkage["vertices"]}
    i, j = next(b["ends"] for b in linkage["bars"] if b["id"] == bar)
    return float(sum((a - b) ** 2 for a, b in zip(pos[i], pos[j], strict=True)) ** 0.5)


def _options(draw: Draw) -> Body:
    return {"time_budget_s": BUDGET, "seed": draw(st.integers(0, 2**32 - 1)),
            "max_components": draw(st.integers(1, 8))}


def _axes(draw: Draw, linkage: Body) -> list[Body]:
    """Two bars with a box around their lengths (positive ends, min < max)."""
    bars = draw(st.permutations(_bars(linkage)))[:2]
    out = []
    for bar in bars:
        length = _length(linkage, bar)
        low = length * draw(st.floats(0.3, 0.95))
        out.append({"bar": bar, "min": low, "max": length * draw(st.floats(1.05, 3.0))})
    return out


def _analysis(draw: Draw, linkage: Body) -> Body:
    return {"linkage": linkage}


def _space(draw: Draw, linkage: Body) -> Body:
    return {"linkage": linkage, "options": _options(draw)}


def _splitting(draw: Draw, linkage: Body) -> Body:
    bar = draw(st.sampled_from(_bars(linkage)))
    return {"linkage": linkage, "options": _options(draw),
            "perturbation": {bar: draw(st.floats(-0.05, 0.05))}}


def _critical_values(draw: Draw, linkage: Body) -> Body:
    return {"linkage": linkage, "axes": _axes(draw, linkage),
            "options": {"resolution": draw(st.integers(8, 16)), "time_budget_s": BUDGET}}


def _robustness(draw: Draw, linkage: Body) -> Body:
    bars = _bars(linkage)
    return {"linkage": linkage, "options": _options(draw),
            "adjustable": draw(st.lists(st.sampled_from(bars), min_size=1, unique=True))}


def _design(draw: Draw, linkage: Body) -> Body:
    return {"linkage": linkage, "options": _options(draw),
            "targets": [{"branch_point": 0, "sign": draw(st.sampled_from([-1, 1]))}],
            "adjustable": draw(st.lists(st.sampled_from(_bars(linkage)), min_size=1,
                                        unique=True))}


def _linkage_figure(draw: Draw, linkage: Body) -> Body:
    return {"linkage": linkage, "show": draw(st.lists(
        st.sampled_from(["zero_modes", "tangents", "self_stress"]), unique=True))}


BODIES: dict[str, Callable[[Draw, Body], Body]] = {
    "/v1/analysis/rigidity": _analysis,
    "/v1/analysis/second-order": _analysis,
    "/v1/analysis/critical-points": _space,
    "/v1/analysis/configuration-space": _space,
    "/v1/analysis/splitting": _splitting,
    "/v1/analysis/robustness": _robustness,
    "/v1/analysis/critical-values": _critical_values,
    "/v1/design/splitting": _design,
    "/v1/figures/linkage": _linkage_figure,
    "/v1/figures/configuration-space": _space,
    "/v1/figures/critical-values": _critical_values,
    "/v1/figures/splitting": _splitting,
}
#: Refusals a valid request may meet, by what the linkage turns out to be: a design that
#: targets branch point 0 of a linkage that has none.
REFUSALS: dict[str, set[str]] = {"/v1/design/splitting": {"/problems/invalid-request"}}


def fuzz_settings(examples: int) -> hypothesis.settings:
    return hypothesis.settings(max_examples=examples, deadline=None, database=None,
                               suppress_health_check=list(hypothesis.HealthCheck))


def _call(path: str, body: Body) -> Any:
    case = schema[path]["POST"].Case(body=body, media_type="application/json")
    response = case.call_and_validate(checks=CHECKS)
    if response.status_code >= 300:
        kind = response.json().get("type")
        assert kind in REFUSALS.get(path, set()), (path, response.status_code, response.text)
    return response


def test_every_post_operation_but_jobs_is_fuzzed_with_valid_linkages() -> None:
    posts = {op.ok().path for op in schema.get_all_operations() if op.ok().method == "post"}
    assert posts - set(BODIES) == {"/v1/jobs", "/v1/sweeps"}  # test_fuzz_valid_jobs


@pytest.mark.parametrize("path", sorted(BODIES))
def test_fuzz_valid_operation(path: str) -> None:
    @fuzz_settings(EXAMPLES)
    @hypothesis.given(linkage=one_dof_linkage_bodies(), data=st.data())
    def run(linkage: Body, data: st.DataObject) -> None:
        _call(path, BODIES[path](data.draw, linkage))

    run()


@pytest.fixture(scope="module")
def dask_app() -> Iterator[None]:
    yield
    app.state.jobs.close()


@pytest.mark.dask
def test_fuzz_valid_jobs(dask_app: None) -> None:
    """Jobs of generated valid requests and sweeps over generated linkages, each followed to
    its end through ``GET /v1/jobs/{job_id}`` and removed with ``DELETE``."""
    @fuzz_settings(max(2, EXAMPLES // 5))
    @hypothesis.given(linkage=one_dof_linkage_bodies(max_dyads=2), data=st.data(),
                      operation=st.sampled_from(["analysis/rigidity",
                                                 "analysis/configuration-space",
                                                 "analysis/critical-points"]))
    def run(linkage: Body, data: st.DataObject, operation: str) -> None:
        body = BODIES[f"/v1/{operation}"](data.draw, linkage)
        bar = data.draw(st.sampled_from(_bars(linkage)))
        length = _length(linkage, bar)
        sweep = {"linkage": linkage, "options": _options(data.draw),
                 "grid": {bar: {"min": 0.9 * length, "max": 1.1 * length, "steps": 2}},
                 "compute": data.draw(st.lists(st.sampled_from(["components", "critical"]),
                                               min_size=1, unique=True))}
        for path, payload in (("/v1/jobs", {"operation": operation, "body": body}),
                              ("/v1/sweeps", sweep)):
            created = _call(path, payload)
            assert created.status_code == 202, created.text
            job_id = created.json()["id"]
            status = schema["/v1/jobs/{job_id}"]["GET"]
            deadline = time.monotonic() + 120
            while True:
                got = status.Case(path_parameters={"job_id": job_id}).call_and_validate(
                    checks=CHECKS)
                assert got.status_code == 200, got.text
                if got.json()["status"] not in ("queued", "running"):
                    break
                assert time.monotonic() < deadline, got.text
                time.sleep(0.2)
            assert got.json()["status"] == "done", got.text
            gone = schema["/v1/jobs/{job_id}"]["DELETE"].Case(
                path_parameters={"job_id": job_id}).call_and_validate(checks=CHECKS)
            assert gone.status_code < 300, gone.text

    run()
