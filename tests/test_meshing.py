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


# ------------------------------------------------------------------ drawing bar
import numpy as np  # noqa: E402
import pytest  # noqa: E402
import ufl  # noqa: E402

import dolfinx  # noqa: E402

from fxcontact import compat  # noqa: E402

from fxcontact.meshing import DRAWING_BAR_TAGS, drawing_bar, sector_plane_normals  # noqa: E402

BAR = dict(radius=5.0, length=14.0, h=1.5, nose_length=4.0, nose_radius=3.5, nose_angle=30.0)


def _bar_volume(radius, length, nose_length, nose_radius, nose_angle, sector=None, **_):
    """Analytic volume: cylinder + cone frustum + nose cylinder, times the sector fraction."""
    L_tr = (radius - nose_radius) / np.tan(np.radians(nose_angle))
    z_body = length - nose_length - L_tr
    V = np.pi * (radius**2 * z_body + L_tr / 3.0 * (radius**2 + radius * nose_radius
                                                    + nose_radius**2)
                 + nose_radius**2 * nose_length)
    return V * (1.0 if sector is None else sector / 360.0)


@pytest.mark.parametrize("sector", [None, 120.0, 90.0])
def test_drawing_bar_volume_and_tags(sector):
    """The mesh volume is the analytic volume of the bar (or its sector) minus the inscribed-
    polygon defect of the round surfaces, 0 < 1 − V_h/V < (h/r_min)²/6 (chord of an edge ≤ h on
    the smallest radius); the tags are those documented and the symmetry faces lie on their
    planes (x·n = 0 with the outward normals of ``sector_plane_normals``)."""
    comm = MPI.COMM_WORLD
    msh, _, ft = drawing_bar(comm, sector=sector, **BAR)
    V = comm.allreduce(dolfinx.fem.assemble_scalar(dolfinx.fem.form(
        dolfinx.fem.Constant(msh, 1.0) * ufl.dx(domain=msh))), op=MPI.SUM)
    Va = _bar_volume(sector=sector, **BAR)
    defect = 1.0 - V / Va
    assert 0.0 < defect < (BAR["h"] / BAR["nose_radius"]) ** 2 / 6.0, defect
    present = set(np.concatenate(comm.allgather(np.unique(ft.values))).tolist())
    expected = {"back", "front", "lateral"} | ({"symmetry_0", "symmetry_1"} if sector else set())
    assert present == {DRAWING_BAR_TAGS[k] for k in expected}
    msh.topology.create_connectivity(2, 0)
    f2v = msh.topology.connectivity(2, 0)
    x = msh.geometry.x

    def face_vertices(tag):
        f = ft.indices[ft.values == DRAWING_BAR_TAGS[tag]]
        if not len(f):
            return np.zeros(0, dtype=np.int32)
        v = np.unique(np.concatenate([f2v.links(i) for i in f])).astype(np.int32)
        return compat.entities_to_geometry(msh, 0, v).ravel()

    assert np.all(np.abs(x[face_vertices("back"), 2]) < 1e-12)
    assert np.all(np.abs(x[face_vertices("front"), 2] - BAR["length"]) < 1e-12)
    rf = np.hypot(x[face_vertices("front"), 0], x[face_vertices("front"), 1])
    assert np.all(rf <= BAR["nose_radius"] + 1e-9)
    if sector:
        normals = sector_plane_normals(sector)
        for tag in ("symmetry_0", "symmetry_1"):
            assert np.all(np.abs(x[face_vertices(tag)] @ normals[tag]) < 1e-9), tag
        # every vertex inside the sector: x·n ≤ 0 for both outward normals
        for n in normals.values():
            assert np.all(x @ n <= 1e-9)


def test_drawing_bar_sector_is_a_fraction_of_the_whole():
    """A third and a quarter hold a third and a quarter of the whole bar's volume (the same
    polygon defect bound)."""
    comm = MPI.COMM_WORLD

    def vol(sector):
        msh = drawing_bar(comm, sector=sector, **BAR)[0]
        return comm.allreduce(dolfinx.fem.assemble_scalar(dolfinx.fem.form(
            dolfinx.fem.Constant(msh, 1.0) * ufl.dx(domain=msh))), op=MPI.SUM)

    V = vol(None)
    tol = (BAR["h"] / BAR["nose_radius"]) ** 2 / 6.0
    for s in (120.0, 90.0):
        assert abs(vol(s) / (V * s / 360.0) - 1.0) < tol


def test_drawing_bar_plain_and_half():
    """Without a nose it is a plain cylinder (an upsetting billet); a half bar has one
    symmetry face, the plane y = 0."""
    comm = MPI.COMM_WORLD
    msh, _, ft = drawing_bar(comm, 4.0, 6.0, 2.0, sector=180.0)
    present = set(np.concatenate(comm.allgather(np.unique(ft.values))).tolist())
    assert present == {DRAWING_BAR_TAGS[k] for k in ("back", "front", "lateral", "symmetry_0")}
    V = comm.allreduce(dolfinx.fem.assemble_scalar(dolfinx.fem.form(
        dolfinx.fem.Constant(msh, 1.0) * ufl.dx(domain=msh))), op=MPI.SUM)
    assert 0 < 1 - V / (0.5 * np.pi * 16.0 * 6.0) < (2.0 / 4.0) ** 2 / 6.0
    n = sector_plane_normals(120.0)["symmetry_1"]
    assert np.allclose(n, [-np.sin(np.radians(120)), np.cos(np.radians(120)), 0.0])


@pytest.mark.parametrize("kwargs,match", [
    (dict(sector=0.0), "sector"), (dict(sector=360.0), "sector"), (dict(sector="a"), "sector"),
    (dict(nose_radius=5.0), "nose_radius"), (dict(nose_radius=None), "nose_radius"),
    (dict(nose_angle=0.0), "nose_angle"), (dict(nose_length=12.0), "shorter"),
    (dict(h=0.0), "h must"), (dict(nose_length=-1.0), "nose_length"),
])
def test_drawing_bar_bad_input(kwargs, match):
    with pytest.raises(ValueError, match=match):
        drawing_bar(MPI.COMM_WORLD, **{**BAR, **kwargs})
