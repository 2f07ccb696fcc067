"""The size of an answer, estimated before it is built, against ``LINKAGE_MAX_ANSWER_MB``.

Every estimate is a lower bound on the JSON the answer would take, from counts known before
the answer is mapped and serialised (the linkage's sizes, the points traced, the critical
points found, the curves and regions of a slice, the rows of a sweep): an answer refused here
would have been larger still, and the refusal (422 ``limit-exceeded``) names the limit and
what to ask for instead. Building the answer is what costs: a configuration space of 10^5
points of a 300-vertex chain is 6 * 10^7 numbers, gigabytes as Python floats before any JSON.
"""

from __future__ import annotations

import numpy as np

from engine.model.errors import InvalidRequest, LimitExceeded
from engine.model.linkage import Linkage
from service.config import Settings

#: Bytes a number of an answer takes as JSON at least: a float64's shortest form and its
#: separator, and the key or brackets around it (measured: 29-30 bytes per number on first-order
#: answers of 3 vertices with 300 and 900 bars and of K20, K30 in 3D).
ANSWER_BYTES_PER_NUMBER = 16
#: Bytes a number takes packed (``options.points = "compact"``): 8 bytes in base64, exactly.
PACKED_BYTES_PER_NUMBER = 32 / 3


def _refuse(size: float, what: str, settings: Settings, advice: str,
            loc: tuple[str, ...] | None = None) -> None:
    """Raise when ``size`` bytes exceed the limit: an :class:`InvalidRequest` at ``loc`` (what
    the request asked for), else a :class:`LimitExceeded` (the linkage itself)."""
    if size > settings.max_answer_mb * 2**20:
        message = (f"the answer would hold {what}, at least {size / 2**20:,.0f} MB of JSON, "
                   f"more than LINKAGE_MAX_ANSWER_MB = {settings.max_answer_mb}; {advice}")
        if loc is not None:
            raise InvalidRequest(message, loc=loc)
        raise LimitExceeded(message, loc=())


def first_order_numbers(linkage: Linkage) -> int:
    """Numbers a first-order answer holds at least, from the sizes alone: ``k M + s E_a`` with
    ``k >= M - E_a - d(d+1)/2`` nontrivial zero modes of ``M`` coordinates and ``s >= E_a - M``
    self-stresses of ``E_a`` bars (rank-nullity, whatever the rank)."""
    m, ea, d = linkage.n_free, int(linkage.active.sum()), linkage.dimension
    return max(0, m - ea - d * (d + 1) // 2) * m + max(0, ea - m) * ea


def check_first_order(linkage: Linkage, settings: Settings) -> None:
    """Refuse (422, before any work) a first-order answer estimated beyond
    ``LINKAGE_MAX_ANSWER_MB``."""
    numbers = first_order_numbers(linkage)
    _refuse(numbers * ANSWER_BYTES_PER_NUMBER,
            f"at least {numbers:,} numbers (M = {linkage.n_free} free coordinates, E = "
            f"{int(linkage.active.sum())} bars: its zero modes and self-stresses)", settings,
            "brace or split the linkage, or ask for /v1/analysis/second-order (no self-stress "
            "basis)")


def check_null_spaces(zero_modes: np.ndarray, self_stresses: np.ndarray,
                      settings: Settings) -> None:
    """Refuse (422) a first- or second-order answer whose computed zero modes and
    self-stresses (each a vector per vertex or bar) would exceed ``LINKAGE_MAX_ANSWER_MB``,
    before they are mapped: the sizes alone (:func:`check_first_order`) bound them from below
    only (a straight 1000-rotor chain: 2,001 zero modes and 999 self-stresses)."""
    numbers = int(zero_modes.size + self_stresses.size)
    _refuse(numbers * ANSWER_BYTES_PER_NUMBER,
            f"{zero_modes.shape[0]:,} zero modes and {self_stresses.shape[0]:,} self-stresses "
            f"({numbers:,} numbers)", settings,
            "brace or split the linkage, or move it off this (highly degenerate) configuration")


def check_points(linkage: Linkage, points: int, critical: int, compact: bool,
                 settings: Settings) -> None:
    """Refuse a configuration-space answer of ``points`` traced points and ``critical``
    critical points estimated beyond the limit: each point places every vertex (``V d``
    numbers), each critical point at least its configuration (``V d``)."""
    vd = linkage.n_vertices * linkage.dimension
    per_number = PACKED_BYTES_PER_NUMBER if compact else ANSWER_BYTES_PER_NUMBER
    size = points * vd * per_number + critical * vd * ANSWER_BYTES_PER_NUMBER
    _refuse(size, f"{points:,} points of {linkage.n_vertices} vertices in {linkage.dimension}D "
            f"({points * vd:,} numbers) and {critical:,} critical points", settings,
            "raise options.step_max, lower options.max_points or options.max_components, or "
            "ask for options.points = \"compact\"" if not compact else
            "raise options.step_max, lower options.max_points or options.max_components",
            loc=("options",))


def check_critical(linkage: Linkage, critical: int, near_misses: int,
                   settings: Settings) -> None:
    """Refuse a critical-point answer estimated beyond the limit: each critical point holds at
    least its configuration (``V d`` numbers), each near miss two configurations."""
    vd = linkage.n_vertices * linkage.dimension
    numbers = (critical + 2 * near_misses) * vd
    _refuse(numbers * ANSWER_BYTES_PER_NUMBER,
            f"{critical:,} critical points and {near_misses:,} near misses of "
            f"{linkage.n_vertices} vertices ({numbers:,} numbers)", settings,
            "lower options.max_components or split the linkage", loc=("options",))


def check_slice(curve_points: int, regions: int, settings: Settings) -> None:
    """Refuse a critical-value slice estimated beyond the limit: two numbers per curve point,
    at least three per region (its point and its cells)."""
    numbers = 2 * curve_points + 3 * regions
    _refuse(numbers * ANSWER_BYTES_PER_NUMBER,
            f"{curve_points:,} curve points and {regions:,} regions", settings,
            "lower options.resolution or narrow the axes", loc=("options",))


#: Numbers of one four-bar cell's tau signs in a sweep's row: its four sides and three signs.
CELL_NUMBERS = 7


def check_sweep(points: int, axes: int, fields: int, settings: Settings) -> None:
    """Refuse (when the sweep is asked for) a sweep whose rows would hold more than the limit:
    each of its ``points`` rows holds its ``axes`` values and one value per computed field."""
    numbers = points * (axes + fields)
    _refuse(numbers * ANSWER_BYTES_PER_NUMBER,
            f"{points:,} rows of {axes + fields} values ({numbers:,} numbers)", settings,
            "sweep fewer points or fewer axes", loc=())
