"""The Newton matrix of a MINI problem with its bubble condensed element by element.

:class:`~fxcontact.condense.CondensedPC` eliminates the bubble from the *assembled* MINI
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

The element matrices come from :mod:`fxcontact.element_condense`: the FFCx kernel of the
problem's own Jacobian form (any form with cell integrals only), or the hand-written Norton–Hoff
kernel where it is the same (checked on sample cells at the first assembly).
"""

from __future__ import annotations

import logging
from typing import Optional

import numba
import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

__all__ = ["CondensedJacobian", "ElementCondensedPC", "condense_cell_numpy",
           "element_condensation_supported"]

log = logging.getLogger(__name__)

#: relative difference between the hand-written kernel and the problem's FFCx kernel, on sample
#: cells, under which the hand-written one is used
KERNEL_MATCH_RTOL = 1e-9


# -- one cell -------------------------------------------------------------------------------------
@numba.njit(cache=True)
def _condense_cell(A, lpos, bpos, S, X, Y, Binv, Abb):
    """S = A_ll − A_lb X, X = A_bb⁻¹ A_bl, Y = A_lb A_bb⁻¹, Binv = A_bb⁻¹, Abb = A_bb (Gauss–Jordan
    with partial pivoting). Returns False when A_bb is singular or a result is not finite."""
    nl = lpos.size
    k = bpos.size
    M = np.empty((k, k))
    R = np.zeros((k, k))
    for i in range(k):
        R[i, i] = 1.0
        for j in range(k):
            M[i, j] = A[bpos[i], bpos[j]]
            Abb[i, j] = M[i, j]
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
                R[col, j], R[piv, j] = R[piv, j], R[col, j]
        d = M[col, col]
        for j in range(k):
            M[col, j] /= d
            R[col, j] /= d
        for i in range(k):
            if i != col:
                f = M[i, col]
                if f != 0.0:
                    for j in range(k):
                        M[i, j] -= f * M[col, j]
                        R[i, j] -= f * R[col, j]
    ok = True
    for i in range(k):
        for j in range(k):
            Binv[i, j] = R[i, j]
            if not np.isfinite(R[i, j]):
                ok = False
    for i in range(k):
        for j in range(nl):
            acc = 0.0
            for q in range(k):
                acc += Binv[i, q] * A[bpos[q], lpos[j]]
            X[i, j] = acc
    for i in range(nl):
        for j in range(k):
            acc = 0.0
            for q in range(k):
                acc += A[lpos[i], bpos[q]] * Binv[q, j]
            Y[i, j] = acc
    for i in range(nl):
        for j in range(nl):
            acc = A[lpos[i], lpos[j]]
            for q in range(k):
                acc -= A[lpos[i], bpos[q]] * X[q, j]
            S[i, j] = acc
    return ok


def condense_cell_numpy(A: np.ndarray, lpos: np.ndarray, bpos: np.ndarray):
    """numpy twin of the cell condensation: (S, X, Y, A_bb⁻¹, A_bb) of one element matrix."""
    Abb = A[np.ix_(bpos, bpos)]
    Binv = np.linalg.inv(Abb)
    X = Binv @ A[np.ix_(bpos, lpos)]
    Y = A[np.ix_(lpos, bpos)] @ Binv
    S = A[np.ix_(lpos, lpos)] - A[np.ix_(lpos, bpos)] @ X
    return S, X, Y, Binv, Abb


@numba.njit
def _jacobian_loop(tab, data, cells, lpos, bpos, A, b, S, X, Y, Binv, Abb):
    """Element matrices of ``cells`` condensed: S[n] of the n-th cell, X[c], Y[c], Binv[c],
    Abb[c] of cell c. Returns the number of cells with a singular bubble block."""
    bad = 0
    for n in range(cells.size):
        c = cells[n]
        tab(data, c, A, b)
        if not _condense_cell(A, lpos, bpos, S[n], X[c], Y[c], Binv[c], Abb[c]):
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


def element_condensation_supported(problem) -> Optional[str]:
    """None if the problem's Jacobian can be condensed element by element, else the reason: a
    MINI space (gdim + 1 dofs per vertex and cell-interior dofs only) and a Jacobian form with
    cell integrals over the whole mesh only."""
    from fxcontact.element_condense import P1P1Layout
    try:
        P1P1Layout(problem.w.function_space)
    except (ValueError, RuntimeError) as e:
        return str(e)
    import dolfinx.cpp.fem
    a = problem.a
    cell = dolfinx.cpp.fem.IntegralType.cell
    other = [t for t in a.integral_types if t != cell]
    if other:
        return f"the Jacobian has {other[0].name.replace('_', ' ')} integrals"
    if list(a.integral_ids(cell)) != [-1]:
        return "the Jacobian has cell integrals over tagged subdomains"
    return None


class CondensedJacobian:
    """The condensed Newton matrix of a MINI :class:`~fxcontact.petsc.NonlinearProblem`.

    Args:
        problem: the problem (its ``w``, ``a``, ``bcs``, ``bc_marker``, ``constraints``).
        tensors: an element-tensor source of :mod:`fxcontact.element_condense` whose matrices
            are the problem's Jacobian (default: :class:`~fxcontact.element_condense.FFCxElementTensors`
            of ``problem.a``).
        fast_tensors: optional callable ``(layout) -> source`` of a faster source of the same
            matrices (the hand-written Norton–Hoff kernel): used if it matches ``tensors`` on sample cells at the first assembly
            (relative ``KERNEL_MATCH_RTOL``), else dropped with a log message.
        chunk: cells condensed at once (bounds the memory of the element tensors).
    """

    def __init__(self, problem, tensors=None, fast_tensors=None, chunk: int = 8192):
        from fxcontact.element_condense import FFCxElementTensors, P1P1Layout
        self.problem = problem
        W = problem.w.function_space
        self.layout = lay = P1P1Layout(W)
        if tensors is None:
            tensors = FFCxElementTensors(lay, problem.a, problem.L)
        self.tensors = tensors
        self._tab = getattr(tensors, "tab_jacobian", tensors.tab)
        self._fast = None if fast_tensors is None else fast_tensors(lay)
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
        nown = W.dofmap.index_map.size_local
        self._nown = nown
        self._bubble_diag = np.ascontiguousarray(lay.w_b.reshape(-1, 1))
        self._work = [problem.create_vector() for _ in range(2)]   # ghosted W vectors
        #: number of assemblies
        self.assemblies = 0

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

    def _ghost_sum(self, k: int = 1) -> PETSc.Vec:
        v = self._work[k]
        with v.localForm() as loc:
            loc.set(0.0)
        return v

    # -- assembly -----------------------------------------------------------------------------
    def _choose_kernel(self):
        """Keep the fast source if its matrices match the problem's on sample cells
        (collective)."""
        if self._fast is None or self.kernel != "ffcx" or self.assemblies:
            return
        lay = self.layout
        n = min(lay.num_cells, 64)
        cells = np.unique(np.linspace(0, max(lay.num_cells - 1, 0), n).astype(np.int32))
        if cells.size and lay.num_cells:
            A_ref, _ = self.tensors.tensors(cells)
            A_fast, _ = self._fast.tensors(cells)
            scale = np.abs(A_ref).max(axis=(1, 2), keepdims=True)
            err = float(np.max(np.abs(A_fast - A_ref) / np.where(scale > 0, scale, 1.0)))
        else:
            err = 0.0
        err = lay.comm.allreduce(err, op=MPI.MAX)
        if err <= KERNEL_MATCH_RTOL:
            self.tensors, self._tab, self.kernel = self._fast, self._fast.tab, "hand"
        else:
            log.info("the hand-written Norton-Hoff kernel differs from the problem's Jacobian "
                     "(relative %.1e): the FFCx kernel is used", err)
        self._fast = None

    def assemble(self, A: PETSc.Mat, bc_marker: np.ndarray):
        """Add the condensed element matrices to the l–l block of the W matrix ``A`` (Dirichlet
        rows and columns zeroed, unit diagonal on the owned Dirichlet dofs and the bubbles); not
        finally assembled. Raises RuntimeError on every rank for a singular bubble block."""
        self._choose_kernel()
        lay = self.layout
        data = self.tensors.data()
        bad = 0
        nl = lay.lpos.size
        for c0 in range(0, lay.num_cells, self.chunk):
            cells = np.arange(c0, min(c0 + self.chunk, lay.num_cells), dtype=np.int32)
            S = np.empty((cells.size, nl, nl))
            bad += _jacobian_loop(self._tab, data, cells, lay.lpos, lay.bpos, self._A, self._b,
                                  S, self.X, self.Y, self.Binv, self.Abb)
            rows = lay.w_l[cells]
            bc = bc_marker[rows]
            if bc.any():
                # Dirichlet rows and columns zeroed but inserted (as dolfinx does): the
                # matrix keeps their pattern, which the symmetry projection's product needs
                keep = ~bc
                S *= keep[:, :, None]
                S *= keep[:, None, :]
            A.setValuesLocalRCV(rows, rows, S.reshape(cells.size, -1),
                                addv=PETSc.InsertMode.ADD_VALUES)
        diag = np.concatenate([self.problem._bc_owned.astype(np.int32).reshape(-1, 1),
                               self._bubble_diag])
        if diag.size:
            A.setValuesLocalRCV(diag, diag, np.ones((diag.shape[0], 1)),
                                addv=PETSc.InsertMode.ADD_VALUES)
        self.assemblies += 1
        if lay.comm.allreduce(bad):
            raise RuntimeError("singular interior (bubble) block in a cell: degenerate element")

    # -- products with J' and solves (vectors of the W layout) ------------------------------
    def mult(self, A: PETSc.Mat, x: PETSc.Vec, y: PETSc.Vec):
        """``y = J' x``: ``A`` the assembled matrix (S' in its l–l block, identity in b–b)."""
        A.mult(x, y)                                   # y_l = S' x_l, y_b = x_b
        u = self._ghosted_M(x, 0)
        g = self._ghost_sum(1)
        lay = self.layout
        ya = y.getArray(readonly=False)
        with u.localForm() as ul, g.localForm() as gl:
            ga = gl.getArray()
            _bubble_product(ul.getArray(readonly=True), ul.getArray(readonly=True), lay.w_l,
                            lay.w_b, self.X, self.Y, self.Abb, ya, ga)
        del ya
        g.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        garr = g.getArray(readonly=False)
        self.apply_M(garr)
        y.axpy(1.0, g)   # b entries of g are zero

    def condensed_rhs(self, f: PETSc.Vec, r: PETSc.Vec):
        """``r = f − M Y f_b`` on the l entries (b entries of r: those of f)."""
        g = self._ghost_sum(1)
        lay = self.layout
        with g.localForm() as gl:
            _add_Y(f.getArray(readonly=True), lay.w_l, lay.w_b, self.Y, gl.getArray())
        g.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        self.apply_M(g.getArray(readonly=False))
        f.copy(r)
        r.axpy(-1.0, g)

    def recover(self, f: PETSc.Vec, y: PETSc.Vec):
        """``y_b = A_bb⁻¹ f_b − X M y_l`` (y's l entries: the condensed solution)."""
        u = self._ghosted_M(y, 0)
        lay = self.layout
        ya = y.getArray(readonly=False)
        with u.localForm() as ul:
            _bubble_solve(f.getArray(readonly=True), ul.getArray(readonly=True), lay.w_l,
                          lay.w_b, self.X, self.Binv, ya)
        del ya

    def destroy(self):
        for v in self._work:
            v.destroy()
        self._work = []


class _JacobianOperator:
    """petsc4py python Mat: the product with J' (:meth:`CondensedJacobian.mult`)."""

    def __init__(self, element: CondensedJacobian, A: PETSc.Mat):
        self.element = element
        self.A = A

    def mult(self, mat, x, y):
        self.element.mult(self.A, x, y)

    def createVecs(self, mat):
        return self.A.createVecs()


def jacobian_shell(element: CondensedJacobian, A: PETSc.Mat) -> PETSc.Mat:
    """A python Mat of A's sizes whose product is J' (collective)."""
    J = PETSc.Mat().createPython(A.getSizes(), _JacobianOperator(element, A), comm=A.comm)
    J.setUp()
    return J


def _condensed_pc_class():
    from fxcontact.condense import CondensedPC

    class ElementCondensedPC(CondensedPC):
        """:class:`~fxcontact.condense.CondensedPC` for a matrix assembled by
        :class:`CondensedJacobian`: the condensed matrix is the l–l block as it stands (one
        sub-matrix extraction), the right-hand side and the bubble from the kept cell
        matrices."""

        def __init__(self, layout, prefix, element: CondensedJacobian, schur_weight=None,
                     problem=None):
            super().__init__(layout, prefix, schur_weight, problem)
            self.element = element
            self._r = None

        def _condensed_matrix(self, P):
            return self._sub(P, "S", self.lay.is_l, self.lay.is_l)

        def _condensed_rhs(self, x):
            if self._r is None:
                self._r = x.duplicate()
            self.element.condensed_rhs(x, self._r)
            rl = self._r.getSubVector(self.lay.is_l)
            rl.copy(self._rl)
            self._r.restoreSubVector(self.lay.is_l, rl)

        def _recover(self, x, y):
            self.element.recover(x, y)

        def destroy(self, pc=None):
            if self._r is not None:
                self._r.destroy()
                self._r = None
            super().destroy(pc)

    return ElementCondensedPC


def ElementCondensedPC(layout, prefix, element, schur_weight=None, problem=None):
    """The preconditioner (an exact solver with a direct inner solve) of a matrix assembled by
    :class:`CondensedJacobian` (see :func:`_condensed_pc_class`)."""
    return _condensed_pc_class()(layout, prefix, element, schur_weight, problem)
