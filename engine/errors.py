"""Exceptions raised by the engine for bad input.

Every error carries ``loc``: the path of the offending field inside the linkage description
(e.g. ``("bars", 3, "ends")``), so that the service can name it in its answer.
Numerical methods that fail to converge do not raise; they return a result with
``success=False`` and a ``message``.
"""

from __future__ import annotations


class EngineError(ValueError):
    """Base class of every input error the engine raises."""

    def __init__(self, message: str, loc: tuple[str | int, ...] = ()) -> None:
        super().__init__(message)
        self.message = message
        self.loc = loc


class InvalidLinkage(EngineError):
    """The linkage description is inconsistent (ids, shapes, numbers, lengths)."""


class LimitExceeded(EngineError):
    """The linkage is larger than the configured limits."""


class NoNearbySolution(EngineError):
    """The given positions could not be projected onto the constraint set."""


class UnknownPreset(EngineError):
    """No preset of that name exists."""


class InvalidParameter(EngineError):
    """A preset parameter is out of range or its lengths admit no configuration."""


class InvalidTolerance(EngineError):
    """A tolerance is out of range."""


class NumericalFailure(RuntimeError):
    """A numerical method could not produce a trustworthy answer (not an input error)."""


class InvalidRequest(EngineError):
    """A request field other than the linkage (a perturbation, a target, ...) is invalid."""
