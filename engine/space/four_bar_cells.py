"""The four-bar cells of a rotor chain (with or without the paper's gate) and their tau signs.

A rotor chain's configuration space is the fibred product of its four-bar cells
``P_k T_k T_(k+1) P_(k+1)``; a chain with the paper's gate (Sec. V) has one more four-bar, the
gate ``P_g T_g R G`` (ground ``D``, input the gate rotor, coupler ``L2``, output ``L1``). Each
four-bar's type is the sign pattern of the paper's ``(tau_1, tau_2, tau_3)`` (Eq. 16, after
McCarthy): the labels of the regions of Fig. 5b.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from engine.model.linkage import Linkage
from engine.space.chain_count import (
    GENERIC_RTOL,
    _chain_order,
    _gate_bars,
    _without_gate,
    chain_sides,
    gated_chain,
)


def tau_signs(sides: tuple[float, float, float, float]) -> tuple[int, int, int]:
    """The signs of the paper's (Eq. 16, after McCarthy) ``tau_1 = a - L1 + L2 - L3``,
    ``tau_2 = a - L1 - L2 + L3``, ``tau_3 = L2 + L3 - a - L1`` of a four-bar with sides
    ``(a, L1, L2, L3)`` = (ground, input rotor at the first pin, coupler, output rotor); 0
    where ``|tau|`` is within ``GENERIC_RTOL`` of the longest side (critical lengths). The
    input rotor turns fully iff ``tau_3 > 0`` and ``tau_1 tau_2 > 0``: ``(+,+,+)``
    (crank-rocker) and ``(-,-,+)`` (double crank).

    Examples
    --------
    >>> tau_signs((2.5, 1.5, 2.0, 2.0)), tau_signs((2.4, 1.5, 2.0, 2.0))
    ((1, 1, 0), (1, 1, 1))
    """
    return _tau_signs(np.array([sides], dtype=float))[0]


def _tau_signs(sides: np.ndarray) -> list[tuple[int, int, int]]:
    """:func:`tau_signs` of each row of ``sides`` (K, 4)."""
    a, l1, l2, l3 = sides.T
    taus = np.column_stack([a - l1 + l2 - l3, a - l1 - l2 + l3, l2 + l3 - a - l1])
    eps = GENERIC_RTOL * np.max(np.abs(sides), axis=1, keepdims=True)
    signs = np.where(np.abs(taus) <= eps, 0, np.sign(taus)).astype(int)
    return [(s1, s2, s3) for s1, s2, s3 in signs.tolist()]


@dataclass(frozen=True)
class FourBarCell:
    """A four-bar of a linkage: ``name`` (``"gate"``, or the chain's ``"r0-l0-r1"``),
    ``bars`` its (input rotor, coupler, output rotor) bar ids, ``sides`` (ground, input,
    coupler, output) and their :func:`tau_signs`."""

    name: str
    bars: tuple[str, str, str]
    sides: tuple[float, float, float, float]
    signs: tuple[int, int, int]
    ground: str | None = None  # the ground's bar (the gate's D); None: the pins' spacing

    def touches(self, bars: set[str]) -> bool:
        """One of ``bars`` is a side of this four-bar (its signs change with that length)."""
        return bool(bars & {*self.bars, *([self.ground] if self.ground else [])})


def four_bar_cells(linkage: Linkage, bars: set[str] | None = None) -> list[FourBarCell]:
    """The four-bar cells of a rotor chain (each ``P_k T_k T_(k+1) P_(k+1)``, ground the pin
    spacing) and, for a chain with the paper's gate, the gate four-bar first (ground ``D``,
    input the gate rotor, coupler ``L2``, output ``L1``: the cell Fig. 5b labels); empty for
    any other linkage. ``bars``: only the chain's cells with one of these bars as a side (the
    gate's cell is kept either way).

    Examples
    --------
    >>> from engine.catalogue.presets import build_preset
    >>> cells = four_bar_cells(build_preset("gated-kl-chain", {"n": 3, "gate": 1, "D": 3.0}))
    >>> [(c.name, c.signs) for c in cells][:2]
    [('gate', (1, 1, -1)), ('r0-l0-r1', (-1, -1, 1))]
    """
    out: list[FourBarCell] = []
    chain = linkage
    parts, gate_bars = gated_chain(linkage), _gate_bars(linkage)
    if parts is not None and gate_bars is not None:
        chain = _without_gate(linkage)
        d_bar, l1_bar, l2_bar = gate_bars[:3]
        out.append(FourBarCell("gate", (parts.rotors[parts.gate], linkage.bar_ids[l2_bar],
                                        linkage.bar_ids[l1_bar]),
                               parts.sides, tau_signs(parts.sides), linkage.bar_ids[d_bar]))
    found = _chain_order(chain)
    if found is None:
        return out
    tips, rotor_bars, couplers = found
    a = chain_sides(chain, found)[3]
    lengths = np.asarray(chain.lengths, dtype=float)
    sides = np.column_stack([a, lengths[rotor_bars[:-1]], lengths[couplers],
                             lengths[rotor_bars[1:]]])  # (K, 4): ground, input, coupler, output
    ids = chain.bar_ids
    keep = np.arange(len(couplers))
    if bars is not None:  # (20,000 cells as objects: 0.3 s; a map's axes touch two or three)
        touched = np.array([b in bars for b in ids], dtype=bool)
        rb, cb = np.asarray(rotor_bars), np.asarray(couplers, dtype=np.intp)
        keep = np.flatnonzero(touched[rb[:-1]] | touched[cb] | touched[rb[1:]])
    for k, side, signs in zip(keep.tolist(), sides[keep].tolist(), _tau_signs(sides[keep]),
                              strict=True):
        names = (ids[rotor_bars[k]], ids[couplers[k]], ids[rotor_bars[k + 1]])
        out.append(FourBarCell("-".join(names), names, (side[0], side[1], side[2], side[3]),
                               signs))
    return out
