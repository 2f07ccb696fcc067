"""Exact margins of spherical four-bars over one or two chords against references written apart
from the engine (`tests/engine/design/sphere_reference.py`): the critical lengths found by
scanning a fine grid of the adjustable chords for sign changes of the arc equalities (and the
flat triangles' lengths where the sampled linkage has a component), the nearest of them; the
returned configuration critical by a rigidity matrix built here; the multistart never below."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from engine.catalogue.presets import build_preset
from engine.design.robustness import robustness
from engine.design.spherical_margin import spherical_margin
from tests.engine.design.sphere_reference import Sphere, preset_sphere
from tests.engine.design.test_spherical_curves import general_linkage, random_spheres

CHORDS = ("L1", "L2", "L3")
CASES = [({}, names) for names in (("L1",), ("L2",), ("L3",), ("L1", "L2"), ("L2", "L3"),
                                   ("L1", "L3"))]
CASES += [(p, names) for p in random_spheres(3, seed=31)
          for names in (("L2",), ("L1", "L3"), ("L2", "L3"))]


def _reference(ref: Sphere, base: np.ndarray, names: tuple[str, ...], n: int) -> float:
    """The nearest critical chords to ``base`` (3,) on a grid of ``n`` per adjustable chord over
    its triangle's whole range ``[|p - q|, p + q]``: a sign change of a signed arc sum minus the
    ground arc (a multiple of 2 pi) between grid neighbours, or a chord at an end of its range
    where the linkage just inside has a component."""
    sides = np.array([[np.linalg.norm(ref.g1), ref.ra], [ref.ra, ref.rb],
                      [ref.rb, np.linalg.norm(ref.g2)]])
    idx = [CHORDS.index(c) for c in names]
    lo = np.maximum(np.abs(sides[:, 0] - sides[:, 1]), 1e-3)
    hi = sides.sum(axis=1)
    axes = [np.linspace(lo[i], hi[i], n) for i in idx]
    grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, len(idx))
    lengths = np.tile(base, (len(grid), 1))
    lengths[:, idx] = grid
    arcs = ref.arcs(lengths).reshape(*(n,) * len(idx), 3)
    pts = lengths.reshape(*(n,) * len(idx), 3)
    best = np.inf
    for s in itertools.product((1, -1), repeat=3):
        for k in (-1, 0, 1):
            f = arcs @ np.array(s, dtype=float) - ref.gamma - 2 * np.pi * k
            for ax in range(len(idx)):
                a = np.moveaxis(f, ax, 0)
                p = np.moveaxis(pts, ax, 0)
                hit = np.sign(a[:-1]) * np.sign(a[1:]) < 0
                mid = 0.5 * (p[:-1][hit] + p[1:][hit])
                if len(mid):
                    best = min(best, float(np.min(np.linalg.norm(
                        mid[:, idx] - base[idx], axis=1))))
    for m, i in enumerate(idx):  # a flat triangle where the rest assembles
        ends = [(hi[i], -1e-7)] + ([(lo[i], 1e-7)] if lo[i] > 1e-3 else [])
        for (end, inward), other in itertools.product(
                ends, axes[1 - m] if len(idx) == 2 else [None]):
            at = base.copy()
            at[i] = end + inward
            if other is not None:
                at[idx[1 - m]] = other
            if ref.components(at, 20000) > 0:
                best = min(best, float(np.linalg.norm(at[idx] - base[idx])))
    return best


def _rigidity_rank_drop(lk, u: np.ndarray, lengths: np.ndarray) -> tuple[float, float]:
    """The smallest singular value of the rigidity matrix built here (rows ``p_i - p_j`` on the
    free coordinates), relative to the largest, and the largest bar-length error."""
    pos = np.array(lk.positions, dtype=float)
    pos[~lk.fixed] = u
    free = ~np.asarray(lk.fixed)
    rows = []
    for i, j in lk.ends:
        row = np.zeros(pos.shape)
        row[i], row[j] = pos[i] - pos[j], pos[j] - pos[i]
        rows.append(row[free])
    sv = np.linalg.svd(np.array(rows), compute_uv=False)
    err = np.abs(np.linalg.norm(pos[lk.ends[:, 0]] - pos[lk.ends[:, 1]], axis=1) - lengths)
    return float(sv[-1] / sv[0]), float(err.max())


@pytest.mark.parametrize(("params", "names"), CASES,
                         ids=[f"{'-'.join(c[1])}-{i}" for i, c in enumerate(CASES)])
def test_the_margin_is_the_nearest_critical_length_as_scanned(params, names):
    lk = build_preset("spherical-four-bar", params)
    adj = np.isin(lk.bar_ids, names)
    m = spherical_margin(lk, adj, 1e-9)
    assert m is not None
    n = 20001 if len(names) == 1 else 801
    default = {"L1": 0.6, "L2": 1.3, "L3": 1.0}
    base = np.array([params.get(c, default[c]) for c in CHORDS], dtype=float)
    ref = _reference(preset_sphere(params), base, names, n)
    h = 2 * ({"R": 1.0} | params)["R"] / (n - 1)
    assert abs(m.margin - ref) <= 1.5 * h, (m.margin, ref)
    assert np.isclose(np.linalg.norm(m.nearest - lk.lengths), m.margin, atol=1e-12)
    assert preset_sphere(params).residual(m.nearest[2:]) < 1e-9
    drop, err = _rigidity_rank_drop(lk, m.critical_u, m.nearest)
    assert drop < 1e-9 and err < 1e-9


@pytest.mark.parametrize("names", [("L1",), ("L1", "L2"), ("L1", "L3")])
def test_pins_off_the_sphere_a_flat_triangle_nearest(names):
    """Every radius different (pins at 1.3 and 0.8 from O, tips at 1.0 and 1.2) and the crank
    0.35, just above its triangle's flat length 1.3 - 1.0: the margin is that flat triangle's
    (0.05) where the rest assembles, as scanned."""
    g1, g2 = np.array([1.3, 0.0, 0.0]), 0.8 * np.array([np.cos(1.1), np.sin(1.1), 0.0])
    chords = (0.35, 1.1, 0.7)
    lk, ref = general_linkage(g1, g2, 1.0, 1.2, chords)
    assert lk is not None
    m = spherical_margin(lk, np.isin(lk.bar_ids, names), 1e-9)
    assert m is not None
    n = 20001 if len(names) == 1 else 801
    expect = _reference(ref, np.array(chords), names, n)
    assert abs(m.margin - expect) <= 3.0 / (n - 1), (m.margin, expect)
    drop, err = _rigidity_rank_drop(lk, m.critical_u, m.nearest)
    assert drop < 1e-9 and err < 1e-9


def test_robustness_answers_exact_and_the_multistart_is_never_below():
    """Through :func:`robustness`: the closed form answers (``exact``, ``derived``); the
    multistart on the same request finds a critical value no nearer."""
    lk = build_preset("spherical-four-bar")
    exact = robustness(lk, ["L1", "L2"])
    assert exact.method == "closed-form" and exact.guarantee == "exact"
    assert exact.search.argument == "derived" and exact.search.complete
    multi = robustness(lk, ["L1", "L2"], method="multistart")
    assert multi.margin >= exact.margin - 1e-6
    assert multi.exact_margin == pytest.approx(exact.margin)


def test_radii_or_three_chords_are_left_to_the_multistart():
    lk = build_preset("spherical-four-bar")
    for names in (["OA"], ["L1", "OB"], ["L1", "L2", "L3"]):
        assert spherical_margin(lk, np.isin(lk.bar_ids, names), 1e-9) is None
    assert spherical_margin(build_preset("four-bar"), np.ones(3, dtype=bool), 1e-9) is None


def test_the_branch_and_bound_stops_at_the_deadline_and_its_budget(monkeypatch):
    """A deadline already passed, or an evaluation budget too small, declines two chords (the
    multistart then answers, incomplete) and leaves one chord (no search) exact."""
    import engine.design.spherical_margin as sm
    from engine.model.budget import Deadline

    lk = build_preset("spherical-four-bar")
    two, one = np.isin(lk.bar_ids, ["L1", "L2"]), np.isin(lk.bar_ids, ["L1"])
    passed = Deadline.after(0.0)
    assert spherical_margin(lk, two, 1e-9, passed) is None
    assert spherical_margin(lk, one, 1e-9, passed) is not None
    monkeypatch.setattr(sm, "MAX_EVALUATIONS", 1000)
    assert spherical_margin(lk, two, 1e-9) is None
    late = robustness(lk, ["L1", "L2"], deadline=Deadline.after(0.0))
    assert late.guarantee == "upper-bound" and not late.search.complete
