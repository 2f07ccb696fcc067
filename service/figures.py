"""Figures of the service's answers: SVG drawn by matplotlib's SVG backend.

Each figure job runs the job of the JSON endpoint it pictures (:mod:`service.jobs`, or the same
engine calls and mappers) and draws the *response model*, so a figure shows exactly what the
JSON answer says. The jobs are module-level functions of picklable arguments, run in the engine
worker pool under the time limit like every analysis (:func:`service.workers.EnginePool.run`).

Drawn elements carry SVG ids (matplotlib's ``gid``) so that clients and tests can find them:
``bar-<k>``, ``pin-<k>``, ``vertex-<k>``, ``slider-<k>``, ``zero-mode-<j>``, ``tangent-<j>``
(linkage); ``component-<k>-<piece>``, ``critical-<kind>-<index>``, ``segment-<k>`` (configuration
space); ``cv-curve-<k>``, ``cv-regions``, ``region-<k>-<components>``, ``current-lengths``
(critical values);
``ray-<b>-<r>``, ``split-<b>-<i>-<j>`` (splitting: branch point ``b``, ray ``r``, joined rays
``i``, ``j``; ``panels-left-out-<k>`` where the time left drew only the first panels).

Only the object-oriented API is used (``Figure``, no ``pyplot``): no global figure state, so
figures may be drawn in any thread or process. Text is drawn as paths (``svg.fonttype``), so an
SVG needs no font to render the same everywhere.
"""

from __future__ import annotations

import contextlib
import io
from collections.abc import Callable
from typing import Any

import matplotlib as mpl
from matplotlib.figure import Figure

from engine.model.errors import InvalidRequest
from service import jobs
from service.config import Settings
from service.figure_drawing import (
    _draw_critical_values,
    _draw_linkage,
    _draw_space,
    _draw_splitting,
    _rotors,
    panels_in_time,
)
from service.schemas import critical_values as cv_schemas
from service.schemas import space
from service.schemas import splitting as splitting_schemas
from service.schemas.common import AnalysisRequest
from service.schemas.figures import LinkageFigureRequest, SpaceFigureRequest

SVG = "image/svg+xml"
#: Seconds past the search's deadline that drawing a figure may take (a share of the margin
#: an answer may come after its time budget).
DRAW_SECONDS = 0.5


# -- jobs (run in the engine worker pool) -----------------------------------------------------


def linkage_figure(body: LinkageFigureRequest, settings: Settings) -> bytes:
    """The linkage at its analysed configuration, with what ``body.show`` asks for."""
    req = AnalysisRequest(linkage=body.linkage, tolerances=body.tolerances)
    if {"tangents", "self_stress"} & set(body.show):
        ans: object = jobs.second_order_analysis(req, settings)
    else:
        ans = jobs.rigidity(req, settings)
    return _svg(_draw_linkage, body.linkage, ans, body.show)


def configuration_space_figure(body: SpaceFigureRequest, settings: Settings) -> bytes:
    """The components in two rotor angles, critical points by kind, segments labelled."""
    if body.linkage.dimension != 2:
        raise InvalidRequest(
            "the configuration-space figure draws the components in the angles of two rotors "
            "in the plane; this linkage is 3D (its components are in the JSON answer of "
            "/v1/analysis/configuration-space)", loc=("linkage", "dimension"))
    rotors = _rotors(body.linkage)
    if body.axes is None:
        if len(rotors) < 2:
            raise InvalidRequest(
                f"the linkage has {len(rotors)} rotor(s) (bars with exactly one pinned end); "
                "the figure needs two for its axes", loc=("linkage", "bars"))
        axes = list(rotors)[:2]
    else:
        axes = list(body.axes)
        for k, bar in enumerate(axes):
            if bar not in rotors:
                raise InvalidRequest(
                    f"{bar!r} is not a rotor (a bar with exactly one pinned end); rotors: "
                    f"{', '.join(rotors) or 'none'}", loc=("axes", k))
        if axes[0] == axes[1]:
            raise InvalidRequest("the two axes must be different rotors", loc=("axes", 1))
    # the figure reads the per-vertex lists: the compact form is for clients of the JSON
    options = None if body.options is None else body.options.model_copy(update={"points": None})
    req = space.SpaceRequest(linkage=body.linkage, tolerances=body.tolerances, options=options)
    ans = jobs.configuration_space(req, settings)
    return _svg(_draw_space, ans, axes, rotors)


def critical_values_figure(body: cv_schemas.CriticalValuesRequest, settings: Settings) -> bytes:
    """The slice: curves, regions shaded and labelled with their component counts."""
    ans = jobs.critical_values(body, settings)
    return _svg(_draw_critical_values, body, ans)


def splitting_figure(body: splitting_schemas.SplittingRequest, settings: Settings) -> bytes:
    """Each branch point's crossing rays and the conic they become under the perturbation."""
    deadline = jobs.search_deadline(body.options, settings, None)
    ans, points = jobs.splitting_with_points(body, settings, deadline)
    # the panels that fit the time left and the drawing's share of the margin past it
    panels = panels_in_time(deadline.remaining() + DRAW_SECONDS)
    return _svg(_draw_splitting, body, ans, points, panels)


# -- shared ------------------------------------------------------------------------------------


def _style() -> contextlib.AbstractContextManager[None]:
    return mpl.rc_context({
        "svg.fonttype": "path",  # self-contained: no font needed where the SVG is shown
        "svg.hashsalt": "linkage-figures",  # stable ids: the same answer gives the same bytes
        "font.size": 9.0,
        "axes.titlesize": 10.0,
    })


def _svg(draw: Callable[..., Figure], *args: Any) -> bytes:
    """``draw(*args)`` as SVG, drawn and saved in the house style."""
    buf = io.BytesIO()
    with _style():
        draw(*args).savefig(buf, format="svg", metadata={"Date": None}, facecolor="white")
    return buf.getvalue()
