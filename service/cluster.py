"""The Dask cluster behind jobs and sweeps: an embedded one that only the service can reach, or
an external one (``LINKAGE_DASK_SCHEDULER``) that the service reconnects to when it returns.

Dask runs pickled functions for anyone who can talk to its scheduler, its nannies or its workers
(``Client.submit``, ``Client.run``, ``Nanny.run``), so the embedded cluster is closed to
everyone but the service:

* its scheduler, nannies and workers listen on 127.0.0.1 only, over TLS with mutual
  authentication: a certificate made at start (``distributed.Security.temporary``, a fresh
  2048-bit RSA key kept in memory and handed to the worker processes by their nannies) that
  every connection must present, so another local user cannot connect;
* its workers run at the engine pool's lower priority (``WORKER_NICE``), the nannies and the
  scheduler at the service's own;
* none of them serves HTTP: ``distributed`` starts an HTTP server on every scheduler (on
  127.0.0.1:8787 even with ``dashboard_address=None``: ``Scheduler.__init__`` always calls
  ``start_http_server`` with the default port 8787, for the routes of
  ``distributed.scheduler.http.routes``) and worker (a random port) and has no setting to turn
  it off, so :class:`QuietScheduler` and :class:`QuietWorker` start none.

An external cluster is reached as ``LINKAGE_DASK_SCHEDULER`` says (``tls://`` with the
certificates in Dask's own settings, ``DASK_DISTRIBUTED__COMM__TLS__*``; see the README). The
client is dropped when its scheduler is lost and made anew on the next use, so a scheduler that
comes back is used again; meanwhile jobs are refused with 503 ``cluster-unavailable``.

This module is the only one that imports ``distributed``: the service imports it with its first
job (:attr:`service.tasks.JobManager.connection`), and a task's deadline on a Dask worker
(:func:`task_deadline`: the job's time limit, cancel flag and progress) is made here too.
"""

from __future__ import annotations

import logging
import math
import os
import threading
import time
from collections.abc import Callable
from typing import Any, TypeVar

from distributed import (
    Client,
    Event,
    Future,
    Nanny,
    Scheduler,
    Security,
    SpecCluster,
    Worker,
    get_worker,
)
from distributed.comm.core import CommClosedError
from distributed.http.routing import RoutingApplication

from engine.model.budget import Deadline, ProgressSink
from service.job_state import ClusterUnavailable
from service.workers import WORKER_NICE

log = logging.getLogger("service.cluster")
T = TypeVar("T")

#: Dask event topic of the jobs' progress reports (``{"job", "chunk", "fraction", "message"}``).
TOPIC = "linkage-jobs"
#: How long connecting to an external scheduler may take.
CONNECT_TIMEOUT_S = 10.0
#: After a failed attempt to connect, jobs are refused (503) this long before the next one.
RECONNECT_S = 2.0

#: The one interface the embedded cluster listens on.
LOOPBACK = "127.0.0.1"
#: Shortest interval between two progress reports of one task (the last one always goes).
PROGRESS_INTERVAL_S = 0.1
#: Shortest interval between two reads of a job's cancel flag by one task.
STOP_CHECK_S = 0.2


class _NoHttp:
    """A Dask server that starts no HTTP server (``Node.start_http_server`` replaced): its
    routing application exists, for the code that stops it at close, but never listens."""

    def start_http_server(self, routes: Any, dashboard_address: Any, default_port: int = 0,
                          ssl_options: Any = None) -> None:
        self.http_application = RoutingApplication([])
        self.http_server = None


class QuietScheduler(_NoHttp, Scheduler):
    """A scheduler without HTTP (no dashboard, no ``/health``, ``/metrics`` or ``/info``)."""


class QuietWorker(_NoHttp, Worker):
    """A worker without HTTP, at the engine pool's lower CPU priority: it is made in the worker
    process its nanny starts, so ``os.nice`` lowers that process only (by ``WORKER_NICE``, as
    :func:`service.workers._limit_memory` lowers the pool's workers), and the service's event
    loop and small requests' lane come first while a sweep saturates the cores."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        os.nice(WORKER_NICE)
        super().__init__(*args, **kwargs)


def embedded_cluster(workers: int, allowed_failures: int) -> SpecCluster:
    """``workers`` worker processes (one thread each, each under its nanny) and a scheduler
    in this process, on loopback over mutually authenticated TLS, without HTTP.
    ``allowed_failures``: how often a task whose worker died is run again elsewhere."""
    security = Security.temporary()  # require_encryption: tls:// only
    common = {"host": LOOPBACK, "protocol": "tls", "security": security}
    scheduler = {"cls": QuietScheduler,
                 "options": {**common, "dashboard": False, "dashboard_address": None,
                             "allowed_failures": allowed_failures}}
    worker = {"cls": Nanny,
              "options": {**common, "nthreads": 1, "worker_class": QuietWorker,
                          "dashboard": False, "silence_logs": logging.ERROR}}
    return SpecCluster(workers=dict.fromkeys(range(workers), worker), scheduler=scheduler,
                       security=security, silence_logs=logging.ERROR,
                       name="linkage-embedded")


def client_for(cluster: SpecCluster) -> Client:
    return Client(cluster, security=cluster.security, set_as_default=False)


def connect(address: str, timeout: float) -> Client:
    """A client of the external scheduler at ``address`` (TLS from Dask's settings)."""
    return Client(address, timeout=timeout, set_as_default=False)


def usable(client: Client) -> bool:
    """The client is connected to its scheduler (not reconnecting, closing or closed)."""
    return client.status == "running"


class Connection:
    """The service's Dask client: to the scheduler at ``address``, else to an embedded cluster
    of ``workers`` (made on first use). A client whose scheduler was lost is dropped and the
    next call connects anew; until the scheduler is back each call is a 503 (at once for
    :data:`RECONNECT_S` after a failed attempt, so that requests do not queue behind connection
    timeouts). ``on_event`` receives the progress reports of :data:`TOPIC`."""

    def __init__(self, address: str | None, workers: int,
                 on_event: Callable[[Any], None], allowed_failures: int) -> None:
        self.address = address
        self.n_workers = workers
        self.allowed_failures = allowed_failures
        self._on_event = on_event
        self._lock = threading.Lock()
        self._connecting = threading.Lock()  # one attempt at a time, outside the state's lock
        self._client: Client | None = None
        self._cluster: SpecCluster | None = None
        self._unreachable: ClusterUnavailable | None = None  # the last failed attempt
        self._retry_at = -math.inf

    @property
    def where(self) -> str:
        return self.address or "the embedded cluster"

    def current(self) -> Client | None:
        """The client now, without connecting (None when there is none)."""
        with self._lock:
            return self._client

    def client(self) -> Client:
        with self._lock:
            if self._client is not None and not usable(self._client):
                self._drop(self._client)
            if self._client is not None:
                return self._client
            if self._unreachable is not None and time.monotonic() < self._retry_at:
                raise self._unreachable
        with self._connecting:
            with self._lock:
                if self._client is not None:
                    return self._client
            try:
                client = self._connect()
            except ClusterUnavailable as err:
                with self._lock:
                    self._unreachable, self._retry_at = err, time.monotonic() + RECONNECT_S
                raise
            client.subscribe_topic(TOPIC, self._on_event)
            with self._lock:
                self._client, self._unreachable = client, None
            return client

    def _connect(self) -> Client:
        try:
            if self.address:
                return connect(self.address, CONNECT_TIMEOUT_S)
            if self._cluster is None:
                self._cluster = embedded_cluster(self.n_workers, self.allowed_failures)
            return client_for(self._cluster)
        except Exception as err:  # unreachable, refused, or a cluster that cannot start
            raise ClusterUnavailable(f"cannot reach the Dask scheduler at {self.where}: {err}",
                                     retry_after=5) from None

    def _drop(self, lost: Client) -> None:
        """Forget a client that lost its scheduler (the lock is held)."""
        if self._client is not lost:
            return
        self._client = None
        log.warning("lost the Dask scheduler at %s (client %s): reconnecting on the next job",
                    self.where, lost.status)
        threading.Thread(target=_close_quietly, args=(lost,), daemon=True).start()

    def call(self, fn: Callable[[Client], T]) -> T:
        """``fn(client)``; a scheduler lost meanwhile is a 503 (and a new client next time)."""
        client = self.client()
        try:
            return fn(client)
        except (OSError, CommClosedError, TimeoutError) as err:
            with self._lock:
                self._drop(client)
            raise ClusterUnavailable(f"lost the Dask scheduler at {self.where}: "
                                     f"{type(err).__name__}: {err}", retry_after=5) from None

    def stop_tasks(self, job_id: str, unstarted: list[Future]) -> None:
        """Set the job's cancel flag (its running tasks stop at their next check) and cancel
        its ``unstarted`` tasks, through the client now (nothing without one)."""
        client = self.current()
        if client is not None:
            Event(cancel_flag(job_id), client=client).set()
            client.cancel(unstarted)

    def forget_flag(self, job_id: str) -> None:
        """Clear the job's cancel flag (the scheduler forgets it)."""
        client = self.current()
        if client is not None:
            Event(cancel_flag(job_id), client=client).clear()

    def workers(self) -> int:
        """Workers of the cluster now (at least one)."""
        return max(1, len(self.call(lambda client: client.nthreads())))

    def close(self) -> None:
        """Close the client and the embedded cluster."""
        with self._lock:
            client, embedded = self._client, self._cluster
            self._client = self._cluster = None
        if client is not None:
            client.close()
        if embedded is not None:
            embedded.close()


def _close_quietly(client: Client) -> None:
    try:
        client.close(timeout=5)
    except Exception as err:  # its scheduler is gone: nothing to close there
        log.debug("closing a lost Dask client: %s", err)


# -- in the Dask worker ----------------------------------------------------------------------


def cancel_flag(job_id: str) -> str:
    """The name of the job's cancel flag (a ``distributed.Event``)."""
    return f"linkage-cancel-{job_id}"


def task_deadline(job_id: str, chunk: int, end_wall: float) -> Deadline:
    """The deadline of one task: the job's time limit (wall clock, as workers may run on
    other machines), its cancel flag, and a progress sink that publishes to :data:`TOPIC`."""
    worker = get_worker()
    flag = Event(cancel_flag(job_id))
    checked = {"at": -math.inf, "set": False, "sent": -math.inf}

    def stop() -> bool:
        now = time.monotonic()
        if not checked["set"] and now - checked["at"] >= STOP_CHECK_S:
            checked["at"], checked["set"] = now, bool(flag.is_set())
        return bool(checked["set"])

    def progress(fraction: float, message: str) -> None:
        now = time.monotonic()
        if fraction < 1.0 and now - checked["sent"] < PROGRESS_INTERVAL_S:
            return
        checked["sent"] = now
        worker.log_event(TOPIC, {"job": job_id, "chunk": chunk, "fraction": fraction,
                                 "message": message})

    sink: ProgressSink = progress
    sink(0.0, f"started on {worker.address}")
    return Deadline.after(end_wall - time.time(), stop=stop, progress=sink)
