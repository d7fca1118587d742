"""Mesh health: the shape quality of known simplices, the per-increment history columns against a
homogeneous compression, and an inverting velocity field caught before the geometry moves."""

import re

import numpy as np
import pytest
from mpi4py import MPI

import dolfinx

from fxcontact.materials import NortonHoff
from fxcontact import compat
from fxcontact.mesh_health import overlapping_facets, simplex_measures
from fxcontact.simulation import MeshInversionError, Simulation
from fxcontact.newton.solver import SolverOptions
from fxcontact.spaces import MixedSpace

from helpers import box_mesh


def test_simplex_measures_of_known_shapes():
    s3 = np.sqrt(3.0)
    regular_tet = np.array([[1, -1, -1], [1, 1, 1], [-1, 1, -1], [-1, -1, 1]], float)
    corner_tet = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float)
    flat_tet = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]], float)
    tri = np.array([[0, 0], [1, 0], [0.5, s3 / 2]])
    vol, q = simplex_measures(np.stack([regular_tet, corner_tet, flat_tet,
                                        corner_tet[[1, 0, 2, 3]]]))
    # regular tetrahedron of edge 2√2: V = a³/(6√2) = 8/3, q = 1
    assert vol[0] == pytest.approx(8.0 / 3.0, rel=1e-14) and q[0] == pytest.approx(1.0, rel=1e-14)
    # corner tetrahedron: V = 1/6, Σl² = 3·1 + 3·2 = 9, q = 12 (1/2)^(2/3) / 9
    assert vol[1] == pytest.approx(1.0 / 6.0, rel=1e-14)
    assert q[1] == pytest.approx(12.0 * 0.5 ** (2.0 / 3.0) / 9.0, rel=1e-14)
    assert vol[2] == 0.0 and q[2] == 0.0
    # swapping two vertices turns it inside out: the signed volume changes sign, q does not
    assert vol[3] == pytest.approx(-1.0 / 6.0, rel=1e-14) and q[3] == pytest.approx(q[1])
    vol, q = simplex_measures(tri[None])
    assert vol[0] == pytest.approx(s3 / 4, rel=1e-14) and q[0] == pytest.approx(1.0, rel=1e-14)
    with pytest.raises(ValueError, match="simplex"):
        simplex_measures(np.zeros((2, 3, 3)))


def _faces(msh):
    loc = dolfinx.mesh.locate_entities_boundary
    return {k: loc(msh, 2, (lambda c, v: (lambda x: np.isclose(x[c], v)))(c, v))
            for k, (c, v) in {"x0": (0, 0.0), "y0": (1, 0.0), "z0": (2, 0.0),
                              "z1": (2, 1.0)}.items()}


def _compressed_cube(n=(3, 3, 3), perturb=0.1, **kw):
    msh = box_mesh(MPI.COMM_WORLD, (1.0, 1.0, 1.0), n, perturb=perturb)
    sim = Simulation(MixedSpace(msh), NortonHoff(K=10.0, m=0.3, regularization=1e-8),
                     progress=False, **kw)
    f = _faces(msh)
    for key, comp in (("x0", 0), ("y0", 1), ("z0", 2)):
        sim.add_velocity_bc(f[key], 0.0, comp)
    sim.add_velocity_bc(f["z1"], -0.1, 2)
    return sim


def test_history_records_the_mesh_health_of_a_homogeneous_compression():
    """Sliding plates: the deformation is homogeneous, so every cell's volume changes by
    det(I + dt ∇v) = (1 + ε/2)²(1 − ε) per increment, ε = 0.1 dt / H (H the current height)
    (without the volume correction, which would give the lost volume back)."""
    sim = _compressed_cube(volume_correction="none")
    q0 = sim.mesh_health()["min_quality"]
    dt, H, ratio = 0.5, 1.0, 1.0
    for _ in range(4):
        row = sim.step(dt).row
        eps = 0.1 * dt / H
        ratio *= (1 + eps / 2) ** 2 * (1 - eps)
        H *= 1 - eps
        assert row["min_volume_ratio"] == pytest.approx(ratio, rel=1e-8)
        assert 0.0 < row["min_quality"] <= 1.0
    # squashing flattens the cells: the worst quality falls
    assert sim.history[-1]["min_quality"] < q0


def _inject(sim, amplitude, scale_with_dt):
    """Wrap the Newton solve: the converged velocity gets an extra velocity at the vertex at the
    centre of the cube, large enough to push it through the opposite faces of its cells."""
    sp = sim.space
    sim._build()
    x0 = sim._x_ref[sp.vertex_geometry, :3]   # initial positions
    centre = np.flatnonzero(np.all(np.isclose(x0, 0.5), axis=1))
    assert MPI.COMM_WORLD.allreduce(len(centre), op=MPI.SUM) >= 1
    solve = sim.solver.solve

    def wrapped():
        info = solve()
        dt = float(sim.dt_c.value)
        sim.w.x.array[sp.vertex_dofs[centre, 0]] += amplitude * (dt if scale_with_dt else 1 / dt)
        return info

    sim.solver.solve = wrapped


def test_inverting_velocity_stops_with_where_and_when():
    sim = _compressed_cube(n=(4, 4, 4), perturb=0.0)
    sim.step(0.1)
    x_before = sim.vertex_positions().copy()
    _inject(sim, 0.6, scale_with_dt=False)   # the centre moves by 0.6 whatever dt is
    with pytest.raises(MeshInversionError) as e:
        sim.step(0.1, max_cutbacks=2)
    msg = str(e.value)
    assert "element inverted" in msg and "increment 2" in msg and "t = 0.1" in msg
    assert "reduce dt or remesh" in msg
    c = np.array([float(v) for v in re.search(r"centroid \[([^\]]*)\]", msg).group(1).split()])
    # the inverted cell is one of the cells around the centre (mesh size 0.25)
    assert np.linalg.norm(c - 0.5) < 0.25
    # nothing was accepted: the geometry and the history are those of increment 1
    assert len(sim.history) == 1 and sim.increment == 1
    assert np.array_equal(sim.vertex_positions(), x_before)


def test_inversion_is_cut_back_when_a_smaller_step_cures_it():
    sim = _compressed_cube(n=(4, 4, 4), perturb=0.0)
    _inject(sim, 3.0, scale_with_dt=True)    # the centre moves by 3 dt²
    row = sim.step(0.4, max_cutbacks=3).row  # 0.48 inverts; 0.12 after one cut-back does not
    assert row["cutbacks"] == 1 and row["min_volume_ratio"] > 0.0
    # the check can be switched off: the same step is then accepted with an inverted cell
    sim2 = _compressed_cube(n=(4, 4, 4), perturb=0.0, check_inversion=False)
    _inject(sim2, 3.0, scale_with_dt=True)
    row = sim2.step(0.4, max_cutbacks=3).row
    assert row["cutbacks"] == 0 and row["min_volume_ratio"] < 0.0 and row["min_quality"] < 0.0


def test_degenerate_mesh_is_refused():
    msh = box_mesh(MPI.COMM_WORLD, n=(2, 2, 2))
    x = msh.geometry.x
    x[np.isclose(x[:, 2], 1.0), 2] = 0.5     # top layer onto the middle one: flat cells
    with pytest.raises(ValueError, match="degenerate"):
        Simulation(MixedSpace(msh), NortonHoff(1.0, 0.2), progress=False)


def test_overlapping_facets_of_two_triangles():
    """Two triangles sharing the edge (0, 1): apart whatever their vertex order (signs of both
    kinds are normal), overlapping once the third vertex of one crosses the edge."""
    X = np.array([[0.0, 0.0], [1.0, 0.0], [0.5, 1.0], [0.5, -1.0]])
    facet, pair = np.array([[0, 1]]), np.array([[0, 1]])
    for cells in ([[0, 1, 2], [0, 1, 3]], [[0, 1, 2], [1, 0, 3]], [[2, 1, 0], [3, 0, 1]]):
        assert not overlapping_facets(X, np.array(cells), facet, pair)[0]
    X[3, 1] = 0.5                              # both on the same side: tangled
    assert overlapping_facets(X, np.array([[0, 1, 2], [1, 0, 3]]), facet, pair)[0]


def test_valid_meshes_of_both_orientations_are_accepted():
    """dolfinx's unit square holds triangles of both signs: a valid mesh, accepted; its mirror
    image too (every sign turned)."""
    msh = dolfinx.mesh.create_unit_square(MPI.COMM_WORLD, 4, 4)
    sp = MixedSpace(msh)
    vol, _ = simplex_measures(sp.vertex_positions()[compat.cell_vertices(msh)])
    signs = {int(v) for vs in MPI.COMM_WORLD.allgather(np.sign(vol).tolist()) for v in vs}
    assert signs == {-1, 1}
    Simulation(sp, NortonHoff(1.0, 0.2), progress=False)
    msh.geometry.x[:, 0] *= -1.0
    Simulation(MixedSpace(msh), NortonHoff(1.0, 0.2), progress=False)
