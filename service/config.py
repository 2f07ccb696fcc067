"""One settings object, read from the environment, overridable in tests."""

from __future__ import annotations

import dataclasses
import os
from dataclasses import dataclass, field
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


def _env_float(name: str, default: float) -> float:
    raw = os.environ.get(name)
    if raw is None or raw == "":
        return default
    value = float(raw)
    if not value > 0 or value == float("inf"):
        raise ValueError(f"{name} must be a positive number of seconds, got {raw!r}")
    return value


def default_workers() -> int:
    """One engine worker per core (at least one)."""
    return max(1, os.cpu_count() or 1)


@dataclass(frozen=True)
class Settings:
    """Service settings, from the environment (see the README):

    ``LINKAGE_MAX_VERTICES`` (50000), ``LINKAGE_MAX_BARS`` (200000), ``LINKAGE_MAX_POINTS``
    (points in one configuration-space answer, 200000), ``LINKAGE_MAX_BODY_BYTES`` (request
    bodies, 5 MB), ``LINKAGE_TIME_LIMIT_S`` (engine time per request, 30 s),
    ``LINKAGE_WORKERS`` (engine worker processes, one per core) and ``LINKAGE_MAX_QUEUE``
    (engine requests admitted at once, running or waiting, 64). Jobs (``service.tasks``):
    ``LINKAGE_DASK_SCHEDULER`` (``tcp://host:port`` of an existing Dask cluster; unset: an
    embedded one with ``LINKAGE_DASK_WORKERS`` worker processes, one per core),
    ``LINKAGE_JOB_TIME_LIMIT_S`` (per job, 3600 s), ``LINKAGE_JOB_TTL_S`` (how long finished
    jobs and their results are kept, 3600 s) and ``LINKAGE_MAX_JOBS`` (queued or running, 64).
    """

    max_vertices: int = 50_000
    max_bars: int = 200_000
    max_points: int = 200_000
    max_body_bytes: int = 5 * 1024 * 1024
    time_limit_s: float = 30.0
    workers: int = field(default_factory=default_workers)
    max_queue: int = 64
    dask_scheduler: str | None = None
    dask_workers: int = field(default_factory=default_workers)
    job_time_limit_s: float = 3600.0
    job_ttl_s: float = 3600.0
    max_jobs: int = 64

    @classmethod
    def from_env(cls) -> Settings:
        return cls(
            max_vertices=_env_int("LINKAGE_MAX_VERTICES", cls.max_vertices),
            max_bars=_env_int("LINKAGE_MAX_BARS", cls.max_bars),
            max_points=_env_int("LINKAGE_MAX_POINTS", cls.max_points),
            max_body_bytes=_env_int("LINKAGE_MAX_BODY_BYTES", cls.max_body_bytes),
            time_limit_s=_env_float("LINKAGE_TIME_LIMIT_S", cls.time_limit_s),
            workers=_env_int("LINKAGE_WORKERS", default_workers()),
            max_queue=_env_int("LINKAGE_MAX_QUEUE", cls.max_queue),
            dask_scheduler=os.environ.get("LINKAGE_DASK_SCHEDULER") or None,
            dask_workers=_env_int("LINKAGE_DASK_WORKERS", default_workers()),
            job_time_limit_s=_env_float("LINKAGE_JOB_TIME_LIMIT_S", cls.job_time_limit_s),
            job_ttl_s=_env_float("LINKAGE_JOB_TTL_S", cls.job_ttl_s),
            max_jobs=_env_int("LINKAGE_MAX_JOBS", cls.max_jobs),
        )

    def replace(self, **changes: object) -> Settings:
        """A copy with some settings changed (e.g. in tests)."""
        return dataclasses.replace(self, **changes)  # type: ignore[arg-type]

    @property
    def limits(self) -> Limits:
        return Limits(max_vertices=self.max_vertices, max_bars=self.max_bars)


@lru_cache(maxsize=1)
def get_settings() -> Settings:
    """FastAPI dependency; tests override it with ``app.dependency_overrides``."""
    return Settings.from_env()
