"""Two degrees of freedom (issue 25): time and triangles of the surfaces (run on demand, not in
the tests).

    .venv/bin/python bench/bench_surfaces.py [--repeat 3] [--proof] [--http]

Rows: the equilateral planar pentagon with one bar pinned (genus 4), a generic pentagon (genus
2), the pentagon at critical lengths (four cones: the cone homotopy and the meshing through the
apexes; genus null; at (1, 2, 1, 1, 1) and (1, 1, 1, 1, 2) nearly flat or narrow cones, meshed
with the step graded near their apexes), a five-bar (genus 3), a 3D sliding torus, a 3D sphere
and three spherical five-bars (4,608 Lagrange paths: ``derived`` by their crank angles' 24). For
each, best of ``--repeat``: the marching alone at the default step, then :func:`explore_surfaces`
with default options (homotopy within 512 paths: the pentagons' Lagrange systems need 240 from
the linear-product start, so their answers are ``proved``), wall and CPU seconds (the process's
CPU time: on a loaded machine the wall time is that CPU time stretched by the other processes);
``--proof`` adds each row with ``homotopy_paths_max = 4096``; ``--http`` posts the pentagon and
the five-bar to ``/v1/analysis/configuration-space`` of a real uvicorn process on loopback
(client-side wall time of the whole request, with ``time_budget_s: 20`` so that a loaded machine
measures the whole answer rather than the default 4 s budget's cut), and a design at the
critical pentagon (every cone asked for two sheets: the cone homotopy, the critical space's mesh
and the two re-meshings) to ``/v1/design/splitting``. BLAS on one thread, as in the service's
workers.
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


def spherical_five_bar(g: float, l1: float, l2: float, l3: float, l4: float) -> Linkage:
    """Unit sphere about the pin O; G1 = (1, 0, 0) and G2 (chord g from it, z = 0) pinned; A,
    B, C on the sphere (bars OA, OB, OC), chords L1 (G1 A), L2 (A B), L3 (B C), L4 (G2 C): a
    five-bar chain (engine.space.surfaces.five_bar), 4,608 Lagrange paths. Started where the
    three spheres of B meet, on a grid of crank angles."""
    gam = 2 * np.arcsin(g / 2)
    pins = {"O": np.zeros(3), "G1": np.array([1.0, 0, 0]),
            "G2": np.array([np.cos(gam), np.sin(gam), 0.0])}

    def circle(pole: np.ndarray, chord: float, t: float) -> np.ndarray:
        u = np.cross(pole, [0, 0, 1.0])
        u /= np.linalg.norm(u)
        al = 2 * np.arcsin(chord / 2)
        return np.cos(al) * pole + np.sin(al) * (np.cos(t) * u + np.sin(t) * np.cross(pole, u))

    for t1, t2 in ((a, b) for a in np.linspace(0.1, 6.2, 48) for b in np.linspace(0.1, 6.2, 48)):
        a, c = circle(pins["G1"], l1, t1), circle(pins["G2"], l4, t2)
        ac, h1, h2 = a @ c, 1 - l2 ** 2 / 2, 1 - l3 ** 2 / 2
        x, y = (h1 - ac * h2) / (1 - ac ** 2), (h2 - ac * h1) / (1 - ac ** 2)
        t2sq = (1 - x * x - y * y - 2 * x * y * ac) / (1 - ac ** 2)
        if t2sq > 1e-3:
            pos = pins | {"A": a, "B": x * a + y * c + np.sqrt(t2sq) * np.cross(a, c), "C": c}
            vs = [VertexSpec(k, tuple(p), k in pins) for k, p in pos.items()]
            ends = [("O", "A"), ("O", "B"), ("O", "C"), ("G1", "A"), ("A", "B"), ("B", "C"),
                    ("G2", "C")]
            return build_linkage(3, vs, [BarSpec(f"b{k}", e) for k, e in enumerate(ends)])
    raise ValueError("no assembly")


ROWS = {
    "pentagon (1,1,1,1,1)": lambda: pentagon((1, 1, 1, 1, 1)),
    "pentagon (1,1,2,2,3)": lambda: pentagon((1, 1, 2, 2, 3)),
    "pentagon (2,1,1,1,1) critical": lambda: pentagon((2, 1, 1, 1, 1)),
    "pentagon (1,2,1,1,1) flat": lambda: pentagon((1, 2, 1, 1, 1)),
    "pentagon (1,1,1,1,2) flat": lambda: pentagon((1, 1, 1, 1, 2)),
    "five-bar (2,1,1.4,1.6,1)": lambda: pentagon((2, 1, 1.4, 1.6, 1)),
    "3D sliding torus": torus,
    "3D sphere": sphere,
    "spherical five-bar genus 3": lambda: spherical_five_bar(1.2, 0.6, 1.0, 0.9, 0.7),
    "spherical five-bar genus 4": lambda: spherical_five_bar(1.2, 0.6, 1.6, 1.5, 1.4),
    "spherical five-bar two tori": lambda: spherical_five_bar(1.2, 0.6, 0.5, 1.5, 1.4),
}


def best(fn, repeat: int):
    """Best wall time, best CPU time (of this process) and the last answer."""
    times, cpus, out = [], [], None
    for _ in range(repeat):
        t, c = time.perf_counter(), time.process_time()
        out = fn()
        times.append(time.perf_counter() - t)
        cpus.append(time.process_time() - c)
    return min(times), min(cpus), out


def body(lk: Linkage) -> dict:
    """The linkage as a request body (positions, pins, bars)."""
    pos = np.asarray(lk.positions, dtype=float)
    fixed = np.asarray(lk.fixed, dtype=bool).all(axis=1)
    return {"vertices": [{"id": v, "position": pos[k].tolist(), "fixed": bool(fixed[k])}
                         for k, v in enumerate(lk.vertex_ids)],
            "bars": [{"id": b, "ends": [lk.vertex_ids[i] for i in lk.ends[k]],
                      "length": float(lk.lengths[k])} for k, b in enumerate(lk.bar_ids)]}


def http_rows(repeat: int) -> None:
    """The pentagon and the five-bar through HTTP (a uvicorn process of its own)."""
    import httpx
    from harness import served_process  # bench/ is on sys.path when run as a script

    with served_process() as url, httpx.Client(base_url=url, timeout=120) as client:
        for name in ("pentagon (1,1,1,1,1)", "five-bar (2,1,1.4,1.6,1)"):
            # (a budget beyond the default 4 s: on a loaded machine the wall time stretches)
            req = {"linkage": body(ROWS[name]()), "options": {"time_budget_s": 20}}
            times, answer = [], {}
            for _ in range(repeat):
                t = time.perf_counter()
                r = client.post("/v1/analysis/configuration-space", json=req)
                times.append(time.perf_counter() - t)
                r.raise_for_status()
                answer = r.json()
            s = answer["search"]
            print(f"HTTP {name:23} {min(times):8.2f} s  triangles "
                  f"{sum(len(x['triangles']) for x in answer['surfaces']):6d}  genus "
                  f"{[x['genus'] for x in answer['surfaces']]}  {s['homotopy_paths']} paths "
                  f"({s['homotopy_start']})  complete {s['complete']} {s['reason']} "
                  f"budget {s.get('time_budget_s')} s")
        req = {"linkage": body(ROWS["pentagon (2,1,1,1,1) critical"]()),
               "targets": [{"branch_point": k, "sheets": 2} for k in range(4)],
               "adjustable": ["b1", "b2", "b3", "b4"], "options": {"time_budget_s": 60}}
        times = []
        for _ in range(repeat):
            t = time.perf_counter()
            r = client.post("/v1/design/splitting", json=req)
            times.append(time.perf_counter() - t)
            r.raise_for_status()
            answer = r.json()
        surf = answer["surface"]
        print(f"HTTP design, critical pentagon {min(times):8.2f} s  verified "
              f"{answer['verified']}  predicted b {surf['predicted_betti_q']}  re-meshed b "
              f"{surf['betti_q']}  complete {answer['search']['complete']}")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--proof", action="store_true")
    ap.add_argument("--http", action="store_true")
    args = ap.parse_args()
    print(f"{'row':28} {'march s':>8} {'tri':>6} {'explore s':>9} {'cpu s':>6} {'tri':>6} "
          f"{'genus':>5} {'morse':>5} {'paths':>5} {'start':>14} {'complete':>8} reason")
    for name, build in ROWS.items():
        lk = build()
        step = 0.25 * float(np.median(lk.lengths[lk.active]))
        t_m, _, m = best(lambda lk=lk, step=step: march(Surface(lk), lk.coordinates(), step,
                                                       20_000), args.repeat)
        for paths in ((512, 4096) if args.proof else (512,)):
            t_e, c_e, r = best(lambda lk=lk, paths=paths: explore_surfaces(
                lk, options=SurfaceOptions(homotopy_paths_max=paths)), args.repeat)
            genus = [None if len(c.apexes) else c.homology.genus for c in r.components]
            print(f"{name + ('' if paths == 512 else ' proof'):28} {t_m:8.2f} "
                  f"{len(m.triangles):6d} {t_e:9.2f} {c_e:6.2f} {r.search['triangles']:6d} "
                  f"{str(genus):>5} {str(r.search['morse_agrees']):>5} "
                  f"{r.search['homotopy_paths']:5d} {str(r.search['homotopy_start']):>14} "
                  f"{str(r.search.complete):>8} {r.search.reason}")
    if args.http:
        http_rows(args.repeat)


if __name__ == "__main__":
    main()
