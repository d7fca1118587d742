"""Symmetry planes of any orientation: ``v·n = 0`` imposed exactly on the Newton system.

A symmetry plane whose normal is a coordinate axis is a velocity condition on one component
(:meth:`Simulation.add_symmetry_plane` turns it into one). An inclined plane — the 120° plane of
a one-third model — constrains a combination of components, which a Dirichlet condition of
dolfinx 0.5.2 cannot express. It is imposed here **exactly**, by a projection of the Newton
system (THEORY §1.6): at every constrained vertex, with ``Q`` an orthonormal basis of the
constrained directions (the plane normals, made orthogonal to the velocity components that
already carry a Dirichlet condition) and ``P = I − Q Qᵀ``,

    residual  r ← P r + Q c,      Jacobian  A ← P A P + Q Qᵀ,

where ``c`` is the violation of the constraints in the ``Q`` basis. Newton then gives
``Qᵀ Δv = −c`` (the constraint exactly, as for a Dirichlet row) and solves the equilibrium in
the free directions only; contributors (contact) at those vertices are projected alike. A
vertex on two planes (the axis of a sector) has both normals constrained, only ``v_z`` free.
The reaction of a plane (the force it exerts on the body) is ``Σ λ_j n_j`` over its vertices,
with the multipliers ``λ = (Nᵀ)⁺ r`` of all the planes through the vertex (coordinate planes
given as velocity conditions included) and ``r`` the residual before the projection and the
Dirichlet rows (the same sign convention as :meth:`Simulation.reaction_force`). A vertex whose
velocity is fully prescribed by other velocity conditions (a sticking die) is left to those.

Each vertex is handled by its owner (owned rows only), so the result is the same on any number
of ranks.
"""

from __future__ import annotations

import logging
from typing import Dict, List

import dolfinx
import dolfinx.fem
import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from fxcontact import compat
from fxcontact.la import same_nonzero_pattern

__all__ = ["SymmetryPlanes", "unit_normal"]

log = logging.getLogger(__name__)

#: singular values of the constrained normals below this fraction of the largest are dropped
#: (a plane whose normal lies in the span of the Dirichlet components, or parallel planes)
RANK_TOL = 1e-8


class SymmetryPlanes:
    """The inclined symmetry planes of a problem (``v·n = 0`` on each), imposed exactly.

    Built by :meth:`fxcontact.simulation.Simulation.add_symmetry_plane`; usable with
    :class:`~fxcontact.newton.problem.NodalNonlinearProblem` directly (``constraints=[planes]``): call
    :meth:`add` for each plane, then the problem calls :meth:`setup` with its Dirichlet marker.

    Args:
        space: the :class:`~fxcontact.spaces.MixedSpace`.
    """

    def __init__(self, space):
        self.space = space
        self.comm = space.mesh.comm
        self.gdim = space.gdim
        self.names: List[str] = []
        self.normals: List[np.ndarray] = []
        self._markers: List[np.ndarray] = []
        self._via_bc: List[bool] = []
        self._prescribed = None
        self._ready = False
        self._P = None
        self._C = {}
        #: per Jacobian matrix: whether P A P has A's nonzero pattern (checked once)
        self._same: Dict[int, bool] = {}
        self._force_local = None

    def __len__(self) -> int:
        return len(self.names)

    @property
    def inclined(self) -> List[str]:
        """Names of the planes imposed by projection (not by a velocity condition)."""
        return [n for n, bc in zip(self.names, self._via_bc) if not bc]

    # ---------------------------------------------------------------- set-up
    def add(self, name: str, facets: np.ndarray, normal, via_bc: bool = False):
        """Add the plane through ``facets`` (local facet indices) with unit ``normal``;
        ``via_bc``: the plane is a coordinate plane already imposed by a velocity condition
        (only its reaction is computed here).

        Raises ValueError (on every rank) if the facets do not lie on one plane of that normal.
        """
        if self._ready:
            raise RuntimeError("symmetry planes are already set up")
        if name in self.names:
            raise ValueError(f"a symmetry plane named '{name}' already exists")
        n = unit_normal(normal, self.gdim)
        msh = self.space.mesh
        fdim = msh.topology.dim - 1
        msh.topology.create_connectivity(fdim, 0)
        f2v = msh.topology.connectivity(fdim, 0)
        facets = np.asarray(facets, dtype=np.int32)
        verts = np.unique(np.concatenate([f2v.links(f) for f in facets])) if len(facets) \
            else np.zeros(0, dtype=np.int32)
        x = self.space.vertex_positions()
        d = x[verts] @ n
        lo = self.comm.allreduce(float(np.min(d, initial=np.inf)), op=MPI.MIN)
        hi = self.comm.allreduce(float(np.max(d, initial=-np.inf)), op=MPI.MAX)
        if not np.isfinite(lo):
            raise ValueError(f"symmetry plane '{name}': no facets given")
        ext = np.ptp(x, axis=0) if len(x) else np.zeros(self.gdim)
        size = self.comm.allreduce(float(np.max(ext, initial=0.0)), op=MPI.MAX)
        if hi - lo > 1e-8 * size:
            raise ValueError(f"symmetry plane '{name}': the facets are not on one plane of normal "
                             f"{np.array2string(n, precision=6)} (x·n varies from {lo:.6g} to "
                             f"{hi:.6g})")
        # owners learn about vertices whose plane facets live on another rank (collective)
        mark = self._vertex_marker(verts)
        self.names.append(str(name))
        self.normals.append(n)
        self._markers.append(mark)
        self._via_bc.append(bool(via_bc))

    def set_prescribed(self, marker: np.ndarray):
        """Dofs prescribed by velocity conditions other than the planes (for the reactions)."""
        self._prescribed = np.asarray(marker, dtype=bool)

    def _vertex_marker(self, verts: np.ndarray) -> np.ndarray:
        """Owned vertices marked by any rank (reverse scatter of a P1 indicator)."""
        msh = self.space.mesh
        Q1 = compat.function_space(msh, ("Lagrange", 1))
        c2v = compat.cell_vertices(msh)
        q1 = compat.dofmap_array(Q1)
        nverts = self.space.vertex_dofs.shape[0]
        v2q = np.empty(nverts, dtype=np.int32)
        v2q[c2v.ravel()] = q1[:, : c2v.shape[1]].ravel()
        f = dolfinx.fem.Function(Q1)
        f.x.array[v2q[verts]] = 1.0
        f.vector.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        f.vector.ghostUpdate(addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)
        return (f.x.array[v2q] > 0) & self.space.vertex_owned

    def setup(self, bc_marker: np.ndarray):
        """Constrained vertices and their projections, given the Dirichlet dofs (collective)."""
        if self._ready:
            return
        sp, d = self.space, self.gdim
        nplanes = len(self.names)
        marks = np.array(self._markers).reshape(nplanes, -1)
        via_bc = np.array(self._via_bc, dtype=bool)
        prescribed = bc_marker if self._prescribed is None else self._prescribed
        verts = np.flatnonzero(np.any(marks, axis=0))
        dofs = sp.vertex_dofs[verts]
        keep, Qs, Bs, Ns, idx = [], [], [], [], []
        rkeep, Ls, RNs, ridx = [], [], [], []
        skipped = 0
        for i, v in enumerate(verts):
            planes = np.flatnonzero(marks[:, v])
            N = np.array([self.normals[k] for k in planes])          # (m, d)
            # reactions: multipliers of every plane through the vertex
            if not np.all(prescribed[dofs[i]]):
                U, S, Vt = np.linalg.svd(N, full_matrices=False)
                k = S > RANK_TOL * S[0]
                rkeep.append(i)
                Ls.append(_pad_rows(U[:, k] @ ((1.0 / S[k])[:, None] * Vt[k]), nplanes))
                RNs.append(_pad_rows(N, nplanes))
                ridx.append(np.r_[planes, -np.ones(nplanes - len(planes), int)])
            # projection: the inclined planes, in the components not already prescribed
            incl = ~via_bc[planes]
            if not np.any(incl):
                continue
            Nf = N[incl] * (~bc_marker[dofs[i]])[None, :]
            U, S, Vt = np.linalg.svd(Nf, full_matrices=False)
            k = S > RANK_TOL * S[0] if S[0] > RANK_TOL else np.zeros(len(S), bool)
            if not np.any(k):
                skipped += 1  # every direction of the normals already prescribed
                continue
            Q = Vt[k].T                                               # (d, r)
            keep.append(i)
            Qs.append(Q @ Q.T)
            Bs.append(_pad_cols(Q @ ((1.0 / S[k])[:, None] * U[:, k].T), nplanes))
            Ns.append(_pad_rows(N[incl], nplanes))
        keep = np.array(keep, dtype=np.int64)
        rkeep = np.array(rkeep, dtype=np.int64)
        self.vertices = verts[keep].astype(np.int32)
        self.dofs = dofs[keep] if len(keep) else np.zeros((0, d), np.int32)
        self._QQ = np.array(Qs).reshape(-1, d, d)
        self._B = np.array(Bs).reshape(-1, d, nplanes)
        self._N = np.array(Ns).reshape(-1, nplanes, d)
        self._rdofs = dofs[rkeep] if len(rkeep) else np.zeros((0, d), np.int32)
        self._L = np.array(Ls).reshape(-1, nplanes, d)
        self._RN = np.array(RNs).reshape(-1, nplanes, d)
        self._plane_idx = np.array(ridx, dtype=np.int64).reshape(-1, nplanes)
        self._force_local = np.zeros((nplanes, d))
        n = self.comm.allreduce(len(self.vertices), op=MPI.SUM)
        self.active = n > 0
        self._ready = True
        ns = self.comm.allreduce(skipped, op=MPI.SUM)
        log.info("symmetry planes %s: %d vertices constrained by projection (%d fully "
                 "prescribed by velocity conditions)", self.names, n, ns)

    # ---------------------------------------------------------------- Newton hooks
    def _violation(self, w) -> np.ndarray:
        """(n, nplanes) v·n_j at the constrained vertices (0 where a plane is absent)."""
        v = w.x.array[self.dofs]
        return np.einsum("nmd,nd->nm", self._N, v)

    def project(self, w):
        """Make ``w`` satisfy the constraints (least-squares correction of the free components
        at the constrained vertices), e.g. the predictor of an increment; collective."""
        if len(self.dofs):
            corr = np.einsum("ndm,nm->nd", self._B, self._violation(w))
            w.x.array[self.dofs] -= corr
        w.x.scatter_forward()

    def record_residual(self, b: PETSc.Vec):
        """The planes' reactions from the residual before the Dirichlet rows and the
        projection (called before ``set_bc``)."""
        if not len(self._rdofs):
            self._force_local = np.zeros_like(self._force_local)
            return
        r = b.getArray(readonly=True)[self._rdofs]
        lam = np.einsum("nmd,nd->nm", self._L, r)                      # multipliers
        f = np.zeros_like(self._force_local)
        for j in range(f.shape[0]):
            f[j] = np.einsum("nm,nmd->d", np.where(self._plane_idx == j, lam, 0.0), self._RN)
        self._force_local = f

    def apply_residual(self, b: PETSc.Vec, w):
        """``r ← P r + Q c`` at the owned constrained vertices (after ``set_bc``)."""
        if not len(self.dofs):
            return
        arr = b.getArray(readonly=False)
        self.project_entries(arr)
        r = arr[self.dofs]
        r += np.einsum("ndm,nm->nd", self._B, self._violation(w))
        arr[self.dofs] = r

    def project_entries(self, arr: np.ndarray):
        """``r ← P r`` at the owned constrained vertices of the owned array ``arr`` (a
        residual-like vector: e.g. a column added to the Jacobian, projected like it)."""
        if not len(self.dofs):
            return
        r = arr[self.dofs]
        r -= np.einsum("nde,ne->nd", self._QQ, r)
        arr[self.dofs] = r

    def apply_jacobian(self, A: PETSc.Mat):
        """``A ← P A P + Q Qᵀ`` (after the final assembly of ``A``; collective)."""
        if not self.active:
            return
        # one product matrix per Jacobian (the start-up and the main problem have their own):
        # PETSc's reused product remembers the matrix it was built from
        C = self._C[A.handle] = self.project_matrix(A, self._C.get(A.handle))
        same = self._same.get(A.handle)
        if same is None:
            same = self._same[A.handle] = same_nonzero_pattern(A, C)
        if same:   # P A P keeps A's vertex-block pattern: a copy of the values
            C.copy(A, structure=PETSc.Mat.Structure.SAME_NONZERO_PATTERN)
        else:      # PETSc's subset-pattern update (row by row, ~30x slower)
            A.zeroEntries()
            A.axpy(1.0, C, structure=PETSc.Mat.Structure.SUBSET_NONZERO_PATTERN)
        if len(self.dofs):
            rows = self._global(self.dofs)
            for i in range(len(rows)):
                A.setValues(rows[i], rows[i], self._QQ[i].ravel(),
                            addv=PETSc.InsertMode.ADD_VALUES)
        A.assemble()

    def project_matrix(self, G: PETSc.Mat, out: PETSc.Mat = None) -> PETSc.Mat:
        """``P G P`` (no ``Q Qᵀ`` added): a matrix of the Jacobian's layout restricted to the
        free directions, e.g. a preconditioner's extra term (collective). ``out``: the result
        of an earlier call on the same matrix, reused."""
        if self._P is None:
            self._P = self._projector(G)
        if out is None:
            return G.ptap(self._P)
        G.ptap(self._P, out)
        return out

    def _global(self, local: np.ndarray) -> np.ndarray:
        imap = self.space.W.dofmap.index_map
        bs = self.space.W.dofmap.index_map_bs
        if bs != 1:
            raise RuntimeError("symmetry planes expect a mixed space with block size 1")
        return (imap.local_range[0] + local).astype(PETSc.IntType)

    def _projector(self, A: PETSc.Mat) -> PETSc.Mat:
        """P = I − Q Qᵀ as a PETSc matrix of A's layout (owned rows, block diagonal)."""
        d = self.gdim
        (nloc, _), _ = A.getSizes()
        r0, _ = A.getOwnershipRange()
        ncols = np.ones(nloc, dtype=np.int64)
        special = np.zeros(nloc, dtype=bool)
        if len(self.dofs):
            special[self.dofs.ravel()] = True
            ncols[self.dofs.ravel()] = d
        indptr = np.r_[0, np.cumsum(ncols)].astype(PETSc.IntType)
        indices = np.empty(indptr[-1], dtype=PETSc.IntType)
        data = np.empty(indptr[-1])
        plain = np.flatnonzero(~special)
        indices[indptr[plain]] = plain + r0
        data[indptr[plain]] = 1.0
        if len(self.dofs):
            rows = self._global(self.dofs)                              # (n, d)
            blocks = np.eye(d)[None] - self._QQ                         # (n, d, d)
            for a in range(d):
                start = indptr[self.dofs[:, a]]
                for b in range(d):
                    indices[start + b] = rows[:, b]
                    data[start + b] = blocks[:, a, b]
        P = PETSc.Mat().createAIJ(A.getSizes(), csr=(indptr, indices, data), comm=self.comm)
        P.assemble()
        return P

    # ---------------------------------------------------------------- diagnostics
    def forces(self) -> Dict[str, np.ndarray]:
        """Force exerted on the body by each plane at the last residual evaluation (collective).
        """
        f = self.comm.allreduce(self._force_local, op=MPI.SUM)
        return {name: f[j] for j, name in enumerate(self.names)}

    def max_violation(self, w) -> float:
        """max |v·n| over the constrained vertices (collective)."""
        loc = float(np.max(np.abs(self._violation(w)), initial=0.0)) if len(self.dofs) else 0.0
        return self.comm.allreduce(loc, op=MPI.MAX)

    def destroy(self):
        for m in [self._P, *self._C.values()]:
            if m is not None:
                m.destroy()
        self._P, self._C, self._same = None, {}, {}


def unit_normal(normal, gdim: int) -> np.ndarray:
    """``normal`` (length ``gdim``) normalised; ValueError if it is not a finite non-zero
    vector of that length."""
    n = np.asarray(normal, dtype=np.float64).reshape(-1)
    if n.shape != (gdim,) or not np.all(np.isfinite(n)):
        raise ValueError(f"normal must be a finite vector of length {gdim}, got {normal!r}")
    nn = np.linalg.norm(n)
    if nn == 0:
        raise ValueError("normal must be non-zero")
    return n / nn


def _pad_cols(a: np.ndarray, m: int) -> np.ndarray:
    out = np.zeros((a.shape[0], m))
    out[:, : a.shape[1]] = a
    return out


def _pad_rows(a: np.ndarray, m: int) -> np.ndarray:
    out = np.zeros((m, a.shape[1]))
    out[: a.shape[0]] = a
    return out
