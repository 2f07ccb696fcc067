"""Dragging in the viewer (issue 27), in Debian's chromium against a real uvicorn on loopback: the
provisional map asked while the hand moves (a coarse map without the homotopy sweeps, drawn
dashed and stamped, then replaced by the full one), the time to the first useful drawing of the
space and the map for the four-bar, the three-rotor, the gated chain and the 3D presets, the
numbers shown against the API's for the same requests, and a drag that makes the linkage
unassemblable. The latencies measured are kept in tests/artifacts/drag-latencies.json beside a
screenshot of each panel."""

from __future__ import annotations

import json
import math
import os
import re
import statistics
import warnings
from typing import Any

import numpy as np
import pytest

from tests.service.test_browser import ARTIFACTS, browser, data, wait_for
from tests.service.test_browser import pytestmark as browser_marks
from tests.service.test_viewer import (
    assert_stayed_local,
    base_url,
    drag,
    element_shot,
    handles,
    js,
    open_viewer,
    post,
    set_param,
    short,
    text,
)

__all__ = ["base_url", "browser"]  # the fixtures, shared with test_viewer

# browser and process tests, skipped without Debian's chromium (the marks of test_browser)
pytestmark = browser_marks

LATENCIES = ARTIFACTS / "drag-latencies.json"
RESET = ("for (const id of ['space', 'map']) { const d = document.getElementById(id).dataset;"
         " for (const k of ['latencyMs', 'refinedMs', 'usefulMs']) delete d[k]; }")


def record(name: str, values: dict[str, Any]) -> None:
    """Keep a preset's measured latencies (ms) in the artifacts' JSON file."""
    ARTIFACTS.mkdir(exist_ok=True)
    known = json.loads(LATENCIES.read_text()) if LATENCIES.exists() else {}
    known[name] = values
    LATENCIES.write_text(json.dumps(known, indent=1, sort_keys=True))


def map_requests(driver: Any) -> list[tuple[str, dict[str, Any]]]:
    """The critical-value requests the page sent since the log was last read: (the browser's
    request id, the body)."""
    out = []
    for entry in driver.get_log("performance"):
        message = json.loads(entry["message"])["message"]
        params = message.get("params", {})
        request = params.get("request", {})
        if (message["method"] == "Network.requestWillBeSent"
                and request.get("url", "").endswith("/v1/analysis/critical-values")):
            out.append((params["requestId"], json.loads(request.get("postData", "{}"))))
    return out


def answer_of(driver: Any, request_id: str) -> dict[str, Any]:
    """The service's answer to one of the page's requests, as the browser received it."""
    body = driver.execute_cdp_cmd("Network.getResponseBody", {"requestId": request_id})
    value: dict[str, Any] = json.loads(body["body"])
    return value


def shown_regions(driver: Any) -> list[tuple[int | None, float, float]]:
    """Each region's button: its count (None: not explored in time) and its point."""
    from selenium.webdriver.common.by import By

    out = []
    for b in driver.find_elements(By.CSS_SELECTOR, "#regions button"):
        m = re.match(r"R\d+: (?:≥?(\d+) components?\b|\? \(not explored in time\)).*"
                     r"at \(([-\d.e]+), ([-\d.e]+)\)", b.text)
        assert m, b.text
        out.append((int(m[1]) if m[1] else None, float(m[2]), float(m[3])))
    return out


def api_regions(answer: dict[str, Any]) -> list[tuple[int | None, float, float]]:
    return [(r["components"], short(r["point"][0]), short(r["point"][1]))
            for r in answer["regions"]]


def free_vertex(driver: Any) -> str:
    linkage = json.loads(js(driver, "return JSON.stringify(state.linkage);"))
    pins = {v["id"] for v in linkage["vertices"] if v.get("fixed") is True}
    return [h for h in handles(driver) if h.startswith("vertex:") and h[7:] not in pins][-1]


def drags(driver: Any, handle: str, step: tuple[float, float], full: bool) -> list[dict[str, Any]]:
    """Three drags of a handle, there and back and there again; after each, what the page
    measured from the last move (ms): the space drawn, the first map drawn, the first map with
    a curve and a counted region (useful), and (``full``) the full map and space."""
    rows = []
    for sign in (1, -1, 1):
        js(driver, RESET)
        drag(driver, handle, sign * step[0], sign * step[1])
        wait_for(lambda: data(driver, "space", "latencyMs") and data(driver, "map", "latencyMs"),
                 60, "the quick answers")
        if full:
            wait_for(lambda: data(driver, "map", "refinedMs")
                     and text(driver, "status") == "ready", 90, "the full answers")
        rows.append({k: int(data(driver, el, key) or 0) or None for k, el, key in (
            ("space", "space", "latencyMs"), ("map", "map", "latencyMs"),
            ("useful", "map", "usefulMs"), ("map_full", "map", "refinedMs"),
            ("space_full", "space", "refinedMs"))})
    return rows


def late(med: dict[str, float | None], keys: tuple[str, ...]) -> str:
    """Which of these median latencies are a second or more ('' when none)."""
    return ", ".join(f"{k} {med[k]} ms" for k in keys if not (med[k] or math.inf) < 1000)


def check_latency(slow: str, rows: list[dict[str, Any]], load: float) -> None:
    """A latency of a second or more is reported as a warning with the numbers and the load
    (they are kept in tests/artifacts/drag-latencies.json): speed is measured, not asserted in
    tests (the house rule; bench/ and docs/benchmarks.md hold the numbers), and the machine
    is shared, so that a late drag says more about the other processes than about the viewer."""
    if not slow:
        return
    per_core = max(load, os.getloadavg()[0]) / (os.cpu_count() or 1)
    warnings.warn(f"{slow} at a load of {per_core:.1f} per core: {rows}", stacklevel=2)


def medians(rows: list[dict[str, Any]]) -> dict[str, float | None]:
    """The median of each column (None: not reached in a drag counts as the slowest)."""
    return {k: statistics.median([r[k] if r[k] is not None else math.inf for r in rows])
            for k in rows[0]}


# -- the provisional map ----------------------------------------------------------------------


@pytest.mark.parametrize("preset", ["four-bar", "three-rotor"])
def test_a_drag_shows_a_provisional_map_then_the_full_one(base_url: str, browser: Any,
                                                          preset: str) -> None:
    """While the hand moves the map is asked coarse and without the homotopy sweeps, drawn
    within a second with its curves and counted regions, dashed and stamped provisional; the
    numbers shown are the service's for that request; then the full map replaces it."""
    open_viewer(browser, base_url, preset)
    assert data(browser, "map", "provisional") == "false"
    handle = free_vertex(browser)
    browser.get_log("performance")
    load = os.getloadavg()[0]
    rows = drags(browser, handle, (12, 6), full=True)
    med = medians(rows)
    record(preset, {"drags": rows, "median": med, "load": [load, os.getloadavg()[0]]})
    # the time to the first useful drawing: the space, and the map with curves and counts
    # (checked last, after the other checks)
    slow = late(med, ("space", "useful"))
    bodies = [b for _, b in map_requests(browser)]
    quick = [b for b in bodies if "options" in b]
    assert quick and all(b["options"]["homotopy_paths_max"] == 0 for b in quick)
    assert "options" not in bodies[-1]  # the last map asked is the full one

    # one more drag, caught while the provisional map is drawn
    js(browser, RESET)
    drag(browser, handle, -12, -6)
    wait_for(lambda: data(browser, "map", "provisional") == "true", 30, "the provisional map")
    numbers = shown_regions(browser)
    curves = int(data(browser, "map", "curves") or -1)
    caption = text(browser, "map-caption")
    element_shot(browser, "map-panel", f"{preset}-provisional-map")
    sent = map_requests(browser)
    request_id, body = [(i, b) for i, b in sent if "options" in b][-1]
    assert "provisional" in caption and "the full map follows" in caption
    # the numbers shown are the service's answer to that request, as the browser received it
    received = answer_of(browser, request_id)
    assert numbers == api_regions(received)
    assert curves == len(received["curves"]) > 0
    # and the same request sent again answers the same (unless the quick budget cut the search
    # short: a search stopped by its clock does not repeat itself)
    if received["search"]["reason"] != "time":
        api = post(base_url, "/v1/analysis/critical-values", body)
        if api["search"]["reason"] != "time":
            assert api_regions(api) == numbers and len(api["curves"]) == curves

    wait_for(lambda: data(browser, "map", "provisional") == "false"
             and data(browser, "map", "refinedMs") and text(browser, "status") == "ready", 90,
             "the full map")
    assert "provisional" not in text(browser, "map-caption")
    sent += map_requests(browser)
    request_id, full_body = sent[-1]
    assert "options" not in full_body and full_body["linkage"] == body["linkage"]
    received = answer_of(browser, request_id)
    assert shown_regions(browser) == api_regions(received)
    assert int(data(browser, "map", "curves") or -1) == len(received["curves"])
    if preset == "four-bar":  # complete (closed form): the full map repeats itself exactly
        api = post(base_url, "/v1/analysis/critical-values", full_body)
        assert api["search"]["complete"] is True and api_regions(api) == api_regions(received)
        assert len(api["curves"]) == len(received["curves"])
    element_shot(browser, "map-panel", f"{preset}-full-map")
    element_shot(browser, "space-panel", f"{preset}-dragged-space")
    element_shot(browser, "linkage-panel", f"{preset}-dragged-linkage")
    assert_stayed_local(browser)
    check_latency(slow, rows, load)


def test_the_gated_chain_drag_is_measured(base_url: str, browser: Any) -> None:
    """The gated chain (22 bars): its quick space and map are measured and kept (its map in the
    chain's rotor lengths counts few regions within the quick budget: the numbers say how
    long the first useful drawing takes), and the full answers follow."""
    open_viewer(browser, base_url, "gated-kl-chain")
    load = os.getloadavg()[0]
    rows = drags(browser, free_vertex(browser), (10, 5), full=True)
    record("gated-kl-chain", {"drags": rows, "median": medians(rows),
                              "load": [load, os.getloadavg()[0]]})
    assert all(r["space"] and r["map"] and r["map_full"] for r in rows)
    assert data(browser, "map", "provisional") == "false"
    element_shot(browser, "map-panel", "gated-kl-chain-full-map")
    assert_stayed_local(browser)


# -- the 3D presets -----------------------------------------------------------------------------


def hinge_angle(conf: dict[str, list[float]], tip: str, pins: tuple[str, str]) -> float:
    """A hinge's angle about the axis through its pins, in a frame of the test's own (a fixed
    vector made normal to the axis by a cross product: the viewer's frame may differ by a
    constant turn)."""
    p, q, t = (np.array(conf[v], dtype=float) for v in (*pins, tip))
    axis = (q - p) / np.linalg.norm(q - p)
    e1 = np.cross(axis, [0.3, 0.5, 0.8])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(axis, e1)
    r = t - p
    return float(math.atan2(r @ e2, r @ e1))


@pytest.mark.parametrize("n", [2, 6])
def test_a_3d_drag_follows(base_url: str, browser: Any, n: int) -> None:
    """rotor-chain-3d with two hinged rotors (a 3D hinge four-bar) and with six: the space
    follows a drag within a second, and for the hinge four-bar the first useful map too; the
    hinges' angles drawn are the positions' (the 3D answers carry no angles)."""
    open_viewer(browser, base_url, "rotor-chain-3d")
    if n != 6:
        set_param(browser, "n", n)
        wait_for(lambda: js(browser, "return state.linkage && state.linkage.vertices.length;")
                 == 3 * n and text(browser, "status") == "ready", 60, f"{n} rotors")
    linkage = json.loads(js(browser, "return JSON.stringify(state.linkage);"))
    load = os.getloadavg()[0]
    rows = drags(browser, free_vertex(browser), (10, 6), full=True)
    med = medians(rows)
    record(f"rotor-chain-3d n={n}", {"drags": rows, "median": med,
                                     "load": [load, os.getloadavg()[0]]})
    slow = late(med, ("space", "useful") if n == 2 else ("space",))

    # the space panel and the 3D view draw the API's components at the hinges' angles
    linkage = json.loads(js(browser, "return JSON.stringify(state.linkage);"))
    space = post(base_url, "/v1/analysis/configuration-space", {"linkage": linkage})
    shown = json.loads(js(browser, "return JSON.stringify(state.space);"))
    assert len(shown["components"]) == len(space["components"]) > 0
    assert int(data(browser, "space", "components") or -1) == len(space["components"])
    hinges = js(browser, "return state.rotors.map((r) => [r.bar, r.pin, r.pin2]);")
    assert len(hinges) == n
    for comp in shown["components"]:
        walk = comp["positions"]
        for tip, pa, pb in hinges:
            turn = np.array([comp["angles"][tip][i] - hinge_angle(
                {v: walk[v][i] for v in (tip, pa, pb)}, tip, (pa, pb))
                for i in range(len(walk[tip]))])
            apart = (turn - turn[0] + math.pi) % math.tau - math.pi
            assert np.abs(apart).max() < 1e-9, tip  # one constant turn apart
    assert len(js(browser, "return view3.projected;")) == sum(
        len(c["positions"][hinges[0][0]]) for c in space["components"])
    for panel in ("linkage-panel", "space-panel", "map-panel", "view3d-panel"):
        element_shot(browser, panel, f"rotor-chain-3d-{n}-{panel}")
    assert_stayed_local(browser)
    check_latency(slow, rows, load)


# -- an error while dragging ---------------------------------------------------------------------


def test_a_drag_past_assembly_shows_the_problem_and_no_provisional_map(base_url: str,
                                                                       browser: Any) -> None:
    """The four-bar's L1 dragged beyond a + L2 + L3 = 3: no configuration has these lengths;
    the status says the service's problem, the space and the map say there is none, no
    provisional map stays drawn."""
    open_viewer(browser, base_url, "four-bar")
    drag(browser, "bar:L1", 100, -170)
    wait_for(lambda: "[422]" in text(browser, "status"), 30, "the 422 in the status line")
    length = js(browser, "return barLength(state.linkage, state.linkage.bars[0]);")
    assert length > 3.0  # beyond the four-bar's assembly (a + L2 + L3)
    assert "No configuration near the given positions" in text(browser, "status")
    # (the space's and the map's 422s arrive in either order)
    wait_for(lambda: text(browser, "map-caption").endswith("no map")
             and text(browser, "space-caption") != "computing…", 30, "both captions")
    assert text(browser, "space-caption") == "no configuration space (see the status line)"
    assert data(browser, "map", "provisional") == "false"
    assert js(browser, "return mapView.answer;") is None
    element_shot(browser, "map-panel", "unassemblable-drag-map")
    element_shot(browser, "space-panel", "unassemblable-drag-space")
    assert_stayed_local(browser, ("status of 422",))
