"""The viewer and /docs as people meet them: a real uvicorn on loopback, Debian's chromium
driven by Selenium. Screenshots are kept under tests/artifacts/ (ignored by git)."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any
from urllib.parse import urlsplit

import httpx
import pytest

from tests.service.test_uvicorn_process import HOST, ROOT, free_port, stop, wait_until_ready

ARTIFACTS = ROOT / "tests" / "artifacts"
CHROMIUM = shutil.which("chromium")
CHROMEDRIVER = shutil.which("chromedriver")
LOCAL_SCHEMES = {"data", "blob", "about", "chrome", "chrome-extension", "devtools"}

pytestmark = [
    pytest.mark.browser,
    pytest.mark.process,
    pytest.mark.skipif(
        CHROMIUM is None or CHROMEDRIVER is None,
        reason="Debian's chromium and chromium-driver are not installed (.ci/run installs them: "
        "apt-get install -y chromium chromium-driver)",
    ),
]


@pytest.fixture(scope="module")
def base_url() -> Iterator[str]:
    port = free_port()
    url = f"http://{HOST}:{port}"
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    with tempfile.TemporaryDirectory() as tmp:
        stderr_path = Path(tmp) / "uvicorn.stderr"
        with stderr_path.open("wb") as stderr:
            proc = subprocess.Popen(
                [sys.executable, "-m", "uvicorn", "service.main:app", "--host", HOST,
                 "--port", str(port), "--log-level", "warning"],
                cwd=ROOT, env=env, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                stderr=stderr,
            )
        try:
            with httpx.Client(base_url=url, trust_env=False, timeout=10.0) as client:
                wait_until_ready(client, proc, stderr_path)
            yield url
        finally:
            stop(proc)


@pytest.fixture
def browser(request: pytest.FixtureRequest) -> Iterator[Any]:
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    options = webdriver.ChromeOptions()
    options.binary_location = str(CHROMIUM)
    for arg in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
                "--window-size=1400,1000", "--no-first-run", "--disable-extensions",
                "--disable-background-networking", "--disable-component-update",
                "--disable-sync", "--disable-default-apps",
                # the network limited to the service: every address but loopback goes to a
                # proxy that is not there (port 9, discard), loopback is reached directly
                f"--proxy-server=http://{HOST}:9", "--proxy-bypass-list=127.0.0.1;localhost"):
        options.add_argument(arg)
    # The page's console and its network requests, read back after each step.
    options.set_capability("goog:loggingPrefs", {"browser": "ALL", "performance": "ALL"})
    driver = webdriver.Chrome(options=options, service=Service(executable_path=CHROMEDRIVER))
    driver.set_page_load_timeout(30)
    ARTIFACTS.mkdir(exist_ok=True)
    try:
        yield driver
    finally:  # the page as it was when the test ended, passed or failed
        driver.save_screenshot(str(ARTIFACTS / f"{request.node.name}.png"))
        driver.quit()


def shot(driver: Any, name: str) -> None:
    driver.save_screenshot(str(ARTIFACTS / name))


#: Seconds a UI change that needs a request may take before a test gives up: a bound for a
#: page that is stuck, not a latency claim (tests/service/test_browser_drag.py measures the
#: latencies), so a loaded machine's slow answers are waited for: waits of 5 and 10 s for an
#: answer drawn were shorter than one request of the served uvicorn takes at load 12.
UI_WAIT_S = 60.0


def wait_for(condition: Callable[[], Any], timeout: float, what: str) -> Any:
    """The first true value of ``condition()``, polled every 50 ms; AssertionError after
    ``timeout`` seconds (a give-up bound: at least :data:`UI_WAIT_S`)."""
    timeout = max(timeout, UI_WAIT_S)
    deadline = time.monotonic() + timeout
    while True:
        value = condition()
        if value:
            return value
        if time.monotonic() > deadline:
            raise AssertionError(f"timed out after {timeout} s waiting for {what}")
        time.sleep(0.05)


def console_errors(driver: Any) -> list[str]:
    return [e["message"] for e in driver.get_log("browser") if e["level"] == "SEVERE"]


def requested_urls(driver: Any) -> list[str]:
    """URLs the page asked for, less those the browser itself blocked before sending (e.g. by
    the page's Content-Security-Policy)."""
    urls: dict[str, str] = {}
    blocked = set()
    for entry in driver.get_log("performance"):
        message = json.loads(entry["message"])["message"]
        params = message.get("params", {})
        if message["method"] == "Network.requestWillBeSent":
            urls[params["requestId"]] = params["request"]["url"]
        elif message["method"] == "Network.loadingFailed" and params.get("blockedReason"):
            blocked.add(params["requestId"])
    return [url for rid, url in urls.items() if rid not in blocked]


def leaving(urls: list[str]) -> list[str]:
    """Requests to anywhere but this machine."""
    return [u for u in urls if urlsplit(u).scheme not in LOCAL_SCHEMES
            and urlsplit(u).hostname not in (HOST, "localhost")]


def data(driver: Any, element_id: str, key: str) -> str | None:
    value: str | None = driver.execute_script(
        "return document.getElementById(arguments[0]).dataset[arguments[1]] ?? null;",
        element_id, key)
    return value


def test_viewer_draws_the_four_bar_and_redraws_when_a_length_moves(
    base_url: str, browser: Any
) -> None:
    from selenium.webdriver.common.by import By
    from selenium.webdriver.common.keys import Keys
    from selenium.webdriver.support.ui import Select

    browser.get(f"{base_url}/viewer")
    assert urlsplit(browser.current_url).path == "/viewer/"
    select = Select(wait_for(lambda: (browser.find_elements(By.CSS_SELECTOR, "#preset option")
                                      or [None])[0] and browser.find_element(By.ID, "preset"),
                             20, "the preset list"))
    wait_for(lambda: len(select.options) > 1, 20, "the presets")
    assert data(browser, "space", "draws") == "0"

    # choosing the four-bar preset (equilateral by default) draws its configuration space
    select.select_by_value("four-bar")
    wait_for(lambda: data(browser, "space", "components"), 60, "the configuration space")
    assert data(browser, "space", "components") == "1"
    assert data(browser, "space", "criticalPoints") == "3"  # the paper's three branch points
    assert int(data(browser, "space", "points") or 0) > 50
    draws = int(data(browser, "space", "draws") or 0)
    lengths = data(browser, "space", "lengths")
    assert lengths == "1.0000,1.0000,1.0000"

    # the map of critical values arrives (JSON drawn on a canvas)
    wait_for(lambda: int(data(browser, "map", "draws") or 0) >= 1
             and data(browser, "map", "regions"), 60, "the map")
    assert int(data(browser, "map", "curves") or 0) >= 1
    shot(browser, "viewer-four-bar.png")

    # clicking the configuration space moves the linkage there
    canvas = browser.find_element(By.ID, "space")
    before = browser.find_element(By.ID, "linkage-caption").text
    browser.execute_script(
        "const c = arguments[0], r = c.getBoundingClientRect();"
        "c.dispatchEvent(new MouseEvent('click', {clientX: r.left + r.width * 0.75,"
        " clientY: r.top + r.height * 0.3, bubbles: true}));", canvas)
    wait_for(lambda: browser.find_element(By.ID, "linkage-caption").text != before, 5,
             "the linkage at the clicked configuration")

    # moving a length slider (keyboard, as a user would) redraws the configuration space
    slider = browser.find_element(By.ID, "param-L2")
    slider.send_keys(Keys.PAGE_UP)
    wait_for(lambda: data(browser, "space", "lengths") not in (None, lengths), 30,
             "the configuration space of the new lengths")
    new_lengths = (data(browser, "space", "lengths") or "").split(",")
    assert new_lengths[0] == "1.0000" and new_lengths[2] == "1.0000"
    assert float(new_lengths[1]) > 1.0
    assert int(data(browser, "space", "draws") or 0) > draws
    # off the critical lengths the branch points are gone
    assert data(browser, "space", "criticalPoints") == "0"
    shot(browser, "viewer.png")

    assert console_errors(browser) == []
    urls = requested_urls(browser)
    assert any("/v1/analysis/configuration-space" in u for u in urls)
    assert leaving(urls) == []


def test_docs_list_every_operation_offline(base_url: str, browser: Any) -> None:
    from selenium.webdriver.common.by import By

    spec = httpx.get(f"{base_url}/openapi.json", trust_env=False).json()
    operations = {(method.upper(), path) for path, item in spec["paths"].items()
                  for method in item}
    browser.get(f"{base_url}/docs")
    wait_for(lambda: len(browser.find_elements(By.CSS_SELECTOR, ".opblock")) >= len(operations),
             20, "Swagger UI's operations")
    shown = {
        (b.find_element(By.CSS_SELECTOR, ".opblock-summary-method").text.strip(),
         b.find_element(By.CSS_SELECTOR, ".opblock-summary-path").get_attribute(
             "data-path"))
        for b in browser.find_elements(By.CSS_SELECTOR, ".opblock")
    }
    assert shown == operations
    shot(browser, "docs.png")
    urls = requested_urls(browser)
    assert console_errors(browser) == []

    browser.get(f"{base_url}/redoc")
    wait_for(lambda: browser.find_elements(By.CSS_SELECTOR, "[data-section-id^='operation']"),
             20, "ReDoc's operations")
    assert len(browser.find_elements(By.CSS_SELECTOR, "[data-section-id^='operation']")) \
        == len(operations)
    shot(browser, "redoc.png")
    urls += requested_urls(browser)
    # ReDoc's logo is the service's own (service/docs.py): no refusal, no error
    assert console_errors(browser) == []
    assert any("/static-offline-docs/swagger-ui-bundle.js" in u for u in urls)
    assert any("/static-offline-docs/redoc.standalone.js" in u for u in urls)
    assert leaving(urls) == []


def test_viewer_gate_slider_offers_only_gates_the_service_takes(
    base_url: str, browser: Any
) -> None:
    from selenium.webdriver.common.by import By
    from selenium.webdriver.support.ui import Select

    browser.get(f"{base_url}/viewer")
    wait_for(lambda: len(browser.find_elements(By.CSS_SELECTOR, "#preset option")) > 1, 20,
             "the presets")
    Select(browser.find_element(By.ID, "preset")).select_by_value("gated-kl-chain")
    gate = wait_for(lambda: (browser.find_elements(By.ID, "param-gate") or [None])[0], 20,
                    "the gate slider")
    n = browser.find_element(By.ID, "param-n")

    def offered() -> tuple[int, int, int]:
        return tuple(int(float(browser.execute_script(f"return arguments[0].{k};", gate)))
                     for k in ("min", "max", "value"))  # type: ignore[return-value]

    for n_value in (int(float(n.get_attribute("value"))), 6, 3, 2):
        # as a user dragging the n slider: its value changes, then "input" fires
        browser.execute_script("arguments[0].value = arguments[1];"
                               "arguments[0].dispatchEvent(new Event('input'));", n, n_value)
        low, high, value = offered()
        assert (low, high) == (0, n_value - 1) and low <= value <= high
        for g in (low, high):  # both ends are taken, one past the end is not
            ok = httpx.get(f"{base_url}/v1/presets/gated-kl-chain",
                           params={"n": n_value, "gate": g}, trust_env=False)
            assert ok.status_code == 200, ok.text
        refused = httpx.get(f"{base_url}/v1/presets/gated-kl-chain",
                            params={"n": n_value, "gate": high + 1}, trust_env=False)
        assert refused.status_code == 422
    assert console_errors(browser) == []


def test_docs_prefill_the_schemas_example(base_url: str, browser: Any) -> None:
    """Swagger UI's "Try it out" body for an analysis is the schema's example (a valid request:
    tests/service/test_examples.py posts it), not one built from the fields' bounds."""
    from selenium.webdriver.common.by import By

    browser.get(f"{base_url}/docs#/analysis/analyseRigidity")
    block = wait_for(lambda: (browser.find_elements(
        By.CSS_SELECTOR, "#operations-analysis-analyseRigidity") or [None])[0], 20,
        "the rigidity operation")
    if not block.find_elements(By.CSS_SELECTOR, ".opblock-body"):
        block.find_element(By.CSS_SELECTOR, ".opblock-summary").click()
    code = wait_for(lambda: [e.text for e in block.find_elements(
        By.CSS_SELECTOR, ".body-param__example, .opblock-body pre") if "residual_atol" in e.text],
        20, "the request body's example")
    shown = json.loads(code[0])
    spec = httpx.get(f"{base_url}/openapi.json", trust_env=False).json()
    assert shown == spec["components"]["schemas"]["AnalysisRequest"]["examples"][0]
    assert shown["tolerances"]["residual_atol"] == 1e-9
    assert console_errors(browser) == []


def test_the_browser_reaches_only_the_machine(base_url: str, browser: Any) -> None:
    """The tests' browser has no way out: the service answers, an outside address does not (the
    page-level checks that no request left are backed by a network that has no exit)."""
    from selenium.common.exceptions import WebDriverException

    with pytest.raises(WebDriverException, match="ERR_PROXY_CONNECTION_FAILED"):
        browser.get("http://example.com/")
    browser.get(f"{base_url}/health")
    assert "ok" in browser.page_source.lower()
    outcome = browser.execute_async_script(
        "const done = arguments[arguments.length - 1];"
        "fetch('http://93.184.215.14/', {mode: 'no-cors'}).then(() => done('reached'),"
        " (e) => done('failed: ' + e.message));")
    assert outcome.startswith("failed"), outcome
