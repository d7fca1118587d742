"""Mixed velocity–pressure spaces (MINI, Taylor–Hood) and velocity boundary conditions.

MINI (P1 ⊕ bubble / P1) is the default: its velocity trace on the boundary is exactly P1, so the
contact nodes are the boundary vertices (THEORY §1.3). The quadrature degree is always explicit:
the default estimate for the Norton–Hoff power law is absurd, and MINI needs degree ≥ 6 to
integrate its bubble block (docs/architecture.md, platform notes).
"""

from __future__ import annotations

import logging
from typing import Callable, Optional, Sequence, Union

import dolfinx
import dolfinx.fem
import numpy as np
import ufl
from mpi4py import MPI

from fxcontact import compat
from fxcontact.collective import check_together, together

__all__ = ["MixedSpace", "velocity_bc", "facets_with_tags"]

log = logging.getLogger(__name__)

#: Default quadrature degree per element kind. MINI: degree 5 (15 points per tetrahedron)
#: integrates every block of a linear material exactly but the bubble–bubble one (degree 6
#: in 3D), and the errors against Poiseuille flow equal those of degree 6 (24 points) to
#: 0.2 %; degree 4 (14 points) gives 20 % larger pressure errors on distorted meshes
#: (benchmarks/README.md, "Quadrature of the MINI bubble").
DEFAULT_QUADRATURE = {"mini": 5, "taylor-hood": 4, "p1p1": 4}
#: The lowest degree allowed for MINI: the pressure–bubble coupling ∫ q div b is of degree 4.
MINI_MIN_QUADRATURE = 4


class MixedSpace:
    """The mixed space W = V × Q of one mesh, with the maps the contact code needs.

    Args:
        msh: a simplex mesh (triangles or tetrahedra, affine geometry).
        element: ``"mini"`` (default) or ``"taylor-hood"``.
        quadrature_degree: quadrature degree of the volume integrals (default 5 for MINI,
            4 for Taylor–Hood; MINI below 4 under-integrates the pressure–bubble coupling and
            raises).

    Attributes:
        W: the mixed function space; ``W.sub(0)`` velocity, ``W.sub(1)`` pressure.
        V, V_to_W: collapsed velocity space and its dof map into W.
        Q, Q_to_W: collapsed pressure space and its dof map into W.
        dx: volume measure with the explicit quadrature degree.
        vertex_dofs: (num_vertices, gdim) W-dof of each velocity component at each mesh vertex
            (local indices, owned and ghost vertices).
        vertex_geometry: (num_vertices,) geometry node of each vertex.
    """

    def __init__(self, msh, element: str = "mini", quadrature_degree: Optional[int] = None):
        kinds = ("mini", "taylor-hood")
        if element not in kinds:
            raise ValueError(f"unknown element {element!r}; choose one of {kinds}")
        tdim = msh.topology.dim
        gdim = msh.geometry.dim
        if tdim != gdim or tdim not in (2, 3):
            raise ValueError(f"need a 2D or 3D mesh of full dimension, got tdim={tdim}, gdim={gdim}")
        if msh.topology.cell_type not in (dolfinx.mesh.CellType.triangle,
                                          dolfinx.mesh.CellType.tetrahedron):
            raise ValueError("MixedSpace needs a simplex mesh (triangles or tetrahedra)")
        if quadrature_degree is None:
            quadrature_degree = DEFAULT_QUADRATURE[element]
        if element == "mini" and quadrature_degree < MINI_MIN_QUADRATURE:
            raise ValueError(f"MINI needs quadrature_degree >= {MINI_MIN_QUADRATURE} (the "
                             "pressure-bubble coupling is under-integrated below), got "
                             f"{quadrature_degree}")
        self.mesh = msh
        self.element = element
        self.quadrature_degree = int(quadrature_degree)
        self.gdim = gdim
        cell = msh.ufl_cell()
        P1 = ufl.FiniteElement("Lagrange", cell, 1)
        if element == "mini":
            B = ufl.FiniteElement("Bubble", cell, tdim + 1)
            Ve = ufl.VectorElement(ufl.EnrichedElement(P1, B))
        else:
            Ve = ufl.VectorElement("Lagrange", cell, 2)
        self.W = compat.function_space(msh, ufl.MixedElement([Ve, P1]))
        self.V, self.V_to_W = compat.collapse(self.W.sub(0))
        self.Q, self.Q_to_W = compat.collapse(self.W.sub(1))
        self.dx = ufl.dx(domain=msh, metadata={"quadrature_degree": self.quadrature_degree})
        self.P1 = compat.vector_function_space(msh, "Lagrange", 1)
        self.DG0 = compat.function_space(msh, ("DG", 0))
        self._build_vertex_maps()

    # -------------------------------------------------------------------------------------
    def _build_vertex_maps(self):
        msh = self.mesh
        c2v = compat.cell_vertices(msh)
        nv_cell = c2v.shape[1]
        imap = msh.topology.index_map(0)
        nverts = imap.size_local + imap.num_ghosts
        vd = np.full((nverts, self.gdim), -1, dtype=np.int32)
        for k in range(self.gdim):
            cd = compat.dofmap_array(self.W.sub(0).sub(k))[:, :nv_cell]
            vd[c2v.ravel(), k] = cd.ravel()
        self.vertex_dofs = vd
        self.vertex_geometry = compat.entities_to_geometry(
            msh, 0, np.arange(nverts, dtype=np.int32)).ravel()
        # ownership of a vertex = ownership of its velocity dofs
        nown = self.W.dofmap.index_map.size_local * self.W.dofmap.index_map_bs
        self.vertex_owned = np.all(vd < nown, axis=1)

    @property
    def num_owned_dofs(self) -> int:
        return self.W.dofmap.index_map.size_local * self.W.dofmap.index_map_bs

    def global_dofs(self) -> int:
        return self.W.dofmap.index_map.size_global * self.W.dofmap.index_map_bs

    def vertex_positions(self) -> np.ndarray:
        """(num_vertices, gdim) current coordinates of the vertices."""
        return self.mesh.geometry.x[self.vertex_geometry, : self.gdim].copy()


def _tag_list(tags, what: str) -> list:
    if tags is None:
        raise ValueError(f"{what}: no tags given: say which tag(s) select the facets")
    if np.isscalar(tags):
        return [int(tags)]
    tags = list(tags)
    if not tags:
        raise ValueError(f"{what}: the tag list is empty: give at least one tag")
    return [int(t) for t in tags]


def _check_facet_tags(msh, facet_tags, what: str):
    """Local checks of facet MeshTags: of this mesh, of the facet dimension, indices in range
    (no collective operation)."""
    if facet_tags is None:
        raise ValueError(f"{what}: facet tags are required to select boundaries by tag")
    if not (hasattr(facet_tags, "indices") and hasattr(facet_tags, "mesh")):
        raise ValueError(f"{what} must be the facet MeshTags of the mesh, got "
                         f"{type(facet_tags).__name__}")
    fdim = msh.topology.dim - 1
    if facet_tags.mesh is not getattr(msh, "_mesh", msh):
        raise ValueError(f"{what}: these MeshTags belong to another mesh (facet tags of another "
                         f"mesh?): give the facet tags made with this mesh")
    if facet_tags.dim != fdim:
        raise ValueError(f"{what}: MeshTags of dimension {facet_tags.dim}, facets have dimension "
                         f"{fdim} (cell tags given for the facet tags?)")
    _check_range(msh, facet_tags.indices, what)


def _check_range(msh, facets: np.ndarray, what: str):
    fdim = msh.topology.dim - 1
    imap = msh.topology.index_map(fdim)
    n = 0 if imap is None else imap.size_local + imap.num_ghosts
    bad = facets[(facets < 0) | (facets >= n)]
    if len(bad):
        raise ValueError(f"{what}: facet index {int(bad[0])} (and {len(bad) - 1} more) out of "
                         f"range [0, {n}) on rank {msh.comm.rank}, the facets of this mesh (facet "
                         f"tags of another mesh?): give facet indices of this mesh, e.g. "
                         f"sim.facets(facet_tags, tag) with this mesh's facet tags")


def checked_facets(msh, facets, what: str, exterior: bool = False,
                   error: Optional[Exception] = None, **agree) -> np.ndarray:
    """``facets`` as int32 local facet indices of ``msh``, checked on every rank together
    (:func:`fxcontact.collective.check_together`): integers, within the local facets
    (including ghosts), not empty on every rank, and on the exterior boundary if
    ``exterior``. A bad argument (e.g. facets of another mesh, which would crash the
    assembly) raises a ValueError naming ``what`` on every rank. ``error``: an error of the
    caller's own local checks, raised the same way; ``agree``: values of the call that must
    be the same on every rank. Collective."""
    err, arr = error, np.zeros(0, dtype=np.int32)
    try:
        if hasattr(facets, "indices") and hasattr(facets, "values"):
            raise ValueError(f"{what}: give facet indices (sim.facets(facet_tags, tag)), not "
                             f"the MeshTags")
        a = np.asarray(facets)
        if a.ndim != 1 or (a.size and a.dtype.kind not in "iu"):
            raise ValueError(f"{what} must be a 1-D array of integer facet indices, got shape "
                             f"{a.shape} of {a.dtype}")
        _check_range(msh, a.astype(np.int64), what)
        arr = a.astype(np.int32)
    except (ValueError, TypeError) as e:
        err = err or e
    sizes = check_together(msh.comm, what, err, share=len(arr), **agree)
    if sum(sizes) == 0:
        raise ValueError(f"{what}: no facets on any rank (an empty selection): check the tags "
                         f"or the locator")
    if exterior:
        tdim = msh.topology.dim
        msh.topology.create_connectivity(tdim - 1, tdim)
        with together(msh.comm, what):
            # dolfinx lists the owned exterior facets only: a ghost facet is checked by its
            # owner (on 2 ranks a ghost of the boundary is otherwise taken for an interior one)
            owned = arr[arr < msh.topology.index_map(tdim - 1).size_local]
            inner = np.setdiff1d(owned, dolfinx.mesh.exterior_facet_indices(msh.topology))
            if len(inner):
                raise ValueError(f"{what}: {len(inner)} facet(s) on rank {msh.comm.rank} are not "
                                 f"on the boundary of the mesh (interior facets: facet indices "
                                 f"of another mesh?): give boundary facets of this mesh")
    return arr


def facets_with_tags(msh, facet_tags, tags: Union[int, Sequence[int]],
                     what: str = "facet_tags") -> np.ndarray:
    """Local facet indices carrying any of ``tags``; ValueError if a tag is absent everywhere,
    if the tag list is empty or if ``facet_tags`` are not this mesh's facet tags (``what``
    names the argument in the message).

    The checks are collective (a tag may live on one rank only), so they never hang under MPI.
    """
    err, tag_list = None, []
    try:
        tag_list = _tag_list(tags, what)
        _check_facet_tags(msh, facet_tags, what)
    except (ValueError, TypeError) as e:
        err = e
    check_together(msh.comm, "facets_with_tags()", err, tags=tuple(tag_list))
    out = []
    for t in tag_list:
        f = facet_tags.indices[facet_tags.values == t]
        n = msh.comm.allreduce(len(f), op=MPI.SUM)
        if n == 0:
            present = sorted(set(int(x) for vals in msh.comm.allgather(
                np.unique(facet_tags.values).tolist()) for x in vals))
            raise ValueError(f"boundary tag {t} is not present in the facet tags "
                             f"(tags present: {present})")
        out.append(f)
    return np.unique(np.concatenate(out)).astype(np.int32)


def velocity_bc(space: MixedSpace, facets: np.ndarray, value: Union[float, Callable, Sequence],
                component: Optional[int] = None, what: str = "velocity_bc"):
    """Dirichlet condition on the velocity (one component or the full vector) on facets.

    Args:
        space: the mixed space.
        facets: local facet indices (see :func:`facets_with_tags`).
        value: constant, a function ``f(x) -> (N,)`` (component) / ``(gdim, N)`` (vector)
            interpolated at the dofs, or a vector for the full velocity.
        component: velocity component index, or None for the whole vector.
        what: the call named in the error messages.

    Bad facets (not integers, out of range: facets of another mesh) and a bad component raise
    a ValueError on every rank (collective).

    Returns:
        ``(bc, g)``: the dolfinx DirichletBC and the Function holding its values (re-interpolate
        into ``g`` to change the value between increments).
    """
    msh = space.mesh
    fdim = msh.topology.dim - 1
    err = None
    if component is not None and not 0 <= component < space.gdim:
        err = ValueError(f"{what}: component must be in [0, {space.gdim}), got {component}")
    facets = checked_facets(msh, facets, f"{what}(facets)", error=err, component=component)
    if component is None:
        Wsub, Vc = space.W.sub(0), space.V
    else:
        Wsub = space.W.sub(0).sub(component)
        Vc, _ = compat.collapse(Wsub)
    dofs = compat.locate_dofs_topological((Wsub, Vc), fdim, facets)
    g = dolfinx.fem.Function(Vc)
    set_function_value(g, value, space.gdim if component is None else None, f"{what}(value)")
    bc = dolfinx.fem.dirichletbc(g, dofs, Wsub)
    return bc, g


def set_function_value(g, value, gdim: Optional[int] = None, what: str = "the value"):
    """Fill ``g`` with a constant, a constant vector or by interpolating a callable.

    A value of the wrong shape, or a function that returns the wrong shape or raises, gives a
    ValueError on every rank naming ``what`` and the shapes expected and got (collective)."""
    err = None
    try:
        _fill(g, value, gdim, what)
    except ValueError as e:
        err = e
    except Exception as e:   # the user's function failed
        err = ValueError(f"{what}: the value function raised {type(e).__name__}: {e}")
    check_together(g.function_space.mesh.comm, what, err)
    g.x.scatter_forward()


def _fill(g, value, gdim: Optional[int], what: str):
    if callable(value):
        def checked(x):
            out = np.asarray(value(x), dtype=np.float64)
            want = (x.shape[1],) if gdim is None else (gdim, x.shape[1])
            if out.shape != want:
                kind = "one value per point" if gdim is None else f"{gdim} components per point"
                raise ValueError(f"{what}: the value function f(x) returns shape {out.shape} for "
                                 f"x of shape {x.shape}, expected {want} ({kind})")
            return out
        g.interpolate(checked)
    else:
        val = np.asarray(value, dtype=np.float64)
        if val.ndim == 0:
            g.x.array[:] = float(val)
        else:
            if gdim is None or val.shape != (gdim,):
                raise ValueError(f"{what}: vector value must have shape ({gdim},), got "
                                 f"{val.shape}")
            g.x.array[:] = np.tile(val, g.x.array.size // gdim)
