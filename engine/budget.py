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
from dataclasses import dataclass

#: Reasons for an incomplete search, as reported in ``search["reason"]``.
REASON_TIME = "time"
REASON_BUDGET = "budget"


@dataclass(frozen=True)
class Deadline:
    """A point in ``time.monotonic()`` time; ``at = inf`` never expires."""

    at: float = float("inf")

    @classmethod
    def after(cls, seconds: float | None) -> Deadline:
        """A deadline ``seconds`` from now (``None``: never)."""
        if seconds is None:
            return cls()
        return cls(time.monotonic() + max(0.0, float(seconds)))

    def expired(self) -> bool:
        return self.at != float("inf") and time.monotonic() >= self.at

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
        return Deadline(time.monotonic() + share * self.remaining())


NEVER = Deadline()
