"""gmsh builders for workpieces. Each builder creates a gmsh model on rank 0 and distributes it.

The facet tags use the names documented by each builder. Every builder runs in
:func:`gmsh_session`, so gmsh options never leak from one builder to another.
"""

from __future__ import annotations

import contextlib
import logging
from typing import Dict

import dolfinx.mesh
import numpy as np
import ufl
from mpi4py import MPI
from scipy.spatial import cKDTree

from fxcontact import compat

__all__ = ["cylinder_billet", "ring", "structured_ring", "block", "drawing_bar", "sector_plane_normals",
           "gmsh_session", "BILLET_TAGS", "RING_TAGS", "RING_SECTORS", "BLOCK_TAGS",
           "DRAWING_BAR_TAGS", "GMSH_MESH_DEFAULTS", "gmsh_model_mesh"]

log = logging.getLogger(__name__)

#: facet tags of :func:`cylinder_billet`
BILLET_TAGS: Dict[str, int] = {"bottom": 1, "top": 2, "lateral": 3, "symmetry_x": 4,
                               "symmetry_y": 5}
#: facet tags of :func:`drawing_bar`: ``back`` (z = 0), ``front`` (z = length, the pulled end
#: of the nose), ``lateral`` (bar, conical transition and nose surfaces), ``symmetry_0`` (the
#: half-plane θ = 0, i.e. y = 0, x ≥ 0) and ``symmetry_1`` (the half-plane θ = sector) of a sector
DRAWING_BAR_TAGS: Dict[str, int] = {"back": 1, "front": 2, "lateral": 3, "symmetry_0": 4,
                                    "symmetry_1": 5}
#: facet tags of :func:`ring`: the die faces ``top`` (z = +H/2) and ``bottom`` (z = −H/2),
#: the ``mid_plane`` z = 0 of the ``"eighth"`` model (instead of ``bottom``), the ``outer`` and
#: ``inner`` (bore) lateral surfaces, and the symmetry planes x = 0 and y = 0 of the
#: ``"eighth"`` and ``"quarter"`` models
RING_TAGS: Dict[str, int] = {"top": 1, "bottom": 2, "outer": 3, "inner": 4, "symmetry_x": 5,
                             "symmetry_y": 6, "mid_plane": 7}
#: models of :func:`ring`: extent in plan and in height
RING_SECTORS = ("eighth", "quarter", "full", "upper")
#: facet tags of :func:`block`
BLOCK_TAGS: Dict[str, int] = {"xmin": 1, "xmax": 2, "ymin": 3, "ymax": 4, "zmin": 5, "zmax": 6}


#: gmsh options a builder may change, with gmsh's defaults; they are reset on entry to
#: :func:`gmsh_session` and restored on exit when gmsh was already initialised by the caller.
GMSH_MESH_DEFAULTS: Dict[str, float] = {
    "Mesh.MeshSizeMin": 0.0, "Mesh.MeshSizeMax": 1e22, "Mesh.MeshSizeFactor": 1.0,
    "Mesh.MeshSizeFromPoints": 1.0, "Mesh.MeshSizeFromCurvature": 0.0,
    "Mesh.MeshSizeExtendFromBoundary": 1.0, "Mesh.MeshSizeFromParametricPoints": 0.0,
    "Mesh.Algorithm": 6.0, "Mesh.Algorithm3D": 1.0, "Mesh.ElementOrder": 1.0,
    "Mesh.Optimize": 1.0, "Mesh.OptimizeNetgen": 0.0, "Mesh.RecombineAll": 0.0,
    "Mesh.MinimumCirclePoints": 7.0, "General.Terminal": 1.0,
}


@contextlib.contextmanager
def gmsh_session(name: str):
    """A fresh gmsh model with default meshing options, isolated from other gmsh users.

    If gmsh is not initialised it is initialised here and finalised on exit, so nothing
    (mesh-size options, fields) leaks from one builder to the next. If the caller already
    initialised gmsh (or may have: gmsh imported before fxcontact could follow it, see
    :func:`fxcontact.compat.gmsh_initialized`), the options of :data:`GMSH_MESH_DEFAULTS` are
    reset to gmsh's defaults for the block and restored afterwards, and only the model created
    here is removed.
    """
    gmsh = compat.import_gmsh()
    state = compat.gmsh_initialized(gmsh)
    owned = state is False
    saved = None
    if state is not True:   # (None: does nothing if the caller's session is open)
        gmsh.initialize([], readConfigFiles=False)
    if not owned:
        saved = {k: gmsh.option.getNumber(k) for k in GMSH_MESH_DEFAULTS}
        for k, v in GMSH_MESH_DEFAULTS.items():
            gmsh.option.setNumber(k, v)
    gmsh.option.setNumber("General.Terminal", 0)
    gmsh.model.add(name)
    try:
        yield gmsh
    finally:
        if owned:
            gmsh.finalize()
        else:
            gmsh.model.remove()
            for k, v in saved.items():
                gmsh.option.setNumber(k, v)


def gmsh_model_mesh(gmsh, comm, gdim):
    """``(mesh, cell_tags, facet_tags)`` of the current gmsh model (rank 0's), distributed
    over ``comm``, with ``gdim`` coordinates (inside :func:`gmsh_session`)."""
    return compat.model_to_mesh(gmsh.model, comm, 0, gdim=gdim)


def cylinder_billet(comm: MPI.Comm, radius: float, height: float, h: float,
                    quarter: bool = True):
    """Tetrahedral cylinder along z, base at z = 0; a quarter (x ≥ 0, y ≥ 0) by default.

    Returns ``(mesh, cell_tags, facet_tags)`` with facet tags :data:`BILLET_TAGS`.
    """
    if not (radius > 0 and height > 0 and h > 0):
        raise ValueError("radius, height and h must be > 0")
    with gmsh_session("billet") as gmsh:
        if comm.rank == 0:
            occ = gmsh.model.occ
            cyl = occ.addCylinder(0, 0, 0, 0, 0, height, radius)
            if quarter:
                box = occ.addBox(0, 0, -1, 2 * radius, 2 * radius, height + 2)
                occ.intersect([(3, cyl)], [(3, box)])
            occ.synchronize()
            vols = gmsh.model.getEntities(3)
            gmsh.model.addPhysicalGroup(3, [v[1] for v in vols], 1)
            groups = {k: [] for k in BILLET_TAGS}
            eps = 1e-6 * max(radius, height)
            for dim, tag in gmsh.model.getEntities(2):
                c = np.array(gmsh.model.occ.getCenterOfMass(dim, tag))
                if abs(c[2]) < eps:
                    groups["bottom"].append(tag)
                elif abs(c[2] - height) < eps:
                    groups["top"].append(tag)
                elif quarter and abs(c[0]) < eps:
                    groups["symmetry_x"].append(tag)
                elif quarter and abs(c[1]) < eps:
                    groups["symmetry_y"].append(tag)
                else:
                    groups["lateral"].append(tag)
            for name, tags in groups.items():
                if tags:
                    gmsh.model.addPhysicalGroup(2, tags, BILLET_TAGS[name])
            gmsh.option.setNumber("Mesh.CharacteristicLengthMax", h)
            gmsh.option.setNumber("Mesh.CharacteristicLengthMin", 0.5 * h)
            gmsh.model.mesh.generate(3)
        return gmsh_model_mesh(gmsh, comm, 3)


def ring(comm: MPI.Comm, outer_radius: float, inner_radius: float, height: float, h: float,
         sector: str = "eighth"):
    """Tetrahedral ring along z, centred on the origin (the mid-plane is z = 0).

    Args:
        outer_radius, inner_radius, height: the ring (0 < inner < outer; e.g. 30, 15, 20 for the
            6:3:2 ring of the ring-compression test).
        h: element size.
        sector: ``"eighth"`` (x ≥ 0, y ≥ 0, 0 ≤ z ≤ H/2: a quarter in plan, the upper half in
            height, with the symmetry planes x = 0, y = 0 and the mid-plane z = 0),
            ``"quarter"`` (x ≥ 0, y ≥ 0, |z| ≤ H/2), ``"full"`` (|z| ≤ H/2) or ``"upper"``
            (the whole plan, 0 ≤ z ≤ H/2 with the mid-plane z = 0: ring rolling).
    Returns ``(mesh, cell_tags, facet_tags)`` with facet tags :data:`RING_TAGS` (only those of
    the surfaces the model has).
    """
    if not (outer_radius > 0 and height > 0 and h > 0):
        raise ValueError("outer_radius, height and h must be > 0")
    if not 0 < inner_radius < outer_radius:
        raise ValueError(f"need 0 < inner_radius < outer_radius, got {inner_radius!r}, "
                         f"{outer_radius!r}")
    if sector not in RING_SECTORS:
        raise ValueError(f"sector must be one of {RING_SECTORS}, got {sector!r}")
    Ro, Ri = float(outer_radius), float(inner_radius)
    z0 = 0.0 if sector in ("eighth", "upper") else -0.5 * height
    planes = sector in ("eighth", "quarter")
    with gmsh_session("ring") as gmsh:
        if comm.rank == 0:
            occ = gmsh.model.occ
            outer = occ.addCylinder(0, 0, z0, 0, 0, 0.5 * height - z0, Ro)
            inner = occ.addCylinder(0, 0, z0 - 1, 0, 0, 0.5 * height - z0 + 2, Ri)
            body, _ = occ.cut([(3, outer)], [(3, inner)])
            if planes:
                box = occ.addBox(0, 0, z0 - 1, 2 * Ro, 2 * Ro, 0.5 * height - z0 + 2)
                body, _ = occ.intersect(body, [(3, box)])
            occ.synchronize()
            vols = gmsh.model.getEntities(3)
            gmsh.model.addPhysicalGroup(3, [v[1] for v in vols], 1)
            groups = {k: [] for k in RING_TAGS}
            eps = 1e-6 * max(Ro, height)
            for dim, tag in gmsh.model.getEntities(2):
                c = np.array(occ.getCenterOfMass(dim, tag))
                if abs(c[2] - 0.5 * height) < eps:
                    groups["top"].append(tag)
                elif abs(c[2] - z0) < eps:
                    groups["mid_plane" if z0 == 0.0 else "bottom"].append(tag)
                elif planes and abs(c[0]) < eps:
                    groups["symmetry_x"].append(tag)
                elif planes and abs(c[1]) < eps:
                    groups["symmetry_y"].append(tag)
                else:
                    # a lateral surface (the centre of mass of a whole circle is on the axis):
                    # the largest in-plane coordinate of its bounding box is its radius (the
                    # corner's distance is not: r√2 of a whole inner circle can exceed the
                    # mean radius of a thick ring)
                    bb = gmsh.model.getBoundingBox(dim, tag)
                    rmax = max(abs(bb[0]), abs(bb[3]), abs(bb[1]), abs(bb[4]))
                    groups["outer" if rmax > 0.5 * (Ri + Ro) else "inner"].append(tag)
            for name, tags in groups.items():
                if tags:
                    gmsh.model.addPhysicalGroup(2, tags, RING_TAGS[name])
            gmsh.option.setNumber("Mesh.CharacteristicLengthMax", h)
            gmsh.option.setNumber("Mesh.CharacteristicLengthMin", 0.5 * h)
            gmsh.model.mesh.generate(3)
        return gmsh_model_mesh(gmsh, comm, 3)


def structured_ring(comm: MPI.Comm, outer_radius: float, inner_radius: float, height: float,
                    n_theta: int, n_r: int, n_z: int, sector: str = "upper"):
    """Structured tetrahedral ring along z centred on the origin: ``n_theta × n_r × n_z``
    curvilinear hexahedra (vertices on the true circles) each split in 6 tetrahedra (Kuhn
    split, conforming across cells and across the closure θ = 2π).

    For ring rolling, where every section passes through a bite much shorter than the wall:
    the circumferential size 2πR/n_theta can be made several times smaller than the radial and
    axial sizes at the cost of the circumferential direction only.

    Args:
        outer_radius, inner_radius, height: the ring.
        n_theta, n_r, n_z: divisions around, through the wall and in height (of the model).
        sector: ``"upper"`` (0 ≤ z ≤ H/2, mid-plane z = 0) or ``"full"`` (|z| ≤ H/2).
    Returns ``(mesh, None, facet_tags)`` with facet tags :data:`RING_TAGS` (``top``, ``outer``,
    ``inner`` and ``mid_plane`` or ``bottom``).
    """
    if not (outer_radius > 0 and height > 0):
        raise ValueError("outer_radius and height must be > 0")
    if not 0 < inner_radius < outer_radius:
        raise ValueError(f"need 0 < inner_radius < outer_radius, got {inner_radius!r}, "
                         f"{outer_radius!r}")
    for name, n, lo in (("n_theta", n_theta, 3), ("n_r", n_r, 1), ("n_z", n_z, 1)):
        if not (isinstance(n, (int, np.integer)) and n >= lo):
            raise ValueError(f"{name} must be an integer >= {lo}, got {n!r}")
    if sector not in ("upper", "full"):
        raise ValueError(f"sector must be 'upper' or 'full', got {sector!r}")
    Ro, Ri, H = float(outer_radius), float(inner_radius), float(height)
    z0 = 0.0 if sector == "upper" else -0.5 * H
    if comm.rank == 0:
        th = 2.0 * np.pi * np.arange(n_theta) / n_theta
        rr = np.linspace(Ri, Ro, n_r + 1)
        zz = np.linspace(z0, 0.5 * H, n_z + 1)
        T, Rr, Z = np.meshgrid(th, rr, zz, indexing="ij")
        x = np.c_[(Rr * np.cos(T)).ravel(), (Rr * np.sin(T)).ravel(), Z.ravel()]

        def vid(i, j, k):
            return ((i % n_theta) * (n_r + 1) + j) * (n_z + 1) + k

        i, j, k = (a.ravel() for a in np.meshgrid(np.arange(n_theta), np.arange(n_r),
                                                  np.arange(n_z), indexing="ij"))
        corner = {(a, b, c): vid(i + a, j + b, k + c) for a in (0, 1) for b in (0, 1)
                  for c in (0, 1)}
        tets = []
        for p in ((0, 1, 2), (0, 2, 1), (1, 0, 2), (1, 2, 0), (2, 0, 1), (2, 1, 0)):
            path = [(0, 0, 0)]
            for ax in p:
                q = list(path[-1])
                q[ax] = 1
                path.append(tuple(q))
            tets.append(np.c_[[corner[v] for v in path]].T)
        cells = np.vstack(tets).astype(np.int64)
    else:
        x = np.zeros((0, 3))
        cells = np.zeros((0, 4), dtype=np.int64)
    domain = ufl.Mesh(ufl.VectorElement("Lagrange", ufl.tetrahedron, 1))
    msh = dolfinx.mesh.create_mesh(comm, cells, x, domain)
    fdim = 2
    msh.topology.create_connectivity(fdim, 3)
    eps = 1e-9 * Ro
    preds = {"top": lambda y: np.abs(y[2] - 0.5 * H) < eps,
             ("mid_plane" if sector == "upper" else "bottom"): lambda y: np.abs(y[2] - z0) < eps,
             "outer": lambda y: np.abs(np.hypot(y[0], y[1]) - Ro) < 1e-6 * Ro,
             "inner": lambda y: np.abs(np.hypot(y[0], y[1]) - Ri) < 1e-6 * Ro}
    idx, val = [], []
    for name, f in preds.items():
        ent = dolfinx.mesh.locate_entities_boundary(msh, fdim, f)
        idx.append(ent)
        val.append(np.full(len(ent), RING_TAGS[name], dtype=np.int32))
    idx, val = np.concatenate(idx), np.concatenate(val)
    order = np.argsort(idx, kind="stable")
    ft = dolfinx.mesh.meshtags(msh, fdim, idx[order].astype(np.int32), val[order])
    return msh, None, ft


def block(comm: MPI.Comm, lower, upper, h: float, refine_box=None, h_fine: float = None,
          dim: int = 3):
    """Box (3D) or rectangle (2D) meshed with simplices, optionally graded towards a box.

    Args:
        lower, upper: corners.
        h: element size far from the refinement box.
        refine_box: ``(lo, hi)`` corners of a region meshed with ``h_fine`` (size grows linearly
            to ``h`` over a distance of the box's largest side).
    Returns ``(mesh, cell_tags, facet_tags)`` with facet tags :data:`BLOCK_TAGS`.
    """
    lower = np.asarray(lower, float)
    upper = np.asarray(upper, float)
    if lower.shape != (dim,) or upper.shape != (dim,) or np.any(upper <= lower) or h <= 0:
        raise ValueError("block needs lower < upper (length dim) and h > 0")
    with gmsh_session("block") as gmsh:
        if comm.rank == 0:
            occ = gmsh.model.occ
            if dim == 3:
                occ.addBox(*lower, *(upper - lower))
            else:
                occ.addRectangle(lower[0], lower[1], 0.0, *(upper - lower))
            occ.synchronize()
            ents = gmsh.model.getEntities(dim)
            gmsh.model.addPhysicalGroup(dim, [e[1] for e in ents], 1)
            names = ["xmin", "xmax", "ymin", "ymax", "zmin", "zmax"]
            eps = 1e-9 * np.max(upper - lower)
            for d_, tag in gmsh.model.getEntities(dim - 1):
                c = np.array(occ.getCenterOfMass(d_, tag))[:dim]
                for k in range(dim):
                    if abs(c[k] - lower[k]) < eps:
                        gmsh.model.addPhysicalGroup(dim - 1, [tag], BLOCK_TAGS[names[2 * k]])
                    elif abs(c[k] - upper[k]) < eps:
                        gmsh.model.addPhysicalGroup(dim - 1, [tag], BLOCK_TAGS[names[2 * k + 1]])
            if refine_box is not None:
                lo, hi = (np.asarray(b, float) for b in refine_box)
                f = gmsh.model.mesh.field
                bx = f.add("Box")
                f.setNumber(bx, "VIn", h_fine)
                f.setNumber(bx, "VOut", h)
                for k, c in enumerate("XYZ"[:dim]):
                    f.setNumber(bx, f"{c}Min", lo[k])
                    f.setNumber(bx, f"{c}Max", hi[k])
                if dim == 2:
                    f.setNumber(bx, "ZMin", -1.0)
                    f.setNumber(bx, "ZMax", 1.0)
                f.setNumber(bx, "Thickness", float(np.max(hi - lo)) * 3.0)
                f.setAsBackgroundMesh(bx)
                gmsh.option.setNumber("Mesh.MeshSizeExtendFromBoundary", 0)
                gmsh.option.setNumber("Mesh.MeshSizeFromPoints", 0)
                gmsh.option.setNumber("Mesh.MeshSizeFromCurvature", 0)
            else:
                gmsh.option.setNumber("Mesh.CharacteristicLengthMax", h)
            gmsh.model.mesh.generate(dim)
        return gmsh_model_mesh(gmsh, comm, dim)


def sector_plane_normals(sector: float) -> Dict[str, np.ndarray]:
    """Outward unit normals of the two symmetry half-planes of a sector ``0 ≤ θ ≤ sector``
    (degrees) about the z axis: ``{"symmetry_0": (0, −1, 0), "symmetry_1": (−sin φ, cos φ, 0)}``
    (the tags of :data:`DRAWING_BAR_TAGS`)."""
    phi = np.radians(_sector_degrees(sector))
    n1 = np.array([-np.sin(phi), np.cos(phi), 0.0])
    n1[np.abs(n1) < 1e-15] = 0.0
    return {"symmetry_0": np.array([0.0, -1.0, 0.0]), "symmetry_1": n1}


def _sector_degrees(sector) -> float:
    try:
        a = float(sector)
    except (TypeError, ValueError):
        raise ValueError(f"sector must be an angle in degrees or None, got {sector!r}") from None
    if not (np.isfinite(a) and 0.0 < a < 360.0):
        raise ValueError(f"sector must be an angle in degrees with 0 < sector < 360 (None for "
                         f"the whole bar), got {sector!r}")
    return a


def drawing_bar(comm: MPI.Comm, radius: float, length: float, h: float,
                nose_length: float = 0.0, nose_radius: float = None,
                nose_angle: float = 45.0, sector: float = None, h_nose: float = None,
                symmetric_mesh: bool = False, replicate: bool = False):
    """Round bar along z with a drawn nose, whole or a sector about the axis: the workpiece of
    wire or bar drawing (with ``nose_length = 0``, a plain cylinder: an upsetting billet).

    The bar occupies ``0 ≤ z ≤ length``: the full radius from the back face ``z = 0``, then a
    conical transition of semi-angle ``nose_angle`` down to ``nose_radius``, and the nose (the
    reduced front end that is passed through the die exit and gripped) of radius
    ``nose_radius`` over its last ``nose_length``, ending at the front face ``z = length``
    (the pulled face). Drawing moves the bar towards +z.

    Args:
        comm: communicator (the model is built on rank 0 and distributed).
        radius: bar radius R₀ > 0.
        length: total length > 0 (back face to front face).
        h: element size.
        nose_length: axial length of the nose (0: no nose, a plain cylinder).
        nose_radius: nose radius, ``0 < nose_radius < radius`` (required with a nose).
        nose_angle: semi-angle of the conical transition, degrees in (0, 90]; the transition is
            ``(radius − nose_radius) / tan(nose_angle)`` long (90: a step).
        sector: None for the whole bar, or an angle φ in degrees (0 < φ < 360): the sector
            ``0 ≤ θ ≤ φ`` about the z axis (θ from +x towards +y), e.g. 120 for one third,
            90 for a quarter, with the symmetry faces ``symmetry_0`` (θ = 0) and
            ``symmetry_1`` (θ = φ); their outward normals are :func:`sector_plane_normals`.
            A half bar (180) has one symmetry face, the plane y = 0, tagged ``symmetry_0``.
        h_nose: element size in the nose and transition (default ``h``).
        symmetric_mesh: with a sector, mesh one half of it (``0 ≤ θ ≤ φ/2``) and complete it
            by its mirror image about the bisector plane θ = φ/2: the sector's mesh is then
            mirror-symmetric about its bisector, and its two symmetry faces carry the same
            triangles (in ``(r, z)``).
        replicate: with a sector whose angle divides 360°, build the **whole bar** from
            ``360 / sector`` turned copies of the ``symmetric_mesh`` sector, merged on the
            former symmetry faces (tags ``back``, ``front``, ``lateral``). The whole mesh is
            then symmetric under every rotation and reflection that maps the sector's symmetry
            planes onto each other, so that the discrete solution of a whole model with
            symmetric loads *is* symmetric about those planes, and a sector model with
            symmetry planes on the ``symmetric_mesh`` sector has the same discrete solution
            (the check of a symmetry model against the whole model, to solver precision).

    Returns:
        ``(mesh, cell_tags, facet_tags)`` with facet tags :data:`DRAWING_BAR_TAGS`.
    """
    for name, v in (("radius", radius), ("length", length), ("h", h)):
        if not (isinstance(v, (int, float, np.floating, np.integer)) and np.isfinite(v)
                and v > 0):
            raise ValueError(f"{name} must be a finite number > 0, got {v!r}")
    if not (np.isfinite(nose_length) and nose_length >= 0):
        raise ValueError(f"nose_length must be finite and >= 0, got {nose_length!r}")
    phi = None if sector is None else _sector_degrees(sector)
    n_copies = 0                       # 0: a plain gmsh mesh of the sector / whole bar
    if (symmetric_mesh or replicate) and (phi is None or phi == 180.0):
        raise ValueError("symmetric_mesh / replicate need a sector of less than 180 degrees, "
                         f"got sector={sector!r}")
    if symmetric_mesh:
        n_copies = 1
    if replicate:
        n_copies = int(round(360.0 / phi))
        if abs(n_copies * phi - 360.0) > 1e-9:
            raise ValueError(f"replicate needs a sector angle that divides 360 degrees, got "
                             f"{phi!r}")
    full_phi = phi
    if n_copies:
        phi = 0.5 * phi                # mesh the half sector, mirrored below
    h_nose = h if h_nose is None else float(h_nose)
    if not h_nose > 0:
        raise ValueError(f"h_nose must be > 0, got {h_nose!r}")
    L_tr = 0.0
    if nose_length > 0:
        if nose_radius is None or not (np.isfinite(nose_radius) and 0 < nose_radius < radius):
            raise ValueError(f"nose_radius must satisfy 0 < nose_radius < radius ({radius}), "
                             f"got {nose_radius!r}")
        if not (np.isfinite(nose_angle) and 0 < nose_angle <= 90):
            raise ValueError(f"nose_angle must be in (0, 90] degrees, got {nose_angle!r}")
        if nose_angle < 90:
            L_tr = (radius - nose_radius) / np.tan(np.radians(nose_angle))
        if nose_length + L_tr >= length:
            raise ValueError(f"the nose ({nose_length}) and its transition ({L_tr:.6g}) must be "
                             f"shorter than the bar ({length})")
    elif nose_radius is not None:
        raise ValueError("nose_radius needs nose_length > 0")
    ang = 2 * np.pi if phi is None else np.radians(phi)
    z_body = length - nose_length - L_tr
    with gmsh_session("drawing_bar") as gmsh:
        if comm.rank == 0:
            occ = gmsh.model.occ
            parts = [(3, occ.addCylinder(0, 0, 0, 0, 0, z_body, radius, angle=ang))]
            if nose_length > 0:
                if L_tr > 0:
                    parts.append((3, occ.addCone(0, 0, z_body, 0, 0, L_tr, radius, nose_radius,
                                                 angle=ang)))
                parts.append((3, occ.addCylinder(0, 0, z_body + L_tr, 0, 0, nose_length,
                                                 nose_radius, angle=ang)))
            if len(parts) > 1:
                occ.fuse(parts[:1], parts[1:])
            occ.synchronize()
            vols = gmsh.model.getEntities(3)
            gmsh.model.addPhysicalGroup(3, [v[1] for v in vols], 1)
            groups = {k: [] for k in DRAWING_BAR_TAGS}
            eps = 1e-6 * max(radius, length)
            n1 = None if phi is None else sector_plane_normals(phi)["symmetry_1"]
            for dim, tag in gmsh.model.getEntities(2):
                c = np.array(occ.getCenterOfMass(dim, tag))
                if abs(c[2]) < eps:
                    groups["back"].append(tag)
                elif abs(c[2] - length) < eps:
                    groups["front"].append(tag)
                elif phi is not None and abs(c[1]) < eps and (c[0] > 0 or phi == 180.0):
                    groups["symmetry_0"].append(tag)
                elif phi is not None and abs(c @ n1) < eps and \
                        c[0] * np.cos(ang) + c[1] * np.sin(ang) > 0:
                    groups["symmetry_1"].append(tag)
                else:
                    groups["lateral"].append(tag)
            for name, tags in groups.items():
                if tags:
                    gmsh.model.addPhysicalGroup(2, tags, DRAWING_BAR_TAGS[name])
            gmsh.option.setNumber("Mesh.CharacteristicLengthMax", max(h, h_nose))
            gmsh.option.setNumber("Mesh.CharacteristicLengthMin", 0.5 * min(h, h_nose))
            if h_nose != h and nose_length > 0:
                f = gmsh.model.mesh.field
                bx = f.add("Box")
                f.setNumber(bx, "VIn", h_nose)
                f.setNumber(bx, "VOut", h)
                f.setNumber(bx, "XMin", -2 * radius)
                f.setNumber(bx, "XMax", 2 * radius)
                f.setNumber(bx, "YMin", -2 * radius)
                f.setNumber(bx, "YMax", 2 * radius)
                f.setNumber(bx, "ZMin", z_body)
                f.setNumber(bx, "ZMax", 2 * length)
                f.setNumber(bx, "Thickness", 2 * max(h, h_nose))
                f.setAsBackgroundMesh(bx)
                gmsh.option.setNumber("Mesh.MeshSizeExtendFromBoundary", 0)
                gmsh.option.setNumber("Mesh.MeshSizeFromPoints", 0)
            gmsh.model.mesh.generate(3)
            if n_copies:
                _mirror_and_replicate(gmsh, full_phi, n_copies, eps)
        return gmsh_model_mesh(gmsh, comm, 3)




def _rotation_z(angle_deg: float) -> np.ndarray:
    a = np.radians(angle_deg)
    return np.array([[np.cos(a), -np.sin(a), 0.0], [np.sin(a), np.cos(a), 0.0],
                     [0.0, 0.0, 1.0]])


def _mirror_and_replicate(gmsh, phi, n_copies, eps):
    """Replace the meshed half sector ``0 ≤ θ ≤ φ/2`` by the sector completed with its mirror
    image about θ = φ/2 (``n_copies = 1``, tags ``symmetry_0``/``symmetry_1`` kept) or by the
    whole bar made of ``n_copies`` turned copies of that sector (the symmetry faces become
    interior), as a discrete gmsh model; coincident nodes are merged."""

    tags, coords, _ = gmsh.model.mesh.getNodes()
    X = coords.reshape(-1, 3)
    index = np.full(int(tags.max()) + 1, -1, dtype=np.int64)
    index[tags.astype(np.int64)] = np.arange(len(tags))

    def elements(dim, etype, phys):
        out = []
        for ent in gmsh.model.getEntitiesForPhysicalGroup(dim, phys):
            types, _, nodes = gmsh.model.mesh.getElements(dim, ent)
            out += [nd for ty, nd in zip(types, nodes) if ty == etype]
        conn = np.concatenate(out).astype(np.int64) if out else np.zeros(0, np.int64)
        nper = {2: 3, 4: 4}[etype]          # gmsh types: 2 triangle, 4 tetrahedron
        return index[conn].reshape(-1, nper)

    tets = elements(3, 4, 1)
    names = [k for k in ("back", "front", "lateral", "symmetry_0")
             if gmsh.model.getEntitiesForPhysicalGroup(2, DRAWING_BAR_TAGS[k]).size]
    faces = {k: elements(2, 2, DRAWING_BAR_TAGS[k]) for k in names}
    a = np.radians(phi)                     # reflection about the bisector plane θ = φ/2
    mirror = np.array([[np.cos(a), np.sin(a), 0.0], [np.sin(a), -np.cos(a), 0.0],
                       [0.0, 0.0, 1.0]])
    n = len(X)
    # copies: (linear map, orientation flip); the sector = half + mirrored half
    maps = []
    for k in range(n_copies):
        R = _rotation_z(k * phi)
        maps += [(R, False), (R @ mirror, True)]
    allX = np.concatenate([X @ M.T for M, _ in maps])
    pairs = cKDTree(allX).query_pairs(10 * eps, output_type="ndarray")
    parent = np.arange(len(allX))

    def find(i):
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    for i, j in pairs:
        ri, rj = find(i), find(j)
        if ri != rj:
            parent[max(ri, rj)] = min(ri, rj)
    root = np.array([find(i) for i in range(len(allX))])
    alive = np.zeros(len(allX), bool)
    for c in range(len(maps)):
        alive[root[np.unique(tets) + c * n]] = True
    keep = np.flatnonzero(alive)
    new_of_root = np.full(len(allX), -1, dtype=np.int64)
    new_of_root[keep] = np.arange(len(keep))
    new_index = new_of_root[root]

    def copy(conn, c, flip):
        out = new_index[conn + c * n]
        return out[:, [1, 0] + list(range(2, conn.shape[1]))] if flip else out

    all_tets = np.concatenate([copy(tets, c, fl) for c, (_, fl) in enumerate(maps)])
    groups = {k: [] for k in ("back", "front", "lateral", "symmetry_0", "symmetry_1")}
    for c, (_, fl) in enumerate(maps):
        for k, f in faces.items():
            if k == "symmetry_0":
                if n_copies == 1:           # the half's plane θ = 0 and its mirror θ = φ
                    groups["symmetry_1" if fl else "symmetry_0"].append(copy(f, c, fl))
            else:
                groups[k].append(copy(f, c, fl))
    gmsh.model.remove()
    gmsh.model.add("drawing_bar_symmetric")
    vol = gmsh.model.addDiscreteEntity(3)
    Y = allX[keep]
    gmsh.model.mesh.addNodes(3, vol, list(range(1, len(Y) + 1)), Y.ravel().tolist())
    gmsh.model.mesh.addElementsByType(vol, 4, [], (all_tets + 1).ravel().tolist())
    gmsh.model.addPhysicalGroup(3, [vol], 1)
    for k, fl in groups.items():
        if fl:
            s = gmsh.model.addDiscreteEntity(2)
            gmsh.model.mesh.addElementsByType(s, 2, [], (np.concatenate(fl) + 1).ravel()
                                              .tolist())
            gmsh.model.addPhysicalGroup(2, [s], DRAWING_BAR_TAGS[k])
