"""How a branch point splits under a length change (paper, Appendix A), and a re-tracing check.

With the main text's ``Q`` (no factor 1/2) and ``delta u = Z^T c + w``, contracting the expanded
constraints with the self-stress gives the conic::

    (c - dc)^T Q (c - dc) = Delta,
    Delta = 2 sigma.(2 L dL + dL^2) - w^T H_sigma w + dc^T Q dc,   dc = -Q^{-1} Z H_sigma w,

where ``w = J^+ (2 L dL + dL^2)`` is the first-order move off the zero modes. To first order
``Delta = 4 sum_a sigma_a L_a dL_a``. With ``Q = diag(lam_1 > 0 > lam_2)`` on the zero modes,
``Delta > 0`` joins the two rays with ``c_1 > 0`` (and the two with ``c_1 < 0``), ``Delta < 0``
the two with ``c_2 > 0`` (and the two with ``c_2 < 0``). Rays are numbered as in the
second-order tangents: ``+t0, -t0, +t1, -t1`` = 0..3.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from engine.local.critical import CriticalPoint
from engine.model.constraints import Constraints
from engine.model.errors import InvalidRequest
from engine.model.linkage import Linkage, changeable_bar
from engine.model.tolerances import Tolerances
from engine.space.trace import TraceOptions, correct, trace_curve


@dataclass(frozen=True)
class Split:
    """Prediction for one critical point.

    ``shift`` is ``dc`` on the zero modes, ``shift_vector`` the same as a move of the free
    coordinates (M,); ``connects`` lists the joined ray pairs (empty when ``sign`` is 0 or the
    point is not a branch point).
    """

    index: int
    delta: float
    delta_linear: float
    shift: np.ndarray
    shift_vector: np.ndarray
    sign: int
    connects: list[tuple[int, int]]


def ray_coefficients(cp: CriticalPoint) -> np.ndarray:
    """Coefficients (4, k) of the rays ``+t0, -t0, +t1, -t1`` on the zero modes."""
    c = cp.analysis.tangent_coefficients
    return np.array([c[0], -c[0], c[1], -c[1]])


def pairing(coeffs: np.ndarray, sign: int) -> list[tuple[int, int]]:
    """Ray pairs joined for the sign of ``Delta`` (see the module docstring)."""
    if sign == 0:
        return []
    axis = 0 if sign > 0 else 1
    side = coeffs[:, axis] > 0
    a = tuple(int(r) for r in np.flatnonzero(side))
    b = tuple(int(r) for r in np.flatnonzero(~side))
    if len(a) != 2 or len(b) != 2:
        return []
    return sorted([(a[0], a[1]), (b[0], b[1])])


def length_change(linkage: Linkage, perturbation: dict[str, float]) -> np.ndarray:
    """Per-bar ``dL`` (E,) from ``{bar_id: dL}``; bars between two pins cannot change."""
    d_l = np.zeros(linkage.n_bars)
    for bar, value in perturbation.items():
        k = changeable_bar(linkage, bar, ("perturbation", bar))
        if not np.isfinite(value):
            raise InvalidRequest("must be finite", loc=("perturbation", bar))
        if linkage.lengths[k] + value <= 0:
            raise InvalidRequest("would make the length non-positive", loc=("perturbation", bar))
        d_l[k] = value
    return d_l


def linear_delta_gradient(linkage: Linkage, cp: CriticalPoint) -> np.ndarray:
    """``d Delta / d(dL)`` at ``dL = 0``: ``4 sigma_a L_a`` per bar (E,)."""
    sigma = cp.analysis.self_stress
    if sigma is None:
        return np.zeros(linkage.n_bars)
    return 4.0 * sigma * linkage.lengths


def split(linkage: Linkage, index: int, cp: CriticalPoint, d_l: np.ndarray) -> Split:
    """Appendix A prediction at critical point ``cp`` (of ``linkage``) for ``dL`` (E,)."""
    res = cp.analysis
    m = linkage.n_free
    if res.self_stress is None or res.q is None or res.kind not in ("branch", "rigid"):
        return Split(index, 0.0, 0.0, np.zeros(0), np.zeros(m), 0, [])
    cons = Constraints(linkage)
    act = cons.bars
    sigma = res.self_stress[act]
    lengths = linkage.lengths[act]
    rhs = 2 * lengths * d_l[act] + d_l[act] ** 2
    jac = cons.jacobian(cp.u, sparse=False)
    w = np.linalg.lstsq(jac, rhs, rcond=1e-10)[0]
    hess = cons.stress_hessian(sigma, sparse=False)
    z = res.zero_modes
    lam = res.q_eigenvalues
    b = z @ (hess @ w)
    dc = -b / lam
    delta = float(2 * sigma @ rhs - w @ hess @ w + dc @ (lam * dc))
    delta_linear = float(4 * sigma @ (lengths * d_l[act]))
    sign = int(np.sign(delta))
    connects = pairing(ray_coefficients(cp), sign) if res.kind == "branch" else []
    return Split(index, delta, delta_linear, dc, dc @ z, sign, connects)


def retraced_pairing(
    perturbed: Linkage,
    cp: CriticalPoint,
    radius: float,
    tol: Tolerances,
    options: TraceOptions | None = None,
) -> list[tuple[int, int]] | None:
    """Which rays of branch point ``cp`` the *perturbed* configuration space joins, by tracing.

    From each ray at distance ``radius`` from the old branch point, project onto the perturbed
    constraints (hyperplane orthogonal to the ray), trace towards the old branch point, and read
    off the ray along which the curve leaves the ball of that radius again. Independent of the
    Appendix A formula. None when a trace does not come back out.
    """
    cons = Constraints(perturbed)
    opts = options or TraceOptions(step_max=radius / 8)
    all_rays = np.array([cp.analysis.tangents[0], -cp.analysis.tangents[0],
                         cp.analysis.tangents[1], -cp.analysis.tangents[1]])
    pairs: set[tuple[int, int]] = set()
    for r, ray in enumerate(all_rays):
        v = cp.u + radius * ray
        w, ok, _ = correct(cons, v, ray, tol)
        if not ok:
            return None
        state = {"inside": False}

        def stop(a: np.ndarray, b: np.ndarray, t: np.ndarray, _s: dict = state) -> str | None:
            d = np.linalg.norm(b - cp.u)
            if d < 0.8 * radius:
                _s["inside"] = True
            if _s["inside"] and d > radius:
                return "out"
            return None

        curve = trace_curve(cons, w, -ray, tol, opts, stop=stop, close=False)
        if curve.stop != "out":
            return None
        d = curve.points[-1] - cp.u
        out_ray = int(np.argmax(all_rays @ (d / np.linalg.norm(d))))
        pairs.add(tuple(sorted((r, out_ray))))  # type: ignore[arg-type]
    result = sorted(pairs)
    if len(result) != 2 or {x for p in result for x in p} != {0, 1, 2, 3}:
        return None
    return result
