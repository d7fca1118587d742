"""The boundary of the current (deformed) body, a triangulated surface gathered on one rank.

dolfinx 0.5 lists only the *owned* exterior facets (``exterior_facet_indices``): each boundary
facet is sent by its owner, once. Its tag may be held by another rank (a ghost facet carries
the tag on the rank that read it): the tags are matched on the root rank by the facet's sorted
global vertex numbers, so a facet owned by a rank without its tag still gets it.
"""

from __future__ import annotations

from dataclasses import dataclass

import dolfinx
import dolfinx.mesh
import numpy as np

from fxcontact import compat

__all__ = ["BoundarySurface", "gather_boundary", "UNTAGGED"]

#: tag of a boundary facet that carries none in the facet tags
UNTAGGED = -1


@dataclass
class BoundarySurface:
    """A closed triangulated surface (on the root rank; empty arrays on the others).

    Attributes:
        points: (n, 3) vertex coordinates (the current geometry).
        triangles: (m, 3) vertex indices, ordered so that the normal (b − a) × (c − a) points
            out of the body.
        tags: (m,) facet tag of each triangle (:data:`UNTAGGED` where the facet has none).
    """

    points: np.ndarray
    triangles: np.ndarray
    tags: np.ndarray

    def normals(self) -> np.ndarray:
        """(m, 3) unit outward normals."""
        P = self.points[self.triangles]
        n = np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0])
        return n / np.linalg.norm(n, axis=1)[:, None]

    def enclosed_volume(self) -> float:
        """The volume the surface encloses (divergence theorem; 0 on the other ranks)."""
        P = self.points[self.triangles]
        return float(np.sum(np.einsum("ij,ij->i", P[:, 0], np.cross(P[:, 1], P[:, 2])))) / 6.0


def _facet_keys(msh, facets) -> np.ndarray:
    """(n, 3) sorted global vertex numbers of facets (a partition-independent key)."""
    f2v = msh.topology.connectivity(msh.topology.dim - 1, 0)
    v = np.asarray(f2v.array, dtype=np.int32).reshape(-1, msh.topology.dim)[facets]
    g = np.asarray(msh.topology.index_map(0).local_to_global(v.ravel())).reshape(v.shape)
    return np.sort(g, axis=1)


def gather_boundary(msh, facet_tags=None, root: int = 0) -> BoundarySurface:
    """The exterior boundary of a tetrahedral mesh at its current geometry, with the facet
    tags, gathered on ``root`` (collective; see the module docstring for ghosts)."""
    tdim = msh.topology.dim
    if tdim != 3:
        raise ValueError(f"gather_boundary: remeshing needs a tetrahedral mesh, got tdim={tdim}")
    fdim = tdim - 1
    msh.topology.create_connectivity(fdim, tdim)
    msh.topology.create_connectivity(fdim, 0)
    msh.topology.create_connectivity(tdim, 0)
    ext = np.asarray(dolfinx.mesh.exterior_facet_indices(msh.topology), dtype=np.int32)
    f2v = np.asarray(msh.topology.connectivity(fdim, 0).array, dtype=np.int32).reshape(-1, 3)
    f2c = msh.topology.connectivity(fdim, tdim)
    cell = np.asarray(f2c.array)[np.asarray(f2c.offsets)[ext]]
    c2v = compat.cell_vertices(msh)
    verts = f2v[ext]                                                  # (m, 3)
    nverts = msh.topology.index_map(0).size_local + msh.topology.index_map(0).num_ghosts
    vgeom = compat.entities_to_geometry(msh, 0, np.arange(nverts, dtype=np.int32)).ravel()
    X = msh.geometry.x[vgeom]
    # outward orientation: the cell's vertex opposite the facet is behind it
    cv = c2v[cell]
    opp = cv[~(cv[:, :, None] == verts[:, None, :]).any(axis=2)]
    P = X[verts]
    inward = np.einsum("ij,ij->i", np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0]),
                       X[opp] - P[:, 0]) > 0
    verts[inward] = verts[inward][:, [0, 2, 1]]
    gverts = np.asarray(msh.topology.index_map(0).local_to_global(verts.ravel()),
                        dtype=np.int64).reshape(-1, 3)
    if facet_tags is not None:
        tkeys, tvals = _facet_keys(msh, facet_tags.indices), np.asarray(facet_tags.values)
    else:
        tkeys, tvals = np.zeros((0, 3), dtype=np.int64), np.zeros(0, dtype=np.int32)
    got = msh.comm.gather((gverts, X[verts].reshape(-1, 3), tkeys, tvals), root=root)
    if msh.comm.rank != root:
        return BoundarySurface(np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int32),
                               np.zeros(0, dtype=np.int32))
    G = np.concatenate([g[0] for g in got])
    XX = np.concatenate([g[1] for g in got])
    ids, first, tri = np.unique(G.ravel(), return_index=True, return_inverse=True)
    points = XX[first]
    triangles = tri.reshape(-1, 3).astype(np.int32)
    tags = np.full(len(triangles), UNTAGGED, dtype=np.int32)
    K = np.concatenate([g[2] for g in got])
    if len(K):
        V = np.concatenate([g[3] for g in got])
        table = dict(zip(map(tuple, K.tolist()), V.tolist()))
        keys = np.sort(G, axis=1)
        tags = np.array([table.get(tuple(k), UNTAGGED) for k in keys.tolist()], dtype=np.int32)
    # an order that does not depend on the partition (gmsh's result depends on the order)
    order = np.lexsort(points.T[::-1])
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    triangles = rank[triangles]
    first = np.argmin(triangles, axis=1)
    triangles = np.take_along_axis(triangles, (first[:, None] + np.arange(3)) % 3, axis=1)
    torder = np.lexsort(triangles.T[::-1])
    return BoundarySurface(points[order], triangles[torder].astype(np.int32), tags[torder])
