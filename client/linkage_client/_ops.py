"""Every operation of the API as a ``Call`` (path, body, parser), shared by both clients."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

from linkage_client._http import Call, bytes_of, drop_none, json_of, model, text_of
from linkage_client.models import (
    CriticalPointsResult,
    CriticalValuesResult,
    DesignResult,
    Health,
    Job,
    JobSummary,
    Linkage,
    Operation,
    PresetInfo,
    Readiness,
    RigidityResult,
    RobustnessResult,
    SecondOrderResult,
    SpaceResult,
    SplittingResult,
    linkage_json,
    sequence,
)

LinkageIn = Linkage | Mapping[str, Any]
Opts = Mapping[str, Any] | None
SVG = {"accept": "image/svg+xml"}
#: The figure formats and the media type each is asked for with (the service's
#: service/figure_formats.py MEDIA_TYPES).
FIGURE_TYPES = {"svg": "image/svg+xml", "png": "image/png", "pdf": "application/pdf",
                "tikz": "application/x-tex", "dxf": "image/vnd.dxf"}
FIGURES = ("linkage", "configuration-space", "critical-values", "splitting")


def _analysis(linkage: LinkageIn, tolerances: Opts, **more: Any) -> dict[str, Any]:
    return drop_none({"linkage": linkage_json(linkage),
                      "tolerances": None if tolerances is None else dict(tolerances), **more})


def _space_options(options: Opts, compact: bool) -> dict[str, Any] | None:
    """``options`` with ``points: "compact"`` unless the caller chose (numpy decodes it)."""
    if not compact:
        return None if options is None else dict(options)
    return {"points": "compact", **(options or {})}


def health() -> Call[Health]:
    return Call("GET", "/health", model(Health.from_json))


def health_live() -> Call[Health]:
    return Call("GET", "/health/live", model(Health.from_json))


def health_ready() -> Call[Readiness]:
    """Ready: the kernels loaded and the engine workers answer (a 503 problem while not)."""
    return Call("GET", "/health/ready", model(Readiness.from_json))


def metrics() -> Call[str]:
    return Call("GET", "/metrics", text_of)


def rigidity(linkage: LinkageIn, tolerances: Opts) -> Call[RigidityResult]:
    return Call("POST", "/v1/analysis/rigidity", model(RigidityResult.from_json),
                json=_analysis(linkage, tolerances))


def second_order(linkage: LinkageIn, tolerances: Opts) -> Call[SecondOrderResult]:
    return Call("POST", "/v1/analysis/second-order", model(SecondOrderResult.from_json),
                json=_analysis(linkage, tolerances))


def critical_points(linkage: LinkageIn, options: Opts,
                    tolerances: Opts) -> Call[CriticalPointsResult]:
    return Call("POST", "/v1/analysis/critical-points", model(CriticalPointsResult.from_json),
                json=_analysis(linkage, tolerances, options=options))


def configuration_space(linkage: LinkageIn, options: Opts, tolerances: Opts,
                        compact: bool) -> Call[SpaceResult]:
    return Call("POST", "/v1/analysis/configuration-space", model(SpaceResult.from_json),
                json=_analysis(linkage, tolerances, options=_space_options(options, compact)))


def splitting(linkage: LinkageIn, perturbation: Mapping[str, float], options: Opts,
              tolerances: Opts) -> Call[SplittingResult]:
    return Call("POST", "/v1/analysis/splitting", model(SplittingResult.from_json),
                json=_analysis(linkage, tolerances, perturbation=dict(perturbation),
                               options=options))


def robustness(linkage: LinkageIn, adjustable: Sequence[str] | None, method: str | None,
               options: Opts, tolerances: Opts) -> Call[RobustnessResult]:
    return Call("POST", "/v1/analysis/robustness", model(RobustnessResult.from_json),
                json=_analysis(linkage, tolerances, options=options, method=method,
                               adjustable=None if adjustable is None else list(adjustable)))


def _axes(axes: Sequence[Mapping[str, Any]]) -> list[dict[str, Any]]:
    return [dict(a) for a in axes]


def critical_values(linkage: LinkageIn, axes: Sequence[Mapping[str, Any]], options: Opts,
                    tolerances: Opts) -> Call[CriticalValuesResult]:
    return Call("POST", "/v1/analysis/critical-values", model(CriticalValuesResult.from_json),
                json=_analysis(linkage, tolerances, axes=_axes(axes), options=options))


def design(linkage: LinkageIn, targets: Sequence[Mapping[str, Any]], adjustable: Sequence[str],
           max_change: float | None, margin: float | None, options: Opts,
           tolerances: Opts) -> Call[DesignResult]:
    body = _analysis(linkage, tolerances, targets=[dict(t) for t in targets],
                     adjustable=list(adjustable), max_change=max_change, margin=margin,
                     options=options)
    return Call("POST", "/v1/design/splitting", model(DesignResult.from_json), json=body)


def draw_linkage(linkage: LinkageIn, show: Sequence[str] | None, tolerances: Opts) -> Call[str]:
    return Call("POST", "/v1/figures/linkage", text_of, headers=SVG,
                json=_analysis(linkage, tolerances, show=None if show is None else list(show)))


def draw_space(linkage: LinkageIn, axes: Sequence[str] | None, options: Opts,
               tolerances: Opts) -> Call[str]:
    return Call("POST", "/v1/figures/configuration-space", text_of, headers=SVG,
                json=_analysis(linkage, tolerances, options=options,
                               axes=None if axes is None else list(axes)))


def draw_critical_values(linkage: LinkageIn, axes: Sequence[Mapping[str, Any]], options: Opts,
                         tolerances: Opts) -> Call[str]:
    return Call("POST", "/v1/figures/critical-values", text_of, headers=SVG,
                json=_analysis(linkage, tolerances, axes=_axes(axes), options=options))


def draw_splitting(linkage: LinkageIn, perturbation: Mapping[str, float], options: Opts,
                   tolerances: Opts) -> Call[str]:
    return Call("POST", "/v1/figures/splitting", text_of, headers=SVG,
                json=_analysis(linkage, tolerances, perturbation=dict(perturbation),
                               options=options))


def draw(figure: str, body: Mapping[str, Any], fmt: str, dpi: int | None) -> Call[bytes]:
    """Any figure in any format: ``body`` is the figure endpoint's request (its ``linkage``
    a model or a mapping), the answer the figure's bytes."""
    if figure not in FIGURES:
        raise ValueError(f"no figure named {figure!r}; known: {', '.join(FIGURES)}")
    if fmt not in FIGURE_TYPES:
        raise ValueError(f"no figure format {fmt!r}; known: {', '.join(FIGURE_TYPES)}")
    data = dict(body)
    if "linkage" in data:
        data["linkage"] = linkage_json(data["linkage"])
    return Call("POST", f"/v1/figures/{figure}", bytes_of,
                headers={"accept": FIGURE_TYPES[fmt]},
                json=drop_none({**data, "format": fmt, "dpi": dpi}))


def create_job(operation: str, body: Mapping[str, Any]) -> Call[Job]:
    return Call("POST", "/v1/jobs", model(Job.from_json),
                json={"operation": operation, "body": dict(body)})


def list_job_operations() -> Call[list[Operation]]:
    return Call("GET", "/v1/jobs/operations",
                model(lambda d: [Operation.from_json(o) for o in sequence(d)]))


def list_jobs(status: str | None = None) -> Call[list[JobSummary]]:
    params = {} if status is None else {"status": status}
    return Call("GET", "/v1/jobs", model(lambda data: [JobSummary.from_json(j) for j in data]),
                params=params)


def get_job(job_id: str) -> Call[Job]:
    return Call("GET", f"/v1/jobs/{job_id}", model(Job.from_json))


def cancel_job(job_id: str) -> Call[Job]:
    return Call("DELETE", f"/v1/jobs/{job_id}", model(Job.from_json))


def job_result(job_id: str, csv: bool) -> Call[Any]:
    if csv:
        return Call("GET", f"/v1/jobs/{job_id}/result", text_of, headers={"accept": "text/csv"})
    return Call("GET", f"/v1/jobs/{job_id}/result", json_of,
                headers={"accept": "application/json"})


def sweep_body(linkage: LinkageIn | None, preset: str | None,
               parameters: Mapping[str, float] | None, grid: Opts, samples: Opts,
               count: int | None, seed: int | None, compute: Sequence[str] | None,
               options: Opts, tolerances: Opts) -> dict[str, Any]:
    """The body of ``POST /v1/sweeps`` (the service checks the combination)."""
    ref = None if preset is None else drop_none({"name": preset, "parameters": (
        None if parameters is None else dict(parameters))})
    return drop_none({
        "linkage": None if linkage is None else linkage_json(linkage), "preset": ref,
        "grid": None if grid is None else {k: dict(v) for k, v in grid.items()},
        "samples": None if samples is None else {k: dict(v) for k, v in samples.items()},
        "count": count, "seed": seed, "compute": None if compute is None else list(compute),
        "options": None if options is None else dict(options),
        "tolerances": None if tolerances is None else dict(tolerances)})


def create_sweep(body: Mapping[str, Any]) -> Call[Job]:
    return Call("POST", "/v1/sweeps", model(Job.from_json), json=dict(body))


def list_presets() -> Call[list[PresetInfo]]:
    return Call("GET", "/v1/presets",
                model(lambda d: [PresetInfo.from_json(p) for p in sequence(d)]))


def get_preset(name: str, parameters: Mapping[str, float]) -> Call[Linkage]:
    return Call("GET", f"/v1/presets/{name}", model(Linkage.from_json),
                params={k: repr(float(v)) if not isinstance(v, int) else str(v)
                        for k, v in parameters.items()})
