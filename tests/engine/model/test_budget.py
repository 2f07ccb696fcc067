"""Anytime searches (issue 11, item 2): every engine search takes a deadline, stops there and
answers with what it found, marked ``complete: False`` with ``reason: "time"``; what it did find
is as valid as in a complete answer, and its progress goes from 0 towards 1.

The deadlines here are stop flags driven by the searches' own progress reports (deterministic
whatever the machine's speed), or deadlines that have already passed."""

from __future__ import annotations

import numpy as np
import pytest

from engine.catalogue.presets import build_preset
from engine.design.critical_values import critical_value_slice
from engine.local.rigidity import first_order
from engine.model.budget import (
    ANSWER_SECONDS_PER_VALUE,
    ANSWER_TIME_S,
    NEVER,
    Deadline,
    answer_values,
)
from engine.model.constraints import Constraints
from engine.model.tolerances import Tolerances
from engine.space.configuration_space import SpaceOptions, explore, find_critical_points
from engine.space.trace import TraceOptions, trace_curve

FAST = SpaceOptions(angles=24, random_starts=4)
#: the general tracer (a six-rotor chain is a dyad chain the closed form would answer at once)
TRACER = SpaceOptions(angles=24, random_starts=4, closed_form=False)


class StopAfter:
    """A stop flag that trips after ``reports`` progress reports containing ``marker``, and
    records every report."""

    def __init__(self, reports: int, marker: str = "") -> None:
        self.reports, self.marker = reports, marker
        self.seen: list[tuple[float, str]] = []

    def progress(self, fraction: float, message: str) -> None:
        self.seen.append((fraction, message))

    def stop(self) -> bool:
        return sum(self.marker in m for _, m in self.seen) >= self.reports

    def deadline(self) -> Deadline:
        return Deadline(stop=self.stop, progress=self.progress)


def assert_on_space(linkage, points: np.ndarray) -> None:
    cons = Constraints(linkage)
    free = ~np.asarray(linkage.fixed)
    scale = float(np.max(linkage.lengths))
    for p in points[:, free] if points.ndim == 3 else points:
        assert cons.max_residual(np.asarray(p).ravel()) <= 1e-8 * scale


def test_an_expired_deadline_ends_an_exploration_at_once_marked_time():
    res = explore(build_preset("kl-chain"), options=FAST, deadline=Deadline.after(0.0))
    assert res.search["complete"] is False and res.search["reason"] == "time"


@pytest.mark.slow
def test_a_deadline_mid_exploration_keeps_what_was_traced():
    lk = build_preset("kl-chain", {"n": 6})
    stop = StopAfter(40, "components")
    res = explore(lk, options=TRACER, deadline=stop.deadline())
    assert res.search["complete"] is False and res.search["reason"] == "time"
    full = explore(lk, options=TRACER)
    assert 0 < len(res.components) < len(full.components)
    for comp in res.components:  # each found component is a true curve of the linkage
        assert_on_space(lk, comp.points)
    fractions = [f for f, _ in stop.seen]
    assert fractions == sorted(fractions) and all(0 <= f <= 1 for f in fractions)


def test_without_a_deadline_the_report_says_complete_and_no_reason():
    res = explore(build_preset("four-bar", {"L2": 1.2}))
    assert res.search["complete"] is True and res.search["reason"] is None
    res = explore(build_preset("four-bar", {"L2": 1.2}), options=SpaceOptions(closed_form=False))
    assert res.search["complete"] is True and res.search["reason"] is None


def test_a_component_budget_is_reported_as_budget():
    res = explore(build_preset("kl-chain", {"n": 6}),
                  options=SpaceOptions(angles=24, random_starts=4, max_components=2,
                                       closed_form=False))
    assert res.search["complete"] is False and res.search["reason"] == "budget"


def test_a_critical_point_search_stops_at_its_deadline():
    lk = build_preset("three-rotor")
    res = find_critical_points(lk, options=SpaceOptions(closed_form=False),
                               deadline=Deadline.after(0.0))
    assert res.search["complete"] is False and res.search["reason"] == "time"
    full = find_critical_points(lk, options=SpaceOptions(closed_form=False))
    assert full.search["complete"] is True and full.search["reason"] is None


def test_the_tracer_stops_at_its_deadline_with_the_points_so_far():
    lk = build_preset("four-bar", {"L2": 1.2})
    cons = Constraints(lk)
    u0 = lk.coordinates()
    t0 = first_order(lk).zero_modes[0]
    calls = {"n": 0}

    def stop() -> bool:
        calls["n"] += 1
        return calls["n"] > 3

    curve = trace_curve(cons, u0, t0, Tolerances(), TraceOptions(), deadline=Deadline(stop=stop))
    assert curve.stop == "time" and len(curve.points) > 1
    assert_on_space(lk, np.array(curve.points))


def test_a_slice_out_of_time_leaves_regions_unexplored_and_says_so():
    lk = build_preset("four-bar")
    axes = [("L2", 0.5, 1.5), ("L3", 0.5, 1.5)]
    stop = StopAfter(2, "regions")
    res = critical_value_slice(lk, axes, resolution=16, deadline=stop.deadline())
    assert res.search["complete"] is False and res.search["reason"] == "time"
    explored = [r for r in res.regions if r.components is not None]
    assert 0 < len(explored) < len(res.regions)
    assert res.search["regions_explored"] == len(explored)
    full = critical_value_slice(lk, axes, resolution=16)
    assert full.search["complete"] is True and full.search["reason"] is None
    assert all(r.components is not None for r in full.regions)
    # the curves were all traced before the regions: the same as without a deadline
    assert len(res.curves) == len(full.curves)


@pytest.mark.parametrize("share", [0.25, 0.5])
def test_a_fraction_of_a_deadline_is_a_share_of_what_remains(share):
    d = Deadline.after(100.0)
    part = d.fraction(share)
    assert part.remaining() == pytest.approx(share * d.remaining(), abs=0.5)
    assert part.stop is d.stop and part.progress is d.progress


def test_the_answer_budget_of_values_is_what_maps_in_its_share_of_the_margin():
    assert answer_values(NEVER) is None
    values = answer_values(Deadline.after(4.0))
    assert values is not None and values > 0
    assert values * ANSWER_SECONDS_PER_VALUE <= ANSWER_TIME_S
