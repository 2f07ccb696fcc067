"""The labels of a map's region (for :mod:`.slice_regions`), as the paper labels Fig. 5b.

A region is explored at one sample point; its label says what designers ask of it:

* ``components``: the number of components, exact where the rules of
  :mod:`engine.space.chain_count` count them (rotor chains, chains with the paper's gate) or the
  exploration's argument proves the traced count, else the traced count as a lower bound
  (``components_exact`` False);
* ``cells``: the tau signs of each four-bar cell (:mod:`engine.space.four_bar_cells`), the gate
  four-bar first (the paper's Fig. 5b labels);
* ``gated`` (chains with a gate): whether no rotor completes a turn on any component, decided from
  the gate four-bar and the chain's cells (:func:`engine.space.chain_count.gate_decision`), not from
  what was traced; None with the reason where that cannot be decided;
* ``windings``: the distinct patterns of the rotors' full turns on the traced components.

Where the chain rules also give every component's turns (:func:`engine.design.sweep_rules.
derive`), :func:`derived_label` labels the point from them without any tracing.
"""

from __future__ import annotations

from dataclasses import dataclass

from engine.design.sweep_rules import DerivedRow
from engine.model.budget import ARGUMENT_DERIVED, Argument
from engine.model.linkage import Linkage
from engine.model.report import count_text
from engine.space.chain_count import gate_decision, gated_chain
from engine.space.configuration_space import SpaceResult, rotor_angles, winding
from engine.space.four_bar_cells import FourBarCell, four_bar_cells
from engine.space.gated_count import exact_components


@dataclass(frozen=True)
class RegionLabel:
    """What a region's sample point is (see the module docstring): ``traced`` components were
    traced (None: none was, the label is derived); ``components_rule`` names the rule that
    counts them exactly (None: no rule)."""

    components: int
    components_exact: bool
    traced: int | None
    components_rule: str | None
    cells: tuple[FourBarCell, ...]
    gated: bool | None
    gated_reason: str | None
    windings: tuple[str, ...]


def winding_patterns(linkage: Linkage, result: SpaceResult) -> tuple[str, ...]:
    """The distinct patterns ``"r0:1,r1:0,..."`` of each rotor's number of full turns (``?``:
    not a closed curve) on the traced components, sorted."""
    patterns = set()
    for comp in result.components:
        angles = rotor_angles(linkage, comp.points)
        patterns.add(",".join(
            f"{b}:{abs(w) if (w := winding(a, comp.closed)) is not None else '?'}"
            for b, a in angles.items()))
    return tuple(sorted(patterns))


def touched_cells(linkage: Linkage, names: tuple[str, ...] = ()) -> tuple[FourBarCell, ...]:
    """The four-bar cells (:func:`engine.space.four_bar_cells.four_bar_cells`, the gate first)
    whose sides one of ``names`` sets: a bar of a cell (or the gate's ground ``D``); a name
    that is not a bar of ``linkage`` (a preset's parameter, e.g. the pin spacing ``a`` or the
    rotors' ``r``) may set any side, so it touches every cell; no names: every cell. A map's
    regions and a sweep's rows are labelled with these (the other cells have the same signs
    at every point).

    Examples
    --------
    >>> from engine.catalogue.presets import build_preset
    >>> lk = build_preset("gated-kl-chain", {"n": 3, "gate": 1, "D": 3.0})
    >>> [(c.name, c.signs) for c in touched_cells(lk, ("L2", "D"))]
    [('gate', (1, 1, -1))]
    >>> len(touched_cells(lk, ("a",)))
    3
    """
    wanted = set(names)
    if not wanted or wanted - set(linkage.bar_ids):
        return tuple(four_bar_cells(linkage))
    return tuple(c for c in four_bar_cells(linkage, wanted) if c.touches(wanted))


def label_region(linkage: Linkage, result: SpaceResult, axes: tuple[str, ...] = ()
                 ) -> RegionLabel:
    """The label of the region whose sample is ``linkage`` (at the sample's lengths), explored
    as ``result``; with ``axes`` (the map's bars) only the cells those bars are sides of (the
    others have the same signs in every region of the map: a chain of 20000 rotors would
    repeat 19999 cells in every region).

    Examples
    --------
    >>> from engine.catalogue.presets import build_preset
    >>> from engine.space.configuration_space import explore
    >>> lk = build_preset("four-bar", {"L2": 1.2, "L1": 0.5})
    >>> lab = label_region(lk, explore(lk))
    >>> lab.components, lab.components_exact, lab.cells[0].signs, lab.gated
    (2, True, (1, 1, 1), None)
    """
    traced = len(result.components)
    count = exact_components(linkage)
    complete = result.search.complete
    if count is not None:
        components, exact, rule = count.components, True, count.rule
    else:
        components, exact, rule = traced, complete, None
    gated, reason = None, None
    if gated_chain(linkage) is not None:
        decision = gate_decision(linkage)
        gated, reason = decision.gated, decision.reason
    cells = touched_cells(linkage, axes)
    return RegionLabel(components, exact, traced, rule, cells, gated, reason,
                       winding_patterns(linkage, result))


def derived_label(linkage: Linkage, row: DerivedRow, axes: tuple[str, ...] = ()
                  ) -> RegionLabel | None:
    """The label of a sample point from the chain rules alone (``row``: the components, the
    rule and every component's rotor turns), nothing traced; None where the rules do not give
    the turns (the point is then explored).

    Examples
    --------
    >>> from engine.catalogue.presets import build_preset
    >>> from engine.design.sweep_rules import derive
    >>> lk = build_preset("gated-kl-chain", {"n": 3, "gate": 1, "D": 3.0})
    >>> lab = derived_label(lk, derive(lk))
    >>> lab.components, lab.traced, lab.windings, lab.gated
    (8, None, ('r0:0,r1:0,r2:0,D:0',), True)
    """
    windings = row.windings
    if windings is None:
        return None
    wanted = set(axes) if axes else None
    cells = tuple(c for c in four_bar_cells(linkage, wanted) if wanted is None or c.touches(wanted))
    gate = gated_chain(linkage) is not None  # (label_region's gated: chains with a gate only)
    return RegionLabel(row.components, True, None, row.rule, cells, row.gated if gate else None,
                       row.gated_reason if gate else None, windings)


def label_signature(label: RegionLabel, result: SpaceResult | None
                    ) -> tuple[str, Argument | None]:
    """A region's ``signature`` (its count, exact or a bound, and the winding patterns: it tells
    topologies apart) and the argument that makes its count exact (None: a lower bound);
    ``result`` None for a :func:`derived_label`."""
    if result is None:
        return (f"components={count_text(label.components)}; turns={'|'.join(label.windings)}",
                ARGUMENT_DERIVED)
    if label.components_exact and label.components_rule is not None:
        argument: Argument | None = (result.search.argument if result.search.complete
                                     else ARGUMENT_DERIVED)
    else:
        argument = result.search.argument if result.search.complete else None
    if label.components_exact:
        shown = count_text(label.components)
        if label.traced is not None and label.traced != label.components:
            shown += f" ({label.traced} traced)"
    else:
        shown = f">={label.traced} (incomplete: {result.search.reason})"
    return f"components={shown}; turns={'|'.join(label.windings)}", argument
