"""The component count of gated chains driven from a four-bar whose gate rotor cranks the gate
four-bar (:func:`engine.space.gated_count.cranked_gate_components`: 4 x the chain's count)
against dense sampling with circle intersections (``tests/gated_reference.py``), and the
configuration-space search at such a point: before the rule it traced the 16 components of the
4-rotor map's corner region but answered ``complete: false`` (the homotopy's 10,240 paths are
past its bound, the assembly enumeration was truncated); now ``derived`` with all 16 closed."""

from __future__ import annotations

import numpy as np
import pytest

from engine.catalogue.presets import build_preset
from engine.model.constraints import on_constraints
from engine.model.linkage import Linkage
from engine.model.tolerances import Tolerances
from engine.space.chain_count import gate_decision, gated_chain_components
from engine.space.configuration_space import SpaceOptions, explore
from engine.space.gated_count import cranked_gate_components, exact_components
from tests.gated_reference import sampled_general_chain

#: (n, gate, r0, r1, l0): a four-bar (ground 1, r0, l0, r1) drives the chain, every other rotor
#: and coupler 1.5, the gate D = L1 = L2 = 2 (its rotor 1.5 cranks it): non-Grashof first cells
#: (the corner of the 4-rotor map among them) and Grashof ones (a short first coupler).
CASES = [
    (4, 2, 1.20625, 1.20625, 1.5),
    (3, 1, 0.936, 1.269, 1.5),
    (3, 2, 1.728, 0.836, 1.5),
    (4, 3, 1.032, 1.057, 1.5),
    (3, 1, 1.189, 1.483, 0.497),
    (3, 2, 1.211, 1.21, 0.778),
    (4, 1, 1.013, 1.054, 0.472),
    (4, 3, 0.652, 1.048, 0.518),
]


def gated(n: int, gate: int, r0: float, r1: float, l0: float) -> Linkage:
    lk = build_preset("gated-kl-chain", {"n": n, "gate": gate})
    new = {"r0": r0, "r1": r1, "l0": l0}
    return lk.with_lengths(np.array([new.get(b, x) for b, x in zip(lk.bar_ids, lk.lengths,
                                                                    strict=True)]))


def sampled(n: int, gate: int, r0: float, r1: float, l0: float) -> tuple[int, bool]:
    """The reference: components and whether a rotor turns, by dense sampling of rotor 0."""
    pins = np.column_stack([np.arange(n, dtype=float), np.zeros(n)])
    sliders = np.array([pins[gate] + [0.0, -2.0], pins[gate] + [0.0, 2.0]])
    r = np.array([r0, r1] + [1.5] * (n - 2))
    couplers = np.array([l0] + [1.5] * (n - 2))
    return sampled_general_chain(pins, r, couplers, gate, sliders, 2.0, 2.0, sampled=0,
                                 samples=3000)


@pytest.mark.parametrize("case", CASES, ids=lambda c: "-".join(f"{v:g}" for v in c))
def test_cranked_gate_count_against_dense_sampling(case: tuple[int, int, float, float, float]
                                                   ) -> None:
    lk = gated(*case)
    assert gated_chain_components(lk) is None  # (driven from no rotor: not the older rule)
    count = cranked_gate_components(lk)
    components, turns = sampled(*case)
    assert count is not None and count.components == components, (count, components)
    assert exact_components(lk) == count
    assert count.four_bar is not None and count.cell == 0
    assert gate_decision(lk).gated is (not turns)


def test_the_rule_declines_elsewhere() -> None:
    """Driven from the gate rotor (the preset): chain_count's rule, not this one; a gate that
    restricts the chain (D = 3: the gate rotor rocks) or a plain chain: None."""
    assert cranked_gate_components(build_preset("gated-kl-chain", {"n": 4, "gate": 2})) is None
    assert exact_components(build_preset("gated-kl-chain", {"n": 4, "gate": 2})
                            ).components == 32
    lk = gated(4, 2, 1.20625, 1.20625, 1.5)
    rocking = lk.with_lengths(np.array([3.0 if b == "D" else x for b, x in
                                        zip(lk.bar_ids, lk.lengths, strict=True)]))
    assert cranked_gate_components(rocking) is None
    assert cranked_gate_components(build_preset("kl-chain", {"n": 4})) is None


def test_the_corner_search_is_derived_with_every_component_closed() -> None:
    """The 4-rotor gated map's corner region (r0 = r1 = 1.20625, the map's sample): the search
    answers complete with the argument ``derived``, the reference's 16 components, each closed
    (no open curve), and no critical point."""
    case = (4, 2, 1.20625, 1.20625, 1.5)
    tol = Tolerances()
    at, _ = on_constraints(gated(*case), tol)
    res = explore(at, tol, SpaceOptions(max_components=64), near_misses=False)
    reference, _ = sampled(*case)
    assert reference == 16
    assert res.search["complete"] and res.search["argument"] == "derived", res.search
    assert len(res.components) == reference and all(c.closed for c in res.components)
    assert res.search["open_curves"] == 0 and not res.critical_points
    assert res.search["proved"]["components"] == {"count": reference, "exact": True}
