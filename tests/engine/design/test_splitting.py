"""Splitting predictions (Appendix A) against re-tracing the perturbed linkage; design."""

from __future__ import annotations

import numpy as np
import pytest

from engine.catalogue.presets import build_preset
from engine.design.design import Target, design, verify
from engine.design.splitting import length_change, retraced_pairing, split
from engine.model.tolerances import Tolerances
from engine.space.configuration_space import SpaceOptions, explore

TOL = Tolerances()
FAST = SpaceOptions(angles=24, random_starts=4)
FOUR_BAR = build_preset("four-bar")
THREE_ROTOR = build_preset("three-rotor")
CRIT = {
    "four-bar": explore(FOUR_BAR, TOL, FAST).critical_points,
    "three-rotor": explore(THREE_ROTOR, TOL, FAST).critical_points,
}


def perturbations(linkage, count: int, seed: int):
    rng = np.random.default_rng(seed)
    for _ in range(count):
        d_l = rng.normal(size=linkage.n_bars)
        d_l *= rng.uniform(5e-5, 5e-4) / np.abs(d_l).max()
        yield d_l


@pytest.mark.parametrize(
    ("name", "linkage", "count", "seed"),
    [("four-bar", FOUR_BAR, 40, 11), ("three-rotor", THREE_ROTOR, 10, 12)],
)
@pytest.mark.slow
def test_predicted_pairings_agree_with_retracing(name, linkage, count, seed):
    """50 random small perturbations in all (40 x 3 + 10 x 12 branch-point checks)."""
    crit = CRIT[name]
    scale = float(np.median(linkage.lengths))
    checked = 0
    for d_l in perturbations(linkage, count, seed):
        perturbed = linkage.with_lengths(linkage.lengths + d_l)
        for k, cp in enumerate(crit):
            s = split(linkage, k, cp, d_l)
            assert s.sign != 0 and len(s.connects) == 2
            assert np.sign(s.delta_linear) == s.sign  # first order decides at these sizes
            lam = float(np.abs(cp.analysis.q_eigenvalues).min())
            radius = float(np.clip(4 * np.sqrt(abs(s.delta) / lam), 0.05 * scale, 0.3 * scale))
            assert retraced_pairing(perturbed, cp, radius, TOL) == s.connects, (k, d_l)
            checked += 1
    assert checked == count * len(crit)


def test_opposite_perturbations_give_opposite_pairings():
    crit = CRIT["four-bar"]
    up = length_change(FOUR_BAR, {"L2": 1e-3})
    down = length_change(FOUR_BAR, {"L2": -1e-3})
    for k, cp in enumerate(crit):
        a, b = split(FOUR_BAR, k, cp, up), split(FOUR_BAR, k, cp, down)
        assert a.sign == -b.sign
        assert set(a.connects).isdisjoint(b.connects)


def test_design_feasible_pattern_is_verified_by_tracing():
    """Targets taken from the signs a reference perturbation produces (feasible by
    construction): the design must reach them, and re-tracing must confirm every pairing."""
    crit = CRIT["three-rotor"]
    adjustable = ["r1", "L1", "L2", "r3", "r2"]
    idx = [THREE_ROTOR.bar_ids.index(b) for b in adjustable]
    ref = np.zeros(THREE_ROTOR.n_bars)
    ref[idx] = np.random.default_rng(5).normal(size=len(idx))
    gradients = [4 * crit[k].analysis.self_stress * THREE_ROTOR.lengths for k in (0, 3, 6, 7)]
    targets = [
        Target(k, int(np.sign(g @ ref))) for k, g in zip((0, 3, 6, 7), gradients, strict=True)
    ]
    result = design(THREE_ROTOR, crit, targets, adjustable, margin=1e-4)
    assert result.feasible and not result.conflicts
    assert np.all(result.perturbation[[k for k in range(5) if k not in idx]] == 0)
    checks = verify(THREE_ROTOR, crit, targets, result.perturbation, TOL)
    for check, target in zip(checks, targets, strict=True):
        assert check.sign == target.sign
        assert check.agrees, check
    assert result.largest_change == pytest.approx(np.abs(result.perturbation).max())


def test_design_tied_pattern_is_infeasible_with_the_conflict_named():
    crit = CRIT["three-rotor"]
    grads = [4 * cp.analysis.self_stress * THREE_ROTOR.lengths for cp in crit]
    tied = next(
        (i, j) for i in range(12) for j in range(i + 1, 12) if np.allclose(grads[i], grads[j])
    )
    result = design(THREE_ROTOR, crit, [Target(tied[0], 1), Target(tied[1], -1)],
                    ["r1", "L1", "L2"], margin=1e-4)
    assert not result.feasible
    assert result.conflicts and result.conflicts[0].branch_points == list(tied)
    assert "tied" in result.conflicts[0].reason
    # the same pair with the same sign is fine
    same = design(THREE_ROTOR, crit, [Target(tied[0], 1), Target(tied[1], 1)],
                  ["r1", "L1", "L2"], margin=1e-4)
    assert same.feasible


def test_design_respects_max_change():
    crit = CRIT["four-bar"]
    result = design(FOUR_BAR, crit, [Target(0, 1)], ["L2"], margin=1e-2, max_change=1e-6)
    assert not result.feasible and "max_change" in result.conflicts[0].reason


@pytest.mark.parametrize(
    ("margin", "max_change", "loc"),
    [(float("nan"), None, "margin"), (0.0, None, "margin"), (-1.0, None, "margin"),
     (1e-4, -1.0, "max_change"), (1e-4, float("inf"), "max_change")],
)
def test_design_rejects_bad_margin_and_max_change(margin, max_change, loc):
    from engine.model.errors import InvalidRequest

    with pytest.raises(InvalidRequest) as info:
        design(FOUR_BAR, CRIT["four-bar"], [Target(0, 1)], ["L2"], margin, max_change)
    assert info.value.loc == (loc,)
