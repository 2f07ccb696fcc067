"""The complete method (issue 23): path counts and times of the witness homotopy, and what a
user gets from ``configuration-space`` with default options (run on demand, not in the tests).

    .venv/bin/python bench/bench_witnesses.py [--repeat 3] [--no-http] [--large]
        [--json bench/results/witnesses.json]

Rows: the four-bar at generic and at critical lengths, the paper's three-rotor (twelve branch
points), a random 3D skew-hinge four-bar, 3D chains of three and (``--large``) four hinged
rotors, a Kane-Lubensky chain of four rotors. For each: the paths of the homotopy (``2^r r``),
its time alone (in-process, best of ``--repeat``), then ``explore`` with default options
in-process and ``POST /v1/analysis/configuration-space`` through HTTP (a warm service on a
loopback port, default options: the 4 s search budget), with the answer's components,
``complete`` and ``argument``. A row whose answer is not complete is not met.

BLAS runs on one thread (``OPENBLAS_NUM_THREADS=1`` unless set), as in the service's workers.
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
from engine.model.linkage import BarSpec, Linkage, VertexSpec, build_linkage  # noqa: E402
from engine.space.configuration_space import explore  # noqa: E402
from engine.space.witnesses import witness_points  # noqa: E402


def skew_four_bar(seed: int = 3) -> Linkage:
    """Two hinged rotors on skew axes (each tip held by two bars to two pins on its axis)
    joined by a coupler, assembled where drawn."""
    rng = np.random.default_rng(seed)
    vertices, bars, tips = [], [], []
    for j in range(2):
        a = rng.normal(size=3)
        b = a + rng.normal(size=3)
        axis = (b - a) / np.linalg.norm(b - a)
        normal = np.cross(axis, [1.0, 0.0, 0.0])
        normal /= np.linalg.norm(normal)
        tip = 0.5 * (a + b) + 0.8 * np.linalg.norm(b - a) * normal
        tips.append(tip)
        vertices += [VertexSpec(f"A{j}", a.tolist(), True), VertexSpec(f"B{j}", b.tolist(), True),
                     VertexSpec(f"T{j}", tip.tolist())]
        bars += [BarSpec(f"a{j}", (f"A{j}", f"T{j}")), BarSpec(f"b{j}", (f"B{j}", f"T{j}"))]
    bars.append(BarSpec("c", ("T0", "T1")))
    return build_linkage(3, vertices, bars)


def cases(large: bool) -> list[tuple[str, Linkage, dict[str, Any] | None]]:
    out: list[tuple[str, Linkage, dict[str, Any] | None]] = [
        ("four-bar L2 = 1.2", build_preset("four-bar", {"L2": 1.2}),
         {"name": "four-bar", "q": "L2=1.2"}),
        ("four-bar L2 = 1 (critical)", build_preset("four-bar", {"L2": 1.0}),
         {"name": "four-bar", "q": "L2=1.0"}),
        ("three-rotor (12 branch points)", build_preset("three-rotor"),
         {"name": "three-rotor", "q": ""}),
        ("3D skew-hinge four-bar", skew_four_bar(), None),
        ("rotor-chain-3d n = 3", build_preset("rotor-chain-3d", {"n": 3}),
         {"name": "rotor-chain-3d", "q": "n=3"}),
        ("kl-chain n = 4", build_preset("kl-chain", {"n": 4}), {"name": "kl-chain", "q": "n=4"}),
    ]
    if large:
        out.append(("rotor-chain-3d n = 4", build_preset("rotor-chain-3d", {"n": 4}),
                    {"name": "rotor-chain-3d", "q": "n=4"}))
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--no-http", action="store_true")
    parser.add_argument("--large", action="store_true", help="add the 896-path 3D chain")
    parser.add_argument("--json", type=Path)
    args = parser.parse_args()
    table = Table("the witness homotopy and configuration-space with default options")
    url_ctx = None if args.no_http else served()
    url = url_ctx.__enter__() if url_ctx is not None else None
    try:
        import httpx

        http = httpx.Client(timeout=120.0) if url else None
        for name, lk, preset in cases(args.large):
            t_hom, w = best_of(lambda lk=lk: witness_points(lk), args.repeat)
            t_exp, res = best_of(lambda lk=lk: explore(lk), 1)
            extra: dict[str, Any] = {
                "paths": w.paths, "explore_s": t_exp, "components": len(res.components),
                "complete": res.search["complete"], "argument": res.search["argument"],
                "homotopy": {**w.counts, "success": w.success},
            }
            if http is not None and url is not None:
                if preset:
                    linkage = http.get(f"{url}/v1/presets/{preset['name']}?{preset['q']}").json()
                else:
                    from service.mappers import linkage_out

                    linkage = linkage_out(lk).model_dump(mode="json")
                body = {"linkage": linkage}
                http.post(f"{url}/v1/analysis/configuration-space", json=body)  # warm
                t0 = time.perf_counter()
                r = http.post(f"{url}/v1/analysis/configuration-space", json=body)
                extra["http_s"] = time.perf_counter() - t0
                extra["http_complete"] = (r.json()["search"]["complete"] if r.is_success
                                          else r.status_code)
            table.record(name, t_hom, "homotopy alone (best of --repeat)", **extra)
    finally:
        if url_ctx is not None:
            url_ctx.__exit__(None, None, None)
    if args.json:
        table.save(args.json, load=os.getloadavg())


if __name__ == "__main__":
    main()
