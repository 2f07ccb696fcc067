"""Numerical tolerances, one name per meaning."""

from __future__ import annotations

from dataclasses import dataclass

from engine.errors import InvalidTolerance


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
        for name in ("rank_rtol", "residual_atol", "q_rtol"):
            value = getattr(self, name)
            if not (value > 0 and value < 1):
                raise InvalidTolerance(
                    f"must lie in (0, 1), got {value!r}", loc=("tolerances", name)
                )
