"""The synchronous client (httpx.Client)."""

from __future__ import annotations

import contextlib
import time
from collections.abc import Mapping, Sequence
from types import TracebackType
from typing import Any, TypeVar

import httpx

from linkage_client import _ops as ops
from linkage_client._http import Call, RetryPolicy, raise_for_problem
from linkage_client._presets import PresetRoutes
from linkage_client.errors import ClientError, JobCancelled, JobFailed, JobTimeout
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
    SweepResult,
    result_of,
)
from linkage_client.progress import Changes, ProgressArg, reporter

T = TypeVar("T")
DEFAULT_URL = "http://127.0.0.1:8000"
Opts = Mapping[str, Any] | None


def finish(job: Job) -> Job:
    """``job`` when done; JobFailed or JobCancelled otherwise."""
    if job.status == "cancelled":
        raise JobCancelled(job)
    if job.status != "done":
        raise JobFailed(job)
    return job


class Client(PresetRoutes[Linkage]):
    """The service over HTTP, one method per operation (``analyseRigidity`` is
    ``analyse_rigidity``), answers as typed models with numpy arrays.

    Parameters
    ----------
    base_url : str
        Where the service is (the README's start command serves ``http://127.0.0.1:8000``).
    timeout : float
        Seconds for each HTTP request (searches answer within their own time budget).
    retry : RetryPolicy
        Retries of a 503 with ``Retry-After`` (busy, worker lost); bounded.
    transport : httpx.BaseTransport, optional
        E.g. ``httpx.WSGITransport``; tests pass the app's ASGI transport to the async client.
    http : httpx.Client, optional
        A configured httpx client to use instead (its base URL is used as is).

    Examples
    --------
    >>> with Client() as c:                                     # doctest: +SKIP
    ...     four_bar = c.get_preset_four_bar(theta=0.5)
    ...     c.analyse_second_order(four_bar).kind
    'regular'
    """

    def __init__(self, base_url: str = DEFAULT_URL, *, timeout: float = 120.0,
                 retry: RetryPolicy | None = None, transport: httpx.BaseTransport | None = None,
                 http: httpx.Client | None = None) -> None:
        self.retry = retry if retry is not None else RetryPolicy()
        self._own = http is None
        self.http = http if http is not None else httpx.Client(
            base_url=base_url, timeout=timeout, transport=transport)

    def __enter__(self) -> Client:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.close()

    def close(self) -> None:
        if self._own:
            self.http.close()

    def _run(self, call: Call[T]) -> T:
        waited = 0.0
        attempt = 0
        while True:
            response = self.http.request(call.method, call.path, json=call.json,
                                         params=call.params, headers=dict(call.headers))
            delay = self.retry.wait_for(response, attempt, waited)
            if delay is None:
                break
            time.sleep(delay)
            waited += delay
            attempt += 1
        raise_for_problem(response)
        return call.parse(response)

    # ------------------------------------------------------------ health, presets

    def get_health_live(self) -> Health:
        return self._run(ops.health_live())

    def get_health_ready(self) -> Readiness:
        """Ready to analyse; a 503 ``not-ready`` problem (raised) while starting or replacing
        a broken worker pool."""
        return self._run(ops.health_ready())

    def list_jobs(self, status: str | None = None) -> list[JobSummary]:
        """The jobs kept, oldest first, without their results (``status`` filters)."""
        return self._run(ops.list_jobs(status))

    def get_health(self) -> Health:
        return self._run(ops.health())

    def get_metrics(self) -> str:
        """The Prometheus text of ``/metrics``."""
        return self._run(ops.metrics())

    def list_presets(self) -> list[PresetInfo]:
        return self._run(ops.list_presets())

    def get_preset(self, name: str, /, **parameters: float) -> Linkage:
        """A catalogue linkage (``GET /v1/presets/{name}``) with any of its parameters."""
        return self._run(ops.get_preset(name, parameters))

    # ------------------------------------------------------------ analysis and design

    def analyse_rigidity(self, linkage: ops.LinkageIn, *,
                         tolerances: Opts = None) -> RigidityResult:
        return self._run(ops.rigidity(linkage, tolerances))

    def analyse_second_order(self, linkage: ops.LinkageIn, *,
                             tolerances: Opts = None) -> SecondOrderResult:
        return self._run(ops.second_order(linkage, tolerances))

    def find_critical_points(self, linkage: ops.LinkageIn, *, options: Opts = None,
                             tolerances: Opts = None) -> CriticalPointsResult:
        return self._run(ops.critical_points(linkage, options, tolerances))

    def explore_configuration_space(self, linkage: ops.LinkageIn, *, options: Opts = None,
                                    tolerances: Opts = None,
                                    compact: bool = True) -> SpaceResult:
        """Components as ``(n, V, d)`` arrays (asked compact unless ``compact=False``)."""
        return self._run(ops.configuration_space(linkage, options, tolerances, compact))

    def predict_splitting(self, linkage: ops.LinkageIn, perturbation: Mapping[str, float], *,
                          options: Opts = None, tolerances: Opts = None) -> SplittingResult:
        return self._run(ops.splitting(linkage, perturbation, options, tolerances))

    def compute_robustness_margin(self, linkage: ops.LinkageIn, *,
                                  adjustable: Sequence[str] | None = None,
                                  method: str | None = None, options: Opts = None,
                                  tolerances: Opts = None) -> RobustnessResult:
        return self._run(ops.robustness(linkage, adjustable, method, options, tolerances))

    def map_critical_values(self, linkage: ops.LinkageIn, axes: Sequence[Mapping[str, Any]], *,
                            options: Opts = None,
                            tolerances: Opts = None) -> CriticalValuesResult:
        """``axes``: two ``{"bar": id, "min": x, "max": y}``."""
        return self._run(ops.critical_values(linkage, axes, options, tolerances))

    def design_splitting(self, linkage: ops.LinkageIn, targets: Sequence[Mapping[str, Any]],
                         adjustable: Sequence[str], *, max_change: float | None = None,
                         margin: float | None = None, options: Opts = None,
                         tolerances: Opts = None) -> DesignResult:
        return self._run(ops.design(linkage, targets, adjustable, max_change, margin, options,
                                    tolerances))

    # ------------------------------------------------------------ figures (SVG text)

    def draw_linkage(self, linkage: ops.LinkageIn, *, show: Sequence[str] | None = None,
                     tolerances: Opts = None) -> str:
        return self._run(ops.draw_linkage(linkage, show, tolerances))

    def draw_configuration_space(self, linkage: ops.LinkageIn, *,
                                 axes: Sequence[str] | None = None, options: Opts = None,
                                 tolerances: Opts = None) -> str:
        return self._run(ops.draw_space(linkage, axes, options, tolerances))

    def draw_critical_values(self, linkage: ops.LinkageIn, axes: Sequence[Mapping[str, Any]], *,
                             options: Opts = None, tolerances: Opts = None) -> str:
        return self._run(ops.draw_critical_values(linkage, axes, options, tolerances))

    def draw_splitting(self, linkage: ops.LinkageIn, perturbation: Mapping[str, float], *,
                       options: Opts = None, tolerances: Opts = None) -> str:
        return self._run(ops.draw_splitting(linkage, perturbation, options, tolerances))

    def draw(self, figure: str, body: Mapping[str, Any], *, format: str = "svg",
             dpi: int | None = None) -> bytes:
        """A figure in a chosen format: its bytes.

        Parameters
        ----------
        figure : str
            ``linkage``, ``configuration-space``, ``critical-values`` or ``splitting``.
        body : mapping
            That figure endpoint's request (``{"linkage": ..., "show": [...]}``, ...).
        format : str
            ``svg``, ``png``, ``pdf``, ``tikz`` (linkage, configuration-space) or ``dxf``
            (linkage).
        dpi : int, optional
            A PNG's dots per inch (the service's default: 150).
        """
        return self._run(ops.draw(figure, body, format, dpi))

    # ------------------------------------------------------------ jobs and sweeps

    def list_job_operations(self) -> list[Operation]:
        return self._run(ops.list_job_operations())

    def create_job(self, operation: str, body: Mapping[str, Any]) -> Job:
        """Start ``operation`` (e.g. ``"analysis/configuration-space"``) on ``body``."""
        return self._run(ops.create_job(operation, body))

    def get_job(self, job_id: str) -> Job:
        return self._run(ops.get_job(job_id))

    def cancel_job(self, job_id: str) -> Job:
        return self._run(ops.cancel_job(job_id))

    def get_job_result(self, job_id: str, *, csv: bool = False) -> Any:
        """The raw result JSON (or a sweep's rows as CSV text with ``csv=True``)."""
        return self._run(ops.job_result(job_id, csv))

    def create_sweep(self, body: Mapping[str, Any] | None = None, *,
                     linkage: ops.LinkageIn | None = None, preset: str | None = None,
                     parameters: Mapping[str, float] | None = None, grid: Opts = None,
                     samples: Opts = None, count: int | None = None, seed: int | None = None,
                     compute: Sequence[str] | None = None, options: Opts = None,
                     tolerances: Opts = None) -> Job:
        """Start a sweep, from a ready ``body`` or from the keywords (``POST /v1/sweeps``)."""
        if body is None:
            body = ops.sweep_body(linkage, preset, parameters, grid, samples, count, seed,
                                  compute, options, tolerances)
        return self._run(ops.create_sweep(body))

    def wait(self, job: Job | str, *, progress: ProgressArg = None, poll_s: float = 0.25,
             timeout_s: float | None = None) -> Job:
        """Poll until ``job`` is finished; the finished job (result included).

        ``progress``: a callback given the job at every change, or True for a text bar.
        On ``timeout_s`` or KeyboardInterrupt the job is cancelled on the service (no work is
        left running) and JobTimeout or the interrupt is raised; a failed or cancelled job
        raises JobFailed or JobCancelled.
        """
        job_id = job if isinstance(job, str) else job.id
        report = Changes(reporter(progress))
        start = time.monotonic()
        try:
            while True:
                current = self.get_job(job_id)
                report(current)
                if current.done:
                    return finish(current)
                if timeout_s is not None and time.monotonic() - start > timeout_s:
                    raise JobTimeout(self.cancel_job(job_id), time.monotonic() - start)
                time.sleep(poll_s)
        except KeyboardInterrupt:
            with contextlib.suppress(ClientError, httpx.HTTPError):  # the interrupt comes first
                self.cancel_job(job_id)
            raise

    def run_job(self, operation: str, body: Mapping[str, Any], *, progress: ProgressArg = None,
                timeout_s: float | None = None) -> Any:
        """Create a job, wait for it, and answer its result as the operation's model."""
        job = self.wait(self.create_job(operation, body), progress=progress, timeout_s=timeout_s)
        return result_of(job.operation, job.result)

    def sweep(self, body: Mapping[str, Any] | None = None, *, progress: ProgressArg = None,
              timeout_s: float | None = None, **keywords: Any) -> SweepResult:
        """``create_sweep`` then ``wait``: the sweep's rows and summary."""
        job = self.wait(self.create_sweep(body, **keywords), progress=progress,
                        timeout_s=timeout_s)
        return SweepResult.from_json(job.result or {})
