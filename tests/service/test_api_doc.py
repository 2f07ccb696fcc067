"""docs/API.md (the binding contract) and openapi/openapi.json (generated from the code) agree:
every route in the doc's tables is in the OpenAPI file with that method and operationId, and
every route of the OpenAPI file is in the doc's tables."""

import json
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
DOC = ROOT / "docs" / "API.md"
SPEC = ROOT / "openapi" / "openapi.json"
# a table row: | GET `/v1/presets/{name}?param=value` | `getPreset` | ...
ROW = re.compile(r"^\|\s*(GET|POST|PUT|PATCH|DELETE)\s+`([^`?]+)[^`]*`\s*\|(?:\s*`(\w+)`\s*\|)?")


def doc_routes() -> dict[tuple[str, str], str | None]:
    routes: dict[tuple[str, str], str | None] = {}
    for line in DOC.read_text().splitlines():
        match = ROW.match(line)
        if match:
            method, path, operation_id = match.groups()
            key = (method.lower(), path)
            assert key not in routes, f"{method} {path} is in docs/API.md twice"
            routes[key] = operation_id
    return routes


def spec_routes() -> dict[tuple[str, str], str]:
    spec = json.loads(SPEC.read_text())
    return {(method, path): op["operationId"]
            for path, item in spec["paths"].items() for method, op in item.items()}


def test_the_doc_parses_into_routes():
    routes = doc_routes()
    assert ("post", "/v1/analysis/rigidity") in routes
    assert routes["post", "/v1/analysis/rigidity"] == "analyseRigidity"


def test_every_route_in_the_doc_is_in_the_openapi_file_with_its_operation_id():
    spec = spec_routes()
    missing = [f"{m.upper()} {p}" for m, p in doc_routes() if (m, p) not in spec]
    assert not missing, f"in docs/API.md but not in openapi/openapi.json: {missing}"
    wrong = {f"{m.upper()} {p}": (given, spec[m, p]) for (m, p), given in doc_routes().items()
             if given is not None and given != spec[m, p]}
    assert not wrong, f"operationId in docs/API.md differs from the OpenAPI file: {wrong}"


def test_every_route_of_the_openapi_file_is_in_the_doc():
    documented = doc_routes()
    missing = [f"{m.upper()} {p}" for m, p in spec_routes() if (m, p) not in documented]
    assert not missing, f"in openapi/openapi.json but not in docs/API.md's tables: {missing}"


def test_every_route_in_the_doc_names_its_operation_id():
    unnamed = [f"{m.upper()} {p}" for (m, p), oid in doc_routes().items() if oid is None]
    assert not unnamed, unnamed
