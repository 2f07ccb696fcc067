"""The explorer's test of whether a seed lies on a traced curve: the nearest curve point is
the closest point of its pass at either end of a curve too (``pass_minima``), so no component
is traced twice. Before, the k-d tree's distance to the nearest point was compared with
``np.linalg.norm``'s distance to its neighbours, which at a curve's end is the point itself
and differed in the last bit: gated chains traced 9, 17 and 18 components where dense sampling
with circle intersections (``tests/gated_reference.py``) finds 8, 16 and 16."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import cKDTree

from engine.catalogue.presets import build_preset
from engine.model.budget import Deadline, answer_values
from engine.model.constraints import on_constraints
from engine.model.linkage import Linkage
from engine.model.tolerances import Tolerances
from engine.space.configuration_space import SpaceOptions, explore
from engine.space.configuration_space.explorer import NEAREST, pass_minima
from tests.gated_reference import sampled_general_chain


def test_the_nearest_point_is_a_pass_minimum_at_either_end() -> None:
    """Points near the first and the last point of a curve (a random walk in 12 coordinates):
    the nearest curve point, found by a k-d tree, is always the closest of its pass."""
    rng = np.random.default_rng(7)
    pts = np.cumsum(rng.normal(scale=0.1, size=(60, 12)), axis=0)
    ends = np.concatenate([pts[[0]], pts[[-1]]])
    us = np.repeat(ends, 200, axis=0) + rng.normal(scale=0.02, size=(400, 12))
    _, idx = cKDTree(pts).query(us, k=NEAREST)
    assert np.isin(idx[:, 0], [0, 1, 58, 59]).all()
    assert pass_minima(pts, us, idx)[:, 0].all()


def test_one_point_per_pass_of_a_fold() -> None:
    """A curve that folds back near itself (a U, its arms 0.1 apart): a point near one arm has
    one pass minimum on each arm, and only those."""
    s = np.linspace(0.0, 1.0, 41)
    pts = np.concatenate([np.column_stack([s, np.zeros_like(s)]),
                          np.column_stack([s[::-1], np.full_like(s, 0.1)])])
    u = np.array([[0.5, 0.03]])
    _, idx = cKDTree(pts).query(u, k=NEAREST)
    keep = pass_minima(pts, u, idx)[0]
    assert sorted(idx[0][keep]) == [20, 61]


#: (n, gate, r0, r1, l0, D) of gated chains (the preset's other lengths) that traced a
#: component twice, and the components dense sampling finds.
TWICE = [
    ((3, 1, 0.5106199161356644, 0.6068123447665775, 1.6267081947318323, 3.2583042477214423), 8),
    ((3, 1, 1.7425319909154264, 1.2273423493057227, 1.7807036694895566, 2.26049807862774), 16),
    ((4, 2, 1.3468447303867082, 0.5649667404006405, 0.6483963200393221, 1.590206744849796), 16),
]


def gated(n: int, gate: int, r0: float, r1: float, l0: float, d: float) -> Linkage:
    lk = build_preset("gated-kl-chain", {"n": n, "gate": gate, "D": d})
    new = {"r0": r0, "r1": r1, "l0": l0}
    return lk.with_lengths(np.array([new.get(b, x) for b, x in zip(lk.bar_ids, lk.lengths,
                                                                    strict=True)]))


@pytest.mark.parametrize(("case", "count"), TWICE, ids=["n3-8", "n3-16", "n4-16"])
def test_no_component_is_traced_twice(case: tuple[int, int, float, float, float, float],
                                      count: int) -> None:
    """The search as the service runs it (a deadline, the answer's budget of values): as many
    traced curves and components as dense sampling of rotor 0 finds, every one closed."""
    n, gate, r0, r1, l0, d = case
    pins = np.column_stack([np.arange(n, dtype=float), np.zeros(n)])
    sliders = np.array([pins[gate] + [0.0, -d], pins[gate] + [0.0, d]])
    reference, _ = sampled_general_chain(pins, np.array([r0, r1] + [1.5] * (n - 2)),
                                         np.array([l0] + [1.5] * (n - 2)), gate, sliders, 2.0,
                                         2.0, sampled=0, samples=3000)
    assert reference == count
    tol = Tolerances()
    at, _ = on_constraints(gated(*case), tol)
    deadline = Deadline.after(60.0)
    res = explore(at, tol, SpaceOptions(max_components=64, max_values=answer_values(deadline)),
                  near_misses=False, deadline=deadline)
    assert res.search["curves_traced"] == len(res.components) == count, res.search
    assert all(c.closed for c in res.components)
    assert "components_disagree" not in res.search
