"""The figures' formats: their media types, which figure offers which, the choice of one from
the request (its ``format`` field or its ``Accept`` header) and the size of a PNG before its
pixels are allocated.

No matplotlib here (the routes import this module to negotiate before any work is done).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from engine.model.errors import InvalidRequest

#: Each format's media type (DXF's is IANA's ``image/vnd.dxf``; TeX has no registered one,
#: ``application/x-tex`` is what ``mimetypes`` and Debian's ``mime.types`` give ``.tex``).
MEDIA_TYPES: dict[str, str] = {
    "svg": "image/svg+xml",
    "png": "image/png",
    "pdf": "application/pdf",
    "tikz": "application/x-tex",
    "dxf": "image/vnd.dxf",
}
#: Other names clients use for the same formats.
ALIASES: dict[str, str] = {"text/x-tex": "tikz", "application/dxf": "dxf",
                           "image/x-dxf": "dxf"}
#: Any figure's bytes: the format is the body's ``format`` (default svg), the answer's
#: Content-Type is this (generated clients read it as bytes: openapi-python-client reads only
#: JSON, ``text/*`` and this media type).
OCTET = "application/octet-stream"
#: The file name extension of each format.
SUFFIXES: dict[str, str] = {"svg": ".svg", "png": ".png", "pdf": ".pdf", "tikz": ".tex",
                            "dxf": ".dxf"}
#: Formats whose bytes are UTF-8 text.
TEXT = frozenset({"svg", "tikz", "dxf"})
#: The formats each figure offers (TikZ: the linkage and the configuration space; DXF: the
#: linkage's geometry).
OFFERED: dict[str, tuple[str, ...]] = {
    "linkage": ("svg", "png", "pdf", "tikz", "dxf"),
    "configuration-space": ("svg", "png", "pdf", "tikz"),
    "critical-values": ("svg", "png", "pdf"),
    "splitting": ("svg", "png", "pdf"),
}
#: The most pixels a PNG may have (width times height): 100 MB of RGBA while it is drawn.
MAX_PIXELS = 25_000_000
#: The smallest size (inches) each figure can have: a PNG larger than MAX_PIXELS at this size
#: is refused before the analysis runs (service.figure_drawing sets the sizes).
MIN_INCHES: dict[str, tuple[float, float]] = {
    "linkage": (6.4, 3.4),
    "configuration-space": (6.0, 6.6),
    "critical-values": (6.0, 6.0),
    "splitting": (4.8, 3.8),
}


@dataclass(frozen=True)
class Choice:
    """The format to draw and the media type to answer with (``OCTET`` or its own)."""

    format: str
    media_type: str


class NotAcceptable(Exception):
    """The Accept header allows none of the formats this figure offers (a 406)."""

    def __init__(self, detail: str) -> None:
        super().__init__(detail)
        self.detail = detail


def _accepted(header: str) -> list[tuple[str, float]]:
    """``(media range, q)`` of an Accept header (RFC 9110 12.5.1; a malformed or
    out-of-range q counts as 0: not acceptable)."""
    out = []
    for item in header.split(","):
        parts = [p.strip() for p in item.split(";")]
        if not parts[0]:
            continue
        q = 1.0
        for param in parts[1:]:
            name, _, value = param.partition("=")
            if name.strip().lower() == "q":
                try:
                    q = float(value)
                except ValueError:
                    q = 0.0
                q = q if 0.0 <= q <= 1.0 else 0.0
        media_range = parts[0].lower()
        out.append((MEDIA_TYPES.get(ALIASES.get(media_range, ""), media_range), q))
    return out


def _quality(ranges: list[tuple[str, float]], media_type: str) -> float:
    """The q the header gives ``media_type``: that of the most specific range matching it
    (``type/subtype`` over ``type/*`` over ``*/*``), 0 when none does."""
    kind = media_type.partition("/")[0]
    for wanted in (media_type, f"{kind}/*", "*/*"):
        found = [q for r, q in ranges if r == wanted]
        if found:
            return max(found)
    return 0.0


def negotiate(figure: str, fmt: str | None, accept: str | None) -> Choice:
    """The format of ``figure`` (a key of :data:`OFFERED`) and the answer's media type.

    Without ``fmt``, the offered format the header gives the highest q (ties: in the order
    of :data:`OFFERED`, svg first), or svg's bytes as ``application/octet-stream`` when that
    is asked for by name with a higher q. With ``fmt``, its own media type if the header
    allows it, else ``application/octet-stream`` if the header names that.

    Parameters
    ----------
    figure : str
        Which figure: ``linkage``, ``configuration-space``, ``critical-values``, ``splitting``.
    fmt : str or None
        The body's ``format`` (None: not given).
    accept : str or None
        The Accept header (None or blank: anything).

    Raises
    ------
    InvalidRequest
        ``fmt`` is a format this figure does not offer (a 422 naming ``format``).
    NotAcceptable
        The header allows none of what is offered, or not ``fmt`` (a 406).

    Examples
    --------
    >>> negotiate("linkage", None, "image/png, image/svg+xml;q=0.5")
    Choice(format='png', media_type='image/png')
    >>> negotiate("splitting", "pdf", None)
    Choice(format='pdf', media_type='application/pdf')
    """
    offered = OFFERED[figure]
    if fmt is not None and fmt not in offered:
        raise InvalidRequest(f"the {figure} figure is offered as {', '.join(offered)}, not as "
                             f"{fmt}", loc=("format",))
    ranges = _accepted(accept) if accept and accept.strip() else [("*/*", 1.0)]
    octet = max((q for r, q in ranges if r == OCTET), default=0.0)
    if fmt is not None:
        if _quality(ranges, MEDIA_TYPES[fmt]) > 0:
            return Choice(fmt, MEDIA_TYPES[fmt])
        if octet > 0:
            return Choice(fmt, OCTET)
        raise NotAcceptable(f"format {fmt!r} is {MEDIA_TYPES[fmt]}, which the Accept header "
                            f"{accept!r} does not allow (nor {OCTET})")
    q, best = max((_quality(ranges, MEDIA_TYPES[f]), -k) for k, f in enumerate(offered))
    if octet > q:
        return Choice("svg", OCTET)
    if q > 0:
        return Choice(offered[-best], MEDIA_TYPES[offered[-best]])
    types = ", ".join(MEDIA_TYPES[f] for f in offered)
    raise NotAcceptable(f"the Accept header {accept!r} allows none of the media types the "
                        f"{figure} figure is offered in: {types} (or {OCTET} with a format "
                        "field)")


def check_pixels(width_in: float, height_in: float, dpi: int) -> tuple[int, int]:
    """The PNG's size in pixels at ``dpi``, or an InvalidRequest naming ``dpi`` and the limit.

    Examples
    --------
    >>> check_pixels(6.4, 5.0, 100)
    (640, 500)
    """
    width, height = math.ceil(width_in * dpi), math.ceil(height_in * dpi)
    if width * height > MAX_PIXELS:
        largest = math.floor(math.sqrt(MAX_PIXELS / (width_in * height_in)))
        raise InvalidRequest(
            f"a {width_in:.3g} x {height_in:.3g} in figure at {dpi} dpi is {width} x {height} "
            f"= {width * height:,} pixels, over the limit of {MAX_PIXELS:,} pixels; at most "
            f"{largest} dpi for this figure", loc=("dpi",))
    return width, height


def check_png_before_drawing(figure: str, fmt: str, dpi: int) -> None:
    """Refuse a PNG that would be too large even at the smallest size ``figure`` can have
    (before any analysis runs; the drawn figure's own size is checked again)."""
    if fmt == "png":
        check_pixels(*MIN_INCHES[figure], dpi)
