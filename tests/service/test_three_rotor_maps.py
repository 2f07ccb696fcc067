"""The three-rotor's critical-value maps through HTTP with the defaults a request gets (issue 23,
item 3; issue 30): the preset matrix's map and issue 23's, complete with their argument, against
the critical set and the component counts written in the tests (circle intersections, dense
sampling of the middle rotor); a closed curve smaller than a raster cell found."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from tests.engine.design.slice_references import ThreeRotor, distance_to_curves, points_inside

PATH = "/v1/analysis/critical-values"


def the_map(client: Any, axes: tuple[str, str], box: np.ndarray, **params: float
            ) -> dict[str, Any]:
    query = "&".join(f"{k}={v}" for k, v in params.items())
    linkage = client.get(f"/v1/presets/three-rotor?{query}").json()
    r = client.post(PATH, json={"linkage": linkage, "axes": [
        {"bar": a, "min": float(lo), "max": float(hi)} for a, (lo, hi) in
        zip(axes, box, strict=True)]})
    assert r.status_code == 200, r.text[:500]
    return r.json()


def check_against_reference(body: dict[str, Any], ref: ThreeRotor, axes: tuple[str, str],
                            box: np.ndarray, resolution: int = 48) -> None:
    """Every curve point critical, every scanned critical point drawn, every region's count
    the dense sampling's at its sample and at four more of its cells."""
    curves = [np.array(c, dtype=float) for c in body["curves"]]
    for c in curves:
        assert ref.residuals(axes, c).max() <= 1e-9
    expected = ref.scanned(axes, box)
    assert len(expected) and distance_to_curves(expected, curves).max() <= 1e-3
    for region in body["regions"]:
        point = np.array(region["point"])
        for q in [point] + points_inside(curves, box, resolution, point):
            assert region["components"] == ref.components(dict(zip(axes, q, strict=True))), \
                (region, q)


@pytest.mark.parametrize(("axes", "box"), [
    (("r1", "r2"), np.array([[0.8, 1.2], [0.8, 1.2]])),  # the preset matrix's cell
    (("L1", "L2"), np.array([[0.6, 1.4], [0.6, 1.4]])),  # issue 23's
], ids=["matrix r1-r2", "issue-23 L1-L2"])
def test_the_default_three_rotor_maps_are_complete_and_right(client, axes, box):
    """With the default options (resolution 48, the default search budget) the maps answer
    complete, derived from the closed form (were ``time`` at 4 s, needing ~20 s to answer only
    ``searched``); their curves and every region's count match the references."""
    body = the_map(client, axes, box)
    search = body["search"]
    assert search["complete"] is True and search["argument"] == "derived", search
    assert search["method"] == "closed form" and search["regions_exact"] == len(body["regions"])
    check_against_reference(body, ThreeRotor(), axes, box)
    if axes == ("L1", "L2"):  # the arc where a component is born: 3 on one side, 4 on the other
        assert {3, 4} <= {r["components"] for r in body["regions"]}


def test_every_region_sample_explored_through_the_service_agrees(client):
    """Each region's count is what the configuration-space endpoint answers, complete, at the
    region's sample (the map's labels are explorations that are themselves complete)."""
    axes, box = ("L1", "L2"), np.array([[0.6, 1.4], [0.6, 1.4]])
    body = the_map(client, axes, box)
    for region in body["regions"]:
        query = "&".join(f"{a}={v!r}" for a, v in zip(axes, region["point"], strict=True))
        built = client.get(f"/v1/presets/three-rotor?{query}")
        if built.status_code == 422:  # assembles nowhere: the region must be empty
            assert region["components"] == 0, region
            continue
        r = client.post("/v1/analysis/configuration-space",
                        json={"linkage": built.json(), "options": {"points": "compact"}})
        assert r.status_code == 200, r.text[:300]
        space = r.json()
        assert space["search"]["complete"] is True, space["search"]
        assert len(space["components"]) == region["components"], (region, space["search"])


def test_a_closed_curve_between_two_scanlines_is_found(client):
    """A middle rotor of 0.008: over (L1, L2) in [1.5, 2.5] (a raster cell and sweep step of
    1/48) the curve where both dyads are straight is a loop about (2, 2) of diameter 0.016,
    between two scanlines: drawn, and the region inside it (one component: both dyads reach B
    only near their straight positions) found with the count of the dense sampling, as every
    other region."""
    axes, box = ("L1", "L2"), np.array([[1.5, 2.5], [1.5, 2.5]])
    body = the_map(client, axes, box, r2=0.008)
    ref = ThreeRotor(r2=0.008)
    expected = ref.scanned(axes, np.array([[1.98, 2.02]] * 2), samples=801)
    loop = expected[np.linalg.norm(expected - 2.0, axis=1) < 0.0081]
    curves = [np.array(c, dtype=float) for c in body["curves"]]
    assert len(loop) >= 16 and distance_to_curves(loop, curves).max() <= 1e-4
    inside = [r for r in body["regions"] if np.linalg.norm(np.array(r["point"]) - 2.0) < 0.007]
    assert inside and all(r["components"] == ref.components(
        dict(zip(axes, r["point"], strict=True))) for r in inside)
    check_against_reference(body, ref, axes, box)
    search = body["search"]
    # (the loop touches the four flat-cell lines where it turns: where two curves touch the
    # strip between them is thinner than any raster, and the answer says so if it cannot
    # show that no region is lost there)
    assert search["complete"] or "run closer than" in search["argument_detail"], search
