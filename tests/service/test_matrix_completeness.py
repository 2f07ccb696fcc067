"""The preset matrix's completeness at the service's defaults (issue 30; its times are
``bench/bench_matrix.py``'s and ``docs/preset-matrix.md``'s, not a test's): every preset with its
default parameters, the chains of the issue (``kl-chain`` n=100, ``gated-kl-chain`` n=4 gate=2)
and the issue's gate slice, through every JSON endpoint they are meaningful for, with the
options and the search budget a request gets by default (``LINKAGE_SEARCH_TIME_S``, 4 s).

Every cell answers 200 within its budget (never the 504 of the time limit); a complete answer
names its argument, an incomplete one its reason and what it established (the argument's
sentence, or the budget it ran out of); and the cells whose completeness rests on an argument
that needs no time (closed forms, the chain rules) are complete. The figures draw these same
analyses and are left out (``tests/service/test_every_preset.py`` asks them)."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import pytest

from service.config import Settings
from service.main import create_app
from tests.conftest import ApiClient
from tests.service.preset_matrix import (
    DESIGN,
    bodies,
    design_body,
    gate_slice,
    one_dof,
    variant_linkages,
)

# Some forty searches of up to the default budget each.
pytestmark = pytest.mark.slow

REASONS = {"time", "budget", "degenerate", "unresolved", "searched"}
#: Cells complete by an argument that takes no search time (closed forms of the one- and
#: two-dyad chains; the chain rules of engine/space/chain_count.py, which prove that a spinner
#: chain has no critical point; the maps of rotor chains and the gate slice, whose curves are
#: flat four-bar planes and whose regions the chain rules count, gated chains' too; the
#: three-rotor's map, whose curves are closed form and whose regions the dyad closed form
#: counts): complete on any machine, however loaded.
MUST_COMPLETE = {
    ("four-bar", path) for path in (
        "/v1/analysis/critical-points", "/v1/analysis/configuration-space",
        "/v1/analysis/splitting", "/v1/analysis/robustness", "/v1/analysis/critical-values",
        DESIGN)
} | {
    ("three-rotor", path) for path in (
        "/v1/analysis/critical-points", "/v1/analysis/splitting", DESIGN,
        "/v1/analysis/critical-values")
} | {
    (chain, path) for chain in ("kl-chain", "kl-chain?n=100")
    for path in ("/v1/analysis/critical-points", "/v1/analysis/splitting",
                 "/v1/analysis/critical-values")
} | {("gated-kl-chain?n=4&gate=2", "gate slice")} | {
    # gated chains in r0 x r1: the chain's flat planes (the gate rotor cranks the gate
    # four-bar), regions counted by the chain rules (tests/service/test_gated_maps.py)
    (chain, "/v1/analysis/critical-values")
    for chain in ("gated-kl-chain", "gated-kl-chain?n=4&gate=2")
} | {
    # the 3D hinged chain: no cell turns in its outer angle at the defaults, so its 2^(n-1)
    # sheets and no critical point are closed form (tests/service/test_hinge_chains.py)
    ("rotor-chain-3d", path) for path in (
        "/v1/analysis/critical-points", "/v1/analysis/configuration-space",
        "/v1/analysis/splitting")
} | {
    # the spherical four-bar's map (OA x OB): its flat configurations and flat triangles in
    # closed form (engine/design/spherical_radii.py), its regions counted from its hinge cells
    ("spherical-four-bar", "/v1/analysis/critical-values")
}


@pytest.fixture(scope="module")
def api() -> Iterator[ApiClient]:
    app = create_app(Settings.from_env().replace(time_limit_s=30.0, search_time_s=4.0))
    # started and warmed as the served app is before it is ready (the ASGI transport runs no
    # lifespan): no cell pays a worker's start or its kernels' loading
    app.state.engine_pool.start()
    client = ApiClient(app)
    yield client
    client.close()
    app.state.engine_pool.close()


def json_cells(api: ApiClient) -> Iterator[tuple[str, str, dict[str, Any]]]:
    for label, linkage in variant_linkages(api):
        for path, body in bodies(linkage):
            if not path.startswith("/v1/figures/"):
                yield label, path, body
        if one_dof(linkage) and (design := design_body(api, linkage)) is not None:
            yield label, DESIGN, design
    yield "gated-kl-chain?n=4&gate=2", "gate slice", gate_slice(api)


def says_why(search: dict[str, Any]) -> bool:
    """An incomplete search says what it did establish: the sentence of its argument (or of
    why there is none), the budget that stopped it, or the time it was given."""
    detail = search.get("argument_detail")
    if isinstance(detail, str) and detail.strip():
        return True
    if search["reason"] == "time":
        return isinstance(search.get("time_budget_s"), float)
    if search["reason"] == "budget":
        return any(search.get(k) for k in ("component_budget_reached", "assemblies_truncated",
                                           "components_total"))
    return False


def test_every_cell_answers_and_says_whether_complete(api):
    seen, incomplete = set(), []
    for label, path, body in json_cells(api):
        endpoint = "/v1/analysis/critical-values" if path == "gate slice" else path
        r = api.post(endpoint, json=body)
        assert r.status_code == 200, (label, path, r.status_code, r.text[:500])
        search = r.json().get("search")
        if endpoint in ("/v1/analysis/rigidity", "/v1/analysis/second-order"):
            continue  # no search: a closed computation
        assert isinstance(search, dict), (label, path)
        seen.add((label, path))
        if search["complete"]:
            assert search["reason"] is None, (label, path, search)
            assert search["argument"] in ("derived", "proved"), (label, path, search)
            assert search["argument_detail"], (label, path, search)
        else:
            assert search["reason"] in REASONS, (label, path, search)
            assert says_why(search), (label, path, search)
            incomplete.append((label, path, search["reason"]))
    assert MUST_COMPLETE <= seen, MUST_COMPLETE - seen
    assert not MUST_COMPLETE & {(label, path) for label, path, _ in incomplete}, incomplete
