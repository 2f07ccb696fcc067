"""Figures: SVG pictures of the analyses, drawn in the engine worker pool (service.figures)."""

from collections.abc import Callable
from typing import Any, TypeVar

from fastapi import APIRouter, Request, Response

from service import figures
from service.bodies import JsonBodyRoute
from service.config import Settings, SettingsDep, with_arrival
from service.errors import problem_responses
from service.schemas.critical_values import CriticalValuesRequest
from service.schemas.figures import LinkageFigureRequest, SpaceFigureRequest
from service.schemas.splitting import SplittingRequest
from service.workers import engine_pool

router = APIRouter(prefix="/v1/figures", tags=["figures"], route_class=JsonBodyRoute)
B = TypeVar("B")
_svg: dict[int | str, dict[str, Any]] = {
    200: {"content": {figures.SVG: {"schema": {"type": "string"}}},
          "description": "an SVG image (self-contained, text as paths)"},
    **problem_responses(400, 413, 422, 503, 504),
}


async def _figure(request: Request, settings: Settings,
                  fn: Callable[[B, Settings], bytes], body: B) -> Response:
    """``fn(body, settings)`` in a worker under the time limit, as ``image/svg+xml``."""
    svg = await engine_pool(request).run(settings.time_limit_s, fn, body,
                                         with_arrival(request, settings))
    return Response(svg, media_type=figures.SVG)


@router.post("/linkage", operation_id="drawLinkage", response_class=Response, responses=_svg)
async def linkage(body: LinkageFigureRequest, request: Request,
                  settings: SettingsDep) -> Response:
    """The linkage at its analysed configuration: pins, sliders with their axis, bars labelled
    by id; on request its zero modes or branch tangents as arrows and its self-stress as bar
    colours."""
    return await _figure(request, settings, figures.linkage_figure, body)


@router.post(
    "/configuration-space", operation_id="drawConfigurationSpace",
    response_class=Response, responses=_svg,
)
async def configuration_space(body: SpaceFigureRequest, request: Request,
                              settings: SettingsDep) -> Response:
    """The components of ``/v1/analysis/configuration-space`` in two rotor angles on the
    torus, each its own colour; critical points marked by kind; segments labelled."""
    return await _figure(request, settings, figures.configuration_space_figure, body)


@router.post(
    "/critical-values", operation_id="drawCriticalValues",
    response_class=Response, responses=_svg,
)
async def critical_values(body: CriticalValuesRequest, request: Request,
                          settings: SettingsDep) -> Response:
    """The slice of ``/v1/analysis/critical-values``: its curves, each region shaded and
    labelled with its number of components."""
    return await _figure(request, settings, figures.critical_values_figure, body)


@router.post("/splitting", operation_id="drawSplitting", response_class=Response, responses=_svg)
async def splitting(body: SplittingRequest, request: Request,
                    settings: SettingsDep) -> Response:
    """For each branch point of ``/v1/analysis/splitting``: the two crossing lines (four
    rays) and the conic the perturbation turns them into, with the rays it joins."""
    return await _figure(request, settings, figures.splitting_figure, body)
