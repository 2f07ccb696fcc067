"""Sweep rows from the chain rules against dense sampling: the rotor angles of every component
sampled along its closed walk, each vertex placed by a closed-form circle intersection (written
here, not the engine's), the turns counted on the unwrapped angles."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from engine.catalogue.presets import build_preset
from engine.design.sweep import BarFamily
from engine.design.sweep_rules import derive
from engine.model.errors import InvalidParameter

SAMPLES = 2048


def meet(c0: np.ndarray, r0: float, c1: np.ndarray, r1: float, side: int
         ) -> tuple[np.ndarray, np.ndarray]:
    """Points (K, 2) at distance r0 from c0 (K, 2) and r1 from c1 (K, 2), on ``side`` (+-1) of
    c0 -> c1, and the squared half-chord h^2 (K,) (negative: the circles do not meet)."""
    d = c1 - c0
    dist = np.hypot(d[:, 0], d[:, 1])
    along = (dist**2 + r0**2 - r1**2) / (2 * dist)
    h2 = r0**2 - along**2
    e = d / dist[:, None]
    normal = np.stack([-e[:, 1], e[:, 0]], axis=1)
    h = np.sqrt(np.maximum(h2, 0.0))
    return c0 + along[:, None] * e + side * h[:, None] * normal, h2


def turns(angles: np.ndarray) -> int:
    """Net turns of an angle sampled along a closed walk (first sample repeated at the end)."""
    return int(np.rint((np.unwrap(angles)[-1] - angles[0]) / (2 * np.pi)))


def chain_walks(pins: np.ndarray, r: list[float], lc: list[float], m: int, tip_m: np.ndarray
                ) -> list[dict[int, np.ndarray]]:
    """Rotor angles (by rotor index) along the walk ``tip_m`` (K, 2) of rotor ``m``'s tip, for
    every choice of assembly mode per cell, the chain placed outwards from ``m``. The modes
    must stay apart along the walk (a driven chain): asserted, the premise of following one
    mode per cell."""
    n = len(pins)
    out = []
    for modes in itertools.product((1, -1), repeat=n - 1):
        tips = {m: tip_m}
        for k in list(range(m + 1, n)) + list(range(m - 1, -1, -1)):
            prev = k - 1 if k > m else k + 1
            cell = min(k, prev)
            p = np.broadcast_to(pins[k], tip_m.shape)
            tips[k], h2 = meet(tips[prev], lc[cell], p, r[k], modes[cell])
            assert h2.min() > 1e-6, "modes meet: not a driven chain"
        out.append({k: np.arctan2(*(t - pins[k]).T[::-1]) for k, t in tips.items()})
    return out


def gated_reference(n: int, gate: int, a: float, r: float, lc: float, D: float, L1: float,
                    L2: float) -> tuple[int, set[str], bool]:
    """Components, rotor-turn patterns and gated of the preset's gated chain, by sampling the
    gate angle: for each of the slider's two places, the gate four-bar's loops (the whole
    circle once per mode where R places everywhere, else each arc of gate angles where it
    does, out on one mode and back on the other), times the chain's mode choices."""
    pins = np.array([[k * a, 0.0] for k in range(n)])
    th = np.linspace(0.0, 2 * np.pi, SAMPLES, endpoint=False)
    tip = pins[gate] + r * np.stack([np.cos(th), np.sin(th)], axis=1)
    count, patterns = 0, set()
    for sy in (-1.0, 1.0):
        slider = np.broadcast_to(pins[gate] + [0.0, sy * D], tip.shape)
        _, h2 = meet(tip, L2, slider, L1, 1)
        ok = h2 > 0
        if ok.all():
            loops = [np.r_[np.arange(SAMPLES), 0]] * 2  # one per mode, the gate rotor turning
        else:
            start = int(np.argmin(ok))  # an angle where R does not place
            idx = np.roll(np.arange(SAMPLES), -start)
            runs = np.split(idx, np.flatnonzero(np.diff(ok[idx].astype(int)) != 0) + 1)
            loops = [np.r_[run, run[::-1]] for run in runs if ok[run[0]]]
        for loop in loops:
            for walk in chain_walks(pins, [r] * n, [lc] * (n - 1), gate, tip[loop]):
                count += 1
                patterns.add(",".join(f"r{k}:{abs(turns(walk[k]))}" for k in range(n))
                             + ",D:0")
    return count, patterns, all(set(p.replace(",", ":").split(":")[1::2]) == {"0"}
                                for p in patterns)


# (L2, D) on both sides of every critical line of the gate four-bar (D, r, L2, L1) = (D, 1.5,
# L2, 2) through the paper's point (2, 2): D = 5/2 (Grashof to non-Grashof), D = 3/2 (double
# crank to crank-rocker), L2 = 1/2 + D, L2 = 3/2 (double rocker), L2 = D + 1/2 ...
SLICE = [(2.0, 2.4), (2.0, 2.6), (2.0, 1.4), (2.0, 1.6), (1.0, 2.0), (1.6, 2.0), (1.4, 2.0),
         (3.4, 3.0), (3.6, 3.0), (0.6, 0.5), (4.0, 1.0), (2.5, 4.5)]


@pytest.mark.parametrize("n,gate,a,r,L1", [(3, 1, 1.0, 1.5, 2.0), (4, 2, 1.0, 1.5, 2.0),
                                            (5, 0, 1.0, 1.5, 2.0), (6, 3, 1.0, 1.5, 2.0),
                                            (4, 1, 0.8, 1.2, 1.7)])
@pytest.mark.parametrize("L2,D", SLICE)
def test_gated_chain_rows_follow_the_sampled_components(n, gate, a, r, L1, L2, D):
    params = {"n": n, "gate": gate, "a": a, "r": r, "l": r, "D": D * a, "L1": L1, "L2": L2}
    count, patterns, gated = gated_reference(n, gate, a, r, r, D * a, L1, L2)
    if not count:  # the gate four-bar does not close: the preset does not assemble, and the
        # rules prove the bars with these lengths (off the space) have no configuration
        with pytest.raises(InvalidParameter):
            build_preset("gated-kl-chain", params)
        off = BarFamily(build_preset("gated-kl-chain", {**params, "D": 2.0 * a, "L2": L1}),
                        ("D", "L2")).at(np.array([D * a, L2]))
        row = derive(off)
        assert row is not None and (row.components, row.windings) == (0, ())
        assert row.gated is None and "closes nowhere" in row.rule
        return
    row = derive(build_preset("gated-kl-chain", params))
    assert row is not None
    assert row.components == count
    assert row.windings == tuple(sorted(patterns))
    assert row.gated is gated
    assert row.gated_reason.startswith("gated" if gated else "ungated")


def test_the_paper_threshold_splits_gated_and_ungated():
    """L2 = L1 = 2a, r = l = 3a/2: ungated below D = 5a/2, gated above (Sec. V)."""
    rows = [derive(build_preset("gated-kl-chain", {"n": 4, "gate": 2, "D": d}))
            for d in (2.45, 2.55)]
    assert [(row.components, row.gated) for row in rows] == [(32, False), (16, True)]


def test_at_the_critical_line_no_row_is_derived():
    """D = 5/2 exactly: the gate four-bar has a flat configuration; the point is explored."""
    assert derive(build_preset("gated-kl-chain", {"n": 3, "gate": 1, "D": 2.5})) is None


def rotor_chain_reference(lk, rotor_ids: list[str], m: int) -> set[str]:
    """Patterns of a rotor chain driven from rotor ``m`` (index in chain order): the driver's
    tip sampled around its whole circle, the chain placed outwards for every mode choice."""
    ends = {b: lk.ends[lk.bar_ids.index(b)] for b in rotor_ids}
    fixed = lk.fixed.all(axis=1)
    pin_of = [int(i) if fixed[i] else int(j) for i, j in (ends[b] for b in rotor_ids)]
    tip_of = [int(j) if fixed[i] else int(i) for i, j in (ends[b] for b in rotor_ids)]
    pins = lk.positions[pin_of]
    r = [float(lk.lengths[lk.bar_ids.index(b)]) for b in rotor_ids]
    lc = []
    for k in range(len(rotor_ids) - 1):
        pair = {tip_of[k], tip_of[k + 1]}
        lc.append(next(float(length) for (i, j), length in zip(lk.ends, lk.lengths, strict=True)
                       if {int(i), int(j)} == pair))
    th = np.linspace(0.0, 2 * np.pi, SAMPLES + 1)
    tip = pins[m] + r[m] * np.stack([np.cos(th), np.sin(th)], axis=1)
    order = [lk.bar_ids[k] for k in range(lk.n_bars)
             if fixed[lk.ends[k, 0]] != fixed[lk.ends[k, 1]]]
    out = set()
    for walk in chain_walks(pins, r, lc, m, tip):
        by_id = {rotor_ids[k]: abs(turns(a)) for k, a in walk.items()}
        out.add(",".join(f"{b}:{by_id[b]}" for b in order))
    return out


@pytest.mark.parametrize("preset,params,rotor_ids,m", [
    ("kl-chain", {"n": 4}, ["r0", "r1", "r2", "r3"], 0),
    # the middle rotor drives, its circle encloses neither neighbour's pin (r2 < a): they rock
    ("three-rotor", {"r1": 1.0, "L1": 1.0, "r2": 0.5, "L2": 1.0, "r3": 1.0, "a": 1.2},
     None, None),
    # ... and both (r2 > a): all three turn
    ("three-rotor", {"r1": 1.6, "L1": 1.7, "r2": 2.0, "L2": 1.7, "r3": 1.6, "a": 1.2},
     None, None),
])
def test_rotor_chain_patterns_follow_the_sampled_components(preset, params, rotor_ids, m):
    lk = build_preset(preset, params)
    row = derive(lk)
    assert row is not None and row.turns is not None
    if rotor_ids is None:  # the rule's own order and driver, checked by the sampling
        from engine.space.chain_count import chain_components

        count = chain_components(lk)
        assert count is not None and count.driver is not None
        rotor_ids, m = list(count.rotors), count.driver
    assert row.windings == tuple(sorted(rotor_chain_reference(lk, rotor_ids, m)))
    assert row.gated is (set(row.turns.values()) == {0}) and row.no_critical
