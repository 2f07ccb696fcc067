"""What drawing costs: each figure job against the JSON job it pictures (run on demand).

    .venv/bin/python bench/bench_figures.py [--repeat 3] [--formats svg,png,pdf,tikz,dxf]

Both run in this process, as a worker runs them (no HTTP); best of ``--repeat`` after a
warm-up (matplotlib's import and font cache are paid once per worker, shown apart).
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable
from typing import Any

from engine.catalogue.presets import build_preset
from service import jobs, mappers
from service.config import Settings
from service.figure_formats import OFFERED
from service.schemas.common import AnalysisRequest
from service.schemas.critical_values import CriticalValuesRequest
from service.schemas.figures import (
    CriticalValuesFigureRequest,
    LinkageFigureRequest,
    SpaceFigureRequest,
    SplittingFigureRequest,
)
from service.schemas.space import SpaceRequest
from service.schemas.splitting import SplittingRequest


def best(fn: Callable[[], Any], repeat: int) -> float:
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--formats", default="svg", help="comma-separated: svg,png,pdf,tikz,dxf "
                        "(each where the figure offers it; png at its default 150 dpi)")
    args = parser.parse_args()
    settings = Settings()
    four_bar = mappers.linkage_out(build_preset("four-bar", {}, settings.limits)).model_dump()
    axes = [{"bar": "L2", "min": 0.4, "max": 2.5}, {"bar": "L3", "min": 0.4, "max": 2.5}]

    t0 = time.perf_counter()
    from service import figures  # matplotlib's import: once per worker process

    print(f"import service.figures (matplotlib): {time.perf_counter() - t0:.2f} s")
    split = {"linkage": four_bar, "perturbation": {"L2": 0.01}}
    cases = [
        ("linkage + zero modes", "linkage", jobs.rigidity, AnalysisRequest(linkage=four_bar),
         figures.linkage_figure, LinkageFigureRequest,
         {"linkage": four_bar, "show": ["zero_modes"]}),
        ("configuration space", "configuration-space", jobs.configuration_space,
         SpaceRequest(linkage=four_bar), figures.configuration_space_figure, SpaceFigureRequest,
         {"linkage": four_bar}),
        ("splitting", "splitting", jobs.splitting, SplittingRequest.model_validate(split),
         figures.splitting_figure, SplittingFigureRequest, split),
        ("critical values", "critical-values", jobs.critical_values,
         CriticalValuesRequest.model_validate({"linkage": four_bar, "axes": axes}),
         figures.critical_values_figure, CriticalValuesFigureRequest,
         {"linkage": four_bar, "axes": axes}),
    ]
    print(f"{'equilateral four-bar':24} {'format':>6} {'JSON job':>10} {'figure job':>11} "
          f"{'drawing':>9} {'bytes':>9}")
    for name, kind, job, body, figure, model, fields in cases:
        t_json = best(lambda job=job, body=body: job(body, settings), args.repeat)
        for fmt in args.formats.split(","):
            if fmt not in OFFERED[kind]:
                continue
            fbody = model.model_validate({**fields, "format": fmt})
            size = len(figure(fbody, settings))  # warm-up (fonts, first figure)
            t_fig = best(lambda figure=figure, fbody=fbody: figure(fbody, settings), args.repeat)
            print(f"{name:24} {fmt:>6} {t_json:9.3f}s {t_fig:10.3f}s {t_fig - t_json:8.3f}s "
                  f"{size:9,}")


if __name__ == "__main__":
    main()
