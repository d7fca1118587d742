"""Nodal normals, Normal Vector Voting and crease-preserving normals (THEORY §8)."""

import math

import numpy as np
import pytest

from fxcontact.tools.normals import (
    CORNER,
    CREASE,
    SURFACE,
    LOCAL_EDGES,
    crease_epsilon,
    edge_topology,
    facet_normals,
    facet_vertex_normals,
    normal_vector_voting,
    unique_rows,
    vertex_normals,
)



from fxcontact.tools import surfaces as tm  # noqa: E402


def _cube_vertex_kind(V, half=0.5):
    """0 = face interior, 1 = cube edge, 2 = cube corner (number of coordinates at ±half - 1)."""
    return np.sum(np.isclose(np.abs(V), half), axis=1) - 1


def test_topology_neighbors_consistent():
    V, T = tm.icosphere(1)
    topo = edge_topology(T)
    assert topo.is_closed and topo.edges.shape[0] == 120
    for f in range(T.shape[0]):
        for k in range(3):
            g, kg = topo.neighbor[f, k], topo.neighbor_edge[f, k]
            assert topo.neighbor[g, kg] == f
            assert set(T[f, LOCAL_EDGES[k]]) == set(T[g, LOCAL_EDGES[kg]])


def test_unique_rows_matches_numpy():
    rng = np.random.default_rng(0)
    a = rng.integers(0, 7, size=(500, 3))
    u, inv, cnt = unique_rows(a, return_inverse=True, return_counts=True)
    u2, inv2, cnt2 = np.unique(a, axis=0, return_inverse=True, return_counts=True)
    np.testing.assert_array_equal(u, u2)
    np.testing.assert_array_equal(inv, inv2.reshape(-1))
    np.testing.assert_array_equal(cnt, cnt2)


@pytest.mark.parametrize("weighting", ["angle", "area"])
def test_weighted_normals_on_symmetric_meshes(weighting):
    V, T = tm.icosphere(2)
    n = vertex_normals(V, T, weighting)
    # icosphere: close to radial, but not exactly (irregular valences)
    assert np.max(np.linalg.norm(n - V, axis=1)) < 3e-2
    # cylinder fans are symmetric: exact (THEORY §8.1)
    V, T = tm.structured_cylinder(1.0, 2.0, 12, 4)
    n = vertex_normals(V, T, weighting)
    inner = np.abs(V[:, 2]) < 0.99
    radial = V[inner] * np.array([1.0, 1.0, 0.0])
    np.testing.assert_allclose(n[inner], radial, atol=1e-12)


def test_crease_epsilon_values():
    # THEORY §8.2: φc = 30° → 12.9, 40° → 6.55, 60° → 2
    assert crease_epsilon(math.radians(30)) == pytest.approx(12.93, abs=0.01)
    assert crease_epsilon(math.radians(40)) == pytest.approx(6.55, abs=0.01)
    assert crease_epsilon(math.radians(60)) == pytest.approx(2.0, abs=1e-12)
    with pytest.raises(ValueError):
        crease_epsilon(math.radians(95))


@pytest.mark.parametrize("phic", [40.0, 50.0])
def test_nvv_classifies_cube(phic):
    V, T = tm.box_surface(n=3)
    nvv = normal_vector_voting(V, T, math.radians(phic))
    kind = _cube_vertex_kind(V)
    assert np.sum(kind == 2) == 8
    assert np.all(nvv.vertex_class[kind == 2] == CORNER)
    assert np.all(nvv.vertex_class[kind == 1] == CREASE)
    assert np.all(nvv.vertex_class[kind == 0] == SURFACE)
    # e3 along the cube edge: the coordinate that is not at ±1/2
    edge = np.flatnonzero(kind == 1)
    along = ~np.isclose(np.abs(V[edge]), 0.5)
    e3 = nvv.e3[edge]
    np.testing.assert_allclose(np.abs(e3[along]), 1.0, atol=1e-12)
    # face vertices: e1 is the face normal, oriented outward
    face = np.flatnonzero(kind == 0)
    np.testing.assert_allclose(nvv.normal[face], 2 * V[face] * np.isclose(np.abs(V[face]), 0.5),
                               atol=1e-12)


def test_cube_crease_preserving_normals_are_facet_normals():
    V, T = tm.box_surface(n=3)
    fvn = facet_vertex_normals(V, T, "nvv", math.radians(50))
    nf, _ = facet_normals(V, T)
    np.testing.assert_allclose(fvn.normals, np.repeat(nf[:, None], 3, axis=1), atol=1e-12)
    # crease edges = the 12 cube edges, 3 mesh edges each
    assert fvn.crease_edges.shape[0] == 36
    mid = 0.5 * (V[fvn.crease_edges[:, 0]] + V[fvn.crease_edges[:, 1]])
    assert np.all(_cube_vertex_kind(mid) >= 1)


@pytest.mark.parametrize("n_theta, rows", [(8, 3), (12, 6), (16, 9)])
def test_nvv_capped_cylinder_rims_only(n_theta, rows):
    V, T = tm.structured_cylinder(1.0, 2.0, n_theta, rows, capped=True)
    fvn = facet_vertex_normals(V, T, "nvv", math.radians(50))
    rim = np.isclose(np.abs(V[:, 2]), 1.0) & (np.hypot(V[:, 0], V[:, 1]) > 0.5)
    assert np.all(fvn.vertex_class[rim] == CREASE)
    assert np.all(fvn.vertex_class[~rim] == SURFACE)
    # crease edges: exactly the two rim polygons
    assert fvn.crease_edges.shape[0] == 2 * n_theta
    assert np.all(rim[fvn.crease_edges])
    # crease tangent = exact circle tangent (polyline refinement), side normals exact
    t_exact = np.stack([-V[rim, 1], V[rim, 0], 0 * V[rim, 0]], axis=1)
    np.testing.assert_allclose(np.abs(np.einsum("ij,ij->i", fvn.crease_tangent[rim], t_exact)),
                               1.0, atol=1e-12)
    f, a = np.nonzero(rim[T])
    n = fvn.normals[f, a]
    cap = np.abs(n[:, 2]) > 0.5
    np.testing.assert_allclose(n[cap], np.sign(V[T[f[cap], a[cap]], 2])[:, None] * [0, 0, 1],
                               atol=1e-12)
    radial = V[T[f[~cap], a[~cap]]] * [1, 1, 0]
    np.testing.assert_allclose(n[~cap], radial, atol=1e-12)


def test_nvv_crease_angle_too_small_flags_coarse_cylinder():
    # THEORY §8.2: on an 8-gon (45° between facets) φc = 40° flags every lateral vertex
    V, T = tm.structured_cylinder(1.0, 2.0, 8, 3, capped=True)
    nvv = normal_vector_voting(V, T, math.radians(40))
    lateral = np.hypot(V[:, 0], V[:, 1]) > 0.5
    assert np.all(nvv.vertex_class[lateral] >= CREASE)
    nvv = normal_vector_voting(V, T, None)
    assert np.all(nvv.vertex_class == SURFACE)


def test_nvv_sphere_normals_close_to_exact():
    V, T = tm.icosphere(2)
    nvv = normal_vector_voting(V, T, math.radians(50))
    assert np.all(nvv.vertex_class == SURFACE)
    assert np.max(np.linalg.norm(nvv.normal - V, axis=1)) < 2e-2
    assert np.all(nvv.eigenvalues[:, 0] >= nvv.eigenvalues[:, 1])


def test_facet_vertex_normals_array_input():
    V, T = tm.icosphere(1)
    fvn = facet_vertex_normals(V, T, 2.0 * V)  # (N, 3), normalised
    np.testing.assert_allclose(fvn.normals, V[T], atol=1e-15)
    fvn = facet_vertex_normals(V, T, V[T])  # (M, 3, 3)
    assert fvn.method == "array" and not fvn.crease.any()
    with pytest.raises(ValueError, match="shape"):
        facet_vertex_normals(V, T, V[:5])
    bad = V.copy()
    bad[3] = 0.0
    with pytest.raises(ValueError, match="zero or non-finite"):
        facet_vertex_normals(V, T, bad)
    with pytest.raises(ValueError, match="unknown normals method"):
        facet_vertex_normals(V, T, "magic")
