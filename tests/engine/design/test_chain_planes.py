"""The closed-form critical lines of a rotor chain's map (``engine/design/chain_planes.py``)
against independent references: the flat four-bar written out here (every point of a line is
a configuration with a self-stress: the rigidity matrix built here loses rank), and a second
method (the traced slice, whose curves must lie on those lines)."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from engine.catalogue.presets import build_preset
from engine.design.chain_planes import chain_planes
from engine.design.critical_values import critical_value_slice

BOX = np.array([[1.2, 1.8], [1.2, 1.8]])  # r0 x r1 of the spinner chain (a = 1, r = l = 1.5)


def flat_residual(x: np.ndarray, a: float = 1.0, coupler: float = 1.5) -> float:
    """Distance of ``(r0, r1)`` rows of ``x`` (k, 2) from the nearest plane where the first
    four-bar ``P0 T0 T1 P1`` is flat: ``+-a +-r0 +-l0 +-r1 = 0``."""
    sums = [abs(a + s0 * x[:, 0] + s1 * coupler + s2 * x[:, 1])
            for s0, s1, s2 in itertools.product((1.0, -1.0), repeat=3)]
    return float(np.max(np.min(np.array(sums), axis=0)))


def meet(c0: np.ndarray, r0: float, c1: np.ndarray, r1: float, side: float) -> np.ndarray | None:
    """Closed-form intersection of two circles on ``side`` of the line c0 -> c1."""
    d = c1 - c0
    dist = float(np.hypot(*d))
    along = (dist**2 + r0**2 - r1**2) / (2 * dist)
    if r0**2 < along**2:
        return None
    h = np.sqrt(r0**2 - along**2)
    u = d / dist
    return c0 + along * u + side * h * np.array([-u[1], u[0]])


def smallest_singular_value(pins: np.ndarray, tips: np.ndarray) -> float:
    """Of the rigidity matrix (E, 2n) of the chain (rotors P_k T_k, couplers T_k T_k+1) in
    the tips' coordinates, divided by its largest."""
    n = len(tips)
    rows = []
    for k in range(n):
        row = np.zeros(2 * n)
        row[2 * k:2 * k + 2] = tips[k] - pins[k]
        rows.append(row)
    for k in range(n - 1):
        row = np.zeros(2 * n)
        row[2 * k:2 * k + 2] = tips[k] - tips[k + 1]
        row[2 * k + 2:2 * k + 4] = tips[k + 1] - tips[k]
        rows.append(row)
    s = np.linalg.svd(np.array(rows), compute_uv=False)
    return float(s[-1] / s[0])


@pytest.mark.parametrize("n", [4, 10, 100])
def test_spinner_map_lines_are_the_first_cells_flat_planes(n: int) -> None:
    """Over r0 x r1 only the first four-bar can go flat: its three planes that cross the box,
    and every point of them is a critical configuration of the whole chain (the flat four-bar
    laid out here, the other tips by circle intersections: the rigidity matrix loses rank)."""
    lk = build_preset("kl-chain", {"n": n})
    planes = chain_planes(lk, (0, 1), BOX)
    assert planes is not None and len(planes) == 1
    assert [lk.bar_ids[b] for b in planes[0].bars] == ["r0", "l0", "r1"]
    s = critical_value_slice(lk, [("r0", 1.2, 1.8), ("r1", 1.2, 1.8)], resolution=24)
    assert s.search.complete and s.search.argument == "derived"
    assert len(s.curves) == 3 and len(s.regions) == 4
    for curve in s.curves:
        assert flat_residual(curve) < 1e-9
    if n != 4:
        return
    pins = np.column_stack([np.arange(n, dtype=float), np.zeros(n)])
    for curve in s.curves:
        r0, r1 = curve[len(curve) // 2]
        # the flat: P0, T0, T1, P1 on the x axis with the signs of the plane it is on
        for s0, s1 in itertools.product((1.0, -1.0), repeat=2):
            t0 = s0 * r0
            t1 = t0 + s1 * 1.5
            if abs(abs(t1 - 1.0) - r1) < 1e-9:
                break
        else:
            raise AssertionError(f"({r0}, {r1}) is on no flat plane")
        tips = [np.array([t0, 0.0]), np.array([t1, 0.0])]
        for k in range(2, n):
            nxt = meet(tips[-1], 1.5, pins[k], 1.5, 1.0)
            assert nxt is not None
            tips.append(nxt)
        assert smallest_singular_value(pins, np.array(tips)) < 1e-9


def test_traced_curves_lie_on_the_closed_form_lines() -> None:
    """A second method: the slice traced from seeds (no closed form) finds curves on the
    first four-bar's flat planes only, as many as the closed form draws."""
    lk = build_preset("kl-chain", {"n": 4})
    axes = [("r0", 1.2, 1.8), ("r1", 1.2, 1.8)]
    auto = critical_value_slice(lk, axes, resolution=24)
    traced = critical_value_slice(lk, axes, resolution=24, method="traced")
    assert auto.search["method"] == "closed form" and traced.search["method"] == "traced"
    assert len(traced.curves) == len(auto.curves) == 3
    for curve in traced.curves:
        assert flat_residual(curve) < 1e-6
    assert sorted(r.components for r in traced.regions) == sorted(
        r.components for r in auto.regions) == [4, 4, 4, 8]


def test_declines_where_two_cells_may_combine() -> None:
    """r1 near 2 and l0 about 1.5: the first four-bar's right rotor and the second's left rotor
    (both r1) stop driving their four-bars in the box, so an alignment in the first and one in
    the second can make a critical configuration off every flat plane: no closed form (the map
    is traced and says so)."""
    lk = build_preset("kl-chain", {"n": 4})
    assert chain_planes(lk, (1, lk.bar_ids.index("l0")), np.array([[1.9, 2.3], [1.4, 1.6]])) \
        is None
    # a gate that restricts the chain (D = 3: the gate rotor rocks in the gate four-bar), or
    # an axis that is a gate's bar: none either
    rocking = build_preset("gated-kl-chain", {"n": 4, "gate": 2, "D": 3.0})
    assert chain_planes(rocking, (0, 1), BOX) is None
    gated = build_preset("gated-kl-chain", {"n": 4, "gate": 2})
    assert chain_planes(gated, (0, gated.bar_ids.index("L2")), BOX) is None


def cranks(d: float, r: float, l2: float, l1: float) -> bool:
    """The gate four-bar (ground d, crank r, coupler l2, rocker l1): the crank turns fully and
    the rocker's two places never meet, written out: |T - G| in [|r - d|, r + d] strictly
    inside (|l2 - l1|, l2 + l1)."""
    return abs(l2 - l1) < abs(r - d) and r + d < l2 + l1


@pytest.mark.parametrize(("n", "gate"), [(4, 2), (10, 5), (5, 1)])
def test_gated_chain_has_its_chains_lines_where_the_gate_cranks(n: int, gate: int) -> None:
    """With the gate rotor a crank of the gate four-bar (D = 2, r = 1.5, L1 = L2 = 2: |T - G|
    in [0.5, 3.5] inside (0, 4)) the gate closes at every angle and carries no stress: the
    gated chain's map in r0 x r1 has the chain's lines, the first cell's flat planes; each
    point of them is a critical configuration of the gated linkage (the flat cell, the other
    tips and the gate's rocker placed by circle intersections, the rigidity matrix written
    here loses rank); a gate rotor on an axis (gate 1 in r0 x r1) is checked over the box."""
    assert cranks(2.0, 1.2, 2.0, 2.0) and cranks(2.0, 1.8, 2.0, 2.0)
    lk = build_preset("gated-kl-chain", {"n": n, "gate": gate})
    planes = chain_planes(lk, (0, 1), BOX)
    assert planes is not None and len(planes) == 1
    assert [lk.bar_ids[b] for b in planes[0].bars] == ["r0", "l0", "r1"]
    s = critical_value_slice(lk, [("r0", 1.2, 1.8), ("r1", 1.2, 1.8)], resolution=24)
    assert s.search.complete and s.search.argument == "derived"
    assert len(s.curves) == 3 and len(s.regions) == 4
    for curve in s.curves:
        assert flat_residual(curve) < 1e-9
    if (n, gate) != (4, 2):
        return
    pins = np.column_stack([np.arange(n, dtype=float), np.zeros(n)])
    slider = pins[gate] + np.array([0.0, -2.0])
    for curve in s.curves:
        r0, r1 = curve[len(curve) // 2]
        for s0, s1 in itertools.product((1.0, -1.0), repeat=2):
            t0 = s0 * r0
            t1 = t0 + s1 * 1.5
            if abs(abs(t1 - 1.0) - r1) < 1e-9:
                break
        else:
            raise AssertionError(f"({r0}, {r1}) is on no flat plane")
        tips = [np.array([t0, 0.0]), np.array([t1, 0.0])]
        for k in range(2, n):
            nxt = meet(tips[-1], 1.5, pins[k], 1.5, 1.0)
            assert nxt is not None
            tips.append(nxt)
        rocker = meet(tips[gate], 2.0, slider, 2.0, 1.0)
        assert rocker is not None  # (the gate closes: it cranks)
        assert gated_singular_value(pins, np.array(tips), gate, slider, rocker) < 1e-9


def gated_singular_value(pins: np.ndarray, tips: np.ndarray, gate: int, slider: np.ndarray,
                         rocker: np.ndarray) -> float:
    """The smallest singular value (over the largest) of the gated linkage's rigidity matrix
    in the free coordinates: the tips' x, y, the slider's y, the rocker's x, y."""
    n = len(tips)
    m = 2 * n + 3
    rows = []
    base = np.zeros(m)
    for k in range(n):  # rotors
        row = base.copy()
        row[2 * k:2 * k + 2] = tips[k] - pins[k]
        rows.append(row)
    for k in range(n - 1):  # couplers
        row = base.copy()
        row[2 * k:2 * k + 2] = tips[k] - tips[k + 1]
        row[2 * k + 2:2 * k + 4] = tips[k + 1] - tips[k]
        rows.append(row)
    row = base.copy()  # D: the pin to the slider (its y only)
    row[2 * n] = slider[1] - pins[gate][1]
    rows.append(row)
    row = base.copy()  # L1: the slider to the rocker
    row[2 * n] = slider[1] - rocker[1]
    row[2 * n + 1:] = rocker - slider
    rows.append(row)
    row = base.copy()  # L2: the gate tip to the rocker
    row[2 * gate:2 * gate + 2] = tips[gate] - rocker
    row[2 * n + 1:] = rocker - tips[gate]
    rows.append(row)
    s = np.linalg.svd(np.array(rows), compute_uv=False)
    return float(s[-1] / s[0])
