"""What an answer proves so far (issue 23, item 5): ``search.proved`` says, for the critical
points and the components, how many were found and whether that is the exact count (the answer
is complete, or an argument covers that part alone) or a lower bound; checked against the
independent dense-sampling references of tests/engine/space/test_witnesses.py and the chain
rules' closed count."""

from __future__ import annotations

import pytest

from engine.catalogue.presets import build_preset
from engine.model.budget import Deadline
from engine.space.configuration_space import SpaceOptions, explore
from tests.engine.space.test_witnesses import circles_of, reference_components, reference_sheets


def reference_count(preset: str, params: dict[str, float]) -> int:
    lk = build_preset(preset, params)
    circles, lengths, _ = circles_of(lk)
    return reference_components(reference_sheets(circles, lengths, 20000))


def claims(answer: dict) -> dict:
    proved = answer["search"]["proved"]
    assert set(proved) <= {"critical_points", "components"}
    return proved


def test_a_component_budget_leaves_the_critical_points_proved():
    # three hinged rotors in 3D on the general path (closed_form off: the homotopy proves
    # every critical point); one component of the reference's several traced: components at
    # least 1, not exact
    params = {"n": 3, "tilt": 0.3, "h": 0.5}
    expected = reference_count("rotor-chain-3d", params)
    assert expected >= 2
    lk = build_preset("rotor-chain-3d", params)
    full = explore(lk, options=SpaceOptions(closed_form=False))
    assert full.search["complete"] and full.search["argument"] == "proved"
    assert claims({"search": full.search.as_dict()})["components"] == {"count": expected,
                                                                       "exact": True}
    cut = explore(lk, options=SpaceOptions(closed_form=False, max_components=1)).search.as_dict()
    assert not cut["complete"]
    proved = claims({"search": cut})
    assert proved["components"] == {"count": 1, "exact": False}
    assert proved["critical_points"] == {"count": len(full.critical_points), "exact": True}


def test_a_component_budget_leaves_the_hinged_chain_counted(client):
    # through HTTP the chain is derived from its cells: the count is exact whatever is shown
    params = {"n": 3, "tilt": 0.3, "h": 0.5}
    expected = reference_count("rotor-chain-3d", params)
    lk = client.get("/v1/presets/rotor-chain-3d?n=3&tilt=0.3&h=0.5").json()
    full = client.post("/v1/analysis/configuration-space", json={"linkage": lk}).json()
    assert full["search"]["complete"] and full["search"]["argument"] == "derived"
    assert len(full["components"]) == expected
    assert claims(full)["components"] == {"count": expected, "exact": True}
    cut = client.post("/v1/analysis/configuration-space",
                      json={"linkage": lk, "options": {"max_components": 1}}).json()
    assert not cut["search"]["complete"] and len(cut["components"]) == 1
    assert claims(cut) == {"components": {"count": expected, "exact": True},
                           "critical_points": {"count": 0, "exact": True}}


def test_beyond_the_path_bound_the_counts_are_lower_bounds():
    # four hinged rotors on the general path: 896 paths, beyond the default bound of 512:
    # what was traced, at least (through HTTP the chain is derived: test_hinge_chains.py)
    lk = build_preset("rotor-chain-3d", {"n": 4, "tilt": 0.7})
    r = explore(lk, options=SpaceOptions(closed_form=False),
                deadline=Deadline.after(4.0)).search.as_dict()
    res_components = r["curves_traced"]
    assert not r["complete"] and r["argument"] is None
    proved = claims({"search": r})
    assert proved["components"]["exact"] is False
    assert 1 <= proved["components"]["count"] <= res_components
    assert proved["components"]["count"] <= reference_count("rotor-chain-3d",
                                                            {"n": 4, "tilt": 0.7})
    assert proved["critical_points"]["exact"] is False


def test_the_chain_rules_count_what_no_budget_traces(client):
    # a 100-rotor spinner chain: 2^99 components by the chain rules (a decimal string beyond
    # 2^53), none traced beyond the answer's size budget, and no critical point
    lk = client.get("/v1/presets/kl-chain?n=100").json()
    r = client.post("/v1/analysis/configuration-space", json={"linkage": lk}).json()
    assert "components_disagree" not in r["search"]
    proved = claims(r)
    assert proved["components"] == {"count": str(2**99), "exact": True}
    assert proved["critical_points"] == {"count": 0, "exact": True}
    crit = client.post("/v1/analysis/critical-points", json={"linkage": lk}).json()
    assert claims(crit)["critical_points"] == {"count": 0, "exact": True}
    assert claims(crit).get("components") is None  # (no components in that answer)


@pytest.mark.parametrize(("preset", "branch_points"), [("three-rotor", 12), ("four-bar", None)])
def test_complete_answers_claim_exactly_what_they_list(client, preset, branch_points):
    lk = client.get(f"/v1/presets/{preset}").json()
    for path in ("/v1/analysis/configuration-space", "/v1/analysis/critical-points"):
        r = client.post(path, json={"linkage": lk}).json()
        assert r["search"]["complete"], r["search"]
        proved = claims(r)
        assert proved["critical_points"] == {"count": len(r["critical_points"]), "exact": True}
        if branch_points is not None:  # the paper's twelve branch points
            assert proved["critical_points"]["count"] == branch_points
        if "components" in r:
            assert proved["components"] == {"count": len(r["components"]), "exact": True}


def test_the_client_reads_the_claims(client):
    from linkage_client.models import CountClaim, ProvedSoFar, SpaceResult

    lk = client.get("/v1/presets/kl-chain?n=100").json()
    data = client.post("/v1/analysis/configuration-space", json={"linkage": lk}).json()
    proved = SpaceResult.from_json(data).search.proved
    assert isinstance(proved, ProvedSoFar)
    assert proved.components == CountClaim(count=str(2**99), exact=True)
    assert proved.critical_points == CountClaim(count=0, exact=True)
