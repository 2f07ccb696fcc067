"""The ``linkage-topology`` command line: each subcommand's exit status and output, ``run``
and ``figure`` in the calling process (no Dask imported, no child process), ``--help`` at
once. Sweeps on Dask are tested in tests/service/test_jobs.py."""

from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path

import pytest

from engine.catalogue.presets import PRESETS

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
    start = time.monotonic()
    proc = cli("--help")
    took = time.monotonic() - start
    assert proc.returncode == 0 and "presets" in proc.stdout and "figure" in proc.stdout
    assert took < 1.0, f"--help took {took:.2f} s"


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
    proc = cli("presets", "five-bar")
    assert proc.returncode == 2 and "no preset named 'five-bar'" in proc.stderr


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
    proc = cli("figure", "linkage", "--preset", "four-bar", "-o", str(tmp_path / "fb.png"))
    assert proc.returncode == 2 and "SVG" in proc.stderr
    proc = cli("figure", "analysis/rigidity", "--preset", "four-bar")
    assert proc.returncode == 2 and "unknown operation" in proc.stderr


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
