"""Every preset with its default parameters through every endpoint it is meaningful for answers
200 (issue 11): never a 504 for work that is merely large, never a 500; an answer cut short says
so (``search.complete: false`` with a ``reason``), a complete one has no reason.

The app here has a short search time of its own (the point is the answers' shape, not their
speed, which ``bench/bench_presets.py`` measures with the service's defaults)."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import pytest

from engine.catalogue.presets import PRESETS
from service.config import Settings
from service.main import create_app
from tests.conftest import ApiClient
from tests.service.preset_matrix import (
    ALWAYS,
    ONE_DOF_ONLY,
    SURFACES,
    TRACING,
    one_dof,
    preset_cases,
    two_dof,
)

# Every preset through every endpoint: the longest single test of the service's.
pytestmark = pytest.mark.slow

REASONS = {"time", "budget", "degenerate", "unresolved", "searched"}


@pytest.fixture(scope="module")
def api() -> Iterator[ApiClient]:
    app = create_app(Settings.from_env().replace(time_limit_s=30.0, search_time_s=1.0))
    client = ApiClient(app)
    yield client
    client.close()
    app.state.engine_pool.close()


def searches(answer: dict[str, Any]) -> list[dict[str, Any]]:
    found = answer.get("search")
    return [found] if isinstance(found, dict) else []


def test_every_listed_preset_is_a_case(api):
    """The cases below are the presets the service lists (none left out, none invented)."""
    assert {p["name"] for p in api.get("/v1/presets").json()} == set(PRESETS)


# One test per preset: the presets spread over the test processes instead of one long test.
@pytest.mark.parametrize("preset", sorted(PRESETS))
def test_every_preset_answers_every_endpoint(api, preset):
    answered = 0
    for name, path, body in preset_cases(api, only=[preset]):
        assert name == preset
        r = api.post(path, json=body)
        assert r.status_code == 200, (preset, path, r.status_code, r.text[:500])
        answered += 1
        if path.startswith("/v1/figures/"):
            assert r.headers["content-type"].startswith("image/svg+xml")
            assert r.text.lstrip().startswith("<?xml") or "<svg" in r.text[:500]
            continue
        for search in searches(r.json()):
            if search["complete"]:
                assert search["reason"] is None, (preset, path, search)
                assert search["argument"] in ("derived", "proved"), (preset, path, search)
            else:
                assert search["reason"] in REASONS, (preset, path, search)
    # every preset: first and second order and a figure; a 1-DOF one also every tracing
    # endpoint (the configuration-space figure only in the plane)
    linkage = api.get(f"/v1/presets/{preset}").json()
    planar = int(linkage.get("dimension", 2)) == 2
    assert answered >= len(ALWAYS) + ((len(TRACING) - (not planar)) if one_dof(linkage) else 0) \
        + ((len(SURFACES) - (not planar)) if two_dof(linkage) else 0)


@pytest.mark.parametrize("preset", sorted(PRESETS))
def test_two_dof_presets_are_refused_where_one_is_needed(api, preset):
    """Two degrees of freedom (issue 25): what needs one (tracing critical points, robustness,
    critical values) is a 422 naming the linkage, never a 5xx nor a silent skip."""
    linkage = api.get(f"/v1/presets/{preset}").json()
    if not two_dof(linkage):
        assert preset not in ("pentagon", "five-bar", "sphere-slider", "spherical-five-bar",
                              "spatial-quadrilateral")
        return
    bars = [b["id"] for b in linkage["bars"]][-2:]
    for path in ONE_DOF_ONLY:
        body = {"linkage": linkage, "axes": [{"bar": b, "min": 0.5, "max": 1.5} for b in bars]}
        r = api.post(path, json=body if path.endswith("critical-values") else
                     {"linkage": linkage})
        assert r.status_code == 422, (preset, path, r.status_code, r.text[:300])
        assert r.headers["content-type"].startswith("application/problem+json")
        assert r.json()["errors"][0]["loc"][:2] == ["body", "linkage"], (preset, path, r.text)
