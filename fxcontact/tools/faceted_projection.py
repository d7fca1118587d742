"""Mesh-level projection kernels of a faceted tool (:class:`~fxcontact.tools.faceted.FacetedTool`):
flat (closest facet, pseudo-normal sign) and Nagata (patches, exact gap derivatives), numba
kernels over the candidate search, and their reference twins (for testing only)."""

from __future__ import annotations

import math

import numba
import numpy as np

from fxcontact.tools.faceted_search import closest_point_triangle_ref, facet_search
from fxcontact.tools.nagata import (ACCEPT_TOL, ACTIVE_TOL, GRADIENT_TOL, RefPatch, patch_gap_nb,
                                    patch_gap_ref, patch_normals, project_patch_nb,
                                    project_patch_ref, pt_nb, xe_nb, xz_nb)
from fxcontact.tools.normals import LOCAL_EDGES

__all__ = ["flat_project_ref", "nagata_project_ref", "flat_kernel", "nagata_kernel"]


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
def flat_kernel(P, left, right, nstart, nend, blo, bhi, binfl, perm, tv, cen, rad, depth, V, T,
                fn, epn, vpn, tie_scale, gap, normal, point, feature, sdist):
    """Flat projection of the points ``P`` (N, 3) on the facets ``T`` of the vertices ``V``
    through the facet hierarchy (:func:`~fxcontact.tools.faceted_search.facet_search`): the
    closest facet, signed by its pseudo-normal; writes ``gap``, ``normal``, ``point``,
    ``feature`` (the facet) and ``sdist`` of every point (numba; the reference twin is
    :func:`flat_project_ref`; called by :class:`~fxcontact.tools.faceted.FacetedTool`)."""
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
        nc = facet_search(p, left, right, nstart, nend, blo, bhi, binfl, perm, tv, cen, rad, infl,
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
    m0 = xe_nb(a, e, z, 1) * xz_nb(a, e, z, 2) - xe_nb(a, e, z, 2) * xz_nb(a, e, z, 1)
    m1 = xe_nb(a, e, z, 2) * xz_nb(a, e, z, 0) - xe_nb(a, e, z, 0) * xz_nb(a, e, z, 2)
    m2 = xe_nb(a, e, z, 0) * xz_nb(a, e, z, 1) - xe_nb(a, e, z, 1) * xz_nb(a, e, z, 0)
    mn = math.sqrt(m0 * m0 + m1 * m1 + m2 * m2)
    if mn == 0.0:
        return 0.0, 0.0, 0.0
    return m0 / mn, m1 / mn, m2 / mn


@numba.njit(cache=True)
def _regular_at(a, e, z):
    """True if ``|x_η × x_ζ| > 1e-8 |x_η||x_ζ|`` at (η, ζ) (non-degenerate parametrisation)."""
    m0 = xe_nb(a, e, z, 1) * xz_nb(a, e, z, 2) - xe_nb(a, e, z, 2) * xz_nb(a, e, z, 1)
    m1 = xe_nb(a, e, z, 2) * xz_nb(a, e, z, 0) - xe_nb(a, e, z, 0) * xz_nb(a, e, z, 2)
    m2 = xe_nb(a, e, z, 0) * xz_nb(a, e, z, 1) - xe_nb(a, e, z, 1) * xz_nb(a, e, z, 0)
    ne = xe_nb(a, e, z, 0) ** 2 + xe_nb(a, e, z, 1) ** 2 + xe_nb(a, e, z, 2) ** 2
    nz = xz_nb(a, e, z, 0) ** 2 + xz_nb(a, e, z, 1) ** 2 + xz_nb(a, e, z, 2) ** 2
    return m0 * m0 + m1 * m1 + m2 * m2 > 1e-16 * ne * nz


@numba.njit(cache=True)
def nagata_kernel(P, left, right, nstart, nend, blo, bhi, binfl, perm, tv, cen, rad, depth, V,
                  T, fn, epn, vpn, A, infl, nbr, nbr_edge, npn, tie_scale, max_iter,
                  max_halvings, want_h, gap, normal, point, hess, feature, flag, sdist_flat):
    """Nagata projection of the points ``P`` (N, 3) on the patches ``A`` of the facets ``T``
    (candidates from the facet hierarchy, Newton on each patch, the flat facet as fall-back,
    flagged): writes ``gap``, ``normal``, ``point``, the gap Hessian ``hess`` (with
    ``want_h``), ``feature``, ``flag`` and the flat signed distance ``sdist_flat`` (numba;
    the reference twin is :func:`nagata_project_ref`; called by
    :class:`~fxcontact.tools.faceted.FacetedTool`)."""
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
        nc = facet_search(p, left, right, nstart, nend, blo, bhi, binfl, perm, tv, cen, rad, infl,
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
            x0, x1, x2 = pt_nb(a, e, z)
            dj = math.sqrt((x0 - p[0]) ** 2 + (x1 - p[1]) ** 2 + (x2 - p[2]) ** 2)
            conv = st == 1
            # stationary (unconstrained gradient zero): interior-type projection
            r0, r1, r2 = x0 - p[0], x1 - p[1], x2 - p[2]
            g0 = xe_nb(a, e, z, 0) * r0 + xe_nb(a, e, z, 1) * r1 + xe_nb(a, e, z, 2) * r2
            g1 = xz_nb(a, e, z, 0) * r0 + xz_nb(a, e, z, 1) * r1 + xz_nb(a, e, z, 2) * r2
            xx = 0.0
            for k in range(3):
                xx += xe_nb(a, e, z, k) ** 2 + xz_nb(a, e, z, k) ** 2
            scale = math.sqrt(x0 * x0 + x1 * x1 + x2 * x2) + math.sqrt(
                p[0] ** 2 + p[1] ** 2 + p[2] ** 2)
            gt = max(GRADIENT_TOL * 2.0 * math.sqrt(xx) * (dj + scale), ACCEPT_TOL * xx)
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
        x0, x1, x2 = pt_nb(a, be, bz)
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
        a0 = bz <= ACTIVE_TOL
        a1 = be >= 1.0 - ACTIVE_TOL
        a2 = (be - bz) <= ACTIVE_TOL
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
                    xs0, xs1, xs2 = (xe_nb(a, be, bz, 0), xe_nb(a, be, bz, 1), xe_nb(a, be, bz, 2))
                    c0, c1, c2 = 2.0 * a[4, 0], 2.0 * a[4, 1], 2.0 * a[4, 2]
                elif kk == 1:
                    xs0, xs1, xs2 = (xz_nb(a, be, bz, 0), xz_nb(a, be, bz, 1), xz_nb(a, be, bz, 2))
                    c0, c1, c2 = 2.0 * a[5, 0], 2.0 * a[5, 1], 2.0 * a[5, 2]
                else:
                    xs0 = xe_nb(a, be, bz, 0) + xz_nb(a, be, bz, 0)
                    xs1 = xe_nb(a, be, bz, 1) + xz_nb(a, be, bz, 1)
                    xs2 = xe_nb(a, be, bz, 2) + xz_nb(a, be, bz, 2)
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


def flat_project_ref(tool, P: np.ndarray, ptr: np.ndarray, idx: np.ndarray):
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


def nagata_project_ref(tool, P: np.ndarray, ptr: np.ndarray, idx: np.ndarray,
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
            Pf = RefPatch(A[f])
            x = Pf.x(e, z)
            dj = np.linalg.norm(x - p)
            X = np.stack([Pf.xe(e, z), Pf.xz(e, z)], axis=1)
            xx = np.sum(X * X)
            scale = np.linalg.norm(x) + np.linalg.norm(p)
            gt = max(GRADIENT_TOL * 2.0 * np.sqrt(xx) * (dj + scale), ACCEPT_TOL * xx)
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
        Pf = RefPatch(A[f])
        point[i] = Pf.x(e, z)
        if key & 1:
            gap[i], normal[i], h = patch_gap_ref(A[f], p, e, z, want_hessian)
            if want_hessian:
                hess[i] = h
            continue
        act = [z <= ACTIVE_TOL, e >= 1.0 - ACTIVE_TOL, (e - z) <= ACTIVE_TOL]
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
