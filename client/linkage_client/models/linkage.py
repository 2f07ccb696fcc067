"""The linkage as the API takes and gives it, and the small answers (health, presets)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Self

import numpy as np

from linkage_client._build import Model, generic
from linkage_client.labelled import Labelled

JSON = dict[str, Any]


def _raw() -> Any:
    return field(default_factory=dict, repr=False, compare=False)


# ---------------------------------------------------------------- the linkage (in and out)


@dataclass(frozen=True)
class Vertex(Model):
    id: str
    position: tuple[float, ...]
    fixed: bool | tuple[bool, ...] = False


@dataclass(frozen=True)
class Bar(Model):
    id: str
    ends: tuple[str, str]
    length: float | None = None


@dataclass(frozen=True)
class Linkage(Model):
    """A bar-and-joint linkage as the API takes and gives it (schema ``Linkage``).

    Examples
    --------
    >>> lk = Linkage.from_json({"vertices": [{"id": "P", "position": [0, 0], "fixed": True},
    ...                                      {"id": "A", "position": [3, 4]}],
    ...                         "bars": [{"id": "r", "ends": ["P", "A"]}]})
    >>> lk.lengths()
    {'r': 5.0}
    """

    vertices: tuple[Vertex, ...]
    bars: tuple[Bar, ...] = ()
    dimension: int = 2

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> Self:
        lk = generic(cls, data)
        if "dimension" not in data and lk.vertices:
            lk = cls(lk.vertices, lk.bars, len(lk.vertices[0].position))
        return lk

    def to_json(self) -> JSON:
        """The request form (every field explicit, ``length`` only where given)."""
        vertices = [{"id": v.id, "position": [float(x) for x in v.position],
                     "fixed": v.fixed if isinstance(v.fixed, bool) else list(v.fixed)}
                    for v in self.vertices]
        bars: list[JSON] = []
        for b in self.bars:
            bar: JSON = {"id": b.id, "ends": list(b.ends)}
            if b.length is not None:
                bar["length"] = float(b.length)
            bars.append(bar)
        return {"dimension": self.dimension, "vertices": vertices, "bars": bars}

    @property
    def vertex_ids(self) -> tuple[str, ...]:
        return tuple(v.id for v in self.vertices)

    @property
    def bar_ids(self) -> tuple[str, ...]:
        return tuple(b.id for b in self.bars)

    @property
    def positions(self) -> Labelled:
        """``(V, d)`` positions, rows in vertex order."""
        return Labelled(self.vertex_ids,
                        np.array([v.position for v in self.vertices], dtype=np.float64)
                        .reshape(len(self.vertices), self.dimension))

    def fixed_axes(self) -> np.ndarray:
        """``(V, d)`` booleans: which axes of each vertex are pinned."""
        return np.array([[v.fixed] * self.dimension if isinstance(v.fixed, bool) else v.fixed
                         for v in self.vertices], dtype=bool).reshape(-1, self.dimension)

    def lengths(self) -> dict[str, float]:
        """Each bar's length: its given ``length``, else the distance of its ends."""
        pos = {v.id: np.asarray(v.position, dtype=np.float64) for v in self.vertices}
        return {b.id: float(b.length) if b.length is not None
                else float(np.linalg.norm(pos[b.ends[0]] - pos[b.ends[1]]))
                for b in self.bars}


def linkage_json(linkage: Linkage | Mapping[str, Any]) -> JSON:
    """A linkage given as a model or as JSON, in the request form."""
    return linkage.to_json() if isinstance(linkage, Linkage) else dict(linkage)


# ---------------------------------------------------------------- shared pieces


@dataclass(frozen=True)
class Health(Model):
    status: str
    version: str


@dataclass(frozen=True)
class Readiness(Model):
    status: str
    version: str
    workers: int


@dataclass(frozen=True)
class PresetInfo(Model):
    name: str
    description: str
    parameters: dict[str, float]
    dimension: int | None = None


@dataclass(frozen=True)
class TolerancesUsed(Model):
    rank_rtol: float
    residual_atol: float
    q_rtol: float


@dataclass(frozen=True)
class CountClaim(Model):
    """How many were found; ``exact`` False: at least that many."""

    count: int | str
    exact: bool


@dataclass(frozen=True)
class ProvedSoFar(Model):
    """What an answer proves, also when incomplete (``search.proved``)."""

    critical_points: CountClaim | None = None
    components: CountClaim | None = None


@dataclass(frozen=True)
class SearchReport(Model):
    complete: bool
    reason: str | None
    time_budget_s: float | None = None
    argument: str | None = None
    argument_detail: str | None = None
    proved: ProvedSoFar | None = None


@dataclass(frozen=True)
class TangentForm(Model):
    vector: Labelled
    orientation: int
    log10_magnitude: float | None



def sequence(data: Any) -> Sequence[Any]:
    if not isinstance(data, list):
        raise TypeError(f"expected a JSON array, got {type(data).__name__}")
    return data
