"""The segments' stop test (:func:`engine.space.configuration_space.segments.captured`, one
vectorised
pass over the critical points a step) against the loop it replaced (``segment_distance`` to one
critical point at a time): the same critical point on random steps, and the same segments of
whole explorations."""

from __future__ import annotations

import numpy as np

from engine.catalogue.presets import build_preset
from engine.model.tolerances import Tolerances
from engine.space.configuration_space import SpaceOptions, explore
from engine.space.configuration_space import segments as segments_module
from engine.space.trace import distances_to_segment, segment_distance

TOL = Tolerances()
FAST = SpaceOptions(angles=24, random_starts=4)


def loop_captured(a: np.ndarray, b: np.ndarray, centres: np.ndarray, capture: float, own: int,
                  start: np.ndarray, leave: float) -> int | None:
    """The stop test as it was: one critical point at a time, the first within ``capture``."""
    for j, c in enumerate(centres):
        if j == own and np.linalg.norm(b - start) < leave:
            continue
        if segment_distance(a, b, c) <= capture:
            return j
    return None


def test_distances_to_a_segment_are_segment_distance():
    rng = np.random.default_rng(16)
    for case in range(200):
        dim = int(rng.integers(1, 13))
        a = rng.normal(size=dim)
        b = a if case % 20 == 0 else a + rng.normal(size=dim) * rng.choice([1e-6, 1e-3, 1.0])
        targets = np.vstack([rng.normal(size=(5, dim)), a, b, 0.5 * (a + b)])
        ours = distances_to_segment(a, b, targets)
        ref = np.array([segment_distance(a, b, c) for c in targets])
        assert np.allclose(ours, ref, rtol=1e-12, atol=1e-15)


def test_captured_is_the_loop_on_random_steps():
    rng = np.random.default_rng(2026)
    hits = 0
    for case in range(2000):
        dim = int(rng.integers(2, 13))
        centres = rng.normal(size=(int(rng.integers(1, 14)), dim))
        capture = float(rng.choice([1e-3, 5e-2, 0.5]))
        # steps that start near one critical point or pass close to several
        a = centres[rng.integers(len(centres))] + rng.normal(size=dim) * rng.choice([1e-3, 0.1, 1])
        b = a + rng.normal(size=dim) * rng.choice([1e-3, 0.05, 0.5])
        own = int(rng.integers(len(centres)))
        start = b + rng.normal(size=dim) * rng.choice([1e-3, 1.0])
        leave = float(rng.choice([0.0, 0.01, 2.0]))
        ours = segments_module.captured(a, b, centres, capture, own, start, leave)
        assert ours == loop_captured(a, b, centres, capture, own, start, leave), case
        hits += ours is not None
    assert 200 < hits < 1800  # both answers are exercised


def test_segments_are_the_loops(monkeypatch):
    """A whole exploration (the equilateral four-bar: branch points joined by segments) with the
    vectorised stop and with the loop: the same segments, point for point, between the same
    critical points and rays."""
    lk = build_preset("four-bar")
    fast = explore(lk, TOL, FAST)
    monkeypatch.setattr(segments_module, "captured", loop_captured)
    slow = explore(lk, TOL, FAST)
    assert fast.segments and len(fast.segments) == len(slow.segments)
    for p, q in zip(fast.segments, slow.segments, strict=True):
        assert (p.start, p.start_ray, p.end, p.end_ray) == (q.start, q.start_ray, q.end, q.end_ray)
        assert np.array_equal(p.points, q.points)
    assert [len(c.points) for c in fast.components] == [len(c.points) for c in slow.components]
