"""The critical lengths of a rotor chain over a map's box, in closed form from its four-bar cells.

A rotor chain (:mod:`engine.space.chain_count`: tips ``T_k`` on rotors ``r_k`` about pins
``P_k``, couplers ``l_k`` from ``T_k`` to ``T_(k+1)``, pin spacings ``a_k``) is the set of rotor
angles ``theta`` with ``g_k(theta_k, theta_(k+1)) = |T_k - T_(k+1)|^2 - l_k^2 = 0`` for every
cell ``k = 0 .. n-2``. Its Jacobian in ``theta`` is bidiagonal: row ``k`` holds
``alpha_k = dg_k/dtheta_k``, zero exactly where the coupler ``l_k`` lies on the line of the rotor
``r_k``, and ``beta_k = dg_k/dtheta_(k+1)``, zero exactly where it lies on the line of
``r_(k+1)``. A configuration is critical iff some ``sigma != 0`` has ``sigma^T J = 0``: the
columns read ``sigma_0 alpha_0 = 0``, ``sigma_(j-1) beta_(j-1) + sigma_j alpha_j = 0`` and
``sigma_(n-2) beta_(n-2) = 0``. With ``i`` the first and ``j`` the last index of the first run of
nonzero ``sigma``, ``alpha_i = 0`` and ``beta_j = 0``; conversely ``alpha_i = 0 = beta_j`` with
``i <= j`` and no vanishing ``alpha`` strictly between gives such a ``sigma`` (solve the columns
in between). So **a configuration is critical iff ``alpha_i = 0`` and ``beta_j = 0`` for some
``i <= j``**.

``alpha_k`` vanishes only where ``|T_(k+1) - P_k|`` is ``r_k + l_k`` or ``|r_k - l_k|``, and
``|T_(k+1) - P_k|`` stays in ``[|r_(k+1) - a_k|, r_(k+1) + a_k]``: where that interval lies
strictly inside ``(|l_k - r_k|, l_k + r_k)`` (the right rotor of cell ``k`` drives it with two
separate assembly modes, ``crank(k, left=False)`` of the chain rules) ``alpha_k`` never
vanishes; likewise ``beta_k`` never vanishes where the left rotor drives cell ``k``. Let ``A``
be the cells whose right rotor does not drive them somewhere in the box and ``B`` those whose
left rotor does not. When no ``i < j`` has ``i`` in ``A`` and ``j`` in ``B`` anywhere in the box,
a critical configuration needs ``alpha_k = beta_k = 0`` in one cell ``k`` (in ``A`` and ``B``):
the four joints ``P_k, T_k, T_(k+1), P_(k+1)`` on one line, i.e. the lengths on one of the
planes ``+-r_k +-l_k +-r_(k+1) = a_k``. Conversely every such flat cell extends to a critical
configuration of the whole chain: the cells right of ``k`` are not in ``B`` (else ``(k, j)``
would be such a pair), so their left rotors drive them and every ``theta_(k+1)`` extends to the
right (two modes per cell), and alike to the left. The critical value set in the box is then
exactly the union of those planes of the cells in ``A`` and ``B`` (a cell whose longest side
outgrows the other three closes through a flat configuration too: the boundary of an empty
configuration space is on the same planes).

"Somewhere in the box" is decided exactly: the drive conditions are strict inequalities between
piecewise linear functions of the two axes' lengths (``|u| - |v| < 0`` and an affine one, with
``u``, ``v`` affine), linear on each piece of the box cut by the lines ``u = 0`` and ``v = 0``;
their maxima are at the pieces' corners: the box's corners, where those lines cross its edges
and where two of them cross.
"""

from __future__ import annotations

import itertools

import numpy as np

from engine.design.dyad_margin import CriticalPlanes
from engine.model.linkage import Linkage
from engine.space.chain_count import (
    GENERIC_RTOL,
    _chain_order,
    _without_gate,
    chain_sides,
    gated_chain,
)
from engine.space.gate_transfer import gate_cranks

SIGNS = np.array(list(itertools.product((1.0, -1.0), repeat=3)))  # (8, 3)


def _affine(bars: list[int], axes: tuple[int, int], lengths: np.ndarray) -> np.ndarray:
    """Each bar's length as ``c + ex x + ey y`` over the map's axes: (len(bars), 3)."""
    out = np.zeros((len(bars), 3))
    for row, b in enumerate(bars):
        if b == axes[0]:
            out[row, 1] = 1.0
        elif b == axes[1]:
            out[row, 2] = 1.0
        else:
            out[row, 0] = float(lengths[b])
    return out


def _corners(lines: list[np.ndarray], box: np.ndarray) -> np.ndarray:
    """The box's corners, where each line ``c + ex x + ey y = 0`` (rows of ``lines``) crosses
    its edges, and where two lines cross, within the box: (m, 2)."""
    (x0, x1), (y0, y1) = box
    pts = [np.array([x, y]) for x in (x0, x1) for y in (y0, y1)]
    live = [ln for ln in lines if np.any(ln[1:] != 0.0)]
    for c, ex, ey in live:
        if ex != 0.0:
            pts += [np.array([-(c + ey * y) / ex, y]) for y in (y0, y1)]
        if ey != 0.0:
            pts += [np.array([x, -(c + ex * x) / ey]) for x in (x0, x1)]
    for p, q in itertools.combinations(live, 2):
        m = np.array([p[1:], q[1:]])
        if abs(np.linalg.det(m)) > 0.0:
            try:
                pts.append(np.linalg.solve(m, -np.array([p[0], q[0]])))
            except np.linalg.LinAlgError:  # (parallel to rounding: no crossing)
                continue
    arr = np.array(pts)
    span = box[:, 1] - box[:, 0]
    inside = np.all((arr >= box[:, 0] - 1e-12 * span) & (arr <= box[:, 1] + 1e-12 * span), axis=1)
    return np.clip(arr[inside], box[:, 0], box[:, 1])


def chain_planes(linkage: Linkage, axes: tuple[int, int], box: np.ndarray
                 ) -> list[CriticalPlanes] | None:
    """The critical planes of a rotor chain over the box of two of its bars' lengths (see the
    module docstring): the flat planes ``+-r_k +-l_k +-r_(k+1) = a_k`` of every cell that may
    be flat, or None when the linkage is not a rotor chain, an axis is not one of its bars, or
    two cells' alignments may combine into a critical configuration somewhere in the box (the
    critical value set is then not these planes alone). A chain with the paper's gate gets
    its chain's planes where the gate rotor cranks the gate four-bar over the whole box
    (:func:`gated_chain_planes`).

    Parameters
    ----------
    linkage : Linkage
    axes : (2,) int
        The bars whose lengths the map varies.
    box : (2, 2) float
        ``[[x_min, x_max], [y_min, y_max]]``, positive.

    Examples
    --------
    >>> from engine.catalogue.presets import build_preset
    >>> lk = build_preset("kl-chain", {"n": 4})
    >>> planes = chain_planes(lk, (0, 1), np.array([[1.2, 1.8], [1.2, 1.8]]))
    >>> [lk.bar_ids[b] for b in planes[0].bars], planes[0].dist, len(planes)
    (['r0', 'l0', 'r1'], 1.0, 1)
    """
    if gated_chain(linkage) is not None:
        return gated_chain_planes(linkage, axes, box)
    found = _chain_order(linkage)
    if found is None:
        return None
    tips, rotor_bars, couplers = found
    if not set(axes) <= set(rotor_bars) | set(couplers):
        return None
    n_cells = len(tips) - 1
    a = chain_sides(linkage, found)[3]
    # per cell the affine lengths (r_k, l_k, r_(k+1)) over the axes, (K, 3, 3), and a_k
    cell_bars = np.column_stack([rotor_bars[:-1], couplers, rotor_bars[1:]])  # (K, 3)
    cells = np.zeros((n_cells, 3, 3))
    cells[:, :, 0] = np.asarray(linkage.lengths, dtype=float)[cell_bars]
    for col, axis in enumerate(axes, start=1):
        on = cell_bars == axis
        cells[on, 0], cells[on, col] = 0.0, 1.0
    ground = np.zeros((n_cells, 3))
    ground[:, 0] = a
    # the kinks of the drive conditions: l_k = r_(k+1), r_k = a_k, l_k = r_k, r_(k+1) = a_k
    kinks = [cells[:, 1] - cells[:, 2], cells[:, 0] - ground, cells[:, 1] - cells[:, 0],
             cells[:, 2] - ground]
    touching = np.flatnonzero(np.any(cells[:, :, 1:] != 0.0, axis=(1, 2))).tolist()
    pts = _corners([kink[k] for kink in kinks for k in touching], box)  # (m, 2)
    xy1 = np.column_stack([np.ones(len(pts)), pts])  # (m, 3)
    r0, lc, r1 = (np.einsum("kj,mj->km", cells[:, s], xy1) for s in range(3))  # (K, m)
    av = a[:, None]
    scale = float(max(np.max(np.abs(r0)), np.max(np.abs(lc)), np.max(np.abs(r1)), a.max()))
    eps = GENERIC_RTOL * scale

    def drives(rd: np.ndarray, ro: np.ndarray) -> np.ndarray:
        """(K,) the rotor ``rd`` drives its cell with separate modes at every point."""
        return np.all((np.abs(lc - ro) - np.abs(rd - av) < -eps)
                      & (rd + av - lc - ro < -eps), axis=1)

    in_a = np.flatnonzero(~drives(r1, r0))  # alpha_k may vanish
    in_b = np.flatnonzero(~drives(r0, r1))  # beta_k may vanish
    if len(in_a) and len(in_b) and in_a.min() < in_b.max():  # some i < j
        return None
    flat = sorted(set(in_a.tolist()) & set(in_b.tolist()))
    return [CriticalPlanes(np.array([rotor_bars[k], couplers[k], rotor_bars[k + 1]]), SIGNS,
                           float(a[k])) for k in flat]


def gated_chain_planes(linkage: Linkage, axes: tuple[int, int], box: np.ndarray
                       ) -> list[CriticalPlanes] | None:
    """The critical planes of a rotor chain with the paper's gate over the box of two of its
    chain's bars: those of the chain without the gate (:func:`chain_planes`), where the slider
    has its two places and the gate rotor cranks the gate four-bar with the rocker's two places
    apart at every point of the box (:func:`engine.space.gate_transfer.gate_cranks`); None
    otherwise (an axis one of the gate's bars ``D``, ``L1``, ``L2``, too).

    Why: reduce the slider ``G`` to its place (the bar ``D`` pivots on its free coordinate,
    nonzero with two places) and let ``phi`` be the rocker's angle. The gate's row of the
    Jacobian has ``dh/dphi != 0`` (``L1`` and ``L2`` never on one line) and no other row has a
    ``phi`` entry, so a self-stress has no weight on the gate: a configuration is critical iff
    its chain is. The gate closes at every gate-rotor angle (twice), so every critical
    configuration of the chain, and every point where the chain cannot close, is one of the
    gated linkage: the critical value set is the chain's.

    Examples
    --------
    >>> from engine.catalogue.presets import build_preset
    >>> lk = build_preset("gated-kl-chain", {"n": 4, "gate": 2})
    >>> planes = gated_chain_planes(lk, (0, 1), np.array([[1.2, 1.8], [1.2, 1.8]]))
    >>> [lk.bar_ids[b] for b in planes[0].bars], len(planes)
    (['r0', 'l0', 'r1'], 1)
    >>> gated_chain_planes(build_preset("gated-kl-chain", {"n": 4, "gate": 2, "D": 3.0}),
    ...                    (0, 1), np.array([[1.2, 1.8], [1.2, 1.8]])) is None
    True
    """
    parts = gated_chain(linkage)
    if parts is None or parts.slider_positions != 2:
        return None
    names = [linkage.bar_ids[b] for b in axes]
    if set(names) & set(parts.gate_bars):
        return None
    d, r, l2, l1 = parts.sides
    gate_rotor = parts.rotors[parts.gate]
    # r_g over the box: |r_g - D| least at D (clipped), r_g + D greatest at the top
    values = [r]
    for name, (lo, hi) in zip(names, box, strict=True):
        if name == gate_rotor:
            values = [float(lo), float(hi), float(np.clip(d, lo, hi))]
    if not all(gate_cranks((d, v, l2, l1), GENERIC_RTOL) for v in values):
        return None
    chain = _without_gate(linkage)
    index = {b: k for k, b in enumerate(chain.bar_ids)}
    planes = chain_planes(chain, (index[names[0]], index[names[1]]), box)
    if planes is None:
        return None
    back = {b: k for k, b in enumerate(linkage.bar_ids)}
    return [CriticalPlanes(np.array([back[chain.bar_ids[b]] for b in pl.bars]), pl.normals,
                           pl.dist) for pl in planes]
