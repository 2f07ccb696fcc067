"""The configuration-space answer, serialised in the worker, is the SpaceResponse FastAPI would
have sent: same JSON values, valid against the schema, content type JSON."""

from __future__ import annotations

import numpy as np
import pytest

from service import jobs
from service.config import get_settings
from service.schemas.space import SpaceRequest, SpaceResponse

FAST = {"angles": 24, "random_starts": 4}


@pytest.mark.parametrize(
    ("params", "method"),
    [("L1=0.5&L2=1.2&L3=1", "closed form"),  # crank-rocker: two components, no critical point
     ("", "tracer")],  # equilateral: three branch points, six segments (aliased "from")
)
def test_answer_equals_the_models_json(app, client, params, method):
    linkage = client.get(f"/v1/presets/four-bar?{params}").json()
    body = {"linkage": linkage, "options": FAST}
    r = client.post("/v1/analysis/configuration-space", json=body)
    assert r.status_code == 200, r.text
    assert r.headers["content-type"].startswith("application/json")
    got = r.json()
    assert got["search"]["method"] == method
    settings = app.dependency_overrides[get_settings]()  # the app's own (conftest)
    expected = jobs.configuration_space(SpaceRequest.model_validate(body), settings)
    assert got == expected.model_dump(mode="json", by_alias=True)
    SpaceResponse.model_validate(got)
    if method == "tracer":
        assert len(got["segments"]) == 6 and all("from" in s for s in got["segments"])
    lengths = {b["id"]: b["length"] for b in linkage["bars"]}
    for comp in got["components"]:
        pos = {v: np.array(p) for v, p in comp["positions"].items()}
        for bar in linkage["bars"]:
            i, j = bar["ends"]
            err = np.abs(np.linalg.norm(pos[i] - pos[j], axis=1) - lengths[bar["id"]])
            assert err.max() <= 1e-9
