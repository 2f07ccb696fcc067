"""Nothing unbounded (issue 23, item 4): every search answers 200 within its time budget plus a
fixed margin, on the inputs that used to run past it (504 after the 30 s limit, or a late
answer): a deep-failing assembly tree, a 100-rotor chain with every cell a parallelogram,
Kane-Lubensky chains of 400 rotors and at the size limit, a collinear chain's critical-value map.

The app has the service's default search time (4 s), so that the deadlines, not the session
app's generous ones, decide when the answers come. Its time limit, 120 s instead of the default
30 s, is only the backstop that kills a worker (tested in tests/service/test_hardening.py): the
searches' deadlines here are 4 s or less whatever the limit, and at 30 s the backstop answered
504 before the bound below could be checked on a machine slowed more than 13-fold (load 12 with
the nice-10 worker: the 20,000-rotor chain's figure and map).

**The margin.** ``MARGIN_S`` = 2 s past ``time_budget_s``: what runs after the deadline is at
most one unit of work that does not look at it (one sparse null space, one trace step, one
refinement or classification: at most 0.5 s measured on these inputs at 400 rotors), then the
mapping and serialising of what was found (at most 0.3 s) and the hop to and from the worker
process; doubled. Those are seconds of an idle machine: on a loaded one that work takes longer
by the factor :func:`tests.load.stretch` measures in an engine worker and in this process just
before and just after the request (the larger of the two, at least 1), and the margin is scaled
by it. The budget itself is not: the deadline is wall-clock time from the request's arrival, on
any machine. (Unscaled, the 20,000-rotor chain's map answered after 4.5 s at load 5, and after
12-68 s at load 12 with the nice-10 worker beside three busy processes, a stretch of 10-30.)
"""

from __future__ import annotations

import time
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest

from service.config import Settings
from service.main import create_app
from tests.conftest import ApiClient
from tests.load import Timer
from tests.service.preset_matrix import bar_length, free_bars

Json = dict[str, Any]

#: Seconds an answer may come after its time budget (see the module docstring).
MARGIN_S = 2.0
#: The default search time (``LINKAGE_SEARCH_TIME_S``) of the app below.
SEARCH_S = 4.0


@pytest.fixture(scope="module")
def api() -> Iterator[ApiClient]:
    # one engine worker, started by ApiClient (tests.conftest.start_ready: the kernels loaded)
    # and then given a first request: no timed request lands on a cold worker or pool
    app = create_app(Settings.from_env().replace(time_limit_s=120.0, search_time_s=SEARCH_S,
                                                 workers=1))
    client = ApiClient(app)
    assert client.post("/v1/analysis/critical-points",
                       json={"linkage": client.get("/v1/presets/four-bar").json()}
                       ).status_code == 200
    yield client
    client.close()
    app.state.engine_pool.close()


def timed_post(api: ApiClient, path: str, body: Json) -> tuple[Any, Timer]:
    with Timer(api.app) as took:
        r = api.post(path, json=body)
    return r, took


def assert_in_time(r: Any, took: Timer, budget: float, search: bool = True) -> None:
    """200 within ``budget`` plus the margin in the machine's current speed; a JSON answer's
    search report complete, or cut by time with ``time_budget_s`` the budget (or incomplete
    for another named reason)."""
    assert r.status_code == 200, r.text[:500]
    assert took.within(budget, MARGIN_S), f"answered after {took} (budget {budget} s)"
    if search:
        report = r.json()["search"]
        assert report["time_budget_s"] == budget
        assert report["complete"] is (report["reason"] is None)
        assert report["reason"] in (None, "time", "budget", "degenerate", "unresolved",
                                    "searched")


def deep_failing_chain(left: int = 24, right: int = 4) -> Json:
    """A rotor chain driven from rotor ``left``, every cell a rhombus (pins 1 apart, rotors and
    couplers of length 1: each tip placed in two ways at almost every angle), except the last
    rotor: 0.05 long, on a pin off the line, so that it fails to assemble at almost every
    angle. The dyad plan places the ``left`` side first (lower indices), then the ``right``
    side: a depth-first enumeration meets the failure below 2^(left + right - 1) partial
    assemblies. Positions: every rotor at the same angle (a valid configuration)."""
    n = left + 1 + right
    up = np.array([np.cos(1.1), np.sin(1.1)])
    pins = np.column_stack([np.arange(n, dtype=float), np.zeros(n)])
    tips = pins + up
    pins[-1] = tips[-1] - 0.05 * np.array([np.cos(0.3), np.sin(0.3)])
    vertices = [{"id": f"P{k}", "position": pins[k].tolist(), "fixed": True} for k in range(n)]
    vertices += [{"id": f"T{k}", "position": tips[k].tolist()} for k in range(n)]
    bars = [{"id": f"r{k}", "ends": [f"P{k}", f"T{k}"]} for k in range(n)]
    bars += [{"id": f"l{k}", "ends": [f"T{k}", f"T{k + 1}"]} for k in range(n - 1)]
    # the driven rotor first: the sweeps take the first rotor of the bar list
    bars.insert(0, bars.pop(left))
    return {"vertices": vertices, "bars": bars}


def test_a_deep_failing_assembly_tree_answers_within_its_budget(api):
    body = {"linkage": deep_failing_chain(), "options": {"time_budget_s": 1.0}}
    r, took = timed_post(api, "/v1/analysis/configuration-space", body)
    assert_in_time(r, took, 1.0)


@pytest.mark.slow
@pytest.mark.parametrize("path", ["/v1/analysis/configuration-space",
                                  "/v1/analysis/critical-points"])
def test_the_parallel_100_rotor_chain_answers_within_its_budget(api, path):
    # a = l: every cell of the chain a parallelogram
    linkage = api.get("/v1/presets/kl-chain?n=100&a=1&l=1&r=1.5").json()
    r, took = timed_post(api, path, {"linkage": linkage})
    assert_in_time(r, took, SEARCH_S)


@pytest.mark.slow
@pytest.mark.parametrize("path", ["/v1/analysis/critical-values",
                                  "/v1/figures/critical-values"])
def test_the_100_rotor_chain_s_critical_value_map_answers_within_its_budget(api, path):
    # the preset matrix's request (its first two free bars over +-20 %): moving the seeds'
    # starts onto the critical set took 10 s of dense algebra past the 4 s deadline (504)
    linkage = api.get("/v1/presets/kl-chain?n=100").json()
    axes = [{"bar": b["id"], "min": 0.8 * bar_length(linkage, b),
             "max": 1.2 * bar_length(linkage, b)} for b in free_bars(linkage)[:2]]
    r, took = timed_post(api, path, {"linkage": linkage, "axes": axes})
    assert_in_time(r, took, SEARCH_S, search=not path.startswith("/v1/figures"))


def kl_bodies(linkage: Json) -> dict[str, Json]:
    """A request for every search endpoint around a Kane-Lubensky chain (default options)."""
    axes = [{"bar": "r0", "min": 1.2, "max": 1.8}, {"bar": "l0", "min": 1.2, "max": 1.8}]
    return {
        "/v1/analysis/configuration-space": {"linkage": linkage},
        "/v1/analysis/critical-points": {"linkage": linkage},
        "/v1/analysis/robustness": {"linkage": linkage},
        "/v1/analysis/critical-values": {"linkage": linkage, "axes": axes},
        "/v1/figures/configuration-space": {"linkage": linkage},
        "/v1/figures/critical-values": {"linkage": linkage, "axes": axes},
    }


KL_PATHS = list(kl_bodies({}))


@pytest.mark.slow
@pytest.mark.parametrize("path", KL_PATHS)
def test_a_400_rotor_chain_answers_every_search_within_its_budget(api, path):
    linkage = api.get("/v1/presets/kl-chain?n=400").json()
    r, took = timed_post(api, path, kl_bodies(linkage)[path])
    assert_in_time(r, took, SEARCH_S, search=not path.startswith("/v1/figures"))


@pytest.fixture(scope="module")
def largest_chain(api: ApiClient) -> Json:
    return api.get("/v1/presets/kl-chain?n=20000").json()  # the preset's largest n


@pytest.mark.slow
@pytest.mark.parametrize("path", KL_PATHS)
def test_a_chain_at_the_size_limit_answers_every_search_within_its_budget(api, largest_chain,
                                                                          path):
    r, took = timed_post(api, path, kl_bodies(largest_chain)[path])
    assert_in_time(r, took, SEARCH_S, search=not path.startswith("/v1/figures"))


def collinear_chain() -> Json:
    """Eight vertices on a line: four pins, four tips, every cell a parallelogram folded flat
    (the Kane-Lubensky chain with a = l = 1, r = 1.5 at rotor angle 0): every dyad collinear."""
    vertices = [{"id": f"P{k}", "position": [float(k), 0.0], "fixed": True} for k in range(4)]
    vertices += [{"id": f"T{k}", "position": [k + 1.5, 0.0]} for k in range(4)]
    bars = [{"id": f"r{k}", "ends": [f"P{k}", f"T{k}"]} for k in range(4)]
    bars += [{"id": f"l{k}", "ends": [f"T{k}", f"T{k + 1}"]} for k in range(3)]
    return {"vertices": vertices, "bars": bars}


#: A small time budget for the test over every search endpoint.
SMALL_BUDGET_S = 0.5


def hard_bodies(api: ApiClient) -> dict[str, Json]:
    """Every search endpoint with ``time_budget_s = SMALL_BUDGET_S`` on an input it cannot
    finish in that time."""
    opts = {"time_budget_s": SMALL_BUDGET_S}
    parallel = api.get("/v1/presets/kl-chain?n=100&a=1&l=1&r=1.5").json()
    three = api.get("/v1/presets/three-rotor").json()  # twelve branch points
    flat = collinear_chain()
    map_axes = [{"bar": "r0", "min": 1.0, "max": 2.0}, {"bar": "l0", "min": 0.5, "max": 1.5}]
    map_opts = {"resolution": 64, "seeds_per_axis": 8, **opts}
    return {
        "/v1/analysis/configuration-space": {"linkage": deep_failing_chain(), "options": opts},
        "/v1/analysis/critical-points": {"linkage": parallel, "options": opts},
        "/v1/analysis/robustness": {"linkage": parallel, "method": "multistart",
                                    "options": opts},
        "/v1/analysis/critical-values": {"linkage": flat, "axes": map_axes,
                                         "options": map_opts},
        "/v1/analysis/splitting": {"linkage": three, "perturbation": {"L1": 1e-3},
                                   "options": opts},
        "/v1/design/splitting": {"linkage": three, "targets": [{"branch_point": 0, "sign": 1}],
                                 "adjustable": ["L1", "L2"], "options": opts},
        "/v1/figures/configuration-space": {"linkage": parallel, "options": opts},
        "/v1/figures/critical-values": {"linkage": flat, "axes": map_axes,
                                        "options": map_opts},
        "/v1/figures/splitting": {"linkage": three, "perturbation": {"L1": 1e-3},
                                  "options": opts},
    }


HARD_PATHS = ["/v1/analysis/configuration-space", "/v1/analysis/critical-points",
              "/v1/analysis/robustness", "/v1/analysis/critical-values",
              "/v1/analysis/splitting", "/v1/design/splitting",
              "/v1/figures/configuration-space",
              "/v1/figures/critical-values",
              "/v1/figures/splitting"]


@pytest.mark.slow
@pytest.mark.parametrize("path", HARD_PATHS)
def test_no_search_answers_later_than_its_budget_plus_the_margin(api, path):
    r, took = timed_post(api, path, hard_bodies(api)[path])
    if path == "/v1/design/splitting" and r.status_code == 422:
        # a search cut before it found the target branch point: the target is named
        assert r.json()["errors"][0]["loc"][-3:-1] == ["targets", 0], r.text
        assert took.within(SMALL_BUDGET_S, MARGIN_S), f"answered after {took}"
        return
    assert_in_time(r, took, SMALL_BUDGET_S, search=not path.startswith("/v1/figures"))


def test_a_search_deadline_counts_from_the_request_s_arrival():
    # parsing, validating and sending the body to a worker spend the request's budget too
    from service.jobs import search_deadline

    settings = Settings.from_env().replace(search_time_s=SEARCH_S,
                                           arrived_at=time.monotonic() - 1.5)
    deadline = search_deadline(None, settings, None)
    assert deadline.budget_s == SEARCH_S  # (what the answer reports as time_budget_s)
    assert SEARCH_S - 1.5 - 0.5 < deadline.remaining() <= SEARCH_S - 1.5
    assert search_deadline(None, settings.replace(arrived_at=None), None).remaining() > 3.5
