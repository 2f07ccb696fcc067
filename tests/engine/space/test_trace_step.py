"""The tracer's step (:func:`engine.space.trace._attempt`) against the step it replaces:

* the predictor: without a previous point the tangent ``u + h t``; with one the cubic through
  both points and tangents, exact on a line, off a circle by O(h^4) (the tangent by O(h^2));
* the corrector: chord Newton only to ``residual_atol``, then Newton with the factorisation at
  the corrected point (the one the tangent needs) to ``CORRECT_TIGHT * residual_atol``; the
  point is within that, and it is the point the chord run to ``CORRECT_TIGHT`` (the corrector
  before) gives (across the curve within what their residuals amount to, along it within the
  polish's move times the turn of the tangent), with the same sign and nearly the same
  tangent, on catalogue and random linkages;
* every regular point of a traced curve is within ``CORRECT_TIGHT * residual_atol``, on both
  tracer paths (the compiled kernel and the Python loop are compared point for point in
  ``test_trace_kernel.py``).
"""

from __future__ import annotations

import numpy as np
import pytest

import engine.space.trace as tr
from engine.catalogue.presets import build_preset
from engine.local.rigidity import first_order
from engine.model.constraints import Constraints
from engine.model.tolerances import CORRECT_TIGHT, Tolerances
from engine.space import trace_kernel
from engine.space.configuration_space import SpaceOptions, explore
from engine.space.trace import TraceOptions, predict, trace_curve

TOL = Tolerances()
TIGHT = CORRECT_TIGHT * TOL.residual_atol


def _random_linkages(count: int, seed: int) -> list[tuple[str, dict[str, float]]]:
    """Seeded four-bars that assemble and Kane-Lubensky chains, plain and gated."""
    rng = np.random.default_rng(seed)
    out: list[tuple[str, dict[str, float]]] = []
    while len(out) < count:
        if len(out) % 2 == 0:
            l1, l2, l3 = (float(x) for x in rng.uniform(0.3, 2.2, 3))
            links = sorted([1.0, l1, l2, l3])
            if links[3] < links[0] + links[1] + links[2]:
                out.append(("four-bar", {"L1": l1, "L2": l2, "L3": l3}))
        else:
            n = int(rng.integers(3, 60))
            r = float(rng.uniform(1.2, 2.0))
            out.append(("kl-chain", {"n": n, "r": r, "l": float(r * rng.uniform(1.0, 1.3)),
                                     "theta": float(rng.uniform(1.0, 1.5))}))
    return out


LINKAGES = [
    ("four-bar", {}),  # equilateral: three branch points
    ("four-bar", {"L1": 0.5, "L2": 1.2, "L3": 1.0}),  # crank-rocker
    ("four-bar", {"L1": 1.0, "L2": 1.0, "L3": 1.0 + 1e-4}),  # a near miss
    ("three-rotor", {}),
    ("kl-chain", {"n": 50}),
    ("kl-chain", {"n": 400}),  # the bench's chain (band path)
    ("gated-kl-chain", {"n": 30, "gate": 15, "D": 2.3}),
    ("rotor-chain-3d", {}),
] + _random_linkages(6, seed=27)


def _ids(items: list[tuple[str, dict]]) -> list:  # type: ignore[type-arg]
    return [pytest.param(n, p, id=n + "".join(f"-{k}{v:.3g}" for k, v in p.items()))
            for n, p in items]


def _curve(name: str, params: dict, path: str,
           monkeypatch: pytest.MonkeyPatch) -> tuple[Constraints, tr.Curve]:
    monkeypatch.setenv(trace_kernel.KERNEL_ENV, path)
    if path == "numba" and not trace_kernel.load():
        pytest.skip("numba is not available")
    lk = build_preset(name, params)
    cons = Constraints(lk)
    z = first_order(lk).zero_modes[0]
    return cons, trace_curve(cons, lk.coordinates(), z, TOL, TraceOptions(max_points=3000))


def test_predict_without_a_previous_point_is_the_tangent() -> None:
    rng = np.random.default_rng(3)
    u, t = rng.normal(size=6), rng.normal(size=6)
    t /= np.linalg.norm(t)
    assert np.array_equal(predict(u, t, 0.3, None, t), u + 0.3 * t)
    assert np.array_equal(predict(u, t, 0.3, u.copy(), t), u + 0.3 * t)  # h0 = 0


def test_predict_is_exact_on_a_line_and_fourth_order_on_a_circle() -> None:
    rng = np.random.default_rng(5)
    a, d = rng.normal(size=4), rng.normal(size=4)
    d /= np.linalg.norm(d)
    # a line: the cubic is the line itself
    assert np.allclose(predict(a, d, 0.7, a - 0.4 * d, d), a + 0.7 * d, rtol=0, atol=1e-14)

    def circle(s: float) -> tuple[np.ndarray, np.ndarray]:
        return (np.array([np.cos(s), np.sin(s)]), np.array([-np.sin(s), np.cos(s)]))

    # off the (unit) circle, what the corrector removes: the cubic's distance falls as h^4,
    # the tangent's as h^2 (along the circle the cubic is off by O(h^3): it is parametrised
    # by the chord |u - u_prev|, not the arc, which moves the prediction along the curve)
    cubic, tangent = [], []
    for h in (0.1, 0.05, 0.025, 0.0125):
        p0, t0 = circle(-h)
        p1, t1 = circle(0.0)
        cubic.append(abs(float(np.linalg.norm(predict(p1, t1, h, p0, t0))) - 1.0))
        tangent.append(abs(float(np.linalg.norm(p1 + h * t1))) - 1.0)
    assert all(14 <= e / f <= 18 for e, f in zip(cubic, cubic[1:], strict=False))
    assert all(3.5 <= e / f <= 4.5 for e, f in zip(tangent, tangent[1:], strict=False))
    assert cubic[0] < 0.02 * tangent[0]


@pytest.mark.parametrize(("name", "params"), _ids(LINKAGES))
def test_polished_step_is_tight_and_the_chord_corrector_s_point(
        name: str, params: dict, monkeypatch: pytest.MonkeyPatch) -> None:
    """From the predictions along a traced curve: the chord to ``residual_atol`` and the polish
    with the factorisation at its point land within ``CORRECT_TIGHT * residual_atol``, where the
    chord run to that tolerance (the corrector before) lands (up to a slide along the curve of
    the polish's move times the angle between the two tangents), with the same tangent and
    sign."""
    cons, curve = _curve(name, params, "numpy", monkeypatch)
    pts, tans, logd = curve.array("points"), curve.array("tangents"), curve.array("logdets")
    regular = [k for k in range(1, len(pts) - 1)
               if np.all(np.isfinite(logd[k - 1:k + 2]))]  # no crossed critical point near
    assert len(regular) > 10
    checked = 0
    for k in regular[::max(1, len(regular) // 25)]:
        u_prev, t_in, u, t = pts[k - 1], tans[k - 1], pts[k], tans[k]
        fac = tr.factor_augmented(cons, u, t_in)
        h = float(np.linalg.norm(pts[k + 1] - u))
        v = predict(u, t, h, u_prev, t_in)
        before, ok_before, _ = tr.correct(cons, v, t, TOL, factor=fac)  # chord to tight
        w, ok, _ = tr.correct(cons, v, t, TOL, factor=fac, tight=False)
        if not (ok and ok_before):
            continue  # (the step would shrink: the chord from this far does not converge)
        assert cons.max_residual(w) <= TOL.residual_atol
        at_w = tr.tangent_at(cons, w, t)
        assert at_w is not None
        after, ok_after, _ = tr.correct(cons, w, t, TOL, factor=at_w.factor)
        assert ok_after and cons.max_residual(after) <= TIGHT
        # the same point of the curve, but for a slide along it: the chord's iterates stay in
        # the hyperplane orthogonal to t_in (the row of the factorisation at u), the polish's
        # in that orthogonal to t, so the two points differ along the curve by about the
        # polish's move times the angle between t and t_in, and across it by no more than
        # their residuals (within TIGHT) move them off it: their Newton corrections, which
        # near a branch point (small singular values) are larger than the residuals
        gap = after - before
        along = float(gap @ at_w.tangent)
        off = sum(float(np.linalg.norm(at_w.factor.solve(
            np.concatenate([[0.0], cons.targets - cons.squared_lengths(x)]))))
            for x in (before, after))
        assert np.linalg.norm(gap - along * at_w.tangent) <= 2 * off + 1e-13
        assert abs(along) <= 2 * np.linalg.norm(after - w) * np.linalg.norm(t - t_in) + 1e-12
        # the tangent information of the polished point is that of the factorisation at w:
        # the same sign, the tangent turned by a fraction (the polish's move over the step) of
        # the step's own turn, far below any test made on it (max_turn)
        at_after = tr.tangent_at(cons, after, t)
        assert at_after is not None and at_after.sign == at_w.sign
        moved = float(np.linalg.norm(after - w))
        turn = float(np.linalg.norm(at_w.tangent - t))
        assert np.linalg.norm(at_after.tangent - at_w.tangent) <= 50 * moved / h * turn + 1e-9
        assert abs(at_after.logdet - at_w.logdet) <= 1e-5
        checked += 1
    assert checked >= 5


@pytest.mark.parametrize("path", ["numba", "numpy"])
@pytest.mark.parametrize(("name", "params"), _ids(LINKAGES[:5] + LINKAGES[6:]))
def test_traced_points_are_within_the_tight_tolerance(
        name: str, params: dict, path: str, monkeypatch: pytest.MonkeyPatch) -> None:
    """Every point after the start that is not a crossed critical point (those are refined by
    their own search) is within ``CORRECT_TIGHT * residual_atol``: the accuracy the chord run
    to that tolerance gave (a point at ``residual_atol`` may sit ``residual_atol / s`` off the
    curve near critical lengths, see :data:`engine.model.tolerances.CORRECT_TIGHT`)."""
    cons, curve = _curve(name, params, path, monkeypatch)
    logd = curve.array("logdets")
    res = [cons.max_residual(p) for k, p in enumerate(curve.points)
           if k > 0 and np.isfinite(logd[k])]
    assert res and max(res) <= TIGHT


def test_after_a_failed_attempt_the_tangent_predicts(monkeypatch: pytest.MonkeyPatch) -> None:
    """The cubic predicts once from a point: every attempt after one that failed there is
    predicted by the tangent. Where the tangent turns within a step (near critical points)
    the cubic's curvature, taken from the last step, sent every halved step astray: the
    collinear three-rotor (curves of critical points) collapsed its steps at 33,275 points
    and looked for a critical point ahead of each (two minutes instead of two seconds)."""
    monkeypatch.setenv(trace_kernel.KERNEL_ENV, "numpy")  # every attempt in Python
    calls: list[tuple[np.ndarray, bool, object]] = []
    attempt = tr._attempt

    def recorded(cons, u, t, h, fac, sign, tol, options, lim, u_prev=None, t_prev=None):
        out = attempt(cons, u, t, h, fac, sign, tol, options, lim, u_prev, t_prev)
        calls.append((u, u_prev is not None, out))
        return out

    monkeypatch.setattr(tr, "_attempt", recorded)
    looked_ahead = []
    cross_ahead = tr._cross_ahead
    monkeypatch.setattr(tr, "_cross_ahead",
                        lambda *a, **k: looked_ahead.append(1) or cross_ahead(*a, **k))
    opt = SpaceOptions(angles=24, random_starts=4, trace=TraceOptions(max_points=1500))
    res = explore(build_preset("three-rotor", {"phi": 0.0}), TOL, opt)
    assert res.degenerate  # (as test_search.py's test of this linkage says)
    failed_then = [b for a, b in zip(calls, calls[1:], strict=False)
                   if a[2] == tr.SHRINK and b[0] is a[0]]
    assert failed_then and not any(cubic for _, cubic, _ in failed_then)
    assert any(cubic for _, cubic, _ in calls)  # (the cubic does predict elsewhere)
    # the steps no longer collapse point after point: a look ahead is rare
    points = sum(len(c.points) for c in res.components)
    assert len(looked_ahead) < 0.01 * points, (len(looked_ahead), points)
