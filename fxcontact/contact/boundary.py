"""Contact boundary: boundary vertices, lumped nodal areas, vertex→dof maps, ownership.

With a P1 trace of the unknown vector field (MINI velocity, or any vector P1 displacement or
velocity), the contact nodes are the boundary vertices and their weight is
``S_n = ∫_Γ N_n dΓ`` (THEORY §1.3), assembled with a P1 test function on the selected facets so
that contributions from all ranks are summed (each vertex is then handled by its owner only).

The field can live in fxcontact's :class:`~fxcontact.spaces.MixedSpace` (its velocity) or in any
dolfinx function space whose trace is P1: a ``VectorFunctionSpace(mesh, ("Lagrange", 1))``, or
the vector P1 (or P1 ⊕ bubble) sub-space ``W.sub(i)`` of a mixed space. The dof maps are taken
from that space; nodal values are read from (and nodal terms added to) a Function of the space
itself, or of the parent mixed space for a sub-space.
"""

from __future__ import annotations

import logging
from typing import Sequence, Union

import dolfinx
import dolfinx.fem
import dolfinx.fem.petsc
import dolfinx.mesh
import numpy as np
import ufl
from mpi4py import MPI
from petsc4py import PETSc

from fxcontact import compat
from fxcontact.collective import together
from fxcontact.contact.friction import shear_flow_stress
from fxcontact.materials.forms import equivalent_strain_rate_ufl
from fxcontact.materials.laws import NortonHoff
from fxcontact.spaces import MixedSpace, facets_with_tags

__all__ = ["ContactBoundary", "p1_trace_check", "vertex_dof_map"]

log = logging.getLogger(__name__)


def _lagrange_degree(e):
    """Polynomial degree of a scalar Lagrange element, or None if ``e`` is not Lagrange."""
    fam = e.family()
    if fam in ("Lagrange", "P", "CG", "Q"):
        return e.degree()
    return None


def p1_trace_check(V):
    """Why the vector field of the dolfinx space ``V`` cannot carry nodal contact, or None.

    Nodal contact needs a vector field whose trace on the boundary is P1: the contact nodes are
    the vertices and their weights the P1 lumped areas. Accepted: vector Lagrange of degree 1,
    or P1 enriched with interior bubbles (MINI, the bubble vanishes on the boundary).
    """
    e = V.ufl_element()
    if not isinstance(e, ufl.VectorElement):
        return (f"nodal contact needs a vector field (one dof per component at each vertex), got "
                f"the element {e}")
    sub = e.sub_elements()[0]
    if isinstance(sub, ufl.EnrichedElement):
        parts = list(getattr(sub, "_elements", ())) or list(sub.sub_elements())
        lag = [p for p in parts if _lagrange_degree(p) is not None]
        bub = [p for p in parts if p.family() == "Bubble"]
        if len(lag) == 1 and len(bub) == len(parts) - 1 and _lagrange_degree(lag[0]) == 1:
            return None
    elif _lagrange_degree(sub) == 1:
        return None
    deg = sub.degree()
    return (f"nodal contact needs a P1 trace of the field (vector Lagrange degree 1, or P1 + "
            f"bubble), got {e} (degree {deg}): with higher-order Lagrange elements the "
            f"boundary has nodes that are not vertices (edge/face nodes) and the row-sum lumped "
            f"areas of P2 are zero at the vertices (THEORY §1.3); use a P1 field for the "
            f"contact")


def vertex_dof_map(V, msh):
    """(num_vertices, gdim) dofs of each vector component at each local vertex, for a vector
    space ``V`` with a P1 trace (blocked, or a sub-space of a mixed space: the indices are then
    the parent's local dofs, unrolled), and the owned flag of each vertex."""
    c2v = compat.cell_vertices(msh)
    nv_cell = c2v.shape[1]
    imap = msh.topology.index_map(0)
    nverts = imap.size_local + imap.num_ghosts
    gdim = msh.geometry.dim
    ncomp = V.num_sub_spaces
    if ncomp != gdim:
        raise ValueError(f"nodal contact needs a vector field with gdim = {gdim} components, "
                         f"the space has {ncomp}")
    vd = np.full((nverts, gdim), -1, dtype=np.int32)
    for k in range(gdim):
        cd = compat.dofmap_array(V.sub(k))[:, :nv_cell]
        vd[c2v.ravel(), k] = cd.ravel()
    nown = V.dofmap.index_map.size_local * V.dofmap.index_map_bs
    return vd, np.all(vd < nown, axis=1)


class ContactBoundary:
    """Owned boundary vertices of some facets with their areas and dofs.

    Args:
        space: the :class:`~fxcontact.spaces.MixedSpace` (its velocity trace must be P1: MINI),
            or any dolfinx vector function space with a P1 trace: ``VectorFunctionSpace(msh,
            ("Lagrange", 1))``, or ``W.sub(i)`` of a mixed space ``W`` whose i-th field is
            vector P1 or P1 ⊕ bubble. Other spaces (P2, scalar) raise a ValueError saying why.
        facet_tags: facet MeshTags, or None for the whole exterior boundary.
        tags: tag value(s) selecting the contact facets (required with ``facet_tags``).

    Attributes:
        vertices: (N,) local indices of the owned contact vertices.
        dofs: (N, gdim) local dofs of their vector components, in the space of the Function
            that holds the unknown (the mixed space for a sub-space).
        areas: (N,) lumped areas S_n on the current geometry (see :meth:`update_areas`).
        mesh: the mesh.
    """

    def __init__(self, space, facet_tags=None, tags: Union[int, Sequence[int], None] = None):
        # checked on every rank together, raised on every rank (fxcontact.collective)
        with together(getattr(getattr(space, "mesh", None), "comm", MPI.COMM_WORLD),
                      "ContactBoundary()"):
            msh, vertex_dofs, vertex_owned = self._space_maps(space)
            if facet_tags is None and tags is not None:
                raise ValueError("tags given without facet_tags")
            if facet_tags is not None and tags is None:
                raise ValueError("facet_tags given without tags: say which tags are in contact")
        self.space = space
        self.mesh = msh
        #: the facet tags and tag values of the selection (None: the whole boundary)
        self.facet_tags = facet_tags
        self.tags = None if tags is None else ([int(tags)] if np.isscalar(tags)
                                               else [int(t) for t in tags])
        self.vertex_dofs = vertex_dofs
        self.comm = msh.comm
        tdim = msh.topology.dim
        fdim = tdim - 1
        msh.topology.create_connectivity(fdim, tdim)
        msh.topology.create_connectivity(fdim, 0)
        if facet_tags is None:
            facets = dolfinx.mesh.exterior_facet_indices(msh.topology)
            ds = ufl.ds(domain=msh)
        else:
            facets = facets_with_tags(msh, facet_tags, tags, "ContactBoundary(facet_tags)")
            tags = [int(tags)] if np.isscalar(tags) else [int(t) for t in tags]
            dsm = ufl.ds(domain=msh, subdomain_data=facet_tags)
            ds = sum((dsm(t) for t in tags[1:]), dsm(tags[0]))
        self._lumped_areas(msh, ds, facets, vertex_dofs, vertex_owned)
        n = self.comm.allreduce(len(self.vertices), op=MPI.SUM)
        if n == 0:
            raise ValueError("ContactBoundary(facet_tags, tags): the facets select no boundary "
                             "vertex (the tags mark interior facets only?): give tags of "
                             "exterior facets")
        log.info("contact boundary: %d vertices, area %.4g", n, self.total_area())

    def remeshed(self, space, facet_tags) -> "ContactBoundary":
        """The same selection on a new mesh of the body: the facets of the same tags in the
        new ``facet_tags`` (or the whole boundary), of the new ``space`` (collective)."""
        if self.tags is None:
            return ContactBoundary(space)
        return ContactBoundary(space, facet_tags, self.tags)

    def _space_maps(self, space):
        """(mesh, vertex→dof map, owned flags) of the space; ValueError if it cannot carry
        nodal contact (local)."""
        if isinstance(space, MixedSpace):
            if space.element != "mini":
                raise ValueError(
                    "nodal contact needs a P1 velocity trace (element='mini'): with Taylor-Hood "
                    "the P2 row-sum lumping gives zero area to boundary vertices (THEORY §1.3)")
            self._gdim = space.gdim
            return space.mesh, space.vertex_dofs, space.vertex_owned
        elif isinstance(space, dolfinx.fem.FunctionSpace):
            why = p1_trace_check(space)
            if why is not None:
                raise ValueError(why)
            msh = space.mesh
            tdim, gdim = msh.topology.dim, msh.geometry.dim
            if tdim != gdim or msh.topology.cell_type not in (
                    dolfinx.mesh.CellType.triangle, dolfinx.mesh.CellType.tetrahedron):
                raise ValueError("nodal contact needs a simplex mesh (triangles or tetrahedra) "
                                 f"of full dimension, got tdim={tdim}, gdim={gdim}")
            self._gdim = gdim
            return msh, *vertex_dof_map(space, msh)
        raise ValueError(f"space must be a fxcontact MixedSpace or a dolfinx FunctionSpace, "
                         f"got {space!r}")

    def _lumped_areas(self, msh, ds, facets, vertex_dofs, vertex_owned):
        """The contact vertices and their lumped areas (collective)."""
        # lumped areas: assemble ∫ N_i ds on a scalar P1 space. The contact vertices are the
        # owned vertices with a positive assembled area: this is collective, so a vertex whose
        # boundary facets all live on another rank is still found by its owner.
        Q1 = compat.function_space(msh, ("Lagrange", 1))
        c2v = compat.cell_vertices(msh)
        q1dofs = compat.dofmap_array(Q1)
        nverts = vertex_dofs.shape[0]
        v2q = np.empty(nverts, dtype=np.int32)
        v2q[c2v.ravel()] = q1dofs[:, : c2v.shape[1]].ravel()
        self._area_form = compat.form(ufl.TestFunction(Q1) * ds)
        self._area_vec = dolfinx.fem.petsc.create_vector(self._area_form)
        self._q1_of_vertex = v2q
        all_areas = self._assemble_areas()
        self.facets = np.asarray(facets, dtype=np.int32)
        self.vertices = np.flatnonzero((all_areas > 0) & vertex_owned).astype(np.int32)
        self._q1_of_vertex = v2q[self.vertices]
        self.dofs = vertex_dofs[self.vertices]
        self.geometry_nodes = compat.entities_to_geometry(msh, 0, self.vertices).reshape(-1)
        self.update_areas()

    @property
    def gdim(self) -> int:
        return self._gdim

    def __len__(self) -> int:
        return len(self.vertices)

    def _assemble_areas(self) -> np.ndarray:
        b = self._area_vec
        with b.localForm() as bl:
            bl.set(0.0)
        dolfinx.fem.petsc.assemble_vector(b, self._area_form)
        b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        b.ghostUpdate(addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)
        with b.localForm() as bl:
            return bl.array[self._q1_of_vertex].copy()

    def update_areas(self):
        """Re-assemble S_n on the current mesh geometry."""
        self.areas = self._assemble_areas()

    def q1_dofs(self, Q1) -> np.ndarray:
        """Dofs of the contact vertices in a scalar P1 space ``Q1`` of the same mesh."""
        c2v = compat.cell_vertices(self.mesh)
        d = compat.dofmap_array(Q1)
        v2q = np.empty(self.vertex_dofs.shape[0], dtype=np.int32)
        v2q[c2v.ravel()] = d[:, : c2v.shape[1]].ravel()
        return v2q[self.vertices]

    def strain_rate(self, w, dx) -> np.ndarray:
        """(N,) equivalent strain rate of the velocity of the mixed Function ``w`` at the
        contact vertices: volume average over the adjacent cells (lumped P1 projection;
        collective). The forms are compiled at the first call for a ``w``."""
        if getattr(self, "_rate_forms", (None,))[0] is not w:
            Q1 = compat.function_space(self.mesh, ("Lagrange", 1))
            q = ufl.TestFunction(Q1)
            rate = equivalent_strain_rate_ufl(ufl.split(w)[0], self.gdim)
            self._rate_forms = (w, compat.form(rate * q * dx), compat.form(q * dx),
                                self.q1_dofs(Q1))
        _, f_rate, f_vol, q1 = self._rate_forms
        rate, vol = _at_vertices((f_rate, f_vol), q1)
        return rate / vol

    def material_law(self, w, dx, material, shear: bool = True):
        """(K, k) at the contact vertices for a Norton–Hoff ``material``: its consistency K
        [MPa s^m] and, with ``shear``, its shear flow stress k = K z^m [MPa] at the node's strain
        rate (:meth:`strain_rate` of the mixed Function ``w``; z = √3 √(ε̄̇² + ε̇₀²); else
        zeros). A law that varies per cell (a :class:`~fxcontact.Viscoplastic`'s: hardening,
        temperature) gives each node the volume averages of K and m over its cells (lumped P1
        projection; each cell's piece for its own rate): the node's own law. Collective."""
        n = len(self)
        rate = self.strain_rate(w, dx) if shear else None
        if type(material).law_ufl is NortonHoff.law_ufl:   # one K, m: as ever
            k = shear_flow_stress(material, rate) if shear else np.zeros(n)
            return np.full(n, float(material.K)), k
        if getattr(self, "_law_forms", (None, None))[:2] != (w, material):
            Q1 = compat.function_space(self.mesh, ("Lagrange", 1))
            q = ufl.TestFunction(Q1)
            K, m = material.law_ufl(material.z_ufl(ufl.sym(ufl.grad(ufl.split(w)[0]))))
            self._law_forms = (w, material, compat.form(K * q * dx), compat.form(m * q * dx),
                               compat.form(q * dx), self.q1_dofs(Q1))
        _, _, f_K, f_m, f_vol, q1 = self._law_forms
        K, m, vol = _at_vertices((f_K, f_m, f_vol), q1)
        K, m = K / vol, m / vol
        if not shear:
            return K, np.zeros(n)
        z = np.sqrt(3.0 * rate ** 2 + 3.0 * material.regularization ** 2)
        return K, K * z ** m

    def total_area(self) -> float:
        return self.comm.allreduce(float(np.sum(self.areas)), op=MPI.SUM)

    def velocities(self, w) -> np.ndarray:
        """(N, gdim) nodal values (velocities, or displacements) of the contact vertices in the
        Function ``w`` (of the space given at construction, or of its parent mixed space)."""
        return w.x.array[self.dofs]

    values = velocities

    def mesh_positions(self) -> np.ndarray:
        """(N, gdim) current mesh coordinates of the contact vertices."""
        return self.mesh.geometry.x[self.geometry_nodes, : self.gdim].copy()


def _at_vertices(forms, q1) -> list:
    """The assembled vectors of the P1 ``forms`` (ghost contributions added to their owners)
    at the P1 dofs ``q1`` of the contact vertices (collective)."""
    out = []
    for f in forms:
        b = dolfinx.fem.petsc.assemble_vector(f)
        b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        out.append(b.getArray(readonly=True)[q1].copy() if len(q1) else np.zeros(0))
        b.destroy()
    return out
