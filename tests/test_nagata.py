"""Nagata patches: edge coefficients, patch geometry, projection, gap derivatives (THEORY §7)."""

import math

import numpy as np
import pytest
from scipy.optimize import minimize

from fxcontact.tools import nagata as ng
from fxcontact.tools.nagata import (
    crease_edge_coefficients,
    domain_samples,
    edge_coefficients,
    patch_derivatives,
    patch_edge_coefficients,
    patch_gap,
    patch_gap_nb,
    patch_gap_ref,
    patch_monomials,
    patch_normals,
    patch_points,
    project_patch,
    project_patch_nb,
    project_patch_ref,
)
from fxcontact.tools.normals import LOCAL_EDGES, edge_topology, facet_vertex_normals



from fxcontact.tools import surfaces as tm  # noqa: E402


def _patches(V, T, normals="nvv", crease_angle=math.radians(50)):
    fvn = facet_vertex_normals(V, T, normals, crease_angle)
    C = patch_edge_coefficients(V, T, fvn)
    return fvn, C, patch_monomials(V, T, C)


@pytest.fixture(scope="module")
def sphere_patches():
    V, T = tm.icosphere(1)
    return (V, T) + _patches(V, T)


@pytest.fixture(scope="module")
def cylinder_patches():
    V, T = tm.structured_cylinder(1.0, 2.0, 8, 2)
    return (V, T) + _patches(V, T)


def _random_patch_points(A, rng, n, offset):
    """Points x(ξ) + t n(ξ), ξ in the interior of random patches, |t| <= offset, both sides."""
    out = []
    for _ in range(n):
        f = rng.integers(A.shape[0])
        e = rng.uniform(0.1, 0.9)
        z = rng.uniform(0.05, e - 0.05)
        t = rng.uniform(-offset, offset)
        out.append((f, e, z, patch_points(A[f], e, z) + t * patch_normals(A[f], e, z), t))
    return out


# ------------------------------------------------------------------------------------------
# edge coefficients
# ------------------------------------------------------------------------------------------


def _random_edges(rng, n, twist):
    x0 = rng.normal(size=(n, 3))
    d = rng.normal(size=(n, 3))
    base = np.cross(d, rng.normal(size=(n, 3)))
    base /= np.linalg.norm(base, axis=1, keepdims=True)
    dh = d / np.linalg.norm(d, axis=1, keepdims=True)
    tw = np.cross(base, dh)
    sgn = rng.choice([-1.0, 1.0], size=(n, 1))
    # normals tilted by up to ~30° against the chord, opposite ways (convex or concave arcs)
    n0 = base - sgn * rng.uniform(0.05, 0.5, (n, 1)) * dh + twist * rng.uniform(-1, 1, (n, 1)) * tw
    n1 = base + sgn * rng.uniform(0.05, 0.5, (n, 1)) * dh + twist * rng.uniform(-1, 1, (n, 1)) * tw
    n0 /= np.linalg.norm(n0, axis=1, keepdims=True)
    n1 /= np.linalg.norm(n1, axis=1, keepdims=True)
    return x0, x0 + d, n0, n1


def test_edge_coefficient_tangency_span_symmetry():
    rng = np.random.default_rng(0)
    # planar data (n0, n1, d coplanar): exact tangency and c in span(n0, n1) (THEORY §7.1)
    x0, x1, n0, n1 = _random_edges(rng, 200, 0.0)
    d = x1 - x0
    c, flag = edge_coefficients(x0, x1, n0, n1)
    ok = flag == 0
    assert ok.sum() > 190
    np.testing.assert_allclose(np.einsum("ij,ij->i", n0, d - c)[ok], 0.0, atol=1e-12)
    np.testing.assert_allclose(np.einsum("ij,ij->i", n1, d + c)[ok], 0.0, atol=1e-12)
    np.testing.assert_allclose(np.einsum("ij,ij->i", np.cross(n0, n1), c)[ok], 0.0, atol=1e-12)
    c_rev, _ = edge_coefficients(x1, x0, n1, n0)
    np.testing.assert_allclose(c_rev, c, atol=1e-12)
    # twisted data: symmetric, in the normal plane of the edge, tangency up to |d·v|
    x0, x1, n0, n1 = _random_edges(rng, 200, 0.1)
    d = x1 - x0
    c, flag = edge_coefficients(x0, x1, n0, n1)
    c_rev, _ = edge_coefficients(x1, x0, n1, n0)
    np.testing.assert_allclose(c_rev, c, atol=1e-12)
    ok = flag == 0
    assert ok.sum() > 150
    v = 0.5 * (n0 + n1)
    w = np.cross(d, v)
    np.testing.assert_allclose(np.einsum("ij,ij->i", w, c)[ok], 0.0, atol=1e-12)
    dv = np.abs(np.einsum("ij,ij->i", d, v))
    assert np.all(np.abs(np.einsum("ij,ij->i", n0, d - c))[ok] <= dv[ok] + 1e-12)
    assert np.all(np.abs(np.einsum("ij,ij->i", n1, d + c))[ok] <= dv[ok] + 1e-12)


@pytest.mark.parametrize("phi_deg, curve_err, chord_err",
                         [(20.0, 1.2e-4, 1.5e-2), (40.0, 1.9e-3, 6.0e-2), (80.0, None, None)])
def test_edge_coefficient_circular_arc(phi_deg, curve_err, chord_err):
    """|c|/|d| = tan(φ/2) for an arc with exact normals; curve error O(θ⁴) (THEORY §7.1)."""
    phi = math.radians(phi_deg)
    a = np.array([-phi / 2, phi / 2])
    X = np.stack([np.cos(a), np.sin(a), 0 * a], axis=1)
    c, flag = edge_coefficients(X[:1], X[1:], X[:1], X[1:])
    assert flag[0] == 0
    assert np.linalg.norm(c) / np.linalg.norm(X[1] - X[0]) == pytest.approx(math.tan(phi / 2),
                                                                            rel=1e-12)
    s = np.linspace(0, 1, 2001)[:, None]
    curve = X[0] + (X[1] - X[0] - c[0]) * s + c[0] * s ** 2
    err = np.max(np.abs(np.linalg.norm(curve, axis=1) - 1.0))
    if curve_err is not None:
        assert err == pytest.approx(curve_err, rel=0.05)
        assert 1 - math.cos(phi / 2) == pytest.approx(chord_err, rel=0.05)


def test_edge_coefficient_degenerate_cases():
    x0, x1 = np.zeros(3), np.array([1.0, 0.0, 0.0])
    n = np.array([0.0, 0.0, 1.0])
    # parallel normals
    c, flag = edge_coefficients(x0, x1, n, n)
    assert flag[0] == 1 and np.all(c == 0)
    tilt = np.array([0.0, math.sin(math.radians(0.05)), math.cos(math.radians(0.05))])
    c, flag = edge_coefficients(x0, x1, n, tilt)
    assert flag[0] == 1 and np.all(c == 0)
    # opposite normals
    c, flag = edge_coefficients(x0, x1, n, -n)
    assert flag[0] == 1 and np.all(c == 0)
    # inconsistent normals (inflection: both tilted the same way) -> |c| > |d| -> straight
    t = math.radians(30)
    n0 = np.array([math.sin(t), 0.0, math.cos(t)])
    n1 = np.array([math.sin(t + 0.01), 0.0, math.cos(t + 0.01)])
    c, flag = edge_coefficients(x0, x1, n0, n1)
    assert flag[0] == 2 and np.all(c == 0)
    c, flag = edge_coefficients(x0, x1, n0, n1, kappa=1e6)
    assert flag[0] == 3 and np.all(c == 0)  # caught by the inflection rule
    c, flag = edge_coefficients(x0, x1, n0, n1, kappa=1e6, inflection=False)
    assert flag[0] == 0 and np.linalg.norm(c) > 1.0
    # near-parallel normals twisting about the chord (a cylinder generator with noisy normals,
    # as on unstructured gmsh meshes): no sideways bulge; same-sign tilts -> inflection, c = 0
    x1 = np.array([0.0, 0.0, 1.6])
    n0 = np.array([1.0, 0.0, 9e-4])
    n1 = np.array([math.cos(0.003), math.sin(0.003), 3e-4])
    n0, n1 = n0 / np.linalg.norm(n0), n1 / np.linalg.norm(n1)
    c, flag = edge_coefficients(x0, x1, n0, n1)
    assert flag[0] == 3 and np.all(c == 0)
    c, flag = edge_coefficients(x0, x1, n0, n1, inflection=False)
    assert flag[0] == 0 and np.hypot(c[0, 0], c[0, 1]) < 1e-3  # the raw formula: 0.6 sideways
    n1[2] = -n1[2]
    c, flag = edge_coefficients(x0, x1, n0, n1)
    assert flag[0] == 0 and np.hypot(c[0, 0], c[0, 1]) < 1e-3


def test_crease_tangent_rule():
    # straight crease -> c = 0 (minimum-norm solution of the singular system)
    x0, x1 = np.zeros(3), np.array([2.0, 0.0, 0.0])
    t = np.array([1.0, 0.0, 0.0])
    c, flag = crease_edge_coefficients(x0, x1, t, -t)
    np.testing.assert_allclose(c, 0.0, atol=1e-15)
    # planar arc: coincides with the normal rule (THEORY §8.3)
    a = np.radians([-20.0, 25.0])
    X = np.stack([np.cos(a), np.sin(a), 0 * a], axis=1)
    tang = np.stack([-np.sin(a), np.cos(a), 0 * a], axis=1)
    c_t, _ = crease_edge_coefficients(X[:1], X[1:], tang[:1], -tang[1:])
    c_n, _ = edge_coefficients(X[:1], X[1:], X[:1], X[1:])
    np.testing.assert_allclose(c_t, c_n, atol=1e-13)


# ------------------------------------------------------------------------------------------
# patch geometry
# ------------------------------------------------------------------------------------------


def test_patch_interpolates_vertices_normals_and_edges(sphere_patches):
    V, T, fvn, C, A = sphere_patches
    xi = [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0)]
    for k, (e, z) in enumerate(xi):
        np.testing.assert_allclose(patch_points(A, e, z), V[T[:, k]], atol=1e-14)
        np.testing.assert_allclose(patch_normals(A, e, z), fvn.normals[:, k], atol=1e-12)
    # edges are the Nagata curves x0 + (d - c) s + c s²
    s = np.linspace(0, 1, 7)
    for k, (ee, zz) in enumerate([(s, 0 * s), (0 * s + 1, s), (s, s)]):
        x0 = V[T[:, LOCAL_EDGES[k, 0]]][:, None]
        d = V[T[:, LOCAL_EDGES[k, 1]]][:, None] - x0
        c = C[:, k][:, None]
        curve = x0 + (d - c) * s[:, None] + c * s[:, None] ** 2
        np.testing.assert_allclose(patch_points(A[:, None], ee, zz), curve, atol=1e-14)
    # deviation from the flat triangle <= max|c|/3 (THEORY §7.2)
    E, Z = domain_samples(20)
    flat = (V[T[:, 0]][:, None] * (1 - E)[:, None] + V[T[:, 1]][:, None] * (E - Z)[:, None]
            + V[T[:, 2]][:, None] * Z[:, None])
    dev = np.linalg.norm(patch_points(A[:, None], E, Z) - flat, axis=2).max(axis=1)
    assert np.all(dev <= np.linalg.norm(C, axis=2).max(axis=1) / 3 + 1e-15)


@pytest.mark.parametrize("mesh", ["sphere", "capped_cylinder"])
def test_patched_surface_is_watertight(mesh):
    if mesh == "sphere":
        V, T = tm.icosphere(2)
    else:
        V, T = tm.structured_cylinder(1.0, 2.0, 12, 4, capped=True)
    _, _, A = _patches(V, T)
    topo = edge_topology(T)
    s = np.linspace(0, 1, 9)
    pts = [np.stack([s, 0 * s], 1), np.stack([0 * s + 1, s], 1), np.stack([s, s], 1)]
    for f in range(T.shape[0]):
        for k in range(3):
            g, kg = topo.neighbor[f, k], topo.neighbor_edge[f, k]
            same = T[g, LOCAL_EDGES[kg, 0]] == T[f, LOCAL_EDGES[k, 0]]
            sg = s if same else 1 - s
            xf = patch_points(A[f], pts[k][:, 0], pts[k][:, 1])
            pg = [np.stack([sg, 0 * s], 1), np.stack([0 * s + 1, sg], 1), np.stack([sg, sg], 1)][kg]
            xg = patch_points(A[g], pg[:, 0], pg[:, 1])
            np.testing.assert_allclose(xf, xg, atol=1e-14)


def test_patch_derivatives_finite_differences(sphere_patches):
    A = sphere_patches[4]
    h = 1e-6
    for f in (0, 17, 55):
        e, z = 0.6, 0.25
        xe, xz = patch_derivatives(A[f], e, z)
        fe = (patch_points(A[f], e + h, z) - patch_points(A[f], e - h, z)) / (2 * h)
        fz = (patch_points(A[f], e, z + h) - patch_points(A[f], e, z - h)) / (2 * h)
        np.testing.assert_allclose(xe, fe, atol=1e-9)
        np.testing.assert_allclose(xz, fz, atol=1e-9)


# ------------------------------------------------------------------------------------------
# projection on one patch
# ------------------------------------------------------------------------------------------


def _brute_force(a, p, n=150):
    E, Z = domain_samples(n)
    d2 = np.sum((patch_points(a, E, Z) - p) ** 2, axis=1)
    i = int(np.argmin(d2))
    cons = [{"type": "ineq", "fun": lambda q: q[1]}, {"type": "ineq", "fun": lambda q: q[0] - q[1]},
            {"type": "ineq", "fun": lambda q: 1 - q[0]}]
    res = minimize(lambda q: 0.5 * np.sum((patch_points(a, q[0], q[1]) - p) ** 2), [E[i], Z[i]],
                   method="SLSQP", constraints=cons, options={"ftol": 1e-16, "maxiter": 200})
    return min(math.sqrt(2 * res.fun), math.sqrt(d2[i]))


@pytest.mark.parametrize("which", ["sphere", "cylinder"])
def test_projection_matches_brute_force(which, sphere_patches, cylinder_patches):
    A = (sphere_patches if which == "sphere" else cylinder_patches)[4]
    rng = np.random.default_rng(1)
    sides = {1: 0, -1: 0}
    for f, e, z, p, t in _random_patch_points(A, rng, 40, 0.3):
        # include points projecting on edges and corners: random lateral shift
        p = p + rng.normal(size=3) * 0.15
        eta, zeta, st, its = project_patch(A[f], p)
        assert st == 1 and its <= 30
        d = np.linalg.norm(patch_points(A[f], eta, zeta) - p)
        db = _brute_force(A[f], p)
        assert d <= db + 1e-10
        assert d == pytest.approx(db, abs=1e-8)
        sides[1 if t > 0 else -1] += 1
    assert min(sides.values()) > 5


def test_numba_kernels_match_numpy_twins(sphere_patches, cylinder_patches):
    rng = np.random.default_rng(2)
    for A in (sphere_patches[4], cylinder_patches[4]):
        for f, e, z, p, t in _random_patch_points(A, rng, 60, 0.5):
            p = p + rng.normal(size=3) * 0.3
            xi0 = tuple(sorted(rng.random(2))[::-1])
            r_nb = project_patch_nb(A[f], p, xi0[0], xi0[1], 30, 12, True)
            r_ref = project_patch_ref(A[f], p, xi0[0], xi0[1], 30, 12, True)
            assert r_nb[2] == r_ref[2]
            assert abs(r_nb[0] - r_ref[0]) <= 1e-12 and abs(r_nb[1] - r_ref[1]) <= 1e-12
            for plain in (False,):
                r_nb = project_patch_nb(A[f], p, xi0[0], xi0[1], 30, 12, plain)
                r_ref = project_patch_ref(A[f], p, xi0[0], xi0[1], 30, 12, plain)
                assert abs(r_nb[0] - r_ref[0]) <= 1e-12 and abs(r_nb[1] - r_ref[1]) <= 1e-12
            n = np.empty(3)
            H = np.empty((3, 3))
            d = patch_gap_nb(A[f], p, e, z, True, n, H)
            d_r, n_r, H_r = patch_gap_ref(A[f], p, e, z)
            assert abs(d - d_r) <= 1e-12
            np.testing.assert_allclose(n, n_r, atol=1e-12)
            np.testing.assert_allclose(H, H_r, atol=1e-12 * max(1.0, np.abs(H_r).max()))
        # domain projection and KKT helper
        for _ in range(200):
            e, z = rng.uniform(-0.5, 1.5, 2)
            assert ng.proj_domain(e, z) == pytest.approx(ng._proj_domain_ref(e, z), abs=1e-15)
            ee, zz = ng.proj_domain(e, z)
            g = rng.normal(size=2)
            assert ng.proj_grad_norm(ee, zz, g[0], g[1]) == pytest.approx(
                ng._proj_grad_norm_ref(ee, zz, g), abs=1e-14)
            assert ng._binding_edge(ee, zz, g[0], g[1]) == ng._binding_edge_ref(ee, zz, g)


def _signed_distance(a, p):
    e, z, st, _ = project_patch(a, p)
    assert st == 1
    d, n, H = patch_gap(a, p, e, z)
    return d, n, H, (e, z)


@pytest.mark.parametrize("which", ["sphere", "cylinder"])
def test_gap_gradient_and_hessian_finite_differences(which, sphere_patches, cylinder_patches):
    """∇d = n* and ∇²d = N_ξ H⁻¹ X_ξᵀ (THEORY §7.5), relative error < 1e-6, both sides."""
    A = (sphere_patches if which == "sphere" else cylinder_patches)[4]
    rng = np.random.default_rng(3)
    h = 1e-5
    checked = {1: 0, -1: 0}
    for f, e, z, p, t in _random_patch_points(A, rng, 24, 0.2):
        d, n, H, xi = _signed_distance(A[f], p)
        if not (0.02 < xi[1] < xi[0] - 0.02 and xi[0] < 0.98):
            continue
        assert abs(d - t) < 1e-12  # offset along the normal is the signed distance
        gfd = np.empty(3)
        hfd = np.empty((3, 3))
        for k in range(3):
            dp = np.zeros(3)
            dp[k] = h
            dpl, npl, _, _ = _signed_distance(A[f], p + dp)
            dmi, nmi, _, _ = _signed_distance(A[f], p - dp)
            gfd[k] = (dpl - dmi) / (2 * h)
            hfd[:, k] = (npl - nmi) / (2 * h)
        assert np.linalg.norm(gfd - n) / np.linalg.norm(n) < 1e-6
        assert np.linalg.norm(hfd - H) / np.linalg.norm(H) < 1e-6
        np.testing.assert_allclose(H, H.T, atol=1e-12 * np.abs(H).max())
        np.testing.assert_allclose(H @ n, 0.0, atol=1e-10 * np.abs(H).max())
        checked[1 if t > 0 else -1] += 1
    assert min(checked.values()) >= 3


# ------------------------------------------------------------------------------------------
# safeguards
# ------------------------------------------------------------------------------------------


def test_sub_incrementation_needed_and_sufficient():
    """Newton without step halving fails near the focal region of a coarse cylinder patch;
    the safeguarded (sub-incremented) Newton converges to the brute-force closest point."""
    V, T = tm.structured_cylinder(1.0, 2.0, 6, 1)
    _, _, A = _patches(V, T, "angle")
    a = A[0]
    p = np.array([0.08420127403862598, 0.06422791990899063, -0.3119524202596566])
    e, z, st, its = project_patch(a, p, max_halvings=12)
    assert st == 1
    d = np.linalg.norm(patch_points(a, e, z) - p)
    assert d == pytest.approx(_brute_force(a, p), abs=1e-9)
    assert 0.0 < z < e < 1.0  # an interior projection
    e0, z0, st0, _ = project_patch(a, p, max_halvings=0)
    assert st0 == 0  # the full step does not decrease f and nothing else is tried
    assert np.linalg.norm(patch_points(a, e0, z0) - p) > d + 1e-3


def test_clamped_plain_newton_stalls_on_edges_and_edge_newton_fixes_it(cylinder_patches):
    """THEORY §7.4 step 4: clamped 2D Newton steps stall short of a boundary minimum."""
    A = cylinder_patches[4]
    a = A[3]
    p = np.array([-0.8537271304063354, 0.5245907161809248, -0.6931947101471263])
    e, z, st, _ = project_patch(a, p)
    assert st == 1 and e == z  # minimum on the edge ζ = η
    d = np.linalg.norm(patch_points(a, e, z) - p)
    assert d == pytest.approx(_brute_force(a, p), abs=1e-9)
    e0, z0, st0, _ = project_patch(a, p, safeguard=False)
    assert st0 == 0
    assert np.linalg.norm(patch_points(a, e0, z0) - p) > d + 1e-5


def test_forced_non_convergence_is_reported(sphere_patches):
    A = sphere_patches[4]
    p = patch_points(A[5], 0.7, 0.2) + 0.1 * patch_normals(A[5], 0.7, 0.2)
    assert project_patch(A[5], p, xi0=(0.05, 0.0), max_iter=0)[2] == ng.STATUS_FAILED
    assert project_patch(A[5], p, xi0=(0.05, 0.0), max_iter=1)[2] == ng.STATUS_FAILED
    assert project_patch(A[5], p, xi0=(0.05, 0.0), max_iter=30)[2] == ng.STATUS_CONVERGED
