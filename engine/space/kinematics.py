"""Kinematics along walks of the configuration space: rotor angles, vertex positions, windings."""

from __future__ import annotations

import numpy as np

from engine.model.linkage import Linkage
from engine.space.assembly import rotors


def rotor_angles(
    linkage: Linkage, points: np.ndarray, positions: np.ndarray | None = None
) -> dict[str, np.ndarray]:
    """Unwrapped angle of every rotor (bar with exactly one fully fixed end) along ``points``
    (n, M): ``atan2`` of the vector from the fixed end to the moving end (planar only).
    ``positions`` (n, V, d), when the caller has them, are ``positions_along(linkage, points)``
    (not computed again)."""
    if linkage.dimension != 2:
        return {}
    out: dict[str, np.ndarray] = {}
    full = np.asarray(linkage.fixed.all(axis=1), dtype=bool)
    pos = positions_along(linkage, points) if positions is None else positions
    for k in rotors(linkage):
        i, j = (int(x) for x in linkage.ends[k])
        pin, tip = (i, j) if full[i] else (j, i)
        vec = pos[:, tip] - pos[:, pin]
        out[linkage.bar_ids[k]] = np.unwrap(np.arctan2(vec[:, 1], vec[:, 0]))
    return out


def positions_along(linkage: Linkage, points: np.ndarray) -> np.ndarray:
    """Vertex positions (n, V, d) of free coordinates ``points`` (n, M), all at once."""
    pts = np.asarray(points, dtype=float).reshape(len(points), -1)
    pos = np.empty((len(pts), *linkage.positions.shape))
    pos[:] = linkage.positions
    pos[:, ~linkage.fixed] = pts
    return pos


def winding(angles: np.ndarray, closed: bool) -> int | None:
    """Net number of turns of an unwrapped angle along a closed walk (None when open)."""
    if not closed or len(angles) < 2:
        return None
    return int(np.rint((angles[-1] - angles[0]) / (2 * np.pi)))
