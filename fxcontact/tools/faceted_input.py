"""Input of a faceted tool (:class:`~fxcontact.tools.faceted.FacetedTool`): the checks of a
triangulated surface, naming the bad triangles and vertices, and reading it from a file."""

from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import Tuple

import meshio
import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from fxcontact.tools.normals import EdgeTopology, edge_topology, unique_rows

__all__ = ["CheckedSurface", "check_surface", "read_surface"]

#: the faceted tool's logger (its warnings about the input keep that name)
logger = logging.getLogger("fxcontact.tools.faceted")


@dataclass(frozen=True)
class CheckedSurface:
    """A validated, consistently oriented triangle surface.

    Attributes:
        vertices: (N, 3) float64 (unused input vertices dropped).
        triangles: (M, 3) int64 (reversed if ``flip``).
        closed: every edge is shared by exactly two triangles.
        vertex_map: (N,) index of each kept vertex in the input vertex array.
        topology: the :class:`~fxcontact.tools.normals.EdgeTopology`.
    """

    vertices: np.ndarray
    triangles: np.ndarray
    closed: bool
    vertex_map: np.ndarray
    topology: EdgeTopology


def _first(a, n=10):
    return np.asarray(a)[:n].tolist()


def check_surface(vertices, triangles, flip: bool = False) -> CheckedSurface:
    """Validate a triangle surface for use as a tool; raise ``ValueError`` naming the culprits.

    Checks, in order: array shapes; NaN/inf coordinates (vertex indices); triangle indices out of
    range (triangle indices); degenerate triangles (repeated vertex or zero area, i.e.
    ``2A ≤ 1e-12 ℓ_max²``); duplicate triangles (same vertex set); non-manifold edges (shared by
    more than two triangles); inconsistent orientation (an interior edge traversed twice in the
    same direction); facet normals pointing into the tool (negative signed volume of a closed
    connected component; components with boundary edges are open surfaces and are not checked).
    Unused vertices are dropped with a warning.

    Args:
        vertices: (N, 3) coordinates.
        triangles: (M, 3) vertex indices, counter-clockwise about the normal pointing to free
            space.
        flip: reverse the orientation of every triangle first (for inward-oriented meshes).

    Returns:
        :class:`CheckedSurface`.
    """
    V = np.asarray(vertices)
    T = np.asarray(triangles)
    if V.ndim != 2 or V.shape[1] != 3 or V.shape[0] < 3:
        raise ValueError(f"vertices must have shape (N >= 3, 3), got {V.shape}")
    if T.ndim != 2 or T.shape[1] != 3 or T.shape[0] < 1:
        raise ValueError(f"triangles must have shape (M >= 1, 3), got {T.shape}")
    try:
        V = V.astype(np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"vertices are not numeric: {exc}") from None
    if not np.issubdtype(T.dtype, np.integer):
        Tf = np.asarray(T, dtype=np.float64)
        if not np.all(np.isfinite(Tf)) or np.any(Tf != np.round(Tf)):
            bad = np.flatnonzero(~np.all(np.isfinite(Tf) & (Tf == np.round(Tf)), axis=1))
            raise ValueError(f"triangles contain non-integer indices in triangles {_first(bad)}")
    T = T.astype(np.int64)
    N, M = V.shape[0], T.shape[0]
    bad = np.flatnonzero(~np.all(np.isfinite(V), axis=1))
    if bad.size:
        raise ValueError(f"vertices contain NaN/inf coordinates at vertex indices {_first(bad)}")
    bad = np.flatnonzero(np.any((T < 0) | (T >= N), axis=1))
    if bad.size:
        raise ValueError(f"triangle vertex indices out of range [0, {N}) in triangles "
                         f"{_first(bad)} (e.g. {T[bad[0]].tolist()})")
    # degenerate triangles
    rep = (T[:, 0] == T[:, 1]) | (T[:, 1] == T[:, 2]) | (T[:, 0] == T[:, 2])
    P = V[T]
    m = np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0])
    two_a = np.linalg.norm(m, axis=1)
    lmax2 = np.max(np.stack([np.sum((P[:, (k + 1) % 3] - P[:, k]) ** 2, axis=1)
                             for k in range(3)], axis=1), axis=1)
    bad = np.flatnonzero(rep | (two_a <= 1e-12 * lmax2) | (lmax2 == 0.0))
    if bad.size:
        raise ValueError(f"degenerate (zero-area) triangles {_first(bad)}")
    # duplicates
    key = np.sort(T, axis=1)
    _, inv, cnt = unique_rows(key, return_inverse=True, return_counts=True)
    inv = inv.reshape(-1)
    if np.any(cnt > 1):
        groups = [np.flatnonzero(inv == g).tolist() for g in np.flatnonzero(cnt > 1)[:10]]
        raise ValueError(f"duplicate triangles (same vertices), groups of triangle indices: "
                         f"{groups}")
    if flip:
        T = T[:, [0, 2, 1]]
    topo = edge_topology(T)
    nm = np.flatnonzero(topo.count > 2)
    if nm.size:
        e = nm[0]
        tris = np.flatnonzero(np.any(topo.tri_edge == e, axis=1))
        raise ValueError(f"non-manifold edges shared by more than 2 triangles: {nm.size} edges, "
                         f"e.g. edge (vertices {topo.edges[e].tolist()}) in triangles "
                         f"{_first(tris)}")
    # orientation: directed half-edges v_k -> v_{k+1} must be unique
    half = np.stack([T, np.roll(T, -1, axis=1)], axis=2).reshape(-1, 2)
    _, hinv, hcnt = unique_rows(half, return_inverse=True, return_counts=True)
    hinv = hinv.reshape(-1)
    if np.any(hcnt > 1):
        g = np.flatnonzero(hcnt > 1)
        slots = np.flatnonzero(hinv == g[0])
        raise ValueError(
            f"inconsistent orientation: {g.size} interior edges are traversed twice in the same "
            f"direction, e.g. edge {half[slots[0]].tolist()} in triangles "
            f"{(slots // 3).tolist()}; reorient the triangles consistently")
    # unused vertices
    used = np.zeros(N, dtype=bool)
    used[T.reshape(-1)] = True
    vmap = np.flatnonzero(used)
    if vmap.size < N:
        logger.warning("tool surface: %d unused vertices dropped (e.g. %s)", N - vmap.size,
                       _first(np.flatnonzero(~used), 5))
        remap = np.full(N, -1, dtype=np.int64)
        remap[vmap] = np.arange(vmap.size)
        T = remap[T]
        V = V[vmap]
        topo = edge_topology(T)
    closed = topo.is_closed
    # signed volume of every closed connected component (components with boundary edges are
    # open surfaces: no inside, no volume check)
    nb = topo.neighbor
    f, k = np.nonzero(nb >= 0)
    graph = coo_matrix((np.ones(f.size), (f, nb[f, k])), shape=(M, M))
    ncomp, lab = connected_components(graph, directed=False)
    open_comp = np.zeros(ncomp, dtype=bool)
    open_comp[lab[np.nonzero(nb < 0)[0]]] = True
    P = V[T]
    vol6 = np.einsum("ij,ij->i", P[:, 0], np.cross(P[:, 1], P[:, 2]))
    vols = np.bincount(lab, weights=vol6, minlength=ncomp) / 6.0
    neg = np.flatnonzero((vols < 0.0) & ~open_comp)
    if neg.size:
        tris = np.flatnonzero(lab == neg[0])
        raise ValueError(
            f"facet normals point into the tool: closed component {int(neg[0])} (triangles "
            f"{_first(tris)}...) has signed volume {vols[neg[0]]:.6g} < 0; orient the "
            f"triangles counter-clockwise about the outward normal or pass flip=True")
    return CheckedSurface(V, T, closed, vmap, topo)


def read_surface(path: str) -> Tuple[np.ndarray, np.ndarray]:
    """Read a triangle surface (gmsh .msh, STL, OBJ, or any format meshio knows).

    All ``triangle`` cell blocks are concatenated (``quad`` cells are split into two triangles);
    other cells (lines, points, volume cells) are ignored. Returns ``(vertices, triangles)``.
    """

    mesh = meshio.read(path)
    tris = []
    for block in mesh.cells:
        data = np.asarray(block.data, dtype=np.int64)
        if block.type == "triangle":
            tris.append(data)
        elif block.type == "quad":
            tris.append(data[:, [0, 1, 2]])
            tris.append(data[:, [0, 2, 3]])
    if not tris:
        raise ValueError(f"{path}: no triangle cells found (cell types: "
                         f"{[b.type for b in mesh.cells]})")
    pts = np.asarray(mesh.points, dtype=np.float64)
    if pts.shape[1] == 2:
        pts = np.hstack([pts, np.zeros((pts.shape[0], 1))])
    return pts, np.vstack(tris)

