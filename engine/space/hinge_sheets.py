"""Hinged rotor chains none of whose cells turns in its outer angle: the count of
:func:`hinge_count` and the sheets (one per choice of branch in every cell, each a graph over
``theta_0``) that :mod:`engine.space.configuration_space.hinge` samples in closed form. The
chains and their cells are those of :mod:`engine.space.hinge_chain`.
"""

from __future__ import annotations

import numpy as np

from engine.model.linkage import Linkage
from engine.space.chain_count import ChainCount
from engine.space.hinge_chain import HingeChain, folds, hinge_chain, solve_next


def angles_of(chain: HingeChain, tips: np.ndarray) -> np.ndarray:
    """Rotor angles (..., n) of tip positions (..., n, 3) on the hinge circles."""
    rel = tips - chain.centres
    return np.arctan2(np.einsum("...ki,ki->...k", rel, chain.frames[:, 1]),
                      np.einsum("...ki,ki->...k", rel, chain.frames[:, 0]))


def sheet_of(chain: HingeChain, theta: np.ndarray) -> np.ndarray:
    """The branch (n - 1,) of each cell at angles ``theta`` (n,): 0 for ``base + spread``, 1 for
    ``base - spread`` (:func:`solve_next`), whichever is nearer ``theta_(k+1)``."""
    bits = np.zeros(chain.n - 1, dtype=int)
    for k in range(chain.n - 1):
        nxt, _ = solve_next(chain.cells[k], theta[k:k + 1])
        bits[k] = int(np.argmin(np.abs(np.angle(np.exp(1j * (nxt[0] - theta[k + 1]))))))
    return bits


def sheets(chain: HingeChain, bits: np.ndarray, theta0: np.ndarray) -> np.ndarray:
    """Angles (S, K, n) of the sheets with branches ``bits`` (S, n - 1) over ``theta0`` (K,)
    (NaN where a sheet does not exist)."""
    s_count = len(bits)
    rows = np.empty((s_count, len(theta0), chain.n))
    rows[:, :, 0] = theta0
    for k in range(chain.n - 1):
        nxt, ok = solve_next(chain.cells[k], rows[:, :, k].ravel())
        pick = np.repeat(bits[:, k], len(theta0))
        val = nxt[np.arange(len(pick)), pick]
        rows[:, :, k + 1] = np.where(ok[np.arange(len(pick)), pick], val, np.nan).reshape(
            s_count, -1)
    return rows


def hinge_count(linkage: Linkage) -> ChainCount | None:
    """The exact number of components of a hinged rotor chain none of whose cells turns in its
    outer angle (no ``b``-fold: every fold polynomial in ``theta_k`` has no real root), else
    None. Each cell's relation is then two disjoint graphs over ``theta_k`` at every angle (or
    none at all), so every choice of one graph per cell is one component, a graph over
    ``theta_0``: ``2^(n-1)`` (0 where a cell never closes); and since a critical point needs
    some ``b_j = 0``, there is none.

    Examples
    --------
    >>> from engine.catalogue.presets import build_preset
    >>> hinge_count(build_preset("rotor-chain-3d", {"n": 5})).components
    16
    """
    chain = hinge_chain(linkage)
    if chain is None:
        return None
    for m in chain.cells:
        pts = folds(m, "b")
        if pts is None or len(pts):
            return None
    theta = np.zeros(1)
    closes = True
    for m in chain.cells:
        nxt, ok = solve_next(m, theta)
        if not ok[0, 0]:
            closes = False
            break
        theta = nxt[:, 0]
    bars = linkage.bar_ids
    rotors = tuple(bars[int(np.flatnonzero((np.asarray(linkage.ends) == t).any(axis=1))[0])]
                   for t in chain.tips)
    return ChainCount(2 ** (chain.n - 1) if closes else 0, rotors, 0, HINGE_RULE)


#: The rule of :func:`hinge_count`, as the answers name it.
HINGE_RULE = ("3D hinged rotor chain, no cell turns in its outer angle (the fold polynomials "
              "in theta_k have no real root): each choice of one branch per cell is one "
              "component, a graph over theta_0")
