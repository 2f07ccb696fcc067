"""The reporting convention for vectors (API.md): unit 2-norm, largest-magnitude entry positive."""

from __future__ import annotations

import numpy as np


def normalise_sign(vectors: np.ndarray) -> np.ndarray:
    """Flip each row so that its largest-magnitude entry is positive.

    Ties (entries equal in magnitude up to ``1e-8`` relative, e.g. ``(s, -s, -s)``) are broken
    by the *first* such entry, so roundoff cannot flip the sign between runs.
    """
    vectors = np.asarray(vectors, dtype=float)
    if vectors.size == 0:
        return vectors
    mags = np.abs(vectors)
    top = mags.max(axis=1, keepdims=True)
    first = np.argmax(mags >= (1 - 1e-8) * top, axis=1)
    signs = np.sign(vectors[np.arange(len(vectors)), first])
    signs[signs == 0] = 1.0
    return vectors * signs[:, None]


def normalised(v: np.ndarray) -> np.ndarray:
    """Unit 2-norm and the sign convention (a zero vector stays zero)."""
    norm = float(np.linalg.norm(v))
    if norm == 0.0:
        return v
    return normalise_sign((v / norm)[None, :])[0]
