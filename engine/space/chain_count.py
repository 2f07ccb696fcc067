"""Exact number of components of a rotor chain, from its four-bar decomposition.

A *rotor chain* (the Kane-Lubensky chain, any lengths) is a planar linkage of ``n >= 2``
rotors: tips ``T_k`` each joined to a pin ``P_k`` by a bar ``r_k``, consecutive tips by
couplers ``l_k``, nothing else (bars between pins are inert). Its configuration space is the
fibred product, over the rotor angles ``theta_k``, of the four-bars ``P_k T_k T_{k+1}
P_{k+1}`` (ground ``a_k = |P_k P_{k+1}|``). Three cases are counted, none by tracing:

* ``n = 2``, one four-bar with generic lengths (no configuration with all four joints on a
  line, i.e. no signed sum ``+-a +-r_0 +-l +-r_1`` vanishes): 2 components when it satisfies
  Grashof's condition ``s + g < p + q`` (``s``, ``g`` the shortest and longest sides), 1 when
  not (the classical classification of the planar quadrilateral).
* any ``n``, when some rotor ``m`` *drives* the chain: in every four-bar to the right of it the
  left rotor turns fully and the two assembly modes never meet (``|l_k - r_{k+1}| <
  |r_k - a_k|`` and ``r_k + a_k < l_k + r_{k+1}``: the distance from ``T_k`` to ``P_{k+1}``
  stays strictly between ``|l_k - r_{k+1}|`` and ``l_k + r_{k+1}``), and symmetrically to the
  left of it. Then each four-bar relation is two disjoint graphs of smooth functions outward
  from ``m``, so every choice of one graph per four-bar is one circle (a graph over
  ``theta_m``): ``2^(n-1)`` components. The spinner chain (``r = l = 3a/2``) is of this kind.
* any ``n >= 3``, when some four-bar ``k`` (generic: not flat) *drives* the chain: every
  four-bar to its right is driven by its left rotor and every one to its left by its right
  rotor, as above. The four-bar's relation in ``(theta_k, theta_(k+1))`` is its own
  configuration space, 1 or 2 smooth circles (Grashof's rule; 0 where it does not close), and
  each further four-bar outwards is two disjoint graphs over the angle it is driven by: every
  circle of the four-bar times every choice of one graph per other four-bar is one component,
  ``c_k 2^(n-2)``. (A tip's velocity sees a stress on its two bars only where they are
  collinear; outwards of four-bar ``k`` the drive conditions exclude it, tip by tip inwards,
  and four-bar ``k`` alone is never flat: no critical point.)

Any other linkage (not a pure chain, 3D, non-generic, other regimes) gets None: the count is
then not known in closed form and the explorer's answer stands alone.

The rules also prove that the configuration space has **no critical point**: a self-stress
vanishes on the two bars at an end tip unless they are collinear (the strict conditions exclude
it), and so tip by tip inwards to the driver; a generic four-bar is never flat.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from engine.model.linkage import Linkage
from engine.space.gate_transfer import (
    GateTransfer,
    cranked_decision,
    gate_cranks,
    gate_transfer,
    transfer_decision,
)

#: Relative margin below which a length condition counts as an equality (non-generic lengths:
#: a configuration space with a singular point, whose components are not counted here).
GENERIC_RTOL = 1e-9


@dataclass(frozen=True)
class ChainCount:
    """The number of components of a rotor chain and why.

    ``rotors`` are the rotor bar ids from one end of the chain to the other; ``driver`` the
    index (in that order) of the rotor whose angle parametrises every component, or None for
    the four-bar rules; ``cell`` the index of the driving four-bar (rotors ``cell`` and
    ``cell + 1``) where a four-bar drives the chain (None: a rotor drives it, or ``n = 2``);
    ``four_bar`` that four-bar's sides (ground, rotor, coupler, rotor) under the four-bar rules."""

    components: int
    rotors: tuple[str, ...]
    driver: int | None
    rule: str
    cell: int | None = None
    four_bar: tuple[float, float, float, float] | None = None


def _chain_order(linkage: Linkage) -> tuple[list[int], list[int], list[int]] | None:
    """Tips, rotor bars and coupler bars in chain order, or None when not a pure chain
    (vectorised over the bars: a 20,000-rotor chain is ordered in milliseconds)."""
    if linkage.dimension != 2:
        return None
    fixed = np.asarray(linkage.fixed)
    full = np.asarray(fixed.all(axis=1), dtype=bool)
    if np.any(fixed.any(axis=1) & ~full):  # a slider: not a pure chain
        return None
    tips = np.flatnonzero(~full)
    if len(tips) < 2:
        return None
    ends = np.asarray(linkage.ends, dtype=np.intp).reshape(-1, 2)
    fi, fj = full[ends[:, 0]], full[ends[:, 1]]
    rot = np.flatnonzero(fi != fj)
    rotor_tip = np.where(fi[rot], ends[rot, 1], ends[rot, 0])
    if len(rot) != len(tips) or len(np.unique(rotor_tip)) != len(tips):
        return None  # two rotors on one tip, or a tip without a rotor
    link = np.flatnonzero(~fi & ~fj)
    side = np.concatenate([ends[link, 0], ends[link, 1]])
    other = np.concatenate([ends[link, 1], ends[link, 0]])
    bar = np.concatenate([link, link])
    degree = np.bincount(side, minlength=len(full))
    at_end = tips[degree[tips] == 1]
    if len(at_end) != 2 or np.any(degree > 2):
        return None
    by = np.argsort(side, kind="stable")
    first = np.concatenate([[0], np.cumsum(degree)])
    nb_v, nb_b = other[by].tolist(), bar[by].tolist()
    slot = first.tolist()
    order, couplers, prev = [int(at_end[0])], [], -1
    for _ in range(len(tips) - 1):
        cur = order[-1]
        nxt = [(nb_v[s], nb_b[s]) for s in range(slot[cur], slot[cur + 1]) if nb_v[s] != prev]
        if len(nxt) != 1:
            return None
        prev = cur
        order.append(nxt[0][0])
        couplers.append(nxt[0][1])
    if len(set(order)) != len(tips):
        return None  # a cycle, or tips off the path
    rotor_of = np.full(len(full), -1, dtype=np.intp)
    rotor_of[rotor_tip] = rot
    return order, rotor_of[order].tolist(), couplers


def chain_sides(chain: Linkage, found: tuple[list[int], list[int], list[int]]
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The pins (vertex indices, chain order), rotor lengths ``r``, coupler lengths ``l`` and
    pin spacings ``a`` of a chain ordered by :func:`_chain_order`."""
    tips, rotor_bars, couplers = found
    ends = np.asarray(chain.ends, dtype=np.intp).reshape(-1, 2)[rotor_bars]
    pins = ends.sum(axis=1) - np.asarray(tips, dtype=np.intp)
    lengths = np.asarray(chain.lengths, dtype=float)
    pos = np.asarray(chain.positions, dtype=float)
    a = np.linalg.norm(np.diff(pos[pins], axis=0), axis=1)
    return pins, lengths[rotor_bars], lengths[couplers], a


def _driven(r: np.ndarray, lc: np.ndarray, a: np.ndarray, margin: float
            ) -> tuple[np.ndarray, np.ndarray]:
    """``left_ok[m]``: every four-bar left of rotor ``m`` is driven leftwards (its right rotor
    turns fully, its assembly modes apart); ``right_ok[m]``: every one right of it rightwards
    (``n`` entries each: rotor ``m`` drives the chain iff both hold)."""

    def crank(rd: np.ndarray, ro: np.ndarray) -> np.ndarray:
        return np.asarray((np.abs(lc - ro) < np.abs(rd - a) - margin) &
                          (rd + a < lc + ro - margin))

    forward, backward = crank(r[:-1], r[1:]), crank(r[1:], r[:-1])
    left_ok = np.concatenate([[True], np.cumprod(backward).astype(bool)])
    right_ok = np.concatenate([np.cumprod(forward[::-1]).astype(bool)[::-1], [True]])
    return left_ok, right_ok


def chain_components(linkage: Linkage) -> ChainCount | None:
    """The exact number of components of a rotor chain's configuration space (see the module
    docstring for the two rules), or None when neither applies.

    Examples
    --------
    >>> from engine.catalogue.presets import build_preset
    >>> chain_components(build_preset("kl-chain", {"n": 5})).components
    16
    >>> chain_components(build_preset("gated-kl-chain")) is None
    True
    """
    found = _chain_order(linkage)
    if found is None:
        return None
    tips, rotor_bars, couplers = found
    _, r, lc, a = chain_sides(linkage, found)
    n = len(tips)
    ids = tuple(linkage.bar_ids[b] for b in rotor_bars)
    scale = float(max(r.max(), lc.max(), a.max()))
    if np.any(a <= GENERIC_RTOL * scale) or np.any(r <= 0) or np.any(lc <= 0):
        return None
    left_ok, right_ok = _driven(r, lc, a, GENERIC_RTOL * scale)
    drivers = np.flatnonzero(left_ok & right_ok)
    if len(drivers):
        return ChainCount(2 ** (n - 1), ids, int(drivers[0]), "driver rotor: two assembly "
                          "modes per four-bar, each a graph outward from the driver")
    if n == 2:
        sides = (float(a[0]), float(r[0]), float(lc[0]), float(r[1]))
        cell = _four_bar_circuits(np.array(sides), scale)
        if cell is None:
            return None  # a flat configuration exists: not generic
        return ChainCount(cell[0], ids, None, cell[1], four_bar=sides)
    # a four-bar k driving the chain (rotor drivers are tried above)
    for k in np.flatnonzero(left_ok[:-1] & right_ok[1:]).tolist():
        sides = (float(a[k]), float(r[k]), float(lc[k]), float(r[k + 1]))
        cell = _four_bar_circuits(np.array(sides), scale)
        if cell is not None:
            kind = {0: "it does not close", 1: "not Grashof: 1 circuit",
                    2: "Grashof: 2 circuits"}[cell[0]]
            return ChainCount(cell[0] * 2 ** (n - 2), ids, None,
                              f"driving four-bar {ids[k]}-{ids[k + 1]} ({kind}), two "
                              "assembly modes per other four-bar, each a graph outward "
                              "from it", cell=k, four_bar=sides)
    return None


def _four_bar_circuits(sides: np.ndarray, scale: float) -> tuple[int, str] | None:
    """The circuits of a four-bar with ``sides`` (ground, rotor, coupler, rotor) and the rule
    that counts them; None where a flat configuration exists (not generic)."""
    signs = np.array(np.meshgrid(*[[1.0, -1.0]] * 3, indexing="ij")).reshape(3, -1).T
    sums = sides[0] + signs @ sides[1:]
    if np.min(np.abs(sums)) <= GENERIC_RTOL * scale:
        return None
    srt = np.sort(sides)
    if srt[3] > srt[0] + srt[1] + srt[2]:
        return 0, ("four-bar: its longest side exceeds the sum of the other three: it does not "
                   "assemble")
    grashof = srt[0] + srt[3] < srt[1] + srt[2]
    return 2 if grashof else 1, "four-bar: Grashof (2 components) or not (1)"


# -- chains with the paper's gate ------------------------------------------------------------

@dataclass(frozen=True)
class GatedChain:
    """A rotor chain with the paper's gate (Sec. V): a slider ``G`` held at distance ``D`` from
    the pin ``P_g`` of rotor ``gate`` (the rotor bars' order index) by a bar, a rocker ``L1``
    from ``G`` to a free vertex ``R`` and a bar ``L2`` from the gate rotor's tip to ``R``.

    ``G`` moves on a line and ``|G - P_g| = D`` holds it at one of the (generically two)
    points where that line meets the circle about ``P_g``: a four-bar ``P_g T_g R G`` (ground
    ``D``, crank ``r_g``, coupler ``L2``, rocker ``L1``) hangs on the chain at each.
    ``slider_positions`` counts those points (0, 1 or 2).
    """

    rotors: tuple[str, ...]
    gate: int
    sides: tuple[float, float, float, float]  # (D, r_g, L2, L1)
    slider_positions: int
    chain_driven: bool  # the driver rule holds with the gate rotor as driver
    slider_offset: float = 0.0  # distance from P_g to the slider's line
    gate_bars: tuple[str, str, str] = ("", "", "")  # the bar ids of D, L2, L1
    driver: int | None = None  # the rotor the chain is driven from nearest the gate (None: none)
    transfer: GateTransfer | None = None  # (driven from another rotor: its components)


@dataclass(frozen=True)
class GateDecision:
    """Whether the gate stops every rotor from completing a turn (``gated``), or None with the
    ``reason`` it cannot be decided here; ``gate_type`` names the gate four-bar's type."""

    gated: bool | None
    gate_type: str
    reason: str


def _gate_type(sides: tuple[float, float, float, float], scale: float) -> tuple[str, bool | None]:
    """The gate four-bar's Grashof type and whether its crank ``r_g`` turns fully (None where a
    flat configuration exists: a critical length, not generic)."""
    d, r, l2, l1 = sides
    signs = np.array(np.meshgrid(*[[1.0, -1.0]] * 3, indexing="ij")).reshape(3, -1).T
    if np.min(np.abs(d + signs @ np.array([r, l2, l1]))) <= GENERIC_RTOL * scale:
        return "critical (a flat configuration exists)", None
    srt = sorted(sides)
    if srt[0] + srt[3] > srt[1] + srt[2]:
        return "non-Grashof (triple rocker: one circuit, the gate rotor rocks)", False
    shortest = int(np.argmin(np.array(sides)))
    kind = {0: "Grashof double crank (the ground D shortest)",
            1: "Grashof crank-rocker (the gate rotor the crank)",
            2: "Grashof double rocker (the coupler L2 shortest)",
            3: "Grashof rocker-crank (the rocker L1 the crank, the gate rotor rocks)"}[shortest]
    return kind, shortest in (0, 1)


def _apart(sides: tuple[float, float, float, float]) -> bool:
    """The four-bar's longest side exceeds the sum of the others (beyond the flat margin): it
    does not assemble."""
    srt = sorted(sides)
    return srt[3] > srt[0] + srt[1] + srt[2] + GENERIC_RTOL * srt[3]


def _gate_bars(linkage: Linkage) -> tuple[int, int, int, int, int, int, int] | None:
    """The gate's bars ``(D, L1, L2)`` and vertices ``(G, R, P_g, T_g)`` as indices, or None
    when ``linkage`` has no gate (one slider vertex held by one bar to a pin and by a rocker
    to a free vertex joined to one more vertex)."""
    if linkage.dimension != 2:
        return None
    fixed = np.asarray(linkage.fixed, dtype=bool)
    full: np.ndarray = np.asarray(fixed.all(axis=1), dtype=bool)
    sliders = np.flatnonzero(fixed.any(axis=1) & ~full)
    if len(sliders) != 1:
        return None
    g = int(sliders[0])
    ends = np.asarray(linkage.ends)
    at_g = np.flatnonzero((ends == g).any(axis=1))
    if len(at_g) != 2:
        return None
    other = [int(ends[k, 1] if ends[k, 0] == g else ends[k, 0]) for k in at_g]
    if full[other[0]] == full[other[1]]:
        return None
    d_bar, l1_bar = (at_g[0], at_g[1]) if full[other[0]] else (at_g[1], at_g[0])
    pin, rocker = (other[0], other[1]) if full[other[0]] else (other[1], other[0])
    at_r = np.flatnonzero((ends == rocker).any(axis=1))
    if len(at_r) != 2:
        return None
    l2_bar = int(at_r[0] if at_r[1] == l1_bar else at_r[1])
    tip = int(ends[l2_bar, 1] if ends[l2_bar, 0] == rocker else ends[l2_bar, 0])
    return int(d_bar), int(l1_bar), l2_bar, g, rocker, pin, tip


def _strip_gate(linkage: Linkage, bars: tuple[int, int, int, int, int, int, int]
                ) -> tuple[Linkage, np.ndarray]:
    """The linkage without the gate's bars and its vertices ``G``, ``R``, and the new index
    of every old vertex."""
    d_bar, l1_bar, l2_bar, g, rocker = bars[:5]
    fixed = np.asarray(linkage.fixed, dtype=bool)
    ends = np.asarray(linkage.ends)
    keep_v = np.ones(linkage.n_vertices, dtype=bool)
    keep_v[[g, rocker]] = False
    keep_b = ~np.isin(np.arange(linkage.n_bars), [d_bar, l1_bar, l2_bar])
    new_index = np.cumsum(keep_v) - 1
    chain = Linkage(2, tuple(v for v, k in zip(linkage.vertex_ids, keep_v, strict=True) if k),
                    np.asarray(linkage.positions)[keep_v], fixed[keep_v],
                    tuple(b for b, k in zip(linkage.bar_ids, keep_b, strict=True) if k),
                    new_index[ends[keep_b]], np.asarray(linkage.lengths)[keep_b])
    return chain, new_index


def _without_gate(linkage: Linkage) -> Linkage:
    """``linkage`` less its gate (itself when it has none)."""
    bars = _gate_bars(linkage)
    return linkage if bars is None else _strip_gate(linkage, bars)[0]


def gated_chain(linkage: Linkage) -> GatedChain | None:
    """The gated chain's parts, or None when ``linkage`` is not a planar rotor chain with the
    paper's gate (one slider vertex, held by one bar to a pin of the chain, and one free vertex
    joined to it and to that pin's tip)."""
    bars = _gate_bars(linkage)
    if bars is None:
        return None
    d_bar, l1_bar, l2_bar, g, rocker, pin, tip = bars
    fixed = np.asarray(linkage.fixed, dtype=bool)
    chain, new_index = _strip_gate(linkage, bars)
    found = _chain_order(chain)
    if found is None or int(new_index[tip]) not in found[0]:
        return None
    tips, rotor_bars, couplers = found
    gate = tips.index(int(new_index[tip]))
    pins = chain_sides(chain, found)[0].tolist()
    if pins[gate] != int(new_index[pin]):
        return None  # the slider is held from another pin than the gate rotor's
    lengths = np.asarray(linkage.lengths)
    sides = (float(lengths[d_bar]), float(chain.lengths[rotor_bars[gate]]),
             float(lengths[l2_bar]), float(lengths[l1_bar]))
    # the slider's line: through G along its free axis; its points at distance D from P_g
    pos = np.asarray(linkage.positions, dtype=float)
    axis = (~fixed[g]).astype(float)
    off = pos[pin] - pos[g]
    perp = float(np.linalg.norm(off - (off @ axis) * axis))
    scale = max(sides)
    positions = 2 if perp < sides[0] - GENERIC_RTOL * scale else (
        1 if perp <= sides[0] + GENERIC_RTOL * scale else 0)
    drivers = _drivers(chain, found)
    driver = min(drivers, key=lambda m: abs(m - gate)) if drivers else None
    transfer = None
    if driver is not None and driver != gate and positions == 2 and not _apart(sides):
        foot = pos[g] + (off @ axis) * axis
        along = np.sqrt(sides[0] ** 2 - perp**2) * axis
        chain_pos = np.asarray(chain.positions, dtype=float)
        transfer = gate_transfer(chain_pos[pins], np.asarray(chain.lengths)[rotor_bars],
                                 np.asarray(chain.lengths)[couplers], driver, gate,
                                 np.array([foot - along, foot + along]), sides[2], sides[3],
                                 GENERIC_RTOL)
    return GatedChain(tuple(chain.bar_ids[b] for b in rotor_bars), gate, sides, positions,
                      driver == gate, perp,
                      (linkage.bar_ids[d_bar], linkage.bar_ids[l2_bar], linkage.bar_ids[l1_bar]),
                      driver, transfer)


def _drivers(chain: Linkage, found: tuple[list[int], list[int], list[int]]) -> list[int]:
    """The rotors (chain-order indices) from which the driver rule of :func:`chain_components`
    holds."""
    _, r, lc, a = chain_sides(chain, found)
    scale = float(max(r.max(), lc.max(), a.max(initial=0.0)))
    left_ok, right_ok = _driven(r, lc, a, GENERIC_RTOL * scale)
    return [int(m) for m in np.flatnonzero(left_ok & right_ok)]


def gated_chain_components(linkage: Linkage, parts: GatedChain | None = None
                           ) -> ChainCount | None:
    """The exact number of components of a gated rotor chain, or None where the rule does not
    apply (not a gated chain, the chain driven from no rotor, critical lengths). Driven from
    another rotor than the gate's, the count is :mod:`engine.space.gate_transfer`'s; driven
    from none, :func:`engine.space.gated_count.cranked_gate_components` counts it where the gate
    rotor cranks the gate four-bar. ``parts``: :func:`gated_chain` of ``linkage`` where given.

    With the chain driven from the gate rotor (every cell's rotor turns fully outwards from it,
    its two assembly modes apart), each of the chain's ``2^(n-1)`` components is a graph over
    the gate angle ``theta_g``, so its fibred product with a component of the gate four-bar
    (over ``theta_g``) is that component again: the count is ``2^(n-1)`` times the gate
    four-bar's components (2 Grashof, 1 not) times the slider's positions (2). For the paper's
    chain (``r = l = 3a/2``, ``L1 = L2 = 2a``): ``2^(n+1)`` for ``D < 5a/2`` (Grashof, ungated),
    ``2^n`` above (non-Grashof, gated).

    Examples
    --------
    >>> from engine.catalogue.presets import build_preset
    >>> gated_chain_components(build_preset("gated-kl-chain", {"n": 4, "gate": 1})).components
    32
    >>> gated_chain_components(build_preset("gated-kl-chain", {"n": 4, "gate": 1, "D": 3.0})
    ...                        ).components
    16
    """
    parts = parts or gated_chain(linkage)
    if parts is None or parts.driver is None or parts.slider_positions != 2:
        return None
    n = len(parts.rotors)
    if _apart(parts.sides):
        return ChainCount(0, parts.rotors, parts.gate, "gated chain: the gate four-bar's "
                          "longest side exceeds the sum of the other three: it does not assemble")
    _, turns = _gate_type(parts.sides, max(parts.sides))
    if turns is None:
        return None
    if not parts.chain_driven:
        t = parts.transfer
        if t is None:
            return None
        k = abs(parts.driver - parts.gate)
        return ChainCount(2 ** (n - 1 - k) * (t.turning + t.folded), parts.rotors, parts.driver,
                          f"gated chain driven from rotor {parts.rotors[parts.driver]}: 2^"
                          f"{n - 1 - k} modes of the cells beyond the path to the gate rotor x "
                          f"{t.turning} components over a whole turn of the driver and "
                          f"{t.folded} over an arc of it (the gate closing where |T_g - G| "
                          "lies between |L2 - L1| and L2 + L1, its ends found by circle "
                          "intersections carried back from the gate rotor)")
    d, r, l2, l1 = parts.sides
    srt = sorted(parts.sides)
    gate_components = 2 if srt[0] + srt[3] < srt[1] + srt[2] else 1
    return ChainCount(2 ** (n - 1) * gate_components * 2, parts.rotors, parts.gate,
                      f"gated chain: 2^{n - 1} chain components (driven from the gate rotor) x "
                      f"{gate_components} of the gate four-bar (D {d:g}, r {r:g}, L2 {l2:g}, "
                      f"L1 {l1:g}) x 2 slider positions")


def gate_decision(linkage: Linkage, parts: GatedChain | None = None) -> GateDecision:
    """Whether the gate stops every rotor from completing a full turn on every component.

    Decided from the gate four-bar's Grashof type and the chain's cells, not from a trace: with
    the chain driven from the gate rotor every rotor angle is a function of ``theta_g`` on each
    component, so none turns where the gate rotor does not, which turns iff it is a crank of
    the gate four-bar; from another rotor, :mod:`.gate_transfer` decides; from none, where the
    gate rotor cranks the gate four-bar (restricting nothing) and a four-bar drives the chain
    (:func:`~engine.space.gate_transfer.cranked_decision`). Otherwise ``gated`` is None with
    the reason. ``parts``: :func:`gated_chain` of ``linkage`` where the caller has it already.

    Examples
    --------
    >>> from engine.catalogue.presets import build_preset
    >>> gate_decision(build_preset("gated-kl-chain", {"n": 4, "gate": 1, "D": 3.0})).gated
    True
    """
    parts = parts or gated_chain(linkage)
    if parts is None:
        return GateDecision(None, "", "not a planar rotor chain with the paper's gate")
    kind, turns = _gate_type(parts.sides, max(parts.sides))
    if parts.slider_positions == 0:
        return GateDecision(None, kind, "the slider's line does not reach distance D from "
                            "the gate's pin: the linkage does not assemble")
    if _apart(parts.sides):
        return GateDecision(None, "does not assemble", "the gate four-bar's longest side "
                            "exceeds the sum of the other three: it does not assemble")
    if turns is None:
        return GateDecision(None, kind, "the gate four-bar has critical lengths (a flat "
                            "configuration): its branch point joins turning and rocking")
    if parts.driver is None:
        count = chain_components(_without_gate(linkage)) if parts.slider_positions == 2 and \
            gate_cranks(parts.sides, GENERIC_RTOL) else None
        if count is None or count.four_bar is None:
            return GateDecision(None, kind, "the chain is driven from no rotor (in every choice "
                                "of driver some cell outwards turns no rotor fully, or its modes "
                                "meet) and its gate restricts it: not decided here")
        rocks, why = cranked_decision(count.four_bar)
        return GateDecision(rocks, kind, why)
    if not parts.chain_driven:
        gated, why = transfer_decision(parts.transfer, str(parts.rotors[parts.driver]))
        return GateDecision(gated, kind, why)
    if turns:
        return GateDecision(False, kind, "ungated: the gate rotor is a crank of the gate "
                            "four-bar: it completes a turn")
    return GateDecision(True, kind, "gated: the gate rotor rocks in the gate four-bar, and "
                        "every rotor angle is a function of it on each component, so none "
                        "completes a turn")

