"""Answers in transit from the engine workers: an answer of at least ``SPILL_MIN_BYTES`` is
written by its worker into a file in memory (``/dev/shm``, else the temporary directory) that
the service handed to the request, instead of going through pebble's result pipe (see
:mod:`service.workers`); files whose request was answered are kept for the next one."""

from __future__ import annotations

import os
import tempfile
import threading

#: Answers from this size on come back from a worker through a file, not pebble's pipe.
SPILL_MIN_BYTES = 1 << 20
#: Files that held more than this are removed after their answer, not kept for the next one.
SPILL_KEEP_MAX_BYTES = 64 << 20


def write_spill(path: str, parts: list[bytes]) -> bool:
    """Write ``parts`` to the existing file ``path``; False where that cannot be done."""
    try:
        # no O_CREAT: the service removes the file when it stops waiting (time limit), and a
        # worker finishing later must not leave a new one behind
        fd = os.open(path, os.O_WRONLY)
    except OSError:
        return False
    try:
        for part in parts:
            view = memoryview(part)
            while view:
                view = view[os.write(fd, view):]
        return True
    except OSError:  # e.g. ENOSPC: a small /dev/shm (Docker's default is 64 MB)
        return False
    finally:
        os.close(fd)


def spill_dir() -> str:
    """A directory in memory for answers in transit: ``/dev/shm`` where it is usable, else the
    temporary directory (on disk, the page cache holds a file that lives milliseconds)."""
    shm = "/dev/shm"
    if os.path.isdir(shm) and os.access(shm, os.W_OK | os.X_OK):
        return shm
    return tempfile.gettempdir()


class SpillFiles:
    """Files for answers in transit from the workers (mode 0600, in :func:`_spill_dir`): one
    per request in flight, and up to ``keep`` of them kept between requests (each at most
    ``SPILL_KEEP_MAX_BYTES``) so that a request writes over pages the file already has."""

    def __init__(self, keep: int) -> None:
        self.keep = keep
        self._free: list[str] = []
        self._lock = threading.Lock()

    def take(self) -> str:
        with self._lock:
            if self._free:
                return self._free.pop()
        fd, path = tempfile.mkstemp(prefix="linkage-answer-", suffix=".json", dir=spill_dir())
        os.close(fd)
        return path

    def give_back(self, path: str, reuse: bool) -> None:
        """Keep ``path`` for another request when ``reuse`` (its worker has finished with it)
        and there is room, else remove it."""
        if reuse:
            try:
                small = os.path.getsize(path) <= SPILL_KEEP_MAX_BYTES
            except OSError:
                small = False
            with self._lock:
                if small and len(self._free) < self.keep:
                    self._free.append(path)
                    return
        unlink(path)

    def close(self) -> None:
        with self._lock:
            free, self._free = self._free, []
        for path in free:
            unlink(path)


def unlink(path: str) -> None:
    try:
        os.unlink(path)
    except FileNotFoundError:
        pass
