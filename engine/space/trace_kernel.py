"""The tracer's regular steps compiled (numba), with the Python loop of :mod:`engine.space.trace` as
the fallback and the reference.

:func:`engine.space.trace.trace_curve` spends almost all of its time in the per-step overhead of
small numpy and LAPACK calls (a four-bar's ``[t; J]`` is 4 x 4; a chain's is a narrow band).
:func:`advance` runs the same predictor-corrector passes in compiled code: predictor (the cubic
through the previous point), strain test, chord Newton with the factorisation of the previous
point to ``residual_atol``, full Newton when the chord fails, the factorisation at the new point
(tangent and ``det([t; J])``) and the polish with it to ``CORRECT_TIGHT``, turn test, step
control. It commits only
passes that it can finish exactly as the Python loop would, and hands every other pass back
(a sign change of the determinant, a collapsed step, a possible closing, an exhausted budget,
a due deadline check, a band too wide for the band LU or a singular bordered system): the
Python loop then runs that one pass with its own code (``_cross_ahead``, ``_jump``,
``_lands_on``, the stop reasons) and calls the kernel again.

Linear algebra: an LU with partial pivoting in LAPACK band storage (as ``gbtrf``/``gbtrs``),
used with full bandwidth for the dense ``[t; J]`` of small linkages and on the band reordering
of ``[e_k; J]`` with the rank-one update of :class:`engine.model.lu.BorderedFactor` for large ones
(the same systems as :func:`engine.space.trace.factor_augmented`, so the same signs and
``log|det|``).

The choice: environment variable ``LINKAGE_TRACER_KERNEL`` = ``numba`` (default; the Python
loop when numba cannot be imported, and until the kernel is compiled: :func:`enabled` loads it
in a background thread, :func:`load` waits for it) or ``numpy`` (always the Python loop).
"""

from __future__ import annotations

import os
import threading
import weakref
from collections.abc import Callable
from typing import Any, NamedTuple

import numpy as np

from engine.catalogue.presets import build_preset
from engine.model.constraints import Constraints

#: Environment variable choosing the tracer's path: ``numba`` or ``numpy``.
KERNEL_ENV = "LINKAGE_TRACER_KERNEL"

#: What :func:`advance` reports when it returns.
EV_FULL = 0  # the output buffer (or the point budget) is full
EV_PASS = 1  # the next pass must run in Python
EV_DEADLINE = 2  # the next pass checks the deadline (the caller does, then calls again)

#: Points per call at most: buffers of about this many floats (a chain's rows are long).
BUFFER_FLOATS = 1 << 18

#: The compiled kernel once :func:`load` has imported and compiled it (None before, or when
#: numba is missing or failed).
_kernel: Callable[..., Any] | None = None
_loader: threading.Thread | None = None
_lock = threading.Lock()


def enabled() -> bool:
    """True when the compiled path is chosen and ready. The first call starts :func:`load` in
    a background thread and the Python loop traces until it is ready: compiling takes tens of
    seconds where numba's cache is cold (a fresh install), which no request's time budget
    should pay."""
    if os.environ.get(KERNEL_ENV, "numba").strip().lower() == "numpy":
        return False
    return _kernel is not None or load(wait=False)


def prepare() -> bool:
    """Load the kernel and wait for it unless the Python loop is chosen: call it before work
    whose answers should not depend on whether the kernel happened to be ready (the two paths
    agree to rounding, not bit for bit). True when the compiled path is in use."""
    if os.environ.get(KERNEL_ENV, "numba").strip().lower() == "numpy":
        return False
    return load()


def load(wait: bool = True) -> bool:
    """Import and compile the kernel (once per process; numba caches the machine code on
    disk); with ``wait`` block until done. True when it is ready."""
    global _loader
    with _lock:
        if _loader is None:
            _loader = threading.Thread(target=_compile, name="tracer-kernel", daemon=True)
            _loader.start()
        loader = _loader
    if wait:
        loader.join()
    return _kernel is not None


def _after_fork() -> None:
    """A forked child has no loader thread: it loads again if the parent had not finished."""
    global _loader, _lock
    _lock = threading.Lock()
    if _kernel is None:
        _loader = None


os.register_at_fork(after_in_child=_after_fork)


#: Why the kernel could not be loaded (None while loading, once loaded, or with numba missing):
#: e.g. no writable cache directory for numba; the Python loop is then the tracer.
failure: str | None = None


def _compile() -> None:
    global failure
    try:
        _compile_kernel()
    except ImportError:  # numba missing: the Python loop is the tracer
        return
    except Exception as err:  # noqa: BLE001 -- any failure leaves the Python loop in charge
        failure = f"{type(err).__name__}: {err}"


def _compile_kernel() -> None:
    global _kernel
    from engine.space._trace_numba import run

    # one call compiles the only signature (the dense and band paths take the same types)
    lk = build_preset("four-bar")
    cons = Constraints(lk)
    u = lk.coordinates()
    t = np.linalg.svd(cons.jacobian(u, sparse=False))[2][-1]
    _advance(run, cons, True, u, t, t, 1, 0.01, 0.0, 16, False, 2, u0=u, close=False,
             close_after=1.0, h_max=0.1, h_min=1e-9, collapse=1e-4, strain_tol=1e-2,
             residual_atol=1e-9, cos_turn=0.9, h_cross=1e-6, band_max_work=256,
             deadline_every=0, checked=-1, cross_ahead=True)
    _kernel = run


class KernelData(NamedTuple):
    """Arrays the kernel reads (computed once per :class:`Constraints`)."""

    fixed_values: np.ndarray  # (F,) fixed coordinates, after u in the gathers
    gather_i: np.ndarray  # (Ea, d) index into [u, fixed] of each bar's first end
    gather_j: np.ndarray  # (Ea, d)
    lengths: np.ndarray  # (Ea,)
    targets: np.ndarray  # (Ea,) L^2
    rows: np.ndarray  # (nnz,) pattern of J
    cols: np.ndarray
    sign: np.ndarray
    axes: np.ndarray
    entry_i: np.ndarray  # (nnz,) index into [u, fixed] of the coordinate of each entry's bar end
    entry_j: np.ndarray  # (nnz,) ... and of the other end's (the entry is 2 sign (ext_i - ext_j))
    col_pos: np.ndarray  # (M,) band column of each column (band path only, else empty)
    entry_rank: np.ndarray  # (nnz,) band row of each entry's bar before the unit row
    entry_col: np.ndarray  # (nnz,) band column of each entry
    keys: np.ndarray  # (Ea,) sorted row keys
    row_rank: np.ndarray  # (Ea,) band row of each bar before the unit row
    sign_perm: int  # sign of the band reordering


_DATA: weakref.WeakKeyDictionary[Constraints, KernelData] = weakref.WeakKeyDictionary()


def kernel_data(cons: Constraints, dense: bool) -> KernelData:
    """The kernel's view of ``cons`` (cached; the band layout only for the sparse path)."""
    data = _DATA.get(cons)
    if data is not None and (dense or len(data.col_pos)):
        return data
    p = cons.pattern
    empty_i = np.zeros(0, dtype=np.int64)
    if dense:
        band: tuple[np.ndarray, ...] = (empty_i, empty_i, empty_i, np.zeros(0), empty_i)
        sign_perm = 1
    else:
        col_pos, entry_rank, entry_col, keys, sign_perm = cons._band_layout
        band = (col_pos, entry_rank, entry_col, keys, cons._band_row_rank)
    i64 = [np.ascontiguousarray(a, dtype=np.int64) for a in band if a.dtype.kind in "iu"]
    col_pos, entry_rank, entry_col, row_rank = i64
    data = KernelData(
        np.ascontiguousarray(cons._fixed_values, dtype=float),
        np.ascontiguousarray(cons._gather_i, dtype=np.int64),
        np.ascontiguousarray(cons._gather_j, dtype=np.int64),
        np.ascontiguousarray(cons.linkage.lengths[cons.bars], dtype=float),
        np.ascontiguousarray(cons.targets, dtype=float),
        np.ascontiguousarray(p.rows, dtype=np.int64),
        np.ascontiguousarray(p.cols, dtype=np.int64),
        np.ascontiguousarray(p.sign, dtype=float),
        np.ascontiguousarray(p.axes, dtype=np.int64),
        np.ascontiguousarray(cons._gather_i[p.rows, p.axes], dtype=np.int64),
        np.ascontiguousarray(cons._gather_j[p.rows, p.axes], dtype=np.int64),
        col_pos, entry_rank, entry_col,
        np.ascontiguousarray(band[3], dtype=float), row_rank, int(sign_perm),
    )
    _DATA[cons] = data
    return data


class Advance(NamedTuple):
    """What one call of the kernel did: the committed points (n, M), tangents, signs and
    ``log|det|``, why it returned, and the tracer's state after the last committed pass
    (``u_prev``: the point before ``u``, None while there is none)."""

    points: np.ndarray
    tangents: np.ndarray
    signs: np.ndarray
    logdets: np.ndarray
    event: int
    u: np.ndarray
    t: np.ndarray
    t_in: np.ndarray
    u_prev: np.ndarray | None
    sign: int
    h: float
    arc: float
    budget: int
    tried: bool


def advance(
    cons: Constraints, dense: bool, u: np.ndarray, t: np.ndarray, t_in: np.ndarray, sign: int,
    h: float, arc: float, budget: int, tried: bool, room: int, **kw: Any,
) -> Advance:
    """:func:`_advance` with the loaded kernel (:func:`enabled` must have said True)."""
    assert _kernel is not None
    return _advance(_kernel, cons, dense, u, t, t_in, sign, h, arc, budget, tried, room, **kw)


def _advance(
    run: Callable[..., Any], cons: Constraints, dense: bool, u: np.ndarray, t: np.ndarray,
    t_in: np.ndarray, sign: int, h: float, arc: float, budget: int, tried: bool, room: int, *,
    u0: np.ndarray, close: bool, u_prev: np.ndarray | None = None,
    close_after: float, h_max: float, h_min: float, collapse: float, strain_tol: float,
    residual_atol: float, cos_turn: float, h_cross: float, band_max_work: int, deadline_every: int,
    checked: int, cross_ahead: bool,
) -> Advance:
    """Run committed passes of the tracer from the state ``(u, t, t_in, u_prev, sign, h, arc,
    budget, tried)`` (``t_in`` is the row of the factorisation at ``u``: the tangent before it,
    at ``u_prev``, the point before ``u`` or None), at most ``room`` points.
    ``deadline_every`` 0 never hands back for the deadline; ``checked`` is the budget value
    whose deadline check the caller has just made."""
    m = len(u)
    cap = max(1, min(room, BUFFER_FLOATS // max(m, 1)))
    pts = np.empty((cap, m))
    tans = np.empty((cap, m))
    signs = np.empty(cap, dtype=np.int64)
    logd = np.empty(cap)
    state_u = np.array(u, dtype=float)
    state_t = np.array(t, dtype=float)
    state_tin = np.array(t_in, dtype=float)
    state_prev = np.zeros(m) if u_prev is None else np.array(u_prev, dtype=float)
    fp = np.array([h, arc, close_after, h_max, h_min, collapse, strain_tol, residual_atol,
                   cos_turn, h_cross])
    ip = np.array([sign, budget, int(tried), int(close), int(dense), band_max_work,
                   deadline_every, checked, int(cross_ahead), int(u_prev is not None)],
                  dtype=np.int64)
    d = kernel_data(cons, dense)
    # u0 contiguous like every other array: a strided view (a row of a seed stack's column
    # selection) is another numba signature, compiled or loaded from the cache on first use
    n, event = run(state_u, state_t, state_tin, state_prev,
                   np.ascontiguousarray(u0, dtype=float), fp, ip,
                   d.fixed_values, d.gather_i, d.gather_j, d.lengths, d.targets, d.rows,
                   d.cols, d.sign, d.axes, d.entry_i, d.entry_j, d.col_pos, d.entry_rank,
                   d.entry_col, d.keys, d.row_rank, d.sign_perm, pts, tans, signs, logd)
    # the buffers handed back as they are, a partial one shrunk in place (a view would keep
    # the whole buffer alive for as long as the curve lives; nothing else refers to these
    # arrays): copying them cost a 400-rotor chain about 7 us of its 60 per point (megabytes
    # of fresh pages per call)
    if n < cap:
        pts.resize((n, m), refcheck=False)
        tans.resize((n, m), refcheck=False)
    return Advance(pts, tans, signs[:n], logd[:n], int(event), state_u,
                   state_t, state_tin, state_prev if ip[9] else None, int(ip[0]),
                   float(fp[0]), float(fp[1]), int(ip[1]), bool(ip[2]))
