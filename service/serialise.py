"""JSON answers with orjson: the same JSON data as pydantic's ``model_dump_json(by_alias=True)``,
several times faster on answers with many points (a configuration space of 10^5 points is some
10^6 floats), and numpy arrays serialised as they are (``OPT_SERIALIZE_NUMPY``).

Non-finite floats (NaN, +-Infinity) become ``null``, as they do with pydantic's default
(``ser_json_inf_nan="null"``): a JSON answer never holds a bare ``NaN``. Errors
(``application/problem+json``) are built in :mod:`service.errors` and do not come here.

Large strings that need no escaping (the base64 of the compact point arrays, megabytes per
component) are spliced in by :func:`dumps_parts` instead of going through orjson: a model names
them in its class variable ``raw_json_fields`` (string fields holding only characters JSON
writes as they are: no quote, backslash or control character), and the answer is written as a
few chunks, the document's JSON around the strings' own bytes, with no pass over those bytes
but one copy (orjson checks each character of a string for escapes: some 10 ms for the 10 MB
of a 120,000-point answer).
"""

from __future__ import annotations

from typing import Any

import orjson
from pydantic import BaseModel
from starlette.responses import Response

_OPTIONS = orjson.OPT_SERIALIZE_NUMPY | orjson.OPT_NON_STR_KEYS


#: A spliced string's place in :func:`dumps_parts`'s document: orjson escapes every control
#: character inside strings (``\u0000``), so a raw NUL byte occurs nowhere else in its output.
_MARK = b"\x00"


def _fields(model: BaseModel) -> dict[str, Any]:
    """A model's fields by their serialised names (``serialization_alias``, else ``alias``), one
    level deep, then the extra fields of ``extra="allow"`` models: orjson calls this again for
    the models inside. The response schemas have no
    computed or excluded fields and no custom serialisers; tests/service/test_serialise.py
    checks every answer against pydantic's own JSON."""
    out = {}
    for name, info in type(model).model_fields.items():
        if info.exclude:
            continue
        out[info.serialization_alias or info.alias or name] = getattr(model, name)
    if model.__pydantic_extra__:  # extra="allow" (e.g. the search report's own counts)
        out.update(model.__pydantic_extra__)
    return out


class RawJSON:
    """JSON bytes kept as they came (a job's answer, serialised by its worker): written into an
    answer as they are (``orjson.Fragment``), parsed only by :meth:`value`. Parsing a large
    answer in the service (10^6 floats and lists for a configuration space of 10^5 points)
    took seconds, and serialising it again for each ``GET`` as long again."""

    __slots__ = ("data", "fragment")

    def __init__(self, data: bytes) -> None:
        self.data = data
        self.fragment = orjson.Fragment(data)

    def value(self) -> Any:
        return orjson.loads(self.data)


def _default(obj: Any) -> Any:
    if isinstance(obj, BaseModel):
        return _fields(obj)
    if isinstance(obj, RawJSON):
        return obj.fragment
    raise TypeError(f"type {type(obj).__name__} is not JSON serialisable")


def dumps(obj: Any) -> bytes:
    """``obj`` (a response model, or plain JSON data) as JSON bytes."""
    return orjson.dumps(obj, default=_default, option=_OPTIONS)


def dumps_parts(obj: Any) -> list[bytes]:
    """``obj`` as JSON in chunks whose concatenation is ``dumps(obj)``: the fields named in a
    model's ``raw_json_fields`` (ASCII strings needing no escape) are chunks of their own,
    copied once, not serialised by orjson."""
    spliced: list[bytes] = []

    def default(value: Any) -> Any:
        if not isinstance(value, BaseModel):
            return _default(value)
        out = _fields(value)
        for name in getattr(value, "raw_json_fields", ()):
            text = getattr(value, name)
            if isinstance(text, str) and text.isascii():  # isascii: O(1) on a str
                out[name] = orjson.Fragment(b'"' + _MARK + str(len(spliced)).encode() + _MARK
                                            + b'"')
                spliced.append(text.encode("ascii"))
        return out

    document = orjson.dumps(obj, default=default, option=_OPTIONS)
    if not spliced:
        return [document]
    pieces = document.split(_MARK)  # text, index, text, index, ..., text
    parts = [pieces[0]]
    for index, text in zip(pieces[1::2], pieces[2::2], strict=True):
        parts += [spliced[int(index)], text]
    return parts


def loads(data: bytes | str) -> Any:
    return orjson.loads(data)


class FastJSONResponse(Response):
    """``application/json`` serialised by :func:`dumps` (models, dicts, numpy arrays)."""

    media_type = "application/json"

    def render(self, content: Any) -> bytes:
        return dumps(content)
