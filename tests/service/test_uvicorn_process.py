"""The service as deployed: a real uvicorn process on a loopback port."""

from __future__ import annotations

import os
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import httpx
import pytest

pytestmark = pytest.mark.process

ROOT = Path(__file__).resolve().parents[2]
HOST = "127.0.0.1"
#: Seconds to give up waiting for ``/health/ready``: not a timed claim (tests/service/
#: test_health.py measures the start-up), a bound for a hung start: the README's start-up
#: takes 8-10 s at load 5-6 and 80-93 s where numba's cache is cold (140 s seen at load 12).
STARTUP_TIMEOUT = 180.0


def free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind((HOST, 0))
        return int(s.getsockname()[1])


def wait_until_ready(
    client: httpx.Client, proc: subprocess.Popen[bytes], stderr_path: Path,
    timeout: float = STARTUP_TIMEOUT,
) -> None:
    deadline = time.monotonic() + timeout
    while True:
        if proc.poll() is not None:
            raise AssertionError(
                f"uvicorn exited with {proc.returncode} before it answered /health:\n"
                + stderr_path.read_text(errors="replace")
            )
        try:
            # ready, as an orchestrator routes to it: the engine workers have started (live
            # alone let requests land on the workers' start-up: the graceful shutdown's request
            # was sent before its worker existed, and uvicorn did not answer within 20 s at
            # load 12)
            if client.get("/health/ready", timeout=1.0).status_code == 200:
                return
        except httpx.TransportError:
            pass
        if time.monotonic() > deadline:
            raise AssertionError(
                f"uvicorn did not answer /health within {timeout} s:\n"
                + stderr_path.read_text(errors="replace")
            )
        time.sleep(0.1)


def stop(proc: subprocess.Popen[bytes]) -> None:
    if proc.poll() is not None:
        return
    proc.terminate()
    try:
        proc.wait(timeout=5)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait(timeout=5)


def test_uvicorn_serves_presets_and_analysis() -> None:
    port = free_port()
    base_url = f"http://{HOST}:{port}"
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    with tempfile.TemporaryDirectory() as tmp:
        stderr_path = Path(tmp) / "uvicorn.stderr"
        with stderr_path.open("wb") as stderr:
            proc = subprocess.Popen(
                [
                    sys.executable,
                    "-m",
                    "uvicorn",
                    "service.main:app",
                    "--host",
                    HOST,
                    "--port",
                    str(port),
                    "--log-level",
                    "warning",
                ],
                cwd=ROOT,
                env=env,
                stdin=subprocess.DEVNULL,
                stdout=subprocess.DEVNULL,
                stderr=stderr,
            )
        # trust_env=False: never route loopback traffic through a proxy from the environment.
        try:
            with httpx.Client(base_url=base_url, trust_env=False, timeout=10.0) as client:
                wait_until_ready(client, proc, stderr_path)

                r = client.get("/v1/presets")
                assert r.status_code == 200, r.text
                names = {p["name"] for p in r.json()}
                assert {"four-bar", "three-rotor", "kl-chain", "gated-kl-chain"} <= names

                r = client.get("/v1/presets/four-bar")
                assert r.status_code == 200, r.text
                linkage = r.json()
                assert len(linkage["vertices"]) == 4 and len(linkage["bars"]) == 3

                r = client.post("/v1/analysis/rigidity", json={"linkage": linkage})
                assert r.status_code == 200, r.text
                assert r.headers["content-type"].startswith("application/json")
                result = r.json()
                assert result["dof"] == 1
                assert result["critical"] is False
                assert result["rank"] == 3
                assert result["trivial_motions"] == 0
                assert len(result["zero_modes"]) == 1

                linkage["bars"][0]["ends"][1] = "nowhere"
                r = client.post("/v1/analysis/rigidity", json={"linkage": linkage})
                assert r.status_code == 422, r.text
                assert r.headers["content-type"].startswith("application/problem+json")
                problem = r.json()
                assert problem["status"] == 422
                assert problem["type"] and problem["title"] and problem["detail"]
                assert problem["errors"][0]["loc"] == ["body", "linkage", "bars", 0, "ends", 1]

                assert client.get("/health").status_code == 200
        finally:
            stop(proc)
        assert proc.returncode is not None
