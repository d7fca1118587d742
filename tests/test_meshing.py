"""gmsh builders: isolation of gmsh options between builders and from a caller's session."""

import numpy as np
import pytest
import ufl
from mpi4py import MPI

import dolfinx.fem

from fxcontact.meshing import RING_TAGS, block, cylinder_billet, gmsh_session, ring

from helpers import load_tool_meshes

tool_meshes = load_tool_meshes()


def _ncells(msh):
    return msh.topology.index_map(msh.topology.dim).size_global


def test_builders_do_not_leak_options():
    """A builder's mesh does not depend on which builders ran before it."""
    comm = MPI.COMM_WORLD
    n_ref = _ncells(block(comm, [0, 0], [1, 1], 0.1, dim=2)[0])
    cylinder_billet(comm, 1.0, 1.0, 0.5)          # sets a minimum size 0.25
    tool_meshes.sphere_surface(1.0, 0.5)          # sets MeshSizeMin/Max = 0.5
    assert _ncells(block(comm, [0, 0], [1, 1], 0.1, dim=2)[0]) == n_ref


def test_caller_session_is_restored():
    """Inside a caller's gmsh session: defaults for the builder, caller's options back after."""
    import gmsh

    comm = MPI.COMM_WORLD
    n_ref = _ncells(block(comm, [0, 0], [1, 1], 0.1, dim=2)[0])
    gmsh.initialize([], readConfigFiles=False)
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.model.add("caller")
        gmsh.option.setNumber("Mesh.MeshSizeMax", 0.3)
        gmsh.option.setNumber("Mesh.MeshSizeFactor", 4.0)
        assert _ncells(block(comm, [0, 0], [1, 1], 0.1, dim=2)[0]) == n_ref
        assert gmsh.option.getNumber("Mesh.MeshSizeMax") == 0.3
        assert gmsh.option.getNumber("Mesh.MeshSizeFactor") == 4.0
        assert gmsh.model.getCurrent() == "caller"
        with gmsh_session("inner") as g:
            assert g.option.getNumber("Mesh.MeshSizeFactor") == 1.0
    finally:
        gmsh.finalize()


def _integral(msh, measure):
    return msh.comm.allreduce(dolfinx.fem.assemble_scalar(dolfinx.fem.form(
        1.0 * measure)), op=MPI.SUM)


@pytest.mark.parametrize("sector, plan, half", [("eighth", 0.25, 0.5), ("quarter", 0.25, 1.0),
                                                ("full", 1.0, 1.0)])
def test_ring_volume_and_tags(sector, plan, half):
    """6:3:2 ring (R_o 30, R_i 15, H 20): volume and area of every tagged surface against the
    exact values (the circles are faceted: relative error of order h²/R_i² ≈ 1 %), and only the
    surfaces the model has are tagged."""
    Ro, Ri, H, h = 30.0, 15.0, 20.0, 3.0
    msh, _, ft = ring(MPI.COMM_WORLD, Ro, Ri, H, h, sector=sector)
    ds = ufl.Measure("ds", domain=msh, subdomain_data=ft)
    V = _integral(msh, ufl.dx(msh))
    # plan: fraction of the annulus; half: fraction of the height
    fraction = plan * half
    assert V == pytest.approx(fraction * np.pi * (Ro ** 2 - Ri ** 2) * H, rel=1e-2)
    annulus = np.pi * (Ro ** 2 - Ri ** 2) * plan
    expected = {"top": annulus, "bottom": 0.0 if sector == "eighth" else annulus,
                "mid_plane": annulus if sector == "eighth" else 0.0,
                "outer": 2 * np.pi * Ro * H * fraction, "inner": 2 * np.pi * Ri * H * fraction,
                "symmetry_x": 0.0 if sector == "full" else (Ro - Ri) * H * half,
                "symmetry_y": 0.0 if sector == "full" else (Ro - Ri) * H * half}
    for name, tag in RING_TAGS.items():
        area = _integral(msh, ds(tag))
        if expected[name] == 0.0:
            assert area == 0.0, name
        else:
            assert area == pytest.approx(expected[name], rel=1e-2), name
    # every exterior facet is tagged
    total = _integral(msh, ufl.ds(msh))
    assert total == pytest.approx(sum(_integral(msh, ds(t)) for t in RING_TAGS.values()),
                                  rel=1e-12)
    x = msh.geometry.x
    zmin = msh.comm.allreduce(np.min(x[:, 2]), op=MPI.MIN)
    assert zmin == pytest.approx(0.0 if sector == "eighth" else -0.5 * H, abs=1e-12)


def test_ring_bad_input():
    with pytest.raises(ValueError, match="inner_radius"):
        ring(MPI.COMM_WORLD, 10.0, 12.0, 5.0, 1.0)
    with pytest.raises(ValueError, match="sector"):
        ring(MPI.COMM_WORLD, 10.0, 5.0, 5.0, 1.0, sector="half")
