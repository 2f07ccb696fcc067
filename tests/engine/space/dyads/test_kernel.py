"""The closed form's compiled loops (:mod:`engine.space.dyads.kernel`, numba) against the numpy path
they replace (``LINKAGE_DYADS_KERNEL=numpy``), on catalogue and random dyad chains:

* each kernel against its numpy code: the placement (positions, ``nu``, ``d2``; one sheet or
  one per sample, dyads forced flat, non-finite samples), the free coordinates against
  ``positions[:, ~fixed]``, the step gaps, the length check, the nearest segments of
  ``walk_distance``: bit for bit; the golden search of the extrema check: to rounding (its
  trigonometry is math's, not numpy's);
* whole explorations: the same method, the same components point for point, the same
  component through the start, the same critical points and the same declines.

No timing here: speed lives in ``bench/bench_issue15.py`` (``--only closed-form``).
"""

from __future__ import annotations

import importlib.util
from dataclasses import replace

import numpy as np
import pytest

from engine.catalogue.presets import build_preset
from engine.model.linkage import Linkage
from engine.model.tolerances import Tolerances
from engine.space.configuration_space import SpaceOptions, explore
from engine.space.configuration_space.closed_form import walk_distance
from engine.space.dyads import chain as chain_module
from engine.space.dyads import closed_form as cf_module
from engine.space.dyads import kernel
from engine.space.dyads.chain import chain_of, place, place_free
from engine.space.trace import polyline_distance
from tests.engine.space.configuration_space.test_search import classical, random_four_bars
from tests.engine.space.dyads.test_closed_form import six_bar, six_bars, three_rotors

TOL = Tolerances()
FAST = SpaceOptions(angles=24, random_starts=4)

pytestmark = pytest.mark.skipif(importlib.util.find_spec("numba") is None,
                                reason="numba is not installed")


def four_bars_of_every_class() -> list[tuple[float, float, float]]:
    """Random four-bars (away from critical lengths) until every Grashof class is there:
    crank-rocker, double crank, double rocker, non-Grashof."""
    seen: dict[str, tuple[float, float, float]] = {}
    for lengths in random_four_bars(200):
        count, cranks = classical(*lengths)
        kind = "non-grashof" if count == 1 else {
            (True, True): "double-crank", (False, False): "double-rocker"}.get(
            (cranks["L1"], cranks["L3"]), "crank-rocker")
        seen.setdefault(kind, lengths)
    assert len(seen) == 4, seen
    return list(seen.values())


def chains() -> list[Linkage]:
    """Dyad chains: the bench's crank-rocker, four-bars of every class, three-rotors (two
    dyads on one rotor, at and away from critical lengths) and chained six-bars."""
    out = [build_preset("four-bar", {"L1": 0.5, "L2": 1.2, "L3": 1.0}),
           build_preset("four-bar"),  # equilateral: critical (the closed form declines)
           build_preset("three-rotor")]  # critical lengths too
    out += [build_preset("four-bar", {"L1": a, "L2": b, "L3": c})
            for a, b, c in four_bars_of_every_class()]
    out += [build_preset("three-rotor", p) for p in three_rotors(3)]
    out += [six_bar(*case) for case in six_bars(3)]
    return out


CHAINS = chains()


@pytest.fixture
def numpy_path(monkeypatch: pytest.MonkeyPatch):
    """A context switch: ``with numpy_path():`` runs its body on the numpy path."""
    from contextlib import contextmanager

    @contextmanager
    def switch():  # type: ignore[no-untyped-def]
        monkeypatch.setenv(kernel.KERNEL_ENV, "numpy")
        try:
            yield
        finally:
            monkeypatch.delenv(kernel.KERNEL_ENV)

    assert kernel.load() and kernel.failure is None
    return switch


def same(a: tuple | np.ndarray, b: tuple | np.ndarray) -> bool:  # type: ignore[type-arg]
    if isinstance(a, np.ndarray):
        return a.shape == np.shape(b) and np.array_equal(a, b, equal_nan=True)
    return all(same(x, y) for x, y in zip(a, b, strict=True))


def test_environment_chooses_the_path(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv(kernel.KERNEL_ENV, "numpy")
    assert kernel.kernels() is None and not kernel.prepare()
    monkeypatch.setenv(kernel.KERNEL_ENV, "numba")
    assert kernel.prepare() and kernel.kernels() is not None and kernel.failure is None


@pytest.mark.parametrize("lk", CHAINS, ids=lambda lk: f"V{lk.n_vertices}")
@pytest.mark.filterwarnings("ignore:invalid value encountered:RuntimeWarning")  # inf angles
def test_placement_is_bitwise_numpys(lk: Linkage, numpy_path) -> None:  # type: ignore[no-untyped-def]
    ch = chain_of(lk)
    assert ch is not None
    rng = np.random.default_rng(lk.n_vertices)
    n = 3000
    theta = rng.uniform(-4.0, 4.0, n)
    theta[:3] = [np.nan, np.inf, 0.0]  # non-finite angles: nan positions on both paths
    signs = rng.choice([-1, 1], size=(n, ch.k))
    flat = rng.random((n, ch.k)) < 0.05
    free = ~np.asarray(lk.fixed)
    for args in ((signs, flat), (signs, None), (signs[:1], None), (signs[1:2], flat)):
        fast = place(ch, theta, *args)
        fast_free = place_free(ch, theta, *args)
        with numpy_path():
            slow = place(ch, theta, *args)
            slow_free = place_free(ch, theta, *args)
        assert same(fast, slow)
        # the free coordinates are the columns of the positions the walks used to copy
        assert same(fast_free, slow[0][:, free]) and same(slow_free, slow[0][:, free])
    # a few angles (the checks' placements) and none
    for m in (0, 1, 5):
        with numpy_path():
            slow = place(ch, theta[:m], signs[:m])
        assert same(place(ch, theta[:m], signs[:m]), slow)


@pytest.mark.parametrize("lk", CHAINS, ids=lambda lk: f"V{lk.n_vertices}")
def test_extrema_search_is_numpys_to_rounding(lk: Linkage, numpy_path) -> None:  # type: ignore[no-untyped-def]
    ch = chain_of(lk)
    assert ch is not None
    rng = np.random.default_rng(7)
    m = 200
    lo = rng.uniform(-np.pi, np.pi, m)
    hi = lo + rng.choice([0.0, 1e-3, 0.3], m)
    sgn = rng.choice([-1.0, 1.0], m)
    dyad = rng.integers(0, ch.k, m)
    signs = rng.choice([-1, 1], size=(m, ch.k))
    fast = cf_module.extremum_minima(ch, lo, hi, sgn, dyad, signs)
    with numpy_path():
        slow = cf_module.extremum_minima(ch, lo, hi, sgn, dyad, signs)
    assert np.array_equal(np.isnan(fast), np.isnan(slow))
    ok = ~np.isnan(slow)
    assert np.allclose(fast[ok], slow[ok], rtol=1e-12, atol=1e-14)


def test_gaps_lengths_and_nearest_segments_are_numpys(numpy_path) -> None:  # type: ignore[no-untyped-def]
    rng = np.random.default_rng(5)
    lk = CHAINS[0]
    ch = chain_of(lk)
    assert ch is not None
    ends = lk.ends[lk.active]
    lengths = lk.lengths[lk.active]
    walk = place_free(ch, np.linspace(0.0, 2 * np.pi, 4000), np.ones((1, 1)))
    for case in range(40):
        w = walk + rng.normal(size=walk.shape) * rng.choice([0.0, 1e-12, 1e-6])
        if case % 10 == 9:
            w[rng.integers(len(w))] = np.nan
        limit = float(rng.choice([1e-3, 2e-3, 1e-2]))
        atol = float(rng.choice([1e-9, 1e-7, 1e-3]))
        target = w[rng.integers(len(w))] + rng.normal(size=w.shape[1]) * rng.choice([0, 1e-3, 1])
        fast = (cf_module.long_gaps(w, limit),
                cf_module.within_lengths(ch, w, ends, lengths, atol))
        with numpy_path():
            slow = (cf_module.long_gaps(w, limit),
                    cf_module.within_lengths(ch, w, ends, lengths, atol))
            slow_d = walk_distance(w, target, limit) if case % 10 != 9 else None
        assert np.array_equal(fast[0], slow[0]) and fast[1] == slow[1]
        if slow_d is not None:
            fast_d = walk_distance(w, target, limit)
            assert fast_d == slow_d
            if not len(fast[0]):  # the step bound holds: the polyline's own distance
                assert abs(fast_d - polyline_distance(w, target)) <= 1e-12 * max(1.0, fast_d)
    assert not cf_module.within_lengths(ch, walk + 1e-3, ends, lengths, 1e-6)


def explorations(lk: Linkage, options: SpaceOptions, numpy_path):  # type: ignore[no-untyped-def]
    fast = explore(lk, TOL, options)
    with numpy_path():
        slow = explore(lk, TOL, options)
    return fast, slow


@pytest.mark.parametrize("lk", CHAINS, ids=lambda lk: f"V{lk.n_vertices}")
@pytest.mark.parametrize("near_misses", [True, False])
def test_explorations_are_the_numpy_paths(lk: Linkage, near_misses: bool, numpy_path) -> None:  # type: ignore[no-untyped-def]
    opt = replace(FAST, trace=replace(FAST.trace, step_max=5e-3, max_points=50_000))
    fast = explore(lk, TOL, opt, near_misses=near_misses)
    with numpy_path():
        slow = explore(lk, TOL, opt, near_misses=near_misses)
    assert fast.search["method"] == slow.search["method"]
    assert fast.search.get("closed_form") == slow.search.get("closed_form")
    assert len(fast.components) == len(slow.components)
    for a, b in zip(fast.components, slow.components, strict=True):
        assert a.points.shape == b.points.shape
        # the closed form's walks are bitwise the same; traced ones to the tracer's rounding
        assert np.allclose(a.points, b.points, rtol=0, atol=1e-9)
        assert (a.closed, a.through_start) == (b.closed, b.through_start)
    assert [cp.kind for cp in fast.critical_points] == [cp.kind for cp in slow.critical_points]
    for p, q in zip(fast.critical_points, slow.critical_points, strict=True):
        assert np.allclose(p.u, q.u, atol=1e-9)
    assert len(fast.near_misses) == len(slow.near_misses)
    if fast.search["method"] == "closed form":
        for a, b in zip(fast.components, slow.components, strict=True):
            assert np.array_equal(a.points, b.points)


def test_dense_crank_rocker_is_the_numpy_path(numpy_path) -> None:  # type: ignore[no-untyped-def]
    """The bench's exploration (step bound 7.5e-5, 60 000 points a component)."""
    lk = CHAINS[0]
    opt = SpaceOptions(trace=replace(FAST.trace, step_max=7.5e-5, max_points=200_000))
    fast = explore(lk, TOL, opt, near_misses=False)
    with numpy_path():
        slow = explore(lk, TOL, opt, near_misses=False)
    assert fast.search["method"] == slow.search["method"] == "closed form"
    assert [len(c.points) for c in fast.components] == [len(c.points) for c in slow.components]
    assert all(np.array_equal(a.points, b.points) and a.through_start == b.through_start
               for a, b in zip(fast.components, slow.components, strict=True))


def test_a_slider_is_declined_on_both_paths(numpy_path) -> None:  # type: ignore[no-untyped-def]
    lk = build_preset("gated-kl-chain", {"n": 4, "gate": 2, "D": 2.0})
    fast, slow = explorations(lk, FAST, numpy_path)
    assert fast.search["method"] == slow.search["method"] == "tracer"
    assert fast.search["closed_form"] == slow.search["closed_form"]
    assert len(fast.components) == len(slow.components)


def test_one_compiled_signature_each(numpy_path) -> None:  # type: ignore[no-untyped-def]
    """Every call takes the types the loader compiled: no compilation inside a request."""
    mod = kernel.kernels()
    assert mod is not None
    for lk in CHAINS[:4]:
        explore(lk, TOL, FAST)
    for name in ("place", "long_gaps", "within_lengths", "golden_signed_nu", "near_segments"):
        assert len(getattr(mod, name).signatures) == 1, name
    assert chain_module.kernel is kernel
