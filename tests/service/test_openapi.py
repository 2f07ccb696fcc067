"""The checked-in openapi/openapi.json is generated from the app and must not be stale."""

import json
from pathlib import Path

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
