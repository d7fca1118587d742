"""Nagata patches: edge coefficients (:mod:`fxcontact.tools.nagata_edges`), patch evaluation
and point projection (THEORY §7).

A Nagata patch interpolates the three vertices ``x00, x10, x11`` of a triangle (counter-clockwise
about the outward normal) and their nodal normals with the quadratic surface

    x(η, ζ) = a00 + a10 η + a01 ζ + a11 η ζ + a20 η² + a02 ζ²,   0 ≤ ζ ≤ η ≤ 1,

built from the edge curvature coefficients ``c1 = c(x00, x10)``, ``c2 = c(x10, x11)``,
``c3 = c(x00, x11)`` (§7.1–7.2). A patch is stored as its (6, 3) monomial coefficients
``A = [a00, a10, a01, a11, a20, a02]`` (see :func:`patch_monomials`).

Kernels: the per-point work (:func:`project_patch_nb`, :func:`patch_gap_nb`) is compiled with
``numba.njit(cache=True)``. Each kernel has a plain numpy/Python twin (suffix ``_ref``) — a
*reference implementation, for testing only* — that the tests compare against.

Barycentric link: λ0 = 1 − η, λ1 = η − ζ, λ2 = ζ; edge 0 is ζ = 0 (x00 → x10, coefficient c1),
edge 1 is η = 1 (x10 → x11, c2), edge 2 is ζ = η (x00 → x11, c3).
"""

from __future__ import annotations

import math
from typing import Optional, Tuple

import numba
import numpy as np

from fxcontact.tools.nagata_edges import (PARALLEL_TOL, crease_edge_coefficients, edge_coefficients,
                                          patch_edge_coefficients, patch_monomials)

__all__ = [
    "PARALLEL_TOL",
    "edge_coefficients",
    "crease_edge_coefficients",
    "patch_edge_coefficients",
    "patch_monomials",
    "patch_points",
    "patch_derivatives",
    "patch_normals",
    "domain_samples",
    "proj_domain",
    "proj_grad_norm",
    "project_patch",
    "project_patch_nb",
    "project_patch_ref",
    "patch_gap",
    "patch_gap_nb",
    "patch_gap_ref",
    "STATUS_CONVERGED",
    "STATUS_FAILED",
    "GRADIENT_TOL",
    "ACCEPT_TOL",
    "ACTIVE_TOL",
    "pt_nb",
    "xe_nb",
    "xz_nb",
    "RefPatch",
]

STATUS_FAILED = 0
STATUS_CONVERGED = 1

_EPS = float(np.finfo(np.float64).eps)
GRADIENT_TOL = 64.0 * _EPS  # rounding-level gradient tolerance factor
_STEP_TOL = 1e-13  # |Δξ| convergence
ACCEPT_TOL = 1e-10  # final acceptance: projected gradient ≤ 1e-10 |X_ξ|²
ACTIVE_TOL = 1e-13  # active-constraint tolerance in parameter space
_S2 = 1.0 / math.sqrt(2.0)


# ------------------------------------------------------------------------------------------
# Vectorised evaluation (numpy)
# ------------------------------------------------------------------------------------------


def _bcast(A, eta, zeta):
    A = np.asarray(A, dtype=np.float64)
    e = np.asarray(eta, dtype=np.float64)[..., None]
    z = np.asarray(zeta, dtype=np.float64)[..., None]
    return A, e, z


def patch_points(A: np.ndarray, eta, zeta) -> np.ndarray:
    """Points x(η, ζ) of patch(es) ``A`` ((6, 3) or (K, 6, 3), broadcast against η, ζ)."""
    A, e, z = _bcast(A, eta, zeta)
    return (A[..., 0, :] + A[..., 1, :] * e + A[..., 2, :] * z + A[..., 3, :] * e * z
            + A[..., 4, :] * e * e + A[..., 5, :] * z * z)


def patch_derivatives(A: np.ndarray, eta, zeta) -> Tuple[np.ndarray, np.ndarray]:
    """Tangents ``x_η, x_ζ`` (§7.3)."""
    A, e, z = _bcast(A, eta, zeta)
    xe = A[..., 1, :] + A[..., 3, :] * z + 2.0 * A[..., 4, :] * e
    xz = A[..., 2, :] + A[..., 3, :] * e + 2.0 * A[..., 5, :] * z
    return xe, xz


def patch_normals(A: np.ndarray, eta, zeta) -> np.ndarray:
    """Unit normals ``x_η × x_ζ / |x_η × x_ζ|`` (outward for counter-clockwise vertices); zero
    where the parametrisation is degenerate (``|x_η × x_ζ| ≤ 1e-12 |x_η||x_ζ|``)."""
    xe, xz = patch_derivatives(A, eta, zeta)
    m = np.cross(xe, xz)
    mn = np.linalg.norm(m, axis=-1, keepdims=True)
    ok = mn > 1e-12 * np.linalg.norm(xe, axis=-1, keepdims=True) * np.linalg.norm(
        xz, axis=-1, keepdims=True)
    return np.where(ok, m / np.where(ok, mn, 1.0), 0.0)


def domain_samples(n: int = 20) -> Tuple[np.ndarray, np.ndarray]:
    """Regular samples of the parameter triangle 0 ≤ ζ ≤ η ≤ 1 ((n+1)(n+2)/2 points;
    n = 20 gives the 231 samples per patch of THEORY §7.7)."""
    i, j = np.meshgrid(np.arange(n + 1), np.arange(n + 1), indexing="ij")
    keep = j <= i
    return (i[keep] / n).astype(np.float64), (j[keep] / n).astype(np.float64)


# ------------------------------------------------------------------------------------------
# numba kernels
# ------------------------------------------------------------------------------------------


@numba.njit(cache=True)
def pt_nb(a, e, z):
    """The point x(η, ζ) = (x0, x1, x2) of the patch ``a`` (6, 3) (numba)."""
    x0 = a[0, 0] + a[1, 0] * e + a[2, 0] * z + a[3, 0] * e * z + a[4, 0] * e * e + a[5, 0] * z * z
    x1 = a[0, 1] + a[1, 1] * e + a[2, 1] * z + a[3, 1] * e * z + a[4, 1] * e * e + a[5, 1] * z * z
    x2 = a[0, 2] + a[1, 2] * e + a[2, 2] * z + a[3, 2] * e * z + a[4, 2] * e * e + a[5, 2] * z * z
    return x0, x1, x2


@numba.njit(cache=True)
def xe_nb(a, e, z, k):
    """Component ``k`` of ∂x/∂η at (η, ζ) of the patch ``a`` (numba)."""
    return a[1, k] + a[3, k] * z + 2.0 * a[4, k] * e


@numba.njit(cache=True)
def xz_nb(a, e, z, k):
    """Component ``k`` of ∂x/∂ζ at (η, ζ) of the patch ``a`` (numba)."""
    return a[2, k] + a[3, k] * e + 2.0 * a[5, k] * z


@numba.njit(cache=True)
def proj_domain(e, z):
    """Euclidean projection of (η, ζ) on the parameter triangle 0 ≤ ζ ≤ η ≤ 1 (exact values
    on the boundary)."""
    if z >= 0.0 and z <= e and e <= 1.0:
        return e, z
    # edge 0: ζ = 0
    e0 = min(max(e, 0.0), 1.0)
    d0 = (e - e0) ** 2 + z * z
    # edge 1: η = 1
    z1 = min(max(z, 0.0), 1.0)
    d1 = (e - 1.0) ** 2 + (z - z1) ** 2
    # edge 2: ζ = η
    s = min(max(0.5 * (e + z), 0.0), 1.0)
    d2 = (e - s) ** 2 + (z - s) ** 2
    if d0 <= d1 and d0 <= d2:
        return e0, 0.0
    if d1 <= d2:
        return 1.0, z1
    return s, s


@numba.njit(cache=True)
def proj_grad_norm(e, z, g0, g1):
    """Norm of the projection of −g on the tangent cone of the domain at (η, ζ) (KKT test)."""
    v0, v1 = -g0, -g1
    a0 = z <= ACTIVE_TOL
    a1 = e >= 1.0 - ACTIVE_TOL
    a2 = (e - z) <= ACTIVE_TOL
    nact = int(a0) + int(a1) + int(a2)
    if nact == 0:
        return math.sqrt(v0 * v0 + v1 * v1)
    if nact == 1:
        if a0:
            n0, n1 = 0.0, -1.0
        elif a1:
            n0, n1 = 1.0, 0.0
        else:
            n0, n1 = -_S2, _S2
        s = v0 * n0 + v1 * n1
        if s > 0.0:
            v0 -= s * n0
            v1 -= s * n1
        return math.sqrt(v0 * v0 + v1 * v1)
    # domain vertex: two active constraints (outward normals na, nb; boundary rays ta, tb)
    if a0 and a2:  # (0, 0)
        na0, na1, nb0, nb1 = 0.0, -1.0, -_S2, _S2
        ta0, ta1, tb0, tb1 = 1.0, 0.0, _S2, _S2
    elif a0 and a1:  # (1, 0)
        na0, na1, nb0, nb1 = 0.0, -1.0, 1.0, 0.0
        ta0, ta1, tb0, tb1 = -1.0, 0.0, 0.0, 1.0
    else:  # (1, 1)
        na0, na1, nb0, nb1 = 1.0, 0.0, -_S2, _S2
        ta0, ta1, tb0, tb1 = 0.0, -1.0, -_S2, -_S2
    if v0 * na0 + v1 * na1 <= 0.0 and v0 * nb0 + v1 * nb1 <= 0.0:
        return math.sqrt(v0 * v0 + v1 * v1)
    return max(0.0, v0 * ta0 + v1 * ta1, v0 * tb0 + v1 * tb1)


@numba.njit(cache=True)
def _edge_param(k, e, z):
    if k == 1:
        return z
    return e


@numba.njit(cache=True)
def _edge_point(k, s):
    if k == 0:
        return s, 0.0
    if k == 1:
        return 1.0, s
    return s, s


@numba.njit(cache=True)
def _edge_tangent(a, k, s, out):
    e, z = _edge_point(k, s)
    for i in range(3):
        if k == 0:
            out[i] = xe_nb(a, e, z, i)
        elif k == 1:
            out[i] = xz_nb(a, e, z, i)
        else:
            out[i] = xe_nb(a, e, z, i) + xz_nb(a, e, z, i)


@numba.njit(cache=True)
def _edge_step(a, p, k, s, f, max_halvings, scale):
    """One safeguarded 1D Newton step along domain edge ``k`` from parameter ``s``.

    Returns ``(s_new, f_new, accepted)``."""
    xs = np.empty(3)
    if k == 0:
        c0, c1, c2 = 2.0 * a[4, 0], 2.0 * a[4, 1], 2.0 * a[4, 2]
    elif k == 1:
        c0, c1, c2 = 2.0 * a[5, 0], 2.0 * a[5, 1], 2.0 * a[5, 2]
    else:
        c0 = 2.0 * (a[4, 0] + a[3, 0] + a[5, 0])
        c1 = 2.0 * (a[4, 1] + a[3, 1] + a[5, 1])
        c2 = 2.0 * (a[4, 2] + a[3, 2] + a[5, 2])
    e, z = _edge_point(k, s)
    x0, x1, x2 = pt_nb(a, e, z)
    r0, r1, r2 = x0 - p[0], x1 - p[1], x2 - p[2]
    _edge_tangent(a, k, s, xs)
    g = xs[0] * r0 + xs[1] * r1 + xs[2] * r2
    xx = xs[0] * xs[0] + xs[1] * xs[1] + xs[2] * xs[2]
    h = xx + c0 * r0 + c1 * r1 + c2 * r2
    if h > 0.0:
        ds = -g / h
    else:  # locally concave along the edge: try the edge end first, then halve
        ds = -s if g > 0.0 else 1.0 - s
    rn = math.sqrt(r0 * r0 + r1 * r1 + r2 * r2)
    ftol = 8.0 * _EPS * (f + rn * scale)
    alpha = 1.0
    for m in range(max_halvings + 1):
        sn = min(max(s + alpha * ds, 0.0), 1.0)
        en, zn = _edge_point(k, sn)
        y0, y1, y2 = pt_nb(a, en, zn)
        fn = 0.5 * ((y0 - p[0]) ** 2 + (y1 - p[1]) ** 2 + (y2 - p[2]) ** 2)
        if fn < f or (m == 0 and fn <= f + ftol):
            return sn, fn, True
        alpha *= 0.5
    return s, f, False


@numba.njit(cache=True)
def _binding_edge(e, z, g0, g1):
    """Active-set choice at (η, ζ): -1 if no active constraint is binding (free 2D step), else
    the domain edge to slide along (0: ζ = 0, 1: η = 1, 2: ζ = η). A constraint is binding when
    the steepest-descent direction −g points out of the domain through it; at a domain vertex
    with both constraints binding, the edge whose ray carries the largest descent is chosen."""
    v0, v1 = -g0, -g1
    b0 = z <= ACTIVE_TOL and -v1 > 0.0
    b1 = e >= 1.0 - ACTIVE_TOL and v0 > 0.0
    b2 = (e - z) <= ACTIVE_TOL and (-v0 + v1) > 0.0
    nb = int(b0) + int(b1) + int(b2)
    if nb == 0:
        return -1
    if nb == 1:
        return 0 if b0 else (1 if b1 else 2)
    if b0 and b2:  # vertex (0, 0): rays (1, 0) on edge 0, (1, 1)/√2 on edge 2
        return 0 if v0 >= _S2 * (v0 + v1) else 2
    if b0 and b1:  # vertex (1, 0): rays (−1, 0) on edge 0, (0, 1) on edge 1
        return 0 if -v0 >= v1 else 1
    # vertex (1, 1): rays (0, −1) on edge 1, (−1, −1)/√2 on edge 2
    return 1 if -v1 >= -_S2 * (v0 + v1) else 2


@numba.njit(cache=True)
def _grad_at(a, p, e, z):
    """(g0, g1, |x_η|² + |x_ζ|², gtol) at (η, ζ)."""
    x0, x1, x2 = pt_nb(a, e, z)
    r0, r1, r2 = x0 - p[0], x1 - p[1], x2 - p[2]
    g0 = xe_nb(a, e, z, 0) * r0 + xe_nb(a, e, z, 1) * r1 + xe_nb(a, e, z, 2) * r2
    g1 = xz_nb(a, e, z, 0) * r0 + xz_nb(a, e, z, 1) * r1 + xz_nb(a, e, z, 2) * r2
    xee = xe_nb(a, e, z, 0) ** 2 + xe_nb(a, e, z, 1) ** 2 + xe_nb(a, e, z, 2) ** 2
    xzz = xz_nb(a, e, z, 0) ** 2 + xz_nb(a, e, z, 1) ** 2 + xz_nb(a, e, z, 2) ** 2
    rn = math.sqrt(r0 * r0 + r1 * r1 + r2 * r2)
    scale = math.sqrt(x0 * x0 + x1 * x1 + x2 * x2) + math.sqrt(p[0] ** 2 + p[1] ** 2 + p[2] ** 2)
    gtol = GRADIENT_TOL * (math.sqrt(xee) + math.sqrt(xzz)) * (rn + scale)
    return g0, g1, xee + xzz, gtol


@numba.njit(cache=True)
def project_patch_nb(a, p, eta0, zeta0, max_iter=30, max_halvings=12, safeguard=True):
    """Closest point of ``p`` on the Nagata patch ``a`` (6, 3) (THEORY §7.4), numba kernel.

    Minimises f(ξ) = ½|x(ξ) − p|² over 0 ≤ ζ ≤ η ≤ 1 from (η0, ζ0) (projected on the domain).
    With ``safeguard`` (the default), each iteration is an active-set Newton step:

    * no binding constraint — 2D Newton step, with the Gauss–Newton matrix ``X_ξᵀX_ξ`` where the
      Hessian is not SPD, step halving (sub-incrementation, at most ``max_halvings``) until f
      decreases, and projection of the trial points on the domain;
    * on a domain edge (or vertex) where −∇f points outward — 1D Newton step along that edge,
      with the same halving (the final edge Newton of §7.4, which avoids the stalling of
      clamped 2D steps).

    Without ``safeguard``: plain Newton (full steps with the exact Hessian, only projected on the
    domain) — kept for comparison. Converged when the projected gradient vanishes (rounding
    level) or |Δξ| < 1e-13, within ``max_iter`` iterations, and the final projected gradient is
    ≤ 1e-10 |X_ξ|².

    Returns:
        ``(eta, zeta, status, iterations)``, status 1 = converged, 0 = failed.
    """
    e, z = proj_domain(eta0, zeta0)
    x0, x1, x2 = pt_nb(a, e, z)
    f = 0.5 * ((x0 - p[0]) ** 2 + (x1 - p[1]) ** 2 + (x2 - p[2]) ** 2)
    pn = math.sqrt(p[0] ** 2 + p[1] ** 2 + p[2] ** 2)
    it = 0
    while it < max_iter:
        it += 1
        x0, x1, x2 = pt_nb(a, e, z)
        r0, r1, r2 = x0 - p[0], x1 - p[1], x2 - p[2]
        xe0, xe1, xe2 = xe_nb(a, e, z, 0), xe_nb(a, e, z, 1), xe_nb(a, e, z, 2)
        xz0, xz1, xz2 = xz_nb(a, e, z, 0), xz_nb(a, e, z, 1), xz_nb(a, e, z, 2)
        g0 = xe0 * r0 + xe1 * r1 + xe2 * r2
        g1 = xz0 * r0 + xz1 * r1 + xz2 * r2
        rn = math.sqrt(r0 * r0 + r1 * r1 + r2 * r2)
        scale = math.sqrt(x0 * x0 + x1 * x1 + x2 * x2) + pn
        gnx = math.sqrt(xe0 * xe0 + xe1 * xe1 + xe2 * xe2) + math.sqrt(
            xz0 * xz0 + xz1 * xz1 + xz2 * xz2)
        if proj_grad_norm(e, z, g0, g1) <= GRADIENT_TOL * gnx * (rn + scale):
            break
        G00 = xe0 * xe0 + xe1 * xe1 + xe2 * xe2
        G01 = xe0 * xz0 + xe1 * xz1 + xe2 * xz2
        G11 = xz0 * xz0 + xz1 * xz1 + xz2 * xz2
        H00 = G00 + 2.0 * (a[4, 0] * r0 + a[4, 1] * r1 + a[4, 2] * r2)
        H01 = G01 + a[3, 0] * r0 + a[3, 1] * r1 + a[3, 2] * r2
        H11 = G11 + 2.0 * (a[5, 0] * r0 + a[5, 1] * r1 + a[5, 2] * r2)
        if not safeguard:
            det = H00 * H11 - H01 * H01
            if det == 0.0:
                break
            en, zn = proj_domain(e - (H11 * g0 - H01 * g1) / det, z - (H00 * g1 - H01 * g0) / det)
            step = math.sqrt((en - e) ** 2 + (zn - z) ** 2)
            e, z = en, zn
            if step < _STEP_TOL:
                break
            continue
        k = _binding_edge(e, z, g0, g1)
        if k >= 0:
            s0 = _edge_param(k, e, z)
            s, fn, ok = _edge_step(a, p, k, s0, f, max_halvings, scale)
            if not ok:
                break
            en, zn = _edge_point(k, s)
        else:
            det = H00 * H11 - H01 * H01
            if not (H00 > 0.0 and det > 1e-14 * H00 * H11):
                H00, H01, H11 = G00, G01, G11
                det = H00 * H11 - H01 * H01
            if det <= 0.0:
                break
            de = -(H11 * g0 - H01 * g1) / det
            dz = -(H00 * g1 - H01 * g0) / det
            ftol = 8.0 * _EPS * (f + rn * scale)
            alpha = 1.0
            ok = False
            en, zn, fn = e, z, f
            for m in range(max_halvings + 1):
                en, zn = proj_domain(e + alpha * de, z + alpha * dz)
                y0, y1, y2 = pt_nb(a, en, zn)
                fn = 0.5 * ((y0 - p[0]) ** 2 + (y1 - p[1]) ** 2 + (y2 - p[2]) ** 2)
                if fn < f or (m == 0 and fn <= f + ftol):
                    ok = True
                    break
                alpha *= 0.5
            if not ok:
                break
        step = math.sqrt((en - e) ** 2 + (zn - z) ** 2)
        e, z, f = en, zn, fn
        if step < _STEP_TOL:
            break
    g0, g1, xx, gtol = _grad_at(a, p, e, z)
    pg = proj_grad_norm(e, z, g0, g1)
    status = STATUS_CONVERGED if (it > 0 and pg <= max(gtol, ACCEPT_TOL * xx)) else STATUS_FAILED
    return e, z, status, it


@numba.njit(cache=True)
def patch_gap_nb(a, p, e, z, want_hessian, normal, hessian):
    """Signed distance ``(p − x*)·n*`` to patch ``a`` at an *interior* foot point (η, ζ), with
    ``normal = n* = ∇d`` and, if ``want_hessian``, ``hessian = ∇²d = N_ξ H⁻¹ X_ξᵀ`` (§7.5)
    written into the output arrays (3,) and (3, 3). Returns ``d``."""
    x0, x1, x2 = pt_nb(a, e, z)
    r0, r1, r2 = x0 - p[0], x1 - p[1], x2 - p[2]
    xe = np.empty(3)
    xz = np.empty(3)
    for i in range(3):
        xe[i] = xe_nb(a, e, z, i)
        xz[i] = xz_nb(a, e, z, i)
    m0 = xe[1] * xz[2] - xe[2] * xz[1]
    m1 = xe[2] * xz[0] - xe[0] * xz[2]
    m2 = xe[0] * xz[1] - xe[1] * xz[0]
    mn = math.sqrt(m0 * m0 + m1 * m1 + m2 * m2)
    normal[0], normal[1], normal[2] = m0 / mn, m1 / mn, m2 / mn
    d = -(r0 * normal[0] + r1 * normal[1] + r2 * normal[2])
    if not want_hessian:
        return d
    # second derivatives
    xee = np.empty(3)
    xez = np.empty(3)
    xzz = np.empty(3)
    for i in range(3):
        xee[i] = 2.0 * a[4, i]
        xez[i] = a[3, i]
        xzz[i] = 2.0 * a[5, i]
    # m_,η = x_ηη × x_ζ + x_η × x_ηζ ;  m_,ζ = x_ηζ × x_ζ + x_η × x_ζζ
    me = np.empty(3)
    mz = np.empty(3)
    for i in range(3):
        j, k = (i + 1) % 3, (i + 2) % 3
        me[i] = (xee[j] * xz[k] - xee[k] * xz[j]) + (xe[j] * xez[k] - xe[k] * xez[j])
        mz[i] = (xez[j] * xz[k] - xez[k] * xz[j]) + (xe[j] * xzz[k] - xe[k] * xzz[j])
    ne = np.empty(3)
    nz = np.empty(3)
    dme = normal[0] * me[0] + normal[1] * me[1] + normal[2] * me[2]
    dmz = normal[0] * mz[0] + normal[1] * mz[1] + normal[2] * mz[2]
    for i in range(3):
        ne[i] = (me[i] - dme * normal[i]) / mn
        nz[i] = (mz[i] - dmz * normal[i]) / mn
    H00 = xe[0] * xe[0] + xe[1] * xe[1] + xe[2] * xe[2] + xee[0] * r0 + xee[1] * r1 + xee[2] * r2
    H01 = xe[0] * xz[0] + xe[1] * xz[1] + xe[2] * xz[2] + xez[0] * r0 + xez[1] * r1 + xez[2] * r2
    H11 = xz[0] * xz[0] + xz[1] * xz[1] + xz[2] * xz[2] + xzz[0] * r0 + xzz[1] * r1 + xzz[2] * r2
    det = H00 * H11 - H01 * H01
    i00, i01, i11 = H11 / det, -H01 / det, H00 / det
    # B = H⁻¹ X_ξᵀ (2 x 3), hessian = N_ξ B, symmetrised
    for i in range(3):
        b0i = i00 * xe[i] + i01 * xz[i]
        b1i = i01 * xe[i] + i11 * xz[i]
        for j in range(3):
            hessian[j, i] = ne[j] * b0i + nz[j] * b1i
    for i in range(3):
        for j in range(i + 1, 3):
            s = 0.5 * (hessian[i, j] + hessian[j, i])
            hessian[i, j] = s
            hessian[j, i] = s
    return d


# ------------------------------------------------------------------------------------------
# Reference twins (plain numpy / Python) — reference implementation, for testing only
# ------------------------------------------------------------------------------------------


def _proj_domain_ref(e: float, z: float) -> Tuple[float, float]:
    """Reference implementation, for testing only (see :func:`proj_domain`)."""
    if 0.0 <= z <= e <= 1.0:
        return e, z
    cands = [(min(max(e, 0.0), 1.0), 0.0), (1.0, min(max(z, 0.0), 1.0))]
    s = min(max(0.5 * (e + z), 0.0), 1.0)
    cands.append((s, s))
    d = [(e - ce) ** 2 + (z - cz) ** 2 for ce, cz in cands]
    return cands[int(np.argmin(d))]


def _proj_grad_norm_ref(e: float, z: float, g: np.ndarray) -> float:
    """Reference implementation, for testing only (see :func:`proj_grad_norm`)."""
    v = -np.asarray(g, dtype=np.float64)
    act = [z <= ACTIVE_TOL, e >= 1.0 - ACTIVE_TOL, (e - z) <= ACTIVE_TOL]
    nus = [np.array([0.0, -1.0]), np.array([1.0, 0.0]), np.array([-_S2, _S2])]
    idx = [i for i in range(3) if act[i]]
    if not idx:
        return float(np.linalg.norm(v))
    if len(idx) == 1:
        nu = nus[idx[0]]
        s = v @ nu
        return float(np.linalg.norm(v - s * nu if s > 0 else v))
    rays = {(0, 2): ([1.0, 0.0], [_S2, _S2]), (0, 1): ([-1.0, 0.0], [0.0, 1.0]),
            (1, 2): ([0.0, -1.0], [-_S2, -_S2])}[tuple(idx[:2])]
    if all(v @ nus[i] <= 0.0 for i in idx[:2]):
        return float(np.linalg.norm(v))
    return max(0.0, *(float(v @ np.array(t)) for t in rays))


class RefPatch:
    """Patch evaluation helpers for the reference twins (reference implementation, testing only)."""

    def __init__(self, a):
        self.a = np.asarray(a, dtype=np.float64)

    def x(self, e, z):
        a = self.a
        return a[0] + a[1] * e + a[2] * z + a[3] * e * z + a[4] * e * e + a[5] * z * z

    def xe(self, e, z):
        return self.a[1] + self.a[3] * z + 2.0 * self.a[4] * e

    def xz(self, e, z):
        return self.a[2] + self.a[3] * e + 2.0 * self.a[5] * z

    def edge(self, k, s):
        return [(s, 0.0), (1.0, s), (s, s)][k]

    def edge_tangent(self, k, s):
        e, z = self.edge(k, s)
        return [self.xe(e, z), self.xz(e, z), self.xe(e, z) + self.xz(e, z)][k]

    def edge_second(self, k):
        a = self.a
        return [2.0 * a[4], 2.0 * a[5], 2.0 * (a[4] + a[3] + a[5])][k]

    def grad(self, p, e, z):
        x = self.x(e, z)
        r = x - p
        X = np.stack([self.xe(e, z), self.xz(e, z)], axis=1)
        g = X.T @ r
        scale = np.linalg.norm(x) + np.linalg.norm(p)
        gtol = GRADIENT_TOL * (np.linalg.norm(X[:, 0]) + np.linalg.norm(X[:, 1])) * (
            np.linalg.norm(r) + scale)
        return g, float(np.sum(X * X)), gtol


def _edge_step_ref(P: RefPatch, p, k, s, f, max_halvings, scale):
    """Reference implementation, for testing only (see ``_edge_step``)."""
    r = P.x(*P.edge(k, s)) - p
    xs = P.edge_tangent(k, s)
    g = xs @ r
    xx = xs @ xs
    h = xx + P.edge_second(k) @ r
    ds = -g / h if h > 0 else (-s if g > 0 else 1.0 - s)
    ftol = 8.0 * _EPS * (f + np.linalg.norm(r) * scale)
    alpha = 1.0
    for m in range(max_halvings + 1):
        sn = min(max(s + alpha * ds, 0.0), 1.0)
        fn = 0.5 * np.sum((P.x(*P.edge(k, sn)) - p) ** 2)
        if fn < f or (m == 0 and fn <= f + ftol):
            return sn, fn, True
        alpha *= 0.5
    return s, f, False


def _binding_edge_ref(e, z, g):
    """Reference implementation, for testing only (see ``_binding_edge``)."""
    v = -np.asarray(g, dtype=np.float64)
    nus = [np.array([0.0, -1.0]), np.array([1.0, 0.0]), np.array([-1.0, 1.0])]
    act = [z <= ACTIVE_TOL, e >= 1.0 - ACTIVE_TOL, (e - z) <= ACTIVE_TOL]
    b = [act[i] and v @ nus[i] > 0.0 for i in range(3)]
    if sum(b) == 0:
        return -1
    if sum(b) == 1:
        return b.index(True)
    rays = {(0, 2): ((1.0, 0.0), (_S2, _S2)), (0, 1): ((-1.0, 0.0), (0.0, 1.0)),
            (1, 2): ((0.0, -1.0), (-_S2, -_S2))}
    pair = tuple(i for i in range(3) if b[i])
    ta, tb = rays[pair]
    return pair[0] if v @ np.array(ta) >= v @ np.array(tb) else pair[1]


def project_patch_ref(a, p, eta0, zeta0, max_iter=30, max_halvings=12, safeguard=True):
    """Reference implementation, for testing only: numpy twin of :func:`project_patch_nb`."""
    P = RefPatch(a)
    p = np.asarray(p, dtype=np.float64)
    e, z = _proj_domain_ref(float(eta0), float(zeta0))
    f = 0.5 * np.sum((P.x(e, z) - p) ** 2)
    pn = np.linalg.norm(p)
    it = 0
    while it < max_iter:
        it += 1
        x = P.x(e, z)
        r = x - p
        X = np.stack([P.xe(e, z), P.xz(e, z)], axis=1)  # (3, 2)
        g = X.T @ r
        rn = np.linalg.norm(r)
        scale = np.linalg.norm(x) + pn
        gtol = GRADIENT_TOL * (np.linalg.norm(X[:, 0]) + np.linalg.norm(X[:, 1])) * (rn + scale)
        if _proj_grad_norm_ref(e, z, g) <= gtol:
            break
        G = X.T @ X
        A = P.a
        H = G + np.array([[2 * A[4] @ r, A[3] @ r], [A[3] @ r, 2 * A[5] @ r]])
        if not safeguard:
            if np.linalg.det(H) == 0.0:
                break
            d = -np.linalg.solve(H, g)
            en, zn = _proj_domain_ref(e + d[0], z + d[1])
            step = np.hypot(en - e, zn - z)
            e, z = en, zn
            if step < _STEP_TOL:
                break
            continue
        k = _binding_edge_ref(e, z, g)
        if k >= 0:
            s, fn, ok = _edge_step_ref(P, p, k, z if k == 1 else e, f, max_halvings, scale)
            if not ok:
                break
            en, zn = P.edge(k, s)
        else:
            det = np.linalg.det(H)
            if not (H[0, 0] > 0 and det > 1e-14 * H[0, 0] * H[1, 1]):
                H = G
            if np.linalg.det(H) <= 0.0:
                break
            d = -np.linalg.solve(H, g)
            ftol = 8.0 * _EPS * (f + rn * scale)
            alpha, ok = 1.0, False
            for m in range(max_halvings + 1):
                en, zn = _proj_domain_ref(e + alpha * d[0], z + alpha * d[1])
                fn = 0.5 * np.sum((P.x(en, zn) - p) ** 2)
                if fn < f or (m == 0 and fn <= f + ftol):
                    ok = True
                    break
                alpha *= 0.5
            if not ok:
                break
        step = np.hypot(en - e, zn - z)
        e, z, f = en, zn, fn
        if step < _STEP_TOL:
            break
    g, xx, gtol = P.grad(p, e, z)
    ok = it > 0 and _proj_grad_norm_ref(e, z, g) <= max(gtol, ACCEPT_TOL * xx)
    return e, z, STATUS_CONVERGED if ok else STATUS_FAILED, it


def patch_gap_ref(a, p, eta, zeta, want_hessian=True):
    """Reference implementation, for testing only: numpy twin of :func:`patch_gap_nb`.

    Returns ``(d, normal, hessian)`` (hessian ``None`` if not wanted)."""
    P = RefPatch(a)
    p = np.asarray(p, dtype=np.float64)
    x = P.x(eta, zeta)
    X = np.stack([P.xe(eta, zeta), P.xz(eta, zeta)], axis=1)
    m = np.cross(X[:, 0], X[:, 1])
    n = m / np.linalg.norm(m)
    d = float((p - x) @ n)
    if not want_hessian:
        return d, n, None
    a = P.a
    xee, xez, xzz = 2 * a[4], a[3], 2 * a[5]
    me = np.cross(xee, X[:, 1]) + np.cross(X[:, 0], xez)
    mz = np.cross(xez, X[:, 1]) + np.cross(X[:, 0], xzz)
    Pn = np.eye(3) - np.outer(n, n)
    N = np.stack([Pn @ me, Pn @ mz], axis=1) / np.linalg.norm(m)
    r = x - p
    H = X.T @ X + np.array([[xee @ r, xez @ r], [xez @ r, xzz @ r]])
    hess = N @ np.linalg.solve(H, X.T)
    return d, n, 0.5 * (hess + hess.T)


# ------------------------------------------------------------------------------------------
# Convenience wrappers
# ------------------------------------------------------------------------------------------


def project_patch(a, p, xi0: Optional[Tuple[float, float]] = None, max_iter: int = 30,
                  max_halvings: int = 12, safeguard: bool = True):
    """Project one point on one patch (numba kernel). ``xi0`` defaults to the centroid
    (η, ζ) = (2/3, 1/3). Returns ``(eta, zeta, status, iterations)``."""
    a = np.ascontiguousarray(a, dtype=np.float64)
    p = np.ascontiguousarray(p, dtype=np.float64)
    e0, z0 = (2.0 / 3.0, 1.0 / 3.0) if xi0 is None else xi0
    return project_patch_nb(a, p, float(e0), float(z0), int(max_iter), int(max_halvings),
                            bool(safeguard))


def patch_gap(a, p, eta: float, zeta: float, want_hessian: bool = True):
    """Signed distance, normal and Hessian at an interior foot point (numba kernel)."""
    n = np.empty(3)
    h = np.zeros((3, 3))
    d = patch_gap_nb(np.ascontiguousarray(a, dtype=np.float64),
                     np.ascontiguousarray(p, dtype=np.float64), float(eta), float(zeta),
                     bool(want_hessian), n, h)
    return d, n, (h if want_hessian else None)
