"""The four-bar cells and their tau signs (``engine/space/four_bar_cells.py``) against the
classical rules: whether the input rotor turns fully by dense sampling of its angle (the
distance from its tip to the other pin, closed form), Grashof by the sorted sides."""

from __future__ import annotations

import numpy as np
import pytest

from engine.catalogue.presets import build_preset
from engine.space.four_bar_cells import four_bar_cells, tau_signs


def input_turns(a: float, l1: float, l2: float, l3: float, samples: int = 20000) -> bool:
    """The input rotor ``l1`` (at the first pin) assembles at every angle: the distance from
    its tip to the second pin, ``sqrt(a^2 + l1^2 - 2 a l1 cos t)``, stays within
    ``[|l2 - l3|, l2 + l3]``."""
    t = np.linspace(0.0, 2 * np.pi, samples, endpoint=False)
    rho = np.sqrt(a**2 + l1**2 - 2 * a * l1 * np.cos(t))
    return bool(np.all((rho >= abs(l2 - l3)) & (rho <= l2 + l3)))


def test_tau_signs_classify_the_input_rotor_and_grashof():
    """200 seeded four-bars: the input turns fully exactly in (+,+,+) and (-,-,+); Grashof
    (s + g < p + q) exactly where tau_1 tau_2 tau_3 > 0."""
    rng = np.random.default_rng(7)
    seen = set()
    for sides in rng.uniform(0.3, 3.0, size=(200, 4)):
        a, l1, l2, l3 = (float(x) for x in sides)
        signs = tau_signs((a, l1, l2, l3))
        seen.add(signs)
        assert 0 not in signs
        assert (signs in ((1, 1, 1), (-1, -1, 1))) == input_turns(a, l1, l2, l3), sides
        srt = sorted(sides)
        assert (srt[0] + srt[3] < srt[1] + srt[2]) == (int(np.prod(signs)) > 0), sides
    assert len(seen) == 8  # every sign pattern was met


def test_zero_sign_at_critical_lengths():
    """D = 5a/2 in the paper's gate (ground D, input r = 3a/2, coupler L2 = 2a, output L1 =
    2a): tau_3 = 0, a flat configuration."""
    assert tau_signs((2.5, 1.5, 2.0, 2.0)) == (1, 1, 0)
    assert tau_signs((2.5 + 1e-6, 1.5, 2.0, 2.0)) == (1, 1, -1)


def test_cells_of_the_presets():
    """A four-bar is its one cell; a chain has n - 1 (ground the pin spacing); a gated chain
    has the gate first (D, the gate rotor, L2, L1); a framework has none."""
    four = four_bar_cells(build_preset("four-bar", {"L1": 0.5, "L2": 1.2, "L3": 1.0}))
    assert [(c.name, c.bars, c.sides) for c in four] == [
        ("L1-L2-L3", ("L1", "L2", "L3"), (1.0, 0.5, 1.2, 1.0))]
    three = four_bar_cells(build_preset("three-rotor"))
    assert len(three) == 2 and {c.bars[1] for c in three} == {"L1", "L2"}
    gated = four_bar_cells(build_preset("gated-kl-chain", {"n": 5, "gate": 2, "a": 2.0,
                                                           "r": 2.6, "l": 2.6, "D": 3.0,
                                                           "L1": 3.1, "L2": 2.8}))
    assert gated[0].name == "gate" and gated[0].bars == ("r2", "L2", "L1")
    assert gated[0].sides == pytest.approx((3.0, 2.6, 2.8, 3.1))
    assert [c.name for c in gated[1:]] == ["r0-l0-r1", "r1-l1-r2", "r2-l2-r3", "r3-l3-r4"]
    assert all(c.sides == pytest.approx((2.0, 2.6, 2.6, 2.6)) for c in gated[1:])
    assert four_bar_cells(build_preset("tetrahedron")) == []
    assert four_bar_cells(build_preset("rotor-chain-3d")) == []
