"""The spherical four-bar's maps over two of its bars through HTTP (issues 23 and 30):
complete with the argument ``derived``, every curve on the critical set in the arcs and every
region's count equal to dense sampling (:mod:`tests.engine.design.sphere_reference`); the
figure draws the same map; the robustness margin over two chords is exact."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from tests.engine.design.sphere_reference import preset_sphere
from tests.service.test_figures import svg_ids, svg_text, with_prefix

BARS = ("OA", "OB", "L1", "L2", "L3")


def _map(client: Any, path: str, axes: list[tuple[str, float, float]]) -> Any:
    linkage = client.get("/v1/presets/spherical-four-bar").json()
    body = {"linkage": linkage,
            "axes": [{"bar": b, "min": lo, "max": hi} for b, lo, hi in axes]}
    return client.post(path, json=body)


@pytest.mark.parametrize("axes", [[("L1", 0.3, 0.9), ("L2", 0.65, 1.95)],
                                  [("L2", 0.5, 1.5), ("L3", 0.5, 1.5)],
                                  [("L3", 0.6, 1.4), ("L1", 0.2, 1.0)],
                                  [("OA", 0.8, 1.2), ("OB", 0.8, 1.2)],  # the preset matrix's
                                  [("OB", 0.5, 1.5), ("L2", 0.6, 1.9)]])
def test_a_map_over_two_bars_is_derived_and_right(client: Any, axes) -> None:
    r = _map(client, "/v1/analysis/critical-values", axes)
    assert r.status_code == 200, r.text
    got = r.json()
    assert got["search"]["complete"] is True, got["search"]
    assert got["search"]["argument"] == "derived"
    assert got["search"]["method"] == "closed form"
    ref = preset_sphere({})
    names = [a[0] for a in axes]

    def lengths(x: float, y: float) -> np.ndarray:
        out = {"OA": 1.0, "OB": 1.0, "L1": 0.6, "L2": 1.3, "L3": 1.0} | dict(
            zip(names, (x, y), strict=True))
        return np.array([out[c] for c in BARS])

    assert got["curves"]
    for curve in got["curves"]:
        pts = np.array(curve)  # [[x, y], ...]
        assert np.all(ref.residual(np.array([lengths(x, y) for x, y in pts])) < 1e-6)
    for region in got["regions"]:
        assert region["components"] == ref.components5(lengths(*region["point"])), region


def test_the_figure_draws_the_derived_map(client: Any) -> None:
    """The critical-values figure of a chord map: one drawn curve per curve of the answer, no
    'incomplete' mark."""
    axes = [("L1", 0.3, 0.9), ("L2", 0.65, 1.95)]
    svg = _map(client, "/v1/figures/critical-values", axes)
    assert svg.status_code == 200, svg.text
    answer = _map(client, "/v1/analysis/critical-values", axes).json()
    ids = svg_ids(svg)
    assert len(with_prefix(ids, "cv-curve-")) == len(answer["curves"]) >= 1
    assert "incomplete" not in svg_text(svg)


def test_a_margin_over_two_chords_is_exact(client: Any) -> None:
    """Robustness over ``L1`` and ``L2``: the closed form, exact and derived; its nearest
    lengths on an arc equality (the reference's); over every bar (radii too) the multistart."""
    linkage = client.get("/v1/presets/spherical-four-bar").json()
    r = client.post("/v1/analysis/robustness",
                    json={"linkage": linkage, "adjustable": ["L1", "L2"]})
    assert r.status_code == 200, r.text
    got = r.json()
    assert got["method"] == "closed-form" and got["guarantee"] == "exact"
    assert got["search"]["complete"] is True and got["search"]["argument"] == "derived"
    nearest = np.array([got["nearest"][b] for b in BARS])
    assert preset_sphere({}).residual(nearest) < 1e-9
    assert got["margin"] == pytest.approx(np.linalg.norm(nearest - [1.0, 1.0, 0.6, 1.3, 1.0]))
    closed = client.post("/v1/analysis/robustness",
                         json={"linkage": linkage, "adjustable": ["OA", "L1"],
                               "method": "closed-form"})
    assert closed.status_code == 422, closed.text
