"""The seeding's enumerations are bounded (issue 23, item 4): dyad plans in O((V + E) log V)
and the same as the scan of every unplaced vertex at every step (written out here), a
depth-first assembly tree cut by its node budget and by the deadline, chain_of deciding a long
chain in O(V + E), and projections that stop at the deadline."""

from __future__ import annotations

import numpy as np
import pytest

from engine.catalogue.presets import PRESETS, build_preset
from engine.model.budget import Deadline
from engine.model.constraints import STOPPED_BY_DEADLINE, Constraints, project
from engine.model.linkage import BarSpec, Linkage, VertexSpec, build_linkage
from engine.model.tolerances import Tolerances
from engine.space.assembly import (
    Step,
    assemblies_at,
    assemblies_at_angles,
    dyad_plan,
    iter_seeds,
    node_budget,
    rotors,
)
from engine.space.dyads import chain_of
from tests.load import Timer
from tests.service.test_bounded import deep_failing_chain

TOL = Tolerances()
GRID = 2 * np.pi * (np.arange(12) + (np.sqrt(5) - 1) / 2) / 12


def scan_plan(linkage: Linkage, rotor: int) -> list[Step] | None:
    """The reference: at every step scan the unplaced vertices in index order for the first
    with two placed neighbours (one on a slider), placed from the first two in bar order."""
    fixed = np.asarray(linkage.fixed, dtype=bool)
    placed = {v for v in range(linkage.n_vertices) if fixed[v].all()}
    pin, tip = (int(x) for x in linkage.ends[rotor])
    placed.add(tip if pin in placed else pin)
    plan: list[Step] = []
    while len(placed) < linkage.n_vertices:
        for v in range(linkage.n_vertices):
            if v in placed:
                continue
            known = [(int(j if i == v else i), float(length))
                     for (i, j), length in zip(linkage.ends, linkage.lengths, strict=True)
                     if v in (i, j) and int(j if i == v else i) in placed]
            free = np.flatnonzero(~fixed[v])
            if len(free) == 2 and len(known) >= 2:
                plan.append(Step(v, known[0][0], known[0][1], known[1][0], known[1][1]))
                break
            if len(free) == 1 and known:
                plan.append(Step(v, known[0][0], known[0][1], axis=int(free[0])))
                break
        else:
            return None
        placed.add(plan[-1].vertex)
    return plan


def random_graph(rng: np.random.Generator, n_free: int) -> Linkage:
    """Pins and free vertices (some on sliders) joined at random: plans that exist or not,
    double bars, vertices reached in any order."""
    n_pins = int(rng.integers(1, 4))
    vertices = [VertexSpec(f"P{k}", rng.normal(size=2).tolist(), True) for k in range(n_pins)]
    for k in range(n_free):
        fixed = [False, True] if rng.random() < 0.2 else False
        vertices.append(VertexSpec(f"V{k}", rng.normal(size=2).tolist(), fixed))
    ids = [v.id for v in vertices]
    bars = [BarSpec("r", ("P0", "V0"))]
    for k in range(int(rng.integers(n_free, 3 * n_free))):
        i, j = rng.choice(len(ids), size=2, replace=False)
        bars.append(BarSpec(f"b{k}", (ids[i], ids[j])))
    return build_linkage(2, vertices, bars)


def test_dyad_plans_are_those_of_the_scan_on_the_catalogue_and_random_graphs():
    linkages = [build_preset(name, {"n": 9, "gate": 4} if "gated" in name
                             else {"n": 9} if "chain" in name else {})
                for name, p in PRESETS.items() if p.dimension == 2]
    rng = np.random.default_rng(23)
    linkages += [random_graph(rng, int(rng.integers(2, 9))) for _ in range(60)]
    compared = found = 0
    for lk in linkages:
        for rotor in rotors(lk):
            ref = scan_plan(lk, rotor)
            assert dyad_plan(lk, rotor) == ref
            compared += 1
            found += ref is not None
    assert compared > 100 and 20 < found < compared  # plans that exist and plans that do not


def test_a_long_chains_plan_is_linear_not_quadratic():
    # 4000 rotors driven from the middle: the scan revisits the left half at every step
    lk = build_preset("kl-chain", {"n": 4000})
    with Timer() as t:  # (its bounds below: seconds of an idle machine, scaled by the load)
        plan = dyad_plan(lk, 2000)
    assert plan is not None and len(plan) == 3999
    assert t.within(0.0, 2.0), t


def _deep_failing() -> tuple[Linkage, int, list[Step]]:
    spec = deep_failing_chain(left=20, right=4)
    lk = build_linkage(2, [VertexSpec(v["id"], v["position"], v.get("fixed", False))
                           for v in spec["vertices"]],
                       [BarSpec(b["id"], b["ends"]) for b in spec["bars"]])
    rotor = rotors(lk)[0]
    plan = dyad_plan(lk, rotor)
    assert plan is not None and len(plan) == 24
    return lk, rotor, plan


def test_a_deep_failing_tree_is_cut_by_its_node_budget():
    lk, rotor, plan = _deep_failing()
    budget = 16
    cuts = 0
    for angle in GRID[:4]:
        with Timer() as t:
            found, cut = assemblies_at(lk, rotor, plan, float(angle), budget)
        # 2^23 partial assemblies lie above the failing rotor; the node budget is 8 * 16 * 25
        assert node_budget(plan, budget) == 3200
        assert t.within(0.0, 2.0), t
        if not found:
            assert cut  # never "no assembly" from a cut tree
        cuts += cut
    assert cuts  # (the tree is deep-failing indeed)
    # the batched sweep answers the same (its trees past the node budget go depth-first)
    batched = assemblies_at_angles(lk, rotor, plan, GRID[:4], budget)
    for angle, (found, cut) in zip(GRID[:4], batched, strict=True):
        ref, ref_cut = assemblies_at(lk, rotor, plan, float(angle), budget)
        assert cut == ref_cut and len(found) == len(ref)


def test_the_deadline_stops_the_enumeration_and_the_seeds():
    lk, rotor, plan = _deep_failing()
    gone = Deadline.after(0.0)
    assert assemblies_at(lk, rotor, plan, 0.3, 10**6, gone) == ([], True)
    assert all(r == ([], True) for r in assemblies_at_angles(lk, rotor, plan, GRID, 10**6,
                                                             gone))
    report: dict[str, object] = {}
    with Timer() as t:
        assert list(iter_seeds(lk, TOL, report, budget=10**6,
                               deadline=Deadline.after(0.3))) == []
    assert t.within(0.3, 1.0), t
    assert report["seeding"] == "stopped: time"


def test_chain_of_declines_a_long_chain_without_a_plan_per_rotor():
    lk = build_preset("kl-chain", {"n": 2000})
    with Timer() as t:
        assert chain_of(lk) is None
    assert t.within(0.0, 0.5), t
    # and still finds the short ones (the four-bar's and a 3-dyad chain's)
    assert chain_of(build_preset("four-bar")) is not None
    assert chain_of(build_preset("kl-chain", {"n": 4})) is not None


@pytest.mark.parametrize("budget_s", [0.0, 0.2])
def test_a_projection_stops_at_its_deadline(budget_s):
    lk = build_preset("kl-chain", {"n": 400})
    rng = np.random.default_rng(1234)
    free = ~np.asarray(lk.fixed, dtype=bool)
    pos = np.array(lk.positions, dtype=float)
    pos[free] += 1.5 * rng.normal(size=int(free.sum()))  # far off: seconds of LSMR steps
    with Timer() as t:
        res = project(lk.with_positions(pos), TOL, deadline=Deadline.after(budget_s))
    assert t.within(budget_s, 0.5), t
    assert not res.success and res.message == STOPPED_BY_DEADLINE


def test_a_rotor_sweep_holds_its_assemblies_a_chunk_of_angles_at_a_time():
    # a 20,000-rotor chain's 90 angles x 64 assemblies of 40,000 vertices held 3.7 GB at once
    # (and the first seed came after the whole sweep): now a chunk of at most
    # SWEEP_CHUNK_BYTES of assemblies, and the first seed after the first chunk
    import tracemalloc

    from engine.space.assembly import SWEEP_CHUNK_BYTES
    chain = build_preset("kl-chain", {"n": 20000})
    one = 8 * np.asarray(chain.positions).size  # bytes of one assembly
    tracemalloc.start()
    try:
        first = next(iter_seeds(chain, TOL, {}, 90, 64, 0, 0, 1, with_random=False,
                                deadline=Deadline.after(60.0)))
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak < 3 * max(SWEEP_CHUNK_BYTES, 64 * one) + 64 * one
    assert peak < 90 * 64 * one / 10  # (a tenth of the whole sweep)
    # the seed is an assembly: every bar at its length (residuals of the squared lengths)
    assert Constraints(chain).max_residual(first) <= 1e-6
