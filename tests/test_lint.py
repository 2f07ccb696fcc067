"""Static checks run with the test suite: ruff on the code, mypy on engine/, service/ and the
client (client/linkage_client)."""

import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.lint

ROOT = Path(__file__).resolve().parents[1]
BIN = Path(sys.executable).parent


def run(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(args, cwd=ROOT, capture_output=True, text=True, timeout=300)


def test_ruff():
    res = run(str(BIN / "ruff"), "check", "engine", "service", "tests", "scripts", "bench",
              "examples", "client")
    assert res.returncode == 0, res.stdout + res.stderr


def test_mypy():
    res = run(sys.executable, "-m", "mypy", "engine", "service")
    assert res.returncode == 0, res.stdout + res.stderr
    res = run(sys.executable, "-m", "mypy", "client/linkage_client")
    assert res.returncode == 0, res.stdout + res.stderr
