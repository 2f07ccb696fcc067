"""The forkserver the engine workers are forked from (``service.workers``), and its early start.

The forkserver is a fresh interpreter that imports the engine and the service's work
(``service.jobs``) and loads the compiled kernels (``service.warm``) once: about 1.5 s of a core
on a 2-core machine, after which a worker, a replacement too, is forked from it ready in
milliseconds. :func:`start` launches it without waiting, so that ``service.main`` can start it
before its own imports (1.7 s of a core): on two cores the two run side by side instead of one
after the other (issue 28: start-up)."""

from __future__ import annotations

import multiprocessing
import os
from multiprocessing import forkserver
from multiprocessing.context import ForkServerContext

#: BLAS thread counts set to one, before numpy loads in the forkserver (one worker per core).
BLAS_THREADS = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")
#: Modules the forkserver imports before it forks any worker: the work (the engine), the kernels,
#: and the figures (matplotlib: imported in a worker's first figure request otherwise, 1-3 s of
#: that request on a loaded 2-core machine, paid again by every worker and replacement).
PRELOAD = ["service.jobs", "service.warm", "service.figures"]


def context() -> ForkServerContext:
    """The multiprocessing context of the engine workers, its forkserver preloading
    :data:`PRELOAD` (the environment it inherits has :data:`BLAS_THREADS` at one)."""
    for name in BLAS_THREADS:
        os.environ.setdefault(name, "1")
    ctx = multiprocessing.get_context("forkserver")
    assert isinstance(ctx, ForkServerContext)
    ctx.set_forkserver_preload(PRELOAD)
    return ctx


def start() -> None:
    """Launch the forkserver now, without waiting for its imports (it is one per process:
    nothing happens when it runs already). The first worker asked for waits for them.

    Not in a child process of ``multiprocessing`` (a worker importing its parent's main
    script, where that script imports ``service.main``): a process may start none while it
    bootstraps, and a worker needs none."""
    bootstrapping = getattr(multiprocessing.current_process(), "_inheriting", False)
    if bootstrapping or multiprocessing.parent_process() is not None:
        return
    context()
    forkserver.ensure_running()
