"""Time budgets: a deadline that engine searches check so that they stop in time.

Every search that can run long (explorations, critical-point searches, slices, margins) takes a
``Deadline``. When it has passed, the search stops where it is and returns what it found,
marked incomplete with the reason ``"time"`` (budgets of counts give ``"budget"``), so that the
service answers before its own time limit instead of being killed there.

>>> d = Deadline.after(None)
>>> d.expired(), d.remaining() == float("inf")
(False, True)
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Final, Literal

#: Reasons for an incomplete search, as reported in ``search["reason"]``.
REASON_TIME = "time"
REASON_BUDGET = "budget"
#: a critical point that is not isolated: the classification cannot go on
REASON_DEGENERATE = "degenerate"
#: a curve or segment that stopped open for a numerical reason (e.g. near a split branch point)
REASON_UNRESOLVED = "unresolved"
#: nothing was cut short, but no argument proves that nothing was missed (seeds and random starts
#: found what they found)
REASON_SEARCHED = "searched"

#: Arguments that make a search complete (``search["argument"]``): a closed form, chain rules or a
#: certified decomposition (derived), or every solution of a polynomial system found (proved).
Argument = Literal["derived", "proved"]
ARGUMENT_DERIVED: Final = "derived"
ARGUMENT_PROVED: Final = "proved"


#: ``progress(fraction, message)``: how far a search has come (0..1), from the engine itself.
ProgressSink = Callable[[float, str], None]


@dataclass(frozen=True)
class Deadline:
    """A point in ``time.monotonic()`` time (``at = inf`` never expires), optionally with a
    ``stop`` flag (e.g. a cancelled job: the search ends as if its time were up) and a
    ``progress`` sink that searches report to."""

    at: float = float("inf")
    stop: Callable[[], bool] | None = field(default=None, compare=False)
    progress: ProgressSink | None = field(default=None, compare=False)
    #: the seconds this deadline was given when it was made (None: never expires), for reports
    budget_s: float | None = field(default=None, compare=False)

    @classmethod
    def after(cls, seconds: float | None, *, stop: Callable[[], bool] | None = None,
              progress: ProgressSink | None = None) -> Deadline:
        """A deadline ``seconds`` from now (``None``: never)."""
        if seconds is None:
            return cls(float("inf"), stop, progress)
        seconds = max(0.0, float(seconds))
        return cls(time.monotonic() + seconds, stop, progress, seconds)

    def expired(self) -> bool:
        if self.stop is not None and self.stop():
            return True
        return self.at != float("inf") and time.monotonic() >= self.at

    def report(self, fraction: float, message: str) -> None:
        """Pass progress on (clipped to 0..1); a no-op without a sink."""
        if self.progress is not None:
            self.progress(min(1.0, max(0.0, float(fraction))), message)

    def remaining(self) -> float:
        """Seconds left (``inf`` without a deadline, never negative)."""
        if self.at == float("inf"):
            return float("inf")
        return max(0.0, self.at - time.monotonic())

    def fraction(self, share: float) -> Deadline:
        """A deadline that leaves ``share`` (0..1) of the remaining time to this one: a
        sub-search gets part of the time so that the caller can still finish its own work."""
        if self.at == float("inf"):
            return self
        seconds = share * self.remaining()
        return Deadline(time.monotonic() + seconds, self.stop, self.progress, seconds)


NEVER = Deadline()


class OutOfTime(RuntimeError):
    """Raised from inside one unit of work that checks its deadline as it goes (e.g. the
    Lanczos iterations of a sparse null space): the caller that handed the deadline down
    catches it and stops its search with the reason ``"time"``."""


def granted(deadline: Deadline) -> float | None:
    """The seconds ``deadline`` was given, rounded for a report (None without a limit)."""
    return None if deadline.budget_s is None else round(deadline.budget_s, 3)


#: Seconds to map and serialise one value of a configuration-space answer (one vertex of one
#: traced point: its coordinates in the answer's per-vertex lists, and its share of the rotor
#: angles), for a loaded machine: the mapping and orjson take 0.29 us per value in the
#: "objects" form (0.07 compact; the default kl-chain's 189,460 values in 55 ms, idle 2-core
#: machine), the whole path through a worker and HTTP 1.1 to 3 us per value (400 rotors, 6.4
#: million values in 7 to 20 s on the shared machine): the upper end of the whole path.
ANSWER_SECONDS_PER_VALUE: Final = 3e-6
#: Seconds of a deadline's answer left to mapping and serialising the points found (a part of
#: the margin past the deadline that an answer may take): 333,333 values, so that the default
#: answers (the 10-rotor chain's 32 traced components: 189,460 values; the gated chain's 32:
#: 53,810) are not cut.
ANSWER_TIME_S: Final = 1.0


def answer_values(deadline: Deadline) -> int | None:
    """The budget of values (points x vertices) an answer under ``deadline`` may carry, so that
    mapping and serialising them takes at most ``ANSWER_TIME_S`` past the deadline (None
    without a deadline: the in-process caller maps nothing, or waits).

    >>> answer_values(NEVER) is None, answer_values(Deadline.after(4.0))
    (True, 333333)
    """
    if deadline.at == float("inf"):
        return None
    return int(ANSWER_TIME_S / ANSWER_SECONDS_PER_VALUE)
