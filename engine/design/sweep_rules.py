"""Sweep rows derived from the chain rules, without tracing: the work a sweep shares between
its points is the chain's cell structure (only the lengths change from point to point).

Where :mod:`engine.space.chain_count` counts the components of a rotor chain (the driver rule,
or one generic four-bar) or of a chain with the paper's gate, the row's count is that number
(``argument`` derived), and the rotor-turn pattern and ``gated`` follow from the same cells:

* on every component of a chain driven from rotor ``m``, rotor ``k + 1`` is placed from rotor
  ``k`` as ``theta_{k+1} = arg(T_k - P_{k+1}) +- alpha`` with the triangle's angle ``alpha``
  strictly inside ``(0, pi)`` (the driver rule keeps ``|T_k - P_{k+1}|`` strictly between
  ``|l_k - r_{k+1}|`` and ``l_k + r_{k+1}``). Along a closed walk ``alpha`` comes back, so
  rotor ``k + 1`` turns as often as ``T_k`` winds about ``P_{k+1}``: as often as rotor ``k``
  when ``P_{k+1}`` lies inside the circle of ``T_k`` (``r_k > a_k``), never when outside
  (``r_k < a_k``; the rule excludes ``r_k = a_k``). Outwards to the left alike.
* the driver itself turns once on every component of a rotor chain (each is a graph over its
  angle); in a gated chain driven from its gate rotor, that rotor turns once on every
  component where it is a crank of the gate four-bar and never where it rocks
  (:func:`gate_decision`); driven from another rotor, it turns once on the components that
  are graphs over its whole turn and nothing turns on those over an arc of it
  (:mod:`engine.space.gate_transfer`): two patterns where both kinds exist. The bar ``D`` to
  the slider never turns (the slider has at most two places).
* one generic four-bar (``n = 2``): in each of the two circuits of a Grashof four-bar a rotor
  turns once iff it or the ground is the shortest side; no rotor turns in a non-Grashof one.
  A chain driven from one of its four-bars (:func:`engine.space.chain_count.chain_components`):
  that four-bar's rotors so, and the others outwards from them as from a driver rotor.

Every component then has the same pattern but in that last case, so the row's ``windings``
is that one pattern (or those two).
A four-bar of the chain (the gate four-bar, or the single four-bar) whose longest side is
longer than the other three together closes nowhere: the linkage then has no configuration
(0 components, derived). A gated chain driven from no rotor is counted where its gate rotor
cranks the gate four-bar (the gate then restricts nothing: four components per component of
the chain, with its turns). Anything else (other linkages, critical lengths, a gated chain
driven from no rotor whose gate restricts it) gets None here and the sweep explores the point.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from engine.model.linkage import Linkage
from engine.space.assembly import rotors
from engine.space.chain_count import (
    GENERIC_RTOL,
    ChainCount,
    GatedChain,
    _without_gate,
    chain_components,
    gate_decision,
    gated_chain,
    gated_chain_components,
)
from engine.space.gate_transfer import gate_cranks


@dataclass(frozen=True)
class DerivedRow:
    """What the chain rules give at one point: ``components`` (exact) and the ``rule`` that
    counts them; ``turns`` the number of turns (absolute) of every rotor on every component,
    by bar id in the order of :func:`engine.space.kinematics.rotor_angles` (None: not
    derived); ``gated`` and ``gated_reason``; ``no_critical`` the rule also proves that there
    is no critical point."""

    components: int
    rule: str
    turns: dict[str, int] | None
    gated: bool | None
    gated_reason: str
    no_critical: bool
    rocking_too: bool = False  # some other components turn no rotor (see windings)

    @property
    def windings(self) -> tuple[str, ...] | None:
        """The rotor-turn patterns of the components, as a traced sweep row writes them:
        ``turns``, and with ``rocking_too`` also the pattern of no turns (a gated chain driven
        from another rotor than its gate: the components on an arc of the driver's angle)."""
        if self.turns is None:
            return None
        if not self.components:
            return ()
        patterns = {",".join(f"{b}:{w}" for b, w in self.turns.items())}
        if self.rocking_too:
            patterns.add(",".join(f"{b}:0" for b in self.turns))
        return tuple(sorted(patterns))


def _cells(linkage: Linkage, chain_rotors: tuple[str, ...]) -> tuple[np.ndarray, np.ndarray]:
    """Rotor lengths ``r`` (n,) and pin distances ``a`` (n - 1,) of the rotors in chain order."""
    full = np.asarray(linkage.fixed.all(axis=1), dtype=bool)
    pos = np.asarray(linkage.positions, dtype=float)
    index = {b: k for k, b in enumerate(linkage.bar_ids)}  # (tuple.index per rotor: O(n^2))
    bars = np.array([index[bar] for bar in chain_rotors], dtype=np.intp)
    ends = np.asarray(linkage.ends, dtype=np.intp).reshape(-1, 2)[bars]
    pins = np.where(full[ends[:, 0]], ends[:, 0], ends[:, 1])
    r = np.asarray(linkage.lengths, dtype=float)[bars]
    return r, np.linalg.norm(np.diff(pos[pins], axis=0), axis=1)


def _chain_turns(r: np.ndarray, a: np.ndarray, driver: int, driver_turns: int) -> list[int]:
    """Turns of each rotor of a chain driven from rotor ``driver`` (see the module docstring):
    cell ``k`` passes the turns of its driving rotor on iff that rotor is longer than ``a_k``."""
    turns = [0] * len(r)
    turns[driver] = driver_turns
    for k in range(driver, len(r) - 1):  # rightwards: rotor k drives rotor k + 1
        turns[k + 1] = turns[k] if r[k] > a[k] else 0
    for k in range(driver - 1, -1, -1):  # leftwards: rotor k + 1 drives rotor k
        turns[k] = turns[k + 1] if r[k + 1] > a[k] else 0
    return turns


def _cell_turns(r: np.ndarray, a: np.ndarray, k: int, cell: list[int]) -> list[int]:
    """Turns of each rotor of a chain driven from its four-bar ``k`` whose rotors turn
    ``cell`` (2,) times: outwards as from a driver rotor (:func:`_chain_turns`)."""
    turns = [0] * len(r)
    turns[k], turns[k + 1] = cell
    for m in range(k + 1, len(r) - 1):
        turns[m + 1] = turns[m] if r[m] > a[m] else 0
    for m in range(k - 1, -1, -1):
        turns[m] = turns[m + 1] if r[m + 1] > a[m] else 0
    return turns


def _four_bar_turns(r: np.ndarray, a: np.ndarray, coupler: float) -> list[int]:
    sides = [float(a[0]), float(r[0]), coupler, float(r[1])]
    srt = sorted(sides)
    if srt[0] + srt[3] > srt[1] + srt[2]:  # non-Grashof: every rotor rocks
        return [0, 0]
    shortest = int(np.argmin(sides))
    return [int(shortest in (0, 1)), int(shortest in (0, 3))]


def _closes(sides: list[float] | tuple[float, ...]) -> bool:
    """A four-bar with these sides assembles somewhere: its longest side is shorter than the
    other three together (the rules count the components of one that does; a linkage given
    with new lengths, off its configuration space, need not)."""
    return 2 * max(sides) < sum(sides)


def _never_closes(sides: list[float] | tuple[float, ...], what: str) -> DerivedRow | None:
    """The empty row of a linkage with a four-bar that closes nowhere (its longest side longer
    than the other three together, beyond rounding), or None."""
    longest = max(sides)
    if longest - (sum(sides) - longest) <= GENERIC_RTOL * longest:
        return None
    return DerivedRow(0, f"{what} closes nowhere: its longest side {longest:g} exceeds the "
                      f"other three together ({sum(sides) - longest:g})", {}, None,
                      "no configuration: nothing turns and nothing is gated", True)


def _ordered(linkage: Linkage, turns: dict[str, int]) -> dict[str, int] | None:
    """``turns`` in the order of the rotor bars, or None when a rotor has no entry."""
    ids = [linkage.bar_ids[k] for k in rotors(linkage)]
    if set(ids) != set(turns):
        return None
    return {b: turns[b] for b in ids}


def _rotor_chain(linkage: Linkage, count: ChainCount) -> DerivedRow | None:
    r, a = _cells(linkage, count.rotors)
    if count.driver is not None:  # (driven cells assemble at every angle of the driver)
        turns = _chain_turns(r, a, count.driver, 1)
    else:  # a generic four-bar (the chain's driving one): its coupler joins the two tips
        k = count.cell or 0
        tips = {int(v) for b in count.rotors[k:k + 2]
                for v in linkage.ends[linkage.bar_ids.index(b)] if not linkage.fixed[v].all()}
        coupler = next(float(linkage.lengths[j]) for j, (u, v) in enumerate(linkage.ends)
                       if {int(u), int(v)} == tips)
        sides = [float(a[k]), float(r[k]), coupler, float(r[k + 1])]
        if not _closes(sides):
            return _never_closes(sides, "the four-bar")
        turns = _cell_turns(r, a, k, _four_bar_turns(r[k:k + 2], a[k:k + 1], coupler))
    by_bar = _ordered(linkage, dict(zip(count.rotors, turns, strict=True)))
    if by_bar is None:
        return DerivedRow(count.components, count.rule, None, None,
                          "a rotor outside the chain (an inert bar between pins)", True)
    turning = any(by_bar.values())
    return DerivedRow(count.components, count.rule, by_bar, not turning,
                      "ungated: " + ", ".join(b for b, w in by_bar.items() if w) + " turn"
                      if turning else "gated: every rotor rocks (Grashof type of each cell)",
                      True)


def _cranked_gate(linkage: Linkage, parts: GatedChain) -> DerivedRow | None:
    """A gated chain driven from no rotor, whose gate rotor cranks the gate four-bar with the
    rocker's two places apart (:func:`engine.space.gate_transfer.gate_cranks`): the gate
    closes twice at every gate angle and never meets itself, so each component of the chain
    (counted by its rules, e.g. a four-bar driving it) is four of the gated linkage (two
    places of the rocker, two of the slider), with the chain's turns (``D`` never turns); no
    self-stress reaches the gate, so the chain's lack of critical points carries over."""
    if parts.slider_positions != 2 or not gate_cranks(parts.sides, GENERIC_RTOL):
        return None
    chain = _without_gate(linkage)
    count = chain_components(chain)
    row = None if count is None else _rotor_chain(chain, count)
    if row is None or row.turns is None:
        return None
    rule = (f"gated chain, the gate rotor a crank of the gate four-bar (its rocker's places "
            f"apart): {row.components} chain components ({row.rule}) x 2 places of the rocker x "
            "2 of the slider")
    if not row.components:
        return DerivedRow(0, rule, {}, None, row.gated_reason, True)
    turns = dict(row.turns)
    turns.update({linkage.bar_ids[k]: 0 for k in rotors(linkage)
                  if linkage.bar_ids[k] not in turns})  # (the bar D: the slider never turns)
    by_bar = _ordered(linkage, turns)
    if by_bar is None or len(by_bar) != len(row.turns) + 1:
        return None
    return DerivedRow(4 * row.components, rule, by_bar, row.gated, row.gated_reason,
                      row.no_critical)


def _gated(linkage: Linkage, parts: GatedChain) -> DerivedRow | None:
    if not _closes(parts.sides):
        return _never_closes(parts.sides, "the gate four-bar (D, r, L2, L1)")
    if parts.driver is None:
        return _cranked_gate(linkage, parts)
    count = gated_chain_components(linkage, parts)
    if count is None:
        return None
    if not count.components:  # (driven from another rotor: the gate closes nowhere on it)
        return DerivedRow(0, count.rule, {}, None, "no configuration: nothing turns and nothing "
                          "is gated", True)
    decision = gate_decision(linkage, parts)
    if decision.gated is None:
        return None
    r, a = _cells(linkage, parts.rotors)
    assert parts.driver is not None  # (counted)
    # (driven from the gate: every component alike; from another rotor: the driver turns once
    # on the components over its whole turn, nothing turns on those over an arc of it)
    rocking_too = parts.transfer is not None and bool(parts.transfer.turning) and \
        bool(parts.transfer.folded)
    turns: dict[str, int] = dict(zip(
        parts.rotors, _chain_turns(r, a, parts.driver, 0 if decision.gated else 1), strict=True))
    others = [linkage.bar_ids[k] for k in rotors(linkage)
              if linkage.bar_ids[k] not in turns]
    if len(others) != 1:  # the bar D to the slider, and nothing else
        return None
    turns[others[0]] = 0  # the slider has at most two places: bar D never turns
    by_bar = _ordered(linkage, turns)
    return DerivedRow(count.components, count.rule, by_bar, decision.gated, decision.reason,
                      False, rocking_too)


def derive(linkage: Linkage) -> DerivedRow | None:
    """The row the chain rules give for ``linkage`` (see the module docstring), or None where
    none applies.

    Examples
    --------
    >>> from engine.catalogue.presets import build_preset
    >>> row = derive(build_preset("gated-kl-chain", {"n": 3, "gate": 1, "D": 3.0}))
    >>> row.components, row.gated, row.windings
    (8, True, ('r0:0,r1:0,r2:0,D:0',))
    >>> derive(build_preset("gated-kl-chain", {"n": 3, "gate": 1})).windings
    ('r0:1,r1:1,r2:1,D:0',)
    """
    count = chain_components(linkage)
    if count is not None:
        return _rotor_chain(linkage, count)
    parts = gated_chain(linkage)
    return None if parts is None else _gated(linkage, parts)
