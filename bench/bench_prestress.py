"""Prestress stability / second-order rigidity: time of the decision against the number of
self-stresses ``s`` and non-trivial flexes ``k``, and agreement with PyRigi 1.3 (run on demand).

    .venv/bin/python bench/bench_prestress.py [--repeat 3] [--json bench/results/prestress.json]
        [--no-pyrigi]

1. **Scaling on frameworks.** ``braced line``: ``n`` free vertices on the x-axis between two pins,
   every pair within ``reach`` steps joined by a bar (collinear, so every bar is in tension in
   some stress): in 3D ``k = 2n`` flexes (the y and z motions) and ``s = E - n`` stresses; all
   prestress stable (the SDP path for ``s, k >= 2``). With ``--unstable`` rows, a free hinged
   rotor is added beside it: one more flex with no energy, so not prestress stable: the dual
   certificate and the search for a second-order flex are timed too. Timed: ``prestress(lk,
   first_order(lk))`` (the ``Q_k``, the SDP, the numpy checks), first-order analysis apart.
2. **Scaling on forms.** :func:`engine.local.prestress.decide` on random ``Q_k`` (seeded) up to the
   limits ``MAX_FLEXES`` / ``MAX_STRESSES``: feasible (a planted definite combination) and
   infeasible (trace-zero forms: no definite combination exists).
3. **PyRigi 1.3.** ``Framework.is_prestress_stable(numerical=True)`` and
   ``is_second_order_rigid(numerical=True)`` on PyRigi's own catalogue, against ours on the same
   positions and edges; PyRigi raises where both ``s`` and ``k`` exceed 1, which is printed.

BLAS on one thread (``OPENBLAS_NUM_THREADS=1``), best of ``--repeat`` wall-clock runs.
"""

from __future__ import annotations

import os

for _name in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_name, "1")

import argparse  # noqa: E402
import sys  # noqa: E402
import warnings  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bench.harness import Table, best_of  # noqa: E402
from engine.local.prestress import MAX_FLEXES, MAX_STRESSES, decide, prestress  # noqa: E402
from engine.local.rigidity import first_order  # noqa: E402
from engine.model.linkage import BarSpec, Linkage, VertexSpec, build_linkage  # noqa: E402
from engine.model.tolerances import Tolerances  # noqa: E402


def braced_line(n: int, reach: int, unstable: bool = False) -> Linkage:
    """``n`` free vertices between pins at x = 0 and x = n + 1, bars up to ``reach`` apart."""
    vertices = [VertexSpec("P0", [0.0, 0.0, 0.0], True)]
    vertices += [VertexSpec(f"V{i}", [float(i), 0.0, 0.0]) for i in range(1, n + 1)]
    vertices.append(VertexSpec(f"P{n + 1}", [float(n + 1), 0.0, 0.0], True))
    names = ["P0"] + [f"V{i}" for i in range(1, n + 1)] + [f"P{n + 1}"]
    bars = [BarSpec(f"b{i}_{j}", (names[i], names[j]))
            for i in range(n + 2) for j in range(i + 1, min(i + reach + 1, n + 2))
            if not (i == 0 and j == n + 1)]
    if unstable:
        vertices += [VertexSpec("H0", [0.0, 3.0, -0.5], True),
                     VertexSpec("H1", [0.0, 3.0, 0.5], True), VertexSpec("C", [0.8, 3.0, 0.0])]
        bars += [BarSpec("c0", ("H0", "C")), BarSpec("c1", ("H1", "C"))]
    return build_linkage(3, vertices, bars)


def random_forms(s: int, k: int, feasible: bool, seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    q = rng.standard_normal((s, k, k))
    q = q + q.transpose(0, 2, 1)
    if feasible:
        q[0] = 3.0 * np.eye(k) * np.sqrt(k) - 0.1 * q[1:].sum(axis=0)
    else:  # trace 0: <Q_k, I/k> = 0 for every k, so no combination is definite
        q -= np.einsum("sii->s", q)[:, None, None] * np.eye(k) / k
    return q, 4.0 * np.abs(q).sum(axis=(1, 2)) / k


def scaling_frameworks(table: Table, repeat: int) -> None:
    for n, reach in ((2, 2), (4, 2), (4, 4), (8, 2), (8, 4), (12, 3), (16, 2), (16, 4), (20, 3),
                     (24, 2), (30, 2)):
        for unstable in (False, True):
            lk = braced_line(n, reach, unstable)
            rig = first_order(lk)
            seconds, pre = best_of(lambda lk=lk, rig=rig: prestress(lk, rig), repeat)
            table.record(
                f"braced line n={n} reach={reach}{' + rotor' if unstable else ''}", seconds,
                f"s={rig.self_stresses.shape[0]} k={rig.dof}",
                stable=pre.prestress_stable, second_order_rigid=pre.second_order_rigid,
                method=pre.method,
            )


def scaling_forms(table: Table, repeat: int) -> None:
    tol = Tolerances()
    for k in (2, 5, 10, 20, 30, MAX_FLEXES):
        for s in (2, 10, 50, 200, MAX_STRESSES):
            for feasible in (True, False):
                q, scales = random_forms(s, k, feasible, seed=1000 * k + s)
                seconds, dec = best_of(lambda q=q, scales=scales: decide(q, scales, tol),
                                       repeat if k <= 20 else 1)
                table.record(f"forms s={s} k={k} {'feasible' if feasible else 'infeasible'}",
                             seconds, "", stable=dec.stable, second_order_rigid=dec.rigid,
                             success=dec.success)


def agreement_with_pyrigi(table: Table) -> None:
    try:
        import pyrigi.frameworkDB as fdb
    except ImportError:
        print("PyRigi is not installed (pip install -e '.[bench]'): agreement skipped")
        return
    from tests.engine.local.test_prestress_pyrigi import PYRIGI_CASES, ours, theirs

    for name in PYRIGI_CASES:
        framework = PYRIGI_CASES[name](fdb)
        seconds, mine = best_of(lambda f=framework: ours(f), 1)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            their_seconds, other = best_of(lambda f=framework: theirs(f), 1)
        agree = all(o is None or o == m for m, o in zip(mine[:2], other, strict=True))
        table.record(f"pyrigi {name}", seconds, f"s={mine[2]} k={mine[3]}",
                     ours=mine[:2], pyrigi=other, pyrigi_seconds=their_seconds, agree=agree)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--json", type=Path, default=None)
    parser.add_argument("--no-pyrigi", action="store_true")
    args = parser.parse_args()
    table = Table(f"prestress decision (limits: {MAX_FLEXES} flexes, {MAX_STRESSES} stresses)")
    scaling_frameworks(table, args.repeat)
    scaling_forms(table, args.repeat)
    if not args.no_pyrigi:
        agreement_with_pyrigi(table)
    if args.json:
        table.save(args.json)


if __name__ == "__main__":
    main()
