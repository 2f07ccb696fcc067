"""Four-bars at critical lengths (parallelogram, anti-parallelogram, kite, rhombus), in the plane
at random scales and rotations and built from hinges in space, against a closed-form enumeration
(issue 11, item 1).

The closed form: with both pins fixed, a self-stress of the three bars must balance at ``B``
(bars ``AB``, ``BC``) and at ``C`` (``BC``, ``CD``), which forces ``A, B, C`` and ``B, C, D`` onto
one line: the critical configurations are exactly the flat ones, ``B = s1 L1`` and
``C = B + s2 L2`` along the ground line with ``|C - a| = L3``. The stress there is
``sigma_i ~ 1/d_i`` (``d`` the signed bar vectors along the line), and the zero modes are the
normal displacements ``(y_B, y_C)``, on which the stress form is

    Q(y) = y_B^2 / d1 + (y_C - y_B)^2 / d2 + y_C^2 / d3:

indefinite is a branch point, definite a rigid point. Each of these families is a union of circles
(the parallelogram and anti-parallelogram modes, or a folded mode for kites) that meet at the
branch points, so its configuration space is one connected component.
"""

from __future__ import annotations

import itertools
import zlib

import numpy as np
import pytest

from engine.model.constraints import Constraints
from engine.model.linkage import BarSpec, Linkage, VertexSpec, build_linkage
from engine.space.configuration_space import explore, find_critical_points, rays

#: (name, a, L1, L2, L3, crank angle of the start, side of the start's dyad)
FAMILIES = [
    ("parallelogram", 2.0, 1.0, 2.0, 1.0, 0.7, 1.0),
    ("parallelogram-long-cranks", 1.0, 1.6, 1.0, 1.6, 1.1, 1.0),
    ("anti-parallelogram", 2.0, 1.0, 2.0, 1.0, 0.7, -1.0),
    ("anti-parallelogram-long-cranks", 1.3, 0.8, 1.3, 0.8, 2.0, -1.0),
    ("kite-at-the-pin", 1.0, 1.0, 0.6, 0.6, 0.9, 1.0),
    ("kite-at-the-crank", 1.0, 0.6, 0.6, 1.0, 0.9, -1.0),
    ("rhombus", 1.0, 1.0, 1.0, 1.0, 1.2, 1.0),
]


def flat_critical_points(
    a: float, l1: float, l2: float, l3: float
) -> list[tuple[float, float, str]]:
    """``(B_x, C_x, kind)`` of every flat configuration (pins at 0 and ``a``)."""
    out: list[tuple[float, float, str]] = []
    for s1, s2 in itertools.product((1.0, -1.0), repeat=2):
        bx = s1 * l1
        cx = bx + s2 * l2
        if abs(abs(cx - a) - l3) > 1e-12 * max(a, l1, l2, l3):
            continue
        if any(abs(bx - b) < 1e-9 and abs(cx - c) < 1e-9 for b, c, _ in out):
            continue
        d1, d2, d3 = bx, cx - bx, a - cx
        q = np.array([[1 / d1 + 1 / d2, -1 / d2], [-1 / d2, 1 / d2 + 1 / d3]])
        det = float(np.linalg.det(q))
        out.append((bx, cx, "branch" if det < 0 else "rigid"))
    return out


def start_positions(a: float, l1: float, l2: float, l3: float, theta: float, side: float):
    """``B`` at crank angle ``theta`` and ``C`` on the ``side`` of the line ``B D``."""
    b = l1 * np.array([np.cos(theta), np.sin(theta)])
    d = np.array([a, 0.0])
    gap = d - b
    dist = float(np.linalg.norm(gap))
    along = (dist**2 + l2**2 - l3**2) / (2 * dist)
    across = np.sqrt(l2**2 - along**2)
    normal = np.array([-gap[1], gap[0]]) / dist
    return b, b + along * gap / dist + side * across * normal


def random_rotation(rng: np.random.Generator, dim: int) -> np.ndarray:
    q, _ = np.linalg.qr(rng.normal(size=(dim, dim)))
    if np.linalg.det(q) < 0:
        q[:, 0] = -q[:, 0]
    return q


def planar(family, rng: np.random.Generator) -> tuple[Linkage, np.ndarray, float, np.ndarray]:
    """The four-bar scaled, rotated and moved at random: ``(linkage, rotation, scale, shift)``."""
    _, a, l1, l2, l3, theta, side = family
    scale, rot, shift = rng.uniform(0.2, 5.0), random_rotation(rng, 2), rng.normal(size=2)
    b, c = start_positions(a, l1, l2, l3, theta, side)
    place = lambda p: (scale * rot @ p + shift).tolist()  # noqa: E731
    vertices = [VertexSpec("A", place(np.zeros(2)), True),
                VertexSpec("D", place(np.array([a, 0.0])), True),
                VertexSpec("B", place(b)), VertexSpec("C", place(c))]
    bars = [BarSpec("L1", ("A", "B"), scale * l1), BarSpec("L2", ("B", "C"), scale * l2),
            BarSpec("L3", ("D", "C"), scale * l3)]
    return build_linkage(2, vertices, bars), rot, scale, shift


def hinged(family, rng: np.random.Generator) -> tuple[Linkage, np.ndarray, float, np.ndarray]:
    """The four-bar in space: each crank a hinge (two bars to two pins on an axis normal to the
    plane), the whole rotated at random."""
    _, a, l1, l2, l3, theta, side = family
    scale, rot, shift = rng.uniform(0.2, 5.0), random_rotation(rng, 3), rng.normal(size=3)
    h = 0.4
    b, c = start_positions(a, l1, l2, l3, theta, side)
    place = lambda p, z=0.0: (scale * rot @ np.array([p[0], p[1], z]) + shift).tolist()  # noqa: E731
    pin_a, pin_d = np.zeros(2), np.array([a, 0.0])
    vertices = [VertexSpec("A-", place(pin_a, -h), True), VertexSpec("A+", place(pin_a, h), True),
                VertexSpec("D-", place(pin_d, -h), True), VertexSpec("D+", place(pin_d, h), True),
                VertexSpec("B", place(b)), VertexSpec("C", place(c))]
    bars = [BarSpec("L1-", ("A-", "B"), scale * np.hypot(l1, h)),
            BarSpec("L1+", ("A+", "B"), scale * np.hypot(l1, h)),
            BarSpec("L2", ("B", "C"), scale * l2),
            BarSpec("L3-", ("D-", "C"), scale * np.hypot(l3, h)),
            BarSpec("L3+", ("D+", "C"), scale * np.hypot(l3, h))]
    return build_linkage(3, vertices, bars), rot, scale, shift


def canonical(lk: Linkage, u: np.ndarray, rot: np.ndarray, scale: float, shift: np.ndarray):
    """``(B, C)`` of free coordinates ``u`` back in the four-bar's own frame (plane coordinates)."""
    pos = lk.positions_of(u)
    ids = list(lk.vertex_ids)
    back = lambda p: (rot.T @ (p - shift)) / scale  # noqa: E731
    return back(pos[ids.index("B")])[:2], back(pos[ids.index("C")])[:2]


def check_against_enumeration(family, lk, frame, crit) -> None:
    _, a, l1, l2, l3, _, _ = family
    expected = flat_critical_points(a, l1, l2, l3)
    assert len(crit) == len(expected), [canonical(lk, c.u, *frame) for c in crit]
    matched = set()
    for cp in crit:
        b, c = canonical(lk, cp.u, *frame)
        hits = [k for k, (bx, cx, _) in enumerate(expected)
                if np.allclose(b, [bx, 0.0], atol=1e-7) and np.allclose(c, [cx, 0.0], atol=1e-7)]
        assert len(hits) == 1, (b, c, expected)
        assert cp.kind == expected[hits[0]][2], (b, c, cp.kind, expected[hits[0]])
        matched.add(hits[0])
    assert len(matched) == len(expected)


@pytest.mark.parametrize("build", [planar, hinged], ids=["2d", "3d-hinges"])
@pytest.mark.parametrize("family", FAMILIES, ids=[f[0] for f in FAMILIES])
def test_whole_space_of_critical_four_bars_matches_the_closed_form(family, build):
    rng = np.random.default_rng(zlib.crc32(f"{family[0]}/{build.__name__}".encode()))
    lk, *frame = build(family, rng)
    res = explore(lk)
    assert res.search["complete"], res.search
    assert not res.degenerate
    check_against_enumeration(family, lk, frame, res.critical_points)
    assert len(res.components) == 1
    assert res.components[0].through_start
    # every ray of every branch point starts or ends exactly one segment, leaving along its ray
    ends = [(s.start, s.start_ray) for s in res.segments]
    ends += [(s.end, s.end_ray) for s in res.segments]
    branch = [k for k, c in enumerate(res.critical_points) if c.kind == "branch"]
    assert sorted(ends) == sorted((k, r) for k in branch for r in range(4))
    cons = Constraints(lk)
    for s in res.segments:
        leave = s.points[1] - s.points[0]
        assert rays(res.critical_points[s.start])[s.start_ray] @ leave > 0.9 * np.linalg.norm(leave)
        arrive = s.points[-2] - s.points[-1]
        assert rays(res.critical_points[s.end])[s.end_ray] @ arrive > 0.9 * np.linalg.norm(arrive)
        assert max(cons.max_residual(p) for p in s.points) <= 1e-8 * lk.lengths.max()


@pytest.mark.parametrize("build", [planar, hinged], ids=["2d", "3d-hinges"])
@pytest.mark.parametrize("family", FAMILIES, ids=[f[0] for f in FAMILIES])
def test_critical_points_of_critical_four_bars_match_the_closed_form(family, build):
    rng = np.random.default_rng(zlib.crc32(f"{family[0]}/{build.__name__}/cp".encode()))
    lk, *frame = build(family, rng)
    res = find_critical_points(lk)
    assert res.search["complete"], res.search
    check_against_enumeration(family, lk, frame, res.critical_points)


def test_the_enumeration_knows_the_classical_counts():
    """The closed form itself: two flat branch points for parallelograms and kites, three for
    the rhombus, one rigid flat point for a linkage that is stretched straight."""
    assert [k for *_, k in flat_critical_points(2.0, 1.0, 2.0, 1.0)] == ["branch"] * 2
    assert [k for *_, k in flat_critical_points(1.0, 1.0, 0.6, 0.6)] == ["branch"] * 2
    assert [k for *_, k in flat_critical_points(1.0, 1.0, 1.0, 1.0)] == ["branch"] * 3
    assert [k for *_, k in flat_critical_points(3.0, 1.0, 1.0, 1.0)] == ["rigid"]


def test_a_deadline_passed_during_the_classification_makes_the_answer_incomplete():
    """resolve() stops classifying once the deadline has passed (issue 23, item 4): the
    closed-form answer built from it, and the general one, then say ``reason: time``."""
    from engine.catalogue.presets import build_preset
    from engine.model.budget import NEVER, Deadline
    from engine.model.tolerances import Tolerances
    from engine.space.configuration_space import Explorer, SpaceOptions, closed_form_critical
    from engine.space.configuration_space.critical_search import resolve
    from engine.space.dyads import critical_candidates

    lk = build_preset("three-rotor")  # the paper's twelve branch points
    tol = Tolerances()
    starts = critical_candidates(lk, tol).points
    assert starts is not None and len(starts) >= 12
    ex = Explorer(lk, tol, SpaceOptions(), NEVER)
    assert len(resolve(ex, list(starts))[0]) == 12 and not ex.timed_out
    # a deadline already passed: nothing is classified, and the explorer knows it
    gone = Deadline.after(0.0)
    cut = Explorer(lk, tol, SpaceOptions(), gone)
    assert resolve(cut, list(starts))[0] == [] and cut.timed_out
    answer = closed_form_critical(Explorer(lk, tol, SpaceOptions(), gone))
    assert answer is None or answer.search.reason == "time"
    res = find_critical_points(lk, tol, deadline=gone)
    assert res.search["complete"] is False and res.search["reason"] == "time"
