"""The closed-form component count of rotor chains against full enumeration by the tracer, and
of gated chains (with the gate decision) against dense sampling with circle intersections."""

from __future__ import annotations

import numpy as np
import pytest

from engine.catalogue.presets import build_preset, circle_intersection
from engine.model.linkage import BarSpec, Linkage, VertexSpec, build_linkage
from engine.space.chain_count import chain_components, gate_decision, gated_chain_components
from engine.space.configuration_space import SpaceOptions, explore, find_critical_points
from tests.gated_reference import sampled_gated_chain


def chain(a: list[float], r: list[float], lc: list[float], side: float = 1.0) -> Linkage | None:
    """A rotor chain with pins spaced ``a`` along x, rotors ``r``, couplers ``lc``, assembled
    outwards from rotor 0 at the first angle that closes (None if none does)."""
    n = len(r)
    pins = np.column_stack([np.concatenate([[0.0], np.cumsum(a)]), np.zeros(n)])
    for theta in np.linspace(0.1, 2 * np.pi, 97):
        tips = [pins[0] + r[0] * np.array([np.cos(theta), np.sin(theta)])]
        for k in range(1, n):
            tip = circle_intersection(tips[-1], lc[k - 1], pins[k], r[k], side)
            if tip is None:
                break
            tips.append(tip)
        if len(tips) == n:
            vertices = [VertexSpec(f"P{k}", pins[k].tolist(), True) for k in range(n)]
            vertices += [VertexSpec(f"T{k}", tips[k].tolist()) for k in range(n)]
            bars = [BarSpec(f"r{k}", (f"P{k}", f"T{k}"), r[k]) for k in range(n)]
            bars += [BarSpec(f"l{k}", (f"T{k}", f"T{k + 1}"), lc[k]) for k in range(n - 1)]
            return build_linkage(2, vertices, bars)
    return None


def traced_components(lk: Linkage, budget: int) -> tuple[int, bool, int]:
    res = explore(lk, options=SpaceOptions(angles=40, assembly_budget=budget, random_starts=4,
                                           max_components=budget))
    return len(res.components), bool(res.search["complete"]), len(res.critical_points)


# (name, a, r, l): per-four-bar lengths, n = len(r)
COUNTED = [
    ("spinner n=2", [1.0], [1.5, 1.5], [1.5]),
    ("spinner n=3", [1.0] * 2, [1.5] * 3, [1.5] * 2),
    ("spinner n=4", [1.0] * 3, [1.5] * 4, [1.5] * 3),
    ("spinner n=5", [1.0] * 4, [1.5] * 5, [1.5] * 4),
    ("spinner n=6", [1.0] * 5, [1.5] * 6, [1.5] * 5),
    ("double cranks, unequal n=4", [1.0, 0.8, 1.1], [2.0, 1.9, 2.2, 2.1], [2.3, 2.0, 2.4]),
    # rotor 1 (the shortest, a crank on both sides) drives; rotor 0 is a rocker
    ("driver in the middle n=4", [1.0] * 3, [1.4, 0.5, 1.4, 1.5], [1.3, 1.3, 1.6]),
    ("crank-rocker n=2", [2.0], [0.6, 1.8], [2.2]),
    ("Grashof double rocker n=2", [2.0], [2.2, 2.5], [0.8]),
    ("non-Grashof n=2", [1.0], [1.0, 1.2], [2.5]),
    # no rotor drives: a four-bar does (non-Grashof: one circuit; rotors 1 and 2 drive the
    # rest outwards), c_k 2^(n-2) components
    ("driving four-bar, not Grashof, n=4", [1.0] * 3, [1.2, 1.25, 1.5, 1.5], [1.5] * 3),
    ("driving four-bar, not Grashof, n=5", [1.0] * 4, [1.5, 1.5, 1.2, 1.25, 1.5], [1.5] * 4),
    # a Grashof double rocker (its coupler the shortest side) in the middle: two circuits
    ("driving four-bar, double rocker, n=4", [1.0] * 3, [1.5] * 4, [1.5, 0.4, 1.5]),
]


@pytest.mark.parametrize(("name", "a", "r", "lc"), COUNTED, ids=[c[0] for c in COUNTED])
def test_count_matches_full_enumeration(name: str, a: list[float], r: list[float],
                                        lc: list[float]) -> None:
    lk = chain(a, r, lc)
    assert lk is not None
    count = chain_components(lk)
    assert count is not None, name
    found, complete, critical = traced_components(lk, budget=2 * count.components + 8)
    assert complete, name
    assert found == count.components, name
    assert critical == 0, name  # the rules also prove a smooth configuration space


def test_count_reported_by_explore() -> None:
    res = explore(build_preset("kl-chain", {"n": 4}))
    assert res.search["components_total"] == 8 == len(res.components)


@pytest.mark.parametrize(
    ("name", "a", "r", "lc"),
    [
        # rotor 0 is a rocker on both sides: no driver (the count would need the fibred product)
        ("rockers n=3", [1.0, 1.0], [1.0, 1.2, 1.0], [2.5, 2.5]),
        # a flat configuration exists (a + r0 = l + r1): not generic
        ("non-generic n=2", [1.0], [1.5, 1.0], [1.5]),
    ],
)
def test_no_count_outside_the_rules(name: str, a: list[float], r: list[float],
                                    lc: list[float]) -> None:
    lk = chain(a, r, lc)
    assert lk is not None
    assert chain_components(lk) is None, name


def test_no_count_for_the_gated_chain_or_other_linkages() -> None:
    assert chain_components(build_preset("gated-kl-chain")) is None
    assert chain_components(build_preset("three-rotor")) is None
    # the equilateral four-bar has branch points (non-generic): no count; a crank-rocker has 2
    assert chain_components(build_preset("four-bar")) is None
    crank_rocker = chain_components(build_preset("four-bar", {"L1": 0.5, "L2": 1.2, "L3": 1.0}))
    assert crank_rocker is not None and crank_rocker.components == 2
    # the gated chain is counted by the gate's rule: a search cut by its component budget
    # reports the true total beside what it traced, and is incomplete (a lower bound)
    res = explore(build_preset("gated-kl-chain", {"n": 4, "gate": 2}),
                  options=SpaceOptions(max_components=2))
    assert res.search["components_total"] == 2 ** 3 * 2 * 2  # D = 2 < 5/2: Grashof gate
    assert len(res.components) == 2 and not res.search["complete"]
    assert res.search["reason"] == "budget" and res.search["gated"] is False
    # at the gate's critical lengths (D = 1.5 = r + L2 - L1) there is no count
    res = explore(build_preset("gated-kl-chain", {"n": 4, "gate": 2, "D": 1.5}),
                  options=SpaceOptions(max_components=2))
    assert "components_total" not in res.search


def test_long_spinner_chain_total() -> None:
    count = chain_components(build_preset("kl-chain", {"n": 100}))
    assert count is not None and count.components == 2**99 and count.driver == 0


def test_four_bar_rule_matches_grashof_on_random_lengths() -> None:
    """The same 200 seeded generic four-bars whose traced components the configuration-space
    tests check against Grashof's rule."""
    from tests.engine.space.configuration_space.test_search import classical, random_four_bars

    for l1, l2, l3 in random_four_bars(200):
        count = chain_components(build_preset("four-bar", {"L1": l1, "L2": l2, "L3": l3}))
        assert count is not None
        assert count.components == classical(l1, l2, l3)[0]


@pytest.mark.parametrize("n", [3, 5])
@pytest.mark.slow
def test_search_skipped_where_the_rules_prove_smoothness(n: int) -> None:
    """Without near misses, a chain the rules count skips the critical-point search: the same
    components, windings and (no) critical points as the full search."""
    lk = build_preset("kl-chain", {"n": n})
    tracer = SpaceOptions(closed_form=False)  # (the closed form would answer these short chains)
    full = explore(lk, options=tracer)
    fast = explore(lk, options=tracer, near_misses=False)
    assert full.search["complete"] and fast.search["complete"]
    assert "critical_search" not in full.search
    assert fast.search["critical_search"].startswith("skipped")
    assert full.critical_points == fast.critical_points == []
    assert len(fast.components) == len(full.components) == 2 ** (n - 1)
    assert sorted(len(c.points) for c in fast.components) == \
        sorted(len(c.points) for c in full.components)
    # never skipped where the rules give no count (the gated chain at critical lengths, D =
    # 5a/2); skipped where they do (D = 2a)
    gated = explore(build_preset("gated-kl-chain", {"n": 4, "gate": 1, "D": 2.5}),
                    near_misses=False, options=SpaceOptions(max_components=2))
    assert "critical_search" not in gated.search
    gated = explore(build_preset("gated-kl-chain", {"n": 4, "gate": 1}), near_misses=False,
                    options=SpaceOptions(max_components=2))
    assert gated.search["critical_search"].startswith("skipped: gated chain")
    gated = explore(build_preset("gated-kl-chain", {"n": 4, "gate": 1, "D": 1.5}),
                    near_misses=False, options=SpaceOptions(max_components=2))
    assert "critical_search" not in gated.search


# -- gated chains against dense sampling --------------------------------------------------------

GATED = [  # (n, a, r, l, gate, D, L1, L2): the gate four-bar's critical D are 1.5, 2.5, 5.5
    (3, 1.0, 1.5, 1.5, 1, 1.2, 2.0, 2.0),   # Grashof double crank: ungated
    (4, 1.0, 1.5, 1.5, 1, 2.0, 2.0, 2.0),   # crank-rocker, the paper's red side of 5a/2
    (4, 1.0, 1.5, 1.5, 1, 2.9, 2.0, 2.0),   # non-Grashof, the blue side: gated
    (5, 1.0, 1.5, 1.5, 2, 2.4, 2.0, 2.0),   # just below 5a/2
    (5, 1.0, 1.5, 1.5, 2, 2.6, 2.0, 2.0),   # just above
    (6, 1.0, 1.5, 1.5, 3, 4.0, 2.0, 2.0),   # far above
    (4, 1.0, 1.5, 1.5, 2, 2.2, 1.2, 2.0),   # Grashof, L1 the crank: two circuits, gated
    (3, 1.0, 1.2, 1.2, 1, 2.0, 1.7, 2.0),   # another chain (r = l = 1.2 a), ungated
    (5, 2.0, 2.6, 2.6, 1, 3.0, 3.1, 2.8),   # another scale and gate: Grashof (D + r - L1 - L2
    (5, 2.0, 2.6, 2.6, 1, 3.6, 3.1, 2.8),   # = -0.3), then not (+0.3): the two sides of it
]


@pytest.mark.slow
@pytest.mark.parametrize("case", GATED, ids=lambda c: "-".join(f"{v:g}" for v in c))
def test_gated_chain_count_and_gate_against_dense_sampling(case):
    """The closed-form count and gate decision against the sampled configuration space."""
    n, a, r, coupler, gate, d, l1, l2 = case
    lk = build_preset("gated-kl-chain", {"n": n, "a": a, "r": r, "l": coupler, "gate": gate,
                                         "D": d, "L1": l1, "L2": l2})
    count = gated_chain_components(lk)
    decision = gate_decision(lk)
    components, turns = sampled_gated_chain(*case)
    assert count is not None and count.components == components, (count, components)
    assert decision.gated is (not turns), decision


def test_the_paper_gate_threshold_at_five_halves():
    """r = l = 3a/2, L1 = L2 = 2a: ungated with 2^(n+1) components below D = 5a/2, gated with
    2^n above (the issue's 4-rotor numbers: 32 and 16)."""
    for d, expected, gated in ((2.4, 32, False), (2.6, 16, True)):
        lk = build_preset("gated-kl-chain", {"n": 4, "gate": 1, "D": d})
        count = gated_chain_components(lk)
        assert count is not None and count.components == expected
        assert gate_decision(lk).gated is gated


def test_undecided_gates_say_why():
    """A chain not driven from the gate rotor (couplers shorter than the pin spacing: a cell
    whose rotors do not turn fully) and critical gate lengths (D = 5a/2): None with a reason,
    and no count."""
    lk = build_preset("gated-kl-chain", {"n": 4, "gate": 1, "r": 0.9, "l": 0.9, "D": 2.0,
                                         "L1": 1.5, "L2": 1.5})
    assert gated_chain_components(lk) is None
    dec = gate_decision(lk)
    assert dec.gated is None and "driven from no rotor" in dec.reason
    critical = build_preset("gated-kl-chain", {"n": 4, "gate": 1, "D": 2.5})
    assert gated_chain_components(critical) is None
    dec = gate_decision(critical)
    assert dec.gated is None and "critical" in dec.reason
    assert gate_decision(build_preset("kl-chain", {"n": 4})).gated is None


def _assembly_modes(lk, u: np.ndarray) -> np.ndarray:
    """The side of the diagonal ``T_k P_{k+1}`` on which ``T_{k+1}`` lies, for every four-bar
    of a Kane-Lubensky chain (vertices ``P<k>``, ``T<k>``): in the driven regime the two modes
    of each four-bar never meet, so these signs name a component."""
    return np.array(_tip_modes(lk, lk.positions_of(u)))


def _tip_modes(lk, pos: np.ndarray) -> tuple[int, ...]:
    ids = list(lk.vertex_ids)
    n = sum(v.startswith("T") for v in ids)
    tips = pos[[ids.index(f"T{k}") for k in range(n)]]
    pins = pos[[ids.index(f"P{k}") for k in range(n)]]
    d, w = pins[1:] - tips[:-1], tips[1:] - tips[:-1]
    return tuple(int(x) for x in np.sign(d[:, 0] * w[:, 1] - d[:, 1] * w[:, 0]))


@pytest.mark.slow
def test_critical_point_search_of_a_long_chain_takes_its_near_misses_on_its_own_component():
    """Where the chain rules prove that no component has a critical point, the critical-point
    search is complete without tracing an arbitrary 32 of the components for near misses (a
    10-rotor spinner chain has 512; issue 30: a 100-rotor chain spent its whole budget there):
    it traces the component the linkage is on, and its near misses lie on that component (the
    same assembly mode in every four-bar as the given configuration)."""
    lk = build_preset("kl-chain", {"n": 10})
    res = find_critical_points(lk)
    assert res.search["complete"] and res.search["argument"] == "derived"
    assert res.critical_points == [] and res.near_misses
    assert res.search["curves_traced"] == 1
    assert "component through the given configuration" in res.search["near_misses_from"]
    start = _assembly_modes(lk, lk.coordinates())
    assert np.all(start != 0)
    for miss in res.near_misses:
        assert np.array_equal(_assembly_modes(lk, miss.u), start)


@pytest.mark.slow
@pytest.mark.parametrize("d", [2.0, 3.0])
def test_a_gated_chain_driven_from_its_gate_has_no_critical_point(d: float):
    """The gated chain (4 rotors, the gate on rotor 2; ungated D = 2, gated D = 3) driven from
    its gate rotor with a generic gate four-bar has no critical point: the critical-point
    search says so with the derived argument, and dense sampling agrees: the smallest singular
    value of J over configurations spread along the traced component, relative to the largest,
    stays far from 0 (an independent measure of how near criticality they are)."""
    lk = build_preset("gated-kl-chain", {"n": 4, "gate": 2, "D": d})
    res = find_critical_points(lk)
    assert res.critical_points == []
    assert res.search["complete"] and res.search["argument"] == "derived"
    assert "gated chain" in res.search["argument_detail"]
    explored = explore(lk, options=SpaceOptions(max_components=64))
    assert explored.critical_points == []
    from engine.model.constraints import Constraints

    cons = Constraints(lk)
    gaps = []
    for comp in explored.components:
        for u in comp.points[:: max(1, len(comp.points) // 50)]:
            s = np.linalg.svd(cons.jacobian(u, sparse=False), compute_uv=False)
            gaps.append(s[-1] / s[0])
    assert len(gaps) > 100 and min(gaps) > 1e-3


def _gated_signature(lk, u: np.ndarray) -> tuple[int, ...]:
    """Which component of the 4-rotor gated chain (gate 2) ``u`` is on, read off the
    geometry: the assembly mode of each chain four-bar (as :func:`_assembly_modes`), the side
    of the diagonal ``T2 G`` on which ``R`` lies (the gate four-bar's circuit: a Grashof
    crank-rocker's transmission angle never reaches 0 or pi) and the slider's side of ``P2``."""
    pos = lk.positions_of(u)
    ids = list(lk.vertex_ids)
    t2, g, r, p2 = (pos[ids.index(v)] for v in ("T2", "G", "R", "P2"))
    d, w = g - t2, r - t2
    gate = np.sign(d[0] * w[1] - d[1] * w[0])
    return (*_tip_modes(lk, pos), int(gate), int(np.sign(g[1] - p2[1])))


@pytest.mark.slow
def test_the_components_of_a_gated_chain_are_derived_from_its_count():
    """The 4-rotor gated chain (gate 2, ungated D = 2): its 32 components (2^3 chain modes x 2
    gate circuits x 2 slider positions) are traced within the default budgets, the count
    proves that none is missing, so the exploration is complete although some assemblies per
    angle were left untried (32 > 16 per angle); each traced component keeps one geometric
    signature along it, and the 32 signatures are all different."""
    lk = build_preset("gated-kl-chain", {"n": 4, "gate": 2})
    res = explore(lk, near_misses=False)
    assert res.search["complete"] and res.search["argument"] == "derived"
    assert res.search["assemblies_truncated"]  # (the count, not the seeds, proves it)
    assert len(res.components) == res.search["components_total"] == 32
    signatures = set()
    for comp in res.components:
        along = {_gated_signature(lk, u) for u in comp.points[:: max(1, len(comp.points) // 40)]}
        assert len(along) == 1 and 0 not in next(iter(along))
        signatures |= along
    assert len(signatures) == 32


@pytest.mark.slow
@pytest.mark.parametrize(("d", "total", "gated"), [(2.0, 16, False), (3.0, 8, True)])
def test_gated_chain_searches_are_complete_and_gated_whatever_was_traced(d, total, gated):
    """The 3-rotor gated chain (the paper's lengths, either side of D = 5a/2): a search that
    traced all the rule's components is complete (derived; the assembly budget then cut
    nothing); one cut to 3 components keeps the same total and the same ``gated`` (decided from
    the gate four-bar, not the traced components) and is incomplete; the critical-point
    search is complete with none. The total against the dense sampling."""
    lk = build_preset("gated-kl-chain", {"n": 3, "gate": 1, "D": d})
    assert sampled_gated_chain(3, 1.0, 1.5, 1.5, 1, d, 2.0, 2.0)[0] == total
    full = explore(lk, near_misses=False)
    assert len(full.components) == total == full.search["components_total"]
    assert full.search["complete"] and full.search["argument"] == "derived"
    assert full.search["gated"] is gated
    cut = explore(lk, near_misses=False, options=SpaceOptions(max_components=3))
    assert len(cut.components) == 3 and cut.search["components_total"] == total
    assert not cut.search["complete"] and cut.search["gated"] is gated
    crit = find_critical_points(lk)
    assert crit.critical_points == [] and crit.search["complete"]
    assert crit.search["gated"] is gated
