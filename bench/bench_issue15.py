"""Every row of issue 15's table, side by side with the peers, in one run (run on demand).

    .venv/bin/python bench/bench_issue15.py [--quick] [--repeat 3] [--only http closed-form ...]
        [--json bench/results/issue15.json]

Calls only the public engine functions and the HTTP API, so it measures whatever code is checked
out; the set-ups are those of the other scripts (``bench_points.py``, ``bench_space.py``,
``bench_maps.py``, ``bench_robustness.py``). Each row: best wall-clock time of ``--repeat`` runs
(``time.perf_counter``; single runs for the rows that take seconds), the CPU time of this process
beside it where the work runs here (``time.process_time``: on a shared machine the steadier
number), the issue's "now" and target, and the peer where there is one (pylinkage 1.3's
``Linkage.step_fast``, compiled by numba when numba is installed, as in the issue's 4.9 M/s).
``--quick`` takes smaller sizes (a smoke run in about a minute; its numbers are not the
issue's).

Prints a markdown table with the machine (CPU model, cores, BLAS threads, load average) and
writes every row as JSON. BLAS runs on one thread (as in the service's workers) unless the
environment says otherwise.
"""

from __future__ import annotations

import argparse
import base64
import json
import os
import platform
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

if __name__ == "__main__":  # before numpy is imported: one BLAS thread, as in the service
    for _name in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(_name, "1")
    # a benchmark measures: the service's default 30 s limit must not cut a request short
    os.environ.setdefault("LINKAGE_TIME_LIMIT_S", "900")

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "bench"))

from bench.bench_points import LENGTHS, pylinkage_points  # noqa: E402
from bench.bench_space import kl_start, kl_trace  # noqa: E402
from bench.harness import best_of_cpu as timed  # noqa: E402
from bench.harness import served_process  # noqa: E402
from engine.catalogue.presets import build_preset  # noqa: E402
from engine.design.critical_values import critical_value_slice  # noqa: E402
from engine.design.robustness import robustness  # noqa: E402
from engine.space import trace_kernel  # noqa: E402
from engine.space.configuration_space import SpaceOptions, explore  # noqa: E402
from engine.space.trace import TraceOptions  # noqa: E402

SPACE = "/v1/analysis/configuration-space"
#: The rows, in the issue's order (``--only`` picks some).
ROWS = ("tracer", "kl", "closed-form", "http", "gate", "slice", "margin", "critical")


def machine() -> dict[str, Any]:
    model = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                model = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    blas = {k: os.environ.get(k) for k in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS",
                                            "MKL_NUM_THREADS")}
    try:
        import numba

        numba_version: str | None = numba.__version__
    except ImportError:
        numba_version = None
    return {"cpu": model, "cores": os.cpu_count(), "blas_threads": blas,
            "python": platform.python_version(), "numpy": np.__version__,
            "numba": numba_version,  # pylinkage's step_fast is compiled when it is there
            "load_average_start": list(os.getloadavg())}


class Rows:
    """The table: one row per line of the issue, printed as it comes."""

    def __init__(self) -> None:
        self.rows: list[dict[str, Any]] = []

    def add(self, work: str, now: str, target: str, measured: str, peer: str = "",
            met: bool | None = None, **data: Any) -> None:
        row = {"work": work, "issue_now": now, "target": target, "measured": measured,
               "peer": peer, "met": met, **data}
        self.rows.append(row)
        flag = "" if met is None else (" [met]" if met else " [not met]")
        print(f"- {work}: {measured}{flag}   (issue: {now}; target {target})"
              + (f"  peer: {peer}" if peer else ""), flush=True)

    def markdown(self, info: dict[str, Any], quick: bool) -> str:
        blas = ", ".join(f"{k}={v}" for k, v in info["blas_threads"].items() if v is not None)
        head = (f"Machine: {info['cpu']}, {info['cores']} cores, BLAS threads: {blas or 'default'}"
                f", Python {info['python']}, numpy {info['numpy']}, numba "
                f"{info['numba'] or 'absent'}, tracer kernel {info.get('tracer_kernel', '?')}; "
                f"load average "
                f"{info['load_average_start'][0]:.2f} at the start, "
                f"{info['load_average_end'][0]:.2f} at the end"
                + (" (--quick: smaller sizes, not the issue's)" if quick else "") + "\n\n")
        lines = ["| work | issue: now | target | measured here | peer | met |",
                 "| --- | --- | --- | --- | --- | --- |"]
        for r in self.rows:
            met = "" if r["met"] is None else ("yes" if r["met"] else "no")
            lines.append(f"| {r['work']} | {r['issue_now']} | {r['target']} | {r['measured']} | "
                         f"{r['peer']} | {met} |")
        return head + "\n".join(lines) + "\n"


def rate(points: int, seconds: float) -> str:
    value = points / seconds
    return f"{value / 1e6:.2f} M/s" if value >= 1e6 else f"{value / 1e3:.0f} k/s"


def general_tracer(rows: Rows, quick: bool, repeat: int) -> None:
    """bench_points.py's row: the crank-rocker by the general tracer, near misses included:
    the best of ``repeat`` explorations, as every other throughput row, and the first one in
    the process apart (it also pays one-time costs: lazily imported modules, first calls)."""
    lk = build_preset("four-bar", LENGTHS)
    step = 2e-2 if quick else 2e-3
    opt = SpaceOptions(closed_form=False, trace=TraceOptions(step_max=step, max_points=200_000))
    first, _, _ = timed(lambda: explore(lk, options=opt))
    wall, cpu, res = timed(lambda: explore(lk, options=opt), repeat)
    n = sum(len(c.points) for c in res.components)
    rows.add("general tracer (`closed_form=False`), crank-rocker, points/s", "3,452",
             ">= 100,000", f"{n / wall:,.0f} /s ({n} points in {1e3 * wall:.1f} ms, step_max "
             f"{step:g}; CPU {n / cpu:,.0f} /s; the first exploration in the process "
             f"{n / first:,.0f} /s)", met=n / wall >= 1e5, points=n, seconds=wall, cpu=cpu,
             first_seconds=first, method=res.search.get("method"))


def kl_chain_trace(rows: Rows, quick: bool, repeat: int) -> None:
    """bench_space.py's row: the component through the start of an n-rotor spinner chain,
    with the tracer's compiled kernel loaded first (else the Python loop traces while numba
    compiles in the background, and the row measures that loop) and one untimed trace."""
    compiled = trace_kernel.prepare()
    measured, data = [], {}
    for n, limit in ((20, 20.0), (50, 60.0)) if quick else ((50, 20.0), (400, 60.0)):
        cons, u0, z = kl_start(n)
        kl_trace(cons, u0, z)
        wall, cpu, pts = timed(lambda c=cons, u=u0, z=z: kl_trace(c, u, z), repeat)
        us = 1e6 * wall / pts
        measured.append((n, us, 1e6 * cpu / pts, limit))
        data[f"n{n}"] = {"points": pts, "seconds": wall, "cpu": cpu, "us_per_point": us,
                         "kernel": "numba" if compiled else "numpy"}
    rows.add("Kane-Lubensky chain trace, time per point, n = "
             + " / ".join(str(m[0]) for m in measured), "198 / 580 us", "<= 20 / 60 us",
             " / ".join(f"{us:.0f}" for _, us, _, _ in measured) + " us (CPU "
             + " / ".join(f"{c:.0f}" for _, _, c, _ in measured) + " us)",
             met=all(us <= lim for _, us, _, lim in measured), **data)


def closed_form_vs_pylinkage(rows: Rows, quick: bool, repeat: int) -> None:
    """bench_points.py's rows: the closed form as the endpoint asks (every component, no near
    misses), dense, against pylinkage's step_fast on one branch of the same four-bar."""
    lk = build_preset("four-bar", LENGTHS)
    step = 7.5e-4 if quick else 7.5e-5
    dense = SpaceOptions(trace=TraceOptions(step_max=step, max_points=200_000))
    explore(lk, options=dense, near_misses=False)  # warm
    wall, cpu, res = timed(lambda: explore(lk, options=dense, near_misses=False),
                           max(repeat, 5))
    assert res.search["method"] == "closed form"
    n = sum(len(c.points) for c in res.components)
    n_peer = 10_000 if quick else 100_000
    pylinkage_points(100, fast=True)  # numba's compilation, if numba is there
    p_wall, p_cpu, p_n = timed(lambda: pylinkage_points(n_peer, fast=True), max(repeat, 5))
    ours, peer = n / wall, p_n / p_wall
    rows.add("closed form points/s vs pylinkage `Linkage.step_fast`", "2.2 M/s (0.45x of "
             "4.9 M/s)", ">= 1x", f"{rate(n, wall)} ({n} points, both components; CPU "
             f"{rate(n, cpu)}): {ours / peer:.2f}x (CPU {n / cpu / (p_n / p_cpu):.2f}x)",
             peer=f"{rate(p_n, p_wall)} (one branch, {p_n} steps; CPU {rate(p_n, p_cpu)})",
             met=ours >= peer, points=n, seconds=wall, cpu=cpu, peer_points=p_n,
             peer_seconds=p_wall, peer_cpu=p_cpu)


def _decode(packed: dict[str, Any], b64decode: Callable[[str], bytes]) -> np.ndarray:
    flat = np.frombuffer(b64decode(packed["base64"]), packed["dtype"])
    return flat.reshape(packed["shape"])


def through_http(rows: Rows, quick: bool, repeat: int) -> None:
    """The configuration-space endpoint on the dense crank-rocker (the service in a uvicorn
    process of its own): points received and parsed by the client, per second, for the default
    form (``json.loads``; and orjson's loads) and the compact one (``json.loads`` and base64
    into numpy arrays: the standard library's ``base64.b64decode``, and pybase64's SIMD
    decoder, a dependency of the service). Beside each, the CPU time of this process (the
    client's share) and, for the default form, what ``json.loads`` alone costs on the answer's
    bytes (no server, no transfer): the bound the default form cannot pass."""
    import httpx
    import orjson
    import pybase64

    from service.mappers import linkage_out

    def fast_b64decode(text: str) -> bytes:
        return pybase64.b64decode(text, validate=True)

    step = 7.5e-4 if quick else 7.5e-5
    linkage = linkage_out(build_preset("four-bar", LENGTHS)).model_dump(mode="json",
                                                                         by_alias=True)
    options = {"step_max": step, "max_points": 200_000}
    with served_process(env={"LINKAGE_WORKERS": "1"}) as url, \
            httpx.Client(base_url=url, timeout=300) as client:

        def receive(form: str | None) -> bytes:
            opts = options if form is None else {**options, "points": form}
            r = client.post(SPACE, json={"linkage": linkage, "options": opts})
            r.raise_for_status()
            return r.content

        def count(comps: list[dict[str, Any]]) -> int:
            return sum(len(next(iter(c["positions"].values()))) for c in comps)

        def default(loads: Callable[[bytes], Any]) -> int:
            return count(loads(receive(None))["components"])

        def compact(b64decode: Callable[[str], bytes]) -> int:
            comps = json.loads(receive("compact"))["components"]
            return sum(len(_decode(c["positions"], b64decode))
                       + 0 * _decode(c["angles"], b64decode).size for c in comps)

        n = default(json.loads)  # warm-up: a worker, imports
        assert compact(base64.b64decode) == compact(fast_b64decode) == n
        body = {form: receive(form) for form in (None, "compact")}
        size = {form: len(b) for form, b in body.items()}
        t_recv, c_recv, _ = timed(lambda: receive(None), repeat)
        t_json, c_json, _ = timed(lambda: default(json.loads), repeat)
        t_orjson, _, _ = timed(lambda: default(orjson.loads), repeat)
        t_loads, c_loads, _ = timed(lambda: count(json.loads(body[None])["components"]), repeat)
        t_oloads, c_oloads, _ = timed(lambda: count(orjson.loads(body[None])["components"]),
                                      repeat)
        t_compact_recv, c_compact_recv, _ = timed(lambda: receive("compact"), repeat)
        t_compact, c_compact, _ = timed(lambda: compact(base64.b64decode), repeat)
        t_fast, c_fast, _ = timed(lambda: compact(fast_b64decode), repeat)
    detail = f"{n} points, {size[None] / 1e6:.1f} MB"
    rows.add("through HTTP, points/s received and parsed by the client, default JSON",
             "164 k/s", ">= 1 M/s", f"{rate(n, t_json)} with `json.loads`, {rate(n, t_orjson)} "
             f"with `orjson.loads`, {rate(n, t_recv)} received only ({detail}); parsing alone, "
             f"no server: {rate(n, t_loads)} `json.loads` (CPU {rate(n, c_loads)}), "
             f"{rate(n, t_oloads)} `orjson.loads` (CPU {rate(n, c_oloads)})",
             met=n / t_json >= 1e6, points=n, bytes=size[None], seconds_received=t_recv,
             cpu_received=c_recv, seconds_json=t_json, cpu_json=c_json,
             seconds_orjson=t_orjson, seconds_json_loads_only=t_loads,
             cpu_json_loads_only=c_loads, seconds_orjson_loads_only=t_oloads,
             cpu_orjson_loads_only=c_oloads)
    compact_detail = (f"{rate(n, t_compact_recv)} received only (client CPU "
                      f"{1e3 * c_compact_recv:.0f} ms; {n} points, "
                      f"{size['compact'] / 1e6:.1f} MB)")
    rows.add("through HTTP, points/s received and parsed, compact (`options.points: "
             "\"compact\"`), `base64.b64decode`", "(new)", ">= 1 M/s",
             f"{rate(n, t_compact)} decoded into numpy (client CPU {1e3 * c_compact:.0f} ms), "
             + compact_detail, met=n / t_compact >= 1e6, points=n, bytes=size["compact"],
             seconds_received=t_compact_recv, cpu_received=c_compact_recv, seconds=t_compact,
             cpu=c_compact)
    rows.add("through HTTP, points/s received and parsed, compact, `pybase64.b64decode`",
             "(new)", ">= 1 M/s", f"{rate(n, t_fast)} decoded into numpy (client CPU "
             f"{1e3 * c_fast:.0f} ms), " + compact_detail, met=n / t_fast >= 1e6, points=n,
             bytes=size["compact"], seconds=t_fast, cpu=c_fast)


def gate_slice(rows: Rows, quick: bool) -> None:
    """bench_maps.py's row: the critical-value slice (L2, D) of a 4-rotor gated chain."""
    res = 8 if quick else 48
    gated = build_preset("gated-kl-chain", {"n": 4, "gate": 2})
    wall, cpu, s = timed(lambda: critical_value_slice(
        gated, [("L2", 1.0, 3.0), ("D", 1.0, 3.5)], resolution=res,
        options=SpaceOptions(angles=12, random_starts=2, max_components=4)))
    rows.add(f"gate slice (L2, D), 4-rotor gated chain, resolution {res}", "19.1 s (res 48)",
             "< 2 s", f"{wall:.2f} s (CPU {cpu:.2f} s; {len(s.curves)} curves, "
             f"{len(s.regions)} regions)", met=wall < 2.0, seconds=wall, cpu=cpu,
             resolution=res)


def four_bar_slice(rows: Rows, quick: bool) -> None:
    res = 48 if quick else 200
    four_bar = build_preset("four-bar", {"L2": 1.2})
    wall, cpu, s = timed(lambda: critical_value_slice(
        four_bar, [("L2", 0.3, 2.2), ("L3", 0.3, 2.2)], resolution=res))
    rows.add(f"four-bar slice (L2, L3), resolution {res}", "3.6 s (res 200)", "< 0.5 s",
             f"{wall:.2f} s (CPU {cpu:.2f} s; {len(s.curves)} curves, {len(s.regions)} "
             "regions)", met=wall < 0.5, seconds=wall, cpu=cpu, resolution=res)


def margin(rows: Rows, repeat: int) -> None:
    """bench_robustness.py's row: the four-bar (L2 = 1.2), every bar adjustable, by the method
    the endpoint picks (auto) and by the multistart every linkage got before."""
    four_bar = build_preset("four-bar", {"L2": 1.2})
    out = {}
    for method in ("auto", "multistart"):
        out[method] = timed(lambda m=method: robustness(four_bar, method=m), repeat)
    wall, cpu, m = out["auto"]
    w_ms, c_ms, m_ms = out["multistart"]
    rows.add("robustness margin, four-bar, all bars adjustable", "1.45 s", "< 20 ms",
             f"{1e3 * wall:.1f} ms by {m.method} (margin {m.margin:.6f}); multistart "
             f"{1e3 * w_ms:.0f} ms (margin {m_ms.margin:.6f})", met=wall < 0.02, seconds=wall,
             cpu=cpu, method=m.method, multistart_seconds=w_ms, multistart_cpu=c_ms)


def critical_search(rows: Rows, quick: bool) -> None:
    """bench_space.py's row: what the critical-point search with near misses adds to the
    exploration of an n-rotor spinner chain (budget 4): explore with near misses minus explore
    without (the rotor-chain rules skip the search there)."""
    n = 30 if quick else 100
    lk = build_preset("kl-chain", {"n": n})
    opts = SpaceOptions(max_components=4)
    w_with, c_with, res = timed(lambda: explore(lk, options=opts, near_misses=True))
    w_without, c_without, _ = timed(lambda: explore(lk, options=opts, near_misses=False))
    wall, cpu = w_with - w_without, c_with - c_without
    rows.add(f"critical-point search with near misses, {n}-rotor chain", "11.1 s (100 rotors)",
             "< 1 s", f"{wall:.2f} s (CPU {cpu:.2f} s; exploration {w_with:.2f} s with, "
             f"{w_without:.2f} s without; {len(res.near_misses)} near misses, "
             f"{len(res.critical_points)} critical points)", met=wall < 1.0, seconds=wall,
             cpu=cpu, explore_with=w_with, explore_without=w_without, rotors=n)


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--quick", action="store_true", help="smaller sizes (a smoke run)")
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--json", type=Path, default=ROOT / "bench/results/issue15.json")
    parser.add_argument("--only", nargs="+", choices=ROWS, default=list(ROWS),
                        help="run these rows only")
    args = parser.parse_args()
    # the tracer's compiled kernel loaded before any timing, as the service's workers do at
    # start-up (trace_kernel.prepare): otherwise the first rows trace with the Python loop
    # while numba loads in a background thread (and competes with them for the CPU)
    kernel = trace_kernel.prepare()
    info = machine()
    info["tracer_kernel"] = "numba" if kernel else "numpy (Python loop)"
    print(f"# issue 15, {'quick' if args.quick else 'full'} run on {info['cpu']} "
          f"({info['cores']} cores)", flush=True)
    rows = Rows()
    run: dict[str, Callable[[], None]] = {
        "tracer": lambda: general_tracer(rows, args.quick, args.repeat),
        "kl": lambda: kl_chain_trace(rows, args.quick, args.repeat),
        "closed-form": lambda: closed_form_vs_pylinkage(rows, args.quick, args.repeat),
        "http": lambda: through_http(rows, args.quick, args.repeat),
        "gate": lambda: gate_slice(rows, args.quick),
        "slice": lambda: four_bar_slice(rows, args.quick),
        "margin": lambda: margin(rows, args.repeat),
        "critical": lambda: critical_search(rows, args.quick),
    }
    for name in ROWS:
        if name in args.only:
            run[name]()
    info["load_average_end"] = list(os.getloadavg())
    table = rows.markdown(info, args.quick)
    print()
    print(table)
    args.json.parent.mkdir(parents=True, exist_ok=True)
    args.json.write_text(json.dumps({"title": "issue 15", "quick": args.quick, "machine": info,
                                     "rows": rows.rows, "markdown": table}, indent=2) + "\n")


if __name__ == "__main__":
    main()
