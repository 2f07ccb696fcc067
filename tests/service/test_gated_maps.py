"""The maps of gated chains in two rotor lengths through HTTP (issue 30: the preset matrix's
cells of ``gated-kl-chain`` with its defaults and with ``n=4&gate=2``, axes ``r0`` x ``r1`` over
``[0.8 L, 1.2 L]``), against references written here: every curve on a Grashof equality
``s + l = p + q`` of the first four-bar cell (ground ``a = 1``, ``r0``, ``l0 = 1.5``, ``r1``),
each of the three that cross the box drawn; every region's count the chain's (the first cell's
circuits by Grashof's rule, two modes per other cell) times two places of the gate's rocker and
two of the slider (the gate rotor, 1.5 long on a ground ``D = 2`` with ``L1 = L2 = 2``, cranks
the gate four-bar); ``gated`` where no rotor of that cell turns; on the 4-rotor chain also the
count of dense sampling with circle intersections (``tests/gated_reference.py``) and, at a
corner region (driven from the first four-bar, the case no rule counted before), the components
the configuration-space search traces there."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from tests.gated_reference import sampled_general_chain

A, COUPLER = 1.0, 1.5
#: The three Grashof equalities of the first cell that cross [1.2, 1.8]^2, as (c0, c1, c):
#: c0 r0 + c1 r1 = c (a + r1 = r0 + l0, a + r0 = r1 + l0, a + l0 = r0 + r1).
LINES = [(-1.0, 1.0, COUPLER - A), (1.0, -1.0, COUPLER - A), (1.0, 1.0, A + COUPLER)]


def grashof(r0: float, r1: float) -> float:
    """``s + l - p - q`` of the first cell: 0 on its critical lines, < 0 Grashof."""
    srt = sorted([A, r0, COUPLER, r1])
    return srt[0] + srt[3] - srt[1] - srt[2]


def expected(n: int, r0: float, r1: float) -> tuple[int, bool]:
    """Components and gated of the gated chain at ``(r0, r1)`` off the lines: the first cell's
    circuits (Grashof 2, else 1) x 2^(n-2) x 2 x 2; gated iff no rotor of the first cell turns
    (non-Grashof, or its coupler shortest: then the gate, which restricts nothing, leaves every
    rotor rocking)."""
    sides = [A, r0, COUPLER, r1]
    turning = grashof(r0, r1) < 0 and int(np.argmin(sides)) != 2
    return (2 if grashof(r0, r1) < 0 else 1) * 2 ** (n - 2) * 4, not turning


def the_map(client: Any, query: dict[str, float]) -> tuple[dict[str, Any], dict[str, Any]]:
    got = client.get("/v1/presets/gated-kl-chain", params=query)
    assert got.status_code == 200, got.text
    linkage = got.json()
    body = {"linkage": linkage,
            "axes": [{"bar": b, "min": 0.8 * 1.5, "max": 1.2 * 1.5} for b in ("r0", "r1")]}
    r = client.post("/v1/analysis/critical-values", json=body)
    assert r.status_code == 200, r.text[:500]
    return linkage, r.json()


@pytest.mark.parametrize("query", [{}, {"n": 4, "gate": 2}], ids=["defaults", "n4-gate2"])
def test_the_gated_maps_are_the_closed_form(client: Any, query: dict[str, float]) -> None:
    linkage, ans = the_map(client, query)
    n = int(query.get("n", 10))
    search = ans["search"]
    assert search["complete"] and search["argument"] == "derived", search
    assert search["method"] == "closed form" and "gate rotor cranks" in search["argument_detail"]
    curves = [np.asarray(c, dtype=float).reshape(-1, 2) for c in ans["curves"]]
    assert len(curves) == 3
    met = set()
    for curve in curves:
        assert max(abs(grashof(*p)) for p in curve) < 1e-9
        on = [k for k, (c0, c1, c) in enumerate(LINES)
              if np.all(np.abs(c0 * curve[:, 0] + c1 * curve[:, 1] - c) < 1e-9)]
        assert len(on) == 1
        met |= set(on)
        # each runs from edge to edge of the box
        for end in (curve[0], curve[-1]):
            assert np.min(np.abs(np.r_[end - 1.2, end - 1.8])) < 1e-9
    assert met == {0, 1, 2}
    assert len(ans["regions"]) == 4
    for region in ans["regions"]:
        r0, r1 = region["point"]
        count, gated = expected(n, r0, r1)
        assert region["components_exact"] and region["argument"] == "derived", region
        assert int(region["components"]) == count, region
        assert region["gated"] is gated, region
        # the cells the axes are sides of (the gate's is not: its rotor is r2 or r5)
        assert [c["cell"] for c in region["tau_signs"]] == ["r0-l0-r1", "r1-l1-r2"], region
        if n == 4:  # a second reference: dense sampling of rotor 0's angle
            pins = np.column_stack([np.arange(n, dtype=float), np.zeros(n)])
            sliders = np.array([pins[2] + [0.0, -2.0], pins[2] + [0.0, 2.0]])
            sampled, turns = sampled_general_chain(
                pins, np.array([r0, r1, 1.5, 1.5]), np.full(n - 1, COUPLER), 2, sliders, 2.0,
                2.0, sampled=0, samples=2000)
            assert (sampled, not turns) == (count, gated), region


@pytest.mark.slow
def test_a_corner_region_is_what_the_search_traces(client: Any) -> None:
    """The corner region of the 4-rotor map nearest (1.2, 1.2) (the first four-bar drives the
    chain, non-Grashof): the configuration space explored at its sample traces as many closed
    components as the label counts, no other curve, and says the same ``gated``; complete, the
    count derived (4 x the chain's: the gate rotor cranks the gate four-bar)."""
    linkage, ans = the_map(client, {"n": 4, "gate": 2})
    region = min(ans["regions"], key=lambda g: g["point"][0] + g["point"][1])
    bars = [{**b, "length": dict(zip(("r0", "r1"), region["point"], strict=True))[b["id"]]}
            if b["id"] in ("r0", "r1") else b for b in linkage["bars"]]
    r = client.post("/v1/analysis/configuration-space", json={
        "linkage": {**linkage, "bars": bars},
        "options": {"max_components": 64, "points": "compact", "time_budget_s": 60.0}})
    assert r.status_code == 200, r.text[:500]
    space = r.json()
    closed = sum(c["closed"] for c in space["components"])
    assert len(space["components"]) == closed == int(region["components"]) == 16
    assert space["search"]["complete"] and space["search"]["argument"] == "derived", space["search"]
    assert space["search"]["gated"] is region["gated"] is True
    assert space["search"]["gated_reason"].startswith("gated: the gate rotor cranks")
