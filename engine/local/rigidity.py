"""First-order analysis: rank, zero modes, self-stresses, trivial motions, tangent form.

Small linkages use a dense SVD of ``J`` (E_a, M). Large ones use shift-invert Lanczos
(``eigsh``) on the symmetric augmented matrix ``[[0, J], [J^T, 0]]`` whose eigenvalues are
``+-s_i`` (the singular values of ``J``) plus ``|M - E_a|`` zeros: working with it rather than
``J^T J`` keeps the small singular values accurate to ``eps * s_max`` instead of
``sqrt(eps) * s_max``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from engine.local.sparse_null import SPARSE_MAX_NULLITY, _sparse_null_spaces
from engine.model.budget import NEVER, Deadline, OutOfTime
from engine.model.constraints import Constraints
from engine.model.errors import LimitExceeded, NumericalFailure
from engine.model.linkage import Linkage
from engine.model.lu import Factor
from engine.model.memory import RESULT_BYTES_PER_VALUE, check_memory
from engine.model.tolerances import Tolerances
from engine.model.vectors import normalise_sign

#: Largest linkage for which an inconsistent sparse search falls back to a dense SVD.
DENSE_FALLBACK_MAX_FREE = 4000
#: Default method: dense SVD up to this many free coordinates, sparse above. The dense SVD is
#: O(M^3) (a 256-rotor chain, M = 512: about 0.12 s on one core) while the sparse search costs
#: about 10 ms there; they break even near M = 150 on Kane-Lubensky chains. The dense method is
#: kept for small linkages because it reports every singular value.
FIRST_ORDER_DENSE_MAX_FREE = 200
#: Default method, continued: the sparse search slows down with the null space it has to
#: hold (about quadratically), the dense SVD does not. Up to ``DENSE_FALLBACK_MAX_FREE`` the
#: dense SVD is the default when ``|M - E_a|`` exceeds this share of ``M``. Measured on pinned
#: chains with M = 2000 (one core): 124 zero modes, sparse 2.8 s and dense 15 s; 499 zero
#: modes, sparse 25 s and dense 9 s (M = 1000, 499: 4.6 s and 0.27 s).
FIRST_ORDER_DENSE_NULLITY_SHARE = 1 / 6


@dataclass(frozen=True)
class TangentForm:
    """The tangent form ``t(u)`` of a linkage with ``M - E = 1`` (paper, Appendix B).

    ``t_i = det([e_i; J])``. ``direction`` is ``t / |t|`` (M,) with its true sign,
    ``log10_magnitude`` is ``log10 |t|`` (``-inf`` at a critical point, where ``t = 0``),
    ``orientation`` is the sign of ``det([w; J])`` for the reported unit zero mode ``w`` (+1, -1,
    or 0 at a critical point). The sign depends on the order of coordinates and bars (vertex
    order, then axis; bar order), as the paper notes.
    """

    direction: np.ndarray
    log10_magnitude: float
    orientation: int


@dataclass(frozen=True)
class RigidityResult:
    """Outcome of :func:`first_order`.

    Attributes
    ----------
    rank : int
        Numerical rank of ``J``.
    n_free : int
        ``M``.
    n_constraints : int
        ``E_a``, the active bars (``J`` has one row each).
    trivial_motions : int
        Dimension of the rigid motions (0 when anything is fixed; 3 in 2D and 6 in 3D for a
        generic free linkage, fewer when degenerate).
    expected_dof : int
        ``M - E_a - trivial_motions`` (the Maxwell count ``M - E`` with rigid motions removed).
    dof : int
        Number of nontrivial zero modes, ``M - rank - trivial_motions``.
    critical : bool
        ``rank < min(E_a, M - trivial_motions)``.
    singular_values : (n,) float64
        Descending. All of them for the dense method; for the sparse method the largest and
        the smallest ones computed (``singular_values_complete`` is False).
    zero_modes : (dof, M) float64
        Orthonormal basis of the nontrivial zero modes (orthogonal to the rigid motions).
    trivial_basis : (trivial_motions, M) float64
        Orthonormal basis of the rigid motions.
    self_stresses : (s, E) float64
        Orthonormal basis of the left null space of ``J`` over *all* bars (0 on inert bars).
    method : str
        ``"dense-svd"`` or ``"sparse-eigsh"``.
    tangent_form : TangentForm or None
        Present when ``M - E_a == 1`` and nothing moves rigidly.
    """

    rank: int
    n_free: int
    n_constraints: int
    trivial_motions: int
    expected_dof: int
    dof: int
    critical: bool
    singular_values: np.ndarray
    singular_values_complete: bool
    zero_modes: np.ndarray
    trivial_basis: np.ndarray
    self_stresses: np.ndarray
    method: str
    tangent_form: TangentForm | None
    tolerances: Tolerances


def trivial_motions(linkage: Linkage, positions: np.ndarray | None = None) -> np.ndarray:
    """Orthonormal basis (t, M) of the infinitesimal rigid motions of a linkage with nothing
    fixed; empty (0, M) as soon as any coordinate is fixed.

    Candidates are the ``d`` translations and the ``d(d-1)/2`` rotations about the centroid;
    their span is 3 (2D) or 6 (3D) generically, less when the vertices are collinear (3D: 5) or
    coincide (translations only).
    """
    m = linkage.n_free
    if linkage.anything_fixed or m == 0:
        return np.zeros((0, m))
    pos = linkage.positions if positions is None else positions
    v, d = pos.shape
    rel = pos - pos.mean(axis=0)
    radius = np.sqrt(np.mean(np.einsum("ij,ij->i", rel, rel)))
    cands = [np.tile(np.eye(d)[k], (v, 1)).ravel() / np.sqrt(v) for k in range(d)]
    if radius > 0.0:
        gens = [(0, 1)] if d == 2 else [(0, 1), (1, 2), (2, 0)]
        for a, b in gens:
            w = np.zeros((v, d))
            w[:, a], w[:, b] = -rel[:, b], rel[:, a]
            cands.append(w.ravel() / (radius * np.sqrt(v)))
    mat = np.array(cands)  # (n_cand, M); nothing fixed, so all V*d coordinates are free
    _, s, vt = np.linalg.svd(mat, full_matrices=False)
    keep = s > 1e-9 * s[0]
    return vt[keep]


def _orthonormal_complement(basis: np.ndarray, within: np.ndarray) -> np.ndarray:
    """Orthonormal basis of the part of span(rows of ``within``) orthogonal to ``basis``."""
    if within.shape[0] == 0 or basis.shape[0] == 0:
        return within
    proj = within - (within @ basis.T) @ basis
    u, s, vt = np.linalg.svd(proj, full_matrices=False)
    return vt[s > 0.5]


def _dense_null_spaces(
    jac: np.ndarray, rtol: float
) -> tuple[int, np.ndarray, np.ndarray, np.ndarray]:
    """rank, singular values, right null basis (k, M), left null basis (s, Ea)."""
    ea, m = jac.shape
    if ea == 0 or m == 0:
        return 0, np.zeros(0), np.eye(m), np.eye(ea)
    u, s, vt = np.linalg.svd(jac, full_matrices=True)
    rank = int(np.sum(s > rtol * s[0])) if s[0] > 0 else 0
    return rank, s, vt[rank:], u[:, rank:].T


def tangent_form(jac: np.ndarray | sp.csr_matrix, w: np.ndarray, critical: bool) -> TangentForm:
    """Tangent form ``t = det([w; J]) * [w; J]^{-1} e_1`` for ``J`` (M-1, M).

    By linearity of the determinant in its first row, ``x . t = det([x; J])`` for every ``x``;
    solving with one LU factorisation of the augmented matrix ``B = [w; J]`` gives ``t`` without
    forming minors. ``w`` should have a component along the zero mode (the zero mode itself is
    best conditioned). For sparse ``J`` the first row of ``B`` is the unit vector at the largest
    ``|w_k|`` instead (same ``t``; see the comment in the code). ``orientation`` is the sign of
    ``t . w = det([w; J])`` either way.
    """
    m = jac.shape[1]
    vanishing = TangentForm(np.zeros(m), -np.inf, 0)
    if critical:
        return vanishing
    if sp.issparse(jac):
        # A dense first row makes sparse LU fill in completely (a 10,000-rotor chain: seconds
        # and gigabytes). Any first row x with det([x; J]) != 0 gives the same t, because
        # det([y; J]) = det(B) y^T B^{-1} e_1 for B = [x; J] and every y. The unit row e_k at
        # the largest |w_k| is sparse and costs at most a factor 1 / |w_k| <= sqrt(M) in the
        # conditioning of B (B^{-1} e_1 = w / w_k when w spans the null space of J).
        k = int(np.argmax(np.abs(w)))
        row = sp.csr_matrix(([1.0], ([0], [k])), shape=(1, m))
        aug: np.ndarray | sp.spmatrix = sp.vstack([row, jac], format="csc")
    else:
        aug = np.vstack([w, jac])
    fac = Factor(aug)
    if not fac.ok:
        return vanishing
    y = fac.solve(np.eye(1, m, 0).ravel())
    norm_y = float(np.linalg.norm(y))
    if not np.isfinite(norm_y) or norm_y == 0.0:
        return vanishing
    direction = fac.sign * y / norm_y
    orientation = int(np.sign(direction @ w)) if direction @ w != 0 else 0
    return TangentForm(direction, fac.logdet / np.log(10) + np.log10(norm_y), orientation)


#: Memory of the sparse LU of the shifted augmented matrix, in float64 per nonzero of that
#: matrix: SuperLU reserves its work arrays from a fill estimate before it factors (a
#: 20,000-rotor chain needed between 1 and 1.5 times an estimate made with 30 under a
#: data-segment limit, though its resident size stayed below).
LU_FILL_BOUND = 120


def first_order_memory(n_free: int, n_constraints: int, nnz: int, sparse: bool) -> int:
    """Estimated peak bytes of :func:`first_order` on ``J`` (E_a, M) with ``nnz`` nonzeros by
    the dense (``sparse=False``) or sparse method, before anything is allocated.

    The null spaces are at least ``k = M - E_a`` (zero modes) and ``s = E_a - M``
    (self-stresses) large whatever the rank, and they are dense: the answer holds ``k M + s E_a``
    numbers (a floppy chain of 8,000 free vertices: 128 million), each costing
    ``RESULT_BYTES_PER_VALUE`` by the time it is answered. Dense: the full SVD of ``J``
    (``U`` (E_a, E_a), ``V^T`` (M, M)) with LAPACK's workspace. Sparse: the Lanczos basis
    (n, ncv) and ARPACK's (ncv, ncv) work array for ``n = E_a + M`` and
    ``ncv = 2 (|M - E_a| + 8) + 1``, the null-space blocks (n, |M - E_a| + 8) and the LU
    factor of the augmented matrix.

    Examples
    --------
    >>> first_order_memory(16_000, 8_001, 64_004, sparse=True) > 2**34  # floppy: > 16 GiB
    True
    """
    m, ea = n_free, n_constraints
    answer = RESULT_BYTES_PER_VALUE * (max(0, m - ea) * m + max(0, ea - m) * ea)
    if not sparse:
        return 8 * (2 * ea * m + ea * ea + m * m + 4 * min(ea, m) ** 2) + answer
    n = ea + m
    block = abs(m - ea) + 8
    ncv = min(n, max(2 * block + 1, 20))
    return 8 * (2 * n * ncv + ncv * ncv + 4 * n * block + LU_FILL_BOUND * 2 * nnz) + answer


def _choose_method(m: int, ea: int, use_sparse: bool) -> tuple[bool, str]:
    """The method for ``J`` (E_a, M): the sparse search cannot hold null spaces larger than
    ``SPARSE_MAX_NULLITY``, so when ``|M - E_a|`` alone exceeds that the dense SVD is used
    where it is allowed, and the linkage is refused otherwise (before any work)."""
    if not use_sparse:
        return False, "dense-svd"
    if abs(m - ea) <= SPARSE_MAX_NULLITY:
        return True, "sparse-eigsh"
    if m <= DENSE_FALLBACK_MAX_FREE:
        return False, "dense-svd (sparse fallback)"
    what = "zero modes" if m > ea else "self-stresses"
    raise LimitExceeded(
        f"at least {abs(m - ea)} independent {what} (M = {m} free coordinates, E = {ea} "
        f"bars): more than the sparse search handles ({SPARSE_MAX_NULLITY}), on more "
        f"free coordinates than the dense SVD takes ({DENSE_FALLBACK_MAX_FREE}); the answer "
        f"alone would hold {abs(m - ea) * max(m, ea):,} numbers. Brace the linkage or "
        "analyse a smaller part of it",
        loc=(),
    )


@dataclass(frozen=True)
class FirstOrderPlan:
    """The method :func:`first_order` will use on a linkage, and its estimated peak memory."""

    sparse: bool
    method: str
    memory: int
    what: str  # the method and sizes, for messages


def plan_first_order(linkage: Linkage, sparse: bool | None = None) -> FirstOrderPlan:
    """Choose the method of :func:`first_order` from the sizes alone (no matrix is built) and
    estimate its memory; raises :class:`LimitExceeded` where no method can answer.

    Examples
    --------
    >>> from engine.catalogue.presets import build_preset
    >>> plan_first_order(build_preset("kl-chain", {"n": 200})).method
    'sparse-eigsh'
    """
    m, ea = linkage.n_free, int(np.count_nonzero(linkage.active))
    if sparse is None:
        floppy = abs(m - ea) > FIRST_ORDER_DENSE_NULLITY_SHARE * m
        use_sparse = m > FIRST_ORDER_DENSE_MAX_FREE and not (
            floppy and m <= DENSE_FALLBACK_MAX_FREE)
    else:
        use_sparse = sparse
    use_sparse, method = _choose_method(m, ea, use_sparse and ea > 0 and m > 2)
    nnz = 2 * linkage.dimension * ea  # J's nonzeros, at most
    return FirstOrderPlan(
        use_sparse, method, first_order_memory(m, ea, nnz, use_sparse),
        f"the first-order analysis ({method}, M = {m} free coordinates, E = {ea} bars)",
    )


def _null_spaces(
    linkage: Linkage, cons: Constraints, u: np.ndarray, plan: FirstOrderPlan, tol: Tolerances,
    deadline: Deadline = NEVER, handover: bool = True,
) -> tuple[
    np.ndarray | sp.csr_matrix, bool, str, tuple[int, np.ndarray, np.ndarray, np.ndarray]
]:
    """``J`` at ``u``, whether it is sparse, the method used, and (rank, singular values, right
    null basis (k, M), left null basis (s, Ea)) by the ``plan``'s method; a sparse search that
    fails falls back to the dense SVD where that is allowed (its memory checked first), and
    with ``handover`` (the method was not forced) so does one that finds a large null space."""
    use_sparse, method = plan.sparse, plan.method
    jac = cons.jacobian(u, sparse=use_sparse)
    if use_sparse:
        try:
            # where the dense fallback is allowed, a null space larger than a share of M goes
            # to it at once (a straight 1000-rotor chain: over 70 s sparse, 13 s dense)
            most = (max(LARGE_NULLITY_MIN, int(LARGE_NULLITY_SHARE * cons.n_free))
                    if handover and cons.n_free <= DENSE_FALLBACK_MAX_FREE else None)
            return jac, use_sparse, method, _sparse_null_spaces(jac, tol.rank_rtol, deadline,
                                                                most)
        except NumericalFailure as err:
            if cons.n_free > DENSE_FALLBACK_MAX_FREE:
                raise NumericalFailure(
                    f"{err}; the linkage is too large for the dense fallback "
                    f"({cons.n_free} > {DENSE_FALLBACK_MAX_FREE} free coordinates)"
                ) from err
            use_sparse, method = False, "dense-svd (sparse fallback)"
            plan = plan_first_order(linkage, sparse=False)
            check_memory(plan.memory, plan.what)
            jac = cons.jacobian(u, sparse=False)
    dense_in_time(jac.shape, deadline)
    return jac, use_sparse, method, _dense_null_spaces(np.asarray(jac), tol.rank_rtol)


#: Where the dense fallback is allowed, the sparse method hands over to it once it has found
#: more null vectors than this share of M (at least ``LARGE_NULLITY_MIN``): block inverse
#: iteration on ``k`` null vectors costs about ``(E + M) k^2`` a step, the SVD ``M^3`` in all
#: (a straight 150-rotor chain, 450 null vectors at M = 300: 0.64 s sparse, 0.04 s dense).
LARGE_NULLITY_SHARE = 0.05
LARGE_NULLITY_MIN = 64

#: Seconds of a full dense SVD per ``max(E, M)^3``, for the estimate before one is started:
#: twice what one core of a loaded machine took (M = 2000 in 12.8 s, 1000 in 1.5 s, 500 in
#: 0.24 s), as the load varies.
DENSE_SVD_SECONDS_PER_CUBE = 3.2e-9


def dense_in_time(shape: tuple[int, int], deadline: Deadline) -> None:
    """Raise :class:`OutOfTime` before a dense SVD of ``shape`` that would not end before
    ``deadline`` (it cannot be stopped once started)."""
    seconds = DENSE_SVD_SECONDS_PER_CUBE * float(max(shape)) ** 3
    if seconds > deadline.remaining():
        raise OutOfTime(
            f"a dense SVD of a {shape[0]} x {shape[1]} Jacobian takes about {seconds:.0f} s, "
            f"more than the {deadline.remaining():.1f} s left"
        )


def first_order(
    linkage: Linkage,
    tolerances: Tolerances | None = None,
    sparse: bool | None = None,
    deadline: Deadline = NEVER,
) -> RigidityResult:
    """Rank, zero modes, self-stresses and trivial motions of ``J`` at the given positions.

    The positions are taken as they are (no projection: see
    :func:`engine.model.constraints.on_constraints`).

    Parameters
    ----------
    sparse : bool, optional
        Force the sparse (True) or dense (False) method; default: sparse above
        ``FIRST_ORDER_DENSE_MAX_FREE`` free coordinates unless the null spaces are large
        (``FIRST_ORDER_DENSE_NULLITY_SHARE``) and the dense SVD is allowed.

    Raises
    ------
    LimitExceeded
        When ``|M - E_a|`` is beyond what either method handles (:func:`plan_first_order`).
    MemoryLimitExceeded
        When the method's estimated peak memory (:func:`first_order_memory`) exceeds what this
        process may allocate; both before any work.
    OutOfTime
        When ``deadline`` passes inside the sparse method, or before a dense SVD estimated to
        end after it (never without a deadline).

    Examples
    --------
    >>> from engine.catalogue.presets import build_preset
    >>> r = first_order(build_preset("four-bar"))
    >>> r.rank, r.dof, r.critical, r.self_stresses.shape
    (3, 1, False, (0, 3))
    """
    tol = tolerances or Tolerances()
    cons = Constraints(linkage)
    u = linkage.coordinates()
    plan = plan_first_order(linkage, sparse)
    check_memory(plan.memory, plan.what)
    jac, use_sparse, method, (rank, svals, right, left) = _null_spaces(
        linkage, cons, u, plan, tol, deadline, handover=sparse is None
    )

    trivial = trivial_motions(linkage)
    zero_modes = _orthonormal_complement(trivial, right)
    m, ea, t = cons.n_free, cons.n_constraints, trivial.shape[0]
    stresses = np.zeros((left.shape[0], linkage.n_bars))
    stresses[:, cons.bars] = left

    tform = None
    if m - ea == 1 and t == 0 and right.shape[0] > 0:
        critical = rank < ea
        w = zero_modes[0] if zero_modes.shape[0] == 1 else right[0]
        tform = tangent_form(jac, normalise_sign(w[None, :])[0], critical)

    return RigidityResult(
        rank=rank,
        n_free=m,
        n_constraints=ea,
        trivial_motions=t,
        expected_dof=m - ea - t,
        dof=zero_modes.shape[0],
        critical=rank < min(ea, m - t),
        singular_values=svals,
        singular_values_complete=not use_sparse,
        zero_modes=zero_modes,
        trivial_basis=trivial,
        self_stresses=stresses,
        method=method,
        tangent_form=tform,
        tolerances=tol,
    )
