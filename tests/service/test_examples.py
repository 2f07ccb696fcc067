"""Every example in the OpenAPI schema is a valid request: what ``/docs`` pre-fills for "Try it
out" (each request body's examples, the examples of the schemas nested in it put in their
place, and each parameter's example or default) is posted and answers 2xx."""

from __future__ import annotations

import copy
import json
from collections.abc import Iterator
from typing import Any

import pytest

from tests.service.test_uvicorn_process import ROOT

SPEC: dict[str, Any] = json.loads((ROOT / "openapi" / "openapi.json").read_text())
#: Operations that start Dask (a job or a sweep): 2xx, but on a real cluster.
DASK_PATHS = {"/v1/jobs", "/v1/sweeps"}


def resolve(schema: dict[str, Any]) -> dict[str, Any]:
    while "$ref" in schema:
        schema = SPEC["components"]["schemas"][schema["$ref"].rsplit("/", 1)[-1]]
    return schema


def own_examples(holder: dict[str, Any]) -> list[Any]:
    """The examples an OpenAPI object or schema carries itself (``example``, ``examples``)."""
    found = [holder["example"]] if "example" in holder else []
    examples = holder.get("examples", [])
    if isinstance(examples, dict):  # a media type's or parameter's named examples
        found += [e["value"] for e in examples.values() if "value" in e]
    else:  # a schema's list
        found += list(examples)
    return found


def variants(schema: dict[str, Any]) -> list[dict[str, Any]]:
    """The schema and, for an optional field (``anyOf`` with null), its non-null options."""
    schema = resolve(schema)
    return [schema] + [resolve(o) for o in schema.get("anyOf", []) if o.get("type") != "null"]


def nested(schema: dict[str, Any], body: Any, path: tuple[str, ...]) -> Iterator[
        tuple[tuple[str, ...], Any]]:
    """``(path, example)`` of every schema nested in ``schema`` (along the properties ``body``
    has) that carries examples of its own: Swagger UI shows them where that schema appears."""
    if not isinstance(body, dict):
        return
    for variant in variants(schema):
        for key, sub in variant.get("properties", {}).items():
            if key not in body:
                continue
            for example in [e for v in variants(sub) for e in own_examples(v)]:
                yield (*path, key), example
            yield from nested(sub, body[key], (*path, key))


def replaced(body: Any, path: tuple[str, ...], value: Any) -> Any:
    out = copy.deepcopy(body)
    target = out
    for key in path[:-1]:
        target = target[key]
    target[path[-1]] = value
    return out


def cases() -> Iterator[Any]:
    for path, item in SPEC["paths"].items():
        for method, op in item.items():
            marks = [pytest.mark.dask] if path in DASK_PATHS else []
            name = f"{method.upper()} {path}"
            if "requestBody" in op:
                media = op["requestBody"]["content"]["application/json"]
                schema = media["schema"]
                tops = own_examples(media) + own_examples(resolve(schema))
                if not tops:  # Swagger UI would build one from the fields' bounds
                    yield pytest.param(method, path, None, None, id=f"{name} (none)")
                for k, top in enumerate(tops):
                    yield pytest.param(method, path, None, top, id=f"{name} #{k}", marks=marks)
                    for where, example in nested(schema, top, ()):
                        yield pytest.param(method, path, None, replaced(top, where, example),
                                           id=f"{name} #{k} {'.'.join(where)}", marks=marks)
            query = {}
            for param in op.get("parameters", []):
                prefill = own_examples(param) + own_examples(param.get("schema", {}))
                if not prefill and "default" in param.get("schema", {}):
                    prefill = [param["schema"]["default"]]
                if prefill and param["in"] == "query":
                    query[param["name"]] = prefill[0]
            if query:
                yield pytest.param(method, path, query, None, id=f"{name} ?parameters")


@pytest.mark.parametrize(("method", "path", "query", "body"), list(cases()))
def test_every_schema_example_is_a_valid_request(client: Any, method: str, path: str,
                                                 query: dict[str, Any] | None,
                                                 body: Any) -> None:
    assert body is not None or query is not None, f"{method.upper()} {path} has no example"
    r = client.request(method.upper(), path, params=query, json=body)
    assert 200 <= r.status_code < 300, f"{method.upper()} {path} {query} {body}: {r.text}"


def test_the_examples_cover_every_body() -> None:
    """The parametrisation above is not empty: a body example for each operation with a body,
    the tolerances' own example substituted in at least one."""
    ids = [c.id for c in cases()]
    with_body = [f"{m.upper()} {p}" for p, item in SPEC["paths"].items()
                 for m, op in item.items() if "requestBody" in op]
    assert with_body and all(any(i.startswith(f"{b} #") for i in ids) for b in with_body)
    assert any(i.endswith(".tolerances") or i.endswith(" tolerances") for i in ids)
