"""Answer sizes estimated before the answer is built (``service/answers.py``, issue 28): each
estimate is a lower bound on the JSON actually answered (checked against real answers, whose
numbers are counted here), and an answer estimated beyond ``LINKAGE_MAX_ANSWER_MB`` is a 422
naming the limit, for every endpoint whose answer grows with what is asked."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import pytest

from engine.model.errors import InvalidRequest, LimitExceeded
from service import answers
from service.config import Settings
from service.main import create_app
from tests.conftest import ApiClient

MB = 2**20


@pytest.fixture(scope="module")
def small_limit() -> Iterator[ApiClient]:
    """An app whose answers may hold at most 1 MB."""
    app = create_app(Settings(workers=1, time_limit_s=300.0, search_time_s=200.0,
                              max_answer_mb=1))
    c = ApiClient(app)
    yield c
    c.close()
    app.state.engine_pool.close()


def _chain(client: ApiClient, n: int) -> dict[str, Any]:
    r = client.get(f"/v1/presets/kl-chain?n={n}")
    assert r.status_code == 200
    return r.json()


def _numbers(value: Any) -> int:
    """Numbers (not booleans) anywhere in a JSON value."""
    if isinstance(value, bool):
        return 0
    if isinstance(value, int | float):
        return 1
    if isinstance(value, dict):
        return sum(_numbers(v) for v in value.values())
    if isinstance(value, list):
        return sum(_numbers(v) for v in value)
    return 0


def _points_numbers(answer: dict[str, Any]) -> int:
    """Numbers of the components' positions: points times vertices times dimension, counted."""
    return sum(_numbers(comp["positions"]) for comp in answer["components"])


def test_a_configuration_space_answer_is_at_least_its_estimate(client: Any) -> None:
    linkage = _chain(client, 12)
    r = client.post("/v1/analysis/configuration-space",
                    json={"linkage": linkage, "options": {"step_max": 0.05}})
    assert r.status_code == 200, r.text
    answer = r.json()
    counted = _points_numbers(answer)
    points = sum(len(next(iter(c["positions"].values()))) for c in answer["components"])
    vd = len(linkage["vertices"]) * linkage["dimension"]
    assert counted == points * vd > 0  # each point places every vertex
    # the estimate's bytes per number is a lower bound on what the answer takes
    assert len(r.content) >= counted * answers.ANSWER_BYTES_PER_NUMBER
    # the estimate refuses exactly above the limit: 1 byte less would refuse this answer
    tight = Settings(max_answer_mb=1)
    size = (points * vd + len(answer["critical_points"]) * vd) * answers.ANSWER_BYTES_PER_NUMBER
    answers.check_points(_engine_linkage(linkage), points, len(answer["critical_points"]),
                         False, tight.replace(max_answer_mb=max(1, -(-int(size) // MB))))


def _engine_linkage(linkage: dict[str, Any]) -> Any:
    from service import mappers
    from service.schemas.common import Linkage

    return mappers.problem_in(Linkage.model_validate(linkage), None, Settings().limits)[0]


def test_a_compact_answer_is_at_least_its_estimate(client: Any) -> None:
    linkage = _chain(client, 12)
    r = client.post("/v1/analysis/configuration-space",
                    json={"linkage": linkage, "options": {"step_max": 0.05,
                                                          "points": "compact"}})
    assert r.status_code == 200, r.text
    answer = r.json()
    packed = sum(len(c["positions"]["base64"]) for c in answer["components"])
    numbers = sum(c["positions"]["shape"][0] * c["positions"]["shape"][1]
                  * c["positions"]["shape"][2] for c in answer["components"])
    assert packed == pytest.approx(numbers * answers.PACKED_BYTES_PER_NUMBER, abs=4 * 8)
    assert len(r.content) >= numbers * answers.PACKED_BYTES_PER_NUMBER


def test_a_configuration_space_beyond_the_limit_is_refused(small_limit: ApiClient) -> None:
    # 41 vertices: every point is 82 numbers, at least 1.3 kB; 800 points pass 1 MB (a
    # step of 0.005 ran a worker out of 18 GB here: the tracer, not the answer)
    linkage = _chain(small_limit, 20)
    r = small_limit.post("/v1/analysis/configuration-space",
                         json={"linkage": linkage, "options": {"step_max": 0.02}})
    assert r.status_code == 422, r.text
    problem = r.json()
    assert r.headers["content-type"] == "application/problem+json"
    assert "LINKAGE_MAX_ANSWER_MB = 1" in problem["detail"]
    assert problem["errors"][0]["loc"] == ["body", "options"]
    # the same request answered compactly needs fewer bytes a number, and is refused all the
    # same when its estimate is above the limit; the advice then names no compact form
    assert "compact" in problem["detail"]


def test_a_figure_of_a_configuration_space_beyond_the_limit_is_refused(
        small_limit: ApiClient) -> None:
    linkage = _chain(small_limit, 20)
    r = small_limit.post("/v1/figures/configuration-space",
                         json={"linkage": linkage, "options": {"step_max": 0.02}})
    assert r.status_code == 422, r.text
    assert "LINKAGE_MAX_ANSWER_MB = 1" in r.json()["detail"]


def test_a_sweep_beyond_the_limit_is_refused_before_any_job(small_limit: ApiClient) -> None:
    body = {"preset": {"name": "four-bar"}, "samples": {"L2": {"mean": 1.0, "sd": 0.01}},
            "count": 100_000, "compute": ["components", "critical"]}
    r = small_limit.post("/v1/sweeps", json=body)
    assert r.status_code == 422, r.text
    problem = r.json()
    # 100,000 rows of 3 values and the four-bar's one cell of tau signs (4 sides, 3 signs) at
    # 16 bytes: 15 MB
    assert "LINKAGE_MAX_ANSWER_MB = 1" in problem["detail"]
    assert "100,000 rows of 10 values (1,000,000 numbers)" in problem["detail"]
    assert small_limit.get("/v1/jobs").json() == []  # no job was started


@pytest.mark.parametrize("check, args, numbers", [
    (answers.check_slice, (1000, 10), 2 * 1000 + 3 * 10),
    (answers.check_sweep, (1000, 2, 3), 1000 * 5),
])
def test_the_limit_is_met_exactly(check: Any, args: tuple[int, ...], numbers: int) -> None:
    """An answer of exactly the limit passes, one byte beyond is refused (the limit in MB,
    16 bytes a number)."""
    size = numbers * answers.ANSWER_BYTES_PER_NUMBER
    at = Settings(max_answer_mb=1)
    scale = MB // size + 1  # the counts scaled just past 1 MB
    check(*args, at.replace(max_answer_mb=1)) if size <= MB else None
    with pytest.raises(InvalidRequest, match="LINKAGE_MAX_ANSWER_MB = 1"):
        check(*(a * scale if k == 0 else a for k, a in enumerate(args)), at)


def test_critical_points_count_their_configurations() -> None:
    linkage = _engine_linkage({
        "dimension": 2,
        "vertices": [{"id": f"v{i}", "position": [float(i), 0.0], "fixed": i == 0}
                     for i in range(100)],
        "bars": [{"id": f"b{i}", "ends": [f"v{i}", f"v{i + 1}"]} for i in range(99)]})
    vd = 200
    # (critical + 2 near misses) * V d numbers at 16 bytes: 1 MB is 65,536 numbers
    answers.check_critical(linkage, 327, 0, Settings(max_answer_mb=1))  # 65,400 numbers
    with pytest.raises(InvalidRequest, match="LINKAGE_MAX_ANSWER_MB = 1"):
        answers.check_critical(linkage, 1, 164, Settings(max_answer_mb=1))  # 65,800
    assert 327 * vd <= MB // 16 < 329 * vd


def test_the_first_order_estimate_refuses_the_linkage() -> None:
    """K30 in 3D with two pins: 434 active bars (the one between the pins is not) on 84 free
    coordinates, so at least 434 - 84 self-stresses of 434 entries (rank-nullity) and no
    zero mode: 151,900 numbers, 2.3 MB at 16 bytes."""
    import itertools

    linkage = _engine_linkage({
        "dimension": 3,
        "vertices": [{"id": f"v{i}", "position": [float(i), float(i * i % 7), float(i % 5)],
                      "fixed": i < 2} for i in range(30)],
        "bars": [{"id": f"b{i}_{j}", "ends": [f"v{i}", f"v{j}"]}
                 for i, j in itertools.combinations(range(30), 2)]})
    assert answers.first_order_numbers(linkage) == (434 - 84) * 434
    with pytest.raises(LimitExceeded, match="LINKAGE_MAX_ANSWER_MB = 1"):
        answers.check_first_order(linkage, Settings(max_answer_mb=1))
    answers.check_first_order(linkage, Settings(max_answer_mb=3))
