"""The cones of a two-degree-of-freedom configuration space: finding every one, laying out the
mesh around each, and what each adds to the Morse count.

A cone is a critical point with one self-stress ``sigma`` where ``Q`` (the stress's Hessian on
the ``D + 1 = 3`` zero modes) is indefinite: to second order the space near it is the quadratic
cone ``gamma^T Q gamma = 0`` in the zero-mode coordinates ``gamma`` (``u = u* + Z^T gamma`` plus
higher order), two *nappes* (discs) meeting at the apex ``u*``; as a complex the critical space
is a surface with its apexes pinched (each apex's link is two circles, one per nappe).

**Every cone** is found by homotopy (:func:`find_cones`), not only near a mesh: a critical
point solves ``f(u) = 0, J(u)^T lambda = 0`` for a nonzero ``lambda``; with a random ``r`` and
one more unknown ``t`` the square system ``f = 0, J^T lambda = t r, a . lambda = 1`` has the
critical points as its solutions with ``t = 0`` (the others are critical points of the height
``r . u``). It is bihomogeneous in ``(u, (lambda, t))`` with the Lagrange system's structure,
so its linear product has ``2^E C(M, E)`` paths (240 for a pentagon).

**The mesh around a cone** (:func:`cone_fans`): with ``Q = diag(lam)`` in its eigenbasis, two
eigenvalues ``lam_i, lam_j`` share a sign and ``lam_k`` has the other; the cone's lines are
``gamma(theta) = (cos theta / sqrt|lam_i|, sin theta / sqrt|lam_j|, +-1 / sqrt|lam_k|)``
(normalised), ``+`` on one nappe and ``-`` on the other. Each nappe gets a fan: the apex and a
ring of points along lines spaced evenly in arc length, projected onto the lengths; the marching
method (:mod:`.mesh`) grows the mesh outwards from the rings' fronts, so it passes through the
apex as the curve tracer passes through a branch point, instead of cutting across the cone.
A cone's features (the gap between its nappes, a nappe's breadth, its radius of curvature
across the lines) are its :func:`cone_width` ``w`` times the distance ``r`` to the apex, and
``w`` goes to zero with the smallest ``|lam|`` against the others (a nearly flat or narrow
cone): the step near the apex is graded as ``w r`` (:class:`.mesh.Fan`), and the rings sit
where the quadratic cone still holds (:func:`cone_fans`).

**Morse count** (:func:`cone_morse_term`): on a surface with cones a generic height ``h``
satisfies ``chi = sum_smooth (-1)^index + sum_apexes (1 - cut)`` (stratified Morse theory: the
apex's Morse data is the cone on its lower link, of Euler characteristic ``1 - chi(lower
link)``), where ``cut`` counts the nappes whose link circle the level ``h = h(u*)`` cuts (an
arc below: ``chi`` 1; a nappe wholly above or below adds a circle or nothing, ``chi`` 0).
"""

from __future__ import annotations

import numpy as np

from engine.local.critical import CriticalPoint, classify, refine_critical
from engine.model.budget import NEVER, Deadline
from engine.model.constraints import Constraints
from engine.model.linkage import Linkage
from engine.model.tolerances import Tolerances
from engine.space.homotopy import REGULAR, SINGULAR, track
from engine.space.linear_product import LinearProduct, Structure, bezout
from engine.space.surfaces.geometry import Surface
from engine.space.surfaces.mesh import Fan
from engine.space.witnesses import FAR_REACH, SINGULAR_IMAG_TOL, _reach, bar_quadrics

#: ``|t|`` (``|r| = 1``) below which an end is a critical-point candidate (a singular end is
#: only within about ``sqrt(T_END)`` of its point: 4e-4 on a pentagon's cone; refinement by
#: Newton then decides).
T_TOL = 1e-2
#: Samples of a cone's link circle (its lines, by angle) from which the rings are spaced and
#: the level's cut is read.
LINK_SAMPLES = 720
#: Fewest points of a ring around an apex (the marching method closes a front of three at
#: once: a ring of three would cap its nappe with one triangle).
RING_MIN = 5
#: Near an apex the step is this times the cone's :func:`cone_width` times the distance to
#: the apex (:class:`.mesh.Fan`): the other nappe (or the far side of its own) is then over
#: two steps away, and an edge leaves the tangent planes by under 30 degrees.
GRADE = 1.0
#: A ring point may move at most this times the cone's width times the ring's radius when
#: it is projected onto the lengths (it stays on its own nappe, near its own line: the
#: quadratic cone holds there); otherwise the ring is put at half the radius.
RING_MOVE = 0.25
#: Times a ring's radius is halved at most.
RING_HALVINGS = 4


def cone_system(quad: np.ndarray, r: np.ndarray, a: np.ndarray, x: np.ndarray,
                lengths: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The values (N, E + M + 1) and Jacobians (N, E + M + 1, M + E + 2) of ``f = 0,
    J^T lambda = t r, a . lambda = 1`` (module docstring) at ``x`` (N, M + E + 2): ``X = (x_0,
    y, mu, t)`` in the scaled coordinates of ``quad`` (:func:`engine.space.witnesses.
    bar_quadrics`); ``lengths`` (N, E): each row's scaled squared lengths, where they differ
    from those in ``quad`` (whose ``[a, 0, 0]`` then holds the rest of the constant term)."""
    e, m = len(quad), quad.shape[1] - 1
    xu, mu, t = x[:, :m + 1], x[:, m + 1:m + 1 + e], x[:, -1]
    g = np.einsum("amn,pn->pam", quad, xu)  # (N, E, M + 1)
    x0 = x[:, 0]
    if lengths is not None:
        g[:, :, 0] -= lengths * x0[:, None]
    f = np.concatenate([np.einsum("pam,pm->pa", g, xu),
                        2 * np.einsum("pa,pam->pm", mu, g[:, :, 1:]) - (t * x0)[:, None] * r,
                        (mu @ a - x0)[:, None]], axis=1)
    jac = np.zeros((len(x), e + m + 1, m + e + 2), dtype=complex)
    jac[:, :e, :m + 1] = 2 * g
    jac[:, e:e + m, :m + 1] = 2 * np.einsum("pa,amn->pmn", mu, quad[:, 1:, :])
    jac[:, e:e + m, 0] -= t[:, None] * r
    jac[:, e:e + m, m + 1:m + 1 + e] = 2 * g[:, :, 1:].transpose(0, 2, 1)
    jac[:, e:e + m, -1] = -x0[:, None] * r
    jac[:, -1, m + 1:m + 1 + e] = a
    jac[:, -1, 0] = -1
    return f, jac


def cone_structure(e: int, m: int) -> tuple[Structure, np.ndarray]:
    """The bihomogeneous structure of :func:`cone_system` (groups ``y`` and ``(mu, t)``) and
    its total degrees."""
    structure = Structure((np.arange(1, m + 1), np.arange(m + 1, m + e + 2)),
                          np.array([[2, 0]] * e + [[1, 1]] * m + [[0, 1]]))
    return structure, np.array([2] * (e + m) + [1])


def cone_paths(e: int, m: int) -> int:
    """The paths of :func:`find_cones`'s homotopy for ``E`` bars and ``M`` free coordinates:
    the linear product's ``2^E C(M, E)`` (240 for a pentagon, 4,608 for a spherical
    five-bar)."""
    return bezout(cone_structure(e, m)[0])


def find_cones(linkage: Linkage, tol: Tolerances, rng: np.random.Generator,
               deadline: Deadline = NEVER, paths_max: int | None = None
               ) -> tuple[list[CriticalPoint], bool]:
    """Every critical point (module docstring), refined and classified; and whether every path
    of the homotopy ended. Where its :func:`cone_paths` exceed ``paths_max`` (None: no bound)
    no path is run: nothing found, not ended."""
    cons = Constraints(linkage)
    e, m = cons.n_constraints, cons.n_free
    if paths_max is not None and cone_paths(e, m) > paths_max:
        return [], False
    quad, scale, centre = bar_quadrics(linkage, cons)
    r = rng.normal(size=m)
    r /= np.linalg.norm(r)
    a = rng.normal(size=e)
    structure, total = cone_structure(e, m)
    assert bezout(structure) > 0
    res = track(lambda x: cone_system(quad, r, a, x), total, rng, deadline,
                far=FAR_REACH * _reach(linkage, cons, scale),
                start=LinearProduct(structure, total, rng))
    return cones_from_ends(linkage, tol, res.ends, res.state, scale, centre), res.success


def cones_from_ends(linkage: Linkage, tol: Tolerances, ends: np.ndarray, state: np.ndarray,
                    scale: float, centre: np.ndarray) -> list[CriticalPoint]:
    """The critical points among the ends (P, M + E + 2) of :func:`cone_system`'s paths (their
    ``state``): the near-real finite ends with ``t`` near 0, refined, classified, without
    repeats, in the order of their coordinates (:func:`refined_points`)."""
    m = Constraints(linkage).n_free
    x0 = ends[:, 0]
    y = ends[:, 1:m + 1] / np.where(np.abs(x0) > 0, x0, np.inf)[:, None]
    t = ends[:, -1] / np.where(np.abs(x0) > 0, x0, np.inf)
    ok = np.isin(state, (REGULAR, SINGULAR)) & np.isfinite(y).all(axis=1)
    near_real = np.linalg.norm(y.imag, axis=1) <= SINGULAR_IMAG_TOL * np.maximum(
        np.linalg.norm(y, axis=1), 1.0)
    cand = ok & near_real & (np.abs(t) <= T_TOL)
    return refined_points(linkage, tol, centre + scale * y[cand].real)


def refined_points(linkage: Linkage, tol: Tolerances, candidates: np.ndarray
                   ) -> list[CriticalPoint]:
    """The critical points the ``candidates`` (N, M) refine to by Newton, classified, without
    repeats, in the order of their coordinates (rounded well above the refinement's error),
    not of the candidates: the cones' numbers, which a design names, do not depend on the
    method's seed or paths."""
    cons = Constraints(linkage)
    m = cons.n_free
    found: list[CriticalPoint] = []
    same = 1e-6 * float(np.median(linkage.lengths[cons.bars]))
    for u0 in np.asarray(candidates, dtype=float).reshape(-1, m):
        ref = refine_critical(cons, u0, tol)
        if not ref.critical or any(np.linalg.norm(cp.u - ref.u) <= same for cp in found):
            continue
        found.append(CriticalPoint(ref.u, classify(linkage, ref.u, tol), ref.length_residual,
                                   ref.stress_residual))
    key = np.round(np.array([cp.u for cp in found]).reshape(len(found), m) / same, 0)
    order = np.lexsort(key.T[::-1]) if len(found) else np.zeros(0, dtype=np.int64)
    return [found[int(k)] for k in order]


def is_cone(cp: CriticalPoint) -> bool:
    """One self-stress and ``Q`` indefinite on three zero modes: a cone of the surface."""
    q = cp.analysis.q_eigenvalues
    return (cp.analysis.self_stress is not None and q is not None and len(q) == 3
            and bool(q.max() > 0 > q.min()))


def _lines(cp: CriticalPoint) -> tuple[np.ndarray, np.ndarray]:
    """The cone's unit lines in the zero-mode coordinates, ``LINK_SAMPLES`` per nappe
    ``(2, S, 3)`` (nappe ``+`` first), and its zero modes ``Z`` (3, M)."""
    lam = np.asarray(cp.analysis.q_eigenvalues)
    z = np.asarray(cp.analysis.zero_modes)
    signs = np.sign(lam)
    k = next(i for i in range(3) if (signs == signs[i]).sum() == 1)
    i, j = (a for a in range(3) if a != k)
    theta = np.linspace(0.0, 2 * np.pi, LINK_SAMPLES, endpoint=False)
    out = np.zeros((2, LINK_SAMPLES, 3))
    for n, side in enumerate((1.0, -1.0)):
        out[n, :, i] = np.cos(theta) / np.sqrt(abs(lam[i]))
        out[n, :, j] = np.sin(theta) / np.sqrt(abs(lam[j]))
        out[n, :, k] = side / np.sqrt(abs(lam[k]))
    return out / np.linalg.norm(out, axis=2, keepdims=True), z


def cone_width(cp: CriticalPoint) -> float:
    """The cone's smallest feature at unit distance from its apex: half the least distance
    between the two nappes' unit lines, half the least across one nappe (its lines at
    ``theta`` and ``theta + pi``), and the least radius of curvature across the lines (one
    over the link's largest geodesic curvature on the unit sphere: a cone's curvature across
    its lines at distance ``r`` is ``k_g / r``). All three scale with the distance, and go
    to zero as the smallest ``|lam|`` does against the others (a flat cone's nappes nearly
    touch along a sharp edge, a narrow one's are thin tubes)."""
    lines, _ = _lines(cp)
    between = float(np.sqrt(max(2.0 - 2.0 * float((lines[0] @ lines[1].T).max()), 0.0)))
    across = min(float(np.linalg.norm(n - np.roll(n, LINK_SAMPLES // 2, axis=0),
                                      axis=1).min()) for n in lines)
    bend = 0.0
    for n in lines:  # k_g = c . (c' x c'') / |c'|^3 of the link c(theta), by differences
        d1 = 0.5 * (np.roll(n, -1, axis=0) - np.roll(n, 1, axis=0))
        d2 = np.roll(n, -1, axis=0) - 2.0 * n + np.roll(n, 1, axis=0)
        k = np.abs(np.einsum("si,si->s", n, np.cross(d1, d2))) / np.maximum(
            np.linalg.norm(d1, axis=1) ** 3, 1e-300)
        bend = max(bend, float(k.max()))
    return min(0.5 * between, 0.5 * across, 1.0 / max(bend, 1e-12))


def _ring(surface: Surface, cp: CriticalPoint, nappe: np.ndarray, z: np.ndarray,
          radius: float, spacing: float, move: float) -> np.ndarray | None:
    """One nappe's ring (n, M) at ``radius``, its points about ``spacing`` apart, projected;
    None where a point moves more than ``move`` along the zero modes ``z`` (3, M) (the move
    across them, about ``radius^2``, takes it onto the lengths and leaves its line alone)."""
    gaps = np.linalg.norm(np.roll(nappe, -1, axis=0) - nappe, axis=1)
    arc = np.concatenate([[0.0], np.cumsum(gaps)])
    n = max(RING_MIN, int(round(radius * arc[-1] / spacing)))
    pick = np.searchsorted(arc, np.arange(n) * arc[-1] / n)
    pts = []
    for g in nappe[np.minimum(pick, len(nappe) - 1)]:
        guess = cp.u + radius * (g @ z)
        u, ok = surface.project(guess)
        if not ok or np.linalg.norm(z @ (u - guess)) > move:
            return None
        pts.append(u)
    ring = np.array(pts)
    # the fan (apex, ring[m], ring[m + 1]) positive in the first ring point's frame: the
    # turn from ring[1] - ring[0] to apex - ring[0] counter-clockwise
    fr = surface.frame(ring[0]).basis
    a = (cp.u - ring[0]) @ fr
    b = (ring[1] - ring[0]) @ fr
    return ring if b[0] * a[1] - b[1] * a[0] > 0 else ring[::-1].copy()


def cone_fans(surface: Surface, cp: CriticalPoint, step: float) -> Fan | None:
    """The apex of the cone ``cp``, two rings (n, M) of points on the space, one per nappe,
    counter-clockwise in their positive frames (module docstring), and the slope of the
    step near the apex (:class:`.mesh.Fan`: ``GRADE`` times :func:`cone_width`).

    The rings are one step out, their points the graded step apart (the slope times the
    radius). A ring whose points move more than ``RING_MOVE`` widths times its radius along
    the zero modes when projected (the quadratic cone does not hold there: its error grows as
    ``r^3`` against the width ``|lam| r^2``) is put at half the radius, at most
    ``RING_HALVINGS`` times; None after that.

    Examples
    --------
    >>> import numpy as np
    >>> from engine.model.tolerances import Tolerances
    >>> from engine.model.linkage import build_linkage, VertexSpec, BarSpec
    >>> pts = {"P0": (0, 0), "P1": (2, 0), "A": (2.5, 0.8), "B": (1.7, 1.4), "C": (0.6, 0.8)}
    >>> vs = [VertexSpec(k, p, k in ("P0", "P1")) for k, p in pts.items()]
    >>> bs = [BarSpec(f"b{i}", e, x) for i, (e, x) in enumerate(zip(
    ...     [("P0", "P1"), ("P1", "A"), ("A", "B"), ("B", "C"), ("C", "P0")], (2, 1, 1, 1, 1)))]
    >>> lk = build_linkage(2, vs, bs)
    >>> cones, _ = find_cones(lk, Tolerances(), np.random.default_rng(0))
    >>> fan = cone_fans(Surface(lk), cones[0], 0.25)
    >>> len(fan.rings), fan.slope > 0
    (2, True)
    """
    lines, z = _lines(cp)
    width = cone_width(cp)
    slope = GRADE * width
    radius = step
    for _ in range(RING_HALVINGS + 1):
        rings = [_ring(surface, cp, nappe, z, radius, min(slope * radius, step),
                       RING_MOVE * width * radius) for nappe in lines]
        if all(r is not None for r in rings):
            return Fan(cp.u, [r for r in rings if r is not None], slope)
        radius *= 0.5
    return None


def cone_morse_term(cp: CriticalPoint, c: np.ndarray) -> int:
    """What the apex of the cone ``cp`` adds to the Morse count of the height ``c . u``:
    ``1 - cut`` (module docstring)."""
    lines, z = _lines(cp)
    h = lines @ (z @ c)  # (2, S): the height along each nappe's lines
    cut = int(sum(bool(row.min() < 0 < row.max()) for row in h))
    return 1 - cut


def _link_cycles(triangles: np.ndarray, apex: int) -> list[list[int]]:
    """The apex's link as cycles of vertices, each in the order its triangles
    ``(apex, x, y)`` (counter-clockwise) run: ``x`` then ``y``."""
    nxt: dict[int, int] = {}
    for t in triangles[(triangles == apex).any(axis=1)]:
        k = int(np.flatnonzero(t == apex)[0])
        nxt[int(t[(k + 1) % 3])] = int(t[(k + 2) % 3])
    cycles, seen = [], set()
    for start in nxt:
        if start in seen:
            continue
        cycle, v = [], start
        while v not in seen:
            seen.add(v)
            cycle.append(v)
            v = nxt[v]
        cycles.append(cycle)
    return cycles


def _tube(vertices: np.ndarray, a: list[int], b: list[int]) -> list[tuple[int, int, int]]:
    """Triangles of an annulus between the cycles ``a`` and ``b`` (each in its apex
    triangles' order) that keeps their surface coherently oriented: ``a`` runs forwards and
    ``b`` backwards along it, zipped from their nearest pair by the shorter next diagonal."""
    br = b[::-1]
    d = np.linalg.norm(vertices[a][:, None] - vertices[br][None], axis=2)
    i0, k0 = np.unravel_index(int(np.argmin(d)), d.shape)
    aa = [a[(i0 + i) % len(a)] for i in range(len(a) + 1)]
    bb = [br[(k0 + k) % len(br)] for k in range(len(br) + 1)]
    out: list[tuple[int, int, int]] = []
    i = k = 0
    while i < len(a) or k < len(br):
        step_a = i < len(a) and (k == len(br) or np.linalg.norm(
            vertices[aa[i + 1]] - vertices[bb[k]]) <= np.linalg.norm(
            vertices[aa[i]] - vertices[bb[k + 1]]))
        if step_a:
            out.append((aa[i], aa[i + 1], bb[k]))
            i += 1
        else:
            out.append((bb[k + 1], bb[k], aa[i]))
            k += 1
    return out


def resolve_apexes(vertices: np.ndarray, triangles: np.ndarray, apexes: np.ndarray,
                   sheets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The mesh of a critical space with each apex resolved as a cone resolves under a length
    change (:mod:`engine.design.surface_splitting`): into two sheets, the apex split in two
    (one vertex per nappe, appended); into one, the apex's star replaced by a tube between its
    two link cycles. Returns the vertices (N', M) and triangles (T', 3); only the complex's
    topology is meant (the tube is no mesh of the perturbed space)."""
    x = np.asarray(vertices, dtype=float)
    tri: list[tuple[int, int, int]] = [(int(t[0]), int(t[1]), int(t[2]))
                                       for t in np.asarray(triangles, dtype=np.int64)]
    extra: list[np.ndarray] = []
    for apex, n in zip(np.asarray(apexes).tolist(), np.asarray(sheets).tolist(), strict=True):
        arr = np.asarray(tri, dtype=np.int64).reshape(-1, 3)
        cycles = _link_cycles(arr, apex)
        if len(cycles) != 2 or n not in (1, 2):
            continue
        star = (arr == apex).any(axis=1)
        if n == 2:  # the second nappe's triangles get a copy of the apex
            twin = len(x) + len(extra)
            extra.append(x[apex])
            second = set(cycles[1])
            tri = [t if not star[j] or not set(t) & second
                   else (t[0] if t[0] != apex else twin, t[1] if t[1] != apex else twin,
                         t[2] if t[2] != apex else twin)
                   for j, t in enumerate(tri)]
        else:
            tri = [t for j, t in enumerate(tri) if not star[j]] + _tube(x, cycles[0], cycles[1])
    out = np.vstack([x] + [e[None] for e in extra]) if extra else x
    return out, np.asarray(tri, dtype=np.int64).reshape(-1, 3)
