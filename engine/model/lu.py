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

#: Double-precision LU and solve of LAPACK (what ``scipy.linalg.lu_factor``/``lu_solve`` call).
_GETRF, _GETRS = sla.get_lapack_funcs(("getrf", "getrs"), dtype=np.float64)


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
    failed), then ``sign`` is 0 and ``logdet`` is ``-inf``. ``logdet`` is ``ln |det|``.

    ``ordering`` is SuperLU's column ordering for sparse matrices (``permc_spec``); row pivoting
    is partial pivoting whatever the ordering, so it changes fill and speed, not stability.
    """

    def __init__(self, mat: np.ndarray | sp.spmatrix, ordering: str = "COLAMD") -> None:
        self.sparse = sp.issparse(mat)
        self.ok = True
        self.sign = 0
        self.logdet = -np.inf
        try:
            if self.sparse:
                csc = mat if getattr(mat, "format", None) == "csc" else sp.csc_matrix(mat)
                self._lu = spla.splu(csc, permc_spec=ordering)
                diag = self._lu.U.diagonal()
                perm = parity(self._lu.perm_r) * parity(self._lu.perm_c)
            else:
                # LAPACK directly: scipy.linalg.lu_factor/lu_solve validate and convert their
                # arguments on every call, which costs more than the factorisation itself for
                # the small systems of the tracer (the same getrf/getrs underneath)
                lu, piv, info = _GETRF(np.asarray(mat, dtype=float))
                if info < 0:
                    raise ValueError(f"getrf: illegal argument {-info}")
                self._lu_piv = (lu, piv)
                diag = np.diag(lu)
                perm = -1 if np.sum(piv != np.arange(len(diag))) % 2 else 1
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
        x, info = _GETRS(*self._lu_piv, rhs)
        if info != 0:
            raise ValueError(f"getrs: illegal argument {-info}")
        return np.asarray(x)

    def solve_first(self) -> np.ndarray:
        """``A^{-1} e_1``."""
        e1 = np.zeros(self._lu.shape[0] if self.sparse else len(self._lu_piv[1]))
        e1[0] = 1.0
        return self.solve(e1)


class BorderedFactor:
    """Solves with ``B = [row; J]`` (square) from a sparse LU ``base`` of ``B0 = [e_k; J]``.

    A dense border row fills the sparse LU of ``B`` (partial pivoting picks it early), while
    ``B0`` has exactly the fill of ``J``. ``B = B0 + e_1 d^T`` with ``d = row - e_k`` is a
    rank-one update: solves follow from Sherman-Morrison and the determinant from the matrix
    determinant lemma, ``det B = det B0 (1 + d . B0^{-1} e_1)``. For a one-degree-of-freedom
    ``J`` with unit null vector ``t``, ``det B0 = t_k det([t; J])``: ``k = argmax |row|`` keeps
    ``B0`` as well conditioned as ``B`` is up to a factor ``|row_k| >= 1/sqrt(M)``.

    Same interface as :class:`Factor` (``ok``, ``sign``, ``logdet``, ``solve``); ``ok`` is False
    when ``B0`` or ``B`` is singular.
    """

    def __init__(self, base: Factor | BandLU, k: int, row: np.ndarray) -> None:
        self.sparse = True
        self.sign = 0
        self.logdet = -np.inf
        self._base = base
        self.ok = self._base.ok
        if not self.ok:
            return
        m = len(row)
        e1 = np.zeros(m)
        e1[0] = 1.0
        self._y0 = self._base.solve(e1)
        self._d = np.array(row, dtype=float)
        self._d[k] -= 1.0
        self._gamma = 1.0 + float(self._d @ self._y0)
        if self._gamma == 0.0 or not np.isfinite(self._gamma):
            self.ok = False
            return
        self.sign = self._base.sign * (1 if self._gamma > 0 else -1)
        self.logdet = self._base.logdet + float(np.log(abs(self._gamma)))

    def solve_first(self) -> np.ndarray:
        """``B^{-1} e_1`` (the tangent direction), already known: ``B0^{-1} e_1 / gamma``."""
        return self._y0 / self._gamma

    def solve(self, rhs: np.ndarray) -> np.ndarray:
        x = self._base.solve(rhs)
        return x - self._y0 * (float(self._d @ x) / self._gamma)


class BandLU:
    """LU with partial pivoting of a square band matrix (LAPACK ``gbtrf``), given in band
    storage: ``ab[kl + ku + i - j, j] = A[i, j]`` with ``kl`` extra leading rows of workspace.
    Optionally the band matrix is a permuted original: row ``i`` of the original is band row
    ``row_pos[i]``, column ``c`` is band column ``col_pos[c]``; solves then take and return
    vectors in the original order.

    For matrices whose bandwidth is small after a fixed reordering (chains) this costs
    ``O(M kl (kl + ku))`` with a call overhead of microseconds, against SuperLU's fixed cost
    of ~0.1 ms per factorisation. ``sign_perm`` is the sign of the row and column permutations
    that produced the band form, so that ``sign`` is the sign of the original matrix.
    Same interface as :class:`Factor`.
    """

    def __init__(
        self,
        ab: np.ndarray,
        kl: int,
        ku: int,
        row_pos: np.ndarray | None = None,
        col_pos: np.ndarray | None = None,
        sign_perm: int = 1,
    ) -> None:
        self.sparse = True
        self.ok = False
        self.sign = 0
        self.logdet = -np.inf
        self._kl, self._ku = kl, ku
        self._row_pos, self._col_pos = row_pos, col_pos
        lu, piv, info = sla.lapack.dgbtrf(ab, kl, ku, overwrite_ab=1)
        if info != 0:  # info > 0: an exactly zero pivot (singular)
            return
        diag = lu[kl + ku]
        if not np.all(np.isfinite(diag)):
            return
        self._lu, self._piv = lu, piv
        # sign: negative pivots and row interchanges, each counted by parity
        flips = int(np.count_nonzero(diag < 0)) + int(np.count_nonzero(piv != np.arange(len(piv))))
        self.ok = True
        self.sign = (-1 if flips % 2 else 1) * sign_perm
        self.logdet = float(np.sum(np.log(np.abs(diag))))

    def solve(self, rhs: np.ndarray) -> np.ndarray:
        if self._row_pos is not None:
            permuted = np.empty_like(rhs, dtype=float)
            permuted[self._row_pos] = rhs
            rhs = permuted
        x, _ = sla.lapack.dgbtrs(self._lu, self._kl, self._ku, rhs, self._piv)
        return x if self._col_pos is None else x[self._col_pos]
