"""Contact boundary: boundary vertices, lumped nodal areas, vertex→velocity dofs, ownership.

With a P1 velocity trace (MINI), the contact nodes are the boundary vertices and their weight is
``S_n = ∫_Γ N_n dΓ`` (THEORY §1.3), assembled with a P1 test function on the selected facets so
that contributions from all ranks are summed (each vertex is then handled by its owner only).
"""

from __future__ import annotations

import logging
from typing import Sequence, Union

import numpy as np
import ufl
from mpi4py import MPI
from petsc4py import PETSc

import dolfinx
import dolfinx.fem
import dolfinx.fem.petsc
import dolfinx.mesh

from fxcontact import compat
from fxcontact.spaces import MixedSpace, facets_with_tags

__all__ = ["ContactBoundary"]

log = logging.getLogger(__name__)


class ContactBoundary:
    """Owned boundary vertices of some facets with their areas and velocity dofs.

    Args:
        space: the :class:`~fxcontact.spaces.MixedSpace` (its velocity trace must be P1: MINI).
        facet_tags: facet MeshTags, or None for the whole exterior boundary.
        tags: tag value(s) selecting the contact facets (required with ``facet_tags``).

    Attributes:
        vertices: (N,) local indices of the owned contact vertices.
        dofs: (N, gdim) W-dofs of their velocity components.
        areas: (N,) lumped areas S_n on the current geometry (see :meth:`update_areas`).
    """

    def __init__(self, space: MixedSpace, facet_tags=None, tags: Union[int, Sequence[int],
                 None] = None):
        if space.element != "mini":
            raise ValueError(
                "nodal contact needs a P1 velocity trace (element='mini'): with Taylor-Hood the "
                "P2 row-sum lumping gives zero area to boundary vertices (THEORY §1.3)")
        msh = space.mesh
        self.space = space
        self.comm = msh.comm
        tdim = msh.topology.dim
        fdim = tdim - 1
        msh.topology.create_connectivity(fdim, tdim)
        msh.topology.create_connectivity(fdim, 0)
        if facet_tags is None:
            if tags is not None:
                raise ValueError("tags given without facet_tags")
            facets = dolfinx.mesh.exterior_facet_indices(msh.topology)
            ds = ufl.ds(domain=msh)
        else:
            if tags is None:
                raise ValueError("facet_tags given without tags: say which tags are in contact")
            facets = facets_with_tags(msh, facet_tags, tags)
            tags = [int(tags)] if np.isscalar(tags) else [int(t) for t in tags]
            dsm = ufl.ds(domain=msh, subdomain_data=facet_tags)
            ds = sum((dsm(t) for t in tags[1:]), dsm(tags[0]))
        # lumped areas: assemble ∫ N_i ds on a scalar P1 space. The contact vertices are the
        # owned vertices with a positive assembled area: this is collective, so a vertex whose
        # boundary facets all live on another rank is still found by its owner.
        Q1 = compat.function_space(msh, ("Lagrange", 1))
        c2v = compat.cell_vertices(msh)
        q1dofs = compat.dofmap_array(Q1)
        nverts = space.vertex_dofs.shape[0]
        v2q = np.empty(nverts, dtype=np.int32)
        v2q[c2v.ravel()] = q1dofs[:, : c2v.shape[1]].ravel()
        self._area_form = compat.form(ufl.TestFunction(Q1) * ds)
        self._area_vec = dolfinx.fem.petsc.create_vector(self._area_form)
        self._q1_of_vertex = v2q
        all_areas = self._assemble_areas()
        self.facets = np.asarray(facets, dtype=np.int32)
        self.vertices = np.flatnonzero((all_areas > 0) & space.vertex_owned).astype(np.int32)
        self._q1_of_vertex = v2q[self.vertices]
        self.dofs = space.vertex_dofs[self.vertices]
        self.geometry_nodes = space.vertex_geometry[self.vertices]
        self.update_areas()
        n = self.comm.allreduce(len(self.vertices), op=MPI.SUM)
        log.info("contact boundary: %d vertices, area %.4g", n, self.total_area())

    @property
    def gdim(self) -> int:
        return self.space.gdim

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
        c2v = compat.cell_vertices(self.space.mesh)
        d = compat.dofmap_array(Q1)
        v2q = np.empty(self.space.vertex_dofs.shape[0], dtype=np.int32)
        v2q[c2v.ravel()] = d[:, : c2v.shape[1]].ravel()
        return v2q[self.vertices]

    def total_area(self) -> float:
        return self.comm.allreduce(float(np.sum(self.areas)), op=MPI.SUM)

    def velocities(self, w) -> np.ndarray:
        """(N, gdim) nodal velocities of the contact vertices in the mixed Function ``w``."""
        return w.x.array[self.dofs]

    def mesh_positions(self) -> np.ndarray:
        """(N, gdim) current mesh coordinates of the contact vertices."""
        return self.space.mesh.geometry.x[self.geometry_nodes, : self.gdim].copy()
