"""A smooth reconstruction of the old boundary on which the new surface nodes are placed.

gmsh puts the new surface nodes on the old *facets*: a curved face remeshed at size h loses up
to the chord's sagitta h²/(8R) of its radius at each remesh. Here each curved patch of the old
boundary (:func:`~fxcontact.remesh.volume.surface_patches`, not the planar ones) is rebuilt as
Nagata patches (THEORY §7; :mod:`fxcontact.tools.nagata`) on nodal normals estimated within the
patch only, so that a sharp edge or a tag boundary is never averaged across:

* the normal of a vertex of patch p is that of the quadric ``w = a u + b v + c u² + d uv + e v²``
  fitted by least squares, in the frame of its angle-weighted normal within p, to the vertex and
  its :data:`NEIGHBOURS` nearest vertices of p (those whose normals are within 60° of it). On a
  smooth surface of principal radii ≥ R the fitted normal is second-order accurate,
  ε = O((h/R)²) (the cubic terms of the surface), third-order on a sphere or a cylinder (no
  cubic term: the quartic one tilts the fit by ~ρ³/(8R³) over a neighbourhood of radius ρ ≈ 2h;
  measured below 0.14 (h/R)³ on gmsh's triangulations of a sphere), where the angle-weighted
  normals are only first-order on an irregular mesh;
* a new node lying on the old triangle f of patch p (its barycentric coordinates from the closest
  point on the candidate triangles of p) goes to the Nagata patch of f at those coordinates.

Error: a Nagata edge through two points of a circle of radius R with exact normals is the
quadratic Bézier arc, off the circle by at most d⁴/(128 R³) (d the edge length); a normal error
ε moves its midpoint by about d ε/4. A new node therefore lands within O(h³/R²) of the smooth
surface, O(h⁴/R³) on a sphere or a cylinder (against h²/(8R) on the chord), and N remeshes
drift by at most N times that (``tests/test_remesh.py``: N h⁴/R³ bounds the drift of a cylinder
and of a ring's convex and concave faces).

A node on several patches (a crease between a curved face and a plane, a tag boundary) is put on
the intersection of the tangent planes there: each curved patch gives the plane through its
Nagata point normal to its Nagata normal, each planar patch its plane (exactly satisfied); curved
constraints within :data:`MERGE_ANGLE` of another (a tag boundary on a smooth face) are averaged
into one, and one within that angle of a plane is dropped.
"""

from __future__ import annotations

import logging
from typing import Dict, Iterable, List, Optional, Tuple

import numpy as np
from scipy.spatial import cKDTree

from fxcontact.tools.nagata import (patch_edge_coefficients, patch_monomials, patch_normals,
                                    patch_points)
from fxcontact.tools.normals import facet_vertex_normals, vertex_normals

__all__ = ["SmoothBoundary", "quadric_normals", "NEIGHBOURS", "MERGE_ANGLE"]

log = logging.getLogger(__name__)

#: vertices (besides the vertex itself) of the least-squares quadric of a nodal normal
NEIGHBOURS = 14

#: a fitted normal more than this angle (degrees) from the first estimate is not trusted (the
#: estimate is kept): a fit across a fold of the surface
MAX_TILT = 30.0

#: curved patches whose normals at a shared node are within this angle (degrees) are one
#: smooth surface (a tag boundary): their target points are averaged
MERGE_ANGLE = 20.0


def _frames(n: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
    """Two unit tangents (t1, t2) completing the unit normals n (k, 3) to right-handed frames."""
    a = np.where((np.abs(n[:, 0]) < 0.9)[:, None], np.array([1.0, 0.0, 0.0]),
                 np.array([0.0, 1.0, 0.0]))
    t1 = np.cross(n, a)
    t1 /= np.linalg.norm(t1, axis=1)[:, None]
    return t1, np.cross(n, t1)


def quadric_normals(points: np.ndarray, normals: np.ndarray, neighbours: int = NEIGHBOURS,
                    sweeps: int = 2) -> np.ndarray:
    """(k, 3) unit normals of a smooth surface sampled by ``points`` (k, 3), from the least-
    squares quadric through each point and its ``neighbours`` nearest points (module docstring).

    ``normals`` (k, 3) are first estimates (e.g. angle-weighted): they orient the result, give
    the first frame, and exclude neighbours whose estimate is more than 60° away (the other side
    of a thin part). A point with too few neighbours or an ill-conditioned fit keeps its
    estimate, and so does one whose fit turns it by more than :data:`MAX_TILT`. ``sweeps``
    fits, each in the frame of the previous normal.
    """
    X = np.asarray(points, dtype=float)
    n = np.asarray(normals, dtype=float)
    n = n / np.linalg.norm(n, axis=1)[:, None]
    k = min(int(neighbours) + 1, len(X))
    if k < 6:
        return n
    _, nb = cKDTree(X).query(X, k=k)
    nb = nb[:, 1:]
    ok = np.einsum("ij,ikj->ik", n, n[nb]) > 0.5
    out = n.copy()
    for _ in range(sweeps):
        t1, t2 = _frames(out)
        d = X[nb] - X[:, None, :]                                   # (k, K, 3)
        scale = np.maximum(np.max(np.linalg.norm(d, axis=2), axis=1), 1e-300)[:, None]
        u = np.einsum("ikj,ij->ik", d, t1) / scale
        v = np.einsum("ikj,ij->ik", d, t2) / scale
        w = np.einsum("ikj,ij->ik", d, out) / scale
        M = np.stack([u, v, u * u, u * v, v * v], axis=2) * ok[:, :, None]
        G = np.einsum("ika,ikb->iab", M, M)
        r = np.einsum("ika,ik->ia", M, w * ok)
        ev = np.linalg.eigvalsh(G)
        good = (ok.sum(axis=1) >= 6) & (ev[:, 0] > 1e-8 * np.maximum(ev[:, -1], 1e-300))
        coef = np.zeros((len(X), 5))
        if np.any(good):
            coef[good] = np.linalg.solve(G[good], r[good][:, :, None])[:, :, 0]
        m = out - coef[:, :1] * t1 - coef[:, 1:2] * t2
        m /= np.linalg.norm(m, axis=1)[:, None]
        good &= np.einsum("ij,ij->i", m, n) > np.cos(np.radians(MAX_TILT))
        out = np.where(good[:, None], m, out)
    return out


class SmoothBoundary:
    """The Nagata reconstruction of the curved patches of an old boundary (module docstring).

    Args:
        points, triangles: the old boundary (outward-oriented triangles).
        patches: (m,) patch number of each triangle.
        curved: the patch numbers to rebuild (the non-planar ones).
    """

    def __init__(self, points: np.ndarray, triangles: np.ndarray, patches: np.ndarray,
                 curved: Iterable[int]):
        V = np.asarray(points, dtype=float)
        T = np.asarray(triangles, dtype=np.int64)
        self.patches = np.asarray(patches)
        self._tri: Dict[int, np.ndarray] = {}
        self._tree: Dict[int, cKDTree] = {}
        rows = []
        normals = []
        for p in sorted(int(q) for q in curved):
            tri = np.flatnonzero(self.patches == p)
            sub = T[tri]
            verts, local = np.unique(sub, return_inverse=True)
            local = local.reshape(-1, 3)
            n0 = vertex_normals(V[verts], local, weighting="angle")
            nv = quadric_normals(V[verts], n0)
            rows.append(tri)
            normals.append(nv[local])                                # (len(tri), 3, 3)
            self._tri[p] = tri
            self._tree[p] = cKDTree(V[sub].mean(axis=1))
        self.V, self.T = V, T
        self.A = np.zeros((len(T), 6, 3))
        if rows:
            tri = np.concatenate(rows)
            fvn = facet_vertex_normals(V, T[tri], method=np.concatenate(normals))
            C = patch_edge_coefficients(V, T[tri], fvn)
            self.A[tri] = patch_monomials(V, T[tri], C)

    @property
    def curved(self) -> List[int]:
        return list(self._tri)

    def locate(self, x: np.ndarray, p: int, candidates: int = 12):
        """The old triangles of patch p that the points x (k, 3) lie on: ``(facet (k,),
        barycentric coordinates (k, 3), distance (k,))`` of the closest point among the
        ``candidates`` triangles of p with the nearest centroids (the clipped projection on
        each triangle's plane: exact for a point on the triangle)."""
        x = np.atleast_2d(np.asarray(x, dtype=float))
        tri = self._tri[p]
        kk = min(candidates, len(tri))
        _, cand = self._tree[p].query(x, k=kk)
        cand = tri[np.asarray(cand).reshape(len(x), kk)]                  # (k, K)
        P = self.V[self.T[cand]]                                          # (k, K, 3, 3)
        e1, e2 = P[:, :, 1] - P[:, :, 0], P[:, :, 2] - P[:, :, 0]
        r = x[:, None, :] - P[:, :, 0]
        g11, g12, g22 = (np.einsum("ikj,ikj->ik", a, b) for a, b in ((e1, e1), (e1, e2),
                                                                     (e2, e2)))
        b1, b2 = np.einsum("ikj,ikj->ik", r, e1), np.einsum("ikj,ikj->ik", r, e2)
        det = g11 * g22 - g12 * g12
        det = np.where(det > 0, det, 1.0)
        l1 = (g22 * b1 - g12 * b2) / det
        l2 = (g11 * b2 - g12 * b1) / det
        lam = np.clip(np.stack([1.0 - l1 - l2, l1, l2], axis=2), 0.0, None)
        lam /= lam.sum(axis=2, keepdims=True)
        q = np.einsum("ika,ikaj->ikj", lam, P)
        dist = np.linalg.norm(q - x[:, None, :], axis=2)
        best = np.argmin(dist, axis=1)
        i = np.arange(len(x))
        return cand[i, best], lam[i, best], dist[i, best]

    def evaluate(self, x: np.ndarray, p: int, tolerance: float = 0.0):
        """The Nagata points and unit normals (k, 3) of patch p at the points x (k, 3) lying on
        its old triangles, and the distance (k,) of x to those triangles. Points farther than
        ``tolerance`` from the triangles found are looked for again among 8 times more
        candidates (a large triangle among small ones)."""
        f, lam, dist = self.locate(x, p)
        again = np.flatnonzero(dist > tolerance)
        if len(again):
            f2, lam2, dist2 = self.locate(x[again], p, candidates=96)
            better = dist2 < dist[again]
            f[again[better]], lam[again[better]] = f2[better], lam2[better]
            dist[again[better]] = dist2[better]
        eta, zeta = lam[:, 1] + lam[:, 2], lam[:, 2]
        A = self.A[f]
        return patch_points(A, eta, zeta), patch_normals(A, eta, zeta), dist


def place_nodes(x: np.ndarray, planes: List[tuple], targets: List[tuple]) -> np.ndarray:
    """The new position of a surface node at x (3,) on the planar patches ``planes`` [(unit
    normal, offset)] and curved patches ``targets`` [(Nagata point, unit normal)] (module
    docstring): the nearest point to x on the intersection of the planes and tangent planes."""
    if not planes and len(targets) == 1:
        return targets[0][0]
    cos_merge = np.cos(np.radians(MERGE_ANGLE))
    groups: List[List[tuple]] = []
    for pt, n in targets:
        if any(abs(n @ pl[0]) > cos_merge for pl in planes):
            continue
        for g in groups:
            if abs(n @ g[0][1]) > cos_merge:
                g.append((pt, n))
                break
        else:
            groups.append([(pt, n)])
    cons = list(planes)
    for g in groups:
        nrm = np.sum([n for _, n in g], axis=0)
        nrm /= np.linalg.norm(nrm)
        cons.append((nrm, float(nrm @ np.mean([pt for pt, _ in g], axis=0))))
    if not cons:
        return x
    N = np.array([c[0] for c in cons])
    d = np.array([c[1] for c in cons])
    lam = np.linalg.lstsq(N @ N.T, N @ x - d, rcond=None)[0]
    return x - N.T @ lam


def place_surface_nodes(gmsh, origin: dict, planes: dict, smooth: Optional[SmoothBoundary],
                        tolerance: float) -> dict:
    """Move the nodes of the new surfaces: onto their planes (planar patches; a node on two
    planes or more onto their intersection) and, with ``smooth``, onto the Nagata patches of the
    curved ones (:func:`place_nodes`). A node farther than ``tolerance`` from the old triangles
    of a curved patch (gmsh did not put it on them) ignores that patch.

    Returns ``{node tag: [planes]}`` of the nodes on planar patches and ``{node tag: position
    without the smoothing}`` of the nodes the smoothing moved."""
    on: Dict[int, tuple] = {}
    for s, p in origin.items():
        tags, xyz, _ = gmsh.model.mesh.getNodes(2, s, includeBoundary=True)
        for t, x in zip(tags.tolist(), xyz.reshape(-1, 3)):
            on.setdefault(t, (x, []))[1].append(p)
    targets: Dict[int, List[tuple]] = {}
    far = 0
    if smooth is not None:
        by_patch: Dict[int, list] = {}
        for t, (x, ps) in on.items():
            for p in dict.fromkeys(ps):
                if p not in planes:
                    by_patch.setdefault(p, []).append(t)
        for p, ts in by_patch.items():
            X = np.array([on[t][0] for t in ts])
            pts, nrm, dist = smooth.evaluate(X, p, tolerance)
            for t, q, n, dd in zip(ts, pts, nrm, dist):
                if dd <= tolerance and np.any(n):
                    targets.setdefault(t, []).append((q, n))
                else:
                    far += 1
    if far:
        log.info("remesh smoothing: %d node-patch pairs farther than %.3g from the old "
                 "triangles were left on the facets", far, tolerance)
    out, flat = {}, {}
    for t, (x, ps) in on.items():
        pl = [planes[p] for p in dict.fromkeys(ps) if p in planes]
        tg = targets.get(t, [])
        if pl:
            out[t] = pl
        if tg:
            flat[t] = place_nodes(x, pl, []) if pl else x
        if pl or tg:
            gmsh.model.mesh.setNode(int(t), place_nodes(x, pl, tg).tolist(), [])
    return out, flat
