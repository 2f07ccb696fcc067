"""One settings object, read from the environment, overridable in tests."""

from __future__ import annotations

import dataclasses
import math
import os
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import lru_cache
from typing import Annotated

from fastapi import Depends, FastAPI, Request

from engine.model.linkage import Limits


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


def cgroup_cpu_limit(root: str = "/sys/fs/cgroup") -> float | None:
    """CPUs allowed by the cgroup CPU quota (a container's ``--cpus``), or None without one.

    cgroup v2: ``cpu.max`` holds ``"<quota> <period>"`` or ``"max <period>"``; cgroup v1:
    ``cpu/cpu.cfs_quota_us`` (-1 for none) and ``cpu/cpu.cfs_period_us``."""
    candidates = (
        (os.path.join(root, "cpu.max"), None),
        (os.path.join(root, "cpu", "cpu.cfs_quota_us"),
         os.path.join(root, "cpu", "cpu.cfs_period_us")),
    )
    for quota_path, period_path in candidates:
        try:
            with open(quota_path) as f:
                fields = f.read().split()
            if period_path is not None:
                with open(period_path) as f:
                    fields += f.read().split()
            quota, period = fields[0], fields[1]
        except (OSError, IndexError):
            continue
        if quota in ("max", "-1") or float(period) <= 0:
            return None
        return float(quota) / float(period)
    return None
def _dask_scheduler_from_env() -> str | None:
    """``LINKAGE_DASK_SCHEDULER``; plain ``tcp://`` to another machine is refused: a Dask
    scheduler runs the pickled code of anyone who reaches it, so one beyond loopback must
    require TLS with client certificates (``tls://``, see the README)."""
    raw = os.environ.get("LINKAGE_DASK_SCHEDULER") or None
    if raw is None:
        return None
    scheme, rest = raw.split("://", 1) if "://" in raw else ("tcp", raw)  # Dask's default
    host = rest.rsplit(":", 1)[0].strip("[]")
    loopback = host in ("localhost", "::1") or host.startswith("127.")
    if scheme != "tls" and not (scheme == "tcp" and loopback):
        raise ValueError(
            f"LINKAGE_DASK_SCHEDULER={raw!r}: a scheduler beyond loopback must be reached "
            "over TLS (tls://host:port, with the certificates in DASK_DISTRIBUTED__COMM__TLS__*)")
    return raw


def _env_list(name: str) -> tuple[str, ...]:
    """A comma-separated setting; empty items dropped."""
    return tuple(item.strip() for item in os.environ.get(name, "").split(",") if item.strip())


def default_workers() -> int:
    """One engine worker per usable core (at least one): the cores this process may run on,
    or fewer when a cgroup CPU quota (e.g. ``docker run --cpus 2``) allows fewer."""
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    cores = max(1, cores or 1)
    quota = cgroup_cpu_limit()
    if quota is not None:
        cores = min(cores, max(1, math.ceil(quota)))
    return cores


#: Share of the machine's memory that the engine workers may hold together by default.
WORKER_MEMORY_SHARE = 0.75
#: Smallest default per-worker memory limit (a warm worker's data segment is about 230 MB).
MIN_WORKER_MEMORY_MB = 512


def machine_memory_mb() -> int:
    """The machine's memory in MB, or the container's (cgroup v2 ``memory.max``) if lower."""
    total = os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    try:
        with open("/sys/fs/cgroup/memory.max") as f:
            raw = f.read().strip()
        if raw.isdigit():
            total = min(total, int(raw))
    except OSError:
        pass
    return int(total // 2**20)


def default_worker_memory_mb(workers: int) -> int:
    """``WORKER_MEMORY_SHARE`` of the machine's memory shared among ``workers`` (at least
    ``MIN_WORKER_MEMORY_MB``): all workers at their limit together still leave a quarter of
    the machine to the service and everything else."""
    return max(MIN_WORKER_MEMORY_MB, int(machine_memory_mb() * WORKER_MEMORY_SHARE) // workers)


#: Smallest ``LINKAGE_WORKER_MEMORY_MB`` accepted: a warm worker's data segment is about 230 MB.
MIN_WORKER_MEMORY_SETTING_MB = 256


def _worker_memory_from_env() -> int | None:
    value = _env_int("LINKAGE_WORKER_MEMORY_MB", 0) or None
    if value is not None and value < MIN_WORKER_MEMORY_SETTING_MB:
        raise ValueError(
            f"LINKAGE_WORKER_MEMORY_MB must be at least {MIN_WORKER_MEMORY_SETTING_MB} (a warm "
            f"engine worker uses about 230 MB), got {value}"
        )
    return value


#: Share of ``LINKAGE_TIME_LIMIT_S`` that a synchronous search may use at most.
SEARCH_SHARE = 0.75


@dataclass(frozen=True)
class Settings:
    """Service settings, from the environment (see the README):

    ``LINKAGE_MAX_VERTICES`` (50000), ``LINKAGE_MAX_BARS`` (200000), ``LINKAGE_MAX_POINTS``
    (points in one configuration-space answer, 200000), ``LINKAGE_MAX_BODY_BYTES`` (request
    bodies, 5 MB), ``LINKAGE_MAX_ANSWER_MB`` (an answer estimated larger is refused before it
    is built, see ``service.answers``, 256), ``LINKAGE_TIME_LIMIT_S`` (engine time per request,
    30 s),
    ``LINKAGE_SEARCH_TIME_S`` (default time a search may take before it answers with what it
    found, marked incomplete: 4 s; a request may ask for more with ``options.time_budget_s``, up
    to three quarters of the time limit),
    ``LINKAGE_WORKERS`` (engine worker processes, one per core) and ``LINKAGE_MAX_QUEUE``
    (engine requests admitted at once, running or waiting, 64),
    ``LINKAGE_WORKER_MEMORY_MB`` (memory each engine worker may allocate, its ``RLIMIT_DATA``;
    default: three quarters of the machine's memory divided among the workers),
    ``LINKAGE_HEADER_TIMEOUT_S``
    (a request's head must arrive within this time, 5 s) and ``LINKAGE_BODY_TIMEOUT_S`` (its
    body within this time, 10 s), ``LINKAGE_CORS_ORIGINS``
    (comma-separated origins allowed to call the service from a browser, e.g.
    ``https://design.example.org``; default none: no CORS headers, ``*`` allows any origin).
    Jobs (``service.tasks``):
    ``LINKAGE_DASK_SCHEDULER`` (``tls://host:port`` of an existing Dask cluster, or
    ``tcp://`` on loopback only; unset: an embedded one with ``LINKAGE_DASK_WORKERS`` worker
    processes, one per core),
    ``LINKAGE_JOB_TIME_LIMIT_S`` (per job, 3600 s), ``LINKAGE_JOB_TTL_S`` (how long finished
    jobs and their results are kept, 3600 s) and ``LINKAGE_MAX_JOBS`` (queued or running, 64).
    """

    max_vertices: int = 50_000
    max_bars: int = 200_000
    max_points: int = 200_000
    max_body_bytes: int = 5 * 1024 * 1024
    max_answer_mb: int = 256
    time_limit_s: float = 30.0
    search_time_s: float = 4.0
    #: ``time.monotonic()`` when the request being answered arrived (set per request by
    #: :func:`service.bodies.with_arrival`, not from the environment): a search's deadline
    #: counts from there, so parsing, validating and sending a large body to a worker spend
    #: the request's budget too
    arrived_at: float | None = None
    workers: int = field(default_factory=default_workers)
    max_queue: int = 64
    worker_memory_mb: int | None = None  # None: default_worker_memory_mb(workers)
    header_timeout_s: float = 5.0
    body_timeout_s: float = 10.0
    cors_origins: tuple[str, ...] = ()
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
            max_answer_mb=_env_int("LINKAGE_MAX_ANSWER_MB", cls.max_answer_mb),
            time_limit_s=_env_float("LINKAGE_TIME_LIMIT_S", cls.time_limit_s),
            search_time_s=_env_float("LINKAGE_SEARCH_TIME_S", cls.search_time_s),
            workers=_env_int("LINKAGE_WORKERS", default_workers()),
            max_queue=_env_int("LINKAGE_MAX_QUEUE", cls.max_queue),
            worker_memory_mb=_worker_memory_from_env(),
            header_timeout_s=_env_float("LINKAGE_HEADER_TIMEOUT_S", cls.header_timeout_s),
            body_timeout_s=_env_float("LINKAGE_BODY_TIMEOUT_S", cls.body_timeout_s),
            cors_origins=_env_list("LINKAGE_CORS_ORIGINS"),
            dask_scheduler=_dask_scheduler_from_env(),
            dask_workers=_env_int("LINKAGE_DASK_WORKERS", default_workers()),
            job_time_limit_s=_env_float("LINKAGE_JOB_TIME_LIMIT_S", cls.job_time_limit_s),
            job_ttl_s=_env_float("LINKAGE_JOB_TTL_S", cls.job_ttl_s),
            max_jobs=_env_int("LINKAGE_MAX_JOBS", cls.max_jobs),
        )

    def replace(self, **changes: object) -> Settings:
        """A copy with some settings changed (e.g. in tests)."""
        return dataclasses.replace(self, **changes)  # type: ignore[arg-type]

    @property
    def worker_memory(self) -> int:
        """Each engine worker's memory limit in MB (``LINKAGE_WORKER_MEMORY_MB``)."""
        if self.worker_memory_mb is not None:
            return self.worker_memory_mb
        return default_worker_memory_mb(self.workers)

    def search_seconds(self, requested: float | None = None) -> float:
        """Seconds a synchronous search may take: ``requested`` (``options.time_budget_s``) or
        ``LINKAGE_SEARCH_TIME_S``, at most :data:`SEARCH_SHARE` of the time limit (the rest is
        for answering: mapping and serialising what was found)."""
        wanted = self.search_time_s if requested is None else requested
        return max(0.0, min(wanted, SEARCH_SHARE * self.time_limit_s))

    @property
    def limits(self) -> Limits:
        return Limits(max_vertices=self.max_vertices, max_bars=self.max_bars)


@lru_cache(maxsize=1)
def get_settings() -> Settings:
    """The settings dependency: the environment's settings, read once.

    This is the one way the service obtains settings. Routes take :data:`SettingsDep`; code
    that runs outside a route's dependencies (the request middleware, large-body parsing) asks
    :func:`app_settings`, which resolves this same dependency. ``create_app(settings)`` and tests
    override it with ``app.dependency_overrides[get_settings]``, and every part of a request
    then sees the override. Outside an application (the uvicorn protocol, the command line) it
    is called directly."""
    return Settings.from_env()


async def request_settings(request: Request) -> Settings:
    """The settings of the application answering ``request`` (:func:`app_settings`), as the
    routes' dependency. A coroutine, so that FastAPI calls it on the event loop: a plain
    function dependency is run in the thread pool, and those two thread hand-offs per request
    were most of a small request's time on a loaded machine (a four-bar's rigidity answered by
    the service within 5 ms in 8-18 % of requests against 94 % for ``/health`` at load 16-21)."""
    return app_settings(request.app)


SettingsDep = Annotated[Settings, Depends(request_settings)]


def app_settings(app: FastAPI) -> Settings:
    """The settings ``app`` runs with: its override of :func:`get_settings`, if any, else the
    environment's (what :data:`SettingsDep` gives its routes)."""
    provider: Callable[[], Settings] = app.dependency_overrides.get(get_settings, get_settings)
    return provider()


def with_arrival(request: Request, settings: Settings) -> Settings:
    """``settings`` with the time ``request`` arrived (before its body was read and parsed:
    :class:`service.bodies.JsonBodyRoute`), from which a search's deadline counts
    (:func:`service.jobs.search_deadline`)."""
    arrived = getattr(request.state, "arrived_at", None)
    return settings if arrived is None else settings.replace(arrived_at=arrived)
