"""Every preset with every pair of its bars as the axes of a map (issue 24): never a 5xx. A
linkage that can be traced (one degree of freedom, both bars with a free end) answers 200;
anything else a 4xx problem naming the field. Each map's labels are checked at its samples
against the configuration space explored there (its count, exact or a bound; ``gated``), the
tau signs of every four-bar cell against Eq. 16 computed here from the linkage's own lengths
and pins, and on the gated chain's gate bars ``gated`` and the count against dense sampling.

Bounded: the chain presets at their shortest interesting length (3 rotors; the 3D chain 2),
resolution 8, two seeds per axis and half a second of search per map and per check."""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterator
from typing import Any

import pytest

from engine.catalogue.presets import PRESETS
from service.config import Settings
from service.main import create_app
from tests.conftest import ApiClient
from tests.gated_reference import sampled_gated_chain
from tests.service.preset_matrix import bar_length, free_bars, one_dof

pytestmark = pytest.mark.slow

#: The chain presets at a short length: the same kinds of bar pairs as the defaults' (rotor with
#: neighbour or distant rotor, coupler, gate bar), in a bounded time.
SMALL = {"kl-chain": {"n": 3}, "gated-kl-chain": {"n": 3, "gate": 1},
         "rotor-chain-3d": {"n": 2}}
OPTIONS = {"resolution": 8, "seeds_per_axis": 2, "time_budget_s": 0.5}
GATE_BARS = {"D", "L1", "L2"}


@pytest.fixture(scope="module")
def api() -> Iterator[ApiClient]:
    app = create_app(Settings.from_env().replace(time_limit_s=30.0, search_time_s=1.0))
    client = ApiClient(app)
    yield client
    client.close()
    app.state.engine_pool.close()


def with_lengths(linkage: dict[str, Any], lengths: dict[str, float]) -> dict[str, Any]:
    bars = [{**b, "length": lengths[b["id"]]} if b["id"] in lengths else b
            for b in linkage["bars"]]
    return {**linkage, "bars": bars}


def taus(a: float, l1: float, l2: float, l3: float) -> list[int]:
    values = (a - l1 + l2 - l3, a - l1 - l2 + l3, l2 + l3 - a - l1)
    return [0 if abs(v) < 1e-9 * max(a, l1, l2, l3) else int(math.copysign(1, v))
            for v in values]


def cell_signs(linkage: dict[str, Any], cell: dict[str, Any]) -> list[int]:
    """Eq. 16 for a cell named by its bars (input rotor, coupler, output rotor), from the
    linkage's lengths and its pins: the ground is the distance between the rotors' pins (the
    gate's: between the gate rotor's pin and the slider)."""
    bars = {b["id"]: b for b in linkage["bars"]}
    pos = {v["id"]: v["position"] for v in linkage["vertices"]}
    fixed = {v["id"]: v.get("fixed", False) for v in linkage["vertices"]}
    inp, coupler, out = (bars[b] for b in cell["bars"])

    def pin(bar: dict[str, Any]) -> str:
        return next(e for e in bar["ends"] if fixed[e] is True)

    def other(bar: dict[str, Any], end: str) -> str:
        return bar["ends"][1] if bar["ends"][0] == end else bar["ends"][0]

    if cell["cell"] == "gate":  # the output rocker L1 ends on the slider G
        tip = other(coupler, other(inp, pin(inp)))
        ground = bar_length(linkage, bars["D"])
        assert other(out, tip) == "G"
    else:
        ground = math.dist(pos[pin(inp)], pos[pin(out)])
    return taus(ground, *(bar_length(linkage, b) for b in (inp, coupler, out)))


def check_region(api: ApiClient, preset: str, linkage: dict[str, Any], axes: list[str],
                 region: dict[str, Any], complete: bool) -> None:
    """One region's labels against the configuration space explored at its sample (the map
    ``complete`` or not)."""
    at = with_lengths(linkage, dict(zip(axes, region["point"], strict=True)))
    signs = [cell_signs(at, cell) for cell in region["tau_signs"] or []]
    assert all(set(cell["bars"]) & set(axes) or cell["cell"] == "gate"
               for cell in region["tau_signs"] or []), (preset, axes, region)
    assert [c["signs"] for c in region["tau_signs"] or []] == signs, (preset, axes, region)
    if any(0 in s for s in signs):
        # the sample lies on a critical line of a cell (a curve the map did not find): its
        # count is that of critical lengths, and the map must not claim to be complete
        assert not complete, (preset, axes, region)
        return
    r = api.post("/v1/analysis/configuration-space",
                 json={"linkage": at, "options": {"time_budget_s": 0.5, "points": "compact"}})
    if r.status_code == 422:  # the sample does not assemble: the region must be empty
        assert region["components"] == 0, (preset, axes, region, r.text[:300])
        return
    assert r.status_code == 200, (preset, axes, r.status_code, r.text[:300])
    space = r.json()
    search = space["search"]
    traced = len(space["components"])
    n = region["components"]
    if region["components_exact"]:
        if "components_total" in search:
            assert int(search["components_total"]) == int(n), (preset, axes, region, search)
        elif search["complete"]:
            assert traced == int(n), (preset, axes, region, traced)
        else:
            assert traced <= int(n), (preset, axes, region, traced)
    elif search["complete"]:  # a lower bound is at most the whole
        assert int(n) <= traced, (preset, axes, region, traced)
    assert region.get("gated") == search.get("gated"), (preset, axes, region, search)
    if preset == "gated-kl-chain" and set(axes) <= GATE_BARS:
        length = {b["id"]: bar_length(at, b) for b in at["bars"]}
        count, turns = sampled_gated_chain(3, 1.0, length["r0"], length["l0"], 1, length["D"],
                                           length["L1"], length["L2"], samples=2000)
        assert int(n) == count, (axes, region, count)
        if count:
            assert region["gated"] is (not turns), (axes, region, turns)


def test_every_listed_preset_is_mapped():
    assert set(SMALL) <= set(PRESETS)


@pytest.mark.parametrize("preset", sorted(PRESETS))
def test_every_pair_of_bars_maps(api: ApiClient, preset: str) -> None:
    linkage = api.get(f"/v1/presets/{preset}", params=SMALL.get(preset, {})).json()
    free = {b["id"] for b in free_bars(linkage)}
    traceable = one_dof(linkage)
    answered = 0
    for a, b in itertools.combinations(linkage["bars"], 2):
        axes = [a["id"], b["id"]]
        body = {"linkage": linkage, "options": OPTIONS, "axes": [
            {"bar": x["id"], "min": 0.8 * bar_length(linkage, x),
             "max": 1.2 * bar_length(linkage, x)} for x in (a, b)]}
        r = api.post("/v1/analysis/critical-values", json=body)
        assert r.status_code < 500, (preset, axes, r.status_code, r.text[:500])
        if not (traceable and set(axes) <= free):
            assert 400 <= r.status_code < 500, (preset, axes, r.status_code)
            assert r.headers["content-type"].startswith("application/problem+json")
            problem = r.json()
            field = problem["errors"][0]["loc"][:2]
            assert field in (["body", "linkage"], ["body", "axes"]), problem
            continue
        assert r.status_code == 200, (preset, axes, r.status_code, r.text[:500])
        answered += 1
        regions = [g for g in r.json()["regions"] if g["components"] is not None]
        if not regions:
            continue
        # the labels at the sample of the largest region explored
        check_region(api, preset, linkage, axes, max(regions, key=lambda g: g["cells"]),
                     r.json()["search"]["complete"])
    assert answered == (math.comb(len(free), 2) if traceable else 0)


@pytest.mark.parametrize("axes", [("r1", "L1"), ("L2", "r3")])
def test_the_three_rotor_maps_of_the_issue(api: ApiClient, axes: tuple[str, str]) -> None:
    """The boxes that answered 500 (issue 24: ``zero-size array`` in the map): each length in
    [0.5, 1.5], the viewer's default slice for that preset."""
    linkage = api.get("/v1/presets/three-rotor").json()
    # (time to explore every region even on a cold worker: the labels are checked)
    body = {"linkage": linkage, "options": {**OPTIONS, "time_budget_s": 10.0},
            "axes": [{"bar": b, "min": 0.5, "max": 1.5} for b in axes]}
    r = api.post("/v1/analysis/critical-values", json=body)
    assert r.status_code == 200, r.text[:500]
    regions = [g for g in r.json()["regions"] if g["components"] is not None]
    assert regions and len(regions) == len(r.json()["regions"])
    # the cells the axes are sides of: the first four-bar for (r1, L1), the second for (L2, r3)
    assert all([c["bars"] for c in g["tau_signs"]] == [["r1", "L1", "r2"] if "r1" in axes
                                                      else ["r2", "L2", "r3"]] for g in regions)
    check_region(api, "three-rotor", linkage, list(axes), max(regions, key=lambda g: g["cells"]),
                 r.json()["search"]["complete"])
