"""The viewer as a design tool (issue 27), in Debian's chromium driven by Selenium against a real
uvicorn on loopback: errors, dragging, the configuration space's arrows and segments, the
splitting and map panels, the 3D view, the keyboard, contrast, and the numbers shown against the
API's for the same requests. Every test checks that no request left the machine. Screenshots of
each panel are kept under tests/artifacts/ (ignored by git)."""

from __future__ import annotations

import json
import math
import os
import re
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import httpx
import numpy as np
import pytest

from tests.service.test_browser import (
    ARTIFACTS,
    CHROMEDRIVER,
    CHROMIUM,
    browser,
    console_errors,
    data,
    leaving,
    requested_urls,
    shot,
    wait_for,
)
from tests.service.test_uvicorn_process import HOST, ROOT, STARTUP_TIMEOUT, free_port, stop

__all__ = ["browser"]  # the fixture, shared with test_browser

pytestmark = [
    pytest.mark.browser,
    pytest.mark.process,
    pytest.mark.skipif(CHROMIUM is None or CHROMEDRIVER is None,
                       reason="Debian's chromium and chromium-driver are not installed"),
]

PANELS = ("linkage-panel", "space-panel", "map-panel", "split-panel", "view3d-panel")


def text(driver: Any, element_id: str) -> str:
    from selenium.webdriver.common.by import By

    value: str = driver.find_element(By.ID, element_id).text
    return value


def js(driver: Any, script: str, *args: Any) -> Any:
    return driver.execute_script(script, *args)


def open_viewer(driver: Any, base: str, preset: str) -> None:
    """The viewer with a preset chosen (by its address), once its space and map are drawn."""
    driver.get(f"{base}/viewer/?preset={preset}")
    wait_for(lambda: data(driver, "space", "components"), 60, "the configuration space")
    wait_for(lambda: text(driver, "status") == "ready", 60, "every request answered")


def set_param(driver: Any, name: str, value: float) -> None:
    js(driver, "const i = document.getElementById(arguments[0]); i.value = arguments[1];"
       "i.dispatchEvent(new Event('change'));", f"param-{name}", str(value))


def assert_stayed_local(driver: Any, allowed_errors: tuple[str, ...] = ()) -> None:
    """No request left the machine; the console has no error but the failed answers expected."""
    assert leaving(requested_urls(driver)) == []
    errors = [e for e in console_errors(driver) if not any(a in e for a in allowed_errors)]
    assert errors == []


def short(x: float, digits: int = 4) -> float:
    """A number as the viewer shows it (JavaScript's toPrecision, then Number)."""
    return float(f"{x:.{digits}g}")


def post(base: str, path: str, body: dict[str, Any]) -> Any:
    res = httpx.post(f"{base}{path}", json=body, trust_env=False, timeout=60.0)
    assert res.status_code == 200, res.text
    return res.json()


# -- defects: errors, pasted linkages, capped counts ---------------------------------------------


def test_errors_set_the_status_and_captions_to_the_new_state(base_url: str, browser: Any) -> None:
    from selenium.webdriver.common.by import By
    from selenium.webdriver.support.ui import Select

    open_viewer(browser, base_url, "four-bar")
    assert text(browser, "space-caption") == "1 component, 3 critical points"

    # a preset whose parameters the service refuses (n must be even): 422 invalid-parameter
    Select(browser.find_element(By.ID, "preset")).select_by_value("cn-symmetric-four-regular")
    wait_for(lambda: browser.find_elements(By.ID, "param-n"), 10, "the preset's sliders")
    # (a rigid framework: its configuration space is refused with a 422 of its own)
    wait_for(lambda: "Invalid linkage" in text(browser, "status"), 60, "the preset's answers")
    set_param(browser, "n", 9)
    wait_for(lambda: "Invalid preset parameter" in text(browser, "status"), 30, "the error")
    status = text(browser, "status")
    assert "computing" not in status
    assert "must be a multiple of 2" in status and "[422]" in status
    assert "four-bar" not in text(browser, "linkage-caption")
    assert "cn-symmetric-four-regular" in text(browser, "linkage-caption")
    assert text(browser, "space-caption") == "no configuration space"
    assert data(browser, "space", "components") == ""
    shot(browser, "viewer-error-preset.png")

    # the four-bar drawn, then lengths that assemble at no angle: nothing of the old one stays
    open_viewer(browser, base_url, "four-bar")
    for name, value in (("L1", 0.2), ("L2", 0.2), ("a", 2.5)):  # 0.2 + 0.2 + 1 < 2.5
        set_param(browser, name, value)
    wait_for(lambda: "assembles at no angle" in text(browser, "status"), 30, "the refusal")
    assert text(browser, "linkage-caption") == "preset four-bar: no linkage"
    assert text(browser, "space-caption") == "no configuration space"
    assert data(browser, "space", "components") == ""
    assert text(browser, "map-caption") == "no map"

    # a pasted linkage the service refuses: its title and detail, and the old sliders go
    open_viewer(browser, base_url, "four-bar")
    bad = {"vertices": [{"id": "P", "position": [0, 0], "fixed": True},
                        {"id": "A", "position": [1, 0]}],
           "bars": [{"id": "b", "ends": ["P", "Q"]}]}
    browser.find_element(By.CSS_SELECTOR, "#paste summary").click()
    area = browser.find_element(By.ID, "linkage-json")
    area.clear()
    area.send_keys(json.dumps(bad))
    browser.find_element(By.ID, "use-linkage").click()
    wait_for(lambda: "[422]" in text(browser, "status"), 30, "the refusal")
    status = text(browser, "status")
    assert "computing" not in status and "Q" in status  # the detail names the unknown end
    assert browser.find_elements(By.CSS_SELECTOR, "#params input") == []
    assert Select(browser.find_element(By.ID, "preset")).first_selected_option.text \
        == "choose a preset…"
    assert text(browser, "linkage-caption").startswith("pasted linkage")
    assert text(browser, "space-caption").startswith("no configuration space")
    assert js(browser, CONTRAST) == []  # the error line too is readable

    # not JSON at all: said in the status line, no request
    area.clear()
    area.send_keys("{not json")
    browser.find_element(By.ID, "use-linkage").click()
    wait_for(lambda: "not JSON" in text(browser, "status"), 5, "the parse error")
    assert_stayed_local(browser, ("status of 422",))


@contextmanager
def service(**settings: str) -> Iterator[str]:
    """A real uvicorn on loopback with these settings; up to a minute to start (the machine is
    shared: the workers' first start loads numba's cached kernels)."""
    port = free_port()
    url = f"http://{HOST}:{port}"
    env = {**os.environ, "PYTHONUNBUFFERED": "1", **settings}
    with tempfile.TemporaryDirectory() as tmp:
        stderr_path = Path(tmp) / "uvicorn.stderr"
        with stderr_path.open("wb") as stderr:
            proc = subprocess.Popen(
                [sys.executable, "-m", "uvicorn", "service.main:app", "--host", HOST,
                 "--port", str(port), "--log-level", "warning"],
                cwd=ROOT, env=env, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                stderr=stderr)
        try:
            deadline = time.monotonic() + STARTUP_TIMEOUT
            with httpx.Client(base_url=url, trust_env=False, timeout=5.0) as client:
                while True:
                    assert proc.poll() is None, stderr_path.read_text(errors="replace")
                    try:
                        if client.get("/health/ready").status_code == 200:
                            break
                    except httpx.TransportError:
                        pass
                    assert time.monotonic() < deadline, "uvicorn was not ready in time"
                    time.sleep(0.2)
            yield url
        finally:
            stop(proc)


@pytest.fixture(scope="module")
def base_url() -> Iterator[str]:
    with service() as url:
        yield url


@pytest.fixture(scope="module")
def busy_url() -> Iterator[str]:
    """A service that admits one engine request at a time: the viewer's parallel requests get
    503 `busy` problems, a real 5xx."""
    with service(LINKAGE_MAX_QUEUE="1", LINKAGE_WORKERS="1") as url:
        yield url


def test_a_5xx_shows_the_problem_title_and_detail(busy_url: str, browser: Any) -> None:
    browser.get(f"{busy_url}/viewer/?preset=four-bar")
    wait_for(lambda: "[503]" in text(browser, "status"), 60, "a 503 in the status line")
    status = text(browser, "status")
    assert "Service busy" in status and "LINKAGE_MAX_QUEUE" in status
    assert "Internal error" not in status and "computing" not in status
    # the panels whose request was refused say so instead of "computing…"
    wait_for(lambda: text(browser, "space-caption") != "computing…"
             and "computing" not in text(browser, "map-caption"), 60, "every answer")
    if text(browser, "map-caption").endswith("no map"):  # the canvas says so too
        assert js(browser, "return mapView.error;")
    shot(browser, "viewer-error-busy.png")
    assert_stayed_local(browser, ("status of 503",))


def test_capped_component_counts_are_shown_as_bounds(base_url: str, browser: Any) -> None:
    open_viewer(browser, base_url, "kl-chain")
    linkage = httpx.get(f"{base_url}/v1/presets/kl-chain", trust_env=False).json()
    search = post(base_url, "/v1/analysis/configuration-space", {"linkage": linkage})["search"]
    traced = int(data(browser, "space", "components") or 0)
    # a chain of 10 rotors: 2^(n - 1) components by the four-bar decomposition, far over the
    # 32 the search traces by default
    assert search["components_total"] == 2 ** 9 and traced < 2 ** 9
    caption = text(browser, "space-caption")
    assert caption.startswith(f"{traced} of 512 components traced")

    # the gated chain's rule counts it too (2^9 chain components x 2 of its Grashof gate x 2
    # slider positions), and the caption says ungated: D = 2a < 5a/2
    open_viewer(browser, base_url, "gated-kl-chain")
    linkage = httpx.get(f"{base_url}/v1/presets/gated-kl-chain", trust_env=False).json()
    search = post(base_url, "/v1/analysis/configuration-space", {"linkage": linkage})["search"]
    assert search["components_total"] == 2 ** 11 and search["gated"] is False
    traced = int(data(browser, "space", "components") or 0)
    caption = text(browser, "space-caption")
    assert caption.startswith(f"{traced} of 2048 components traced") and traced < 2048
    assert caption.endswith(", ungated")
    assert_stayed_local(browser)


# -- dragging -------------------------------------------------------------------------------------


def handles(driver: Any) -> dict[str, list[float]]:
    value: dict[str, list[float]] = json.loads(data(driver, "linkage", "handles") or "{}")
    return value


def drag(driver: Any, handle: str, dx: float, dy: float, steps: int = 8) -> None:
    from selenium.webdriver.common.action_chains import ActionChains
    from selenium.webdriver.common.by import By

    canvas = driver.find_element(By.ID, "linkage")
    rect = js(driver, "const r = arguments[0].getBoundingClientRect();"
              "return [r.width, r.height];", canvas)
    x, y = handles(driver)[handle]
    chain = ActionChains(driver, duration=10)
    chain.move_to_element_with_offset(canvas, x - rect[0] / 2, y - rect[1] / 2).click_and_hold()
    for _ in range(steps):
        chain.move_by_offset(dx / steps, dy / steps)
    chain.release().perform()


def lengths(driver: Any) -> list[float]:
    return [float(x) for x in (data(driver, "space", "lengths") or "").split(",")]


def test_dragging_a_joint_and_a_length_redraws_space_and_map(base_url: str, browser: Any) -> None:
    open_viewer(browser, base_url, "four-bar")
    assert lengths(browser) == [1.0, 1.0, 1.0]
    draws = int(data(browser, "space", "draws") or 0)
    map_draws = int(data(browser, "map", "draws") or 0)
    browser.get_log("performance")  # only the drag's requests from here

    # the joint B to the right: L2 and L3 change, L1 does not
    drag(browser, "vertex:B", 60, 0)
    wait_for(lambda: lengths(browser)[1] > 1.05 and text(browser, "status") == "ready", 30,
             "the space of the dragged linkage")
    moved = lengths(browser)
    assert moved[0] == 1.0 and moved[1] > 1.05 and moved[2] != 1.0
    assert int(data(browser, "space", "draws") or 0) > draws
    wait_for(lambda: int(data(browser, "map", "draws") or 0) > map_draws, 30, "the map")
    # from the last move to the space drawn, as the page measured it: within a second
    assert int(data(browser, "space", "latencyMs") or 1e9) < 1000
    assert int(data(browser, "map", "latencyMs") or 1e9) < 1000
    urls = requested_urls(browser)
    spaces = [u for u in urls if u.endswith("/v1/analysis/configuration-space")]
    assert 1 <= len(spaces) < 8  # debounced: fewer requests than moves
    assert "edited" in text(browser, "linkage-caption")

    # the square on L1 dragged along the bar (up and right, as L1 points): L1 grows
    before = lengths(browser)
    drag(browser, "bar:L1", 15, -26)
    wait_for(lambda: lengths(browser)[0] > before[0] + 0.02 and text(browser, "status")
             == "ready", 30, "the space of the longer L1")
    assert lengths(browser)[1:] == pytest.approx(before[1:], abs=2e-4)
    shot(browser, "viewer-dragged.png")
    assert_stayed_local(browser)


def test_a_three_rotor_drag_redraws_space_and_map_within_a_second(base_url: str,
                                                                   browser: Any) -> None:
    """While the hand moves, the space's search skips its completeness proof and the map's search
    is short and runs beside it; once the hand rests both are asked again in full."""
    open_viewer(browser, base_url, "three-rotor")
    assert data(browser, "space", "complete") == "true"
    linkage = json.loads(js(browser, "return JSON.stringify(state.linkage);"))
    pins = {v["id"] for v in linkage["vertices"] if v.get("fixed")}
    free = [h for h in handles(browser) if h.startswith("vertex:") and h[7:] not in pins]
    browser.get_log("performance")
    # from the last move to the space and the map drawn, as the page measured it; the median of
    # three drags (the machine running the tests is shared: one drag can be slowed by others)
    latencies = []
    for step in (1, -1, 1):
        map_draws = int(data(browser, "map", "draws") or 0)
        js(browser, "delete document.getElementById('space').dataset.latencyMs;")
        drag(browser, free[-1], 12 * step, 6 * step)
        wait_for(lambda drawn=map_draws: int(data(browser, "map", "draws") or 0) > drawn
                 and data(browser, "space", "latencyMs") is not None
                 and data(browser, "space", "complete") == "false", 30, "the quick answers")
        assert "completeness not yet proved" in text(browser, "space-caption")
        latencies.append((int(data(browser, "space", "latencyMs") or 1e9),
                          int(data(browser, "map", "latencyMs") or 1e9)))
    space_ms, map_ms = (sorted(column)[1] for column in zip(*latencies, strict=True))
    assert space_ms < 1000 and map_ms < 1000, latencies
    # then the full search: the caption of a complete answer, the tangent arrows back
    wait_for(lambda: data(browser, "space", "complete") == "true"
             and text(browser, "status") == "ready", 60, "the refined space")
    assert "not yet proved" not in text(browser, "space-caption")
    assert int(data(browser, "space", "tangentArrows") or 0) > 0
    bodies = []
    for entry in browser.get_log("performance"):
        message = json.loads(entry["message"])["message"]
        request = message.get("params", {}).get("request", {})
        if request.get("url", "").endswith("/v1/analysis/configuration-space"):
            bodies.append(json.loads(request.get("postData", "{}")))
    assert bodies[0]["options"] == {"homotopy_paths_max": 0}
    assert len(bodies) >= 4 and "options" not in bodies[-1]  # the refinement: the defaults
    assert_stayed_local(browser)


def test_a_new_linkage_aborts_the_requests_it_supersedes(base_url: str, browser: Any) -> None:
    from selenium.webdriver.common.by import By
    from selenium.webdriver.support.ui import Select

    browser.get(f"{base_url}/viewer/?preset=kl-chain")
    # the kl-chain's searches take seconds: choose the four-bar while they run
    wait_for(lambda: "computing" in text(browser, "status"), 30, "the kl-chain's requests")
    Select(browser.find_element(By.ID, "preset")).select_by_value("four-bar")
    wait_for(lambda: data(browser, "space", "lengths") == "1.0000,1.0000,1.0000"
             and text(browser, "status") == "ready", 60, "the four-bar")
    cancelled = []
    urls = {}
    for entry in browser.get_log("performance"):
        message = json.loads(entry["message"])["message"]
        params = message.get("params", {})
        if message["method"] == "Network.requestWillBeSent":
            urls[params["requestId"]] = params["request"]["url"]
        elif message["method"] == "Network.loadingFailed" and params.get("canceled"):
            cancelled.append(urls.get(params["requestId"], ""))
    assert any(u.endswith("/v1/analysis/configuration-space") for u in cancelled), cancelled
    assert text(browser, "space-caption") == "1 component, 3 critical points"
    assert leaving(list(urls.values())) == []
    assert console_errors(browser) == []  # an aborted request is no error


# -- the configuration space: ticks, legend, arrows, segments -------------------------------------


def walk_direction(comp: dict[str, Any], axes: list[str], i: int) -> tuple[float, float]:
    """The component's direction at point i in two rotor angles, by central differences."""
    a, b = comp["angles"][axes[0]], comp["angles"][axes[1]]
    da, db = a[i + 1] - a[i - 1], b[i + 1] - b[i - 1]
    n = math.hypot(da, db)
    return da / n, db / n


def test_space_has_ticks_legend_tangent_arrows_and_segments(base_url: str, browser: Any) -> None:
    from selenium.webdriver.common.by import By

    open_viewer(browser, base_url, "four-bar")
    assert data(browser, "space", "ticksX") == data(browser, "space", "ticksY") == "5"
    legend = text(browser, "space-legend")
    for kind in ("branch point", "rigid point", "degenerate point", "tangent form"):
        assert kind in legend
    assert data(browser, "space", "kinds") == "branch,branch,branch"
    assert data(browser, "space", "rays") == "12"  # four rays at each branch point

    # the tangent form is tangent to the traced curve (paper, appendix: away from critical
    # points): each arrow against the walk's own central difference
    wait_for(lambda: int(data(browser, "space", "tangentArrows") or 0) == 8, 30, "the arrows")
    linkage = httpx.get(f"{base_url}/v1/presets/four-bar", trust_env=False).json()
    answer = post(base_url, "/v1/analysis/configuration-space", {"linkage": linkage})
    for arrow in json.loads(data(browser, "space", "arrows") or "[]"):
        comp = answer["components"][arrow["component"]]
        da, db = walk_direction(comp, ["L1", "L3"], arrow["index"])
        n = math.hypot(*arrow["d"])
        assert abs(da * arrow["d"][0] + db * arrow["d"][1]) / n > 0.99

    # every segment of the answer is found along the walk and can be chosen
    buttons = browser.find_elements(By.CSS_SELECTOR, "#segments button")
    assert len(buttons) == len(answer["segments"]) == 6
    assert all(b.is_enabled() for b in buttons)
    for j in (0, 3):
        buttons = browser.find_elements(By.CSS_SELECTOR, "#segments button")
        buttons[j].click()
        wait_for(lambda j=j: data(browser, "space", "selectedSegment") == str(j), 5,
                 "the segment chosen")
        assert browser.find_elements(By.CSS_SELECTOR, "#segments button")[j] \
            .get_attribute("aria-pressed") == "true"
        seg = answer["segments"][j]
        # the configuration shown lies on that segment: strictly between its critical points
        # in the angle of L1 along the walk, and not at either end
        caption = text(browser, "linkage-caption")
        k, i = map(int, re.findall(r"component (\d+), point (\d+)", caption)[0])
        assert k == seg["component"]
        conf = {v: w[i] for v, w in answer["components"][k]["positions"].items()}
        ends = [answer["critical_points"][seg["from"]]["configuration"],
                answer["critical_points"][seg["to"]]["configuration"]]
        for end in ends:
            assert max(math.dist(conf[v], end[v]) for v in conf) > 0.05
    element_shot(browser, "space-panel")
    assert_stayed_local(browser)


def element_shot(driver: Any, element_id: str, name: str = "") -> None:
    from selenium.webdriver.common.by import By

    ARTIFACTS.mkdir(exist_ok=True)
    driver.set_window_size(1400, 2400)  # the whole panel in the viewport
    element = driver.find_element(By.ID, element_id)
    js(driver, "arguments[0].scrollIntoView();", element)
    element.screenshot(str(ARTIFACTS / f"panel-{name or element_id}.png"))


# -- splitting ------------------------------------------------------------------------------------


def grashof_circuits(a: float, l1: float, l2: float, l3: float) -> int:
    """Circuits of a four-bar (ground a): two when s + l < p + q (Grashof), else one."""
    s = sorted([a, l1, l2, l3])
    return 2 if s[0] + s[3] < s[1] + s[2] else 1


def test_splitting_panel_checks_predictions_by_the_retrace(base_url: str, browser: Any) -> None:
    from selenium.webdriver.common.by import By
    from selenium.webdriver.support.ui import Select

    open_viewer(browser, base_url, "four-bar")
    joins = {}
    for dl in (0.02, -0.02):
        Select(browser.find_element(By.ID, "split-bar")).select_by_value("L2")
        field = browser.find_element(By.ID, "split-dl")
        field.clear()
        field.send_keys(str(dl))
        browser.find_element(By.ID, "split-run").click()
        wait_for(lambda: data(browser, "split", "verified") is not None, 60, "the re-trace")
        assert data(browser, "split", "verified") == "true"
        assert int(data(browser, "split", "perturbedComponents") or 0) \
            == grashof_circuits(1, 1, 1 + dl, 1)
        rows = browser.find_elements(By.CSS_SELECTOR, "#split-table tr[data-branch-point]")
        assert len(rows) == 3 and all(r.get_attribute("data-agree") == "true" for r in rows)
        joins[dl] = [r.find_elements(By.TAG_NAME, "td")[4].text for r in rows]
        element_shot(browser, "split-panel")
        js(browser, "delete document.getElementById('split').dataset.verified;")
    # the two resolutions join the rays differently at every branch point: the check reads the
    # re-traced curves, it does not echo the prediction
    assert all(p != m for p, m in zip(joins[0.02], joins[-0.02], strict=True))

    # design: a sign per branch point, the service's re-trace says verified
    for sel in browser.find_elements(By.CSS_SELECTOR, "#design-targets select"):
        Select(sel).select_by_value("-1")
    browser.find_element(By.ID, "design-run").click()
    wait_for(lambda: data(browser, "split", "verified") is not None, 60, "the design")
    assert "service verified: true" in text(browser, "split-perturbation")
    assert data(browser, "split", "verified") == "true"

    # the three-rotor's twelve branch points split both ways under one change of r2: the
    # re-trace confirms each, whichever way its rays join
    open_viewer(browser, base_url, "three-rotor")
    Select(browser.find_element(By.ID, "split-bar")).select_by_value("r2")
    field = browser.find_element(By.ID, "split-dl")
    field.clear()
    field.send_keys("0.01")
    browser.find_element(By.ID, "split-run").click()
    wait_for(lambda: data(browser, "split", "verified") is not None, 90, "the re-trace")
    rows = browser.find_elements(By.CSS_SELECTOR, "#split-table tr[data-branch-point]")
    assert len(rows) == 12 and data(browser, "split", "verified") == "true"
    assert len({r.find_elements(By.TAG_NAME, "td")[3].text for r in rows}) == 2
    assert_stayed_local(browser)


# -- map ------------------------------------------------------------------------------------------


def region_numbers(driver: Any) -> list[tuple[int, float, float]]:
    from selenium.webdriver.common.by import By

    out = []
    for b in driver.find_elements(By.CSS_SELECTOR, "#regions button"):
        m = re.match(r"R\d+: ≥?(\d+) components?\b.*at \(([-\d.e]+), ([-\d.e]+)\)", b.text)
        assert m, b.text
        out.append((int(m[1]), float(m[2]), float(m[3])))
    return out


def test_map_regions_margin_disc_and_loading_a_region(base_url: str, browser: Any) -> None:
    from selenium.webdriver.common.by import By

    open_viewer(browser, base_url, "four-bar")
    set_param(browser, "L2", 1.2)
    wait_for(lambda: data(browser, "map", "margin") not in (None, "", "0")
             and text(browser, "status") == "ready", 60, "the margin off the critical lengths")
    # the nearest critical lengths of a four-bar lie on the planes +-a +-L1 +-L2 +-L3 = 0: in
    # (L2, L3) from (1.2, 1) the nearest are L2 - L3 = 0 and L2 + L3 = 2, at 0.2 / sqrt(2)
    assert float(data(browser, "map", "margin") or 0) == short(0.2 / math.sqrt(2), 6)
    assert "0.141421" in text(browser, "margin")
    element_shot(browser, "map-panel")

    regions = region_numbers(browser)
    # a click on a region's marker on the map loads its sample
    from selenium.webdriver.common.action_chains import ActionChains

    canvas = browser.find_element(By.ID, "map")
    js(browser, "arguments[0].scrollIntoView({block: 'center'});", canvas)
    markers = json.loads(data(browser, "map", "markers") or "[]")
    rect = js(browser, "const r = arguments[0].getBoundingClientRect();"
              "return [r.width, r.height];", canvas)
    k = max(range(len(regions)), key=lambda i: regions[i][0])
    ActionChains(browser).move_to_element_with_offset(
        canvas, markers[k][0] - rect[0] / 2, markers[k][1] - rect[1] / 2).click().perform()
    wait_for(lambda: f"map region R{k}" in text(browser, "linkage-caption")
             and text(browser, "status") == "ready", 60, "the region's sample from the map")
    assert int(data(browser, "space", "components") or 0) == regions[k][0]

    # and so does its button (keyboard): the sample of another region
    regions = region_numbers(browser)
    k = next(i for i, r in enumerate(regions) if r[0] >= 1)
    browser.find_elements(By.CSS_SELECTOR, "#regions button")[k].click()
    wait_for(lambda: f"map region R{k}" in text(browser, "linkage-caption")
             and text(browser, "status") == "ready", 60, "the region's sample")
    shown = lengths(browser)
    _, x, y = regions[k]
    assert shown[1] == pytest.approx(x, abs=1e-4) and shown[2] == pytest.approx(y, abs=1e-4)
    # that sample has the number of components its region is labelled with
    assert int(data(browser, "space", "components") or 0) == regions[k][0]
    assert browser.find_elements(By.CSS_SELECTOR, "#params input") == []

    # labels the service may add to a region (tau signs, gated) are shown as given, in the
    # page's own labelling function; a region not explored in time says so
    label = js(browser, "return [regionLabel({point: [1, 2], components: 2, signature: 's',"
               " cells: 4, tau: '+-', gated: true}), regionLabel({point: [1, 2],"
               " components: null, signature: null, cells: 0, gated: false})];")
    assert label == ["2 components, tau +-, gated", "? (not explored in time), ungated"]
    # and the legend names each extra field the regions carry, with the service's own
    # description (its OpenAPI RegionOut) where it has one; the fields the label shows by its
    # own rules (the count's: argument, components_exact, ...) are not extra: the merge of the
    # Fig. 5b labels made the count say whether it is exact, so argument left the legend
    spec = httpx.get(f"{base_url}/openapi.json", trust_env=False).json()
    docs = spec["components"]["schemas"]["RegionOut"]["properties"]
    js(browser, "mapView.answer = {regions: [{point: [1, 2], components: 2, signature: 's',"
       " cells: 4, tau: '+-', gated: true, windings: ['r0:1,D:0'], argument: 'proved',"
       " components_exact: true}], curves: []};"
       " showRegions();")
    wait_for(lambda: len(browser.find_elements(By.CSS_SELECTOR, "#region-fields dt")) == 3, 10,
             "the legend of the regions' fields")
    terms = {dt.text: dt.find_element(By.XPATH, "following-sibling::dd[1]").text
             for dt in browser.find_elements(By.CSS_SELECTOR, "#region-fields dt")}
    assert set(terms) == {"tau", "gated", "windings"}
    for field, meaning in terms.items():
        described = docs.get(field, {}).get("description", "").replace("``", "")
        assert meaning.startswith(described or "as the service gives it"), (field, meaning)
    assert terms["gated"].endswith('(shown as "gated" or "ungated")')
    assert terms["tau"].endswith('(shown as "tau <value>")')
    assert terms["windings"].endswith('(shown as "turns <pattern>")')
    assert js(browser, CONTRAST) == []
    element_shot(browser, "map-panel", "map-panel-fields")

    # the same slice as the service's SVG figure, in a dialog
    browser.find_element(By.CSS_SELECTOR, "[data-figure='critical-values']").click()
    img = wait_for(lambda: browser.find_elements(By.CSS_SELECTOR, "#figure-body img"), 60,
                   "the slice figure")[0]
    wait_for(lambda: js(browser, "return arguments[0].naturalWidth;", img) > 100, 10,
             "the figure loaded")
    assert js(browser, "return document.getElementById('figure-dialog').open;")
    assert_stayed_local(browser)


def eq16(d: float, r: float, l2: float, l1: float) -> str:
    """The gate four-bar's tau signs (the paper's Eq. 16: ground D, input r, coupler L2,
    output L1) as the viewer writes them."""
    values = (d - r + l2 - l1, d - r - l2 + l1, l2 + l1 - d - r)
    return "(" + ",".join("+" if v > 0 else "-" for v in values) + ")"


def test_gate_map_labels_regions_as_figure_5b(base_url: str, browser: Any) -> None:
    """A real gated chain (3 rotors, the paper's lengths) mapped in (L2, D): every region's
    button and marker say its count, the gate's tau signs (Eq. 16 at its sample, computed
    here) and gated or not as the sampled configuration space says (blue gated, red ungated,
    the paper's colours), the legend says what they mean, and the labels are the API's."""
    from selenium.webdriver.common.by import By

    from tests.gated_reference import sampled_gated_chain

    open_viewer(browser, base_url, "gated-kl-chain")
    set_param(browser, "gate", 1)  # (first: the gate must stay below n)
    wait_for(lambda: text(browser, "status") == "ready", 90, "the gate moved")
    set_param(browser, "n", 3)
    wait_for(lambda: data(browser, "space", "components") == "16"
             and text(browser, "status") == "ready", 90, "the 3-rotor gated chain")
    js(browser, "for (const [id, v] of [['axis-x', 'L2'], ['axis-y', 'D']]) {"
       "const s = document.getElementById(id); s.value = v;"
       "s.dispatchEvent(new Event('change')); }")
    wait_for(lambda: "L2 × D:" in text(browser, "map-caption")
             and "regions" in text(browser, "map-caption")
             and "cut short" not in text(browser, "map-caption"), 180, "the gate map")
    request = js(browser, "return mapRequest();")
    assert [a["bar"] for a in request["axes"]] == ["L2", "D"]
    answer = post(base_url, "/v1/analysis/critical-values", request)
    buttons = browser.find_elements(By.CSS_SELECTOR, "#regions button")
    assert len(buttons) == len(answer["regions"]) >= 6
    fills = js(browser, """
        const ctx = document.getElementById('map').getContext('2d');
        return mapView.answer.regions.map((r) => {
          const [x, y] = mapView.frame.to(r.point);
          return Array.from(ctx.getImageData(Math.round(x - 5), Math.round(y + 5), 1, 1).data);
        });""")
    seen = {}
    for k, (button, region) in enumerate(zip(buttons, answer["regions"], strict=True)):
        l2, d = region["point"]
        signs = eq16(d, 1.5, l2, 2.0)
        count, turns = sampled_gated_chain(3, 1.0, 1.5, 1.5, 1, d, 2.0, l2, samples=2000)
        label = button.text
        assert label.startswith(f"R{k}: {count} component"), label
        assert f"τ gate {signs}" in label and button.get_attribute("data-tau") == signs
        if count == 0:  # the gate does not assemble there
            assert region["gated"] is None and "gated" not in label
            continue
        gated = not turns
        seen[signs] = gated
        assert region["gated"] is gated and button.get_attribute("data-gated") == str(gated).lower()
        assert (", gated" in label) is gated and (", ungated" in label) is (not gated)
        # the marker's fill: blue gated, red ungated (within the canvas' smoothing)
        blue, red = np.array([0xcf, 0xe3, 0xf5]), np.array([0xf6, 0xd0, 0xd8])
        near = np.abs(np.array(fills[k][:3]) - (blue if gated else red)).max()
        assert near <= 12 < np.abs(blue - red).max(), fills[k]
    # the paper's text: (+,+,+) and (-,-,+) ungated, the other regions of Fig. 5b gated
    assert {s for s, g in seen.items() if not g} == {"(+,+,+)", "(-,-,+)"}
    assert len(seen) >= 5
    legend = json.loads(data(browser, "map", "legend") or "[]")
    assert legend[:3] == ["gated: no rotor completes a turn", "ungated: the rotors turn fully",
                          "(τ1,τ2,τ3) of the gate four-bar"]
    element_shot(browser, "map-panel")
    assert_stayed_local(browser)


# -- 3D -------------------------------------------------------------------------------------------


def test_3d_view_rotates_and_picks(base_url: str, browser: Any) -> None:
    from selenium.webdriver.common.action_chains import ActionChains
    from selenium.webdriver.common.by import By
    from selenium.webdriver.common.keys import Keys

    open_viewer(browser, base_url, "three-rotor")
    chosen = [js(browser, f"return document.getElementById('d3-{a}').value;") for a in "xyz"]
    assert chosen == ["angle:r1", "angle:r2", "angle:r3"]  # the paper's Fig. 2c axes
    canvas = browser.find_element(By.ID, "view3d")
    yaw = data(browser, "view3d", "yaw")
    ActionChains(browser).move_to_element(canvas).click_and_hold().move_by_offset(60, 20) \
        .release().perform()
    assert data(browser, "view3d", "yaw") != yaw
    pitch = data(browser, "view3d", "pitch")
    canvas.send_keys(Keys.ARROW_DOWN)
    assert data(browser, "view3d", "pitch") != pitch

    # a click on a drawn point shows the linkage there
    point = js(browser, "const p = view3.projected[Math.floor(view3.projected.length / 3)];"
               "const c = document.getElementById('view3d');"
               "const k = c.getBoundingClientRect().width / c.width;"
               "return [p.x * k, p.y * k, p.component, p.index];")
    rect = js(browser, "const r = arguments[0].getBoundingClientRect();"
              "return [r.width, r.height];", canvas)
    ActionChains(browser).move_to_element_with_offset(
        canvas, point[0] - rect[0] / 2, point[1] - rect[1] / 2).click().perform()
    wait_for(lambda: f"component {point[2]}, point" in text(browser, "linkage-caption"), 5,
             "the picked configuration")
    element_shot(browser, "view3d-panel")

    # the points drawn are the API's: every point of every component, each at its three rotor
    # angles (wrapped to [-pi, pi), over pi) turned by yaw about the vertical and pitch about
    # the horizontal axis and projected orthographically
    linkage = json.loads(js(browser, "return JSON.stringify(state.linkage);"))
    space = post(base_url, "/v1/analysis/configuration-space", {"linkage": linkage})
    drawn = js(browser, "const c = document.getElementById('view3d');"
               "return [c.width, c.height, view3.yaw, view3.pitch,"
               " view3.projected.map((p) => [p.component, p.index, p.x, p.y])];")
    width, height, yaw, pitch, points = drawn
    assert len(points) == sum(len(c["angles"]["r1"]) for c in space["components"])
    scale = 0.32 * min(width, height)
    cy, sy, cp, sp = math.cos(yaw), math.sin(yaw), math.cos(pitch), math.sin(pitch)

    def drawn_at(angles: tuple[float, ...]) -> list[tuple[float, float]]:
        """Where a point can be drawn: -pi and pi are one angle, so at either end of an axis."""
        ends = [[u] if abs(abs(u) - 1) > 1e-9 else [-1.0, 1.0] for u in angles]
        return [(width / 2 + scale * (cy * a + sy * c),
                 height / 2 - scale * (sp * sy * a + cp * b - sp * cy * c))
                for a in ends[0] for b in ends[1] for c in ends[2]]

    for k, i, x, y in points[:: max(1, len(points) // 50)]:
        angles = tuple(((space["components"][k]["angles"][r][i] + math.pi) % math.tau - math.pi)
                       / math.pi for r in ("r1", "r2", "r3"))
        assert min(math.dist((x, y), p) for p in drawn_at(angles)) < 1e-6, (k, i)
    assert_stayed_local(browser)


# -- keyboard, contrast, the numbers shown --------------------------------------------------------


CONTRAST = """
function lum(c) {
  const [r, g, b] = c.match(/[\\d.]+/g).slice(0, 3).map(Number).map((v) => {
    v /= 255; return v <= 0.03928 ? v / 12.92 : ((v + 0.055) / 1.055) ** 2.4; });
  return 0.2126 * r + 0.7152 * g + 0.0722 * b;
}
function background(el) {
  for (; el; el = el.parentElement) {
    const c = getComputedStyle(el).backgroundColor;
    const alpha = (c.match(/[\\d.]+/g) || [])[3];
    if (c && c !== "transparent" && alpha !== "0") return c;
  }
  return "rgb(255, 255, 255)";
}
const worst = [];
for (const el of document.querySelectorAll("body *")) {
  const own = [...el.childNodes].some((n) => n.nodeType === 3 && n.textContent.trim());
  if (!own || !el.offsetParent && el.tagName !== "BODY") continue;
  const [a, b] = [lum(getComputedStyle(el).color), lum(background(el))];
  const ratio = (Math.max(a, b) + 0.05) / (Math.min(a, b) + 0.05);
  if (ratio < 4.5) worst.push([el.tagName, el.id, el.textContent.trim().slice(0, 30), ratio]);
}
return worst;
"""


def test_keyboard_reaches_every_control_and_text_is_readable(base_url: str,
                                                              browser: Any) -> None:
    from selenium.webdriver.common.by import By
    from selenium.webdriver.common.keys import Keys

    open_viewer(browser, base_url, "four-bar")
    body = browser.find_element(By.TAG_NAME, "body")
    body.click()
    seen = set()
    for _ in range(80):
        browser.switch_to.active_element.send_keys(Keys.TAB)
        el = browser.switch_to.active_element
        seen.add(el.get_attribute("id") or el.get_attribute("data-segment") or el.tag_name)
    for wanted in ("preset", "param-L2", "paste-summary", "axis-x", "linkage", "space-x", "space",
                   "split-bar", "split-dl", "split-run", "design-run", "d3-x", "view3d"):
        assert wanted in seen, (wanted, sorted(seen))
    # the drawing by keyboard: choose the joint B and move it: the lengths follow
    canvas = browser.find_element(By.ID, "linkage")
    canvas.send_keys("]", "]", "]", Keys.ARROW_RIGHT, Keys.ARROW_RIGHT)
    wait_for(lambda: lengths(browser)[1] > 1.0 and text(browser, "status") == "ready", 30,
             "the space after the keyboard move")
    # on the configuration space the arrow keys walk along the component
    before = text(browser, "linkage-caption")
    browser.find_element(By.ID, "space").send_keys(Keys.ARROW_RIGHT)
    assert text(browser, "linkage-caption") != before
    assert js(browser, CONTRAST) == []
    assert_stayed_local(browser)


def test_the_numbers_shown_equal_the_apis(base_url: str, browser: Any) -> None:
    open_viewer(browser, base_url, "four-bar")
    set_param(browser, "L2", 1.2)
    wait_for(lambda: data(browser, "map", "margin") not in (None, "", "0")
             and text(browser, "status") == "ready", 60, "the four-bar with L2 = 1.2")
    # the same linkage (the viewer writes what it asks about into its JSON box)
    linkage = json.loads(js(browser, "return document.getElementById('linkage-json').value;"))
    assert [b["length"] for b in linkage["bars"]] == [1.0, 1.2, 1.0]
    space = post(base_url, "/v1/analysis/configuration-space", {"linkage": linkage})
    assert int(data(browser, "space", "components") or -1) == len(space["components"])
    assert int(data(browser, "space", "criticalPoints") or -1) == len(space["critical_points"])
    assert int(data(browser, "space", "points") or -1) == sum(
        len(c["angles"]["L1"]) for c in space["components"])
    n = len(space["components"])
    assert text(browser, "space-caption").startswith(f"{n} component{'' if n == 1 else 's'}")

    axes = [{"bar": "L2", "min": 1.2 / 2.5, "max": 1.2 * 2.5},
            {"bar": "L3", "min": 1 / 2.5, "max": 2.5}]
    cv = post(base_url, "/v1/analysis/critical-values", {"linkage": linkage, "axes": axes})
    assert region_numbers(browser) == [(r["components"], short(r["point"][0]),
                                        short(r["point"][1])) for r in cv["regions"]]
    assert int(data(browser, "map", "curves") or -1) == len(cv["curves"])
    margin = post(base_url, "/v1/analysis/robustness",
                  {"linkage": linkage, "adjustable": ["L2", "L3"]})
    assert float(data(browser, "map", "margin") or 0) == short(margin["margin"], 6)
    # the readout of the configuration shown: the rigidity analysis of that point
    wait_for(lambda: data(browser, "readout", "rank"), 30, "the readout")
    k, i = map(int, re.findall(r"component (\d+), point (\d+)",
                               text(browser, "linkage-caption"))[0])
    walk = space["components"][k]["positions"]
    here = {**linkage, "vertices": [{**v, "position": walk[v["id"]][i]}
                                    for v in linkage["vertices"]]}
    rigidity = post(base_url, "/v1/analysis/rigidity", {"linkage": here})
    assert int(data(browser, "readout", "rank") or -1) == rigidity["rank"]
    assert int(data(browser, "readout", "dof") or -1) == rigidity["dof"]
    assert ("critical" in text(browser, "readout")) == rigidity["critical"]
    for panel in PANELS:
        element_shot(browser, panel)

    # the splitting panel's table: the service's prediction for the same perturbation, row by
    # row (Delta as shown, the sign, the rays joined)
    from selenium.webdriver.common.by import By
    from selenium.webdriver.support.ui import Select

    open_viewer(browser, base_url, "four-bar")
    linkage = json.loads(js(browser, "return document.getElementById('linkage-json').value;"))
    Select(browser.find_element(By.ID, "split-bar")).select_by_value("L3")
    field = browser.find_element(By.ID, "split-dl")
    field.clear()
    field.send_keys("0.03")
    browser.find_element(By.ID, "split-run").click()
    wait_for(lambda: data(browser, "split", "verified") is not None, 60, "the re-trace")
    split = post(base_url, "/v1/analysis/splitting",
                 {"linkage": linkage, "perturbation": {"L3": 0.03}})
    rows = [[td.text for td in r.find_elements(By.TAG_NAME, "td")]
            for r in browser.find_elements(By.CSS_SELECTOR, "#split-table tr[data-branch-point]")]
    assert rows and [r[:4] for r in rows] == [
        [f"#{b['index']}", f"{short(b['delta'])}".removesuffix(".0"),
         "+1" if b["sign"] > 0 else "−1", ", ".join(f"{p}–{q}" for p, q in b["connects"])]
        for b in split["branch_points"]]
    assert_stayed_local(browser)
