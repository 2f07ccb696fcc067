"""The presets of issue 25 (engine/catalogue/mechanisms.py): built on their own lengths, with
the degrees of freedom their geometry says (rank-nullity of a rigidity matrix written here), and
a 422 naming the parameter for lengths that give no assembly."""

from __future__ import annotations

from itertools import combinations

import numpy as np
import pytest

from engine.catalogue.presets import PRESETS, build_preset, parameter_bounds
from engine.model.errors import InvalidParameter
from engine.model.linkage import Linkage

#: (preset, parameters, D): the planar pentagon and five-bar, the sphere-slider, the spherical
#: five-bar and the spatial quadrilateral have two degrees of freedom, the spherical four-bar one.
CASES = [
    ("pentagon", {}, 2),
    ("pentagon", {"L0": 2.0, "L1": 1.0, "L2": 1.4, "L3": 1.6, "L4": 1.0}, 2),
    ("five-bar", {}, 2),
    ("five-bar", {"a": 2.0, "L2": 1.4, "L3": 1.6}, 2),
    ("spherical-four-bar", {}, 1),
    ("spherical-four-bar", {"R": 2.0, "g": 2.5, "L1": 1.0, "L2": 2.9, "L3": 2.2}, 1),
    ("sphere-slider", {}, 2),
    ("sphere-slider", {"theta": 2.0, "side": -1.0}, 2),
    ("spherical-five-bar", {}, 2),
    ("spherical-five-bar", {"R": 2.0, "g": 2.4, "L1": 1.2, "L2": 2.0, "L3": 1.8, "L4": 1.4,
                            "side": -1.0}, 2),
    ("spatial-quadrilateral", {}, 2),
    ("spatial-quadrilateral", {"l1": 2.0, "l2": 1.5, "l3": 1.2, "l4": 0.4, "theta": -1.0}, 2),
    ("spatial-quadrilateral", {"phi": 0.0}, 2),  # d = l1 + l2 at phi = 0: the next angle
]


def rigidity_dof(lk: Linkage) -> int:
    """``M - rank R``: ``R`` has a row ``(p_i - p_j)`` at the free coordinates of each bar's ends
    (bars between two fully fixed vertices constrain nothing and are left out)."""
    free = ~lk.fixed
    column = -np.ones(lk.fixed.shape, dtype=int)
    column[free] = np.arange(int(free.sum()))
    rows = []
    for i, j in lk.ends:
        if lk.fixed[i].all() and lk.fixed[j].all():
            continue
        row = np.zeros(int(free.sum()))
        d = lk.positions[i] - lk.positions[j]
        for v, sign in ((i, 1.0), (j, -1.0)):
            for k in range(lk.dimension):
                if free[v, k]:
                    row[column[v, k]] += sign * d[k]
        rows.append(row)
    rank = np.linalg.matrix_rank(np.array(rows), tol=1e-9)
    return int(free.sum()) - int(rank)


@pytest.mark.parametrize(("name", "params", "dof"), CASES)
def test_built_on_its_lengths_with_its_degrees_of_freedom(name, params, dof):
    lk = build_preset(name, params)
    assert lk.dimension == PRESETS[name].dimension
    np.testing.assert_allclose(lk.bar_lengths(), lk.lengths, atol=1e-12)
    for key, value in params.items():
        if key in lk.bar_ids:
            assert lk.lengths[lk.bar_ids.index(key)] == value
    assert lk.anything_fixed
    assert rigidity_dof(lk) == dof


def test_the_equilateral_pentagon_is_generic():
    """Generic: no subset of the sides sums to half the perimeter (no flat configuration); the
    same for the five-bar's defaults."""
    for name, keys in (("pentagon", ("L0", "L1", "L2", "L3", "L4")),
                       ("five-bar", ("a", "L1", "L2", "L3", "L4"))):
        lengths = [PRESETS[name].parameters[k] for k in keys]
        half = sum(lengths) / 2
        sums = [sum(s) for r in range(1, 5) for s in combinations(lengths, r)]
        assert min(abs(s - half) for s in sums) >= 0.1, name


def test_spherical_geometry():
    """Every moving point of the spherical four-bar on the sphere about O, the ground pins too;
    the sphere-slider's B in the plane z = 0 and on its circle about Q."""
    lk = build_preset("spherical-four-bar", {"R": 1.5})
    pos = dict(zip(lk.vertex_ids, lk.positions, strict=True))
    for v in ("G1", "G2", "A", "B"):
        assert np.linalg.norm(pos[v] - pos["O"]) == pytest.approx(1.5, abs=1e-12)
    lk = build_preset("sphere-slider", {"theta": 1.0})
    pos = dict(zip(lk.vertex_ids, lk.positions, strict=True))
    assert pos["B"][2] == 0.0 and list(lk.fixed[lk.vertex_ids.index("B")]) == [False, False, True]
    assert np.linalg.norm(pos["B"] - [2.5, 0.0, 0.0]) == pytest.approx(0.8, abs=1e-12)


@pytest.mark.parametrize(("name", "params", "loc"), [
    ("pentagon", {"L0": 5.0}, ("L0",)),          # does not close: 5 >= 1 + 1 + 1 + 1
    ("pentagon", {"L3": 4.0}, ("L3",)),          # flat only: not a surface
    ("pentagon", {"L1": -1.0}, ("L1",)),
    ("five-bar", {"a": 6.0}, ("a",)),
    ("five-bar", {"L4": 0.0}, ("L4",)),
    ("spherical-four-bar", {"L2": 2.5}, ("L2",)),  # a chord longer than the diameter
    ("spherical-four-bar", {"g": 2.0}, ("g",)),
    ("spherical-four-bar", {"L1": 0.1, "L2": 0.1}, ()),  # the cranks never reach each other
    ("sphere-slider", {"c": 0.5}, ("c",)),        # d + s >= r + c: not a torus
    ("sphere-slider", {"d": 1.5}, ("d",)),        # |r - c| >= d - s
    ("sphere-slider", {"d": 1.0, "s": 0.1}, ()),  # two given: both named in the message
    ("sphere-slider", {"side": 0.0}, ("side",)),
    ("spherical-five-bar", {"L4": 2.0}, ("L4",)),  # a chord as long as the diameter
    ("spherical-five-bar", {"L1": 0.1, "L2": 0.2, "L3": 0.2}, ()),  # B meets no C
    ("spherical-five-bar", {"R": 0.5}, ("R",)),    # every chord too long
    ("spatial-quadrilateral", {"l4": 3.0}, ("l4",)),  # |l3 - l4| = 1.8 > l1 + l2 = 1.5
    ("spatial-quadrilateral", {"l2": 3.5}, ("l2",)),  # |l1 - l2| = 2.5 > l3 + l4 = 2.2
    ("spherical-five-bar", {"side": 0.0}, ("side",)),
    ("spatial-quadrilateral", {"l1": 4.0}, ("l1",)),  # |l1 - l2| = 3.5 > l3 + l4 = 2.2
    ("spatial-quadrilateral", {"l3": 0.0}, ("l3",)),
])
def test_bad_parameters_are_named(name, params, loc):
    with pytest.raises(InvalidParameter) as err:
        build_preset(name, params)
    assert err.value.loc == loc


@pytest.mark.parametrize("name", ["pentagon", "five-bar", "spherical-four-bar", "sphere-slider",
                                  "spherical-five-bar", "spatial-quadrilateral"])
def test_lengths_are_positive_in_the_bounds(name):
    bounds = parameter_bounds(name)
    lk = build_preset(name)
    for bar in lk.bar_ids:
        if bar in bounds:
            assert bounds[bar].exclusive_minimum == 0.0, bar
    if "side" in bounds:  # (the spatial quadrilateral's v3 has an angle, theta, instead)
        assert bounds["side"].choices == (-1.0, 1.0)


def test_spherical_five_bar_and_spatial_quadrilateral_geometry():
    """The spherical five-bar's pins and moving points on the sphere about O, its cranks at
    their chords from the ground pins; the quadrilateral's v2 in the plane z = 0 (z fixed) at
    angle phi about v1, v3 at angle theta about the diagonal v0 v2 (theta = pi/2: straight
    above the diagonal's foot, in the vertical plane through it)."""
    lk = build_preset("spherical-five-bar", {"R": 1.5, "g": 1.8})
    pos = dict(zip(lk.vertex_ids, lk.positions, strict=True))
    for v in ("G1", "G2", "A", "B", "C"):
        assert np.linalg.norm(pos[v] - pos["O"]) == pytest.approx(1.5, abs=1e-12)
    assert np.linalg.norm(pos["G1"] - pos["G2"]) == pytest.approx(1.8, abs=1e-12)
    assert pos["G2"][2] == 0.0 and lk.fixed[:3].all() and not lk.fixed[3:].any()
    # B's side of the plane O A C: side = +1 along A x C
    for side in (1.0, -1.0):
        lk = build_preset("spherical-five-bar", {"side": side})
        pos = dict(zip(lk.vertex_ids, lk.positions, strict=True))
        assert np.sign(np.cross(pos["A"], pos["C"]) @ pos["B"]) == side
    lk = build_preset("spatial-quadrilateral", {"phi": 2.0, "theta": np.pi / 2})
    pos = dict(zip(lk.vertex_ids, lk.positions, strict=True))
    assert list(lk.fixed[lk.vertex_ids.index("v2")]) == [False, False, True]
    assert pos["v2"][2] == 0.0 and pos["v1"].tolist() == [1.0, 0.0, 0.0]
    np.testing.assert_allclose(pos["v2"], [1 + 0.5 * np.cos(2.0), 0.5 * np.sin(2.0), 0.0],
                               atol=1e-12)
    # theta = pi/2: v3 straight above its circle's centre on the diagonal (x, y along v2)
    v2, v3 = pos["v2"], pos["v3"]
    assert v3[2] > 0 and abs(v2[0] * v3[1] - v2[1] * v3[0]) < 1e-12
