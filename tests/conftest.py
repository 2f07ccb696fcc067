"""Shared fixtures: a synchronous httpx client on the ASGI app, and linkage builders."""

from __future__ import annotations

import asyncio
import os
from collections.abc import Iterator
from typing import Any

import httpx
import pytest

from engine.space import trace_kernel
from service.config import Settings
from service.main import create_app

#: Markers that make a test slow by their nature (registered in pyproject.toml).
SLOW_KINDS = ("process", "browser", "dask", "fuzz", "lint")


#: The longest tests and modules of the suite (``--durations`` of a full run on 2 cores: the
#: matrix 40 s, the costly fuzzing 140 s in all, the rigid point 30 s, the cold start-up 27 s,
#: ...), longest first. ``-n auto`` hands tests out in collection order (``--dist loadgroup``
#: in pyproject.toml: one test at a time to whichever worker is free), so these start first and
#: the run does not end with one worker on a 40 s test while the other is idle. Only the order
#: changes; a name that goes stale only costs time.
LONGEST_FIRST = (
    "tests/service/test_matrix_completeness.py",
    "tests/service/test_fuzz_openapi.py::test_fuzz_costly_operation",
    "tests/engine/space/test_witnesses.py::"
    "test_the_largest_coupler_of_a_skew_four_bar_is_one_rigid_point",
    "tests/service/test_health.py::test_the_port_answers_at_once_and_ready_follows_the_kernels",
    "tests/service/test_every_map.py",
    "tests/engine/local/test_critical_batched.py",
    "tests/test_doc_blocks.py",
    "tests/service/test_fuzz_openapi.py",
    "tests/service/test_cli.py",
    "tests/service/test_bounded.py",
    "tests/engine/design/test_critical_values.py",
    "tests/service/test_every_preset.py",
    "tests/engine/design/test_region_labels.py",
    "tests/test_examples.py",
)
#: Modules whose module-scoped fixtures start processes (Dask clusters, uvicorn, chromium): with
#: ``--dist loadgroup`` each runs whole on one worker, so its fixtures start once in the run
#: rather than once on each worker that gets some of its tests.
ONE_WORKER = (
    "tests/service/test_jobs.py", "tests/client/test_jobs.py", "tests/service/test_cluster.py",
    "tests/service/test_fuzz_valid.py", "tests/service/test_viewer.py",
    "tests/service/test_browser.py", "tests/service/test_served.py",
)


def _listed(nodeid: str) -> int | None:
    """The rank of ``nodeid`` (a test's or a module's) in :data:`LONGEST_FIRST`, if named."""
    for rank, prefix in enumerate(LONGEST_FIRST):
        if nodeid == prefix or nodeid.startswith(prefix + ("[" if "::" in prefix else "::")):
            return rank
    return None


def _longest_first(items: list[pytest.Item]) -> None:
    """Sort ``items`` stably: the tests named in :data:`LONGEST_FIRST`, then whole modules in
    its order, then the other modules with a ``slow`` test, then the rest (a module's tests stay
    together, so its fixtures are set up once on a worker, except the tests named on their own).
    """
    rest = len(LONGEST_FIRST)
    module_rank: dict[str, int] = {}
    for item in items:
        module = item.nodeid.split("::", 1)[0]
        rank = _listed(module)
        if rank is None:
            rank = rest if item.get_closest_marker("slow") else rest + 1
        module_rank[module] = min(module_rank.get(module, rest + 1), rank)

    def key(item: pytest.Item) -> int:
        rank = _listed(item.nodeid)
        return rank if rank is not None else module_rank[item.nodeid.split("::", 1)[0]]

    items.sort(key=key)


@pytest.hookimpl(tryfirst=True)  # before -m selects, and before xdist reads xdist_group
def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Every test marked with one of ``SLOW_KINDS`` is also ``slow``, so that the README's quick
    command (``-m "not slow"``) leaves it out without each module having to say it twice; the
    longest tests start first and the modules of :data:`ONE_WORKER` run on one worker each."""
    for item in items:
        if any(item.get_closest_marker(kind) for kind in SLOW_KINDS) \
                and not item.get_closest_marker("slow"):
            item.add_marker(pytest.mark.slow)
        module = item.nodeid.split("::", 1)[0]
        if module in ONE_WORKER:
            item.add_marker(pytest.mark.xdist_group(module))
    _longest_first(items)


# Fuzzing (tests/service/test_fuzz_openapi.py): examples per operation, fewer for the costly
# operations and for each preset's own route, and one seed for the whole run, drawn here
# unless the environment gives one and put back into it, so that every process of the run
# fuzzes with the seed the header prints.
FUZZ_EXAMPLES = int(os.environ.get("FUZZ_EXAMPLES", "300"))
FUZZ_COSTLY_EXAMPLES = int(os.environ.get("FUZZ_COSTLY_EXAMPLES", "60"))
FUZZ_PRESET_EXAMPLES = int(os.environ.get("FUZZ_PRESET_EXAMPLES", "60"))
FUZZ_SEED = int(os.environ.get("FUZZ_SEED") or int.from_bytes(os.urandom(4), "little"))
os.environ["FUZZ_SEED"] = str(FUZZ_SEED)


def pytest_sessionstart(session: pytest.Session) -> None:
    """The tracer's path is one for the whole run: the compiled kernel is loaded before the
    first test (outside tests the tracer uses the Python loop until it is ready);
    ``LINKAGE_TRACER_KERNEL=numpy`` runs every test on the Python loop."""
    if os.environ.get(trace_kernel.KERNEL_ENV, "numba") != "numpy":
        trace_kernel.load()


def pytest_report_header(config: pytest.Config) -> list[str]:
    return [f"schemathesis: {FUZZ_EXAMPLES} examples per operation ({FUZZ_COSTLY_EXAMPLES} for "
            f"the costly ones, {FUZZ_PRESET_EXAMPLES} for each preset's own route), seed "
            f"{FUZZ_SEED} (replay with FUZZ_SEED={FUZZ_SEED})",
            f"tracer: {'compiled (numba)' if trace_kernel.enabled() else 'Python loop'}"]


def start_ready(app: Any) -> Any:
    """``app`` brought into the state a user meets (``/health/ready`` 200, as an orchestrator
    routes to it): its engine workers started as the lifespan's start-up step starts them
    (``EnginePool.start``: until each has answered once, and the watchdog; the lifespan's
    ``malloc`` tuning of the service process is left out, the test process runs the engine's
    own tests too). The ASGI transport (httpx's, and Starlette's ``TestClient`` outside
    a ``with``) runs no lifespan: without this the pool starts inside the first engine request,
    and on a loaded machine (8-10 s at load 5-6, 80-93 s with numba's cache cold) that start-up
    is counted as the request's time waited for a worker (503 ``busy`` instead of 422) and spends
    its search budget and its timed bounds. Returns ``app``; a second call does nothing."""
    pool = app.state.engine_pool
    if not pool.ready:
        pool.start()
    return app


class ApiClient:
    """Synchronous facade over ``httpx.AsyncClient`` with the ASGI transport (no network), on
    ``app`` started as a server's lifespan would (:func:`start_ready`)."""

    def __init__(self, app: Any) -> None:
        self.app = start_ready(app)
        self._loop = asyncio.new_event_loop()
        self._client = httpx.AsyncClient(
            transport=httpx.ASGITransport(app=app, raise_app_exceptions=False),
            base_url="http://testserver",
        )

    def request(self, method: str, url: str, **kw: Any) -> httpx.Response:
        return self._loop.run_until_complete(self._client.request(method, url, **kw))

    def get(self, url: str, **kw: Any) -> httpx.Response:
        return self.request("GET", url, **kw)

    def post(self, url: str, **kw: Any) -> httpx.Response:
        return self.request("POST", url, **kw)

    def close(self) -> None:
        self._loop.run_until_complete(self._client.aclose())
        self._loop.close()


@pytest.fixture(scope="session")
def app() -> Iterator[Any]:
    # A generous time limit and search time: CI machines are shared and slow, and most tests
    # check complete answers; the limit itself is tested in tests/service/test_hardening.py,
    # the default search time (anytime answers) in tests/service/test_anytime.py, with apps of
    # their own.
    application = start_ready(create_app(Settings.from_env().replace(time_limit_s=600.0,
                                                                     search_time_s=300.0)))
    yield application
    application.state.engine_pool.close()


@pytest.fixture(scope="session")
def client(app: Any) -> Iterator[ApiClient]:
    c = ApiClient(app)
    yield c
    c.close()
