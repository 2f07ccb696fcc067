"""A job's state, kept by :class:`service.tasks.JobManager` and mapped out by
:func:`service.mappers.jobs.job_out` (below both, so neither imports the other)."""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from service.workers import ServiceFault

if TYPE_CHECKING:  # a type only: the command line's in-process runs never import Dask
    from distributed import Future


class ClusterUnavailable(ServiceFault):
    """No Dask scheduler to run a job on (503; ``service.cluster`` raises it, and the job
    manager catches it without importing Dask)."""

    status = 503
    kind = "cluster-unavailable"
    title = "Dask cluster unavailable"


@dataclass
class Job:
    """One job's state (guarded by the manager's lock)."""

    id: str
    operation: str
    end_wall: float
    sizes: list[int]
    names: tuple[str, ...] = ()
    status: str = "queued"
    done: list[float] = field(default_factory=list)
    message: str = "queued"
    created: float = field(default_factory=time.time)
    started: float | None = None
    finished: float | None = None
    result: Any = None
    error: dict[str, Any] | None = None
    futures: list[Future] = field(default_factory=list)
    parts: dict[int, Any] = field(default_factory=dict)
    #: chunks whose task has reported from a worker (started): a stopped job keeps their rows
    started_chunks: set[int] = field(default_factory=set)
    #: the result holds only the work finished before the job stopped
    partial: bool = False

    @property
    def fraction(self) -> float:
        if self.status == "done":
            return 1.0
        total = sum(self.sizes)
        return sum(d * s for d, s in zip(self.done, self.sizes, strict=True)) / total

    @property
    def finished_state(self) -> bool:
        return self.status in ("done", "failed", "cancelled")
