"""The report of a configuration-space search: what was done, and whether it is complete.

Every search of :mod:`engine.space.configuration_space` (the tracer, the closed forms) ends in one
:class:`SearchReport`. Its ``details`` are the counts of what was done (seeds, curves, candidates,
closed-form samples: they differ between methods); whether the answer is complete, and if not
why, is decided in one place from four flags and an argument, :attr:`SearchReport.complete` and
:attr:`SearchReport.reason`: a search is complete only when nothing was cut short *and* an
argument proves that nothing was missed (``derived``: a closed form, chain rules, a certified
decomposition; ``proved``: every solution of a polynomial system found, see
:mod:`engine.space.witnesses`), named in ``argument`` with a sentence in ``argument_detail``;
without one the answer is incomplete with reason ``searched``. It reads like the ``search``
object of the HTTP answers (a read-only mapping: ``report["complete"]``,
``report.get("seeds")``), which :meth:`SearchReport.as_dict` gives.

>>> r = SearchReport({"method": "tracer", "curves_traced": 3}, budget=True)
>>> r.complete, r.reason, r["curves_traced"]
(False, 'budget', 3)
>>> SearchReport({"method": "tracer"}).reason
'searched'
>>> SearchReport({}, argument="derived", argument_detail="closed form").complete
True
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field, replace
from typing import Any

from engine.model.budget import (
    REASON_BUDGET,
    REASON_DEGENERATE,
    REASON_SEARCHED,
    REASON_TIME,
    REASON_UNRESOLVED,
    Argument,
)


@dataclass(frozen=True)
class SearchReport(Mapping[str, Any]):
    """What a search did (``details``) and why it may be incomplete.

    Attributes
    ----------
    details : Mapping[str, object]
        Counts and choices of the method (e.g. ``method``, ``seeds``, ``curves_traced``,
        ``closed_form_sheets``), as the answer's ``search`` shows them.
    timed_out : bool
        The deadline stopped some part of the search.
    budget : bool
        A count ran out: components, assemblies per angle, points of a curve.
    degenerate : bool
        A critical point is not isolated: the classification cannot go on.
    unresolved : bool
        A curve or segment stopped open for a numerical reason (e.g. near a split branch point).
    time_budget_s : float or None
        Seconds the search was given (None: no deadline).
    argument : str or None
        What proves that nothing was missed: ``"derived"`` or ``"proved"``; None: the search
        found what it found (reason ``searched`` when nothing else applies).
    argument_detail : str or None
        The argument in a sentence (which closed form, rule or system, with its counts).
    """

    details: Mapping[str, object] = field(default_factory=dict)
    timed_out: bool = False
    budget: bool = False
    degenerate: bool = False
    unresolved: bool = False
    time_budget_s: float | None = None
    argument: Argument | None = None
    argument_detail: str | None = None

    @property
    def reason(self) -> str | None:
        """Why the search is incomplete (the first that applies: time, budget, degenerate,
        unresolved, searched), None when it is complete."""
        return (REASON_TIME if self.timed_out else REASON_BUDGET if self.budget
                else REASON_DEGENERATE if self.degenerate
                else REASON_UNRESOLVED if self.unresolved
                else REASON_SEARCHED if self.argument is None else None)

    @property
    def complete(self) -> bool:
        return self.reason is None

    def with_details(self, **more: object) -> SearchReport:
        """The same report with more (or changed) details."""
        return replace(self, details={**self.details, **more})

    def with_argument(self, argument: Argument | None, detail: str | None) -> SearchReport:
        """The same report with an argument (or none)."""
        return replace(self, argument=argument, argument_detail=detail)

    def as_dict(self) -> dict[str, object]:
        """The answer's ``search``: the details, ``complete``, ``reason``, ``argument``,
        ``argument_detail`` and (with a deadline) ``time_budget_s``."""
        out: dict[str, object] = {**self.details, "complete": self.complete,
                                  "reason": self.reason, "argument": self.argument,
                                  "argument_detail": self.argument_detail}
        if self.time_budget_s is not None:
            out["time_budget_s"] = self.time_budget_s
        return out

    # -- read-only mapping (the answer's ``search``) ------------------------------------------
    def __getitem__(self, key: str) -> Any:
        return self.as_dict()[key]

    def __iter__(self) -> Iterator[str]:
        return iter(self.as_dict())

    def __len__(self) -> int:
        return len(self.as_dict())


#: Largest count written out in digits in a sentence (``str`` refuses more than 4300 digits).
COUNT_DIGITS_MAX = 1000


def count_text(n: int) -> str:
    """``n`` for a sentence: its digits, or ``2^k`` (a 20000-rotor chain has 2^19999
    components, 6021 digits: ``str`` refuses them), or its order of magnitude.

    >>> count_text(12), count_text(2**19999), count_text(3**20000)
    ('12', '2^19999', 'about 10^9542')
    """
    if n.bit_length() <= COUNT_DIGITS_MAX * 3:  # (below 10^903: far below the limit)
        return str(n)
    if n > 0 and n & (n - 1) == 0:
        return f"2^{n.bit_length() - 1}"
    return f"about 10^{int(math.log10(n))}"
