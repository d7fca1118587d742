"""Tool surface meshes: gmsh builders and pure-numpy structured generators.

gmsh builders (OpenCASCADE kernel, gmsh >= 4.8):

* :func:`cylinder_surface` — closed capped cylinder of radius ``R`` and length ``L`` with a
  target facet size (the thesis's ironing tool: R = 5 mm, coarse facets 1.7 mm);
* :func:`sphere_surface` — sphere with a target facet size;
* :func:`extruded_cylinder_surface` — open (lateral) cylinder surface, structured: a circle of
  ``n_theta`` equal segments extruded in layers, so every cross-section is the same regular
  polygon (the ironing demo's quasi-2D tool, with a chosen generator at the bottom).

Pure-numpy generators (fast, deterministic, used by the tests):

* :func:`icosphere` (20·4^k triangles), :func:`structured_cylinder` (open or capped with fan
  caps), :func:`box_surface` (n×n quads per face, each split in two triangles).

Every function returns ``(vertices (N, 3) float64, triangles (M, 3) int64)`` oriented
counter-clockwise about the outward normal, as :class:`fxcontact.tools.faceted.FacetedTool`
expects. :func:`write_surface` writes ``.msh`` (gmsh 2.2 format), ``.stl`` or ``.obj`` files.

Command line: ``python -m fxcontact.tools.surfaces OUTDIR [--length L] [--fine H] [--structured]``
writes the coarse (1.7 mm) and fine cylinder R = 5 mm tool meshes as .msh and .stl into
``OUTDIR`` (``--structured``: also the open extruded ones).
"""

from __future__ import annotations

import argparse
import logging
import os
from collections import deque
from typing import Sequence, Tuple

import meshio
import numpy as np

from fxcontact.meshing import gmsh_session

__all__ = [
    "icosphere",
    "structured_cylinder",
    "box_surface",
    "orient_outward",
    "transform_to_axis",
    "cylinder_surface",
    "sphere_surface",
    "extruded_cylinder_surface",
    "write_surface",
]

logger = logging.getLogger(__name__)

Mesh = Tuple[np.ndarray, np.ndarray]


# ------------------------------------------------------------------------------------------
# helpers
# ------------------------------------------------------------------------------------------


def _rotation_z_to(axis: Sequence[float]) -> np.ndarray:
    """Rotation matrix mapping e_z onto the unit vector along ``axis``."""
    a = np.asarray(axis, dtype=np.float64)
    a = a / np.linalg.norm(a)
    z = np.array([0.0, 0.0, 1.0])
    v = np.cross(z, a)
    s, c = np.linalg.norm(v), float(z @ a)
    if s < 1e-15:
        return np.eye(3) if c > 0 else np.diag([1.0, -1.0, -1.0])
    W = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]]) / s
    return np.eye(3) + s * W + (1 - c) * W @ W


def transform_to_axis(vertices: np.ndarray, center=(0.0, 0.0, 0.0),
                      axis=(0.0, 0.0, 1.0)) -> np.ndarray:
    """Rigidly map vertices built about the z axis at the origin to ``center`` / ``axis``."""
    return np.asarray(vertices) @ _rotation_z_to(axis).T + np.asarray(center, dtype=np.float64)


def _signed_volume(V: np.ndarray, T: np.ndarray) -> float:
    return float(np.einsum("ij,ij->i", V[T[:, 0]], np.cross(V[T[:, 1]], V[T[:, 2]])).sum() / 6)


def orient_outward(vertices: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """Return the triangles consistently oriented, outward for each closed component.

    Orientation is propagated across manifold edges by breadth-first search; then every
    connected component with a negative signed volume is reversed. (Open components keep the
    orientation of their first triangle.)
    """
    V = np.asarray(vertices, dtype=np.float64)
    T = np.array(triangles, dtype=np.int64, copy=True)
    M = T.shape[0]
    half = {}
    for f in range(M):
        for k in range(3):
            a, b = T[f, k], T[f, (k + 1) % 3]
            half.setdefault((min(a, b), max(a, b)), []).append(f)
    seen = np.zeros(M, dtype=bool)
    comp = np.full(M, -1)
    ncomp = 0
    for s in range(M):
        if seen[s]:
            continue
        seen[s] = True
        comp[s] = ncomp
        queue = deque([s])
        while queue:
            f = queue.popleft()
            for k in range(3):
                a, b = T[f, k], T[f, (k + 1) % 3]
                for g in half[(min(a, b), max(a, b))]:
                    if g == f or seen[g]:
                        continue
                    # consistent orientation: g traverses the edge as b -> a
                    for m in range(3):
                        if T[g, m] == a and T[g, (m + 1) % 3] == b:
                            T[g, [1, 2]] = T[g, [2, 1]]
                            break
                    seen[g] = True
                    comp[g] = ncomp
                    queue.append(g)
        ncomp += 1
    for c in range(ncomp):
        sel = comp == c
        if _signed_volume(V, T[sel]) < 0.0:
            T[sel] = T[sel][:, [0, 2, 1]]
    return T


def _merge_vertices(V: np.ndarray, T: np.ndarray, decimals: int = 10) -> Mesh:
    key = np.round(V, decimals)
    _, idx, inv = np.unique(key, axis=0, return_index=True, return_inverse=True)
    return V[idx], inv.reshape(-1)[T]


# ------------------------------------------------------------------------------------------
# pure-numpy generators
# ------------------------------------------------------------------------------------------


def icosphere(subdivisions: int = 1, radius: float = 1.0, center=(0.0, 0.0, 0.0)) -> Mesh:
    """Geodesic icosphere with 20·4^subdivisions triangles, vertices on the sphere."""
    t = (1.0 + 5.0 ** 0.5) / 2.0
    V = np.array([[-1, t, 0], [1, t, 0], [-1, -t, 0], [1, -t, 0], [0, -1, t], [0, 1, t],
                  [0, -1, -t], [0, 1, -t], [t, 0, -1], [t, 0, 1], [-t, 0, -1], [-t, 0, 1]],
                 dtype=np.float64)
    T = np.array([[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9],
                  [5, 11, 4], [11, 10, 2], [10, 7, 6], [7, 1, 8], [3, 9, 4], [3, 4, 2],
                  [3, 2, 6], [3, 6, 8], [3, 8, 9], [4, 9, 5], [2, 4, 11], [6, 2, 10],
                  [8, 6, 7], [9, 8, 1]], dtype=np.int64)
    V /= np.linalg.norm(V, axis=1, keepdims=True)
    for _ in range(int(subdivisions)):
        e = np.sort(T[:, [[0, 1], [1, 2], [2, 0]]], axis=2).reshape(-1, 2)
        uniq, inv = np.unique(e, axis=0, return_inverse=True)
        mid = V[uniq[:, 0]] + V[uniq[:, 1]]
        mid /= np.linalg.norm(mid, axis=1, keepdims=True)
        m = (inv.reshape(-1, 3) + V.shape[0])
        V = np.vstack([V, mid])
        a, b, c = T[:, 0], T[:, 1], T[:, 2]
        ab, bc, ca = m[:, 0], m[:, 1], m[:, 2]
        T = np.vstack([np.stack([a, ab, ca], 1), np.stack([b, bc, ab], 1),
                       np.stack([c, ca, bc], 1), np.stack([ab, bc, ca], 1)])
    return V * radius + np.asarray(center, dtype=np.float64), T


def structured_cylinder(radius: float = 1.0, length: float = 2.0, n_theta: int = 16,
                        n_axial: int = 4, capped: bool = False, center=(0.0, 0.0, 0.0),
                        axis=(0.0, 0.0, 1.0), theta0: float = 0.0) -> Mesh:
    """Structured cylinder: ``n_theta`` facets around, ``n_axial`` rows of quads split in two.

    Args:
        radius: cylinder radius (vertices lie on it).
        length: length along the axis, centred on ``center``.
        n_theta: number of facets around.
        n_axial: number of quad rows along the axis.
        capped: add the two end caps (fans around a centre vertex) to close the surface.
        center, axis: placement of the axis.
        theta0: angular offset of the first generator.

    Returns:
        (vertices, triangles), outward normals (radially outward on the lateral surface).
    """
    th = theta0 + 2 * np.pi * np.arange(n_theta) / n_theta
    z = -0.5 * length + length * np.arange(n_axial + 1) / n_axial
    TH, Z = np.meshgrid(th, z, indexing="xy")  # (n_axial+1, n_theta)
    V = np.stack([radius * np.cos(TH), radius * np.sin(TH), Z], axis=-1).reshape(-1, 3)
    j = np.arange(n_theta)
    k = np.arange(n_axial)
    J, K = np.meshgrid(j, k, indexing="xy")
    a = K * n_theta + J
    b = K * n_theta + (J + 1) % n_theta
    c = (K + 1) * n_theta + (J + 1) % n_theta
    d = (K + 1) * n_theta + J
    T = np.vstack([np.stack([a, b, c], -1).reshape(-1, 3), np.stack([a, c, d], -1).reshape(-1, 3)])
    if capped:
        nv = V.shape[0]
        V = np.vstack([V, [[0, 0, -0.5 * length], [0, 0, 0.5 * length]]])
        bot = np.stack([np.full(n_theta, nv), (j + 1) % n_theta, j], -1)
        top_ring = n_axial * n_theta
        top = np.stack([np.full(n_theta, nv + 1), top_ring + j, top_ring + (j + 1) % n_theta], -1)
        T = np.vstack([T, bot, top])
    return transform_to_axis(V, center, axis), T.astype(np.int64)


def box_surface(size=(1.0, 1.0, 1.0), n: int = 3, center=(0.0, 0.0, 0.0)) -> Mesh:
    """Box surface with ``n`` × ``n`` quads per face, each split into two triangles."""
    s = np.asarray(size, dtype=np.float64)
    faces = [((1, 0, 0), (0, 1, 0), (0, 0, 1)), ((-1, 0, 0), (0, 0, 1), (0, 1, 0)),
             ((0, 1, 0), (0, 0, 1), (1, 0, 0)), ((0, -1, 0), (1, 0, 0), (0, 0, 1)),
             ((0, 0, 1), (1, 0, 0), (0, 1, 0)), ((0, 0, -1), (0, 1, 0), (1, 0, 0))]
    g = np.linspace(-0.5, 0.5, n + 1)
    A, B = np.meshgrid(g, g, indexing="ij")
    Vs, Ts, off = [], [], 0
    for nn, u, v in faces:
        nn, u, v = (np.asarray(x, dtype=np.float64) for x in (nn, u, v))
        P = (0.5 * nn + A[..., None] * u + B[..., None] * v) * s
        Vs.append(P.reshape(-1, 3))
        i, j = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
        p00 = i * (n + 1) + j
        p10 = (i + 1) * (n + 1) + j
        p11 = (i + 1) * (n + 1) + j + 1
        p01 = i * (n + 1) + j + 1
        Ts.append(np.vstack([np.stack([p00, p10, p11], -1).reshape(-1, 3),
                             np.stack([p00, p11, p01], -1).reshape(-1, 3)]) + off)
        off += (n + 1) ** 2
    V, T = _merge_vertices(np.vstack(Vs), np.vstack(Ts))
    return V + np.asarray(center, dtype=np.float64), T


# ------------------------------------------------------------------------------------------
# gmsh builders
# ------------------------------------------------------------------------------------------


def _gmsh_surface_mesh(gmsh) -> Mesh:
    """Nodes and triangles of the current gmsh model's 2D mesh, renumbered compactly."""
    tags, coords, _ = gmsh.model.mesh.getNodes()
    coords = np.asarray(coords).reshape(-1, 3)
    etags, enodes = gmsh.model.mesh.getElementsByType(2)
    enodes = np.asarray(enodes, dtype=np.int64).reshape(-1, 3)
    lookup = np.full(int(np.max(tags)) + 1, -1, dtype=np.int64)
    lookup[np.asarray(tags, dtype=np.int64)] = np.arange(len(tags))
    T = lookup[enodes]
    used = np.unique(T)
    remap = np.full(coords.shape[0], -1, dtype=np.int64)
    remap[used] = np.arange(used.size)
    return coords[used].copy(), remap[T]


def cylinder_surface(radius: float = 5.0, length: float = 20.0, facet_size: float = 1.7,
                     center=(0.0, 0.0, 0.0), axis=(0.0, 0.0, 1.0)) -> Mesh:
    """Closed capped cylinder surface meshed by gmsh (OpenCASCADE) with a target facet size.

    Args:
        radius: cylinder radius [mm].
        length: length along the axis, centred on ``center`` [mm].
        facet_size: target triangle edge length [mm] (1.7 mm = the thesis's coarse tool).
        center, axis: placement.

    Returns:
        (vertices, triangles) oriented outward.
    """
    with gmsh_session("cylinder_tool") as gmsh:
        gmsh.model.occ.addCylinder(0, 0, -0.5 * length, 0, 0, length, radius)
        gmsh.model.occ.synchronize()
        gmsh.option.setNumber("Mesh.MeshSizeMin", facet_size)
        gmsh.option.setNumber("Mesh.MeshSizeMax", facet_size)
        gmsh.option.setNumber("Mesh.MeshSizeFromCurvature", 0)
        gmsh.model.mesh.generate(2)
        V, T = _gmsh_surface_mesh(gmsh)
    T = orient_outward(V, T)
    return transform_to_axis(V, center, axis), T


def sphere_surface(radius: float = 1.0, facet_size: float = 0.3, center=(0.0, 0.0, 0.0)) -> Mesh:
    """Sphere surface meshed by gmsh (OpenCASCADE) with a target facet size, oriented outward."""
    with gmsh_session("sphere_tool") as gmsh:
        gmsh.model.occ.addSphere(0, 0, 0, radius)
        gmsh.model.occ.synchronize()
        gmsh.option.setNumber("Mesh.MeshSizeMin", facet_size)
        gmsh.option.setNumber("Mesh.MeshSizeMax", facet_size)
        gmsh.model.mesh.generate(2)
        V, T = _gmsh_surface_mesh(gmsh)
    T = orient_outward(V, T)
    return V + np.asarray(center, dtype=np.float64), T


def extruded_cylinder_surface(radius: float = 5.0, length: float = 20.0,
                              facet_size: float = 1.7, n_theta: int = None,
                              n_axial: int = None, theta0: float = 0.0,
                              center=(0.0, 0.0, 0.0), axis=(0.0, 0.0, 1.0)) -> Mesh:
    """Open lateral cylinder surface meshed by gmsh as a structured extrusion.

    A circle split into ``n_theta`` equal segments (transfinite curve) is extruded along the
    axis in ``n_axial`` layers of triangles: every cross-section is the same regular
    ``n_theta``-gon inscribed in the circle (vertices on the true cylinder), facet edges run
    along the generators, and each quad is split by the same diagonal. The ends are open.

    Args:
        radius: cylinder radius [mm].
        length: length along the axis, centred on ``center`` [mm].
        facet_size: target facet width around the circumference [mm], used when ``n_theta``
            is None: ``n_theta = round(2πR / facet_size)`` (R = 5, 1.7 mm → 18 facets, chord
            1.74 mm, the thesis's coarse ironing tool).
        n_theta: number of facets around (>= 3).
        n_axial: number of layers along the axis (default: facets about as long as wide).
        theta0: angle of the first generator in the builder's frame (axis z, generator at
            ``(R cos θ0, R sin θ0)``), before the rigid map to ``center``/``axis``.
        center, axis: placement of the axis.

    Returns:
        (vertices, triangles), oriented with the normals pointing radially outward.
    """
    if not (radius > 0 and length > 0):
        raise ValueError("radius and length must be > 0")
    if n_theta is None:
        if not facet_size > 0:
            raise ValueError("facet_size must be > 0")
        n_theta = max(3, int(round(2.0 * np.pi * radius / facet_size)))
    n_theta = int(n_theta)
    if n_theta < 3:
        raise ValueError("n_theta must be >= 3")
    if n_axial is None:
        chord = 2.0 * radius * np.sin(np.pi / n_theta)
        n_axial = max(1, int(round(length / chord)))
    n_axial = int(n_axial)
    if n_axial < 1:
        raise ValueError("n_axial must be >= 1")
    with gmsh_session("extruded_cylinder_tool") as gmsh:
        occ = gmsh.model.occ
        circle = occ.addCircle(0.0, 0.0, -0.5 * length, radius)
        occ.synchronize()
        gmsh.model.mesh.setTransfiniteCurve(circle, n_theta + 1)
        occ.extrude([(1, circle)], 0.0, 0.0, length, numElements=[n_axial], recombine=False)
        occ.synchronize()
        gmsh.model.mesh.generate(2)
        V, T = _gmsh_surface_mesh(gmsh)
    V, T = _merge_vertices(V, T)
    c, s = np.cos(theta0), np.sin(theta0)
    V = V @ np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]).T
    T = orient_outward(V, T)  # consistent; an open surface keeps its first triangle's sense
    P = V[T]
    m = np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0])
    radial = P.mean(axis=1) * np.array([1.0, 1.0, 0.0])
    if np.sum(np.einsum("ij,ij->i", m, radial)) < 0.0:
        T = T[:, [0, 2, 1]]
    return transform_to_axis(V, center, axis), np.ascontiguousarray(T)


def write_surface(path: str, vertices: np.ndarray, triangles: np.ndarray) -> str:
    """Write a triangle surface with meshio; the format follows the extension (.msh = gmsh 2.2
    ASCII, .stl = binary STL, .obj, .vtk, ...). Returns ``path``."""

    mesh = meshio.Mesh(np.asarray(vertices, dtype=np.float64),
                       [("triangle", np.asarray(triangles, dtype=np.int64))])
    ext = os.path.splitext(path)[1].lower()
    if ext == ".msh":
        ntri = len(triangles)
        mesh.cell_data = {"gmsh:physical": [np.ones(ntri, dtype=np.int32)],
                          "gmsh:geometrical": [np.ones(ntri, dtype=np.int32)]}
        meshio.write(path, mesh, file_format="gmsh22", binary=False)
    elif ext == ".stl":
        meshio.write(path, mesh, file_format="stl", binary=True)
    else:
        meshio.write(path, mesh)
    return path


def main(argv=None) -> None:
    """Write coarse and fine R = 5 mm cylinder tool meshes (.msh and .stl) into a directory."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("outdir", help="output directory (created if needed)")
    ap.add_argument("--radius", type=float, default=5.0)
    ap.add_argument("--length", type=float, default=20.0)
    ap.add_argument("--coarse", type=float, default=1.7, help="coarse facet size [mm]")
    ap.add_argument("--fine", type=float, default=0.4, help="fine facet size [mm]")
    ap.add_argument("--structured", action="store_true",
                    help="also write the open extruded (structured) cylinders")
    args = ap.parse_args(argv)
    os.makedirs(args.outdir, exist_ok=True)
    for label, h in (("coarse", args.coarse), ("fine", args.fine)):
        V, T = cylinder_surface(args.radius, args.length, h)
        stem = os.path.join(args.outdir, f"cylinder_R{args.radius:g}_{label}")
        for ext in (".msh", ".stl"):
            write_surface(stem + ext, V, T)
        print(f"{stem}.{{msh,stl}}: {V.shape[0]} vertices, {T.shape[0]} triangles, h = {h} mm")
        if args.structured:
            V, T = extruded_cylinder_surface(args.radius, args.length, h)
            for ext in (".msh", ".stl"):
                write_surface(f"{stem}_structured{ext}", V, T)
            print(f"{stem}_structured.{{msh,stl}}: {V.shape[0]} vertices, {T.shape[0]} "
                  f"triangles, open")


if __name__ == "__main__":
    main()
