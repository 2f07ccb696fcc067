"""Every critical point of a two-degree-of-freedom linkage, for its splitting and design: derived
for a five-bar chain, else found by the cone homotopy within its path bound.

**Five-bar chains** (planar, or spherical: :mod:`engine.space.surfaces.five_bar`): the
linkage is critical exactly at the critical points of ``s = |A - C|^2`` on the edge of the
band where the middle vertex is real, found by the 24 paths of the crank-angle systems
(``search.argument = "derived"``) instead of the cone homotopy's ``2^E C(M, E)`` (4,608 for a
spherical five-bar, past the default bound of 512).

**Any other linkage**: the cone homotopy (:func:`engine.space.surfaces.cones.find_cones`),
where its path count is within ``homotopy_paths_max``; over it no path runs and the answer
says so, naming the count and the bound (``argument = "proved"`` when every path ended).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np

from engine.local.critical import CriticalPoint
from engine.model.budget import Deadline
from engine.model.constraints import Constraints
from engine.model.linkage import Linkage
from engine.model.report import count_text
from engine.model.tolerances import Tolerances
from engine.space.surfaces.cones import cone_paths, find_cones, refined_points
from engine.space.surfaces.five_bar import ChainSeeds, chain_seeds, five_bar_chain
from engine.space.surfaces.geometry import Surface


@dataclass(frozen=True)
class CriticalSearch:
    """Every critical point ``found`` (cones or not), whether the search's argument holds
    (``ended``: every one found), that argument (``"derived"`` or ``"proved"``), the
    ``method``, its ``paths``, why it does not hold (``message``, '' where it does) and the
    argument in a sentence (``detail``); ``chain``: a five-bar chain's seeds, which the
    meshing of the critical space need not derive again."""

    found: list[CriticalPoint]
    ended: bool
    argument: Literal["derived", "proved"]
    method: str
    paths: int
    message: str
    detail: str
    chain: ChainSeeds | None = None


def critical_search(linkage: Linkage, tol: Tolerances, paths_max: int,
                    rng: np.random.Generator, deadline: Deadline) -> CriticalSearch:
    """Every critical point of the ``D = 2`` ``linkage`` (module docstring): by the five-bar
    chain's argument where it is one, else by the cone homotopy if its paths are at most
    ``paths_max`` (else none run).

    Examples
    --------
    A spherical five-bar (4,608 paths of the cone homotopy) is derived from 24:

    >>> from engine.model.budget import NEVER
    >>> from engine.model.linkage import build_linkage, VertexSpec, BarSpec
    >>> g2 = (np.cos(2 * np.arcsin(0.6)), np.sin(2 * np.arcsin(0.6)), 0.0)
    >>> pos = {"O": (0, 0, 0), "G1": (1, 0, 0), "G2": g2}
    >>> vs = [VertexSpec(k, p, True) for k, p in pos.items()]
    >>> vs += [VertexSpec(k, p) for k, p in (("A", (0.8, 0.6, 0.0)), ("B", (0.0, 0.8, 0.6)),
    ...                                     ("C", (0.0, 0.6, -0.8)))]
    >>> ends = [("O", "A"), ("O", "B"), ("O", "C"), ("G1", "A"), ("A", "B"), ("B", "C"),
    ...         ("G2", "C")]
    >>> lk = build_linkage(3, vs, [BarSpec(f"b{k}", e) for k, e in enumerate(ends)])
    >>> out = critical_search(lk, Tolerances(), 512, np.random.default_rng(0), NEVER)
    >>> out.argument, out.paths, out.ended
    ('derived', 24, True)
    """
    cons = Constraints(linkage)
    chain = five_bar_chain(linkage, cons)
    if chain is not None:
        seeds = chain_seeds(Surface(linkage, cons, tol.residual_atol), chain, rng, deadline)
        found = refined_points(linkage, tol, seeds.critical)
        ended = seeds.success and len(found) == len(seeds.critical)
        why = seeds.message if not seeds.success else "" if ended else (
            f"{len(seeds.critical) - len(found)} critical points of |A - C|^2 on the band's "
            "edge did not refine to critical points of the linkage")
        return CriticalSearch(found, ended, "derived", "five-bar chain", seeds.paths, why,
                              seeds.detail, seeds)
    paths = cone_paths(cons.n_constraints, cons.n_free)
    if paths > paths_max:
        return CriticalSearch([], False, "proved", "cone homotopy", paths,
                              f"the cone homotopy's {count_text(paths)} paths exceed the "
                              f"bound of {paths_max} (options.homotopy_paths_max): none ran",
                              "")
    found, ended = find_cones(linkage, tol, rng, deadline, paths_max)
    return CriticalSearch(found, ended, "proved", "cone homotopy", paths,
                          "" if ended else "the cones' homotopy did not end on every path",
                          f"every critical point found by the cone homotopy's "
                          f"{count_text(paths)} paths (every path ended)")
