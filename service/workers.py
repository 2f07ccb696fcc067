"""Engine work outside the event loop: a pool of worker processes with a per-request time limit.

Heavy analyses run in ``LINKAGE_WORKERS`` processes (``pebble.ProcessPool``: it stops a task
that exceeds its time limit by killing its worker and starts a replacement, and reports a
worker that died as ``ProcessExpired``; both are things ``concurrent.futures`` cannot do).
Workers come from a ``forkserver`` that has imported the engine once, so a replacement is
ready in well under a second, and each worker's BLAS runs on one thread (one worker per core).

Small first- and second-order requests, whose worst cost estimated from their sizes before any
work is some milliseconds (``LIGHT_MAX_NUMBERS``, ``LIGHT_SECOND_ORDER_MAX_PRODUCT``), run in the
service's thread pool instead, so they stay fast while every worker is busy; they are admitted
under the same ``LINKAGE_MAX_QUEUE`` (a lane of their own: 503 ``busy`` beyond it). The first
order of a tiny linkage (``INLINE_MAX_VERTICES``, about a millisecond) is answered in the same
lane on the event loop itself, without the two thread hand-offs.

Each worker may allocate at most ``LINKAGE_WORKER_MEMORY_MB`` (its ``RLIMIT_DATA``, set when
it starts), so one request can never take the machine's memory: the engine estimates the cost
of its method before allocating and refuses what does not fit (422), and an allocation beyond
the limit that the estimate missed fails with a ``MemoryError`` in the worker instead of
waking the kernel's out-of-memory killer.

An answer of at least ``SPILL_MIN_BYTES`` (a configuration space of 10^5 points is 10-20 MB
of JSON) comes back from its worker through a file in memory (``/dev/shm``, else the temporary
directory) that the service hands to the request, instead of pebble's result pipe: there it
would be pickled, pushed through a 64 kB pipe buffer in some two hundred wake-ups of the two
processes, and unpickled (30-80 ms for 13 MB on a 2-core machine), where the file costs one
write and one read of the bytes. A file whose request was answered is kept for the next
request (``SpillFiles``: a new file's pages cost the kernel as much again as the copy);
one whose worker may still be running (time limit, cancellation, failure) is removed at once.
Each worker's ``malloc`` (glibc) keeps freed memory for the next request
(:func:`tune_malloc`): by default every array of more than 128 kB is mapped fresh from the
kernel and returned when freed, so a configuration-space answer of 10^5 points pays some 10^4
page faults (half its worker's CPU time on a virtual machine) on every request.

Outcomes that are not the engine's answer become :class:`ServiceFault`s, which the service
turns into problem+json: 504 when the time limit stopped the work, 422 when the work ran out of
the worker's memory, 503 when the worker died (killed) or when too many engine requests are
already admitted.
"""

from __future__ import annotations

import asyncio
import ctypes
import logging
import os
import resource
import threading
import time
from collections.abc import Callable, Iterator
from concurrent.futures import TimeoutError as FutureTimeout
from concurrent.futures.process import BrokenProcessPool
from contextlib import contextmanager
from typing import Any, TypeVar

import pebble
from pydantic import BaseModel
from starlette.concurrency import run_in_threadpool
from starlette.requests import Request
from starlette.responses import Response

from engine.model.budget import OutOfTime
from engine.space import trace_kernel
from engine.space.dyads import kernel as dyads_kernel
from service import forkserver, serialise
from service.config import Settings, with_arrival
from service.spill import SPILL_MIN_BYTES, SpillFiles, write_spill

T = TypeVar("T")
B = TypeVar("B")
log = logging.getLogger("service.workers")

#: The small requests' lane takes a first- or second-order request by its worst cost, estimated
#: from its sizes before any work (``M`` free coordinates, ``E`` bars: service.jobs.is_light).
#: The first order's zero modes and self-stresses hold at most ``M^2 + E^2`` numbers (``k <= M``
#: modes of ``M`` numbers, ``s <= E`` stresses of ``E``), whose mapping and JSON cost more than
#: the SVD; degenerate linkages (collinear in 2D, flat in 3D) reach it. Measured in-process
#: with the answer's JSON (bench/bench_light_cost.py, one BLAS thread as here, load 4.8): at
#: most 3.4 ms up to 13,572, 8-16 ms from 17,680 to 28,260, 36 ms at 100,132.
LIGHT_MAX_NUMBERS = 12_288
#: Second order adds the prestress SDP where there are two flexes and two self-stresses or more,
#: of a size bounded by ``k <= M`` and ``s <= E``: at most 3 ms up to ``M E`` = 128, 7 ms at
#: 144, 0.2 s at 288 and 0.63 s at 7,680 (the same bench).
LIGHT_SECOND_ORDER_MAX_PRODUCT = 128
#: First-order requests up to this many vertices and bars are answered on the event loop
#: itself: about 1 ms (0.6-1.0 ms measured for 4-16 vertices and up to 40 bars, 2D and 3D), less
#: than the two thread hand-offs of the thread pool cost on a loaded machine (each waits for the
#: scheduler: a four-bar's rigidity had p50 84 ms against /health's 35 ms at load 15).
INLINE_MAX_VERTICES = 16
INLINE_MAX_BARS = 48
#: Niceness added to each engine worker: with every core busy with engine work, the service
#: process (the event loop, health checks and the small requests' lane) is scheduled first, so
#: that cheap requests keep their latency while heavy ones saturate the workers.
WORKER_NICE = 10
#: Seconds the workers may take to answer once at start-up: the first start after an install
#: compiles the tracer's kernel into numba's cache (78 s measured on a loaded 2-core machine).
START_TIMEOUT_S = 600.0
#: Seconds between two looks of the watchdog for a broken pool.
WATCH_INTERVAL_S = 0.5


class ServiceFault(Exception):
    """The engine gave no answer for a reason of the service, not of the input."""

    status = 503
    kind = "service-fault"
    title = "Service fault"

    def __init__(self, detail: str, retry_after: int | None = None) -> None:
        super().__init__(detail)
        self.detail = detail
        self.retry_after = retry_after

    def __reduce__(self) -> tuple[Any, ...]:
        # raised in a worker and pickled back: ``retry_after`` too (Exception keeps its args)
        return type(self), (self.detail, self.retry_after)


class TimeLimitExceeded(ServiceFault):
    status = 504
    kind = "time-limit"
    title = "Time limit exceeded"


class WorkerFailed(ServiceFault):
    status = 503
    kind = "worker-failed"
    title = "Worker failed"


class MemoryLimit(ServiceFault):
    """The work needed more memory than a worker may allocate: asking again will not help."""

    status = 422
    kind = "memory-limit"
    title = "Memory limit exceeded"


class Busy(ServiceFault):
    status = 503
    kind = "busy"
    title = "Service busy"


def _warm() -> int:
    trace_kernel.prepare()  # the worker's tracer path, before its first request
    dyads_kernel.prepare()  # the closed form's compiled loops (loaded on first use otherwise)
    return os.getpid()


#: ``mallopt`` parameters (glibc's malloc.h) and the values :func:`tune_malloc` sets.
_M_TRIM_THRESHOLD, _M_MMAP_THRESHOLD = -1, -3
#: Blocks from this size on are mapped from the kernel and unmapped when freed (glibc's
#: default is 128 kB, raised as blocks are freed up to this very value, but never for the
#: first requests, and never again once the trim threshold is set).
MALLOC_MMAP_THRESHOLD = 32 << 20
#: Free memory at the top of the heap beyond this is returned to the kernel (the default is
#: twice the mmap threshold): a worker keeps at most this much between requests.
MALLOC_TRIM_THRESHOLD = 128 << 20


def tune_malloc() -> bool:
    """Let this process's ``malloc`` reuse freed memory for arrays up to
    ``MALLOC_MMAP_THRESHOLD`` and keep up to ``MALLOC_TRIM_THRESHOLD`` of free heap, instead of
    mapping each large array fresh (a page fault per 4 kB touched, the page zeroed by the
    kernel) and unmapping it when freed. False where the C library has no ``mallopt`` (not
    glibc): nothing changes there."""
    try:
        mallopt = ctypes.CDLL(None).mallopt
    except (OSError, AttributeError):
        return False
    mallopt.argtypes, mallopt.restype = [ctypes.c_int, ctypes.c_int], ctypes.c_int
    return (mallopt(_M_MMAP_THRESHOLD, MALLOC_MMAP_THRESHOLD) == 1
            and mallopt(_M_TRIM_THRESHOLD, MALLOC_TRIM_THRESHOLD) == 1)


def _limit_memory(limit_bytes: int | None) -> None:
    """Worker initializer: cap the memory this worker may allocate (its data segment, which
    holds the heap and every anonymous mapping, numpy's arrays included), let its ``malloc``
    reuse freed memory (:func:`tune_malloc`), and lower its CPU priority by ``WORKER_NICE``."""
    os.nice(WORKER_NICE)
    tune_malloc()
    if limit_bytes is not None:
        resource.setrlimit(resource.RLIMIT_DATA, (limit_bytes, limit_bytes))


class EnginePool:
    """Worker processes for one application, started on first use (or by :meth:`start`).

    A pebble pool whose worker dies while no task is running (an idle worker killed, as the
    out-of-memory killer would) declares itself broken for good: every later ``schedule``
    raises ``RuntimeError("Unexpected error within the Pool")``. The pool is therefore
    replaced when it is found broken: by a watchdog thread every ``watch_interval_s``
    (started by :meth:`start`; None for none) and by the next request, whichever comes
    first. :attr:`ready` is False while the pool is broken."""

    def __init__(self, workers: int, max_queue: int,
                 on_event: Callable[[str], None] | None = None,
                 memory_mb: int | None = None,
                 watch_interval_s: float | None = WATCH_INTERVAL_S) -> None:
        self.workers = workers
        self.max_queue = max_queue
        self.memory_mb = memory_mb
        self.watch_interval_s = watch_interval_s
        self.admitted = 0
        self.light_admitted = 0
        self.replacements = 0
        self.spill_files = SpillFiles(keep=workers)
        self._pool: pebble.ProcessPool | None = None
        self._started = False
        #: True while a thread forks the workers of a new pool (start-up, a replacement).
        self.starting = False
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._watchdog: threading.Thread | None = None
        self._on_event = on_event or (lambda event: None)

    def _new_pool(self) -> pebble.ProcessPool:
        # the forkserver imports the engine and loads the compiled kernels once (service.warm):
        # each worker forked from it, a replacement too, starts with them
        ctx = forkserver.context()
        limit = None if self.memory_mb is None else self.memory_mb * 2**20
        return pebble.ProcessPool(max_workers=self.workers, context=ctx,
                                  initializer=_limit_memory, initargs=(limit,))

    def _ensure(self) -> pebble.ProcessPool:
        """The pool, made (or remade where it is broken) under the lock."""
        with self._lock:
            if self._pool is not None and not self._pool.active:
                self._replace_locked()
            if self._pool is None:
                self._pool = self._new_pool()
            return self._pool

    def _replace_locked(self) -> None:
        """Drop the broken pool (its threads are stopped and its workers killed in the
        background) and count the replacement; the caller holds the lock."""
        broken, self._pool = self._pool, None
        self.replacements += 1
        self._on_event("pool_replaced")
        log.warning("engine pool broken (a worker died while no task was running): replacing "
                    "it (replacement %d)", self.replacements)
        if broken is not None:
            threading.Thread(target=_dispose, args=(broken,), daemon=True,
                             name="engine-pool-dispose").start()

    @property
    def broken(self) -> bool:
        """True when the current pool can take no task (it will be replaced). Never waits:
        while a thread forks a new pool's workers (:attr:`starting`) the pool is not looked
        at, since pebble's ``active`` would wait for that start under its lock (seconds at
        start-up, with the event loop that asked waiting too: /health/live stalled 6 s)."""
        with self._lock:
            pool, starting = self._pool, self.starting
        return pool is not None and not starting and not pool.active

    @property
    def ready(self) -> bool:
        """Started (every worker answered once), not starting a new pool, and not broken."""
        return self._started and not self.starting and not self.broken

    def start(self) -> None:
        """Start the workers, wait until each has answered once, and start the watchdog."""
        self._warm_all()
        self._started = True
        if self.watch_interval_s is not None and self._watchdog is None:
            self._watchdog = threading.Thread(target=self._watch, daemon=True,
                                              name="engine-pool-watchdog")
            self._watchdog.start()

    def _warm_all(self) -> None:
        self.starting = True
        try:
            pool = self._ensure()
            for future in [pool.schedule(_warm) for _ in range(self.workers)]:
                future.result(timeout=START_TIMEOUT_S)
        finally:
            self.starting = False

    def _watch(self) -> None:
        """Replace a broken pool without waiting for a request, and warm its workers."""
        assert self.watch_interval_s is not None
        while not self._stop.wait(self.watch_interval_s):
            if not self.broken:
                continue
            try:
                self._warm_all()  # _ensure replaces it
            except Exception:  # the next round tries again
                log.exception("engine pool: the replacement workers did not start")

    def worker_pids(self) -> list[int]:
        """Process ids of the live workers (diagnostics and fault tests; reads pebble's
        worker table, an implementation detail of the pinned pebble 5)."""
        with self._lock:
            pool = self._pool
        if pool is None:
            return []
        try:
            workers = pool._pool_manager.worker_manager.workers
            return [int(pid) for pid, proc in list(workers.items()) if proc.is_alive()]
        except AttributeError:  # another pebble: no diagnostics
            return []

    def close(self) -> None:
        """Let running tasks finish, then stop the workers (graceful shutdown)."""
        self._stop.set()
        if self._watchdog is not None:  # it may be warming a replacement: let it finish
            self._watchdog.join(timeout=130)
            self._watchdog = None
        with self._lock:
            pool, self._pool = self._pool, None
            self._started = False
        if pool is not None:
            if pool.active:
                pool.close()
                pool.join()
            else:
                _dispose(pool)
        self.spill_files.close()

    @contextmanager
    def light_lane(self, time_limit: float) -> Iterator[None]:
        """Admission of a small request answered in the service's thread pool: at most
        ``max_queue`` at once (503 ``busy`` beyond), counted apart from the workers' queue so
        that heavy requests never crowd out cheap ones."""
        if self.light_admitted >= self.max_queue:
            self._on_event("busy")
            raise Busy(f"{self.light_admitted} small requests are being answered (LINKAGE_MAX_"
                       f"QUEUE = {self.max_queue}); retry shortly", retry_after=1)
        self.light_admitted += 1
        try:
            yield
        finally:
            self.light_admitted -= 1

    def _schedule(self, fn: Callable[..., T], args: tuple[Any, ...],
                  time_limit: float) -> pebble.ProcessFuture:
        """Schedule on the pool; a pool found broken at this moment is replaced once."""
        try:
            return self._ensure().schedule(fn, args, timeout=time_limit)
        except RuntimeError:  # broken between the check in _ensure and schedule
            return self._ensure().schedule(fn, args, timeout=time_limit)

    async def run(self, time_limit: float, fn: Callable[..., T], *args: Any) -> T:
        """``fn(*args)`` in a worker, stopped after ``time_limit`` seconds of running."""
        if self.admitted >= self.max_queue:
            self._on_event("busy")
            raise Busy(
                f"{self.admitted} engine requests are running or waiting (LINKAGE_MAX_QUEUE = "
                f"{self.max_queue}); retry shortly",
                retry_after=max(1, round(time_limit / 4)),
            )
        self.admitted += 1
        try:
            if self.ready:
                future = self._schedule(fn, args, time_limit)
            else:  # a pool being started (or replaced) would hold the event loop meanwhile
                future = await run_in_threadpool(self._schedule, fn, args, time_limit)
            try:
                return await asyncio.wrap_future(future)
            except FutureTimeout:
                self._on_event("time_limit")
                raise TimeLimitExceeded(
                    f"the analysis ran longer than LINKAGE_TIME_LIMIT_S = {time_limit:g} s and "
                    "was stopped; ask for less (e.g. fewer components, a coarser resolution, a "
                    "smaller linkage) or raise the limit"
                ) from None
            except MemoryError as err:
                self._on_event("memory_limit")
                log.warning("engine worker out of memory running %s: %s",
                            getattr(fn, "__name__", fn), err)
                raise MemoryLimit(
                    f"the analysis needed more memory than an engine worker may allocate "
                    f"(LINKAGE_WORKER_MEMORY_MB = {self.memory_mb}) and was stopped; ask for "
                    "less (a smaller or less floppy linkage) or raise the limit"
                ) from None
            except pebble.ProcessExpired as err:
                self._on_event("worker_failed")
                log.warning("engine worker died (exit code %s) running %s", err.exitcode,
                            getattr(fn, "__name__", fn))
                raise WorkerFailed(
                    f"the worker process running this analysis stopped unexpectedly (exit code "
                    f"{err.exitcode}: killed, e.g. out of memory); it has been replaced, and "
                    "the request may be retried",
                    retry_after=1,
                ) from None
            except BrokenProcessPool:  # another worker died while this task waited
                self._on_event("worker_failed")
                log.warning("engine pool broke while %s waited; it is being replaced",
                            getattr(fn, "__name__", fn))
                raise WorkerFailed(
                    "an engine worker stopped unexpectedly while this analysis waited for one "
                    "(killed, e.g. out of memory); the workers are being replaced, and the "
                    "request may be retried",
                    retry_after=1,
                ) from None
        finally:
            self.admitted -= 1


def _dispose(pool: pebble.ProcessPool) -> None:
    """Stop a broken pool's threads and kill its workers."""
    try:
        pool.stop()
        pool.join(timeout=10)
    except Exception:  # a broken pool may fail to stop cleanly: it is dropped anyway
        log.exception("engine pool: stopping a broken pool failed")


def engine_pool(request: Request) -> EnginePool:
    pool: EnginePool = request.app.state.engine_pool
    return pool


def _as_json(fn: Callable[[B, Settings], BaseModel], body: B, settings: Settings,
             spill: str | None = None, kernel: bool = True,
             queued_at: float | None = None) -> bytes | int:
    """Run a job and serialise its answer where it ran: in a worker that is in parallel with
    the event loop, and one bytes object crosses the process boundary instead of a model tree
    (for answers with many points this is most of the cost of the hop). The tracer's compiled
    kernel is loaded first (once per worker: from numba's on-disk cache about a second,
    compiled where the cache is cold), so that every answer of a worker traces on one path (the
    Python loop's points agree with the kernel's to rounding, not bit for bit); inside the task,
    so that a worker dying meanwhile fails this request like any other. Not with ``kernel``
    False: the small requests answered in the service's process trace nothing, and that
    process loads no kernel.

    With ``spill`` (a file the service handed to this request), an answer of at least
    ``SPILL_MIN_BYTES`` is written there and only its size returned; where that fails (the
    file is gone, the file system full) the bytes are returned as for a small answer.
    ``queued_at``: when the pool was handed the request with every worker taken (``monotonic``),
    to tell the time lost in the queue (_queued_too_long); None where one was free."""
    waited = 0.0 if queued_at is None else time.monotonic() - queued_at
    if kernel:
        trace_kernel.prepare()
    try:
        answer = fn(body, settings)
    except OutOfTime as err:
        raise _queued_too_long(err, settings, waited) from None
    parts = serialise.dumps_parts(answer)
    if spill is not None:
        size = sum(len(part) for part in parts)
        if size >= SPILL_MIN_BYTES and write_spill(spill, parts):
            return size
    return b"".join(parts)


#: A request that waited for a worker over this share of its time limit and then would not end
#: in the time left (``OutOfTime``) is a 503 ``busy``, not a 422 ``too-costly``: the queue's
#: fault (bench/bench_lanes.py: 20 ms of work refused after 3 s behind heavy requests).
QUEUE_SHARE = 0.1


def _queued_too_long(err: OutOfTime, settings: Settings, waited: float) -> Exception:
    """``err``, or :class:`Busy` where the request ``waited`` for a worker more than
    :data:`QUEUE_SHARE` of its time limit (reading and parsing its body is its own time)."""
    if waited <= QUEUE_SHARE * settings.time_limit_s:
        return err
    return Busy(f"the request waited {waited:.1f} s for an engine worker, and its analysis "
                f"would not finish in the time left ({err}); retry when the service is less "
                "busy", retry_after=max(1, round(waited)))


def _read_spill(path: str, size: int) -> bytes:
    with open(path, "rb", buffering=0) as f:
        data = f.read(size)
    if len(data) != size:
        raise WorkerFailed(f"the answer in transit was cut short ({len(data)} of {size} bytes)",
                           retry_after=1)
    return data


async def engine_call(request: Request, settings: Settings,
                      fn: Callable[[B, Settings], BaseModel], body: B,
                      light: bool = False, inline: bool = False) -> Response:
    """The JSON answer of the job ``fn(body, settings)`` for an endpoint (the route's
    ``response_model`` documents it): on the event loop itself when ``inline`` (about a
    millisecond: ``INLINE_MAX_VERTICES``), in the service's thread pool when ``light`` (bounded
    cost), else in a worker process under ``settings.time_limit_s``."""
    settings = with_arrival(request, settings)  # (searches count their time from there)
    pool = engine_pool(request)
    if light or inline:
        with pool.light_lane(settings.time_limit_s):
            answer = (_as_json(fn, body, settings, None, False) if inline
                      else await run_in_threadpool(_as_json, fn, body, settings, None, False))
        assert isinstance(answer, bytes)  # no spill file: the bytes themselves
        payload = answer
    else:
        spill, answered = pool.spill_files.take(), False
        # a free worker's late start is the load's, no queue's (503 "waited" instead of a 422)
        queued = not pool.ready or pool.admitted >= pool.workers
        try:
            answer = await pool.run(settings.time_limit_s, _as_json, fn, body, settings, spill,
                                    True, time.monotonic() if queued else None)
            payload = (answer if isinstance(answer, bytes)
                       else await run_in_threadpool(_read_spill, spill, answer))
            answered = True
        finally:  # a worker stopped at the time limit may still write: not for reuse
            pool.spill_files.give_back(spill, reuse=answered)
    return Response(payload, media_type="application/json")
