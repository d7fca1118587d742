"""Static condensation of the MINI bubble in the element kernel (fxcontact.element_condense).

The condensed P1/P1 matrix and right-hand side assembled from condensed element tensors must
equal the algebraic condensation of the assembled MINI system (fxcontact.condense) to round-off,
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
from fxcontact.condense import CondensationLayout, CondensedPC
from fxcontact.dual import DualStress
from fxcontact.element_condense import (CondensedAssembler, FFCxElementTensors, P1P1Layout)
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

    def __init__(self, m, comm=MPI.COMM_WORLD, n=4, volume_rate=0.0):
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
        v, p = ufl.split(self.w)
        wt, q = ufl.TestFunctions(sp.W)
        dv, dp = ufl.TrialFunctions(sp.W)
        self.J = (self.dual.tangent_form(v, dv, wt, sp.dx)
                  + mat.incompressibility_ufl(dv, dp, wt, q, sp.dx))
        self.F = mat.residual(v, p, wt, q, sp.dx, 1.0) - q * volume_rate * sp.dx
        self.a, self.L = compat.form(self.J), compat.form(self.F)

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


def solve_condensed(asm, Sm, rm, w):
    """Solve the condensed system by MUMPS and write the full solution (vertex values and
    recovered bubbles) into the Function ``w``."""
    xm = rm.duplicate()
    ksp = _mumps(Sm)
    ksp.solve(rm, xm)
    assert ksp.getConvergedReason() > 0
    w.x.array[:] = 0.0
    asm.layout.to_w(xm, w.x.array)
    asm.recover(w.x.array)
    w.x.scatter_forward()


@pytest.mark.parametrize("m", [0.15, 0.016])
def test_ffcx_condensed_system_equals_algebraic_condensation(m):
    case = Case(m, volume_rate=0.05)
    # the dual stress is not the primal one (a dual update along a step)
    primal = DualStress(case.material, case.space.W, case.space.quadrature_degree)
    primal.begin(case.w.vector)
    comm = case.space.mesh.comm
    diff = comm.allreduce(np.abs(primal.s.x.array - case.dual.s.x.array).max(), op=MPI.MAX)
    assert diff > 1e-2 * comm.allreduce(np.abs(primal.s.x.array).max(), op=MPI.MAX)
    A, b = case.full_system()
    S, r, positions, _, _ = algebraic_condensation(case.space.W, A, b)
    asm = CondensedAssembler(FFCxElementTensors(case.layout, case.a, case.L), chunk=100)
    Sm, rm = asm.assemble()
    assert Sm.getBlockSize() == 4
    assert_same_condensed_system(Sm, rm, S, r, positions(case.layout))
    # the recovered bubble with the vertex solution solves the full system
    x = dolfinx.fem.Function(case.space.W)
    solve_condensed(asm, Sm, rm, x)
    res = b.duplicate()
    A.mult(x.vector, res)
    res.axpy(-1.0, b)
    assert res.norm() <= 1e-12 * b.norm(), (res.norm(), b.norm())
    # a second assembly into the same objects gives the same system
    Sm2, rm2 = asm.assemble(Sm, rm)
    assert Sm2 is Sm
    assert_same_condensed_system(Sm2, rm2, S, r, positions(case.layout))
