"""The ``linkage-topology`` command line: each subcommand's exit status and output, ``run``
and ``figure`` in the calling process (no Dask imported, no child process), ``--help`` at
once. Sweeps on Dask are tested in tests/service/test_jobs.py."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from engine.catalogue.presets import PRESETS
from tests.load import Timer

pytestmark = pytest.mark.process
SCRIPT = str(Path(sys.executable).with_name("linkage-topology"))
#: Runs the command line's main() in a fresh interpreter, then reports what it left behind.
PROBE = """
import json, sys, psutil
from service.cli import main
rc = main(sys.argv[1:])
print(json.dumps({"rc": rc, "dask": sorted(m for m in sys.modules
                                           if m.split(".")[0] in ("distributed", "dask")),
                  "children": len(psutil.Process().children(recursive=True))}),
      file=sys.stderr)
"""


def cli(*args: str, cwd: Path | None = None) -> subprocess.CompletedProcess[str]:
    return subprocess.run([SCRIPT, *args], capture_output=True, text=True, timeout=300,
                          cwd=cwd)


def probe(*args: str, cwd: Path) -> tuple[str, dict]:
    proc = subprocess.run([sys.executable, "-c", PROBE, *args], capture_output=True, text=True,
                          timeout=300, cwd=cwd)
    report = json.loads(proc.stderr.strip().splitlines()[-1])
    return proc.stdout, report


def test_help_answers_at_once() -> None:
    with Timer() as t:
        proc = cli("--help")
    assert proc.returncode == 0 and "presets" in proc.stdout and "figure" in proc.stdout
    # a second of an idle machine, scaled by the slowdown measured around it (tests/load.py)
    assert t.within(0.0, 1.0), f"--help took {t}"


def test_version() -> None:
    from importlib.metadata import version

    proc = cli("--version")
    assert proc.returncode == 0
    assert proc.stdout.strip() == f"linkage-topology {version('linkage-topology')}"


def test_presets_lists_and_shows() -> None:
    proc = cli("presets")
    assert proc.returncode == 0 and proc.stdout.split() == list(PRESETS)
    proc = cli("presets", "four-bar")
    assert proc.returncode == 0
    shown = json.loads(proc.stdout)
    assert shown["name"] == "four-bar"
    assert shown["parameters"] == dict(PRESETS["four-bar"].parameters)
    proc = cli("presets", "no-such-bar")
    assert proc.returncode == 2 and "no preset named 'no-such-bar'" in proc.stderr


def test_run_is_in_process_without_dask(tmp_path: Path) -> None:
    out, report = probe("run", "analysis/critical-points", "--preset", "four-bar",
                        "--param", "L2=1", cwd=tmp_path)
    assert report == {"rc": 0, "dask": [], "children": 0}
    answer = json.loads(out)
    # the equilateral four-bar: three branch points (the paper's)
    assert sorted(p["kind"] for p in answer["critical_points"]) == ["branch"] * 3


def test_run_from_a_request_file_and_its_errors(tmp_path: Path) -> None:
    lk = json.loads(cli("run", "analysis/rigidity", "--preset", "four-bar").stdout)
    assert lk["critical"] is False
    request = tmp_path / "request.json"
    request.write_text(json.dumps({"linkage": {"vertices": [{"id": "A", "position": [0, 0]}],
                                               "bars": [{"id": "b", "ends": ["A", "X"]}]}}))
    proc = cli("run", "analysis/rigidity", str(request), "-o", str(tmp_path / "out.json"))
    assert proc.returncode == 2 and "X" in proc.stderr
    proc = cli("run", "analysis/nothing", "--preset", "four-bar")
    assert proc.returncode == 2 and "unknown operation" in proc.stderr
    proc = cli("run", "analysis/rigidity")
    assert proc.returncode == 2 and "give a request file or --preset" in proc.stderr
    proc = cli("run", "analysis/rigidity", "--preset", "four-bar", "--param", "a=0")
    assert proc.returncode == 2 and "positive" in proc.stderr
    proc = cli("frobnicate")
    assert proc.returncode == 2  # argparse


def test_figure_writes_svg_in_process(tmp_path: Path) -> None:
    out, report = probe("figure", "linkage", "--preset", "four-bar", "-o", "fb.svg",
                        cwd=tmp_path)
    assert report == {"rc": 0, "dask": [], "children": 0}
    svg = (tmp_path / "fb.svg").read_text()
    assert svg.lstrip().startswith("<?xml") and "<svg" in svg and svg.rstrip().endswith("</svg>")
    assert "<text" in svg  # text as text
    proc = cli("figure", "analysis/rigidity", "--preset", "four-bar")
    assert proc.returncode == 2 and "unknown operation" in proc.stderr


@pytest.mark.parametrize("dpi", [40, 80])
def test_figure_writes_png_at_its_dpi_in_process(tmp_path: Path, dpi: int) -> None:
    from tests.service.test_figure_formats import png_size_and_dpi

    _, report = probe("figure", "linkage", "--preset", "four-bar", "-o", "fb.png", "--dpi",
                      str(dpi), cwd=tmp_path)
    assert report == {"rc": 0, "dask": [], "children": 0}
    width, height, dots = png_size_and_dpi((tmp_path / "fb.png").read_bytes())
    assert dots == pytest.approx(dpi, abs=0.02)
    # the linkage figure is 6.4 in wide (service/figure_drawing.py): its pixels at this dpi
    assert abs(width - 6.4 * dpi) <= 1


def test_figure_writes_pdf_tikz_and_dxf_in_process(tmp_path: Path) -> None:
    import io

    import ezdxf
    from pypdf import PdfReader

    _, report = probe("figure", "configuration-space", "--preset", "four-bar", "--options",
                      '{"max_points": 2000}', "-o", "space.pdf", cwd=tmp_path)
    assert report == {"rc": 0, "dask": [], "children": 0}
    pdf = (tmp_path / "space.pdf").read_bytes()
    assert pdf.startswith(b"%PDF-") and pdf.rstrip().endswith(b"%%EOF")
    assert len(PdfReader(io.BytesIO(pdf)).pages) == 1
    tikz, report = probe("figure", "linkage", "--preset", "four-bar", "--format", "tikz",
                         cwd=tmp_path)  # to stdout
    assert report["rc"] == 0 and "\\begin{tikzpicture}" in tikz
    _, report = probe("figure", "linkage", "--preset", "four-bar", "-o", "fb.dxf",
                      cwd=tmp_path)
    assert report["rc"] == 0
    doc = ezdxf.readfile(tmp_path / "fb.dxf")
    assert len(doc.modelspace().query("LINE[layer=='BARS']")) == 3


def test_figure_search_stops_at_the_time_limit(tmp_path: Path) -> None:
    """In-process figures search under --time-limit (the job's deadline): a second is too
    short for the space of the deep-failing assembly tree (tests/service/test_bounded.py, whose
    enumeration fails below every partial assembly until the deadline), and the figure says its
    search is incomplete."""
    from tests.service.test_bounded import deep_failing_chain

    request = tmp_path / "deep.json"
    request.write_text(json.dumps({"linkage": deep_failing_chain()}))
    tikz, report = probe("figure", "configuration-space", str(request),
                         "--time-limit", "1", "--format", "tikz", cwd=tmp_path)
    assert report == {"rc": 0, "dask": [], "children": 0}
    assert "(search incomplete: time)" in tikz


def test_figure_usage_errors(tmp_path: Path) -> None:
    for args, says in (
            (["-o", str(tmp_path / "fb.gif")], "a figure is written as"),
            (["-o", str(tmp_path / "fb.png"), "--format", "pdf"], "is not a pdf file"),
            (["--format", "bmp"], "invalid choice"),
            (["-o", str(tmp_path / "fb.png"), "--dpi", "5000"], "dpi"),
    ):
        proc = cli("figure", "linkage", "--preset", "four-bar", *args)
        assert proc.returncode == 2 and says in proc.stderr, (args, proc.stderr)
    proc = cli("figure", "linkage", "--preset", "four-bar", "-o", str(tmp_path / "fb.png"),
               "--dpi", "1200")
    assert proc.returncode == 2 and "25,000,000 pixels" in proc.stderr
    from service.schemas.common import EXAMPLE_LINKAGE

    request = tmp_path / "split.json"
    request.write_text(json.dumps({"linkage": EXAMPLE_LINKAGE, "perturbation": {"L2": 0.01}}))
    proc = cli("figure", "splitting", str(request), "-o", str(tmp_path / "split.tex"))
    assert proc.returncode == 2 and "not as tikz" in proc.stderr
    assert not list(tmp_path.glob("fb.*")) and not list(tmp_path.glob("*.tex"))


def test_sweep_usage_errors_start_no_cluster(tmp_path: Path) -> None:
    """A sweep's bad input is exit status 2, found before any Dask process starts (the sweeps
    themselves: tests/service/test_jobs.py and the README's block in tests/test_doc_blocks.py)."""
    for args, says in ((["sweep"], "give a request file or --preset"),
                       (["sweep", "--preset", "four-bar", "--grid", "L2=1:x:3"], "not a number"),
                       (["sweep", "--preset", "four-bar", "--grid", "L2=1:2"],
                        "expected 3 numbers"),
                       (["sweep", str(tmp_path / "missing.json")], "cannot read")):
        _, report = probe(*args, cwd=tmp_path)
        assert report == {"rc": 2, "dask": report["dask"], "children": 0}, args
        proc = cli(*args, cwd=tmp_path)
        assert proc.returncode == 2 and says in proc.stderr, (args, proc.stderr)
