"""Faceted rigid tools: triangulated surfaces, flat (Forge) or Nagata-smoothed (THEORY §6–8).

:class:`FacetedTool` projects points on a triangle mesh in one of two modes:

* ``"flat"`` — Forge's model: the closest facet (by true point–triangle distance, Ericson's
  Voronoi-region algorithm) is selected and the gap is the signed distance to *its plane*, the
  normal its facet normal, the gap Hessian zero.
* ``"nagata"`` — projection on the Nagata patches (§7.4) built from nodal normals (§8, Normal
  Vector Voting with crease-preserving per-(facet, vertex) normals by default), with the exact
  gap gradient and Hessian (§7.5), so that the ``implicit-exact`` scheme can be used.

The per-point work runs in ``numba.njit(cache=True)`` kernels; each has a plain numpy/Python
twin (suffix ``_ref``, reference implementation, for testing only).

Candidate search (both modes) — exact branch and bound over a box hierarchy. The hierarchy is
the node structure of a :class:`scipy.spatial.cKDTree` built on the facet centroids (library
construction, ``leafsize`` facets per leaf), refitted with the axis-aligned boxes of the facets
of each node and the largest Nagata inflation ``δ_f = max_k|c_k|/3`` of its facets (§7.2; 0 in
flat mode). For each point, a numba kernel visits the nodes nearest child first and keeps

    U = min_f (d_f + δ_f),   d_f = exact point–triangle distance (Ericson),

an upper bound of the distance to the surface; a node (or a facet, by its bounding sphere) is
pruned when its distance minus its inflation exceeds ``U``. The surviving facets
(``d_f − δ_f ≤ U``, typically 1–6 near the surface) are exactly those whose flat triangle or
Nagata patch can hold the closest point (§7.6). No candidate list is ever materialised in Python
and there is no search cut-off: **every point, however far, gets its exact (flat or patch)
distance and sign** — there is no sentinel value. The cost is logarithmic near the surface;
for a far point it grows with the area of the surface lying within a facet size of the
distance sphere (≈ 0.05–0.1 ms per point 5–20 mm away from a 10^5-facet R = 5 mm cylinder),
which is acceptable because the contact layer mostly projects nodes close to the tool.

Sign: the surface must be consistently oriented (counter-clockwise about the normal pointing to
free space). For a **closed** surface this is the outward normal and the signed volume must be
positive (use ``flip=True`` for inward-oriented meshes). **Open** surfaces (a die insert, a roll
barrel) are legal: free space is the side the oriented facet normals point to, the other side is
the tool. In flat mode the sign is that of the angle-weighted pseudo-normal of the closest
feature (Bærentzen–Aanæs: facet, edge or vertex), which is exact on closed surfaces; among
facets tied at the minimum distance, the one whose plane distance has this sign and the largest
magnitude is selected, so the Forge plane gap never has the wrong sign (|gap| ≤ true distance,
equal in face regions). In Nagata mode the sign of an interior projection is that of
``(p − x*)·n*``; for a projection on a patch edge or vertex it uses the sum of the patch normals
meeting there (edge) or the angle-weighted patch normals (vertex). Points beyond the boundary of
an open surface are in free space when they lie on the normal side of its boundary facets.
"""

from __future__ import annotations

import logging
import math
import os
from typing import Optional, Tuple

import numpy as np
from scipy.spatial import cKDTree

from fxcontact.console import ALL_RANKS
from fxcontact.tools.base import Projection, RigidMotion, Tool, as_points
from fxcontact.tools.faceted_input import CheckedSurface, check_surface, read_surface
from fxcontact.tools.faceted_projection import (flat_kernel, flat_project_ref, nagata_kernel,
                                                nagata_project_ref)
from fxcontact.tools.faceted_search import (candidates_kernel, closest_point_triangle,
                                            closest_point_triangle_nb, closest_point_triangle_ref,
                                            kdtree_hierarchy, refit_boxes)
from fxcontact.tools.nagata import (patch_derivatives, patch_edge_coefficients, patch_monomials,
                                    patch_normals)
from fxcontact.tools.normals import (FacetVertexNormals, corner_angles, facet_normals,
                                     facet_vertex_normals)
from fxcontact.tools.revolved import RevolvedProfile, faceted_revolved

__all__ = [
    "FacetedTool",
    "CheckedSurface",
    "check_surface",
    "read_surface",
    "closest_point_triangle",
    "closest_point_triangle_nb",
    "closest_point_triangle_ref",
    "flat_project_ref",
    "nagata_project_ref",
    "FLAG_OK",
    "FLAG_FALLBACK",
    "REGION_FACE",
]

logger = logging.getLogger(__name__)

#: Projection flags.
FLAG_OK = 0
FLAG_FALLBACK = 1  #: Nagata projection did not converge; the flat projection was used.

#: Closest-point regions of a triangle: 0 face, 1 + k vertex k, 4 + k local edge k
#: (:data:`fxcontact.tools.normals.LOCAL_EDGES`).
REGION_FACE = 0


# ------------------------------------------------------------------------------------------
# The tool
# ------------------------------------------------------------------------------------------


class FacetedTool(Tool):
    """A rigid tool given by a triangulated surface, flat (Forge) or Nagata-smoothed.

    Args:
        vertices: (N, 3) vertex coordinates in the reference frame (t = 0).
        triangles: (M, 3) vertex indices, counter-clockwise about the normal pointing to free
            space (the outward normal of a closed tool). Open surfaces are legal: free space is
            the side the oriented normals point to.
        mode: ``"nagata"`` (smoothed patches, exact gap Hessian) or ``"flat"`` (Forge: plane of
            the closest facet, Hessian 0).
        normals: nodal normals for the Nagata patches: ``"nvv"`` (Normal Vector Voting,
            crease-preserving, default), ``"angle"``, ``"area"`` (weighted averages, creases
            smeared), or an array of (N, 3) vertex normals or (M, 3, 3) per-(facet, vertex)
            normals (e.g. from CAD). Ignored in flat mode.
        crease_angle: NVV crease angle φc [rad] (§8.2); ``None`` disables crease detection.
        flip: reverse every triangle (for meshes oriented inward).
        velocity, angular_velocity, axis_point, axis: the rigid motion
            (:class:`~fxcontact.tools.base.RigidMotion`).
        name: label.
        kappa: Nagata safeguard κ: edge coefficients with |c| > κ|d| are zeroed (§7.1).
        max_iter: Newton iterations per patch projection (§7.4).
        max_halvings: step halvings per Newton iteration (sub-incrementation).
        leafsize: facets per leaf of the search hierarchy (tuning only; results do not depend
            on it).

    Attributes:
        last_fallbacks: number of points of the last projection for which the Nagata projection
            did not converge and the flat projection was used (``flag == 1``); also logged as a
            warning. ``total_fallbacks`` accumulates over all projections.
        closed: whether the surface is closed.
        has_hessian: True in both modes (zero in flat mode).

    Projection fields: ``gap``/``normal``/``hessian`` as in :class:`~fxcontact.tools.base.
    Projection`; ``point`` is the closest patch point (Nagata) or the foot ``p − gap n`` on the
    chosen facet plane (flat); ``feature`` is the index of the chosen facet/patch (triangle order
    is that of the input); ``flag`` is 1 for a flat fall-back. For a projection on a patch
    edge or vertex (sharp creases, open boundaries) the normal is ``(p − x*)/d`` and the Hessian
    the distance-to-curve / distance-to-point one. See the module docstring for the candidate
    search and the sign conventions.
    """

    has_hessian = True

    def __init__(self, vertices, triangles, mode: str = "nagata", normals="nvv",
                 crease_angle: Optional[float] = math.radians(50.0), flip: bool = False,
                 velocity=(0.0, 0.0, 0.0), angular_velocity=0.0, axis_point=(0.0, 0.0, 0.0),
                 axis=(0.0, 0.0, 1.0), name: str = "faceted", kappa: float = 1.0,
                 max_iter: int = 30, max_halvings: int = 12, leafsize: int = 4):
        if mode not in ("nagata", "flat"):
            raise ValueError(f"mode must be 'nagata' or 'flat', got {mode!r}")
        if int(max_iter) < 0 or int(max_halvings) < 0:
            raise ValueError("max_iter and max_halvings must be >= 0")
        self.mode = mode
        self.name = name
        self.motion = RigidMotion(velocity, angular_velocity, axis_point, axis)
        self.max_iter = int(max_iter)
        self.max_halvings = int(max_halvings)
        self.kappa = float(kappa)
        self.crease_angle = crease_angle
        self.last_fallbacks = 0
        self.total_fallbacks = 0
        n_in = np.asarray(vertices).shape[0] if np.ndim(vertices) == 2 else -1
        surf = check_surface(vertices, triangles, flip=flip)
        self.surface = surf
        self.closed = surf.closed
        V, T = surf.vertices, surf.triangles
        self._V = np.ascontiguousarray(V)
        self._T = np.ascontiguousarray(T)
        topo = surf.topology
        self._fn, self._area = facet_normals(V, T)
        ang = corner_angles(V, T)
        # flat pseudo-normals (Bærentzen–Aanæs): edges n_f + n_g, vertices angle-weighted
        nbr = topo.neighbor
        self._nbr = np.ascontiguousarray(nbr)
        self._nbr_edge = np.ascontiguousarray(topo.neighbor_edge)
        epn = np.repeat(self._fn[:, None, :], 3, axis=1)
        epn = epn + np.where((nbr >= 0)[:, :, None], self._fn[np.maximum(nbr, 0)], 0.0)
        self._epn = np.ascontiguousarray(epn)
        self._vpn = self._vertex_sum(ang, np.repeat(self._fn[:, None, :], 3, axis=1))
        centroids = V[T].mean(axis=1)
        self._tie_scale = float(np.max(np.abs(V)) + np.linalg.norm(V.max(0) - V.min(0)))
        tree = cKDTree(centroids, leafsize=int(leafsize))
        self._perm = np.ascontiguousarray(tree.indices, dtype=np.int64)
        self._left, self._right, self._nstart, self._nend, self._depth = kdtree_hierarchy(tree)
        # facet data in leaf order: vertices, bounding-sphere centre and radius
        self._tv = np.ascontiguousarray(V[T[self._perm]])
        self._cen = np.ascontiguousarray(centroids[self._perm])
        self._rad = np.linalg.norm(self._tv - self._cen[:, None, :], axis=2).max(axis=1)
        self.fvn: Optional[FacetVertexNormals] = None
        if mode == "nagata":
            if not isinstance(normals, str):
                arr = np.asarray(normals, dtype=np.float64)
                if arr.ndim == 2 and arr.shape[0] == n_in and arr.shape[1] == 3:
                    arr = arr[surf.vertex_map]
                normals = arr
            self.fvn = facet_vertex_normals(V, T, normals, crease_angle=crease_angle,
                                            topology=topo)
            C = patch_edge_coefficients(V, T, self.fvn, kappa=self.kappa)
            self._C = C
            self._A = patch_monomials(V, T, C)
            self._infl = np.max(np.linalg.norm(C, axis=2), axis=1) / 3.0
            self._infl = self._infl * (1.0 + 1e-12) + 1e-15 * self._tie_scale
            # Nagata vertex pseudo-normals: angle-weighted patch normals at the corners
            xi = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0]])
            corner_n = np.stack([patch_normals(self._A, xi[k, 0], xi[k, 1]) for k in range(3)],
                                axis=1)
            degenerate = np.linalg.norm(corner_n, axis=2) == 0.0  # collapsed corner tangents
            corner_n[degenerate] = np.repeat(self._fn[:, None, :], 3, axis=1)[degenerate]
            self._npn = self._vertex_sum(self._patch_corner_angles(), corner_n)
        else:
            self._C = np.zeros((T.shape[0], 3, 3))
            self._A = patch_monomials(V, T, self._C)
            self._infl = np.zeros(T.shape[0])
            self._npn = self._vpn
        self._blo, self._bhi, self._binfl = refit_boxes(self._left, self._nstart, self._nend,
                                                        self._perm, self._V, self._T,
                                                        self._infl)
        logger.info("%s: %d vertices, %d triangles, %s surface, mode %s, max|c|/3 = %.3g",
                    name, V.shape[0], T.shape[0], "closed" if self.closed else "open", mode,
                    float(self._infl.max()))

    # -- construction helpers ---------------------------------------------------------------

    def _vertex_sum(self, w: np.ndarray, vec: np.ndarray) -> np.ndarray:
        """Sum ``w[f, a] * vec[f, a]`` into the vertices ``T[f, a]``; (N, 3) contiguous."""
        idx = self._T.reshape(-1)
        contrib = (w[:, :, None] * vec).reshape(-1, 3)
        out = np.stack([np.bincount(idx, weights=contrib[:, j], minlength=self._V.shape[0])
                        for j in range(3)], axis=1)
        return np.ascontiguousarray(out)

    def _patch_corner_angles(self) -> np.ndarray:
        A = self._A
        xe0, xz0 = patch_derivatives(A, 0.0, 0.0)
        xe1, xz1 = patch_derivatives(A, 1.0, 0.0)
        xe2, xz2 = patch_derivatives(A, 1.0, 1.0)
        pairs = [(xe0, xe0 + xz0), (-xe1, xz1), (-xz2, -(xe2 + xz2))]
        out = np.empty((A.shape[0], 3))
        for k, (u, w) in enumerate(pairs):
            out[:, k] = np.arctan2(np.linalg.norm(np.cross(u, w), axis=1),
                                   np.einsum("ij,ij->i", u, w))
        return out

    @classmethod
    def from_file(cls, path: str, **kwargs) -> "FacetedTool":
        """Build a tool from a surface mesh file (gmsh .msh, STL, OBJ, ... read with meshio).

        STL files carry no connectivity; meshio merges exactly coincident points, which is
        what CAD exports need. ``kwargs`` are passed to the constructor (``name`` defaults to
        the file name)."""

        V, T = read_surface(path)
        kwargs.setdefault("name", os.path.basename(path))
        return cls(V, T, **kwargs)

    @classmethod
    def from_revolved(cls, tool, n_theta: int, sector=None, ds: Optional[float] = None,
                      max_angle: float = math.radians(10.0), extension: float = 0.0,
                      **kwargs) -> "FacetedTool":
        """Triangulate a :class:`~fxcontact.tools.revolved.RevolvedProfile` (a die, a roll)
        and build the faceted tool in one call, with the analytic tool's motion.

        Args:
            tool: the analytic surface of revolution.
            n_theta, ds, max_angle, extension: as in
                :func:`~fxcontact.tools.revolved.faceted_revolved`.
            sector: None (whole turn) or ``(θ0, θ1)`` in **degrees** about the tool's axis
                (measured from ``tool.e_fixed``, +x for an axis along z), e.g. ``(0, 120)``
                for the die of a one-third model; the triangulation is mirror-symmetric about
                the sector's mid-plane.
            kwargs: passed to the constructor (``mode``, ``normals``, ``crease_angle``, ...;
                ``name`` defaults to the tool's). The motion is the analytic tool's.
        """

        if not isinstance(tool, RevolvedProfile):
            raise ValueError(f"tool must be a RevolvedProfile, got {type(tool).__name__}")
        for key in ("velocity", "angular_velocity", "axis_point", "axis"):
            if key in kwargs:
                raise ValueError(f"{key} comes from the revolved tool's motion; do not pass it")
        if sector is not None:
            try:
                a0, a1 = (float(v) for v in sector)
            except (TypeError, ValueError):
                raise ValueError(f"sector must be (theta0, theta1) in degrees, got "
                                 f"{sector!r}") from None
            sector = (math.radians(a0), math.radians(a1))
        V, T = faceted_revolved(tool, n_theta, sector=sector, ds=ds, max_angle=max_angle,
                                extension=extension)
        kwargs.setdefault("name", tool.name)
        out = cls(V, T, **kwargs)
        out.motion = tool.motion
        return out

    # -- properties ----------------------------------------------------------------------

    @property
    def vertices(self) -> np.ndarray:
        """(N, 3) vertices in the reference frame (read-only view)."""
        v = self._V.view()
        v.flags.writeable = False
        return v

    @property
    def triangles(self) -> np.ndarray:
        """(M, 3) triangles (read-only view)."""
        t = self._T.view()
        t.flags.writeable = False
        return t

    @property
    def facet_normals(self) -> np.ndarray:
        return self._fn

    @property
    def patch_coefficients(self) -> np.ndarray:
        """(M, 3, 3) Nagata edge coefficients (c1, c2, c3) per triangle (zero in flat mode)."""
        return self._C

    @property
    def patches(self) -> np.ndarray:
        """(M, 6, 3) Nagata monomial coefficients (flat triangles in flat mode)."""
        return self._A

    @property
    def vertex_class(self) -> Optional[np.ndarray]:
        """NVV vertex classes (1 surface, 2 crease, 3 corner), ``None`` in flat mode."""
        return None if self.fvn is None else self.fvn.vertex_class

    # -- candidate search ----------------------------------------------------------------

    def _bvh(self):
        return (self._left, self._right, self._nstart, self._nend, self._blo, self._bhi,
                self._binfl, self._perm, self._tv, self._cen, self._rad)

    def candidates(self, y: np.ndarray, flat: bool = False) -> Tuple[np.ndarray, np.ndarray]:
        """Candidate facets/patches of each point (reference frame), CSR ``(ptr, idx)``.

        These are exactly the facets the projection kernels examine: every facet whose flat
        triangle (flat mode or ``flat=True``; then only the facets at the minimum distance) or
        Nagata patch (nagata mode) can hold the closest point (see the module docstring)."""
        y = np.ascontiguousarray(y, dtype=np.float64)
        infl = np.zeros(self._T.shape[0]) if flat else self._infl
        return candidates_kernel(y, *self._bvh(), self._T, infl, self._tie_scale, self._depth)

    # -- projection ----------------------------------------------------------------------

    def flat_signed_distance(self, x, t: float = 0.0) -> np.ndarray:
        """Exact signed distance of points to the flat triangulated surface at time ``t``
        (pseudo-normal sign), independent of the mode."""
        x = as_points(x)
        y = x if self.motion.is_static else self.motion.to_reference(x, t)
        n = y.shape[0]
        out = [np.empty(n), np.empty((n, 3)), np.empty((n, 3)), np.empty(n, dtype=np.int64),
               np.empty(n)]
        flat_kernel(y, *self._bvh(), self._depth, self._V, self._T, self._fn, self._epn,
                    self._vpn, self._tie_scale, *out)
        return out[4]

    def _project_reference(self, y: np.ndarray, hessian: bool) -> Projection:
        n = y.shape[0]
        gap = np.empty(n)
        normal = np.empty((n, 3))
        point = np.empty((n, 3))
        feature = np.empty(n, dtype=np.int64)
        flag = np.zeros(n, dtype=np.int64)
        sdist = np.empty(n)
        if n == 0:
            self.last_fallbacks = 0
            return Projection(gap, normal, point, np.zeros((0, 3, 3)) if hessian else None,
                              feature, flag)
        if self.mode == "flat":
            flat_kernel(y, *self._bvh(), self._depth, self._V, self._T, self._fn, self._epn,
                        self._vpn, self._tie_scale, gap, normal, point, feature, sdist)
            hess = np.zeros((n, 3, 3)) if hessian else None
            self.last_fallbacks = 0
            return Projection(gap, normal, point, hess, feature, flag)
        hess = np.zeros((n, 3, 3)) if hessian else np.zeros((1, 3, 3))
        nagata_kernel(y, *self._bvh(), self._depth, self._V, self._T, self._fn, self._epn,
                      self._vpn, self._A, self._infl, self._nbr, self._nbr_edge, self._npn,
                      self._tie_scale, self.max_iter, self.max_halvings, bool(hessian), gap,
                      normal, point, hess, feature, flag, sdist)
        nfb = int(np.count_nonzero(flag))
        self.last_fallbacks = nfb
        self.total_fallbacks += nfb
        if nfb:
            logger.warning("%s: Nagata projection did not converge for %d of %d points; the "
                           "flat projection was used for them (flag = 1)", self.name, nfb, n,
                           extra=ALL_RANKS)  # rank-local: this rank's points
        return Projection(gap, normal, point, hess if hessian else None, feature, flag)

    def __repr__(self) -> str:
        return (f"FacetedTool(name={self.name!r}, mode={self.mode!r}, vertices="
                f"{self._V.shape[0]}, triangles={self._T.shape[0]}, closed={self.closed})")
