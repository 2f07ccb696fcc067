"""Figures: pictures of the analyses in SVG, PNG, PDF, TikZ or DXF, drawn in the engine worker
pool (service.figures, imported there only: see service.operations.draw); the format is the
body's ``format`` or the best the ``Accept`` header allows (service.figure_formats)."""

from collections.abc import Callable
from functools import partial
from typing import Any, TypeVar

from fastapi import APIRouter, Request, Response

from service import figure_formats
from service.bodies import JsonBodyRoute
from service.config import Settings, SettingsDep, with_arrival
from service.errors import problem, problem_responses
from service.operations import draw
from service.schemas.figures import (
    CriticalValuesFigureRequest,
    FigureOutput,
    LinkageFigureRequest,
    SpaceFigureRequest,
    SplittingFigureRequest,
)
from service.workers import engine_pool

router = APIRouter(prefix="/v1/figures", tags=["figures"], route_class=JsonBodyRoute)
B = TypeVar("B", bound=FigureOutput)
_DESCRIBE = {
    "svg": "SVG (text as <text> elements)", "png": "PNG at the body's dpi", "pdf": "PDF, one page",
    "tikz": "TikZ: a tikzpicture for LaTeX", "dxf": "DXF (R2010) of the linkage's geometry",
}


def _responses(figure: str) -> dict[int | str, dict[str, Any]]:
    """The figure's 200 in each offered media type, and ``application/octet-stream`` last
    (the bytes of the body's ``format``: what a generated client that knows no image type,
    such as openapi-python-client's, reads as a file instead of dropping the answer)."""
    offered = figure_formats.OFFERED[figure]
    content: dict[str, Any] = {
        figure_formats.MEDIA_TYPES[f]: {"schema": {"type": "string", "format": "binary"}}
        for f in offered}
    content[figure_formats.OCTET] = {"schema": {"type": "string", "format": "binary"}}
    text = "; ".join(f"{figure_formats.MEDIA_TYPES[f]}: {_DESCRIBE[f]}" for f in offered)
    return {
        200: {"content": content, "description": f"the figure, in the format the body's "
              f"`format` names or the best the Accept header allows ({text}); "
              f"{figure_formats.OCTET}: the bytes of the body's `format` (default svg)"},
        **problem_responses(400, 406, 413, 422, 503, 504),
    }


async def _figure(request: Request, settings: Settings, figure: str, name: str,
                  body: B) -> Response:
    """``service.figures.<name>(body, settings)`` in a worker under the time limit, in the
    negotiated format."""
    try:
        choice = figure_formats.negotiate(figure, body.format, request.headers.get("accept"))
    except figure_formats.NotAcceptable as err:
        return problem(406, "not-acceptable", "Not acceptable", err.detail,
                       [{"loc": ["header", "accept"], "msg": err.detail}])
    figure_formats.check_png_before_drawing(figure, choice.format, body.dpi)
    body = body.model_copy(update={"format": choice.format})
    fn: Callable[[B, Settings], bytes] = partial(draw, name)
    data = await engine_pool(request).run(settings.time_limit_s, fn, body,
                                          with_arrival(request, settings))
    name = f"{figure}{figure_formats.SUFFIXES[choice.format]}"
    return Response(data, media_type=choice.media_type, headers={
        "content-disposition": f'inline; filename="{name}"', "vary": "accept"})


@router.post("/linkage", operation_id="drawLinkage", response_class=Response,
             responses=_responses("linkage"))
async def linkage(body: LinkageFigureRequest, request: Request,
                  settings: SettingsDep) -> Response:
    """The linkage at its analysed configuration: pins, sliders with their axis, bars labelled
    by id; on request its zero modes or branch tangents as arrows and its self-stress as bar
    colours. In SVG, PNG, PDF, TikZ or DXF (its geometry for CAD)."""
    return await _figure(request, settings, "linkage", "linkage_figure", body)


@router.post(
    "/configuration-space", operation_id="drawConfigurationSpace",
    response_class=Response, responses=_responses("configuration-space"),
)
async def configuration_space(body: SpaceFigureRequest, request: Request,
                              settings: SettingsDep) -> Response:
    """The components of ``/v1/analysis/configuration-space`` in two rotor angles on the
    torus, each its own colour; critical points marked by kind; segments labelled. In SVG,
    PNG, PDF or TikZ."""
    return await _figure(request, settings, "configuration-space",
                         "configuration_space_figure", body)


@router.post(
    "/critical-values", operation_id="drawCriticalValues",
    response_class=Response, responses=_responses("critical-values"),
)
async def critical_values(body: CriticalValuesFigureRequest, request: Request,
                          settings: SettingsDep) -> Response:
    """The slice of ``/v1/analysis/critical-values``: its curves, each region shaded and
    labelled with its number of components. In SVG, PNG or PDF."""
    return await _figure(request, settings, "critical-values", "critical_values_figure",
                         body)


@router.post("/splitting", operation_id="drawSplitting", response_class=Response,
             responses=_responses("splitting"))
async def splitting(body: SplittingFigureRequest, request: Request,
                    settings: SettingsDep) -> Response:
    """For each branch point of ``/v1/analysis/splitting``: the two crossing lines (four
    rays) and the conic the perturbation turns them into, with the rays it joins. In SVG, PNG
    or PDF."""
    return await _figure(request, settings, "splitting", "splitting_figure", body)
