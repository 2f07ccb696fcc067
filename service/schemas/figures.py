"""Requests of the figure endpoints (answers are ``image/svg+xml``)."""

from __future__ import annotations

from typing import Literal

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
from service.schemas.space import SpaceOptions

Show = Literal["zero_modes", "tangents", "self_stress"]


class LinkageFigureRequest(Strict):
    model_config = ConfigDict(extra="forbid", json_schema_extra=examples(
        {"linkage": EXAMPLE_LINKAGE, "show": ["zero_modes"],
         "tolerances": EXAMPLE_TOLERANCES}))

    linkage: Linkage
    show: list[Show] = Field(
        default_factory=list, max_length=3,
        description="what to draw on the linkage besides pins, sliders and bars: zero modes or "
        "branch tangents as arrows, the self-stress as bar colours (at a critical configuration)",
    )
    tolerances: Tolerances | None = None


class SpaceFigureRequest(Strict):
    model_config = ConfigDict(extra="forbid", json_schema_extra=examples(
        {"linkage": EXAMPLE_LINKAGE, "tolerances": EXAMPLE_TOLERANCES, "axes": ["L1", "L3"]}))

    linkage: Linkage
    tolerances: Tolerances | None = None
    options: SpaceOptions | None = None
    axes: list[Ident] | None = Field(
        None, min_length=2, max_length=2,
        description="two rotors (bars with one pinned end) whose angles are the axes (default: "
        "the first two rotors)",
    )
