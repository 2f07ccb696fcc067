"""The tracer's compiled path (:mod:`engine.space.trace_kernel`, numba) against the Python loop it
replaces (``LINKAGE_TRACER_KERNEL=numpy``), on catalogue and random linkages:

* the compiled LU of ``[row; J]`` (dense, and band with the rank-one update) gives the sign,
  ``log|det|`` and solves of a dense LU;
* whole curves: the same points (to rounding), signs and ``log|det|``, the same stop reason,
  every point on the constraints;
* whole explorations with ``closed_form=False``: the same components (points, closure,
  windings), the same critical points and segments (the Python loop's crossings, the stop
  callbacks of the segments);
* the band kernels specialised for a chain's band (``kl = ku = 2``) give bit for bit what the
  kernels for any band give, and chains on that path (Kane-Lubensky chains up to n = 400) and
  off it (a gated chain's wider band, the dense LU) trace as the Python loop does;
* the hand-backs: deadlines (an expired one, a stop flag that flips during a trace), a band too
  wide for the band LU (every pass then runs in Python), the point budget.

No timing here: speed lives in ``bench/bench_tracer.py``.
"""

from __future__ import annotations

import importlib.util
import itertools
import sys
import threading

import numpy as np
import pytest

import engine.space.trace as tr
from engine.catalogue.presets import build_preset
from engine.local.rigidity import first_order
from engine.model.budget import Deadline
from engine.model.constraints import Constraints
from engine.model.tolerances import Tolerances
from engine.space import trace_kernel
from engine.space.configuration_space import SpaceOptions, explore, rotor_angles, winding
from engine.space.trace import TraceOptions, trace_curve

TOL = Tolerances()

pytestmark = pytest.mark.skipif(importlib.util.find_spec("numba") is None,
                                reason="numba is not installed")

CATALOGUE = [
    ("four-bar", {}),  # equilateral: three branch points
    ("four-bar", {"L1": 0.5, "L2": 1.2, "L3": 1.0}),  # crank-rocker
    ("four-bar", {"L1": 1.0, "L2": 1.0, "L3": 1.0 + 1e-4}),  # a near miss
    ("three-rotor", {}),
    ("kl-chain", {"n": 10}),
    ("kl-chain", {"n": 30, "r": 2.0, "l": 2.2}),
    ("gated-kl-chain", {"n": 30, "gate": 15, "D": 2.3}),
    ("rotor-chain-3d", {}),
]


def random_four_bars(count: int, seed: int) -> list[dict[str, float]]:
    """Seeded length sets (a = 1) that assemble, near critical values or not."""
    rng = np.random.default_rng(seed)
    out: list[dict[str, float]] = []
    while len(out) < count:
        l1, l2, l3 = (float(x) for x in rng.uniform(0.3, 2.2, 3))
        links = sorted([1.0, l1, l2, l3])
        if links[3] < links[0] + links[1] + links[2]:
            out.append({"L1": l1, "L2": l2, "L3": l3})
    return out


def random_chains(count: int, seed: int) -> list[tuple[str, dict[str, float]]]:
    """Seeded Kane-Lubensky chains (rotor and link lengths, angle), plain and gated."""
    rng = np.random.default_rng(seed)
    out: list[tuple[str, dict[str, float]]] = []
    for k in range(count):
        n = int(rng.integers(3, 40))
        r = float(rng.uniform(1.2, 2.0))
        params = {"n": n, "r": r, "l": float(r * rng.uniform(1.0, 1.3)),
                  "theta": float(rng.uniform(1.0, 1.5))}
        out.append(("kl-chain", params) if k % 2 == 0 else
                   ("gated-kl-chain", {**params, "gate": int(rng.integers(0, n)),
                                       "D": float(rng.uniform(2.0, 3.0))}))
    return out


def cases(items: list[tuple[str, dict]]) -> list:  # type: ignore[type-arg]
    """``(name, params)`` pairs as parameters with readable ids."""
    return [pytest.param(n, p, id=n + "".join(f"-{k}{v:.3g}" for k, v in p.items()))
            for n, p in items]


def _trace(name: str, params: dict, path: str, monkeypatch: pytest.MonkeyPatch,
           options: TraceOptions | None = None, **kw: object) -> tuple[Constraints, tr.Curve]:
    monkeypatch.setenv(trace_kernel.KERNEL_ENV, path)
    if path == "numba":  # compiled before the comparison, or it would compare the loop with itself
        assert trace_kernel.load() and trace_kernel.enabled()
    lk = build_preset(name, params)
    cons = Constraints(lk)
    z = first_order(lk).zero_modes[0]
    return cons, trace_curve(cons, lk.coordinates(), z, TOL, options or TraceOptions(),
                             **kw)  # type: ignore[arg-type]


def assert_same_curve(fast: tr.Curve, slow: tr.Curve, cons: Constraints) -> None:
    assert fast.stop == slow.stop
    assert len(fast.points) == len(slow.points)
    assert np.max(np.abs(np.array(fast.points) - np.array(slow.points))) <= 1e-8
    assert np.max(np.abs(np.array(fast.tangents) - np.array(slow.tangents))) <= 1e-7
    assert fast.signs == slow.signs
    assert np.allclose(fast.logdets, slow.logdets, atol=1e-7)
    # every point on the constraint manifold (crossed critical points included)
    assert max(cons.max_residual(p) for p in fast.points) <= TOL.residual_atol


def test_environment_chooses_the_path(monkeypatch: pytest.MonkeyPatch) -> None:
    """``numpy`` always the Python loop; otherwise the kernel, once loaded."""
    monkeypatch.setenv(trace_kernel.KERNEL_ENV, "numpy")
    assert not trace_kernel.enabled()
    monkeypatch.setenv(trace_kernel.KERNEL_ENV, "numba")
    assert trace_kernel.load() and trace_kernel.enabled()


@pytest.mark.parametrize(("name", "params", "dense"), [
    ("four-bar", {}, True), ("three-rotor", {}, True), ("rotor-chain-3d", {}, True),
    ("kl-chain", {"n": 10}, True),  # the dense LU also where the tracer takes the band
    ("kl-chain", {"n": 30}, False), ("gated-kl-chain", {"n": 30, "gate": 15}, False),
])
def test_compiled_factor_matches_dense_lu(name: str, params: dict, dense: bool) -> None:
    from engine.space._trace_numba import _factor, _solve

    lk = build_preset(name, params)
    cons = Constraints(lk)
    d = trace_kernel.kernel_data(cons, dense)
    rng = np.random.default_rng(3)
    z = first_order(lk).zero_modes[0]
    vals = np.empty(len(d.rows))
    lay = np.full(4, -1, dtype=np.int64)
    lay_pos = np.empty(len(d.rows), dtype=np.int64)
    lay_rp = np.zeros(0, dtype=np.int64)
    for trial in range(12):
        u = lk.coordinates() + 0.05 * rng.normal(size=cons.n_free)
        row = z + 0.3 * rng.normal(size=cons.n_free) if trial % 2 else \
            rng.normal(size=cons.n_free)
        row /= np.linalg.norm(row)
        st, ab, piv, kl, ku, sign, logdet, rp, y0, dv, gam = _factor(
            u, row, dense, 10**6, d.fixed_values, d.gather_i, d.gather_j, d.rows, d.cols,
            d.sign, d.axes, d.entry_i, d.entry_j, d.col_pos, d.entry_rank, d.entry_col, d.keys,
            d.row_rank, d.sign_perm, vals, lay, lay_pos, lay_rp)
        lay_rp = rp
        mat = np.vstack([row, cons.jacobian(u, sparse=False)])
        ref_sign, ref_logdet = np.linalg.slogdet(mat)
        assert st == 0 and sign == int(ref_sign)
        assert logdet == pytest.approx(ref_logdet, abs=1e-8)
        rhs = rng.normal(size=cons.n_free)
        x = _solve(ab, piv, kl, ku, rp, d.col_pos, y0, dv, gam, dense, rhs)
        assert np.linalg.norm(mat @ x - rhs) <= 1e-9 * np.linalg.norm(rhs)


def _random_band(rng: np.random.Generator, n: int, kl: int, ku: int,
                 zeros: float) -> np.ndarray:
    """An unfactored band matrix in LAPACK storage (``kl`` rows of room for the fill), some
    entries exact zeros (skipped updates) and pivots in every position."""
    ab = np.zeros((2 * kl + ku + 1, n))
    for j in range(n):
        for i in range(max(0, j - ku), min(n, j + kl + 1)):
            if rng.random() >= zeros:
                ab[kl + ku + i - j, j] = rng.normal() * (1e3 if rng.random() < 0.1 else 1.0)
    return ab


@pytest.mark.parametrize("zeros", [0.0, 0.3])
def test_chain_band_kernels_match_any_band_bit_for_bit(zeros: float) -> None:
    """``kl = ku = 2`` (a chain's band): the unrolled LU and the solve with its window in
    registers against the loops for any band, for every size around the edge cases."""
    from engine.space._trace_numba import (
        _band_lu,
        _band_lu_from,
        _band_solve,
        _band_solve_any,
        _diagonal,
    )

    rng = np.random.default_rng(int(100 * zeros) + 7)
    for n in list(range(1, 24)) + [57, 200]:
        for _ in range(3):
            ab = _random_band(rng, n, 2, 2, zeros)
            fast, slow = ab.copy(), ab.copy()
            piv_f, piv_s = np.empty(n, dtype=np.int64), np.empty(n, dtype=np.int64)
            ok_f = _band_lu(fast, n, 2, 2, piv_f)
            ok_s = _band_lu_from(slow, n, 2, 2, piv_s, 0)
            assert ok_f == ok_s
            if not ok_s:
                continue
            assert np.array_equal(piv_f, piv_s) and np.array_equal(fast, slow)
            assert _diagonal(fast, 4, piv_f, n) == _diagonal(slow, 4, piv_s, n)
            b = rng.normal(size=n)
            b[rng.random(n) < zeros] = 0.0
            x_f, x_s = b.copy(), b.copy()
            _band_solve(fast, n, 2, 2, piv_f, x_f)
            _band_solve_any(slow, n, 2, 2, piv_s, x_s)
            assert np.array_equal(x_f, x_s)
            if n <= 40:  # and the solve is a solve: against the dense matrix
                dense = np.zeros((n, n))
                for j in range(n):
                    for i in range(max(0, j - 2), min(n, j + 3)):
                        dense[i, j] = ab[4 + i - j, j]
                if np.linalg.cond(dense) < 1e8:
                    assert np.allclose(dense @ x_f, b, atol=1e-8 * (1 + np.abs(b).max()))


def test_a_zero_pivot_in_the_chain_band() -> None:
    """An exactly singular chain band: the unrolled LU stops at the zero pivot as the loop
    for any band does."""
    from engine.space._trace_numba import _band_lu, _band_lu_from

    for col in (0, 11, 25, 29):  # in the unrolled columns and in the tail
        ab = _random_band(np.random.default_rng(col), 30, 2, 2, 0.0)
        ab[:, col] = 0.0  # an empty column: its pivot is an exact zero
        a1, a2 = ab.copy(), ab.copy()
        p1, p2 = np.empty(30, dtype=np.int64), np.empty(30, dtype=np.int64)
        assert not _band_lu(a1, 30, 2, 2, p1)
        assert not _band_lu_from(a2, 30, 2, 2, p2, 0)
        assert np.array_equal(p1[:col + 1], p2[:col + 1])
        assert np.array_equal(a1[:, :col], a2[:, :col])


def test_kernel_reductions_match_their_loops() -> None:
    """The corrector's and the step control's reductions without a branch per entry or with
    partial sums against the plain expressions they replace (NaN and infinite entries
    included: a NaN residual is within no tolerance, a NaN strain strains)."""
    from engine.space._trace_numba import (
        _dist2,
        _dot,
        _dot_gather,
        _gap,
        _segment_distance,
        _strained,
        _within,
    )

    rng = np.random.default_rng(5)
    for n in list(range(0, 12)) + [99, 800]:
        for trial in range(6):
            lengths = rng.uniform(0.5, 2.0, n)
            sq = lengths ** 2 + rng.normal(size=n) * 10.0 ** rng.uniform(-16, -8, n)
            if trial == 1 and n:
                sq[rng.integers(n)] = np.nan
            if trial == 2 and n:
                sq[rng.integers(n)] = np.inf
            if trial == 3:
                sq = lengths ** 2  # exactly on: every tolerance met
            with np.errstate(invalid="ignore"):
                r = np.abs(np.sqrt(sq) - lengths)
            res = np.inf if np.isnan(r).any() else float(np.max(r, initial=0.0))
            for atol, tight in ((1e-9, 1e-12), (1e-12, 1e-15), (1e-6, 1e-6)):
                assert _within(sq, lengths, atol, tight) == (res <= atol, res <= tight)
            strain = np.inf if np.isnan(r).any() else float(np.max(r / lengths, initial=0.0))
            for tol in (1e-12, 1e-9, 1e-2):
                assert _strained(sq, lengths, tol) == (strain > tol)
            targets = lengths ** 2
            pos = rng.permutation(n + 1)[:n]
            rhs = np.full(n + 1, 7.0)
            norm2 = _gap(sq, targets, pos, rhs)
            g = sq - targets
            with np.errstate(invalid="ignore"):
                assert np.array_equal(rhs[pos], -g, equal_nan=True)
                ref = float(np.sum(g * g))
            assert norm2 == pytest.approx(ref, rel=1e-13, nan_ok=True)
            a, b, c = rng.normal(size=(3, n))
            perm = rng.permutation(n)
            assert _dot(a, b) == pytest.approx(float(a @ b), rel=1e-12, abs=1e-12)
            assert _dot_gather(a, b, perm) == pytest.approx(float(a @ b[perm]), rel=1e-12,
                                                           abs=1e-12)
            assert _dist2(a, b) == pytest.approx(float((a - b) @ (a - b)), rel=1e-13)
            if n:
                ref_d = tr.segment_distance(a, b, c)
                assert _segment_distance(a, b, c) == pytest.approx(ref_d, rel=1e-12, abs=1e-14)
                assert _segment_distance(a, a, c) == pytest.approx(
                    float(np.linalg.norm(a - c)), rel=1e-12)


@pytest.mark.parametrize(("name", "params"), [
    ("kl-chain", {"n": 30}), ("kl-chain", {"n": 130, "r": 1.6, "l": 1.9}),
    ("gated-kl-chain", {"n": 30, "gate": 15, "D": 2.3}),
])
def test_band_values_are_the_bordered_band(name: str, params: dict) -> None:
    """The kernel's ``[e_k; J]`` in band storage (the Jacobian's values written through flat
    indices straight from ``u`` and the fixed coordinates) is what
    ``Constraints.unit_bordered_band`` builds, for every ``k``."""
    from engine.space._trace_numba import _band_values, _factor

    lk = build_preset(name, params)
    cons = Constraints(lk)
    d = trace_kernel.kernel_data(cons, False)
    rng = np.random.default_rng(11)
    lay = np.full(4, -1, dtype=np.int64)
    lay_pos = np.empty(len(d.rows), dtype=np.int64)
    for k in list(rng.choice(cons.n_free, 6, replace=False)) + [0, cons.n_free - 1]:
        u = lk.coordinates() + 0.05 * rng.normal(size=cons.n_free)
        row = 0.01 * rng.normal(size=cons.n_free)
        row[k] = 1.0  # the largest entry: the unit row is e_k
        out = _factor(u, row, False, 10**6, d.fixed_values, d.gather_i, d.gather_j, d.rows,
                      d.cols, d.sign, d.axes, d.entry_i, d.entry_j, d.col_pos, d.entry_rank,
                      d.entry_col, d.keys, d.row_rank, d.sign_perm, np.empty(len(d.rows)), lay,
                      lay_pos, np.zeros(0, dtype=np.int64))
        assert lay[0] == k
        band = cons.unit_bordered_band(u, int(k), 10**6)
        assert band is not None
        ref, kl, ku = band[0], band[1], band[2]
        assert (out[3], out[4]) == (kl, ku)
        mine = np.zeros_like(ref)
        _band_values(mine.reshape(-1), np.concatenate([u, d.fixed_values]), d.entry_i,
                     d.entry_j, d.sign, lay_pos)
        ck = d.col_pos[k]
        mine[kl + ku + lay[3] - ck, ck] = 1.0
        assert np.array_equal(mine, ref)


@pytest.mark.parametrize(("name", "params", "band"), [
    ("kl-chain", {"n": 20}, (2, 2)), ("kl-chain", {"n": 60}, (2, 2)),
    ("kl-chain", {"n": 130, "r": 1.6, "l": 1.9}, (2, 2)),
    ("kl-chain", {"n": 400}, (2, 2)),  # the bench's chain
    ("gated-kl-chain", {"n": 30, "gate": 0}, (2, 2)),
    ("gated-kl-chain", {"n": 30, "gate": 15, "D": 2.3}, (3, 2)),  # off the chain's kernels
])
def test_chain_band_curves_match_python_loop(name: str, params: dict, band: tuple,
                                             monkeypatch: pytest.MonkeyPatch) -> None:
    """Chains of several sizes on the band path: the band they take (so the specialised
    kernels run, or not), and the same curve as the Python loop."""
    from engine.space._trace_numba import _factor

    lk = build_preset(name, params)
    cons = Constraints(lk)
    d = trace_kernel.kernel_data(cons, False)
    z = first_order(lk).zero_modes[0]
    out = _factor(lk.coordinates(), z / np.linalg.norm(z), False, 10**6, d.fixed_values,
                  d.gather_i, d.gather_j, d.rows, d.cols, d.sign, d.axes, d.entry_i,
                  d.entry_j, d.col_pos, d.entry_rank, d.entry_col, d.keys, d.row_rank,
                  d.sign_perm,
                  np.empty(len(d.rows)), np.full(4, -1, dtype=np.int64),
                  np.empty(len(d.rows), dtype=np.int64), np.zeros(0, dtype=np.int64))
    assert out[0] == 0 and (out[3], out[4]) == band
    cons, fast = _trace(name, params, "numba", monkeypatch)
    _, slow = _trace(name, params, "numpy", monkeypatch)
    assert fast.stop == "closed"
    assert_same_curve(fast, slow, cons)


@pytest.mark.parametrize(("name", "params"), cases(
    CATALOGUE + random_chains(6, seed=15) + [("four-bar", p) for p in random_four_bars(6, 15)]))
def test_curve_matches_python_loop(name: str, params: dict,
                                   monkeypatch: pytest.MonkeyPatch) -> None:
    cons, fast = _trace(name, params, "numba", monkeypatch)
    _, slow = _trace(name, params, "numpy", monkeypatch)
    assert_same_curve(fast, slow, cons)


def test_curve_with_small_steps_and_stop_matches(monkeypatch: pytest.MonkeyPatch) -> None:
    """Many points per call and a stop callback checked on every committed point.

    (``step_max`` 1.25e-3: the cubic predictor lets the steps reach ``step_max``, where the
    tangent's chord corrector held them at about 0.63 of it; at 2e-3 this curve now has
    2,154 points instead of 3,441.)"""
    def stop(a: np.ndarray, b: np.ndarray, t: np.ndarray) -> str | None:
        return "far" if b[0] < -0.3 else None

    opt = TraceOptions(step_max=1.25e-3)
    params = {"L1": 0.5, "L2": 1.2, "L3": 1.0}
    cons, fast = _trace("four-bar", params, "numba", monkeypatch, opt, stop=stop)
    _, slow = _trace("four-bar", params, "numpy", monkeypatch, opt, stop=stop)
    assert fast.stop == "far"
    assert_same_curve(fast, slow, cons)
    cons, fast = _trace("four-bar", params, "numba", monkeypatch, opt)
    _, slow = _trace("four-bar", params, "numpy", monkeypatch, opt)
    assert fast.stop == "closed" and len(fast.points) > 3000
    assert_same_curve(fast, slow, cons)


def _count_kernel_calls(monkeypatch: pytest.MonkeyPatch) -> list[int]:
    """The points each call of the compiled kernel hands back, appended as it is called."""
    calls: list[int] = []
    advance = trace_kernel.advance

    def counted(*a: object, **k: object) -> trace_kernel.Advance:
        out = advance(*a, **k)  # type: ignore[arg-type]
        calls.append(len(out.points))
        return out

    monkeypatch.setattr(trace_kernel, "advance", counted)
    return calls


def test_a_stop_check_is_handed_points_in_growing_chunks(monkeypatch: pytest.MonkeyPatch) -> None:
    """With a stop check the kernel hands back 32, 64, ... points: a curve stopped early is not
    traced on to the kernel's buffer first, and a check that never stops changes nothing."""
    calls = _count_kernel_calls(monkeypatch)
    opt = TraceOptions(step_max=2e-3)
    params = {"L1": 0.5, "L2": 1.2, "L3": 1.0}
    cons, free = _trace("four-bar", params, "numba", monkeypatch, opt)
    assert len(calls) == 1  # one call without a check
    calls.clear()
    _, checked = _trace("four-bar", params, "numba", monkeypatch, opt,
                        stop=lambda a, b, t: None)
    assert calls[:3] == [tr.STOP_CHUNK_MIN, 2 * tr.STOP_CHUNK_MIN, 4 * tr.STOP_CHUNK_MIN]
    assert max(calls) <= tr.STOP_CHUNK_MAX
    assert checked.stop == free.stop == "closed"
    assert_same_curve(checked, free, cons)
    calls.clear()
    _, early = _trace("four-bar", params, "numba", monkeypatch, opt,
                      stop=lambda a, b, t: "early" if len(calls) else None)
    # stopped at the first point handed back, after the kernel traced 32 points (not 2,154)
    assert early.stop == "early" and len(early.points) == 2 and calls == [tr.STOP_CHUNK_MIN]


@pytest.mark.parametrize("max_points", [1, 2, 57])
def test_point_budget_matches(max_points: int, monkeypatch: pytest.MonkeyPatch) -> None:
    opt = TraceOptions(max_points=max_points)
    cons, fast = _trace("kl-chain", {"n": 30}, "numba", monkeypatch, opt)
    _, slow = _trace("kl-chain", {"n": 30}, "numpy", monkeypatch, opt)
    assert fast.stop == "max points" and len(fast.points) == max_points
    assert_same_curve(fast, slow, cons)


def test_band_too_wide_runs_every_pass_in_python(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(tr, "BAND_MAX_WORK", -1)  # SuperLU for every factorisation
    calls = _count_kernel_calls(monkeypatch)
    cons, fast = _trace("kl-chain", {"n": 30}, "numba", monkeypatch)
    assert calls and not any(calls)  # the kernel committed nothing
    _, slow = _trace("kl-chain", {"n": 30}, "numpy", monkeypatch)
    assert_same_curve(fast, slow, cons)


def test_expired_deadline_stops_both_paths(monkeypatch: pytest.MonkeyPatch) -> None:
    for path in ("numba", "numpy"):
        _, curve = _trace("kl-chain", {"n": 30}, path, monkeypatch,
                          deadline=Deadline.after(0.0))
        assert curve.stop == tr.STOP_TIME and len(curve.points) < 20


def test_stop_flag_during_a_trace(monkeypatch: pytest.MonkeyPatch) -> None:
    """A cancel flag that flips after a number of deadline checks stops the compiled trace at
    the same pass as the Python loop: the kernel hands back every DEADLINE_EVERY passes."""
    curves = {}
    for path in ("numba", "numpy"):
        checks = itertools.count()
        deadline = Deadline(stop=lambda c=checks: next(c) >= 7)
        cons, curves[path] = _trace("kl-chain", {"n": 30}, path, monkeypatch,
                                    deadline=deadline)
    assert curves["numba"].stop == tr.STOP_TIME
    assert_same_curve(curves["numba"], curves["numpy"], cons)


def _summary(lk, res) -> tuple:  # noqa: ANN001
    comps = []
    for comp in res.components:
        turns = {k: winding(a, comp.closed) for k, a in rotor_angles(lk, comp.points).items()}
        comps.append((comp.closed, comp.through_start, len(comp.points),
                      tuple(sorted(turns.items())), tuple(comp.critical_points)))
    crit = sorted((cp.kind, tuple(np.round(cp.u, 6))) for cp in res.critical_points)
    segs = [(s.start, s.start_ray, s.end, s.end_ray, len(s.points)) for s in res.segments]
    return comps, crit, segs, res.search["complete"]


@pytest.mark.parametrize(("name", "params"), cases(
    [c for c in CATALOGUE if c[0] != "kl-chain" or c[1]["n"] <= 10]
    + [("four-bar", p) for p in random_four_bars(4, seed=16)]))
def test_exploration_matches_python_loop(name: str, params: dict,
                                         monkeypatch: pytest.MonkeyPatch) -> None:
    lk = build_preset(name, params)
    opt = SpaceOptions(closed_form=False, angles=24, random_starts=4, max_components=8)
    out = {}
    for path in ("numba", "numpy"):
        monkeypatch.setenv(trace_kernel.KERNEL_ENV, path)
        assert trace_kernel.enabled() == (path == "numba")
        res = explore(lk, options=opt)
        out[path] = (_summary(lk, res), res)
    assert out["numba"][0] == out["numpy"][0]
    fast, slow = out["numba"][1], out["numpy"][1]
    for a, b in zip(fast.components, slow.components, strict=True):
        assert np.max(np.abs(a.points - b.points)) <= 1e-8
    for a, b in zip(fast.critical_points, slow.critical_points, strict=True):
        assert np.max(np.abs(a.u - b.u)) <= 1e-8
    cons = Constraints(lk)
    for comp in fast.components:
        assert max(cons.max_residual(p) for p in comp.points) <= TOL.residual_atol


def test_without_numba_the_python_loop_traces(monkeypatch: pytest.MonkeyPatch) -> None:
    """numba missing (the import fails): the tracer is the Python loop, with the same curve."""
    cons, fast = _trace("kl-chain", {"n": 10}, "numba", monkeypatch)
    monkeypatch.setitem(sys.modules, "engine.space._trace_numba", None)  # import raises ImportError
    monkeypatch.setattr(trace_kernel, "_kernel", None)
    monkeypatch.setattr(trace_kernel, "_loader", None)
    assert not trace_kernel.load()
    assert not trace_kernel.enabled()
    _, slow = _trace("kl-chain", {"n": 10}, "numpy", monkeypatch)
    monkeypatch.setenv(trace_kernel.KERNEL_ENV, "numba")
    lk = build_preset("kl-chain", {"n": 10})
    z = first_order(lk).zero_modes[0]
    assert_same_curve(trace_curve(cons, lk.coordinates(), z, TOL, TraceOptions()), slow, cons)
    assert_same_curve(fast, slow, cons)


def test_a_forked_child_loads_again(monkeypatch: pytest.MonkeyPatch) -> None:
    """A child forked while the parent was still loading starts its own loader."""
    monkeypatch.setattr(trace_kernel, "_kernel", None)
    monkeypatch.setattr(trace_kernel, "_loader", threading.Thread(target=lambda: None))
    trace_kernel._after_fork()
    assert trace_kernel._loader is None
    assert trace_kernel.load()  # a fresh loader thread compiles (from numba's cache)


def test_a_kernel_that_fails_to_compile_leaves_the_python_loop_and_says_why(monkeypatch):
    """E.g. numba with no writable cache directory: the loader thread must not die with a
    traceback and leave nothing behind; the failure is kept and the Python loop traces."""
    from engine.space import trace_kernel

    def broken() -> None:
        raise RuntimeError("cannot cache function: no locator available")

    monkeypatch.setattr(trace_kernel, "_compile_kernel", broken)
    monkeypatch.setattr(trace_kernel, "failure", None)
    trace_kernel._compile()
    assert trace_kernel.failure == "RuntimeError: cannot cache function: no locator available"


def test_explorations_call_the_kernel_with_its_one_signature(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """Every array reaches the kernel contiguous, as in the signature that :func:`load`
    compiles: a strided ``u0`` (the start taken from a view of a seed stack) was a second
    signature, compiled or loaded from numba's cache during the first exploration."""
    monkeypatch.setenv(trace_kernel.KERNEL_ENV, "numba")
    assert trace_kernel.load()
    from engine.space._trace_numba import run

    opt = SpaceOptions(closed_form=False, angles=24, random_starts=4, max_components=8)
    for name, params in [("four-bar", {}), ("four-bar", {"L1": 0.5, "L2": 1.2, "L3": 1.0}),
                         ("three-rotor", {}), ("kl-chain", {"n": 10})]:
        explore(build_preset(name, params), options=opt)
    assert len(run.signatures) == 1


@pytest.mark.parametrize(("name", "params", "dense"), [
    ("four-bar", {}, True), ("three-rotor", {}, True), ("rotor-chain-3d", {}, True),
    ("kl-chain", {"n": 30}, False), ("gated-kl-chain", {"n": 30, "gate": 15}, False),
])
def test_factorisations_into_shared_work_arrays_are_those_with_their_own(
        name: str, params: dict, dense: bool) -> None:
    """The kernel's loop factorises into work arrays it keeps for the whole call
    (``_factor_into``): one after another into the same arrays, each factorisation is bit
    for bit the one made with arrays of its own (``_factor``), and solves alike."""
    from engine.space._trace_numba import _factor, _factor_into, _solve

    lk = build_preset(name, params)
    cons = Constraints(lk)
    d = trace_kernel.kernel_data(cons, dense)
    rng = np.random.default_rng(4)
    z = first_order(lk).zero_modes[0]
    common = (d.fixed_values, d.gather_i, d.gather_j, d.rows, d.cols, d.sign, d.axes,
              d.entry_i, d.entry_j, d.col_pos, d.entry_rank, d.entry_col, d.keys, d.row_rank,
              d.sign_perm)
    ext = np.empty(cons.n_free + len(d.fixed_values))
    ext[cons.n_free:] = d.fixed_values
    empty_i, empty_f = np.zeros(0, dtype=np.int64), np.zeros(0)
    lay_a, lay_b = np.full(4, -1, dtype=np.int64), np.full(4, -1, dtype=np.int64)
    pos_a, pos_b = (np.empty(len(d.rows), dtype=np.int64) for _ in range(2))
    rp_a = rp_b = np.zeros(0, dtype=np.int64)
    for _ in range(6):
        u = lk.coordinates() + 0.05 * rng.normal(size=cons.n_free)
        row = z + 0.3 * rng.normal(size=cons.n_free)
        row /= np.linalg.norm(row)
        own = _factor(u, row, dense, 10**6, *common, np.empty(len(d.rows)), lay_a, pos_a, rp_a)
        shared = _factor_into(u, row, dense, 10**6, *common, np.empty(len(d.rows)), lay_b,
                              pos_b, rp_b, ext, empty_i, empty_f)
        rp_a, rp_b = own[7], shared[7]
        for a, b in zip(own, shared, strict=True):
            np.testing.assert_array_equal(a, b)
        rhs = rng.normal(size=cons.n_free)
        np.testing.assert_array_equal(_solve(*own[1:5], own[7], d.col_pos, *own[8:], dense, rhs),
                                      _solve(*shared[1:5], shared[7], d.col_pos, *shared[8:],
                                             dense, rhs))
