"""The parameter homotopy's follower against systems whose solutions are known in closed form."""

from __future__ import annotations

import numpy as np

from engine.model.budget import NEVER
from engine.space.homotopy import REGULAR
from engine.space.parameter_homotopy import Parameter, follow


class SquareRoots:
    """``X0^2 - w X1^2 = 0`` (homogeneous in ``X = (X0, X1)``): ``X0 / X1 = +-sqrt(w)``."""

    def __call__(self, x: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        f = (x[:, 0] ** 2 - w * x[:, 1] ** 2)[:, None]
        fx = np.stack([2 * x[:, 0], -2 * w * x[:, 1]], axis=1)[:, None, :]
        return f, fx

    def dw(self, x: np.ndarray) -> np.ndarray:
        return (-(x[:, 1] ** 2))[:, None]


def on_patch(ratio: np.ndarray, patch: np.ndarray) -> np.ndarray:
    x = np.stack([ratio, np.ones_like(ratio)], axis=1).astype(complex)
    return x / (x @ patch)[:, None]


def test_the_roots_follow_the_parameter_to_their_closed_form():
    patch = np.array([0.3 + 0.7j, 1.1 - 0.2j])
    start = on_patch(np.array([2.0, -2.0]), patch)  # the roots at w = 4
    for bump in (0.0, 0.5):
        hom = Parameter(SquareRoots(), 4.0, 9.0 + 0j, patch, bump)
        # the follower goes from t = 1 (w0 = 4, where the starts are) to t = 0 (w1 = 9)
        ends, state, message = follow(hom, start, NEVER)
        assert (state == REGULAR).all() and message == ""
        ratio = ends[:, 0] / ends[:, 1]
        assert np.allclose(sorted(ratio.real), [-3.0, 3.0], atol=1e-9)
        assert np.allclose(ratio.imag, 0.0, atol=1e-9)


def test_every_step_is_watched_and_ends_on_the_path():
    patch = np.array([1.0, 0.5j])
    start = on_patch(np.array([1.0]), patch)
    seen: list[float] = []
    hom = Parameter(SquareRoots(), 1.0, 16.0 + 0j, patch, 0.3)
    ends, state, _ = follow(hom, start, NEVER, watch=lambda paths, x, t: seen.extend(t))
    assert state[0] == REGULAR and seen and seen[-1] == 0.0
    assert all(a > b for a, b in zip(seen, seen[1:], strict=False))
    w = hom.w(np.array(seen))
    assert np.allclose(w[-1], 16.0)
    assert np.isclose(ends[0, 0] / ends[0, 1], 4.0)
