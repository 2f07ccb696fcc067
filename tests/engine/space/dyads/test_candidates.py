"""Critical points of planar dyad chains from closed-form candidates (engine.space.dyads),
cross-checked
against the general search (traced curves, sign changes and minima of the augmented determinant,
multistart): ``find_critical_points`` with ``closed_form=False``. The fast path is opt-in
(``SpaceOptions.critical_closed_form``); these tests turn it on.

Every case compares the two answers point by point (matched by nearest configuration, within
1e-6, same kinds) and checks that the fast path was really used where it should be; where it
declines the answer must be the general path's, near misses included.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from engine.catalogue.presets import build_preset
from engine.model.errors import InvalidParameter
from engine.model.tolerances import Tolerances
from engine.space.configuration_space import (
    CriticalSearch,
    SpaceOptions,
    _closed_form_critical,
    _Explorer,
    explore,
    find_critical_points,
)
from engine.space.dyads import critical_candidates

TOL = Tolerances()
FAST = SpaceOptions(critical_closed_form=True)
GENERAL = replace(FAST, closed_form=False)
USED = "closed-form candidates"


def both(lk) -> tuple[CriticalSearch, CriticalSearch]:
    return find_critical_points(lk, TOL, FAST), find_critical_points(lk, TOL, GENERAL)


def assert_same(fast: CriticalSearch, general: CriticalSearch) -> None:
    assert general.search["method"] == "tracer"
    assert len(fast.critical_points) == len(general.critical_points)
    if fast.critical_points:
        a = np.array([c.u for c in fast.critical_points])
        b = np.array([c.u for c in general.critical_points])
        dist = np.linalg.norm(a[:, None, :] - b[None, :, :], axis=2)
        match = np.argmin(dist, axis=1)
        assert sorted(match.tolist()) == list(range(len(b)))  # a bijection
        assert np.all(dist[np.arange(len(a)), match] <= 1e-6)
        for i, j in enumerate(match):
            assert fast.critical_points[i].kind == general.critical_points[j].kind
    assert fast.degenerate == general.degenerate
    assert len(fast.near_misses) == len(general.near_misses)
    for m, n in zip(fast.near_misses, general.near_misses, strict=True):
        assert np.allclose(m.critical_u, n.critical_u, atol=1e-12)
    if general.search["complete"]:
        assert fast.search["complete"]


def test_three_rotor_twelve_branch_points():
    fast, general = both(build_preset("three-rotor"))
    assert fast.search["method"] == USED, fast.search.get("closed_form")
    assert len(fast.critical_points) == 12
    assert all(cp.kind == "branch" for cp in fast.critical_points)
    assert fast.search["complete"] and not fast.degenerate
    assert_same(fast, general)


def test_equilateral_four_bar_three_branch_points():
    # the ground, rotor and coupler equal: the coupler's centres meet at theta = 0 (the vertex
    # is free on a circle there), handled by the circle rule of the candidates
    fast, general = both(build_preset("four-bar"))
    assert fast.search["method"] == USED, fast.search.get("closed_form")
    assert len(fast.critical_points) == 3
    assert_same(fast, general)


def _critical_four_bar(rng: np.random.Generator, variant: int):
    a, l1, l2 = rng.uniform(0.6, 1.6, 3)
    # a +- L1 +- L2 +- L3 = 0 with L3 > 0: the Grashof equalities
    l3 = {0: a + l1 - l2, 1: a + l2 - l1, 2: l1 + l2 - a}[variant]
    if l3 <= 0.2:
        return None
    try:
        return build_preset("four-bar", {"a": a, "L1": l1, "L2": l2, "L3": l3})
    except InvalidParameter:
        return None


@pytest.mark.parametrize("seed", range(6))
def test_random_critical_four_bars(seed):
    rng = np.random.default_rng(100 + seed)
    lk = None
    while lk is None:
        lk = _critical_four_bar(rng, seed % 3)
    fast, general = both(lk)
    assert general.critical_points  # really critical lengths
    assert_same(fast, general)
    assert fast.search["method"] == USED, fast.search.get("closed_form")


def _critical_three_rotor(rng: np.random.Generator, variant: int):
    p = {k: float(v) for k, v in zip(("a", "r1", "r2", "r3", "L1", "L2"),
                                      rng.uniform(0.7, 1.4, 6), strict=True)}
    p["phi"] = float(rng.uniform(0.3, 2.8))
    # the first loop (P1, A, B, P2) at a Grashof equality: dyad B collinear at an extremum
    if variant == 0:
        p["L1"] = p["a"] + p["r1"] - p["r2"]
    elif variant == 1:
        p["r2"] = p["a"] + p["L1"] - p["r1"]
    else:  # the second loop: B's farthest point from P3 stretches L2 + r3
        p["r3"] = p["a"] + p["r2"] - p["L2"]
    if min(p["L1"], p["r2"], p["r3"]) <= 0.2:
        return None
    try:
        return build_preset("three-rotor", p)
    except InvalidParameter:
        return None


@pytest.mark.parametrize("seed", range(6))
def test_random_critical_three_rotors(seed):
    rng = np.random.default_rng(200 + seed)
    lk = None
    while lk is None:
        lk = _critical_three_rotor(rng, seed % 3)
    fast, general = both(lk)
    assert_same(fast, general)


def test_random_critical_three_rotors_use_the_fast_path():
    used = 0
    for seed in range(6):
        rng = np.random.default_rng(200 + seed)
        lk = None
        while lk is None:
            lk = _critical_three_rotor(rng, seed % 3)
        used += find_critical_points(lk, TOL, FAST).search["method"] == USED
    assert used >= 3


@pytest.mark.parametrize("params", [("four-bar", {"L2": 1.2}), ("four-bar", {"L2": 0.5}),
                                    ("three-rotor", {"L1": 1.3, "r3": 0.8})])
def test_regular_lengths_no_critical_point_and_the_general_near_misses(params):
    lk = build_preset(*params)
    cc = critical_candidates(lk, TOL)
    assert cc.points is not None and len(cc.points) == 0  # the certificate: none
    fast, general = both(lk)
    assert not general.critical_points and general.near_misses
    assert_same(fast, general)
    assert fast.search["method"] == "tracer"  # near misses come from the general search


@pytest.mark.parametrize("eps", [1e-7, -1e-7])
def test_near_critical_three_rotor_declines(eps):
    # lengths just off the twelve branch points: candidates that do not refine to a critical
    # point make the fast path decline; the answer is the general one (near misses)
    lk = build_preset("three-rotor", {"L1": 1.0 + eps})
    fast, general = both(lk)
    assert fast.search["method"] == "tracer"
    assert_same(fast, general)


def test_degenerate_three_rotor_declines():
    # pins on a line: non-isolated critical sets; the general search (tested in
    # tests/engine/space/configuration_space/test_search.py) answers, the fast path never does
    lk = build_preset("three-rotor", {"phi": 0.0})
    ex = _Explorer(lk, TOL, FAST)
    assert _closed_form_critical(ex) is None
    assert str(ex.report["closed_form"]).startswith("declined")


@pytest.mark.parametrize("name,params", [("four-bar", {}), ("three-rotor", {})])
def test_on_by_default_and_numbered_like_the_traced_search(name: str, params: dict) -> None:
    """The closed-form candidates answer by default; with them off the traced search answers,
    and both number the critical points alike (one canonical order), so an index such as the
    design endpoint's branch_point means the same point whichever path found it, and the same
    as in explore's answer."""
    lk = build_preset(name, params)
    fast = find_critical_points(lk, TOL)
    assert fast.search["method"] == "closed-form candidates"
    traced = find_critical_points(lk, TOL, SpaceOptions(critical_closed_form=False))
    assert "method" not in traced.search and traced.search["seeds"] > 0
    full = explore(lk, TOL, SpaceOptions(closed_form=False))
    assert len(fast.critical_points) == len(traced.critical_points) == len(full.critical_points)
    for a, b, c in zip(fast.critical_points, traced.critical_points, full.critical_points,
                       strict=True):
        assert np.linalg.norm(a.u - b.u) <= 1e-6 and np.linalg.norm(a.u - c.u) <= 1e-6
        assert a.kind == b.kind == c.kind == "branch"
