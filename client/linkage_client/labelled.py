"""Arrays whose one axis is named by ids (vertices or bars), and the packed arrays of the API."""

from __future__ import annotations

import base64
import binascii
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

#: The only dtype the service packs (little-endian IEEE 754 float64, docs/API.md).
PACKED_DTYPE = "<f8"


@dataclass(frozen=True, eq=False)
class Labelled:
    """A float64 array whose axis ``axis`` is named by ``ids`` in order.

    Per-vertex vectors (a zero mode, a configuration) are ``(V, d)`` with ``axis=0``; a traced
    component's positions are ``(n, V, d)`` and its rotor angles ``(n, R)``, both with
    ``axis=1``. ``labelled["A"]`` is the slice of vertex (or bar) ``A``.

    Examples
    --------
    >>> z = Labelled.from_mapping({"A": [0.0, 1.0], "B": [0.0, 0.5]})
    >>> z.array.shape, z["B"].tolist()
    ((2, 2), [0.0, 0.5])
    """

    ids: tuple[str, ...]
    array: np.ndarray
    axis: int = 0

    def __post_init__(self) -> None:
        if self.array.ndim <= self.axis or self.array.shape[self.axis] != len(self.ids):
            raise ValueError(f"{len(self.ids)} ids do not name axis {self.axis} of an array "
                             f"of shape {self.array.shape}")

    @classmethod
    def from_mapping(cls, data: Mapping[str, Any], dimension: int | None = None) -> Labelled:
        """``{id: value or [x, y(, z)]}`` (the API's per-vertex and per-bar objects)."""
        values = list(data.values())
        array = np.asarray(values, dtype=np.float64)
        if not values and dimension is not None:
            array = np.empty((0, dimension))
        return cls(tuple(data), array, 0)

    @classmethod
    def from_series(cls, data: Mapping[str, Sequence[Any]]) -> Labelled:
        """``{id: [p0, p1, ...]}`` (a component's points in the default form): ids on axis 1."""
        if not data:
            return cls((), np.empty((0, 0)), 1)
        return cls(tuple(data), np.stack([np.asarray(v, dtype=np.float64) for v in data.values()],
                                         axis=1), 1)

    @classmethod
    def from_packed(cls, packed: Mapping[str, Any]) -> Labelled:
        """A ``PackedArray`` (``{ids, shape, dtype, base64}``) decoded: ids on axis 1."""
        return cls(tuple(packed["ids"]), decode_packed(packed), 1)

    def __getitem__(self, key: str) -> np.ndarray:
        try:
            k = self.ids.index(key)
        except ValueError:
            raise KeyError(key) from None
        return np.take(self.array, k, axis=self.axis)

    def __contains__(self, key: object) -> bool:
        return key in self.ids

    def __iter__(self) -> Iterator[str]:
        return iter(self.ids)

    def __len__(self) -> int:
        return len(self.ids)

    def to_dict(self) -> dict[str, Any]:
        """Back to the API's ``{id: list}`` form."""
        return {i: np.take(self.array, k, axis=self.axis).tolist() for k, i in enumerate(self.ids)}

    def __repr__(self) -> str:
        return f"Labelled(ids={list(self.ids)!r}, shape={self.array.shape}, axis={self.axis})"


def decode_packed(packed: Mapping[str, Any]) -> np.ndarray:
    """The array of a ``PackedArray``: ``shape`` float64 values in C order, RFC 4648 base64.

    Raises ``ValueError`` on a dtype other than ``<f8``, invalid base64, or a byte count that
    does not match the shape (a truncated or altered answer).
    """
    if packed.get("dtype") != PACKED_DTYPE:
        raise ValueError(f"packed array dtype {packed.get('dtype')!r}, expected {PACKED_DTYPE}")
    shape = tuple(int(n) for n in packed["shape"])
    try:
        raw = base64.b64decode(packed["base64"], validate=True)
    except binascii.Error as exc:
        raise ValueError(f"packed array base64 is invalid: {exc}") from None
    expected = int(np.prod(shape, dtype=np.int64)) * 8
    if len(raw) != expected:
        raise ValueError(f"packed array has {len(raw)} bytes, shape {shape} needs {expected}")
    return np.frombuffer(raw, dtype=PACKED_DTYPE).reshape(shape)
