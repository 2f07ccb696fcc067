"""Jobs: long work on ``dask.distributed``, with progress from the engine and cancellation.

A job is one operation (any analysis endpoint's work from :mod:`service.jobs`, or a sweep) run
as Dask tasks. By default the tasks run on an embedded cluster (worker processes, one thread
each, ``LINKAGE_DASK_WORKERS`` of them, on loopback over TLS with a certificate made at start,
without HTTP: :mod:`service.cluster`), started on first use and closed at shutdown; with
``LINKAGE_DASK_SCHEDULER=tls://host:port`` on an existing cluster instead (reconnected when
its scheduler comes back). The job table lives in the service process (a restart forgets it).

Progress and cancellation cross the process boundary with Dask's own primitives, not timers:

* each task builds a :class:`~engine.model.budget.Deadline` whose ``progress`` sink publishes what
  the engine reports (points done, components traced, ...) with ``Worker.log_event`` on the
  topic :data:`service.cluster.TOPIC`, which the service's client subscribes to;
* ``DELETE`` sets a ``distributed.Event`` per job that the deadline's ``stop`` flag reads
  (at most every :data:`service.cluster.STOP_CHECK_S`), so running tasks end at their next
  check, and cancels the tasks not yet started.

A task whose worker dies runs again once on another worker (the embedded scheduler's
``allowed_failures``; an external scheduler retries as its
``distributed.scheduler.allowed-failures`` says); a second death fails the job with
``KilledWorker``. Each job has its own time limit (``LINKAGE_JOB_TIME_LIMIT_S``): tasks see it
as their deadline, and a job still running :data:`GRACE_S` after it is failed and its tasks
cancelled. A job that stops early (time limit, cancel, a failed task) keeps what was finished:
the rows of the sweep's points done (the running tasks stop at their next check and return
theirs), or the incomplete answer of an analysis, as a result marked ``partial``. Finished jobs
and their results are kept ``LINKAGE_JOB_TTL_S`` seconds.
"""

from __future__ import annotations

import dataclasses
import inspect
import logging
import threading
import time
import uuid
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import numpy as np
from pydantic import BaseModel

from engine.design.sweep import PointResult, run_points
from engine.model.errors import EngineError, NumericalFailure
from engine.space import trace_kernel
from service import mappers, serialise
from service.config import Settings
from service.job_state import ClusterUnavailable, Job
from service.operations import OPERATIONS, SWEEPS
from service.workers import Busy, ServiceFault

if TYPE_CHECKING:  # Dask is imported with the first job (JobManager.connection), not before
    from distributed import Client, Future

    from service.cluster import Connection

log = logging.getLogger("service.tasks")
#: uvicorn's own logger (at INFO under uvicorn): the first job's loading of Dask is a start-up
#: step of its own, said beside the service's other start-up lines (service.main).
startup_log = logging.getLogger("uvicorn.error")

#: A job still running this long after its time limit is failed and its tasks cancelled.
GRACE_S = 10.0
#: Finished jobs kept at most, per job that may be active (``LINKAGE_MAX_JOBS``).
KEPT_PER_ACTIVE = 10
#: Sweep chunks per worker: enough to balance uneven points, few enough to keep tasks cheap.
CHUNKS_PER_WORKER = 4




class UnknownJob(ServiceFault):
    status = 404
    kind = "unknown-job"
    title = "Unknown job"


class JobNotDone(ServiceFault):
    status = 409
    kind = "job-not-done"
    title = "Job not done"


class NotAcceptable(ServiceFault):
    status = 406
    kind = "not-acceptable"
    title = "Not acceptable"


# -- in the Dask worker ----------------------------------------------------------------------


def run_operation(job_id: str, operation: str, body: BaseModel, settings: Settings,
                  end_wall: float) -> bytes:
    """One analysis as a task: the synchronous endpoint's JSON answer."""
    from service.cluster import task_deadline  # in a Dask worker: Dask is loaded there
    trace_kernel.prepare()  # one tracer path per worker process (see engine/space/trace_kernel.py)
    fn = OPERATIONS[operation].run
    deadline = task_deadline(job_id, 0, end_wall)
    # the engine searches take the deadline as they gain one (engine/model/budget.py)
    kwargs = {"deadline": deadline} if "deadline" in inspect.signature(fn).parameters else {}
    payload = serialise.dumps(fn(body, settings, **kwargs))
    deadline.report(1.0, "done")
    return payload


def run_sweep_chunk(job_id: str, chunk: int, sweep: mappers.SweepJob, points: np.ndarray,
                    end_wall: float) -> list[PointResult]:
    """Some ``points`` of a sweep as a task (fewer rows than points when stopped); ``sweep``
    says what to compute (its own points are not used)."""
    from service.cluster import task_deadline  # in a Dask worker: Dask is loaded there
    trace_kernel.prepare()  # one tracer path per worker process (see engine/space/trace_kernel.py)
    return run_points(sweep.family, points, sweep.compute, sweep.tolerances, sweep.options,
                      task_deadline(job_id, chunk, end_wall))


# -- in the service --------------------------------------------------------------------------


def _failure(err: BaseException) -> dict[str, Any]:
    """A job's ``error`` from the exception its task raised."""
    name = type(err).__name__
    if isinstance(err, EngineError):
        loc = [p if isinstance(p, int) else str(p) for p in err.loc]
        return {"title": "Invalid input", "detail": err.message, "loc": loc}
    if isinstance(err, NumericalFailure):
        return {"title": "No trustworthy answer", "detail": str(err), "loc": []}
    if name == "KilledWorker":
        return {"title": "Worker failed", "detail": "the Dask worker running this job died "
                f"(killed, e.g. out of memory): {err}", "loc": []}
    return {"title": "Job failed", "detail": f"{name}: {err}", "loc": []}


class JobManager:
    """Jobs of one service process on one Dask client (connected on first use)."""

    def __init__(self, settings: Settings) -> None:
        self.settings = settings
        self._lock = threading.RLock()
        self._jobs: dict[str, Job] = {}
        self._connection: Connection | None = None

    # -- cluster ------------------------------------------------------------------------

    @property
    def connection(self) -> Connection:
        """The connection to the Dask cluster, made on first use: ``service.cluster`` imports
        ``distributed`` (0.2-0.4 s of a core), which the service's start-up does not wait for
        and a service that runs no job never loads."""
        with self._lock:
            if self._connection is None:
                where = self.settings.dask_scheduler or (
                    f"an embedded cluster of {self.settings.dask_workers} workers")
                startup_log.info("jobs: the first job loads Dask and connects to %s", where)
                from service.cluster import Connection  # on first use: see the docstring

                # a task whose worker dies is run again once on another worker (embedded
                # cluster)
                self._connection = Connection(self.settings.dask_scheduler,
                                              self.settings.dask_workers, self._on_event,
                                              allowed_failures=1)
            return self._connection

    def _current(self) -> Client | None:
        """The Dask client now, without connecting or importing Dask (None when there is
        none)."""
        return None if self._connection is None else self._connection.current()

    def client(self) -> Client:
        """The Dask client (connected on first use; see :class:`service.cluster.Connection`)."""
        return self.connection.client()

    def workers(self) -> int:
        """Workers of the cluster now (at least one, for sizing chunks)."""
        return self.connection.workers()

    def close(self) -> None:
        """Cancel unfinished jobs, then close the client and the embedded cluster."""
        with self._lock:
            unfinished = [j for j in self._jobs.values() if not j.finished_state]
        if self._current() is not None:
            for job in unfinished:
                self._stop(job, "cancelled", "the service shut down")
        if self._connection is not None:
            self._connection.close()

    # -- jobs ---------------------------------------------------------------------------

    def _admit(self, job: Job) -> None:
        self._purge()
        with self._lock:
            active = sum(not j.finished_state for j in self._jobs.values())
            if active >= self.settings.max_jobs:
                raise Busy(f"{active} jobs are queued or running (LINKAGE_MAX_JOBS = "
                           f"{self.settings.max_jobs}); retry later", retry_after=5)
            self._jobs[job.id] = job

    def submit(self, operation: str, body: BaseModel) -> Job:
        """Start one analysis (``operation`` a key of :data:`OPERATIONS`)."""
        self.client()  # 503 before admitting when there is no cluster
        job = Job(uuid.uuid4().hex, operation, time.time() + self.settings.job_time_limit_s,
                  sizes=[1], done=[0.0])
        self._admit(job)
        future = self._submit(job, lambda client: [client.submit(
            run_operation, job.id, operation, body, self.settings, job.end_wall,
            key=f"linkage-job-{job.id}", pure=False)])
        self._watch(job, future)
        return job

    def submit_sweep(self, sweep: mappers.SweepJob, names: tuple[str, ...]) -> Job:
        """Start a sweep, in chunks of its points spread over the workers."""
        n = len(sweep.points)
        chunks = np.array_split(np.arange(n), min(n, CHUNKS_PER_WORKER * self.workers()))
        job = Job(uuid.uuid4().hex, SWEEPS, time.time() + self.settings.job_time_limit_s,
                  sizes=[len(c) for c in chunks], names=names, done=[0.0] * len(chunks))
        self._admit(job)
        # each task gets its own points only (not every point of the sweep)
        shared = dataclasses.replace(sweep, points=sweep.points[:0])
        futures = self._submit(job, lambda client: [
            client.submit(run_sweep_chunk, job.id, k, shared, sweep.points[idx], job.end_wall,
                          key=f"linkage-job-{job.id}-{k}", pure=False)
            for k, idx in enumerate(chunks)
        ])
        self._watch(job, futures)
        return job

    def _submit(self, job: Job, call: Callable[[Client], list[Future]]) -> list[Future]:
        """The admitted ``job``'s tasks; a job that could not be submitted is forgotten."""
        try:
            return self.connection.call(call)
        except ClusterUnavailable:
            with self._lock:
                self._jobs.pop(job.id, None)
            raise

    def _watch(self, job: Job, futures: list[Future]) -> None:
        with self._lock:
            job.futures = futures
        for k, future in enumerate(futures):
            future.add_done_callback(lambda f, k=k: self._on_done(job, k, f))

    def _on_event(self, event: tuple[float, dict[str, Any]]) -> None:
        """A progress report from a task (runs on the client's event loop)."""
        msg = event[1]
        with self._lock:
            job = self._jobs.get(str(msg.get("job")))
            if job is None:
                return
            k = int(msg["chunk"])
            job.started_chunks.add(k)  # even after the job ended: its rows are still wanted
            if job.finished_state:
                return
            if job.status == "queued":
                job.status, job.started = "running", time.time()
            job.done[k] = max(job.done[k], float(msg["fraction"]))  # tasks report in order
            if job.operation == SWEEPS:
                total = sum(job.sizes)
                job.message = f"{round(job.fraction * total)} of {total} points done"
            else:
                job.message = str(msg["message"])

    def _on_done(self, job: Job, k: int, future: Future) -> None:
        """A task ended: keep its part; the job is done when every part is in. A part that
        arrives after the job ended (a task stopped by the cancel flag, or still running when
        another failed) joins its partial result."""
        if future.cancelled():  # by us (a task not started when the job ended), or a lost cluster
            self._stop(job, "failed", error={
                "title": "Worker failed", "loc": [], "detail": "the Dask cluster dropped this "
                "job's task (scheduler restarted or unreachable); the job may be resubmitted"})
            return
        try:
            part = future.result()
        except BaseException as err:  # the task's exception, or its worker died twice
            with self._lock:
                if job.finished_state:
                    return
            log.warning("job %s failed: %s: %s", job.id, type(err).__name__, err)
            self._stop(job, "failed", error=_failure(err))
            return
        with self._lock:
            job.parts[k] = part
            if job.finished_state:
                if job.status != "done":
                    job.result, job.partial = self._partial_result(job), True
                return
            if len(job.parts) < len(job.sizes):
                return
        self._finish(job)

    def _partial_result(self, job: Job) -> Any:
        """The result of the parts that are in (the lock is held): a sweep's rows finished so
        far, or an analysis's answer (incomplete when its task was stopped), else None."""
        if not job.parts:
            return None
        if job.operation != SWEEPS:
            return serialise.loads(job.parts[0])
        rows = [row for k in sorted(job.parts) for row in job.parts[k]]
        return mappers.sweep_out(job.names, rows, partial=True).model_dump(mode="json")

    def _finish(self, job: Job) -> None:
        if job.operation == SWEEPS:
            rows = [row for k in range(len(job.sizes)) for row in job.parts[k]]
            if len(rows) < sum(job.sizes):  # a task stopped early: the time limit
                self._stop(job, "failed", error={
                    "title": "Time limit exceeded", "loc": [],
                    "detail": f"{len(rows)} of {sum(job.sizes)} points were done within "
                    f"LINKAGE_JOB_TIME_LIMIT_S = {self.settings.job_time_limit_s:g} s (the "
                    "result holds them, marked partial)"})
                return
            result: Any = mappers.sweep_out(job.names, rows).model_dump(mode="json")
        else:  # kept as the worker's JSON: parsing it here took seconds for large answers
            result = serialise.RawJSON(job.parts[0])
        with self._lock:
            job.result, job.parts = result, {}
            job.status, job.message, job.finished = "done", "done", time.time()
            job.started = job.started or job.finished
            job.futures = []
        self._forget_flag(job)

    def _stop(self, job: Job, status: str, reason: str = "",
              error: dict[str, Any] | None = None) -> None:
        """End a job: its running tasks stop at their next check (cancel flag) and what they
        finished joins the partial result; the tasks not started are dropped."""
        with self._lock:
            if job.finished_state:
                return
            job.status, job.finished = status, time.time()
            job.message = reason or status
            job.error = error
            job.result = self._partial_result(job)
            job.partial = job.result is not None
            pending = [(k, f) for k, f in enumerate(job.futures) if k not in job.parts]
            unstarted = [f for k, f in pending if k not in job.started_chunks]
            # the running ones stay referenced (a future let go is released by the scheduler,
            # and its rows with it) until they hand their rows in
            job.futures = [f for k, f in pending if k in job.started_chunks]
        if self._connection is None:
            return
        try:
            self._connection.stop_tasks(job.id, unstarted)
        except Exception as err:  # e.g. the cluster went away: nothing left to stop
            log.warning("could not stop the tasks of job %s: %s", job.id, err)

    def _forget_flag(self, job: Job) -> None:
        if self._connection is not None:
            try:
                self._connection.forget_flag(job.id)
            except Exception as err:
                log.debug("cancel flag of job %s: %s", job.id, err)

    def cancel(self, job_id: str) -> Job:
        job = self.get(job_id)
        self._stop(job, "cancelled", "cancelled on request")
        return job

    def get(self, job_id: str) -> Job:
        self._purge()
        with self._lock:
            job = self._jobs.get(job_id)
        if job is None:
            raise UnknownJob(f"no job {job_id!r} (finished jobs are kept LINKAGE_JOB_TTL_S = "
                             f"{self.settings.job_ttl_s:g} s)")
        return job

    def jobs(self) -> list[Job]:
        """The jobs kept now (queued, running, and finished ones not yet forgotten), oldest
        first."""
        self._purge()
        with self._lock:
            return sorted(self._jobs.values(), key=lambda j: j.created)

    def expires(self, job: Job) -> float | None:
        return None if job.finished is None else job.finished + self.settings.job_ttl_s

    def _purge(self) -> None:
        """Forget expired jobs (and the oldest finished ones beyond :data:`KEPT_PER_ACTIVE`
        times ``LINKAGE_MAX_JOBS``, which bounds the memory results take); fail the jobs far
        past their time limit."""
        now = time.time()
        with self._lock:
            finished = sorted((j for j in self._jobs.values() if j.finished is not None),
                              key=lambda j: j.finished or 0.0)
            surplus = len(finished) - KEPT_PER_ACTIVE * self.settings.max_jobs
            expired = [j.id for k, j in enumerate(finished)
                       if k < surplus or now > (j.finished or 0.0) + self.settings.job_ttl_s]
            gone = [self._jobs.pop(job_id) for job_id in expired]
            overdue = [j for j in self._jobs.values()
                       if not j.finished_state and now > j.end_wall + GRACE_S]
        for job in gone:
            if job.status != "done":
                self._forget_flag(job)
        for job in overdue:
            self._stop(job, "failed", error={
                "title": "Time limit exceeded", "loc": [],
                "detail": f"the job ran longer than LINKAGE_JOB_TIME_LIMIT_S = "
                f"{self.settings.job_time_limit_s:g} s and was stopped"})
