"""Exact number of components of a rotor chain, from its four-bar decomposition.

A *rotor chain* (the Kane-Lubensky chain and its variants with unequal lengths) is a planar
linkage of ``n >= 2`` rotors: tips ``T_k`` (free vertices) each joined to one pin ``P_k`` (a
fully fixed vertex) by a bar of length ``r_k``, consecutive tips joined by couplers of length
``l_k``, and nothing else (bars between two pins are inert). Its configuration space is the
fibred product, over the rotor angles ``theta_k``, of the relations of the four-bars
``P_k T_k T_{k+1} P_{k+1}`` (ground ``a_k = |P_k P_{k+1}|``).

Two cases are counted, both without any tracing:

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

Any other linkage (not a pure chain, sliders, 3D, non-generic or other length regimes) gets
None: the count is then not known in closed form and the explorer's answer stands alone.

Both rules also prove that the configuration space has **no critical point**: a self-stress
would have to vanish on the two bars at an end tip unless they are collinear (which the strict
conditions exclude), and so on inwards tip by tip to the driver, whose rotor alone is left; a
generic four-bar is never flat. The tests check this against the explorer too.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from engine.model.linkage import Linkage

#: Relative margin below which a length condition counts as an equality (non-generic lengths:
#: a configuration space with a singular point, whose components are not counted here).
GENERIC_RTOL = 1e-9


@dataclass(frozen=True)
class ChainCount:
    """The number of components of a rotor chain and why.

    ``rotors`` are the rotor bar ids from one end of the chain to the other; ``driver`` the
    index (in that order) of the rotor whose angle parametrises every component, or None for
    the single four-bar rule."""

    components: int
    rotors: tuple[str, ...]
    driver: int | None
    rule: str


def _chain_order(linkage: Linkage) -> tuple[list[int], list[int], list[int]] | None:
    """Tips, rotor bars and coupler bars in chain order, or None when not a pure chain."""
    if linkage.dimension != 2:
        return None
    fixed = np.asarray(linkage.fixed)
    full = np.asarray(fixed.all(axis=1), dtype=bool)
    if np.any(fixed.any(axis=1) & ~full):  # a slider: not a pure chain
        return None
    tips = np.flatnonzero(~full)
    if len(tips) < 2:
        return None
    rotor_of: dict[int, int] = {}
    links: dict[int, list[tuple[int, int]]] = {int(t): [] for t in tips}
    for k, (i, j) in enumerate(linkage.ends):
        i, j = int(i), int(j)
        if bool(full[i]) and bool(full[j]):
            continue  # inert
        if full[i] != full[j]:
            tip = j if full[i] else i
            if tip in rotor_of:
                return None  # two rotors on one tip
            rotor_of[tip] = k
        else:
            links[i].append((j, k))
            links[j].append((i, k))
    if len(rotor_of) != len(tips):
        return None
    ends = [t for t, nb in links.items() if len(nb) == 1]
    if len(ends) != 2 or any(len(nb) > 2 for nb in links.values()):
        return None
    order, couplers = [min(ends)], []
    while len(order) < len(tips):
        nxt = [(v, k) for v, k in links[order[-1]] if v not in order[-2:-1]]
        if len(nxt) != 1:
            return None
        order.append(nxt[0][0])
        couplers.append(nxt[0][1])
    if len(set(order)) != len(tips) or len(couplers) != len(tips) - 1:
        return None  # a cycle, or tips off the path
    return order, [rotor_of[t] for t in order], couplers


def _strictly_less(x: float, y: float, scale: float) -> bool:
    return x < y - GENERIC_RTOL * scale


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
    pos = np.asarray(linkage.positions, dtype=float)
    pins = [int(linkage.ends[b, 0]) if int(linkage.ends[b, 1]) == t else int(linkage.ends[b, 1])
            for b, t in zip(rotor_bars, tips, strict=True)]
    r = np.array([linkage.lengths[b] for b in rotor_bars], dtype=float)
    lc = np.array([linkage.lengths[b] for b in couplers], dtype=float)
    a = np.array([np.linalg.norm(pos[pins[k + 1]] - pos[pins[k]]) for k in range(len(tips) - 1)])
    n = len(tips)
    ids = tuple(linkage.bar_ids[b] for b in rotor_bars)
    scale = float(max(r.max(), lc.max(), a.max()))
    if np.any(a <= GENERIC_RTOL * scale) or np.any(r <= 0) or np.any(lc <= 0):
        return None

    def crank(k: int, left: bool) -> bool:
        """In four-bar k, the left (or right) rotor turns fully with separate modes."""
        rd, ro = (r[k], r[k + 1]) if left else (r[k + 1], r[k])
        return _strictly_less(abs(lc[k] - ro), abs(rd - a[k]), scale) and \
            _strictly_less(rd + a[k], lc[k] + ro, scale)

    forward = [crank(k, True) for k in range(n - 1)]
    backward = [crank(k, False) for k in range(n - 1)]
    for m in range(n):
        if all(backward[:m]) and all(forward[m:]):
            return ChainCount(2 ** (n - 1), ids, m, "driver rotor: two assembly modes per "
                              "four-bar, each a graph outward from the driver")
    if n == 2:
        sides = np.array([a[0], r[0], lc[0], r[1]])
        signs = np.array(np.meshgrid(*[[1.0, -1.0]] * 3, indexing="ij")).reshape(3, -1).T
        sums = sides[0] + signs @ sides[1:]
        if np.min(np.abs(sums)) <= GENERIC_RTOL * scale:
            return None  # a flat configuration exists: not generic
        srt = np.sort(sides)
        grashof = srt[0] + srt[3] < srt[1] + srt[2]
        return ChainCount(2 if grashof else 1, ids, None,
                          "four-bar: Grashof (2 components) or not (1)")
    return None
