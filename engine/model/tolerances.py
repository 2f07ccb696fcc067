"""Numerical tolerances, one name per meaning."""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from engine.model.errors import InvalidLinkage, InvalidTolerance

#: Default ``residual_atol`` relative to the linkage's median bar length.
RESIDUAL_REL = 1e-9
#: A coordinate ``x`` is resolved in float64 to about ``eps |x|``; positions whose resolution is
#: coarser than ``residual_atol / RESOLUTION_MARGIN`` cannot be analysed to that tolerance.
RESOLUTION_MARGIN = 8.0
#: Largest ``residual_atol`` relative to the median bar length.
MAX_RESIDUAL_REL = 1e-6
#: Smallest relative tolerance (``rank_rtol``, ``q_rtol``) that means anything in float64.
MIN_RELATIVE = 1e-14
#: Two configurations (or dyad centres) closer than this, relative to the median bar length,
#: are the same point: duplicates of a critical point, a seed on a traced curve, centres that
#: coincide.
SAME_POINT_REL = 1e-6
#: Shortest bar of a critical configuration, in units of ``residual_atol``: a bar shorter than
#: this is degenerate (a zero-length bar has a self-stress of its own at every configuration),
#: not a critical value of the linkage.
MIN_CRITICAL_LENGTH_ATOL = 1e3

#: Floor of a norm or distance that is divided by (a zero vector has no direction: its
#: quotient is then 0 instead of a division by zero).
NORM_FLOOR = 1e-300

#: A critical-value curve this close to a raster cell's edge (in cells) blocks the cells on both
#: sides of that edge: which side a curve through a cell corner or along an edge falls on would
#: otherwise hinge on rounding (two refinements of the same curve, 1e-8 apart, blocked
#: different cells where a curve ends on a corner of the box's edge).
CELL_EDGE_TOL = 1e-6

#: The corrector converges to this fraction of ``residual_atol`` (Newton's last step costs
#: little and squares the error): near critical lengths the Jacobian's smallest singular value
#: ``s`` is small, and a point accepted at ``residual_atol`` could sit ``residual_atol / s``
#: off the curve, farther than the steps that pass a narrow neck (the tracer then crawled
#: inside the tolerance band, e.g. a four-bar 1e-8 from critical lengths).
CORRECT_TIGHT = 1e-3

#: The tracer's corrector polishes its point with the factorisation at the point the chord
#: reached (made for the tangent anyway); the tangent, sign and ``log|det|`` of that
#: factorisation stand for the polished point while the polish moved it by at most this
#: fraction of the step (the tangent is then off by about as much of the step's own turn).
#: Near critical lengths the polish moves farther (``residual_atol / s``, ``s`` the Jacobian's
#: smallest singular value, as far as the step itself in a narrow neck, where the tangent
#: turns fast): the tangent is then factorised again at the polished point.
POLISH_TANGENT_MOVE = 1e-5

#: A splitting's model bound (:func:`engine.design.splitting.delta_error`) holds where the
#: off-mode move it leaves out is a contraction by less than this: the fixed point then lies in
#: the ball of twice the first iterate (``1 / (1 - ell) <= 2``); beyond it the length change is
#: too large for the second-order model, and the sign is left undecided.
MODEL_CONTRACTION_MAX = 0.5

#: A dual certificate's eigenvalues below this fraction of its largest are off its range when
#: it is polished (:func:`engine.local.certificates.decide`): the solver's interior point leaves
#: them at about the square root of its own tolerance, far above rounding.
DUAL_RANGE_RTOL = float(np.sqrt(np.finfo(float).eps))


@dataclass(frozen=True)
class Tolerances:
    """Tolerances used by the analyses; responses echo them.

    Attributes
    ----------
    rank_rtol : float
        A singular value ``s`` of the Jacobian counts as zero when
        ``s <= rank_rtol * s_max`` (relative, like SciPy's ``rcond``).
    residual_atol : float
        A configuration satisfies the constraints when every bar length is within
        ``residual_atol`` of its target (absolute, in length units).
    q_rtol : float
        An eigenvalue ``lam`` of the second-order form ``Q`` counts as zero when
        ``|lam| <= q_rtol * ||H_sigma||`` (relative to the stress-contracted Hessian's norm).
    """

    rank_rtol: float = 1e-8
    residual_atol: float = 1e-9
    q_rtol: float = 1e-6

    def __post_init__(self) -> None:
        if not (self.residual_atol > 0 and np.isfinite(self.residual_atol)):
            raise InvalidTolerance(
                f"must be a positive number, got {self.residual_atol!r}",
                loc=("tolerances", "residual_atol"),
            )
        for name in ("rank_rtol", "q_rtol"):
            value = getattr(self, name)
            if not (value > 0 and value < 1):
                raise InvalidTolerance(
                    f"must lie in (0, 1), got {value!r}", loc=("tolerances", name)
                )
        for name in ("rank_rtol", "q_rtol"):
            # Computed singular values and eigenvalues carry errors of a few eps times the
            # largest one: a relative threshold below that decides nothing.
            value = getattr(self, name)
            if value < MIN_RELATIVE:
                raise InvalidTolerance(
                    f"must be at least {MIN_RELATIVE:g} (a few machine epsilons), got {value!r}",
                    loc=("tolerances", name),
                )


def scaled_tolerances(
    length_scale: float, rank_rtol: float | None = None, residual_atol: float | None = None,
    q_rtol: float | None = None,
) -> Tolerances:
    """Tolerances for a linkage whose bars are about ``length_scale`` long.

    ``residual_atol`` defaults to ``RESIDUAL_REL * length_scale`` (``1e-9`` for unit bars), so
    that the same linkage drawn in metres or in micrometres is analysed alike; the relative
    tolerances do not depend on the scale. Values that are given are kept.

    Examples
    --------
    >>> scaled_tolerances(1e-6).residual_atol
    1e-15
    """
    tol = Tolerances()
    changes: dict[str, float] = {"residual_atol": RESIDUAL_REL * length_scale}
    for name, value in (("rank_rtol", rank_rtol), ("residual_atol", residual_atol),
                        ("q_rtol", q_rtol)):
        if value is not None:
            changes[name] = value
    return replace(tol, **changes)


def check_residual_scale(tol: Tolerances, length_scale: float) -> None:
    """Refuse a ``residual_atol`` that is not small against the bars (more than
    ``MAX_RESIDUAL_REL`` of the median length ``length_scale``): configurations that far off
    the lengths are not points of the configuration space, and every search would wander."""
    if tol.residual_atol > MAX_RESIDUAL_REL * length_scale:
        raise InvalidTolerance(
            f"residual_atol = {tol.residual_atol:g} is not small against the bars (median "
            f"length {length_scale:g}): at most {MAX_RESIDUAL_REL:g} of it",
            loc=("tolerances", "residual_atol"),
        )


def check_resolution(positions: np.ndarray, tol: Tolerances) -> None:
    """Refuse positions that float64 cannot resolve to ``residual_atol``.

    Near ``|x| = 1e12`` a coordinate is only known to about ``1e-4``: bars of unit length there
    cannot be held to ``1e-9``, and every answer would be noise. Raises
    :class:`InvalidLinkage` naming the vertex with the largest coordinate.
    """
    mags = np.max(np.abs(positions), axis=1) if positions.size else np.zeros(0)
    if mags.size == 0:
        return
    k = int(np.argmax(mags))
    resolution = float(np.finfo(float).eps * mags[k])
    if RESOLUTION_MARGIN * resolution > tol.residual_atol:
        raise InvalidLinkage(
            f"coordinates as large as {mags[k]:.3g} are resolved in float64 only to about "
            f"{resolution:.2g}, coarser than residual_atol = {tol.residual_atol:.3g} allows: "
            "move the linkage near the origin (or raise tolerances.residual_atol)",
            loc=("vertices", k, "position"),
        )
