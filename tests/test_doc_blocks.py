"""Every code block of README.md and docs/*.md that is Python or shell runs (issue 31): each is
extracted as it is written and run against a real uvicorn on a free loopback port (the blocks'
``http://127.0.0.1:8000`` is that server's address), shell blocks with ``bash -e`` from a
scratch directory (``.venv/bin/`` is this interpreter's). A block that cannot run here
(installs, the suite itself, processes that run until stopped) is marked in the page by an
HTML comment ``<!-- not run: why -->`` on the line before it; the marked blocks are listed in
:data:`NOT_RUN` so that a new mark is a visible change."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
import tempfile
from collections.abc import Iterator
from pathlib import Path

import httpx
import pytest

from tests.service.test_uvicorn_process import HOST, ROOT, free_port, stop, wait_until_ready

pytestmark = pytest.mark.process

PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
RUNNABLE = {"python": "python", "py": "python", "bash": "bash", "sh": "bash", "shell": "bash"}
BLOCK = re.compile(r"^(?P<mark><!-- not run: (?P<why>.*?) -->\n)?```(?P<lang>\w*)\n(?P<code>.*?)"
                   r"^```$", re.M | re.S)
ADDRESS = "http://127.0.0.1:8000"
#: The blocks marked ``not run`` (page, first line): each says why on its page.
NOT_RUN = {
    ("README.md", "python3 -m venv .venv && .venv/bin/pip install -e . && .venv/bin/uvicorn "
     "service.main:app --host 127.0.0.1 --port 8000 --http service.protocol:GuardedH11Protocol"),
    ("README.md", '.venv/bin/python -m pytest -q -m "not slow"'),
    ("README.md", ".venv/bin/python examples/three_rotor.py --url http://127.0.0.1:8000 "
                  "--out figures"),
    ("jobs.md", "openssl req -x509 -newkey rsa:3072 -nodes -days 365 "
                '-subj "/CN=linkage-dask-ca" \\'),
    ("examples.md", "pip install ./client                      # the client, into the "
                    "environment that runs the examples"),
}


def blocks() -> Iterator[tuple[str, int, str, str, str | None]]:
    """``(page, line, language, code, why not run)`` of every Python or shell block."""
    for page in PAGES:
        text = page.read_text()
        for m in BLOCK.finditer(text):
            lang = RUNNABLE.get(m["lang"])
            if lang is not None:
                line = text.count("\n", 0, m.start("lang"))
                yield page.name, line, lang, m["code"], m["why"]


RUN = [pytest.param(lang, code, id=f"{page}:{line}")
       for page, line, lang, code, why in blocks() if why is None]


def test_the_blocks_not_run_are_the_listed_ones() -> None:
    marked = {(page, code.splitlines()[0]) for page, _, _, code, why in blocks()
              if why is not None}
    assert marked == NOT_RUN
    assert all(why.strip() for *_, why in blocks() if why is not None)
    assert len(RUN) >= 5  # the curl examples, the numpy checks, the command line


@pytest.fixture(scope="module")
def base_url() -> Iterator[str]:
    port = free_port()
    url = f"http://{HOST}:{port}"
    with tempfile.TemporaryDirectory() as tmp:
        stderr_path = Path(tmp) / "uvicorn.stderr"
        with stderr_path.open("wb") as stderr:
            proc = subprocess.Popen(
                [sys.executable, "-m", "uvicorn", "service.main:app", "--host", HOST, "--port",
                 str(port), "--log-level", "warning"],
                cwd=ROOT, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=stderr)
        try:
            with httpx.Client(base_url=url, trust_env=False, timeout=10.0) as client:
                # generous: the first start after an install compiles the tracer's kernel
                wait_until_ready(client, proc, stderr_path, timeout=180.0)
            yield url
        finally:
            stop(proc)


@pytest.mark.parametrize(("lang", "code"), RUN)
def test_block_runs(lang: str, code: str, base_url: str, tmp_path: Path) -> None:
    code = code.replace(ADDRESS, base_url).replace(".venv/bin/", f"{Path(sys.executable).parent}/")
    # the client (client/, installed with `pip install ./client`) as pytest's pythonpath has it
    client = str(Path(__file__).resolve().parents[1] / "client")
    path = os.pathsep.join(p for p in (client, os.environ.get("PYTHONPATH", "")) if p)
    env = {**os.environ, "LINKAGE_DASK_WORKERS": "1", "NO_PROXY": "*", "no_proxy": "*",
           "PYTHONPATH": path}
    command = ([sys.executable, "-c", code] if lang == "python"
               else ["bash", "-e", "-o", "pipefail", "-c", code])
    proc = subprocess.run(command, capture_output=True, text=True, timeout=600, cwd=tmp_path,
                          env=env)
    assert proc.returncode == 0, proc.stderr
    if lang == "bash" and code.lstrip().startswith("curl"):  # curl -s: the answer, not a problem
        answer = json.loads(proc.stdout)
        assert "type" not in answer or not str(answer["type"]).startswith("/problems"), answer
