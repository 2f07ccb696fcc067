"""Linkage validation: each bad input raises an EngineError subclass naming the field."""

from __future__ import annotations

import numpy as np
import pytest

from engine.model.errors import InvalidLinkage, LimitExceeded
from engine.model.linkage import BarSpec, Limits, VertexSpec, build_linkage

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


def _loop_only(monkeypatch: pytest.MonkeyPatch) -> None:
    import engine.model.linkage

    monkeypatch.setattr(engine.model.linkage, "_build_vectorised", lambda *args: None)


def _same_linkage(a, b) -> None:
    assert (a.dimension, a.vertex_ids, a.bar_ids) == (b.dimension, b.vertex_ids, b.bar_ids)
    for name in ("positions", "fixed", "ends", "lengths", "free_index", "active"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
        assert getattr(a, name).dtype == getattr(b, name).dtype


@pytest.mark.parametrize("seed", range(8))
def test_vectorised_build_equals_the_checking_loop(seed, monkeypatch):
    """Valid input takes the vectorised path; it must give what the loop gives."""
    rng = np.random.default_rng(seed)
    d = 2 + seed % 2
    n = int(rng.integers(2, 40))
    fixed_choices = [False, True, [True] + [False] * (d - 1)]
    vertices = [VertexSpec(f"v{k}", rng.normal(size=d).tolist(),
                           fixed_choices[int(rng.integers(0, 3))]) for k in range(n)]
    pairs = [(i, j) for i in range(n) for j in range(i + 1, n)]
    chosen = rng.choice(len(pairs), size=min(len(pairs), 2 * n), replace=False)
    bars = []
    for k, c in enumerate(chosen):
        i, j = pairs[c]
        both_pinned = vertices[i].fixed is True and vertices[j].fixed is True
        length = None if both_pinned or rng.random() < 0.5 else float(rng.uniform(0.5, 2))
        bars.append(BarSpec(f"b{k}", (f"v{i}", f"v{j}"), length))
    import engine.model.linkage

    assert engine.model.linkage._build_vectorised(d, vertices, bars, 1e-9) is not None
    fast = build_linkage(d, vertices, bars)
    _loop_only(monkeypatch)
    _same_linkage(fast, build_linkage(d, vertices, bars))


def test_vectorised_build_of_a_large_chain_equals_the_loop(monkeypatch):
    from engine.catalogue.presets import build_preset

    lk = build_preset("kl-chain", {"n": 500})
    vertices = [VertexSpec(v, p.tolist(), bool(f.all()))
                for v, p, f in zip(lk.vertex_ids, lk.positions, lk.fixed, strict=True)]
    bars = [BarSpec(b, (lk.vertex_ids[i], lk.vertex_ids[j]), float(ln))
            for b, (i, j), ln in zip(lk.bar_ids, lk.ends, lk.lengths, strict=True)]
    fast = build_linkage(2, vertices, bars)
    _same_linkage(fast, lk)
    _loop_only(monkeypatch)
    _same_linkage(fast, build_linkage(2, vertices, bars))


def test_several_problems_report_the_first_as_the_loop_does():
    """The vectorised path gives up on any problem; the loop then names the first one."""
    vertices = [P, A, VertexSpec("B", [np.nan, 0.0]), VertexSpec("A", [3, 3])]
    with pytest.raises(InvalidLinkage) as err:
        build_linkage(2, vertices, [])
    assert err.value.loc == ("vertices", 2, "position")
    with pytest.raises(InvalidLinkage) as err:
        build_linkage(2, [P, A, Q], [BarSpec("b", "PA", -1.0), BarSpec("c", ("A", "Z"))])
    assert err.value.loc == ("bars", 0, "length")
    with pytest.raises(InvalidLinkage) as err:
        build_linkage(2, [P, VertexSpec("S", [1, 1], [True, 1])], [])
    assert err.value.loc == ("vertices", 1, "fixed")


def test_vectorised_build_refuses_a_zero_length_bar_like_the_loop():
    far = VertexSpec("F", [5.0, 5.0])
    with pytest.raises(InvalidLinkage) as err:
        build_linkage(2, [P, A, far], [BarSpec("long", "PA"), BarSpec("tiny", ("A", "F"), 1e-13)])
    assert err.value.loc == ("bars", 1, "length")
