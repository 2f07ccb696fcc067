"""``linkage-topology``: the service's jobs and sweeps from the command line, no server needed.

Examples::

    linkage-topology sweep --preset four-bar --grid L2=0.5:2:20 -o sweep.csv
    linkage-topology sweep --preset gated-kl-chain --param n=4 --param gate=2 \\
        --sample D=2.5:0.2 --count 100 --seed 0 --compute components,windings -o gate.json
    linkage-topology sweep request.json -o rows.csv        # a POST /v1/sweeps body
    linkage-topology run analysis/configuration-space request.json -o space.json
    linkage-topology run analysis/critical-points --preset four-bar --param L2=1
    linkage-topology presets                  # the names; ``presets four-bar``: one in full
    linkage-topology figure linkage --preset four-bar -o four-bar.svg   # .png, .pdf, .tex, .dxf
    linkage-topology figure configuration-space --preset four-bar -o space.png --dpi 300
    linkage-topology --version

``run`` and ``figure`` work in this process (no Dask), under ``--time-limit`` (default
``LINKAGE_JOB_TIME_LIMIT_S``), unless ``--scheduler`` is given: then, like sweeps, they run on
Dask exactly as in the service: on ``--scheduler`` (default ``LINKAGE_DASK_SCHEDULER``) or an
embedded cluster of ``--workers`` processes, with progress from the engine drawn with ``rich``
unless ``--no-progress``. Heavy modules are imported when a command needs them, so that
``--help`` answers at once.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:  # imported where used: --help and presets need none of them
    from pydantic import BaseModel

    from service import tasks

#: How often the progress bar reads the job's state (the state itself is pushed by the tasks).
REFRESH_S = 0.1
#: The figure formats and their file suffixes (service.figure_formats.SUFFIXES, named here so
#: that --help imports nothing).
FIGURE_FORMATS = ("svg", "png", "pdf", "tikz", "dxf")
_SUFFIXES = {".svg": "svg", ".png": "png", ".pdf": "pdf", ".tex": "tikz", ".tikz": "tikz",
             ".dxf": "dxf"}


class UsageError(Exception):
    """Bad command-line input: reported on stderr with exit status 2."""


def _pairs(items: list[str], what: str) -> dict[str, str]:
    out = {}
    for item in items:
        key, sep, value = item.partition("=")
        if not sep or not key:
            raise UsageError(f"{what}: expected NAME=VALUE, got {item!r}")
        out[key] = value
    return out


def _numbers(text: str, count: int, what: str) -> list[float]:
    parts = text.split(":")
    try:
        values = [float(p) for p in parts]
    except ValueError:
        raise UsageError(f"{what}: not a number in {text!r}") from None
    if len(values) != count:
        raise UsageError(f"{what}: expected {count} numbers separated by ':', got {text!r}")
    return values


def _preset(args: argparse.Namespace) -> dict[str, Any]:
    given = _pairs(args.param, "--param")
    params = {k: _numbers(v, 1, f"--param {k}")[0] for k, v in given.items()}
    return {"name": args.preset, "parameters": params}


def _request(args: argparse.Namespace, model: type[BaseModel]) -> BaseModel:
    """The request from a JSON file, or built from the flags."""
    from pydantic import ValidationError

    from engine.catalogue.presets import build_preset
    from service import mappers
    from service.schemas.jobs import SweepRequest

    if args.request is not None:
        if args.preset is not None:
            raise UsageError("give a request file or --preset, not both")
        try:
            body = json.loads(Path(args.request).read_text())
        except (OSError, json.JSONDecodeError) as err:
            raise UsageError(f"cannot read {args.request}: {err}") from None
    elif args.preset is None:
        raise UsageError("give a request file or --preset")
    elif model is SweepRequest:
        body = {"preset": _preset(args), "seed": args.seed,
                "compute": args.compute.split(",")}
        if args.grid:
            body["grid"] = {k: dict(zip(("min", "max", "steps"), _numbers(v, 3, f"--grid {k}"),
                                        strict=True))
                            for k, v in _pairs(args.grid, "--grid").items()}
            for axis in body["grid"].values():
                axis["steps"] = int(axis["steps"])
        if args.sample:
            body["samples"] = {k: dict(zip(("mean", "sd"), _numbers(v, 2, f"--sample {k}"),
                                           strict=True))
                               for k, v in _pairs(args.sample, "--sample").items()}
            body["count"] = args.count
    else:
        preset = _preset(args)
        linkage = mappers.linkage_out(build_preset(preset["name"], preset["parameters"]))
        body = {"linkage": linkage.model_dump(mode="json", exclude_none=True)}
    if args.options:
        body["options"] = json.loads(args.options)
    if getattr(args, "command", None) == "figure":
        _figure_fields(args, body)
    try:
        return model.model_validate_json(json.dumps(body))
    except ValidationError as err:
        lines = [f"  {'.'.join(map(str, e['loc']))}: {e['msg']}" for e in err.errors()]
        raise UsageError("invalid request:\n" + "\n".join(lines)) from None


def _wait(manager: tasks.JobManager, job: tasks.Job, show: bool) -> None:
    """Until the job finishes, drawing its progress unless ``show`` is False."""
    from rich.console import Console
    from rich.progress import (
        BarColumn,
        Progress,
        TaskProgressColumn,
        TextColumn,
        TimeElapsedColumn,
    )

    if not show:
        while not job.finished_state:
            time.sleep(REFRESH_S)
        return
    columns = (TextColumn("{task.description}"), BarColumn(), TaskProgressColumn(),
               TimeElapsedColumn(), TextColumn("{task.fields[message]}"))
    with Progress(*columns, console=Console(stderr=True)) as bar:  # stdout: the result
        task = bar.add_task(job.operation, total=1.0, message=job.message)
        while not job.finished_state:
            bar.update(task, completed=job.fraction, message=job.message)
            time.sleep(REFRESH_S)
        bar.update(task, completed=job.fraction, message=job.message)


def _figure_fields(args: argparse.Namespace, body: dict[str, Any]) -> None:
    """The figure's ``format`` (--format, the request's, the suffix of --output, else svg) and
    ``dpi`` in its request body."""
    suffix = Path(args.output).suffix.lower() if args.output not in (None, "-") else ""
    if suffix and suffix not in _SUFFIXES:
        raise UsageError(f"-o {args.output}: a figure is written as "
                         f"{', '.join(sorted(_SUFFIXES))}")
    fmt = args.format or body.get("format") or _SUFFIXES.get(suffix, "svg")
    if suffix and _SUFFIXES[suffix] != fmt:
        raise UsageError(f"-o {args.output} is not a {fmt} file (--format or the request's "
                         "format)")
    body["format"] = fmt
    if args.dpi is not None:
        body["dpi"] = args.dpi


def _write(result: Any, out: str | None, fmt: str | None, sweep: bool) -> None:
    from service import mappers, serialise

    if isinstance(result, serialise.RawJSON):
        result = result.value()
    fmt = fmt or ("csv" if out and out.endswith(".csv") else "json")
    if fmt == "csv":
        if not sweep:
            raise UsageError("CSV is written for sweeps only")
        text = mappers.sweep_csv(result)
    else:
        text = json.dumps(result, indent=2) + "\n"
    if out in (None, "-"):
        sys.stdout.write(text)
    else:
        Path(out).write_text(text)


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="linkage-topology", description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = p.add_subparsers(dest="command", required=True)
    common = argparse.ArgumentParser(add_help=False)
    common.add_argument("--preset", help="build the linkage from this preset")
    common.add_argument("--param", action="append", default=[], metavar="NAME=VALUE",
                        help="a preset parameter (repeatable)")
    common.add_argument("--options", help="search options as JSON (the requests' options)")
    common.add_argument("-o", "--output", help="write here (default stdout)")
    common.add_argument("--no-progress", action="store_true", help="no progress bar")
    common.add_argument("--scheduler", help="Dask scheduler address (default "
                        "LINKAGE_DASK_SCHEDULER, else an embedded cluster)")
    common.add_argument("--workers", type=int, help="embedded cluster workers (default: cores)")
    common.add_argument("--time-limit", type=float, help="seconds (default "
                        "LINKAGE_JOB_TIME_LIMIT_S)")
    sw = sub.add_parser("sweep", parents=[common], help="a sweep (grid or Monte Carlo)")
    sw.add_argument("request", nargs="?", help="a JSON file with a POST /v1/sweeps body")
    sw.add_argument("--format", choices=("json", "csv"), help="default: from --output")
    sw.add_argument("--grid", action="append", default=[], metavar="NAME=MIN:MAX:STEPS")
    sw.add_argument("--sample", action="append", default=[], metavar="NAME=MEAN:SD")
    sw.add_argument("--count", type=int, help="Monte Carlo points")
    sw.add_argument("--seed", type=int, default=0)
    sw.add_argument("--compute", default="components",
                    help="comma-separated: components,critical,margin,windings")
    run = sub.add_parser("run", parents=[common], help="one analysis, e.g. "
                         "analysis/configuration-space (in this process; on Dask with "
                         "--scheduler)")
    run.add_argument("operation", help="an analysis path (see GET /v1/jobs/operations)")
    run.add_argument("request", nargs="?", help="a JSON file with that endpoint's request body")
    run.add_argument("--format", choices=("json", "csv"), help="default: from --output")
    fig = sub.add_parser("figure", parents=[common], help="a figure as SVG, PNG, PDF, TikZ or "
                         "DXF, e.g. linkage")
    fig.add_argument("operation", help="linkage, configuration-space, critical-values or "
                     "splitting (or figures/<name>)")
    fig.add_argument("request", nargs="?", help="a JSON file with that endpoint's request body")
    fig.add_argument("--format", choices=FIGURE_FORMATS, help="default: the request's "
                     "format, else from --output's suffix (.svg, .png, .pdf, .tex, .dxf), else svg")
    fig.add_argument("--dpi", type=int, help="a PNG's dots per inch (default 150)")
    pre = sub.add_parser("presets", help="the preset names, or one preset in full")
    pre.add_argument("name", nargs="?", help="a preset: its description and parameters")
    p.add_argument("--version", action="version", version=f"%(prog)s {_version()}")
    return p


def _version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("linkage-topology")
    except PackageNotFoundError:  # run from a source tree that is not installed
        return "unknown"


def _presets(name: str | None) -> int:
    from engine.catalogue.presets import PRESETS
    from service import mappers

    if name is None:
        for preset in PRESETS.values():
            sys.stdout.write(f"{preset.name}\n")
        return 0
    if name not in PRESETS:
        raise UsageError(f"no preset named {name!r}; known: {', '.join(sorted(PRESETS))}")
    info = next(p for p in mappers.presets_out() if p.name == name)
    sys.stdout.write(info.model_dump_json(indent=2) + "\n")
    return 0


def _in_process(args: argparse.Namespace, operation: str) -> Any:
    """One operation run here under the time limit: its answer as JSON data (a figure: its
    bytes)."""
    import inspect

    from engine.model.budget import Deadline
    from service.config import get_settings
    from service.operations import OPERATIONS

    op = OPERATIONS[operation]
    settings = get_settings()
    limit = args.time_limit or settings.job_time_limit_s
    body = _request(args, op.request)
    run = op.run
    if op.media_type != "application/json":  # a figure: its bytes (any format), not the job's text
        from service import figures

        run = getattr(figures, op.run.__name__)
    kwargs = ({"deadline": Deadline.after(limit)}
              if "deadline" in inspect.signature(run).parameters else {})
    answer = run(body, settings, **kwargs)
    return answer if isinstance(answer, bytes | str) else answer.model_dump(mode="json")


def _operation(args: argparse.Namespace) -> str:
    from service.operations import OPERATIONS

    name = args.operation
    if args.command == "figure" and not name.startswith("figures/"):
        name = f"figures/{name}"
    figure = name.startswith("figures/")
    if name not in OPERATIONS or figure != (args.command == "figure"):
        known = [k for k in OPERATIONS if k.startswith("figures/") == (args.command == "figure")]
        raise UsageError(f"unknown operation {args.operation!r}; known: {', '.join(known)}")
    return name


def _on_dask(args: argparse.Namespace, operation: str | None) -> Any:
    """A sweep, or an operation with --scheduler, as a job on Dask (the service's path)."""
    from service import mappers, tasks
    from service.config import get_settings
    from service.operations import OPERATIONS
    from service.schemas.jobs import SweepRequest

    changes: dict[str, Any] = {}
    if args.scheduler:
        changes["dask_scheduler"] = args.scheduler
    if args.workers:
        changes["dask_workers"] = args.workers
    if args.time_limit:
        changes["job_time_limit_s"] = args.time_limit
    settings = get_settings().replace(**changes)
    manager = tasks.JobManager(settings)
    try:
        if operation is None:
            body = _request(args, SweepRequest)
            assert isinstance(body, SweepRequest)
            sweep_job = mappers.sweep_in(body, settings.limits)
            job = manager.submit_sweep(sweep_job, sweep_job.names)
        else:
            job = manager.submit(operation, _request(args, OPERATIONS[operation].request))
        try:
            _wait(manager, job, show=not args.no_progress)
        except KeyboardInterrupt:
            manager.cancel(job.id)
            raise
        if job.status != "done":
            error = job.error or {"title": job.status, "detail": job.message}
            raise _Failed(f"{error['title']}: {error['detail']}")
        return job.result
    finally:
        manager.close()


class _Failed(Exception):
    """The work ran and failed (exit status 1)."""


def _figure_out(figure: Any, out: str | None) -> None:
    """A figure's answer (its bytes in-process; a job's text or data: URL on Dask) written."""
    from service import serialise
    from service.operations import figure_bytes

    if isinstance(figure, serialise.RawJSON):
        figure = figure.value()
    data = figure if isinstance(figure, bytes) else figure_bytes(figure)[0]
    if out in (None, "-"):
        sys.stdout.buffer.write(data)
        sys.stdout.flush()
        return
    Path(out).write_bytes(data)


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    from engine.model.errors import EngineError
    from service.workers import ServiceFault

    try:
        if args.command == "presets":
            return _presets(args.name)
        if args.command == "sweep":
            _write(_on_dask(args, None), args.output, args.format, True)
            return 0
        operation = _operation(args)
        result = (_on_dask(args, operation) if args.scheduler
                  else _in_process(args, operation))
        if args.command == "figure":
            _figure_out(result, args.output)
        else:
            _write(result, args.output, args.format, False)
        return 0
    except KeyboardInterrupt:
        print("cancelled", file=sys.stderr)
        return 130
    except (UsageError, EngineError) as err:
        print(f"linkage-topology: {err}", file=sys.stderr)
        return 2
    except _Failed as err:
        print(f"linkage-topology: {err}", file=sys.stderr)
        return 1
    except ServiceFault as err:
        print(f"linkage-topology: {err.title}: {err.detail}", file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())
