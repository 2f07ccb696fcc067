"""The projection's Gauss-Newton step (:func:`min_norm_step`), and sparse damped least squares
(LSMR) within a deadline.

On large linkages the step is an LSMR solve with an iteration limit of ``20 (E + M)``, each
iteration O(E + M): seconds from a few hundred rotors on, and no way to look at a deadline
inside one call. :func:`lsmr_within` runs such a solve in one call where its limit fits the
time left, else in pieces, the deadline looked at between them.

>>> import scipy.sparse as sp
>>> x = lsmr_within(sp.identity(3, format="csr"), np.ones(3), damp=0.0, limit=10)
>>> np.allclose(x, 1.0)
True
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from engine.model.budget import NEVER, Deadline

#: What one LSMR iteration is taken to cost at least: seconds per iteration and per stored value
#: of the matrix or unknown (measured: 3.3e-4 s an iteration at E + M = 1600, 3200 values).
LSMR_SECONDS_PER_ITERATION = 1e-4
LSMR_SECONDS_PER_VALUE = 5e-8
#: Seconds a piece of iterations takes at that rate, where the solve runs in pieces.
LSMR_PIECE_S = 0.05


def lsmr_within(
    a: sp.csr_matrix, b: np.ndarray, damp: float, limit: int, deadline: Deadline = NEVER,
    tol: float = 1e-14,
) -> np.ndarray | None:
    """``lsmr(a, b, damp, atol=btol=tol, maxiter=limit)[0]``, or None when ``deadline`` passed
    first. Where ``limit`` iterations could outlast the deadline at the rates above, the solve
    runs in pieces of about :data:`LSMR_PIECE_S`, each continuing from the last one's solution
    (the damping then applies to each piece's correction: a damped least-squares solution
    still, no longer the minimum-norm one)."""
    per = LSMR_SECONDS_PER_ITERATION + LSMR_SECONDS_PER_VALUE * (a.nnz + sum(a.shape))
    if limit * per <= deadline.remaining():
        return spla.lsmr(a, b, damp=damp, atol=tol, btol=tol, maxiter=limit)[0]
    x = np.zeros(a.shape[1])
    done = 0
    while done < limit:
        if deadline.expired():
            return None
        x, istop, itn = spla.lsmr(a, b, damp=damp, atol=tol, btol=tol, x0=x,
                                  maxiter=min(max(1, int(LSMR_PIECE_S / per)), limit - done))[:3]
        done += max(int(itn), 1)
        if istop != 7:  # (7: the piece's iteration limit)
            break
    return x


#: Singular values below this fraction of the largest are left out of Gauss-Newton steps: near a
#: critical configuration they would turn the step into a huge move along a near-null direction.
STEP_RCOND = 1e-7


def min_norm_step(
    jac: np.ndarray | sp.csr_matrix, rhs: np.ndarray, rcond: float = STEP_RCOND,
    deadline: Deadline = NEVER,
) -> np.ndarray | None:
    """Minimum-norm least-squares solution of ``J du = rhs`` with small singular values cut
    (dense: truncated SVD; sparse: LSMR with a matching Tikhonov damping, in pieces where it
    could outlast ``deadline``: :func:`lsmr_within`); None when ``deadline``
    passed first."""
    if sp.issparse(jac):
        scale = float(np.sqrt(abs(jac).sum(axis=0).max() * abs(jac).sum(axis=1).max()))
        return lsmr_within(sp.csr_matrix(jac), rhs, rcond * scale, 20 * sum(jac.shape),
                           deadline)
    return np.linalg.lstsq(jac, rhs, rcond=rcond)[0]
