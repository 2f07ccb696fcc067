"""Memory of one analysis: what this process may still allocate, and the refusal of a method
whose estimated peak would not fit (:func:`check_memory`, :class:`MemoryLimitExceeded`).
"""

from __future__ import annotations

import os
import resource

from engine.model.errors import LimitExceeded


class MemoryLimitExceeded(LimitExceeded):
    """The chosen method would need more memory than this process may allocate."""


#: Estimates below this many bytes are not checked (reading the process's usage costs ~50 us).
MEMORY_CHECK_MIN_BYTES = 64 << 20
#: Bytes one number of an analysis result costs at the peak of answering with it: its float64
#: in the engine's arrays, its Python float in a caller's lists and dictionaries, and its JSON
#: text (measured on the zero modes of floppy chains answered by the service's rigidity job:
#: 147 to 152 bytes per zero-mode coordinate at the peak, all work included).
RESULT_BYTES_PER_VALUE = 160


def _status_bytes(field: str) -> int:
    """``field`` (e.g. ``VmData``) of ``/proc/self/status`` in bytes; 0 where unknown."""
    try:
        with open("/proc/self/status") as status:
            for line in status:
                if line.startswith(field + ":"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    return 0


def _machine_available() -> int:
    """Memory the machine can still give (``MemAvailable``, else the free pages)."""
    try:
        with open("/proc/meminfo") as meminfo:
            for line in meminfo:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return int(os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE"))
    except (OSError, ValueError):
        return 1 << 62


def available_memory() -> int:
    """Bytes this process may still allocate: what its soft ``RLIMIT_DATA`` and ``RLIMIT_AS``
    leave above its current data and address-space sizes, and without such a limit what the
    machine has available."""
    room = []
    for limit, used in ((resource.RLIMIT_DATA, "VmData"), (resource.RLIMIT_AS, "VmSize")):
        soft, _ = resource.getrlimit(limit)
        if soft != resource.RLIM_INFINITY:
            room.append(soft - _status_bytes(used))
    return max(0, min(room) if room else _machine_available())


def check_memory(need: int, what: str, budget: int | None = None) -> None:
    """Refuse, before allocating, a method whose estimated peak ``need`` (bytes) exceeds
    ``budget`` (default :func:`available_memory`).

    Raises
    ------
    MemoryLimitExceeded
        Naming ``what`` (the method and the sizes that drive its cost) and both amounts.

    Examples
    --------
    >>> check_memory(1 << 20, "a small analysis")  # below MEMORY_CHECK_MIN_BYTES: no check
    """
    if need < MEMORY_CHECK_MIN_BYTES and budget is None:
        return
    room = available_memory() if budget is None else budget
    if need > room:
        raise MemoryLimitExceeded(
            f"{what} would need about {need / 2**20:,.0f} MB, more than the "
            f"{room / 2**20:,.0f} MB this process may still allocate: ask for a smaller or "
            "less floppy linkage",
            loc=(),
        )
