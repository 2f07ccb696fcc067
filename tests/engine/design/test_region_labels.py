"""Region labels (``engine/design/region_labels.py``) against independent references: the gate
four-bar's tau signs written out here, and the components and full turns of gated chains by
dense sampling with closed-form circle intersections (``tests/gated_reference.py``), on both
sides of every critical line; the gated (L2, D) map of the paper's Fig. 5b."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from engine.catalogue.presets import build_preset
from engine.design.critical_values import critical_value_slice
from engine.design.dyad_margin import gate_planes
from engine.design.region_labels import derived_label, label_region, label_signature
from engine.design.sweep_rules import derive
from engine.model.errors import InvalidParameter
from engine.model.linkage import Linkage
from engine.space.chain_count import gate_decision
from engine.space.configuration_space import SpaceOptions, explore
from engine.space.four_bar_cells import four_bar_cells
from engine.space.gated_count import exact_components
from tests.gated_reference import sampled_gated_chain


def taus(d: float, r: float, l2: float, l1: float) -> tuple[int, int, int]:
    """The paper's Eq. 16 for the gate four-bar (ground D, input the gate rotor r, coupler L2,
    output L1), as signs."""
    values = (d - r + l2 - l1, d - r - l2 + l1, l2 + l1 - d - r)
    return tuple(int(np.sign(v)) for v in values)  # type: ignore[return-value]


def critical_d(r: float, l2: float, l1: float) -> list[float]:
    """Every D > 0 at which the gate four-bar has a flat configuration: D = s_r r + s_2 L2 +
    s_1 L1 for some signs."""
    out = {round(sr * r + s2 * l2 + s1 * l1, 12)
           for sr, s2, s1 in itertools.product((1, -1), repeat=3)}
    return sorted(d for d in out if d > 0)


# (n, a, r, l, gate, L1, L2): several chains, pin spacings, rotor lengths and rockers
CASES = [
    (3, 1.0, 1.5, 1.5, 1, 2.0, 2.0),  # the paper's: critical D 1.5, 2.5, 5.5
    (4, 1.0, 1.5, 1.5, 2, 1.7, 2.3),  # critical D 0.9, 2.1, 2.5, 5.5
    (5, 2.0, 2.6, 2.6, 1, 3.1, 2.8),  # another scale: critical D 2.3, 2.9, 3.3, 8.5
    (6, 1.0, 1.5, 1.5, 3, 2.0, 2.0),
]
DELTA = 0.08


def gated_at(case: tuple[float, ...], d: float) -> Linkage:
    """The gated chain of ``case`` with ``D = d``: built by the preset where it assembles, else
    (the gate four-bar apart) built at a D where it does and given the length ``d``."""
    n, a, r, coupler, gate, l1, l2 = case
    params = {"n": n, "a": a, "r": r, "l": coupler, "gate": gate, "L1": l1, "L2": l2}
    try:
        return build_preset("gated-kl-chain", {**params, "D": d})
    except InvalidParameter:
        crit = critical_d(r, l2, l1)
        base = build_preset("gated-kl-chain", {**params, "D": (crit[0] + crit[-1]) / 2})
        lengths = base.lengths.copy()
        lengths[base.bar_ids.index("D")] = d
        return base.with_lengths(lengths)


@pytest.mark.slow
@pytest.mark.parametrize("case", CASES, ids=lambda c: "-".join(f"{v:g}" for v in c))
def test_gated_labels_on_both_sides_of_every_critical_line(case):
    """At D just below and just above each critical D: the exact count and ``gated`` against
    the sampled configuration space, and the gate cell's tau signs against Eq. 16 (the input
    rotor turns fully exactly in (+,+,+) and (-,-,+), where the chain is ungated)."""
    n, a, r, coupler, gate, l1, l2 = case
    for dc in critical_d(r, l2, l1):
        for d in (dc - DELTA, dc + DELTA):
            if d <= 0:
                continue
            lk = gated_at(case, d)
            components, turns = sampled_gated_chain(n, a, r, coupler, gate, d, l1, l2,
                                                    samples=2000)
            count = exact_components(lk)
            assert count is not None and count.components == components, (d, count, components)
            signs = taus(d, r, l2, l1)
            cell = four_bar_cells(lk)[0]
            assert cell.name == "gate" and cell.signs == signs, (d, cell)
            decision = gate_decision(lk)
            if components == 0:  # the gate does not assemble: nothing to gate
                assert decision.gated is None and "assemble" in decision.reason
                continue
            assert decision.gated is (not turns), (d, decision, turns)
            assert decision.gated is (signs not in ((1, 1, 1), (-1, -1, 1))), (d, signs)


def test_labels_say_exact_or_bound():
    """A 10-rotor spinner chain traced to a budget of 4 components: its label is the rules'
    512, exact (derived), with 4 traced; a gated chain's label says gated whatever was traced;
    a four-bar's cell is the four-bar itself; an incomplete search without a rule is a bound."""
    lk = build_preset("kl-chain", {"n": 10})
    res = explore(lk, options=SpaceOptions(max_components=4), near_misses=False)
    label = label_region(lk, res)
    assert (label.components, label.components_exact, label.traced) == (512, True, 4)
    assert not res.search["complete"]  # the search itself is a lower bound ...
    signature, argument = label_signature(label, res)
    assert signature.startswith("components=512 (4 traced)") and argument == "derived"
    assert label.gated is None and len(label.cells) == 9
    # on a map of (r4, l4) only the cells those bars are sides of
    assert [c.name for c in label_region(lk, res, ("r4", "l4")).cells] == ["r3-l3-r4",
                                                                           "r4-l4-r5"]

    gated = build_preset("gated-kl-chain", {"n": 4, "gate": 1, "D": 3.0})
    two = explore(gated, options=SpaceOptions(max_components=2), near_misses=False)
    lab = label_region(gated, two)
    assert lab.gated is True and lab.traced == 2 and lab.components == 16
    assert lab.cells[0].signs == taus(3.0, 1.5, 2.0, 2.0) == (1, 1, -1)

    four = build_preset("four-bar", {"L1": 0.5, "L2": 1.2, "L3": 1.0})
    lab = label_region(four, explore(four))
    assert lab.components == 2 and lab.components_exact and lab.gated is None
    assert [c.bars for c in lab.cells] == [("L1", "L2", "L3")]
    assert lab.cells[0].sides == (1.0, 0.5, 1.2, 1.0)
    # (a - L1 + L2 - L3, a - L1 - L2 + L3, L2 + L3 - a - L1) = (0.7, 0.3, 0.7): a crank-rocker
    assert lab.cells[0].signs == (1, 1, 1)
    assert all(w.startswith("L1:1,L3:0") for w in lab.windings)

    # no rule and a search cut short: the traced count is a lower bound, and says so
    rotor = build_preset("three-rotor", {"r1": 1.05})
    cut = explore(rotor, options=SpaceOptions(max_components=1), near_misses=False)
    lab = label_region(rotor, cut)
    assert not cut.search["complete"] and lab.components_exact is False
    assert label_signature(lab, cut)[0].startswith(f"components=>={lab.traced} (incomplete")


@pytest.mark.slow
def test_gate_map_reproduces_figure_5b():
    """The gated chain's (L2, D) map over [0.5, 5]^2 (r = l = 3a/2, L1 = 2a): the threshold
    D = 5a/2 at L2 = 2a lies on a curve; the six regions of Fig. 5b and the two where the gate
    does not assemble, each labelled with the gate's tau signs (Eq. 16 at its point), its exact
    count and gated or not as the sampled configuration space says; (+,+,+) and (-,-,+)
    ungated, the rest gated (the paper's text)."""
    lk = build_preset("gated-kl-chain", {"n": 3, "gate": 1})
    s = critical_value_slice(lk, [("L2", 0.5, 5.0), ("D", 0.5, 5.0)], resolution=24)
    assert s.search.complete and s.search.argument == "derived"
    threshold = np.array([2.0, 2.5])
    assert any(_on_polyline(threshold, c) for c in s.curves)
    # every curve lies on a line where the gate four-bar is flat, +-D +-L2 +-L1 = r, and each
    # such line that crosses the box is there (five: three of Fig. 5b, two where it stops
    # assembling)
    lines = [np.array(sg) for sg in itertools.product((1.0, -1.0), repeat=3)]
    on = []
    for c in s.curves:
        hit = [k for k, sg in enumerate(lines)
               if np.all(np.abs(sg[0] * c[:, 1] + sg[1] * c[:, 0] + sg[2] * 2.0 - 1.5) < 1e-9)]
        assert hit, c[:3]
        on.append(hit[0])
    assert len(set(on)) == len(s.curves) == 5
    seen = {}
    for region in s.regions:
        l2, d = region.point
        label = region.label
        assert label is not None
        signs = taus(d, 1.5, l2, 2.0)
        # the one cell the axes are sides of: the gate (the chain's cells never change here)
        assert [c.name for c in label.cells] == ["gate"] and label.cells[0].signs == signs
        components, turns = sampled_gated_chain(3, 1.0, 1.5, 1.5, 1, d, 2.0, l2, samples=2000)
        assert region.components == components and label.components_exact
        if components == 0:
            assert label.gated is None
        else:
            assert label.gated is (not turns)
            seen[signs] = label.gated
    assert seen == {(1, 1, 1): False, (-1, -1, 1): False, (-1, 1, 1): True, (1, -1, 1): True,
                    (1, 1, -1): True, (-1, 1, -1): True}
    assert len(s.regions) == 8
    # either side of the threshold at L2 = 2a, by the reference alone
    assert sampled_gated_chain(3, 1.0, 1.5, 1.5, 1, 2.45, 2.0, 2.0)[1] is True
    assert sampled_gated_chain(3, 1.0, 1.5, 1.5, 1, 2.55, 2.0, 2.0)[1] is False


def _on_polyline(p: np.ndarray, line: np.ndarray) -> bool:
    a, b = line[:-1], line[1:]
    ab = b - a
    s = np.clip(np.einsum("ij,ij->i", p - a, ab) / np.einsum("ij,ij->i", ab, ab), 0.0, 1.0)
    return bool(np.min(np.linalg.norm(a + s[:, None] * ab - p, axis=1)) < 1e-9)


def test_gate_planes_only_where_they_are_every_critical_value():
    """The closed-form gate map needs the chain driven from the gate rotor: couplers shorter
    than the pin spacing leave cells with critical configurations of their own (traced then)."""
    assert gate_planes(build_preset("gated-kl-chain", {"n": 3, "gate": 1})) is not None
    assert gate_planes(build_preset("gated-kl-chain", {"n": 4, "gate": 1, "r": 0.9, "l": 0.9,
                                                       "D": 2.0, "L1": 1.5, "L2": 1.5})) is None
    assert gate_planes(build_preset("kl-chain", {"n": 3})) is None


def test_gate_slice_regions_are_derived_and_agree_with_sampling():
    """The gate slice of issue 30 (4 rotors, gate 2, L2 in [1, 3] x D in [1, 3.5]) labels its
    regions from the chain rules alone (nothing traced): each region's count and whether a
    rotor turns agree with the configuration space sampled densely with closed-form circle
    intersections, and the turns are the same on every component (one pattern)."""
    lk = build_preset("gated-kl-chain", {"n": 4, "gate": 2})
    s = critical_value_slice(lk, [("L2", 1.0, 3.0), ("D", 1.0, 3.5)])
    assert s.search.complete and s.search.argument == "derived"
    assert len(s.regions) == 6
    for region in s.regions:
        l2, d = region.point
        label = region.label
        assert label is not None and label.traced is None and label.components_exact
        assert region.argument == "derived" and len(label.windings) == 1
        components, turns = sampled_gated_chain(4, 1.0, 1.5, 1.5, 2, d, 2.0, l2, samples=2000)
        assert region.components == components, region
        turning = any(int(w.split(":")[1]) for w in label.windings[0].split(","))
        assert turning is turns, region


def test_derived_label_is_the_traced_label():
    """A second method: where the rules give the turns, the derived label of a 10-rotor chain
    (and of a gated chain, gated and not) says what the traced exploration's label says."""
    from tests.engine.space.test_chain_count import chain

    driven_by_a_four_bar = chain([1.0] * 3, [1.2, 1.25, 1.5, 1.5], [1.5] * 3)
    for lk in (build_preset("kl-chain", {"n": 10}), driven_by_a_four_bar,
               build_preset("gated-kl-chain", {"n": 4, "gate": 1, "D": 3.0}),
               build_preset("gated-kl-chain", {"n": 4, "gate": 2})):
        assert lk is not None
        row = derive(lk)
        assert row is not None
        derived = derived_label(lk, row)
        res = explore(lk, options=SpaceOptions(max_components=8), near_misses=False)
        traced = label_region(lk, res)
        assert derived is not None and derived.traced is None
        assert (derived.components, derived.components_exact, derived.components_rule,
                derived.gated, derived.gated_reason, derived.cells) == (
            traced.components, traced.components_exact, traced.components_rule, traced.gated,
            traced.gated_reason, traced.cells)
        assert derived.windings == traced.windings, lk
        assert label_signature(derived, None) == (
            f"components={derived.components}; turns={derived.windings[0]}", "derived")
