"""The gmsh model of a triangulated boundary cut into patches, built in a reproducible order.

gmsh 4.8's ``createTopology`` finds the curves between the patches and their end points itself,
but numbers the points in an order that changes from one gmsh session to the next (6 corners of
a quarter billet came out in 14 different orders in 14 sessions), and the meshes it then makes
differ (the same boundary remeshed 8 times gave 6 different meshes). Here the points, curves and
surfaces are made with tags and node orders taken from the vertex numbers only, so that the same
boundary gives the same mesh every time (``tests/test_remesh.py``).

The boundary must be a closed 2-manifold (every edge on two triangles) whose patches meet along
edges only (a vertex shared by patches lies on an edge between two of them); otherwise
:func:`discrete_model` returns False and the caller uses ``createTopology``.
"""

from __future__ import annotations

from typing import Dict, List, Tuple

import numpy as np

__all__ = ["discrete_model"]


def _cut_edges(triangles: np.ndarray, patches: np.ndarray):
    """(edges (k, 2) sorted, the patch pair (k, 2) sorted) of the edges between two patches, or
    None if some edge is not on exactly two triangles."""
    T = np.asarray(triangles, dtype=np.int64)
    E = np.sort(np.concatenate([T[:, [0, 1]], T[:, [1, 2]], T[:, [2, 0]]]), axis=1)
    owner = np.tile(np.arange(len(T)), 3)
    order = np.lexsort(E.T[::-1])
    E, owner = E[order], owner[order]
    if len(E) % 2 or not np.all(E[0::2] == E[1::2]) or \
            (len(E) > 2 and np.any(np.all(E[2::2] == E[1:-1:2], axis=1))):
        return None
    e = E[0::2]
    pa, pb = patches[owner[0::2]], patches[owner[1::2]]
    cut = pa != pb
    return e[cut], np.sort(np.stack([pa[cut], pb[cut]], axis=1), axis=1)


def _curves(n: int, edges: np.ndarray, pairs: np.ndarray) -> Tuple[List[Tuple], np.ndarray]:
    """The curves between patches: ``[(patch pair, [vertices along it])]`` cut at the corners
    (vertices on three cut edges or more, or on cut edges of two patch pairs; one vertex of
    every closed loop without any), in an order given by the vertex numbers; and the corners
    (n,) bool."""
    deg = np.bincount(edges.ravel(), minlength=n)
    corner = deg > 2
    key = pairs[:, 0] * (int(pairs.max(initial=0)) + 1) + pairs[:, 1]
    lo = np.full(n, np.iinfo(np.int64).max)
    hi = np.full(n, -1)
    for k in range(2):   # a vertex on the cut edges of two patch pairs
        np.minimum.at(lo, edges[:, k], key)
        np.maximum.at(hi, edges[:, k], key)
    corner |= (hi >= 0) & (lo != hi)
    adj: Dict[Tuple[int, int], List[int]] = {}
    order = np.lexsort((edges[:, 1], edges[:, 0], pairs[:, 1], pairs[:, 0]))
    rows = [(tuple(pairs[i].tolist()), tuple(edges[i].tolist())) for i in order]
    for pp, (i, j) in rows:
        adj.setdefault((i, pp), []).append(j)
        adj.setdefault((j, pp), []).append(i)
    used = set()

    def walk(s, t, pp):
        chain = [s, t]
        used.add((min(s, t), max(s, t)))
        while not corner[chain[-1]] and chain[-1] != chain[0]:
            nxt = [w for w in adj[(chain[-1], pp)]
                   if (min(chain[-1], w), max(chain[-1], w)) not in used]
            if not nxt:
                break
            w = min(nxt)
            used.add((min(chain[-1], w), max(chain[-1], w)))
            chain.append(w)
        return chain

    curves = []
    for pp, (i, j) in rows:
        for s, t in ((i, j), (j, i)):
            if corner[s] and (min(s, t), max(s, t)) not in used:
                curves.append((pp, walk(s, t, pp)))
    for pp, (i, j) in rows:    # closed loops without a corner: start at their lowest vertex
        if (i, j) not in used:
            corner[i] = True
            curves.append((pp, walk(i, min(adj[(i, pp)]), pp)))
    return curves, corner


def discrete_model(gmsh, points: np.ndarray, triangles: np.ndarray, patches: np.ndarray) -> bool:
    """Add to gmsh's current model the discrete surfaces (tag: patch + 1), the curves between
    them and their end points, with their nodes (tag: vertex + 1) and elements; True if done,
    False (nothing added) if the boundary is not a closed 2-manifold whose patches meet along
    edges (module docstring)."""
    P = np.asarray(points, dtype=float)
    T = np.asarray(triangles, dtype=np.int64)
    patches = np.asarray(patches, dtype=np.int64)
    cut = _cut_edges(T, patches)
    if cut is None:
        return False
    edges, pairs = cut
    curves, corner = _curves(len(P), edges, pairs)
    on_curve = np.zeros(len(P), dtype=bool)
    for _, c in curves:
        on_curve[c] = True
    # a vertex of two patches must lie on a curve between them
    lo = np.full(len(P), np.iinfo(np.int64).max)
    hi = np.full(len(P), -1)
    np.minimum.at(lo, T.ravel(), np.repeat(patches, 3))
    np.maximum.at(hi, T.ravel(), np.repeat(patches, 3))
    if np.any((lo != hi) & ~on_curve):
        return False
    model, mesh = gmsh.model, gmsh.model.mesh
    ends = sorted(set(v for _, c in curves for v in (c[0], c[-1])))
    ptag = {v: k + 1 for k, v in enumerate(ends)}
    for v in ends:
        model.addDiscreteEntity(0, ptag[v])
        mesh.addNodes(0, ptag[v], [v + 1], P[v].tolist())
    surface_curves: Dict[int, List[int]] = {}
    etag = 1
    for k, (pp, c) in enumerate(curves):
        tag = k + 1
        model.addDiscreteEntity(1, tag, [ptag[c[0]], ptag[c[-1]]])
        inner = np.asarray(c[1:-1], dtype=np.int64)
        if len(inner):
            mesh.addNodes(1, tag, (inner + 1).tolist(), P[inner].ravel().tolist())
        lines = np.stack([c[:-1], c[1:]], axis=1) + 1
        mesh.addElementsByType(tag, 1, list(range(etag, etag + len(lines))),
                               lines.ravel().tolist())
        etag += len(lines)
        for p in pp:
            surface_curves.setdefault(int(p), []).append(tag)
    for p in np.unique(patches).tolist():
        tri = T[patches == p]
        model.addDiscreteEntity(2, p + 1, surface_curves.get(p, []))
        inner = np.unique(tri)
        inner = inner[~on_curve[inner]]
        if len(inner):
            mesh.addNodes(2, p + 1, (inner + 1).tolist(), P[inner].ravel().tolist())
        mesh.addElementsByType(p + 1, 2, list(range(etag, etag + len(tri))),
                               (tri + 1).ravel().tolist())
        etag += len(tri)
    return True
