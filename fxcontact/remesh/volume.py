"""A new tetrahedral mesh of a body from its triangulated boundary, made by gmsh on rank 0 and
distributed (as the workpiece builders of :mod:`fxcontact.meshing` do).

The boundary (:class:`~fxcontact.remesh.surface.BoundarySurface`) is cut into patches: the
triangles of one facet tag connected across edges whose dihedral angle is below
``feature_angle``. Each patch becomes a gmsh discrete surface, with its boundary curves and
corners (the sharp edges and the tag boundaries are kept as curves) made in a reproducible order
(:mod:`fxcontact.remesh.topology`: gmsh's ``createTopology`` numbers them differently in each
session, and its meshes differ), and ``createGeometry`` a parametrisation of each patch on its
old triangles, so that the new surface nodes lie on the old surface and the patches are remeshed
at the new sizes. Nodes of planar patches (symmetry planes, flat die faces) are then projected
onto the patch's plane, or the intersection of the planes they lie on, so those faces stay
exactly planar. The nodes of the
curved patches would lie on the old chords (a face of radius R remeshed at size h loses up to
h²/(8R) of its radius each time): they are moved onto Nagata patches of the old boundary built
on nodal normals fitted within each patch (:mod:`fxcontact.remesh.smooth`; ``smooth=False``
leaves them on the facets). Last, all the surface nodes but those on two planes move along their
normals by one common offset so that the new mesh has the old volume: with the smoothing that
offset is the change of the facets' mean gap to the smooth surface (2.6e-5 of the radius of a
cylinder remeshed 5 times at h = R/10), on the chords it is the whole loss of volume.

The element size is ``h`` away from the tools and ``zone.h + zone.grading × distance`` near a
:class:`SizeZone` (the distance to its points or its box): graded, finer where the tools bite.
gmsh evaluates it with its own fields (:func:`size_fields`), not by calling Python.

gmsh's mesh of a given boundary is the same every time; if it has a cell of quality below
:data:`MIN_QUALITY` (a sliver between boundary nodes, which gmsh's optimiser cannot fix), other
2-D algorithms are tried (:data:`GMSH_VARIANTS`) and the best mesh is kept.

Each new boundary surface takes the facet tag that most of its triangles' nearest old
triangles carry (the old facet nearest to each new facet's centroid).
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass
from typing import Optional, Sequence

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from fxcontact import compat
from fxcontact.collective import together
from fxcontact.mesh_health import simplex_measures
from fxcontact.meshing import gmsh_session
from fxcontact.remesh.smooth import SmoothBoundary, place_surface_nodes
from fxcontact.remesh.surface import UNTAGGED, BoundarySurface
from fxcontact.remesh.topology import discrete_model

__all__ = ["SizeZone", "size_field", "size_fields", "surface_patches", "volume_mesh", "CELL_TAG"]

log = logging.getLogger(__name__)

#: the cell tag of the new mesh's volume
CELL_TAG = 1

#: a patch within this fraction of the body's diameter of a plane is planar (kept planar,
#: its nodes moved within the plane only)
PLANAR_TOLERANCE = 1e-4

#: gmsh's options of the meshes tried in turn until one has no cell of quality below
#: MIN_QUALITY: its defaults (Frontal-Delaunay 2-D, Delaunay 3-D), then Delaunay, then MeshAdapt
#: in 2-D (set in full: gmsh's options are global; HXT in 3-D is left out: its meshes differ
#: from run to run). gmsh optimises the cells that have an inner node but cannot fix a sliver
#: whose four nodes are on the boundary (two symmetry planes meeting at the axis of a 45° sector
#: gave one of quality 0.014 in the upsetting test; 2-D Delaunay gave 0.32 there, MeshAdapt 0.41)
GMSH_VARIANTS = ({"Mesh.Algorithm": 6, "Mesh.Algorithm3D": 1},
                 {"Mesh.Algorithm": 5, "Mesh.Algorithm3D": 1},
                 {"Mesh.Algorithm": 1, "Mesh.Algorithm3D": 1})

#: the smallest cell quality (:func:`~fxcontact.mesh_health.simplex_measures`) accepted without
#: trying gmsh's other options
MIN_QUALITY = 0.1

#: a cell that the smoothing leaves with less than this fraction of its volume (or inverted)
#: gets its nodes back on the old facets
MIN_VOLUME_KEPT = 0.1

#: size the elements by :func:`_size_callback` instead of gmsh's fields (:func:`size_fields`):
#: the same sizes, ~100 times slower; for comparisons
SIZE_CALLBACK = False

#: a new surface node within this fraction of the body's diameter of an old triangle lies on it
#: (gmsh puts the nodes of a discrete surface on its old triangles, to rounding)
ON_FACET_TOLERANCE = 1e-6


@dataclass
class SizeZone:
    """A region meshed finer: size ``h`` within it, growing by ``grading`` per unit distance
    away from it (bounded by the mesh's size far away).

    Args:
        h: element size in the zone (> 0).
        points: (n, 3) points (e.g. sample points of a tool's surface, the contact nodes): the
            distance is to the nearest of them.
        box: ``(lower, upper)`` corners of an axis-aligned box (a mesh box around the bite):
            the distance is 0 inside.
        grading: growth of the size per unit distance (0.3: +30 % of the distance).
    """

    h: float
    points: Optional[np.ndarray] = None
    box: Optional[Sequence] = None
    grading: float = 0.3

    def __post_init__(self):
        if not (np.isfinite(self.h) and self.h > 0):
            raise ValueError(f"SizeZone: h must be > 0, got {self.h!r}")
        if not (np.isfinite(self.grading) and self.grading >= 0):
            raise ValueError(f"SizeZone: grading must be >= 0, got {self.grading!r}")
        if (self.points is None) == (self.box is None):
            raise ValueError("SizeZone: give either points= or box= (one of them)")
        if self.points is not None:
            self.points = np.asarray(self.points, dtype=float).reshape(-1, 3)
            if len(self.points) == 0:
                raise ValueError("SizeZone: points= is empty: give at least one point")
        else:
            lo, hi = (np.asarray(b, dtype=float) for b in self.box)
            if lo.shape != (3,) or hi.shape != (3,) or np.any(hi < lo):
                raise ValueError(f"SizeZone: box must be (lower, upper) corners with lower <= "
                                 f"upper, got {self.box!r}")
            self.box = (lo, hi)

    def distance(self, x: np.ndarray) -> np.ndarray:
        """(n,) distance of the points x (n, 3) to the zone."""
        if self.points is not None:
            if not hasattr(self, "_tree"):
                self._tree = cKDTree(self.points)
            return self._tree.query(x)[0]
        lo, hi = self.box
        return np.linalg.norm(np.maximum(np.maximum(lo - x, x - hi), 0.0), axis=1)


def size_field(x: np.ndarray, h: float, zones: Sequence[SizeZone] = ()) -> np.ndarray:
    """(n,) element size at the points x (n, 3): ``min(h, min_k(h_k + g_k d_k(x)))``."""
    x = np.atleast_2d(np.asarray(x, dtype=float))
    out = np.full(len(x), float(h))
    for z in zones:
        out = np.minimum(out, z.h + z.grading * z.distance(x))
    return out


def surface_patches(surface: BoundarySurface, feature_angle: float = 40.0) -> np.ndarray:
    """(m,) patch number of each triangle: the triangles of one tag connected across edges
    whose dihedral angle (between the outward normals) is below ``feature_angle`` degrees."""
    T = surface.triangles
    m = len(T)
    edges = np.sort(np.concatenate([T[:, [0, 1]], T[:, [1, 2]], T[:, [2, 0]]]), axis=1)
    owner = np.tile(np.arange(m), 3)
    order = np.lexsort(edges.T[::-1])
    e, o = edges[order], owner[order]
    same = np.all(e[1:] == e[:-1], axis=1)
    a, b = o[:-1][same], o[1:][same]
    n = surface.normals()
    smooth = (np.einsum("ij,ij->i", n[a], n[b]) >= np.cos(np.radians(feature_angle))) \
        & (surface.tags[a] == surface.tags[b])
    g = coo_matrix((np.ones(int(smooth.sum())), (a[smooth], b[smooth])), shape=(m, m))
    return connected_components(g, directed=False)[1]


def _patch_planes(surface: BoundarySurface, patches: np.ndarray, tol: float):
    """{patch: (unit normal, offset)} of the planar patches (every vertex within ``tol`` of the
    least-squares plane)."""
    out = {}
    for p in np.unique(patches):
        P = surface.points[np.unique(surface.triangles[patches == p])]
        c = P.mean(axis=0)
        _, s, vt = np.linalg.svd(P - c, full_matrices=False)
        nrm = vt[-1]
        if np.max(np.abs((P - c) @ nrm)) <= tol:
            # an axis plane stays an axis plane exactly
            k = np.argmax(np.abs(nrm))
            if np.all(np.abs(np.delete(nrm, k)) < 1e-12):
                nrm = np.eye(3)[k] * np.sign(nrm[k])
            out[int(p)] = (nrm, float(nrm @ c))
    return out


def _size_callback(h: float, zones):
    """gmsh's size callback (gmsh 4.8: ``f(dim, tag, x, y, z)``): :func:`size_field` called by
    gmsh point by point, slow (a Python call per sample: 5.0 s against 0.74 s with the fields
    for the ring of ``benchmarks/bench_remesh.py --generate``); kept to check
    :func:`size_fields` against. An exception inside a ctypes callback would abort the
    process, so a failure gives ``h`` and is logged once."""
    failed = []

    def size(*args):
        x, y, z = args[2:5]
        try:
            return float(size_field(np.array([[x, y, z]]), h, zones)[0])
        except Exception as e:   # never propagate into gmsh
            if not failed:
                failed.append(e)
                log.warning("remesh size field failed at (%g, %g, %g): %s", x, y, z, e)
            return float(h)
    return size


def size_fields(gmsh, h: float, zones: Sequence[SizeZone]) -> list:
    """Make :func:`size_field` gmsh's background mesh size with gmsh's own fields (on rank 0,
    in the current model, synchronised): a "MathEval" field ``h``; per box zone a "Box" field
    (``VIn`` = h_k, ``VOut`` = h, a linear transition over ``Thickness`` = (h − h_k)/g_k:
    h_k + g_k d up to h); per point zone a "Distance" field to its points, added as geometry
    points, and a "Threshold" field (h_k at distance 0 to h at (h − h_k)/g_k); their "Min".
    A zone with h_k ≥ h changes nothing; one with g_k = 0 is the constant h_k.

    Returns the tags of the geometry points added: remove them (and their mesh node) after
    meshing (:func:`_remove_points`)."""
    F = gmsh.model.mesh.field

    def constant(v):
        f = F.add("MathEval")
        F.setString(f, "F", repr(float(v)))
        return f

    fields, points = [constant(h)], []
    next_tag = max([t for _, t in gmsh.model.getEntities(0)], default=0) + 1
    for z in zones:
        if z.h >= h:
            continue
        if z.grading == 0.0:
            fields.append(constant(z.h))
            continue
        reach = (h - z.h) / z.grading
        if z.box is not None:
            f = F.add("Box")
            for name, v in zip(("XMin", "YMin", "ZMin", "XMax", "YMax", "ZMax"),
                               np.concatenate(z.box)):
                F.setNumber(f, name, float(v))
            F.setNumber(f, "VIn", float(z.h))
            F.setNumber(f, "VOut", float(h))
            F.setNumber(f, "Thickness", float(reach))
        else:
            tags = list(range(next_tag, next_tag + len(z.points)))
            next_tag += len(z.points)
            for t, x in zip(tags, z.points):
                gmsh.model.geo.addPoint(float(x[0]), float(x[1]), float(x[2]), tag=t)
            points += tags
            d = F.add("Distance")
            F.setNumbers(d, "PointsList", tags)
            f = F.add("Threshold")
            F.setNumber(f, "InField", d)
            F.setNumber(f, "DistMin", 0.0)
            F.setNumber(f, "DistMax", float(reach))
            F.setNumber(f, "SizeMin", float(z.h))
            F.setNumber(f, "SizeMax", float(h))
        fields.append(f)
    f = F.add("Min")
    F.setNumbers(f, "FieldsList", fields)
    F.setAsBackgroundMesh(f)
    gmsh.model.geo.synchronize()
    return points


def _remove_points(gmsh, points: list):
    """Remove the geometry points of :func:`size_fields` and their mesh nodes; node tags
    made contiguous again."""
    if points:
        tags = [(0, t) for t in points]
        gmsh.model.mesh.clear(tags)
        gmsh.model.removeEntities(tags)
        gmsh.model.mesh.renumberNodes()


def _build_on_root(gmsh, surface: BoundarySurface, h: float, zones, feature_angle: float,
                   optimize: bool, smooth: bool = True, options: Optional[dict] = None) -> float:
    """The new mesh in gmsh's current model (gmsh ``options`` set first); returns its smallest
    cell quality (:func:`~fxcontact.mesh_health.simplex_measures`)."""
    patches = surface_patches(surface, feature_angle)
    diam = np.linalg.norm(np.ptp(surface.points, axis=0))
    # planar to 1e-4 of the body's size: a face pressed by a flat tool is planar to its
    # penetration only, and must not be pushed into the tool by the volume restoration
    planes = _patch_planes(surface, patches, PLANAR_TOLERANCE * diam)
    ids = np.unique(patches)
    if not discrete_model(gmsh, surface.points, surface.triangles, patches):
        # not a closed manifold, or patches touching at a vertex only: gmsh's own topology
        # (its meshes are then not reproducible)
        log.info("volume_mesh: the boundary's curves and corners are left to gmsh")
        node_tags = np.arange(1, len(surface.points) + 1)
        for p in ids:
            gmsh.model.addDiscreteEntity(2, int(p) + 1)
        gmsh.model.mesh.addNodes(2, int(ids[0]) + 1, node_tags, surface.points.ravel())
        etag = 1
        for p in ids:
            tri = surface.triangles[patches == p]
            gmsh.model.mesh.addElementsByType(int(p) + 1, 2, np.arange(etag, etag + len(tri)),
                                              (tri + 1).ravel())
            etag += len(tri)
        gmsh.model.mesh.createTopology()
    gmsh.model.mesh.createGeometry()
    surfs = [t for _, t in gmsh.model.getEntities(2)]
    loop = gmsh.model.geo.addSurfaceLoop(surfs)
    gmsh.model.geo.addVolume([loop])
    gmsh.model.geo.synchronize()
    gmsh.option.setNumber("Mesh.MeshSizeExtendFromBoundary", 0)
    gmsh.option.setNumber("Mesh.MeshSizeFromPoints", 0)
    gmsh.option.setNumber("Mesh.MeshSizeFromCurvature", 0)
    gmsh.option.setNumber("Mesh.Optimize", 1 if optimize else 0)
    gmsh.option.setNumber("General.NumThreads", 1)   # the same mesh every time (with the
    # reproducible topology of discrete_model)
    for key, value in (options or {}).items():
        gmsh.option.setNumber(key, value)
    if SIZE_CALLBACK:
        gmsh.model.mesh.setSizeCallback(_size_callback(h, zones))
        points = []
    else:
        points = size_fields(gmsh, h, zones)
    gmsh.model.mesh.generate(3)
    _remove_points(gmsh, points)
    origin = _entity_patches(gmsh, surface, patches)
    curved = [int(p) for p in ids if int(p) not in planes]
    rebuilt = SmoothBoundary(surface.points, surface.triangles, patches, curved) \
        if smooth and curved else None
    _, X, tets = _tetrahedra(gmsh)
    generated = simplex_measures(X[tets])[0]
    on_planes, flat = place_surface_nodes(gmsh, origin, planes, rebuilt,
                                          ON_FACET_TOLERANCE * diam)
    _unflatten(gmsh, flat, generated)
    for _ in range(2):
        _restore_volume(gmsh, surface.enclosed_volume(), on_planes)
    groups = {}
    for s, p in origin.items():
        groups.setdefault(int(surface.tags[np.flatnonzero(patches == p)[0]]), []).append(s)
    for tag, ss in sorted(groups.items()):
        if tag != UNTAGGED:
            gmsh.model.addPhysicalGroup(2, ss, tag)
    gmsh.model.addPhysicalGroup(3, [t for _, t in gmsh.model.getEntities(3)], CELL_TAG)
    _, X, tets = _tetrahedra(gmsh)
    return float(np.min(simplex_measures(X[tets])[1]))


def _entity_patches(gmsh, surface: BoundarySurface, patches: np.ndarray) -> dict:
    """{new surface entity: the old patch it lies on}: the patch that most of the nearest old
    triangles of its triangles' centroids belong to."""
    tags, xyz, _ = gmsh.model.mesh.getNodes()
    lookup = np.zeros(int(tags.max()) + 1, dtype=np.int64)
    lookup[tags.astype(np.int64)] = np.arange(len(tags))
    X = xyz.reshape(-1, 3)
    tree = cKDTree(surface.points[surface.triangles].mean(axis=1))
    out = {}
    for _, s in gmsh.model.getEntities(2):
        _, _, enodes = gmsh.model.mesh.getElements(2, s)
        if len(enodes) and len(enodes[0]):
            c = X[lookup[np.asarray(enodes[0], dtype=np.int64)]].reshape(-1, 3, 3).mean(axis=1)
            vals, counts = np.unique(patches[tree.query(c)[1]], return_counts=True)
            out[s] = int(vals[np.argmax(counts)])
    return out


def _tetrahedra(gmsh):
    """(node tags (n,), coordinates (n, 3), tetrahedra (m, 4) as rows of those)."""
    tags, xyz, _ = gmsh.model.mesh.getNodes()
    lookup = np.zeros(int(tags.max()) + 1, dtype=np.int64)
    lookup[tags.astype(np.int64)] = np.arange(len(tags))
    _, _, enodes = gmsh.model.mesh.getElements(3)
    return tags, xyz.reshape(-1, 3), lookup[np.asarray(enodes[0], dtype=np.int64).reshape(-1, 4)]


def boundary_faces(X: np.ndarray, tets: np.ndarray) -> np.ndarray:
    """(k, 3) the faces of the tetrahedra that belong to one only, oriented outward."""
    F = np.concatenate([tets[:, [1, 2, 3]], tets[:, [0, 3, 2]], tets[:, [0, 1, 3]],
                        tets[:, [0, 2, 1]]])
    opp = np.concatenate([tets[:, 0], tets[:, 1], tets[:, 2], tets[:, 3]])
    _, inv, cnt = np.unique(np.sort(F, axis=1), axis=0, return_inverse=True, return_counts=True)
    once = cnt[inv.ravel()] == 1
    F, opp = F[once], opp[once]
    P = X[F]
    inward = np.einsum("ij,ij->i", np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0]),
                       X[opp] - P[:, 0]) > 0
    F[inward] = F[inward][:, [0, 2, 1]]
    return F


def _unflatten(gmsh, flat: dict, generated: np.ndarray, rounds: int = 5) -> int:
    """Put back on the old facets (``flat``: {node tag: position}) the smoothed nodes of the
    cells the smoothing flattened or turned inside out (volume below :data:`MIN_VOLUME_KEPT`
    of gmsh's, ``generated``): a sliver lying along a curved face can flip when its nodes move
    onto the smooth surface. Returns the number of nodes put back."""
    back = 0
    for _ in range(rounds):
        tags, X, tets = _tetrahedra(gmsh)
        bad = simplex_measures(X[tets])[0] < MIN_VOLUME_KEPT * generated
        nodes = [t for t in np.unique(tags[tets[bad]]).tolist() if t in flat]
        if not nodes:
            break
        for t in nodes:
            gmsh.model.mesh.setNode(int(t), list(flat.pop(t)), [])
        back += len(nodes)
    if back:
        log.info("remesh smoothing: %d nodes of flattened cells left on the old facets", back)
    return back


def _restore_volume(gmsh, volume: float, on_planes):
    """Move the surface nodes along their normals (within their planes for nodes on planar
    patches) by the one offset that gives the new surface the old enclosed ``volume``: the new
    nodes lie on the old facets, so a remeshed convex surface cuts its creases and loses volume
    (≈ h²/(8R) × area); the offset puts them back between the old facets and the smooth surface
    they approximate. Nodes on two planes or more (a sector's axis) stay."""
    tags, X, tets = _tetrahedra(gmsh)
    dV = volume - np.sum(np.abs(simplex_measures(X[tets])[0]))
    T = boundary_faces(X, tets)
    P = X[T]
    an = 0.5 * np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0])     # area-weighted normals
    N = np.zeros_like(X)
    for k in range(3):
        np.add.at(N, T[:, k], an / 3.0)
    planar = np.zeros(len(X), dtype=bool)
    for i, t in enumerate(tags.tolist()):
        pl = on_planes.get(t)
        if pl:
            if len(pl) > 1:
                N[i] = 0.0
            else:
                nrm = pl[0][0]
                N[i] -= (N[i] @ nrm) * nrm
            planar[i] = True
    # dV ≈ δ Σ_i N_i · n̂_i |...|: the volume swept by moving node i by δ n̂_i is N_i · n̂_i δ
    length = np.linalg.norm(N, axis=1)
    move = length > 1e-14 * max(length.max(), 1e-300)
    u = np.zeros_like(N)
    u[move] = N[move] / length[move, None]
    rate = np.sum(np.einsum("ij,ij->i", N, u))
    if rate <= 0 or not np.isfinite(dV):
        return
    delta = dV / rate
    for i in np.flatnonzero(move):
        gmsh.model.mesh.setNode(int(tags[i]), (X[i] + delta * u[i]).tolist(), [])


def _best_variant(gmsh, surface, h, zones, feature_angle, optimize, smooth):
    """The mesh of the first of :data:`GMSH_VARIANTS` whose smallest cell quality reaches
    :data:`MIN_QUALITY`, else the best of them, as gmsh's current model (each variant in a model
    of its own, the others removed)."""
    best = None
    for k, options in enumerate(GMSH_VARIANTS):
        if k:
            gmsh.model.add(f"remesh variant {k}")
        q = _build_on_root(gmsh, surface, h, zones, feature_angle, optimize, smooth, options)
        name = gmsh.model.getCurrent()
        if best is None or q > best[0]:
            if best is not None:
                gmsh.model.setCurrent(best[1])
                gmsh.model.remove()
            best = (q, name)
        else:
            gmsh.model.remove()
        if q >= MIN_QUALITY:
            break
        log.info("volume_mesh: gmsh's mesh with %s has a cell of quality %.3f", options, q)
    gmsh.model.setCurrent(best[1])


def volume_mesh(comm, surface: BoundarySurface, h: float, zones: Sequence[SizeZone] = (),
                feature_angle: float = 40.0, optimize: bool = True, root: int = 0,
                times: Optional[dict] = None, smooth: bool = True):
    """A tetrahedral mesh of the body bounded by ``surface`` (given on ``root``), made there by
    gmsh and distributed over ``comm`` (collective; module docstring).

    Args:
        surface: the boundary (:func:`~fxcontact.remesh.surface.gather_boundary`).
        h: element size away from the zones (> 0).
        zones: :class:`SizeZone` s where the mesh is finer (near the tools).
        feature_angle: edges whose dihedral angle exceeds it (degrees) are kept as sharp edges.
        optimize: gmsh's tetrahedron optimisation.
        smooth: put the new nodes of the curved patches on a Nagata reconstruction of the
            old surface (:mod:`fxcontact.remesh.smooth`) instead of its facets.
        times: a dict that receives this rank's wall times of ``generate`` (gmsh, on
            ``root``) and ``distribute`` (the mesh over ``comm``).
    Returns:
        ``(mesh, cell_tags, facet_tags)``; the facet tags are those of the old boundary.
    """
    with together(comm, "volume_mesh()", h=h, feature_angle=feature_angle):
        if not (np.isfinite(h) and h > 0):
            raise ValueError(f"volume_mesh: h must be > 0, got {h!r}")
        if not 0.0 < feature_angle < 180.0:
            raise ValueError(f"volume_mesh: feature_angle must be in (0, 180) degrees, got "
                             f"{feature_angle!r}")
    times = {} if times is None else times
    t0 = time.perf_counter()
    for attempt in (1, 2):
        # gmsh 4.8 has refused a boundary once ("overlapping facets") and meshed it when asked
        # again with the same input: one more attempt in a fresh session before giving up
        with gmsh_session("remesh") as gmsh:
            err = None
            if comm.rank == root:
                try:
                    _best_variant(gmsh, surface, h, list(zones), feature_angle, optimize,
                                  smooth)
                except Exception as e:   # gmsh's errors are plain Exceptions
                    err = f"{type(e).__name__}: {e}"
            err = comm.bcast(err, root=root)
            if err is None:
                t1 = time.perf_counter()
                out = compat.model_to_mesh(gmsh.model, comm, root, gdim=3)
                times.update(generate=t1 - t0, distribute=time.perf_counter() - t1)
                return out
        if attempt == 1:
            log.warning("volume_mesh: gmsh failed (%s); trying once more", err)
    raise RuntimeError(f"volume_mesh: gmsh failed to mesh the boundary twice ({err}): a "
                       f"boundary that is not closed or intersects itself, or a size too large "
                       f"for its thinnest part; try a smaller h or feature_angle")
