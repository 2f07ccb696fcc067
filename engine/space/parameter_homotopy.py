"""A parameter homotopy and its path follower (for the scanlines of
:mod:`engine.design.slice_scan`): ``F(X; w(t)) = 0`` followed from ``t = 1`` to ``0`` as
:func:`engine.space.homotopy.track` follows its paths. ``system(x, w)`` answers the values and
the Jacobian in ``x`` of a square system on the complex points ``x`` (K, M + 1) at the
parameter ``w`` (K,); ``system.dw(x)`` its derivative in ``w``."""

from __future__ import annotations

from collections.abc import Callable
from typing import Protocol

import numpy as np

from engine.model.budget import Deadline
from engine.space.homotopy import (
    FAILED,
    H_MAX,
    REGULAR,
    RUNNING,
    TRUST,
    _adapt,
    _Homotopy,
    _jumped,
    _rk4,
)


class ParameterSystem(Protocol):
    """A square system with one complex parameter ``w``."""

    def __call__(self, x: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, np.ndarray]: ...

    def dw(self, x: np.ndarray) -> np.ndarray: ...


class Parameter(_Homotopy):
    """The parameter homotopy ``F(X; w(t)) = 0``, ``w(t) = w_1 + t (w_0 - w_1) + i b t (1 - t)``,
    on the patch ``a . X = 1`` (as :class:`engine.space.homotopy._Homotopy`, whose predictor
    velocity and Newton corrector it takes, with
    ``H_t = F_w w'(t)``): a segment, bent off the real line by ``b`` (a sweep along real
    lengths passes the points where two real solutions meet at a distance, instead of through
    them)."""

    def __init__(self, system: ParameterSystem, w0: complex, w1: complex, patch: np.ndarray,
                 bump: float = 0.0) -> None:
        self.equations, self.w0, self.w1, self.patch, self.bump = system, w0, w1, patch, bump

    def w(self, t: np.ndarray) -> np.ndarray:
        return self.w1 + t * (self.w0 - self.w1) + 1j * self.bump * t * (1.0 - t)

    def parts(self, x: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        f, fx = self.equations(x, self.w(t))
        full = np.concatenate([fx, np.broadcast_to(self.patch, (len(x), 1, len(self.patch)))],
                              axis=1)
        value = np.concatenate([f, (x @ self.patch - 1.0)[:, None]], axis=1)
        rate = (self.w0 - self.w1) + 1j * self.bump * (1.0 - 2.0 * t)
        return value, full, self.equations.dw(x) * rate[:, None]


#: ``watch(paths, points, t)``: called with the paths (K,) that took a step, their new points
#: (K, M + 1) and ``t`` (K,).
Watch = Callable[[np.ndarray, np.ndarray, np.ndarray], None]


def follow(hom: Parameter, x: np.ndarray, deadline: Deadline, max_steps: int = 4000,
            h_max: float = H_MAX, watch: Watch | None = None
            ) -> tuple[np.ndarray, np.ndarray, str]:
    """Every path of ``hom`` from ``t = 1`` (the rows of ``x``, on the patch) to 0, as
    :func:`engine.space.homotopy.track` follows its paths (RK4 predictor, Newton corrector,
    geometric endgame), no step longer than ``h_max``: the ends and their states
    (``REGULAR``, ``SINGULAR``, ``FAILED``, ``RUNNING`` where the deadline or the step limit
    stopped them), and what went wrong. ``watch`` sees every step taken."""
    x = np.array(x, dtype=complex)
    p = len(x)
    t, h = np.ones(p), np.full(p, h_max)
    wins = np.zeros(p, dtype=int)
    state = np.full(p, RUNNING)
    endgame = np.zeros(p, dtype=bool)
    for _ in range(max_steps):
        if not (state == RUNNING).any() or deadline.expired():
            break
        act = np.flatnonzero(state == RUNNING)
        xa, ta = x[act], t[act]
        ha = np.minimum(h[act], ta)
        new, ok, first = hom.newton(_rk4(hom, xa, ta, ha), ta - ha)
        ok &= (first <= TRUST) & np.isfinite(new).all(axis=1)
        good = act[ok]
        x[good], t[good] = new[ok], (ta - ha)[ok]
        if watch is not None and len(good):
            watch(good, x[good], t[good])
        _adapt(act, ok, ta, ha, t, h, wins, endgame, state, h_max)
    running, failed = int((state == RUNNING).sum()), int((state == FAILED).sum())
    jumped = _jumped(x[state == REGULAR])
    message = "; ".join(m for m in (
        f"{running} of {p} paths stopped by the deadline or the step limit" if running else "",
        f"{failed} of {p} paths failed" if failed else "",
        f"{jumped} regular ends coincide (a path jumped)" if jumped else "") if m)
    return x, state, message
