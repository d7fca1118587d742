"""gmsh builders: isolation of gmsh options between builders and from a caller's session."""

import numpy as np
import pytest
import ufl
from mpi4py import MPI

import dolfinx.fem

from fxcontact.meshing import RING_TAGS, block, cylinder_billet, gmsh_session, ring


from fxcontact.tools import surfaces as tool_meshes  # noqa: E402


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


class _StrictGmsh:
    """A stand-in for gmsh 4.8's module (no ``isInitialized``) that fails on any call of its
    API while it is not initialised: the real one may then end the process with exit status 1
    and no message."""

    def __init__(self, initialized=False):
        import types
        self.initialized, self.calls = initialized, []
        self.opts = {}
        self.option = types.SimpleNamespace(
            getNumber=self._api("getNumber", self.opts.get),
            setNumber=self._api("setNumber", self.opts.__setitem__),
            getString=self._api("getString", lambda name: "4.8.0"))
        self.model = types.SimpleNamespace(add=self._api("add", lambda n: None),
                                           remove=self._api("remove", lambda: None))

    def _api(self, name, fn):
        def call(*args):
            self.calls.append(name)
            if not self.initialized:
                raise AssertionError(f"gmsh.{name} called before gmsh.initialize")
            return fn(*args)
        return call

    def initialize(self, *args, **kwargs):
        self.calls.append("initialize")
        if not self.initialized:
            from fxcontact.meshing import GMSH_MESH_DEFAULTS
            self.opts.update(GMSH_MESH_DEFAULTS)
        self.initialized = True

    def finalize(self):
        self._api("finalize", lambda: None)()
        self.initialized = False


@pytest.mark.parametrize("imported, initialized", [(False, False), (True, False), (True, True)])
def test_session_never_calls_gmsh_before_initialize(monkeypatch, imported, initialized):
    """gmsh_session calls nothing of gmsh's API before it is initialised, whether gmsh is
    imported first by fxcontact, imported by someone else (its state unknown), or open in a
    caller's session (which it leaves open, with the caller's options back)."""
    import sys
    fake = _StrictGmsh(initialized)
    if initialized:
        fake.initialize()
        fake.opts["Mesh.MeshSizeMax"] = 0.3
    if imported:
        monkeypatch.setitem(sys.modules, "gmsh", fake)
    else:
        monkeypatch.delitem(sys.modules, "gmsh", raising=False)
        import importlib.machinery

        class _Finder:   # the first ``import gmsh`` finds the stand-in
            def find_spec(self, name, path=None, target=None):
                if name != "gmsh":
                    return None
                loader = type("L", (), {"create_module": lambda _s, spec: fake,
                                        "exec_module": lambda _s, m: None})()
                return importlib.machinery.ModuleSpec("gmsh", loader)
        monkeypatch.setattr(sys, "meta_path", [_Finder()] + sys.meta_path)
    with gmsh_session("probe") as g:
        assert g is fake and fake.initialized
        g.option.setNumber("Mesh.MeshSizeMax", 2.0)
    assert fake.calls[0] == "initialize"
    # fxcontact's own session is closed again; a session it cannot tell from the caller's
    # (gmsh imported elsewhere) or the caller's own stays open with the caller's options
    assert fake.initialized == imported
    assert ("finalize" in fake.calls) == (not imported)
    if initialized:
        assert fake.opts["Mesh.MeshSizeMax"] == 0.3
    with gmsh_session("again"):    # followed from now on: no second initialize
        pass
    assert fake.calls.count("initialize") == (1 + initialized if imported else 2)


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
def _integral(msh, measure):
    return msh.comm.allreduce(dolfinx.fem.assemble_scalar(dolfinx.fem.form(
        1.0 * measure)), op=MPI.SUM)


@pytest.mark.parametrize("sector, plan, half", [("eighth", 0.25, 0.5), ("quarter", 0.25, 1.0),
                                                ("full", 1.0, 1.0), ("upper", 1.0, 0.5)])
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
    mid = sector in ("eighth", "upper")
    expected = {"top": annulus, "bottom": 0.0 if mid else annulus,
                "mid_plane": annulus if mid else 0.0,
                "outer": 2 * np.pi * Ro * H * fraction, "inner": 2 * np.pi * Ri * H * fraction,
                "symmetry_x": 0.0 if plan == 1.0 else (Ro - Ri) * H * half,
                "symmetry_y": 0.0 if plan == 1.0 else (Ro - Ri) * H * half}
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
    assert zmin == pytest.approx(0.0 if mid else -0.5 * H, abs=1e-12)


def test_ring_bad_input():
    with pytest.raises(ValueError, match="inner_radius"):
        ring(MPI.COMM_WORLD, 10.0, 12.0, 5.0, 1.0)
    with pytest.raises(ValueError, match="sector"):
        ring(MPI.COMM_WORLD, 10.0, 5.0, 5.0, 1.0, sector="half")
