"""The typed models against the OpenAPI schemas, and the packed arrays decoded."""

from __future__ import annotations

import base64
import dataclasses

import numpy as np
import pytest
from linkage_client import models
from linkage_client._build import json_name
from linkage_client.labelled import Labelled, decode_packed

from tests.client.conftest import OPENAPI

#: Answer schemas of openapi/openapi.json and the model of each.
MODELS = {
    "Linkage": models.Linkage, "Vertex": models.Vertex, "Bar": models.Bar,
    "Health": models.Health, "PresetInfo": models.PresetInfo,
    "TolerancesUsed": models.TolerancesUsed, "SearchReport": models.SearchReport,
    "TangentForm": models.TangentForm, "RigidityResponse": models.RigidityResult,
    "StressCertificate": models.StressCertificate, "DualCertificate": models.DualCertificate,
    "SecondOrderFlex": models.SecondOrderFlex, "SecondOrderResponse": models.SecondOrderResult,
    "CriticalPointOut": models.CriticalPoint, "NearMissOut": models.NearMiss,
    "CriticalPointsResponse": models.CriticalPointsResult, "ComponentOut": models.Component,
    "SegmentOut": models.Segment, "SpaceResponse": models.SpaceResult,
    "SurfaceOut": models.Surface, "HeightCriticalOut": models.HeightCritical,
    "BranchSplitOut": models.BranchSplit, "SplittingResponse": models.SplittingResult,
    "RobustnessSearch": models.RobustnessSearch, "RobustnessResponse": models.RobustnessResult,
    "RegionOut": models.Region, "CellSigns": models.CellSigns, "SliceSearch": models.SliceSearch,
    "CriticalValuesResponse": models.CriticalValuesResult, "PredictedOut": models.Predicted,
    "ConflictOut": models.Conflict, "DesignResponse": models.DesignResult,
    "Progress": models.Progress, "JobError": models.JobError, "JobOut": models.Job,
    "JobSummary": models.JobSummary, "Readiness": models.Readiness,
    "OperationOut": models.Operation, "CountClaim": models.CountClaim,
    "ProvedSoFar": models.ProvedSoFar, "ConeSplitOut": models.ConeSplit,
    "SurfaceSplitOut": models.SurfaceSplit, "SurfaceDesignOut": models.SurfaceDesign,
}


@pytest.mark.parametrize("schema", sorted(MODELS))
def test_model_fields_are_the_schema_properties(schema: str) -> None:
    properties = set(OPENAPI["components"]["schemas"][schema]["properties"])
    fields = {json_name(f) for f in dataclasses.fields(MODELS[schema]) if f.name != "raw"}
    assert fields == properties


def test_every_answer_schema_has_a_model() -> None:
    """Schemas that are answers (refs of 200/202 answers, recursively) all have a model."""
    schemas = OPENAPI["components"]["schemas"]
    seen: set[str] = set()

    def walk(node: object) -> None:
        if isinstance(node, dict):
            ref = node.get("$ref")
            if isinstance(ref, str):
                name = ref.rsplit("/", 1)[1]
                if name not in seen:
                    seen.add(name)
                    walk(schemas[name])
            for value in node.values():
                walk(value)
        elif isinstance(node, list):
            for value in node:
                walk(value)

    for item in OPENAPI["paths"].values():
        for op in item.values():
            for status in ("200", "202"):
                walk(op["responses"].get(status, {}))
    # PackedArray is decoded into Labelled (tests below)
    assert seen - {"PackedArray"} <= set(MODELS), seen - set(MODELS)


def packed(array: np.ndarray, ids: list[str]) -> dict[str, object]:
    return {"ids": ids, "shape": list(array.shape), "dtype": "<f8",
            "base64": base64.b64encode(array.astype("<f8").tobytes()).decode()}


def test_packed_arrays_decode_bit_for_bit() -> None:
    rng = np.random.default_rng(1)
    walk = rng.normal(size=(7, 3, 2))
    lab = Labelled.from_packed(packed(walk, ["a", "b", "c"]))
    assert np.array_equal(lab.array, walk) and lab["b"].shape == (7, 2)
    assert np.array_equal(lab["c"], walk[:, 2])
    series = Labelled.from_series({k: walk[:, i].tolist() for i, k in enumerate("abc")})
    assert np.array_equal(series.array, walk)


@pytest.mark.parametrize("change, message", [
    ({"dtype": "<f4"}, "dtype"), ({"shape": [7, 3, 3]}, "bytes"),
    ({"base64": "not base64!"}, "base64"),
])
def test_bad_packed_arrays_are_refused(change: dict[str, object], message: str) -> None:
    good = packed(np.zeros((7, 3, 2)), ["a", "b", "c"])
    with pytest.raises(ValueError, match=message):
        decode_packed({**good, **change})


def test_labelled_checks_its_ids() -> None:
    with pytest.raises(ValueError):
        Labelled(("a",), np.zeros((2, 2)))
    lab = Labelled.from_mapping({"a": [1.0, 2.0], "b": [3.0, 4.0]})
    assert lab.to_dict() == {"a": [1.0, 2.0], "b": [3.0, 4.0]} and "a" in lab
    with pytest.raises(KeyError):
        lab["c"]


def test_linkage_round_trip_and_lengths() -> None:
    data = {"dimension": 2, "vertices": [
        {"id": "P", "position": [0.0, 0.0], "fixed": True},
        {"id": "S", "position": [3.0, 0.0], "fixed": [False, True]},
        {"id": "A", "position": [0.0, 4.0], "fixed": False}],
        "bars": [{"id": "r", "ends": ["P", "A"]}, {"id": "c", "ends": ["A", "S"], "length": 5.5}]}
    lk = models.Linkage.from_json(data)
    assert lk.to_json() == data and models.Linkage.from_json(lk.to_json()) == lk
    assert lk.lengths() == {"r": 4.0, "c": 5.5}
    assert lk.fixed_axes().tolist() == [[True, True], [False, True], [False, False]]
    assert lk.positions["A"].tolist() == [0.0, 4.0]


def test_unknown_answer_keys_are_ignored_and_kept_on_raw() -> None:
    answer = {"branch_points": [], "critical_points_found": 0, "new_field": 1,
              "search": {"complete": True, "reason": None, "time_budget_s": 1.0, "more": 2},
              "tolerances": {"rank_rtol": 1e-8, "residual_atol": 1e-9, "q_rtol": 1e-6}}
    result = models.SplittingResult.from_json(answer)
    assert result.raw["new_field"] == 1 and result.search.complete is True


def test_surfaces_decode_alike_from_packed_and_lists() -> None:
    """A two-degree-of-freedom answer's surface: positions ``(mesh vertices, V, d)`` from
    either form, triangles an ``(F, 3)`` int array, the height's critical points typed."""
    rng = np.random.default_rng(2)
    mesh = rng.normal(size=(4, 2, 2))
    surface = {"closed": False, "triangles": [[0, 1, 2], [0, 2, 3]], "euler": 1,
               "orientable": True, "betti_z2": [1, 0, 0], "betti_q": [1, 0, 0], "genus": None,
               "defects": {"open_edges": 4}, "inverted_triangles": 0,
               "tangent_angle_max": 1.5, "morse_sum": None, "morse_agrees": False,
               "critical_points": []}
    height = {"configuration": {"a": [0.0, 1.0], "b": [1.0, 0.0]}, "index": 2, "surface": 0}
    series = models.Surface.from_json(
        {**surface, "positions": {k: mesh[:, i].tolist() for i, k in enumerate("ab")}})
    compact = models.Surface.from_json({**surface, "positions": packed(mesh, ["a", "b"])})
    for s in (series, compact):
        assert np.array_equal(s.positions.array, mesh) and s.positions.ids == ("a", "b")
        assert s.triangles.shape == (2, 3) and s.triangles.dtype.kind == "i"
        assert s.betti_q == [1, 0, 0] and s.genus is None and s.defects == {"open_edges": 4}
    h = models.HeightCritical.from_json(height)
    assert h.index == 2 and h.surface == 0 and h.configuration["b"].tolist() == [1.0, 0.0]
