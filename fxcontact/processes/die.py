"""Die pieces shared by the processes through a conical die (drawing, extrusion): the bar's
nose and the die's placement, the exact die and its faceted sectors, the die radius along the
axis and the true penetration against the exact die.

The bar of :func:`fxcontact.drawing_bar` starts with a pointed nose already through the die: its
conical transition has the die's angle and lies 2 % of an element behind the die's cone (along
the axis), the nose (radius ``nose_ratio`` R₁) passes through the bearing and the relief.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Optional

import numpy as np
from mpi4py import MPI

from fxcontact.materials import NortonHoff
from fxcontact.meshing import DRAWING_BAR_TAGS, drawing_bar, gmsh_session, sector_plane_normals
from fxcontact.simulation import Simulation
from fxcontact.spaces import MixedSpace
from fxcontact.tools.faceted import FacetedTool
from fxcontact.tools.revolved import RevolvedProfile

__all__ = ["DIES", "DIE_MESHES", "NoseLayout", "nose_layout", "bar_simulation", "die_profile_tool",
           "gmsh_die_sector", "die_tool", "die_radius", "true_penetration"]

#: how the die is represented: the exact surface of revolution, or its faceted sector projected
#: on flat facets or on Nagata patches
DIES = ("exact", "flat", "nagata")
#: how a faceted die sector is triangulated
DIE_MESHES = ("structured", "gmsh")


@dataclass(frozen=True)
class NoseLayout:
    """Element size, nose and die placement of a bar with a nose through a die (mm).

    ``z_body``: where the full radius ends (the transition starts); ``s0``: axial position of
    the die's entry (radius ``entry_radius``); ``A0``/``A1``: entry and exit areas of the
    modelled sector."""

    h: float
    facet: float
    nose_radius: float
    nose_length: float
    L_tr: float
    z_body: float
    s0: float
    entry_radius: float
    relief: Optional[float]
    A0: float
    A1: float


def nose_layout(R0, R1, alpha_deg, land, fillet, relief_angle, relief_length, nose_ratio, h,
                facet, length, sector, entry_radius=None) -> NoseLayout:
    """The bar's nose and the die's placement (all ranks alike). ``entry_radius`` of the die
    defaults to 1.1 R₀ (the cone goes on beyond the bar); the nose must pass the bearing (land,
    fillet tangent length) and the relief, plus 1.5 h."""
    a = math.radians(alpha_deg)
    nose_r = nose_ratio * R1
    L_tr = (R0 - nose_r) / math.tan(a)
    relief = math.radians(relief_angle) if relief_angle else None
    tl = fillet * math.tan(0.5 * a)
    nose_len = land + tl + (relief_length if relief else 0.0) + 1.5 * h \
        - (R1 - nose_r) / math.tan(a)
    nose_len = max(nose_len, 1.5 * h)
    if nose_len + L_tr >= 0.8 * length:
        raise ValueError(f"the bar (length {length}) is too short for the nose "
                         f"({nose_len:.3g} mm) and the transition ({L_tr:.3g} mm): give a "
                         f"longer length")
    z_body = length - nose_len - L_tr
    clearance = 0.02 * h                       # axial gap between the bar's cone and the die's
    if entry_radius is None:
        entry_radius = R0 + 0.1 * R0
    s0 = z_body + clearance - (entry_radius - R0) / math.tan(a)
    return NoseLayout(h=h, facet=facet, nose_radius=nose_r, nose_length=nose_len, L_tr=L_tr,
                      z_body=z_body, s0=s0, entry_radius=entry_radius, relief=relief,
                      A0=math.radians(sector) / 2 * R0 ** 2,
                      A1=math.radians(sector) / 2 * R1 ** 2)


def bar_simulation(case, g: NoseLayout, comm, strain_rate: float, solver_options,
                   driven: str, reaction: str, output_dir=None, vtk_every: int = 0,
                   name: str = "bar"):
    """The bar (:func:`fxcontact.drawing_bar`) of ``case`` (fields R0, length, alpha, sector,
    K, m, speed) with the nose of ``g``, Norton–Hoff with the regularisation 1e-3
    ``strain_rate``, in a :class:`~fxcontact.Simulation` with the sector's symmetry planes
    ``sym0``/``sym1`` and the face ``driven`` ("front": pulled, "back": pushed) moved at
    ``case.speed`` along +z, its reaction named ``reaction``. Returns ``(sim, facet_tags,
    facets by tag name, material)``; the VTK series every ``vtk_every`` increments into
    ``output_dir`` (0: none)."""

    mat = getattr(case, "material", None) or NortonHoff(K=case.K, m=case.m,
                                                         regularization=1e-3 * strain_rate)
    msh, _, ft = drawing_bar(comm, case.R0, case.length, g.h, nose_length=g.nose_length,
                             nose_radius=g.nose_radius, nose_angle=case.alpha,
                             sector=case.sector)
    sim = Simulation(MixedSpace(msh), mat, solver_options=solver_options,
                     output_dir=output_dir if vtk_every else None, name=name,
                     output_every=max(1, int(vtk_every or 1)), progress=False)
    f = {k: sim.facets(ft, v) for k, v in DRAWING_BAR_TAGS.items()}
    normals = sector_plane_normals(case.sector)
    sim.add_symmetry_plane(f["symmetry_0"], normals["symmetry_0"], name="sym0")
    sim.add_symmetry_plane(f["symmetry_1"], normals["symmetry_1"], name="sym1")
    sim.add_velocity_bc(f[driven], case.speed, 2)
    sim.add_reaction(reaction, f[driven])
    return sim, ft, f, mat


def die_profile_tool(g: NoseLayout, R1, alpha_deg, land, fillet, relief_length,
                     name="die") -> RevolvedProfile:
    """The exact die (:meth:`RevolvedProfile.die`) placed by the layout ``g``."""
    return RevolvedProfile.die(entry_radius=g.entry_radius, exit_radius=R1,
                               half_angle=math.radians(alpha_deg), land_length=land,
                               fillet_radius=fillet, relief_angle=g.relief,
                               relief_length=relief_length if g.relief else 0.0, s0=g.s0,
                               name=name)


def gmsh_die_sector(exact, sector_deg: float, facet: float, extension: float, comm):
    """The die's sector meshed by gmsh (unstructured triangles, size ``facet``): each profile
    segment (entry cone with ``extension`` before it, fillet arc, land, relief with
    ``extension`` after it) revolved by ``sector_deg`` about the axis with OpenCASCADE and
    meshed by the frontal-Delaunay mesher — the triangles are not aligned with the generators
    (as a die from a CAD mesher; the structured :func:`fxcontact.faceted_revolved` sector has
    its edges along the generators and rings). The vertices are moved onto the exact surface;
    the triangles are oriented towards free space. Built on rank 0, broadcast."""
    V = T = None
    if comm.rank == 0:
        pts = np.asarray(exact.points, float)
        arcs = exact.arcs or (None,) * (len(pts) - 1)
        with gmsh_session("die") as gmsh:
            occ = gmsh.model.occ
            curves = []
            n = len(pts) - 1
            for i in range(n):
                p0, p1 = pts[i].copy(), pts[i + 1].copy()
                if arcs[i] is None:
                    u = (p1 - p0) / np.linalg.norm(p1 - p0)
                    if i == 0:
                        p0 = p0 - extension * u
                    if i == n - 1:
                        p1 = p1 + extension * u
                    a = occ.addPoint(p0[1], 0.0, p0[0])
                    b = occ.addPoint(p1[1], 0.0, p1[0])
                    curves.append(occ.addLine(a, b))
                else:   # arc of signed radius r: centre on the left of the chord if r > 0
                    r = arcs[i]
                    c = p1 - p0
                    half = 0.5 * np.linalg.norm(c)
                    left = np.array([-c[1], c[0]]) / (2 * half)
                    ctr = 0.5 * (p0 + p1) + np.sign(r) * math.sqrt(r * r - half * half) * left
                    a = occ.addPoint(p0[1], 0.0, p0[0])
                    b = occ.addPoint(p1[1], 0.0, p1[0])
                    o = occ.addPoint(ctr[1], 0.0, ctr[0])
                    curves.append(occ.addCircleArc(a, o, b))
            occ.revolve([(1, c) for c in curves], 0, 0, 0, 0, 0, 1,
                        math.radians(sector_deg))
            occ.removeAllDuplicates()
            occ.synchronize()
            gmsh.option.setNumber("Mesh.CharacteristicLengthMax", facet)
            gmsh.option.setNumber("Mesh.CharacteristicLengthMin", 0.5 * facet)
            gmsh.option.setNumber("Mesh.Algorithm", 6)
            gmsh.model.mesh.generate(2)
            tags, X, _ = gmsh.model.mesh.getNodes()
            index = {int(t): k for k, t in enumerate(tags)}
            V = X.reshape(-1, 3).copy()
            tri = []
            for et, _, conn in zip(*gmsh.model.mesh.getElements(2)):
                if et == 2:
                    tri.append(np.array([index[int(t)] for t in conn]).reshape(-1, 3))
            T = np.concatenate(tri)
        used = np.unique(T)
        remap = -np.ones(len(V), int)
        remap[used] = np.arange(len(used))
        V, T = V[used], remap[T]
        V = exact.project(V, 0.0, hessian=False).point          # onto the exact surface
        nrm = np.cross(V[T[:, 1]] - V[T[:, 0]], V[T[:, 2]] - V[T[:, 0]])
        free = exact.project(V[T].mean(axis=1), 0.0, hessian=False).normal
        flip = np.einsum("ij,ij->i", nrm, free) < 0
        T[flip] = T[flip][:, [0, 2, 1]]
    return comm.bcast(V, root=0), comm.bcast(T, root=0)


def die_tool(exact, die: str, die_mesh: str, sector: float, facet: float, h: float,
             R0: float, R1: float, fillet: float, comm=MPI.COMM_WORLD):
    """``(die used, facet sag)``: the exact die itself, or its faceted sector (``die`` "flat"
    or "nagata") meshed by gmsh or structured (``die_mesh``), extended by 2 h at both ends."""
    if die == "exact":
        return exact, 0.0
    if die not in DIES:
        raise ValueError(f"die must be one of {DIES}, got {die!r}")
    if die_mesh == "gmsh":
        V, T = gmsh_die_sector(exact, sector, facet, 2.0 * h, comm)
        tool = FacetedTool(V, T, mode=die, name=exact.name)
        e = np.linalg.norm(V[T[:, 1]] - V[T[:, 0]], axis=1)
        return tool, float(np.max(e)) ** 2 / (8.0 * R1)
    r_mid = 0.5 * (R0 + R1)
    n_theta = max(2, int(math.ceil(math.radians(sector) * r_mid / facet)))
    tool = FacetedTool.from_revolved(exact, n_theta, sector=(0.0, sector), ds=facet,
                                     extension=2.0 * h,
                                     max_angle=facet / max(fillet, 1e-9)
                                     if fillet else math.radians(10.0), mode=die)
    return tool, R0 * (1.0 - math.cos(0.5 * math.radians(sector) / n_theta))


def die_radius(exact, s):
    """Radius of the die surface at axial positions ``s`` (bisection on rays from the axis of
    the sign of the exact gap)."""
    pts = np.zeros((len(s), 3))
    pts[:, 0] = 1e-3
    pts[:, 2] = s
    lo, hi = np.full(len(s), 1e-3), np.full(len(s), 3.0 * exact.points[:, 1].max())
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        pts[:, 0] = mid
        g = exact.project(pts, 0.0, hessian=False).gap
        inside = g > 0
        lo = np.where(inside, mid, lo)
        hi = np.where(inside, hi, mid)
    return 0.5 * (lo + hi)


def true_penetration(comm, exact, contact, sim) -> float:
    """Largest depth of the contact nodes inside the exact tool ``exact`` at the current time
    (all ranks; 0 if none is inside)."""
    b = contact.boundary
    X = sim.vertex_positions()[b.vertices]
    gap = exact.project(X, sim.t, hessian=False).gap if len(X) else np.zeros(0)
    pen = comm.allreduce(float(np.max(-gap, initial=-np.inf)), op=MPI.MAX)
    return max(pen, 0.0)
