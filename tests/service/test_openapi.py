"""The checked-in openapi/openapi.json is generated from the app and must not be stale."""

import inspect
import json
import re
from pathlib import Path
from typing import Any

from engine.catalogue.presets import PRESETS
from engine.design.critical_values import critical_value_slice
from engine.design.robustness import robustness
from engine.model.tolerances import Tolerances
from engine.space.configuration_space import SpaceOptions
from engine.space.trace import TraceOptions
from service.main import create_app

SPEC = Path(__file__).resolve().parents[2] / "openapi" / "openapi.json"


def test_checked_in_openapi_is_current():
    assert SPEC.exists(), "run: python scripts/export_openapi.py"
    current = json.loads(json.dumps(create_app().openapi()))
    assert json.loads(SPEC.read_text()) == current, (
        "openapi/openapi.json is stale: run python scripts/export_openapi.py"
    )


def test_openapi_names_the_contract_paths():
    paths = create_app().openapi()["paths"]
    for path in (
        "/health",
        "/v1/presets",
        "/v1/presets/{name}",
        "/v1/analysis/rigidity",
        "/v1/analysis/second-order",
    ):
        assert path in paths


def test_every_operation_has_a_readable_unique_operation_id():
    spec = create_app().openapi()
    ids = [op["operationId"] for item in spec["paths"].values() for op in item.values()]
    assert len(ids) == len(set(ids)), sorted(i for i in ids if ids.count(i) > 1)
    unreadable = [i for i in ids if not re.fullmatch(r"[a-z]+(?:[A-Z0-9][a-z0-9]*)*", i)]
    assert not unreadable, unreadable
    assert spec["paths"]["/v1/analysis/rigidity"]["post"]["operationId"] == "analyseRigidity"
    assert spec["paths"]["/v1/presets/four-bar"]["get"]["operationId"] == "getPresetFourBar"


def _option_default(schemas: dict[str, Any], model: str, field: str) -> Any:
    prop = schemas[model]["properties"][field]
    assert "default" in prop, f"{model}.{field} shows no default"
    return prop["default"]


def test_option_defaults_in_the_schema_are_the_engines():
    """The defaults the schema documents are the ones the engine applies when a field is
    omitted (the schema keeps the field optional; the engine's dataclasses and signatures are
    the independent reference)."""
    schemas = create_app().openapi()["components"]["schemas"]
    space, trace = SpaceOptions(), TraceOptions()
    expected = {
        ("SpaceOptions", "max_points"): trace.max_points,
        ("SpaceOptions", "strain_tol"): trace.strain_tol,
        ("SpaceOptions", "angles"): space.angles,
        ("SpaceOptions", "random_starts"): space.random_starts,
        ("SpaceOptions", "max_components"): space.max_components,
        ("SpaceOptions", "seed"): space.seed,
        ("Tolerances", "rank_rtol"): Tolerances().rank_rtol,
        ("Tolerances", "q_rtol"): Tolerances().q_rtol,
        ("RobustnessRequest", "method"):
            inspect.signature(robustness).parameters["method"].default,
    }
    slice_params = inspect.signature(critical_value_slice).parameters
    for name in ("resolution", "seeds_per_axis"):
        expected["CriticalValuesOptions", name] = slice_params[name].default
    for (model, field), value in expected.items():
        assert _option_default(schemas, model, field) == value, (model, field)
    # bounds are machine-readable too
    angles = schemas["SpaceOptions"]["properties"]["angles"]["anyOf"][0]
    assert (angles["minimum"], angles["maximum"]) == (4, 2000)


def test_preset_query_parameters_show_their_defaults():
    paths = create_app().openapi()["paths"]
    for name, preset in PRESETS.items():
        params = paths[f"/v1/presets/{name}"]["get"]["parameters"]
        shown = {p["name"]: p["schema"].get("default") for p in params if p["in"] == "query"}
        assert shown == dict(preset.parameters), name
