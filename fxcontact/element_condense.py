"""Static condensation of the MINI bubble inside the element kernel: the P1+/P1 Newton system
assembled directly as a P1/P1 one (gdim + 1 unknowns per vertex).

:mod:`fxcontact.condense` assembles the full MINI Jacobian on the mixed space W and eliminates
the bubble algebraically inside the linear solve (sub-matrices, matrix products). Here the
elimination is done cell by cell on the element tensors, before any global assembly. With the
element unknowns ordered as l (the vertex velocities and pressures) and b (the bubble),

    S_e = A_ll − A_lb A_bb⁻¹ A_bl,    r_e = b_l − A_lb A_bb⁻¹ b_b,

and the global condensed system ``S x_l = r`` is the sum of the element ones (the bubble is
interior to its cell, so A_bb is block diagonal by cell). The bubble part of the solution of the
full system ``A x = b`` is recovered cell by cell, ``x_b = A_bb⁻¹ b_b − (A_bb⁻¹ A_bl) x_l``
(:meth:`CondensedAssembler.recover`, from the kept ``A_bb⁻¹ A_bl`` and ``A_bb⁻¹ b_b``).

The element tensors come from either

* :class:`FFCxElementTensors`: the FFCx kernels of any MINI form pair (Jacobian, residual) with
  cell integrals only, called from numba through cffi; or
* :class:`NortonHoffElementTensors`: a hand-written numba kernel of the Norton–Hoff residual
  and its primal–dual tangent (:class:`~fxcontact.dual.DualStress`; the consistent tangent
  without a dual stress) on affine tetrahedra, at the quadrature points and with the basis
  tabulation FFCx uses, with a plain-numpy twin (:func:`norton_hoff_tensors_numpy`).

:class:`P1P1Layout` is the layout of the condensed system: a P1 vector space of dimension
gdim + 1 (one block per vertex: the velocity components, then the pressure), numbered and
distributed by dolfinx like the vertices, so that a vertex owned by a rank has its W dofs and its
condensed block owned there. :class:`CondensedAssembler` computes the condensed element tensors
of the owned cells in chunks and adds them to a PETSc matrix and a ghosted vector of that layout
(collective; any number of ranks).
"""

from __future__ import annotations

import basix
import cffi
import numba
import numpy as np
import ufl
from mpi4py import MPI
from petsc4py import PETSc

import dolfinx
import dolfinx.fem.petsc

from fxcontact import compat
from fxcontact.materials import NortonHoff

__all__ = ["P1P1Layout", "CondensedAssembler", "FFCxElementTensors"]

_ffi = cffi.FFI()


# -- the condensation of one cell -----------------------------------------------------------
@numba.njit(cache=True)
def _condense_cell(A, b, lpos, bpos, S, r, X, y):
    """Condense the ``bpos`` dofs of one element (A, b): S = A_ll − A_lb X, r = b_l − A_lb y
    with X = A_bb⁻¹ A_bl, y = A_bb⁻¹ b_b (Gaussian elimination with partial pivoting).
    Returns False when A_bb is singular or not finite."""
    nl = lpos.size
    k = bpos.size
    M = np.empty((k, k))
    R = np.empty((k, nl + 1))
    for i in range(k):
        for j in range(k):
            M[i, j] = A[bpos[i], bpos[j]]
        for j in range(nl):
            R[i, j] = A[bpos[i], lpos[j]]
        R[i, nl] = b[bpos[i]]
    for col in range(k):
        piv = col
        for i in range(col + 1, k):
            if abs(M[i, col]) > abs(M[piv, col]):
                piv = i
        if not abs(M[piv, col]) > 0.0:
            return False
        if piv != col:
            for j in range(k):
                M[col, j], M[piv, j] = M[piv, j], M[col, j]
            for j in range(nl + 1):
                R[col, j], R[piv, j] = R[piv, j], R[col, j]
        for i in range(col + 1, k):
            f = M[i, col] / M[col, col]
            for j in range(col, k):
                M[i, j] -= f * M[col, j]
            for j in range(nl + 1):
                R[i, j] -= f * R[col, j]
    for i in range(k - 1, -1, -1):
        for j in range(nl + 1):
            acc = R[i, j]
            for q in range(i + 1, k):
                acc -= M[i, q] * R[q, j]
            R[i, j] = acc / M[i, i]
    for i in range(k):
        for j in range(nl):
            X[i, j] = R[i, j]
        y[i] = R[i, nl]
    for i in range(nl):
        li = lpos[i]
        for j in range(nl):
            acc = A[li, lpos[j]]
            for q in range(k):
                acc -= A[li, bpos[q]] * R[q, j]
            S[i, j] = acc
        acc = b[li]
        for q in range(k):
            acc -= A[li, bpos[q]] * R[q, nl]
        r[i] = acc
    return np.all(np.isfinite(R))


# -- generic loops over cells of an element-tensor source ``tab(data, cell, A, b)`` ----------
@numba.njit
def _tensors_loop(tab, data, cells, A_out, b_out):
    for n in range(cells.size):
        tab(data, cells[n], A_out[n], b_out[n])


@numba.njit
def _kernel_loop(tab, data, cells, A, b):
    """The element tensors of ``cells`` into one scratch pair (timing of the kernel alone);
    returns a checksum."""
    acc = 0.0
    for n in range(cells.size):
        tab(data, cells[n], A, b)
        acc += A[0, 0]
    return acc


@numba.njit
def _condense_loop(tab, data, cells, lpos, bpos, A, b, S, r, X, y):
    """Element tensors and their condensation for ``cells``: S[n], r[n] of the n-th cell,
    X[c], y[c] of cell c. Returns the number of cells with a singular bubble block."""
    bad = 0
    for n in range(cells.size):
        c = cells[n]
        tab(data, c, A, b)
        if not _condense_cell(A, b, lpos, bpos, S[n], r[n], X[c], y[c]):
            bad += 1
    return bad


@numba.njit
def _recover_loop(w, w_l, w_b, X, y):
    """x_b = y − X x_l for every cell (w: local W values; the bubble entries are written)."""
    for c in range(w_l.shape[0]):
        for i in range(w_b.shape[1]):
            acc = y[c, i]
            for j in range(w_l.shape[1]):
                acc -= X[c, i, j] * w[w_l[c, j]]
            w[w_b[c, i]] = acc


@numba.njit(cache=True)
def _scatter_add(vals, blocks, bs, out):
    for n in range(blocks.shape[0]):
        for i in range(blocks.shape[1]):
            for k in range(bs):
                out[blocks[n, i] * bs + k] += vals[n, i * bs + k]


# -- layout -----------------------------------------------------------------------------------
class P1P1Layout:
    """The P1/P1 layout of the condensed MINI system: one block of gdim + 1 unknowns per vertex
    (velocity components, then pressure), on a dolfinx P1 vector space of that dimension.

    Args:
        W: a mixed space whose dofs are gdim + 1 per vertex and cell-interior ones (MINI).

    Attributes:
        Vc: the P1 vector space of dimension gdim + 1 (block size ``bs``) of the condensed system.
        lpos, bpos: element-local dofs of W kept (vertex by vertex, ``bs`` each, in the order of
            the blocks) and condensed (the cell interior).
        num_cells: number of owned cells (the cells whose element tensors are computed).
        cell_blocks: (num_cells, vertices per cell) local block of Vc of each cell vertex.
        w_l, w_b: (num_cells, ·) local W dofs of ``lpos`` and ``bpos`` of each owned cell.
        block_w: (num_blocks incl. ghosts, bs) local W dofs of each block of Vc.
    """

    def __init__(self, W):
        msh = W.mesh
        self.W = W
        self.comm = msh.comm
        tdim = msh.topology.dim
        lay = W.dofmap.dof_layout
        vdofs = [list(lay.entity_dofs(0, i)) for i in range(tdim + 1)]
        bs = len(vdofs[0])
        if (W.dofmap.index_map_bs != 1 or bs != msh.geometry.dim + 1
                or any(len(d) != bs for d in vdofs)
                or any(len(lay.entity_dofs(d, 0)) for d in range(1, tdim))
                or len(lay.entity_dofs(tdim, 0)) == 0):
            raise ValueError("the element condensation needs a MINI space (gdim + 1 dofs per "
                             "vertex and cell-interior dofs only): use MixedSpace(msh, 'mini')")
        self.bs = bs
        self.lpos = np.array(vdofs, dtype=np.int32).ravel()
        self.bpos = np.asarray(lay.entity_dofs(tdim, 0), dtype=np.int32)
        self.num_cells = msh.topology.index_map(tdim).size_local
        self.Vc = compat.function_space(
            msh, ufl.VectorElement("Lagrange", msh.ufl_cell(), 1, dim=bs))
        dm = compat.dofmap_array(W)
        cb = compat.dofmap_array(self.Vc)
        self.cell_blocks = np.ascontiguousarray(cb[: self.num_cells])
        self.w_l = np.ascontiguousarray(dm[: self.num_cells][:, self.lpos])
        self.w_b = np.ascontiguousarray(dm[: self.num_cells][:, self.bpos])
        imap = self.Vc.dofmap.index_map
        nblocks = imap.size_local + imap.num_ghosts
        self.block_w = np.full((nblocks, bs), -1, dtype=np.int32)
        self.block_w[cb.ravel()] = dm[:, self.lpos].reshape(-1, bs)
        nown = W.dofmap.index_map.size_local
        owned = np.arange(nblocks) < imap.size_local
        if (np.any(self.block_w < 0) or np.any((self.block_w < nown).all(axis=1) != owned)
                or np.any(self.w_b >= nown)):
            raise RuntimeError("the vertex dofs of W and the blocks of the P1/P1 space are not "
                               "owned by the same ranks")
        self._pattern_form = None

    def create_matrix(self) -> PETSc.Mat:
        """An empty PETSc matrix of the condensed system (the vertex–vertex pattern of the
        cells, block size ``bs``, local-to-global maps set)."""
        if self._pattern_form is None:
            u, v = ufl.TrialFunction(self.Vc), ufl.TestFunction(self.Vc)
            self._pattern_form = compat.form(ufl.inner(u, v) * ufl.dx)
        A = dolfinx.fem.petsc.create_matrix(self._pattern_form)
        A.setOption(PETSc.Mat.Option.NEW_NONZERO_ALLOCATION_ERR, True)
        return A

    def create_vector(self) -> PETSc.Vec:
        """A ghosted PETSc vector of the condensed system."""
        return compat.ghosted_vector(self.Vc)

    def owned_w_dofs(self) -> np.ndarray:
        """(owned blocks, bs) local W dofs of the owned blocks, in the order of the owned part of
        a condensed vector."""
        return self.block_w[: self.Vc.dofmap.index_map.size_local]

    def to_w(self, xc: PETSc.Vec, w: np.ndarray):
        """Copy the vertex values of the condensed vector ``xc`` (ghosts updated here) into the
        local W array ``w`` (owned and ghost entries)."""
        xc.ghostUpdate(addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)
        with xc.localForm() as loc:
            w[self.block_w.ravel()] = loc.getArray(readonly=True)


# -- element tensors from the FFCx kernels ------------------------------------------------------
def _ffcx_tabulators(kernel_a, kernel_L):
    """numba element-tensor sources calling the FFCx kernels of a (Jacobian, residual) pair:
    both, and the Jacobian alone (benchmarks)."""
    ffi = _ffi

    @numba.njit
    def _coords(data, c):
        x, xdofs, coords = data[0], data[1], data[6]
        for i in range(xdofs.shape[1]):
            for j in range(3):
                coords[i, j] = x[xdofs[c, i], j]

    @numba.njit
    def tab(data, c, A, b):
        _coords(data, c)
        ca, ka, cL, kL, coords, ent, perm = data[2], data[3], data[4], data[5], data[6], \
            data[7], data[8]
        A[:] = 0.0
        b[:] = 0.0
        kernel_a(ffi.from_buffer(A), ffi.from_buffer(ca[c]), ffi.from_buffer(ka),
                 ffi.from_buffer(coords), ffi.from_buffer(ent), ffi.from_buffer(perm))
        kernel_L(ffi.from_buffer(b), ffi.from_buffer(cL[c]), ffi.from_buffer(kL),
                 ffi.from_buffer(coords), ffi.from_buffer(ent), ffi.from_buffer(perm))

    @numba.njit
    def tab_jacobian(data, c, A, b):
        _coords(data, c)
        ca, ka, coords, ent, perm = data[2], data[3], data[6], data[7], data[8]
        A[:] = 0.0
        kernel_a(ffi.from_buffer(A), ffi.from_buffer(ca[c]), ffi.from_buffer(ka),
                 ffi.from_buffer(coords), ffi.from_buffer(ent), ffi.from_buffer(perm))

    return tab, tab_jacobian


class FFCxElementTensors:
    """Element tensors of a MINI form pair from its FFCx kernels.

    Args:
        layout: the :class:`P1P1Layout` of the forms' space.
        a, L: the Jacobian (bilinear) and residual (linear) forms on ``layout.W``, UFL or
            compiled by dolfinx; cell integrals over the whole mesh only (a term on facets or
            on tagged cells is refused: the condensation works on whole-cell element tensors).
    """

    def __init__(self, layout: P1P1Layout, a, L):
        self.layout = layout
        self.a = a if hasattr(a, "ufcx_form") else compat.form(a)
        self.L = L if hasattr(L, "ufcx_form") else compat.form(L)
        ka = compat.cell_kernel(self.a, "a")
        kL = compat.cell_kernel(self.L, "L")
        self.tab, self.tab_jacobian = _ffcx_tabulators(ka, kL)
        msh = layout.W.mesh
        self._x = msh.geometry.x
        self._xdofs = compat.geometry_dofmap(msh)
        self._scratch = (np.zeros((self._xdofs.shape[1], 3)), np.zeros(1, dtype=np.int32),
                         np.zeros(1, dtype=np.uint8))

    def data(self):
        """The kernels' inputs at the current coefficients and constants (packed here)."""
        return (self._x, self._xdofs, compat.pack_cell_coefficients(self.a),
                compat.pack_constants(self.a), compat.pack_cell_coefficients(self.L),
                compat.pack_constants(self.L)) + self._scratch

    def tensors(self, cells: np.ndarray):
        """(A, b): the (n, ndofs, ndofs) element matrices and (n, ndofs) vectors of ``cells``
        in the element order of W."""
        return _element_tensors(self, cells)


def _element_tensors(src, cells):
    ndofs = src.layout.W.element.space_dimension
    cells = np.asarray(cells, dtype=np.int32)
    A = np.zeros((cells.size, ndofs, ndofs))
    b = np.zeros((cells.size, ndofs))
    _tensors_loop(src.tab, src.data(), cells, A, b)
    return A, b


# -- assembly of the condensed system ----------------------------------------------------------
class CondensedAssembler:
    """Assembly of the condensed P1/P1 system from element tensors, and bubble recovery.

    Args:
        tensors: an element-tensor source (:class:`FFCxElementTensors` or
            :class:`NortonHoffElementTensors`).
        chunk: number of cells condensed at once (bounds the memory of the element tensors).

    Attributes:
        X, y: (num_cells, n_int, nl) ``A_bb⁻¹ A_bl`` and (num_cells, n_int) ``A_bb⁻¹ b_b`` of
            each owned cell at the last :meth:`assemble`.
    """

    def __init__(self, tensors, chunk: int = 8192):
        self.tensors = tensors
        self.layout = lay = tensors.layout
        self.chunk = max(int(chunk), 1)
        nl, k = lay.lpos.size, lay.bpos.size
        self.X = np.zeros((lay.num_cells, k, nl))
        self.y = np.zeros((lay.num_cells, k))
        ndofs = lay.W.element.space_dimension
        self._A = np.zeros((ndofs, ndofs))
        self._b = np.zeros(ndofs)

    def condense(self, cells: np.ndarray, data=None):
        """(S, r) of ``cells`` (condensed element matrices and vectors, ``X``/``y`` updated);
        returns also the number of cells with a singular bubble block."""
        lay = self.layout
        cells = np.asarray(cells, dtype=np.int32)
        nl = lay.lpos.size
        S = np.empty((cells.size, nl, nl))
        r = np.empty((cells.size, nl))
        bad = _condense_loop(self.tensors.tab, self.tensors.data() if data is None else data,
                             cells, lay.lpos, lay.bpos, self._A, self._b, S, r, self.X, self.y)
        return S, r, bad

    def assemble(self, A: PETSc.Mat = None, b: PETSc.Vec = None):
        """The condensed matrix and right-hand side (collective). ``A``/``b``: reused (their
        values replaced) or created by the layout. Raises RuntimeError on every rank when a
        cell's bubble block is singular (a degenerate element)."""
        lay = self.layout
        A = lay.create_matrix() if A is None else A
        b = lay.create_vector() if b is None else b
        A.zeroEntries()
        data = self.tensors.data()
        bad = 0
        with b.localForm() as bl:
            bl.set(0.0)
            barr = bl.getArray()
            for c0 in range(0, lay.num_cells, self.chunk):
                cells = np.arange(c0, min(c0 + self.chunk, lay.num_cells), dtype=np.int32)
                S, r, nbad = self.condense(cells, data)
                bad += nbad
                blocks = lay.cell_blocks[cells]
                A.setValuesBlockedLocalRCV(blocks, blocks, S.reshape(cells.size, -1),
                                           addv=PETSc.InsertMode.ADD)
                _scatter_add(r, blocks, lay.bs, barr)
        A.assemble()
        b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        if lay.comm.allreduce(bad):
            raise RuntimeError("singular interior (bubble) block in a cell: degenerate element")
        return A, b

    def recover(self, w: np.ndarray):
        """Write the bubble values of the solution of the full system into the local W array
        ``w``, from its vertex values (owned and ghosts: :meth:`P1P1Layout.to_w`); owned cells
        only: scatter ``w`` forward afterwards for the bubbles of ghost cells."""
        lay = self.layout
        _recover_loop(w, lay.w_l, lay.w_b, self.X, self.y)
