"""One settings object, read from the environment, overridable in tests."""

from __future__ import annotations

import os
from dataclasses import dataclass
from functools import lru_cache

from engine.linkage import Limits


def _env_int(name: str, default: int) -> int:
    raw = os.environ.get(name)
    if raw is None or raw == "":
        return default
    value = int(raw)
    if value <= 0:
        raise ValueError(f"{name} must be a positive integer, got {raw!r}")
    return value


@dataclass(frozen=True)
class Settings:
    """Service settings, from the environment (see the README):

    ``LINKAGE_MAX_VERTICES`` (50000), ``LINKAGE_MAX_BARS`` (200000), ``LINKAGE_MAX_POINTS``
    (points in one configuration-space answer, 200000), ``LINKAGE_MAX_BODY_BYTES`` (request
    bodies, 5 MB).
    """

    max_vertices: int = 50_000
    max_bars: int = 200_000
    max_points: int = 200_000
    max_body_bytes: int = 5 * 1024 * 1024

    @classmethod
    def from_env(cls) -> Settings:
        return cls(
            max_vertices=_env_int("LINKAGE_MAX_VERTICES", cls.max_vertices),
            max_bars=_env_int("LINKAGE_MAX_BARS", cls.max_bars),
            max_points=_env_int("LINKAGE_MAX_POINTS", cls.max_points),
            max_body_bytes=_env_int("LINKAGE_MAX_BODY_BYTES", cls.max_body_bytes),
        )

    @property
    def limits(self) -> Limits:
        return Limits(max_vertices=self.max_vertices, max_bars=self.max_bars)


@lru_cache(maxsize=1)
def get_settings() -> Settings:
    """FastAPI dependency; tests override it with ``app.dependency_overrides``."""
    return Settings.from_env()
