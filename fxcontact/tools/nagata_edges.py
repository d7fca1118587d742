"""Nagata patches from a triangle mesh and its nodal normals: the edge curvature coefficients
(THEORY §7.1, crease edges §8.3) and the patches' monomial coefficients (see
:mod:`fxcontact.tools.nagata` for the patch and its projection)."""

from __future__ import annotations

import logging
import math
from typing import Tuple

import numpy as np

from fxcontact.tools.normals import CREASE, LOCAL_EDGES, FacetVertexNormals

__all__ = ["PARALLEL_TOL", "edge_coefficients", "crease_edge_coefficients",
           "patch_edge_coefficients", "patch_monomials"]

#: the Nagata module's logger (the messages about the edges keep that name)
logger = logging.getLogger("fxcontact.tools.nagata")

#: Angle below which two normals are treated as parallel (or opposite): c = 0 (§7.1).
PARALLEL_TOL = math.radians(0.1)


# ------------------------------------------------------------------------------------------
# Edge coefficients (§7.1, §8.3)
# ------------------------------------------------------------------------------------------


def edge_coefficients(x0, x1, n0, n1, kappa: float = 1.0, parallel_tol: float = PARALLEL_TOL,
                      inflection: bool = True) -> Tuple[np.ndarray, np.ndarray]:
    """Nagata curvature coefficients of edges ``x0 → x1`` with unit end normals (normal rule).

    ``c = (d·Δv)/(1 − Δc) v + (d·v)/Δc Δv`` with ``d = x1 − x0``, ``v = (n0 + n1)/2``,
    ``Δv = (n0 − n1)/2``, ``Δc = n0·Δv`` (boxed formula of §7.1). Degenerate rules: if
    ``|n0·n1| > cos(parallel_tol)`` (parallel or opposite normals) or ``|c| > κ|d|`` (more than a
    90° turn over the edge for κ = 1: inconsistent normals), ``c = 0``.

    Two further safeguards **[design choice]**, both inactive for exact normals of spheres and
    cylinders: (i) the component of ``c`` along ``ŵ = d̂ × n̂`` (``n̂`` the mean normal made
    orthogonal to the chord) is removed, so the edge bends only in its normal plane — with
    near-parallel normals twisting about the chord, the formula amplifies normal-estimation
    noise ``d·v`` by ``~2/φ`` into a sideways bulge of the edge (up to ``|c| ≈ 0.7|d|`` seen on
    unstructured gmsh meshes); the tangency conditions then hold up to ``|d·v|``; (ii) if the
    chord tilts the same way against both normals, ``(n0·d)(n1·d) > 0`` (an S-shaped edge or
    inflection, not representable by a quadratic), ``c = 0`` (``inflection=True``).

    Args:
        x0, x1: (E, 3) end points.
        n0, n1: (E, 3) unit normals at the end points.
        kappa: bound κ of |c|/|d|.
        parallel_tol: angle [rad] below which normals count as parallel.

    Returns:
        ``(c, flag)``: (E, 3) coefficients and (E,) int flags (0 = regular, 1 = parallel or
        opposite normals, 2 = |c| > κ|d|, 3 = inflection), all but 0 giving a straight edge.
    """
    x0, x1, n0, n1 = (np.atleast_2d(np.asarray(a, dtype=np.float64)) for a in (x0, x1, n0, n1))
    d = x1 - x0
    v = 0.5 * (n0 + n1)
    dv = 0.5 * (n0 - n1)
    cos01 = np.einsum("ij,ij->i", n0, n1)
    dc = 0.5 * (1.0 - cos01)
    par = np.abs(cos01) > math.cos(parallel_tol)
    with np.errstate(divide="ignore", invalid="ignore"):
        c = (np.einsum("ij,ij->i", d, dv) / (1.0 - dc))[:, None] * v + (
            np.einsum("ij,ij->i", d, v) / dc)[:, None] * dv
    c[par] = 0.0
    dn = np.linalg.norm(d, axis=1)
    # keep c in the normal plane of the edge, span(d, n̄): drop the sideways component along
    # ŵ = d̂ × n̂ (zero for exact normals with d·v = 0, e.g. spheres and cylinders; otherwise an
    # amplification 2(d·v)/φ of normal noise when the normals twist about the chord)
    dh = d / np.where(dn > 0.0, dn, 1.0)[:, None]
    nb = v - np.einsum("ij,ij->i", v, dh)[:, None] * dh
    nbn = np.linalg.norm(nb, axis=1)
    w = np.cross(dh, nb / np.where(nbn > 0.0, nbn, 1.0)[:, None])
    c -= np.where((nbn > 0.0)[:, None], np.einsum("ij,ij->i", c, w)[:, None] * w, 0.0)
    big = ~par & (np.linalg.norm(c, axis=1) > kappa * dn)
    c[big] = 0.0
    flag = np.zeros(d.shape[0], dtype=np.int64)
    flag[par] = 1
    flag[big] = 2
    if inflection:
        # the chord tilts the same way against both end normals: both end tangents on the same
        # side of the chord (S-shape / twisted near-parallel normals), not a quadratic arc
        infl = ~par & ~big & (np.einsum("ij,ij->i", n0, d) * np.einsum("ij,ij->i", n1, d) > 0.0)
        c[infl] = 0.0
        flag[infl] = 3
    return c, flag


def crease_edge_coefficients(x0, x1, t0, t1, kappa: float = 1.0) -> Tuple[np.ndarray, np.ndarray]:
    """Edge coefficients of crease edges by the tangent rule (THEORY §8.3).

    Solves ``min_c |(I − t0 t0ᵀ)(d − c)|² + |(I − t1 t1ᵀ)(d + c)|²``, i.e.
    ``(2I − t0 t0ᵀ − t1 t1ᵀ) c = (t1 t1ᵀ − t0 t0ᵀ) d`` (minimum-norm solution, c = 0 for a
    straight crease). The signs of the unit tangents do not matter. ``|c| > κ|d|`` gives c = 0.

    Returns:
        ``(c, flag)`` as :func:`edge_coefficients` (flag 2 = |c| > κ|d|).
    """
    x0, x1, t0, t1 = (np.atleast_2d(np.asarray(a, dtype=np.float64)) for a in (x0, x1, t0, t1))
    d = x1 - x0
    P0 = t0[:, :, None] * t0[:, None, :]
    P1 = t1[:, :, None] * t1[:, None, :]
    Mat = 2.0 * np.eye(3) - P0 - P1
    rhs = np.einsum("eij,ej->ei", P1 - P0, d)
    w, Q = np.linalg.eigh(Mat)
    inv = np.where(w > 1e-10, 1.0 / np.where(w > 1e-10, w, 1.0), 0.0)
    c = np.einsum("eij,ej,ekj,ek->ei", Q, inv, Q, rhs)
    big = np.linalg.norm(c, axis=1) > kappa * np.linalg.norm(d, axis=1)
    c[big] = 0.0
    return c, np.where(big, 2, 0).astype(np.int64)


def patch_edge_coefficients(vertices: np.ndarray, triangles: np.ndarray,
                            fvn: FacetVertexNormals, kappa: float = 1.0) -> np.ndarray:
    """Coefficients ``(c1, c2, c3)`` of every triangle, (M, 3, 3), built once per tool.

    Non-crease edges use the normal rule with the per-(facet, vertex) normals, crease edges the
    tangent rule with the crease tangents ``e3`` (class-2 ends) or the edge direction (corner
    ends). Each edge is evaluated in a canonical direction (lower vertex index first) so that
    the two facets sharing it obtain bit-identical coefficients: the patched surface is
    watertight.
    """
    V = np.asarray(vertices, dtype=np.float64)
    T = np.asarray(triangles, dtype=np.int64)
    M = T.shape[0]
    C = np.zeros((M, 3, 3))
    nflag = np.zeros(4, dtype=np.int64)
    for k in range(3):
        la, lb = LOCAL_EDGES[k]
        ia, ib = T[:, la], T[:, lb]
        na, nb = fvn.normals[:, la], fvn.normals[:, lb]
        swap = ia > ib
        i0 = np.where(swap, ib, ia)
        i1 = np.where(swap, ia, ib)
        n0 = np.where(swap[:, None], nb, na)
        n1 = np.where(swap[:, None], na, nb)
        c, flag = edge_coefficients(V[i0], V[i1], n0, n1, kappa)
        cr = fvn.crease[:, k]
        if np.any(cr):
            x0, x1 = V[i0[cr]], V[i1[cr]]
            dhat = x1 - x0
            dhat /= np.linalg.norm(dhat, axis=1, keepdims=True)
            t0 = np.where((fvn.vertex_class[i0[cr]] == CREASE)[:, None],
                          fvn.crease_tangent[i0[cr]], dhat)
            t1 = np.where((fvn.vertex_class[i1[cr]] == CREASE)[:, None],
                          fvn.crease_tangent[i1[cr]], dhat)
            c[cr], flag[cr] = crease_edge_coefficients(x0, x1, t0, t1, kappa)
        C[:, k] = c
        nflag += np.bincount(flag, minlength=4)[:4]
    if nflag[2] or nflag[3]:
        logger.info("Nagata: straight edges (c = 0) for %d (facet, edge) pairs with |c| > "
                    "kappa|d| and %d with inflected (S-shaped) normal data", nflag[2], nflag[3])
    return C


def patch_monomials(vertices: np.ndarray, triangles: np.ndarray, C: np.ndarray) -> np.ndarray:
    """Monomial coefficients (M, 6, 3) ``[a00, a10, a01, a11, a20, a02]`` of the patches (§7.2)."""
    V = np.asarray(vertices, dtype=np.float64)
    T = np.asarray(triangles, dtype=np.int64)
    x00, x10, x11 = V[T[:, 0]], V[T[:, 1]], V[T[:, 2]]
    c1, c2, c3 = C[:, 0], C[:, 1], C[:, 2]
    return np.ascontiguousarray(np.stack(
        [x00, x10 - x00 - c1, x11 - x10 + c1 - c3, c3 - c1 - c2, c1, c2], axis=1))
