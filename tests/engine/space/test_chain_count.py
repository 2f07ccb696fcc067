"""The closed-form component count of rotor chains against full enumeration by the tracer."""

from __future__ import annotations

import numpy as np
import pytest

from engine.catalogue.presets import build_preset, circle_intersection
from engine.model.linkage import BarSpec, Linkage, VertexSpec, build_linkage
from engine.space.chain_count import chain_components
from engine.space.configuration_space import SpaceOptions, explore


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
    res = explore(build_preset("gated-kl-chain", {"n": 4, "gate": 2}),
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
    # never skipped where the rules give no count (the gated chain has critical lengths)
    gated = explore(build_preset("gated-kl-chain", {"n": 4, "gate": 1}), near_misses=False,
                    options=SpaceOptions(max_components=2))
    assert "critical_search" not in gated.search
