"""The figure endpoints: SVG that parses, with as many drawn things as the JSON answers hold."""

from __future__ import annotations

import math
import re
import xml.etree.ElementTree as ET
from collections import Counter
from typing import Any

import numpy as np
import pytest

SVG_NS = "{http://www.w3.org/2000/svg}"


def svg_ids(response: Any) -> list[str]:
    assert response.status_code == 200, response.text
    assert response.headers["content-type"] == "image/svg+xml"
    root = ET.fromstring(response.content)  # valid XML, an <svg> document
    assert root.tag == f"{SVG_NS}svg"
    ids = [el.get("id", "") for el in root.iter()]
    named = [i for i in ids if i]
    assert len(named) == len(set(named)), "SVG ids must be unique"
    return ids


def with_prefix(ids: list[str], prefix: str) -> list[str]:
    return [i for i in ids if i.startswith(prefix)]


def preset(client: Any, name: str, **params: float) -> dict[str, Any]:
    r = client.get(f"/v1/presets/{name}", params=params)
    assert r.status_code == 200, r.text
    linkage: dict[str, Any] = r.json()
    return linkage


def assert_problem(response: Any, status: int, loc_prefix: list[Any]) -> None:
    assert response.status_code == status, response.text
    assert response.headers["content-type"].startswith("application/problem+json")
    problem = response.json()
    assert problem["status"] == status and problem["title"] and problem["detail"]
    assert problem["errors"][0]["loc"][: len(loc_prefix)] == loc_prefix


# -- linkage -------------------------------------------------------------------------------


def test_linkage_figure_draws_pins_joints_bars_and_zero_modes(client: Any) -> None:
    linkage = preset(client, "four-bar", L2=1.2)
    ids = svg_ids(client.post("/v1/figures/linkage",
                              json={"linkage": linkage, "show": ["zero_modes"]}))
    assert len(with_prefix(ids, "bar-")) == len(linkage["bars"])
    assert len(with_prefix(ids, "pin-")) == 2
    assert len(with_prefix(ids, "vertex-")) == 2
    rig = client.post("/v1/analysis/rigidity", json={"linkage": linkage}).json()
    assert len(with_prefix(ids, "zero-mode-")) == len(rig["zero_modes"]) == 1
    assert with_prefix(ids, "tangent-") == []


def test_linkage_figure_at_a_branch_point_draws_tangents(client: Any) -> None:
    # theta = pi puts the equilateral four-bar on a branch point (A, P1, B, P2 collinear)
    linkage = preset(client, "four-bar", theta=math.pi)
    ids = svg_ids(client.post("/v1/figures/linkage",
                              json={"linkage": linkage, "show": ["tangents", "self_stress"]}))
    second = client.post("/v1/analysis/second-order", json={"linkage": linkage}).json()
    assert second["kind"] == "branch"
    assert len(with_prefix(ids, "tangent-")) == len(second["tangents"]) == 2
    assert len(with_prefix(ids, "bar-")) == 3


def test_linkage_figure_draws_a_slider_with_its_axis(client: Any) -> None:
    linkage = preset(client, "gated-kl-chain", n=4, gate=2)
    sliders = [v for v in linkage["vertices"] if isinstance(v["fixed"], list)]
    assert len(sliders) == 1
    ids = svg_ids(client.post("/v1/figures/linkage", json={"linkage": linkage}))
    assert len(with_prefix(ids, "slider-axis-")) == 1
    assert len([i for i in ids if re.fullmatch(r"slider-\d+", i)]) == 1
    assert len(with_prefix(ids, "bar-")) == len(linkage["bars"])


def test_a_100_rotor_linkage_is_one_collection_of_bars(client: Any) -> None:
    """199 bars and 200 joints: the bars one LineCollection (its segments the bars' ends as
    the answer places them), the joints one marker artist per kind, no text per element (the
    figure says so): a handful of artists, not 400 (counted on the drawn Figure); the SVG has
    the collection's id and no per-bar ids."""
    from matplotlib.collections import LineCollection

    from service.config import Settings
    from service.figure_drawing import _draw_linkage
    from service.jobs import rigidity
    from service.schemas.common import AnalysisRequest, Linkage

    linkage = preset(client, "kl-chain", n=100)
    assert len(linkage["bars"]) == 199 and len(linkage["vertices"]) == 200
    model = Linkage.model_validate(linkage)
    ans = rigidity(AnalysisRequest(linkage=model), Settings.from_env())
    fig = _draw_linkage(model, ans, [])
    ax = fig.axes[0]
    assert len(ax.collections) == 1 and isinstance(ax.collections[0], LineCollection)
    segments = ax.collections[0].get_segments()
    assert len(segments) == 199
    at = {v: ans.configuration[v][:2] for v in ans.configuration}
    for bar, seg in zip(linkage["bars"], segments, strict=True):
        assert np.allclose(seg, [at[bar["ends"][0]], at[bar["ends"][1]]])
    assert len(ax.lines) == 2  # pins, joints
    assert len(ax.texts) == 0 and "drawn without their names" in ax.get_title()
    ids = svg_ids(client.post("/v1/figures/linkage", json={"linkage": linkage}))
    assert {"bars", "pins", "vertices"} <= set(ids)
    assert with_prefix(ids, "bar-") == [] and with_prefix(ids, "pin-") == []


# -- configuration space ---------------------------------------------------------------------


def test_equilateral_four_bar_has_three_branch_points_marked(client: Any) -> None:
    linkage = preset(client, "four-bar")
    ids = svg_ids(client.post("/v1/figures/configuration-space", json={"linkage": linkage}))
    answer = client.post("/v1/analysis/configuration-space", json={"linkage": linkage}).json()
    assert len(with_prefix(ids, "critical-branch-")) == 3
    assert len(with_prefix(ids, "critical-")) == len(answer["critical_points"]) == 3
    components = {re.match(r"component-(\d+)-", i).group(1)  # type: ignore[union-attr]
                  for i in with_prefix(ids, "component-")}
    assert len(components) == len(answer["components"])
    # each segment between critical points is labelled once on its piece of the curve
    assert len(with_prefix(ids, "segment-")) == len(answer["segments"]) == 6


@pytest.mark.parametrize("lengths", [{"L2": 1.2}, {"L1": 0.6, "L2": 1.4, "L3": 1.2}])
def test_components_match_the_json_answer(client: Any, lengths: dict[str, float]) -> None:
    linkage = preset(client, "four-bar", **lengths)
    ids = svg_ids(client.post("/v1/figures/configuration-space",
                              json={"linkage": linkage, "axes": ["L3", "L1"]}))
    answer = client.post("/v1/analysis/configuration-space", json={"linkage": linkage}).json()
    components = {i.split("-")[1] for i in with_prefix(ids, "component-")}
    assert len(components) == len(answer["components"]) >= 1
    assert with_prefix(ids, "critical-") == [] == answer["critical_points"]


def test_configuration_space_figure_refuses_an_axis_that_is_no_rotor(client: Any) -> None:
    linkage = preset(client, "four-bar")
    r = client.post("/v1/figures/configuration-space",
                    json={"linkage": linkage, "axes": ["L2", "L1"]})
    assert_problem(r, 422, ["body", "axes", 0])
    assert "rotor" in r.json()["detail"]
    r = client.post("/v1/figures/configuration-space",
                    json={"linkage": linkage, "axes": ["L1", "L1"]})
    assert_problem(r, 422, ["body", "axes", 1])


def test_configuration_space_figure_needs_two_rotors(client: Any) -> None:
    linkage = {"vertices": [{"id": "P", "position": [0, 0], "fixed": True},
                            {"id": "A", "position": [1, 0]}],
               "bars": [{"id": "r", "ends": ["P", "A"]}]}
    r = client.post("/v1/figures/configuration-space", json={"linkage": linkage})
    assert_problem(r, 422, ["body", "linkage", "bars"])


def test_configuration_space_figure_of_a_3d_linkage_is_a_422_not_a_500(client: Any) -> None:
    """Rotor angles are planar: a 3D one-degree-of-freedom linkage (the hinged rotor chain)
    was a 500 (KeyError) here; it is a problem naming the dimension."""
    linkage = client.get("/v1/presets/rotor-chain-3d").json()
    r = client.post("/v1/figures/configuration-space", json={"linkage": linkage})
    assert_problem(r, 422, ["body", "linkage", "dimension"])
    assert "3D" in r.json()["detail"]


# -- critical values and splitting ---------------------------------------------------------


def svg_text(response: Any) -> str:
    root = ET.fromstring(response.content)
    return " ".join("".join(el.itertext()) for el in root.iter(f"{SVG_NS}text"))


def test_a_map_of_an_incomplete_analysis_says_so(client: Any) -> None:
    """A 3D two-rotor chain's map (no closed form: traced) with a tenth of a second: the JSON
    answer is incomplete (time), and the figure of the same body says so in its title; a
    complete map does not. (The three-rotor's map is closed form now, complete at once.)"""
    linkage = preset(client, "rotor-chain-3d", n=2)
    body = {"linkage": linkage, "options": {"time_budget_s": 0.1},
            "axes": [{"bar": "r0b", "min": 1.3, "max": 1.9}, {"bar": "l0", "min": 1.2, "max": 1.8}]}
    answer = client.post("/v1/analysis/critical-values", json=body).json()
    assert answer["search"]["complete"] is False and answer["search"]["reason"] == "time"
    r = client.post("/v1/figures/critical-values", json=body)
    assert r.status_code == 200
    assert "incomplete (time)" in svg_text(r)
    four_bar = {"linkage": preset(client, "four-bar"),
                "axes": [{"bar": "L2", "min": 0.8, "max": 1.2},
                         {"bar": "L3", "min": 0.8, "max": 1.2}]}
    assert "incomplete" not in svg_text(client.post("/v1/figures/critical-values",
                                                    json=four_bar))


@pytest.mark.slow
def test_critical_values_figure_draws_every_curve_and_region(client: Any) -> None:
    body = {"linkage": preset(client, "four-bar"),
            "axes": [{"bar": "L2", "min": 0.4, "max": 2.5}, {"bar": "L3", "min": 0.4, "max": 2.5}]}
    ids = svg_ids(client.post("/v1/figures/critical-values", json=body))
    answer = client.post("/v1/analysis/critical-values", json=body).json()
    assert len(with_prefix(ids, "cv-curve-")) == len(answer["curves"]) >= 2
    drawn = Counter(int(i.rsplit("-", 1)[1]) for i in with_prefix(ids, "region-"))
    assert drawn == Counter(r["components"] for r in answer["regions"])
    assert "cv-regions" in ids
    assert "current-lengths" in ids  # (1, 1) lies in the box


def test_gate_map_figure_labels_regions_as_figure_5b(client: Any) -> None:
    """The gated chain's (L2, D) map: every region drawn with its count, the gate's tau signs
    (Eq. 16 at its sample, computed here) and gated or not; a configuration-space figure's
    title gives the rules' total beside the components traced."""
    from service.figure_drawing import _components_text, region_text
    from service.schemas.critical_values import RegionOut
    from service.schemas.space import SpaceResponse

    body = {"linkage": preset(client, "gated-kl-chain", n=3, gate=1),
            "axes": [{"bar": "L2", "min": 0.5, "max": 5.0}, {"bar": "D", "min": 0.5, "max": 5.0}],
            "options": {"resolution": 16}}
    ids = svg_ids(client.post("/v1/figures/critical-values", json=body))
    answer = client.post("/v1/analysis/critical-values", json=body).json()
    drawn = Counter(int(i.rsplit("-", 1)[1]) for i in with_prefix(ids, "region-"))
    assert drawn == Counter(r["components"] for r in answer["regions"])
    for r in answer["regions"]:
        l2, d = r["point"]
        taus = (d - 1.5 + l2 - 2.0, d - 1.5 - l2 + 2.0, l2 + 2.0 - d - 1.5)
        signs = "(" + ",".join("+" if t > 0 else "-" for t in taus) + ")"
        gate = "" if r["components"] == 0 else \
            "\nungated" if signs in ("(+,+,+)", "(-,-,+)") else "\ngated"
        assert region_text(RegionOut.model_validate(r)) == f"{r['components']}\n{signs}{gate}"
    chain = preset(client, "kl-chain", n=10)
    space = client.post("/v1/analysis/configuration-space", json={"linkage": chain}).json()
    traced = len(space["components"])
    assert traced < 512 and _components_text(SpaceResponse.model_validate(space)) == \
        f"512 components ({traced} traced)"


def test_splitting_figure_joins_the_rays_the_answer_says(client: Any) -> None:
    body = {"linkage": preset(client, "four-bar"), "perturbation": {"L2": 0.01}}
    ids = svg_ids(client.post("/v1/figures/splitting", json=body))
    answer = client.post("/v1/analysis/splitting", json=body).json()
    assert len(answer["branch_points"]) == 3
    assert len(with_prefix(ids, "ray-")) == 4 * len(answer["branch_points"])
    for b in answer["branch_points"]:
        # the figure finds the joined rays from where each drawn branch of the conic runs
        drawn = sorted([int(i.split("-")[2]), int(i.split("-")[3])]
                       for i in with_prefix(ids, f"split-{b['index']}-"))
        assert drawn == sorted(b["connects"])


def test_splitting_figure_draws_the_panels_that_fit_and_names_those_left_out(client: Any
                                                                             ) -> None:
    from service import figures, jobs
    from service.config import Settings
    from service.figure_splitting import _draw_splitting, panels_in_time
    from service.schemas.figures import SplittingFigureRequest

    assert panels_in_time(0.0) == 1 and panels_in_time(100.0) > panels_in_time(1.0)
    body = SplittingFigureRequest.model_validate(
        {"linkage": preset(client, "four-bar"), "perturbation": {"L2": 0.01}})
    ans, points = jobs.splitting_with_points(body, Settings.from_env())
    assert len(ans.branch_points) == 3
    for panels, left_out in ((1, 2), (3, 0), (None, 0)):
        root = ET.fromstring(figures._render(body, _draw_splitting, body, ans, points, panels))
        ids = [el.get("id", "") for el in root.iter()]
        drawn = ans.branch_points[:3 - left_out]
        assert sorted(with_prefix(ids, "ray-")) == sorted(
            f"ray-{b.index}-{r}" for b in drawn for r in range(4))
        assert with_prefix(ids, "panels-left-out-") == (
            [f"panels-left-out-{left_out}"] if left_out else [])


# -- bad input -------------------------------------------------------------------------------


@pytest.mark.parametrize("path", ["linkage", "configuration-space", "critical-values",
                                  "splitting"])
def test_figure_without_a_linkage_is_a_problem(client: Any, path: str) -> None:
    r = client.post(f"/v1/figures/{path}", json={})
    assert_problem(r, 422, ["body", "linkage"])
    assert client.get("/health").status_code == 200


def test_figure_problems_name_the_field(client: Any) -> None:
    linkage = preset(client, "four-bar")
    r = client.post("/v1/figures/linkage", json={"linkage": linkage, "show": ["colours"]})
    assert_problem(r, 422, ["body", "show", 0])
    r = client.post("/v1/figures/splitting",
                    json={"linkage": linkage, "perturbation": {"L2": -5.0}})
    assert_problem(r, 422, ["body", "perturbation", "L2"])
    r = client.post("/v1/figures/critical-values",
                    json={"linkage": linkage, "axes": [{"bar": "L2", "min": 0.5, "max": 1.5}]})
    assert_problem(r, 422, ["body", "axes"])
    broken = {**linkage, "bars": [{"id": "L1", "ends": ["P1", "nowhere"]}]}
    r = client.post("/v1/figures/linkage", json={"linkage": broken})
    assert_problem(r, 422, ["body", "linkage", "bars", 0, "ends", 1])


def test_a_3d_linkage_is_drawn_in_its_x_y_projection(client: Any) -> None:
    linkage = {"dimension": 3, "vertices": [
        {"id": "P", "position": [0, 0, 0], "fixed": True},
        {"id": "Q", "position": [2, 0, 0], "fixed": True},
        {"id": "A", "position": [1, 0, 1]}],
        "bars": [{"id": "a", "ends": ["P", "A"]}, {"id": "b", "ends": ["Q", "A"]}]}
    ids = svg_ids(client.post("/v1/figures/linkage",
                              json={"linkage": linkage, "show": ["zero_modes"]}))
    assert len(with_prefix(ids, "bar-")) == 2
    assert len(with_prefix(ids, "zero-mode-")) == 1  # A turns about the axis PQ


def test_figures_run_under_the_time_limit() -> None:
    from service.config import Settings
    from service.main import create_app
    from tests.conftest import ApiClient

    app = create_app(Settings.from_env().replace(time_limit_s=0.05, workers=1))
    c = ApiClient(app)
    try:
        linkage = preset(c, "three-rotor")
        # a fine step: tens of thousands of points, far beyond 0.05 s whatever the machine (the
        # default step's figure could finish within it once workers start with the kernels)
        r = c.post("/v1/figures/configuration-space",
                   json={"linkage": linkage, "options": {"step_max": 0.0005}})
        assert r.status_code == 504, r.text
        assert r.headers["content-type"].startswith("application/problem+json")
        assert r.json()["type"] == "/problems/time-limit"
        assert c.get("/health").status_code == 200
    finally:
        c.close()
        app.state.engine_pool.close()


def test_the_figure_media_type_of_jobs_is_the_routes() -> None:
    """service.operations names the SVG media type itself (matplotlib is imported only to
    draw): it is the one the figure routes answer with."""
    from service import figures, operations

    assert operations.SVG == figures.SVG
    assert {op.media_type for name, op in operations.OPERATIONS.items()
            if name.startswith("figures/")} == {figures.SVG}
