"""Exceptions raised by the engine, and the one rule for numerical methods that fail.

Bad input raises a subclass of :class:`EngineError` (a ``ValueError``). Every error carries
``loc``: the path of the offending field inside the linkage description or the request (e.g.
``("bars", 3, "ends")``), so that the service can name it in its answer (problem+json).

A numerical method that does not converge is not an error of the caller: what a caller can rely
on, by kind of method,

* **An iterative method with one answer** (projection, margin, design, prestress) returns a
  frozen result dataclass with ``success: bool`` and ``message: str`` (SciPy's
  ``OptimizeResult`` habit): ``success=False`` when it did not converge, with the message
  saying why; its numbers are then whatever the method reached, not a converged answer.
* **A search** (configuration spaces, critical points, slices, sweeps) answers what it found
  with a :class:`engine.model.report.SearchReport`: ``complete`` is False, with a ``reason``
  ("time",
  "budget", "unresolved", ...), whenever anything was left out; what it did find is as valid as
  in a complete answer.
* **A traced curve** (:class:`engine.space.curve.Curve`) says why it ended in ``stop`` ("closed",
  "time", "max points", "singular start", ...); the searches turn that into their report.
* **No result can be formed** (the sparse null spaces of :mod:`engine.local.rigidity` are
  inconsistent, Lanczos does not converge and the dense fallback is not allowed): raise
  :class:`NumericalFailure`, never a bare ``RuntimeError`` or a ``LinAlgError``. The service
  answers 422 ``numerical-failure`` (``service/errors.py``), a job fails with that error
  (``service/tasks.py``), a sweep records it on the row (:mod:`engine.design.sweep`).

So a non-converged answer never looks like a converged one: it is ``success=False``,
``complete=False``, a curve whose ``stop`` names the limit it hit, or a
:class:`NumericalFailure`. Internally, helpers may return ``None`` for "this step did not
converge" or "this fast path does not apply" (the closed forms decline, the caller falls back
to the general method); the public function turns that into one of the forms above.

Linear algebra that raises on singular matrices of finite entries (``np.linalg.solve``,
``scipy.sparse.linalg.splu``, ``eigsh``) is called inside a ``try`` that handles it, or on
matrices checked non-singular first. ``tests/engine/model/test_errors.py`` checks these rules where
a
program can.
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
