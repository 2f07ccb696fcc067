"""Hardening as clients meet it (issue 17), against one real uvicorn process started with the
README's command (plus short timeouts): slow clients lose their connection while others are
served, large bodies neither stall small requests nor wait for a 422, invented methods add no
metric series, and every request leaves one parseable JSON access-log line on stdout.

Bounds on time are the issue's; each is measured up to three times and the best attempt counts
(this machine is shared: other jobs only ever add delay, so the best attempt is the service's own
behaviour), and the baselines are measured in the same attempt. When every attempt misses the
bound while the machine is overloaded (load average above twice its cores: each process then
gets a fraction of a core, and any pause of a few ms stretches accordingly), the test is skipped
with the measurement rather than passed or failed: the bound cannot be judged then.
"""

from __future__ import annotations

import json
import os
import socket
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import httpx
import pytest

from tests.service.test_uvicorn_process import HOST, ROOT, free_port, stop, wait_until_ready

pytestmark = pytest.mark.process

HEADER_TIMEOUT = 1.0
BODY_TIMEOUT = 1.5
SLOW_CLIENTS = 20


def readme_start_command() -> list[str]:
    """The uvicorn arguments of the README's first command (host and port replaced)."""
    readme = (ROOT / "README.md").read_text()
    line = next(ln for ln in readme.splitlines() if ".venv/bin/uvicorn service.main:app" in ln)
    args = line.split(".venv/bin/uvicorn ", 1)[1].split()
    assert args[0] == "service.main:app"
    assert "--http" in args and args[args.index("--http") + 1] == \
        "service.protocol:GuardedH11Protocol"
    return args


class Served:
    def __init__(self, proc: subprocess.Popen[bytes], port: int, stdout: Path) -> None:
        self.proc, self.port, self.stdout = proc, port, stdout
        self.base_url = f"http://{HOST}:{port}"

    def client(self, timeout: float = 30.0) -> httpx.Client:
        return httpx.Client(base_url=self.base_url, trust_env=False, timeout=timeout)

    def log_lines(self) -> list[dict[str, Any]]:
        lines = []
        for text in self.stdout.read_text(errors="replace").splitlines():
            if text.startswith("{"):
                lines.append(json.loads(text))
        return lines


@pytest.fixture(scope="module")
def served() -> Iterator[Served]:
    args = readme_start_command()
    port = free_port()
    args[args.index("--host") + 1] = HOST
    args[args.index("--port") + 1] = str(port)
    env = {**os.environ, "PYTHONUNBUFFERED": "1", "LINKAGE_WORKERS": "1",
           "LINKAGE_HEADER_TIMEOUT_S": str(HEADER_TIMEOUT),
           "LINKAGE_BODY_TIMEOUT_S": str(BODY_TIMEOUT)}
    with tempfile.TemporaryDirectory() as tmp:
        stdout_path, stderr_path = Path(tmp) / "stdout", Path(tmp) / "stderr"
        with stdout_path.open("wb") as out, stderr_path.open("wb") as err:
            proc = subprocess.Popen([sys.executable, "-m", "uvicorn", *args], cwd=ROOT, env=env,
                                    stdin=subprocess.DEVNULL, stdout=out, stderr=err)
        try:
            with httpx.Client(base_url=f"http://{HOST}:{port}", trust_env=False) as c:
                wait_until_ready(c, proc, stderr_path)
            yield Served(proc, port, stdout_path)
        finally:
            stop(proc)


def overloaded() -> bool:
    return os.getloadavg()[0] > 2 * (os.cpu_count() or 1)


def check_bound(ok: bool, message: str) -> None:
    if not ok and overloaded():
        pytest.skip(f"machine overloaded (load {os.getloadavg()[0]:.1f}): {message}")
    assert ok, message


def best_of(attempts: int, run: Any) -> Any:
    """``run()`` returns ``(ok, measurement)``; up to ``attempts`` tries, the first good one
    (else the last) is returned."""
    result = None
    for _ in range(attempts):
        ok, result = run()
        if ok:
            break
    return result


class HealthProbe:
    """Asks ``/health`` every 10 ms on its own keep-alive connection, recording latencies."""

    def __init__(self, served: Served) -> None:
        self.served = served
        self.latencies: list[float] = []
        self.statuses: list[int] = []
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)

    def _run(self) -> None:
        with self.served.client(timeout=10) as c:
            while not self._stop.is_set():
                t = time.perf_counter()
                r = c.get("/health")
                self.latencies.append(time.perf_counter() - t)
                self.statuses.append(r.status_code)
                time.sleep(0.01)

    def __enter__(self) -> HealthProbe:
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        self._thread.join()


def raw_exchange(port: int, head: bytes, body: bytes = b"") -> tuple[float, bytes]:
    """Send a whole request on a fresh socket (``sendall`` releases the GIL, so the probe in
    this process is not held up by the client's own work) and read until the server closes.
    Returns (seconds, raw answer)."""
    with socket.create_connection((HOST, port)) as s:
        t = time.perf_counter()
        s.sendall(head + body)
        chunks = []
        while chunk := s.recv(1 << 20):
            chunks.append(chunk)
        return time.perf_counter() - t, b"".join(chunks)


def post_head(path: str, length: int, content_type: str = "application/json") -> bytes:
    return (f"POST {path} HTTP/1.1\r\nhost: {HOST}\r\ncontent-type: {content_type}\r\n"
            f"content-length: {length}\r\nconnection: close\r\n\r\n").encode()


def status_and_json(raw: bytes) -> tuple[int, Any]:
    head, _, body = raw.partition(b"\r\n\r\n")
    status = int(head.split(b" ", 2)[1])
    return status, json.loads(body) if body.startswith(b"{") else None


# --- slow clients ------------------------------------------------------------------------


def drip(port: int, payload: bytes, interval: float, give_up: float,
         prefix: bytes = b"") -> tuple[float, bytes]:
    """Send ``prefix`` at once, then ``payload`` one byte per ``interval`` until the server
    closes the connection; returns (seconds until closed, what the server sent). Fails after
    ``give_up`` seconds."""
    with socket.create_connection((HOST, port)) as s:
        s.settimeout(interval)
        t0 = time.monotonic()
        s.sendall(prefix)
        received = b""
        for i in range(10**6):
            try:
                s.send(payload[i % len(payload):i % len(payload) + 1])
            except OSError:  # reset: closed
                return time.monotonic() - t0, received
            try:
                chunk = s.recv(4096)
                if not chunk:
                    return time.monotonic() - t0, received
                received += chunk
            except TimeoutError:
                pass
            except OSError:
                return time.monotonic() - t0, received
            if time.monotonic() - t0 > give_up:
                raise AssertionError(f"still connected after {give_up} s")
        raise AssertionError("unreachable")


def test_slow_clients_are_disconnected_within_the_header_timeout_while_health_answers(
        served: Served) -> None:
    head = f"GET /health HTTP/1.1\r\nhost: {HOST}\r\nx-padding: ".encode() + b"a" * 10_000
    results: list[tuple[float, bytes]] = []
    errors: list[BaseException] = []

    def one() -> None:
        try:
            results.append(drip(served.port, head, 0.1, give_up=HEADER_TIMEOUT + 10))
        except BaseException as err:  # reported below
            errors.append(err)

    threads = [threading.Thread(target=one) for _ in range(SLOW_CLIENTS)]
    with HealthProbe(served) as probe:
        for th in threads:
            th.start()
        for th in threads:
            th.join()
    assert not errors, errors
    assert len(results) == SLOW_CLIENTS
    for seconds, received in results:
        # disconnected within the timeout (plus scheduling slack on a shared machine)
        assert HEADER_TIMEOUT - 0.05 <= seconds < HEADER_TIMEOUT + 2.0, seconds
        status, problem = status_and_json(received)
        assert status == 408 and problem["type"] == "/problems/header-timeout"
    assert probe.statuses and set(probe.statuses) == {200}
    assert len(probe.statuses) >= 10  # /health kept answering all along
    assert max(probe.latencies) < HEADER_TIMEOUT  # never waited for the slow ones


def test_idle_connection_is_closed_after_the_header_timeout(served: Served) -> None:
    with socket.create_connection((HOST, served.port)) as s:
        s.settimeout(HEADER_TIMEOUT + 10)
        t0 = time.monotonic()
        assert s.recv(100) == b""  # closed without a word: no request was begun
        assert time.monotonic() - t0 < HEADER_TIMEOUT + 2.0


def test_slow_body_gets_408_within_the_body_timeout(served: Served) -> None:
    payload = b'{"linkage": {"vertices": []}}' + b" " * 1000
    head = post_head("/v1/analysis/rigidity", len(payload))
    seconds, received = drip(served.port, payload, 0.05, give_up=BODY_TIMEOUT + 10,
                             prefix=head)
    status, problem = status_and_json(received)
    assert status == 408 and problem["type"] == "/problems/body-timeout", received[:300]
    assert "LINKAGE_BODY_TIMEOUT_S" in problem["detail"]
    assert BODY_TIMEOUT - 0.05 <= seconds < BODY_TIMEOUT + 2.0, seconds
    with served.client() as c:
        assert c.get("/health").status_code == 200


# --- large bodies ------------------------------------------------------------------------


@pytest.fixture(scope="module")
def chain_body() -> bytes:
    from engine.catalogue.presets import build_preset
    from service.mappers import linkage_out

    lk = linkage_out(build_preset("kl-chain", {"n": 15_000})).model_dump(mode="json")
    body = json.dumps({"linkage": lk}).encode()
    assert 3.9e6 < len(body) < 4.5e6  # the size
    return body


def test_a_4mb_body_does_not_delay_health(served: Served, chain_body: bytes) -> None:
    def attempt() -> tuple[bool, tuple[float, int, float]]:
        with HealthProbe(served) as probe:
            time.sleep(0.3)
            baseline = sorted(probe.latencies)[len(probe.latencies) // 2]
            n_before = len(probe.latencies)
            _, raw = raw_exchange(served.port, post_head("/v1/analysis/rigidity",
                                                         len(chain_body)), chain_body)
            time.sleep(0.1)
        during = probe.latencies[n_before:]
        delay = max(during) - baseline
        status, _ = status_and_json(raw)
        return delay < 0.1, (delay, status, len(during))

    delay, status, probes = best_of(3, attempt)
    assert status == 200
    assert probes >= 10
    check_bound(delay < 0.1, f"/health delayed by {1e3 * delay:.0f} ms by a 4 MB body")


def test_an_over_limit_linkage_is_refused_fast(served: Served) -> None:
    n = 50_001  # LINKAGE_MAX_VERTICES is 50000
    body = json.dumps({"linkage": {
        "vertices": [{"id": f"v{i}", "position": [0.5 * i, 0.25 * (i % 7)]} for i in range(n)],
        "bars": [{"id": f"b{i}", "ends": [f"v{i}", f"v{i + 1}"]} for i in range(40_000)],
    }}).encode()
    assert len(body) > 3.9e6

    def attempt() -> tuple[bool, tuple[float, int, Any]]:
        seconds, raw = raw_exchange(served.port, post_head("/v1/analysis/rigidity", len(body)),
                                    body)
        status, problem = status_and_json(raw)
        return seconds < 0.5, (seconds, status, problem)

    seconds, status, problem = best_of(3, attempt)
    assert status == 422 and problem["type"] == "/problems/limit-exceeded", problem
    assert problem["errors"][0]["loc"] == ["body", "linkage", "vertices"]
    check_bound(seconds < 0.5, f"refused after {seconds:.2f} s")


def test_large_bodies_are_validated_like_small_ones(served: Served, chain_body: bytes) -> None:
    bad = chain_body.replace(b'"id": "T14999"', b'"id": "T\\u000014999"', 1)
    assert bad != chain_body
    _, raw = raw_exchange(served.port, post_head("/v1/analysis/rigidity", len(bad)), bad)
    status, problem = status_and_json(raw)
    assert status == 422 and problem["type"] == "/problems/validation-error"
    loc = problem["errors"][0]["loc"]
    assert loc[:4] == ["body", "linkage", "vertices", loc[3]] and loc[-1] == "id"
    broken = chain_body[:-10]
    _, raw = raw_exchange(served.port, post_head("/v1/analysis/rigidity", len(broken)), broken)
    status, problem = status_and_json(raw)
    assert status == 422 and problem["errors"][0]["loc"][0] == "body"
    assert problem["errors"][0]["msg"] == "JSON decode error"


# --- metrics and the access log ----------------------------------------------------------


def series(text: str) -> set[str]:
    return {line.rsplit(" ", 1)[0] for line in text.splitlines()
            if line.startswith("linkage_requests_total{")}


def test_invented_methods_add_no_metric_series(served: Served) -> None:
    with served.client() as c:
        c.request("ZZMETHOD0", "/health")
        before = series(c.get("/metrics").text)
        for i in range(1, 51):
            assert c.request(f"ZZMETHOD{i}", "/health").status_code == 405
            assert c.request(f"ZZMETHOD{i}", f"/nowhere/{i}").status_code == 404
        text = c.get("/metrics").text
    after = series(text)
    assert after - before <= {'linkage_requests_total{method="GET",route="/metrics",status="200"}',
                              'linkage_requests_total{method="other",route="other",status="404"}'}
    assert not any("ZZMETHOD" in s or "/nowhere" in s for s in after)
    assert 'linkage_requests_total{method="other",route="/health",status="405"}' in after


def test_every_request_leaves_one_json_access_log_line(served: Served) -> None:
    with served.client() as c:
        answers = [c.get("/health"), c.get("/v1/presets/four-bar"), c.get("/docs"),
                   c.get("/no/such/page"),
                   c.post("/v1/analysis/rigidity", content=b"x", headers={"content-type":
                                                                          "text/plain"})]
        lk = answers[1].json()
        answers.append(c.post("/v1/analysis/rigidity", json={"linkage": lk}))
    expected = {r.headers["x-request-id"]: r for r in answers}
    deadline = time.monotonic() + 5
    while True:
        lines = {ln["request_id"]: ln for ln in served.log_lines() if ln["request_id"]}
        if set(expected) <= set(lines) or time.monotonic() > deadline:
            break
        time.sleep(0.05)
    assert set(expected) <= set(lines), "missing access-log lines"
    routes = []
    for request_id, r in expected.items():
        line = lines[request_id]
        assert line["status"] == r.status_code
        assert line["method"] == r.request.method and line["path"] == r.request.url.path
        assert isinstance(line["duration_ms"], float) and line["duration_ms"] >= 0
        routes.append(line["route"])
    # (each preset has a route of its own: its template is its path, a bounded label)
    assert routes == ["/health", "/v1/presets/four-bar", "/docs", "other",
                      "/v1/analysis/rigidity", "/v1/analysis/rigidity"]
    assert [r.status_code for r in answers] == [200, 200, 200, 404, 415, 200]
