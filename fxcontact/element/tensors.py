"""Static condensation of the MINI bubble inside the element kernel: the P1+/P1 Newton system
assembled directly as a P1/P1 one (gdim + 1 unknowns per vertex).

:mod:`fxcontact.element.assembled` assembles the full MINI Jacobian on the mixed space W and eliminates
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
  and its primal–dual tangent (:class:`~fxcontact.element.dual.DualStress`; the consistent tangent
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
import dolfinx
import dolfinx.fem.petsc
import numba
import numba.experimental.function_type  # noqa: F401 (numba's typing of first-class functions)
import numpy as np
import ufl
from ffcx.element_interface import create_element
from petsc4py import PETSc

from fxcontact import compat
from fxcontact.element.cell import condense_system, tet_geometry
from fxcontact.materials.laws import NortonHoff, kernel_reads_law

__all__ = ["P1P1Layout", "CondensedAssembler", "FFCxElementTensors",
           "NortonHoffElementTensors", "KernelTables", "ffcx_tab_jacobian", "nh_tab", "norton_hoff_forms",
           "norton_hoff_tensors_numpy"]

_ffi = cffi.FFI()


# -- generic loops over cells of an element-tensor source ``tab(data, cell, A, b)`` ----------
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
        if not condense_system(A, b, lpos, bpos, S[n], r[n], X[c], y[c]):
            bad += 1
    return bad


@numba.njit(cache=True)
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

    def create_matrix(self, mat_type=None) -> PETSc.Mat:
        """An empty PETSc matrix of the condensed system (the vertex–vertex pattern of the
        cells, block size ``bs``, local-to-global maps set); ``mat_type``: a PETSc type
        (default dolfinx's, AIJ; ``"baij"`` stores and inserts by blocks)."""
        if self._pattern_form is None:
            u, v = ufl.TrialFunction(self.Vc), ufl.TestFunction(self.Vc)
            self._pattern_form = compat.form(ufl.inner(u, v) * ufl.dx)
        A = dolfinx.fem.petsc.create_matrix(self._pattern_form, mat_type)
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
#: the signature of FFCx's ``tabulate_tensor_float64``: (A, w, c, coordinate_dofs,
#: entity_local_index, quadrature_permutation)
_KERNEL_SIGNATURE = numba.types.void(*(numba.types.CPointer(t) for t in (
    numba.types.float64, numba.types.float64, numba.types.float64, numba.types.float64,
    numba.types.int32, numba.types.uint8)))


class _FFCxKernel(numba.types.WrapperAddressProtocol):
    """An FFCx ``tabulate_tensor`` (a cffi function pointer) as a numba first-class function:
    every kernel has the same numba type, so the loops that call one are compiled once and
    cached on disk, not compiled again for each form (2–3 s each: every new problem, every
    remesh)."""

    def __init__(self, fn):
        self._fn = fn                                  # keeps the compiled module alive
        self._address = int(_ffi.cast("uintptr_t", fn))

    def __wrapper_address__(self):
        return self._address

    def signature(self):
        return _KERNEL_SIGNATURE


@numba.njit(cache=True)
def _ffcx_coords(data, c):
    x, xdofs, coords = data[0], data[1], data[6]
    for i in range(xdofs.shape[1]):
        for j in range(3):
            coords[i, j] = x[xdofs[c, i], j]


@numba.njit(cache=True)
def _ffcx_tab(data, c, A, b):
    """Element matrix and vector of cell c from the FFCx kernels in ``data``
    (:meth:`FFCxElementTensors.data`)."""
    _ffcx_coords(data, c)
    ca, ka, cL, kL, coords, ent, perm = data[2], data[3], data[4], data[5], data[6], \
        data[7], data[8]
    kernel_a, kernel_L = data[9], data[10]
    A[:] = 0.0
    b[:] = 0.0
    kernel_a(_ffi.from_buffer(A), _ffi.from_buffer(ca[c]), _ffi.from_buffer(ka),
             _ffi.from_buffer(coords), _ffi.from_buffer(ent), _ffi.from_buffer(perm))
    kernel_L(_ffi.from_buffer(b), _ffi.from_buffer(cL[c]), _ffi.from_buffer(kL),
             _ffi.from_buffer(coords), _ffi.from_buffer(ent), _ffi.from_buffer(perm))


@numba.njit(cache=True)
def ffcx_tab_jacobian(data, c, A, b):
    """The element matrix of cell c alone (``b`` untouched)."""
    _ffcx_coords(data, c)
    ca, ka, coords, ent, perm, kernel_a = data[2], data[3], data[6], data[7], data[8], data[9]
    A[:] = 0.0
    kernel_a(_ffi.from_buffer(A), _ffi.from_buffer(ca[c]), _ffi.from_buffer(ka),
             _ffi.from_buffer(coords), _ffi.from_buffer(ent), _ffi.from_buffer(perm))


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
        self._kernel_a, self._kernel_L = ka, kL
        self._kernels = (_FFCxKernel(ka), _FFCxKernel(kL))
        self.tab, self.tab_jacobian = _ffcx_tab, ffcx_tab_jacobian
        msh = layout.W.mesh
        self._x = msh.geometry.x
        self._xdofs = compat.geometry_dofmap(msh)
        self._scratch = (np.zeros((self._xdofs.shape[1], 3)), np.zeros(1, dtype=np.int32),
                         np.zeros(1, dtype=np.uint8))

    def data(self):
        """The kernels' inputs at the current coefficients and constants (packed here)."""
        return (self._x, self._xdofs, compat.pack_cell_coefficients(self.a),
                compat.pack_constants(self.a), compat.pack_cell_coefficients(self.L),
                compat.pack_constants(self.L)) + self._scratch + self._kernels

    def tensors(self, cells: np.ndarray):
        """(A, b): the (n, ndofs, ndofs) element matrices and (n, ndofs) vectors of ``cells``
        in the element order of W. The FFCx kernels are called from Python (cffi), one cell
        at a time: no numba compilation for a few cells (the sample check of the hand kernel,
        the tests); the assembly loops call them from numba."""
        ndofs = self.layout.W.element.space_dimension
        cells = np.asarray(cells, dtype=np.int32)
        A = np.zeros((cells.size, ndofs, ndofs))
        b = np.zeros((cells.size, ndofs))
        (x, xdofs, ca, ka, cL, kL, coords, ent, perm) = self.data()[:9]
        ptr = _ffi.cast
        ka_p, kL_p = ptr("double *", ka.ctypes.data), ptr("double *", kL.ctypes.data)
        ent_p, perm_p = ptr("int *", ent.ctypes.data), ptr("uint8_t *", perm.ctypes.data)
        for n, c in enumerate(cells):
            crd = np.ascontiguousarray(x[xdofs[c]])
            crd_p = ptr("double *", crd.ctypes.data)
            wa, wL = np.ascontiguousarray(ca[c]), np.ascontiguousarray(cL[c])
            self._kernel_a(ptr("double *", A[n].ctypes.data), ptr("double *", wa.ctypes.data),
                           ka_p, crd_p, ent_p, perm_p)   # (A[n], b[n]: contiguous, zeroed)
            self._kernel_L(ptr("double *", b[n].ctypes.data), ptr("double *", wL.ctypes.data),
                           kL_p, crd_p, ent_p, perm_p)
        return A, b


# -- element tensors of Norton–Hoff from a hand-written kernel ----------------------------------
def norton_hoff_forms(space, material: NortonHoff, w, dual=None, pressure_source=None):
    """(Jacobian, residual) UFL forms of the Norton–Hoff law on ``space`` at the state ``w``:
    the residual ``material.residual`` (plus ``−q g dx`` with a ``pressure_source`` g, the
    volume correction of :class:`~fxcontact.simulation.Simulation`) and the primal–dual
    tangent of ``dual`` (:class:`~fxcontact.element.dual.DualStress`; the consistent Jacobian without)
    — the forms whose element tensors :class:`NortonHoffElementTensors` computes by hand."""
    W = space.W
    v, p = ufl.split(w)
    wt, q = ufl.TestFunctions(W)
    dw = ufl.TrialFunction(W)
    dv, dp = ufl.split(dw)
    F = material.residual(v, p, wt, q, space.dx, 1.0)
    if pressure_source is not None:
        F = F - q * pressure_source * space.dx
    if dual is None:
        return ufl.derivative(F, w, dw), F
    return (dual.tangent_form(v, dv, wt, space.dx)
            + material.incompressibility_ufl(dv, dp, wt, q, space.dx), F)


#: the element order of the MINI space on tetrahedra that the hand kernel is written for:
#: velocity node n (vertices 0-3, bubble 4) component c at 3 n + c, pressure of vertex i at 15 + i
_MINI_TET_LPOS = np.array([[3 * i, 3 * i + 1, 3 * i + 2, 15 + i] for i in range(4)]).ravel()
_MINI_TET_BPOS = np.array([12, 13, 14])


def _reference_tables(space):
    """The quadrature weights and the reference tabulation FFCx uses for the MINI space:
    (velocity basis reference gradients (nq, 5, 3), pressure basis values (nq, 4), weights
    (nq,)). The velocity basis is the element's own: basix's enriched P1 + bubble element,
    whose vertex functions are not the P1 hat functions (they hold a share of the bubble), so
    their gradients vary over the cell."""

    cell = basix.cell.string_to_type(space.mesh.topology.cell_type.name)
    pts, wts = basix.make_quadrature(cell, space.quadrature_degree)
    vel, pre = space.W.ufl_element().sub_elements()
    tv = np.asarray(create_element(vel.sub_elements()[0]).tabulate(1, pts))   # (4, nq, 5)
    tp = np.asarray(create_element(pre).tabulate(0, pts))[0]                  # (nq, 4)
    return (np.ascontiguousarray(np.transpose(tv[1:], (1, 2, 0))), np.ascontiguousarray(tp),
            np.ascontiguousarray(wts))


class KernelTables:
    """The reference tables of the hand kernel, split as the element is: the velocity basis
    of the MINI element is φ_n = λ_n + c_n B (n < 4: the P1 hat functions plus a share c_n of
    the bubble B; φ_4 = B), checked on the tabulation.

    Attributes:
        full: (gradients of φ (nq, 5, 3), pressure basis values (nq, 4), weights (nq,)): the
            tables of the numpy twin.
        g1: (4, 3) reference gradients of the hat functions; gb: (nq, 3) of the bubble;
        share: (4,) the c_n; psi_w: (4,) ∫ ψ_i (reference cell); psi_gb: (4, 3) ∫ ψ_i ∇B.
    """

    def __init__(self, space):

        gref, psi, wq = self.full = _reference_tables(space)
        _, pre = space.W.ufl_element().sub_elements()
        cell = basix.cell.string_to_type(space.mesh.topology.cell_type.name)
        g1 = np.asarray(create_element(pre).tabulate(1, basix.geometry(cell)[:1]))[1:, 0].T
        gb = gref[:, 4]
        rest = gref[:, :4] - g1[None]                                      # (nq, 4, 3)
        share = np.einsum("qnk,qk->n", rest, gb) / np.einsum("qk,qk->", gb, gb)
        if np.abs(rest - share[None, :, None] * gb[:, None]).max() > 1e-10 * np.abs(gref).max():
            raise ValueError("the velocity element is not P1 plus a bubble: use "
                             "FFCxElementTensors")
        self.g1 = np.ascontiguousarray(g1)
        self.gb = np.ascontiguousarray(gb)
        self.share = share
        self.wq = wq
        self.psi_w = psi.T @ wq
        self.psi_gb = np.einsum("q,qi,qk->ik", wq, psi, gb)

    def arrays(self) -> tuple:
        return (self.g1, self.gb, self.share, self.wq, self.psi_w, self.psi_gb)


@numba.njit(cache=True, error_model="numpy")
def _nh_cell(coords, wv, s, has_dual, Kc, mc, zn, eps0, g, g1, gb, share, wq, psi_w, psi_gb,
             A, b):
    """Element matrix A (19 × 19) and vector b (19) of the Norton–Hoff residual and of its
    primal–dual tangent (dual stress ``s`` (nq, 3, 3); ``has_dual`` False: the primal stress,
    the consistent tangent) on an affine tetrahedron, in the element order of W (not finite on
    a degenerate cell: the condensation then reports it). The law of the cell is K = Kc[j],
    m = mc[j] on the rate interval j of each quadrature point's z (bounds ``zn``, in z:
    :meth:`~fxcontact.materials.NortonHoff.kernel_law`).

    Written in the basis (λ_n, B) of the hat functions, whose gradients are constant, and the
    bubble: the vertex–vertex block is a contraction of sums over the quadrature points
    (Σ ω η, Σ ω c Ŝ⊗e), the blocks with the bubble per point; then changed to the element's
    basis φ_n = λ_n + c_n B (a congruence with the shares c_n)."""
    Ki = np.empty((3, 3))      # J⁻¹
    G = np.empty((4, 3))       # gradients of the hat functions
    adet = abs(tet_geometry(coords, g1, Ki, G))
    vb = np.empty(3)           # bubble coefficient in the (λ, B) basis
    for c in range(3):
        vb[c] = wv[12 + c]
        for n in range(4):
            vb[c] += share[n] * wv[3 * n + c]
    Lc = np.zeros((3, 3))
    for n in range(4):
        for i in range(3):
            for j in range(3):
                Lc[i, j] += wv[3 * n + i] * G[n, j]
    trc = Lc[0, 0] + Lc[1, 1] + Lc[2, 2]
    # sums over the quadrature points
    H = 0.0                              # Σ ω η
    X = np.zeros(3)                      # Σ ω η ∇B
    Y = np.zeros((3, 3))                 # Σ ω η ∇B ⊗ ∇B
    E = np.zeros((3, 3))                 # Σ ω η e
    Z = np.zeros(3)                      # Σ ω η e ∇B
    M = np.zeros((3, 3, 3, 3))           # Σ ω c Ŝ ⊗ e
    N = np.zeros((3, 3, 3))              # Σ ω c (Ŝ ⊗ e∇B + e ⊗ Ŝ∇B)
    Rbb = np.zeros((3, 3))               # Σ ω c (Ŝ∇B ⊗ e∇B)
    gB = np.empty(3)
    e = np.empty((3, 3))
    sh = np.empty((3, 3))
    eg = np.empty(3)
    sg = np.empty(3)
    for q in range(wq.size):
        for j in range(3):
            gB[j] = Ki[0, j] * gb[q, 0] + Ki[1, j] * gb[q, 1] + Ki[2, j] * gb[q, 2]
        tr = trc + vb[0] * gB[0] + vb[1] * gB[1] + vb[2] * gB[2]
        ee = 0.0
        for i in range(3):
            for j in range(3):
                e[i, j] = 0.5 * (Lc[i, j] + Lc[j, i] + vb[i] * gB[j] + vb[j] * gB[i])
            e[i, i] -= tr / 3.0
        for i in range(3):
            for j in range(3):
                ee += e[i, j] * e[i, j]
        z = np.sqrt(2.0 * ee + 3.0 * eps0 * eps0)
        j = 0
        while j < zn.size and z >= zn[j]:
            j += 1
        K = Kc[j]
        m = mc[j]
        om = wq[q] * adet
        eta = om * 2.0 * K * z ** (m - 1.0)
        cr = om * 2.0 * (1.0 - m) / (z * z)
        if has_dual:
            trs = (s[q, 0, 0] + s[q, 1, 1] + s[q, 2, 2]) / 3.0
            for i in range(3):
                for j in range(3):
                    sh[i, j] = 0.5 * (s[q, i, j] + s[q, j, i])
                sh[i, i] -= trs
        else:
            for i in range(3):
                for j in range(3):
                    sh[i, j] = eta / om * e[i, j]
        for i in range(3):
            eg[i] = e[i, 0] * gB[0] + e[i, 1] * gB[1] + e[i, 2] * gB[2]
            sg[i] = sh[i, 0] * gB[0] + sh[i, 1] * gB[1] + sh[i, 2] * gB[2]
        H += eta
        for i in range(3):
            X[i] += eta * gB[i]
            Z[i] += eta * eg[i]
            for j in range(3):
                Y[i, j] += eta * gB[i] * gB[j]
                E[i, j] += eta * e[i, j]
                Rbb[i, j] += cr * sg[i] * eg[j]
                for d in range(3):
                    N[i, j, d] += cr * (sh[i, j] * eg[d] + e[i, j] * sg[d])
                    for l in range(3):
                        M[i, j, d, l] += cr * sh[i, j] * e[d, l]
    A[:, :] = 0.0
    b[:] = 0.0
    # vertex-vertex: H (½δ g_n·g_k + ½ g_n,d g_k,c − ⅓ g_n,c g_k,d) − ½ Σ g_n,j g_k,l (M + Mᵀ)
    P = np.zeros((4, 3, 3, 3))           # P[n, c, d, l] = Σ_j g_n,j M[c, j, d, l]
    Q = np.zeros((4, 3, 3, 3))           # Q[n, d, c, j] = Σ_l g_n,l M[c, j, d, l]
    for n in range(4):
        for c in range(3):
            for j in range(3):
                for d in range(3):
                    for l in range(3):
                        P[n, c, d, l] += G[n, j] * M[c, j, d, l]
                        Q[n, d, c, j] += G[n, l] * M[c, j, d, l]
    for n in range(4):
        for k in range(n, 4):
            gg = G[n, 0] * G[k, 0] + G[n, 1] * G[k, 1] + G[n, 2] * G[k, 2]
            for c in range(3):
                for d in range(3):
                    r1 = 0.0
                    for l in range(3):
                        r1 += P[n, c, d, l] * G[k, l] + Q[n, c, d, l] * G[k, l]
                    val = H * (0.5 * G[n, d] * G[k, c] - G[n, c] * G[k, d] / 3.0) - 0.5 * r1
                    if c == d:
                        val += 0.5 * H * gg
                    A[3 * n + c, 3 * k + d] = val
                    A[3 * k + d, 3 * n + c] = val
    # vertex-bubble and bubble-bubble
    for n in range(4):
        gx = G[n, 0] * X[0] + G[n, 1] * X[1] + G[n, 2] * X[2]
        for c in range(3):
            for d in range(3):
                r1 = 0.0
                for j in range(3):
                    r1 += G[n, j] * N[c, j, d]
                val = 0.5 * G[n, d] * X[c] - G[n, c] * X[d] / 3.0 - 0.5 * r1
                if c == d:
                    val += 0.5 * gx
                A[3 * n + c, 12 + d] = val
                A[12 + d, 3 * n + c] = val
    trY = Y[0, 0] + Y[1, 1] + Y[2, 2]
    for c in range(3):
        for d in range(3):
            val = 0.5 * Y[d, c] - Y[c, d] / 3.0 - 0.5 * (Rbb[c, d] + Rbb[d, c])
            if c == d:
                val += 0.5 * trY
            A[12 + c, 12 + d] = val
    # pressure coupling, residual
    pw = 0.0
    for i in range(4):
        pw += psi_w[i] * wv[15 + i]
    pgb = np.zeros((4, 3))               # ∫ ψ_i ∇B on the cell
    for i in range(4):
        for j in range(3):
            pgb[i, j] = adet * (Ki[0, j] * psi_gb[i, 0] + Ki[1, j] * psi_gb[i, 1]
                                + Ki[2, j] * psi_gb[i, 2])
    for i in range(4):
        for n in range(4):
            for c in range(3):
                val = -adet * psi_w[i] * G[n, c]
                A[3 * n + c, 15 + i] = val
                A[15 + i, 3 * n + c] = val
        for c in range(3):
            A[12 + c, 15 + i] = -pgb[i, c]
            A[15 + i, 12 + c] = -pgb[i, c]
        b[15 + i] = -adet * psi_w[i] * (trc + g) - (vb[0] * pgb[i, 0] + vb[1] * pgb[i, 1]
                                                    + vb[2] * pgb[i, 2])
    for n in range(4):
        for c in range(3):
            b[3 * n + c] = (E[c, 0] * G[n, 0] + E[c, 1] * G[n, 1] + E[c, 2] * G[n, 2]
                            - adet * pw * G[n, c])
    for c in range(3):
        b[12 + c] = Z[c]
        for i in range(4):
            b[12 + c] -= wv[15 + i] * pgb[i, c]
    # to the element's basis φ_n = λ_n + c_n B
    for n in range(4):
        for c in range(3):
            for j in range(19):
                A[3 * n + c, j] += share[n] * A[12 + c, j]
            b[3 * n + c] += share[n] * b[12 + c]
    for n in range(4):
        for c in range(3):
            for i in range(19):
                A[i, 3 * n + c] += share[n] * A[i, 12 + c]


@numba.njit(cache=True)
def nh_tab(data, c, A, b):
    (x, xdofs, warr, wdofs, sarr, sdofs, prm, Kc, mc, zn, g1, gb, share, wq, psi_w, psi_gb,
     coords, wv, s) = data
    for i in range(4):
        for j in range(3):
            coords[i, j] = x[xdofs[c, i], j]
    for i in range(wdofs.shape[1]):
        wv[i] = warr[wdofs[c, i]]
    has_dual = prm[2] != 0.0
    if has_dual:
        for q in range(sdofs.shape[1]):
            for k in range(9):
                s[q, k // 3, k % 3] = sarr[sdofs[c, q] * 9 + k]
    _nh_cell(coords, wv, s, has_dual, Kc[c], mc[c], zn, prm[0], prm[1], g1, gb, share, wq,
             psi_w, psi_gb, A, b)


@numba.njit(cache=True)
def _nh_tensors_loop(data, cells, A_out, b_out):
    """The element tensors of ``cells`` by the hand kernel (called directly: cached on disk)."""
    for n in range(cells.size):
        nh_tab(data, cells[n], A_out[n], b_out[n])


def norton_hoff_tensors_numpy(coords, wv, s, K, m, eps0, g, tables, z_nodes=()):
    """numpy twin of the hand-written kernel: (A (n, 19, 19), b (n, 19)) of n cells from their
    vertex coordinates (n, 4, 3), element values of W (n, 19), dual stresses (n, nq, 3, 3) or
    None (primal stress: the consistent tangent), the law's K, m (numbers, or (n, nint) per cell
    and rate interval with the interval bounds ``z_nodes`` in z), ε̇₀, the pressure source g and
    :func:`_reference_tables`."""
    gref, psi, wq = tables
    n = coords.shape[0]
    J = np.transpose(coords[:, 1:] - coords[:, :1], (0, 2, 1))
    Ki = np.linalg.inv(J)
    om = wq[None, :] * np.abs(np.linalg.det(J))[:, None]                       # (n, nq)
    G = np.einsum("qak,nkj->nqaj", gref, Ki)                                   # (n, nq, 5, 3)
    V = wv[:, :15].reshape(n, 5, 3)
    P = wv[:, 15:]
    L = np.einsum("nai,nqaj->nqij", V, G)
    eps = 0.5 * (L + np.swapaxes(L, -1, -2))
    tr = np.trace(eps, axis1=-2, axis2=-1)
    I3 = np.eye(3)
    e = eps - tr[..., None, None] / 3.0 * I3
    z = np.sqrt(2.0 * np.einsum("nqij,nqij->nq", e, e) + 3.0 * eps0**2)
    if np.ndim(K):   # the piece of each point's rate interval
        j = np.searchsorted(np.asarray(z_nodes, dtype=float), z, side="right")
        K = np.take_along_axis(np.asarray(K, dtype=float), j, axis=1)
        m = np.take_along_axis(np.asarray(m, dtype=float), j, axis=1)
    eta2 = 2.0 * K * z ** (m - 1.0)
    cr = 2.0 * (1.0 - m) / z**2
    if s is None:
        sh = eta2[..., None, None] * e
    else:
        ssym = 0.5 * (s + np.swapaxes(s, -1, -2))
        sh = ssym - np.trace(s, axis1=-2, axis2=-1)[..., None, None] / 3.0 * I3
    pq = np.einsum("qi,ni->nq", psi, P)
    u = np.einsum("nqcj,nqaj->nqac", sh, G).reshape(n, wq.size, 15)
    t = np.einsum("nqcj,nqaj->nqac", e, G).reshape(n, wq.size, 15)
    b = np.zeros((n, 19))
    b[:, :15] = np.einsum("nq,nqa->na", om, eta2[..., None] * t
                          - (pq[..., None, None] * G).reshape(n, wq.size, 15))
    b[:, 15:] = -np.einsum("nq,qi->ni", om * (tr + g), psi)
    GG = np.einsum("nqaj,nqbj->nqab", G, G)
    Avv = (0.5 * np.einsum("nqab,cd->nqacbd", GG, I3)
           + 0.5 * np.einsum("nqad,nqbc->nqacbd", G, G)
           - np.einsum("nqac,nqbd->nqacbd", G, G) / 3.0).reshape(n, wq.size, 15, 15)
    Avv = eta2[..., None, None] * Avv - 0.5 * cr[..., None, None] * (
        np.einsum("nqa,nqb->nqab", u, t) + np.einsum("nqa,nqb->nqab", t, u))
    A = np.zeros((n, 19, 19))
    A[:, :15, :15] = np.einsum("nq,nqab->nab", om, Avv)
    Bp = -np.einsum("nq,qi,nqa->nai", om, psi, G.reshape(n, wq.size, 15))
    A[:, :15, 15:] = Bp
    A[:, 15:, :15] = np.swapaxes(Bp, 1, 2)
    return A, b


class NortonHoffElementTensors:
    """Element tensors of the Norton–Hoff residual and its primal–dual (or consistent) tangent
    from a hand-written numba kernel: the forms of :func:`norton_hoff_forms` on affine
    tetrahedra, at the quadrature points of the space's degree (basix's, as FFCx) with the
    basis tabulated by the element itself.

    Args:
        layout: the :class:`P1P1Layout` of a 3D MINI :class:`~fxcontact.spaces.MixedSpace`.
        space: that MixedSpace (quadrature degree, measures).
        material: a :class:`~fxcontact.materials.NortonHoff` with its own law (a subclass that
            redefines the stress, z, the exponent or the residual is refused: use
            :class:`FFCxElementTensors` with its forms).
        w: the state (a Function on W).
        dual: the :class:`~fxcontact.element.dual.DualStress` whose stress enters the tangent, or None
            for the consistent tangent.
        pressure_source: the constant g of the term ``−q g dx`` of the residual (attribute,
            may change between assemblies).
    """

    def __init__(self, layout: P1P1Layout, space, material, w, dual=None,
                 pressure_source: float = 0.0):
        if not (isinstance(material, NortonHoff) and all(
                getattr(type(material), name) is getattr(NortonHoff, name)
                for name in ("stress_ufl", "z_ufl", "exponent_ufl", "residual",
                             "incompressibility_ufl", "dual_tangent_ufl"))
                and kernel_reads_law(material)):
            raise ValueError("the hand-written kernel is NortonHoff's own law: for a material "
                             f"{type(material).__name__} use FFCxElementTensors with its forms")
        if (space.mesh.topology.cell_type != dolfinx.mesh.CellType.tetrahedron
                or space.element != "mini"
                or not np.array_equal(layout.lpos, _MINI_TET_LPOS)
                or not np.array_equal(layout.bpos, _MINI_TET_BPOS)
                or compat.geometry_dofmap(space.mesh).shape[1] != 4):
            raise ValueError("the hand-written kernel is for the MINI space on affine "
                             "tetrahedra: use FFCxElementTensors on other spaces")
        self.layout = layout
        self.space = space
        self.material = material
        self.w = w
        self.dual = dual
        self.pressure_source = float(pressure_source)
        self.tables = KernelTables(space)
        msh = space.mesh
        self._x = msh.geometry.x
        self._xdofs = compat.geometry_dofmap(msh)
        self._wdofs = compat.dofmap_array(space.W)
        nq = self.tables.wq.size
        if dual is not None:
            self._sdofs = compat.dofmap_array(dual.Q)
            if self._sdofs.shape[1] != nq or dual.Q.dofmap.index_map_bs != 9:
                raise ValueError("the dual stress is not at the quadrature points of the space")
        else:
            self._sdofs = np.zeros((0, 0), dtype=np.int32)
        self._scratch = (np.zeros((4, 3)), np.zeros(19), np.zeros((nq, 3, 3)))
        self.tab = nh_tab

    def data(self):
        """The kernel's inputs at the current state."""
        mat = self.material
        prm = np.array([mat.regularization, self.pressure_source,
                        0.0 if self.dual is None else 1.0])
        sarr = np.zeros(0) if self.dual is None else self.dual.s.x.array
        law = mat.kernel_law(self._xdofs.shape[0])
        return (self._x, self._xdofs, self.w.x.array, self._wdofs, sarr, self._sdofs, prm) \
            + law + self.tables.arrays() + self._scratch

    def tensors(self, cells: np.ndarray):
        """(A, b): the (n, 19, 19) element matrices and (n, 19) vectors of ``cells``."""
        cells = np.asarray(cells, dtype=np.int32)
        A = np.zeros((cells.size, 19, 19))
        b = np.zeros((cells.size, 19))
        _nh_tensors_loop(self.data(), cells, A, b)
        return A, b

    def inputs(self, cells: np.ndarray) -> tuple:
        """The arguments of :func:`norton_hoff_tensors_numpy` for ``cells`` (the numpy twin)."""
        cells = np.asarray(cells, dtype=np.int32)
        coords = self._x[self._xdofs[cells]]
        wv = self.w.x.array[self._wdofs[cells]]
        s = None
        if self.dual is not None:
            s = self.dual.s.x.array.reshape(-1, 3, 3)[self._sdofs[cells]]
        mat = self.material
        K, m, zn = mat.kernel_law(self._xdofs.shape[0])
        return (coords, wv, s, K[cells], m[cells], mat.regularization, self.pressure_source,
                self.tables.full, zn)


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
