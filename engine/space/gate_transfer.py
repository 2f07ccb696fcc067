"""A gated rotor chain driven from another rotor than its gate: its components and full turns,
from closed-form circle intersections along the cells between the driver and the gate.

The chain (the gate left out) is driven from rotor ``m`` (the driver rule of
:mod:`engine.space.chain_count`): each of its components is a graph over ``theta_m``, one per
choice ``b`` of assembly mode in every cell, and on it the gate rotor's angle is a smooth map
``theta_g = f_b(theta_m)`` of the circle (the cells between ``m`` and ``g`` composed; the cells
beyond them only multiply the components by two each). The gate (a slider ``G`` at one of its
points at distance ``D`` from ``P_g``, a rocker ``L1`` to ``R`` and a bar ``L2`` from ``T_g``
to ``R``) closes where ``d = |T_g - G|`` lies in ``[|L2 - L1|, L2 + L1]``, with two positions
of ``R`` that meet where ``d`` is at either end. So over a component ``b`` and a slider place:

* where ``d`` never reaches an end: two circles (both places of ``R``) if ``d`` stays inside,
  each a graph over ``theta_m`` (the driver completes a turn on them), none if outside;
* else ``theta_m`` crosses the ends at ``2K`` angles (transversally: see below) and the gated
  linkage has ``K`` components, one per arc of ``theta_m`` where ``d`` is inside, the two
  places of ``R`` joined at the arc's ends: there ``theta_m`` goes forth and back, and so does
  every rotor (no full turn).

The crossings are found exactly: the gate rotor's angles where ``d`` is at an end are closed
form (the gate four-bar's triangle), and each is carried back cell by cell towards the driver
by a circle intersection (a tip at distance ``r`` from its pin and ``l`` from the next tip),
keeping the branch it lies on (the side of the diagonal ``T_near P_far`` the far tip is on,
which never changes on a component). A crossing is transversal where no carried-back circle
intersection is tangent (a tip with its rotor and coupler on one line: the far rotor at an
extreme) and the gate four-bar is not flat; within ``rtol`` of either, the count is not decided
here (None). Transversal crossings also leave no critical point: a self-stress vanishes on
the gate's bars unless ``R`` is at an end, and there it would need ``d`` stationary along the
chain's motion, which is the tangency excluded.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: Most cells between the driver and the gate the rule walks: every choice of assembly mode in
#: them is evaluated (2^k of them), a bounded cost.
MAX_PATH_CELLS = 12


@dataclass(frozen=True)
class GateTransfer:
    """Over every choice of assembly mode in the cells between the driver and the gate and both
    slider places: ``turning`` the components that are graphs over the driver's angle (it
    turns once on each), ``folded`` those on an arc of it (no rotor turns); the chain's other
    cells multiply both by two each."""

    turning: int
    folded: int


def _meet(c0: np.ndarray, r0: float | np.ndarray, c1: np.ndarray, r1: float | np.ndarray,
          side: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The intersection of circles ``(c0, r0)`` and ``(c1, r1)``, ``c0``/``c1`` (N, 2), on
    ``side`` (N,) of the line from ``c0`` to ``c1`` (+1: left); and ``h^2`` (N,) (the squared
    half chord: negative where they do not meet)."""
    d = c1 - c0
    dist = np.hypot(d[:, 0], d[:, 1])
    along = (dist**2 + np.square(r0) - np.square(r1)) / (2 * dist)
    h2 = np.square(r0) - along**2
    unit = d / dist[:, None]
    normal = np.column_stack([-unit[:, 1], unit[:, 0]])
    h = np.sqrt(np.maximum(h2, 0.0))
    return c0 + along[:, None] * unit + (side * h)[:, None] * normal, h2


def _cross(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    return np.asarray(u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0])


def gate_transfer(pins: np.ndarray, r: np.ndarray, couplers: np.ndarray, driver: int, gate: int,
                  sliders: np.ndarray, l2: float, l1: float, rtol: float
                  ) -> GateTransfer | None:
    """The components of a gated chain driven from rotor ``driver`` (see the module
    docstring), or None where a crossing is within ``rtol`` (relative to the longest length)
    of tangent or the path is longer than :data:`MAX_PATH_CELLS`.

    ``pins`` (n, 2) and ``r`` (n,) the chain's pins and rotor lengths in chain order,
    ``couplers`` (n - 1,) the bars between consecutive tips, ``sliders`` (s, 2) the slider's
    places (at distance ``D`` from ``pins[gate]``), ``l2``, ``l1`` the gate's bars.

    Examples
    --------
    Rotor 0 (0.3) drives; the gate rotor 1 (0.8) rocks; the slider at ``(1, -+2)``, ``L2 = 2``:

    >>> pins = np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]])
    >>> r, couplers = np.array([0.3, 0.8, 1.5]), np.array([1.0, 1.5])
    >>> sliders = np.array([[1.0, -2.0], [1.0, 2.0]])
    >>> [gate_transfer(pins, r, couplers, 0, 1, sliders, 2.0, l1, 1e-9) for l1 in (0.49, 1.4)]
    [GateTransfer(turning=0, folded=2), GateTransfer(turning=8, folded=0)]
    """
    step = 1 if gate >= driver else -1
    path = [(k, k + step) for k in range(driver, gate, step)]  # (near, far) rotors
    if len(path) > MAX_PATH_CELLS:
        return None
    coupler = [float(couplers[min(a, b)]) for a, b in path]
    scale = float(max(r.max(), couplers.max(), l1, l2,
                      np.abs(sliders - pins[gate]).max(initial=0.0)))
    flat = 2 * rtol * scale * scale  # a length margin rtol * scale, as h^2 ~ 2 r delta
    lo, hi = abs(l2 - l1), l2 + l1
    pg, rg = pins[gate], float(r[gate])
    n_modes = 2 ** len(path)
    turning = folded = 0
    # every mode's gate tip at theta_driver = 0 (the driver rule: every cell closes there)
    tip = np.tile(pins[driver] + np.array([float(r[driver]), 0.0]), (n_modes, 1))
    for bit, ((_, far), lk) in enumerate(zip(path, coupler, strict=True)):
        side = np.where((np.arange(n_modes) >> bit) & 1, 1.0, -1.0)
        tip, _ = _meet(tip, lk, np.tile(pins[far], (n_modes, 1)), float(r[far]), side)
    for g in sliders:
        w = pg - g
        dist, psi = float(np.hypot(*w)), float(np.arctan2(w[1], w[0]))
        angles = []
        for c in (lo, hi):
            cos = (c * c - rg * rg - dist * dist) / (2 * rg * dist)
            if abs(abs(cos) - 1) <= rtol * 4:
                return None  # the gate four-bar flat: not generic
            if abs(cos) < 1:
                angles += [psi + np.arccos(cos), psi - np.arccos(cos)]
        crossings = _carry_back(pins, r, path, coupler, np.array(angles), gate, flat)
        if crossings is None:
            return None
        d = np.hypot(*(tip - g).T)
        if np.any(np.minimum(np.abs(d - lo), np.abs(d - hi)) <= rtol * scale):
            return None  # the driver's zero angle on an end: undecided here
        inside = (d > lo) & (d < hi)
        if np.any(crossings % 2):
            return None  # (transversal crossings on a circle come in pairs)
        turning += 2 * int(np.sum(inside & (crossings == 0)))
        folded += int(np.sum(crossings)) // 2
    return GateTransfer(turning, folded)


def _carry_back(pins: np.ndarray, r: np.ndarray, path: list[tuple[int, int]],
                coupler: list[float], angles: np.ndarray, gate: int, flat: float
                ) -> np.ndarray | None:
    """The number of crossings on each mode (2^len(path),): the gate rotor at ``angles``
    carried back to the driver through every cell (both intersections, each on the mode it
    lies on); None where an intersection is within ``flat`` of tangent."""
    tips = pins[gate] + float(r[gate]) * np.column_stack([np.cos(angles), np.sin(angles)])
    modes = np.zeros(len(tips), dtype=np.int64)
    for bit in range(len(path) - 1, -1, -1):
        near, far = path[bit]
        both = np.concatenate([tips, tips])
        side = np.repeat([1.0, -1.0], len(tips))
        back, h2 = _meet(np.tile(pins[near], (len(both), 1)), float(r[near]), both,
                         coupler[bit], side)
        if np.any(np.abs(h2) <= flat):
            return None  # a tip with its rotor and coupler on one line: tangent
        keep = h2 > 0
        mode_side = _cross(pins[far] - back, both - back)  # the far tip's side of T_near P_far
        bits = (mode_side > 0).astype(np.int64) << bit
        tips, modes = back[keep], (np.concatenate([modes, modes]) | bits)[keep]
    return np.bincount(modes, minlength=2 ** len(path))


def transfer_decision(t: GateTransfer | None, driver: str) -> tuple[bool | None, str]:
    """Whether a gated chain driven from rotor ``driver`` (not the gate's) is gated, and why:
    the driver turns once on a component that is a graph over its whole turn, and on one over
    an arc of it every rotor goes forth and back."""
    if t is None:
        return None, (f"the chain is driven from rotor {driver}, not from the gate rotor, and "
                      "the gate's ends are within the generic margin of tangent along the cells "
                      f"between them (or more than {MAX_PATH_CELLS} cells apart): not decided "
                      "here")
    if t.turning:
        return False, (f"ungated: the chain is driven from rotor {driver}, which completes a "
                       f"turn on {t.turning} of the components the gate closes on over the "
                       "whole turn")
    if not t.folded:
        return None, "no configuration: the gate closes nowhere along the chain's motion"
    return True, (f"gated: the chain is driven from rotor {driver}, and the gate closes on "
                  "arcs of its angle only: on each component every rotor goes forth and back, "
                  "none completes a turn")


def gate_cranks(sides: tuple[float, float, float, float], rtol: float) -> bool:
    """The gate rotor turns fully in the gate four-bar ``sides = (D, r_g, L2, L1)`` with the
    rocker's two places ``R`` apart: ``|T_g - G|`` runs over ``[|r_g - D|, r_g + D]``, strictly
    inside ``(|L2 - L1|, L2 + L1)`` (by ``rtol`` of the longest side). The gate then closes at
    every angle of the gate rotor, twice, and ``L1``, ``L2`` are never on one line: it neither
    restricts the chain nor carries a self-stress.

    Examples
    --------
    >>> gate_cranks((2.0, 1.5, 2.0, 2.0), 1e-9), gate_cranks((3.0, 1.5, 2.0, 2.0), 1e-9)
    (True, False)
    """
    d, r, l2, l1 = sides
    margin = rtol * max(sides)
    return abs(l2 - l1) < abs(r - d) - margin and r + d < l2 + l1 - margin


def cranked_decision(four_bar: tuple[float, float, float, float]) -> tuple[bool, str]:
    """Whether a gated chain whose gate rotor cranks the gate four-bar (:func:`gate_cranks`:
    the gate restricts nothing) and which is driven from its four-bar with ``four_bar`` =
    (ground, rotor, coupler, rotor) is gated, and why. Outwards from that four-bar each rotor
    turns only where its inner neighbour does, so some rotor turns iff one of the four-bar's
    own does: in a Grashof four-bar a rotor turns iff it or the ground is the shortest side;
    in a non-Grashof one no rotor turns.

    Examples
    --------
    >>> cranked_decision((1.0, 1.2, 1.5, 1.2))[0], cranked_decision((1.0, 1.5, 1.2, 1.6))[0]
    (True, False)
    """
    srt = sorted(four_bar)
    shortest = int(np.argmin(np.array(four_bar)))
    if srt[0] + srt[3] < srt[1] + srt[2] and shortest != 2:
        return False, ("ungated: the gate rotor cranks the gate four-bar (which restricts "
                       "nothing) and the chain's driving four-bar is Grashof with a rotor or its "
                       "ground shortest: a rotor completes a turn")
    return True, ("gated: the gate rotor cranks the gate four-bar (which restricts nothing), and "
                  "in the chain's driving four-bar no rotor turns (non-Grashof, or its coupler "
                  "shortest), so none outwards from it does either")
