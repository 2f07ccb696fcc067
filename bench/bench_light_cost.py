"""What a first- or second-order request costs in the service's own process, against the
estimate the light lane decides by (``service.jobs.is_light``: ``M^2 + E^2`` numbers of zero
modes and self-stresses, ``M E`` for second order's SDP), on the degenerate linkages that reach
the worst case: collinear in the plane, flat in space, with a seeded random set of bars
(run on demand; bounded: at most some hundred analyses of at most 64 vertices).

    .venv/bin/python bench/bench_light_cost.py [--repeat 2] [--json bench/results/light.json]

BLAS runs on one thread, as in the service's process (``service/__init__.py``, imported before
numpy: with a thread per core on a loaded 2-core machine the same SVD took 1.8-136 ms). Each row is
the best of ``--repeat`` runs of the lane's work in-process (the analysis, its answer's model and
JSON: ``service.workers._as_json`` of ``service.jobs.rigidity`` / ``second_order_analysis``), with
``M``, ``E``, the estimate and whether the lane takes it: every row the lane takes should be a
few milliseconds, every row of 0.1 s or more should be left to the workers.
"""

from __future__ import annotations

import argparse
import os
import random
from pathlib import Path
from typing import Any

from harness import Table, best_of  # bench/ is on sys.path when run as a script

from service import jobs
from service.config import get_settings
from service.schemas.common import AnalysisRequest
from service.workers import _as_json

SHAPES = (("line", 2), ("flat", 3), ("line", 3), ("generic", 3))
SIZES = (4, 8, 12, 16, 24, 32, 48, 64)
BARS_PER_VERTEX = (1.0, 2.0, 4.0)


def degenerate(vertices: int, bars: int, dimension: int, shape: str, pinned: int,
               seed: int) -> dict[str, Any]:
    """A linkage of ``vertices`` (the first ``pinned`` pinned) on a line (``line``), in the
    plane z = 0 (``flat``) or in general position, with a path of bars and random chords."""
    rng = random.Random(seed)
    kept = {"line": 1, "flat": dimension - 1}.get(shape, dimension)  # the other axes are 0
    pos = [[rng.gauss(0.0, 1.0) if a < kept else 0.0 for a in range(dimension)]
           for _ in range(vertices)]
    pairs = {(i, i + 1) for i in range(vertices - 1)}
    while len(pairs) < min(bars, vertices * (vertices - 1) // 2):
        i, j = sorted(rng.sample(range(vertices), 2))
        pairs.add((i, j))
    return {"dimension": dimension,
            "vertices": [{"id": f"v{i}", "position": p, "fixed": i < pinned}
                         for i, p in enumerate(pos)],
            "bars": [{"id": f"b{k}", "ends": [f"v{i}", f"v{j}"]}
                     for k, (i, j) in enumerate(sorted(pairs))]}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeat", type=int, default=2)
    parser.add_argument("--json", type=Path)
    args = parser.parse_args()
    settings = get_settings()
    table = Table(f"first and second order in-process on degenerate linkages, load average "
                  f"{os.getloadavg()[0]:.1f}")
    for seed, (shape, d) in enumerate(SHAPES):
        for v in SIZES:
            for per in BARS_PER_VERTEX:
                body = AnalysisRequest.model_validate(
                    {"linkage": degenerate(v, int(per * v), d, shape, 2, seed)})
                m, e = jobs.free_coordinates(body.linkage), len(body.linkage.bars)
                for name, fn, second in (("rigidity", jobs.rigidity, False),
                                         ("second", jobs.second_order_analysis, True)):
                    seconds, _ = best_of(
                        lambda fn=fn, body=body: _as_json(fn, body, settings, None, False),
                        args.repeat)
                    table.record(f"{shape} {d}D V={v} E={e} {name}", seconds,
                                 f"M={m} M^2+E^2={m * m + e * e} ME={m * e}",
                                 light=jobs.is_light(body, second))
    if args.json:
        table.save(args.json, load_average=os.getloadavg())


if __name__ == "__main__":
    main()
