"""The general tracer (issue 15): before (the Python loop) and after (its regular passes
compiled, ``engine/space/_trace_numba/``), side by side in one run (run on demand).

    .venv/bin/python bench/bench_tracer.py [--repeat 3] [--sizes 50 400]
        [--json bench/results/tracer.json]

Rows (best of ``--repeat`` wall-clock runs each, the two paths interleaved so that the load of a
shared machine hits both alike):

* crank-rocker four-bar (pins (0, 0), (1, 0), crank 0.5, coupler 1.2, rocker 1), the general
  tracer as ``bench/bench_points.py`` measures it: ``explore`` with ``closed_form=False``,
  ``step_max`` 2e-3, with the near-miss search; points of all components per second (issue
  target >= 100,000 points/s). Also the component through the start traced alone
  (``trace_curve``), which is the tracer's own rate without seeds and critical points;
* Kane-Lubensky chains (preset ``kl-chain``): the component through the start traced until it
  closes, time per point (issue target <= 20 / 60 us at n = 50 / 400), as
  ``bench/bench_space.py`` does.

"before" is ``LINKAGE_TRACER_KERNEL=numpy`` (the loop of main), "after" the default. The first
compiled use in a process loads numba and its cached machine code (about a second;
compiling from scratch, tens of seconds, once per install): it is timed separately as
``warm-up`` and left out of the best-of rows (the tracer itself runs the Python loop while the
kernel loads in the background).

BLAS runs on one thread (``OPENBLAS_NUM_THREADS=1`` unless set), as in the service's workers.
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import time
from pathlib import Path
from typing import Any

if __name__ == "__main__":  # before numpy is imported: one BLAS thread, as in the service
    for _name in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(_name, "1")

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bench.bench_space import kl_start  # noqa: E402
from bench.harness import Table  # noqa: E402
from engine.catalogue.presets import build_preset  # noqa: E402
from engine.local.rigidity import first_order  # noqa: E402
from engine.model.constraints import Constraints  # noqa: E402
from engine.model.tolerances import Tolerances  # noqa: E402
from engine.space import trace_kernel  # noqa: E402
from engine.space.configuration_space import Explorer, SpaceOptions, explore  # noqa: E402
from engine.space.configuration_space.critical_search import critical_points  # noqa: E402
from engine.space.trace import TraceOptions, trace_curve  # noqa: E402

CRANK_ROCKER = {"L1": 0.5, "L2": 1.2, "L3": 1.0}
TRACER = SpaceOptions(closed_form=False, trace=TraceOptions(step_max=2e-3, max_points=200_000))
PATHS = ("numpy", "numba")  # before, after


def with_path(path: str, fn: Any) -> tuple[float, Any]:
    """Time ``fn()`` with the tracer's path chosen by the environment variable."""
    old = os.environ.get(trace_kernel.KERNEL_ENV)
    os.environ[trace_kernel.KERNEL_ENV] = path
    try:
        t0 = time.perf_counter()
        out = fn()
        return time.perf_counter() - t0, out
    finally:
        if old is None:
            del os.environ[trace_kernel.KERNEL_ENV]
        else:
            os.environ[trace_kernel.KERNEL_ENV] = old


def interleaved(fn: Any, repeat: int) -> dict[str, tuple[float, Any]]:
    """Best time and last output of ``fn`` on each path, the paths alternating."""
    best: dict[str, tuple[float, Any]] = {p: (float("inf"), None) for p in PATHS}
    for _ in range(max(1, repeat)):
        for p in PATHS:
            t, out = with_path(p, fn)
            best[p] = (min(best[p][0], t), out)
    return best


def crank_rocker_explore() -> int:
    res = explore(build_preset("four-bar", CRANK_ROCKER), options=TRACER, near_misses=True)
    assert res.search["complete"] and not res.critical_points and len(res.components) == 2
    return sum(len(c.points) for c in res.components)


def crank_rocker_start() -> tuple[Constraints, np.ndarray, np.ndarray]:
    lk = build_preset("four-bar", CRANK_ROCKER)
    return Constraints(lk), lk.coordinates(), first_order(lk).zero_modes[0]


def trace_closed(cons: Constraints, u0: np.ndarray, z: np.ndarray, opt: TraceOptions) -> int:
    curve = trace_curve(cons, u0, z, Tolerances(), opt)
    assert curve.stop == "closed", curve.stop
    return len(curve.points)


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--sizes", type=int, nargs="+", default=[50, 400])
    parser.add_argument("--json", type=Path, default=Path("bench/results/tracer.json"))
    args = parser.parse_args()
    table = Table(f"general tracer, before (Python loop) / after (compiled), best of "
                  f"{args.repeat}")
    t0 = time.perf_counter()
    if not trace_kernel.load():
        sys.exit("numba is not importable: there is no compiled path to measure")
    table.record("warm-up: loading the compiled kernel (numba import, compile or cache)",
                 time.perf_counter() - t0)

    cons, u0, z = crank_rocker_start()

    rates: dict[str, float] = {}
    best = interleaved(crank_rocker_explore, args.repeat)
    for p in PATHS:
        t, n = best[p]
        rates[p] = n / t
        table.record(f"crank-rocker, explore closed_form=False step_max 2e-3, {p}", t,
                     f"{n} points, 2 components", path=p, points_per_s=n / t)
    table.record("crank-rocker, explore closed_form=False: after / before", 0.0,
                 "target >= 100,000 points/s", speedup=rates["numba"] / rates["numpy"])

    # where the compiled explore's time goes: tracing (seeds, curves) vs the critical points
    ex = Explorer(build_preset("four-bar", CRANK_ROCKER), Tolerances(), TRACER)
    t_trace, _ = with_path("numba", lambda: ex.trace_all(None))
    t_crit, _ = with_path("numba", lambda: critical_points(ex))
    table.record("  of which seeds and curves (trace_all), numba", t_trace,
                 f"{len(ex.curves)} curves")
    table.record("  of which the critical-point search (refinements), numba", t_crit,
                 f"{ex.report.get('critical_candidates')} candidates refined")

    opt = TraceOptions(step_max=2e-3, max_points=200_000)
    best = interleaved(lambda: trace_closed(cons, u0, z, opt), args.repeat)
    for p in PATHS:
        t, n = best[p]
        rates[p] = n / t
        table.record(f"crank-rocker, trace_curve of one component step_max 2e-3, {p}", t,
                     f"{n} points", path=p, points_per_s=n / t)
    table.record("crank-rocker, trace_curve: after / before", 0.0, "",
                 speedup=rates["numba"] / rates["numpy"])

    for n in args.sizes:
        kcons, ku0, kz = kl_start(n)
        best = interleaved(lambda c=kcons, u=ku0, v=kz: trace_closed(c, u, v, TraceOptions()),
                           args.repeat)
        per: dict[str, float] = {}
        for p in PATHS:
            t, pts = best[p]
            per[p] = 1e6 * t / pts
            table.record(f"{n}-rotor KL chain, trace of the component through the start, {p}",
                         t, f"{pts} points", path=p, n=n, us_per_point=per[p])
        table.record(f"{n}-rotor KL chain: before / after (time per point)", 0.0,
                     "target <= 20 us (n = 50), <= 60 us (n = 400)", n=n,
                     speedup=per["numpy"] / per["numba"])
    table.save(args.json, machine={"cpus": os.cpu_count(), "platform": platform.platform(),
                                   "python": platform.python_version(),
                                   "load_average": os.getloadavg()})


if __name__ == "__main__":
    main()
