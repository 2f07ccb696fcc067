"""Every critical point of a two-degree-of-freedom linkage for its splitting: a spherical
five-bar's cone derived by the chain's argument (24 paths) and checked here by the rank of ``J``
and the great circle through ``A``, ``B``, ``C``; a cone homotopy over its path bound refused
before any path runs, naming the count and the bound."""

from __future__ import annotations

import numpy as np

from engine.design.surface_critical import critical_search
from engine.model.budget import NEVER, Deadline
from engine.model.tolerances import Tolerances
from engine.space.surfaces.cones import cone_paths, find_cones
from tests.engine.space.surfaces.conftest import cone_lengths, spherical_five_bar
from tests.engine.space.surfaces.test_five_bar import jacobian

#: (g, L1, L2, L4) of the spherical five-bar whose L3 is put at a cone (:func:`cone_lengths`).
AT_CONE = (1.2, 0.6, 1.0, 0.7)


def test_a_spherical_five_bar_cone_is_derived():
    lengths, s_max = cone_lengths(*AT_CONE)
    lk = spherical_five_bar(*lengths)
    out = critical_search(lk, Tolerances(), 512, np.random.default_rng(0), NEVER)
    assert out.ended and out.argument == "derived" and out.method == "five-bar chain"
    assert out.paths == 24 and out.message == "" and "24 paths" in out.detail
    (cp,) = out.found
    jac = jacobian(lk, cp.u)
    sv = np.linalg.svd(jac, compute_uv=False)
    assert sv[-1] <= 1e-7 * sv[0] < sv[-2]  # rank E - 1: one self-stress
    pos = lk.positions_of(cp.u)
    a, b, c = pos[3], pos[4], pos[5]
    assert abs(np.linalg.det(np.stack([a, b, c]))) < 1e-6  # one great circle
    assert np.isclose(np.sum((a - c) ** 2), s_max, atol=1e-8)
    q = cp.analysis.q_eigenvalues
    assert q is not None and q.max() > 0 > q.min()  # a cone


def test_a_cone_homotopy_over_its_bound_is_refused_before_any_path_runs():
    """``B``'s third bar to ``G1`` (off ``C``'s axis): no five-bar chain, and the cone
    homotopy's linear product has 2^7 C(9, 7) = 4,608 paths (counted here), over 512."""
    lengths, _ = cone_lengths(*AT_CONE)
    lk = spherical_five_bar(*lengths, pin_b="G1")
    assert cone_paths(7, 9) == 2 ** 7 * 36 == 4608
    # an expired deadline would stop running paths with "did not end": the refusal comes first
    out = critical_search(lk, Tolerances(), 512, np.random.default_rng(0), Deadline.after(0.0))
    assert not out.ended and out.found == [] and out.paths == 4608
    assert "4608 paths exceed the bound of 512" in out.message and "none ran" in out.message
    assert find_cones(lk, Tolerances(), np.random.default_rng(0), paths_max=4607) == ([], False)
    # within a bound that allows it the homotopy runs (here stopped by the deadline at once)
    late = critical_search(lk, Tolerances(), 8192, np.random.default_rng(0),
                           Deadline.after(0.0))
    assert not late.ended and late.argument == "proved"
    assert late.message == "the cones' homotopy did not end on every path"
