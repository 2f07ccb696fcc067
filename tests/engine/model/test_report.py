"""The search report (issue 16, item 2): one place decides ``complete`` and ``reason``."""

from __future__ import annotations

import doctest

import pytest

import engine.model.report
from engine.catalogue.presets import build_preset
from engine.model.budget import Deadline, granted
from engine.model.report import SearchReport
from engine.space.configuration_space import explore, find_critical_points


@pytest.mark.parametrize(("flags", "reason"), [
    ({}, "searched"),
    ({"argument": "derived"}, None),
    ({"argument": "proved"}, None),
    ({"unresolved": True, "argument": "proved"}, "unresolved"),
    ({"unresolved": True}, "unresolved"),
    ({"degenerate": True, "unresolved": True}, "degenerate"),
    ({"budget": True, "degenerate": True}, "budget"),
    ({"timed_out": True, "budget": True, "degenerate": True, "unresolved": True}, "time"),
])
def test_the_first_reason_that_applies(flags, reason):
    r = SearchReport({"method": "tracer"}, **flags)
    assert r.reason == reason and r.complete is (reason is None)
    assert r["complete"] is r.complete and r["reason"] == reason


def test_it_reads_like_the_answers_search():
    r = SearchReport({"seeds": 4}, time_budget_s=2.5, argument="derived", argument_detail="x")
    assert dict(r) == {"seeds": 4, "complete": True, "reason": None, "argument": "derived",
                       "argument_detail": "x", "time_budget_s": 2.5}
    assert r.get("seeds") == 4 and r.get("missing") is None and len(r) == 6
    assert SearchReport({}).with_argument("proved", "y")["complete"] is True
    assert "time_budget_s" not in SearchReport({"seeds": 4})
    more = r.with_details(seeds=5, curves=1)
    assert more["seeds"] == 5 and more["curves"] == 1 and r["seeds"] == 4  # frozen


def test_every_search_answers_a_report_with_the_seconds_it_was_given():
    lk = build_preset("four-bar", {"L2": 1.2})
    for res in (explore(lk), find_critical_points(lk)):
        assert isinstance(res.search, SearchReport) and res.search.complete
        assert res.search.argument == "derived"  # the closed form, the four-bar's rules
        assert "time_budget_s" not in res.search
    d = Deadline.after(7.0)
    assert granted(d) == 7.0
    assert explore(lk, deadline=d).search["time_budget_s"] == 7.0


def test_the_module_example_holds():
    assert doctest.testmod(engine.model.report).failed == 0
