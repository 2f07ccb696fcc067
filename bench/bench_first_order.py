"""First-order analysis (rank, zero modes, self-stresses) of pinned Kane-Lubensky chains, side
by side with PyRigi 1.3 (run on demand, never in the tests).

    .venv/bin/python bench/bench_first_order.py [--repeat 5] [--sizes 64 256]
        [--large 1000 2000 5000 10000] [--grounded 64] [--json bench/results/first_order.json]

What is compared, on the same framework (the ``kl-chain`` preset: ``n`` pins on a line, ``n``
rotors, ``n - 1`` coupling bars, ``M = 2n`` free coordinates):

* ours, engine only: ``first_order(linkage)`` (rank, nontrivial zero modes, self-stresses,
  tangent form) on the linkage built from the preset;
* ours, through HTTP: ``POST /v1/analysis/rigidity`` with the preset's JSON (as returned by
  ``GET /v1/presets/kl-chain?n=...``), the real service on a loopback port, one client; the
  time includes sending the body, validation, the worker process, the projection onto the
  constraints, the analysis, the response model and JSON both ways, and the client's parse of
  the answer. Twice: with ``bench.harness.served()`` (uvicorn in a thread of this process, so
  client and server share one interpreter and its garbage collector) and with ``uvicorn
  service.main:app`` in a process of its own, as deployed;
* PyRigi (numerical mode): ``Framework.inf_flexes(numerical=True, fixed_vertices=pins)`` (the
  pins get flex 0, i.e. the null space of the rigidity matrix without the pins' columns: our
  ``J``) plus ``Framework.stresses(numerical=True)`` -- the calls the issue names. PyRigi's
  ``stresses`` has no pinned variant: it returns the stresses of the *free* framework, which
  must also balance at the pins; for this chain both spaces are 0 at a generic configuration,
  so the counts agree but the two calls do not mean the same in general;
* PyRigi, grounded (like for like, ``--grounded`` sizes): the pins joined into one rigid body by
  an isostatic ground (one extra vertex off the line; bars P0-P1, P0-G, P1-G and Pk-P(k-1),
  Pk-G), whose nontrivial flexes and stresses are exactly those of the pinned chain (an
  isostatic, infinitesimally rigid ground has no stress and resolves any equilibrium load).
  Its rigidity matrix is about twice as large, so it is slower than the call above.

Counts (flexes, stresses) of PyRigi and ours are printed and must agree; the grounded check is
also run on a straight chain (a critical configuration with one self-stress).

Peak memory of the large sizes: the high-water resident size (``VmHWM``) of a fresh subprocess
that builds the chain and analyses it once (baseline after imports and building, and the peak
after the analysis).

BLAS runs on one thread (``OPENBLAS_NUM_THREADS=1``, as in the service's workers) unless
``--blas-threads`` says otherwise: on a shared 2-core machine threaded BLAS is slower and
noisier. Best of ``--repeat`` wall-clock runs (PyRigi: one run at 256 and above).
"""

from __future__ import annotations

import argparse
import os
import sys

if __name__ == "__main__":  # before numpy is imported
    _threads = "1"
    if "--blas-threads" in sys.argv:
        _threads = sys.argv[sys.argv.index("--blas-threads") + 1]
    for _name in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(_name, _threads)

import json  # noqa: E402
import resource  # noqa: E402
import subprocess  # noqa: E402
import time  # noqa: E402
import warnings  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Any  # noqa: E402

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bench.harness import Table, best_of, served, served_process  # noqa: E402
from engine.catalogue.presets import build_preset  # noqa: E402
from engine.local.rigidity import first_order  # noqa: E402
from engine.model.linkage import BarSpec, Linkage, VertexSpec, build_linkage  # noqa: E402


def pyrigi_counts(linkage: Linkage, grounded: bool) -> tuple[int, int]:
    """PyRigi's (number of nontrivial inf. flexes, number of stresses), numerical mode."""
    from pyrigi import Framework, Graph

    ids = list(linkage.vertex_ids)
    edges = [(ids[i], ids[j]) for i, j in linkage.ends]
    realization = {v: [float(x) for x in p] for v, p in zip(ids, linkage.positions, strict=True)}
    pins = [v for v, f in zip(ids, linkage.fixed, strict=True) if f.all()]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # "fixed_vertices are not an edge" (intended here)
        if not grounded:
            fw = Framework(Graph(edges), realization)
            flexes = fw.inf_flexes(numerical=True, fixed_vertices=pins)
            return len(flexes), len(fw.stresses(numerical=True))
        pts = np.array([realization[p] for p in pins])
        span = float(np.ptp(pts[:, 0])) if len(pins) > 1 else 1.0
        ground = "__ground__"
        realization[ground] = [float(pts[:, 0].mean()), float(pts[:, 1].mean()) - max(span, 1.0)]
        gedges = [(pins[0], pins[1]), (pins[0], ground), (pins[1], ground)]
        gedges += [e for k in range(2, len(pins)) for e in ((pins[k], pins[k - 1]),
                                                            (pins[k], ground))]
        fw = Framework(Graph(edges + gedges), realization)
        return len(fw.inf_flexes(numerical=True)), len(fw.stresses(numerical=True))


def straight_chain(n: int) -> Linkage:
    """Pins P, Q and ``n`` free vertices on one line: one self-stress, ``n`` flexes."""
    names = ["P"] + [f"v{k}" for k in range(n)] + ["Q"]
    vertices = [VertexSpec(v, [float(k), 0.0], v in ("P", "Q")) for k, v in enumerate(names)]
    return build_linkage(2, vertices, [BarSpec(f"b{k}", (names[k], names[k + 1]))
                                       for k in range(n + 1)])


def ours_counts(linkage: Linkage) -> tuple[int, int]:
    rig = first_order(linkage)
    return rig.dof, rig.self_stresses.shape[0]


def high_water_mb() -> float:
    """Peak resident memory of this process in MB: ``VmHWM`` (Linux), which, unlike
    ``ru_maxrss``, does not carry over the parent's peak through fork and exec."""
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("VmHWM:"):
                return float(line.split()[1]) / 1024
    except OSError:
        pass
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def child(n: int) -> None:
    """Subprocess: peak resident memory of building and analysing an ``n``-rotor chain."""
    lk = build_preset("kl-chain", {"n": n})
    first_order(build_preset("kl-chain", {"n": 8}))  # libraries loaded
    base = high_water_mb()
    t0 = time.perf_counter()
    rig = first_order(lk)
    seconds = time.perf_counter() - t0
    peak = high_water_mb()
    print(json.dumps({"base_mb": base, "peak_mb": peak, "seconds": seconds,
                      "dof": rig.dof, "stresses": rig.self_stresses.shape[0]}))


def peak_memory(n: int) -> dict[str, Any]:
    out = subprocess.run([sys.executable, __file__, "--child", str(n)], capture_output=True,
                         text=True, check=True)
    return dict(json.loads(out.stdout.strip().splitlines()[-1]))


def through_http(client: Any, n: int, repeat: int) -> tuple[float, dict[str, Any]]:
    """Best time of ``POST /v1/analysis/rigidity`` with the ``n``-rotor preset's JSON, the
    client's JSON parse of the answer included."""
    body = {"linkage": client.get("/v1/presets/kl-chain", params={"n": n}).json()}
    payload = json.dumps(body).encode()

    def call() -> dict[str, Any]:
        t0 = time.perf_counter()
        r = client.post("/v1/analysis/rigidity", content=payload,
                        headers={"content-type": "application/json"})
        r.raise_for_status()
        t1 = time.perf_counter()
        out = r.json()
        parse = time.perf_counter() - t1
        # a summary only: keeping whole answers alive would slow the collector later
        return {"dof": out["dof"], "stresses": len(out["self_stresses"]),
                "parse_seconds": parse, "post_seconds": t1 - t0,
                "response_bytes": len(r.content)}

    call()  # warm: worker processes started
    seconds, out = best_of(call, repeat)
    return seconds, {**out, "request_bytes": len(payload)}


def http_detail(resp: dict[str, Any]) -> str:
    return (f"request {resp['request_bytes'] / 1e6:.2f} MB, response "
            f"{resp['response_bytes'] / 1e6:.2f} MB, client JSON parse "
            f"{resp['parse_seconds'] * 1e3:.0f} ms")


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--sizes", type=int, nargs="*", default=[64, 256])
    parser.add_argument("--large", type=int, nargs="*", default=[1000, 2000, 5000, 10000])
    parser.add_argument("--grounded", type=int, nargs="*", default=[64])
    parser.add_argument("--blas-threads", type=int, default=1)
    parser.add_argument("--child", type=int)
    parser.add_argument("--json", type=Path, default=Path("bench/results/first_order.json"))
    args = parser.parse_args()
    if args.child:
        child(args.child)
        return
    import httpx

    table = Table(f"First-order analysis of pinned KL chains vs PyRigi 1.3 (numerical), "
                  f"BLAS threads {os.environ.get('OPENBLAS_NUM_THREADS')}")

    # Ours first, PyRigi (sympy underneath) last: its objects would stay in this process's heap,
    # and the service in the thread below pays garbage-collector passes over all of them.
    ours: dict[int, dict[str, Any]] = {}
    for n in args.sizes + args.large:
        lk = build_preset("kl-chain", {"n": n})
        t_eng, rig = best_of(lambda lk=lk: first_order(lk), args.repeat)
        cpu0 = time.process_time()
        first_order(lk)
        ours[n] = {"engine": t_eng, "engine_cpu": time.process_time() - cpu0,
                   "counts": (rig.dof, rig.self_stresses.shape[0]),
                   "label": f"M={rig.n_free}, {rig.method}"}
    for name, server in (("http", served), ("http_process", served_process)):
        with server() as url, httpx.Client(base_url=url, timeout=300.0) as client:
            for n in args.sizes + args.large:
                t_http, resp = through_http(client, n, args.repeat)
                assert (resp["dof"], resp["stresses"]) == ours[n]["counts"]
                ours[n][name], ours[n][name + "_resp"] = t_http, resp

    for n in args.sizes + args.large:
        o = ours[n]
        extra = peak_memory(n) if n in args.large else {}
        mem = {"peak_rss_mb": extra["peak_mb"], "base_rss_mb": extra["base_mb"]} if extra else {}
        t_peer, counts, reps = None, None, 0
        if n in args.sizes:
            lk = build_preset("kl-chain", {"n": n})
            reps = 1 if n >= 256 else max(1, min(3, args.repeat))
            t_peer, counts = best_of(lambda lk=lk: pyrigi_counts(lk, grounded=False), reps)
            assert counts == o["counts"], (counts, o["counts"])
        vs = {"speedup": t_peer / o["engine"]} if t_peer else {}
        table.record(f"{n}-rotor chain, ours engine ({o['label']})", o["engine"],
                     f"dof {o['counts'][0]}, stresses {o['counts'][1]}",
                     cpu_seconds=o["engine_cpu"], **vs, **mem)
        vs = {"speedup": t_peer / o["http"]} if t_peer else {}
        table.record(f"{n}-rotor chain, ours HTTP", o["http"], http_detail(o["http_resp"]),
                     **vs)
        vs = {"speedup": t_peer / o["http_process"]} if t_peer else {}
        table.record(f"{n}-rotor chain, ours HTTP, uvicorn in its own process",
                     o["http_process"], http_detail(o["http_process_resp"]), **vs)
        if t_peer and counts:
            table.record(f"{n}-rotor chain, PyRigi inf_flexes(pins) + stresses", t_peer,
                         f"flexes {counts[0]}, stresses {counts[1]} (best of {reps})")
        if n in args.grounded and n in args.sizes:
            t_g, g = best_of(lambda lk=lk: pyrigi_counts(lk, grounded=True), 1)
            assert g == o["counts"], (g, o["counts"])
            table.record(f"{n}-rotor chain, PyRigi grounded (like for like)", t_g,
                         f"flexes {g[0]}, stresses {g[1]}", speedup_engine=t_g / o["engine"],
                         speedup_http=t_g / o["http"])

    straight = straight_chain(12)
    expected = ours_counts(straight)
    got = pyrigi_counts(straight, grounded=True)
    assert got == expected, (got, expected)
    table.record("check: straight 12-vertex chain (critical), PyRigi grounded", 0.0,
                 f"flexes/stresses ours {expected}, PyRigi {got}")
    table.save(args.json)


if __name__ == "__main__":
    main()
