"""The operations a job (or the command line) may run: each analysis or figure endpoint's
request schema and the work behind it. No Dask here: the command line runs them in-process."""

from __future__ import annotations

import base64
import inspect
from collections.abc import Callable
from dataclasses import dataclass
from importlib import import_module
from typing import Any

from pydantic import BaseModel

from service import jobs
from service.config import Settings
from service.schemas.common import AnalysisRequest
from service.schemas.critical_values import CriticalValuesRequest
from service.schemas.design import DesignRequest
from service.schemas.figures import (
    CriticalValuesFigureRequest,
    LinkageFigureRequest,
    SpaceFigureRequest,
    SplittingFigureRequest,
)
from service.schemas.jobs import SweepRequest
from service.schemas.robustness import RobustnessRequest
from service.schemas.space import SpaceRequest
from service.schemas.splitting import SplittingRequest

__all__ = ["OPERATIONS", "REQUESTS", "SWEEPS", "Operation", "draw"]


@dataclass(frozen=True)
class Operation:
    """An analysis endpoint's request schema and the work behind it (its answer: a model, or
    for a figure the SVG's text, served with ``media_type`` by ``/v1/jobs/{id}/result``, or
    a ``data:`` URL of another format, served decoded with its own media type)."""

    request: type[BaseModel]
    run: Callable[..., BaseModel | str]
    media_type: str = "application/json"


#: A figure's media type (``service.figures.SVG``, named here so that matplotlib is imported
#: only when a figure is drawn: 1.5 s of the command line's start otherwise).
SVG = "image/svg+xml"
#: What a figure job's answer in another format than SVG starts with (RFC 2397).
DATA_URL = "data:"


def figure_text(data: bytes, fmt: str | None) -> str:
    """A figure as a job's answer (a JSON string): an SVG's text as it is, any other format
    as a ``data:`` URL with its media type, base64 (RFC 2397)."""
    if fmt in (None, "svg"):
        return data.decode("utf-8")
    from service.figure_formats import MEDIA_TYPES

    return f"{DATA_URL}{MEDIA_TYPES[fmt]};base64,{base64.b64encode(data).decode('ascii')}"


def figure_bytes(text: str) -> tuple[bytes, str]:
    """A figure job's answer back to its bytes and media type (the inverse of figure_text)."""
    if not text.startswith(DATA_URL):
        return text.encode("utf-8"), SVG
    head, _, data = text.partition(",")
    return base64.b64decode(data, validate=True), head[len(DATA_URL):].split(";")[0]


#: The module that draws figures (matplotlib: 0.5-0.8 s of a core to import), named here
#: and imported only where a figure is drawn: the engine workers (their forkserver has loaded it
#: before forking them: ``service.forkserver.PRELOAD``), a Dask worker or the command line, never
#: the service process, whose start-up it would lengthen.
FIGURES = "service.figures"


def draw(name: str, body: Any, settings: Settings) -> bytes:
    """``service.figures.<name>(body, settings)``: a figure route's work, run in an engine
    worker (``functools.partial(draw, name)`` pickles by name, so the service process that
    schedules it never imports the figures)."""
    fn: Callable[[Any, Settings], bytes] = getattr(import_module(FIGURES), name)
    return fn(body, settings)


def _figure_job(draw: str) -> Callable[[Any, Settings], str]:
    """A figure as a job's answer: ``service.figures.<draw>``'s figure as text (a JSON
    string in the job: see figure_text)."""

    def figure(body: Any, settings: Settings, deadline: Any = None) -> str:
        fn = getattr(import_module(FIGURES), draw)
        # the job's deadline (its time limit, cancel flag and progress) for the search
        given = "deadline" in inspect.signature(fn).parameters and deadline is not None
        data: bytes = fn(body, settings, **({"deadline": deadline} if given else {}))
        return figure_text(data, body.format)

    figure.__name__ = draw
    return figure


#: The operations a job may run: the analysis endpoints' paths (without ``/v1/``).
OPERATIONS: dict[str, Operation] = {
    "analysis/rigidity": Operation(AnalysisRequest, jobs.rigidity),
    "analysis/second-order": Operation(AnalysisRequest, jobs.second_order_analysis),
    "analysis/critical-points": Operation(SpaceRequest, jobs.critical_points),
    "analysis/configuration-space": Operation(SpaceRequest, jobs.configuration_space),
    "analysis/splitting": Operation(SplittingRequest, jobs.splitting),
    "analysis/robustness": Operation(RobustnessRequest, jobs.robustness_margin),
    "analysis/critical-values": Operation(CriticalValuesRequest, jobs.critical_values),
    "design/splitting": Operation(DesignRequest, jobs.design_splitting),
    "figures/linkage": Operation(LinkageFigureRequest, _figure_job("linkage_figure"), SVG),
    "figures/configuration-space": Operation(
        SpaceFigureRequest, _figure_job("configuration_space_figure"), SVG),
    "figures/critical-values": Operation(
        CriticalValuesFigureRequest, _figure_job("critical_values_figure"), SVG),
    "figures/splitting": Operation(SplittingFigureRequest, _figure_job("splitting_figure"), SVG),
}
#: A sweep is a job too (``POST /v1/sweeps``, or ``POST /v1/jobs`` with this operation).
SWEEPS = "sweeps"
REQUESTS: dict[str, type[BaseModel]] = {
    **{name: op.request for name, op in OPERATIONS.items()}, SWEEPS: SweepRequest
}
