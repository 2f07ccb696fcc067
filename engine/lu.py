"""One LU factorisation (dense or sparse) with solves and the sign of the determinant.

Used wherever the engine needs ``det([row; J])``: the tangent form (its sign is the
orientation) and the tracer (a sign change between neighbours flags a branch jump or a crossed
critical point).
"""

from __future__ import annotations

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla


def parity(perm: np.ndarray) -> int:
    """+1 for an even permutation, -1 for an odd one (``n - cycles`` transpositions).

    Cycles are counted without a Python loop over the entries (sparse LU permutations have
    tens of thousands): after ``k`` rounds of pointer doubling, ``label[i]`` is the smallest
    index among ``i, perm(i), ..., perm^(2^k - 1)(i)``, so after ``ceil(log2 n)`` rounds it is
    the smallest index of the cycle through ``i`` and each cycle has one entry with
    ``label[i] == i``.
    """
    perm = np.asarray(perm, dtype=np.intp)
    n = len(perm)
    label = np.arange(n)
    jump = perm.copy()
    span = 1
    while span < n:
        label = np.minimum(label, label[jump])
        jump = jump[jump]
        span *= 2
    cycles = int(np.count_nonzero(label == np.arange(n)))
    return -1 if (n - cycles) % 2 else 1


class Factor:
    """LU of a square matrix; ``ok`` is False when it is singular (or the factorisation
    failed), then ``sign`` is 0 and ``logdet`` is ``-inf``. ``logdet`` is ``ln |det|``."""

    def __init__(self, mat: np.ndarray | sp.spmatrix) -> None:
        self.sparse = sp.issparse(mat)
        self.ok = True
        self.sign = 0
        self.logdet = -np.inf
        try:
            if self.sparse:
                self._lu = spla.splu(sp.csc_matrix(mat))
                diag = self._lu.U.diagonal()
                perm = parity(self._lu.perm_r) * parity(self._lu.perm_c)
            else:
                self._lu_piv = sla.lu_factor(mat, check_finite=False)
                diag = np.diag(self._lu_piv[0])
                perm = -1 if np.sum(self._lu_piv[1] != np.arange(len(diag))) % 2 else 1
        except (RuntimeError, ValueError, sla.LinAlgError):
            self.ok = False
            return
        if np.any(diag == 0) or not np.all(np.isfinite(diag)):
            self.ok = False
            return
        self.sign = int(np.prod(np.sign(diag))) * perm
        self.logdet = float(np.sum(np.log(np.abs(diag))))

    def solve(self, rhs: np.ndarray) -> np.ndarray:
        if self.sparse:
            return self._lu.solve(rhs)
        return sla.lu_solve(self._lu_piv, rhs, check_finite=False)
