"""The client stands alone: it imports nothing of engine/ or service/, installs from client/
with one pip command, and talks to a real uvicorn over loopback (sync and async)."""

from __future__ import annotations

import ast
import asyncio
import os
import subprocess
import sys
import tempfile
import time
import zipfile
from collections.abc import Iterator
from pathlib import Path

import httpx
import numpy as np
import pytest
from linkage_client import AsyncClient, Client

from tests.service.test_uvicorn_process import STARTUP_TIMEOUT, free_port, stop

ROOT = Path(__file__).resolve().parents[2]
CLIENT = ROOT / "client"
#: What the client may not import: the service's code and its web stack.
FORBIDDEN = {"engine", "service", "fastapi", "pydantic", "starlette", "uvicorn", "distributed",
             "dask", "numba", "scipy"}


def test_client_sources_import_neither_engine_nor_service() -> None:
    offenders = []
    for path in (CLIENT / "linkage_client").rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            names: list[str] = []
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
                names = [node.module]
            offenders += [f"{path.name}: {n}" for n in names if n.split(".")[0] in FORBIDDEN]
    assert not offenders, offenders


def test_importing_the_client_loads_no_service_module() -> None:
    code = ("import sys, linkage_client, linkage_client.formats; "
            f"bad = sorted(m for m in sys.modules if m.split('.')[0] in {sorted(FORBIDDEN)!r}); "
            "assert not bad, bad")
    env = {**os.environ, "PYTHONPATH": str(CLIENT)}
    res = subprocess.run([sys.executable, "-c", code], cwd=tempfile.gettempdir(), env=env,
                         capture_output=True, text=True, timeout=60)
    assert res.returncode == 0, res.stderr


@pytest.mark.process
def test_client_builds_as_its_own_distribution(tmp_path: Path) -> None:
    """``pip install ./client`` builds this wheel: the package, and httpx and numpy only."""
    # pip builds it as `pip install ./client` does (setuptools in an isolated environment)
    res = subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "-q",
                          "-w", str(tmp_path), str(CLIENT)],
                         capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stdout + res.stderr
    (wheel,) = tmp_path.glob("linkage_client-*.whl")
    with zipfile.ZipFile(wheel) as z:
        names = z.namelist()
        metadata = next(z.read(n).decode() for n in names if n.endswith("METADATA"))
    assert "linkage_client/__init__.py" in names and "linkage_client/py.typed" in names
    assert not any(n.startswith(("engine/", "service/")) for n in names)
    requires = [line.split(":", 1)[1].strip() for line in metadata.splitlines()
                if line.startswith("Requires-Dist:") and "extra ==" not in line]
    assert sorted(r.split(">")[0] for r in requires) == ["httpx", "numpy"]


#: Generous: the machine is shared (a load of 10 on 2 cores seen while writing this), and the
#: start loads the compiled kernels and warms the engine worker (the give-up bound of
#: tests/service/test_uvicorn_process.py: 140 s seen with numba's cache cold at load 12).
STARTUP_TIMEOUT_S = STARTUP_TIMEOUT


def wait_until_ready(base: str, proc: subprocess.Popen[bytes], stderr: Path) -> None:
    deadline = time.monotonic() + STARTUP_TIMEOUT_S
    with httpx.Client(base_url=base) as probe:
        while time.monotonic() < deadline:
            assert proc.poll() is None, stderr.read_text(errors="replace")
            try:
                if probe.get("/health/ready", timeout=1.0).status_code == 200:
                    return
            except httpx.TransportError:
                pass
            time.sleep(0.1)
    raise AssertionError(f"no /health/ready after {STARTUP_TIMEOUT_S} s:\n"
                         + stderr.read_text(errors="replace"))


@pytest.fixture(scope="module")
def served() -> Iterator[str]:
    """The README's service: a real uvicorn on a free loopback port, one engine worker."""
    port = free_port()
    base = f"http://127.0.0.1:{port}"
    with tempfile.TemporaryDirectory() as tmp:
        stderr = Path(tmp) / "stderr"
        with stderr.open("wb") as err:
            proc = subprocess.Popen(
                [sys.executable, "-m", "uvicorn", "service.main:app", "--host", "127.0.0.1",
                 "--port", str(port), "--http", "service.protocol:GuardedH11Protocol"],
                cwd=ROOT, stdout=subprocess.DEVNULL, stderr=err,
                env={**os.environ, "LINKAGE_WORKERS": "1"})
        try:
            wait_until_ready(base, proc, stderr)
            yield base
        finally:
            stop(proc)


@pytest.mark.process
def test_sync_round_trip_over_loopback(served: str) -> None:
    with Client(served) as client:
        assert client.get_health().status == "ok"
        four = client.get_preset_four_bar(L2=0.9)
        space = client.explore_configuration_space(four, options={"angles": 24})
        assert len(space.components) == 2  # a double rocker (Grashof: 1 + 1.0 < 0.9 + 1)
        for comp in space.components:
            a, p1 = comp.positions["A"], comp.positions["P1"]
            assert np.allclose(np.linalg.norm(a - p1, axis=1), 1.0, atol=1e-8)


@pytest.mark.process
def test_async_round_trip_over_loopback(served: str) -> None:
    async def scenario() -> tuple[str, list[str]]:
        async with AsyncClient(served) as client:
            four = await client.get_preset_four_bar()
            second, critical = await asyncio.gather(
                client.analyse_second_order(four),
                client.find_critical_points(four, options={"angles": 24}))
            return second.kind, [cp.kind for cp in critical.critical_points]

    kind, kinds = asyncio.run(scenario())
    assert kind == "regular" and kinds == ["branch"] * 3
