"""Where the curves of a slice turn, by homotopy (for :mod:`.critical_values`).

The curves of a slice in the lengths ``(L_x, L_y)`` are the image, under ``u -> (l_x(u),
l_y(u))``, of the critical set ``C`` of the linkage without bars ``x`` and ``y`` (a space ``S``
of three degrees of freedom): ``C`` is where the full Jacobian ``J(u)`` (E, M) loses rank, a
curve in ``S``. Every compact component of ``C`` holds a maximum of the generic function
``ell = a l_x^2 + b l_y^2``; there ``ell`` is stationary on ``C`` (a turning point of the
slice's curve, where its tangent is normal to ``(a, b)`` in squared lengths, or a cusp, where
the component's tangent is a zero mode of the linkage), or ``C`` is singular there (two
curves cross). All of these solve the square system in the ``M`` unknowns ``u``::

    f_a(u) = 0 (a != x, y),  det [J; c_1] = 0,  det [J; c_2] = 0,
    T(u) = det [ grad f_a (a != x, y); grad det [J; c_1]; grad det [J; c_2]; grad ell ] = 0

(the first ``E`` equations cut ``C``, with extra curves where ``t != 0`` is orthogonal to the
random ``c_1, c_2``, dropped by the rank of ``J``; ``T`` is their Jacobian bordered by
``ell``'s gradient): ``E - 2`` quadrics, two determinants of degree ``E`` and ``T`` of degree
``3 (E - 1)``, so ``2^(E-2) E^2 3 (E - 1)`` paths of the total-degree homotopy of
:mod:`engine.space.homotopy` (108 for the four-bar, 2,400 for the three-rotor). When every path
ended and none jumped, the real critical ends with lengths in the box are every place where a
curve inside the box turns: a closed curve that no scanline of the box meets (smaller than a
sweep step) holds one of them.

The gradients and Hessians of the determinants come from the SVD ``[J; c] = U S V^H``, stable
where ``[J; c]`` is singular (at every solution): with ``H' = U^H H V``, ``d det = ph sum_r
(prod_{k != r} s_k) H'_rr`` and ``d^2 det [H, K] = ph sum_{r != s} (prod_{k != r, s} s_k)
(H'_rr K'_ss - H'_rs K'_sr)``, ``ph = det U det V^H``.

>>> from engine.catalogue.presets import build_preset
>>> lk = build_preset("four-bar", {"L2": 1.2})
>>> found = turning_points(lk, (1, 2), np.array([[0.5, 1.5], [0.5, 1.5]]))
>>> found.success, found.paths
(True, 108)
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from engine.design.slice_scan import (
    CRITICAL_RTOL,
    SINGULAR_RTOL,
    ScanSystem,
    _bounded_without,
    _det_adjugate,
)
from engine.model.budget import NEVER, Deadline
from engine.model.constraints import Constraints
from engine.model.linkage import Linkage
from engine.space.homotopy import REGULAR, SINGULAR, track
from engine.space.witnesses import FAR_REACH, REAL_TOL, SINGULAR_IMAG_TOL, _reach

#: Lengths this far outside the box (relative to its span) still count as in it (a turning
#: point on the box's edge is found by the edge's scanline too).
BOX_MARGIN = 1e-6


@dataclass(frozen=True)
class Turning:
    """The turning points of a slice's curves.

    Attributes
    ----------
    starts : (K, M + E + 2) float
        ``(u, sigma, p)`` at each real critical end with lengths ``p`` in the box (``sigma``
        the self-stress, ``p`` in the slice's axis order).
    paths : int
        Paths of the homotopy (0: not run).
    singular : int
        How many of ``starts`` are singular ends (a crossing of two curves, or a cusp met
        tangentially): refined by the tracing's projection onto the critical set.
    success : bool
        Every path ended, none jumped, the deadline kept, the space without the two bars
        bounded: ``starts`` holds every turning point in the box.
    message : str
    """

    starts: np.ndarray
    paths: int
    singular: int
    success: bool
    message: str


def turning_paths(linkage: Linkage) -> int:
    """The paths of the turning points' homotopy, ``2^(E-2) E^2 3 (E - 1)``."""
    e = Constraints(linkage).n_constraints
    return int(2 ** (e - 2) * e * e * 3 * (e - 1)) if e >= 2 else 0


class TurningSystem:
    """The system of the module docstring in homogeneous, scaled coordinates ``X = (x_0, y)``,
    ``u = centre + scale * y / x_0`` (the quadrics of :class:`engine.design.slice_scan.
    ScanSystem`)."""

    def __init__(self, linkage: Linkage, cons: Constraints, rows: tuple[int, int],
                 rng: np.random.Generator) -> None:
        m, e = cons.n_free, cons.n_constraints
        base = ScanSystem(linkage, cons, rows[1], rows[0], rng.normal(size=(2, m)))
        self.base, self.n, self.e = base, m, e
        self.c = base.c  # (2, M)
        self.others = np.delete(np.arange(e), list(rows))
        self.rows = rows
        ab = rng.random(2) + 0.5  # (the weights of l_x^2 and l_y^2 in ell: generic, positive)
        self.ell = ab[0] * base.quad[rows[0]] + ab[1] * base.quad[rows[1]]  # (M + 1, M + 1)
        # d [J; c] / dX_i (M + 1, M, M): row a of J is 2 Q_a[1:, :] X, the c row is constant
        dirs = np.zeros((m + 1, m, m))
        dirs[:, :e, :] = 2.0 * np.transpose(base.quad[:, 1:, :], (2, 0, 1))
        self.dirs = dirs
        self.degrees = np.array([2] * (e - 2) + [e, e, 3 * (e - 1)], dtype=int)
        eye = np.eye(m, dtype=bool)
        self._one = eye  # (M, M): k == r
        self._two = eye[:, None, :] | eye[None, :, :]  # (M, M, M): k in {r, s}

    def _det_parts(self, jac: np.ndarray, c: np.ndarray
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``det [J; c]`` (N,), its gradient (N, M + 1) and Hessian (N, M + 1, M + 1) in X."""
        p, m = len(jac), self.n
        mat = np.empty((p, m, m), dtype=complex)
        mat[:, :-1] = jac
        mat[:, -1] = c
        u, s, vh = np.linalg.svd(mat)
        phase = np.linalg.det(u) * np.linalg.det(vh)
        one = np.prod(np.where(self._one[None], 1.0, s[:, None, :]), axis=2)  # (N, M)
        two = np.prod(np.where(self._two[None], 1.0, s[:, None, None, :]), axis=3)
        two[:, np.arange(m), np.arange(m)] = 0.0
        # H'_i = U^H B_i V (N, M + 1, M, M)
        h = np.conj(np.transpose(u, (0, 2, 1)))[:, None] @ self.dirs[None] \
            @ np.conj(np.transpose(vh, (0, 2, 1)))[:, None]
        diag = np.diagonal(h, axis1=2, axis2=3)  # (N, M + 1, M)
        det = phase * np.prod(s, axis=1)
        grad = (diag @ one[:, :, None])[:, :, 0]
        flat = (h * two[:, None]).reshape(p, m + 1, m * m)
        swapped = np.transpose(h, (0, 1, 3, 2)).reshape(p, m + 1, m * m)
        hess = diag @ two @ np.transpose(diag, (0, 2, 1)) \
            - flat @ np.transpose(swapped, (0, 2, 1))
        grad = phase[:, None] * grad
        return det, grad, phase[:, None, None] * hess

    def __call__(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Values (N, M) and Jacobians (N, M, M + 1) at ``x`` (N, M + 1)."""
        b = self.base
        p, m, e = len(x), self.n, self.e
        grads = 2.0 * (b._rows @ x.T).T.reshape(p, e, m + 1)  # (N, E, M + 1)
        others = grads[:, self.others]
        values = np.empty((p, m), dtype=complex)
        jac = np.empty((p, m, m + 1), dtype=complex)
        values[:, :e - 2] = 0.5 * (others @ x[:, :, None])[:, :, 0]
        jac[:, :e - 2] = others
        amat = np.empty((p, m, m), dtype=complex)  # the bordered Jacobian whose det is T
        damat = np.empty((p, m, m, m + 1), dtype=complex)  # d amat / dX
        amat[:, :e - 2] = others[:, :, 1:]
        damat[:, :e - 2] = 2.0 * b.quad[self.others][None, :, 1:, :]
        for k in range(2):
            det, grad, hess = self._det_parts(grads[:, :, 1:], self.c[k])
            values[:, e - 2 + k] = det
            jac[:, e - 2 + k] = grad
            amat[:, e - 2 + k] = grad[:, 1:]
            damat[:, e - 2 + k] = hess[:, 1:, :]
        amat[:, -1] = 2.0 * x @ self.ell[1:, :].T
        damat[:, -1] = 2.0 * self.ell[None, 1:, :]
        det_t, adj = _det_adjugate(amat)
        values[:, -1] = det_t
        # dT / dX_i = sum_{r, j} adj[j, r] d amat[r, j] / dX_i
        jac[:, -1] = (np.transpose(adj, (0, 2, 1)).reshape(p, 1, m * m)
                      @ damat.reshape(p, m * m, m + 1))[:, 0]
        return values, jac


def turning_points(linkage: Linkage, bars: tuple[int, int], box: np.ndarray, seed: int = 0,
                   deadline: Deadline = NEVER) -> Turning:
    """Every turning point (and cusp, and crossing) of the curves of the slice of ``bars``
    (linkage bar indices, the slice's axis order) over ``box`` (2, 2): see the module
    docstring."""
    lengths = np.array(linkage.lengths, dtype=float)
    lengths[list(bars)] = box[:, 1]  # (the reach bounds every configuration in the box)
    at = linkage.with_lengths(lengths)
    cons = Constraints(at)
    m, e = cons.n_free, cons.n_constraints
    empty = np.zeros((0, m + e + 2))
    act = [int(b) for b in cons.bars]
    if m - e != 1 or any(b not in act for b in bars):
        return Turning(empty, 0, 0, False, "needs M - E = 1 and both bars active")
    rows = (act.index(bars[0]), act.index(bars[1]))
    if not _bounded_without(at, cons, []):  # (the configurations with lengths in the box)
        return Turning(empty, 0, 0, False, "a piece of the linkage holds no pinned vertex")
    rng = np.random.default_rng(seed)
    system = TurningSystem(at, cons, rows, rng)
    reach = _reach(at, cons, system.base.scale)
    res = track(system, system.degrees, rng, deadline, far=FAR_REACH * reach)
    done = np.isin(res.state, (REGULAR, SINGULAR))
    ends, loose = res.ends[done], (res.state == SINGULAR)[done]
    starts, singular = _critical_in_box(at, cons, system, ends, loose, bars, box, reach)
    return Turning(starts, len(res.ends), singular, res.success, res.message)


def _critical_in_box(at: Linkage, cons: Constraints, system: TurningSystem, ends: np.ndarray,
                     loose: np.ndarray, bars: tuple[int, int], box: np.ndarray, reach: float
                     ) -> tuple[np.ndarray, int]:
    """``(u, sigma, p)`` of the ends (N, M + 1) that are real (``loose``: singular ends, within
    ``SINGULAR_IMAG_TOL``), in reach, critical (``J`` loses rank) and with lengths in the box;
    and how many of them are singular ends."""
    m, e = cons.n_free, cons.n_constraints
    sys_ = system.base
    x0 = ends[:, 0]
    y = ends[:, 1:] / np.where(np.abs(x0) > 0, x0, np.inf)[:, None]
    size = np.linalg.norm(y, axis=1)
    near = np.isfinite(size) & (size <= reach) & (np.abs(x0) > 0)
    imag = np.linalg.norm(y.imag, axis=1) / np.maximum(size, 1.0)
    real = near & (imag <= np.where(loose, SINGULAR_IMAG_TOL, REAL_TOL))
    margin = BOX_MARGIN * (box[:, 1] - box[:, 0])
    starts, singular = [], 0
    for k in np.flatnonzero(real):
        u = sys_.centre + sys_.scale * y[k].real
        jac = cons.jacobian(u, sparse=False)  # (E, M)
        left, sv, _ = np.linalg.svd(jac)
        if sv[-1] > (SINGULAR_RTOL if loose[k] else CRITICAL_RTOL) * max(sv[0], 1e-300):
            continue  # t != 0: an extra solution, not critical
        pos = at.positions_of(u)
        p = np.array([float(np.linalg.norm(np.subtract(*pos[at.ends[b]]))) for b in bars])
        if np.any(p < box[:, 0] - margin) or np.any(p > box[:, 1] + margin):
            continue
        starts.append(np.concatenate([u, left[:, -1], p]))
        singular += int(loose[k])
    return np.array(starts, dtype=float).reshape(-1, m + e + 2), singular


@dataclass(frozen=True)
class TurningFound:
    """The turning points of a slice's curves (:mod:`.slice_turning`) and how many of those in
    the box lie on a traced curve (``found`` None: the homotopy was not run, ``why``)."""

    paths: int
    found: Turning | None
    on_curves: int
    why: str

    @property
    def complete(self) -> bool:
        """Every path ended and every turning point in the box is on a traced curve."""
        return self.found is not None and self.found.success and \
            self.on_curves == len(self.found.starts)

    def details(self) -> dict[str, object]:
        """The report's keys: ``turning_paths`` (0: not run), ``turning_points`` (in the box),
        ``turning_points_traced`` (on a traced curve), ``turning_complete``."""
        n = 0 if self.found is None else len(self.found.starts)
        return {"turning_paths": self.paths if self.found is not None else 0,
                "turning_points": n, "turning_points_traced": self.on_curves,
                "turning_complete": self.complete}

    def summary(self) -> str:
        """What the turning points prove, in a sentence."""
        if self.found is None:
            return f"the turning points were not solved for ({self.why})"
        if not self.found.success:
            return f"the turning points' {self.paths}-path homotopy: {self.found.message}"
        n = len(self.found.starts)
        return (f"every turning point, cusp and crossing of a curve in the box (the "
                f"{self.paths}-path total-degree homotopy of the critical set bordered by a "
                f"generic combination of the two squared lengths, every path ended, none "
                f"jumped): {n} in the box, {self.on_curves} of them on a traced curve")
