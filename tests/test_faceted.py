"""Faceted tools: input checks, flat (Forge) and Nagata projections, search, motion, I/O."""

import logging
import math

import numpy as np
import pytest

from fxcontact.tools.faceted import (
    FLAG_FALLBACK,
    FacetedTool,
    check_surface,
    closest_point_triangle,
    closest_point_triangle_nb,
    closest_point_triangle_ref,
    flat_project_ref,
    nagata_project_ref,
    read_surface,
)
from fxcontact.tools.nagata import domain_samples, patch_points



from fxcontact.tools import surfaces as tm  # noqa: E402


def sphere_sdf(X, R=1.0):
    return np.linalg.norm(X, axis=1) - R


def cylinder_sdf(X, R=1.0):
    return np.hypot(X[:, 0], X[:, 1]) - R


def capped_cylinder_sdf(X, R=1.0, H=2.0):
    q1 = np.hypot(X[:, 0], X[:, 1]) - R
    q2 = np.abs(X[:, 2]) - H / 2
    return np.hypot(np.maximum(q1, 0), np.maximum(q2, 0)) + np.minimum(np.maximum(q1, q2), 0)


def box_sdf(X, half=0.5):
    q = np.abs(X) - half
    return np.linalg.norm(np.maximum(q, 0), axis=1) + np.minimum(q.max(axis=1), 0)


def near_points(sdf_surface_points, normals, rng, band):
    return sdf_surface_points + normals * rng.uniform(-band, band, (len(normals), 1))


def all_candidates(n_points, n_tri):
    return np.arange(n_points + 1) * n_tri, np.tile(np.arange(n_tri), n_points)


def patch_samples(tool, n=20):
    E, Z = domain_samples(n)
    return patch_points(tool.patches[:, None], E[None], Z[None]).reshape(-1, 3)


def flat_samples(tool, n=20):
    E, Z = domain_samples(n)
    P = tool.vertices[tool.triangles]
    lam = np.stack([1 - E, E - Z, Z], axis=1)
    return np.einsum("sk,fkd->fsd", lam, P).reshape(-1, 3)


@pytest.fixture(scope="module")
def sphere80():
    return tm.icosphere(1)


# ------------------------------------------------------------------------------------------
# closest point on a triangle
# ------------------------------------------------------------------------------------------


def test_closest_point_triangle_regions_and_brute_force():
    rng = np.random.default_rng(0)
    E, Z = domain_samples(300)
    lam = np.stack([1 - E, E - Z, Z], axis=1)
    regions = set()
    for _ in range(200):
        a, b, c = rng.normal(size=(3, 3))
        p = (a + b + c) / 3 + rng.normal(size=3) * 1.5
        q, bary, reg = closest_point_triangle(p, a, b, c)
        regions.add(reg)
        samples = lam @ np.stack([a, b, c])
        dbrute = np.min(np.linalg.norm(samples - p, axis=1))
        d = np.linalg.norm(q - p)
        assert d <= dbrute + 1e-12
        assert d == pytest.approx(dbrute, abs=2e-2)
        np.testing.assert_allclose(bary @ np.stack([a, b, c]), q, atol=1e-12)
        # numba kernel == numpy twin
        qr, br, rr = closest_point_triangle_ref(p, a, b, c)
        assert rr[0] == reg
        np.testing.assert_allclose(qr[0], q, atol=1e-12)
        np.testing.assert_allclose(br[0], bary, atol=1e-12)
    assert regions == set(range(7))
    assert callable(closest_point_triangle_nb)


# ------------------------------------------------------------------------------------------
# input checking
# ------------------------------------------------------------------------------------------


def test_bad_inputs_raise_with_indices(sphere80, caplog):
    V, T = sphere80
    with pytest.raises(ValueError, match=r"NaN/inf coordinates at vertex indices \[3\]"):
        Vb = V.copy()
        Vb[3, 1] = np.nan
        FacetedTool(Vb, T)
    with pytest.raises(ValueError, match=r"NaN/inf.*\[7\]"):
        Vb = V.copy()
        Vb[7, 0] = np.inf
        check_surface(Vb, T)
    Tb = T.copy()
    Tb[5] = [0, 1, 999]
    with pytest.raises(ValueError, match=r"out of range \[0, 42\) in triangles \[5\]"):
        FacetedTool(V, Tb)
    Tb = T.copy()
    Tb[9, 2] = Tb[9, 0]
    with pytest.raises(ValueError, match=r"degenerate \(zero-area\) triangles \[9\]"):
        FacetedTool(V, Tb)
    Vb = np.vstack([V, 0.5 * (V[T[4, 0]] + V[T[4, 1]])])  # collinear third vertex
    Tb = np.vstack([T, [T[4, 0], T[4, 1], V.shape[0]]])
    with pytest.raises(ValueError, match=r"degenerate \(zero-area\) triangles \[80\]"):
        FacetedTool(Vb, Tb)
    Tb = np.vstack([T, T[7][[1, 2, 0]]])
    with pytest.raises(ValueError, match=r"duplicate triangles.*\[\[7, 80\]\]"):
        FacetedTool(V, Tb)
    # non-manifold: a fin on an existing edge
    Vb = np.vstack([V, [[0.0, 0.0, 3.0]]])
    Tb = np.vstack([T, [T[0, 0], T[0, 1], V.shape[0]]])
    with pytest.raises(ValueError, match=r"non-manifold edges.*triangles \[0, \d+, 80\]"):
        FacetedTool(Vb, Tb)
    Tb = T.copy()
    Tb[11] = Tb[11, [0, 2, 1]]
    with pytest.raises(ValueError, match=r"inconsistent orientation.*triangles \[.*11.*\]"):
        FacetedTool(V, Tb)
    with pytest.raises(ValueError, match=r"normals point into the tool.*flip=True"):
        FacetedTool(V, T[:, [0, 2, 1]])
    # a closed inverted component next to an open one is still detected
    plate_V = np.array([[3.0, 0, 0], [4, 0, 0], [4, 1, 0], [3, 1, 0]])
    Vb = np.vstack([V, plate_V])
    Tb = np.vstack([T[:, [0, 2, 1]], [[42, 43, 44], [42, 44, 45]]])
    with pytest.raises(ValueError, match=r"closed component .*triangles \[0, 1, 2"):
        FacetedTool(Vb, Tb)
    assert not FacetedTool(Vb, np.vstack([T, [[42, 43, 44], [42, 44, 45]]]), mode="flat").closed
    with pytest.raises(ValueError, match="shape"):
        FacetedTool(V[:, :2], T)
    with pytest.raises(ValueError, match="shape"):
        FacetedTool(V, T[:, :2])
    with pytest.raises(ValueError, match="non-integer"):
        FacetedTool(V, T + 0.5)
    with pytest.raises(ValueError, match="mode"):
        FacetedTool(V, T, mode="smooth")
    # unused vertices: dropped with a warning
    Vb = np.vstack([[[9.0, 9.0, 9.0]], V])
    with caplog.at_level(logging.WARNING, logger="fxcontact.tools.faceted"):
        tool = FacetedTool(Vb, T + 1)
    assert "1 unused vertices dropped" in caplog.text
    assert tool.vertices.shape == V.shape


def test_flip_option(sphere80):
    V, T = sphere80
    rng = np.random.default_rng(1)
    X = rng.normal(size=(50, 3)) * 0.6
    for mode in ("flat", "nagata"):
        ref = FacetedTool(V, T, mode=mode).project(X)
        flipped = FacetedTool(V, T[:, [0, 2, 1]], mode=mode, flip=True).project(X)
        np.testing.assert_allclose(flipped.gap, ref.gap, atol=1e-14)
        np.testing.assert_allclose(flipped.normal, ref.normal, atol=1e-14)
    # flipping a correctly oriented closed surface is an error (inside-out)
    with pytest.raises(ValueError, match="signed volume"):
        FacetedTool(V, T, flip=True)


@pytest.mark.parametrize("mode", ["flat", "nagata"])
def test_open_surface_sign(mode):
    """Open surfaces: free space is the side the oriented facet normals point to."""
    g = np.linspace(-1, 1, 4)
    Xg, Yg = np.meshgrid(g, g, indexing="ij")
    V = np.stack([Xg.ravel(), Yg.ravel(), 0.1 * Xg.ravel() ** 2], axis=1)  # gently curved plate
    idx = np.arange(16).reshape(4, 4)
    a, b, c, d = idx[:-1, :-1], idx[1:, :-1], idx[1:, 1:], idx[:-1, 1:]
    T = np.vstack([np.stack([a, b, c], -1).reshape(-1, 3), np.stack([a, c, d], -1).reshape(-1, 3)])
    tool = FacetedTool(V, T, mode=mode)
    assert not tool.closed
    rng = np.random.default_rng(2)
    XY = rng.uniform(-0.9, 0.9, (100, 2))
    h = rng.uniform(0.02, 0.5, 100) * rng.choice([-1, 1], 100)
    X = np.column_stack([XY, 0.1 * XY[:, 0] ** 2 + h])
    pr = tool.project(X)
    assert np.all(np.sign(pr.gap) == np.sign(h))
    assert np.all(pr.normal[:, 2] > 0.9)
    # beyond the boundary, on the normal side: free space
    far = np.array([[3.0, 0.0, 0.5], [0.0, -3.0, 0.2], [2.0, 2.0, 1.0]])
    assert np.all(tool.project(far).gap > 0)
    # reversed orientation: the other side is free space
    tool_r = FacetedTool(V, T, mode=mode, flip=True)
    np.testing.assert_allclose(tool_r.project(X).gap, -pr.gap, atol=1e-12)


# ------------------------------------------------------------------------------------------
# flat (Forge) mode
# ------------------------------------------------------------------------------------------


def test_flat_mode_on_cube_matches_box_sdf():
    V, T = tm.box_surface(n=3)
    tool = FacetedTool(V, T, mode="flat")
    X = np.random.default_rng(3).uniform(-1, 1, (3000, 3))
    sdf = box_sdf(X)
    # exact signed distance with pseudo-normal sign (THEORY §6)
    np.testing.assert_allclose(tool.flat_signed_distance(X), sdf, atol=1e-14)
    pr = tool.project(X)
    assert np.all(np.sign(pr.gap) == np.sign(sdf))  # the plane gap never has the wrong sign
    assert np.all(np.abs(pr.gap) <= np.abs(sdf) + 1e-14)
    face_region = (np.sum(np.abs(X) > 0.5, axis=1) <= 1)
    np.testing.assert_allclose(pr.gap[face_region], sdf[face_region], atol=1e-14)
    np.testing.assert_allclose(pr.hessian, 0.0)
    assert tool.has_hessian
    np.testing.assert_allclose(pr.normal, tool.facet_normals[pr.feature])
    np.testing.assert_allclose(pr.point, X - pr.gap[:, None] * pr.normal, atol=1e-14)


@pytest.mark.parametrize("mesh", ["sphere", "capped_cylinder"])
def test_flat_mode_matches_brute_force_and_twin(mesh):
    V, T = tm.icosphere(2) if mesh == "sphere" else tm.structured_cylinder(1, 2, 12, 4, True)
    tool = FacetedTool(V, T, mode="flat")
    rng = np.random.default_rng(4)
    X = np.vstack([rng.uniform(-1.4, 1.4, (300, 3)), rng.normal(size=(30, 3)) * 30])
    pr = tool.project(X)
    ptr, idx = all_candidates(len(X), len(T))
    g, n, p, feat, sd = flat_project_ref(tool, X, ptr, idx)
    np.testing.assert_allclose(pr.gap, g, atol=1e-12)
    np.testing.assert_allclose(tool.flat_signed_distance(X), sd, atol=1e-12)
    ptr, idx = tool.candidates(X, flat=True)
    g2 = flat_project_ref(tool, X, ptr, idx)[0]
    np.testing.assert_allclose(pr.gap, g2, atol=1e-12)


# ------------------------------------------------------------------------------------------
# Nagata mode
# ------------------------------------------------------------------------------------------


@pytest.mark.parametrize("mesh", ["sphere", "capped_cylinder", "cube"])
@pytest.mark.slow
def test_nagata_matches_brute_force_over_all_patches_and_twin(mesh):
    meshes = {"sphere": lambda: tm.icosphere(1),
              "capped_cylinder": lambda: tm.structured_cylinder(1, 2, 8, 3, True),
              "cube": lambda: tm.box_surface(n=3)}
    V, T = meshes[mesh]()
    tool = FacetedTool(V, T)
    rng = np.random.default_rng(5)
    X = np.vstack([rng.uniform(-1.3, 1.3, (250, 3)), rng.normal(size=(20, 3)) * 20])
    pr = tool.project(X)
    assert pr.flag.sum() == 0
    # brute force: every patch projected (reference twin with all candidates)
    sub = np.r_[0:80, 250:270]
    ptr, idx = all_candidates(len(sub), len(T))
    g = nagata_project_ref(tool, X[sub], ptr, idx)[0]
    np.testing.assert_allclose(pr.gap[sub], g, atol=1e-12)
    # numba kernel == numpy twin on the kernel's own candidate lists
    ptr, idx = tool.candidates(X)
    g, n, p, h, feat, flag = nagata_project_ref(tool, X, ptr, idx)
    np.testing.assert_allclose(pr.gap, g, atol=1e-12)
    np.testing.assert_allclose(pr.normal, n, atol=1e-12)
    np.testing.assert_allclose(pr.point, p, atol=1e-12)
    scale = np.maximum(1.0, np.abs(h).max(axis=(1, 2)))[:, None, None]
    np.testing.assert_allclose(pr.hessian / scale, h / scale, atol=1e-12)
    # dense sampling of all patches: nobody is closer than the projection
    S = patch_samples(tool, 30)
    for i in rng.choice(len(X), 40, replace=False):
        dmin = np.min(np.linalg.norm(S - X[i], axis=1))
        assert abs(pr.gap[i]) <= dmin + 1e-12
        assert abs(pr.gap[i]) == pytest.approx(dmin, abs=2e-2)  # sampling resolution


def test_nagata_sign_consistent_with_solid(sphere80):
    V, T = tm.structured_cylinder(1, 2, 12, 6, True)
    tool = FacetedTool(V, T)
    X = np.random.default_rng(6).uniform(-1.5, 1.5, (3000, 3))
    sdf = capped_cylinder_sdf(X)
    pr = tool.project(X)
    clear = np.abs(sdf) > 2e-3  # beyond the patch error
    assert np.all(np.sign(pr.gap[clear]) == np.sign(sdf[clear]))
    assert np.max(np.abs(pr.gap - sdf)) < 2e-3


def test_nagata_mesh_gap_derivatives_finite_differences(sphere80):
    V, T = sphere80
    tool = FacetedTool(V, T)
    rng = np.random.default_rng(7)
    X = rng.normal(size=(40, 3))
    X *= (1 + rng.uniform(-0.08, 0.08, (40, 1))) / np.linalg.norm(X, axis=1, keepdims=True)
    pr = tool.project(X)
    h = 1e-5
    n_ok = 0
    for i in range(len(X)):
        plus = tool.project(X[i] + h * np.eye(3))
        minus = tool.project(X[i] - h * np.eye(3))
        if np.any(plus.feature != pr.feature[i]) or np.any(minus.feature != pr.feature[i]):
            continue  # too close to a patch boundary for central differences
        g = (plus.gap - minus.gap) / (2 * h)
        H = (plus.normal - minus.normal).T / (2 * h)
        assert np.linalg.norm(g - pr.normal[i]) < 1e-6
        assert np.linalg.norm(H - pr.hessian[i]) / np.linalg.norm(pr.hessian[i]) < 1e-6
        n_ok += 1
    assert n_ok > 20
    # ∇²d n = 0, symmetric, and ≈ (I − nn)/(R + d) on a sphere
    np.testing.assert_allclose(np.einsum("nij,nj->ni", pr.hessian, pr.normal), 0, atol=1e-10)


# ------------------------------------------------------------------------------------------
# accuracy (THEORY §7.7, §8.4)
# ------------------------------------------------------------------------------------------


@pytest.mark.parametrize("mesh, sdf, nagata_ref", [
    ("sphere80", sphere_sdf, 1.26e-3), ("sphere320", sphere_sdf, 1.07e-3),
    ("cyl8", cylinder_sdf, 3.14e-3), ("cyl12", cylinder_sdf, 6.01e-4),
    ("cyl16", cylinder_sdf, 1.88e-4)])
def test_nagata_nvv_ten_times_closer_than_flat(mesh, sdf, nagata_ref):
    if mesh.startswith("sphere"):
        V, T = tm.icosphere(1 if mesh == "sphere80" else 2)
    else:
        n = int(mesh[3:])
        V, T = tm.structured_cylinder(1.0, 4 * 2 * np.pi / n, n, 4)
    tool = FacetedTool(V, T, normals="nvv")
    err_flat = np.max(np.abs(sdf(flat_samples(tool))))
    err_nag = np.max(np.abs(sdf(patch_samples(tool))))
    assert err_nag * 10 <= err_flat
    # same order as THEORY §7.7 (open cylinders: boundary rings slightly worse)
    assert err_nag < 2.6 * nagata_ref


@pytest.mark.parametrize("n_theta, rows, flat_ref, crease_ref", [
    (8, 3, 7.61e-2, 3.22e-3), (12, 6, 3.41e-2, 1.04e-3), (16, 9, 1.92e-2, 7.51e-4)])
def test_capped_cylinder_crease_preserving(n_theta, rows, flat_ref, crease_ref):
    V, T = tm.structured_cylinder(1.0, 2.0, n_theta, rows, capped=True)
    tool = FacetedTool(V, T, normals="nvv", crease_angle=math.radians(50))
    rim = np.isclose(np.abs(V[:, 2]), 1.0) & (np.hypot(V[:, 0], V[:, 1]) > 0.5)
    assert np.all(tool.vertex_class[rim] == 2) and np.all(tool.vertex_class[~rim] == 1)
    err_flat = np.max(np.abs(capped_cylinder_sdf(flat_samples(tool))))
    err_crease = np.max(np.abs(capped_cylinder_sdf(patch_samples(tool))))
    smeared = FacetedTool(V, T, normals="angle")
    err_angle = np.max(np.abs(capped_cylinder_sdf(patch_samples(smeared))))
    assert err_flat == pytest.approx(flat_ref, rel=0.01)
    assert err_crease <= 1.05 * crease_ref  # THEORY §8.4 (or better)
    assert 0.3 * err_flat < err_angle < 0.7 * err_flat  # averaged normals bulge at the rims


def test_cube_patches_exactly_flat():
    V, T = tm.box_surface(n=3)
    tool = FacetedTool(V, T)
    cls = tool.vertex_class
    kind = np.sum(np.isclose(np.abs(V), 0.5), axis=1) - 1
    assert np.all(cls == kind + 1)
    assert np.all(tool.patch_coefficients == 0.0)
    X = np.random.default_rng(8).uniform(-1, 1, (2000, 3))
    np.testing.assert_allclose(tool.project(X).gap, box_sdf(X), atol=1e-14)


# ------------------------------------------------------------------------------------------
# fallback, motion, far points, empty input
# ------------------------------------------------------------------------------------------


def test_forced_non_convergence_is_flagged_counted_and_logged(sphere80, caplog):
    V, T = sphere80
    rng = np.random.default_rng(9)
    X = rng.normal(size=(100, 3))
    X *= (1 + rng.uniform(-0.1, 0.1, (100, 1))) / np.linalg.norm(X, axis=1, keepdims=True)
    flat = FacetedTool(V, T, mode="flat").project(X)
    for max_iter in (0, 1):
        tool = FacetedTool(V, T, max_iter=max_iter, name="sphere-tool")
        with caplog.at_level(logging.WARNING, logger="fxcontact.tools.faceted"):
            pr = tool.project(X)
        nfb = int(np.sum(pr.flag == FLAG_FALLBACK))
        assert nfb > (95 if max_iter == 0 else 10)
        assert tool.last_fallbacks == nfb
        assert f"did not converge for {nfb} of 100 points" in caplog.text
        fb = pr.flag == FLAG_FALLBACK
        np.testing.assert_allclose(pr.gap[fb], flat.gap[fb], atol=1e-14)
        np.testing.assert_allclose(pr.normal[fb], flat.normal[fb], atol=1e-14)
        np.testing.assert_allclose(pr.hessian[fb], 0.0)
        caplog.clear()
    tool.project(X)
    assert tool.total_fallbacks == 2 * tool.last_fallbacks
    good = FacetedTool(V, T)
    good.project(X)
    assert good.last_fallbacks == 0


@pytest.mark.parametrize("mode", ["flat", "nagata"])
def test_moving_tool_equals_static_tool_at_moved_position(mode):
    V, T = tm.structured_cylinder(1.0, 2.0, 12, 4, capped=True)
    motion = dict(velocity=(0.3, -0.2, 0.5), angular_velocity=0.7, axis_point=(0.5, 0.0, 0.2),
                  axis=(1.0, 1.0, 0.3))
    tool = FacetedTool(V, T, mode=mode, **motion)
    t = 1.3
    Vt = tool.motion.from_reference(V, t)
    static = FacetedTool(Vt, T, mode=mode)
    rng = np.random.default_rng(10)
    X = tool.motion.from_reference(rng.uniform(-1.4, 1.4, (200, 3)), t)
    a, b = tool.project(X, t), static.project(X)
    np.testing.assert_allclose(a.gap, b.gap, atol=1e-10)
    np.testing.assert_allclose(a.normal, b.normal, atol=1e-9)
    np.testing.assert_allclose(a.point, b.point, atol=1e-10)
    scale = np.maximum(1, np.abs(b.hessian).max(axis=(1, 2)))[:, None, None]
    np.testing.assert_allclose(a.hessian / scale, b.hessian / scale, atol=1e-8)
    # tool velocity at the contact points: rigid-body field
    v = tool.velocity(a.point, t)
    w = tool.motion.angular_velocity * np.asarray(motion["axis"]) / np.linalg.norm(motion["axis"])
    np.testing.assert_allclose(
        v, motion["velocity"] + np.cross(w, a.point - tool.motion.axis_point_at(t)), atol=1e-12)


@pytest.mark.parametrize("mode", ["flat", "nagata"])
def test_far_points_exact(mode, sphere80):
    V, T = sphere80
    tool = FacetedTool(V, T, mode=mode)
    rng = np.random.default_rng(11)
    X = rng.normal(size=(50, 3))
    X *= rng.uniform(5, 500, (50, 1)) / np.linalg.norm(X, axis=1, keepdims=True)
    X = np.vstack([X, [[0.0, 0.0, 0.0], [0.01, -0.02, 0.03]]])  # deep inside too
    pr = tool.project(X)
    ptr, idx = all_candidates(len(X), len(T))
    ref = (nagata_project_ref if mode == "nagata" else flat_project_ref)(tool, X, ptr, idx)
    np.testing.assert_allclose(pr.gap, ref[0], rtol=1e-13, atol=1e-13)
    assert np.all(pr.gap[:50] > 0) and np.all(pr.gap[50:] < 0)


def test_empty_and_single_point(sphere80):
    tool = FacetedTool(*sphere80)
    pr = tool.project(np.zeros((0, 3)))
    assert len(pr) == 0 and pr.hessian.shape == (0, 3, 3)
    pr = tool.project([0.0, 0.0, 2.0], hessian=False)
    assert len(pr) == 1 and pr.hessian is None and pr.gap[0] > 0.9
    assert "FacetedTool" in repr(tool)


@pytest.mark.slow
def test_large_tool_runs():
    """10^5 triangles, 10^4 points near the surface (nothing timed: the projection throughput
    is a benchmark figure, ``benchmarks/bench_projection_faceted.py``)."""
    V, T = tm.structured_cylinder(5.0, 40.0, 250, 200)
    assert T.shape[0] == 100_000
    tool = FacetedTool(V, T)
    rng = np.random.default_rng(12)
    th = rng.uniform(0, 2 * np.pi, 10_000)
    z = rng.uniform(-19, 19, 10_000)
    r = 5 + rng.uniform(-0.05, 0.05, 10_000)
    X = np.stack([r * np.cos(th), r * np.sin(th), z], axis=1)
    pr = tool.project(X)
    assert pr.flag.sum() == 0
    np.testing.assert_allclose(pr.gap, r - 5, atol=1e-6)


# ------------------------------------------------------------------------------------------
# files and gmsh builders
# ------------------------------------------------------------------------------------------


@pytest.mark.parametrize("ext", [".msh", ".stl", ".obj"])
def test_from_file_roundtrip(tmp_path, ext, sphere80):
    V, T = sphere80
    path = tm.write_surface(str(tmp_path / f"sphere{ext}"), V, T)
    tool = FacetedTool.from_file(path, mode="flat")
    assert tool.name == f"sphere{ext}" and tool.triangles.shape == T.shape
    X = np.random.default_rng(13).normal(size=(30, 3))
    ref = FacetedTool(V, T, mode="flat").project(X)
    tol = 1e-6 if ext == ".stl" else 1e-12  # binary STL stores float32
    np.testing.assert_allclose(tool.project(X).gap, ref.gap, atol=tol)
    Vr, Tr = read_surface(path)
    assert Tr.shape == T.shape


def test_gmsh_builders_and_main(tmp_path):
    V, T = tm.cylinder_surface(radius=5.0, length=10.0, facet_size=1.7)
    tool = FacetedTool(V, T, mode="flat")
    assert tool.closed
    rho = np.hypot(V[:, 0], V[:, 1])
    on_lateral = np.isclose(rho, 5.0, atol=1e-9)
    on_caps = np.isclose(np.abs(V[:, 2]), 5.0, atol=1e-9) & (rho <= 5.0 + 1e-9)
    assert np.all(on_lateral | on_caps)
    n_around = np.sum(on_lateral & np.isclose(V[:, 2], 5.0))
    assert 16 <= n_around <= 22  # ~2π·5/1.7 ≈ 18 facets per turn (thesis coarse tool)
    # the thesis's coarse tool, smoothed: about an order of magnitude closer than the facets
    smooth = FacetedTool(V, T)
    rims = np.isclose(np.abs(V[:, 2]), 5.0) & on_lateral
    assert np.all(smooth.vertex_class[rims] == 2) and np.all(smooth.vertex_class[~rims] == 1)
    sdf = lambda X: capped_cylinder_sdf(X, 5.0, 10.0)  # noqa: E731
    err_flat = np.max(np.abs(sdf(flat_samples(smooth))))
    err_nag = np.max(np.abs(sdf(patch_samples(smooth))))
    assert err_nag * 8 < err_flat
    Vs, Ts = tm.sphere_surface(radius=2.0, facet_size=0.8)
    assert FacetedTool(Vs, Ts, mode="flat").closed
    np.testing.assert_allclose(np.linalg.norm(Vs, axis=1), 2.0, atol=1e-9)
    tm.main([str(tmp_path), "--length", "4", "--fine", "1.0"])
    for label in ("coarse", "fine"):
        for ext in (".msh", ".stl"):
            t = FacetedTool.from_file(str(tmp_path / f"cylinder_R5_{label}{ext}"), mode="flat")
            assert t.closed
