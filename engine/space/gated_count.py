"""Exact component counts of rotor chains with and without the paper's gate, from every rule
of :mod:`engine.space.chain_count` and one more: a gated chain **driven from no rotor** (a
four-bar drives the chain) whose gate rotor **cranks the gate four-bar**.

That case (the corner regions of a gated chain's map in its first rotors' lengths) was counted
only by :func:`engine.design.sweep_rules.derive` for the maps; a configuration-space search at
such a point had no argument (the homotopy has too many paths), so it traced the components
and answered ``complete: false``. The count is the same rule:

* the gate rotor cranks the gate four-bar ``P_g T_g R G`` (ground ``D``, crank ``r_g``,
  coupler ``L2``, rocker ``L1``) with the rocker's two places apart
  (:func:`engine.space.gate_transfer.gate_cranks`): ``|T_g - G|`` stays strictly inside
  ``(|L2 - L1|, L2 + L1)`` at every angle of the gate rotor, so the gate closes at every
  configuration of the chain, in two places of ``R`` that never meet;
* the slider's line crosses the circle of radius ``D`` about ``P_g`` transversally (two
  places of ``G``, :attr:`engine.space.chain_count.GatedChain.slider_positions` = 2), each
  fixed along the motion.

So the gated linkage is four disjoint copies (two places of ``G`` times two of ``R``) of the
chain with its gate left out, each a graph over the chain's configuration space, and its
components are 4 x the chain's (counted by its rules: here a four-bar drives it, or it is one
four-bar). No self-stress reaches the gate (``L1`` and ``L2`` are never on one line, and
``G`` is held transversally), so the chain rules' proof that there is no critical point
carries over.
"""

from __future__ import annotations

from engine.model.linkage import Linkage
from engine.space.chain_count import (
    GENERIC_RTOL,
    ChainCount,
    GatedChain,
    _apart,
    _without_gate,
    chain_components,
    gated_chain,
    gated_chain_components,
)
from engine.space.gate_transfer import gate_cranks


def cranked_gate_components(linkage: Linkage, parts: GatedChain | None = None
                            ) -> ChainCount | None:
    """The exact number of components of a gated chain driven from no rotor whose gate rotor
    cranks the gate four-bar (see the module docstring): 4 x the chain's own count; None where
    that rule does not apply (not a gated chain, driven from a rotor, the gate restricting the
    chain, the slider's places not two, the chain not counted by its rules). ``parts``:
    :func:`~engine.space.chain_count.gated_chain` of ``linkage`` where the caller has it.

    Examples
    --------
    >>> from engine.catalogue.presets import build_preset
    >>> lk = build_preset("gated-kl-chain", {"n": 4, "gate": 2})
    >>> corner = lk.with_lengths([1.2 if b in ("r0", "r1") else x
    ...                           for b, x in zip(lk.bar_ids, lk.lengths)])
    >>> cranked_gate_components(corner).components
    16
    >>> cranked_gate_components(lk) is None  # (driven from the gate rotor: chain_count's rule)
    True
    """
    parts = parts or gated_chain(linkage)
    if parts is None or parts.driver is not None or parts.slider_positions != 2 \
            or _apart(parts.sides) or not gate_cranks(parts.sides, GENERIC_RTOL):
        return None
    count = chain_components(_without_gate(linkage))
    if count is None:
        return None
    d, r, l2, l1 = parts.sides
    return ChainCount(4 * count.components, parts.rotors, None,
                      f"gated chain whose gate rotor cranks the gate four-bar (D {d:g}, r {r:g}, "
                      f"L2 {l2:g}, L1 {l1:g}: the rocker's two places apart, the gate closing "
                      f"at every angle): {count.components} chain components ({count.rule}) x 2 "
                      "places of the rocker x 2 of the slider",
                      cell=count.cell, four_bar=count.four_bar)


def exact_components(linkage: Linkage) -> ChainCount | None:
    """The exact number of components of a rotor chain
    (:func:`~engine.space.chain_count.chain_components`), of a rotor chain with the paper's
    gate driven from a rotor (:func:`~engine.space.chain_count.gated_chain_components`) or
    from a four-bar with a cranked gate (:func:`cranked_gate_components`), None where no rule
    applies (the count is then what a search traced: a lower bound unless its argument proves
    it). Where it is not None the rules also prove there is no critical point.

    Examples
    --------
    >>> from engine.catalogue.presets import build_preset
    >>> exact_components(build_preset("gated-kl-chain", {"n": 4, "gate": 1})).components
    32
    """
    count = chain_components(linkage)
    if count is not None:
        return count
    parts = gated_chain(linkage)
    if parts is None:
        return None
    return gated_chain_components(linkage, parts) or cranked_gate_components(linkage, parts)
