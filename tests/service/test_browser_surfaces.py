"""Surfaces in the viewer's 3D view (issue 27), in Debian's chromium against a real uvicorn on
loopback: a planar pentagon with one bar pinned (two degrees of freedom) pasted, its
configuration space drawn as the service's triangulated surface (every mesh vertex where the
test's own rotation and projection put it, every triangle but those across an angle's cut),
rotated, a mesh vertex clicked and the linkage loaded there (its lengths kept, its readout the
API's); dragged; and a pentagon that cannot close, whose 422 the status line shows. A screenshot
of each panel is kept under tests/artifacts/."""

from __future__ import annotations

import json
import math
from typing import Any

import numpy as np
import pytest

from tests.service.test_browser import browser, data, wait_for
from tests.service.test_browser import pytestmark as browser_marks
from tests.service.test_viewer import (
    assert_stayed_local,
    base_url,
    drag,
    element_shot,
    js,
    post,
    text,
)

__all__ = ["base_url", "browser"]  # the fixtures, shared with test_viewer

# browser and process tests, skipped without Debian's chromium (the marks of test_browser)
pytestmark = browser_marks


def pentagon(lengths: tuple[float, ...] = (1.0, 1.0, 1.0, 1.0, 1.0)) -> dict[str, Any]:
    """A planar pentagon P0 P1 A B C with the bar P0 P1 pinned, near a convex one (the service
    projects it onto the lengths)."""
    pts = [[0.0, 0.0], [lengths[0], 0.0]]
    th = 0.0
    for k in range(3):
        th += 2 * math.pi / 5
        pts.append([pts[-1][0] + lengths[k + 1] * math.cos(th),
                    pts[-1][1] + lengths[k + 1] * math.sin(th)])
    ids = ["P0", "P1", "A", "B", "C"]
    ends = [("P0", "P1"), ("P1", "A"), ("A", "B"), ("B", "C"), ("C", "P0")]
    return {"dimension": 2,
            "vertices": [{"id": i, "position": p, "fixed": i in ("P0", "P1")}
                         for i, p in zip(ids, pts, strict=True)],
            "bars": [{"id": f"b{k}", "ends": list(e), "length": x}
                     for k, (e, x) in enumerate(zip(ends, lengths, strict=True))]}


def paste(driver: Any, base: str, linkage: dict[str, Any]) -> None:
    from selenium.webdriver.common.by import By

    driver.get(f"{base}/viewer/")
    wait_for(lambda: text(driver, "status") == "choose a preset or paste a linkage", 30,
             "the viewer")
    js(driver, "document.getElementById('paste').open = true;"
       "document.getElementById('linkage-json').value = arguments[0];", json.dumps(linkage))
    driver.find_element(By.ID, "use-linkage").click()


def received(driver: Any, path: str) -> tuple[dict[str, Any], dict[str, Any]]:
    """The last request to a path the page sent since the log was last read, and the service's
    answer to it as the browser received it."""
    sent = []
    for entry in driver.get_log("performance"):
        message = json.loads(entry["message"])["message"]
        params = message.get("params", {})
        request = params.get("request", {})
        if message["method"] == "Network.requestWillBeSent" and request.get(
                "url", "").endswith(path):
            sent.append((params["requestId"], json.loads(request.get("postData", "{}"))))
    request_id, body = sent[-1]
    answer = driver.execute_cdp_cmd("Network.getResponseBody", {"requestId": request_id})
    return body, json.loads(answer["body"])


def same_surfaces(base: str, body: dict[str, Any], answer: dict[str, Any]) -> None:
    """The same request sent again answers the same surfaces, unless either search was stopped
    by its clock (a mesh cut short by the deadline does not repeat itself)."""
    if answer["search"]["reason"] == "time":
        return
    again = post(base, "/v1/analysis/configuration-space", body)
    if again["search"]["reason"] != "time":
        assert [s["triangles"] for s in again["surfaces"]] == [
            s["triangles"] for s in answer["surfaces"]]


def shown_int(value: int | None) -> str:
    """A count as the surface list's data attributes carry it ('' for null: not known)."""
    return "" if value is None else str(value)


def projection(driver: Any) -> tuple[float, float, float, np.ndarray]:
    """The 3D view's canvas size and its rotation, from the yaw and pitch it shows: yaw about
    the vertical axis, then pitch about the horizontal one (the test's own matrices)."""
    width, height, yaw, pitch = js(driver, "const c = document.getElementById('view3d');"
                                   "return [c.width, c.height, view3.yaw, view3.pitch];")
    turn_yaw = np.array([[math.cos(yaw), 0, math.sin(yaw)], [0, 1, 0],
                         [-math.sin(yaw), 0, math.cos(yaw)]])
    turn_pitch = np.array([[1, 0, 0], [0, math.cos(pitch), -math.sin(pitch)],
                           [0, math.sin(pitch), math.cos(pitch)]])
    return width, height, 0.32 * min(width, height), turn_pitch @ turn_yaw


def mesh_coordinates(surf: dict[str, Any]) -> np.ndarray:
    """(n, 3): the angles of b1 (P1 -> A) and b4 (P0 -> C) and the x of B at each mesh vertex,
    each scaled to [-1, 1] as the view does (angles over [-pi, pi], x over its range)."""
    pos = {v: np.array(p) for v, p in surf["positions"].items()}
    a = np.arctan2(*(pos["A"] - pos["P1"]).T[::-1])
    c = np.arctan2(*(pos["C"] - pos["P0"]).T[::-1])
    x = pos["B"][:, 0]
    return np.column_stack([a / math.pi, c / math.pi, x])


def test_a_two_dof_space_is_drawn_as_its_surfaces(base_url: str, browser: Any) -> None:
    from selenium.webdriver.common.action_chains import ActionChains
    from selenium.webdriver.common.by import By
    from selenium.webdriver.common.keys import Keys

    linkage = pentagon()
    paste(browser, base_url, linkage)
    wait_for(lambda: data(browser, "view3d", "surfaces") not in (None, "0")
             and text(browser, "status") == "ready", 60, "the surfaces")
    body, api = received(browser, "/v1/analysis/configuration-space")
    assert body["linkage"] == linkage
    same_surfaces(base_url, body, api)
    (surf,) = api["surfaces"]
    # the topology as the service gives it
    (row,) = browser.find_elements(By.CSS_SELECTOR, "#surface-list li")
    assert row.get_attribute("data-genus") == shown_int(surf["genus"])
    assert row.get_attribute("data-euler") == shown_int(surf["euler"])
    assert f"{len(surf['triangles'])} triangles" in row.text
    if api["search"]["reason"] != "time":  # the whole mesh: the equilateral pentagon's space
        # has genus 4 (Farber and Schuetz: b1 = 8)
        assert surf["genus"] == 4 and surf["euler"] == -6 and "genus 4" in row.text
    assert text(browser, "space-caption").startswith("two degrees of freedom: 1 surface")
    # no map is asked: the maps trace curves, which needs one degree of freedom
    assert "one degree of freedom" in text(browser, "map-caption")
    chosen = [js(browser, f"return document.getElementById('d3-{a}').value;") for a in "xyz"]
    assert chosen == ["angle:b1", "angle:b4", "x:B:0"]

    # every mesh vertex drawn where the test's rotation and projection put it
    shown = json.loads(js(browser, "return JSON.stringify(state.space);"))
    assert shown["surfaces"][0]["triangles"] == surf["triangles"]
    u = mesh_coordinates(surf)
    lo, hi = u[:, 2].min(), u[:, 2].max()
    u[:, 2] = 2 * (u[:, 2] - lo) / (hi - lo) - 1
    width, height, scale, turn = projection(browser)
    q = u @ turn.T
    expected = np.column_stack([width / 2 + scale * q[:, 0], height / 2 - scale * q[:, 1]])
    drawn = js(browser, "return view3.projected.map((p) => [p.surface, p.index, p.x, p.y]);")
    assert len(drawn) == len(u) == int(data(browser, "view3d", "meshVertices") or -1)
    for s, i, x, y in drawn:
        assert s == 0 and math.dist((x, y), expected[i]) < 1e-6, i
    # every triangle but those across the cut of an angle (two of its corners more than pi
    # apart in b1's or b4's angle)
    tri = np.array(surf["triangles"])
    angles = u[:, :2][tri]  # (T, 3, 2)
    spread = np.abs(angles[:, :, None, :] - angles[:, None, :, :]).max(axis=(1, 2, 3))
    assert int(data(browser, "view3d", "triangles") or -1) == int((spread <= 1.0).sum())
    assert (spread > 1.0).sum() < 0.2 * len(tri)

    # rotated by a drag and by the keyboard
    canvas = browser.find_element(By.ID, "view3d")
    yaw, draws = data(browser, "view3d", "yaw"), int(data(browser, "view3d", "draws") or 0)
    ActionChains(browser).move_to_element(canvas).click_and_hold().move_by_offset(50, 15) \
        .release().perform()
    assert data(browser, "view3d", "yaw") != yaw
    pitch = data(browser, "view3d", "pitch")
    canvas.send_keys(Keys.ARROW_UP)
    assert data(browser, "view3d", "pitch") != pitch
    assert int(data(browser, "view3d", "draws") or 0) > draws

    # a click on the front-most mesh vertex loads the linkage there
    width, height, scale, turn = projection(browser)
    q = u @ turn.T
    front = int(np.argmax(q[:, 2]))
    at = (width / 2 + scale * q[front, 0], height / 2 - scale * q[front, 1])
    rect = js(browser, "const r = arguments[0].getBoundingClientRect();"
              "return [r.width, r.height];", canvas)
    k = rect[0] / width
    ActionChains(browser).move_to_element_with_offset(
        canvas, at[0] * k - rect[0] / 2, at[1] * k - rect[1] / 2).click().perform()
    wait_for(lambda: data(browser, "view3d", "picked"), 10, "the picked vertex")
    picked = json.loads(data(browser, "view3d", "picked") or "{}")
    i = picked["index"]
    assert picked["surface"] == 0
    # the vertex picked is within a few pixels of the click and not behind the one aimed at
    here = (width / 2 + scale * q[i, 0], height / 2 - scale * q[i, 1])
    assert math.dist(here, at) <= 6 + 1 and q[i, 2] >= q[front, 2] - 1e-9
    assert text(browser, "linkage-caption").endswith(f"surface 0, mesh vertex {i}")
    positions = js(browser, "return currentPositions();")
    for v, walk in surf["positions"].items():
        assert positions[v] == pytest.approx(walk[i], abs=1e-12)
    for bar in linkage["bars"]:  # the lengths kept there
        p, r = (np.array(positions[e]) for e in bar["ends"])
        assert np.linalg.norm(p - r) == pytest.approx(bar["length"], abs=1e-8)
    # the readout is the API's rigidity analysis of that configuration
    wait_for(lambda: data(browser, "readout", "dof"), 30, "the readout")
    there = {**linkage, "vertices": [{**v, "position": positions[v["id"]]}
                                     for v in linkage["vertices"]]}
    rigidity = post(base_url, "/v1/analysis/rigidity", {"linkage": there})
    wait_for(lambda: data(browser, "readout", "dof") == str(rigidity["dof"]), 10,
             "the readout of the picked configuration")
    assert rigidity["dof"] == 2 and data(browser, "readout", "rank") == str(rigidity["rank"])
    for panel in ("linkage-panel", "space-panel", "map-panel", "view3d-panel"):
        element_shot(browser, panel, f"surface-{panel}")

    # a drag of a joint: the surfaces of the new lengths replace them, no error is left over
    # from the map the drag asked (refused: two degrees of freedom)
    draws = int(data(browser, "view3d", "draws") or 0)
    drag(browser, "vertex:B", 25, 10)
    wait_for(lambda: "edited" in text(browser, "linkage-caption")
             and data(browser, "view3d", "surfaces") == "1"
             and data(browser, "space", "refinedMs") and text(browser, "status") == "ready",
             60, "the dragged pentagon's surfaces")
    assert int(data(browser, "view3d", "draws") or 0) > draws
    edited = json.loads(js(browser, "return JSON.stringify(state.linkage);"))
    body, api = received(browser, "/v1/analysis/configuration-space")
    assert body == {"linkage": edited}  # the full search after the drag's quick one
    same_surfaces(base_url, body, api)
    rows = browser.find_elements(By.CSS_SELECTOR, "#surface-list li")
    assert [r.get_attribute("data-triangles") for r in rows] == [
        str(len(s["triangles"])) for s in api["surfaces"]]
    assert [r.get_attribute("data-genus") for r in rows] == [
        shown_int(s["genus"]) for s in api["surfaces"]]
    element_shot(browser, "view3d-panel", "surface-dragged-view3d-panel")
    assert_stayed_local(browser, ("status of 422",))


def test_a_pentagon_that_cannot_close_shows_the_problem(base_url: str, browser: Any) -> None:
    """Lengths (1, 1, 1, 1, 5): one side longer than the others together; the service answers
    422, the status line says it, and the 3D view draws no surface."""
    paste(browser, base_url, pentagon((1.0, 1.0, 1.0, 1.0, 5.0)))
    wait_for(lambda: "[422]" in text(browser, "status"), 30, "the 422")
    assert text(browser, "space-caption") == "no configuration space (see the status line)"
    assert data(browser, "view3d", "surfaces") == "0"
    assert js(browser, "return document.getElementById('surface-list').children.length;") == 0
    element_shot(browser, "view3d-panel", "surface-error-view3d-panel")
    assert_stayed_local(browser, ("status of 422",))
