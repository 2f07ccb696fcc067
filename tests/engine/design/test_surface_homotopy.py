"""One homotopy for the three linkages of a D = 2 splitting: the cones at ``L`` against the
collinear pentagons enumerated in the tests, the height's critical points at ``L +- dL``
against Farber and Schuetz's Euler characteristic (their Morse sum) and against the Lagrange
system solved on its own (a second method), and what a stopped homotopy claims."""

from __future__ import annotations

import numpy as np
import pytest

from engine.design.surface_homotopy import LineFamily, line_witnesses
from engine.model.budget import NEVER, Deadline
from engine.model.constraints import Constraints
from engine.model.tolerances import Tolerances
from engine.space.surfaces.geometry import Surface
from engine.space.surfaces.morse import height_witnesses
from tests.engine.design.test_surface_splitting import CRITICAL, collinear_pentagons
from tests.engine.space.surfaces.conftest import (
    five_bar,
    five_bar_reference,
    pentagon,
    pentagon_betti,
)


def euler(b: tuple[int, ...]) -> int:
    return b[0] - b[1] + b[2]


def test_the_cones_at_critical_lengths_are_the_collinear_pentagons():
    lk = pentagon(CRITICAL)
    d_l = np.array([0.0, 0.0, 0.05, 0.0, 0.0])
    lw = line_witnesses(lk, d_l, Tolerances(), np.random.default_rng(3), NEVER)
    ref = collinear_pentagons(CRITICAL)
    assert lw.ended and len(lw.cones) == len(ref) == 4
    got = np.array([cp.u for cp in lw.cones])
    gap = np.linalg.norm(got[:, None] - ref[None], axis=2)
    assert gap.min(axis=1).max() < 1e-8 and gap.min(axis=0).max() < 1e-8


@pytest.mark.parametrize(("lengths", "bar", "change"), [
    ((1.0, 1.0, 1.0, 1.0, 1.0), 1, 1e-3),  # generic: the same space on both sides
    (CRITICAL, 2, 0.05),  # across the critical lengths: the cones resolve, the topology changes
])
def test_the_heights_morse_sums_are_farber_schuetz_euler_characteristics(lengths, bar, change):
    lk = pentagon(lengths)
    d_l = np.zeros(5)
    d_l[bar] = change
    tol = Tolerances()
    lw = line_witnesses(lk, d_l, tol, np.random.default_rng(0), NEVER,
                        at=(1.0, -1.0))
    assert lw.cones == [] and set(lw.heights) == {1.0, -1.0}
    for w, wit in lw.heights.items():
        at = tuple(np.asarray(lengths) + w * d_l)
        assert wit.success, wit.message
        idx = wit.critical.index
        assert (idx >= 0).all()  # a generic height: every critical point nondegenerate
        # a closed surface: sum (-1)^index = chi, here Farber and Schuetz's
        assert int(sum((-1) ** int(i) for i in idx)) == euler(pentagon_betti(at))
        # the Lagrange system solved on its own finds the same points
        moved = lk.with_lengths(lk.lengths + w * d_l)
        ref = height_witnesses(Surface(moved, Constraints(moved), tol.residual_atol),
                               lw.height, np.random.default_rng(1))
        assert ref.success and len(ref.critical.points) == len(wit.critical.points)
        gap = np.linalg.norm(ref.critical.points[:, None] - wit.critical.points[None], axis=2)
        assert gap.min(axis=1).max() < 1e-8
        # and every point is on the moved linkage's lengths, the height's gradient normal there
        for u, lam in zip(wit.critical.points, wit.critical.multipliers, strict=True):
            assert Constraints(moved).max_residual(u) <= tol.residual_atol
            jac = np.asarray(Constraints(moved).jacobian(u, sparse=False))
            assert np.linalg.norm(lw.height - jac.T @ lam) < 1e-8


def test_a_five_bar_on_both_sides():
    """The five-bar's default lengths (ground 1; cranks 1, 1; couplers 1.3, 1.2) changed by
    ``+-1e-3`` in the first coupler: the Morse sums against the Euler characteristic of the
    dense sampling of the crank angles (``five_bar_reference``)."""
    lk = five_bar(1.0, 1.0, 1.3, 1.2, 1.0)
    d_l = np.array([0.0, 1e-3, 0.0, 0.0])  # the bars L1, L2, L3, L4
    lw = line_witnesses(lk, d_l, Tolerances(), np.random.default_rng(2), NEVER)
    assert lw.ended and lw.cones == []
    for w, wit in lw.heights.items():
        assert wit.success
        chi, _ = five_bar_reference(1.0, 1.0, 1.3 + w * 1e-3, 1.2, 1.0)
        assert int(sum((-1) ** int(i) for i in wit.critical.index)) == chi


def test_the_family_derivative_in_w_is_its_difference_quotient():
    lk = pentagon(CRITICAL)
    cons = Constraints(lk)
    rng = np.random.default_rng(4)
    e, m = cons.n_constraints, cons.n_free  # (the pinned bar P0 P1 is no constraint)
    fam = LineFamily(lk, cons, np.array([0.0, 0.1, -0.2, 0.0, 0.3]), rng.normal(size=m),
                     rng.normal(size=e))
    x = rng.normal(size=(3, m + e + 2)) + 1j * rng.normal(size=(3, m + e + 2))
    w = np.array([0.3 + 0.2j, -1.0, 2.0j])
    h = 1e-6
    quotient = (fam(x, w + h)[0] - fam(x, w - h)[0]) / (2 * h)
    assert np.allclose(fam.dw(x, w), quotient, atol=1e-7)
    # at w = 0 the family is the cone system at L: the bars' rows vanish on its lengths
    u = lk.coordinates()
    y = (u - fam.centre) / fam.scale
    point = np.concatenate([[1.0], y, np.zeros(e), [0.0]]).astype(complex)[None]
    assert np.abs(fam(point, np.zeros(1))[0][0, :e]).max() < 1e-12


def test_a_stopped_homotopy_claims_nothing():
    lk = pentagon((1.0, 1.0, 1.0, 1.0, 1.0))
    lw = line_witnesses(lk, np.array([0.0, 1e-3, 0.0, 0.0, 0.0]), Tolerances(),
                        np.random.default_rng(0), Deadline.after(0.0))
    assert not lw.ended
    assert not any(h.success for h in lw.heights.values())
    assert all(h.message != "every path ended" for h in lw.heights.values())
