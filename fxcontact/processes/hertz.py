"""Hertz's contact of a rigid sphere or cylinder with an elastic half-space (THEORY §11): the
formulas, the graded block the sphere indents and the octahedral faceted sphere tool.

* :func:`hertz_sphere` — point contact at a given indentation δ:
  P = 4/3 E* R^½ δ^{3/2}, a = √(Rδ), p0 = 3P/(2πa²), p(r) = p0 √(1 − r²/a²);
* :func:`hertz_line` — line contact for a given load P per unit length (in 2D the indentation
  of a half-space is not defined): a = √(4PR/(πE*)), p0 = 2P/(πa);
* :func:`graded_block` — the quarter block ``[0, w]² × [−H, 0]`` whose element size grows
  linearly with the distance to the first contact point (the far field of a point load decays
  like 1/r: linear elements resolve it only if their size grows gently);
* :func:`octahedral_sphere`, :func:`octahedral_divisions`, :func:`make_tool` — the indenter:
  the analytic :class:`~fxcontact.tools.analytic.Sphere` or a triangulated sphere that is
  mirror-symmetric about the coordinate planes (needed by the quarter model), flat facets or
  Nagata patches (:class:`~fxcontact.tools.faceted.FacetedTool`).

E* = E/(1 − ν²) is the plane-strain modulus of the block (the tool is rigid). Units: mm, N,
MPa (N/mm for the line load).

The indentation runs that use these pieces are :mod:`fxcontact.processes.hertz_sphere` and
:mod:`fxcontact.processes.hertz_cylinder`.
"""

from __future__ import annotations

import math

import numpy as np
from dolfinx.io import gmshio

from fxcontact.meshing import BLOCK_TAGS, gmsh_session
from fxcontact.tools.analytic import Sphere
from fxcontact.tools.faceted import FacetedTool

__all__ = ["TOOLS", "hertz_sphere", "hertz_line", "graded_block", "octahedral_sphere",
           "octahedral_divisions", "make_tool"]

#: the indenters of :func:`make_tool`: the exact sphere, the faceted sphere with Nagata
#: patches, the faceted sphere with flat facets
TOOLS = ("analytic", "nagata", "flat")


# ------------------------------------------------------------------ Hertz's formulas

def hertz_sphere(delta: float, R: float, E_star: float):
    """Hertz's rigid sphere on an elastic half-space at the indentation ``delta``.

    Args:
        delta: indentation δ [mm] (rigid displacement of the sphere from first touch).
        R: sphere radius [mm].
        E_star: plane-strain modulus E/(1 − ν²) of the half-space [MPa].
    Returns:
        ``(P, a, p0)``: load [N], contact radius [mm], peak (central) pressure [MPa].
    """
    P = 4.0 / 3.0 * E_star * math.sqrt(R) * delta**1.5
    a = math.sqrt(R * delta)
    return P, a, 3.0 * P / (2.0 * math.pi * a**2)


def hertz_line(P: float, R: float, E_star: float):
    """Hertz's rigid cylinder on an elastic half-space (plane strain) under a line load.

    Args:
        P: load per unit length [N/mm].
        R: cylinder radius [mm].
        E_star: plane-strain modulus E/(1 − ν²) of the half-space [MPa].
    Returns:
        ``(a, p0)``: contact half-width [mm] and peak pressure [MPa].
    """
    a = math.sqrt(4.0 * P * R / (math.pi * E_star))
    return a, 2.0 * P / (math.pi * a)


# ------------------------------------------------------------------ the graded quarter block

def graded_block(comm, width: float, height: float, h_fine: float, refine: float,
                 growth: float, h: float):
    """Quarter block ``[0, width]² × [-height, 0]`` meshed with tetrahedra graded radially
    from the origin (the first contact point), with facet tags :data:`BLOCK_TAGS`.

    The element size is ``h_fine`` within the distance ``refine`` of the origin and grows
    linearly with the distance, with slope ``growth``, up to ``h`` (gmsh Distance + Threshold
    fields). :func:`fxcontact.meshing.block` grades over a fixed distance (3 × its refinement
    box), i.e. with a size gradient above 1 for a block large enough for Hertz: measured at
    δ = 13.3 µm, h_fine = 0.05 mm, a 10 mm block meshed that way is 12 % too stiff and a 20 mm
    block 29 %. The stiffening of a graded mesh grows like ``growth²`` (≈ +1.3 % on the force at
    0.2).

    Args:
        comm: the communicator of the mesh (gmsh runs on its rank 0).
        width, height: block size [mm].
        h_fine: element size near the origin [mm].
        refine: radius of the region of size ``h_fine`` [mm].
        growth: size gradient dh/dr beyond it (dimensionless, > 0).
        h: largest element size [mm].
    Returns:
        ``(mesh, cell tags, facet tags)``.
    """
    if not (0 < h_fine <= h and refine > 0 and growth > 0):
        raise ValueError("need 0 < h_fine <= h, refine > 0 and growth > 0")
    with gmsh_session("hertz_block") as gmsh:
        if comm.rank == 0:
            occ = gmsh.model.occ
            occ.addBox(0.0, 0.0, -height, width, width, height)
            occ.synchronize()
            gmsh.model.addPhysicalGroup(3, [e[1] for e in gmsh.model.getEntities(3)], 1)
            lower, upper = np.array([0.0, 0.0, -height]), np.array([width, width, 0.0])
            names = ["xmin", "xmax", "ymin", "ymax", "zmin", "zmax"]
            eps = 1e-9 * max(width, height)
            for d_, tag in gmsh.model.getEntities(2):
                c = np.array(occ.getCenterOfMass(d_, tag))
                for k in range(3):
                    for j, ref in enumerate((lower[k], upper[k])):
                        if abs(c[k] - ref) < eps:
                            gmsh.model.addPhysicalGroup(2, [tag], BLOCK_TAGS[names[2 * k + j]])
            origin = [t for _, t in gmsh.model.getEntities(0)
                      if np.allclose(gmsh.model.getValue(0, t, []), 0.0)]
            f = gmsh.model.mesh.field
            dist = f.add("Distance")
            f.setNumbers(dist, "PointsList", origin)
            thr = f.add("Threshold")
            f.setNumber(thr, "InField", dist)
            f.setNumber(thr, "SizeMin", h_fine)
            f.setNumber(thr, "SizeMax", h)
            f.setNumber(thr, "DistMin", refine)
            f.setNumber(thr, "DistMax", refine + (h - h_fine) / growth)
            f.setAsBackgroundMesh(thr)
            for k in ("Mesh.MeshSizeExtendFromBoundary", "Mesh.MeshSizeFromPoints",
                      "Mesh.MeshSizeFromCurvature"):
                gmsh.option.setNumber(k, 0)
            gmsh.model.mesh.generate(3)
        msh, ct, ft = gmshio.model_to_mesh(gmsh.model, comm, 0, gdim=3)
    return msh, ct, ft


# ------------------------------------------------------------------ the octahedral sphere tool

def octahedral_sphere(n: int, radius: float = 1.0, center=(0.0, 0.0, 0.0)):
    """Sphere triangulated from an octahedron, n² triangles per octant, mirror-symmetric about
    the coordinate planes through ``center``; vertices on the sphere, outward orientation.

    Each of the 8 octant faces of the octahedron is split into n² triangles (barycentric grid,
    mapped to the sphere with equal angles along the octahedron's edges). A generic sphere
    triangulation (gmsh, icosphere) is not symmetric about the planes x = 0 and y = 0, which
    the quarter model of the Hertz test needs; here one octahedron vertex (valence 4) is the
    lowest point of the sphere. The edges at a vertex are 2R sin(π/4n) long, the facets
    elsewhere up to 1.45× longer.

    Args:
        n: divisions per octant edge (>= 1).
        radius: sphere radius [mm]; center: its centre [mm].
    Returns:
        ``(vertices (N, 3) [mm], triangles (8 n², 3))``; N = 4 n² + 2.
    """
    n = int(n)
    if n < 1:
        raise ValueError("n must be >= 1")
    index, verts, tris = {}, [], []
    # barycentric grid (i, j, k = n - i - j) on one octant face, equal angles along its edges
    grid = [(i, j) for i in range(n + 1) for j in range(n + 1 - i)]
    lam = np.array([(i, j, n - i - j) for i, j in grid], dtype=np.float64) / n
    w = np.sin(0.5 * np.pi * lam)
    local = []
    for i in range(n):
        for j in range(n - i):
            local.append(((i, j), (i + 1, j), (i, j + 1)))
            if i + j < n - 1:
                local.append(((i + 1, j), (i + 1, j + 1), (i, j + 1)))
    for sx in (1.0, -1.0):
        for sy in (1.0, -1.0):
            for sz in (1.0, -1.0):
                p = w * np.array([sx, sy, sz])
                p /= np.linalg.norm(p, axis=1, keepdims=True)
                ids = {}
                for (ij, q) in zip(grid, p):
                    key = tuple(np.round(q, 12) + 0.0)
                    if key not in index:
                        index[key] = len(verts)
                        verts.append(q)
                    ids[ij] = index[key]
                T = np.array([[ids[a], ids[b], ids[c]] for a, b, c in local], dtype=np.int64)
                if sx * sy * sz < 0:  # mirrored octant: reverse to keep the outward orientation
                    T = T[:, [0, 2, 1]]
                tris.append(T)
    V = np.array(verts) * radius + np.asarray(center, dtype=np.float64)
    return V, np.vstack(tris)


def octahedral_divisions(radius: float, facet_size: float) -> int:
    """n such that the edges at an octahedron vertex, 2R sin(π/4n), are closest to
    ``facet_size`` (at least 1); ``radius`` and ``facet_size`` in mm."""
    if not 0 < facet_size < 2 * radius:
        raise ValueError("tool_facet_size must be in (0, 2R)")
    return max(1, int(round(0.5 * math.pi / (2.0 * math.asin(0.5 * facet_size / radius)))))


def make_tool(kind: str, radius: float, speed: float, facet_size: float = 1.0,
              normals="nvv"):
    """The indenter touching the origin at t = 0 and moving down at ``speed``: the analytic
    sphere, or the octahedral faceted sphere (lowest vertex at the origin) in Nagata or flat
    mode.

    The vertices of the faceted sphere lie on the true sphere and its facets inside it (a chord
    sags by h²/8R); its lowest vertex is placed where the analytic sphere first touches, so
    that first touch happens at the same place and time for every tool and the indentation is
    the same rigid displacement. The Nagata patches interpolate that vertex and its normal
    (vertical by symmetry): they are tangent to the block there, like the true sphere. Flat
    facets make a shallow square pyramid there (slopes ≈ 0.10–0.14), i.e. a conical indenter.

    Args:
        kind: one of :data:`TOOLS`.
        radius: sphere radius R [mm].
        speed: downward speed [mm/s] (the indentation at t = 1 s for a unit-time run).
        facet_size: edge length at the lowest vertex of the faceted sphere [mm].
        normals: nodal normals of the Nagata patches: ``"nvv"`` (estimated from the facets),
            ``"exact"`` (the sphere's radial normals) or any value
            :class:`~fxcontact.tools.faceted.FacetedTool` accepts.
    Returns:
        ``(tool, info)``; ``info`` is empty for the analytic sphere, else ``tool_divisions``
        (n), ``tool_triangles`` and ``tool_facet_size`` (the edge at the lowest vertex [mm]).
    """
    center = (0.0, 0.0, radius)
    velocity = (0.0, 0.0, -speed)
    if kind == "analytic":
        return Sphere(center=center, radius=radius, velocity=velocity, name="sphere"), {}
    if kind not in ("nagata", "flat"):
        raise ValueError(f"tool must be 'analytic', 'nagata' or 'flat', got {kind!r}")
    n = octahedral_divisions(radius, facet_size)
    V, T = octahedral_sphere(n, radius, center)
    if isinstance(normals, str) and normals == "exact":
        normals = (V - np.asarray(center)) / radius
    tool = FacetedTool(V, T, mode=kind, normals=normals, velocity=velocity, name="sphere")
    info = {"tool_divisions": n, "tool_triangles": int(T.shape[0]),
            "tool_facet_size": 2.0 * radius * math.sin(0.25 * math.pi / n)}
    return tool, info
