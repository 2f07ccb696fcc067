"""Hostile inputs that were 500s (issue 28, item 4), sent to a real uvicorn server on a
loopback port over one kept-alive connection: each is answered 4xx (or 200) with
problem+json, and the next request on the same connection is served. A 500 used to close the
connection (uvicorn closes one whose application raised), failing the client's next request.
"""

from __future__ import annotations

import json
import socket
import threading
import time
from collections.abc import Iterator
from typing import Any

import pytest
import uvicorn
from fastapi import FastAPI

from service.config import Settings
from service.main import create_app
from service.protocol import GuardedH11Protocol
from tests.load import Timer
from tests.service.test_uvicorn_process import HOST, STARTUP_TIMEOUT, free_port

pytestmark = pytest.mark.process


class Server:
    """uvicorn serving ``app`` in a thread of this process (with its lifespan: the workers
    start as in production), on a free loopback port."""

    def __init__(self, app: FastAPI) -> None:
        self.port = free_port()
        self.app = app
        config = uvicorn.Config(app, host=HOST, port=self.port, log_level="warning",
                                http=GuardedH11Protocol, access_log=False)
        self.server = uvicorn.Server(config)
        self.thread = threading.Thread(target=self.server.run, daemon=True)

    def __enter__(self) -> Server:
        self.thread.start()
        deadline = time.monotonic() + STARTUP_TIMEOUT
        # ready, as an orchestrator routes to it (/health/ready): the lifespan starts the
        # workers in the background once the port is open, and a request sent before then
        # lands on their start-up (the server closed the connection at load 12)
        while not (self.server.started and self.app.state.engine_pool.ready):
            assert time.monotonic() < deadline and self.thread.is_alive(), "did not start"
            time.sleep(0.05)
        return self

    def __exit__(self, *exc: object) -> None:
        self.server.should_exit = True
        self.thread.join(timeout=30)


class Connection:
    """One HTTP/1.1 connection, kept alive, read by hand: a closed connection is an error,
    never silently reopened (as client libraries do)."""

    def __init__(self, port: int) -> None:
        self.sock = socket.create_connection((HOST, port), timeout=120)
        self.buffer = b""

    def close(self) -> None:
        self.sock.close()

    def _read_until(self, marker: bytes) -> bytes:
        while marker not in self.buffer:
            chunk = self.sock.recv(1 << 16)
            if not chunk:
                raise ConnectionError("the server closed the connection")
            self.buffer += chunk
        head, self.buffer = self.buffer.split(marker, 1)
        return head

    def request(self, method: str, path: str,
                body: bytes | None = None) -> tuple[int, dict[str, str], bytes]:
        head = f"{method} {path} HTTP/1.1\r\nHost: {HOST}\r\n"
        if body is not None:
            head += f"Content-Type: application/json\r\nContent-Length: {len(body)}\r\n"
        self.sock.sendall(head.encode() + b"\r\n" + (body or b""))
        lines = self._read_until(b"\r\n\r\n").decode("latin-1").split("\r\n")
        status = int(lines[0].split()[1])
        headers = {k.lower(): v.strip() for k, v in (h.split(":", 1) for h in lines[1:])}
        length = int(headers["content-length"])
        while len(self.buffer) < length:
            chunk = self.sock.recv(1 << 16)
            if not chunk:
                raise ConnectionError("the server closed the connection mid-answer")
            self.buffer += chunk
        data, self.buffer = self.buffer[:length], self.buffer[length:]
        return status, headers, data


@pytest.fixture(scope="module")
def server() -> Iterator[Server]:
    app = create_app(Settings(workers=1, time_limit_s=60))
    with Server(app) as s:
        yield s


@pytest.fixture()
def conn(server: Server) -> Iterator[Connection]:
    c = Connection(server.port)
    yield c
    c.close()


def still_serving(conn: Connection) -> None:
    status, headers, data = conn.request("GET", "/health")
    assert status == 200 and json.loads(data)["status"] == "ok"
    assert headers.get("connection") != "close"


def problem_of(status: int, headers: dict[str, str], data: bytes, expected: int) -> Any:
    assert status == expected, data[:500]
    assert headers["content-type"].startswith("application/problem+json")
    body = json.loads(data)
    assert body["status"] == expected and body["detail"]
    return body


@pytest.mark.parametrize("n", [55, 65, 70])
def test_a_kl_chain_with_more_components_than_a_json_number_holds(conn, n):
    """2^(n-1) components: beyond 2^53 - 1 the count is a decimal string (beyond 2^64 the
    JSON encoder refused the integer: a 500)."""
    status, _, data = conn.request("GET", f"/v1/presets/kl-chain?n={n}")
    assert status == 200
    body = json.dumps({"linkage": json.loads(data),
                       "options": {"max_components": 2, "angles": 8}}).encode()
    status, _, data = conn.request("POST", "/v1/analysis/configuration-space", body)
    assert status == 200, data[:500]
    search = json.loads(data)["search"]
    assert search["components_total"] == str(2 ** (n - 1))  # the chain-count rule, exact
    assert int(search["components_total"]) > 2**53 - 1
    still_serving(conn)


@pytest.mark.parametrize("depth", [5_000, 300_000])
def test_json_nested_deeper_than_the_parser_allows_is_a_400(conn, depth):
    # 600 kB for 300,000 levels: the path for bodies over 256 kB, parsed in a worker
    body = b'{"linkage": ' + b"[" * depth + b"]" * depth + b"}"
    problem = problem_of(*conn.request("POST", "/v1/analysis/rigidity", body), 400)
    assert problem["errors"][0]["loc"] == ["body"]
    if depth > 256 * 1024:
        assert "nested deeper" in problem["detail"]
    still_serving(conn)


def test_an_unhandled_error_is_a_500_and_the_connection_is_kept():
    """Any error the service did not foresee: a 500 problem, and the next request on the same
    connection is answered (Starlette re-raises after its 500 and uvicorn then closed the
    connection)."""
    app = create_app(Settings(workers=1))

    @app.get("/boom")
    async def boom() -> None:
        raise RuntimeError("not foreseen")

    with Server(app) as s:
        c = Connection(s.port)
        try:
            problem = problem_of(*c.request("GET", "/boom"), 500)
            assert problem["type"] == "/problems/internal-error"
            still_serving(c)
        finally:
            c.close()


def parallel_bars(n_bars: int) -> dict[str, Any]:
    """3 vertices (one pinned) and ``n_bars`` bars spread over their three pairs: M = 4 free
    coordinates, so at least n_bars - 4 self-stresses of n_bars entries each."""
    pairs = (["a", "b"], ["b", "c"], ["a", "c"])
    return {"dimension": 2,
            "vertices": [{"id": "a", "position": [0.0, 0.0], "fixed": True},
                         {"id": "b", "position": [1.0, 0.0]},
                         {"id": "c", "position": [0.3, 0.8]}],
            "bars": [{"id": f"e{i}", "ends": pairs[i % 3]} for i in range(n_bars)]}


def complete_graph_3d(n: int) -> dict[str, Any]:
    """K_n in 3D on generic points: n(n-1)/2 bars against 3n coordinates."""
    points = [[float(i), float(i * i % 7), float(i * i * i % 11)] for i in range(n)]
    return {"dimension": 3,
            "vertices": [{"id": f"v{i}", "position": p} for i, p in enumerate(points)],
            "bars": [{"id": f"e{i}_{j}", "ends": [f"v{i}", f"v{j}"]}
                     for i in range(n) for j in range(i + 1, n)]}


@pytest.mark.parametrize("linkage, numbers", [
    (parallel_bars(4500), (4500 - 4) * 4500),  # 582 MB of JSON before (12.6 s, 2.74 GB)
    (complete_graph_3d(100), (4950 - 300) * 4950),  # 693 MB before
])
def test_an_answer_beyond_the_answer_limit_is_refused_before_any_work(conn, linkage, numbers):
    body = json.dumps({"linkage": linkage}).encode()
    with Timer() as t:  # (the server runs in this process: its slowdown is this one's)
        problem = problem_of(*conn.request("POST", "/v1/analysis/rigidity", body), 422)
    assert problem["type"] == "/problems/limit-exceeded"
    assert "LINKAGE_MAX_ANSWER_MB = 256" in problem["detail"]
    # rank-nullity: at least E - M self-stresses of E entries, whatever the rank
    assert f"at least {numbers:,} numbers" in problem["detail"]
    assert problem["errors"][0]["loc"] == ["body", "linkage"]
    assert t.within(0.0, 10.0), t  # refused from the sizes, not after the SVD (idle seconds)
    still_serving(conn)


def test_an_answer_within_the_limit_is_served(conn):
    """900 bars on the three sides of a triangle pinned at one vertex: rank 3 (three bar
    directions), so 897 self-stresses and one zero mode (the turn about the pin); some 24 MB
    of JSON, answered in full."""
    body = json.dumps({"linkage": parallel_bars(900)}).encode()
    status, _, data = conn.request("POST", "/v1/analysis/rigidity", body)
    assert status == 200
    answer = json.loads(data)
    assert len(answer["self_stresses"]) == 900 - 3 and len(answer["zero_modes"]) == 1
    still_serving(conn)
