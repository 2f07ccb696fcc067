"""``assemblies_at_angles`` (every angle of a rotor sweep at once) against ``assemblies_at``
(one angle at a time, depth-first), which it replaces in the seed generation."""

from __future__ import annotations

import numpy as np
import pytest

from engine.catalogue.presets import PRESETS, build_preset
from engine.model.budget import NEVER
from engine.model.errors import EngineError
from engine.model.tolerances import Tolerances
from engine.space import assembly
from engine.space.assembly import assemblies_at, assemblies_at_angles, dyad_plan, rotors, seeds

TOL = Tolerances()
GRID = 2 * np.pi * (np.arange(40) + (np.sqrt(5) - 1) / 2) / 40
#: budgets below, at and above the trees' sizes (1, 2, 4, 8, ... assemblies per angle), so that
#: the cut and its flag are met with later assemblies, with dead ends only, and not at all
BUDGETS = (1, 2, 3, 4, 7, 8, 32, 33, 64, 10**6)


def _planar_presets() -> list[str]:
    return [name for name, p in PRESETS.items() if p.dimension == 2]


def _random_linkages() -> list[tuple[str, dict[str, float]]]:
    """Catalogue shapes with random lengths (some do not assemble at every angle: dead ends)."""
    rng = np.random.default_rng(20261123)
    out: list[tuple[str, dict[str, float]]] = []
    for _ in range(6):
        out.append(("four-bar", {k: float(rng.uniform(0.4, 2.0)) for k in ("a", "L1", "L2", "L3")}))
        out.append(("three-rotor", {k: float(rng.uniform(0.5, 1.6))
                                    for k in ("r1", "r2", "r3", "L1", "L2")}))
        out.append(("kl-chain", {"n": int(rng.integers(2, 7)), "r": float(rng.uniform(0.8, 2.0)),
                                 "l": float(rng.uniform(0.8, 2.0))}))
        out.append(("gated-kl-chain", {"n": 4, "gate": int(rng.integers(0, 4)),
                                       "D": float(rng.uniform(1.0, 3.5)),
                                       "L2": float(rng.uniform(1.0, 3.0))}))
    return out


def _build(name: str, params: dict[str, float]):
    try:
        return build_preset(name, params)
    except (EngineError, ValueError):
        return None


def _assert_same(linkage, budgets=BUDGETS) -> int:
    compared = 0
    for rotor in rotors(linkage):
        plan = dyad_plan(linkage, rotor)
        if plan is None:
            continue
        for budget in budgets:
            batched = assemblies_at_angles(linkage, rotor, plan, GRID, budget)
            assert len(batched) == len(GRID)
            for angle, (found, cut) in zip(GRID, batched, strict=True):
                ref, ref_cut = assemblies_at(linkage, rotor, plan, float(angle), budget)
                assert cut == ref_cut, (rotor, budget, angle)
                assert len(found) == len(ref), (rotor, budget, angle)
                for a, b in zip(found, ref, strict=True):
                    assert a.shape == b.shape
                if ref:  # the same arithmetic: equal up to the last bits of a square (every
                    # element of every assembly: one allclose over them all)
                    assert np.allclose(np.concatenate([a.ravel() for a in found]),
                                       np.concatenate([b.ravel() for b in ref]),
                                       rtol=0, atol=1e-12), (rotor, budget, angle)
                compared += len(ref)
    return compared


@pytest.mark.parametrize("name", _planar_presets())
def test_batched_assemblies_equal_the_depth_first_ones_on_the_catalogue(name):
    params: dict[str, float] = {"n": 4} if "chain" in name else {}
    if name == "gated-kl-chain":
        params["gate"] = 2
    linkage = build_preset(name, params)
    _assert_same(linkage)


def test_batched_assemblies_equal_the_depth_first_ones_on_random_linkages():
    compared = 0
    for name, params in _random_linkages():
        linkage = _build(name, params)
        if linkage is not None:
            compared += _assert_same(linkage, budgets=(1, 3, 8, 64))
    assert compared > 1000


def test_trees_too_large_to_batch_go_to_the_depth_first_search(monkeypatch):
    monkeypatch.setattr(assembly, "MAX_BATCHED_ASSEMBLIES", 64)
    linkage = build_preset("kl-chain", {"n": 5})
    assert _assert_same(linkage, budgets=(4, 16, 10**6)) > 0


def _one_angle_at_a_time(linkage, rotor, plan, angles, budget, deadline=NEVER):
    return [assemblies_at(linkage, rotor, plan, float(a), budget, deadline) for a in angles]


@pytest.mark.parametrize("name,params", [
    ("four-bar", {"L2": 1.2}), ("three-rotor", {}), ("kl-chain", {"n": 6}),
    ("gated-kl-chain", {"n": 4, "gate": 2}), ("gated-kl-chain", {"n": 4, "gate": 2, "D": 3.2}),
])
@pytest.mark.parametrize("budget", [5, 64])
def test_seeds_equal_those_of_the_one_angle_at_a_time_sweep(monkeypatch, name, params, budget):
    linkage = build_preset(name, params)
    fast = seeds(linkage, TOL, angles=24, budget=budget, random_starts=4)
    monkeypatch.setattr(assembly, "assemblies_at_angles", _one_angle_at_a_time)
    ref = seeds(linkage, TOL, angles=24, budget=budget, random_starts=4)
    assert fast.report == ref.report
    assert len(fast.points) == len(ref.points) > 0
    for a, b in zip(fast.points, ref.points, strict=True):
        assert np.allclose(a, b, rtol=0, atol=1e-12)
