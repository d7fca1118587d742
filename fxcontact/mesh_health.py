"""Mesh health of simplex cells: signed measure and shape quality, vectorised.

The quality is the normalised shape ratio

    q = 12 (3|V|)^(2/3) / Σ l²   (tetrahedron),     q = 4√3 |A| / Σ l²   (triangle),

Σ l² the sum of the squared edge lengths: 1 for the regular simplex, → 0 for a flat one. The
:class:`~fxcontact.simulation.Simulation` records per increment the smallest quality (made
negative for a cell whose signed volume changed sign) and the smallest ratio of a cell's signed
volume to its initial one, and rejects a geometry update that would turn a cell inside out.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["simplex_measures"]


def simplex_measures(P: np.ndarray):
    """Signed measure and shape quality of simplices.

    Args:
        P: (N, d + 1, d) vertex coordinates of N triangles (d = 2) or tetrahedra (d = 3).
    Returns:
        ``(measure, quality)``: (N,) signed area/volume det[P1−P0, …]/d! and (N,) q in [0, 1].
    """
    P = np.asarray(P, dtype=np.float64)
    n, nv, d = P.shape
    if nv != d + 1 or d not in (2, 3):
        raise ValueError(f"need (N, d+1, d) simplex vertices with d = 2 or 3, got {P.shape}")
    if n == 0:
        return np.zeros(0), np.zeros(0)
    E = P[:, 1:] - P[:, :1]
    vol = np.linalg.det(E) / math.factorial(d)
    L2 = sum(np.sum((P[:, i] - P[:, j]) ** 2, axis=1) for i in range(nv)
             for j in range(i + 1, nv))
    with np.errstate(divide="ignore", invalid="ignore"):
        if d == 3:
            q = 12.0 * np.cbrt(3.0 * np.abs(vol)) ** 2 / L2
        else:
            q = 4.0 * math.sqrt(3.0) * np.abs(vol) / L2
    return vol, np.where(L2 > 0, q, 0.0)
