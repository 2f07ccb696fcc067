"""A traced curve, what it is traced with, and its geometry: :class:`Curve` (what
:func:`engine.space.trace.trace_curve` returns), :class:`TraceOptions` and the step bounds
they give one trace (:func:`_limits`), the predictor's cubic through two points with their
tangents (:func:`predict`), and distances to segments and polylines of points (closing tests,
the search's queries).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from engine.model.constraints import Constraints


@dataclass(frozen=True)
class TraceOptions:
    """Controls of the tracer.

    Attributes
    ----------
    strain_tol : float
        Largest relative bar strain ``|l - L| / L`` allowed at a predicted point.
    step_max : float or None
        Largest distance between consecutive points (free coordinates); default a tenth of
        the median bar length. Consecutive points are never farther apart than this.
    max_points : int
        Budget of points for one curve.
    max_turn : float
        Largest angle (radians) between consecutive tangents.
    """

    strain_tol: float = 1e-2
    step_max: float | None = None
    max_points: int = 20_000
    max_turn: float = 0.35

    def resolved_step_max(self, cons: Constraints) -> float:
        if self.step_max is not None:
            return self.step_max
        return 0.1 * float(np.median(cons.linkage.lengths[cons.bars]))


@dataclass(frozen=True)
class _Limits:
    """The step bounds of one trace: largest step, smallest (the scale's resolution), steps
    that may cross a sign change of the augmented determinant, and the loop's pass budget."""

    h_max: float
    h_min: float
    h_cross: float
    passes: int


def _limits(cons: Constraints, u0: np.ndarray, options: TraceOptions) -> _Limits:
    h_max = options.resolved_step_max(cons)
    # Below ~1e-12 of the linkage's scale a step no longer moves u in floating point: the
    # smallest step is bounded there whatever step_max is, and every pass of the loop (kept
    # or halved) counts against a budget, so no option can make a trace run forever.
    scale = max(float(np.max(np.abs(u0), initial=0.0)),
                float(np.median(cons.linkage.lengths[cons.bars])))
    return _Limits(h_max, max(1e-9 * h_max, 1e-12 * scale), 1e-5 * h_max,
                   40 * options.max_points + 1000)

def predict(
    u: np.ndarray, t: np.ndarray, h: float, prev: np.ndarray | None, t_prev: np.ndarray
) -> np.ndarray:
    """The predictor: ``h`` along the curve from ``u`` (unit tangent ``t``).

    With the previous point ``prev`` (unit tangent ``t_prev``) the cubic through both points
    with both tangents (Hermite, parametrised by the distance ``h0 = |u - prev|``),
    extrapolated to ``h``: ``u + h t + r^2 (3 + 2 r) (prev - u + h0 t) + h0 r^2 (1 + r)
    (t_prev - t)`` with ``r = h / h0``; the terms after ``u + h t`` vanish on a straight
    line and are ``O(h^2)`` (the curvature) otherwise, so the prediction is off the curve by
    ``O(h^4)`` instead of the tangent's ``O(h^2)``: the chord corrector starts about two of its
    iterations closer (a 400-rotor chain's step at ``step_max``: residual ``4e-8`` instead of
    ``1e-4``). Without ``prev`` (the first step, the step after a crossing, and every attempt
    from a point after one that failed there: see :func:`trace_curve`), or with ``h0 = 0``, the
    tangent ``u + h t``.
    """
    v = u + h * t
    if prev is None:
        return v
    h0 = float(np.linalg.norm(u - prev))
    if not h0 > 0.0:
        return v
    r = h / h0
    return v + (r * r * (3.0 + 2.0 * r)) * (prev - u + h0 * t) + (h0 * r * r * (1.0 + r)) * \
        (t_prev - t)


@dataclass
class Curve:
    """A traced curve: points (n, M), unit tangents (n, M), ``det([t_prev; J])`` signs and
    ``log|det|`` per point, and why tracing stopped."""

    points: list[np.ndarray] = field(default_factory=list)
    tangents: list[np.ndarray] = field(default_factory=list)
    signs: list[int] = field(default_factory=list)
    logdets: list[float] = field(default_factory=list)
    stop: str = ""
    stop_index: int | None = None
    #: :meth:`array`'s arrays: per field, the list and its length they were built from
    _arrays: dict[str, tuple[list[object], int, np.ndarray]] = field(
        default_factory=dict, init=False, repr=False, compare=False)
    #: per field, the list and the blocks that :meth:`append` and :meth:`extend` added to
    #: it: the arrays :meth:`extend` was given, and counts of single items :meth:`append`
    #: added one after another; :meth:`array` joins them while they are the whole list
    _blocks: dict[str, tuple[list[object], list[np.ndarray | int]]] = field(
        default_factory=dict, init=False, repr=False, compare=False)

    def _add_block(self, name: str, block: np.ndarray | int) -> None:
        values = getattr(self, name)
        kept = self._blocks.get(name)
        if kept is None or kept[0] is not values:
            kept = self._blocks[name] = (values, [])
        blocks = kept[1]
        if isinstance(block, int) and blocks and isinstance(blocks[-1], int):
            blocks[-1] += block
        else:
            blocks.append(block)

    def append(self, u: np.ndarray, t: np.ndarray, sign: int, logdet: float) -> None:
        self.points.append(u)
        self.tangents.append(t)
        self.signs.append(sign)
        self.logdets.append(logdet)
        for name in ("points", "tangents", "signs", "logdets"):
            self._add_block(name, 1)

    def extend(self, points: np.ndarray, tangents: np.ndarray, signs: np.ndarray,
               logdets: np.ndarray) -> None:
        """Append the rows of ``points`` (n, M), ``tangents`` (n, M), ``signs`` (n,) and
        ``logdets`` (n,) (the fields stay lists of rows, ints and floats)."""
        self.points.extend(points)
        self.tangents.extend(tangents)
        self.signs.extend(signs.tolist())
        self.logdets.extend(logdets.tolist())
        for name, block in (("points", points), ("tangents", tangents), ("signs", signs),
                            ("logdets", logdets)):
            self._add_block(name, block)

    def array(self, name: str) -> np.ndarray:
        """``np.array`` of the field ``name`` (``points``, ``tangents``, ``signs`` or
        ``logdets``), read-only, built once: again only when the field is another list or
        has grown (a traced curve's thousands of rows are converted once, not by every
        step of the search that reads them)."""
        values = getattr(self, name)
        cached = self._arrays.get(name)
        if cached is not None and cached[0] is values and cached[1] == len(values):
            return cached[2]
        kept = self._blocks.get(name)
        if kept is not None and kept[0] is values and kept[1] and \
                sum(b if isinstance(b, int) else len(b) for b in kept[1]) == len(values):
            # the list is exactly the blocks added to it: joined (runs of single items
            # converted as a slice of the list), not rebuilt row by row
            parts, at = [], 0
            for b in kept[1]:
                n = b if isinstance(b, int) else len(b)
                parts.append(np.array(values[at:at + n]) if isinstance(b, int) else b)
                at += n
            out = np.concatenate(parts)
        else:
            out = np.array(values)
        out.flags.writeable = False
        self._arrays[name] = (values, len(values), out)
        return out


StopCheck = Callable[[np.ndarray, np.ndarray, np.ndarray], str | None]
"""``check(u_prev, u_new, t_new)`` returns a reason to stop after accepting ``u_new``."""


def closest_on_segment(a: np.ndarray, b: np.ndarray, target: np.ndarray) -> np.ndarray:
    """The point of the segment ``[a, b]`` closest to ``target``."""
    ab = b - a
    denom = float(ab @ ab)
    s = 0.0 if denom == 0.0 else float(np.clip((target - a) @ ab / denom, 0.0, 1.0))
    return a + s * ab


def segment_distance(a: np.ndarray, b: np.ndarray, target: np.ndarray) -> float:
    """Distance from ``target`` to the segment ``[a, b]``."""
    return float(np.linalg.norm(closest_on_segment(a, b, target) - target))


def distances_to_segment(a: np.ndarray, b: np.ndarray, targets: np.ndarray) -> np.ndarray:
    """Distances from each of ``targets`` (K, M) to the segment ``[a, b]``, vectorised over the
    targets (``segment_distance`` of each row, to rounding)."""
    ab = b - a
    denom = float(ab @ ab)
    if denom == 0.0:
        s = np.zeros(len(targets))
    else:
        s = np.clip((targets - a) @ ab / denom, 0.0, 1.0)
    gap = a + s[:, None] * ab - targets
    return np.sqrt(np.einsum("ij,ij->i", gap, gap))


def polyline_distance(points: np.ndarray, target: np.ndarray) -> float:
    """Distance from ``target`` to the polyline through ``points`` (n, M), vectorised over
    its segments (one point: the distance to it)."""
    if len(points) < 2:
        return float(np.linalg.norm(points[0] - target))
    return segments_distance(points[:-1], points[1:], target)


def segments_distance(a: np.ndarray, b: np.ndarray, target: np.ndarray) -> float:
    """Distance from ``target`` to the nearest of the segments ``[a_k, b_k]`` (K, M),
    vectorised over the segments."""
    ab = b - a
    denom = np.einsum("ij,ij->i", ab, ab)
    num = np.einsum("ij,ij->i", target - a, ab)
    s = np.clip(np.divide(num, denom, out=np.zeros_like(num), where=denom > 0), 0.0, 1.0)
    gap = a + s[:, None] * ab - target
    return float(np.sqrt(np.min(np.einsum("ij,ij->i", gap, gap))))
