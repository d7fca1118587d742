"""gmsh builders: isolation of gmsh options between builders and from a caller's session."""

from mpi4py import MPI

from fxcontact.meshing import block, cylinder_billet, gmsh_session

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
