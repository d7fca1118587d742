"""The Newton matrix of a MINI problem with its bubble condensed element by element.

:class:`~fxcontact.element.assembled.CondensedPC` eliminates the bubble from the *assembled* MINI
Jacobian (sub-matrices, a block inverse, a matrix product) at every Newton iteration, after the
full 19-dof element matrices have been assembled into the mixed matrix. Here the element
matrices are condensed before they are assembled: per cell, with the element unknowns split into
l (vertex velocities and pressures) and b (bubble),

    S_e = A_ll − A_lb A_bb⁻¹ A_bl,

and only S_e enters the matrix (its l–l block; the b–b block holds an identity). The nodal
contributors' blocks, the Dirichlet rows and columns and the symmetry-plane projection are then
added by the usual code: they act on vertex dofs only, so they commute with the condensation —
with M the l-side operator (Dirichlet zeroing, then the projection P) and E their diagonal extras
(the unit Dirichlet diagonal, Q Qᵀ), the full modified matrix

    J' = [[M (A_ll + K_c) M + E,  M A_lb],
          [A_bl M,                A_bb  ]]

has the Schur complement S' = M (S + K_c) M + E, which is exactly what that code makes of the
assembled S. The Newton system ``J' δ = f`` is then solved by ``S' δ_l = f_l − M Y f_b`` and
``δ_b = A_bb⁻¹ f_b − X M δ_l`` with the kept cell matrices ``X = A_bb⁻¹ A_bl`` and
``Y = A_lb A_bb⁻¹`` (:class:`ElementCondensedPC`), and the product with J' — the line search's
slope, a Krylov method, the bordered operator — is exact from the same data
(:class:`CondensedJacobian.mult`). The Newton step equals the algebraic condensation's to
round-off; what changes is the cost: no 19 × 19 insertion, no sub-matrix algebra.

The element matrices come from :mod:`fxcontact.element.tensors`: the FFCx kernel of the
problem's own Jacobian form (any form with cell integrals only), or the hand-written Norton–Hoff
kernel where it is the same (checked on sample cells at the first assembly).
"""

from __future__ import annotations

import copy
import logging
from typing import List, Optional

import dolfinx.cpp.fem
import dolfinx.la
import numba
import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from fxcontact.element.assembled import CondensedPC
from fxcontact.element.cell import condense_matrix
from fxcontact.element.tensors import FFCxElementTensors, P1P1Layout, ffcx_tab_jacobian, nh_tab
from fxcontact.la import add_nodal_jacobian

__all__ = ["CondensedJacobian", "ElementCondensedPC", "element_condensation_supported"]

log = logging.getLogger(__name__)

#: relative difference between the hand-written kernel and the problem's FFCx kernel, on sample
#: cells, under which the hand-written one is used
KERNEL_MATCH_RTOL = 1e-9


# -- one cell -------------------------------------------------------------------------------------
@numba.njit(cache=True)
def _jacobian_loop_ffcx(data, cells, lpos, bpos, A, b, S, X, Y, Binv, Abb):
    """Element matrices of ``cells`` from the FFCx kernels, condensed: S[n] of the n-th cell,
    X[c], Y[c], Binv[c], Abb[c] of cell c. Returns the number of cells with a singular bubble
    block. (Cached on disk: the kernels are first-class functions in ``data``, one
    compilation for every form; a loop taking the tabulator as an argument could not be
    cached, hence one loop per source.)"""
    bad = 0
    for n in range(cells.size):
        c = cells[n]
        ffcx_tab_jacobian(data, c, A, b)
        if not condense_matrix(A, lpos, bpos, S[n], X[c], Y[c], Binv[c], Abb[c]):
            bad += 1
    return bad


@numba.njit(cache=True)
def _jacobian_loop_nh(data, cells, lpos, bpos, A, b, S, X, Y, Binv, Abb):
    """:func:`_jacobian_loop_ffcx` of the hand-written Norton–Hoff kernel."""
    bad = 0
    for n in range(cells.size):
        c = cells[n]
        nh_tab(data, c, A, b)
        if not condense_matrix(A, lpos, bpos, S[n], X[c], Y[c], Binv[c], Abb[c]):
            bad += 1
    return bad


# -- per-cell vector operations (numba, with numpy twins used in the tests) -----------------------
@numba.njit(cache=True)
def _add_Y(f, w_l, w_b, Y, out):
    """out[l dofs of c] += Y_c f[b dofs of c] for every cell (scatter-add)."""
    for c in range(w_l.shape[0]):
        for i in range(w_l.shape[1]):
            acc = 0.0
            for q in range(w_b.shape[1]):
                acc += Y[c, i, q] * f[w_b[c, q]]
            out[w_l[c, i]] += acc


def add_Y_numpy(f, w_l, w_b, Y, out):
    np.add.at(out, w_l, np.einsum("ciq,cq->ci", Y, f[w_b]))


@numba.njit(cache=True)
def _bubble_solve(f, u, w_l, w_b, X, Binv, out):
    """out[b dofs of c] = Binv_c f_b − X_c u_l for every cell."""
    k = w_b.shape[1]
    for c in range(w_l.shape[0]):
        for i in range(k):
            acc = 0.0
            for q in range(k):
                acc += Binv[c, i, q] * f[w_b[c, q]]
            for j in range(w_l.shape[1]):
                acc -= X[c, i, j] * u[w_l[c, j]]
            out[w_b[c, i]] = acc


def bubble_solve_numpy(f, u, w_l, w_b, X, Binv, out):
    out[w_b] = np.einsum("ciq,cq->ci", Binv, f[w_b]) - np.einsum("cij,cj->ci", X, u[w_l])


@numba.njit(cache=True)
def _bubble_product(x, u, w_l, w_b, X, Y, Abb, out_b, out_l):
    """t_c = A_bb,c (X_c u_l + x_b): out_b[b dofs] = t_c, out_l[l dofs] += Y_c t_c."""
    k = w_b.shape[1]
    z = np.empty(k)
    for c in range(w_l.shape[0]):
        for i in range(k):
            acc = x[w_b[c, i]]
            for j in range(w_l.shape[1]):
                acc += X[c, i, j] * u[w_l[c, j]]
            z[i] = acc
        for i in range(k):
            acc = 0.0
            for q in range(k):
                acc += Abb[c, i, q] * z[q]
            out_b[w_b[c, i]] = acc
        for i in range(w_l.shape[1]):
            acc = 0.0
            for q in range(k):
                acc += Y[c, i, q] * out_b[w_b[c, q]]
            out_l[w_l[c, i]] += acc


def bubble_product_numpy(x, u, w_l, w_b, X, Y, Abb, out_b, out_l):
    t = np.einsum("ciq,cq->ci", Abb, x[w_b] + np.einsum("cij,cj->ci", X, u[w_l]))
    out_b[w_b] = t
    np.add.at(out_l, w_l, np.einsum("ciq,cq->ci", Y, t))


@numba.njit(cache=True)
def _project_cells(S, blocks, proj, flag):
    """S_e ← D S_e D for every cell touching a projected vertex block (D = blockdiag of the
    blocks' projectors ``proj``; ``flag``: the blocks with a projector)."""
    nv = blocks.shape[1]
    bs = proj.shape[1]
    T = np.empty((nv * bs, nv * bs))
    for n in range(blocks.shape[0]):
        hit = False
        for i in range(nv):
            if flag[blocks[n, i]]:
                hit = True
        if not hit:
            continue
        # T = S D (columns), then S = D T (rows)
        for r in range(nv * bs):
            for j in range(nv):
                P = proj[blocks[n, j]]
                for b in range(bs):
                    acc = 0.0
                    for a in range(bs):
                        acc += S[n, r, j * bs + a] * P[a, b]
                    T[r, j * bs + b] = acc
        for i in range(nv):
            P = proj[blocks[n, i]]
            for a in range(bs):
                for c in range(nv * bs):
                    acc = 0.0
                    for b in range(bs):
                        acc += P[a, b] * T[i * bs + b, c]
                    S[n, i * bs + a, c] = acc


def project_cells_numpy(S, blocks, proj, flag):
    D = proj[blocks]                                           # (n, nv, bs, bs)
    n, nv, bs, _ = D.shape
    Sb = S.reshape(n, nv, bs, nv, bs)
    out = np.einsum("niab,nibjc,njcd->niajd", D, Sb, D).reshape(S.shape)
    hit = flag[blocks].any(axis=1)
    S[hit] = out[hit]


def element_condensation_supported(problem) -> Optional[str]:
    """None if the problem's Jacobian can be condensed element by element, else the reason: a
    MINI space (gdim + 1 dofs per vertex and cell-interior dofs only) and Jacobian and residual
    forms with cell integrals over the whole mesh only (a facet term, e.g. a traction, keeps the
    algebraic condensation)."""
    try:
        P1P1Layout(problem.w.function_space)
    except (ValueError, RuntimeError) as e:
        return str(e)
    cell = dolfinx.cpp.fem.IntegralType.cell
    # the FFCx element source compiles the residual's kernel too (element vectors of the
    # same cells): both forms must be whole-mesh cell integrals
    for form, what in ((problem.a, "Jacobian"), (problem.L, "residual")):
        other = [t for t in form.integral_types if t != cell]
        if other:
            return f"the {what} has {other[0].name.replace('_', ' ')} integrals"
        if list(form.integral_ids(cell)) != [-1]:
            return f"the {what} has cell integrals over tagged subdomains"
    return None


class CondensedJacobian:
    """The condensed Newton matrix of a MINI :class:`~fxcontact.newton.problem.NodalNonlinearProblem`,
    assembled on the P1/P1 layout (:class:`~fxcontact.element.tensors.P1P1Layout`: one block
    of gdim + 1 unknowns per vertex, a BAIJ matrix).

    Args:
        problem: the problem (its ``w``, ``a``, ``bcs``, ``bc_marker``, ``constraints``).
        tensors: an element-tensor source of :mod:`fxcontact.element.tensors` whose matrices
            are the problem's Jacobian (default: :class:`~fxcontact.element.tensors.FFCxElementTensors`
            of ``problem.a``).
        fast_tensors: optional callable ``(layout) -> source`` of a faster source of the same
            matrices (the hand-written Norton–Hoff kernel): used if it matches ``tensors`` on
            sample cells at the first assembly (relative ``KERNEL_MATCH_RTOL``), else dropped
            with a log message.
        chunk: cells condensed at once (bounds the memory of the element tensors).

    Attributes:
        S: the condensed matrix S' after :meth:`assemble` (P1/P1 layout, BAIJ: inserted by
            vertex blocks), and ``S_aij`` its AIJ copy for the linear solvers.
        kernel: ``"ffcx"`` or ``"hand"``, the element kernel in use.
    """

    def __init__(self, problem, tensors=None, fast_tensors=None, chunk: int = 8192):
        self.problem = problem
        W = problem.w.function_space
        self.layout = lay = P1P1Layout(W)
        if tensors is None:
            tensors = FFCxElementTensors(lay, problem.a, problem.L)
        self.tensors = tensors
        self._tab = getattr(tensors, "tab_jacobian", tensors.tab)
        if self._tab not in (nh_tab, ffcx_tab_jacobian):
            raise ValueError("tensors: FFCxElementTensors or NortonHoffElementTensors expected, "
                             f"got {type(tensors).__name__}")
        self._fast = None
        if fast_tensors is not None:
            try:
                self._fast = fast_tensors(lay)
            except ValueError as e:   # not for this space or material: the FFCx kernel
                log.info("condensed Jacobian with the FFCx kernel: %s", e)
        self.kernel = "ffcx"
        self.chunk = max(int(chunk), 1)
        nl, k, nc = lay.lpos.size, lay.bpos.size, lay.num_cells
        self.X = np.zeros((nc, k, nl))
        self.Y = np.zeros((nc, nl, k))
        self.Binv = np.zeros((nc, k, k))
        self.Abb = np.zeros((nc, k, k))
        ndofs = W.element.space_dimension
        self._A = np.zeros((ndofs, ndofs))
        self._b = np.zeros(ndofs)
        imap = W.dofmap.index_map
        nw = imap.size_local + imap.num_ghosts
        #: local W dof -> local index of the P1/P1 layout (-1: a cell-interior dof)
        self.w2c = np.full(nw, -1, dtype=np.int32)
        self.w2c[lay.block_w.ravel()] = np.arange(lay.block_w.size, dtype=np.int32)
        #: the owned W dofs in the order of the owned part of a P1/P1 vector
        self.owned_w = np.ascontiguousarray(lay.owned_w_dofs().ravel())
        self.S = lay.create_matrix("baij")
        self.S_aij = None
        self._setup_projection()
        #: Dirichlet marker of the P1/P1 layout's local indices
        self._bc_marker_c = np.zeros(lay.block_w.size, dtype=bool)
        self._bc_marker_c[self.w2c[np.flatnonzero(problem.bc_marker & (self.w2c >= 0))]] = True
        self.comm = lay.comm
        self._bc_c = np.ascontiguousarray(
            self.w2c[problem._bc_owned].astype(np.int32).reshape(-1, 1))
        self._work = [problem.create_vector() for _ in range(2)]   # ghosted W vectors
        self._xc, self._yc = self.S.createVecs()
        #: number of assemblies
        self.assemblies = 0

    def _setup_projection(self):
        """The symmetry planes' projectors P = I − Q Qᵀ per vertex block (owned and ghost:
        the element matrices are projected before the assembly, (P S P)_ij = P_i S_ij P_j),
        and the Q Qᵀ blocks added at the owned constrained vertices (collective)."""
        lay = self.layout
        bs, d = lay.bs, lay.bs - 1
        cimap = lay.Vc.dofmap.index_map
        nblocks = cimap.size_local + cimap.num_ghosts
        vec = dolfinx.la.vector(cimap, bs=d * d)
        arr = vec.array.reshape(-1, d, d)
        own_blocks, own_qq = [], []
        for c in self.problem.constraints:
            if not c.active or not len(c.dofs):
                continue
            blocks = self.w2c[c.dofs[:, 0]] // bs
            arr[blocks] += c._QQ
            own_blocks.append(blocks)
            own_qq.append(c._QQ)
        vec.scatter_forward()
        qq = arr.copy()
        self._flag = np.any(qq != 0.0, axis=(1, 2))
        self._proj = np.tile(np.eye(bs), (nblocks, 1, 1))
        self._proj[:, :d, :d] -= qq
        blocks = np.concatenate(own_blocks) if own_blocks else np.zeros(0, dtype=np.int64)
        qqb = np.zeros((blocks.size, bs, bs))
        if blocks.size:
            qqb[:, :d, :d] = np.concatenate(own_qq)
        self._qq_blocks = blocks.astype(np.int32).reshape(-1, 1)
        self._qq_values = qqb.reshape(blocks.size, bs * bs)

    # -- the l-side operator M (Dirichlet zeroing, then the symmetry projection) -------------
    def apply_M(self, arr: np.ndarray):
        """``arr ← M arr`` on the owned entries of a W array."""
        arr[self.problem._bc_owned] = 0.0
        for c in self.problem.constraints:
            if c.active:
                c.project_entries(arr)

    def _ghosted_M(self, x: PETSc.Vec, k: int = 0) -> PETSc.Vec:
        """Work vector k holding M x (owned l entries; b entries of x kept), ghosts updated."""
        u = self._work[k]
        x.copy(u)
        self.apply_M(u.getArray(readonly=False))
        u.ghostUpdate(addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)
        return u

    def _zeroed(self, k: int = 1) -> PETSc.Vec:
        v = self._work[k]
        with v.localForm() as loc:
            loc.set(0.0)
        return v

    # -- between the W layout and the P1/P1 layout (owned entries) ----------------------------
    def to_condensed(self, x: PETSc.Vec, xc: PETSc.Vec):
        """xc = the vertex entries of the W vector x."""
        xc.setArray(x.getArray(readonly=True)[self.owned_w])

    def from_condensed(self, xc: PETSc.Vec, y: PETSc.Vec):
        """The vertex entries of the W vector y = xc."""
        ya = y.getArray(readonly=False)
        ya[self.owned_w] = xc.getArray(readonly=True)

    # -- assembly -----------------------------------------------------------------------------
    def _choose_kernel(self):
        """Keep the fast source if its matrices match the problem's on sample cells
        (collective)."""
        if self._fast is None or self.kernel != "ffcx" or self.assemblies:
            return
        lay = self.layout
        n = min(lay.num_cells, 64)
        cells = np.unique(np.linspace(0, max(lay.num_cells - 1, 0), n).astype(np.int32))
        err = 0.0
        if cells.size and lay.num_cells:
            A_ref, _ = self.tensors.tensors(cells)
            A_fast, _ = self._fast.tensors(cells)
            scale = np.abs(A_ref).max(axis=(1, 2), keepdims=True)
            err = float(np.max(np.abs(A_fast - A_ref) / np.where(scale > 0, scale, 1.0)))
        err = lay.comm.allreduce(err, op=MPI.MAX)
        if err <= KERNEL_MATCH_RTOL:
            self.tensors, self._tab, self.kernel = self._fast, self._fast.tab, "hand"
        else:
            log.info("the hand-written Norton-Hoff kernel differs from the problem's Jacobian "
                     "(relative %.1e): the FFCx kernel is used", err)
        self._fast = None

    def assemble(self, terms, timers):
        """S' = M (S + K_c) M + E (collective): the condensed element matrices and the nodal
        contributors' blocks ``terms`` (a list of :class:`~fxcontact.newton.problem.NodalTerms` of the W
        layout) with the Dirichlet rows and columns zeroed, the unit Dirichlet diagonal, then
        the symmetry projection. Raises RuntimeError on every rank for a singular bubble
        block."""
        S = self.S
        bc_marker = self.problem.bc_marker
        S.zeroEntries()
        if terms:
            with timers("contact"):
                for t in terms:
                    if t.jacobian is None or t.dofs.shape[0] == 0:
                        continue
                    mapped = copy.copy(t)
                    mapped.dofs = np.where(t.dofs >= 0, self.w2c[np.maximum(t.dofs, 0)], -1)
                    mapped.jacobian = self._project_nodal(mapped.dofs, t.jacobian)
                    add_nodal_jacobian(S, mapped, self._bc_marker_c)
        with timers("assembly", "assembly_jacobian"):
            self._assemble_cells(bc_marker)
            if self._bc_c.size:
                S.setValuesLocalRCV(self._bc_c, self._bc_c, np.ones((self._bc_c.shape[0], 1)),
                                    addv=PETSc.InsertMode.ADD_VALUES)
            if self._qq_blocks.size:
                S.setValuesBlockedLocalRCV(self._qq_blocks, self._qq_blocks, self._qq_values,
                                           addv=PETSc.InsertMode.ADD_VALUES)
            S.assemble()
            # the linear solvers' copy: MUMPS's L D Lᵀ and the field split's sub-matrices
            # need AIJ (a copy of the values once the pattern is known)
            # (petsc4py converts in place without an output matrix: an empty one first)
            self.S_aij = S.convert(PETSc.Mat.Type.AIJ,
                                   PETSc.Mat() if self.S_aij is None else self.S_aij)

    def _project_nodal(self, cdofs: np.ndarray, K: np.ndarray) -> np.ndarray:
        """Nodal gdim × gdim blocks at the P1/P1 indices ``cdofs`` projected, P K P (the
        node's velocity components; Dirichlet components are not mixed by P)."""
        d = self.layout.bs - 1
        ok = cdofs[:, 0] >= 0
        blocks = np.where(ok, cdofs[:, 0] // self.layout.bs, 0)
        hit = ok & self._flag[blocks]
        if not hit.any():
            return K
        K = K.copy()
        P = self._proj[blocks[hit], :d, :d]
        K[hit] = np.einsum("nab,nbc,ndc->nad", P, K[hit], P)
        return K

    def _assemble_cells(self, bc_marker):
        self._choose_kernel()
        lay = self.layout
        data = self.tensors.data()
        bad = 0
        nl = lay.lpos.size
        for c0 in range(0, lay.num_cells, self.chunk):
            cells = np.arange(c0, min(c0 + self.chunk, lay.num_cells), dtype=np.int32)
            S = np.empty((cells.size, nl, nl))
            loop = _jacobian_loop_nh if self._tab is nh_tab else _jacobian_loop_ffcx
            bad += loop(data, cells, lay.lpos, lay.bpos, self._A, self._b, S, self.X, self.Y,
                        self.Binv, self.Abb)
            bc = bc_marker[lay.w_l[cells]]
            hit = np.flatnonzero(bc.any(axis=1))
            if hit.size:   # Dirichlet rows and columns zeroed (kept in the pattern)
                keep = ~bc[hit]
                S[hit] *= keep[:, :, None] & keep[:, None, :]
            _project_cells(S, lay.cell_blocks[cells], self._proj, self._flag)
            self.S.setValuesBlockedLocalRCV(lay.cell_blocks[cells], lay.cell_blocks[cells],
                                            S.reshape(cells.size, -1),
                                            addv=PETSc.InsertMode.ADD_VALUES)
        self.assemblies += 1
        if lay.comm.allreduce(bad):
            raise RuntimeError("singular interior (bubble) block in a cell: degenerate element")

    # -- products with J' and solves (vectors of the W layout) ------------------------------
    def mult(self, x: PETSc.Vec, y: PETSc.Vec):
        """``y = J' x``."""
        self.to_condensed(x, self._xc)
        self.S.mult(self._xc, self._yc)
        u = self._ghosted_M(x, 0)
        g = self._zeroed(1)
        lay = self.layout
        ya = y.getArray(readonly=False)
        with u.localForm() as ul, g.localForm() as gl:
            ua = ul.getArray(readonly=True)
            _bubble_product(ua, ua, lay.w_l, lay.w_b, self.X, self.Y, self.Abb, ya, gl.getArray())
        del ya
        g.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        ga = g.getArray(readonly=False)
        self.apply_M(ga)
        ya = y.getArray(readonly=False)
        ya[self.owned_w] = self._yc.getArray(readonly=True) + ga[self.owned_w]

    def condensed_rhs(self, f: PETSc.Vec, rc: PETSc.Vec):
        """``rc = f_l − M Y f_b`` (P1/P1 layout)."""
        g = self._zeroed(1)
        lay = self.layout
        with g.localForm() as gl:
            _add_Y(f.getArray(readonly=True), lay.w_l, lay.w_b, self.Y, gl.getArray())
        g.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        ga = g.getArray(readonly=False)
        self.apply_M(ga)
        rc.setArray(f.getArray(readonly=True)[self.owned_w] - ga[self.owned_w])

    def condensed_rhs_many(self, fs: List[PETSc.Vec]) -> List[np.ndarray]:
        """The owned entries of ``f_l − M Y f_b`` (P1/P1 layout) of each vector of ``fs``
        (collective, the same number of vectors on every rank). Vectors without bubble
        entries on any rank (the contact columns of the active-set prediction) need no pass
        over the cells: their vertex entries."""
        lay = self.layout
        arrays = [f.getArray(readonly=True) for f in fs]
        if lay.comm.allreduce(any(bool(np.any(a[lay.w_b])) for a in arrays), op=MPI.LOR):
            out = []
            for f in fs:
                self.condensed_rhs(f, self._xc)
                out.append(self._xc.getArray(readonly=True).copy())
            return out
        return [a[self.owned_w].copy() for a in arrays]

    def recover(self, f: PETSc.Vec, yc: PETSc.Vec, y: PETSc.Vec):
        """y_l = yc, ``y_b = A_bb⁻¹ f_b − X M y_l``."""
        self.from_condensed(yc, y)
        u = self._ghosted_M(y, 0)
        lay = self.layout
        ya = y.getArray(readonly=False)
        with u.localForm() as ul:
            _bubble_solve(f.getArray(readonly=True), ul.getArray(readonly=True), lay.w_l,
                          lay.w_b, self.X, self.Binv, ya)
        del ya

    # -- the condensed system's layout for the field split (CondensedPC's interface) -----------
    def split_is(self):
        """(velocity IS, pressure IS) of the P1/P1 system (global indices)."""
        lay = self.layout
        bs, d = lay.bs, lay.bs - 1
        nown = lay.Vc.dofmap.index_map.size_local
        r0 = lay.Vc.dofmap.index_map.local_range[0] * bs
        base = r0 + bs * np.arange(nown)
        iu = PETSc.IS().createGeneral((base[:, None] + np.arange(d)).ravel().astype(
            PETSc.IntType), comm=lay.comm)
        iu.setBlockSize(d)
        ip = PETSc.IS().createGeneral((base + d).astype(PETSc.IntType), comm=lay.comm)
        return iu, ip

    def node_coordinates(self) -> np.ndarray:
        """(owned vertices, gdim) current positions, in the order of the P1/P1 blocks."""
        lay = self.layout
        nown = lay.Vc.dofmap.index_map.size_local
        return lay.Vc.tabulate_dof_coordinates()[:nown, : lay.bs - 1].copy()

    def pressure_w_dofs(self) -> np.ndarray:
        """Local W dofs of the owned vertex pressures, in the order of the pressure split."""
        return self.layout.owned_w_dofs()[:, -1]

    def destroy(self):
        for v in self._work + [self._xc, self._yc, self.S] + (
                [self.S_aij] if self.S_aij is not None else []):
            v.destroy()
        self._work = []


class _JacobianOperator:
    """petsc4py python Mat: the product with J' (:meth:`CondensedJacobian.mult`)."""

    def __init__(self, element: CondensedJacobian, W_vector: PETSc.Vec):
        self.element = element
        self._v = W_vector

    def mult(self, mat, x, y):
        self.element.mult(x, y)

    def createVecs(self, mat):
        return self._v.duplicate(), self._v.duplicate()


def jacobian_shell(element: CondensedJacobian) -> PETSc.Mat:
    """A python Mat of the W layout whose product is J' (collective)."""
    v = element._work[0]
    n, N = v.getLocalSize(), v.getSize()
    J = PETSc.Mat().createPython(((n, N), (n, N)), _JacobianOperator(element, v),
                                 comm=element.layout.comm)
    J.setUp()
    return J


def _condensed_pc_class():

    class ElementCondensedPC(CondensedPC):
        """:class:`~fxcontact.element.assembled.CondensedPC` on the P1/P1 matrix of a
        :class:`CondensedJacobian` (no matrix algebra at its set-up), the right-hand side and
        the bubble from the kept cell matrices."""

        def __init__(self, prefix, element: CondensedJacobian, schur_weight=None,
                     problem=None):
            super().__init__(element, prefix, schur_weight, problem)
            self.element = element

        def _condensed_matrix(self, P):
            return self.element.S_aij

        def _condensed_rhs(self, x):
            self.element.condensed_rhs(x, self._rl)

        def _write_solution(self, x, y):
            self.element.recover(x, self._yl, y)

        def _recover(self, x, y):
            pass

        def _condensed_rhs_many(self, xs):
            return self.element.condensed_rhs_many(xs)

        def _weighted_mass(self) -> np.ndarray:
            return self._weighted_mass_at(self.element.pressure_w_dofs())

        def _augmented(self, S):
            if PETSc.Options().getReal(self.prefix + "augment_scale", 0.0) != 0.0:
                raise ValueError("augment_scale needs the algebraic condensation "
                                 "(element_condensation=False)")
            return None

    return ElementCondensedPC


def ElementCondensedPC(prefix, element, schur_weight=None, problem=None):
    """The preconditioner (an exact solver with a direct inner solve) of the Newton matrix of a
    :class:`CondensedJacobian` (see :func:`_condensed_pc_class`)."""
    return _condensed_pc_class()(prefix, element, schur_weight, problem)
