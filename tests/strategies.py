"""Hypothesis strategies and independent reference computations for the engine tests."""

from __future__ import annotations

import numpy as np
from hypothesis import assume
from hypothesis import strategies as st

from engine.model.linkage import BarSpec, Linkage, VertexSpec, build_linkage


@st.composite
def random_linkages(
    draw: st.DrawFn,
    dims: tuple[int, ...] = (2, 3),
    min_vertices: int = 3,
    max_vertices: int = 7,
    allow_fixed: bool = True,
    dof: int | None = None,
) -> Linkage:
    """Random linkage with pins, sliders and free vertices at random (generic) positions.

    With ``dof`` set, exactly ``M - dof`` bars with a free end are drawn (``M`` free
    coordinates), and at least one coordinate is fixed.
    """
    d = draw(st.sampled_from(dims))
    v = draw(st.integers(min_vertices, max_vertices))
    seed = draw(st.integers(0, 2**32 - 1))
    rng = np.random.default_rng(seed)
    pos = rng.normal(size=(v, d))
    vertices = []
    for k in range(v):
        kind = rng.integers(0, 4) if allow_fixed else 0  # 0,1 free, 2 pinned, 3 slider
        if kind == 2:
            fixed: bool | list[bool] = True
        elif kind == 3:
            fixed = [bool(b) for b in rng.integers(0, 2, size=d)]
        else:
            fixed = False
        vertices.append(VertexSpec(f"v{k}", pos[k].tolist(), fixed))
    pairs = [(i, j) for i in range(v) for j in range(i + 1, v)]
    if dof is None:
        n_bars = draw(st.integers(1, len(pairs)))
    else:
        masks = [np.broadcast_to(np.asarray(vx.fixed, dtype=bool), (d,)) for vx in vertices]
        pairs = [(i, j) for i, j in pairs if not (masks[i].all() and masks[j].all())]
        m = int(sum((~mask).sum() for mask in masks))
        n_bars = m - dof
        assume(1 <= n_bars <= len(pairs) and m < v * d)
    chosen = rng.choice(len(pairs), size=n_bars, replace=False)
    bars = [BarSpec(f"b{k}", (f"v{pairs[c][0]}", f"v{pairs[c][1]}")) for k, c in enumerate(chosen)]
    return build_linkage(d, vertices, bars)


def squared_lengths_reference(linkage: Linkage, u: np.ndarray) -> np.ndarray:
    """l^2 of the active bars, computed bar by bar (independent of engine.model.constraints)."""
    pos = linkage.positions_of(u)
    out = []
    for (i, j), active in zip(linkage.ends, linkage.active, strict=True):
        if active:
            out.append(float(np.sum((pos[i] - pos[j]) ** 2)))
    return np.array(out)


def squared_lengths_jacobian_reference(linkage: Linkage, u: np.ndarray) -> np.ndarray:
    """d(l^2)/du of the active bars (E, M), bar by bar: 2 (p_i - p_j) at i, its negative at j,
    read at the free coordinates (independent of engine.model.constraints)."""
    pos = linkage.positions_of(u)
    rows = []
    for (i, j), active in zip(linkage.ends, linkage.active, strict=True):
        if active:
            grad = np.zeros(pos.shape)
            grad[i] += 2.0 * (pos[i] - pos[j])
            grad[j] -= 2.0 * (pos[i] - pos[j])
            rows.append(grad[~linkage.fixed])
    return np.array(rows).reshape(len(rows), int(np.count_nonzero(~linkage.fixed)))


def nearest_solution(linkage: Linkage, u0: np.ndarray, starts: int = 8) -> np.ndarray:
    """Nearest point to ``u0`` with l = L, by SLSQP from ``u0`` and seeded nearby starts (a
    start at a symmetric point can stall); independent of engine.model.constraints."""
    from scipy.optimize import minimize

    targets = linkage.lengths[linkage.active] ** 2
    constraint = {"type": "eq", "fun": lambda x: squared_lengths_reference(linkage, x) - targets,
                  "jac": lambda x: squared_lengths_jacobian_reference(linkage, x)}
    rng = np.random.default_rng(12345)
    scale = 0.05 * float(np.median(linkage.lengths))
    best = None
    for k in range(starts):
        x0 = u0 if k == 0 else u0 + scale * rng.normal(size=u0.size)
        res = minimize(
            lambda x: float(np.sum((x - u0) ** 2)),
            x0,
            jac=lambda x: 2 * (x - u0),
            constraints=[constraint],
            method="SLSQP",
            options={"ftol": 1e-16, "maxiter": 500},
        )
        feasible = np.max(np.abs(squared_lengths_reference(linkage, res.x) - targets)) < 1e-10
        if feasible and (best is None or np.linalg.norm(res.x - u0) < np.linalg.norm(best - u0)):
            best = res.x
    assert best is not None, "the reference SLSQP found no feasible point"
    return best


@st.composite
def one_dof_linkage_bodies(draw: st.DrawFn, max_dyads: int = 3) -> dict[str, object]:
    """A valid one-degree-of-freedom planar linkage as the service takes it (JSON): two pins,
    a rotor on the first, then ``1..max_dyads`` dyads (a free vertex on two bars to earlier
    vertices, the first one to the second pin, which closes a four-bar), at generic random
    positions; the lengths are the distances as drawn, so the configuration is on the
    constraints. Rank-nullity gives one degree of freedom at a generic configuration: every
    dyad adds two coordinates and two bars."""
    dyads = draw(st.integers(1, max_dyads))
    seed = draw(st.integers(0, 2**32 - 1))
    rng = np.random.default_rng(seed)
    pos = rng.uniform(-2.0, 2.0, size=(3 + dyads, 2))
    pos[1] = pos[0] + [draw(st.floats(1.0, 3.0)), 0.0]  # the ground, a generic length
    ids = ["p0", "p1", "a"] + [f"d{k}" for k in range(dyads)]
    bars = [("r", "p0", "a")]
    for k in range(dyads):
        first = "a" if k == 0 else ids[3 + int(rng.integers(0, k))]  # an earlier moving vertex
        second = "p1" if k == 0 else ids[int(rng.integers(0, 3 + k))]
        if second == first:
            second = "p0"
        bars += [(f"b{k}a", first, ids[3 + k]), (f"b{k}b", second, ids[3 + k])]
    vertices = [{"id": i, "position": [float(x), float(y)], "fixed": i in ("p0", "p1")}
                for i, (x, y) in zip(ids, pos, strict=True)]
    return {"dimension": 2, "vertices": vertices,
            "bars": [{"id": b, "ends": [i, j]} for b, i, j in bars]}
