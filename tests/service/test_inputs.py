"""Issue 17 in-process: 415 for bodies that are not JSON, ids of printable characters only,
large bodies (parsed in a worker) answered exactly like small ones, bounded metric labels, and
engine workers from the cgroup CPU quota."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest

from service import config
from service.bodies import OFFLOAD_BYTES
from tests.service.test_errors import JSON_HEADERS, assert_still_serving
from tests.service.test_errors import assert_problem as assert_problem_status
from tests.service.test_hostile import bodies, four_bar

POST = list(bodies(four_bar()))


def assert_problem(r: Any, status: int, kind: str) -> dict[str, Any]:
    problem = assert_problem_status(r, status)
    assert problem["type"] == kind, problem
    return problem


@pytest.mark.parametrize("url", POST)
@pytest.mark.parametrize("content_type", ["text/plain", "application/x-www-form-urlencoded",
                                          "application/xml", "multipart/form-data; boundary=x"])
def test_bodies_that_are_not_json_get_415(client: Any, url: str, content_type: str) -> None:
    body = json.dumps(bodies(four_bar())[url]).encode()
    r = client.post(url, content=body, headers={"content-type": content_type})
    problem = assert_problem(r, 415, "/problems/unsupported-media-type")
    assert problem["errors"][0]["loc"] == ["header", "content-type"]
    assert_still_serving(client)


@pytest.mark.parametrize("content_type", ["application/json", "application/json; charset=utf-8",
                                          "application/vnd.linkage+json"])
def test_json_content_types_are_accepted(client: Any, content_type: str) -> None:
    body = json.dumps({"linkage": four_bar()}).encode()
    r = client.post("/v1/analysis/rigidity", content=body,
                    headers={"content-type": content_type})
    assert r.status_code == 200, r.text


@pytest.mark.parametrize("bad", ["P\x00", "\x07", "a\nb", "tab\there", "del\x7f", "c1\x85",
                                 "rtl\u202eoverride", "zero\u200bwidth", "\ufeffbom"])
@pytest.mark.parametrize("where", ["vertex", "bar", "end"])
def test_ids_with_control_or_invisible_characters_are_refused(client: Any, bad: str,
                                                              where: str) -> None:
    lk = four_bar()
    if where == "vertex":
        lk["vertices"][2]["id"] = bad
        lk["bars"][0]["ends"][1] = bad
        loc = ["body", "linkage", "vertices", 2, "id"]
    elif where == "bar":
        lk["bars"][1]["id"] = bad
        loc = ["body", "linkage", "bars", 1, "id"]
    else:
        lk["bars"][2]["ends"][0] = bad
        loc = ["body", "linkage", "bars", 2, "ends", 0]
    r = client.post("/v1/analysis/rigidity", json={"linkage": lk})
    problem = assert_problem(r, 422, "/problems/validation-error")
    assert loc in [e["loc"] for e in problem["errors"]]
    assert "pattern" in problem["detail"]


def test_printable_unicode_ids_are_fine(client: Any) -> None:
    lk = four_bar()
    names = {"A": "Gelenk Ä ✓", "B": "关节 B"}
    for v in lk["vertices"]:
        v["id"] = names.get(v["id"], v["id"])
    for b in lk["bars"]:
        b["ends"] = [names.get(e, e) for e in b["ends"]]
    r = client.post("/v1/analysis/rigidity", json={"linkage": lk})
    assert r.status_code == 200, r.text
    assert set(r.json()["zero_modes"][0]) >= set(names.values())


def padded(body: Any) -> bytes:
    """The same JSON, made larger than OFFLOAD_BYTES by trailing whitespace (still valid)."""
    text = body if isinstance(body, bytes) else json.dumps(body).encode()
    return text + b" " * (OFFLOAD_BYTES + 1)


def broken_bodies() -> dict[str, bytes]:
    lk = four_bar()
    control = json.loads(json.dumps(lk))
    control["vertices"][3]["id"] = "B\x01"
    unknown = json.loads(json.dumps(lk))
    unknown["bars"][1]["colour"] = "red"
    wrong = json.loads(json.dumps(lk))
    wrong["vertices"][0]["position"] = ["0", 0]
    return {
        "control id": json.dumps({"linkage": control}).encode(),
        "unknown field": json.dumps({"linkage": unknown}).encode(),
        "wrong type": json.dumps({"linkage": wrong}).encode(),
        "NaN": json.dumps({"linkage": lk}).encode().replace(b"0.0", b"NaN", 1),
        "malformed": b'{"linkage": {"vertices": [}',
        "not an object": b"[1, 2, 3]",
        "missing linkage": b'{"tolerances": {}}',
    }


@pytest.mark.parametrize("name", list(broken_bodies()))
def test_large_bodies_get_the_same_problems_as_small_ones(client: Any, name: str) -> None:
    body = broken_bodies()[name]
    small = client.post("/v1/analysis/second-order", content=body, headers=JSON_HEADERS)
    large = client.post("/v1/analysis/second-order", content=padded(body), headers=JSON_HEADERS)
    assert small.status_code == large.status_code == 422, (small.text, large.text)
    assert small.json() == large.json()


def test_large_bodies_are_analysed_like_small_ones(client: Any) -> None:
    body = {"linkage": four_bar(), "tolerances": {"rank_rtol": 1e-9}}
    small = client.post("/v1/analysis/rigidity", json=body)
    large = client.post("/v1/analysis/rigidity", content=padded(body), headers=JSON_HEADERS)
    assert small.status_code == large.status_code == 200
    assert small.json() == large.json()


def test_large_bodies_over_the_limits_are_refused_before_validation(app: Any, client: Any
                                                                    ) -> None:
    lk = four_bar()
    lk["vertices"].append({"id": "bad\x00", "position": "not even a position"})
    before = app.dependency_overrides[config.get_settings]
    app.dependency_overrides[config.get_settings] = lambda: before().replace(max_vertices=4)
    try:
        r = client.post("/v1/analysis/rigidity", content=padded({"linkage": lk}),
                        headers=JSON_HEADERS)
    finally:
        app.dependency_overrides[config.get_settings] = before
    problem = assert_problem(r, 422, "/problems/limit-exceeded")
    assert problem["errors"] == [{"loc": ["body", "linkage", "vertices"],
                                  "msg": "5 vertices exceed the limit of 4"}]


def series(text: str) -> set[str]:
    return {ln.rsplit(" ", 1)[0] for ln in text.splitlines()
            if ln.startswith("linkage_requests_total{")}


def test_metric_routes_are_templates_docs_or_other(client: Any) -> None:
    for url in ("/docs", "/redoc", "/openapi.json", "/v1/presets/four-bar",
                "/no/such/thing", "/v1/presets/four-bar/extra"):
        client.get(url)
    for i in range(50):
        client.request(f"INVENTED{i}", "/health")
        client.request(f"INVENTED{i}", f"/random/{i}")
    found = series(client.get("/metrics").text)
    routes = {s.split('route="', 1)[1].split('"', 1)[0] for s in found}
    methods = {s.split('method="', 1)[1].split('"', 1)[0] for s in found}
    # each preset has its own route (issue 11), so its template is its own path
    assert {"/docs", "/redoc", "/openapi.json", "/v1/presets/four-bar", "other"} <= routes
    assert "unmatched" not in routes and not any(r.startswith("/random") for r in routes)
    assert methods <= {"GET", "HEAD", "POST", "PUT", "PATCH", "DELETE", "OPTIONS", "other"}


def write(path: Path, text: str) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)


def test_cgroup_cpu_quota(tmp_path: Path) -> None:
    v2 = tmp_path / "v2"
    write(v2 / "cpu.max", "150000 100000\n")
    assert config.cgroup_cpu_limit(str(v2)) == 1.5
    write(v2 / "cpu.max", "max 100000\n")
    assert config.cgroup_cpu_limit(str(v2)) is None
    v1 = tmp_path / "v1"
    write(v1 / "cpu" / "cpu.cfs_quota_us", "50000\n")
    write(v1 / "cpu" / "cpu.cfs_period_us", "100000\n")
    assert config.cgroup_cpu_limit(str(v1)) == 0.5
    write(v1 / "cpu" / "cpu.cfs_quota_us", "-1\n")
    assert config.cgroup_cpu_limit(str(v1)) is None
    assert config.cgroup_cpu_limit(str(tmp_path / "none")) is None


@pytest.mark.parametrize("quota, cap", [(None, None), (0.5, 1), (1.0, 1), (1.2, 2), (64.0, None)])
def test_default_workers_follow_the_cpu_quota(monkeypatch: Any, quota: float | None,
                                              cap: int | None) -> None:
    import os

    cores = len(os.sched_getaffinity(0))
    monkeypatch.setattr(config, "cgroup_cpu_limit", lambda root="/sys/fs/cgroup": quota)
    assert config.default_workers() == (cores if cap is None else min(cores, cap))
