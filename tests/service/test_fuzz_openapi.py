"""Property-based fuzzing of every operation in the OpenAPI schema (schemathesis).

Each operation gets generated requests, valid and invalid, with the seed printed in the pytest
header (``FUZZ_SEED`` to replay one). Every response must be a non-5xx whose status code,
content type and body conform to the schema.

How many requests an operation gets follows what one answer costs (``COSTLY_PATHS``): the
operations that only read, validate or do first- and second-order linear algebra get
``FUZZ_EXAMPLES`` (300 unless the environment says otherwise); those that explore a
configuration space, draw a figure or start a Dask job get ``FUZZ_COSTLY_EXAMPLES`` (60 unless
the environment says otherwise). The presets' own routes (``PRESET_ROUTES``: one per preset,
all one handler that ``/v1/presets/{name}`` shares, which gets ``FUZZ_EXAMPLES``) get
``FUZZ_PRESET_EXAMPLES`` each (60 unless the environment says otherwise; with schemathesis's
coverage cases of every parameter: they were half of the fuzzing's time at 300 each, and
``tests/service/test_preset_parameters.py`` takes every parameter to the edges of float64).
``FUZZ_EXAMPLES=300 FUZZ_COSTLY_EXAMPLES=300 FUZZ_PRESET_EXAMPLES=300`` is the deep run.
"""

from __future__ import annotations

import hypothesis
import pytest
import schemathesis
from schemathesis.checks import not_a_server_error
from schemathesis.specs.openapi.checks import (
    content_type_conformance,
    response_schema_conformance,
    status_code_conformance,
)

from engine.catalogue.presets import PRESETS
from service.config import Settings
from service.main import create_app
from tests.conftest import FUZZ_COSTLY_EXAMPLES, FUZZ_EXAMPLES, FUZZ_PRESET_EXAMPLES, FUZZ_SEED

pytestmark = pytest.mark.fuzz

CHECKS = [not_a_server_error, status_code_conformance, content_type_conformance,
          response_schema_conformance]

#: The operations whose valid requests are costly: they explore a configuration space or
#: search for critical points (seconds for a random linkage), draw a figure (matplotlib), or
#: start a job on a Dask cluster. Every one of them is POST-only.
COSTLY_PATHS = (r"^/v1/(analysis/(configuration-space|critical-points|critical-values|robustness"
                r"|splitting)|design/|figures/|jobs$|sweeps$)")

# Small linkages only (the fuzzer's linkages are random; a valid one can be costly to explore)
# and a generous time limit: the test is about answers, not about the limit. A search asked
# without ``options.time_budget_s`` gets 1 s, not the default 4 s (as in test_fuzz_valid.py): an
# answer cut short by its budget is the same 200 with the same schema (``search.complete``
# false, ``reason: "time"``), and the searches that ran to their 4 s were a quarter of the
# costly operations' time (and a design request of several searches passed schemathesis's 10 s
# read timeout on a loaded machine). A request that asks for a budget gets it, as before.
#: The presets' own routes (``/v1/presets/four-bar``, ...; not ``/v1/presets/{name}``).
PRESET_ROUTES = r"^/v1/presets/[a-z0-9-]+$"

app = create_app(Settings(max_vertices=12, max_bars=24, time_limit_s=120.0, search_time_s=1.0,
                          workers=2))
schema = schemathesis.openapi.from_asgi("/openapi.json", app)
#: Readiness answers 503 until the app's lifespan has started the engine workers, which this
#: in-process app never does (tests/service/test_workers.py covers it against a started one).
NOT_FUZZED = {"GET /health/ready"}
cheap = (schema.exclude(path_regex=COSTLY_PATHS, method="POST").exclude(path_regex=PRESET_ROUTES)
         .exclude(path="/health/ready"))
costly = schema.include(path_regex=COSTLY_PATHS, method="POST")
presets = schema.include(path_regex=PRESET_ROUTES)


def fuzz_settings(examples: int) -> hypothesis.settings:
    return hypothesis.settings(max_examples=examples, deadline=None, derandomize=False,
                               suppress_health_check=list(hypothesis.HealthCheck),
                               database=None)


@cheap.parametrize()
@fuzz_settings(FUZZ_EXAMPLES)
@hypothesis.seed(FUZZ_SEED)
def test_fuzz_operation(case: schemathesis.Case) -> None:
    case.call_and_validate(checks=CHECKS)


@costly.parametrize()
@fuzz_settings(FUZZ_COSTLY_EXAMPLES)
@hypothesis.seed(FUZZ_SEED)
def test_fuzz_costly_operation(case: schemathesis.Case) -> None:
    case.call_and_validate(checks=CHECKS)


@presets.parametrize()
@fuzz_settings(FUZZ_PRESET_EXAMPLES)
@hypothesis.seed(FUZZ_SEED)
def test_fuzz_preset_route(case: schemathesis.Case) -> None:
    case.call_and_validate(checks=CHECKS)


def test_every_operation_is_fuzzed_once() -> None:
    def labels(s: schemathesis.schemas.BaseSchema) -> set[str]:
        return {result.ok().label for result in s.get_all_operations()}

    groups = [labels(cheap), labels(costly), labels(presets)]
    every = set().union(*groups)
    assert sum(len(g) for g in groups) == len(every)  # no operation in two groups
    assert every | NOT_FUZZED == labels(schema) and len(every) >= 30
    assert all(label.startswith("POST ") for label in labels(costly))
    # one route per listed preset, and the route for any name among the cheap ones
    assert labels(presets) == {f"GET /v1/presets/{name}" for name in PRESETS}
    assert "GET /v1/presets/{name}" in labels(cheap)
