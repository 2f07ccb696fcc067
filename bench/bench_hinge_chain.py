"""3D hinged rotor chains derived from their cells (issue 23, issue 30): what a user gets from
``critical-points``, ``configuration-space`` and ``splitting`` with default options through
HTTP (a warm service on a loopback port, the default 4 s search budget), for the default
``rotor-chain-3d`` (n = 6), n = 10 and 20, and a chain whose cells turn (n = 4, tilt 1.4,
h 0.3: seeds from folds, traced). Each request is a distinct linkage (the first rotor's angle
moved), median of ``--repeat``; a row whose answer is not complete says what it proved.

    .venv/bin/python bench/bench_hinge_chain.py [--repeat 3] [--json bench/results/hinge.json]

BLAS runs on one thread (``OPENBLAS_NUM_THREADS=1`` unless set), as in the service's workers.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from pathlib import Path

if __name__ == "__main__":  # before numpy is imported: one BLAS thread, as in the service
    for _name in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(_name, "1")

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bench.harness import Table, served  # noqa: E402

CASES = ("", "n=10", "n=20", "n=4&tilt=1.4&h=0.3")
ROUTES = ("critical-points", "configuration-space", "splitting")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--json", type=Path, default=None)
    args = parser.parse_args()
    import httpx

    table = Table("3D hinged rotor chains through HTTP, default options")
    with served() as url, httpx.Client(base_url=url, timeout=120.0) as http:
        for case in CASES:
            for r, route in enumerate(ROUTES):
                times, answer = [], {}
                for rep in range(args.repeat):
                    query = "&".join(q for q in (case, f"theta={1.3 + 0.01 * rep + 0.1 * r}") if q)
                    linkage = http.get(f"/v1/presets/rotor-chain-3d?{query}").json()
                    body = {"linkage": linkage}
                    if route == "splitting":
                        body["perturbation"] = {"l0": 0.01}
                    start = time.perf_counter()
                    answer = http.post(f"/v1/analysis/{route}", json=body).json()
                    times.append(time.perf_counter() - start)
                search = answer["search"]
                table.record(f"{case or 'default'} {route}", statistics.median(times),
                             f"complete={search['complete']} reason={search['reason']}",
                             argument=search["argument"], proved=search.get("proved"))
    if args.json:
        table.save(args.json, repeat=args.repeat)


if __name__ == "__main__":
    main()
