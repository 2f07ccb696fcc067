"""Conversions of the preset catalogue (query overrides in, preset descriptions out)."""

from __future__ import annotations

from collections.abc import Iterable

from engine.catalogue.presets import PRESETS
from engine.model.errors import InvalidParameter
from service.schemas.presets import PresetInfo

#: Default margin of ``/v1/design/splitting``, relative to the median bar length.


def preset_overrides_in(query: Iterable[tuple[str, str]]) -> dict[str, float]:
    """A preset's parameters from a query string, each a number (the engine names unknown
    parameters and values that give no valid linkage)."""
    overrides: dict[str, float] = {}
    for key, raw in query:
        try:
            overrides[key] = float(raw)
        except ValueError:
            raise InvalidParameter(f"not a number: {raw!r}", loc=(key,)) from None
    return overrides


def presets_out() -> list[PresetInfo]:
    return [
        PresetInfo(
            name=p.name, description=p.description, parameters=dict(p.parameters),
            dimension=p.dimension,
        )
        for p in PRESETS.values()
    ]
