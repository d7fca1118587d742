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

__all__ = ["simplex_measures", "degenerate_cells", "overlapping_facets", "DEGENERATE_VOLUME",
           "DEGENERATE_QUALITY"]


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


#: a cell is degenerate if its volume is below this fraction of the mean cell volume …
DEGENERATE_VOLUME = 1e-10
#: … or its shape quality below this (a flat cell of normal size)
DEGENERATE_QUALITY = 1e-6


def degenerate_cells(measure: np.ndarray, quality: np.ndarray, mean_measure: float) -> np.ndarray:
    """(N,) bool: cells of (nearly) zero measure (relative to ``mean_measure``, the mean
    |measure| of the mesh) or of (nearly) zero shape quality."""
    return (np.abs(measure) <= DEGENERATE_VOLUME * mean_measure) | (quality <= DEGENERATE_QUALITY)


def overlapping_facets(X: np.ndarray, cells: np.ndarray, facet_vertices: np.ndarray,
                       facet_cells: np.ndarray) -> np.ndarray:
    """Interior facets whose two cells overlap: a tangled mesh.

    In a valid mesh the two cells that share a facet lie on opposite sides of it, whatever the
    order of their vertices (dolfinx does not orient cells consistently: a mesh may hold cells
    of both signs of the signed volume). A cell turned inside out lies on the same side as its
    neighbour across its facets.

    Args:
        X: (num_vertices, d) vertex positions.
        cells: (num_cells, d + 1) vertices of the cells.
        facet_vertices: (N, d) vertices of N interior facets.
        facet_cells: (N, 2) the two cells of each facet.
    Returns:
        (N,) bool: True where both cells' opposite vertices lie on the same side of the facet.
    """
    F = np.asarray(facet_vertices)
    if len(F) == 0:
        return np.zeros(0, dtype=bool)
    E = X[F[:, 1:]] - X[F[:, :1]]                 # (N, d-1, d) edges of the facet
    side = []
    for j in range(2):
        c = cells[facet_cells[:, j]]              # (N, d+1)
        in_facet = (c[:, :, None] == F[:, None, :]).any(axis=2)
        opp = c[~in_facet]                        # the vertex opposite the facet
        side.append(np.linalg.det(np.concatenate([E, (X[opp] - X[F[:, 0]])[:, None]], axis=1)))
    return side[0] * side[1] > 0.0
