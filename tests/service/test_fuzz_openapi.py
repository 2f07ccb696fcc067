"""Property-based fuzzing of every operation in the OpenAPI schema (schemathesis).

Each operation gets ``FUZZ_EXAMPLES`` generated requests (300 unless the environment says
otherwise), valid and invalid, with the seed printed in the pytest header (``FUZZ_SEED`` to
replay one). Every response must be a non-5xx whose status code, content type and body
conform to the schema.
"""

from __future__ import annotations

import os

import hypothesis
import schemathesis
from schemathesis.checks import not_a_server_error
from schemathesis.specs.openapi.checks import (
    content_type_conformance,
    response_schema_conformance,
    status_code_conformance,
)

from service.config import Settings
from service.main import create_app

FUZZ_EXAMPLES = int(os.environ.get("FUZZ_EXAMPLES", "300"))
FUZZ_SEED = int(os.environ.get("FUZZ_SEED") or int.from_bytes(os.urandom(4), "little"))
CHECKS = [not_a_server_error, status_code_conformance, content_type_conformance,
          response_schema_conformance]

# Small linkages only (the fuzzer's linkages are random; a valid one can be costly to explore)
# and a generous time limit: the test is about answers, not about the limit.
app = create_app(Settings(max_vertices=12, max_bars=24, time_limit_s=120.0, workers=2))
schema = schemathesis.openapi.from_asgi("/openapi.json", app)


@schema.parametrize()
@hypothesis.settings(max_examples=FUZZ_EXAMPLES, deadline=None, derandomize=False,
                     suppress_health_check=list(hypothesis.HealthCheck),
                     database=None)
@hypothesis.seed(FUZZ_SEED)
def test_fuzz_operation(case: schemathesis.Case) -> None:
    case.call_and_validate(checks=CHECKS)
