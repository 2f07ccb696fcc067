"""Conversions of the preset catalogue (query overrides in, preset descriptions out)."""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

from engine.catalogue.presets import PRESETS, Bounds
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


def parameter_schema(bounds: Bounds) -> dict[str, Any]:
    """The JSON-schema keywords of a preset parameter's bounds (the engine's, so that the
    OpenAPI schema offers only what the engine takes); ``below`` has no keyword: it is said
    in the description (:func:`parameter_description`)."""
    out: dict[str, Any] = {}
    if bounds.minimum is not None:
        out["minimum"] = bounds.minimum
    if bounds.exclusive_minimum is not None:
        out["exclusiveMinimum"] = bounds.exclusive_minimum
    if bounds.maximum is not None:
        out["maximum"] = bounds.maximum
    if bounds.multiple_of is not None:
        out["multipleOf"] = bounds.multiple_of
    if bounds.choices:
        out["enum"] = list(bounds.choices)
    return out


def parameter_description(default: float, bounds: Bounds) -> str:
    """A preset parameter's description: what it is, its default and its bounds in words."""
    kind = "a number" if bounds.multiple_of is None else (
        "an integer" if bounds.multiple_of == 1 else f"a multiple of {bounds.multiple_of:g}")
    parts = [f"{kind}, default {default:g}"]
    if bounds.exclusive_minimum is not None:
        parts.append(f"> {bounds.exclusive_minimum:g}")
    if bounds.choices:
        parts.append("one of " + ", ".join(f"{c:g}" for c in bounds.choices))
    if bounds.minimum is not None or bounds.maximum is not None:
        low = "" if bounds.minimum is None else f"{bounds.minimum:g} <= "
        high = "" if bounds.maximum is None else f" <= {bounds.maximum:g}"
        parts.append(f"{low}value{high}")
    if bounds.below is not None:
        parts.append(f"less than {bounds.below}")
    return "; ".join(parts)


def presets_out() -> list[PresetInfo]:
    return [
        PresetInfo(
            name=p.name, description=p.description, parameters=dict(p.parameters),
            dimension=p.dimension,
        )
        for p in PRESETS.values()
    ]
