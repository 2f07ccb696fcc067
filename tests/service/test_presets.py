"""Preset endpoints."""

import numpy as np


def test_list_presets(client):
    r = client.get("/v1/presets")
    assert r.status_code == 200
    body = {p["name"]: p for p in r.json()}
    assert {"four-bar", "three-rotor", "kl-chain", "gated-kl-chain"} <= set(body)
    catalogue = {"tetrahedron", "octahedron", "bricard-line", "bricard-plane", "three-prism",
                 "three-prism-flexible", "k33-conic", "k33-dixon", "cn-symmetric-four-regular",
                 "rotor-chain-3d"}
    assert set(body) == {"four-bar", "three-rotor", "kl-chain", "gated-kl-chain"} | catalogue
    assert body["tetrahedron"]["dimension"] == 3 and body["four-bar"]["dimension"] == 2
    assert {"a", "L1", "L2", "L3"} <= set(body["four-bar"]["parameters"])
    assert {"a", "r1", "r2", "r3", "L1", "L2", "phi"} <= set(body["three-rotor"]["parameters"])
    assert {"n", "a", "r", "l"} <= set(body["kl-chain"]["parameters"])
    assert {"n", "a", "r", "l", "gate", "D", "L1", "L2"} <= set(
        body["gated-kl-chain"]["parameters"]
    )


def test_preset_with_parameters_is_a_linkage_on_its_configuration_space(client):
    r = client.get("/v1/presets/four-bar?L2=1.1&a=1.2")
    assert r.status_code == 200
    lk = r.json()
    lengths = {b["id"]: b["length"] for b in lk["bars"]}
    assert lengths["L2"] == 1.1
    pos = {v["id"]: np.array(v["position"]) for v in lk["vertices"]}
    for b in lk["bars"]:
        i, j = b["ends"]
        assert abs(np.linalg.norm(pos[i] - pos[j]) - b["length"]) < 1e-12
    assert pos["P2"].tolist() == [1.2, 0.0]
    # and it round-trips into an analysis without projection
    body = client.post("/v1/analysis/rigidity", json={"linkage": lk}).json()
    assert body["projection_distance"] == 0.0 and body["dof"] == 1


def test_kl_chain_size(client):
    lk = client.get("/v1/presets/kl-chain?n=25").json()
    assert len(lk["vertices"]) == 50 and len(lk["bars"]) == 49
