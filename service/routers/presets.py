"""Preset linkages: the catalogue, one route per preset with its parameters as documented query
parameters (generated from the engine's catalogue, so a preset added there is routed and
documented here without a change), and ``/v1/presets/{name}`` for any name."""

import inspect
from collections.abc import Callable
from typing import Any

from fastapi import APIRouter, Query, Request

from engine.catalogue.presets import PRESETS, Preset, build_preset, parameter_bounds
from service import mappers
from service.config import Settings, SettingsDep
from service.errors import problem_responses
from service.schemas.common import Linkage
from service.schemas.presets import PresetInfo

router = APIRouter(prefix="/v1/presets", tags=["presets"])
_problems = problem_responses(404, 422)


@router.get("", operation_id="listPresets", response_model=list[PresetInfo])
def list_presets() -> list[PresetInfo]:
    """The preset linkages with their parameters and defaults."""
    return mappers.presets_out()


def _build(name: str, request: Request, settings: Settings) -> Linkage:
    """The preset with every query parameter as an override: the engine names unknown ones,
    values out of range and values that give no valid linkage."""
    overrides = mappers.preset_overrides_in(request.query_params.items())
    return mappers.linkage_out(build_preset(name, overrides, settings.limits))


def _preset_route(preset: Preset) -> Callable[..., Linkage]:
    """``GET /v1/presets/<name>`` with the preset's parameters declared as optional query
    parameters (so that they are documented in OpenAPI and reached by its fuzzer)."""

    def get_this_preset(request: Request, settings: SettingsDep, **_: Any) -> Linkage:
        return _build(preset.name, request, settings)

    bounds = parameter_bounds(preset.name)
    declared = [
        inspect.Parameter(
            f"p{i}", inspect.Parameter.KEYWORD_ONLY, annotation=float,
            # The handler reads the query string itself (_build), so this default documents
            # the preset's default in the schema and is never used as a value; the bounds are
            # the engine's (it refuses what is outside them with a 422 naming the parameter).
            default=Query(preset.parameters[key], alias=key,
                          description=mappers.parameter_description(preset.parameters[key],
                                                                    bounds[key]),
                          json_schema_extra=mappers.parameter_schema(bounds[key])),
        )
        for i, key in enumerate(preset.parameters)
    ]
    get_this_preset.__signature__ = inspect.Signature(  # type: ignore[attr-defined]
        [inspect.Parameter("request", inspect.Parameter.POSITIONAL_OR_KEYWORD,
                           annotation=Request),
         inspect.Parameter("settings", inspect.Parameter.POSITIONAL_OR_KEYWORD,
                           annotation=SettingsDep),
         *declared])
    get_this_preset.__doc__ = (
        f"Build the {preset.name} preset: {preset.description} Parameters not given keep "
        "their defaults; parameters that give no valid linkage (no assembly, overflowing or "
        "degenerate geometry, sizes beyond the limits) are a 422 naming them.")
    return get_this_preset


def preset_operation_id(name: str) -> str:
    """The operationId of a preset's own route: ``four-bar`` -> ``getPresetFourBar``."""
    return "getPreset" + "".join(part[:1].upper() + part[1:] for part in name.split("-"))


for _preset in PRESETS.values():
    router.add_api_route(
        f"/{_preset.name}", _preset_route(_preset), methods=["GET"], response_model=Linkage,
        responses=_problems, name=f"get_preset_{_preset.name.replace('-', '_')}",
        operation_id=preset_operation_id(_preset.name),
    )


@router.get("/{name}", operation_id="getPreset", response_model=Linkage, responses=_problems)
def get_preset(name: str, request: Request, settings: SettingsDep) -> Linkage:
    """Build preset ``name``; any parameter listed by ``/v1/presets`` may be given as a query
    parameter (e.g. ``/v1/presets/four-bar?L2=1.1``). Each preset also has a route of its own
    above, which documents its parameters."""
    return _build(name, request, settings)
