"""Figures of the service's answers: SVG, PNG and PDF drawn by matplotlib, TikZ
(:mod:`service.figure_tikz`) and DXF (:mod:`service.figure_dxf`) written from the same answers;
the format is the body's ``format`` (the routes set it from the Accept header when it is not
given: :mod:`service.figure_formats`).

Each figure job runs the job of the JSON endpoint it pictures (:mod:`service.jobs`, or the same
engine calls and mappers) and draws the *response model*, so a figure shows exactly what the
JSON answer says. The jobs are module-level functions of picklable arguments, run in the engine
worker pool under the time limit like every analysis (:func:`service.workers.EnginePool.run`);
the command line runs them in its own process with a ``deadline`` for the search (the drawing
after it is bounded by the answer's size: the engine's point limit, a PNG's pixel limit).

Drawn elements carry SVG ids (matplotlib's ``gid``) so that clients and tests can find them:
``bar-<k>``, ``pin-<k>``, ``vertex-<k>``, ``slider-<k>``, ``zero-mode-<j>``, ``tangent-<j>``
(linkage; over ``NAMED_BARS_MAX`` bars one collection ``bars`` and ``pins``, ``sliders``,
``vertices``, unnamed); ``component-<k>-<piece>``, ``critical-<kind>-<index>``,
``segment-<k>`` (configuration space; with two degrees of freedom ``surface-<k>``,
``height-critical-<i>`` and ``critical-<kind>-<index>``, :mod:`service.figure_surface`);
``cv-curve-<k>``, ``cv-regions``, ``region-<k>-<components>``, ``current-lengths``
(critical values);
``ray-<b>-<r>``, ``split-<b>-<i>-<j>`` (splitting: branch point ``b``, ray ``r``, joined rays
``i``, ``j``; ``panels-left-out-<k>`` where the time left drew only the first panels).

Only the object-oriented API is used (``Figure``, no ``pyplot``): no global figure state, so
figures may be drawn in any thread or process. An SVG's text is ``<text>`` (``svg.fonttype``
none: searchable, selectable, editable; a viewer without DejaVu Sans substitutes its own font);
a PDF embeds its fonts. A PNG's pixels are counted before they are allocated
(:func:`service.figure_formats.check_pixels`).
"""

from __future__ import annotations

import contextlib
import io
from collections.abc import Callable
from typing import Any

import matplotlib as mpl
from matplotlib.figure import Figure

from engine.model.budget import Deadline
from engine.model.errors import InvalidRequest
from service import figure_tikz, jobs
from service.config import Settings
from service.figure_drawing import (
    _draw_critical_values,
    _draw_linkage,
    _draw_space,
    _rotors,
)
from service.figure_formats import MEDIA_TYPES, check_pixels, check_png_before_drawing, negotiate
from service.figure_splitting import _draw_splitting, panels_in_time
from service.figure_surface import degrees_of_freedom, draw_surfaces, surface_axes
from service.schemas import space
from service.schemas.common import AnalysisRequest
from service.schemas.figures import (
    CriticalValuesFigureRequest,
    FigureOutput,
    LinkageFigureRequest,
    SpaceFigureRequest,
    SplittingFigureRequest,
)

SVG = MEDIA_TYPES["svg"]
#: Seconds past the search's deadline that drawing a figure may take (a share of the margin
#: an answer may come after its time budget).
DRAW_SECONDS = 0.5


# -- jobs (run in the engine worker pool) -----------------------------------------------------


def linkage_figure(body: LinkageFigureRequest, settings: Settings) -> bytes:
    """The linkage at its analysed configuration, with what ``body.show`` asks for."""
    fmt = _format("linkage", body)
    req = AnalysisRequest(linkage=body.linkage, tolerances=body.tolerances)
    if {"tangents", "self_stress"} & set(body.show):
        ans: object = jobs.second_order_analysis(req, settings)
    else:
        ans = jobs.rigidity(req, settings)
    if fmt == "tikz":
        return figure_tikz.linkage(body.linkage, ans, body.show)
    if fmt == "dxf":
        # ezdxf on the first DXF only: 0.22 s of a core that the workers' forkserver (which
        # preloads this module) would otherwise spend before the service is ready
        from service import figure_dxf

        return figure_dxf.linkage(body.linkage, ans, body.show)
    return _render(body, _draw_linkage, body.linkage, ans, body.show)


def configuration_space_figure(body: SpaceFigureRequest, settings: Settings,
                               deadline: Deadline | None = None) -> bytes:
    """The components in two rotor angles, critical points by kind, segments labelled; with
    two degrees of freedom the surfaces in three bar angles."""
    fmt = _format("configuration-space", body)
    if body.linkage.dimension != 2:
        raise InvalidRequest(
            "the configuration-space figure draws the components in the angles of two rotors "
            "in the plane; this linkage is 3D (its components are in the JSON answer of "
            "/v1/analysis/configuration-space)", loc=("linkage", "dimension"))
    if degrees_of_freedom(body.linkage) == 2:
        return _surface_figure(body, settings, fmt, deadline)
    rotors = _rotors(body.linkage)
    if body.axes is not None and len(body.axes) != 2:
        raise InvalidRequest("a one-degree-of-freedom linkage's figure takes two axes (rotors)",
                             loc=("axes",))
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
    ans = jobs.configuration_space(req, settings, deadline)
    if fmt == "tikz":
        return figure_tikz.configuration_space(ans, axes, rotors)
    return _render(body, _draw_space, ans, axes, rotors)


def _surface_figure(body: SpaceFigureRequest, settings: Settings, fmt: str,
                    deadline: Deadline | None) -> bytes:
    """Two degrees of freedom: the answer's surfaces in the angles of three bars
    (:mod:`service.figure_surface`); SVG, PNG or PDF."""
    if fmt not in ("svg", "png", "pdf"):
        raise InvalidRequest(f"the figure of a two-degree-of-freedom linkage's surfaces is "
                             f"drawn in svg, png or pdf, not {fmt}", loc=("format",))
    axes = surface_axes(body.linkage, body.axes)
    options = None if body.options is None else body.options.model_copy(update={"points": None})
    req = space.SpaceRequest(linkage=body.linkage, tolerances=body.tolerances, options=options)
    ans = jobs.configuration_space(req, settings, deadline)
    return _render(body, draw_surfaces, ans, axes)


def critical_values_figure(body: CriticalValuesFigureRequest, settings: Settings,
                           deadline: Deadline | None = None) -> bytes:
    """The slice: curves, regions shaded and labelled with their component counts."""
    _format("critical-values", body)
    ans = jobs.critical_values(body, settings, deadline)
    return _render(body, _draw_critical_values, body, ans)


def splitting_figure(body: SplittingFigureRequest, settings: Settings,
                     deadline: Deadline | None = None) -> bytes:
    """Each branch point's crossing rays and the conic they become under the perturbation."""
    _format("splitting", body)
    if degrees_of_freedom(body.linkage) == 2:
        raise InvalidRequest(
            "the splitting figure draws the branch points of one degree of freedom; a "
            "two-degree-of-freedom linkage's cones and their resolution are in the JSON answer "
            "of /v1/analysis/splitting (surface)", loc=("linkage",))
    deadline = deadline or jobs.search_deadline(body.options, settings, None)
    ans, points = jobs.splitting_with_points(body, settings, deadline)
    # the panels that fit the time left and the drawing's share of the margin past it (all
    # without a finite deadline)
    left = deadline.remaining()
    panels = None if left == float("inf") else panels_in_time(left + DRAW_SECONDS)
    return _render(body, _draw_splitting, body, ans, points, panels)


# -- shared ------------------------------------------------------------------------------------


#: Metadata that would make the same figure differ from one drawing to the next: left out.
_METADATA: dict[str, dict[str, Any]] = {
    "svg": {"Date": None}, "pdf": {"CreationDate": None, "ModDate": None}, "png": {},
}


def _format(figure: str, body: FigureOutput) -> str:
    """The body's format (default svg), checked against what ``figure`` offers, and a PNG's
    resolution against the smallest size the figure can have, before any work."""
    fmt = negotiate(figure, body.format, None).format
    check_png_before_drawing(figure, fmt, body.dpi)
    return fmt


def _style() -> contextlib.AbstractContextManager[None]:
    return mpl.rc_context({
        "svg.fonttype": "none",  # text as <text>, not paths (searchable, editable)
        "pdf.fonttype": 42,  # TrueType fonts embedded whole (editable in Illustrator etc.)
        "svg.hashsalt": "linkage-figures",  # stable ids: the same answer gives the same bytes
        "font.size": 9.0,
        "axes.titlesize": 10.0,
    })


def _render(body: FigureOutput, draw: Callable[..., Figure], *args: Any) -> bytes:
    """``draw(*args)`` in the body's format (svg, png at ``body.dpi``, pdf), in the house
    style; a PNG's pixels are counted on the drawn figure before any is allocated."""
    fmt = body.format or "svg"
    buf = io.BytesIO()
    with _style():
        fig = draw(*args)
        dpi: float | str = "figure"
        if fmt == "png":
            width, height = (float(v) for v in fig.get_size_inches())
            check_pixels(width, height, body.dpi)
            dpi = body.dpi
        fig.savefig(buf, format=fmt, dpi=dpi, metadata=_METADATA[fmt], facecolor="white")
    return buf.getvalue()
