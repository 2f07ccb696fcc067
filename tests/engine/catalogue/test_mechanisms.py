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

#: (preset, parameters, D): the planar pentagon and five-bar and the sphere-slider have two
#: degrees of freedom, the spherical four-bar one.
CASES = [
    ("pentagon", {}, 2),
    ("pentagon", {"L0": 2.0, "L1": 1.0, "L2": 1.4, "L3": 1.6, "L4": 1.0}, 2),
    ("five-bar", {}, 2),
    ("five-bar", {"a": 2.0, "L2": 1.4, "L3": 1.6}, 2),
    ("spherical-four-bar", {}, 1),
    ("spherical-four-bar", {"R": 2.0, "g": 2.5, "L1": 1.0, "L2": 2.9, "L3": 2.2}, 1),
    ("sphere-slider", {}, 2),
    ("sphere-slider", {"theta": 2.0, "side": -1.0}, 2),
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
])
def test_bad_parameters_are_named(name, params, loc):
    with pytest.raises(InvalidParameter) as err:
        build_preset(name, params)
    assert err.value.loc == loc


@pytest.mark.parametrize("name", ["pentagon", "five-bar", "spherical-four-bar", "sphere-slider"])
def test_lengths_are_positive_in_the_bounds(name):
    bounds = parameter_bounds(name)
    lk = build_preset(name)
    for bar in lk.bar_ids:
        if bar in bounds:
            assert bounds[bar].exclusive_minimum == 0.0, bar
    assert bounds["side"].choices == (-1.0, 1.0)
