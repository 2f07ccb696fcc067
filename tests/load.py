"""The machine's slowdown at the moment of a timed test, measured, for bounds that must hold on
a loaded machine (CI's 2 cores shared by the run's own workers and whatever else runs).

A timed bound such as "answered within its budget plus ``MARGIN_S``" has two parts: the
budget, a wall-clock deadline the engine reads itself (it holds on any machine), and the margin,
some CPU work that runs after the deadline (a unit of work, the mapping and serialising, the
hop between processes), which a loaded machine stretches. The engine workers run at
``WORKER_NICE`` (service.workers): beside other processes at the default priority a worker gets
a small share of a core (a nice-10 process weighs 110 against 1,024 for each nice-0 one in
Linux's scheduler), so that work stretches far more than the load average says. :func:`stretch`
measures that factor in an engine worker and in this process (wall time over CPU time of the
same fixed work), and a test scales its margin by it: the margin stays the idle machine's
seconds of work, counted in the machine's current speed."""

from __future__ import annotations

import asyncio
import time
from typing import Any

#: Iterations of the reference work: about 40 ms of CPU on the 2-core test machine when idle,
#: enough for the clocks' resolution and short beside the timed requests.
REFERENCE_ITERATIONS = 1_000_000


def reference_work(iterations: int = REFERENCE_ITERATIONS) -> float:
    """Wall seconds over CPU seconds of a fixed pure-Python loop in the calling process (1 on
    an idle core, ``k`` where the process got ``1/k`` of a core meanwhile). Module-level and
    light to import, so that an engine worker can run it (pickled by reference)."""
    wall, cpu = time.monotonic(), time.process_time()
    total = 0
    for i in range(iterations):
        total += i & 7
    cpu = max(time.process_time() - cpu, 1e-6)
    return (time.monotonic() - wall) / cpu


def stretch(app: Any) -> float:
    """The larger slowdown of an engine worker of ``app`` (started: tests.conftest.start_ready)
    and of this process, at least 1: the factor by which CPU work after a deadline takes longer
    than on an idle machine right now."""
    pool = app.state.engine_pool
    worker = asyncio.run(pool.run(60.0, reference_work, REFERENCE_ITERATIONS))
    return max(1.0, worker, reference_work())
