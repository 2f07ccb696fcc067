"""One homotopy for the linkages a two-degree-of-freedom splitting meshes: ``L`` and
``L +- dL``.

The cone system of :func:`engine.space.surfaces.cones.cone_system` (``f = 0, J^T lambda =
t r, a . lambda = 1``) has as solutions the critical points of the linkage (``t = 0``) and the
critical points of the height ``r . u`` (``t != 0``, the Lagrange system's solutions with
multipliers ``lambda / t``). A splitting needs the first at ``L`` (its cones) and the second
at ``L + dL`` and ``L - dL`` (the seeds of the re-meshings). It solved them with three
homotopies of ``2^E C(M, E)`` paths each (240 for a pentagon); here the lengths move along the
complex line ``L(w) = L + w dL``:

1. the linear-product homotopy of the cone system at a random complex ``w*`` (one
   ``2^E C(M, E)``-path homotopy): with probability one ``w*`` is a generic parameter of the
   family, so its finite nonsingular solutions are all of them, ``N`` (48 for a pentagon);
2. from those ``N`` solutions, a parameter homotopy (:mod:`engine.space.parameter_homotopy`)
   to each of ``w = 0, 1, -1``. By the parameter continuation theorem (Morgan and Sommese,
   1989; Sommese and Wampler, *The Numerical Solution of Systems of Polynomials*, 2005,
   Thm. 7.1.6) every isolated solution at the end is the end of one of these paths (a
   solution of multiplicity ``k``, as a cone's apex is, of ``k`` of them) when the path in
   the parameter avoids the finitely many points of the line where solutions meet, which a
   segment from a random complex ``w*`` does with probability one. So the ends at ``w = 0``
   hold every critical point of the linkage (what :func:`.cones.find_cones` claims), and the
   ends at ``w = +-1`` every critical point of the height there (what
   :func:`engine.space.surfaces.morse.height_witnesses` claims), as long as every path ended.
   (At ``w = 0`` the height's critical points are not taken: at critical lengths some lie
   next to a cone, ill-conditioned beside its double end, and the critical space's meshing
   solves for them on its own.)

The paths: ``2^E C(M, E) + 3 N`` instead of ``3 x 2^E C(M, E)`` (a pentagon: 384 instead of
720), the parameter paths short (the lengths move by ``dL``); a design, whose ``dL`` follows
from the cones, asks for ``w = +-1`` only.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from engine.local.critical import CriticalPoint
from engine.model.budget import Deadline
from engine.model.constraints import Constraints
from engine.model.linkage import Linkage
from engine.model.tolerances import Tolerances
from engine.space.homotopy import REGULAR, SINGULAR, track
from engine.space.linear_product import LinearProduct, bezout
from engine.space.parameter_homotopy import Parameter, follow
from engine.space.surfaces.cones import cone_structure, cone_system, cones_from_ends
from engine.space.surfaces.geometry import Surface
from engine.space.surfaces.morse import HeightWitnesses, classify_points
from engine.space.witnesses import (
    FAR_REACH,
    REAL_TOL,
    SINGULAR_IMAG_TOL,
    _reach,
    bar_quadrics,
)

#: The generic parameter ``w*``: its real part uniform in ``(-REAL, REAL)``, its imaginary
#: part in ``(IMAG_MIN, IMAG_MAX)`` (off the real line, where the lengths are real).
REAL, IMAG_MIN, IMAG_MAX = 1.0, 0.5, 1.5
#: Name of the start in the surfaces' reports.
START = "linear product at generic lengths on the line L + w dL, then parameter"


class LineFamily:
    """The cone system at the lengths ``L(w) = L + w dL`` (each row of ``x`` its own ``w``),
    in the scaled coordinates of ``L`` (:func:`engine.space.witnesses.bar_quadrics`), with
    its derivative in ``w``."""

    def __init__(self, linkage: Linkage, cons: Constraints, d_l: np.ndarray, r: np.ndarray,
                 a: np.ndarray) -> None:
        self.quad, self.scale, self.centre = bar_quadrics(linkage, cons)
        self.l0 = linkage.lengths[cons.bars] / self.scale  # (E,)
        self.dl = np.asarray(d_l, dtype=float)[cons.bars] / self.scale
        self.quad[:, 0, 0] += self.l0 ** 2  # the constant term without the lengths
        self.r, self.a, self.e = r, a, len(self.l0)

    def __call__(self, x: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        lengths = (self.l0[None] + np.asarray(w)[:, None] * self.dl[None]) ** 2  # (N, E)
        return cone_system(self.quad, self.r, self.a, x, lengths)

    def dw(self, x: np.ndarray, w: np.ndarray) -> np.ndarray:
        """The values' derivative in ``w`` (N, E + M + 1): ``-2 (l0 + w dl) dl x0^2`` in the
        bars' rows."""
        out = np.zeros((len(x), x.shape[1] - 1), dtype=complex)
        out[:, :self.e] = -2.0 * (self.l0[None] + w[:, None] * self.dl[None]) * self.dl[None] \
            * (x[:, :1] ** 2)
        return out


class _Segment(Parameter):
    """:class:`engine.space.parameter_homotopy.Parameter` for a system whose derivative in the
    parameter depends on it (the squared lengths are quadratic in ``w``)."""

    def __init__(self, family: LineFamily, w0: complex, w1: complex, patch: np.ndarray
                 ) -> None:
        self.family, self.w0, self.w1, self.patch, self.bump = family, w0, w1, patch, 0.0

    def parts(self, x: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        w = self.w(t)
        f, fx = self.family(x, w)
        full = np.concatenate([fx, np.broadcast_to(self.patch, (len(x), 1, len(self.patch)))],
                              axis=1)
        value = np.concatenate([f, (x @ self.patch - 1.0)[:, None]], axis=1)
        rate = (self.w0 - self.w1) + 1j * self.bump * (1.0 - 2.0 * t)
        return value, full, self.family.dw(x, w) * rate[:, None]


@dataclass(frozen=True)
class LineWitnesses:
    """Outcome of :func:`line_witnesses`: every critical point at ``L`` (``cones``, as
    :func:`engine.space.surfaces.cones.find_cones` gives them) and whether every path to
    ``w = 0`` ended (``ended``), the height ``r`` (M,) and, for each nonzero ``w`` asked, the
    height's critical points at ``L + w dL`` as :func:`engine.space.surfaces.morse.height_witnesses`
    gives them (``heights``), the start's finite solutions ``n_start`` and ``message``."""

    cones: list[CriticalPoint]
    ended: bool
    height: np.ndarray
    heights: dict[float, HeightWitnesses]
    n_start: int
    message: str


def _start(family: LineFamily, w_star: complex, far: float, total: np.ndarray,
           rng: np.random.Generator, deadline: Deadline, e: int, m: int
           ) -> tuple[np.ndarray, bool, str]:
    """The finite nonsingular solutions (N, M + E + 2) at ``w*`` by the linear-product
    homotopy, whether every path ended, and its message."""
    structure, _ = cone_structure(e, m)
    res = track(lambda x: family(x, np.full(len(x), w_star)), total, rng, deadline, far=far,
                start=LinearProduct(structure, total, rng))
    x0 = res.ends[:, 0]
    size = np.linalg.norm(res.ends[:, 1:m + 1], axis=1)
    finite = (res.state == REGULAR) & (np.abs(x0) > 0) & (size <= far * np.abs(x0))
    return res.ends[finite], res.success, res.message


def _heights(at: Linkage, tol: Tolerances, family: LineFamily, ends: np.ndarray,
             state: np.ndarray, ok: bool, message: str, paths: int, m: int
             ) -> HeightWitnesses:
    """The height's critical points at ``at`` (lengths off the critical ones: every solution
    has ``t != 0``) from the parameter homotopy's ends: the near-real ends, refined and
    indexed by :func:`engine.space.surfaces.morse.classify_points`, counted as
    ``height_witnesses`` counts them. Singular ends count too: near a cone of ``L`` the
    perturbed space's neck holds critical points of the height whose multipliers are large,
    and the follower may stop short of such an ill-conditioned end; Newton on the Lagrange
    system then decides (an end that does not refine to a point of its own fails the
    argument)."""
    cons = Constraints(at)
    x0 = ends[:, 0]
    y = ends[:, 1:m + 1] / np.where(np.abs(x0) > 0, x0, np.inf)[:, None]
    size = np.linalg.norm(y, axis=1)
    near = np.isfinite(size) & (size <= _reach(at, cons, family.scale))
    imag = np.linalg.norm(y.imag, axis=1) / np.maximum(size, 1.0)
    real = near & (((state == REGULAR) & (imag <= REAL_TOL))
                   | ((state == SINGULAR) & (imag <= SINGULAR_IMAG_TOL)))
    surface = Surface(at, cons, tol.residual_atol)
    crit = classify_points(surface, family.r, family.centre + family.scale * y[real].real)
    counts = {"paths": paths, "regular": int(((state == REGULAR) & near).sum()),
              "singular": int(((state == SINGULAR) & near).sum()), "real": int(real.sum()),
              "refined": len(crit.points)}
    success = ok and len(crit.points) == int(real.sum())
    why = message or (f"{int(real.sum()) - len(crit.points)} real ends did not refine to "
                      "distinct points")
    return HeightWitnesses(crit, paths, counts, success,
                           "every path ended" if success else why, START)


def line_witnesses(linkage: Linkage, d_l: np.ndarray, tol: Tolerances,
                   rng: np.random.Generator, deadline: Deadline,
                   at: tuple[float, ...] = (0.0, 1.0, -1.0),
                   height: np.ndarray | None = None) -> LineWitnesses:
    """Every critical point of the linkage at ``L`` (where ``0`` is in ``at``) and of a random
    height at ``L + w dL`` for each other ``w`` in ``at`` (module docstring; those lengths must
    not be critical); ``height``: the unit height ``r`` (M,), else drawn from ``rng``.

    Examples
    --------
    The pentagon with its bar P0 P1 pinned at lengths (2, 1, 1, 1, 1) has four cones (its
    collinear configurations); every path ends at ``L`` and at ``L +- dL``:

    >>> from engine.model.linkage import build_linkage, VertexSpec, BarSpec
    >>> pts = {"P0": (0, 0), "P1": (2, 0), "A": (2.5, 0.8), "B": (1.6, 1.3), "C": (0.7, 0.7)}
    >>> vs = [VertexSpec(k, p, k in ("P0", "P1")) for k, p in pts.items()]
    >>> ends = [("P0", "P1"), ("P1", "A"), ("A", "B"), ("B", "C"), ("C", "P0")]
    >>> bs = [BarSpec(f"b{i}", e, x) for i, (e, x) in enumerate(zip(ends, (2, 1, 1, 1, 1)))]
    >>> from engine.model.budget import NEVER
    >>> lw = line_witnesses(build_linkage(2, vs, bs), np.array([0, 0, 0.01, 0, 0]),
    ...                     Tolerances(), np.random.default_rng(0), NEVER)
    >>> len(lw.cones), lw.ended, [(w, h.success) for w, h in lw.heights.items()]
    (4, True, [(1.0, True), (-1.0, True)])
    """
    cons = Constraints(linkage)
    e, m = cons.n_constraints, cons.n_free
    r = rng.normal(size=m) if height is None else np.asarray(height, dtype=float)
    r = r / np.linalg.norm(r)
    family = LineFamily(linkage, cons, d_l, r, rng.normal(size=e))
    w_star = complex(rng.uniform(-REAL, REAL), rng.uniform(IMAG_MIN, IMAG_MAX))
    structure, total = cone_structure(e, m)
    paths = bezout(structure)
    far = 10.0 * FAR_REACH * _reach(linkage, cons, family.scale)
    start, ok, message = _start(family, w_star, far, total, rng, deadline, e, m)
    patch = rng.normal(size=e + m + 2) + 1j * rng.normal(size=e + m + 2)
    patch /= np.linalg.norm(patch)
    x = start / (start @ patch)[:, None]
    cones: list[CriticalPoint] = []
    ended = False
    heights: dict[float, HeightWitnesses] = {}
    for w in at:
        hom = _Segment(family, w_star, complex(w), patch)
        ends, state, why = follow(hom, x, deadline)
        done = ok and not why
        if w == 0:
            cones = cones_from_ends(linkage, tol, ends, state, family.scale, family.centre)
            ended = done
            continue
        text = "; ".join(s for s in (message if not ok else "", why) if s)
        here = linkage.with_lengths(linkage.lengths + w * np.asarray(d_l, dtype=float))
        heights[w] = _heights(here, tol, family, ends, state, done, text, paths, m)
    return LineWitnesses(cones, ended, r, heights, len(start), message)
