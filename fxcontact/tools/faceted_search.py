"""Search structures of a faceted tool (:class:`~fxcontact.tools.faceted.FacetedTool`): the
closest point on a triangle and the exact branch-and-bound candidate search over a box hierarchy
(see :mod:`fxcontact.tools.faceted`). Numba kernels with their numpy twins."""

from __future__ import annotations

import math

import numba
import numpy as np
from scipy.spatial import cKDTree

__all__ = ["closest_point_triangle", "closest_point_triangle_nb", "closest_point_triangle_ref",
           "facet_search", "candidates_kernel", "kdtree_hierarchy", "refit_boxes"]


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


def kdtree_hierarchy(tree: cKDTree):
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
def refit_boxes(left, start, end, perm, V, T, infl):
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
def facet_search(p, left, right, nstart, nend, blo, bhi, binfl, perm, tv, cen, rad, infl, tie_scale,
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
def candidates_kernel(P, left, right, nstart, nend, blo, bhi, binfl, perm, tv, cen, rad, T,
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
        nc = facet_search(P[i], left, right, nstart, nend, blo, bhi, binfl, perm, tv, cen, rad,
                          infl, tie_scale, stack, cf, cd, creg, cq, cb)
        if ptr[i] + nc > out.shape[0]:
            bigger = np.empty(2 * (ptr[i] + nc), dtype=np.int64)
            bigger[:ptr[i]] = out[:ptr[i]]
            out = bigger
        out[ptr[i]:ptr[i] + nc] = np.sort(cf[:nc])
        ptr[i + 1] = ptr[i] + nc
    return ptr, out[:ptr[n]].copy()
