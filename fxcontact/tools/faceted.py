"""Faceted rigid tools: triangulated surfaces, flat (Forge) or Nagata-smoothed (THEORY §6–8).

:class:`FacetedTool` projects points on a triangle mesh in one of two modes:

* ``"flat"`` — Forge's model: the closest facet (by true point–triangle distance, Ericson's
  Voronoi-region algorithm) is selected and the gap is the signed distance to *its plane*, the
  normal its facet normal, the gap Hessian zero.
* ``"nagata"`` — projection on the Nagata patches (§7.4) built from nodal normals (§8, Normal
  Vector Voting with crease-preserving per-(facet, vertex) normals by default), with the exact
  gap gradient and Hessian (§7.5), so that the ``implicit-exact`` scheme can be used.

The per-point work runs in ``numba.njit(cache=True)`` kernels; each has a plain numpy/Python
twin (suffix ``_ref``, reference implementation, for testing only).

Candidate search (both modes) — exact branch and bound over a box hierarchy. The hierarchy is
the node structure of a :class:`scipy.spatial.cKDTree` built on the facet centroids (library
construction, ``leafsize`` facets per leaf), refitted with the axis-aligned boxes of the facets
of each node and the largest Nagata inflation ``δ_f = max_k|c_k|/3`` of its facets (§7.2; 0 in
flat mode). For each point, a numba kernel visits the nodes nearest child first and keeps

    U = min_f (d_f + δ_f),   d_f = exact point–triangle distance (Ericson),

an upper bound of the distance to the surface; a node (or a facet, by its bounding sphere) is
pruned when its distance minus its inflation exceeds ``U``. The surviving facets
(``d_f − δ_f ≤ U``, typically 1–6 near the surface) are exactly those whose flat triangle or
Nagata patch can hold the closest point (§7.6). No candidate list is ever materialised in Python
and there is no search cut-off: **every point, however far, gets its exact (flat or patch)
distance and sign** — there is no sentinel value. The cost is logarithmic near the surface;
for a far point it grows with the area of the surface lying within a facet size of the
distance sphere (≈ 0.05–0.1 ms per point 5–20 mm away from a 10^5-facet R = 5 mm cylinder),
which is acceptable because the contact layer mostly projects nodes close to the tool.

Sign: the surface must be consistently oriented (counter-clockwise about the normal pointing to
free space). For a **closed** surface this is the outward normal and the signed volume must be
positive (use ``flip=True`` for inward-oriented meshes). **Open** surfaces (a die insert, a roll
barrel) are legal: free space is the side the oriented facet normals point to, the other side is
the tool. In flat mode the sign is that of the angle-weighted pseudo-normal of the closest
feature (Bærentzen–Aanæs: facet, edge or vertex), which is exact on closed surfaces; among
facets tied at the minimum distance, the one whose plane distance has this sign and the largest
magnitude is selected, so the Forge plane gap never has the wrong sign (|gap| ≤ true distance,
equal in face regions). In Nagata mode the sign of an interior projection is that of
``(p − x*)·n*``; for a projection on a patch edge or vertex it uses the sum of the patch normals
meeting there (edge) or the angle-weighted patch normals (vertex). Points beyond the boundary of
an open surface are in free space when they lie on the normal side of its boundary facets.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass
from typing import Optional, Tuple

import numba
import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from fxcontact.console import ALL_RANKS
from fxcontact.tools.base import Projection, RigidMotion, Tool, as_points
from fxcontact.tools.nagata import (
    _GT,
    _LOOSE,
    _RefPatch,
    _TOLA,
    _pt,
    _xe,
    _xz,
    patch_edge_coefficients,
    patch_gap_nb,
    patch_gap_ref,
    patch_monomials,
    patch_derivatives,
    patch_normals,
    project_patch_nb,
    project_patch_ref,
)
from fxcontact.tools.normals import (
    LOCAL_EDGES,
    EdgeTopology,
    FacetVertexNormals,
    corner_angles,
    edge_topology,
    facet_normals,
    facet_vertex_normals,
    unique_rows,
)

__all__ = [
    "FacetedTool",
    "CheckedSurface",
    "check_surface",
    "read_surface",
    "closest_point_triangle",
    "closest_point_triangle_nb",
    "closest_point_triangle_ref",
    "flat_project_ref",
    "nagata_project_ref",
    "FLAG_OK",
    "FLAG_FALLBACK",
    "REGION_FACE",
]

logger = logging.getLogger(__name__)

#: Projection flags.
FLAG_OK = 0
FLAG_FALLBACK = 1  #: Nagata projection did not converge; the flat projection was used.

#: Closest-point regions of a triangle: 0 face, 1 + k vertex k, 4 + k local edge k
#: (:data:`fxcontact.tools.normals.LOCAL_EDGES`).
REGION_FACE = 0


# ------------------------------------------------------------------------------------------
# Input checking and reading
# ------------------------------------------------------------------------------------------


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
    import meshio

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


# ------------------------------------------------------------------------------------------
# Closest point on a triangle (Ericson, Real-Time Collision Detection, sect. 5.1.5; THEORY §6)
# ------------------------------------------------------------------------------------------


@numba.njit(cache=True)
def closest_point_triangle_nb(p0, p1, p2, a, b, c):
    """Closest point of ``p`` on triangle ``(a, b, c)`` by Voronoi regions (numba kernel).

    Returns:
        ``(q0, q1, q2, l0, l1, l2, region)``: the point, its barycentric coordinates and the
        region (0 face, 1/2/3 vertex a/b/c, 4 edge ab, 5 edge bc, 6 edge ac).
    """
    ab0, ab1, ab2 = b[0] - a[0], b[1] - a[1], b[2] - a[2]
    ac0, ac1, ac2 = c[0] - a[0], c[1] - a[1], c[2] - a[2]
    ap0, ap1, ap2 = p0 - a[0], p1 - a[1], p2 - a[2]
    d1 = ab0 * ap0 + ab1 * ap1 + ab2 * ap2
    d2 = ac0 * ap0 + ac1 * ap1 + ac2 * ap2
    if d1 <= 0.0 and d2 <= 0.0:
        return a[0], a[1], a[2], 1.0, 0.0, 0.0, 1
    bp0, bp1, bp2 = p0 - b[0], p1 - b[1], p2 - b[2]
    d3 = ab0 * bp0 + ab1 * bp1 + ab2 * bp2
    d4 = ac0 * bp0 + ac1 * bp1 + ac2 * bp2
    if d3 >= 0.0 and d4 <= d3:
        return b[0], b[1], b[2], 0.0, 1.0, 0.0, 2
    vc = d1 * d4 - d3 * d2
    if vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:
        v = d1 / (d1 - d3)
        return a[0] + v * ab0, a[1] + v * ab1, a[2] + v * ab2, 1.0 - v, v, 0.0, 4
    cp0, cp1, cp2 = p0 - c[0], p1 - c[1], p2 - c[2]
    d5 = ab0 * cp0 + ab1 * cp1 + ab2 * cp2
    d6 = ac0 * cp0 + ac1 * cp1 + ac2 * cp2
    if d6 >= 0.0 and d5 <= d6:
        return c[0], c[1], c[2], 0.0, 0.0, 1.0, 3
    vb = d5 * d2 - d1 * d6
    if vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0:
        w = d2 / (d2 - d6)
        return a[0] + w * ac0, a[1] + w * ac1, a[2] + w * ac2, 1.0 - w, 0.0, w, 6
    va = d3 * d6 - d5 * d4
    if va <= 0.0 and (d4 - d3) >= 0.0 and (d5 - d6) >= 0.0:
        w = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        return (b[0] + w * (c[0] - b[0]), b[1] + w * (c[1] - b[1]), b[2] + w * (c[2] - b[2]),
                0.0, 1.0 - w, w, 5)
    denom = 1.0 / (va + vb + vc)
    v = vb * denom
    w = vc * denom
    return (a[0] + ab0 * v + ac0 * w, a[1] + ab1 * v + ac1 * w, a[2] + ab2 * v + ac2 * w,
            1.0 - v - w, v, w, 0)


def closest_point_triangle_ref(p, a, b, c):
    """Reference implementation, for testing only: vectorised numpy twin of
    :func:`closest_point_triangle_nb` for arrays of points/triangles (K, 3).

    Returns ``(q (K, 3), bary (K, 3), region (K,))``."""
    p, a, b, c = (np.atleast_2d(np.asarray(x, dtype=np.float64)) for x in (p, a, b, c))
    p, a, b, c = np.broadcast_arrays(p, a, b, c)
    ab, ac = b - a, c - a

    def dot(u, w):
        return np.einsum("ij,ij->i", u, w)

    d1, d2 = dot(ab, p - a), dot(ac, p - a)
    d3, d4 = dot(ab, p - b), dot(ac, p - b)
    d5, d6 = dot(ab, p - c), dot(ac, p - c)
    vc = d1 * d4 - d3 * d2
    vb = d5 * d2 - d1 * d6
    va = d3 * d6 - d5 * d4
    with np.errstate(divide="ignore", invalid="ignore"):
        v_ab = d1 / (d1 - d3)
        w_ac = d2 / (d2 - d6)
        w_bc = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        den = va + vb + vc
        v_f, w_f = vb / den, vc / den
    conds = [(d1 <= 0) & (d2 <= 0), (d3 >= 0) & (d4 <= d3), (vc <= 0) & (d1 >= 0) & (d3 <= 0),
             (d6 >= 0) & (d5 <= d6), (vb <= 0) & (d2 >= 0) & (d6 <= 0),
             (va <= 0) & ((d4 - d3) >= 0) & ((d5 - d6) >= 0)]
    one, zero = np.ones_like(d1), np.zeros_like(d1)
    bary_choices = [np.stack(x, axis=1) for x in (
        (one, zero, zero), (zero, one, zero), (1 - v_ab, v_ab, zero), (zero, zero, one),
        (1 - w_ac, zero, w_ac), (zero, 1 - w_bc, w_bc))]
    region_choices = [1, 2, 4, 3, 6, 5]
    bary = np.stack([1 - v_f - w_f, v_f, w_f], axis=1)
    region = np.zeros(d1.shape, dtype=np.int64)
    done = np.zeros(d1.shape, dtype=bool)
    for cond, bc, rg in zip(conds, bary_choices, region_choices):
        sel = cond & ~done
        bary[sel] = bc[sel]
        region[sel] = rg
        done |= sel
    # points exactly as Ericson's formulas compute them (vertex, a + v ab, a + w ac, b + w bc)
    q = a + ab * bary[:, 1:2] + ac * bary[:, 2:3]
    q[region == 1] = a[region == 1]
    q[region == 2] = b[region == 2]
    q[region == 3] = c[region == 3]
    s5 = region == 5
    q[s5] = b[s5] + bary[s5, 2:3] * (c[s5] - b[s5])
    return q, bary, region


def closest_point_triangle(p, a, b, c):
    """Closest point of point ``p`` on triangle ``(a, b, c)`` (numba kernel, single point).

    Returns ``(q (3,), barycentric (3,), region)`` (region: 0 face, 1–3 vertices, 4 ab, 5 bc,
    6 ac)."""
    p, a, b, c = (np.ascontiguousarray(x, dtype=np.float64) for x in (p, a, b, c))
    r = closest_point_triangle_nb(p[0], p[1], p[2], a, b, c)
    return np.array(r[:3]), np.array(r[3:6]), int(r[6])


# ------------------------------------------------------------------------------------------
# Search structure: bounding-box hierarchy over the k-d tree of facet centroids
# ------------------------------------------------------------------------------------------


def _kdtree_hierarchy(tree: cKDTree):
    """Flatten the node structure of a :class:`scipy.spatial.cKDTree` built on the facet
    centroids: arrays ``left, right`` (-1 for leaves), ``start, end`` (ranges in
    ``tree.indices``) and the maximum depth."""
    root = tree.tree
    nodes = [root]
    left, right, start, end, depth = [-1], [-1], [root.start_idx], [root.end_idx], [0]
    i = 0
    while i < len(nodes):
        nd = nodes[i]
        if nd.split_dim != -1 and nd.lesser is not None:
            for child, arr in ((nd.lesser, left), (nd.greater, right)):
                arr[i] = len(nodes)
                nodes.append(child)
                left.append(-1)
                right.append(-1)
                start.append(child.start_idx)
                end.append(child.end_idx)
                depth.append(depth[i] + 1)
        i += 1
    as64 = lambda a: np.asarray(a, dtype=np.int64)  # noqa: E731
    return as64(left), as64(right), as64(start), as64(end), int(max(depth))


@numba.njit(cache=True)
def _refit_boxes(left, start, end, perm, V, T, infl):
    """Axis-aligned box of the facets of every node and the largest facet inflation in it."""
    nn = left.shape[0]
    lo = np.empty((nn, 3))
    hi = np.empty((nn, 3))
    ninfl = np.zeros(nn)
    for nd in range(nn):
        for k in range(3):
            lo[nd, k] = np.inf
            hi[nd, k] = -np.inf
        for j in range(start[nd], end[nd]):
            f = perm[j]
            ninfl[nd] = max(ninfl[nd], infl[f])
            for a in range(3):
                v = T[f, a]
                for k in range(3):
                    lo[nd, k] = min(lo[nd, k], V[v, k])
                    hi[nd, k] = max(hi[nd, k], V[v, k])
    return lo, hi, ninfl


@numba.njit(cache=True)
def _box_dist(p, lo, hi, nd):
    s = 0.0
    for k in range(3):
        if p[k] < lo[nd, k]:
            s += (lo[nd, k] - p[k]) ** 2
        elif p[k] > hi[nd, k]:
            s += (p[k] - hi[nd, k]) ** 2
    return math.sqrt(s)


@numba.njit(cache=True)
def _search(p, left, right, nstart, nend, blo, bhi, binfl, perm, tv, cen, rad, infl, tie_scale,
            stack, cf, cd, creg, cq, cb):
    """Exact branch-and-bound candidate search for one point.

    Visits the hierarchy nearest child first and prunes a node when its box distance minus its
    largest facet inflation exceeds ``U = min_f (d_f + infl_f)`` (an upper bound of the
    distance to the surface; ``d_f`` the exact point–triangle distance). Stores in the buffers
    every facet with ``d_f − infl_f ≤ U`` (facet id, distance, Voronoi region, closest point,
    barycentric coordinates); returns their number."""
    U = np.inf
    nc = 0
    sp = 1
    stack[0] = 0
    while sp > 0:
        sp -= 1
        nd = stack[sp]
        tol = 1e-12 * tie_scale + 1e-10 * U
        if _box_dist(p, blo, bhi, nd) - binfl[nd] > U + tol:
            continue
        if left[nd] < 0:
            for j in range(nstart[nd], nend[nd]):
                f = perm[j]
                # cheap bound from the facet's bounding sphere
                dc = math.sqrt((p[0] - cen[j, 0]) ** 2 + (p[1] - cen[j, 1]) ** 2
                               + (p[2] - cen[j, 2]) ** 2)
                if dc - rad[j] - infl[f] > U + tol:
                    continue
                q0, q1, q2, l0, l1, l2, rg = closest_point_triangle_nb(
                    p[0], p[1], p[2], tv[j, 0], tv[j, 1], tv[j, 2])
                d = math.sqrt((p[0] - q0) ** 2 + (p[1] - q1) ** 2 + (p[2] - q2) ** 2)
                if d + infl[f] < U:
                    U = d + infl[f]
                    tol = 1e-12 * tie_scale + 1e-10 * U
                if d - infl[f] <= U + tol:
                    cf[nc] = f
                    cd[nc] = d
                    creg[nc] = rg
                    cq[nc, 0], cq[nc, 1], cq[nc, 2] = q0, q1, q2
                    cb[nc, 0], cb[nc, 1], cb[nc, 2] = l0, l1, l2
                    nc += 1
        else:
            lc, rc = left[nd], right[nd]
            dl = _box_dist(p, blo, bhi, lc) - binfl[lc]
            dr = _box_dist(p, blo, bhi, rc) - binfl[rc]
            if dl <= dr:
                if dr <= U + tol:
                    stack[sp] = rc
                    sp += 1
                if dl <= U + tol:
                    stack[sp] = lc
                    sp += 1
            else:
                if dl <= U + tol:
                    stack[sp] = lc
                    sp += 1
                if dr <= U + tol:
                    stack[sp] = rc
                    sp += 1
    tol = 1e-12 * tie_scale + 1e-10 * U
    k = 0
    for j in range(nc):
        if cd[j] - infl[cf[j]] <= U + tol:
            if k != j:
                cf[k] = cf[j]
                cd[k] = cd[j]
                creg[k] = creg[j]
                for m in range(3):
                    cq[k, m] = cq[j, m]
                    cb[k, m] = cb[j, m]
            k += 1
    return k


@numba.njit(cache=True)
def _candidates_kernel(P, left, right, nstart, nend, blo, bhi, binfl, perm, tv, cen, rad, T,
                       infl, tie_scale, depth):
    """CSR candidate lists of all points (for inspection and the reference twins)."""
    n = P.shape[0]
    M = T.shape[0]
    stack = np.empty(2 * depth + 8, dtype=np.int64)
    cf = np.empty(M, dtype=np.int64)
    cd = np.empty(M)
    creg = np.empty(M, dtype=np.int64)
    cq = np.empty((M, 3))
    cb = np.empty((M, 3))
    ptr = np.zeros(n + 1, dtype=np.int64)
    out = np.empty(max(16, 8 * n), dtype=np.int64)
    for i in range(n):
        nc = _search(P[i], left, right, nstart, nend, blo, bhi, binfl, perm, tv, cen, rad, infl,
                     tie_scale, stack, cf, cd, creg, cq, cb)
        if ptr[i] + nc > out.shape[0]:
            bigger = np.empty(2 * (ptr[i] + nc), dtype=np.int64)
            bigger[:ptr[i]] = out[:ptr[i]]
            out = bigger
        out[ptr[i]:ptr[i] + nc] = np.sort(cf[:nc])
        ptr[i + 1] = ptr[i] + nc
    return ptr, out[:ptr[n]].copy()


@numba.njit(cache=True)
def _pseudo_normal(region, f, T, fn, epn, vpn):
    if region == 0:
        return fn[f, 0], fn[f, 1], fn[f, 2]
    if region <= 3:
        v = T[f, region - 1]
        return vpn[v, 0], vpn[v, 1], vpn[v, 2]
    k = region - 4
    return epn[f, k, 0], epn[f, k, 1], epn[f, k, 2]


@numba.njit(cache=True)
def _flat_select(p, nc, cf, cd, creg, cq, V, T, fn, epn, vpn, tie_scale):
    """Forge facet choice among the ``nc`` buffered candidates.

    The facet at minimum distance gives the sign (pseudo-normal of its closest feature); among
    the facets tied at that distance, the one whose plane distance has that sign and the
    largest magnitude is chosen. Returns ``(facet, plane_gap, signed_true_distance)``."""
    jb = 0
    for j in range(1, nc):
        if cd[j] < cd[jb]:
            jb = j
    fb = cf[jb]
    dmin = cd[jb]
    n0, n1, n2 = _pseudo_normal(creg[jb], fb, T, fn, epn, vpn)
    sd = (p[0] - cq[jb, 0]) * n0 + (p[1] - cq[jb, 1]) * n1 + (p[2] - cq[jb, 2]) * n2
    a = V[T[fb, 0]]
    plane_b = (p[0] - a[0]) * fn[fb, 0] + (p[1] - a[1]) * fn[fb, 1] + (p[2] - a[2]) * fn[fb, 2]
    if sd > 0.0:
        s = 1.0
    elif sd < 0.0:
        s = -1.0
    else:
        s = 1.0 if plane_b >= 0.0 else -1.0
    tol = 1e-12 * tie_scale + 1e-10 * dmin
    choose = fb
    gbest = plane_b
    for j in range(nc):
        if j == jb or cd[j] > dmin + tol:
            continue
        f = cf[j]
        a = V[T[f, 0]]
        g = (p[0] - a[0]) * fn[f, 0] + (p[1] - a[1]) * fn[f, 1] + (p[2] - a[2]) * fn[f, 2]
        if s * g > s * gbest:
            gbest = g
            choose = f
    return choose, gbest, s * dmin


@numba.njit(cache=True)
def _flat_kernel(P, left, right, nstart, nend, blo, bhi, binfl, perm, tv, cen, rad, depth, V, T,
                 fn, epn, vpn, tie_scale, gap, normal, point, feature, sdist):
    n = P.shape[0]
    M = T.shape[0]
    infl = np.zeros(M)
    stack = np.empty(2 * depth + 8, dtype=np.int64)
    cf = np.empty(M, dtype=np.int64)
    cd = np.empty(M)
    creg = np.empty(M, dtype=np.int64)
    cq = np.empty((M, 3))
    cb = np.empty((M, 3))
    for i in range(n):
        p = P[i]
        nc = _search(p, left, right, nstart, nend, blo, bhi, binfl, perm, tv, cen, rad, infl,
                     tie_scale, stack, cf, cd, creg, cq, cb)
        f, g, sd = _flat_select(p, nc, cf, cd, creg, cq, V, T, fn, epn, vpn, tie_scale)
        gap[i] = g
        sdist[i] = sd
        feature[i] = f
        for k in range(3):
            normal[i, k] = fn[f, k]
            point[i, k] = p[k] - g * fn[f, k]


@numba.njit(cache=True)
def _patch_normal_at(a, e, z):
    m0 = _xe(a, e, z, 1) * _xz(a, e, z, 2) - _xe(a, e, z, 2) * _xz(a, e, z, 1)
    m1 = _xe(a, e, z, 2) * _xz(a, e, z, 0) - _xe(a, e, z, 0) * _xz(a, e, z, 2)
    m2 = _xe(a, e, z, 0) * _xz(a, e, z, 1) - _xe(a, e, z, 1) * _xz(a, e, z, 0)
    mn = math.sqrt(m0 * m0 + m1 * m1 + m2 * m2)
    if mn == 0.0:
        return 0.0, 0.0, 0.0
    return m0 / mn, m1 / mn, m2 / mn


@numba.njit(cache=True)
def _regular_at(a, e, z):
    """True if ``|x_η × x_ζ| > 1e-8 |x_η||x_ζ|`` at (η, ζ) (non-degenerate parametrisation)."""
    m0 = _xe(a, e, z, 1) * _xz(a, e, z, 2) - _xe(a, e, z, 2) * _xz(a, e, z, 1)
    m1 = _xe(a, e, z, 2) * _xz(a, e, z, 0) - _xe(a, e, z, 0) * _xz(a, e, z, 2)
    m2 = _xe(a, e, z, 0) * _xz(a, e, z, 1) - _xe(a, e, z, 1) * _xz(a, e, z, 0)
    ne = _xe(a, e, z, 0) ** 2 + _xe(a, e, z, 1) ** 2 + _xe(a, e, z, 2) ** 2
    nz = _xz(a, e, z, 0) ** 2 + _xz(a, e, z, 1) ** 2 + _xz(a, e, z, 2) ** 2
    return m0 * m0 + m1 * m1 + m2 * m2 > 1e-16 * ne * nz


@numba.njit(cache=True)
def _nagata_kernel(P, left, right, nstart, nend, blo, bhi, binfl, perm, tv, cen, rad, depth, V,
                   T, fn, epn, vpn, A, infl, nbr, nbr_edge, npn, tie_scale, max_iter,
                   max_halvings, want_h, gap, normal, point, hess, feature, flag, sdist_flat):
    n = P.shape[0]
    M = T.shape[0]
    stack = np.empty(2 * depth + 8, dtype=np.int64)
    cf = np.empty(M, dtype=np.int64)
    cd = np.empty(M)
    creg = np.empty(M, dtype=np.int64)
    cq = np.empty((M, 3))
    cb = np.empty((M, 3))
    nrm = np.empty(3)
    hh = np.zeros((3, 3))
    for i in range(n):
        p = P[i]
        nc = _search(p, left, right, nstart, nend, blo, bhi, binfl, perm, tv, cen, rad, infl,
                     tie_scale, stack, cf, cd, creg, cq, cb)
        ub = np.inf
        for j in range(nc):
            ub = min(ub, cd[j] + infl[cf[j]])
        ffl, gfl, sfl = _flat_select(p, nc, cf, cd, creg, cq, V, T, fn, epn, vpn, tie_scale)
        sdist_flat[i] = sfl
        tol = 1e-12 * tie_scale + 1e-10 * ub
        # project on the candidate patches that can hold the closest point
        bj = -1
        bd = np.inf
        bconv = False
        bstat = False
        be = 0.0
        bz = 0.0
        for j in range(nc):
            f = cf[j]
            a = A[f]
            e, z, st, _ = project_patch_nb(a, p, cb[j, 1] + cb[j, 2], cb[j, 2], max_iter,
                                           max_halvings, True)
            x0, x1, x2 = _pt(a, e, z)
            dj = math.sqrt((x0 - p[0]) ** 2 + (x1 - p[1]) ** 2 + (x2 - p[2]) ** 2)
            conv = st == 1
            # stationary (unconstrained gradient zero): interior-type projection
            r0, r1, r2 = x0 - p[0], x1 - p[1], x2 - p[2]
            g0 = _xe(a, e, z, 0) * r0 + _xe(a, e, z, 1) * r1 + _xe(a, e, z, 2) * r2
            g1 = _xz(a, e, z, 0) * r0 + _xz(a, e, z, 1) * r1 + _xz(a, e, z, 2) * r2
            xx = 0.0
            for k in range(3):
                xx += _xe(a, e, z, k) ** 2 + _xz(a, e, z, k) ** 2
            scale = math.sqrt(x0 * x0 + x1 * x1 + x2 * x2) + math.sqrt(
                p[0] ** 2 + p[1] ** 2 + p[2] ** 2)
            gt = max(_GT * 2.0 * math.sqrt(xx) * (dj + scale), _LOOSE * xx)
            stat = math.sqrt(g0 * g0 + g1 * g1) <= gt and _regular_at(a, e, z)
            better = False
            if bj < 0 or dj < bd - tol:
                better = True
            elif dj <= bd + tol:
                # tie: prefer converged, then stationary (interior), then the lower patch index
                # (not the smaller distance: on a shared patch edge that is decided by round-off
                # and the chosen feature would flip between Newton iterations)
                key_new = 2 * int(conv) + int(stat)
                key_old = 2 * int(bconv) + int(bstat)
                if key_new > key_old or (key_new == key_old and f < cf[bj]):
                    better = True
            if better:
                bj, bd, bconv, bstat, be, bz = j, dj, conv, stat, e, z
        if bj < 0 or not bconv:
            # fall back to the flat (Forge) projection
            flag[i] = 1
            feature[i] = ffl
            gap[i] = gfl
            for k in range(3):
                normal[i, k] = fn[ffl, k]
                point[i, k] = p[k] - gfl * fn[ffl, k]
            if want_h:
                for k in range(3):
                    for m in range(3):
                        hess[i, k, m] = 0.0
            continue
        f = cf[bj]
        a = A[f]
        flag[i] = 0
        feature[i] = f
        x0, x1, x2 = _pt(a, be, bz)
        point[i, 0], point[i, 1], point[i, 2] = x0, x1, x2
        if bstat:
            d = patch_gap_nb(a, p, be, bz, want_h, nrm, hh)
            gap[i] = d
            for k in range(3):
                normal[i, k] = nrm[k]
            if want_h:
                for k in range(3):
                    for m in range(3):
                        hess[i, k, m] = hh[k, m]
            continue
        # projection on a patch edge or vertex: pseudo-normal sign, edge/vertex derivatives
        a0 = bz <= _TOLA
        a1 = be >= 1.0 - _TOLA
        a2 = (be - bz) <= _TOLA
        nact = int(a0) + int(a1) + int(a2)
        kk = -1
        if nact >= 2:
            if a0 and a2:
                lv = 0
            elif a0 and a1:
                lv = 1
            else:
                lv = 2
            v = T[f, lv]
            pn0, pn1, pn2 = npn[v, 0], npn[v, 1], npn[v, 2]
        else:
            kk = 0 if a0 else (1 if a1 else 2)
            pn0, pn1, pn2 = _patch_normal_at(a, be, bz)
            g = nbr[f, kk]
            if g >= 0:
                kg = nbr_edge[f, kk]
                s = bz if kk == 1 else be
                la = 0 if kk != 1 else 1  # first local vertex of edge kk (0,1 / 1,2 / 0,2)
                lga = 0 if kg != 1 else 1
                sg = s if T[g, lga] == T[f, la] else 1.0 - s
                if kg == 0:
                    eg, zg = sg, 0.0
                elif kg == 1:
                    eg, zg = 1.0, sg
                else:
                    eg, zg = sg, sg
                m0, m1, m2 = _patch_normal_at(A[g], eg, zg)
                pn0 += m0
                pn1 += m1
                pn2 += m2
        if pn0 == 0.0 and pn1 == 0.0 and pn2 == 0.0:
            pn0, pn1, pn2 = fn[f, 0], fn[f, 1], fn[f, 2]
        u0, u1, u2 = p[0] - x0, p[1] - x1, p[2] - x2
        u = math.sqrt(u0 * u0 + u1 * u1 + u2 * u2)
        sd = u0 * pn0 + u1 * pn1 + u2 * pn2
        sg_ = -1.0 if sd < 0.0 else 1.0
        gap[i] = sg_ * u
        if u <= 1e-14 * tie_scale:
            pnn = math.sqrt(pn0 * pn0 + pn1 * pn1 + pn2 * pn2)
            normal[i, 0], normal[i, 1], normal[i, 2] = pn0 / pnn, pn1 / pnn, pn2 / pnn
            if want_h:
                for k in range(3):
                    for m in range(3):
                        hess[i, k, m] = 0.0
            continue
        e0, e1, e2 = u0 / u, u1 / u, u2 / u
        normal[i, 0], normal[i, 1], normal[i, 2] = sg_ * e0, sg_ * e1, sg_ * e2
        if want_h:
            ev = (e0, e1, e2)
            for k in range(3):
                for m in range(3):
                    hess[i, k, m] = ((1.0 if k == m else 0.0) - ev[k] * ev[m])
            if kk >= 0:
                # distance to the edge curve: subtract x_s x_sᵀ / H1
                if kk == 0:
                    xs0, xs1, xs2 = (_xe(a, be, bz, 0), _xe(a, be, bz, 1), _xe(a, be, bz, 2))
                    c0, c1, c2 = 2.0 * a[4, 0], 2.0 * a[4, 1], 2.0 * a[4, 2]
                elif kk == 1:
                    xs0, xs1, xs2 = (_xz(a, be, bz, 0), _xz(a, be, bz, 1), _xz(a, be, bz, 2))
                    c0, c1, c2 = 2.0 * a[5, 0], 2.0 * a[5, 1], 2.0 * a[5, 2]
                else:
                    xs0 = _xe(a, be, bz, 0) + _xz(a, be, bz, 0)
                    xs1 = _xe(a, be, bz, 1) + _xz(a, be, bz, 1)
                    xs2 = _xe(a, be, bz, 2) + _xz(a, be, bz, 2)
                    c0 = 2.0 * (a[4, 0] + a[3, 0] + a[5, 0])
                    c1 = 2.0 * (a[4, 1] + a[3, 1] + a[5, 1])
                    c2 = 2.0 * (a[4, 2] + a[3, 2] + a[5, 2])
                xxs = xs0 * xs0 + xs1 * xs1 + xs2 * xs2
                h1 = xxs - (c0 * u0 + c1 * u1 + c2 * u2)
                if h1 <= 1e-12 * xxs:
                    h1 = xxs
                xs = (xs0, xs1, xs2)
                for k in range(3):
                    for m in range(3):
                        hess[i, k, m] -= xs[k] * xs[m] / h1
            for k in range(3):
                for m in range(3):
                    hess[i, k, m] *= sg_ / u


# ------------------------------------------------------------------------------------------
# Reference twins of the mesh-level kernels (reference implementation, for testing only)
# ------------------------------------------------------------------------------------------


def _flat_select_ref(p, cands, d, reg, q, tool):
    jb = int(np.argmin(d))
    fb = cands[jb]
    if reg[jb] == 0:
        pn = tool._fn[fb]
    elif reg[jb] <= 3:
        pn = tool._vpn[tool._T[fb, reg[jb] - 1]]
    else:
        pn = tool._epn[fb, reg[jb] - 4]
    sd = (p - q[jb]) @ pn
    planes = np.einsum("ij,ij->i", p - tool._V[tool._T[cands, 0]], tool._fn[cands])
    s = 1.0 if sd > 0 else (-1.0 if sd < 0 else (1.0 if planes[jb] >= 0 else -1.0))
    tol = 1e-12 * tool._tie_scale + 1e-10 * d[jb]
    choose, gbest = jb, planes[jb]
    for j in range(len(cands)):
        if j != jb and d[j] <= d[jb] + tol and s * planes[j] > s * gbest:
            choose, gbest = j, planes[j]
    return cands[choose], gbest, s * d[jb]


def flat_project_ref(tool: "FacetedTool", P: np.ndarray, ptr: np.ndarray, idx: np.ndarray):
    """Reference implementation, for testing only: twin of the flat mesh kernel.

    Returns ``(gap, normal, point, feature, signed_true_distance)``."""
    P = np.asarray(P, dtype=np.float64)
    n = P.shape[0]
    gap, sd = np.empty(n), np.empty(n)
    feature = np.empty(n, dtype=np.int64)
    for i in range(n):
        cands = idx[ptr[i]:ptr[i + 1]]
        tri = tool._V[tool._T[cands]]
        q, _, reg = closest_point_triangle_ref(P[i], tri[:, 0], tri[:, 1], tri[:, 2])
        d = np.linalg.norm(P[i] - q, axis=1)
        feature[i], gap[i], sd[i] = _flat_select_ref(P[i], cands, d, reg, q, tool)
    normal = tool._fn[feature]
    return gap, normal, P - gap[:, None] * normal, feature, sd


def nagata_project_ref(tool: "FacetedTool", P: np.ndarray, ptr: np.ndarray, idx: np.ndarray,
                       want_hessian: bool = True):
    """Reference implementation, for testing only: twin of the Nagata mesh kernel.

    Returns ``(gap, normal, point, hessian, feature, flag)``."""
    P = np.asarray(P, dtype=np.float64)
    n = P.shape[0]
    gap = np.empty(n)
    normal = np.empty((n, 3))
    point = np.empty((n, 3))
    hess = np.zeros((n, 3, 3))
    feature = np.empty(n, dtype=np.int64)
    flag = np.zeros(n, dtype=np.int64)
    A, infl = tool._A, tool._infl
    for i in range(n):
        p = P[i]
        cands = idx[ptr[i]:ptr[i + 1]]
        tri = tool._V[tool._T[cands]]
        q, bary, reg = closest_point_triangle_ref(p, tri[:, 0], tri[:, 1], tri[:, 2])
        d = np.linalg.norm(p - q, axis=1)
        ffl, gfl, _ = _flat_select_ref(p, cands, d, reg, q, tool)
        ub = np.min(d + infl[cands])
        tol = 1e-12 * tool._tie_scale + 1e-10 * ub
        best = None
        for j, f in enumerate(cands):
            if d[j] - infl[f] > ub + tol:
                continue
            e, z, st, _ = project_patch_ref(A[f], p, bary[j, 1] + bary[j, 2], bary[j, 2],
                                            tool.max_iter, tool.max_halvings, True)
            Pf = _RefPatch(A[f])
            x = Pf.x(e, z)
            dj = np.linalg.norm(x - p)
            X = np.stack([Pf.xe(e, z), Pf.xz(e, z)], axis=1)
            xx = np.sum(X * X)
            scale = np.linalg.norm(x) + np.linalg.norm(p)
            gt = max(_GT * 2.0 * np.sqrt(xx) * (dj + scale), _LOOSE * xx)
            m = np.cross(X[:, 0], X[:, 1])
            regular = m @ m > 1e-16 * (X[:, 0] @ X[:, 0]) * (X[:, 1] @ X[:, 1])
            stat = np.linalg.norm(X.T @ (x - p)) <= gt and regular
            key = 2 * int(st == 1) + int(stat)
            if best is None or dj < best[1] - tol or (
                    dj <= best[1] + tol and (key > best[2] or (key == best[2] and f < best[0]))):
                best = (f, dj, key, e, z)
        if best is None or best[2] < 2:
            flag[i] = 1
            feature[i] = ffl
            gap[i] = gfl
            normal[i] = tool._fn[ffl]
            point[i] = p - gfl * normal[i]
            continue
        f, dj, key, e, z = best
        feature[i] = f
        Pf = _RefPatch(A[f])
        point[i] = Pf.x(e, z)
        if key & 1:
            gap[i], normal[i], h = patch_gap_ref(A[f], p, e, z, want_hessian)
            if want_hessian:
                hess[i] = h
            continue
        act = [z <= _TOLA, e >= 1.0 - _TOLA, (e - z) <= _TOLA]
        kk = -1
        if sum(act) >= 2:
            lv = 0 if (act[0] and act[2]) else (1 if (act[0] and act[1]) else 2)
            pn = tool._npn[tool._T[f, lv]]
        else:
            kk = act.index(True)
            pn = patch_normals(A[f], e, z)
            g = tool._nbr[f, kk]
            if g >= 0:
                kg = tool._nbr_edge[f, kk]
                s = z if kk == 1 else e
                same = tool._T[g, LOCAL_EDGES[kg, 0]] == tool._T[f, LOCAL_EDGES[kk, 0]]
                sg = s if same else 1.0 - s
                eg, zg = [(sg, 0.0), (1.0, sg), (sg, sg)][kg]
                pn = pn + patch_normals(A[g], eg, zg)
        if not np.any(pn):
            pn = tool._fn[f]
        w = p - point[i]
        u = np.linalg.norm(w)
        sgn = -1.0 if w @ pn < 0 else 1.0
        gap[i] = sgn * u
        if u <= 1e-14 * tool._tie_scale:
            normal[i] = pn / np.linalg.norm(pn)
            continue
        ev = w / u
        normal[i] = sgn * ev
        if want_hessian:
            h = np.eye(3) - np.outer(ev, ev)
            if kk >= 0:
                xs = Pf.edge_tangent(kk, z if kk == 1 else e)
                xss = Pf.edge_second(kk)
                h1 = xs @ xs - xss @ w
                if h1 <= 1e-12 * (xs @ xs):
                    h1 = xs @ xs
                h -= np.outer(xs, xs) / h1
            hess[i] = sgn * h / u
    return gap, normal, point, (hess if want_hessian else None), feature, flag


# ------------------------------------------------------------------------------------------
# The tool
# ------------------------------------------------------------------------------------------


class FacetedTool(Tool):
    """A rigid tool given by a triangulated surface, flat (Forge) or Nagata-smoothed.

    Args:
        vertices: (N, 3) vertex coordinates in the reference frame (t = 0).
        triangles: (M, 3) vertex indices, counter-clockwise about the normal pointing to free
            space (the outward normal of a closed tool). Open surfaces are legal: free space is
            the side the oriented normals point to.
        mode: ``"nagata"`` (smoothed patches, exact gap Hessian) or ``"flat"`` (Forge: plane of
            the closest facet, Hessian 0).
        normals: nodal normals for the Nagata patches: ``"nvv"`` (Normal Vector Voting,
            crease-preserving, default), ``"angle"``, ``"area"`` (weighted averages, creases
            smeared), or an array of (N, 3) vertex normals or (M, 3, 3) per-(facet, vertex)
            normals (e.g. from CAD). Ignored in flat mode.
        crease_angle: NVV crease angle φc [rad] (§8.2); ``None`` disables crease detection.
        flip: reverse every triangle (for meshes oriented inward).
        velocity, angular_velocity, axis_point, axis: the rigid motion
            (:class:`~fxcontact.tools.base.RigidMotion`).
        name: label.
        kappa: Nagata safeguard κ: edge coefficients with |c| > κ|d| are zeroed (§7.1).
        max_iter: Newton iterations per patch projection (§7.4).
        max_halvings: step halvings per Newton iteration (sub-incrementation).
        leafsize: facets per leaf of the search hierarchy (tuning only; results do not depend
            on it).

    Attributes:
        last_fallbacks: number of points of the last projection for which the Nagata projection
            did not converge and the flat projection was used (``flag == 1``); also logged as a
            warning. ``total_fallbacks`` accumulates over all projections.
        closed: whether the surface is closed.
        has_hessian: True in both modes (zero in flat mode).

    Projection fields: ``gap``/``normal``/``hessian`` as in :class:`~fxcontact.tools.base.
    Projection`; ``point`` is the closest patch point (Nagata) or the foot ``p − gap n`` on the
    chosen facet plane (flat); ``feature`` is the index of the chosen facet/patch (triangle order
    is that of the input); ``flag`` is 1 for a flat fall-back. For a projection on a patch
    edge or vertex (sharp creases, open boundaries) the normal is ``(p − x*)/d`` and the Hessian
    the distance-to-curve / distance-to-point one. See the module docstring for the candidate
    search and the sign conventions.
    """

    has_hessian = True

    def __init__(self, vertices, triangles, mode: str = "nagata", normals="nvv",
                 crease_angle: Optional[float] = math.radians(50.0), flip: bool = False,
                 velocity=(0.0, 0.0, 0.0), angular_velocity=0.0, axis_point=(0.0, 0.0, 0.0),
                 axis=(0.0, 0.0, 1.0), name: str = "faceted", kappa: float = 1.0,
                 max_iter: int = 30, max_halvings: int = 12, leafsize: int = 4):
        if mode not in ("nagata", "flat"):
            raise ValueError(f"mode must be 'nagata' or 'flat', got {mode!r}")
        if int(max_iter) < 0 or int(max_halvings) < 0:
            raise ValueError("max_iter and max_halvings must be >= 0")
        self.mode = mode
        self.name = name
        self.motion = RigidMotion(velocity, angular_velocity, axis_point, axis)
        self.max_iter = int(max_iter)
        self.max_halvings = int(max_halvings)
        self.kappa = float(kappa)
        self.crease_angle = crease_angle
        self.last_fallbacks = 0
        self.total_fallbacks = 0
        n_in = np.asarray(vertices).shape[0] if np.ndim(vertices) == 2 else -1
        surf = check_surface(vertices, triangles, flip=flip)
        self.surface = surf
        self.closed = surf.closed
        V, T = surf.vertices, surf.triangles
        self._V = np.ascontiguousarray(V)
        self._T = np.ascontiguousarray(T)
        topo = surf.topology
        self._fn, self._area = facet_normals(V, T)
        ang = corner_angles(V, T)
        # flat pseudo-normals (Bærentzen–Aanæs): edges n_f + n_g, vertices angle-weighted
        nbr = topo.neighbor
        self._nbr = np.ascontiguousarray(nbr)
        self._nbr_edge = np.ascontiguousarray(topo.neighbor_edge)
        epn = np.repeat(self._fn[:, None, :], 3, axis=1)
        epn = epn + np.where((nbr >= 0)[:, :, None], self._fn[np.maximum(nbr, 0)], 0.0)
        self._epn = np.ascontiguousarray(epn)
        self._vpn = self._vertex_sum(ang, np.repeat(self._fn[:, None, :], 3, axis=1))
        centroids = V[T].mean(axis=1)
        self._tie_scale = float(np.max(np.abs(V)) + np.linalg.norm(V.max(0) - V.min(0)))
        tree = cKDTree(centroids, leafsize=int(leafsize))
        self._perm = np.ascontiguousarray(tree.indices, dtype=np.int64)
        self._left, self._right, self._nstart, self._nend, self._depth = _kdtree_hierarchy(tree)
        # facet data in leaf order: vertices, bounding-sphere centre and radius
        self._tv = np.ascontiguousarray(V[T[self._perm]])
        self._cen = np.ascontiguousarray(centroids[self._perm])
        self._rad = np.linalg.norm(self._tv - self._cen[:, None, :], axis=2).max(axis=1)
        self.fvn: Optional[FacetVertexNormals] = None
        if mode == "nagata":
            if not isinstance(normals, str):
                arr = np.asarray(normals, dtype=np.float64)
                if arr.ndim == 2 and arr.shape[0] == n_in and arr.shape[1] == 3:
                    arr = arr[surf.vertex_map]
                normals = arr
            self.fvn = facet_vertex_normals(V, T, normals, crease_angle=crease_angle,
                                            topology=topo)
            C = patch_edge_coefficients(V, T, self.fvn, kappa=self.kappa)
            self._C = C
            self._A = patch_monomials(V, T, C)
            self._infl = np.max(np.linalg.norm(C, axis=2), axis=1) / 3.0
            self._infl = self._infl * (1.0 + 1e-12) + 1e-15 * self._tie_scale
            # Nagata vertex pseudo-normals: angle-weighted patch normals at the corners
            xi = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0]])
            corner_n = np.stack([patch_normals(self._A, xi[k, 0], xi[k, 1]) for k in range(3)],
                                axis=1)
            degenerate = np.linalg.norm(corner_n, axis=2) == 0.0  # collapsed corner tangents
            corner_n[degenerate] = np.repeat(self._fn[:, None, :], 3, axis=1)[degenerate]
            self._npn = self._vertex_sum(self._patch_corner_angles(), corner_n)
        else:
            self._C = np.zeros((T.shape[0], 3, 3))
            self._A = patch_monomials(V, T, self._C)
            self._infl = np.zeros(T.shape[0])
            self._npn = self._vpn
        self._blo, self._bhi, self._binfl = _refit_boxes(self._left, self._nstart, self._nend,
                                                         self._perm, self._V, self._T,
                                                         self._infl)
        logger.info("%s: %d vertices, %d triangles, %s surface, mode %s, max|c|/3 = %.3g",
                    name, V.shape[0], T.shape[0], "closed" if self.closed else "open", mode,
                    float(self._infl.max()))

    # -- construction helpers ---------------------------------------------------------------

    def _vertex_sum(self, w: np.ndarray, vec: np.ndarray) -> np.ndarray:
        """Sum ``w[f, a] * vec[f, a]`` into the vertices ``T[f, a]``; (N, 3) contiguous."""
        idx = self._T.reshape(-1)
        contrib = (w[:, :, None] * vec).reshape(-1, 3)
        out = np.stack([np.bincount(idx, weights=contrib[:, j], minlength=self._V.shape[0])
                        for j in range(3)], axis=1)
        return np.ascontiguousarray(out)

    def _patch_corner_angles(self) -> np.ndarray:
        A = self._A
        xe0, xz0 = patch_derivatives(A, 0.0, 0.0)
        xe1, xz1 = patch_derivatives(A, 1.0, 0.0)
        xe2, xz2 = patch_derivatives(A, 1.0, 1.0)
        pairs = [(xe0, xe0 + xz0), (-xe1, xz1), (-xz2, -(xe2 + xz2))]
        out = np.empty((A.shape[0], 3))
        for k, (u, w) in enumerate(pairs):
            out[:, k] = np.arctan2(np.linalg.norm(np.cross(u, w), axis=1),
                                   np.einsum("ij,ij->i", u, w))
        return out

    @classmethod
    def from_file(cls, path: str, **kwargs) -> "FacetedTool":
        """Build a tool from a surface mesh file (gmsh .msh, STL, OBJ, ... read with meshio).

        STL files carry no connectivity; meshio merges exactly coincident points, which is
        what CAD exports need. ``kwargs`` are passed to the constructor (``name`` defaults to
        the file name)."""
        import os

        V, T = read_surface(path)
        kwargs.setdefault("name", os.path.basename(path))
        return cls(V, T, **kwargs)

    # -- properties ----------------------------------------------------------------------

    @property
    def vertices(self) -> np.ndarray:
        """(N, 3) vertices in the reference frame (read-only view)."""
        v = self._V.view()
        v.flags.writeable = False
        return v

    @property
    def triangles(self) -> np.ndarray:
        """(M, 3) triangles (read-only view)."""
        t = self._T.view()
        t.flags.writeable = False
        return t

    @property
    def facet_normals(self) -> np.ndarray:
        return self._fn

    @property
    def patch_coefficients(self) -> np.ndarray:
        """(M, 3, 3) Nagata edge coefficients (c1, c2, c3) per triangle (zero in flat mode)."""
        return self._C

    @property
    def patches(self) -> np.ndarray:
        """(M, 6, 3) Nagata monomial coefficients (flat triangles in flat mode)."""
        return self._A

    @property
    def vertex_class(self) -> Optional[np.ndarray]:
        """NVV vertex classes (1 surface, 2 crease, 3 corner), ``None`` in flat mode."""
        return None if self.fvn is None else self.fvn.vertex_class

    # -- candidate search ----------------------------------------------------------------

    def _bvh(self):
        return (self._left, self._right, self._nstart, self._nend, self._blo, self._bhi,
                self._binfl, self._perm, self._tv, self._cen, self._rad)

    def candidates(self, y: np.ndarray, flat: bool = False) -> Tuple[np.ndarray, np.ndarray]:
        """Candidate facets/patches of each point (reference frame), CSR ``(ptr, idx)``.

        These are exactly the facets the projection kernels examine: every facet whose flat
        triangle (flat mode or ``flat=True``; then only the facets at the minimum distance) or
        Nagata patch (nagata mode) can hold the closest point (see the module docstring)."""
        y = np.ascontiguousarray(y, dtype=np.float64)
        infl = np.zeros(self._T.shape[0]) if flat else self._infl
        return _candidates_kernel(y, *self._bvh(), self._T, infl, self._tie_scale, self._depth)

    # -- projection ----------------------------------------------------------------------

    def flat_signed_distance(self, x, t: float = 0.0) -> np.ndarray:
        """Exact signed distance of points to the flat triangulated surface at time ``t``
        (pseudo-normal sign), independent of the mode."""
        x = as_points(x)
        y = x if self.motion.is_static else self.motion.to_reference(x, t)
        n = y.shape[0]
        out = [np.empty(n), np.empty((n, 3)), np.empty((n, 3)), np.empty(n, dtype=np.int64),
               np.empty(n)]
        _flat_kernel(y, *self._bvh(), self._depth, self._V, self._T, self._fn, self._epn,
                     self._vpn, self._tie_scale, *out)
        return out[4]

    def _project_reference(self, y: np.ndarray, hessian: bool) -> Projection:
        n = y.shape[0]
        gap = np.empty(n)
        normal = np.empty((n, 3))
        point = np.empty((n, 3))
        feature = np.empty(n, dtype=np.int64)
        flag = np.zeros(n, dtype=np.int64)
        sdist = np.empty(n)
        if n == 0:
            self.last_fallbacks = 0
            return Projection(gap, normal, point, np.zeros((0, 3, 3)) if hessian else None,
                              feature, flag)
        if self.mode == "flat":
            _flat_kernel(y, *self._bvh(), self._depth, self._V, self._T, self._fn, self._epn,
                         self._vpn, self._tie_scale, gap, normal, point, feature, sdist)
            hess = np.zeros((n, 3, 3)) if hessian else None
            self.last_fallbacks = 0
            return Projection(gap, normal, point, hess, feature, flag)
        hess = np.zeros((n, 3, 3)) if hessian else np.zeros((1, 3, 3))
        _nagata_kernel(y, *self._bvh(), self._depth, self._V, self._T, self._fn, self._epn,
                       self._vpn, self._A, self._infl, self._nbr, self._nbr_edge, self._npn,
                       self._tie_scale, self.max_iter, self.max_halvings, bool(hessian), gap,
                       normal, point, hess, feature, flag, sdist)
        nfb = int(np.count_nonzero(flag))
        self.last_fallbacks = nfb
        self.total_fallbacks += nfb
        if nfb:
            logger.warning("%s: Nagata projection did not converge for %d of %d points; the "
                           "flat projection was used for them (flag = 1)", self.name, nfb, n,
                           extra=ALL_RANKS)  # rank-local: this rank's points
        return Projection(gap, normal, point, hess if hessian else None, feature, flag)

    def __repr__(self) -> str:
        return (f"FacetedTool(name={self.name!r}, mode={self.mode!r}, vertices="
                f"{self._V.shape[0]}, triangles={self._T.shape[0]}, closed={self.closed})")
