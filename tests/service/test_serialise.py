"""JSON answers through orjson (service/serialise.py) and the compact form of point arrays
(``options.points = "compact"``).

References: pydantic's own ``model_dump_json(by_alias=True)``, which served every answer before,
for the JSON data; the default (per-vertex lists) answer for the compact one, bit for bit."""

from __future__ import annotations

import base64
import json
import math
from typing import Any

import numpy as np
import pytest

from engine.catalogue.presets import build_preset
from service import jobs, serialise
from service.config import get_settings
from service.mappers import linkage_out
from service.schemas.common import AnalysisRequest, SearchReport
from service.schemas.critical_values import CriticalValuesRequest
from service.schemas.design import DesignRequest
from service.schemas.robustness import RobustnessRequest
from service.schemas.space import SpaceRequest, SpaceResponse
from service.schemas.splitting import SplittingRequest

FAST = {"angles": 24, "random_starts": 4}
SPACE = "/v1/analysis/configuration-space"


def _linkage(name: str, **params: float) -> dict[str, Any]:
    return linkage_out(build_preset(name, params)).model_dump(mode="json", by_alias=True)


def _same_json(model: Any) -> None:
    ours = serialise.dumps(model)
    assert json.loads(ours) == json.loads(model.model_dump_json(by_alias=True))


@pytest.mark.parametrize(("name", "params"), [
    ("four-bar", {"L1": 0.5, "L2": 1.2, "L3": 1.0}),  # closed form, two components
    ("four-bar", {}),  # critical lengths: three branch points, segments (alias "from")
    ("three-rotor", {}),
    ("kl-chain", {"n": 4}),
])
def test_every_answer_serialises_to_pydantics_json(app, name, params):
    """The same JSON data as pydantic's serialiser, answer by answer (search reports with their
    extra keys, aliases, nulls, nested models)."""
    settings = app.dependency_overrides[get_settings]()
    lk = _linkage(name, **params)
    bars = [b["id"] for b in lk["bars"]]
    _same_json(jobs.rigidity(AnalysisRequest.model_validate({"linkage": lk}), settings))
    _same_json(jobs.second_order_analysis(AnalysisRequest.model_validate({"linkage": lk}),
                                          settings))
    space = SpaceRequest.model_validate({"linkage": lk, "options": FAST})
    _same_json(jobs.critical_points(space, settings))
    _same_json(jobs.configuration_space(space, settings))
    compact = SpaceRequest.model_validate({"linkage": lk,
                                           "options": {**FAST, "points": "compact"}})
    _same_json(jobs.configuration_space(compact, settings))
    _same_json(jobs.splitting(SplittingRequest.model_validate(
        {"linkage": lk, "perturbation": {bars[-1]: 1e-3}, "options": FAST}), settings))
    _same_json(jobs.robustness_margin(RobustnessRequest.model_validate(
        {"linkage": lk, "options": FAST}), settings))
    if name == "four-bar":
        _same_json(jobs.critical_values(CriticalValuesRequest.model_validate({
            "linkage": lk, "axes": [{"bar": "L2", "min": 0.3, "max": 2.2},
                                    {"bar": "L3", "min": 0.3, "max": 2.2}],
            "options": {"resolution": 12, "seeds_per_axis": 2}}), settings))
    if name == "three-rotor":
        _same_json(jobs.design_splitting(DesignRequest.model_validate({
            "linkage": lk, "targets": [{"branch_point": 0, "sign": 1}],
            "adjustable": ["r1", "L1", "L2"], "options": FAST}), settings))


@pytest.mark.parametrize("points", [None, "compact"])
def test_parts_join_to_the_same_bytes(points):
    """dumps_parts: the compact arrays' base64 spliced in as chunks of their own, the rest
    orjson's; together byte for byte what dumps gives (and so pydantic's JSON data)."""
    settings = get_settings()
    lk = _linkage("four-bar", L1=0.5, L2=1.2, L3=1.0)
    answer = jobs.configuration_space(SpaceRequest.model_validate(
        {"linkage": lk, "options": {**FAST, "step_max": 1e-3, "points": points}}), settings)
    parts = serialise.dumps_parts(answer)
    assert b"".join(parts) == serialise.dumps(answer)
    packed = [a for comp in answer.components for a in (comp.positions, comp.angles)]
    if points == "compact":
        # text, base64, text, base64, ...: every packed array spliced, none through orjson
        assert parts[1::2] == [a.base64.encode() for a in packed]
        assert all(p.endswith(b'"base64":"') for p in parts[:-1:2])
    else:
        assert len(parts) == 1
    plain = {"a": [1.5, "x\x00y"]}  # a NUL in a string is escaped, never taken for a splice
    assert serialise.dumps_parts(plain) == [serialise.dumps(plain)]


def test_non_finite_numbers_are_null_as_before():
    """NaN and +-Infinity were ``null`` in pydantic's JSON (ser_json_inf_nan="null"); they
    still are, in fields, in extra keys and in numpy arrays, and the output is valid JSON."""
    report = SearchReport(complete=False, reason="time", time_budget_s=math.nan,
                          **{"worst": math.inf, "gaps": [1.0, -math.inf, math.nan]})
    before = json.loads(report.model_dump_json(by_alias=True))
    assert before["time_budget_s"] is None and before["gaps"] == [1.0, None, None]
    raw = serialise.dumps(report)
    assert b"NaN" not in raw and b"Infinity" not in raw
    assert json.loads(raw) == before
    arr = serialise.dumps({"a": np.array([math.nan, math.inf, -math.inf, 0.5])})
    assert json.loads(arr) == {"a": [None, None, None, 0.5]}


def _decode(packed: dict[str, Any]) -> np.ndarray:
    assert packed["dtype"] == "<f8"
    flat = np.frombuffer(base64.b64decode(packed["base64"], validate=True), "<f8")
    return flat.reshape(packed["shape"])


@pytest.mark.parametrize(("name", "params", "options"), [
    ("four-bar", {"L1": 0.5, "L2": 1.2, "L3": 1.0}, {"step_max": 1e-3}),  # closed form
    # dense: answers of megabytes, which come back from the worker through a file
    ("four-bar", {"L1": 0.5, "L2": 1.2, "L3": 1.0}, {"step_max": 2.5e-4}),
    ("four-bar", {}, {}),  # critical lengths: tracer, open segments between branch points
    ("three-rotor", {}, {}),
    ("kl-chain", {"n": 6}, {}),
    ("gated-kl-chain", {"n": 6, "gate": 3}, {}),
])
def test_compact_points_decode_to_the_default_points(client, name, params, options):
    lk = _linkage(name, **params)
    answers = {}
    for form in ("objects", "compact", None):
        opts = {**FAST, **options, **({} if form is None else {"points": form})}
        r = client.post(SPACE, json={"linkage": lk, "options": opts})
        assert r.status_code == 200, r.text
        assert r.headers["content-type"].startswith("application/json")
        answers[form] = r.json()
    assert answers["objects"] == answers[None]  # "objects" is the default
    default, compact = answers[None], answers["compact"]
    SpaceResponse.model_validate(compact)
    assert default["components"], "nothing to compare"
    rotors = None
    for d, c in zip(default["components"], compact["components"], strict=True):
        pos = _decode(c["positions"])
        assert c["positions"]["ids"] == list(d["positions"]) == [v["id"] for v in lk["vertices"]]
        n = len(next(iter(d["positions"].values())))
        assert pos.shape == (n, len(lk["vertices"]), 2)
        for k, vid in enumerate(c["positions"]["ids"]):
            assert np.array_equal(pos[:, k], np.array(d["positions"][vid]))  # bit for bit
        ang = _decode(c["angles"])
        assert c["angles"]["ids"] == list(d["angles"]) and ang.shape == (n, len(d["angles"]))
        for k, bar in enumerate(c["angles"]["ids"]):
            assert np.array_equal(ang[:, k], np.array(d["angles"][bar]))
        rotors = c["angles"]["ids"]
        # everything else is the default answer's
        rest = {k: v for k, v in c.items() if k not in ("positions", "angles")}
        assert rest == {k: v for k, v in d.items() if k not in ("positions", "angles")}
    assert rotors, "a linkage without rotors tests no angles"
    strip = ("components", "search")
    assert {k: v for k, v in compact.items() if k not in strip} \
        == {k: v for k, v in default.items() if k not in strip}


def test_points_option_is_validated(client):
    lk = _linkage("four-bar")
    r = client.post(SPACE, json={"linkage": lk, "options": {"points": "base64"}})
    assert r.status_code == 422
    assert r.headers["content-type"].startswith("application/problem+json")
    assert r.json()["errors"][0]["loc"] == ["body", "options", "points"]


def test_figure_ignores_the_compact_form(client):
    """The configuration-space figure draws from the per-vertex lists whatever the option."""
    lk = _linkage("four-bar", L1=0.5, L2=1.2, L3=1.0)
    r = client.post("/v1/figures/configuration-space",
                    json={"linkage": lk, "options": {**FAST, "points": "compact"}})
    assert r.status_code == 200 and r.headers["content-type"].startswith("image/svg+xml")


def test_critical_points_ignore_the_compact_form(client):
    lk = _linkage("four-bar")
    a = client.post("/v1/analysis/critical-points", json={"linkage": lk, "options": FAST})
    b = client.post("/v1/analysis/critical-points",
                    json={"linkage": lk, "options": {**FAST, "points": "compact"}})
    assert a.status_code == b.status_code == 200
    strip = ("search",)
    assert {k: v for k, v in a.json().items() if k not in strip} \
        == {k: v for k, v in b.json().items() if k not in strip}


def test_raw_json_is_written_as_it_is_and_parsed_only_when_asked() -> None:
    """A job's answer kept as its worker's JSON: inside a model it is spliced in byte for byte,
    and its value is the parsed JSON."""
    from service.serialise import RawJSON, dumps

    data = b'{"a":[1.5,2,null],"b":"x\\u00e9"}'
    raw = RawJSON(data)
    assert raw.value() == {"a": [1.5, 2, None], "b": "x\u00e9"}
    assert dumps({"result": raw, "id": "j"}) == b'{"result":' + data + b',"id":"j"}'


def test_counts_beyond_a_json_number_are_decimal_strings():
    """A sweep row of a chain with 2^69 components and a search report with 2^64 of them:
    JSON numbers up to 2^53 - 1 (exact in a double), decimal strings beyond (orjson refused
    integers beyond 64 bits: a 500)."""
    from engine.design.sweep import PointResult
    from service.mappers.jobs import sweep_out
    from service.mappers.space import search_out

    rows = [PointResult((1.0,), components=2**69, complete=True),
            PointResult((2.0,), components=2**53 - 1, complete=True)]
    data = json.loads(serialise.dumps(sweep_out(("r",), rows)))
    assert [r["components"] for r in data["rows"]] == [str(2**69), 2**53 - 1]
    report = SearchReport.model_validate(search_out(
        {"complete": False, "reason": "budget", "components_total": np.int64(2**53),
         "big": 2**64, "small": -5, "flag": True}))
    data = json.loads(serialise.dumps(report))
    assert data["components_total"] == str(2**53) and data["big"] == str(2**64)
    assert data["small"] == -5 and data["flag"] is True


@pytest.mark.parametrize("total", [2**64, -(2**70), 2**19999, 10**3000, 10**4000 - 1],
                         ids=["2^64", "-2^70", "2^19999", "10^3000", "10^4000-1"])
def test_counts_of_any_size_are_their_decimal_strings(total):
    """Beyond ``str(int)``'s 4300 digits too (the 20000-rotor chain's 2^19999 components made
    a 500); the reference digits come from ``decimal``, which has no such limit."""
    from decimal import Decimal, localcontext

    from service.mappers.space import search_out

    with localcontext() as ctx:
        ctx.prec = 7000
        digits = format(Decimal(total), "f")
    report = SearchReport.model_validate(search_out(
        {"complete": True, "reason": None, "components_total": total}))
    assert f'"components_total":"{digits}"' in serialise.dumps(report).decode()


def test_counts_inside_nested_report_objects_are_decimal_strings_too():
    """A homotopy's path count (2^199 for a 100-rotor chain) sits in ``search.homotopy``: it
    made a 500 (orjson refuses integers beyond 64 bits) where only top-level counts were
    converted."""
    from service.mappers.space import search_out

    report = SearchReport.model_validate(search_out(
        {"complete": False, "reason": "searched",
         "homotopy": {"paths": 2**199, "quadrics": 57, "success": False},
         "rows": [2**70, 3]}))
    data = json.loads(serialise.dumps(report))
    assert data["homotopy"] == {"paths": str(2**199), "quadrics": 57, "success": False}
    assert data["rows"] == [str(2**70), 3]
