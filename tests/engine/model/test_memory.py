"""Memory estimates of the first- and second-order analyses (issue 11, item 4).

The estimates are checked against the real thing: each analysis runs in a subprocess whose
``RLIMIT_DATA`` leaves it exactly the estimated room, and must succeed there (the estimate is
enough), while a room below the estimate is refused before anything is allocated.
"""

from __future__ import annotations

import subprocess
import sys
import textwrap

import pytest

from engine.catalogue.presets import build_preset
from engine.local.rigidity import (
    DENSE_FALLBACK_MAX_FREE,
    SPARSE_MAX_NULLITY,
    first_order,
    plan_first_order,
)
from engine.local.second_order import second_order, second_order_memory
from engine.model.errors import LimitExceeded
from engine.model.linkage import BarSpec, Linkage, VertexSpec, build_linkage
from engine.model.memory import (
    MEMORY_CHECK_MIN_BYTES,
    MemoryLimitExceeded,
    available_memory,
    check_memory,
)
from tests.load import Timer
from tests.service.test_uvicorn_process import ROOT


def floppy(free: int, braced_every: int = 0) -> Linkage:
    """Two pins joined by a zigzag path of ``free`` free vertices (``free - 1`` zero modes);
    with ``braced_every``, every so many free vertex is also tied to a pin below it."""
    vertices = [VertexSpec("P0", [0.0, 0.0], True)]
    vertices += [VertexSpec(f"v{k}", [0.5 * k, 0.3 * (k % 2)]) for k in range(1, free + 1)]
    vertices.append(VertexSpec("P1", [0.5 * (free + 1), 0.0], True))
    ids = [v.id for v in vertices]
    bars = [BarSpec(f"b{k}", (ids[k], ids[k + 1])) for k in range(len(ids) - 1)]
    if braced_every:
        for k in range(1, free + 1, braced_every):
            vertices.append(VertexSpec(f"G{k}", [0.5 * k, -1.0], True))
            bars.append(BarSpec(f"g{k}", (f"v{k}", f"G{k}")))
    return build_linkage(2, vertices, bars)


@pytest.mark.parametrize("free", [8000, 49_998])
def test_floppy_chains_beyond_both_methods_are_refused_at_once(free):
    linkage = floppy(free)
    for analysis in (first_order, second_order):
        with Timer() as t, pytest.raises(LimitExceeded) as err:
            analysis(linkage)
        # refused from the sizes, nothing computed: 5 s on an idle machine, scaled by the load
        assert t.within(0.0, 5.0), t
        assert not isinstance(err.value, MemoryLimitExceeded)
        assert f"{free - 1} independent zero modes" in err.value.message
        assert f"({SPARSE_MAX_NULLITY})" in err.value.message
        assert f"({DENSE_FALLBACK_MAX_FREE})" in err.value.message


def test_overbraced_linkages_beyond_the_sparse_search_are_refused():
    # every free vertex of a 2,500-vertex path tied to two pins: E - M = 2501 self-stresses
    free = 2500
    vertices = [VertexSpec("P0", [0.0, 0.0], True)]
    vertices += [VertexSpec(f"v{k}", [0.5 * k, 0.3 * (k % 2)]) for k in range(1, free + 1)]
    vertices.append(VertexSpec("P1", [0.5 * (free + 1), 0.0], True))
    ids = [v.id for v in vertices]
    bars = [BarSpec(f"b{k}", (ids[k], ids[k + 1])) for k in range(len(ids) - 1)]
    for k in range(1, free + 1):
        for side, y in (("a", -1.0), ("b", 2.0)):
            vertices.append(VertexSpec(f"G{side}{k}", [0.5 * k + 0.1, y], True))
            bars.append(BarSpec(f"g{side}{k}", (f"v{k}", f"G{side}{k}")))
    linkage = build_linkage(2, vertices, bars)
    assert linkage.n_free == 5000 and int(linkage.active.sum()) - linkage.n_free == 2501
    with pytest.raises(LimitExceeded, match="2501 independent self-stresses"):
        plan_first_order(linkage)


def test_large_null_spaces_go_to_the_dense_svd_where_it_is_allowed():
    assert plan_first_order(floppy(1000)).method == "dense-svd"  # M = 2000, 999 zero modes
    assert plan_first_order(floppy(1000, braced_every=1)).method == "sparse-eigsh"  # none
    assert plan_first_order(build_preset("kl-chain", {"n": 200})).method == "sparse-eigsh"
    # forced sparse beyond what it holds: the dense SVD (M <= 4000) instead of a doomed search
    chain = floppy(999)
    loose = [VertexSpec(f"w{k}", [float(k), 5.0]) for k in range(1000)]  # no bars at all
    vertices = [VertexSpec(i, p.tolist(), bool(f.all()))
                for i, p, f in zip(chain.vertex_ids, chain.positions, chain.fixed, strict=True)]
    bars = [BarSpec(b, (chain.vertex_ids[i], chain.vertex_ids[j]))
            for b, (i, j) in zip(chain.bar_ids, chain.ends, strict=True)]
    linkage = build_linkage(2, vertices + loose, bars)  # M = 3998, E = 1000
    plan = plan_first_order(linkage, sparse=True)
    assert plan.method == "dense-svd (sparse fallback)" and not plan.sparse


def test_check_memory():
    check_memory(MEMORY_CHECK_MIN_BYTES - 1, "small")  # not even looked up
    check_memory(10, "fits", budget=10)
    with pytest.raises(MemoryLimitExceeded) as err:
        check_memory(3 * 2**30, "the big thing", budget=2**30)
    assert err.value.message.startswith("the big thing would need about 3,072 MB")
    assert "1,024 MB" in err.value.message
    assert isinstance(err.value, LimitExceeded)
    assert available_memory() > 0


def test_estimates_grow_with_the_null_space():
    sizes = [plan_first_order(floppy(n)).memory for n in (100, 200, 400, 800)]
    assert all(b > 3 * a for a, b in zip(sizes, sizes[1:], strict=False))  # ~ k M, quadratic
    for n in (100, 400):
        assert second_order_memory(floppy(n))[0] > plan_first_order(floppy(n)).memory


# The analysis runs with RLIMIT_DATA = its data segment now + the estimate (+ a few MB for
# the interpreter's own growth): the estimate must be enough, and half of it must be refused
# before anything is allocated (not a MemoryError half way).
_RUN = textwrap.dedent("""
    import resource, sys
    from engine.model.memory import MemoryLimitExceeded, _status_bytes
    from engine.catalogue.presets import build_preset
    from engine.local.rigidity import first_order, plan_first_order
    from engine.local.second_order import second_order, second_order_memory
    from tests.engine.model.test_memory import floppy

    kind, size, which, share = sys.argv[1], int(sys.argv[2]), sys.argv[3], float(sys.argv[4])
    sparse = {"default": None, "sparse": True, "dense": False}[sys.argv[5]]
    linkage = floppy(size) if kind == "floppy" else build_preset("kl-chain", {"n": size})
    analysis = first_order if which == "first" else second_order
    for warm in (True, False):  # every code path imported and warm
        analysis(floppy(20), sparse=warm)
    need = (plan_first_order(linkage, sparse).memory if which == "first"
            else second_order_memory(linkage, sparse)[0])
    limit = _status_bytes("VmData") + int(share * need) + (16 << 20)
    resource.setrlimit(resource.RLIMIT_DATA, (limit, limit))
    try:
        analysis(linkage, sparse=sparse)
    except MemoryLimitExceeded:
        print("refused")
    else:
        print("answered")
""")

# (each estimate is above MEMORY_CHECK_MIN_BYTES, so that it is checked)
CASES = [
    ("floppy", 600, "first", "default"),   # dense SVD, 599 zero modes: 145 MB
    ("floppy", 600, "second", "default"),
    ("floppy", 400, "first", "sparse"),    # the sparse search holding 399 zero modes: 84 MB
    ("floppy", 400, "second", "sparse"),
    ("kl-chain", 20000, "first", "default"),  # sparse, one zero mode, M = 40000: 125 MB
    ("kl-chain", 20000, "second", "default"),
]


def _run(case: tuple[str, int, str, str], share: float) -> str:
    kind, size, which, method = case
    out = subprocess.run(
        [sys.executable, "-c", _RUN, kind, str(size), which, str(share), method],
        cwd=ROOT, capture_output=True, text=True, timeout=300,
        env={"OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "PATH": ""},
    )
    assert out.returncode == 0, out.stderr[-3000:]
    return out.stdout.strip()


@pytest.mark.parametrize("case", CASES, ids=["-".join(map(str, c)) for c in CASES])
@pytest.mark.slow
def test_the_estimate_is_enough_and_less_is_refused_before_allocating(case):
    assert _run(case, 1.0) == "answered"
    assert _run(case, 0.5) == "refused"
