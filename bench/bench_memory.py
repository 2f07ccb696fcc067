"""Peak worker memory and time of floppy chains through the service (run on demand, never in
the tests; issue 11, item 4).

    .venv/bin/python bench/bench_memory.py [--free 8000 49998] [--json bench/results/memory.json]
        [--env LINKAGE_WORKER_MEMORY_MB=2048]

A floppy chain: two pins joined by a zigzag path of ``free`` free vertices (``free + 1`` bars,
lengths the current distances). It has ``M - E = free - 1`` independent zero modes, so its
first-order answer is a dense (k, M) array of about ``2 free^2`` numbers: 8,000 free vertices
(a 0.74 MB body) mean 128 million numbers, 49,998 (50,000 vertices, the size limit) five
billion.

Each size is posted to ``/v1/analysis/rigidity`` and ``/v1/analysis/second-order``, each
request to a fresh ``uvicorn service.main:app`` process (one engine worker,
``LINKAGE_WORKERS=1``, plus any ``--env``). Recorded per request: the status and problem type, the
wall-clock time, and the peak resident size of the engine worker(s) while it ran: every
descendant of the server process (the forkserver and its workers) is sampled every 20 ms
(``VmRSS`` from ``/proc``), and the largest sample is reported with the worker's own
high-water mark (``VmHWM``) where it is still alive. After each request ``/health`` must still
answer.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import httpx

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bench.harness import Table, served_process  # noqa: E402


def floppy_chain(free: int) -> dict[str, Any]:
    """JSON linkage: pins ``P0`` and ``P1`` joined by a zigzag path of ``free`` free vertices."""
    vertices: list[dict[str, Any]] = [{"id": "P0", "position": [0.0, 0.0], "fixed": True}]
    vertices += [{"id": f"v{k}", "position": [0.5 * k, 0.3 * (k % 2)]}
                 for k in range(1, free + 1)]
    vertices.append({"id": "P1", "position": [0.5 * (free + 1), 0.0], "fixed": True})
    ids = [v["id"] for v in vertices]
    bars = [{"id": f"b{k}", "ends": [ids[k], ids[k + 1]]} for k in range(len(ids) - 1)]
    return {"dimension": 2, "vertices": vertices, "bars": bars}


def _descendants(root: int) -> list[int]:
    children: dict[int, list[int]] = {}
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            stat = Path(f"/proc/{entry}/stat").read_text()
        except OSError:
            continue
        ppid = int(stat.rsplit(")", 1)[1].split()[1])
        children.setdefault(ppid, []).append(int(entry))
    out, todo = [], [root]
    while todo:
        for child in children.get(todo.pop(), []):
            out.append(child)
            todo.append(child)
    return out


def _status_kb(pid: int, field: str) -> int:
    try:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith(field + ":"):
                return int(line.split()[1])
    except OSError:
        pass
    return 0


@contextmanager
def peak_rss(root: int) -> Iterator[dict[str, int]]:
    """Largest ``VmRSS`` (kB) of any descendant of ``root`` while the block runs, sampled every
    20 ms, and the largest ``VmHWM`` of the live ones at the end (key ``kb``)."""
    peak = {"kb": 0}
    stop = threading.Event()

    def sample() -> None:
        while not stop.is_set():
            for pid in _descendants(root):
                peak["kb"] = max(peak["kb"], _status_kb(pid, "VmRSS"))
            stop.wait(0.02)

    thread = threading.Thread(target=sample, daemon=True)
    thread.start()
    try:
        yield peak
    finally:
        stop.set()
        thread.join()
        for pid in _descendants(root):
            peak["kb"] = max(peak["kb"], _status_kb(pid, "VmHWM"))


def _server_pid(url: str) -> int:
    port = url.rsplit(":", 1)[1]
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            try:
                cmd = Path(f"/proc/{entry}/cmdline").read_bytes().split(b"\0")
            except OSError:
                continue
            if b"uvicorn" in b" ".join(cmd) and port.encode() in cmd:
                return int(entry)
    raise RuntimeError("server process not found")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--free", type=int, nargs="+", default=[8000, 49998])
    parser.add_argument("--json", type=Path, default=Path("bench/results/memory.json"))
    parser.add_argument("--env", nargs="*", default=[], help="NAME=VALUE for the service")
    args = parser.parse_args()
    env = {"LINKAGE_WORKERS": "1", **dict(e.split("=", 1) for e in args.env)}
    settings = " ".join(f"{k}={v}" for k, v in env.items())
    table = Table(f"floppy chains through the service ({settings})")
    for free in args.free:
        body = json.dumps({"linkage": floppy_chain(free)}).encode()
        for route in ("/v1/analysis/rigidity", "/v1/analysis/second-order"):
            # a fresh server each time: the worker's high-water mark is this request's alone
            with served_process(env=env) as url, httpx.Client(base_url=url, timeout=600) as client:
                with peak_rss(_server_pid(url)) as peak:
                    t0 = time.perf_counter()
                    r = client.post(route, content=body,
                                    headers={"content-type": "application/json"})
                    took = time.perf_counter() - t0
                kind = (r.json().get("type", "") if r.headers.get("content-type", "")
                        .startswith("application/problem+json") else "")
                health = client.get("/health").status_code
            table.record(f"{route} free={free}", took, f"{r.status_code} {kind}".strip(),
                         body_mb=len(body) / 1e6, peak_worker_mb=peak["kb"] / 1024,
                         health=health)
    table.save(args.json)


if __name__ == "__main__":
    main()
