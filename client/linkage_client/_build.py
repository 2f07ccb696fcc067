"""Answers (JSON) to the typed models: one builder driven by the dataclasses' type hints."""

from __future__ import annotations

import dataclasses
import types
import typing
from collections.abc import Mapping
from functools import cache
from typing import Any, Self, TypeVar, Union

import numpy as np

from linkage_client.labelled import Labelled

T = TypeVar("T")


def json_name(f: dataclasses.Field[Any]) -> str:
    """The answer's key of a model field (``from_`` is ``from``)."""
    return str(f.metadata.get("json", f.name))


@cache
def _hints(cls: Any) -> dict[str, Any]:
    return typing.get_type_hints(cls)


def build(cls: type[T], data: Any) -> T:
    """``data`` (decoded JSON) as an instance of the dataclass ``cls``.

    Keys the model does not know are ignored (the contract lets the service add fields); the
    whole answer stays on ``raw`` where the model has that field.
    """
    if not isinstance(data, Mapping):
        raise TypeError(f"{cls.__name__} expects a JSON object, got {type(data).__name__}")
    return typing.cast(T, cls.from_json(data))  # type: ignore[attr-defined]


def generic(cls: type[T], data: Mapping[str, Any]) -> T:
    """The field-by-field construction that ``Model.from_json`` does unless a model has its own."""
    hints = _hints(typing.cast(Any, cls))
    kwargs: dict[str, Any] = {}
    for f in dataclasses.fields(cls):  # type: ignore[arg-type]
        if f.name == "raw":
            kwargs["raw"] = dict(data)
            continue
        key = json_name(f)
        if key in data:
            kwargs[f.name] = convert(hints[f.name], data[key])
    return cls(**kwargs)


def convert(tp: Any, value: Any) -> Any:
    """``value`` converted to the annotation ``tp`` (dataclasses, arrays, containers)."""
    if value is None:
        return None
    origin = typing.get_origin(tp)
    if origin in (Union, types.UnionType):
        return _union(typing.get_args(tp), value)
    if tp is np.ndarray:
        return np.asarray(value, dtype=np.float64)
    if tp is Labelled:
        return Labelled.from_mapping(value)
    if dataclasses.is_dataclass(tp) and isinstance(tp, type):
        return build(tp, value)
    if origin is list:
        (item,) = typing.get_args(tp)
        return [convert(item, v) for v in value]
    if origin is tuple:
        args = typing.get_args(tp)
        if len(args) == 2 and args[1] is Ellipsis:
            return tuple(convert(args[0], v) for v in value)
        return tuple(convert(a, v) for a, v in zip(args, value, strict=True))
    if origin is dict:
        _, item = typing.get_args(tp)
        return {k: convert(item, v) for k, v in value.items()}
    return value


def _union(args: tuple[Any, ...], value: Any) -> Any:
    options = [a for a in args if a is not type(None)]
    if len(options) == 1:
        return convert(options[0], value)
    for option in options:  # dataclasses: the first whose required keys are all present
        if isinstance(option, type) and dataclasses.is_dataclass(option) \
                and isinstance(value, Mapping):
            required = {json_name(f) for f in dataclasses.fields(option)
                        if f.default is dataclasses.MISSING
                        and f.default_factory is dataclasses.MISSING}
            if required <= set(value):
                return build(option, value)
    for option in options:  # containers by the JSON type
        origin = typing.get_origin(option) or option
        if origin is tuple:
            origin = list  # a JSON array
        if isinstance(origin, type) and isinstance(value, origin):
            return convert(option, value)
    return value


class Model:
    """Base of the answer models: ``Model.from_json(data)`` builds one from decoded JSON."""

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> Self:
        return generic(cls, data)
