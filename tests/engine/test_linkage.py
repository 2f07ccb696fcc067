"""Linkage validation: each bad input raises an EngineError subclass naming the field."""

from __future__ import annotations

import numpy as np
import pytest

from engine.errors import InvalidLinkage, LimitExceeded
from engine.linkage import BarSpec, Limits, VertexSpec, build_linkage

P = VertexSpec("P", [0, 0], True)
Q = VertexSpec("Q", [2, 0], True)
A = VertexSpec("A", [1, 1])


@pytest.mark.parametrize(
    ("dim", "vertices", "bars", "error", "loc", "words"),
    [
        (2, [P, A], [BarSpec("b", ("P", "Z"))], InvalidLinkage, ("bars", 0, "ends", 1), "unknown"),
        (2, [P, VertexSpec("P", [1, 0])], [], InvalidLinkage, ("vertices", 1, "id"), "duplicate"),
        (2, [P, A], [BarSpec("b", "PA"), BarSpec("b", "AP")], InvalidLinkage,
         ("bars", 1, "id"), "duplicate"),
        (2, [VertexSpec("A", [1, 1, 1])], [], InvalidLinkage, ("vertices", 0, "position"),
         "expected 2"),
        (3, [VertexSpec("A", [1, 1])], [], InvalidLinkage, ("vertices", 0, "position"),
         "expected 3"),
        (2, [VertexSpec("A", [np.nan, 1])], [], InvalidLinkage, ("vertices", 0, "position"),
         "finite"),
        (2, [VertexSpec("A", [np.inf, 1])], [], InvalidLinkage, ("vertices", 0, "position"),
         "finite"),
        (2, [P, A], [BarSpec("b", ("A", "A"))], InvalidLinkage, ("bars", 0, "ends"), "itself"),
        (2, [VertexSpec("A", [1e200, 1])], [], InvalidLinkage, ("vertices", 0, "position"),
         "beyond"),
        (2, [P, A], [BarSpec("b", "PA", 1e300)], InvalidLinkage, ("bars", 0, "length"),
         "finite"),
        (2, [P, A], [BarSpec("b", "PA", 0.0)], InvalidLinkage, ("bars", 0, "length"), "positive"),
        (2, [P, A], [BarSpec("b", "PA", -1.0)], InvalidLinkage, ("bars", 0, "length"), "positive"),
        (2, [P, A], [BarSpec("b", "PA", float("nan"))], InvalidLinkage, ("bars", 0, "length"),
         "finite"),
        (2, [P, Q], [BarSpec("g", "PQ", 1.5)], InvalidLinkage, ("bars", 0, "length"),
         "two fixed"),
        (2, [P, VertexSpec("B", [0, 0])], [BarSpec("b", "PB")], InvalidLinkage,
         ("bars", 0, "length"), "coincide"),
        (2, [VertexSpec("A", [0, 0], [True])], [], InvalidLinkage, ("vertices", 0, "fixed"),
         "one per axis"),
        (4, [P], [], InvalidLinkage, ("dimension",), "2 or 3"),
        (2, [], [], InvalidLinkage, ("vertices",), "at least one"),
    ],
)
def test_bad_input_names_the_field(dim, vertices, bars, error, loc, words):
    with pytest.raises(error) as info:
        build_linkage(dim, vertices, bars)
    assert info.value.loc == loc
    assert words in info.value.message


def test_limits():
    with pytest.raises(LimitExceeded) as info:
        build_linkage(2, [P, Q, A], [], Limits(max_vertices=2))
    assert info.value.loc == ("vertices",)
    with pytest.raises(LimitExceeded) as info:
        build_linkage(2, [P, A], [BarSpec("a", "PA"), BarSpec("b", "AP")], Limits(max_bars=1))
    assert info.value.loc == ("bars",)


def test_model_basics():
    lk = build_linkage(
        3,
        [VertexSpec("P", [0, 0, 0], True), VertexSpec("S", [1, 0, 0], [False, True, True]),
         VertexSpec("A", [1, 1, 0])],
        [BarSpec("a", "PA"), BarSpec("s", "SA", 2.0), BarSpec("g", "PS")],
    )
    assert lk.n_free == 4  # S moves along x only, A is free
    np.testing.assert_allclose(lk.lengths, [np.sqrt(2), 2.0, 1.0])
    u = lk.coordinates()
    np.testing.assert_allclose(lk.positions_of(u), lk.positions)
    with pytest.raises(ValueError):
        lk.positions[0, 0] = 5.0  # read-only
    # the pinned-pinned bar with matching length is accepted and inert
    both = build_linkage(2, [P, Q, A], [BarSpec("g", "PQ", 2.0), BarSpec("a", "PA")])
    assert list(both.active) == [False, True]
