"""The tracer's fast linear algebra against the direct methods it replaces.

* ``[row; J]`` from the structure computed once equals the matrix assembled from scratch;
* the band LU and the SuperLU of ``[e_k; J]`` with the rank-one update give the determinant
  (sign and log) and the solves of ``[row; J]`` as a dense LU does;
* whole curves traced with the fast factorisations equal curves traced with the direct sparse LU
  of ``[t_prev; J]`` (the method before), and explorations give the same components and windings;
* seeds generated on demand give the same explorations as seeds generated up front.
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

import engine.space.configuration_space.explorer as cs  # where the seeds are drawn
import engine.space.trace as tr
from engine.catalogue.presets import build_preset
from engine.local.rigidity import first_order
from engine.model.constraints import Constraints
from engine.model.lu import Factor
from engine.model.tolerances import Tolerances
from engine.space import trace_kernel
from engine.space.assembly import iter_seeds, seeds
from engine.space.configuration_space import SpaceOptions, explore, rotor_angles, winding
from engine.space.trace import TraceOptions, factor_augmented, polyline_distance, segment_distance

TOL = Tolerances()
CATALOGUE = [
    ("kl-chain", {"n": 30}),
    ("kl-chain", {"n": 40, "r": 2.0, "l": 2.2}),
    ("gated-kl-chain", {"n": 30, "gate": 15, "D": 2.3}),
    ("gated-kl-chain", {"n": 30, "gate": 15, "D": 2.7}),
]


def direct_factor(cons: Constraints, u: np.ndarray, row: np.ndarray) -> Factor:
    """The method before: sparse LU of ``[row; J]`` assembled with ``vstack`` (COLAMD)."""
    if cons.n_free <= tr.SPARSE_LU_MIN_FREE:
        return Factor(np.vstack([row, cons.jacobian(u, sparse=False)]))
    jac = cons.jacobian(u, sparse=True)
    return Factor(sp.vstack([sp.csr_matrix(row.reshape(1, -1)), jac]).tocsc())


@pytest.mark.parametrize(("name", "params"), CATALOGUE)
def test_structures_match_assembly_from_scratch(name: str, params: dict) -> None:
    lk = build_preset(name, params)
    cons = Constraints(lk)
    rng = np.random.default_rng(1)
    u = lk.coordinates() + 0.1 * rng.normal(size=cons.n_free)
    pos = lk.positions_of(u)
    assert np.array_equal(cons.bar_vectors(u), pos[cons._i] - pos[cons._j])
    dense = cons.jacobian(u, sparse=False)
    assert np.array_equal(cons.jacobian(u, sparse=True).toarray(), dense)
    row = rng.normal(size=cons.n_free)
    assert np.array_equal(cons.bordered_jacobian(u, row, sparse=True).toarray(),
                          np.vstack([row, dense]))
    k = int(np.argmax(np.abs(row)))
    unit = np.zeros(cons.n_free)
    unit[k] = 1.0
    assert np.array_equal(cons.unit_bordered_jacobian(u, k).toarray(), np.vstack([unit, dense]))


@pytest.mark.parametrize("band", [True, False], ids=["band LU", "SuperLU"])
@pytest.mark.parametrize(("name", "params"), CATALOGUE)
def test_factor_matches_dense_lu(name: str, params: dict, band: bool,
                                 monkeypatch: pytest.MonkeyPatch) -> None:
    if not band:
        monkeypatch.setattr(tr, "BAND_MAX_WORK", -1)
    lk = build_preset(name, params)
    cons = Constraints(lk)
    rng = np.random.default_rng(2)
    u = lk.coordinates()
    z = first_order(lk).zero_modes[0]
    for trial in range(12):
        # near the tangent (as in tracing) and far from it (a generic row)
        row = z + 0.3 * rng.normal(size=cons.n_free) if trial % 2 else rng.normal(size=cons.n_free)
        row /= np.linalg.norm(row)
        fac = factor_augmented(cons, u, row)
        mat = np.vstack([row, cons.jacobian(u, sparse=False)])
        sign, logdet = np.linalg.slogdet(mat)
        assert fac.ok and fac.sign == int(sign)
        assert fac.logdet == pytest.approx(logdet, abs=1e-8)
        rhs = rng.normal(size=cons.n_free)
        x = fac.solve(rhs)
        assert np.linalg.norm(mat @ x - rhs) <= 1e-9 * np.linalg.norm(rhs)


def test_band_path_is_taken_on_chains() -> None:
    lk = build_preset("kl-chain", {"n": 30})
    cons = Constraints(lk)
    band = cons.unit_bordered_band(lk.coordinates(), 5, tr.BAND_MAX_WORK)
    assert band is not None and band[1] + band[2] <= 8


@pytest.mark.parametrize(("name", "params"), CATALOGUE)
def test_curve_matches_direct_lu(name: str, params: dict, monkeypatch: pytest.MonkeyPatch) -> None:
    lk = build_preset(name, params)
    cons = Constraints(lk)
    z = first_order(lk).zero_modes[0]
    fast = tr.trace_curve(cons, lk.coordinates(), z, TOL, TraceOptions())
    monkeypatch.setattr(tr, "factor_augmented", direct_factor)
    # the Python loop, where every factorisation goes through factor_augmented (the compiled
    # path has its own, checked in test_trace_kernel.py)
    monkeypatch.setenv(trace_kernel.KERNEL_ENV, "numpy")
    slow = tr.trace_curve(cons, lk.coordinates(), z, TOL, TraceOptions())
    assert fast.stop == slow.stop
    assert len(fast.points) == len(slow.points)
    assert np.max(np.abs(np.array(fast.points) - np.array(slow.points))) <= 1e-8
    assert fast.signs == slow.signs
    assert np.allclose(fast.logdets, slow.logdets, atol=1e-6)


def _summary(lk, res) -> list[tuple]:  # noqa: ANN001
    out = []
    for comp in res.components:
        turns = {k: winding(a, comp.closed) for k, a in rotor_angles(lk, comp.points).items()}
        out.append((comp.closed, comp.through_start, len(comp.points),
                    tuple(sorted(turns.items()))))
    return out


@pytest.mark.parametrize(("name", "params"), CATALOGUE)
@pytest.mark.slow
def test_exploration_matches_direct_lu_and_upfront_seeds(
    name: str, params: dict, monkeypatch: pytest.MonkeyPatch
) -> None:
    lk = build_preset(name, params)
    opts = SpaceOptions(angles=12, random_starts=2, max_components=3)
    fast = explore(lk, options=opts)
    monkeypatch.setattr(tr, "factor_augmented", direct_factor)

    def upfront(*args, **kwargs):  # noqa: ANN002, ANN003, ANN202
        return iter(list(iter_seeds(*args, **kwargs)))

    monkeypatch.setattr(cs, "iter_seeds", upfront)
    slow = explore(lk, options=opts)
    assert _summary(lk, fast) == _summary(lk, slow)
    assert len(fast.critical_points) == len(slow.critical_points)


def test_iter_seeds_equals_seeds() -> None:
    lk = build_preset("three-rotor")
    report: dict[str, object] = {}
    lazy = list(iter_seeds(lk, TOL, report, 24, 16, 4, 0, 4))
    eager = seeds(lk, TOL, 24, 16, 4, 0, 4)
    assert len(lazy) == len(eager.points)
    assert all(np.array_equal(a, b) for a, b in zip(lazy, eager.points, strict=True))
    assert report == eager.report


def test_polyline_distance_matches_segments() -> None:
    rng = np.random.default_rng(3)
    for n in (1, 2, 5, 30):
        pts = rng.normal(size=(n, 6))
        if n > 2:
            pts[2] = pts[1]  # a zero-length segment
        target = rng.normal(size=6)
        ref = min((segment_distance(pts[i], pts[i + 1], target) for i in range(n - 1)),
                  default=float(np.linalg.norm(pts[0] - target)))
        assert polyline_distance(pts, target) == pytest.approx(ref, abs=1e-12)
