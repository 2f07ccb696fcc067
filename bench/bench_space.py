"""Benchmarks of the configuration-space engine (run on demand, not in the test suite).

    .venv/bin/python bench/bench_space.py [--repeat 3] [--sizes 50 100 200 400]
        [--explore-sizes 50 100 200] [--budget 4] [--explore-repeat 1] [--no-http] [--small]
        [--json bench/results/space.json]

Best of ``--repeat`` wall-clock runs (``time.perf_counter``, :func:`bench.harness.best_of`).
Engine-only rows call the engine in this process; the ``HTTP`` row posts the request to the real
service on a loopback port (:func:`bench.harness.served`), paying JSON and HTTP like a client.

Kane-Lubensky scaling: for each chain length ``n`` the component through the start is traced
(zero mode at the start, then :func:`engine.space.trace.trace_curve` until it closes; both timed,
the time per point is the trace's) and the
configuration space is explored with a budget of ``--budget`` components; the log-log slopes of
time, points per component and time per point against ``n`` are fitted and written with the rows.

BLAS runs on one thread (``OPENBLAS_NUM_THREADS=1`` unless set), as in the service's workers:
on a shared 2-core machine threaded BLAS is slower and noisier.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path
from typing import Any

if __name__ == "__main__":  # before numpy is imported: one BLAS thread, as in the service
    for _name in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(_name, "1")

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bench.harness import Table, best_of, served  # noqa: E402
from engine.catalogue.presets import build_preset  # noqa: E402
from engine.local.rigidity import first_order  # noqa: E402
from engine.model.constraints import Constraints  # noqa: E402
from engine.model.tolerances import Tolerances  # noqa: E402
from engine.space.chain_count import chain_components  # noqa: E402
from engine.space.configuration_space import (  # noqa: E402
    SPARSE_SEED_RIGIDITY_MIN_FREE,
    SpaceOptions,
    _Explorer,
    explore,
    find_critical_points,
)
from engine.space.trace import TraceOptions, trace_curve  # noqa: E402


def kl_start(n: int) -> tuple[Constraints, np.ndarray, np.ndarray]:
    """An ``n``-rotor spinner chain's constraints, start and zero mode (as the explorer gets
    it: the sparse first-order method above 128 free coordinates)."""
    lk = build_preset("kl-chain", {"n": n})
    cons = Constraints(lk)
    sparse = True if cons.n_free > SPARSE_SEED_RIGIDITY_MIN_FREE else None
    return cons, lk.coordinates(), first_order(lk, sparse=sparse).zero_modes[0]


def kl_trace(cons: Constraints, u0: np.ndarray, z: np.ndarray) -> int:
    """Trace the component through ``u0`` until it closes; its points."""
    curve = trace_curve(cons, u0, z, Tolerances(), TraceOptions())
    assert curve.stop == "closed"
    return len(curve.points)


def critical_points_http(repeat: int) -> tuple[float, dict[str, Any]]:
    """Best-of time of POST /v1/analysis/critical-points for the three-rotor through the real
    service (uvicorn on a loopback port, worker processes as deployed), after one warm-up."""
    import httpx

    with served() as url, httpx.Client(base_url=url, timeout=120.0) as client:
        body = {"linkage": client.get("/v1/presets/three-rotor").json()}
        client.post("/v1/analysis/critical-points", json=body).raise_for_status()  # warm-up

        def once() -> dict[str, Any]:
            r = client.post("/v1/analysis/critical-points", json=body)
            r.raise_for_status()
            return dict(r.json())

        return best_of(once, repeat)


def slope(x: list[float], y: list[float]) -> float:
    """Least-squares slope of ``log y`` against ``log x``."""
    return float(np.polyfit(np.log(x), np.log(y), 1)[0])


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--sizes", type=int, nargs="+", default=[50, 100, 200, 400])
    # (400 rotors: the dense critical-point refinement alone takes tens of minutes)
    parser.add_argument("--explore-sizes", type=int, nargs="*", default=[50, 100, 200])
    parser.add_argument("--budget", type=int, default=4, help="components per exploration")
    parser.add_argument("--explore-repeat", type=int, default=1,
                        help="best of this many explorations and HTTP requests")
    parser.add_argument("--no-http", action="store_true")
    parser.add_argument("--small", action="store_true", help="also the four-bars, three-rotor")
    parser.add_argument("--json", type=Path, default=Path("bench/results/space.json"))
    args = parser.parse_args()
    table = Table(f"configuration space, best of {args.repeat}")
    fits: list[dict[str, Any]] = []

    if args.small:
        for label, params in (("four-bar crank-rocker (L1=0.5, L2=1.2, L3=1)",
                               {"L1": 0.5, "L2": 1.2, "L3": 1.0}),
                              ("four-bar equilateral (3 branch points)", {})):
            t, res = best_of(lambda p=params: explore(build_preset("four-bar", p)), args.repeat)
            pts = sum(len(c.points) for c in res.components)
            table.record(f"configuration space, {label}", t,
                         f"{len(res.components)} components, {pts} points, "
                         f"{len(res.critical_points)} critical points")
        t, res = best_of(lambda: explore(build_preset("three-rotor")), args.repeat)
        table.record("configuration space, three-rotor (all lengths a)", t,
                     f"{len(res.critical_points)} critical points, {len(res.segments)} segments")
        t, crit = best_of(lambda: find_critical_points(build_preset("three-rotor")), args.repeat)
        table.record("all critical points, three-rotor (engine)", t,
                     f"{len(crit.critical_points)} critical points")
        opt_in = SpaceOptions(critical_closed_form=True)
        t, crit = best_of(lambda: find_critical_points(build_preset("three-rotor"), None, opt_in),
                          args.repeat)
        table.record("all critical points, three-rotor (engine, critical_closed_form)", t,
                     f"{len(crit.critical_points)} critical points, {crit.search['method']}")
        if not args.no_http:
            t, body = critical_points_http(args.repeat)
            table.record("all critical points, three-rotor (HTTP, POST critical-points)", t,
                         f"{len(body['critical_points'])} critical points")

    comp_t, trace_t, comp_pts = [], [], []
    for n in args.sizes:
        t_start, (cons, u0, z) = best_of(lambda n=n: kl_start(n), args.repeat)
        t_trace, pts = best_of(lambda c=cons, u=u0, z=z: kl_trace(c, u, z), args.repeat)
        comp_t.append(t_start + t_trace)
        trace_t.append(t_trace)
        comp_pts.append(pts)
        table.record(f"component through the start, {n}-rotor KL chain", t_start + t_trace,
                     f"{pts} points", n=n, points=pts, zero_mode_s=t_start, trace_s=t_trace,
                     us_per_point=1e6 * t_trace / pts)
    if len(args.sizes) >= 2:
        per_point = [t / p for t, p in zip(trace_t, comp_pts, strict=True)]
        fits += [
            {"fit": "component time (zero mode + trace) ~ n^p", "p": slope(args.sizes, comp_t)},
            {"fit": "trace time ~ n^p", "p": slope(args.sizes, trace_t)},
            {"fit": "points per component ~ n^p", "p": slope(args.sizes, comp_pts)},
            {"fit": "trace time per point ~ n^p", "p": slope(args.sizes, per_point)},
        ]

    exp_t = []
    opts = SpaceOptions(max_components=args.budget)
    for n in args.explore_sizes:
        lk = build_preset("kl-chain", {"n": n})
        # as the configuration-space endpoint asks: no near misses, so the critical-point
        # search is skipped where the chain rules prove there is no critical point
        t, res = best_of(lambda lk=lk: explore(lk, options=opts, near_misses=False),
                         args.explore_repeat)
        exp_t.append(t)
        pts = sum(len(c.points) for c in res.components)
        total = res.search.get("components_total")
        table.record(f"explore {n}-rotor KL chain, budget {args.budget} (endpoint's options)", t,
                     f"{len(res.components)} of {total} components (2^{n - 1}), {pts} points, "
                     f"complete={res.search['complete']}", n=n, points=pts)
    if args.explore_sizes:
        # where an exploration's time goes: tracing (seeds, curves) vs the critical-point search
        n = 100 if 100 in args.explore_sizes else args.explore_sizes[0]
        lk = build_preset("kl-chain", {"n": n})
        ex = _Explorer(lk, Tolerances(), opts)
        t0 = time.perf_counter()
        ex.trace_all(lk.coordinates())
        t1 = time.perf_counter()
        crit, _, _ = ex.critical_points()
        t2 = time.perf_counter()
        table.record(f"  of which tracing ({n} rotors, budget {args.budget})", t1 - t0,
                     f"{len(ex.curves)} curves, {sum(len(c.points) for c in ex.curves)} points")
        table.record(f"  critical-point search, if near misses are asked ({n} rotors)", t2 - t1,
                     f"{ex.report.get('critical_candidates')} candidates refined, "
                     f"{len(crit)} critical points")
    if len(args.explore_sizes) >= 2:
        fits.append({"fit": f"exploration (budget {args.budget}) time ~ n^p",
                     "p": slope(args.explore_sizes, exp_t)})

    if not args.no_http:
        import httpx

        # a benchmark measures, it must not be cut by the service's default 30 s limit
        os.environ.setdefault("LINKAGE_TIME_LIMIT_S", "900")

        with served() as url, httpx.Client(base_url=url, timeout=300) as client:
            linkage = client.get("/v1/presets/kl-chain", params={"n": 100}).json()
            body = {"linkage": linkage, "options": {"max_components": args.budget}}

            def post() -> dict[str, Any]:
                r = client.post("/v1/analysis/configuration-space", json=body)
                r.raise_for_status()
                return dict(r.json())

            t, out = best_of(post, args.explore_repeat)
            search = out["search"]
            table.record(f"HTTP: configuration space, 100-rotor KL chain, budget {args.budget}", t,
                         f"{len(out['components'])} components of "
                         f"components_total={search.get('components_total')}, "
                         f"complete={search['complete']}")
    count = chain_components(build_preset("kl-chain", {"n": 100}))
    print(f"components of the 100-rotor chain (four-bar decomposition): "
          f"{count.components if count else None}")
    for f in fits:
        print(f"{f['fit']:<50} p = {f['p']:.2f}")
    table.rows += fits
    table.save(args.json)


if __name__ == "__main__":
    main()
