"""Gated chains driven from another rotor than the gate's (engine/space/gate_transfer.py,
through :func:`engine.space.chain_count.gated_chain_components` and ``gate_decision``): counts
and ``gated`` against dense sampling of a rotor's angle with closed-form circle intersections
(tests/gated_reference.py), on both sides of every critical line in ``L1``, which this test
finds itself: where ``L2 + L1`` or ``|L2 - L1|`` meets an extreme of the distance from the gate
rotor's tip to the slider along the chain's motion (sampled here from rotor 0, which drives
these chains)."""

from __future__ import annotations

import functools
import itertools

import numpy as np
import pytest
from scipy.optimize import minimize_scalar

from engine.catalogue.presets import build_preset
from engine.design.sweep_rules import derive
from engine.model.linkage import BarSpec, VertexSpec, build_linkage
from engine.space.chain_count import gate_decision, gated_chain, gated_chain_components
from tests.gated_reference import sampled_general_chain


def meet(c0: np.ndarray, r0: float, c1: np.ndarray, r1: float, side: float) -> np.ndarray | None:
    d = c1 - c0
    dist = float(np.hypot(*d))
    along = (dist**2 + r0**2 - r1**2) / (2 * dist)
    if r0**2 - along**2 < 0:
        return None
    u = d / dist
    return c0 + along * u + side * np.sqrt(r0**2 - along**2) * np.array([-u[1], u[0]])


def chain_tips(pins, r, couplers, theta: float, sides) -> list[np.ndarray] | None:
    """Tips solved rightwards from rotor 0 at ``theta`` (rotor 0 drives the test chains)."""
    tips = [pins[0] + r[0] * np.array([np.cos(theta), np.sin(theta)])]
    for k in range(1, len(pins)):
        tip = meet(tips[-1], couplers[k - 1], pins[k], r[k], sides[k - 1])
        if tip is None:
            return None
        tips.append(tip)
    return tips


def build(xs, r, couplers, gate: int, d: float, l1: float, l2: float):
    """The gated chain as a bar list: pins at (x_k, 0), the slider G on the vertical line
    through P_gate at (x_g, -D), assembled at the first angle of rotor 0 where it closes."""
    n = len(xs)
    pins = np.column_stack([xs, np.zeros(n)])
    slider = pins[gate] + np.array([0.0, -d])
    for theta in np.linspace(0, 2 * np.pi, 721):
        for sides in itertools.product((1.0, -1.0), repeat=n):
            tips = chain_tips(pins, r, couplers, theta, sides[:-1])
            rk = None if tips is None else meet(tips[gate], l2, slider, l1, sides[-1])
            if rk is None:
                continue
            verts = [VertexSpec(f"P{k}", pins[k].tolist(), True) for k in range(n)]
            verts += [VertexSpec(f"T{k}", tips[k].tolist()) for k in range(n)]
            verts += [VertexSpec("G", slider.tolist(), [True, False]),
                      VertexSpec("R", rk.tolist())]
            bars = [BarSpec(f"r{k}", (f"P{k}", f"T{k}"), r[k]) for k in range(n)]
            bars += [BarSpec(f"l{k}", (f"T{k}", f"T{k + 1}"), couplers[k]) for k in range(n - 1)]
            bars += [BarSpec("D", (f"P{gate}", "G"), d), BarSpec("L1", ("G", "R"), l1),
                     BarSpec("L2", (f"T{gate}", "R"), l2)]
            return build_linkage(2, verts, bars), pins
    return None, pins


def critical_l1(xs, r, couplers, gate: int, d: float, l2: float) -> list[float]:
    """The L1 where the gate's closing range ``[|L2 - L1|, L2 + L1]`` has an end at an extreme
    of ``|T_gate - G|`` along some chain component (rotor 0 sampled, every extreme refined)."""
    n = len(xs)
    pins = np.column_stack([xs, np.zeros(n)])
    theta = np.linspace(0, 2 * np.pi, 2001)
    out = []
    for sides in itertools.product((1.0, -1.0), repeat=n - 1):
        for sy in (-d, d):
            g = pins[gate] + np.array([0.0, sy])

            def dist(t: float, sides=sides, g=g) -> float:
                tips = chain_tips(pins, r, couplers, t, sides)
                assert tips is not None  # rotor 0 drives the chain
                return float(np.hypot(*(tips[gate] - g)))

            vals = np.array([dist(t) for t in theta])
            for i in range(1, len(theta) - 1):
                for sgn in (1.0, -1.0):
                    if sgn * vals[i] >= sgn * vals[i - 1] and sgn * vals[i] > sgn * vals[i + 1]:
                        res = minimize_scalar(lambda t, sgn=sgn: -sgn * dist(t),
                                              bounds=(theta[i - 1], theta[i + 1]),
                                              method="bounded", options={"xatol": 1e-12})
                        e = -sgn * float(res.fun) * 1.0
                        out += [e - l2, l2 + e, l2 - e]
    return sorted({round(v, 9) for v in out if v > 0.05})


#: (xs of the pins, rotor lengths, couplers, gate, D, L2): chains that rotor 0 drives and the
#: gate rotor does not (rotor 1 rocks in the first cell: r0 < a, its far side shorter)
CHAINS = [
    ((0.0, 1.0, 2.0), (0.3, 0.8, 1.5), (1.0, 1.5), 1, 2.0, 2.0),
    ((0.0, 1.0, 2.0, 3.0), (0.35, 0.8, 1.5, 1.5), (1.05, 1.5, 1.5), 2, 1.6, 1.7),
    ((0.0, 1.3, 2.6, 3.9, 5.2), (0.4, 1.0, 2.0, 2.0, 2.0), (1.3, 2.0, 2.0, 2.0), 1, 2.5, 2.2),
    ((0.0, 1.0, 2.0, 3.0, 4.0, 5.0), (0.3, 0.8, 1.5, 1.5, 1.5, 1.5), (1.0, 1.5, 1.5, 1.5, 1.5),
     3, 2.2, 1.8),
]


def test_the_test_chains_are_driven_from_rotor_0_and_not_from_the_gate():
    for xs, r, couplers, gate, d, l2 in CHAINS:
        lk, _ = build(xs, r, couplers, gate, d, l2, l2)
        parts = gated_chain(lk)
        assert parts is not None and parts.driver == 0 and not parts.chain_driven


@functools.cache
def picks(chain: int) -> tuple[float, ...]:
    """Three of the chain's critical L1 spread over its list, each with both sides: the line
    moved by 0.04, or by less than half the gap to the neighbouring lines."""
    xs, r, couplers, gate, d, l2 = CHAINS[chain]
    crit = critical_l1(xs, r, couplers, gate, d, l2)
    out: list[float] = []
    for c in crit[:: max(1, len(crit) // 3)][:3]:
        gap = min([abs(c - o) for o in crit if o != c] + [1.0])
        delta = min(0.04, 0.45 * gap)
        if delta >= 0.005:
            out += [round(c - delta, 6), round(c + delta, 6)]
    return tuple(out)


@pytest.mark.slow
@pytest.mark.parametrize("chain", range(len(CHAINS)), ids=lambda k: f"n{len(CHAINS[k][0])}")
@pytest.mark.parametrize("pick", range(6))
def test_count_and_gated_against_dense_sampling(chain: int, pick: int):
    """Each chain at six L1: three of its critical lines, on either side of each."""
    if pick >= len(picks(chain)):
        pytest.skip("the chain has fewer critical lines apart enough to sample")
    xs, r, couplers, gate, d, l2 = CHAINS[chain]
    l1 = picks(chain)[pick]
    lk, pins = build(xs, r, couplers, gate, d, l1, l2)
    if lk is None:  # built where it closes, then given this L1 (off its configuration space)
        lk, pins = build(xs, r, couplers, gate, d, l2, l2)
        lengths = np.array(lk.lengths)
        lengths[lk.bar_ids.index("L1")] = l1
        lk = lk.with_lengths(lengths)
    count = gated_chain_components(lk)
    decision = gate_decision(lk)
    sliders = np.array([pins[gate] + [0.0, -d], pins[gate] + [0.0, d]])
    comps, turns = sampled_general_chain(pins, np.array(r), np.array(couplers), gate, sliders,
                                         l1, l2, sampled=0, samples=3000)
    assert count is not None and count.components == comps, (count, comps)
    assert decision.gated is (not turns if comps else None), decision
    row = derive(lk)  # a sweep's row, from the same rules
    assert row is not None and (row.components, row.gated) == (comps, decision.gated)
    if comps:
        turning = {w for w in row.windings if any(p.split(":")[1] != "0"
                                                   for p in w.split(","))}
        assert bool(turning) is turns, row.windings


@pytest.mark.parametrize("l1", [0.49, 1.4])
def test_no_critical_point_where_the_crossings_are_transversal(l1: float):
    """The rule says the chain has no critical point (the search then skips it): along the
    configuration space, sampled densely from rotor 0 with circle intersections here (every
    assembly mode, both slider places, both places of R, up to the folds), the rigidity
    matrix written here (rows d(l^2)/du of every bar; free: the tips, R and the slider's y)
    keeps full rank, its smallest singular value over its largest far from 0."""
    xs, r, couplers, gate, d, l2 = CHAINS[0]
    lk, pins = build(xs, r, couplers, gate, d, l1, l2)
    assert gated_chain_components(lk) is not None
    n = len(xs)
    worst = np.inf
    for theta in np.linspace(0, 2 * np.pi, 1500, endpoint=False):
        for sides in itertools.product((1.0, -1.0), repeat=n + 1):
            tips = chain_tips(pins, r, couplers, theta, sides[: n - 1])
            g = pins[gate] + np.array([0.0, sides[n - 1] * d])
            rk = None if tips is None else meet(tips[gate], l2, g, l1, sides[n])
            if rk is None:
                continue
            # free coordinates: T_k (2n), R (2), G_y (1)
            rows = []
            for k in range(n):
                row = np.zeros(2 * n + 3)
                row[2 * k:2 * k + 2] = 2 * (tips[k] - pins[k])
                rows.append(row)
            for k in range(n - 1):
                row = np.zeros(2 * n + 3)
                diff = tips[k] - tips[k + 1]
                row[2 * k:2 * k + 2], row[2 * k + 2:2 * k + 4] = 2 * diff, -2 * diff
                rows.append(row)
            row = np.zeros(2 * n + 3)  # D: P_g to G, G moves in y
            row[-1] = 2 * (g - pins[gate])[1]
            rows.append(row)
            row = np.zeros(2 * n + 3)  # L1: G to R
            row[2 * n:2 * n + 2] = 2 * (rk - g)
            row[-1] = -2 * (rk - g)[1]
            rows.append(row)
            row = np.zeros(2 * n + 3)  # L2: T_g to R
            row[2 * gate:2 * gate + 2] = 2 * (tips[gate] - rk)
            row[2 * n:2 * n + 2] = -2 * (tips[gate] - rk)
            rows.append(row)
            sv = np.linalg.svd(np.array(rows), compute_uv=False)
            worst = min(worst, sv[-1] / sv[0])
    assert worst > 1e-3, worst


def shuffled(lk, seed: int):
    """The same linkage with its vertices and bars listed in another order."""
    rng = np.random.default_rng(seed)
    vorder = rng.permutation(lk.n_vertices)
    border = rng.permutation(lk.n_bars)
    verts = [VertexSpec(lk.vertex_ids[i], [float(x) for x in lk.positions[i]],
                        [bool(f) for f in lk.fixed[i]]) for i in vorder]
    bars = [BarSpec(lk.bar_ids[k], (lk.vertex_ids[int(lk.ends[k, 1])],
                                    lk.vertex_ids[int(lk.ends[k, 0])]), float(lk.lengths[k]))
            for k in border]
    return build_linkage(2, verts, bars)


@pytest.mark.parametrize("l1", [0.347, 1.3866, 3.053])
def test_count_and_gated_do_not_depend_on_the_order_of_the_lists(l1: float):
    """Whichever rotor the vertex and bar lists put first (and whichever end of a bar), the
    count, its driver and gated are the same."""
    xs, r, couplers, gate, d, l2 = CHAINS[1]
    lk, _ = build(xs, r, couplers, gate, d, l1, l2)
    count, decision = gated_chain_components(lk), gate_decision(lk)
    assert count is not None
    for seed in range(4):
        other = shuffled(lk, seed)
        again = gated_chain_components(other)
        assert again is not None and again.components == count.components
        assert again.rotors[again.driver] == count.rotors[count.driver] == "r0"
        assert gate_decision(other).gated is decision.gated


# -- gated chains driven from no rotor, the gate rotor a crank of the gate four-bar ------------

#: (r0, r1) in the corners of the matrix's map r0 x r1 in [1.2, 1.8]^2 of the spinner chain
#: (a = 1, r = l = 1.5) beyond the first cell's Grashof lines s + l = p + q: there no rotor
#: drives the chain (the first four-bar, non-Grashof, does); and one inside (a rotor drives).
CORNERS = [(1.2, 1.2), (1.8, 1.2), (1.2, 1.8), (1.25, 1.7)]


def written_grashof_turns(a: float, r0: float, coupler: float, r1: float) -> bool:
    """Some rotor of the first four-bar (ground a) turns: Grashof (s + l < p + q) with a rotor
    or the ground the shortest side, written out."""
    sides = [a, r0, coupler, r1]
    srt = sorted(sides)
    return srt[0] + srt[3] < srt[1] + srt[2] and int(np.argmin(sides)) != 2


@pytest.mark.parametrize(("n", "gate"), [(4, 2), (3, 1)])
@pytest.mark.parametrize(("r0", "r1"), CORNERS)
def test_a_cranking_gate_restricts_nothing(n: int, gate: int, r0: float, r1: float) -> None:
    """Count and ``gated`` of gated chains whose gate rotor cranks the gate four-bar (D = 2,
    r_g = 1.5 or r1, L1 = L2 = 2), driven from their first four-bar or a rotor, against dense
    sampling of rotor 0's angle (its tip sampled round its circle, every other vertex by circle
    intersections, folds joined): the chain's count (Grashof 2 circuits or not 1, times 2 per
    other cell) times 2 places of the rocker times 2 of the slider."""
    lk = build_preset("gated-kl-chain", {"n": n, "gate": gate})
    lengths = lk.lengths.copy()
    lengths[[lk.bar_ids.index("r0"), lk.bar_ids.index("r1")]] = r0, r1
    lk = lk.with_lengths(lengths)
    pins = np.column_stack([np.arange(n, dtype=float), np.zeros(n)])
    r = np.array([r0, r1] + [1.5] * (n - 2))
    sliders = np.array([pins[gate] + [0.0, -2.0], pins[gate] + [0.0, 2.0]])
    count, turns = sampled_general_chain(pins, r, np.full(n - 1, 1.5), gate, sliders, 2.0, 2.0,
                                         sampled=0, samples=3000)
    sides = [1.0, r0, 1.5, r1]
    srt = sorted(sides)
    assert count == (2 if srt[0] + srt[3] < srt[1] + srt[2] else 1) * 2 ** (n - 2) * 4
    row = derive(lk)
    assert row is not None and row.components == count
    decision = gate_decision(lk)
    assert decision.gated is (not turns) is row.gated, decision
    parts = gated_chain(lk)
    assert parts is not None
    if (r0, r1) != CORNERS[-1]:  # the corners: no rotor drives, the first four-bar does
        assert parts.driver is None
        assert turns == written_grashof_turns(1.0, r0, 1.5, r1)
