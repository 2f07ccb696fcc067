"""Shared timing helpers for the benchmarks in ``bench/`` (run on demand, never in the tests).

* :func:`best_of` -- best wall-clock time of ``repeat`` runs (``time.perf_counter``);
* :class:`Table` -- rows printed as they come and written as JSON;
* :func:`served` -- the real service in a uvicorn server on a free loopback port, so that a
  benchmark "through the API" pays HTTP and JSON cost exactly like a client;
  :func:`served_process` -- the same in a uvicorn process of its own.
"""

from __future__ import annotations

import json
import os
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import IO, Any


def best_of(fn: Callable[[], Any], repeat: int = 3) -> tuple[float, Any]:
    """Best of ``repeat`` timings of ``fn()`` and the output of the last run."""
    best, out = float("inf"), None
    for _ in range(max(1, repeat)):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return best, out


def best_of_cpu(fn: Callable[[], Any], repeat: int = 1) -> tuple[float, float, Any]:
    """Best wall-clock and best CPU time (this process, ``time.process_time``) of ``repeat``
    runs of ``fn()``, and the last output: on a shared machine the CPU time is the steadier
    number."""
    wall, cpu, out = float("inf"), float("inf"), None
    for _ in range(max(1, repeat)):
        w0, c0 = time.perf_counter(), time.process_time()
        out = fn()
        wall = min(wall, time.perf_counter() - w0)
        cpu = min(cpu, time.process_time() - c0)
    return wall, cpu, out


class Table:
    """Benchmark rows: printed as they come, written as JSON by :meth:`save`."""

    def __init__(self, title: str) -> None:
        self.title = title
        self.rows: list[dict[str, Any]] = []
        print(f"## {title}")

    def record(self, name: str, seconds: float, detail: str = "", **extra: Any) -> None:
        row = {"benchmark": name, "seconds": seconds, "detail": detail, **extra}
        self.rows.append(row)
        extras = "".join(f"  {k}={_fmt(v)}" for k, v in extra.items())
        print(f"{name:<64} {seconds:10.4f} s  {detail}{extras}", flush=True)

    def save(self, path: Path, **meta: Any) -> None:
        """Write the title, ``meta`` (e.g. the machine's load) and the rows as JSON."""
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps({"title": self.title, **meta, "rows": self.rows}, indent=2)
                        + "\n")


def _fmt(v: Any) -> str:
    return f"{v:.4g}" if isinstance(v, float) else str(v)


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@contextmanager
def served(app: Any | None = None, timeout: float = 60.0) -> Iterator[str]:
    """Run the service (``service.main.create_app()`` unless ``app`` is given) in uvicorn on a
    free loopback port in a background thread; yields the base URL and stops the server after."""
    import uvicorn

    if app is None:
        from service.main import create_app

        app = create_app()
    port = free_port()
    server = uvicorn.Server(uvicorn.Config(app, host="127.0.0.1", port=port, log_level="warning"))
    thread = threading.Thread(target=server.run, daemon=True)
    thread.start()
    url = f"http://127.0.0.1:{port}"
    wait_until_healthy(url, timeout, thread.is_alive)
    try:
        yield url
    finally:
        server.should_exit = True
        thread.join(timeout)


@contextmanager
def served_process(uvicorn_args: list[str] | tuple[str, ...] = (),
                   env: dict[str, str] | None = None, timeout: float = 60.0,
                   repo: Path | None = None, python: str | None = None,
                   log: Path | None = None) -> Iterator[str]:
    """The service as deployed: ``uvicorn service.main:app`` in a process of its own on a free
    loopback port (no client work shares its interpreter, as it does with :func:`served`), with
    more uvicorn options and environment (e.g. ``LINKAGE_WORKERS``); yields the base URL.

    ``repo`` (default: this checkout) is the working directory, so the code served is that
    tree's (``python -m`` puts it first on ``sys.path``), run by ``python`` (default: this
    interpreter); ``log`` takes the server's output (default: discarded)."""
    port = free_port()
    out: IO[str] | int = subprocess.DEVNULL if log is None else open(log, "w")
    proc = subprocess.Popen(
        [python or sys.executable, "-m", "uvicorn", "service.main:app", "--host", "127.0.0.1",
         "--port", str(port), "--log-level", "warning", *uvicorn_args],
        cwd=repo or Path(__file__).resolve().parents[1], env={**os.environ, **(env or {})},
        stdout=out, stderr=out,
    )
    url = f"http://127.0.0.1:{port}"
    try:
        wait_until_healthy(url, timeout, lambda: proc.poll() is None)
        yield url
    finally:
        proc.terminate()
        try:
            proc.wait(timeout)
        except subprocess.TimeoutExpired:
            proc.kill()
        if not isinstance(out, int):
            out.close()


def wait_until_healthy(url: str, timeout: float, alive: Callable[[], bool]) -> None:
    """Poll ``url/health`` until it answers 200; RuntimeError after ``timeout`` seconds or once
    the server is no longer ``alive``."""
    import httpx

    deadline = time.monotonic() + timeout
    while True:
        try:
            if httpx.get(url + "/health", timeout=1.0).status_code == 200:
                return
        except httpx.HTTPError:
            pass
        if time.monotonic() > deadline or not alive():
            raise RuntimeError("the service did not start")
        time.sleep(0.05)
