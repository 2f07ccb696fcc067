"""Presets: built on a point of their configuration space, with the documented geometry."""

from __future__ import annotations

import numpy as np
import pytest

from engine.catalogue.presets import PRESETS, build_preset
from engine.local.rigidity import first_order
from engine.model.errors import InvalidParameter, UnknownPreset

CASES = [
    ("four-bar", {}),
    ("four-bar", {"a": 2.0, "L1": 0.7, "L2": 2.1, "L3": 1.4, "theta": 0.0}),
    ("three-rotor", {}),
    ("three-rotor", {"phi": 2.0, "r1": 1.05}),
    ("kl-chain", {}),
    ("kl-chain", {"n": 40, "r": 1.2, "l": 1.1}),
    ("gated-kl-chain", {}),
    ("gated-kl-chain", {"D": 3.0}),
    ("gated-kl-chain", {"n": 21, "gate": 10, "D": 2.2}),
]


@pytest.mark.parametrize(("name", "params"), CASES)
def test_preset_lies_on_its_configuration_space(name, params):
    lk = build_preset(name, params)
    np.testing.assert_allclose(lk.bar_lengths(), lk.lengths, atol=1e-12)
    for key, value in params.items():
        if key in lk.bar_ids:
            assert lk.lengths[lk.bar_ids.index(key)] == value
    rig = first_order(lk)
    assert rig.expected_dof == 1 and rig.trivial_motions == 0


def test_every_preset_is_listed_with_defaults():
    assert set(PRESETS) == {
        "four-bar", "three-rotor", "kl-chain", "gated-kl-chain",
        # engine/catalogue/catalogue.py
        "tetrahedron", "octahedron", "bricard-line", "bricard-plane", "three-prism",
        "three-prism-flexible", "k33-conic", "k33-dixon", "cn-symmetric-four-regular",
        "rotor-chain-3d",
        # engine/catalogue/mechanisms.py
        "pentagon", "five-bar", "spherical-four-bar", "sphere-slider", "spherical-five-bar",
        "spatial-quadrilateral",
    }
    for preset in PRESETS.values():
        assert preset.description and preset.parameters


def test_geometry_of_the_gate():
    lk = build_preset("gated-kl-chain", {"n": 8, "gate": 3, "D": 2.5})
    pos = dict(zip(lk.vertex_ids, lk.positions, strict=True))
    np.testing.assert_allclose(pos["P3"], [3.0, 0.0])
    np.testing.assert_allclose(pos["G"], [3.0, -2.5])
    g = lk.vertex_ids.index("G")
    assert list(lk.fixed[g]) == [True, False]  # slider along y
    ends = {b: tuple(lk.vertex_ids[i] for i in e) for b, e in zip(lk.bar_ids, lk.ends, strict=True)}
    assert ends["D"] == ("P3", "G") and ends["L1"] == ("G", "R") and ends["L2"] == ("T3", "R")


def test_three_rotor_pins():
    lk = build_preset("three-rotor", {"a": 2.0, "phi": np.pi / 2})
    pos = dict(zip(lk.vertex_ids, lk.positions, strict=True))
    np.testing.assert_allclose(pos["P3"], [2.0, 2.0], atol=1e-12)


@pytest.mark.parametrize(
    ("name", "params", "error", "loc"),
    [
        ("nope", {}, UnknownPreset, ("name",)),
        ("four-bar", {"x": 1.0}, InvalidParameter, ("x",)),
        ("four-bar", {"L1": -1.0}, InvalidParameter, ("L1",)),
        ("four-bar", {"L2": 5.0}, InvalidParameter, ()),
        ("four-bar", {"side": 0.5}, InvalidParameter, ("side",)),
        ("kl-chain", {"n": 2.5}, InvalidParameter, ("n",)),
        ("kl-chain", {"n": 1}, InvalidParameter, ("n",)),
        ("kl-chain", {"r": 0.2, "l": 3.0}, InvalidParameter, ()),
        ("gated-kl-chain", {"gate": 10}, InvalidParameter, ("gate",)),
        ("four-bar", {"a": float("inf")}, InvalidParameter, ("a",)),
    ],
)
def test_bad_parameters(name, params, error, loc):
    with pytest.raises(error) as info:
        build_preset(name, params)
    assert info.value.loc == loc


CATALOGUE_NAMES = [
    "tetrahedron", "octahedron", "bricard-line", "bricard-plane", "three-prism",
    "three-prism-flexible", "k33-conic", "k33-dixon", "cn-symmetric-four-regular",
    "rotor-chain-3d",
]


@pytest.mark.parametrize("name", CATALOGUE_NAMES)
def test_catalogue_frameworks_are_built_on_their_lengths(name):
    lk = build_preset(name)
    assert lk.dimension == PRESETS[name].dimension
    np.testing.assert_allclose(lk.bar_lengths(), lk.lengths, atol=1e-12)


def test_catalogue_geometry():
    """The defining symmetries and incidences, checked on the built positions."""
    pos = {n: build_preset(n).positions for n in ("bricard-line", "bricard-plane", "k33-conic")}
    half_turn = np.diag([-1.0, -1.0, 1.0])
    line = pos["bricard-line"]
    for i in (0, 2, 4):
        np.testing.assert_allclose(line[i + 1], half_turn @ line[i])
    plane = pos["bricard-plane"]
    assert plane[0][0] == plane[1][0] == 0.0
    for i in (2, 4):
        np.testing.assert_allclose(plane[i + 1], np.diag([-1.0, 1.0, 1.0]) @ plane[i])
    x, y = pos["k33-conic"].T
    np.testing.assert_allclose((x / 2.0) ** 2 + y**2, 1.0)
    chain = build_preset("rotor-chain-3d", {"n": 4})
    assert first_order(chain).dof == 1 and chain.anything_fixed


@pytest.mark.parametrize(("name", "params", "loc"), [
    ("cn-symmetric-four-regular", {"n": 9}, ("n",)),
    ("rotor-chain-3d", {"h": -1.0}, ("h",)),
    ("rotor-chain-3d", {"l": 40.0}, ()),
])
def test_catalogue_bad_parameters(name, params, loc):
    with pytest.raises(InvalidParameter) as err:
        build_preset(name, params)
    assert err.value.loc == loc
