"""Progress of jobs: a callback per change, or a text bar on a stream (no dependency)."""

from __future__ import annotations

import sys
from collections.abc import Callable
from typing import TextIO

from linkage_client.models import Job

#: ``progress=`` of the waiting methods: a callback given each changed job, True for the text
#: bar on stderr, None or False for nothing.
ProgressArg = Callable[[Job], object] | bool | None


class TextBar:
    """``[#########-----------]  45%  tracing the components`` rewritten in place.

    Parameters
    ----------
    stream : text stream
        Where to draw (stderr by default).
    width : int
        Characters of the bar itself.
    """

    def __init__(self, stream: TextIO | None = None, width: int = 30) -> None:
        self.stream = stream if stream is not None else sys.stderr
        self.width = width

    def __call__(self, job: Job) -> None:
        fraction = min(max(job.progress.fraction, 0.0), 1.0)
        filled = round(fraction * self.width)
        line = (f"\r[{'#' * filled}{'-' * (self.width - filled)}] {fraction:4.0%}  "
                f"{job.status}: {job.progress.message}"[:200])
        self.stream.write(line.ljust(80))
        if job.done:
            self.stream.write("\n")
        self.stream.flush()


def reporter(progress: ProgressArg) -> Callable[[Job], object] | None:
    """The callback that ``progress=`` asks for."""
    if progress is True:
        return TextBar()
    if progress is None or progress is False:
        return None
    return progress


class Changes:
    """Calls ``report`` with a job only when its status, fraction or message changed."""

    def __init__(self, report: Callable[[Job], object] | None) -> None:
        self.report = report
        self.last: tuple[str, float, str] | None = None

    def __call__(self, job: Job) -> None:
        key = (job.status, job.progress.fraction, job.progress.message)
        if self.report is not None and key != self.last:
            self.last = key
            self.report(job)
