from typing import Annotated

from fastapi import APIRouter, Depends, Request

from engine.errors import InvalidParameter
from engine.presets import build_preset
from service import mappers
from service.config import Settings, get_settings
from service.errors import PROBLEM_JSON
from service.schemas.common import Linkage, Problem
from service.schemas.presets import PresetInfo

router = APIRouter(prefix="/v1/presets", tags=["presets"])
_problems = {
    status: {"model": Problem, "content": {PROBLEM_JSON: {}}} for status in (404, 422)
}


@router.get("", response_model=list[PresetInfo])
def list_presets() -> list[PresetInfo]:
    """The preset linkages with their parameters and defaults."""
    return mappers.presets_out()


@router.get("/{name}", response_model=Linkage, responses=_problems)  # type: ignore[arg-type]
def get_preset(
    name: str, request: Request, settings: Annotated[Settings, Depends(get_settings)]
) -> Linkage:
    """Build preset ``name``; any parameter listed by ``/v1/presets`` may be given as a query
    parameter (e.g. ``/v1/presets/four-bar?L2=1.1``)."""
    overrides: dict[str, float] = {}
    for key, raw in request.query_params.items():
        try:
            overrides[key] = float(raw)
        except ValueError:
            raise InvalidParameter(f"not a number: {raw!r}", loc=(key,)) from None
    return mappers.linkage_out(build_preset(name, overrides, settings.limits))
