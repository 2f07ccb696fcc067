"""The faster paths of the design loop (issue 15) against the paths they replace: the closed-form
slice of one-dyad chains against the traced one, the vectorised raster against the loop it
replaced, the critical-point refinement against MINPACK's (random and catalogue linkages)."""

from __future__ import annotations

import numpy as np
import pytest

from engine.catalogue.presets import build_preset
from engine.design.critical_values import critical_value_slice
from engine.design.slice_regions import _blocked_cells, _polyline_distance
from engine.model.errors import InvalidRequest
from engine.space.configuration_space import SpaceOptions, explore


def _hausdorff(a: list[np.ndarray], b: list[np.ndarray]) -> float:
    """Largest distance of a point of one family of polylines to the other family."""
    if not a or not b:
        return 0.0 if not a and not b else np.inf
    one = max(float(np.max(np.min([_polyline_distance(c, k) for k in b], axis=0))) for c in a)
    two = max(float(np.max(np.min([_polyline_distance(c, k) for k in a], axis=0))) for c in b)
    return max(one, two)


def _random_four_bar(seed: int) -> tuple[dict[str, float], list[tuple[str, float, float]]]:
    rng = np.random.default_rng(seed)
    params = dict(zip(("L1", "L2", "L3"), rng.uniform(0.4, 1.8, 3), strict=True))
    names = [str(x) for x in rng.choice(["L1", "L2", "L3"], 2, replace=False)]
    return params, [(names[0], 0.25, 2.6), (names[1], 0.3, 2.4)]


CASES = [
    ({"L2": 1.2}, [("L2", 0.3, 2.2), ("L3", 0.3, 2.2)]),
    ({"L2": 1.2}, [("L2", 0.3, 3.6), ("L3", 0.3, 2.2)]),  # with the empty region
    ({"L2": 1.2}, [("L1", 0.4, 2.0), ("L2", 0.3, 2.2)]),
    ({}, [("L3", 0.5, 1.5), ("L1", 0.5, 1.5)]),  # through the equilateral (critical) four-bar
    _random_four_bar(1),
    _random_four_bar(2),
    _random_four_bar(3),
]


def _four_bar_components(lengths: dict[str, float]) -> int:
    """Classical: 0 when the longest side is at least the sum of the others, else 2 for a
    Grashof four-bar (s + g < p + q) and 1 for a non-Grashof one (ground a = 1)."""
    links = sorted([1.0, *lengths.values()])
    if links[3] >= links[0] + links[1] + links[2]:
        return 0
    return 2 if links[0] + links[3] < links[1] + links[2] else 1


def _plane_residual(lengths: dict[str, float]) -> float:
    """min over signs of |a + e1 L1 + e2 L2 + e3 L3| (a = 1): zero on the critical values."""
    return min(abs(1.0 + e1 * lengths["L1"] + e2 * lengths["L2"] + e3 * lengths["L3"])
               for e1 in (1, -1) for e2 in (1, -1) for e3 in (1, -1))


@pytest.mark.parametrize(("params", "axes"), CASES)
def test_closed_form_slice_is_the_traced_slice(params, axes):
    """Every traced curve is a closed-form curve; where the seeds of the traced path reach every
    line (all but short pieces in corners of the box) the maps are the same; the closed-form
    curves are critical values and its regions count components by the classical rules."""
    lk = build_preset("four-bar", params)
    base = dict(zip(lk.bar_ids, (float(x) for x in lk.lengths), strict=True))
    opt = SpaceOptions(angles=24, random_starts=4)
    fast = critical_value_slice(lk, axes, resolution=24, options=opt)
    slow = critical_value_slice(lk, axes, resolution=24, options=opt, method="traced")
    assert fast.search["method"] == "closed form"
    assert slow.search["method"] == "traced"
    # the closed-form curves and exact region counts are derived; traced curves are a search
    assert fast.search["complete"] and fast.search["argument"] == "derived"
    # traced curves are a search, proved only where the sweeps and the turning points of the
    # curves (engine.design.slice_turning) cover the box
    assert slow.search["complete"] is (slow.search["argument"] == "proved")
    if not slow.search["complete"]:
        assert slow.search["reason"] == "searched"
    assert all(r.argument is not None for r in fast.regions + slow.regions)
    span = max(hi - lo for _, lo, hi in axes)
    (x, *_), (y, *_) = axes
    # the traced curves lie on the closed-form ones
    assert slow.curves
    for c in slow.curves:
        assert np.max(np.min([_polyline_distance(c, k) for k in fast.curves], axis=0)) \
            <= 1e-7 * span
    # every closed-form point is a critical value, and the curves are sampled at the step
    for c in fast.curves:
        assert max(_plane_residual({**base, x: p, y: q}) for p, q in c) <= 1e-9
        assert np.max(np.linalg.norm(np.diff(c, axis=0), axis=1)) <= fast.search["step"] + 1e-12
    for r in fast.regions + slow.regions:
        assert r.components == _four_bar_components({**base, x: r.point[0], y: r.point[1]})
    if slow.search["complete"]:  # proved: every closed-form point lies on a traced curve
        for c in fast.curves:
            assert np.max(np.min([_polyline_distance(c, k) for k in slow.curves], axis=0)) \
                <= 1e-7 * span
    if len(fast.curves) == len(slow.curves):  # the traced path found every line
        assert _hausdorff(fast.curves, slow.curves) <= 1e-7 * span
        # the same regions (rasters of two samplings of one line differ by a few cells; a
        # region's sample point may be another of equally central cells; the regions thinner
        # than a cell, found in a finer raster, depend on the sampling: each is checked above)
        key = sorted((r.components, r.signature, r.cells) for r in fast.regions if r.cells)
        ref = sorted((r.components, r.signature, r.cells) for r in slow.regions if r.cells)
        assert [k[:2] for k in key] == [k[:2] for k in ref]
        assert all(abs(a[2] - b[2]) <= max(2, 0.05 * b[2]) for a, b in zip(key, ref, strict=True))


def test_other_linkages_are_traced():
    """A linkage without a closed form (a 3D two-rotor chain; the three-rotor has one now)."""
    lk = build_preset("rotor-chain-3d", {"n": 2})
    res = critical_value_slice(lk, [("r0b", 1.4, 1.7), ("l0", 1.4, 1.6)], resolution=6,
                               seeds_per_axis=1,
                               options=SpaceOptions(angles=12, random_starts=1, max_components=2,
                                                    homotopy_paths_max=0))
    assert res.search["method"] == "traced"


def test_unknown_slice_method():
    with pytest.raises(InvalidRequest):
        critical_value_slice(build_preset("four-bar"), [("L2", 0.5, 1.5), ("L3", 0.5, 1.5)],
                             method="fast")


def _blocked_by_loop(curves: list[np.ndarray], box: np.ndarray, n: int) -> np.ndarray:
    """The raster as it was computed before (a Python loop over segments and samples)."""
    span = box[:, 1] - box[:, 0]
    blocked = np.zeros((n, n), dtype=bool)
    for c in curves:
        for a, b in zip(c[:-1], c[1:], strict=True):
            steps = int(np.ceil(4 * np.max(np.abs(b - a) / span) * n)) + 1
            for s in np.linspace(0.0, 1.0, steps + 1):
                q = (a + s * (b - a) - box[:, 0]) / span * n
                i, j = np.clip(q.astype(int), 0, n - 1)
                blocked[i, j] = True
    return blocked


@pytest.mark.parametrize("seed", range(8))
def test_vectorised_raster_is_the_loop(seed):
    rng = np.random.default_rng(seed)
    box = np.array([[0.3, 2.2], [0.5, 3.0]])
    curves = [box[:, 0] + rng.random((int(rng.integers(2, 30)), 2)) * (box[:, 1] - box[:, 0])
              for _ in range(int(rng.integers(1, 4)))]
    n = int(rng.integers(8, 64))
    assert np.array_equal(_blocked_cells(curves, box, n), _blocked_by_loop(curves, box, n))
    assert not _blocked_cells([], box, n).any()


@pytest.mark.parametrize(("name", "params"), [
    ("four-bar", {"L2": 1.2}), ("four-bar", {"L1": 0.5, "L2": 1.3, "L3": 0.9}),
    ("gated-kl-chain", {"n": 4, "gate": 2}), ("kl-chain", {"n": 5}),
])
def test_regions_need_no_near_misses(name, params):
    """A region's signature explores without the near misses: the same components."""
    lk = build_preset(name, params)
    opt = SpaceOptions(angles=12, random_starts=2, max_components=4)
    with_misses = explore(lk, options=opt)
    without = explore(lk, options=opt, near_misses=False)
    assert len(with_misses.components) == len(without.components)
    assert with_misses.search.complete == without.search.complete
    for a, b in zip(with_misses.components, without.components, strict=True):
        assert a.closed == b.closed
        assert _hausdorff([a.points], [b.points]) <= 1e-9 * float(np.max(np.abs(a.points)))


# -- the sparse Levenberg-Marquardt of the critical-point refinement against MINPACK's -------

def _starts(lk, count: int, seed: int) -> list[np.ndarray]:
    """Candidates of the critical-point search and seeded projected random starts."""
    from engine.model.tolerances import Tolerances
    from engine.space.assembly import projected_random_starts
    from engine.space.configuration_space import Explorer
    from engine.space.configuration_space.critical_search import candidates

    ex = Explorer(lk, Tolerances(), SpaceOptions(max_components=4, random_starts=0))
    ex.trace_all(lk.coordinates())
    rng = np.random.default_rng(seed)
    return candidates(ex)[:count] + projected_random_starts(lk, Tolerances(), 3, rng)


@pytest.mark.parametrize(("name", "params"), [
    ("three-rotor", {}), ("four-bar", {}), ("four-bar", {"L2": 1.2}), ("kl-chain", {"n": 6}),
    ("gated-kl-chain", {"n": 4, "gate": 2}), ("kl-chain", {"n": 12, "l": 1.4, "r": 1.3}),
])
def test_sparse_refinement_is_minpacks(name, params):
    """From the same starts both land on the same critical point (critical lengths), or on
    near misses with the same residuals: the same verdict, the same point where it is one."""
    from scipy.optimize import least_squares

    from engine.local.critical import AugmentedSystem, SparseAugmentedSystem, refine_critical
    from engine.model.constraints import Constraints
    from engine.model.tolerances import Tolerances

    lk = build_preset(name, params)
    cons, tol = Constraints(lk), Tolerances()
    scale = float(np.median(lk.lengths))
    agree = 0
    for u0 in _starts(lk, 8, 3):
        dense = refine_critical(cons, u0, tol, method="minpack")
        sparse = refine_critical(cons, u0, tol, method="sparse")
        assert dense.critical == sparse.critical
        if dense.critical:
            assert np.linalg.norm(dense.u - sparse.u) <= 1e-6 * scale
            assert sparse.length_residual <= tol.residual_atol
        else:
            # A near miss: within the budget of 100 evaluations both may still creep along a
            # flat valley of |F| (a floppy chain); run to convergence, both reach the same
            # local minimum.
            x0 = np.concatenate([u0, _start_stress(cons, u0)])
            far = SparseAugmentedSystem(cons).solve(x0, max_nfev=3000)
            ref = least_squares(AugmentedSystem(cons).residual, x0,
                                jac=AugmentedSystem(cons).jacobian, method="lm", xtol=1e-15,
                                ftol=1e-15, gtol=1e-15, max_nfev=3000).x
            m = cons.n_free
            assert np.linalg.norm(far[:m] - ref[:m]) <= 1e-5 * scale
            assert min(np.linalg.norm(far[m:] - ref[m:]), np.linalg.norm(far[m:] + ref[m:])) \
                <= 1e-5
        agree += np.linalg.norm(dense.u - sparse.u) <= 1e-6 * scale
    assert agree >= 1


def _start_stress(cons, u0: np.ndarray) -> np.ndarray:
    """The start stress of :func:`engine.local.critical.refine_critical`."""
    return np.linalg.svd(cons.jacobian(u0, sparse=False))[0][:, -1]


def test_critical_search_through_the_sparse_refinement(monkeypatch):
    """The whole critical-point search with every refinement sparse: the same critical points
    (three-rotor: twelve branch points) in the same order, the same kinds."""
    import engine.local.critical as critical
    from engine.space.configuration_space import find_critical_points

    lk = build_preset("three-rotor")
    opt = SpaceOptions(critical_closed_form=False)
    dense = find_critical_points(lk, options=opt)
    monkeypatch.setattr(critical, "SPARSE_REFINE_MIN_UNKNOWNS", 0)
    sparse = find_critical_points(lk, options=opt)
    assert len(dense.critical_points) == len(sparse.critical_points) == 12
    for a, b in zip(dense.critical_points, sparse.critical_points, strict=True):
        assert a.kind == b.kind
        assert np.linalg.norm(a.u - b.u) <= 1e-7


def test_unknown_refine_method():
    from engine.local.critical import refine_critical
    from engine.model.constraints import Constraints
    from engine.model.tolerances import Tolerances

    lk = build_preset("four-bar")
    with pytest.raises(ValueError, match="unknown method"):
        refine_critical(Constraints(lk), lk.coordinates(), Tolerances(), method="qr")


SEEDED = [
    ("gated-kl-chain", {"n": 4, "gate": 2}, [("L2", 1.0, 3.0), ("D", 1.0, 3.5)], "traced"),
    ("three-rotor", {}, [("L1", 0.5, 2.0), ("L2", 0.5, 2.0)], "traced"),
    ("four-bar", {"L1": 0.5, "L2": 1.3, "L3": 0.9}, [("L2", 0.3, 2.2), ("L3", 0.3, 2.2)],
     "traced"),
]


def _same_slice(fast, slow) -> None:
    """The same curves (within a small fraction of the step), regions and seed counts."""
    assert fast.search["complete"] == slow.search["complete"]
    assert len(fast.curves) == len(slow.curves) > 0
    assert _hausdorff(fast.curves, slow.curves) <= 1e-3 * float(fast.search["step"])
    for key in ("seed_lengths", "seed_configurations", "curves", "regions_explored"):
        assert fast.search[key] == slow.search[key]
    assert [(r.point, r.components, r.signature, r.cells) for r in fast.regions] == \
        [(r.point, r.components, r.signature, r.cells) for r in slow.regions]


@pytest.mark.slow
@pytest.mark.parametrize(("name", "params", "axes", "method"), SEEDED,
                         ids=[c[0] for c in SEEDED])
def test_seeds_taken_a_column_at_once_are_the_seeds_taken_one_by_one(
        name, params, axes, method, monkeypatch):
    """The slice's seeds moved onto ``G = 0`` one column of seed lengths at once (one batch)
    against one seed's starts at a time (as the seed loop took them before)."""
    from engine.design.critical_values import _CurveTracing

    lk = build_preset(name, params)
    # (no homotopy: the seed lengths' path, which slices take where the sweeps cannot run)
    opt = SpaceOptions(angles=12, random_starts=2, max_components=4, homotopy_paths_max=0)
    fast = critical_value_slice(lk, axes, resolution=16, options=opt, method=method)
    batches: list[int] = []
    take = _CurveTracing.take

    def one_by_one(self, starts):
        for s in starts:
            batches.append(len(s))
            take(self, [s])

    monkeypatch.setattr(_CurveTracing, "take", one_by_one)
    slow = critical_value_slice(lk, axes, resolution=16, options=opt, method=method)
    assert len(batches) == slow.search["seed_lengths"] == 25
    assert sum(batches) == slow.search["seed_configurations"]
    _same_slice(fast, slow)


@pytest.mark.parametrize("shift", [-1e-9, 0.0, 1e-9])
def test_a_curve_through_cell_corners_blocks_the_same_cells_however_it_rounds(shift):
    """A critical-value line through raster corners (as the gated chain's ``D = L2 - 0.5`` runs
    through the corners of a 16 x 16 raster of ``[1, 3] x [1, 3.5]``) and one ending on a
    corner of the box's edge: moved by 1e-9 (far below ``CELL_EDGE_TOL`` cells) the same cells
    are blocked, and where a point of the curve is a corner every cell at the corner is."""
    box = np.array([[1.0, 3.0], [1.0, 3.5]])
    n = 16
    line = np.array([[1.5, 1.0], [2.125, 1.625], [3.0, 2.5]]) + shift
    ends = np.array([[1.0, 2.5], [2.5, 1.0]]) + shift
    blocked = _blocked_cells([line, ends], box, n)
    assert np.array_equal(blocked, _blocked_cells([line - shift, ends - shift], box, n))
    i, j = np.rint((np.array([2.125, 1.625]) - box[:, 0]) / (box[:, 1] - box[:, 0]) * n
                   ).astype(int)  # a traced point of the line on a corner: its four cells
    assert (i, j) == (9, 4) and blocked[i - 1:i + 1, j - 1:j + 1].all()
    assert blocked[11, 0] and blocked[12, 0]  # the end on the box's edge, between two cells
