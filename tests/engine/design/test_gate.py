"""The paper's gated Kane-Lubensky chain: gated or not, read from the rotor windings."""

from __future__ import annotations

import pytest

from engine.catalogue.presets import build_preset
from engine.space.configuration_space import SpaceOptions, explore, rotor_angles, winding

QUICK = SpaceOptions(max_components=2, angles=12, random_starts=2)


def chain_windings(n: int, gate: int, d: float) -> set[int | None]:
    """Windings of every chain rotor on every traced component (r = l = 3a/2, L1 = L2 = 2a)."""
    lk = build_preset("gated-kl-chain", {"n": n, "gate": gate, "D": d})
    res = explore(lk, options=QUICK)
    assert res.components and not res.critical_points
    out: set[int | None] = set()
    for comp in res.components:
        assert comp.closed
        angles = rotor_angles(lk, comp.points)
        out |= {abs(w) if w is not None else None
                for w in (winding(angles[f"r{k}"], True) for k in range(n))}
    return out


@pytest.mark.parametrize("d", [2.0, 2.3, 2.45])
def test_ungated_below_five_halves(d):
    """D < 5a/2: the gate four-bar (ground D, crank r, coupler L2, rocker L1) is Grashof with the
    crank shortest, the gate rotor turns fully, and so does every rotor of the chain."""
    assert chain_windings(6, 3, d) == {1}


@pytest.mark.parametrize("d", [2.55, 2.8, 3.2])
def test_gated_above_five_halves(d):
    """D > 5a/2: non-Grashof gate four-bar; no rotor completes a turn: the soliton cannot pass."""
    assert chain_windings(6, 3, d) == {0}


@pytest.mark.parametrize(("d", "expected"), [(2.3, {1}), (2.7, {0})])
def test_gate_in_the_middle_of_a_long_chain(d, expected):
    """21 rotors with the gate on rotor 10: the answer holds along the whole chain."""
    assert chain_windings(21, 10, d) == expected
