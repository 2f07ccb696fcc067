"""The spherical four-bar's critical curves in closed form against the references of
`tests/engine/design/sphere_reference.py` (written apart from the engine): its configuration
space by dense sampling of the crank angle, and its critical set as equalities of the arcs."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from engine.catalogue.presets import build_preset
from engine.design.critical_values import critical_value_slice
from engine.design.spherical_curves import spherical_curves, spherical_four_bar
from engine.model.linkage import BarSpec, VertexSpec, build_linkage
from tests.engine.design.slice_references import distance_to_curves, points_inside
from tests.engine.design.sphere_reference import Sphere, preset_sphere

SHORTEST = 1e-6
CHORDS = ("L1", "L2", "L3")


def general_linkage(g1: np.ndarray, g2: np.ndarray, ra: float, rb: float,
                    chords: tuple[float, float, float], seed: int = 0):
    """A spherical four-bar with pins off the tips' spheres (every radius different), built
    from a configuration found by sampling the reference: None where none was found."""
    ref = Sphere(g1, g2, ra, rb)
    if ref.components(np.array(chords)) == 0:
        return None, ref
    rng = np.random.default_rng(seed)
    l1, l2, l3 = chords
    for _ in range(20000):  # A on its circle at random, then B from the three spheres
        d1 = float(np.linalg.norm(g1))
        along = (ra**2 - l1**2 + d1**2) / (2 * d1)
        axis = g1 / d1
        e1 = np.cross(axis, rng.normal(size=3))
        e1 /= np.linalg.norm(e1)
        a = along * axis + np.sqrt(ra**2 - along**2) * e1
        m = np.array([g2, a])
        rhs = np.array([(rb**2 + g2 @ g2 - l3**2) / 2, (rb**2 + ra**2 - l2**2) / 2])
        base = np.linalg.lstsq(m, rhs, rcond=None)[0]
        h2 = rb**2 - base @ base
        if h2 > 0:
            nrm = np.cross(g2, a)
            b = base + np.sqrt(h2) * nrm / np.linalg.norm(nrm)
            verts = [VertexSpec("O", [0, 0, 0], True), VertexSpec("G1", g1.tolist(), True),
                     VertexSpec("G2", g2.tolist(), True), VertexSpec("A", a.tolist()),
                     VertexSpec("B", b.tolist())]
            bars = [BarSpec("OA", ("O", "A")), BarSpec("OB", ("O", "B")),
                    BarSpec("L1", ("G1", "A")), BarSpec("L2", ("A", "B")),
                    BarSpec("L3", ("G2", "B"))]
            return build_linkage(3, verts, bars), ref
    return None, ref


def random_spheres(count: int, seed: int = 11) -> list[dict[str, float]]:
    """Preset parameters (chords shorter than 2 R) that assemble."""
    rng = np.random.default_rng(seed)
    out: list[dict[str, float]] = []
    while len(out) < count:
        p = {"R": float(rng.uniform(0.7, 1.5))}
        p |= {k: float(rng.uniform(0.25, 1.9) * p["R"]) for k in ("g", "L1", "L2", "L3")}
        if preset_sphere(p).components(np.array([p["L1"], p["L2"], p["L3"]])) > 0:
            out.append(p)
    return out


CASES = [({}, ("L1", "L2"), (0.3, 0.9), (0.65, 1.95)),
         ({}, ("L2", "L3"), (0.5, 1.5), (0.5, 1.5)),
         ({}, ("L1", "L3"), (0.2, 1.0), (0.6, 1.4)),
         ({}, ("L3", "L1"), (0.6, 1.4), (0.2, 2.3))]  # past L1 = 2 R: empty beyond
for params in random_spheres(4):
    for pair in itertools.combinations(CHORDS, 2):
        CASES.append((params, pair, (0.6 * params[pair[0]], min(1.4 * params[pair[0]], 1.99)),
                      (0.6 * params[pair[1]], min(1.4 * params[pair[1]], 1.99))))


BARS5 = ("OA", "OB", "L1", "L2", "L3")


def _lengths5(lk, axes: tuple[str, str], xy: np.ndarray) -> np.ndarray:
    out = np.tile(np.array([lk.lengths[lk.bar_ids.index(b)] for b in BARS5]), (len(xy), 1))
    for m, name in enumerate(axes):
        out[:, BARS5.index(name)] = xy[:, m]
    return out


def _lengths(params: dict[str, float], axes: tuple[str, str], xy: np.ndarray) -> np.ndarray:
    base = {"L1": 0.6, "L2": 1.3, "L3": 1.0} | {k: v for k, v in params.items() if k in CHORDS}
    out = np.array([[base[c] for c in CHORDS]] * len(xy))
    for m, name in enumerate(axes):
        out[:, CHORDS.index(name)] = xy[:, m]
    return out


@pytest.mark.parametrize(("params", "axes", "xs", "ys"), CASES,
                         ids=[f"{c[1][0]}-{c[1][1]}-{i}" for i, c in enumerate(CASES)])
def test_every_drawn_point_is_critical_and_every_critical_point_is_drawn(params, axes, xs, ys):
    """Every point of every piece satisfies an arc equality (to rounding); scanning 41 lines of
    each axis, every sign change of an equality's residual where the linkage assembles (the
    reference sampler) is within a chord's sag of a piece; pieces a step apart at most."""
    lk = build_preset("spherical-four-bar", params)
    ref = preset_sphere(params)
    box = np.array([xs, ys])
    step = float(min(box[:, 1] - box[:, 0])) / 48
    curves = spherical_curves(lk, tuple(lk.bar_ids.index(a) for a in axes), box, step, SHORTEST)
    assert curves is not None
    for c in curves:
        assert np.all(np.linalg.norm(np.diff(c, axis=0), axis=1) <= step * (1 + 1e-9))
        assert np.all((c >= box[:, 0] - 1e-12) & (c <= box[:, 1] + 1e-12))
        assert np.all(ref.residual(_lengths(params, axes, c)) < 1e-6)
    # scan: the signed sums' residuals change sign along a line where a curve crosses it
    found = []
    for m in range(2):
        for v in np.linspace(*box[m], 41)[1:-1]:
            t = np.linspace(*box[1 - m], 4001)
            xy = np.zeros((len(t), 2))
            xy[:, m], xy[:, 1 - m] = v, t
            lengths = _lengths(params, axes, xy)
            arcs = ref.arcs(lengths)  # (n, 3)
            for s in itertools.product((1, -1), repeat=3):
                for k in (-1, 0, 1):
                    f = arcs @ np.array(s) - ref.gamma - 2 * np.pi * k
                    for i in np.flatnonzero(np.sign(f[:-1]) * np.sign(f[1:]) < 0):
                        found.append(0.5 * (xy[i] + xy[i + 1]))
    if found:
        gap = distance_to_curves(np.array(found), curves)
        assert np.all(gap <= 2 * step), gap.max()


@pytest.mark.parametrize(("params", "axes", "xs", "ys"), CASES[:9],
                         ids=[f"{c[1][0]}-{c[1][1]}-{i}" for i, c in enumerate(CASES[:9])])
def test_points_joined_away_from_the_curves_have_equal_counts(params, axes, xs, ys):
    """Random points of the box whose joining segment stays a step away from every curve have
    the same number of components (dense sampling): the curves hold every change."""
    lk = build_preset("spherical-four-bar", params)
    ref = preset_sphere(params)
    box = np.array([xs, ys])
    step = float(min(box[:, 1] - box[:, 0])) / 48
    curves = spherical_curves(lk, tuple(lk.bar_ids.index(a) for a in axes), box, step, SHORTEST)
    rng = np.random.default_rng(3)
    pts = box[:, 0] + (box[:, 1] - box[:, 0]) * rng.uniform(size=(25, 2))
    pts = pts[distance_to_curves(pts, curves) > 2 * step] if curves else pts
    counts = [ref.components(x) for x in _lengths(params, axes, pts)]
    for i, j in itertools.combinations(range(len(pts)), 2):
        seg = pts[i] + np.linspace(0, 1, 100)[:, None] * (pts[j] - pts[i])
        if not curves or np.min(distance_to_curves(seg, curves)) > step:
            assert counts[i] == counts[j], (pts[i], pts[j])


SLICES = [({}, ("L1", "L2"), (0.3, 0.9), (0.65, 1.95)),
          ({}, ("L2", "L3"), (0.5, 1.5), (0.5, 1.5)),
          ({}, ("L1", "L3"), (0.2, 1.0), (0.6, 1.4)),
          ({}, ("OA", "OB"), (0.8, 1.2), (0.8, 1.2)),  # the preset matrix's map
          ({}, ("OB", "L2"), (0.5, 1.5), (0.6, 1.9)),
          ({}, ("OA", "L1"), (0.5, 1.5), (0.3, 1.2))]


@pytest.mark.parametrize(("params", "axes", "xs", "ys"), SLICES,
                         ids=[f"{c[1][0]}-{c[1][1]}-{i}" for i, c in enumerate(SLICES)])
def test_the_slice_is_derived_and_every_region_counts_as_dense_sampling(params, axes, xs, ys):
    """The map through :func:`critical_value_slice` is complete with argument ``derived`` (the
    curves the closed form's, the regions' counts exact) and every region's count, at its
    sample and at points inside it, equals the dense sampling's."""
    lk = build_preset("spherical-four-bar", params)
    ref = preset_sphere(params)
    box = np.array([xs, ys])
    s = critical_value_slice(lk, [(axes[0], *xs), (axes[1], *ys)], resolution=48)
    assert s.search.complete and s.search.argument == "derived", s.search.argument_detail
    assert s.search.details["method"] == "closed form"
    for r in s.regions:
        at = [np.array(r.point)] + points_inside(s.curves, box, 48, np.array(r.point))
        for x in _lengths5(lk, axes, np.array(at)):
            assert ref.components5(x) == r.components, (r.point, x)


def test_pins_off_the_sphere_are_recognised_and_their_curves_critical():
    """A spherical four-bar with every radius different (pins at 1.3 and 0.8 from O, tips at 1.0
    and 1.2): recognised; its curves over two chords satisfy the arc equalities or a flat
    triangle (the lines L = |p - q| in the box), and counts agree across them as sampled."""
    g1, g2 = np.array([1.3, 0.0, 0.0]), 0.8 * np.array([np.cos(1.1), np.sin(1.1), 0.0])
    lk, ref = general_linkage(g1, g2, 1.0, 1.2, (0.9, 1.1, 0.7))
    assert lk is not None and spherical_four_bar(lk) is not None
    box = np.array([[0.2, 2.0], [0.1, 1.6]])  # L1 over |1.3 - 1.0| = 0.3 .. 2.3: the line 0.3
    step = 1.8 / 48
    axes = (lk.bar_ids.index("L1"), lk.bar_ids.index("L3"))
    curves = spherical_curves(lk, axes, box, step, SHORTEST)
    assert curves
    for c in curves:
        assert np.all(ref.residual(np.column_stack([c[:, 0], np.full(len(c), 1.1), c[:, 1]]))
                      < 1e-6)
    edge = [c for c in curves if np.allclose(c[:, 0], 0.3)]  # the crank's flat triangle
    assert edge
    for c in edge:  # drawn where the rest assembles: just inside the edge, it does
        assert ref.components(np.array([0.3 + 1e-6, 1.1, c[len(c) // 2, 1]])) > 0
    rng = np.random.default_rng(8)
    pts = box[:, 0] + (box[:, 1] - box[:, 0]) * rng.uniform(size=(30, 2))
    pts = pts[distance_to_curves(pts, curves) > 2 * step]
    counts = [ref.components(np.array([x, 1.1, y])) for x, y in pts]
    assert len(set(counts)) > 1
    for i, j in itertools.combinations(range(len(pts)), 2):
        seg = pts[i] + np.linspace(0, 1, 100)[:, None] * (pts[j] - pts[i])
        if np.min(distance_to_curves(seg, curves)) > step:
            assert counts[i] == counts[j], (pts[i], pts[j])


def test_other_linkages_and_axes_decline():
    """Not spherical four-bars (a planar four-bar, a 3D rotor chain whose hinges share no pin,
    pins on one line through the centre) are left to the tracing; maps over a radius go to
    :func:`radius_curves`, maps over two chords to :func:`spherical_curves`."""
    box = np.array([[0.8, 1.2], [0.8, 1.2]])
    assert spherical_four_bar(build_preset("four-bar")) is None
    assert spherical_four_bar(build_preset("rotor-chain-3d", {"n": 2})) is None
    lk = build_preset("spherical-four-bar")
    assert spherical_curves(lk, (0, 1), box, 0.01, SHORTEST) is None  # OA, OB
    assert spherical_curves(lk, (0, 2), box, 0.01, SHORTEST) is None  # OA, L1
    from engine.design.spherical_radii import radius_curves

    assert radius_curves(lk, (2, 3), box, 0.01, SHORTEST) is None  # two chords: no radius
    assert radius_curves(build_preset("four-bar"), (0, 1), box, 0.01, SHORTEST) is None
    g1, g2 = np.array([1.0, 0.0, 0.0]), np.array([-1.2, 0.0, 0.0])
    line, _ = general_linkage(g1, g2, 1.0, 1.1, (0.9, 1.2, 1.0))
    assert line is None or spherical_four_bar(line) is None


def test_a_box_where_the_space_is_empty_has_no_curves():
    """Chords past the triangle's range (L1 > 2 R) everywhere in the box: the space is empty,
    no critical value; the third chord's triangle open: likewise."""
    lk = build_preset("spherical-four-bar")
    assert spherical_curves(lk, (2, 3), np.array([[2.1, 2.5], [0.5, 1.0]]), 0.01,
                            SHORTEST) == []
    assert preset_sphere({}).components(np.array([2.2, 0.7, 1.0])) == 0


# -- maps with a radius among the axes (engine/design/spherical_radii.py, tested here with the
# chords' maps: the same reference, the same checks)

RADIUS_CASES = [({}, ("OA", "OB"), (0.8, 1.2), (0.8, 1.2)),  # the preset matrix's map
                ({}, ("OA", "OB"), (0.3, 2.5), (0.3, 2.5)),
                ({}, ("OA", "L1"), (0.5, 1.5), (0.3, 1.2)),
                ({}, ("OA", "L2"), (0.5, 1.5), (0.6, 1.9)),
                ({}, ("OA", "L3"), (0.5, 1.5), (0.5, 1.5)),
                ({}, ("OB", "L1"), (0.5, 1.5), (0.3, 1.2)),
                ({}, ("L3", "OB"), (0.5, 1.5), (0.5, 1.5))]
for params in random_spheres(2, seed=21):
    for pair in (("OA", "OB"), ("OA", "L2"), ("OB", "L1")):
        r = params["R"]
        hi = [1.4 * (r if n in ("OA", "OB") else params[n]) for n in pair]
        RADIUS_CASES.append((params, pair, (0.6 * hi[0] / 1.4, hi[0]), (0.6 * hi[1] / 1.4, hi[1])))


def _radius_map(params, axes, xs, ys):
    from engine.design.spherical_radii import radius_curves

    lk = build_preset("spherical-four-bar", params)
    box = np.array([xs, ys])
    step = float(min(box[:, 1] - box[:, 0])) / 48
    curves = radius_curves(lk, tuple(lk.bar_ids.index(a) for a in axes), box, step, SHORTEST)
    return lk, preset_sphere(params), box, step, curves


@pytest.mark.parametrize(("params", "axes", "xs", "ys"), RADIUS_CASES,
                         ids=[f"{c[1][0]}-{c[1][1]}-{i}" for i, c in enumerate(RADIUS_CASES)])
def test_over_a_radius_every_drawn_point_is_critical_and_every_one_drawn(params, axes, xs, ys):
    """As for two chords: every drawn point on an arc equality (the radii moving the arcs
    too), every sign change of an equality along 41 lines of each axis near a piece, pieces a
    step apart at most and in the box."""
    lk, ref, box, step, curves = _radius_map(params, axes, xs, ys)
    assert curves is not None
    for c in curves:
        assert np.all(np.linalg.norm(np.diff(c, axis=0), axis=1) <= step * (1 + 1e-9))
        assert np.all((c >= box[:, 0] - 1e-12) & (c <= box[:, 1] + 1e-12))
        at = _lengths5(lk, axes, c)
        assert np.all(ref.residual(at) < 1e-6)
        # a flat triangle's point (no flat equality) is drawn only where the rest assembles:
        # just off it, the sampled linkage has a component
        for k in np.flatnonzero(ref.flat_residual(at) > 1e-3)[2:-2]:
            near = [at[k] + e for e in 1e-6 * np.vstack([np.eye(5), -np.eye(5)])]
            assert any(ref.components5(x, 50000) > 0 for x in near), c[k]
    found = []
    for m in range(2):
        for v in np.linspace(*box[m], 41)[1:-1]:
            t = np.linspace(*box[1 - m], 4001)
            xy = np.zeros((len(t), 2))
            xy[:, m], xy[:, 1 - m] = v, t
            arcs = ref.arcs(_lengths5(lk, axes, xy))
            for s in itertools.product((1, -1), repeat=3):
                for k in (-1, 0, 1):
                    f = arcs @ np.array(s) - ref.gamma - 2 * np.pi * k
                    for i in np.flatnonzero(np.sign(f[:-1]) * np.sign(f[1:]) < 0):
                        found.append(0.5 * (xy[i] + xy[i + 1]))
    if found:
        gap = distance_to_curves(np.array(found), curves)
        assert np.all(gap <= 2 * step), gap.max()


@pytest.mark.parametrize(("params", "axes", "xs", "ys"), RADIUS_CASES,
                         ids=[f"{c[1][0]}-{c[1][1]}-{i}" for i, c in enumerate(RADIUS_CASES)])
def test_over_a_radius_points_joined_away_from_the_curves_have_equal_counts(params, axes, xs,
                                                                            ys):
    lk, ref, box, step, curves = _radius_map(params, axes, xs, ys)
    rng = np.random.default_rng(4)
    pts = box[:, 0] + (box[:, 1] - box[:, 0]) * rng.uniform(size=(25, 2))
    pts = pts[distance_to_curves(pts, curves) > 2 * step] if curves else pts
    counts = [ref.components5(x) for x in _lengths5(lk, axes, pts)]
    for i, j in itertools.combinations(range(len(pts)), 2):
        seg = pts[i] + np.linspace(0, 1, 100)[:, None] * (pts[j] - pts[i])
        if not curves or np.min(distance_to_curves(seg, curves)) > step:
            assert counts[i] == counts[j], (pts[i], pts[j])
