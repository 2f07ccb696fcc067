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

A sign is only reported where it is resolved: every ``Delta`` carries ``delta_error``, the scale
of its own error (:func:`delta_error`: the self-stress known to its residual over the spectral gap
of ``J``, the critical point's length residual, the rounding of each term and the first term the
Appendix A model leaves out), and ``|Delta| <= delta_error`` is sign 0 (undecided) with no
pairing: a perturbation that leaves a branch point critical (a bar it does not stress, a ``dL``
along its critical set) has ``Delta = 0`` and rounding alone gives it a sign.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from engine.local.critical import CriticalPoint
from engine.model.constraints import Constraints
from engine.model.errors import InvalidRequest
from engine.model.linkage import Linkage, changeable_bar
from engine.model.tolerances import MODEL_CONTRACTION_MAX, NORM_FLOOR, Tolerances
from engine.space.trace import TraceOptions, correct, trace_curve


@dataclass(frozen=True)
class Split:
    """Prediction for one critical point.

    ``shift`` is ``dc`` on the zero modes, ``shift_vector`` the same as a move of the free
    coordinates (M,); ``delta_error`` the scale of the error of ``delta`` (see
    :func:`delta_error`); ``sign`` is that of ``delta`` where ``|delta| > delta_error`` and 0
    (undecided) otherwise; ``connects`` lists the joined ray pairs (empty when ``sign`` is 0 or
    the point is not a branch point).
    """

    index: int
    delta: float
    delta_linear: float
    shift: np.ndarray
    shift_vector: np.ndarray
    sign: int
    connects: list[tuple[int, int]]
    delta_error: float = 0.0

    @property
    def resolved(self) -> bool:
        """The sign is decided: ``|delta| > delta_error``."""
        return self.sign != 0


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


@dataclass(frozen=True)
class _Terms:
    """The pieces of one ``Delta`` that its error scale is made of (``sigma`` (Ea,) the unit
    stress on the active bars, ``rhs`` (Ea,) ``2 L dL + dL^2``, ``w`` (M,) the off-mode move,
    ``b`` (k,) ``Z H_sigma w``, ``lam`` (k,) ``Q``'s eigenvalues, ``dc`` (k,) the shift)."""

    sigma: np.ndarray
    lengths: np.ndarray
    rhs: np.ndarray
    w: np.ndarray
    b: np.ndarray
    lam: np.ndarray
    dc: np.ndarray


def delta_error(cons: Constraints, u: np.ndarray, zero_modes: np.ndarray, t: _Terms) -> float:
    """The scale of the error of ``Delta = 2 sigma.rhs - w^T H w + dc^T Q dc`` at ``u``.

    The sum of

    - the self-stress's error: ``sigma`` is the left null vector of ``J (Ea, M)`` computed in
      float64 at a point that is critical only to its residual; by Wedin's theorem it is off
      by ``e_s <= (|J^T sigma| + max(Ea, M) eps s_max) / s_gap`` (``s_gap`` the smallest
      singular value of ``J`` but the stress's own), which moves ``2 sigma.rhs`` by
      ``2 e_s |rhs|``, ``H_sigma`` by ``|dH| <= 4 sqrt(Ea) e_s`` (each ``Hess(l_a^2)`` has norm
      4), hence ``w^T H w`` by ``|dH| |w|^2`` and ``b^2 / lam`` by
      ``(2 |dH| |w| / |b| + |dH| / |lam|) b^2 / |lam|``;
    - the critical point's length residual: ``u`` sits on lengths ``l(u)``, not ``L``, which
      moves ``rhs`` by ``|L^2 - l^2| <= 2 L |l - L|``;
    - rounding: ``w`` solves a least-squares problem of condition ``s_max / s_gap`` (relative
      error ``max(Ea, M) eps s_max / s_gap``, twice in ``w^T H w`` and in ``b^2``), ``Q``'s
      eigenvalues are known to ``M eps |H_sigma|``, and each dot product of ``n`` terms is
      off by ``gamma_n = n eps / (1 - n eps)`` of the sum of its absolute terms (Higham);
    - the model: with quadratic constraints the only thing the formula leaves out is the range
      part ``v`` of the move, a fixed point of ``v = -J^+ q(du0 + v)`` at the conic's centre
      ``du0 = Z^T dc + w`` (``q_a(du) = |du_i - du_j|^2`` exactly); see :func:`_model_error`.
    """
    eps = float(np.finfo(float).eps)
    jac = cons.jacobian(u, sparse=False)
    ea, m = jac.shape
    sv = np.linalg.svd(jac, compute_uv=False)  # descending, min(Ea, M)
    s_max = float(sv[0]) if sv.size else 0.0
    s_gap = float(sv[ea - 2]) if 2 <= ea <= sv.size + 1 else s_max
    s_gap = max(s_gap, NORM_FLOOR)
    p = max(ea, m)
    cond = p * eps * s_max / s_gap
    e_s = (float(np.linalg.norm(jac.T @ t.sigma)) + p * eps * s_max) / s_gap
    hess = cons.stress_hessian(t.sigma, sparse=False)
    h_norm = float(np.linalg.norm(hess, 2)) if hess.size else 0.0
    d_h = 4.0 * np.sqrt(ea) * e_s
    w_norm = float(np.linalg.norm(t.w))
    abs_lam = np.maximum(np.abs(t.lam), NORM_FLOOR)
    t3_terms = t.b**2 / abs_lam  # |dc^T Q dc| term by term
    gamma = (ea + 3) * eps / (1 - (ea + 3) * eps)
    stress = 2.0 * e_s * float(np.linalg.norm(t.rhs)) + d_h * w_norm**2 + float(np.sum(
        (2.0 * d_h * w_norm / np.maximum(np.abs(t.b), NORM_FLOOR) + d_h / abs_lam) * t3_terms))
    lengths = 4.0 * float(np.abs(t.sigma) @ (t.lengths * np.abs(cons.residual(u))))
    rounding = (gamma * 2.0 * float(np.abs(t.sigma) @ np.abs(t.rhs))
                + (2.0 * cond + gamma) * float(np.abs(t.w) @ (np.abs(hess) @ np.abs(t.w)))
                + float(np.sum((2.0 * cond + gamma + m * eps * h_norm / abs_lam) * t3_terms)))
    model = _model_error(cons, u, jac, hess, s_gap, t.dc @ zero_modes + t.w, float(abs_lam.min()))
    return stress + lengths + rounding + model


def _model_error(
    cons: Constraints, u: np.ndarray, jac: np.ndarray, hess: np.ndarray, s_gap: float,
    du0: np.ndarray, lam_min: float,
) -> float:
    """Bound on what ``Delta`` leaves out: the range part ``v`` of the move (inf where the
    bound does not hold: a change too large for the model).

    The constraints are quadratic, ``l^2(u + du) = l^2(u) + J du + q(du)``, so the move off the
    zero modes solves ``v = -J^+ q(du0 + v)`` exactly (``v = 0`` in the formula). Its first
    iterate is ``v2 = -J^+ q(du0)``; ``q(a) - q(b) = J_{(a+b)/2} (a - b)`` with ``J_x = J(u + x)
    - J(u)`` (``J`` is linear in the coordinates) and ``|J_x| <= 4 sqrt(deg_max) |x|``, so on the
    ball ``|v| <= 2 |v2|`` the map contracts by ``ell = (|J_du0| + 8 sqrt(deg_max) |v2|) /
    s_gap``; for ``ell < 1/2`` (``MODEL_CONTRACTION_MAX``) the fixed point ``v*`` has
    ``|v* - v2| <= ell |v2| / (1 - ell)``.
    The conic's constant then moves by ``2 du0^T H v* + v*^T H v*`` at its centre, and its
    critical value by at most ``|p|^2 / (4 lam_min)`` more, ``p`` the gradient of that change
    in ``c`` (``|dv/dc| <= ell / (1 - ell)``).
    """
    quad = cons.squared_lengths(u + du0) - cons.squared_lengths(u) - jac @ du0
    v2 = -np.linalg.lstsq(jac, quad, rcond=1e-10)[0]
    v2_norm = float(np.linalg.norm(v2))
    ends = cons.linkage.ends[cons.bars]
    deg_max = float(np.bincount(ends.ravel()).max()) if ends.size else 0.0
    j_du0 = cons.jacobian(u + du0, sparse=False) - jac
    ell = (float(np.linalg.norm(j_du0, 2)) + 8.0 * np.sqrt(deg_max) * v2_norm) / s_gap
    if ell >= MODEL_CONTRACTION_MAX:
        return float("inf")
    h_norm = float(np.linalg.norm(hess, 2))
    big_v = v2_norm / (1.0 - ell)
    h_du0 = float(np.linalg.norm(hess @ du0))
    constant = (abs(2.0 * float(du0 @ hess @ v2)) + 2.0 * h_du0 * ell * big_v
                + h_norm * big_v**2)
    grad = 2.0 * h_norm * big_v + 2.0 * ell / (1.0 - ell) * (h_du0 + h_norm * big_v)
    return constant + grad**2 / (4.0 * max(lam_min, NORM_FLOOR))


def split(linkage: Linkage, index: int, cp: CriticalPoint, d_l: np.ndarray) -> Split:
    """Appendix A prediction at critical point ``cp`` (of ``linkage``) for ``dL`` (E,).

    The sign is 0 (and there is no pairing) where ``|Delta|`` does not exceed its error scale
    (:func:`delta_error`).

    Examples
    --------
    >>> from engine.catalogue.presets import build_preset
    >>> from engine.space.configuration_space import SpaceOptions, explore
    >>> lk = build_preset("four-bar")
    >>> cp = explore(lk, Tolerances(), SpaceOptions(angles=24)).critical_points[0]
    >>> split(lk, 0, cp, length_change(lk, {"L2": 1e-3})).sign in (-1, 1)
    True
    """
    res = cp.analysis
    m = linkage.n_free
    if (res.self_stress is None or res.q is None or res.q_eigenvalues is None
            or res.kind not in ("branch", "rigid")):
        return Split(index, 0.0, 0.0, np.zeros(0), np.zeros(m), 0, [])
    delta, delta_linear, dc, error = conic_delta(linkage, cp, d_l)
    sign = int(np.sign(delta)) if abs(delta) > error else 0
    connects = pairing(ray_coefficients(cp), sign) if res.kind == "branch" else []
    return Split(index, delta, delta_linear, dc, dc @ res.zero_modes, sign, connects, error)


def conic_delta(linkage: Linkage, cp: CriticalPoint, d_l: np.ndarray
                ) -> tuple[float, float, np.ndarray, float]:
    """``Delta`` of the conic (or, with ``D + 1`` zero modes, the quadric) at ``cp`` for ``dL``
    (E,): ``(delta, delta_linear, dc, delta_error)`` (module docstring); ``cp`` has one
    self-stress and ``Q``'s eigenvalues."""
    res = cp.analysis
    assert res.self_stress is not None and res.q_eigenvalues is not None
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
    error = delta_error(cons, cp.u, z, _Terms(sigma, lengths, rhs, w, b, lam, dc))
    return delta, delta_linear, dc, error


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
