"""Dask secure by default (issue 28, item 2), on real clusters on loopback.

The embedded cluster serves no HTTP and accepts only its own certificate; an external cluster
set up as docs/jobs.md says (mutual TLS with certificates made by ``openssl``, every address on
loopback) serves jobs, and when its scheduler is lost jobs are refused with 503 until it is
back, then served again without restarting the service.
"""

from __future__ import annotations

import os
import re
import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import dask
import psutil
import pytest
from distributed import Client, Security
from fastapi.testclient import TestClient

from service.cluster import embedded_cluster
from service.main import create_app
from service.workers import WORKER_NICE
from tests.service.test_jobs import free_port, settings, wait

pytestmark = [pytest.mark.dask, pytest.mark.process]

#: A small sweep whose rows are known: the equilateral four-bar with L2 = 0.5 (2, Grashof) and
#: 1.5 (1 component).
SMALL = {"preset": {"name": "four-bar"}, "grid": {"L2": {"min": 0.5, "max": 1.5, "steps": 2}}}


def listening(pids: list[int]) -> set[tuple[str, int]]:
    """Addresses that these processes listen on (TCP)."""
    out = set()
    for pid in pids:
        for conn in psutil.Process(pid).net_connections(kind="inet"):
            if conn.status == psutil.CONN_LISTEN:
                out.add((conn.laddr.ip, conn.laddr.port))
    return out


def host_port(address: str) -> tuple[str, int]:
    host, port = address.split("://", 1)[1].rsplit(":", 1)
    return host, int(port)


def test_the_embedded_cluster_listens_only_on_loopback_tls_and_serves_no_http():
    before = listening([os.getpid()])
    cluster = embedded_cluster(2, allowed_failures=0)
    try:
        with Client(cluster, security=cluster.security, set_as_default=False) as client:
            assert client.submit(sum, [1, 2, 3]).result(timeout=60) == 6
            # the workers that run the engine's tasks at the pool's lower priority (issue 28):
            # os.nice(0) is the niceness of the process it runs in
            own = os.nice(0)
            assert client.submit(os.nice, 0, pure=False).result(timeout=60) == own + WORKER_NICE
            assert set(client.run(os.nice, 0).values()) == {own + WORKER_NICE}
            info = client.scheduler_info()
            worker_pids = list(client.run(os.getpid).values())
            ours = (listening([os.getpid()]) - before) | listening(worker_pids)
            # the scheduler, two nannies and two workers: their Dask addresses, nothing else
            # (no dashboard on 8787, no worker HTTP port)
            expected = {host_port(cluster.scheduler_address)}
            for address, worker in info["workers"].items():
                expected |= {host_port(address), host_port(worker["nanny"])}
            assert ours == expected, ours - expected
            assert len(expected) == 5 and {h for h, _ in ours} == {"127.0.0.1"}
            assert info["services"] == {} and all(
                w["services"] == {} for w in info["workers"].values())
            for host, port in ours:
                refused_without_the_certificate(host, port)
    finally:
        cluster.close()


def refused_without_the_certificate(host: str, port: int) -> None:
    """Plain TCP, plain HTTP and TLS with another certificate are all refused."""
    with socket.create_connection((host, port), timeout=10) as s:
        s.sendall(b"GET / HTTP/1.1\r\nHost: x\r\n\r\n")
        s.settimeout(10)
        try:
            answer = s.recv(100)
        except ConnectionResetError:
            answer = b""
        assert not answer.startswith(b"HTTP/"), answer
    for address, security in ((f"tcp://{host}:{port}", None),
                              (f"tls://{host}:{port}", Security.temporary())):
        with pytest.raises((OSError, TimeoutError)):
            Client(address, timeout=3, security=security, set_as_default=False)


# -- an external cluster as docs/jobs.md sets it up -----------------------------------------------


def readme_openssl() -> str:
    """The ``openssl`` commands of docs/jobs.md (continuation lines joined), as written there."""
    readme = (Path(__file__).resolve().parents[2] / "docs" / "jobs.md").read_text()
    block = next(b for b in re.findall(r"```bash\n(.*?)```", readme, re.S)
                 if "openssl req -x509" in b)
    commands = block.replace("\\\n", " ").splitlines()
    found = [c for c in commands if c.startswith("openssl ")]
    assert len(found) == 3, found
    return "\n".join(found)


def readme_worker_nice() -> list[str]:
    """The ``nice`` prefix of docs/jobs.md's ``dask worker`` command (the service cannot lower
    the priority of workers it does not start: the operator does, as the docs say)."""
    readme = (Path(__file__).resolve().parents[2] / "docs" / "jobs.md").read_text()
    found = re.findall(r"^(nice -n \d+) \.venv/bin/dask worker ", readme, re.M)
    assert len(found) == 1, found
    return found[0].split()


@pytest.fixture(scope="module")
def certificates(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The certificates of docs/jobs.md: a CA and one certificate it signed, by ``openssl``."""
    folder = tmp_path_factory.mktemp("tls")
    subprocess.run(["bash", "-c", "set -e\n" + readme_openssl()], cwd=folder, check=True,
                   capture_output=True, timeout=120)
    return folder


def tls_args(folder: Path) -> list[str]:
    return ["--tls-ca-file", str(folder / "ca.pem"), "--tls-cert", str(folder / "dask.pem"),
            "--tls-key", str(folder / "dask.key")]


class External:
    """``dask scheduler`` and one ``dask worker`` over TLS on loopback, as docs/jobs.md starts
    them; the scheduler (and its worker) can be stopped and started again on the same port."""

    def __init__(self, folder: Path) -> None:
        self.folder = folder
        self.port = free_port()
        self.address = f"tls://127.0.0.1:{self.port}"
        self.procs: list[subprocess.Popen[bytes]] = []

    def start(self) -> None:
        dask_cli = [sys.executable, "-m", "dask"]
        quiet: dict[str, Any] = {"stdout": subprocess.DEVNULL, "stderr": subprocess.DEVNULL,
                                 "env": {**os.environ,
                                         "DASK_DISTRIBUTED__SCHEDULER__HTTP__ROUTES": "[]",
                                         "DASK_DISTRIBUTED__WORKER__HTTP__ROUTES": "[]"}}
        self.procs = [subprocess.Popen(
            [*dask_cli, "scheduler", "--protocol", "tls", "--host", "127.0.0.1",
             "--port", str(self.port), "--no-dashboard", "--dashboard-address", "127.0.0.1:0",
             *tls_args(self.folder)], **quiet)]
        self.procs.append(subprocess.Popen(
            [*readme_worker_nice(), *dask_cli, "worker", self.address, "--host", "127.0.0.1",
             "--nthreads", "1", "--no-dashboard", "--dashboard-address", "127.0.0.1:0",
             *tls_args(self.folder)], **quiet))
        with dask.config.set(self.client_config()), Client(
                self.address, timeout=60, set_as_default=False) as client:
            client.wait_for_workers(1, timeout=90)

    def stop(self) -> None:
        for p in reversed(self.procs):
            p.terminate()
        for p in reversed(self.procs):
            try:
                p.wait(timeout=20)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait(timeout=20)

    def client_config(self) -> dict[str, Any]:
        """The service's side, as the environment variables of docs/jobs.md set it."""
        return {"distributed.comm.tls.ca-file": str(self.folder / "ca.pem"),
                "distributed.comm.tls.client.cert": str(self.folder / "dask.pem"),
                "distributed.comm.tls.client.key": str(self.folder / "dask.key"),
                "distributed.comm.require-encryption": True}


@pytest.fixture()
def external(certificates: Path) -> Iterator[External]:
    ext = External(certificates)
    ext.start()
    try:
        yield ext
    finally:
        ext.stop()


def post_until_accepted(api: TestClient, body: dict[str, Any], within: float) -> Any:
    deadline = time.monotonic() + within
    while True:
        r = api.post("/v1/sweeps", json=body)
        if r.status_code == 202 or time.monotonic() > deadline:
            return r
        assert r.status_code == 503, r.text
        time.sleep(float(r.headers["retry-after"]) / 5)


def test_an_external_tls_cluster_lost_and_back(external):
    with dask.config.set(external.client_config()), TestClient(
            create_app(settings(dask_scheduler=external.address))) as api:
        r = api.post("/v1/sweeps", json=SMALL)
        assert r.status_code == 202, r.text
        job = wait(api, r.headers["location"])
        assert [row["components"] for row in job["result"]["rows"]] == [2, 1]
        # the worker started as docs/jobs.md says runs at the engine pool's lower priority
        with Client(external.address, timeout=30, set_as_default=False) as client:
            nice = set(client.run(os.nice, 0).values())
        assert nice == {os.nice(0) + WORKER_NICE}, nice

        external.stop()
        time.sleep(1.0)
        lost = api.post("/v1/sweeps", json=SMALL)
        assert lost.status_code == 503, lost.text
        assert lost.json()["type"] == "/problems/cluster-unavailable"
        assert lost.headers["retry-after"] == "5"
        assert external.address in lost.json()["detail"]
        assert api.get("/health/live").status_code == 200

        external.start()  # the same address: the service connects again by itself
        back = post_until_accepted(api, SMALL, within=60)
        assert back.status_code == 202, back.text
        job = wait(api, back.headers["location"])
        assert job["status"] == "done", job
        assert [row["components"] for row in job["result"]["rows"]] == [2, 1]


def test_the_readme_external_cluster_listens_on_loopback_only_and_wants_its_certificate(
        external):
    pids = [p.pid for p in external.procs]
    pids += [c.pid for pid in pids for c in psutil.Process(pid).children(recursive=True)]
    addresses = listening(pids)
    # scheduler, nanny, worker, and the HTTP ports docs/jobs.md binds to loopback
    assert len(addresses) >= 3 and {h for h, _ in addresses} == {"127.0.0.1"}, addresses
    with pytest.raises((OSError, TimeoutError)):
        Client(external.address.replace("tls://", "tcp://"), timeout=3, set_as_default=False)
    with pytest.raises((OSError, TimeoutError)):
        Client(external.address, timeout=3, security=Security.temporary(),
               set_as_default=False)


@pytest.mark.parametrize("address, accepted", [
    ("tls://10.0.0.5:8786", True), ("tcp://127.0.0.1:8786", True), ("127.0.0.1:8786", True),
    ("tcp://localhost:8786", True), ("tcp://[::1]:8786", True),
    ("tcp://10.0.0.5:8786", False), ("10.0.0.5:8786", False), ("tcp://0.0.0.0:8786", False),
    ("ucx://10.0.0.5:8786", False),
])
def test_a_plain_scheduler_address_beyond_loopback_stops_the_start(monkeypatch, address,
                                                                   accepted):
    from service.config import Settings

    monkeypatch.setenv("LINKAGE_DASK_SCHEDULER", address)
    if accepted:
        assert Settings.from_env().dask_scheduler == address
    else:
        with pytest.raises(ValueError, match="TLS"):
            Settings.from_env()
