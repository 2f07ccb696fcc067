"""The three-rotor's critical curves in closed form against its critical set written here
(circle intersections, scanned along lines): every drawn point critical, every critical point in
the box drawn."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from engine.catalogue.presets import build_preset
from engine.design.chain_curves import flat_everywhere, two_cell_curves
from tests.engine.design.slice_references import ThreeRotor, distance_to_curves

NAMES = ThreeRotor.NAMES
SHORTEST = 1e-6


def random_rotors(count: int, seed: int = 5) -> list[dict[str, float]]:
    """Three-rotors with random lengths and pin angle that assemble."""
    rng = np.random.default_rng(seed)
    out = []
    while len(out) < count:
        p = dict(zip(NAMES, rng.uniform(0.5, 1.6, 5).tolist(), strict=True))
        p["phi"] = float(rng.uniform(0.3, 2.8))
        try:
            build_preset("three-rotor", p)
        except Exception:  # noqa: BLE001  (does not assemble)
            continue
        out.append(p)
    return out


CASES = [({}, ("r1", "r2"), (0.8, 1.2), (0.8, 1.2)),  # the preset matrix's map
         ({}, ("L1", "L2"), (0.6, 1.4), (0.6, 1.4))]  # issue 23's
for k, params in enumerate(random_rotors(4)):
    for pair in itertools.combinations(NAMES, 2):
        if k % 2 == 0 or pair in (("r1", "L1"), ("r3", "L2"), ("r2", "L1"), ("r1", "r3")):
            CASES.append((params, pair, (0.7 * params[pair[0]], 1.3 * params[pair[0]]),
                          (0.7 * params[pair[1]], 1.3 * params[pair[1]])))


def curves_of(params: dict[str, float], axes: tuple[str, str], box: np.ndarray,
              step: float) -> list[np.ndarray] | None:
    lk = build_preset("three-rotor", params)
    return two_cell_curves(lk, (lk.bar_ids.index(axes[0]), lk.bar_ids.index(axes[1])), box,
                           step, SHORTEST)


@pytest.mark.parametrize(("params", "axes", "xs", "ys"), CASES,
                         ids=[f"{c[1][0]}-{c[1][1]}-{i}" for i, c in enumerate(CASES)])
def test_every_critical_point_in_the_box_is_drawn_and_nothing_else(params, axes, xs, ys):
    """Every point of every piece is critical (a flat cell whose other dyad assembles, or both
    dyads straight: residual 0 to rounding); every critical point found by scanning 41 lines
    of each axis for sign changes of those conditions is within a chord's sag of a piece; the
    pieces are sampled at most a step apart and stay in the box."""
    box = np.array([xs, ys])
    step = float(min(box[:, 1] - box[:, 0])) / 48
    ref = ThreeRotor(**params)
    curves = curves_of(params, axes, box, step)
    assert curves is not None
    scale = max(ref.lengths.values())
    for c in curves:
        assert np.all(c >= box[:, 0] - 1e-12) and np.all(c <= box[:, 1] + 1e-12)
        assert np.all(np.linalg.norm(np.diff(c, axis=0), axis=1) <= step * (1 + 1e-9))
        res = ref.residuals(axes, c)
        assert res.max() <= 1e-9 * scale, c[np.argmax(res)]
    expected = ref.scanned(axes, box)
    if len(expected):
        assert curves, "critical points in the box but no curve"
        # a chord of a curve of radius R sampled at step h is within h^2 / (8 R) of it
        assert distance_to_curves(expected, curves).max() <= 0.05 * step


def test_both_dyads_straight_is_drawn_where_a_component_is_born():
    """Issue 23: the default three-rotor over (L1, L2) lacked the arc from (0.98, 0.6) to
    (0.6, 0.98) where both dyads are straight; across it the count goes from 3 to 4 (a
    component born at a rigid point)."""
    box = np.array([[0.6, 1.4], [0.6, 1.4]])
    curves = curves_of({}, ("L1", "L2"), box, 0.8 / 48)
    ref = ThreeRotor()
    t = -np.pi / 4  # B = P2 + (cos t, sin t) as far from P1 as from P3: the arc's middle
    b = np.array([1.0 + np.cos(t), np.sin(t)])
    on = np.array([np.linalg.norm(b) - 1.0, np.linalg.norm(b - ref.p3) - 1.0])  # (0.85, 0.85)
    assert abs(on[0] - on[1]) < 1e-12 and 0.6 < on[0] < 1.4
    assert distance_to_curves(on[None], curves)[0] <= 1e-3
    normal = np.array([1.0, 1.0]) / np.sqrt(2.0)
    counts = {ref.components({"L1": q[0], "L2": q[1]}) for q in (on - 0.02 * normal,
                                                                on + 0.02 * normal)}
    assert counts == {3, 4}


def test_a_small_closed_curve_between_two_scanlines_is_drawn():
    """A middle rotor of 0.008: over (L1, L2) in [1.5, 2.5] the curve where both dyads are
    straight is a closed loop about (2, 2) of diameter 0.016, less than a raster cell (and a
    sweep step) of 1/48: drawn whole, every reference point of it on a piece."""
    params = {"r2": 0.008}
    box = np.array([[1.5, 2.5], [1.5, 2.5]])
    curves = curves_of(params, ("L1", "L2"), box, 1.0 / 48)
    # (scanned about it: 41 lines 0.001 apart, 16 of them across it)
    expected = ThreeRotor(**params).scanned(("L1", "L2"), np.array([[1.98, 2.02]] * 2),
                                            lines=41, samples=801)
    loop = expected[np.linalg.norm(expected - 2.0, axis=1) < 0.0081]
    assert len(loop) >= 16
    assert distance_to_curves(loop, curves).max() <= 1e-4
    closed = [c for c in curves if np.allclose(c[0], c[-1]) and len(c) > 2]
    assert closed and np.ptp(np.concatenate(closed), axis=0).max() < 1.0 / 48


@pytest.mark.parametrize(("name", "params"), [("four-bar", {}), ("kl-chain", {"n": 4}),
                                              ("gated-kl-chain", {"n": 3, "gate": 1})])
def test_other_linkages_are_declined(name, params):
    lk = build_preset(name, params)
    assert two_cell_curves(lk, (0, 1), np.array([[0.5, 1.5], [0.5, 1.5]]), 0.1, 1e-6) is None


def test_a_cell_flat_at_every_length_of_the_box_is_declined():
    """The preset's lengths (all 1, a = 1) hold the cell P2 B C P3 flat whatever r1 and L1
    are (r2 - L2 + r3 = a): every length of the (r1, L1) box is critical, no curve can say
    so."""
    assert curves_of({}, ("r1", "L1"), np.array([[0.5, 1.5], [0.5, 1.5]]), 0.02) is None
    assert curves_of({"r3": 1.1}, ("r1", "L1"), np.array([[0.5, 1.5], [0.5, 1.5]]),
                     0.02) is not None
    lk = build_preset("three-rotor")
    r1, l1, r3 = (lk.bar_ids.index(b) for b in ("r1", "L1", "r3"))
    assert "r2-L2-r3 is flat at every length" in flat_everywhere(lk, (r1, l1))
    assert flat_everywhere(lk, (r1, r3)) is None  # (each cell has an axis)
    assert flat_everywhere(build_preset("three-rotor", {"r3": 1.1}), (r1, l1)) is None
    assert flat_everywhere(build_preset("four-bar"), (0, 1)) is None
