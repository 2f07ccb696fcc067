"""An independent reference for rotor chains with the paper's gate: their components and
whether a rotor completes a turn, by dense sampling with closed-form circle intersections (no
code of the engine). Used by ``tests/engine/space/test_chain_count.py``,
``tests/engine/design/test_region_labels.py``, ``tests/engine/space/test_gate_transfer.py``
and ``tests/service/test_every_map.py``."""

from __future__ import annotations

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import breadth_first_order, connected_components


def _meet(c0: np.ndarray, r0: float, c1: np.ndarray, r1: float, side: float) -> np.ndarray:
    """Closed-form intersection of circles (c0, r0) and (c1, r1), (N, 2) centres, on ``side``
    of the line from c0 to c1 (NaN where they do not meet)."""
    d = c1 - c0
    dist = np.hypot(d[:, 0], d[:, 1])
    along = (dist**2 + r0**2 - r1**2) / (2 * dist)
    with np.errstate(invalid="ignore"):
        h = np.sqrt(r0**2 - along**2)
    unit = d / dist[:, None]
    normal = np.column_stack([-unit[:, 1], unit[:, 0]])
    return c0 + along[:, None] * unit + side * h[:, None] * normal


def sampled_gated_chain(n: int, a: float, r: float, coupler: float, gate: int, d: float, l1: float,
                        l2: float, samples: int = 3000) -> tuple[int, bool]:
    """Components of the gated chain and whether any rotor completes a turn on one, by dense
    sampling: the gate angle at ``samples`` values, every other vertex by closed-form circle
    intersections (the slider at ``P_g + (0, -+D)``, ``R`` and every tip outwards on either side
    of its centre line), one node per sample and choice of sides that exists. Nodes of the same
    choices at neighbouring samples are joined; where one intersection stops existing between
    two samples (a fold) the two sides of that intersection are joined at the last sample.
    Windings: each rotor's angle is unwound along a spanning tree of each component; an edge
    that closes a loop with a 2 pi jump is a full turn."""
    theta = 2 * np.pi * np.arange(samples) / samples
    pins = [np.array([k * a, 0.0]) for k in range(n)]
    tip_g = pins[gate] + r * np.column_stack([np.cos(theta), np.sin(theta)])
    right, left = list(range(gate + 1, n)), list(range(gate - 1, -1, -1))
    steps = 2 + len(right) + len(left)  # slider, R, then the chain outwards
    labels = 2 ** steps
    exists = np.zeros((samples, labels), dtype=bool)
    step_ok = np.zeros((steps, samples, labels), dtype=bool)
    angles = np.zeros((n, samples, labels))
    full = np.ones(samples, dtype=bool)
    for lab in range(labels):
        bits = [(lab >> s) & 1 for s in range(steps)]
        sign = [1.0 if b else -1.0 for b in bits]
        g = np.tile(pins[gate] + np.array([0.0, sign[0] * d]), (samples, 1))
        ok = full.copy()
        step_ok[0, :, lab] = ok
        rk = _meet(tip_g, l2, g, l1, sign[1])
        ok = ok & ~np.isnan(rk[:, 0])
        step_ok[1, :, lab] = ok
        tips = {gate: tip_g}
        for s, (k, prev) in enumerate([(k, k - 1) for k in right] + [(k, k + 1) for k in left]):
            tip = _meet(tips[prev], coupler, np.tile(pins[k], (samples, 1)), r,
                        sign[2 + s] * (1.0 if k > gate else -1.0))
            ok = ok & ~np.isnan(tip[:, 0])
            step_ok[2 + s, :, lab] = ok
            tips[k] = tip
        exists[:, lab] = ok
        for k in range(n):
            v = tips[k] - pins[k]
            angles[k, :, lab] = np.arctan2(v[:, 1], v[:, 0])
    node = np.arange(samples * labels).reshape(samples, labels)
    rows, cols = [], []
    nxt = np.roll(np.arange(samples), -1)
    both = exists & exists[nxt]
    rows.append(node[both])
    cols.append(node[nxt][both])
    for s in range(1, steps):  # folds of step s: it exists here, upstream exists next door
        bit = 1 << s
        lab = np.array([x for x in range(labels) if not x & bit])
        for other in (nxt, np.roll(np.arange(samples), 1)):
            upstream = step_ok[s - 1][other][:, lab]
            fold = step_ok[s][:, lab] & upstream & ~step_ok[s][other][:, lab]
            fold &= exists[:, lab] & exists[:, lab | bit]
            rows.append(node[:, lab][fold])
            cols.append(node[:, lab | bit][fold])
    return _graph_components_and_turns(rows, cols, exists, angles, samples * labels)


def sampled_general_chain(pins: np.ndarray, r: np.ndarray, couplers: np.ndarray, gate: int,
                          sliders: np.ndarray, l1: float, l2: float, sampled: int = 0,
                          samples: int = 4000) -> tuple[int, bool]:
    """Components and full turns of any gated rotor chain (pins ``(n, 2)`` and rotor lengths
    ``r`` in chain order, ``couplers`` between consecutive tips, the slider's two places
    ``sliders`` (2, 2)), by the same dense sampling as :func:`sampled_gated_chain` but with
    rotor ``sampled``'s angle sampled: the chain's tips outwards from it, then the slider's
    place, then ``R``, every one by closed-form circle intersections on either side, folds
    joined wherever one intersection stops existing between two samples."""
    n = len(pins)
    theta = 2 * np.pi * np.arange(samples) / samples
    first = pins[sampled] + r[sampled] * np.column_stack([np.cos(theta), np.sin(theta)])
    order = [(k, k - 1) for k in range(sampled + 1, n)] + \
        [(k, k + 1) for k in range(sampled - 1, -1, -1)]
    steps = len(order) + 2  # the chain outwards, the slider's place, R
    labels = 2 ** steps
    exists = np.zeros((samples, labels), dtype=bool)
    step_ok = np.zeros((steps, samples, labels), dtype=bool)
    angles = np.zeros((n, samples, labels))
    for lab in range(labels):
        sign = [1.0 if (lab >> s) & 1 else -1.0 for s in range(steps)]
        tips = {sampled: first}
        ok = np.ones(samples, dtype=bool)
        for s, (k, prev) in enumerate(order):
            tip = _meet(tips[prev], couplers[min(k, prev)], np.tile(pins[k], (samples, 1)), r[k],
                        sign[s])
            ok = ok & ~np.isnan(tip[:, 0])
            step_ok[s, :, lab] = ok
            tips[k] = tip
        step_ok[len(order), :, lab] = ok
        g = np.tile(sliders[0 if sign[len(order)] < 0 else 1], (samples, 1))
        rk = _meet(tips[gate], l2, g, l1, sign[-1])
        ok = ok & ~np.isnan(rk[:, 0])
        step_ok[-1, :, lab] = ok
        exists[:, lab] = ok
        for k in range(n):
            v = tips[k] - pins[k]
            angles[k, :, lab] = np.arctan2(v[:, 1], v[:, 0])
    return _components_and_turns(exists, step_ok, angles)


def _components_and_turns(exists: np.ndarray, step_ok: np.ndarray, angles: np.ndarray
                          ) -> tuple[int, bool]:
    """The sampled nodes joined along the samples and at folds; their components and whether
    a rotor's unwound angle jumps by a full turn around a loop."""
    steps, samples, labels = step_ok.shape
    node = np.arange(samples * labels).reshape(samples, labels)
    rows, cols = [], []
    nxt = np.roll(np.arange(samples), -1)
    both = exists & exists[nxt]
    rows.append(node[both])
    cols.append(node[nxt][both])
    for s in range(steps):  # folds of step s: it exists here, upstream exists next door
        bit = 1 << s
        lab = np.array([x for x in range(labels) if not x & bit])
        for other in (nxt, np.roll(np.arange(samples), 1)):
            upstream = step_ok[s - 1][other][:, lab] if s else np.ones((samples, len(lab)), bool)
            fold = step_ok[s][:, lab] & upstream & ~step_ok[s][other][:, lab]
            fold &= exists[:, lab] & exists[:, lab | bit]
            rows.append(node[:, lab][fold])
            cols.append(node[:, lab | bit][fold])
    return _graph_components_and_turns(rows, cols, exists, angles, samples * labels)


def _graph_components_and_turns(rows: list[np.ndarray], cols: list[np.ndarray],
                                exists: np.ndarray, angles: np.ndarray, nodes: int
                                ) -> tuple[int, bool]:
    """The components of the sampled fibres joined by the edges ``rows`` -> ``cols``, and whether
    some rotor turns along a cycle (an edge whose angle increments disagree with the potential
    of a spanning tree by a whole turn)."""
    r_idx, c_idx = np.concatenate(rows), np.concatenate(cols)
    graph = coo_matrix((np.ones(len(r_idx)), (r_idx, c_idx)),
                       shape=(nodes,) * 2).tocsr()
    _, comp = connected_components(graph, directed=False)
    live = exists.ravel()
    components = len(np.unique(comp[live]))
    flat = angles.reshape(len(angles), -1)
    pot = np.zeros_like(flat)
    seen = np.zeros(nodes, dtype=bool)
    for root in np.flatnonzero(live):
        if seen[root]:
            continue
        order, pred = breadth_first_order(graph, root, directed=False, return_predecessors=True)
        seen[order] = True
        pot[:, root] = flat[:, root]
        for v in order[1:]:
            u = pred[v]
            pot[:, v] = pot[:, u] + np.angle(np.exp(1j * (flat[:, v] - flat[:, u])))
    inc = np.angle(np.exp(1j * (flat[:, c_idx] - flat[:, r_idx])))
    jump = np.round((pot[:, c_idx] - pot[:, r_idx] - inc) / (2 * np.pi))
    return components, bool(np.any(jump != 0))
