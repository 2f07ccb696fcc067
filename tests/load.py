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
from types import TracebackType
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


class Timer:
    """Wall seconds of a block and the machine's slowdown around it (:func:`stretch` of
    ``app``'s engine worker and this process, or this process's alone without ``app``), for a
    bound whose margin is seconds of work on an idle machine::

        with Timer() as t:
            work()
        assert t.within(budget, margin), t
    """

    def __init__(self, app: Any = None) -> None:
        self.app = app
        self.seconds = 0.0
        self.stretch = 1.0

    def _stretch(self) -> float:
        return stretch(self.app) if self.app is not None else max(1.0, reference_work())

    def __enter__(self) -> Timer:
        self.stretch = self._stretch()
        self._t0 = time.monotonic()
        return self

    def __exit__(self, kind: type[BaseException] | None, err: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.seconds = time.monotonic() - self._t0
        self.stretch = max(self.stretch, self._stretch())

    def within(self, budget: float, margin: float) -> bool:
        """True when the block took at most ``budget`` (wall-clock, e.g. a deadline's) plus
        ``margin`` (idle seconds of work) times the slowdown measured."""
        return self.seconds <= budget + margin * self.stretch

    def __str__(self) -> str:
        return f"{self.seconds:.2f} s at a measured slowdown of {self.stretch:.1f}"
