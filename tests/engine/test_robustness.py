"""Robustness margins against the exact distance to the four-bar's critical value set."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from engine.configuration_space import SpaceOptions
from engine.errors import InvalidRequest
from engine.presets import build_preset
from engine.robustness import robustness

FAST = SpaceOptions(angles=24, random_starts=4)


def exact_margin(l1: float, l2: float, l3: float, adjustable: list[int]) -> float:
    """Distance from (L1, L2, L3) to the nearest plane a +- L1 +- L2 +- L3 = 0 (a = 1) moving
    only the adjustable lengths: |signed sum| / |normal restricted to them|."""
    best = np.inf
    for signs in itertools.product((1, -1), repeat=3):
        s = 1 + signs[0] * l1 + signs[1] * l2 + signs[2] * l3
        best = min(best, abs(s) / np.linalg.norm(np.array(signs)[adjustable]))
    return float(best)


def cases(count: int, seed: int):
    rng = np.random.default_rng(seed)
    out = []
    while len(out) < count:
        lengths = rng.uniform(0.6, 1.8, 3)
        if exact_margin(*lengths, [0, 1, 2]) < min(lengths):  # the planes are nearest
            out.append(tuple(float(x) for x in lengths))
    return out


@pytest.mark.parametrize("lengths", cases(5, 31), ids=lambda x: "-".join(f"{v:.3f}" for v in x))
@pytest.mark.parametrize(
    ("adjustable", "index"), [(None, [0, 1, 2]), (["L2"], [1]), (["L1", "L3"], [0, 2])]
)
def test_four_bar_margin_is_the_distance_to_the_nearest_collinearity_plane(
    lengths, adjustable, index
):
    l1, l2, l3 = lengths
    lk = build_preset("four-bar", {"L1": l1, "L2": l2, "L3": l3})
    res = robustness(lk, adjustable, options=FAST)
    assert res.success
    assert res.margin == pytest.approx(exact_margin(l1, l2, l3, index), abs=1e-7)
    # the nearest lengths are critical: collinear configuration, lengths consistent
    pos = lk.positions_of(res.critical_u)
    assert np.allclose(pos[:, 1], 0.0, atol=1e-6)
    changed = [b for b in lk.bar_ids if adjustable is not None and b not in adjustable]
    for bar in changed:
        k = lk.bar_ids.index(bar)
        assert res.nearest[k] == pytest.approx(lk.lengths[k], abs=1e-9)
    assert np.linalg.norm(res.nearest - lk.lengths) == pytest.approx(res.margin, abs=1e-7)


def test_bad_adjustable():
    lk = build_preset("four-bar", {"L2": 1.2})
    with pytest.raises(InvalidRequest) as info:
        robustness(lk, ["nope"])
    assert info.value.loc == ("adjustable", 0)
