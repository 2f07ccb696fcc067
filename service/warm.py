"""Loaded by the engine workers' forkserver (``service.workers``, its preload): importing this
module loads the compiled kernels (the tracer's and the closed form's, from numba's on-disk
cache, or compiled into it where the cache is cold), so that every worker forked from the
forkserver, the replacements of dead ones included, starts with them loaded instead of
loading them itself (half a second of a core each on a 2-core machine, and the service
process, whose small requests trace nothing, needs none)."""

from engine.space import trace_kernel
from engine.space.dyads import kernel as dyads_kernel

#: Whether each compiled path is in use in the processes forked from here (False: numpy's,
#: numba missing, chosen by the environment or failed to load: see each module's ``failure``).
TRACER_COMPILED = trace_kernel.prepare()
DYADS_COMPILED = dyads_kernel.prepare()
