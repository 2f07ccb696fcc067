"""A linear-product start system: fewer homotopy paths for systems with a multihomogeneous
structure.

The variables ``x = (x_1 .. x_n)`` of a square system are split into groups ``x = (x^1 .. x^m)``
of sizes ``n_1 .. n_m``; equation ``e`` has, in group ``g``, degree ``d_{e,g}`` (the Lagrange
system of a height, :mod:`engine.space.surfaces.morse`: the bars ``f_a(u)`` have degrees
``(2, 0)`` in ``(u, lambda)``, the equations ``c - J(u)^T lambda`` degrees ``(1, 1)``). The start
system replaces equation ``e`` by a product of ``sum_g d_{e,g}`` random complex affine forms,
``d_{e,g}`` of them in group ``g`` alone::

    G_e(x) = prod_k (a_{e,k,0} + a_{e,k} . x^{g(e,k)})

Its solutions pick one factor per equation; the picked forms split into ``m`` independent linear
systems, and a pick has a solution (exactly one, for random forms) when group ``g`` receives
exactly ``n_g`` factors. Their number is the multihomogeneous Bezout number: the coefficient of
``prod_g z_g^{n_g}`` in ``prod_e sum_g d_{e,g} z_g`` (Morgan and Sommese, *A homotopy for
solving general polynomial systems that respects m-homogeneous structures*, Appl. Math. Comput.
24, 1987; Sommese and Wampler, *The Numerical Solution of Systems of Polynomials*, 2005,
Sec. 8.4.3). With the gamma trick, ``H = (1 - t) F + t gamma G`` from these solutions reaches
every isolated solution of ``F`` in ``C^n`` whenever each ``F_e`` lies in the span of the
products of its factors' groups (Sommese and Wampler, Thm. 8.4.7): for the Lagrange system of a
``D = 2`` pentagon that is ``2^4 C(6, 4) = 240`` paths instead of ``2^10 = 1024``.

:func:`engine.space.homotopy.track` tracks the paths in homogeneous coordinates ``X = (x_0,
x)`` (one patch of ``P^n``); ``G`` is homogenised with ``x_0`` to the same total degree as ``F``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from engine.model.errors import NumericalFailure

#: Name of this start in search reports (the other: ``"total degree"``).
NAME = "linear product"


@dataclass(frozen=True)
class Structure:
    """A multihomogeneous structure of a square system in ``n`` affine variables.

    Attributes
    ----------
    groups : tuple of (n_g,) int arrays
        Each group's variables, as indices ``1 .. n`` into ``X = (x_0, x)``; a partition.
    degrees : (n, m) int
        ``degrees[e, g]``: the degree of equation ``e`` in group ``g``.
    """

    groups: tuple[np.ndarray, ...]
    degrees: np.ndarray

    @property
    def n(self) -> int:
        return int(sum(len(g) for g in self.groups))


def bezout(structure: Structure) -> int:
    """The multihomogeneous Bezout number of ``structure``: the number of picks of one factor
    per equation that give each group as many factors as it has variables (a count over the
    partial picks, one equation at a time: states are the factors given to each group)."""
    sizes = tuple(len(g) for g in structure.groups)
    states: dict[tuple[int, ...], int] = {tuple(0 for _ in sizes): 1}
    for row in np.asarray(structure.degrees, dtype=int):
        nxt: dict[tuple[int, ...], int] = {}
        for state, count in states.items():
            for g, d in enumerate(row):
                if d <= 0 or state[g] >= sizes[g]:
                    continue
                key = state[:g] + (state[g] + 1,) + state[g + 1:]
                nxt[key] = nxt.get(key, 0) + count * int(d)
        states = nxt
    return states.get(sizes, 0)


class LinearProduct:
    """The start system of ``structure`` with random complex factors drawn from ``rng``.

    ``forms`` (n, k_max, n + 1): factor ``k`` of equation ``e`` as a linear form in ``X``
    (``x_0`` and its group's variables); ``used`` (n, k_max) marks real factors (an equation of
    total degree below ``k_max`` is padded with the constant 1, then multiplied by ``x_0`` up to
    ``total`` so that ``G_e`` is homogeneous of the target's degree).

    Examples
    --------
    Two groups of one variable each, an equation of degrees (1, 1) and one of (2, 0): the
    total degree is 4, the linear product has 2 solutions.

    >>> s = Structure((np.array([1]), np.array([2])), np.array([[1, 1], [2, 0]]))
    >>> lp = LinearProduct(s, np.array([2, 2]), np.random.default_rng(0))
    >>> bezout(s), len(lp.solutions())
    (2, 2)
    """

    def __init__(self, structure: Structure, total: np.ndarray, rng: np.random.Generator
                 ) -> None:
        self.structure = structure
        n = structure.n
        deg = np.asarray(structure.degrees, dtype=int)
        self.total = np.asarray(total, dtype=int)
        per_eq = deg.sum(axis=1)
        if (per_eq > self.total).any():
            raise NumericalFailure("a factor count exceeds its equation's total degree")
        kmax = int(per_eq.max())
        self.forms = np.zeros((n, kmax, n + 1), dtype=complex)
        self.group = np.full((n, kmax), -1, dtype=int)
        for e in range(n):
            k = 0
            for g, d in enumerate(deg[e]):
                cols = np.concatenate([[0], structure.groups[g]])
                for _ in range(int(d)):
                    self.forms[e, k, cols] = rng.normal(size=len(cols)) \
                        + 1j * rng.normal(size=len(cols))
                    self.group[e, k] = g
                    k += 1
        self.used = self.group >= 0
        self._rows = self.forms.reshape(n * kmax, n + 1)
        self.pad = self.total - per_eq  # powers of x_0

    @property
    def paths(self) -> int:
        return bezout(self.structure)

    def __call__(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``G`` (N, n) and ``G_X`` (N, n, n + 1) at ``x`` (N, n + 1)."""
        n, kmax, width = self.forms.shape
        lin = (x @ self._rows.T).reshape(len(x), n, kmax)  # every factor's value
        lin = np.where(self.used[None], lin, 1.0)
        # products of the other factors, from prefix and suffix products (no division)
        ones = np.ones((len(x), n, 1), dtype=complex)
        left = np.concatenate([ones, np.cumprod(lin[:, :, :-1], axis=2)], axis=2)
        right = np.concatenate([np.cumprod(lin[:, :, :0:-1], axis=2)[:, :, ::-1], ones], axis=2)
        others = np.where(self.used[None], left * right, 0.0)  # (N, n, k_max)
        full = left[:, :, -1] * lin[:, :, -1]
        x0 = x[:, :1]
        scale = x0 ** self.pad[None]  # (N, n)
        # (n, N, k_max) @ (n, k_max, n + 1): each equation's gradient, batched over equations
        jac = np.matmul(others.transpose(1, 0, 2), self.forms).transpose(1, 0, 2)
        jac = jac * scale[:, :, None]
        dpad = self.pad[None] * x0 ** np.maximum(self.pad[None] - 1, 0)
        jac[:, :, 0] += full * dpad
        return full * scale, jac

    def solutions(self) -> np.ndarray:
        """Every solution ``(1, x)`` of ``G = 0`` in ``C^n`` (bezout, n + 1): one per pick of a
        factor per equation that gives each group as many factors as it has variables."""
        st = self.structure
        sizes = [len(g) for g in st.groups]
        choices = [np.flatnonzero(self.used[e]) for e in range(st.n)]
        out = []
        for pick in _picks(self.group, choices, sizes):
            x = np.zeros(st.n + 1, dtype=complex)
            x[0] = 1.0
            rows = self.forms[np.arange(st.n), pick]  # (n, n + 1)
            gp = self.group[np.arange(st.n), pick]
            for g, cols in enumerate(st.groups):
                a = rows[gp == g]
                try:
                    x[cols] = np.linalg.solve(a[:, cols], -a[:, 0])
                except np.linalg.LinAlgError as err:  # (random forms: probability zero)
                    raise NumericalFailure("a singular start system: draw it again") from err
            out.append(x)
        return np.asarray(out).reshape(-1, st.n + 1)


def _picks(group: np.ndarray, choices: list[np.ndarray], sizes: list[int]):
    """Picks (one factor index per equation) giving group ``g`` exactly ``sizes[g]`` factors:
    a depth-first walk that drops a partial pick as soon as a group is over-full (the groups'
    sizes add up to the equations, so a full pick that over-fills none fills each exactly)."""
    n = len(choices)
    pick = np.zeros(n, dtype=int)
    count = [0] * len(sizes)

    def walk(e: int):
        if e == n:
            yield pick.copy()
            return
        for k in choices[e]:
            g = int(group[e, k])
            if count[g] >= sizes[g]:
                continue
            count[g] += 1
            pick[e] = k
            yield from walk(e + 1)
            count[g] -= 1

    yield from walk(0)


def total_degree_paths(total: np.ndarray) -> int:
    """``prod d_e``: the total-degree start's path count (exact integer)."""
    out = 1
    for d in np.asarray(total, dtype=int):
        out *= int(d)
    return out


