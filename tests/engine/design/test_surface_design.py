"""Designs that resolve the cones of a two-degree-of-freedom space as asked, against Farber and
Schuetz's homology of planar pentagon spaces on both sides of a critical length vector."""

from __future__ import annotations

import numpy as np
import pytest

from engine.design.surface_design import MARGIN_REL, ConeTarget, check_targets, design_surface
from engine.model.budget import Deadline
from engine.model.errors import InvalidRequest
from tests.engine.space.surfaces.conftest import pentagon, pentagon_betti

#: A critical length vector: 2 + 1 = 1 + 1 + 1, four collinear pentagons (cones).
CRITICAL = (2.0, 1.0, 1.0, 1.0, 1.0)
FREE = ["b1", "b2", "b3", "b4"]


def euler(b: tuple[int, ...]) -> int:
    return b[0] - b[1] + b[2]


@pytest.mark.slow
@pytest.mark.parametrize("sheets", [1, 2])
def test_every_cone_resolves_as_asked_and_the_re_meshing_matches_farber_schuetz(sheets):
    """All four cones asked for one sheet (necks: the genus grows) or two (parted): the
    designed change resolves each as asked, and the re-meshed topology at L + dL and L - dL
    is the published one for those lengths, as the predicted Euler change says."""
    lk = pentagon(CRITICAL)
    out = design_surface(lk, [ConeTarget(k, sheets=sheets) for k in range(4)], FREE,
                         MARGIN_REL)
    assert out.result.feasible and out.cones_ended and len(out.cones) == 4
    d_l = out.result.perturbation
    assert d_l[0] == 0.0 and out.result.largest_change > 0
    split = out.split
    assert split is not None and out.targets_met
    assert [c.sheets for c in split.cones] == [sheets] * 4
    plus = pentagon_betti(tuple(np.asarray(CRITICAL) + d_l))
    minus = pentagon_betti(tuple(np.asarray(CRITICAL) - d_l))
    assert split.betti == (plus, minus)
    assert split.euler == (euler(plus), euler(minus))
    # the prediction: each cone changes chi by 2 sheets - 3 from the critical space
    assert out.euler_change == 4 * (2 * sheets - 3)
    assert split.predicted_euler_difference == 2 * out.euler_change == euler(plus) - euler(minus)
    # and the Betti numbers predicted from the critical space's mesh, resolved at each apex
    chi = (euler(plus) + euler(minus)) // 2
    assert split.critical_betti == (1, 2 - chi, 1)
    assert split.predicted_betti == (plus, minus)
    assert split.verified and split.complete and out.search.complete
    assert out.search["betti_verified"]


def test_tied_cones_asked_for_opposite_signs_conflict():
    """With b2 alone every cone's Delta moves along one line: two cones whose Delta grow with
    opposite signs of dL_2 cannot both take two sheets when that needs the same sign of
    Delta for one and the opposite for the other; the answer says so without re-meshing."""
    lk = pentagon(CRITICAL)
    probe = design_surface(lk, [ConeTarget(0, sheets=2)], ["b2"], MARGIN_REL)
    assert probe.result.feasible and probe.split is not None
    # a cone that resolved into one sheet while cone 0 got two is tied to it the other way
    other = next(k for k, c in enumerate(probe.split.cones) if c.sheets == 1)
    out = design_surface(lk, [ConeTarget(0, sheets=2), ConeTarget(other, sheets=2)], ["b2"],
                         0.05)
    assert not out.result.feasible and out.split is None and out.targets_met is None
    (conflict,) = out.result.conflicts
    assert sorted(conflict.branch_points) == sorted([0, other])


def test_targets_are_checked():
    lk = pentagon(CRITICAL)
    with pytest.raises(InvalidRequest) as err:
        design_surface(lk, [ConeTarget(4, sheets=1)], FREE, 0.05)
    assert err.value.loc == ("targets", 0, "branch_point") and "found 4" in str(err.value)
    for bad, field in ((ConeTarget(0, sheets=1, sign=1), "sheets"),
                       (ConeTarget(0, sheets=3), "sheets"), (ConeTarget(0), "sheets")):
        with pytest.raises(InvalidRequest) as err:
            check_targets([ConeTarget(1, sheets=1), bad])
        assert err.value.loc == ("targets", 1, field)
    with pytest.raises(InvalidRequest) as err:
        design_surface(lk, [ConeTarget(0, sheets=1)], ["b0"], 0.05)  # between the two pins
    assert err.value.loc == ("adjustable", 0)


def test_a_cone_search_stopped_by_its_deadline_is_no_refusal():
    """Cone 3 exists (the collinear pentagons: four); a search stopped before it ended found
    none, and the answer says so instead of refusing the target as a cone that is not there."""
    lk = pentagon(CRITICAL)
    out = design_surface(lk, [ConeTarget(3, sheets=1)], FREE, 0.05,
                         deadline=Deadline.after(0.0))
    assert not out.cones_ended and out.split is None and not out.result.feasible
    assert out.search.reason == "time" and "no cone 3" in out.search.argument_detail


@pytest.mark.parametrize("sheets", [1, pytest.param(2, marks=pytest.mark.slow)])
def test_a_spherical_five_bar_cone_resolves_as_asked(sheets):
    """The spherical five-bar's cone (derived: 24 paths, not the cone homotopy's 4,608) asked
    for one sheet or two by changing ``L3``: the re-meshed Euler characteristics at
    ``L +- dL`` are the dense crank-angle grid's, and differ by ``2 (2 sheets - 3)``."""
    from tests.engine.design.test_surface_critical import AT_CONE, cone_lengths
    from tests.engine.space.surfaces.conftest import (
        spherical_five_bar,
        spherical_five_bar_reference,
    )

    lengths, _ = cone_lengths(*AT_CONE)
    lk = spherical_five_bar(*lengths)
    out = design_surface(lk, [ConeTarget(0, sheets=sheets)], ["L3"], MARGIN_REL)
    assert out.result.feasible and out.cones_ended and len(out.cones) == 1
    change = float(out.result.perturbation[lk.bar_ids.index("L3")])
    assert change != 0.0
    split = out.split
    assert split is not None and out.targets_met and split.cones[0].sheets == sheets
    chi = tuple(sum(spherical_five_bar_reference(*np.add(lengths, (0, 0, 0, s * change, 0))))
                for s in (1, -1))
    assert out.euler_change == 2 * sheets - 3
    assert split.euler == chi and chi[0] - chi[1] == 2 * out.euler_change
    assert split.verified and split.complete
    assert out.search.complete and out.search.argument == "derived"
