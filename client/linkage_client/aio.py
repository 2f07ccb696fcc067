"""The asynchronous client (httpx.AsyncClient): the methods of ``Client``, awaited."""

from __future__ import annotations

import asyncio
import contextlib
import time
from collections.abc import Coroutine, Mapping, Sequence
from types import TracebackType
from typing import Any, TypeVar

import httpx

from linkage_client import _ops as ops
from linkage_client._http import Call, RetryPolicy, raise_for_problem
from linkage_client._presets import PresetRoutes
from linkage_client.errors import ClientError, JobTimeout
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
from linkage_client.sync import DEFAULT_URL, finish

T = TypeVar("T")
Opts = Mapping[str, Any] | None


class AsyncClient(PresetRoutes[Coroutine[Any, Any, Linkage]]):
    """The service over HTTP without blocking an event loop: the methods of ``Client``, each a
    coroutine (``await client.analyse_rigidity(linkage)``).

    Parameters
    ----------
    base_url : str
        Where the service is (the README's start command serves ``http://127.0.0.1:8000``).
    timeout : float
        Seconds for each HTTP request (searches answer within their own time budget).
    retry : RetryPolicy
        Retries of a 503 with ``Retry-After`` (busy, worker lost); bounded.
    transport : httpx.AsyncBaseTransport, optional
        E.g. ``httpx.ASGITransport(app=app)`` to call an ASGI app in process (no network).
    http : httpx.AsyncClient, optional
        A configured httpx client to use instead (its base URL is used as is).

    Examples
    --------
    >>> async with AsyncClient() as c:                          # doctest: +SKIP
    ...     four_bar = await c.get_preset_four_bar(theta=0.5)
    ...     (await c.analyse_second_order(four_bar)).kind
    'regular'
    """

    def __init__(self, base_url: str = DEFAULT_URL, *, timeout: float = 120.0,
                 retry: RetryPolicy | None = None,
                 transport: httpx.AsyncBaseTransport | None = None,
                 http: httpx.AsyncClient | None = None) -> None:
        self.retry = retry if retry is not None else RetryPolicy()
        self._own = http is None
        self.http = http if http is not None else httpx.AsyncClient(
            base_url=base_url, timeout=timeout, transport=transport)

    async def __aenter__(self) -> AsyncClient:
        return self

    async def __aexit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        await self.aclose()

    async def aclose(self) -> None:
        if self._own:
            await self.http.aclose()

    async def _run(self, call: Call[T]) -> T:
        waited = 0.0
        attempt = 0
        while True:
            response = await self.http.request(call.method, call.path, json=call.json,
                                         params=call.params, headers=dict(call.headers))
            delay = self.retry.wait_for(response, attempt, waited)
            if delay is None:
                break
            await asyncio.sleep(delay)
            waited += delay
            attempt += 1
        raise_for_problem(response)
        return call.parse(response)

    # ------------------------------------------------------------ health, presets

    async def get_health_live(self) -> Health:
        return await self._run(ops.health_live())

    async def get_health_ready(self) -> Readiness:
        """Ready to analyse; a 503 ``not-ready`` problem (raised) while starting or replacing
        a broken worker pool."""
        return await self._run(ops.health_ready())

    async def list_jobs(self, status: str | None = None) -> list[JobSummary]:
        """The jobs kept, oldest first, without their results (``status`` filters)."""
        return await self._run(ops.list_jobs(status))

    async def get_health(self) -> Health:
        return await self._run(ops.health())

    async def get_metrics(self) -> str:
        """The Prometheus text of ``/metrics``."""
        return await self._run(ops.metrics())

    async def list_presets(self) -> list[PresetInfo]:
        return await self._run(ops.list_presets())

    async def get_preset(self, name: str, /, **parameters: float) -> Linkage:
        """A catalogue linkage (``GET /v1/presets/{name}``) with any of its parameters."""
        return await self._run(ops.get_preset(name, parameters))

    # ------------------------------------------------------------ analysis and design

    async def analyse_rigidity(self, linkage: ops.LinkageIn, *,
                         tolerances: Opts = None) -> RigidityResult:
        return await self._run(ops.rigidity(linkage, tolerances))

    async def analyse_second_order(self, linkage: ops.LinkageIn, *,
                             tolerances: Opts = None) -> SecondOrderResult:
        return await self._run(ops.second_order(linkage, tolerances))

    async def find_critical_points(self, linkage: ops.LinkageIn, *, options: Opts = None,
                             tolerances: Opts = None) -> CriticalPointsResult:
        return await self._run(ops.critical_points(linkage, options, tolerances))

    async def explore_configuration_space(self, linkage: ops.LinkageIn, *, options: Opts = None,
                                    tolerances: Opts = None,
                                    compact: bool = True) -> SpaceResult:
        """Components as ``(n, V, d)`` arrays (asked compact unless ``compact=False``)."""
        return await self._run(ops.configuration_space(linkage, options, tolerances, compact))

    async def predict_splitting(self, linkage: ops.LinkageIn,
                                perturbation: Mapping[str, float], *, options: Opts = None,
                                tolerances: Opts = None) -> SplittingResult:
        return await self._run(ops.splitting(linkage, perturbation, options, tolerances))

    async def compute_robustness_margin(self, linkage: ops.LinkageIn, *,
                                  adjustable: Sequence[str] | None = None,
                                  method: str | None = None, options: Opts = None,
                                  tolerances: Opts = None) -> RobustnessResult:
        return await self._run(ops.robustness(linkage, adjustable, method, options, tolerances))

    async def map_critical_values(self, linkage: ops.LinkageIn,
                                  axes: Sequence[Mapping[str, Any]], *, options: Opts = None,
                                  tolerances: Opts = None) -> CriticalValuesResult:
        """``axes``: two ``{"bar": id, "min": x, "max": y}``."""
        return await self._run(ops.critical_values(linkage, axes, options, tolerances))

    async def design_splitting(self, linkage: ops.LinkageIn,
                               targets: Sequence[Mapping[str, Any]], adjustable: Sequence[str],
                               *, max_change: float | None = None, margin: float | None = None,
                               options: Opts = None, tolerances: Opts = None) -> DesignResult:
        return await self._run(ops.design(linkage, targets, adjustable, max_change, margin, options,
                                    tolerances))

    # ------------------------------------------------------------ figures (SVG text)

    async def draw_linkage(self, linkage: ops.LinkageIn, *, show: Sequence[str] | None = None,
                     tolerances: Opts = None) -> str:
        return await self._run(ops.draw_linkage(linkage, show, tolerances))

    async def draw_configuration_space(self, linkage: ops.LinkageIn, *,
                                 axes: Sequence[str] | None = None, options: Opts = None,
                                 tolerances: Opts = None) -> str:
        return await self._run(ops.draw_space(linkage, axes, options, tolerances))

    async def draw_critical_values(self, linkage: ops.LinkageIn,
                                   axes: Sequence[Mapping[str, Any]], *, options: Opts = None,
                                   tolerances: Opts = None) -> str:
        return await self._run(ops.draw_critical_values(linkage, axes, options, tolerances))

    async def draw_splitting(self, linkage: ops.LinkageIn, perturbation: Mapping[str, float],
                             *, options: Opts = None, tolerances: Opts = None) -> str:
        return await self._run(ops.draw_splitting(linkage, perturbation, options, tolerances))

    async def draw(self, figure: str, body: Mapping[str, Any], *, format: str = "svg",
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
        return await self._run(ops.draw(figure, body, format, dpi))

    # ------------------------------------------------------------ jobs and sweeps

    async def list_job_operations(self) -> list[Operation]:
        return await self._run(ops.list_job_operations())

    async def create_job(self, operation: str, body: Mapping[str, Any]) -> Job:
        """Start ``operation`` (e.g. ``"analysis/configuration-space"``) on ``body``."""
        return await self._run(ops.create_job(operation, body))

    async def get_job(self, job_id: str) -> Job:
        return await self._run(ops.get_job(job_id))

    async def cancel_job(self, job_id: str) -> Job:
        return await self._run(ops.cancel_job(job_id))

    async def get_job_result(self, job_id: str, *, csv: bool = False) -> Any:
        """The raw result JSON (or a sweep's rows as CSV text with ``csv=True``)."""
        return await self._run(ops.job_result(job_id, csv))

    async def create_sweep(self, body: Mapping[str, Any] | None = None, *,
                     linkage: ops.LinkageIn | None = None, preset: str | None = None,
                     parameters: Mapping[str, float] | None = None, grid: Opts = None,
                     samples: Opts = None, count: int | None = None, seed: int | None = None,
                     compute: Sequence[str] | None = None, options: Opts = None,
                     tolerances: Opts = None) -> Job:
        """Start a sweep, from a ready ``body`` or from the keywords (``POST /v1/sweeps``)."""
        if body is None:
            body = ops.sweep_body(linkage, preset, parameters, grid, samples, count, seed,
                                  compute, options, tolerances)
        return await self._run(ops.create_sweep(body))

    async def wait(self, job: Job | str, *, progress: ProgressArg = None,
                   poll_s: float = 0.25, timeout_s: float | None = None) -> Job:
        """Poll until ``job`` is finished; the finished job (result included).

        ``progress``: a callback given the job at every change, or True for a text bar.
        On ``timeout_s``, KeyboardInterrupt or the task's cancellation the job is cancelled on
        the service (no work is left running) and JobTimeout, the interrupt or the
        CancelledError is raised; a failed or cancelled job raises JobFailed or JobCancelled.
        """
        job_id = job if isinstance(job, str) else job.id
        report = Changes(reporter(progress))
        start = time.monotonic()
        try:
            while True:
                current = await self.get_job(job_id)
                report(current)
                if current.done:
                    return finish(current)
                if timeout_s is not None and time.monotonic() - start > timeout_s:
                    raise JobTimeout(await self.cancel_job(job_id), time.monotonic() - start)
                await asyncio.sleep(poll_s)
        except (KeyboardInterrupt, asyncio.CancelledError):
            # the caller gave up (task cancelled): stop the job too, shielded from the cancel
            with contextlib.suppress(ClientError, httpx.HTTPError):  # the cancel comes first
                await asyncio.shield(self.cancel_job(job_id))
            raise

    async def run_job(self, operation: str, body: Mapping[str, Any], *,
                      progress: ProgressArg = None, timeout_s: float | None = None) -> Any:
        """Create a job, wait for it, and answer its result as the operation's model."""
        job = await self.wait(await self.create_job(operation, body), progress=progress,
                              timeout_s=timeout_s)
        return result_of(job.operation, job.result)

    async def sweep(self, body: Mapping[str, Any] | None = None, *,
                    progress: ProgressArg = None, timeout_s: float | None = None,
                    **keywords: Any) -> SweepResult:
        """``create_sweep`` then ``wait``: the sweep's rows and summary."""
        job = await self.wait(await self.create_sweep(body, **keywords), progress=progress,
                        timeout_s=timeout_s)
        return SweepResult.from_json(job.result or {})
