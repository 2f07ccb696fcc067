"""Jobs (long work with progress, on Dask) and sweeps (a job over a family of linkages)."""

from typing import Annotated

from fastapi import APIRouter, Depends, Request, Response
from fastapi.exceptions import RequestValidationError

from service import answers, mappers, serialise, tasks
from service.bodies import JsonBodyRoute
from service.config import SettingsDep
from service.errors import problem_responses
from service.figure_formats import MEDIA_TYPES
from service.operations import OPERATIONS, REQUESTS, SWEEPS, figure_bytes
from service.schemas.jobs import (
    JobOut,
    JobRequest,
    JobStatusName,
    JobSummary,
    OperationOut,
    SweepRequest,
)
from service.serialise import FastJSONResponse
from service.tasks import JobManager

router = APIRouter(prefix="/v1", tags=["jobs"], route_class=JsonBodyRoute)
_CSV = "text/csv"
_SVG = "image/svg+xml"
_FIGURE_TYPES = [t for t in MEDIA_TYPES.values() if t != _SVG]


async def job_manager(request: Request) -> JobManager:
    """The application's job manager (a coroutine: called on the event loop, not in the thread
    pool; see :func:`service.config.request_settings`)."""
    manager: JobManager = request.app.state.jobs
    return manager


Manager = Annotated[JobManager, Depends(job_manager)]


def _accepted(manager: JobManager, job: tasks.Job) -> Response:
    return FastJSONResponse(mappers.job_out(job, manager.expires(job)), status_code=202,
                            headers={"location": f"/v1/jobs/{job.id}"})


@router.get("/jobs", operation_id="listJobs", response_model=list[JobSummary],
            responses=problem_responses(422))
def list_jobs(manager: Manager, status: JobStatusName | None = None) -> Response:
    """The jobs the service keeps (queued, running, and finished ones until they expire),
    oldest first, without their results; ``status`` keeps those in that state."""
    return FastJSONResponse([mappers.job_summary_out(j, manager.expires(j))
                             for j in manager.jobs() if status in (None, j.status)])


@router.post("/jobs", operation_id="createJob", status_code=202, response_model=JobOut,
             responses=problem_responses(400, 413, 422, 503))
def create_job(job: JobRequest, manager: Manager, settings: SettingsDep) -> Response:
    """Run any analysis as a job: ``operation`` is its path (e.g.
    ``analysis/configuration-space``), ``body`` the request that path takes. Answers 202 with
    the job's ``Location``; the job's result is that endpoint's answer."""
    model = REQUESTS.get(job.operation)
    if model is None:
        known = ", ".join(REQUESTS)
        raise RequestValidationError([{
            "loc": ("body", "operation"), "type": "value_error",
            "msg": f"unknown operation {job.operation!r}; known: {known}"}])
    body = mappers.job_body_in(model, job.body)
    if isinstance(body, SweepRequest):
        return create_sweep(body, manager, settings)
    return _accepted(manager, manager.submit(job.operation, body))


@router.get(
    "/jobs/operations", operation_id="listJobOperations",
    response_model=list[OperationOut],
)
def operations() -> list[OperationOut]:
    """The operations a job can run, with the request schema of each one's body."""
    return [OperationOut(operation=k, request=m.__name__)
            for k, m in REQUESTS.items()]


@router.get(
    "/jobs/{job_id}", operation_id="getJob",
    response_model=JobOut, responses=problem_responses(404),
)
def get_job(job_id: str, manager: Manager) -> Response:
    """Status (queued, running, done, failed, cancelled), progress, and the result when done."""
    job = manager.get(job_id)
    return FastJSONResponse(mappers.job_out(job, manager.expires(job)))


@router.delete(
    "/jobs/{job_id}", operation_id="cancelJob",
    response_model=JobOut, responses=problem_responses(404),
)
def cancel_job(job_id: str, manager: Manager) -> Response:
    """Cancel a job: running tasks stop at their next check, the others never start. A job
    that has already finished is left as it is."""
    job = manager.cancel(job_id)
    return FastJSONResponse(mappers.job_out(job, manager.expires(job)))


@router.get(
    "/jobs/{job_id}/result", operation_id="getJobResult",
    responses={**problem_responses(404, 406, 409),
               200: {"content": {"application/json": {}, _CSV: {}, _SVG: {},
                                 **{t: {} for t in _FIGURE_TYPES}},
                     "description": "the result; a sweep's rows as CSV with Accept: text/csv; "
                     "a figure in its format (the body's `format`, default SVG)"}},
)
def job_result(job_id: str, request: Request, manager: Manager) -> Response:
    """The result of a finished job alone (of a failed or cancelled one: what it finished,
    marked ``partial``); ``Accept: text/csv`` gives a sweep's rows as CSV; a figure's job
    answers its SVG (``image/svg+xml``), or the format its body's ``format`` names."""
    job = manager.get(job_id)
    if job.result is None:
        raise tasks.JobNotDone(f"job {job_id} is {job.status}, not done, and has no partial "
                               "result")
    if _CSV in request.headers.get("accept", ""):
        if job.operation != SWEEPS:
            raise tasks.NotAcceptable("CSV is offered for sweeps only; ask for application/json")
        return Response(mappers.sweep_csv(job.result), media_type=_CSV)
    operation = OPERATIONS.get(job.operation)
    if isinstance(job.result, serialise.RawJSON):
        if operation is not None and operation.media_type != "application/json":  # a figure
            data, media_type = figure_bytes(job.result.value())
            return Response(data, media_type=media_type)
        return Response(job.result.data, media_type="application/json")
    return FastJSONResponse(job.result)


@router.post("/sweeps", operation_id="createSweep", status_code=202, response_model=JobOut,
             responses=problem_responses(400, 413, 422, 503))
def create_sweep(body: SweepRequest, manager: Manager, settings: SettingsDep) -> Response:
    """One analysis over a grid of lengths or Monte Carlo samples (with a seed), as a job whose
    result is ``{rows, summary}`` (CSV from ``/v1/jobs/{id}/result`` with Accept: text/csv)."""
    sweep = mappers.sweep_in(body, settings.limits)
    answers.check_sweep(len(sweep.points), len(sweep.names),
                        len(sweep.compute) + answers.CELL_NUMBERS * sweep.cells, settings)
    return _accepted(manager, manager.submit_sweep(sweep, sweep.names))
