"""Every operation of openapi/openapi.json through the client, against the real app, with the
answers checked against references written here (closed forms, the bar lengths)."""

from __future__ import annotations

import inspect
import itertools
import math
import re
import tomllib
import xml.etree.ElementTree as ET
from typing import Any

import linkage_client
import numpy as np
import pytest
from linkage_client import AsyncClient, Client, Labelled, Linkage, ProblemError

from tests.client.conftest import OPENAPI, ROOT, operations

FAST = {"angles": 24, "random_starts": 4}


def snake(operation_id: str) -> str:
    return re.sub(r"(?<=[a-z0-9])([A-Z])", r"_\1", operation_id).lower()


def preset_routes() -> dict[str, str]:
    """operationId -> preset name of each preset's own route."""
    return {op: path.rsplit("/", 1)[1] for (method, path), op in operations().items()
            if path.startswith("/v1/presets/") and "{" not in path}


@pytest.mark.parametrize("client_class", [Client, AsyncClient])
def test_every_operation_id_has_a_client_method(client_class: type) -> None:
    missing = [op for op in operations().values() if not callable(
        getattr(client_class, snake(op), None))]
    assert not missing, f"operationIds without a {client_class.__name__} method: {missing}"


def test_async_methods_are_coroutines_and_mirror_the_sync_ones() -> None:
    for op in operations().values():
        name = snake(op)
        if op in preset_routes():  # shared: returns the client's get_preset (awaitable)
            continue
        assert inspect.iscoroutinefunction(getattr(AsyncClient, name)), name
        sync_params = inspect.signature(getattr(Client, name)).parameters
        async_params = inspect.signature(getattr(AsyncClient, name)).parameters
        assert list(sync_params) == list(async_params), name


def grashof_critical_gap(sides: list[float]) -> float:
    """Smallest |a +- L1 +- L2 +- L3| (zero: a configuration with all joints on a line)."""
    a, rest = sides[0], sides[1:]
    return min(abs(a + sum(s * x for s, x in zip(signs, rest, strict=True)))
               for signs in itertools.product((1, -1), repeat=3))


def bar_residual(linkage: Linkage, positions: Labelled) -> float:
    """Largest |distance - length| over the bars, on (V, d) or (n, V, d) positions."""
    lengths = linkage.lengths()
    worst = 0.0
    for bar in linkage.bars:
        a, b = positions[bar.ends[0]], positions[bar.ends[1]]
        worst = max(worst, float(np.max(np.abs(np.linalg.norm(a - b, axis=-1)
                                                - lengths[bar.id]))))
    return worst


def test_presets_every_route_and_the_generic_one(sync: Client) -> None:
    infos = {p.name: p for p in sync.list_presets()}
    routes = preset_routes()
    assert set(routes.values()) == set(infos)
    for op, name in routes.items():
        own = getattr(sync, snake(op))()
        assert own == sync.get_preset(name)
        assert own.dimension == infos[name].dimension
        raw = sync.http.get(f"/v1/presets/{name}").json()
        assert own == Linkage.from_json(raw) and own.to_json()["vertices"] == raw["vertices"]
    four = sync.get_preset_four_bar(L2=1.2, theta=0.5)
    assert four.lengths()["L2"] == pytest.approx(1.2, abs=1e-12)


def test_health_and_metrics(sync: Client) -> None:
    health = sync.get_health()
    assert health.status == "ok" and health.version == OPENAPI["info"]["version"]
    client_project = tomllib.loads((ROOT / "client" / "pyproject.toml").read_text())["project"]
    assert linkage_client.__version__ == client_project["version"] == health.version
    assert "linkage_requests_total" in sync.get_metrics()


def test_rigidity_zero_mode_is_a_flex_by_the_bar_equations(sync: Client) -> None:
    four = sync.get_preset_four_bar(theta=0.5)
    r = sync.analyse_rigidity(four)
    assert (r.rank, r.dof, r.critical) == (3, 1, False)
    (z,) = r.zero_modes
    pos = r.configuration
    assert z.array.shape == (4, 2) and pos.array.shape == (4, 2)
    for bar in four.bars:  # d/dt |p_a - p_b|^2 = 2 (p_a - p_b) . (z_a - z_b) = 0
        u, v = bar.ends
        assert abs(np.dot(pos[u] - pos[v], z[u] - z[v])) < 1e-12
    assert np.linalg.norm(z.array) == pytest.approx(1.0)
    assert np.all(z["P1"] == 0) and np.all(z["P2"] == 0)
    assert r.tolerances.rank_rtol == 1e-8


def test_second_order_at_the_readme_branch_point(sync: Client) -> None:
    body = {"vertices": [{"id": "P1", "position": [0, 0], "fixed": True},
                         {"id": "P2", "position": [1, 0], "fixed": True},
                         {"id": "A", "position": [-1, 0]}, {"id": "B", "position": [0, 0]}],
            "bars": [{"id": "L1", "ends": ["P1", "A"]}, {"id": "L2", "ends": ["A", "B"]},
                     {"id": "L3", "ends": ["P2", "B"]}]}
    r = sync.analyse_second_order(body)
    assert r.kind == "branch" and r.critical and len(r.tangents) == 2
    assert r.q_eigenvalues is not None and r.q_eigenvalues[0] * r.q_eigenvalues[1] < 0
    assert r.self_stress is not None and np.allclose(np.abs(r.self_stress.array), 3 ** -0.5)
    # sigma J = 0: the stressed bars' forces balance at each free vertex
    pos = Linkage.from_json(body).positions
    for vid in ("A", "B"):
        force = sum(r.self_stress[b["id"]] * (pos[vid] - pos[next(e for e in b["ends"]
                                                                  if e != vid)])
                    for b in body["bars"] if vid in b["ends"])
        assert np.allclose(force, 0, atol=1e-12)


def test_critical_points_of_the_equilateral_four_bar(sync: Client) -> None:
    r = sync.find_critical_points(sync.get_preset_four_bar(), options=FAST)
    assert [cp.kind for cp in r.critical_points] == ["branch"] * 3  # the paper's Fig. 1
    for cp in r.critical_points:  # all joints on a line: every vertex has y = 0
        assert np.allclose(cp.configuration.array[:, 1], 0, atol=1e-8)
    assert r.search.complete


def test_configuration_space_compact_and_default_agree_and_keep_the_lengths(
        sync: Client) -> None:
    four = sync.get_preset_four_bar(L2=0.9)  # a double rocker: two components
    compact = sync.explore_configuration_space(four, options=FAST)
    plain = sync.explore_configuration_space(four, options=FAST, compact=False)
    assert compact.raw["components"][0]["positions"]["dtype"] == "<f8"
    assert len(compact.components) == len(plain.components) == 2
    for c, p in zip(compact.components, plain.components, strict=True):
        assert c.positions.ids == p.positions.ids == four.vertex_ids
        assert np.array_equal(c.positions.array, p.positions.array)  # bit for bit
        assert np.array_equal(c.angles.array, p.angles.array) and c.angles.ids == ("L1", "L3")
        n = c.positions.array.shape[0]
        assert c.positions.array.shape == (n, 4, 2) and c.angles.array.shape == (n, 2)
        assert bar_residual(four, c.positions) < 1e-8
        assert c.winding == {"L1": 0, "L3": 0}


def test_splitting_signs_flip_with_the_perturbation(sync: Client) -> None:
    four = sync.get_preset_four_bar()
    up = sync.predict_splitting(four, {"L2": 1e-3}, options=FAST)
    down = sync.predict_splitting(four, {"L2": -1e-3}, options=FAST)
    assert len(up.branch_points) == 3
    for a, b in zip(up.branch_points, down.branch_points, strict=True):
        assert a.index == b.index and a.sign == -b.sign
        assert abs(a.delta - a.delta_linear) < 0.01 * abs(a.delta_linear)


def test_robustness_margin_is_the_closed_form_distance(sync: Client) -> None:
    four = sync.get_preset_four_bar(L2=1.2)
    r = sync.compute_robustness_margin(four)
    # the critical lengths are the signed sums a +- L1 +- L2 +- L3 = 0 with a pinned: a plane
    # in the three adjustable lengths at distance |sum| / sqrt(3)
    assert r.margin == pytest.approx(grashof_critical_gap([1, 1, 1.2, 1]) / math.sqrt(3),
                                     abs=1e-9)
    assert r.success and r.method == "closed-form"
    near = [r.nearest[b] for b in ("L1", "L2", "L3")]
    assert grashof_critical_gap([1, *near]) < 1e-9


def test_critical_values_lie_on_the_grashof_lines(sync: Client) -> None:
    four = sync.get_preset_four_bar(L2=1.2)
    axes = [{"bar": "L2", "min": 0.3, "max": 2.2}, {"bar": "L3", "min": 0.3, "max": 2.2}]
    r = sync.map_critical_values(four, axes, options={"resolution": 16, "seeds_per_axis": 3})
    assert r.curves and all(c.ndim == 2 and c.shape[1] == 2 for c in r.curves)
    for curve in r.curves:
        assert all(grashof_critical_gap([1, 1, l2, l3]) < 1e-6 for l2, l3 in curve)
    assert {region.components for region in r.regions} == {1, 2}


def test_design_splitting_is_verified_by_retracing(sync: Client) -> None:
    rotor = sync.get_preset_three_rotor()
    r = sync.design_splitting(rotor, [{"branch_point": 0, "sign": 1}], ["r1", "L1", "L2"],
                              options=FAST)
    assert r.feasible and r.verified
    assert set(r.perturbation) == {"r1", "L1", "L2"}
    assert r.predicted[0].connects == r.predicted[0].traced_connects


def svg_root(text: str) -> ET.Element:
    root = ET.fromstring(text)
    assert root.tag == "{http://www.w3.org/2000/svg}svg"
    return root


def test_figures_are_svg_documents(sync: Client) -> None:
    four = sync.get_preset_four_bar()
    svg_root(sync.draw_linkage(four, show=["zero_modes"]))
    svg_root(sync.draw_configuration_space(four, axes=["L1", "L3"], options=FAST))
    svg_root(sync.draw_splitting(four, {"L2": 1e-3}, options=FAST))
    svg_root(sync.draw_critical_values(
        sync.get_preset_four_bar(L2=1.2),
        [{"bar": "L2", "min": 0.4, "max": 2.5}, {"bar": "L3", "min": 0.4, "max": 2.5}],
        options={"resolution": 12, "seeds_per_axis": 2}))


def test_figures_in_a_chosen_format(sync: Client, aio: Any) -> None:
    """``draw``: any figure in any format, its bytes (each format opened by its reader in
    tests/service/test_figure_formats.py; here: that the client asks for and returns them)."""
    four = sync.get_preset_four_bar(L2=1.2)
    png = sync.draw("linkage", {"linkage": four, "show": ["zero_modes"]}, format="png", dpi=40)
    assert png[:8] == b"\x89PNG\r\n\x1a\n"
    width = int.from_bytes(png[16:20], "big")
    assert abs(width - 6.4 * 40) <= 1  # the linkage figure is 6.4 in wide
    assert sync.draw("linkage", {"linkage": four}, format="pdf").startswith(b"%PDF-")
    dxf = sync.draw("linkage", {"linkage": four}, format="dxf")
    assert b"LINKAGE_TOPOLOGY" in dxf
    client, loop = aio
    tikz = loop.run(client.draw("configuration-space", {"linkage": four, "options": FAST},
                                format="tikz"))
    assert b"\\begin{tikzpicture}" in tikz
    svg_root(loop.run(client.draw("linkage", {"linkage": four})).decode("utf-8"))
    with pytest.raises(ProblemError) as err:  # offered for the linkage only
        sync.draw("splitting", {"linkage": four, "perturbation": {"L2": 1e-3}}, format="dxf")
    assert err.value.status == 422 and err.value.errors[0].loc == ("body", "format")
    with pytest.raises(ValueError, match="no figure format 'gif'"):
        sync.draw("linkage", {"linkage": four}, format="gif")
    with pytest.raises(ValueError, match="no figure named"):
        sync.draw("linkages", {"linkage": four})


def test_job_routes_answer_without_a_cluster(sync: Client) -> None:
    """The job operations whose answers need no Dask worker (the jobs themselves run in
    tests/client/test_jobs.py): the list, and the problems of unknown jobs and bad bodies."""
    ops = {o.operation: o.request for o in sync.list_job_operations()}
    assert ops["analysis/configuration-space"] == "SpaceRequest" and "sweeps" in ops
    for call in (sync.get_job, sync.cancel_job, sync.get_job_result):
        with pytest.raises(ProblemError) as err:
            call("nope")
        assert err.value.status == 404 and err.value.kind == "unknown-job"
    with pytest.raises(ProblemError) as err:
        sync.create_job("analysis/nope", {})
    assert err.value.status == 422 and err.value.errors[0].loc == ("body", "operation")
    with pytest.raises(ProblemError) as err:
        sync.create_sweep(preset="four-bar", grid={"L9": {"min": 1, "max": 2, "steps": 2}})
    assert err.value.status == 422 and err.value.errors[0].loc == ("body", "grid", "L9")


def test_async_client_answers_as_the_sync_one(sync: Client, aio: Any) -> None:
    client, loop = aio
    four = loop.run(client.get_preset_four_bar(theta=0.5))
    assert four == sync.get_preset_four_bar(theta=0.5)
    assert loop.run(client.get_health()) == sync.get_health()
    a = loop.run(client.analyse_rigidity(four))
    b = sync.analyse_rigidity(four)
    assert np.array_equal(a.zero_modes[0].array, b.zero_modes[0].array)
    space = loop.run(client.explore_configuration_space(four, options=FAST))
    assert bar_residual(four, space.components[0].positions) < 1e-8
    presets = loop.run(client.list_presets())
    assert [p.name for p in presets] == [p.name for p in sync.list_presets()]
    with pytest.raises(ProblemError) as err:
        loop.run(client.get_preset("nope"))
    assert err.value.status == 404 and err.value.kind == "unknown-preset"


EMPTY: dict[str, Any] = {"vertices": []}  # refused at once: 422 naming body.linkage.vertices


def calls() -> dict[str, Any]:
    """For each operationId, a call of its client method (cheap: invalid bodies where the
    answer would cost a search; the problem still comes from that operation)."""
    table: dict[str, Any] = {op: (lambda c, op=op: getattr(c, snake(op))())
                             for op in preset_routes()}
    table.update({
        "getHealth": lambda c: c.get_health(),
        "getHealthLive": lambda c: c.get_health_live(),
        "getHealthReady": lambda c: c.get_health_ready(),
        "listJobs": lambda c: c.list_jobs(),
        "getMetrics": lambda c: c.get_metrics(),
        "listPresets": lambda c: c.list_presets(),
        "getPreset": lambda c: c.get_preset("nope"),  # named presets have routes of their own
        "analyseRigidity": lambda c: c.analyse_rigidity(EMPTY),
        "analyseSecondOrder": lambda c: c.analyse_second_order(EMPTY),
        "findCriticalPoints": lambda c: c.find_critical_points(EMPTY),
        "exploreConfigurationSpace": lambda c: c.explore_configuration_space(EMPTY),
        "predictSplitting": lambda c: c.predict_splitting(EMPTY, {"L2": 1e-3}),
        "computeRobustnessMargin": lambda c: c.compute_robustness_margin(EMPTY),
        "mapCriticalValues": lambda c: c.map_critical_values(EMPTY, []),
        "designSplitting": lambda c: c.design_splitting(EMPTY, [], []),
        "drawLinkage": lambda c: c.draw_linkage(EMPTY),
        "drawConfigurationSpace": lambda c: c.draw_configuration_space(EMPTY),
        "drawCriticalValues": lambda c: c.draw_critical_values(EMPTY, []),
        "drawSplitting": lambda c: c.draw_splitting(EMPTY, {}),
        "listJobOperations": lambda c: c.list_job_operations(),
        "createJob": lambda c: c.create_job("analysis/rigidity", {"linkage": EMPTY}),
        "getJob": lambda c: c.get_job("nope"),
        "cancelJob": lambda c: c.cancel_job("nope"),
        "getJobResult": lambda c: c.get_job_result("nope"),
        "createSweep": lambda c: c.create_sweep(linkage=EMPTY, grid={"L": {"min": 1, "max": 2,
                                                                          "steps": 2}}),
    })
    return table


def test_each_method_calls_its_own_operation(sync: Client, recorder: Any) -> None:
    table = calls()
    assert set(table) == set(operations().values())
    for op, call in table.items():
        recorder.seen.clear()
        try:
            call(sync)
        except ProblemError as err:
            if op == "getHealthReady":  # (this app's pool is not started: not ready, a 503)
                assert err.status == 503 and err.kind == "not-ready", (op, err)
            else:
                assert 400 <= err.status < 500 and err.kind in {
                    "validation-error", "unknown-job", "unknown-preset"}, (op, err)
        assert recorder.seen == {op}, (op, recorder.seen)
