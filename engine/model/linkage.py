"""Linkage model: vertices (pinned, sliding or free) joined by bars of fixed length.

Notation (as in the paper): ``V`` vertices in ``d`` dimensions, ``E`` bars. Only the free
coordinates move; they form the configuration vector ``u`` of length ``M``. A vertex may be
free, fully fixed (a pin) or fixed along some axes only (a slider).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from engine.model.errors import InvalidLinkage, InvalidRequest, LimitExceeded

#: Coordinates beyond this magnitude are refused: their squared distances would overflow.
MAX_COORDINATE = 1e100
#: Shortest bar accepted, relative to the longest one.
MIN_LENGTH_RATIO = 1e-12


@dataclass(frozen=True)
class Limits:
    """Size limits that keep the cost of one analysis bounded."""

    max_vertices: int = 50_000
    max_bars: int = 200_000


@dataclass(frozen=True)
class VertexSpec:
    """A vertex as described by a client (validated by :func:`build_linkage`)."""

    id: str
    position: Sequence[float]
    fixed: bool | Sequence[bool] = False


@dataclass(frozen=True)
class BarSpec:
    """A bar as described by a client; ``length=None`` means the current distance."""

    id: str
    ends: Sequence[str]
    length: float | None = None


class VertexLike(Protocol):
    """Anything with a vertex's fields (a :class:`VertexSpec`, or a request model as it is)."""

    @property
    def id(self) -> str: ...

    @property
    def position(self) -> Sequence[float]: ...

    @property
    def fixed(self) -> bool | Sequence[bool]: ...


class BarLike(Protocol):
    """Anything with a bar's fields (a :class:`BarSpec`, or a request model as it is)."""

    @property
    def id(self) -> str: ...

    @property
    def ends(self) -> Sequence[str]: ...

    @property
    def length(self) -> float | None: ...


@dataclass(frozen=True, eq=False)
class Linkage:
    """A validated linkage. Arrays are read-only.

    Attributes
    ----------
    dimension : int
        ``d``, 2 or 3.
    vertex_ids : tuple of str
        ``V`` ids, in request order.
    positions : (V, d) float64
        The configuration as given.
    fixed : (V, d) bool
        True where a coordinate is held fixed.
    bar_ids : tuple of str
        ``E`` ids, in request order.
    ends : (E, 2) int64
        Vertex indices of the two ends of each bar.
    lengths : (E,) float64
        Target lengths ``L``.
    """

    dimension: int
    vertex_ids: tuple[str, ...]
    positions: np.ndarray
    fixed: np.ndarray
    bar_ids: tuple[str, ...]
    ends: np.ndarray
    lengths: np.ndarray
    free_index: np.ndarray = field(init=False, repr=False)
    active: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        free = ~self.fixed
        index = np.full(self.fixed.shape, -1, dtype=np.int64)
        index[free] = np.arange(int(free.sum()), dtype=np.int64)
        # A bar between two fully fixed vertices is a constant: it constrains nothing.
        fully_fixed = np.asarray(self.fixed.all(axis=1), dtype=bool)
        active = ~(fully_fixed[self.ends[:, 0]] & fully_fixed[self.ends[:, 1]])
        object.__setattr__(self, "free_index", index)
        object.__setattr__(self, "active", active)
        for arr in (self.positions, self.fixed, self.ends, self.lengths, index, active):
            arr.flags.writeable = False

    @property
    def n_vertices(self) -> int:
        """``V``."""
        return len(self.vertex_ids)

    @property
    def n_bars(self) -> int:
        """``E``, counting every bar (also inert ones between two pins)."""
        return len(self.bar_ids)

    @property
    def n_free(self) -> int:
        """``M``, the number of free coordinates."""
        return int((~self.fixed).sum())

    @property
    def anything_fixed(self) -> bool:
        """True when at least one coordinate is held fixed (no trivial rigid motions)."""
        return bool(self.fixed.any())

    def coordinates(self, positions: np.ndarray | None = None) -> np.ndarray:
        """The free coordinates ``u`` (M,) of ``positions`` (default: the given ones)."""
        pos = self.positions if positions is None else positions
        return np.asarray(pos, dtype=float)[~self.fixed]

    def positions_of(self, u: np.ndarray) -> np.ndarray:
        """Vertex positions (V, d) with the free coordinates replaced by ``u`` (M,)."""
        pos = np.array(self.positions, dtype=float)
        pos[~self.fixed] = u
        return pos

    def vertex_vectors(self, v: np.ndarray) -> np.ndarray:
        """Lift a vector over free coordinates (M,) to per-vertex vectors (V, d)."""
        out = np.zeros(self.fixed.shape)
        out[~self.fixed] = v
        return out

    def with_positions(self, positions: np.ndarray) -> Linkage:
        """The same linkage at other positions (targets unchanged)."""
        return Linkage(
            self.dimension,
            self.vertex_ids,
            np.array(positions, dtype=float),
            np.array(self.fixed),
            self.bar_ids,
            np.array(self.ends),
            np.array(self.lengths),
        )

    def with_lengths(self, lengths: np.ndarray) -> Linkage:
        """The same linkage with other target lengths (positions unchanged)."""
        return Linkage(
            self.dimension,
            self.vertex_ids,
            np.array(self.positions),
            np.array(self.fixed),
            self.bar_ids,
            np.array(self.ends),
            np.array(lengths, dtype=float),
        )

    def bar_lengths(self, positions: np.ndarray | None = None) -> np.ndarray:
        """Current bar lengths (E,) at ``positions`` (default: the given ones)."""
        pos = self.positions if positions is None else positions
        diff = pos[self.ends[:, 0]] - pos[self.ends[:, 1]]
        return np.sqrt(np.einsum("ij,ij->i", diff, diff))


def _fixed_mask(fixed: bool | Sequence[bool], d: int, k: int) -> np.ndarray:
    if isinstance(fixed, bool | np.bool_):
        return np.full(d, bool(fixed))
    mask = list(fixed)
    if len(mask) != d or not all(isinstance(b, bool | np.bool_) for b in mask):
        raise InvalidLinkage(
            f"fixed must be a boolean or a list of {d} booleans (one per axis)",
            loc=("vertices", k, "fixed"),
        )
    return np.array(mask, dtype=bool)


def _build_vectorised(
    dimension: int,
    vertices: Sequence[VertexLike],
    bars: Sequence[BarLike],
    length_atol: float,
) -> Linkage | None:
    """:func:`build_linkage` for valid input with whole-array checks (a 10,000-rotor chain: a
    few milliseconds instead of half a second in a loop over vertices and bars); None as soon
    as anything is off, and the checking loop then reports the first problem exactly."""
    n = len(vertices)
    vertex_ids = [v.id for v in vertices]
    index = dict(zip(vertex_ids, range(n), strict=True))
    if len(index) != n:
        return None
    try:
        positions = np.array([v.position for v in vertices], dtype=float)
    except (TypeError, ValueError):
        return None
    if positions.shape != (n, dimension) or not np.all(np.isfinite(positions)):
        return None
    if np.any(np.abs(positions) > MAX_COORDINATE):
        return None
    flags = [v.fixed for v in vertices]
    if all(type(f) is bool for f in flags):
        fixed = np.repeat(np.array(flags, dtype=bool).reshape(n, 1), dimension, axis=1)
    else:  # every other vertex check passed: the first bad ``fixed`` is the first problem
        fixed = np.array([_fixed_mask(f, dimension, k) for k, f in enumerate(flags)])

    bar_ids = [b.id for b in bars]
    if len(set(bar_ids)) != len(bar_ids):
        return None
    pairs = [b.ends for b in bars]
    if any(len(e) != 2 for e in pairs):
        return None
    try:
        ends = np.array([(index[e[0]], index[e[1]]) for e in pairs], dtype=np.int64)
    except (KeyError, TypeError):
        return None
    ends = ends.reshape(len(bars), 2)
    if np.any(ends[:, 0] == ends[:, 1]):
        return None
    current = _norms(positions[ends[:, 0]] - positions[ends[:, 1]])
    raw = [b.length for b in bars]
    missing = np.array([x is None for x in raw], dtype=bool)
    try:
        given = np.array([np.nan if x is None else x for x in raw], dtype=float)
    except (TypeError, ValueError):
        return None
    if np.any(missing & (current == 0.0)):
        return None
    explicit = given[~missing]
    if not np.all(np.isfinite(explicit) & (explicit > 0.0) & (explicit <= 2 * MAX_COORDINATE)):
        return None
    fully_fixed = np.asarray(fixed.all(axis=1), dtype=bool)
    pinned = fully_fixed[ends[:, 0]] & fully_fixed[ends[:, 1]] & ~missing
    off = np.abs(current[pinned] - given[pinned]) > length_atol * np.maximum(1.0, given[pinned])
    if np.any(off):
        return None
    lengths = np.where(missing, current, given)
    if len(bars) and np.min(lengths) < MIN_LENGTH_RATIO * float(np.max(lengths)):
        return None  # a zero-length bar: the loop names it
    return Linkage(
        dimension=dimension,
        vertex_ids=tuple(vertex_ids),
        positions=positions,
        fixed=fixed,
        bar_ids=tuple(bar_ids),
        ends=ends,
        lengths=lengths,
    )


def build_linkage(
    dimension: int,
    vertices: Sequence[VertexLike],
    bars: Sequence[BarLike],
    limits: Limits | None = None,
    length_atol: float = 1e-9,
) -> Linkage:
    """Validate a client description and build a :class:`Linkage`.

    Parameters
    ----------
    dimension : int
        2 or 3.
    vertices, bars : sequences of specs
        Ids must be unique; bar ends must name vertices. Any objects with the fields of
        :class:`VertexSpec` and :class:`BarSpec` will do (the service passes its request
        models as they are).
    limits : Limits, optional
        Size limits (default :class:`Limits`).
    length_atol : float
        A bar between two fully fixed vertices must have its target length within this
        of the pins' distance.

    Raises
    ------
    InvalidLinkage, LimitExceeded
        With ``loc`` naming the offending field.

    Examples
    --------
    >>> lk = build_linkage(2, [VertexSpec("P", [0, 0], True), VertexSpec("A", [1, 0])],
    ...                    [BarSpec("r", ["P", "A"])])
    >>> lk.n_free, float(lk.lengths[0])
    (2, 1.0)
    """
    limits = limits or Limits()
    _check_sizes(dimension, vertices, bars, limits)

    fast = _build_vectorised(dimension, vertices, bars, length_atol)
    if fast is not None:
        return fast

    index, positions, fixed = _checked_vertices(dimension, vertices)
    ends, lengths = _checked_bars(bars, index, positions, fixed, length_atol)
    _check_no_tiny_bar(bars, lengths)
    return Linkage(
        dimension=dimension,
        vertex_ids=tuple(v.id for v in vertices),
        positions=positions,
        fixed=fixed,
        bar_ids=tuple(b.id for b in bars),
        ends=ends,
        lengths=lengths,
    )


def _check_sizes(
    dimension: int, vertices: Sequence[VertexLike], bars: Sequence[BarLike], limits: Limits
) -> None:
    """Raise on a bad dimension, no vertices, or more vertices or bars than ``limits`` allow."""
    if dimension not in (2, 3):
        raise InvalidLinkage(f"dimension must be 2 or 3, got {dimension!r}", loc=("dimension",))
    if len(vertices) == 0:
        raise InvalidLinkage("a linkage needs at least one vertex", loc=("vertices",))
    if len(vertices) > limits.max_vertices:
        raise LimitExceeded(
            f"{len(vertices)} vertices exceed the limit of {limits.max_vertices}",
            loc=("vertices",),
        )
    if len(bars) > limits.max_bars:
        raise LimitExceeded(
            f"{len(bars)} bars exceed the limit of {limits.max_bars}", loc=("bars",)
        )


def _checked_vertices(
    dimension: int, vertices: Sequence[VertexLike]
) -> tuple[dict[str, int], np.ndarray, np.ndarray]:
    """Vertex index by id, positions ``(V, d)`` and fixed mask ``(V, d)``, checking each
    vertex in order (the first fault raises, with ``loc`` naming it)."""
    index: dict[str, int] = {}
    positions = np.empty((len(vertices), dimension))
    fixed = np.empty((len(vertices), dimension), dtype=bool)
    for k, v in enumerate(vertices):
        if v.id in index:
            raise InvalidLinkage(f"duplicate vertex id {v.id!r}", loc=("vertices", k, "id"))
        index[v.id] = k
        pos = np.asarray(v.position, dtype=float)
        if pos.shape != (dimension,):
            raise InvalidLinkage(
                f"position of {v.id!r} has {pos.size} coordinates, expected {dimension}",
                loc=("vertices", k, "position"),
            )
        if not np.all(np.isfinite(pos)):
            raise InvalidLinkage(
                f"position of {v.id!r} is not finite", loc=("vertices", k, "position")
            )
        if np.any(np.abs(pos) > MAX_COORDINATE):
            raise InvalidLinkage(
                f"position of {v.id!r} has a coordinate beyond {MAX_COORDINATE:g} in magnitude "
                "(squared lengths would overflow)",
                loc=("vertices", k, "position"),
            )
        positions[k] = pos
        fixed[k] = _fixed_mask(v.fixed, dimension, k)
    return index, positions, fixed


def _checked_bars(
    bars: Sequence[BarLike],
    index: dict[str, int],
    positions: np.ndarray,
    fixed: np.ndarray,
    length_atol: float,
) -> tuple[np.ndarray, np.ndarray]:
    """Ends ``(E, 2)`` int64 and lengths ``(E,)``, checking each bar in order (the first
    fault raises, with ``loc`` naming it); a bar without a length keeps its current one."""
    bar_index: dict[str, int] = {}
    ends = np.empty((len(bars), 2), dtype=np.int64)
    lengths = np.empty(len(bars))
    fully_fixed = np.asarray(fixed.all(axis=1), dtype=bool)
    for k, b in enumerate(bars):
        if b.id in bar_index:
            raise InvalidLinkage(f"duplicate bar id {b.id!r}", loc=("bars", k, "id"))
        bar_index[b.id] = k
        i0, i1 = _checked_ends(b, k, index)
        ends[k] = (i0, i1)
        current = float(_norms(positions[i0] - positions[i1]))
        if b.length is None:
            if current == 0.0:
                raise InvalidLinkage(
                    f"bar {b.id!r} has no length and its ends coincide, so its length would be 0",
                    loc=("bars", k, "length"),
                )
            lengths[k] = current
            continue
        pinned = bool(fully_fixed[i0] and fully_fixed[i1])
        lengths[k] = _checked_length(b.id, k, float(b.length), current, pinned, length_atol)
    return ends, lengths


def _checked_ends(b: BarLike, k: int, index: dict[str, int]) -> tuple[int, int]:
    """Vertex indices of the two ends of bar ``b`` (number ``k``): two known, distinct ids."""
    if len(b.ends) != 2:
        raise InvalidLinkage("a bar has exactly two ends", loc=("bars", k, "ends"))
    for j, end in enumerate(b.ends):
        if end not in index:
            raise InvalidLinkage(
                f"bar {b.id!r} names unknown vertex {end!r}", loc=("bars", k, "ends", j)
            )
    i0, i1 = index[b.ends[0]], index[b.ends[1]]
    if i0 == i1:
        raise InvalidLinkage(
            f"bar {b.id!r} joins vertex {b.ends[0]!r} to itself", loc=("bars", k, "ends")
        )
    return i0, i1


def _checked_length(
    bar_id: str, k: int, length: float, current: float, pinned: bool, length_atol: float
) -> float:
    """The given ``length`` of bar ``bar_id`` (number ``k``): finite, positive, bounded, and,
    when both ends are fully fixed (``pinned``), within ``length_atol`` of their distance
    ``current``."""
    if not np.isfinite(length) or length > 2 * MAX_COORDINATE:
        raise InvalidLinkage(
            f"length of {bar_id!r} is not finite or beyond {2 * MAX_COORDINATE:g}",
            loc=("bars", k, "length"),
        )
    if length <= 0.0:
        raise InvalidLinkage(
            f"length of {bar_id!r} must be positive, got {length!r}",
            loc=("bars", k, "length"),
        )
    if pinned and abs(current - length) > length_atol * max(1.0, length):
        raise InvalidLinkage(
            f"bar {bar_id!r} joins two fixed vertices {current!r} apart but asks for length "
            f"{length!r}",
            loc=("bars", k, "length"),
        )
    return length


def _norms(diff: np.ndarray) -> np.ndarray:
    """Euclidean norms along the last axis, summed in the same order for one vector and for
    many (``np.linalg.norm`` of one vector goes through BLAS ``dot``, with fused multiply-adds on
    some CPUs: the checking loop and the vectorised build then differed by an ulp)."""
    return np.sqrt(np.add.reduce(diff * diff, axis=-1))


def _check_no_tiny_bar(bars: Sequence[BarLike], lengths: np.ndarray) -> None:
    """Raise on the shortest bar when it is below ``MIN_LENGTH_RATIO`` of the longest."""
    if len(bars):
        # A bar many orders of magnitude shorter than the rest is zero-length geometry in
        # float64: its direction, Jacobian row and stress are noise.
        k = int(np.argmin(lengths))
        if lengths[k] < MIN_LENGTH_RATIO * float(np.max(lengths)):
            raise InvalidLinkage(
                f"bar {bars[k].id!r} has length {lengths[k]:.3g}, below {MIN_LENGTH_RATIO:g} of "
                f"the longest bar ({float(np.max(lengths)):.3g}): treat its ends as one vertex",
                loc=("bars", k, "length"),
            )


def changeable_bar(linkage: Linkage, bar: str, loc: tuple[str | int, ...]) -> int:
    """Index of bar ``bar`` whose length a request may change, or :class:`InvalidRequest` at
    ``loc`` (unknown bar, or a bar between two fully fixed vertices: its length is their
    distance)."""
    if bar not in linkage.bar_ids:
        raise InvalidRequest(f"unknown bar {bar!r}", loc=loc)
    k = linkage.bar_ids.index(bar)
    if not linkage.active[k]:
        raise InvalidRequest(
            f"bar {bar!r} joins two fixed vertices: its length is their distance and cannot "
            "change",
            loc=loc,
        )
    return k
