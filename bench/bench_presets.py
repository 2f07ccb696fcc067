"""Every preset with its default parameters through every synchronous POST endpoint it is
meaningful for (issue 11), over HTTP, one request at a time (run on demand).

    .venv/bin/python bench/bench_presets.py [--time-limit 30] [--only four-bar kl-chain]
                                            [--json bench/results/presets.json]
    # the same matrix on another checkout (e.g. the code before a change), served by its venv:
    /work/wt/before/.venv/bin/python bench/bench_presets.py --repo /work/wt/before \\
                                     --json bench/results/presets-before.json

The cases come from ``tests/service/preset_matrix.py`` (loaded by path, so this script runs
against any checkout): each preset from ``GET /v1/presets/{name}`` with defaults, then the
endpoints that its linkage is meaningful for. The service runs as ``uvicorn service.main:app``
in a process of its own, started in ``--repo`` (default: this checkout) by that checkout's
``.venv/bin/python`` when there is one (else this interpreter); the JSON records which files
that interpreter imports ``service`` and ``engine`` from, and the checkout's commit. Each row:
HTTP status, wall seconds of the request, and for JSON answers ``search.complete`` and
``search.reason`` where present; for an error, the problem's title and detail. The machine's
load average is recorded per row: on a shared machine the seconds are an upper bound.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import os
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import httpx
from harness import Table, served_process  # bench/ is on sys.path when run as a script

HERE = Path(__file__).resolve().parents[1]


def load_matrix() -> Any:
    """``tests/service/preset_matrix.py`` of this checkout, by path (the served checkout may
    not have it)."""
    spec = importlib.util.spec_from_file_location(
        "preset_matrix", HERE / "tests" / "service" / "preset_matrix.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


class TimedClient:
    """An ``httpx.Client`` whose POSTs are timed and remembered by (path, body): the matrix
    asks critical-points to decide on a design case, and that answer is the one measured."""

    def __init__(self, client: httpx.Client) -> None:
        self.client = client
        self.seen: dict[tuple[str, str], tuple[httpx.Response, float]] = {}

    def get(self, url: str, **kw: Any) -> httpx.Response:
        return self.client.get(url, **kw)

    def timed_post(self, url: str, json: Any) -> tuple[httpx.Response, float]:
        key = (url, _canonical(json))
        if key not in self.seen:
            self.seen[key] = self._post(url, json)
        return self.seen[key]

    def _post(self, url: str, body: Any) -> tuple[httpx.Response, float]:
        # uvicorn closes the connection after an unhandled exception (a 500): a request sent on
        # that kept-alive connection fails before reaching the server, and is sent again once
        for attempt in (0, 1):
            t0 = time.perf_counter()
            try:
                return self.client.post(url, json=body), time.perf_counter() - t0
            except httpx.TimeoutException:
                return httpx.Response(599, json={"title": "client timeout"}), \
                    time.perf_counter() - t0
            except httpx.TransportError as exc:
                if attempt:
                    return httpx.Response(0, json={"title": f"no answer: {exc!r}"}), \
                        time.perf_counter() - t0
        raise AssertionError("unreachable")

    def post(self, url: str, json: Any = None, **_: Any) -> httpx.Response:
        return self.timed_post(url, json)[0]


def _canonical(body: Any) -> str:
    return json.dumps(body, sort_keys=True, separators=(",", ":"))


def outcome(r: httpx.Response) -> dict[str, Any]:
    """Status, and ``search.complete``/``search.reason`` of a JSON answer, or the problem."""
    out: dict[str, Any] = {"status": r.status_code, "complete": None, "reason": None}
    if "json" not in r.headers.get("content-type", ""):
        return out
    try:
        doc = r.json()
    except ValueError:
        return out
    if r.status_code == 200:
        search = doc.get("search") if isinstance(doc, dict) else None
        if isinstance(search, dict):
            out["complete"] = search.get("complete")
            out["reason"] = search.get("reason")
            out["search"] = {k: v for k, v in search.items()
                             if k not in ("complete", "reason") and isinstance(v, int | float)}
    else:
        out["problem"] = f"{doc.get('title', '')}: {doc.get('detail', '')}"[:300]
    return out


def served_code(python: str, repo: Path) -> dict[str, str]:
    """Where ``python`` started in ``repo`` imports the service from (as ``python -m uvicorn``
    does: the working directory first on ``sys.path``), and the checkout's commit."""
    where = subprocess.run(
        [python, "-c", "import engine, service; print(service.__file__); print(engine.__file__)"],
        cwd=repo, capture_output=True, text=True, check=True).stdout.split()
    head = subprocess.run(["git", "-C", str(repo), "rev-parse", "HEAD"],
                          capture_output=True, text=True).stdout.strip()
    dirty = subprocess.run(["git", "-C", str(repo), "status", "--porcelain", "--", "engine",
                            "service"], capture_output=True, text=True).stdout.strip()
    for path in where:
        if not Path(path).resolve().is_relative_to(repo.resolve()):
            raise SystemExit(f"{python} in {repo} imports {path}: not the code of {repo}")
    return {"repo": str(repo), "python": python, "service": where[0], "engine": where[1],
            "commit": head + (" (engine/ or service/ modified)" if dirty else "")}


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--time-limit", type=float, default=None,
                        help="LINKAGE_TIME_LIMIT_S of the served process (default: the "
                        "service's own, 30 s)")
    parser.add_argument("--only", nargs="+", default=None, metavar="PRESET")
    parser.add_argument("--repo", type=Path, default=HERE,
                        help="checkout whose code is served (default: this one)")
    parser.add_argument("--json", type=Path, default=Path("bench/results/presets.json"))
    parser.add_argument("--log", type=Path, default=None, help="the server's output")
    args = parser.parse_args()

    venv = args.repo / ".venv" / "bin" / "python"
    python = str(venv) if venv.exists() else sys.executable
    code = served_code(python, args.repo)
    env = {} if args.time_limit is None else {"LINKAGE_TIME_LIMIT_S": str(args.time_limit)}
    matrix = load_matrix()
    table = Table(f"presets with defaults through every endpoint, one request at a time "
                  f"({os.cpu_count()} cores), {code['commit'][:12]}")
    load_before = os.getloadavg()
    t_start = time.perf_counter()

    def save() -> None:  # after every row: a run stopped half-way keeps what it measured
        table.save(args.json, code=code, time_limit_s=args.time_limit or 30.0,
                   only=args.only, wall_s=round(time.perf_counter() - t_start, 1),
                   load_before=[round(x, 2) for x in load_before],
                   load_now=[round(x, 2) for x in os.getloadavg()],
                   note=f"{os.cpu_count()} cores shared with other work (e.g. test runs): "
                   "load1 per row is the 1-minute load average when the answer came")

    with served_process(["--no-access-log"], env=env, timeout=120, repo=args.repo,
                        python=python, log=args.log) as url, \
            httpx.Client(base_url=url, timeout=(args.time_limit or 30.0) + 120) as http:
        client = TimedClient(http)
        for preset, path, body in matrix.preset_cases(client, args.only):
            r, seconds = client.timed_post(path, body)
            table.record(f"{preset} {path}", seconds, **outcome(r),
                         load1=round(os.getloadavg()[0], 2), preset=preset, endpoint=path)
            save()


if __name__ == "__main__":
    main()
