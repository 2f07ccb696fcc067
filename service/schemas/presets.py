"""Preset catalogue models."""

from __future__ import annotations

from pydantic import BaseModel


class PresetInfo(BaseModel):
    name: str
    description: str
    parameters: dict[str, float]
    dimension: int = 2


class Health(BaseModel):
    status: str
    version: str


class Readiness(BaseModel):
    """Ready to analyse: the compiled kernels are loaded and every engine worker answered."""

    status: str
    version: str
    workers: int
