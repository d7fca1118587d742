"""Static condensation of the MINI bubble in the element kernel (fxcontact.element.tensors).

The condensed P1/P1 matrix and right-hand side assembled from condensed element tensors must
equal the algebraic condensation of the assembled MINI system (fxcontact.element.assembled) to round-off,
and the recovered bubble plus the vertex solution must solve the full system, on a Norton–Hoff
state that is not trivial: a sheared velocity field with bubbles, m = 0.15 and m = 0.016, and a
primal–dual tangent whose dual stress differs from the primal one (one dual update along a
step). Serially and on 2 ranks (each run compares the two condensations on the same
communicator).
"""

import numpy as np
import pytest
import ufl
from mpi4py import MPI
from petsc4py import PETSc

import dolfinx
import dolfinx.fem.petsc

import fxcontact as fx
from fxcontact import compat
from fxcontact.element.assembled import CondensationLayout, CondensedPC
from fxcontact.element.dual import DualStress
from fxcontact.element.tensors import (CondensedAssembler, FFCxElementTensors,
                                        NortonHoffElementTensors, P1P1Layout,
                                        norton_hoff_forms, norton_hoff_tensors_numpy)
from helpers import box_mesh

PREFIX = "test_ec_"


def set_state(layout, w, phase=0.0):
    """A sheared velocity with bubbles and a linear pressure, functions of the positions
    (the same state on any partition)."""
    X = layout.Vc.tabulate_dof_coordinates()
    x, y, z = X[:, 0], X[:, 1], X[:, 2]
    w.x.array[layout.block_w] = np.stack(
        [y * z + 0.3 * x + phase * y, np.sin(3 * x + phase) + z, -z * x + phase * x * y,
         x - y + phase], axis=1)
    msh = layout.W.mesh
    mid = dolfinx.mesh.compute_midpoints(msh, 3, np.arange(layout.num_cells, dtype=np.int32))
    w.x.array[layout.w_b] = 0.1 * np.sin(np.stack(
        [7 * mid[:, 0] + phase, 5 * mid[:, 1] + 1, 3 * mid[:, 2] + 2], axis=1))
    w.x.scatter_forward()


class Case:
    """A Norton–Hoff primal–dual Jacobian and residual on a distorted box, at a state reached
    by one dual update (dual stress ≠ primal stress)."""

    def __init__(self, m, comm=MPI.COMM_WORLD, n=4, volume_rate=0.05):
        msh = box_mesh(comm, n=(n, n, n), perturb=0.25)
        self.space = sp = fx.MixedSpace(msh)
        self.material = mat = fx.NortonHoff(K=2.0, m=m, regularization=1e-2)
        self.layout = P1P1Layout(sp.W)
        self.w = dolfinx.fem.Function(sp.W)
        self.dual = DualStress(mat, sp.W, sp.quadrature_degree)
        set_state(self.layout, self.w)
        self.dual.begin(self.w.vector)
        set_state(self.layout, self.w, phase=0.7)
        self.dual.accept(self.w.vector)
        self.volume_rate = volume_rate
        g = dolfinx.fem.Constant(msh, PETSc.ScalarType(volume_rate))
        J, F = norton_hoff_forms(sp, mat, self.w, self.dual, pressure_source=g)
        self.a, self.L = compat.form(J), compat.form(F)

    def sources(self):
        """The two element-tensor sources: FFCx's kernels and the hand-written one."""
        return {"ffcx": FFCxElementTensors(self.layout, self.a, self.L),
                "hand": NortonHoffElementTensors(self.layout, self.space, self.material, self.w,
                                                 self.dual, pressure_source=self.volume_rate)}

    def full_system(self):
        A = dolfinx.fem.petsc.assemble_matrix(self.a)
        A.assemble()
        b = dolfinx.fem.petsc.assemble_vector(self.L)
        b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        return A, b


def _mumps(A):
    ksp = PETSc.KSP().create(A.getComm())
    ksp.setOperators(A)
    ksp.setType("preonly")
    ksp.getPC().setType("lu")
    ksp.getPC().setFactorSolverType("mumps")
    return ksp


def algebraic_condensation(W, A, b):
    """(S, r, positions): CondensedPC's condensed matrix of the assembled W matrix and the
    condensed right-hand side b_l − A_lb A_bb⁻¹ b_b, in the numbering of CondensationLayout;
    ``positions(layout)`` maps a P1P1Layout's owned entries to that numbering (local)."""
    clay = CondensationLayout(W)
    opts = PETSc.Options()
    for k, v in {"ksp_type": "preonly", "pc_type": "lu",
                 "pc_factor_mat_solver_type": "mumps"}.items():
        opts[PREFIX + k] = v
    pc = PETSc.PC().create(W.mesh.comm)
    pc.setType(PETSc.PC.Type.PYTHON)
    cpc = CondensedPC(clay, PREFIX)
    pc.setPythonContext(cpc)
    pc.setOperators(A, A)
    pc.setUp()
    for k in ("ksp_type", "pc_type", "pc_factor_mat_solver_type"):
        opts.delValue(PREFIX + k)
    S = cpc.ksp.getOperators()[0]
    Abb = A.createSubMatrix(clay.is_b, clay.is_b)
    Alb = A.createSubMatrix(clay.is_l, clay.is_b)
    bb, bl = b.getSubVector(clay.is_b), b.getSubVector(clay.is_l)
    t = Abb.createVecRight()
    _mumps(Abb).solve(bb, t)
    r = bl.copy()
    u = bl.duplicate()
    Alb.mult(t, u)
    r.axpy(-1.0, u)
    b.restoreSubVector(clay.is_b, bb)
    b.restoreSubVector(clay.is_l, bl)

    def positions(layout):
        dofs = layout.owned_w_dofs().ravel()
        pos = np.searchsorted(clay.retained, dofs)
        assert np.array_equal(clay.retained[pos], dofs)
        assert len(dofs) == len(clay.retained)
        return pos

    return S, r, positions, cpc, pc


def _permuted(vec, pos):
    return vec.getArray(readonly=True)[pos]


def assert_same_condensed_system(Sm, rm, S, r, pos, rtol=1e-12):
    """The P1P1Layout system (Sm, rm) equals (S, r) of the CondensationLayout numbering:
    right-hand sides entry by entry, matrices by their products with random vectors and their
    Frobenius norms."""
    comm = Sm.getComm().tompi4py()
    rmax = comm.allreduce(np.abs(r.getArray(readonly=True)).max(), op=MPI.MAX)
    err = comm.allreduce(np.abs(rm.getArray(readonly=True)[: len(pos)]
                                - _permuted(r, pos)).max(initial=0.0), op=MPI.MAX)
    assert err <= rtol * rmax, (err, rmax)
    assert abs(Sm.norm(PETSc.NormType.FROBENIUS) - S.norm(PETSc.NormType.FROBENIUS)) \
        <= rtol * S.norm(PETSc.NormType.FROBENIUS)
    rng = np.random.default_rng(3 + comm.rank)
    x, y = S.createVecs()
    xm, ym = Sm.createVecs()
    for _ in range(3):
        vals = rng.standard_normal(len(pos))
        x.setArray(np.zeros(len(pos)))
        x.getArray()[pos] = vals
        xm.setArray(vals)
        S.mult(x, y)
        Sm.mult(xm, ym)
        ref = comm.allreduce(np.abs(y.getArray(readonly=True)).max(), op=MPI.MAX)
        err = comm.allreduce(np.abs(ym.getArray(readonly=True) - _permuted(y, pos)).max(),
                             op=MPI.MAX)
        assert err <= rtol * ref, (err, ref)


def recovered_solution(asm, Sm, rm):
    """A vertex field (a function of the positions) in the condensed layout, the full W
    Function it gives with the recovered bubbles, and S x_l − r."""
    lay = asm.layout
    xm = rm.duplicate()
    nown = lay.Vc.dofmap.index_map.size_local
    X = lay.Vc.tabulate_dof_coordinates()[:nown]
    xm.setArray(np.stack([np.cos(X[:, 0] + X[:, 2]), X[:, 1] ** 2, X[:, 0] * X[:, 2],
                          np.sin(2 * X[:, 1])], axis=1).ravel())
    w = dolfinx.fem.Function(lay.W)
    lay.to_w(xm, w.x.array)
    asm.recover(w.x.array)
    w.x.scatter_forward()
    res = rm.duplicate()
    Sm.mult(xm, res)
    res.axpy(-1.0, rm)
    return w, res


def assert_recovery_solves_full_system(asm, Sm, rm, A, b, rtol=1e-12):
    """With the recovered bubbles, the full residual A x − b vanishes in the bubble rows and
    equals the condensed one S x_l − r in the vertex rows: so the bubble plus the solution of
    the condensed system solves the full system."""
    lay = asm.layout
    w, res_c = recovered_solution(asm, Sm, rm)
    res = b.duplicate()
    A.mult(w.vector, res)
    scale = max(res.norm(PETSc.NormType.INFINITY), b.norm(PETSc.NormType.INFINITY))
    res.axpy(-1.0, b)
    arr = res.getArray(readonly=True)
    comm = lay.comm
    err_b = comm.allreduce(np.abs(arr[lay.w_b.ravel()]).max(initial=0.0), op=MPI.MAX)
    err_l = comm.allreduce(np.abs(arr[lay.owned_w_dofs().ravel()]
                                  - res_c.getArray(readonly=True)).max(initial=0.0), op=MPI.MAX)
    assert err_b <= rtol * scale and err_l <= rtol * scale, (err_b, err_l, scale)


def _max_rel(X, Y):
    """Largest difference of two stacks of element tensors, relative to each cell's largest
    entry."""
    n = len(Y)
    return float(np.max(np.abs(X - Y).reshape(n, -1).max(axis=1)
                        / np.abs(Y).reshape(n, -1).max(axis=1), initial=0.0))


@pytest.mark.parametrize("m", [0.15, 0.016])
def test_hand_kernel_equals_ffcx_element_tensors(m):
    """Element matrices and vectors of the hand kernel (numba and its numpy twin) equal FFCx's
    on a distorted mesh, with the primal-dual tangent and with the consistent one."""
    case = Case(m)
    cells = np.arange(case.layout.num_cells, dtype=np.int32)
    matrices = []
    for dual in (case.dual, None):
        a, L = norton_hoff_forms(case.space, case.material, case.w, dual,
                                 pressure_source=case.volume_rate)
        A_f, b_f = FFCxElementTensors(case.layout, a, L).tensors(cells)
        hand = NortonHoffElementTensors(case.layout, case.space, case.material, case.w, dual,
                                        pressure_source=case.volume_rate)
        A_h, b_h = hand.tensors(cells)
        A_n, b_n = norton_hoff_tensors_numpy(*hand.inputs(cells))
        assert _max_rel(A_h, A_f) <= 1e-12 and _max_rel(b_h, b_f) <= 1e-12
        assert _max_rel(A_n, A_h) <= 1e-12 and _max_rel(b_n, b_h) <= 1e-12
        matrices.append(A_f)
    # the primal-dual and consistent tangents differ here (the dual stress is not the primal)
    assert _max_rel(*matrices) > 1e-3


def test_ffcx_tensors_of_forms_without_coefficients():
    """FFCx's element tensors of a form pair without coefficients (a linear Stokes problem:
    nothing to pack) equal those of the same forms written with a coefficient equal to 1."""
    msh = box_mesh(MPI.COMM_WORLD, n=(3, 3, 3), perturb=0.25)
    sp = fx.MixedSpace(msh)
    lay = P1P1Layout(sp.W)
    du, dp = ufl.TrialFunctions(sp.W)
    v, q = ufl.TestFunctions(sp.W)
    one = dolfinx.fem.Function(sp.DG0)
    one.x.array[:] = 1.0
    f = dolfinx.fem.Constant(msh, PETSc.ScalarType((1.0, -2.0, 0.5)))
    cells = np.arange(lay.num_cells, dtype=np.int32)
    out = []
    for c in (1.0, one):
        a = (c * ufl.inner(ufl.grad(du), ufl.grad(v)) - dp * ufl.div(v) - q * ufl.div(du)) * sp.dx
        L = c * ufl.inner(f, v) * sp.dx
        out.append(FFCxElementTensors(lay, a, L).tensors(cells))
    (A0, b0), (A1, b1) = out
    assert np.abs(A0).max() > 0 and np.abs(b0).max() > 0
    assert _max_rel(A0, A1) <= 1e-13 and _max_rel(b0, b1) <= 1e-13


def test_hand_kernel_jacobian_is_derivative_of_its_residual():
    """Without a dual stress the hand kernel's matrix is the derivative of its vector (central
    differences in every element unknown of a few cells)."""
    case = Case(0.15)
    hand = NortonHoffElementTensors(case.layout, case.space, case.material, case.w, None,
                                    pressure_source=case.volume_rate)
    dofs = compat.dofmap_array(case.space.W)
    w = case.w.x.array
    for c in range(0, case.layout.num_cells, max(case.layout.num_cells // 4, 1)):
        A, _ = hand.tensors([c])
        fd = np.empty_like(A[0])
        for j, d in enumerate(dofs[c]):
            h = 1e-6 * max(1.0, abs(w[d]))
            w0 = w[d]
            w[d] = w0 + h
            bp = hand.tensors([c])[1][0]
            w[d] = w0 - h
            bm = hand.tensors([c])[1][0]
            w[d] = w0
            fd[:, j] = (bp - bm) / (2 * h)
        assert np.abs(fd - A[0]).max() <= 1e-6 * np.abs(A[0]).max(), c


@pytest.mark.parametrize("source", ["ffcx", "hand"])
@pytest.mark.parametrize("m", [0.15, 0.016])
def test_condensed_system_equals_algebraic_condensation(m, source):
    case = Case(m)
    # the dual stress is not the primal one (a dual update along a step)
    primal = DualStress(case.material, case.space.W, case.space.quadrature_degree)
    primal.begin(case.w.vector)
    comm = case.space.mesh.comm
    diff = comm.allreduce(np.abs(primal.s.x.array - case.dual.s.x.array).max(), op=MPI.MAX)
    assert diff > 1e-2 * comm.allreduce(np.abs(primal.s.x.array).max(), op=MPI.MAX)
    A, b = case.full_system()
    S, r, positions, _, _ = algebraic_condensation(case.space.W, A, b)
    asm = CondensedAssembler(case.sources()[source], chunk=100)
    Sm, rm = asm.assemble()
    assert Sm.getBlockSize() == 4
    assert_same_condensed_system(Sm, rm, S, r, positions(case.layout))
    assert_recovery_solves_full_system(asm, Sm, rm, A, b)
    # a second assembly into the same objects, and one into a block matrix, give the same
    Sm2, rm2 = asm.assemble(Sm, rm)
    assert Sm2 is Sm
    assert_same_condensed_system(Sm2, rm2, S, r, positions(case.layout))
    Sb, rb = asm.assemble(case.layout.create_matrix("baij"))
    assert "baij" in Sb.getType()
    assert_same_condensed_system(Sb, rb, S, r, positions(case.layout))


@pytest.mark.skipif(MPI.COMM_WORLD.size == 1, reason="compares the ranks with one process")
def test_parallel_equals_serial():
    """The condensed system and the recovered bubbles on all ranks equal those of the same mesh
    on one process (norms: independent of the numbering)."""
    out = {}
    for name, comm in (("world", MPI.COMM_WORLD), ("self", MPI.COMM_SELF)):
        case = Case(0.016, comm=comm)
        asm = CondensedAssembler(case.sources()["hand"])
        Sm, rm = asm.assemble()
        w, res = recovered_solution(asm, Sm, rm)
        out[name] = np.array([Sm.norm(PETSc.NormType.FROBENIUS), rm.norm(), w.vector.norm(),
                              res.norm()])
    assert np.allclose(out["world"], out["self"], rtol=1e-10, atol=0.0), out
