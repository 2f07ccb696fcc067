"""The spherical four-bar's reference for the map tests, written apart from the engine: its arcs
(law of cosines), its critical equalities in the arcs, and its components by dense sampling of
the crank angle (``A`` on its hinge circle, ``B`` where three spheres meet)."""

from __future__ import annotations

import itertools

import numpy as np


class Sphere:
    """A spherical four-bar as the tests see it: pins ``O = 0``, ``G1``, ``G2``; tips at
    ``ra``, ``rb`` from ``O``; chords ``l1`` (G1 A), ``l2`` (A B), ``l3`` (B G2)."""

    def __init__(self, g1: np.ndarray, g2: np.ndarray, ra: float, rb: float) -> None:
        self.g1, self.g2, self.ra, self.rb = g1, g2, ra, rb
        self.gamma = float(np.arccos(g1 @ g2 / np.linalg.norm(g1) / np.linalg.norm(g2)))

    def arcs(self, lengths: np.ndarray) -> np.ndarray:
        """(..., 3) the angles at ``O`` of its three triangles (NaN: does not close), the
        chords ``lengths`` (..., 3) at the tips' radii; (..., 5) lengths are ``OA, OB, L1, L2,
        L3`` (the radii too)."""
        lengths = np.asarray(lengths, dtype=float)
        if lengths.shape[-1] == 5:
            ra, rb, lengths = lengths[..., 0], lengths[..., 1], lengths[..., 2:]
        else:
            ra, rb = np.full(lengths.shape[:-1], self.ra), np.full(lengths.shape[:-1], self.rb)
        p = np.stack([np.full(ra.shape, np.linalg.norm(self.g1)), ra, rb], axis=-1)
        q = np.stack([ra, rb, np.full(rb.shape, np.linalg.norm(self.g2))], axis=-1)
        cos = (p * p + q * q - lengths**2) / (2 * p * q)
        with np.errstate(invalid="ignore"):
            # (a flat triangle's cosine may round past 1)
            return np.where(np.abs(cos) <= 1 + 1e-12, np.arccos(np.clip(cos, -1, 1)), np.nan)

    def residual(self, lengths: np.ndarray) -> np.ndarray:
        """(...,) how far (radians) the arcs are from a critical equality: a signed sum minus
        the ground arc a multiple of 2 pi, or an arc 0 or pi (where a triangle is flat)."""
        a = self.arcs(lengths)
        return np.minimum(np.min(np.minimum(np.abs(a), np.abs(np.pi - a)), axis=-1),
                          self.flat_residual(lengths))

    def flat_residual(self, lengths: np.ndarray) -> np.ndarray:
        """(...,) how far (radians) a signed sum of the arcs minus the ground arc is from a
        multiple of 2 pi (every joint on one great circle)."""
        a = self.arcs(lengths)
        best = np.full(a.shape[:-1], np.inf)
        for s in itertools.product((1, -1), repeat=3):
            v = a @ np.array(s, dtype=float) - self.gamma
            best = np.minimum(best, np.abs(v - 2 * np.pi * np.round(v / (2 * np.pi))))
        return best

    def components5(self, lengths: np.ndarray, n: int = 6000) -> int:
        """:meth:`components` at the lengths ``OA, OB, L1, L2, L3`` (5,)."""
        return Sphere(self.g1, self.g2, float(lengths[0]), float(lengths[1])).components(
            np.asarray(lengths[2:], dtype=float), n)

    def components(self, lengths: np.ndarray, n: int = 6000) -> int:
        """Components by dense sampling: ``A`` at ``n`` angles on its hinge circle, ``B`` the
        (up to two) points at ``rb`` from ``O``, ``l3`` from ``G2`` and ``l2`` from ``A``. The
        angles where ``B`` exists form arcs: the whole circle holds two components (the two
        sides of the plane ``O A G2``, apart throughout), every other arc one (its ends are
        folds where the two sides meet)."""
        l1, l2, l3 = lengths
        d1 = float(np.linalg.norm(self.g1))
        axis = self.g1 / d1
        along = (self.ra**2 - l1**2 + d1**2) / (2 * d1)
        if self.ra**2 - along**2 <= 0:
            return 0
        rho = np.sqrt(self.ra**2 - along**2)
        e1 = np.cross(axis, [0.3, 0.5, 0.8])
        e1 /= np.linalg.norm(e1)
        e2 = np.cross(axis, e1)
        t = 2 * np.pi * np.arange(n) / n
        a = along * axis + rho * (np.cos(t)[:, None] * e1 + np.sin(t)[:, None] * e2)  # (n, 3)
        # B = x G2 + y A + z (G2 x A): B . G2 and B . A fixed, |B| = rb
        bg = (self.rb**2 + self.g2 @ self.g2 - l3**2) / 2
        ba = (self.rb**2 + self.ra**2 - l2**2) / 2
        gg, ga, aa = self.g2 @ self.g2, a @ self.g2, np.einsum("ij,ij->i", a, a)
        det = gg * aa - ga**2
        x = (bg * aa - ba * ga) / det
        y = (ba * gg - bg * ga) / det
        base2 = x**2 * gg + 2 * x * y * ga + y**2 * aa
        exists = self.rb**2 - base2 > 0  # (n,) the height off the plane O A G2 is real
        if exists.all():
            return 2
        if not exists.any():
            return 0
        return int(np.sum(exists & ~np.roll(exists, 1)))  # runs of the circular sequence


def preset_sphere(params: dict[str, float]) -> Sphere:
    p = {"R": 1.0, "g": 1.2} | params
    gam = 2 * np.arcsin(p["g"] / (2 * p["R"]))
    return Sphere(np.array([p["R"], 0.0, 0.0]), p["R"] * np.array([np.cos(gam), np.sin(gam), 0]),
                  p["R"], p["R"])
