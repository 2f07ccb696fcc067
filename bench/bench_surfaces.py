"""Two degrees of freedom (issue 25): time and triangles of the surfaces (run on demand, not in
the tests).

    .venv/bin/python bench/bench_surfaces.py [--repeat 3] [--proof]

Rows: the equilateral planar pentagon with one bar pinned (genus 4), a generic pentagon
(genus 2), a five-bar (genus 3), a 3D sliding torus and a 3D sphere. For each, best of
``--repeat``: the marching alone at the default step, then :func:`explore_surfaces` with default
options (homotopy within 512 paths: the pentagons' 1024 are skipped, their answers are
``searched``); ``--proof`` adds each row with ``homotopy_paths_max = 4096`` (the complete
answer). BLAS on one thread, as in the service's workers.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

if __name__ == "__main__":
    for _name in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(_name, "1")

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from engine.model.constraints import project  # noqa: E402
from engine.model.linkage import BarSpec, Linkage, VertexSpec, build_linkage  # noqa: E402
from engine.space.surfaces.explore import SurfaceOptions, explore_surfaces  # noqa: E402
from engine.space.surfaces.geometry import Surface  # noqa: E402
from engine.space.surfaces.mesh import march  # noqa: E402


def pentagon(lengths: tuple[float, ...]) -> Linkage:
    pts = [np.zeros(2), np.array([lengths[0], 0.0])]
    th = 0.0
    for k in range(3):
        th += 2 * np.pi / 5
        pts.append(pts[-1] + lengths[k + 1] * np.array([np.cos(th), np.sin(th)]))
    ids = ["P0", "P1", "A", "B", "C"]
    vs = [VertexSpec(i, tuple(p), i in ("P0", "P1")) for i, p in zip(ids, pts, strict=True)]
    ends = [("P0", "P1"), ("P1", "A"), ("A", "B"), ("B", "C"), ("C", "P0")]
    bs = [BarSpec(f"b{i}", e, float(x)) for i, (e, x) in enumerate(zip(ends, lengths,
                                                                        strict=True))]
    lk = build_linkage(2, vs, bs)
    return lk.with_positions(project(lk).positions)


def torus() -> Linkage:
    x = (1.2 ** 2 - 2.2 ** 2 + 3.3 ** 2) / (2 * 3.3)
    vs = [VertexSpec("P", (0.0, 0.0, 0.0), True), VertexSpec("Q", (2.5, 0.0, 0.0), True),
          VertexSpec("A", (x, np.sqrt(1.2 ** 2 - x ** 2), 0.0)),
          VertexSpec("B", (3.3, 0.0, 0.0), (False, False, True))]
    return build_linkage(3, vs, [BarSpec("PA", ("P", "A")), BarSpec("QB", ("Q", "B")),
                                 BarSpec("AB", ("A", "B"))])


def sphere() -> Linkage:
    vs = [VertexSpec("P", (0.0, 0.0, 0.0), True), VertexSpec("A", (1.3, 0.0, 0.0))]
    return build_linkage(3, vs, [BarSpec("r", ("P", "A"))])


ROWS = {
    "pentagon (1,1,1,1,1)": lambda: pentagon((1, 1, 1, 1, 1)),
    "pentagon (1,1,2,2,3)": lambda: pentagon((1, 1, 2, 2, 3)),
    "five-bar (2,1,1.4,1.6,1)": lambda: pentagon((2, 1, 1.4, 1.6, 1)),
    "3D sliding torus": torus,
    "3D sphere": sphere,
}


def best(fn, repeat: int):
    times, out = [], None
    for _ in range(repeat):
        t = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t)
    return min(times), out


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--proof", action="store_true")
    args = ap.parse_args()
    print(f"{'row':28} {'march s':>8} {'tri':>6} {'explore s':>9} {'tri':>6} "
          f"{'genus':>5} {'morse':>5} {'complete':>8} reason")
    for name, build in ROWS.items():
        lk = build()
        step = 0.25 * float(np.median(lk.lengths[lk.active]))
        t_m, m = best(lambda lk=lk, step=step: march(Surface(lk), lk.coordinates(), step,
                                                       20_000), args.repeat)
        for paths in ((512, 4096) if args.proof else (512,)):
            t_e, r = best(lambda lk=lk, paths=paths: explore_surfaces(
                lk, options=SurfaceOptions(homotopy_paths_max=paths)), args.repeat)
            genus = [c.homology.genus for c in r.components]
            print(f"{name + ('' if paths == 512 else ' proof'):28} {t_m:8.2f} "
                  f"{len(m.triangles):6d} {t_e:9.2f} {r.search['triangles']:6d} "
                  f"{str(genus):>5} {str(r.search['morse_agrees']):>5} "
                  f"{str(r.search.complete):>8} {r.search.reason}")


if __name__ == "__main__":
    main()
