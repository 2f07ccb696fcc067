"""Requests of the figure endpoints: what to draw, and in which format (``format``, or the
request's ``Accept`` header; see :mod:`service.figure_formats`)."""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import ConfigDict, Field

from service.schemas.common import (
    EXAMPLE_LINKAGE,
    EXAMPLE_TOLERANCES,
    Ident,
    Linkage,
    Strict,
    Tolerances,
    examples,
)
from service.schemas.critical_values import CriticalValuesRequest
from service.schemas.space import SpaceOptions
from service.schemas.splitting import SplittingRequest

Show = Literal["zero_modes", "tangents", "self_stress"]
#: The formats a figure can be written in (which figure offers which: figure_formats.OFFERED).
FigureFormat = Literal["svg", "png", "pdf", "tikz", "dxf"]
#: Default and bounds of a PNG's resolution (dots per inch).
DEFAULT_DPI, MIN_DPI, MAX_DPI = 150, 10, 1200


class FigureOutput(Strict):
    """The format of the answer (the figure itself is what the other fields ask for)."""

    format: FigureFormat | None = Field(
        None, description="svg (text as text), png (at `dpi`), pdf, tikz (a tikzpicture: "
        "linkage and configuration-space figures) or dxf (the linkage's geometry for CAD: "
        "linkage figures). Default: the best match of the Accept header, else svg. Given "
        "together with an Accept header, the header must allow it (else 406)",
    )
    dpi: Annotated[int, Field(strict=True, ge=MIN_DPI, le=MAX_DPI)] = Field(
        DEFAULT_DPI, description="dots per inch of a PNG (its pixels: the figure's size in "
        "inches times dpi, at most figure_formats.MAX_PIXELS in all, else 422)",
    )


class _LinkageFigure(Strict):
    model_config = ConfigDict(extra="forbid", json_schema_extra=examples(
        {"linkage": EXAMPLE_LINKAGE, "show": ["zero_modes"],
         "tolerances": EXAMPLE_TOLERANCES},
        {"linkage": EXAMPLE_LINKAGE, "format": "png", "dpi": 200}))

    linkage: Linkage
    show: list[Show] = Field(
        default_factory=list, max_length=3,
        description="what to draw on the linkage besides pins, sliders and bars: zero modes or "
        "branch tangents as arrows, the self-stress as bar colours (at a critical configuration)",
    )
    tolerances: Tolerances | None = None


class _SpaceFigure(Strict):
    model_config = ConfigDict(extra="forbid", json_schema_extra=examples(
        {"linkage": EXAMPLE_LINKAGE, "tolerances": EXAMPLE_TOLERANCES, "axes": ["L1", "L3"]},
        {"linkage": EXAMPLE_LINKAGE, "axes": ["L1", "L3"], "format": "tikz"}))

    linkage: Linkage
    tolerances: Tolerances | None = None
    options: SpaceOptions | None = None
    axes: list[Ident] | None = Field(
        None, min_length=2, max_length=3,
        description="one degree of freedom: two rotors (bars with one pinned end) whose angles "
        "are the axes (default: the first two rotors); two degrees of freedom: three bars with "
        "a moving end whose direction angles are the axes of the surfaces, drawn in 3D "
        "(default: the first three such bars)",
    )


class LinkageFigureRequest(FigureOutput, _LinkageFigure):
    """The linkage figure's request and its format."""


class SpaceFigureRequest(FigureOutput, _SpaceFigure):
    """The configuration-space figure's request and its format."""


class CriticalValuesFigureRequest(FigureOutput, CriticalValuesRequest):
    """``/v1/analysis/critical-values``'s request and the figure's format."""


class SplittingFigureRequest(FigureOutput, SplittingRequest):
    """``/v1/analysis/splitting``'s request and the figure's format."""
