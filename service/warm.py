"""Loaded by the engine workers' forkserver (``service.forkserver``, its preload): importing this
module loads the compiled kernels (the tracer's and the closed form's, from numba's on-disk
cache, or compiled into it where the cache is cold), so that every worker forked from the
forkserver, the replacements of dead ones included, starts with them loaded instead of
loading them itself (half a second of a core each on a 2-core machine), and says so on
standard error, beside the service's log (the forkserver has no logging configured)."""

import os
import sys
import time

from engine.space import trace_kernel
from engine.space.dyads import kernel as dyads_kernel


def _say(message: str) -> None:
    sys.stderr.write(f"INFO:     start-up: {message}\n")
    sys.stderr.flush()


_t0 = time.perf_counter()
_say(f"the workers' forkserver (pid {os.getpid()}) has imported the engine; loading the "
     "compiled kernels (compiled now if numba's cache is cold)")
#: Whether each compiled path is in use in the processes forked from here (False: numpy's,
#: numba missing, chosen by the environment or failed to load: see each module's ``failure``).
TRACER_COMPILED = trace_kernel.prepare()
DYADS_COMPILED = dyads_kernel.prepare()
_say(f"kernels loaded in {time.perf_counter() - _t0:.1f} s (tracer "
     f"{'compiled' if TRACER_COMPILED else 'numpy: ' + str(trace_kernel.failure)}, closed form "
     f"{'compiled' if DYADS_COMPILED else 'numpy: ' + str(dyads_kernel.failure)}) in the "
     "workers' forkserver")
