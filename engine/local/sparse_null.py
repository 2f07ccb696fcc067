"""The sparse first-order method (for :mod:`engine.local.rigidity`): the null spaces of a large
sparse ``J`` (E_a, M) by deflated shift-invert Lanczos (``eigsh``) on the symmetric augmented
matrix ``[[0, J], [J^T, 0]]``, whose eigenvalues are ``+-s_i`` (the singular values of ``J``)
plus ``|M - E_a|`` zeros, completed by block inverse iteration, and the smallest nonzero
singular value with its error bound.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from engine.model.budget import NEVER, Deadline, OutOfTime
from engine.model.errors import NumericalFailure


def _sparse_null_spaces(
    jac: sp.csr_matrix, rtol: float, deadline: Deadline = NEVER,
    max_nullity: int | None = None,
) -> tuple[int, np.ndarray, np.ndarray, np.ndarray]:
    """As :func:`_dense_null_spaces`, by deflated shift-invert Lanczos on the augmented matrix.

    The shift ``-1e-12 s_max`` sits far closer to the zero eigenvalues than to any eigenvalue
    above the threshold ``rtol * s_max``, so null vectors always come first. Lanczos can miss
    copies of a repeated eigenvalue, so the search is repeated on the operator with the vectors
    found so far projected out (deflation) until the nearest remaining eigenvalue lies above the
    threshold, and then completed by block inverse iteration (:func:`_complete_null_space`),
    which also finds copies that every Lanczos round missed. Raises :class:`NumericalFailure`
    when the counts are inconsistent, and :class:`~engine.model.budget.OutOfTime` when
    ``deadline`` passes during the Lanczos rounds (each operator application checks it: on a
    100-rotor chain of parallelograms one ``eigsh`` took 1.5 s, past a search's deadline).
    ``max_nullity`` (default :data:`SPARSE_MAX_NULLITY`): more null vectors than that raise
    :class:`NumericalFailure` as soon as they are found (the caller's dense SVD is then faster:
    block inverse iteration costs ``O((E + M) k^2)`` a step for ``k`` null vectors).
    """
    most = SPARSE_MAX_NULLITY if max_nullity is None else min(max_nullity, SPARSE_MAX_NULLITY)
    ea, m = jac.shape
    n = ea + m
    if jac.nnz == 0 or not np.any(jac.data):
        return 0, np.zeros(min(ea, m)), np.eye(m), np.eye(ea)
    aug = sp.bmat([[None, jac], [jac.T, None]], format="csc")
    rng = np.random.default_rng(0)
    s_max = _largest_singular_value(jac, rng)
    thresh = rtol * s_max
    lu = None
    for factor in (1e-12, 3.7e-12, 1.3e-11):
        try:
            shift = -factor * s_max
            lu = spla.splu((aug - shift * sp.identity(n, format="csc")).tocsc())
            break
        except RuntimeError:  # the shift hit an eigenvalue exactly: move it
            continue
    if lu is None:
        raise NumericalFailure("sparse LU of the shifted augmented matrix failed")
    found = np.zeros((n, 0))
    others: list[np.ndarray] = []  # Ritz vectors of eigenvalues above the threshold
    k = min(n - 2, abs(m - ea) + 8)
    for _ in range(64):
        basis = found

        def apply(x: np.ndarray, basis: np.ndarray = basis) -> np.ndarray:
            if deadline.expired():
                raise OutOfTime("the sparse null space ran past the deadline")
            if basis.shape[1]:
                x = x - basis @ (basis.T @ x)
            y = lu.solve(x)
            if basis.shape[1]:
                y = y - basis @ (basis.T @ y)
            return y

        op = spla.LinearOperator((n, n), matvec=apply, dtype=float)
        k_round = max(1, min(k, n - basis.shape[1] - 2))
        try:
            mu, vecs = spla.eigsh(op, k=k_round, which="LM", tol=1e-12, v0=rng.normal(size=n))
        except spla.ArpackError as err:  # ArpackNoConvergence included: no answer to form
            raise NumericalFailure(f"Lanczos did not converge: {err}") from err
        lam = shift + 1.0 / mu
        null = np.abs(lam) <= thresh
        if null.any():
            new = vecs[:, null]
            new = new - found @ (found.T @ new)
            q, r = np.linalg.qr(new)
            keep = np.abs(np.diag(r)) > 1e-6
            found = np.hstack([found, q[:, keep]])
            if found.shape[1] > most:
                raise NumericalFailure(f"null space larger than {most} for the sparse search")
        others.append(vecs[:, ~null])
        if not null.all():
            break  # the nearest remaining eigenvalue is above the threshold
        # every Ritz value null: the null space may be large. Lanczos converges badly on a
        # cluster of that many equal eigenvalues (a straight 150-rotor chain, 450 null vectors:
        # 22 s with k doubled each round), block inverse iteration well: it completes the null
        # space, and the next round, with all of it deflated, finds the nearest others
        found = _complete_null_space(aug, lu, found, thresh, rng, deadline=deadline,
                                     most=most)
    else:
        raise NumericalFailure("sparse null-space search did not terminate")
    found = _complete_null_space(aug, lu, found, thresh, rng, deadline=deadline,
                                     most=most)
    for _ in range(2):  # polish: block inverse iteration damps other directions by >= 1e-4 a step
        if found.shape[1]:
            found = np.linalg.qr(lu.solve(found))[0]
    if deadline.expired():
        raise OutOfTime("the sparse null space ran past the deadline")
    small = _smallest_nonzero(aug, lu, found, np.hstack(others), s_max, rng)
    left, right = _span_rows(found[:ea].T), _span_rows(found[ea:].T)
    rank = m - right.shape[0]
    if right.shape[0] - left.shape[0] != m - ea or rank > min(ea, m) or rank < 0:
        raise NumericalFailure(
            f"inconsistent sparse null spaces ({right.shape[0]} right, {left.shape[0]} left)"
        )
    zero_sv = np.linalg.norm(jac.T @ left.T, axis=0) if left.shape[0] else np.zeros(0)
    svals = np.concatenate([[s_max], np.sort(small)[::-1], np.sort(zero_sv)[::-1]])
    return rank, svals, right, left


#: A smallest nonzero singular value is reported only when its error bound (see
#: :func:`_smallest_nonzero`) is below this fraction of ``s_max``.
SMALL_SV_RESIDUAL_RTOL = 1e-9


def _smallest_nonzero(
    aug: sp.csc_matrix,
    lu: spla.SuperLU,
    found: np.ndarray,
    start: np.ndarray,
    s_max: float,
    rng: np.random.Generator,
    steps: int = 8,
) -> list[float]:
    """The smallest nonzero singular values of ``J`` that can be certified, from the Lanczos
    Ritz vectors ``start`` (n, k) of eigenvalues above the threshold.

    Those Ritz vectors can be poor when the null space is large: the null directions dominate
    the Krylov space by ~1e12 and swamp the rest (a random linkage with 62 zero modes gave
    0.0206 for a singular value of 0.0215). So they are refined by block inverse iteration
    with the null space projected out, followed by Rayleigh-Ritz, until every Ritz value is
    certified (or ``steps`` run out), and only certified values are reported: a Ritz value
    ``theta`` with residual ``r`` lies within ``r`` of an eigenvalue, and within ``r^2 / gap``
    when the rest of the spectrum is ``gap`` away (estimated by the other Ritz values);
    certified means ``r <= tol`` or ``r <= 1e3 tol`` and ``r^2 / gap <= tol``, with
    ``tol = SMALL_SV_RESIDUAL_RTOL * s_max``. Each negative Ritz value ``-s`` of the augmented
    matrix is one singular value ``s``.
    """
    n = aug.shape[0]
    if start.shape[1] == 0 or n - found.shape[1] < 2:
        return []
    limit = SMALL_SV_RESIDUAL_RTOL * s_max
    ok = np.zeros(0, dtype=bool)
    theta = np.zeros(0)
    for step in range(steps + 1):
        if step == 0:
            q, r = np.linalg.qr(_deflate(start, found))
            x = q[:, np.abs(np.diag(r)) > 1e-6 * np.abs(np.diag(r)).max()]
        else:
            x = np.linalg.qr(_deflate(_deflate(lu.solve(x), found), found))[0]
        ax = aug @ x
        h = x.T @ ax
        theta, w = np.linalg.eigh(0.5 * (h + h.T))
        res = np.linalg.norm(ax @ w - (x @ w) * theta, axis=0)
        # |theta - lambda| <= res always, and <= res^2 / gap with gap the distance to the rest
        # of the spectrum (estimated by the other Ritz values)
        gap = np.array([np.min(np.abs(np.delete(theta, i) - t)) if len(theta) > 1 else np.inf
                        for i, t in enumerate(theta)])
        ok = (res <= limit) | ((res <= 1e3 * limit) & (res**2 <= limit * gap))
        if ok.all():
            break
        extra = min(8, n - found.shape[1] - x.shape[1])
        if step == 0 and extra > 0:  # a wider block converges faster
            x = np.hstack([x, _deflate(rng.normal(size=(n, extra)), found)])
    return [float(-t) for t, good in zip(theta, ok, strict=True) if t < 0 and good]


#: Largest null space the sparse search handles (the block vectors are dense, (E_a + M, k)).
SPARSE_MAX_NULLITY = 2000


def _deflate(x: np.ndarray, basis: np.ndarray) -> np.ndarray:
    """``x`` with the span of the orthonormal columns of ``basis`` projected out."""
    return x - basis @ (basis.T @ x) if basis.shape[1] else x


def _complete_null_space(
    aug: sp.csc_matrix,
    lu: spla.SuperLU,
    found: np.ndarray,
    thresh: float,
    rng: np.random.Generator,
    block: int = 8,
    steps: int = 3,
    deadline: Deadline = NEVER,
    most: int = SPARSE_MAX_NULLITY,
) -> np.ndarray:
    """Add the null vectors of ``aug`` that the Lanczos rounds missed to ``found`` (n, k).

    Lanczos from one start vector sees a repeated eigenvalue once in exact arithmetic, and the
    rounds stop at the first eigenvalue above the threshold even when copies of 0 are still
    missing (a straight chain of 80 free vertices: 73 of 81 found). Block inverse iteration has
    no such blind spot: a random block, with ``found`` projected out, is multiplied ``steps``
    times by the shifted inverse, which enlarges every remaining null direction against all
    others by at least ``s / (thresh + |shift|)`` per step, and Rayleigh-Ritz then exposes them.
    A block that comes back all null may hide more: it doubles and the check is repeated until
    it finds none.
    """
    n = aug.shape[0]
    while True:
        if deadline.expired():
            raise OutOfTime("the sparse null space's completion ran past the deadline")
        p = min(block, n - found.shape[1])
        if p <= 0:
            return found
        # one round: about 2 + 2 steps deflations (4 n k p flops each) and QRs (2 n p^2)
        seconds = BLOCK_SECONDS_PER_FLOP * (2 * steps + 2) * n * p * (4 * found.shape[1] + 2 * p)
        if seconds > deadline.remaining():
            raise OutOfTime(f"a round of the sparse null space's completion ({found.shape[1]} "
                            f"null vectors found, a block of {p}) would take about "
                            f"{seconds:.1f} s, more than the {deadline.remaining():.1f} s left")

        x = np.linalg.qr(_deflate(rng.normal(size=(n, p)), found))[0]
        for _ in range(steps):
            # twice: the solve enlarges rounding-level components along ``found`` by 1e12
            x = np.linalg.qr(_deflate(_deflate(lu.solve(x), found), found))[0]
        h = x.T @ (aug @ x)
        theta, w = np.linalg.eigh(0.5 * (h + h.T))
        null = np.abs(theta) <= thresh
        if not null.any():
            return found
        new = _deflate(x @ w[:, null], found)
        q, r = np.linalg.qr(new)
        found = np.hstack([found, q[:, np.abs(np.diag(r)) > 1e-6]])
        if found.shape[1] > most:
            raise NumericalFailure(f"null space larger than {most} for the sparse search")
        if null.all():
            block *= 2


#: Seconds per floating-point operation of the dense block algebra, for the estimate of a round
#: of :func:`_complete_null_space` before it starts (4 GFLOP/s: one core of a loaded machine;
#: measured 3 to 10).
BLOCK_SECONDS_PER_FLOP = 2.5e-10


def _largest_singular_value(jac: sp.csr_matrix, rng: np.random.Generator, steps: int = 60) -> float:
    """``s_max`` of ``J`` by power iteration on ``J^T J`` (to about a percent: it only scales the
    rank threshold). Lanczos is no faster here: the top of a chain's spectrum is clustered."""
    x = rng.normal(size=jac.shape[1])
    x /= np.linalg.norm(x)
    est = 0.0
    for _ in range(steps):
        y = jac.T @ (jac @ x)
        norm = float(np.linalg.norm(y))
        if norm == 0.0:
            return 0.0
        x = y / norm
        est = norm
    return float(np.sqrt(est))


def _span_rows(rows: np.ndarray) -> np.ndarray:
    """Orthonormal basis of the row span of ``rows`` (rows that are numerically present)."""
    if rows.shape[0] == 0:
        return rows
    _, s, vt = np.linalg.svd(rows, full_matrices=False)
    return vt[s > 0.5]
