"""The configuration-space figure of two-degree-of-freedom linkages (service/figure_surface.py):
what it draws is counted against the JSON answer of /v1/analysis/configuration-space, with the
bar angles and the cut at +-pi recomputed here."""

from __future__ import annotations

import xml.etree.ElementTree as ET
from typing import Any

import numpy as np
import pytest

from tests.service.test_figures import SVG_NS, svg_ids
from tests.service.test_space import pentagon_body

FAST = {"surface_step": 0.5, "random_starts": 2}


def answer_and_figure(client: Any, body: dict, fmt: str = "svg") -> tuple[dict, Any]:
    ans = client.post("/v1/analysis/configuration-space", json=body)
    assert ans.status_code == 200, ans.text
    fig = client.post("/v1/figures/configuration-space", json={**body, "format": fmt})
    return ans.json(), fig


def drawn_triangles(surface: dict, bars: list[tuple[str, str]]) -> int:
    """Triangles whose three direction angles of each axis bar stay within pi of each other
    (the rest cross the cut of the angle torus)."""
    theta = np.stack([np.arctan2(*(np.asarray(surface["positions"][b])
                                   - np.asarray(surface["positions"][a])).T[::-1])
                      for a, b in bars], axis=1)
    t = theta[np.asarray(surface["triangles"])]
    return int(((t.max(axis=1) - t.min(axis=1)) <= np.pi).all(axis=1).sum())


def test_the_pentagon_surface_is_drawn_with_its_critical_points(client: Any) -> None:
    body = {"linkage": pentagon_body(), "options": FAST}
    ans, fig = answer_and_figure(client, body)
    ids = svg_ids(fig)
    (surf,) = ans["surfaces"]
    assert surf["genus"] == 4
    # default axes: the first three bars with a moving end (P1-A, A-B, B-C)
    want = drawn_triangles(surf, [("P1", "A"), ("A", "B"), ("B", "C")])
    assert 0.8 * len(surf["triangles"]) < want <= len(surf["triangles"])
    root = ET.fromstring(fig.content)
    (group,) = [el for el in root.iter() if el.get("id") == "surface-0"]
    assert len(list(group.iter(f"{SVG_NS}path"))) == want
    heights = ans["height_critical_points"]
    assert len(heights) == 12  # 2 + 8 + 2 critical points of a Morse height on genus 4, at least
    assert {f"height-critical-{i}" for i in range(len(heights))} <= set(ids)


def test_cones_at_critical_lengths_are_marked(client: Any) -> None:
    body = {"linkage": pentagon_body((2.0, 1.0, 1.0, 1.0, 1.0)), "options": FAST}
    ans, fig = answer_and_figure(client, body)
    ids = set(svg_ids(fig))
    assert ans["critical_points"]
    for cp in ans["critical_points"]:
        assert f"critical-{cp['kind']}-{cp['index']}" in ids


def test_chosen_axes_and_png(client: Any) -> None:
    body = {"linkage": pentagon_body(), "options": FAST, "axes": ["b2", "b3", "b4"],
            "format": "png"}
    fig = client.post("/v1/figures/configuration-space", json=body)
    assert fig.status_code == 200 and fig.headers["content-type"] == "image/png"
    assert fig.content[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.parametrize(("axes", "loc"), [
    (["b1", "b2"], ["body", "axes"]),
    (["b1", "b2", "b0"], ["body", "axes", 2]),  # b0 joins two pinned vertices
    (["b1", "b2", "nope"], ["body", "axes", 2]),
    (["b1", "b1", "b2"], ["body", "axes"]),
])
def test_bad_axes_are_problems_naming_them(client: Any, axes: list[str], loc: list) -> None:
    r = client.post("/v1/figures/configuration-space",
                    json={"linkage": pentagon_body(), "axes": axes})
    assert r.status_code == 422, r.text
    assert r.headers["content-type"].startswith("application/problem+json")
    assert r.json()["errors"][0]["loc"] == loc


def test_tikz_of_a_surface_is_refused_naming_the_format(client: Any) -> None:
    r = client.post("/v1/figures/configuration-space",
                    json={"linkage": pentagon_body(), "format": "tikz"})
    assert r.status_code == 422, r.text
    assert r.json()["errors"][0]["loc"] == ["body", "format"]


def test_the_splitting_figure_of_a_surface_is_refused_before_any_work(client: Any) -> None:
    r = client.post("/v1/figures/splitting",
                    json={"linkage": pentagon_body((2.0, 1.0, 1.0, 1.0, 1.0)),
                          "perturbation": {"b2": 0.05}})
    assert r.status_code == 422, r.text
    assert r.json()["errors"][0]["loc"] == ["body", "linkage"]
    assert "/v1/analysis/splitting" in r.json()["errors"][0]["msg"]
