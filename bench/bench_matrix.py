"""The preset matrix of issue 30 (run on demand): every preset with its default parameters (and
the chains of the issue: ``kl-chain`` n=100, ``gated-kl-chain`` n=4 gate=2 and its gate slice)
through every endpoint it is meaningful for, with the options a request gets by default, through
HTTP on a warm service and in-process; time and completeness per cell.

    .venv/bin/python bench/bench_matrix.py [--repeat 3] [--only kl-chain] [--no-in-process]
        [--json bench/results/matrix.json] [--markdown docs/preset-matrix.md]

With ``--only``, the rows of those presets (and of their variants) replace theirs in the JSON
file already there (the runs merged into it are listed in its ``merged``) and in the Markdown
page already there (its other rows and sentences kept as written, the count of cells met
recounted, a sentence on the run added); the others are kept as they were measured.

The cases are those of ``tests/service/preset_matrix.py`` (the maps: the first two bars with a
free end as axes over ``[0.8 L, 1.2 L]`` each, resolution and budget by default), for each
variant in ``preset_matrix.VARIANTS``, plus the gate slice (``preset_matrix.gate_slice``).

The service runs as deployed (``uvicorn service.main:app`` in a process of its own, its
default settings: ``LINKAGE_SEARCH_TIME_S`` 4 s) and is measured once it is *ready*
(``/health/ready``: the workers started and warmed). Each cell is asked once untimed-for-the-
median (its first call, reported as ``first``), then ``--repeat`` times; the table gives the
median. In-process: the same job function the route runs (``service.jobs`` or
``service.figures``), serialised as in a worker, in this process with the same settings, after
one warm-up call. A cell is *met* when it answers 200, its answer is complete (a figure: the
analysis it draws is) and the median is under the target (2 s; the gate slice 1 s).

The machine's load average is recorded with every cell: on a shared machine the seconds are an
upper bound of an idle machine's.
"""

from __future__ import annotations

import argparse
import datetime
import importlib.util
import json
import os
import platform
import re
import statistics
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import httpx
from harness import served_process  # bench/ is on sys.path when run as a script

HERE = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(HERE))

Json = dict[str, Any]

#: Target median seconds of a cell (issue 30), and of the named cells.
TARGET_S = 2.0
GATE_SLICE = "gate slice L2 x D"
TARGETS = {GATE_SLICE: 1.0}


def load_matrix() -> Any:
    """``tests/service/preset_matrix.py`` by path (it imports nothing of the project)."""
    spec = importlib.util.spec_from_file_location(
        "preset_matrix", HERE / "tests" / "service" / "preset_matrix.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def cells(client: httpx.Client, only: list[str] | None
          ) -> Iterator[tuple[str, str, str, Json]]:
    """``(preset label, cell label, endpoint, body)`` of the whole matrix: every preset with
    its defaults and every variant (``preset_matrix.VARIANTS``) through every endpoint it is
    meaningful for, then the gate slice."""
    matrix = load_matrix()
    for label, linkage in matrix.variant_linkages(client):
        if only is not None and label.split("?")[0] not in only:
            continue
        for path, body in matrix.bodies(linkage):
            yield label, path, path, body
        if matrix.one_dof(linkage):
            design = matrix.design_body(client, linkage)
            if design is not None:
                yield label, matrix.DESIGN, matrix.DESIGN, design
    if only is None or "gated-kl-chain" in only:
        yield ("gated-kl-chain?n=4&gate=2", GATE_SLICE, "/v1/analysis/critical-values",
               matrix.gate_slice(client))


def outcome(status: int, content_type: str, payload: bytes) -> Json:
    """Status, ``search.complete``, ``reason``, ``argument`` and what the search proved."""
    out: Json = {"status": status, "complete": None, "reason": None}
    if "json" not in content_type:
        return out
    doc = json.loads(payload)
    if status != 200:
        out["problem"] = f"{doc.get('title', '')}: {doc.get('detail', '')}"[:300]
        return out
    search = doc.get("search") if isinstance(doc, dict) else None
    if isinstance(search, dict):
        out.update(complete=search.get("complete"), reason=search.get("reason"),
                   argument=search.get("argument"),
                   detail=search.get("argument_detail"),
                   proved={k: search[k] for k in ("components_total", "critical_points_found",
                                                   "regions_explored", "regions_exact",
                                                   "curves_traced", "starts_run",
                                                   "starts_planned", "homotopy")
                           if k in search})
    return out


# -- in-process: the route's job, serialised as a worker does ----------------------------------


def in_process_runner() -> Callable[[str, Json], tuple[int, str, bytes]]:
    from service import figures, jobs, serialise
    from service.config import Settings
    from service.schemas.common import AnalysisRequest
    from service.schemas.critical_values import CriticalValuesRequest
    from service.schemas.design import DesignRequest
    from service.schemas.figures import (
        CriticalValuesFigureRequest,
        LinkageFigureRequest,
        SpaceFigureRequest,
        SplittingFigureRequest,
    )
    from service.schemas.robustness import RobustnessRequest
    from service.schemas.space import SpaceRequest
    from service.schemas.splitting import SplittingRequest

    routes: dict[str, tuple[Callable[..., Any], type]] = {
        "/v1/analysis/rigidity": (jobs.rigidity, AnalysisRequest),
        "/v1/analysis/second-order": (jobs.second_order_analysis, AnalysisRequest),
        "/v1/analysis/critical-points": (jobs.critical_points, SpaceRequest),
        "/v1/analysis/configuration-space": (jobs.configuration_space, SpaceRequest),
        "/v1/analysis/splitting": (jobs.splitting, SplittingRequest),
        "/v1/analysis/robustness": (jobs.robustness_margin, RobustnessRequest),
        "/v1/analysis/critical-values": (jobs.critical_values, CriticalValuesRequest),
        "/v1/design/splitting": (jobs.design_splitting, DesignRequest),
        "/v1/figures/linkage": (figures.linkage_figure, LinkageFigureRequest),
        "/v1/figures/configuration-space": (figures.configuration_space_figure,
                                            SpaceFigureRequest),
        "/v1/figures/critical-values": (figures.critical_values_figure,
                                        CriticalValuesFigureRequest),
        "/v1/figures/splitting": (figures.splitting_figure, SplittingFigureRequest),
    }
    settings = Settings.from_env()

    def run(path: str, body: Json) -> tuple[int, str, bytes]:
        fn, model = routes[path]
        answer = fn(model.model_validate(body), settings)
        if isinstance(answer, bytes):
            return 200, "image/svg+xml", answer
        return 200, "application/json", b"".join(serialise.dumps_parts(answer))

    return run


# -- the table ---------------------------------------------------------------------------------


def met(row: Json) -> bool:
    return (row["status"] == 200 and row.get("complete") is not False
            and row["http_s"] <= row["target_s"])


def table_row(r: Json) -> str:
    """One cell of the matrix as a row of the Markdown table."""
    why = r.get("problem") or r.get("reason") or r.get("argument") or ""
    if r.get("reason") and r.get("proved"):
        why += " (" + ", ".join(f"{k} {v}" for k, v in r["proved"].items()
                                if k != "homotopy") + ")"
    ip = "" if r.get("in_process_s") is None else f"{r['in_process_s']:.3f}"
    complete = {True: "yes", False: "**no**", None: "n/a"}[r.get("complete")]
    return (f"| {r['preset']} | `{r['cell']}` | {r['http_s']:.3f} | {r['first_s']:.3f} | {ip} "
            f"| {complete} | {why} | {'yes' if met(r) else '**no**'} |")


def markdown(rows: list[Json], meta: Json) -> str:
    """The matrix as a Markdown page (``docs/preset-matrix.md``)."""
    lines = [
        "# The preset matrix at the defaults",
        "",
        "Every preset with its default parameters (and a 100-rotor chain, the 4-rotor gated "
        "chain and its gate slice) through every endpoint it is meaningful for, **with the "
        "options a request gets by default**, "
        "measured by `bench/bench_matrix.py` (run on demand; `tests/service/"
        "test_matrix_completeness.py` checks its completeness column, not the times). Maps "
        "take the first two bars with a free end as axes over `[0.8 L, 1.2 L]` each; the gate "
        "slice is the 4-rotor gated chain's (`L2` in [1, 3] x `D` in [1, 3.5]).",
        "",
        f"Measured {meta['date']} on {meta['machine']}, commit `{meta['commit']}`; load average "
        f"{meta['load_before']} before, {meta['load_after']} after (several engineers share "
        "the machine: the seconds are an upper bound of an idle machine's). HTTP: a real "
        "`uvicorn service.main:app` on loopback, ready and warm, one request at a time; "
        f"median of {meta['repeat']} after a first call (`first`). In-process: the route's "
        "job in the benchmark's own process, serialised, median of the same number after a "
        "warm-up. *Met*: 200, complete (a figure: the analysis it draws), median under the "
        "target (2 s; the gate slice 1 s).",
        "",
        "| preset | endpoint | HTTP s | first s | in-process s | complete | reason / argument "
        "| met |",
        "| --- | --- | ---: | ---: | ---: | --- | --- | --- |",
    ]
    lines += [table_row(r) for r in rows]
    n_met = sum(met(r) for r in rows)
    lines += ["", f"{n_met} of {len(rows)} cells met; wall time of the run "
              f"{meta['wall_s']:.0f} s."]
    lines += ["", *WHY_INCOMPLETE, ""]
    return "\n".join(lines)


#: What the reasons of the incomplete cells mean here (the answers' ``search`` says it per
#: answer: ``reason``, ``argument_detail``, ``components_total``, ``homotopy``).
WHY_INCOMPLETE = [
    "## Why a cell is incomplete",
    "",
    "- `budget` on a configuration space of a long chain: the chain rules "
    "(`engine/space/chain_count.py`) count 2^(n-1) components (512 for the 10-rotor chain, "
    "2^99 for 100 rotors), more than `max_components` (32) can trace; `components_total` says "
    "how many there are. The critical points of these chains are derived (none), so "
    "`critical-points`, `splitting` and `design` are complete.",
    "- 3D hinged chains (`rotor-chain-3d`, `spherical-four-bar`) are derived from their cells "
    "(`engine/space/hinge_chain.py`): their critical points, configuration spaces and splitting "
    "are complete; their maps are not (below).",
    "- `searched` or `time` on `robustness` (not the four-bar family): the margin is a "
    "multistart's upper bound (`guarantee: upper-bound`); no argument bounds it from below.",
    "- `time` or `searched` on `critical-values` (maps) of linkages without a closed form: the "
    "curves are traced from seed lengths, and no argument proves that every critical curve "
    "crossing the box was found (`engine/design/critical_values.py`). The four-bar family, "
    "the gate four-bar's own lengths (the gate slice) and rotor chains (`kl-chain`: the flat "
    "planes of their four-bar cells where no two cells' alignments can combine in the box, "
    "`engine/design/chain_planes.py`) are closed form, and their regions are counted by the "
    "chain rules without tracing. So are gated chains in their chain's lengths (`r0` x `r1`) "
    "wherever the gate rotor cranks the gate four-bar over the whole box (`gated_chain_planes`:"
    " the gate then closes at every angle, twice, and carries no self-stress, so the critical "
    "values are the chain's), their regions counted by the chain rules also where a four-bar "
    "drives the chain (four components per component of the chain, `sweep_rules`); a gate "
    "that restricts the chain (the gate rotor rocking) leaves such a map traced. The "
    "three-rotor's map is closed form too (`engine/design/chain_curves.py`). 3D chains' maps "
    "are traced: the turning points of their slices need more homotopy paths than the bound "
    "(2,400 for a 3D two-rotor chain), so their regions' counts are exact but the curves "
    "are `searched`.",
    "- a figure is complete when the analysis it draws is (the JSON cell of the same preset: "
    "`draws` names its reason); the figure says so in its title.",
    "- a configuration-space answer of a 100-rotor chain holds some 10^4 points of 100 "
    "vertices each (40-90 MB of JSON as objects): mapping and serialising it takes seconds "
    "beyond the search budget; `options.points = \"compact\"` sends it as packed arrays.",
]


#: The JSON endpoint whose answer each figure draws.
DRAWS = {"/v1/figures/configuration-space": "/v1/analysis/configuration-space",
         "/v1/figures/critical-values": "/v1/analysis/critical-values",
         "/v1/figures/splitting": "/v1/analysis/splitting"}


def figures_complete(rows: list[Json]) -> None:
    """A figure's completeness is that of the analysis it draws (its preset's JSON cell)."""
    by_cell = {(r["preset"], r["cell"]): r for r in rows}
    for r in rows:
        drawn = by_cell.get((r["preset"], DRAWS.get(r["cell"], "")))
        if r["status"] == 200 and drawn is not None and drawn.get("complete") is not None:
            r["complete"] = drawn["complete"]
            if not drawn["complete"]:
                r["reason"] = f"draws `{drawn['cell']}`: {drawn['reason']}"


def merge(old: Json, rows: list[Json], meta: Json, only: list[str]) -> Json:
    """``old`` (a previous run's JSON) with the rows of the presets in ``only`` replaced by
    ``rows``: they take the place of the first row they replace, or (new presets) go before
    the variants (labels with a query) and the gate slice; ``meta`` joins ``merged``."""
    mine = {_base(r["preset"]) for r in rows} | set(only)
    kept = [r for r in old["rows"] if _base(r["preset"]) not in mine]
    replaced = [k for k, r in enumerate(old["rows"]) if _base(r["preset"]) in mine]
    if replaced:
        at = sum(1 for r in old["rows"][:replaced[0]] if _base(r["preset"]) not in mine)
    else:
        at = next((k for k, r in enumerate(kept) if "?" in r["preset"]), len(kept))
    merged = {k: v for k, v in old.items() if k != "rows"}
    merged["merged"] = [*old.get("merged", []), {**meta, "only": sorted(only)}]
    return {**merged, "rows": kept[:at] + rows + kept[at:]}


def _base(preset: str) -> str:
    return preset.split("?")[0]


def merge_markdown(text: str, rows: list[Json], meta: Json, only: list[str]) -> str:
    """The page ``text`` (``docs/preset-matrix.md``, whose other rows and sentences may have
    been written since) with the table rows of the presets in ``only`` replaced by ``rows``
    (placed as :func:`merge` places them), the count of cells met recounted from the table,
    and a sentence saying what was measured when."""
    mine = {_base(r["preset"]) for r in rows} | set(only)
    lines = text.split("\n")
    body = [k for k, line in enumerate(lines) if line.startswith("| ") and "`/v1/" in line
            or line.startswith(f"| gated-kl-chain?n=4&gate=2 | `{GATE_SLICE}`")]
    if not body:
        raise SystemExit("no table rows in the page to merge into")
    first, last = body[0], body[-1]
    table = lines[first:last + 1]

    def preset_of(line: str) -> str:
        return _base(line.split("|")[1].strip())

    kept = [line for line in table if preset_of(line) not in mine]
    replaced = [k for k, line in enumerate(table) if preset_of(line) in mine]
    at = (sum(1 for line in table[:replaced[0]] if preset_of(line) not in mine) if replaced
          else next((k for k, line in enumerate(kept) if "?" in line.split("|")[1]),
                    len(kept)))
    table = kept[:at] + [table_row(r) for r in rows] + kept[at:]
    n_met = sum(line.rstrip().endswith("| yes |") for line in table)
    note = (f" The rows of {', '.join(f'`{o}`' for o in sorted(only))} were measured "
            f"{meta['date']}, commit `{meta['commit']}` (`bench/bench_matrix.py --only "
            f"{' '.join(sorted(only))}`: median of {meta['repeat']}; load average "
            f"{meta['load_before']} before, {meta['load_after']} after; {meta['wall_s']:.0f} s) "
            "and merged into the table.")
    rest = [re.sub(r"^\d+ of \d+ cells met", f"{n_met} of {len(table)} cells met", line)
            + (note if re.match(r"^\d+ of \d+ cells met", line) else "")
            for line in lines[last + 1:]]
    return "\n".join(lines[:first] + table + rest)


def commit() -> str:
    head = subprocess.run(["git", "-C", str(HERE), "rev-parse", "--short=12", "HEAD"],
                          capture_output=True, text=True).stdout.strip()
    dirty = subprocess.run(["git", "-C", str(HERE), "status", "--porcelain", "--", "engine",
                            "service"], capture_output=True, text=True).stdout.strip()
    return head + (" (modified)" if dirty else "")


def wait_ready(url: str, timeout: float) -> None:
    deadline = time.monotonic() + timeout
    while True:
        try:  # (a loaded machine may keep a probe waiting for seconds)
            if httpx.get(url + "/health/ready", timeout=30.0).status_code == 200:
                return
        except httpx.TimeoutException:
            pass
        if time.monotonic() > deadline:
            raise RuntimeError("the service did not become ready")
        time.sleep(0.2)


def timed(fn: Callable[[], tuple[int, str, bytes]]) -> tuple[float, tuple[int, str, bytes]]:
    t0 = time.perf_counter()
    out = fn()
    return time.perf_counter() - t0, out


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--only", nargs="+", default=None, metavar="PRESET")
    parser.add_argument("--no-in-process", action="store_true")
    parser.add_argument("--json", type=Path, default=Path("bench/results/matrix.json"))
    parser.add_argument("--markdown", type=Path, default=None,
                        help="write the table there too (e.g. docs/preset-matrix.md)")
    parser.add_argument("--log", type=Path, default=None, help="the server's output")
    args = parser.parse_args()

    load_before = [round(x, 2) for x in os.getloadavg()]
    served = commit()  # (the code the server imports as it starts)
    t_start = time.perf_counter()
    rows: list[Json] = []
    run_local = None if args.no_in_process else in_process_runner()
    with served_process(["--no-access-log"], timeout=300, log=args.log) as url, \
            httpx.Client(base_url=url, timeout=200) as http:
        wait_ready(url, 300)

        def post(path: str, body: Json) -> tuple[int, str, bytes]:
            r = http.post(path, json=body)
            return r.status_code, r.headers.get("content-type", ""), r.content

        for preset, cell, path, body in list(cells(http, args.only)):
            first, answer = timed(lambda p=path, b=body: post(p, b))
            times = [timed(lambda p=path, b=body: post(p, b))[0] for _ in range(args.repeat)]
            row: Json = {"preset": preset, "cell": cell, "endpoint": path,
                         "first_s": first, "http_s": statistics.median(times or [first]),
                         "http_all_s": times, "target_s": TARGETS.get(cell, TARGET_S),
                         **outcome(*answer)}
            if run_local is not None and answer[0] == 200:
                run_local(path, body)  # warm-up: this process's first call of the path
                local = [timed(lambda p=path, b=body: run_local(p, b))[0]
                         for _ in range(max(1, args.repeat))]
                row["in_process_s"] = statistics.median(local)
            row["load1"] = round(os.getloadavg()[0], 2)
            rows.append(row)
            ip = row.get("in_process_s")
            print(f"{preset:<28} {cell:<34} http {row['http_s']:7.3f} first {first:7.3f} "
                  f"local {'-' if ip is None else f'{ip:7.3f}'} {row['status']} "
                  f"complete={row['complete']} reason={row['reason']} load={row['load1']}",
                  flush=True)
    figures_complete(rows)
    meta = {"date": datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%d %H:%M UTC"),
            "machine": f"{platform.machine()}, {os.cpu_count()} cores",
            "commit": served, "repeat": args.repeat, "load_before": load_before,
            "load_after": [round(x, 2) for x in os.getloadavg()],
            "wall_s": time.perf_counter() - t_start}
    document: Json = {**meta, "rows": rows}
    if args.only is not None and args.json.exists():
        document = merge(json.loads(args.json.read_text()), rows, meta, args.only)
    args.json.parent.mkdir(parents=True, exist_ok=True)
    args.json.write_text(json.dumps(document, indent=2) + "\n")
    if args.markdown is not None and args.only is not None and args.markdown.exists():
        args.markdown.write_text(merge_markdown(args.markdown.read_text(), rows, meta,
                                                args.only))
    elif args.markdown is not None:
        args.markdown.write_text(markdown(rows, meta))


if __name__ == "__main__":
    main()
