"""PETSc linear-algebra primitives shared by the Newton layer (:mod:`fxcontact.newton`) and the
element layer (:mod:`fxcontact.element`), without knowledge of either:

* the nodal entries of contributors (:class:`~fxcontact.newton.problem.NodalTerms`: per-vertex
  residual entries and 3×3 blocks) added into a PETSc vector or matrix;
* several right-hand sides in one solve: a MUMPS factorisation applied to k vectors at once
(``MatMatSolve``: the factors are read once for all of them, instead of k back-substitutions),
and preconditioners that can do the same (``apply_many(xs, ys) -> bool``: the condensed
preconditioner, the bordered one).

Used by the active-set prediction (:mod:`fxcontact.newton.prediction`), whose Woodbury correction
needs one solve per contact node that changes status.

Also the small matrix helpers the Newton layer and the condensed solvers share: whether two
matrices have the same nonzero pattern, and the rigid-body modes (near-null space) of a
vertex-interlaced vector block.
"""

from __future__ import annotations

from typing import List

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

__all__ = ["add_nodal_jacobian", "add_nodal_residual", "direct_mumps", "factor_solve_many",
           "pc_apply_many", "rigid_body_modes", "same_nonzero_pattern"]


def direct_mumps(ksp) -> bool:
    """True if ``ksp`` is a single application of a MUMPS factorisation."""
    if ksp is None or ksp.getType() != PETSc.KSP.Type.PREONLY:
        return False
    pc = ksp.getPC()
    return (pc.getType() in (PETSc.PC.Type.LU, PETSc.PC.Type.CHOLESKY)
            and pc.getFactorSolverType() == "mumps")


def factor_solve_many(F: PETSc.Mat, template: PETSc.Vec, columns, comm):
    """The solutions with the factored matrix ``F`` of the right-hand sides ``columns``
    (arrays of the owned entries of vectors laid out as ``template``), in one solve with
    several right-hand sides (``MatMatSolve``; collective, every rank the same number of
    columns). Returns the solutions as arrays of the owned entries."""
    k = len(columns)
    n, N = template.getLocalSize(), template.getSize()
    B = PETSc.Mat().createDense(((n, N), (PETSc.DECIDE, k)), comm=comm)
    X = PETSc.Mat().createDense(((n, N), (PETSc.DECIDE, k)), comm=comm)
    try:
        B.setUp()
        X.setUp()
        Ba = B.getDenseArray()
        for j, c in enumerate(columns):
            Ba[:, j] = c
        del Ba
        B.assemble()
        X.assemble()
        F.matSolve(B, X)
        Xa = X.getDenseArray()
        return [Xa[:, j].copy() for j in range(k)]
    finally:
        B.destroy()
        X.destroy()


def pc_apply_many(pc: PETSc.PC, xs: List[PETSc.Vec], ys: List[PETSc.Vec]) -> bool:
    """``ys[j]`` = ``pc`` applied to ``xs[j]``, all in one solve with several right-hand
    sides, when ``pc`` is a MUMPS factorisation (``lu`` or ``cholesky``) or a python
    preconditioner with an ``apply_many(xs, ys) -> bool`` method; returns False (nothing
    done) otherwise. Collective (the same number of vectors on every rank).

    Under ``preonly`` that is the KSP's solve itself; under a Krylov method it is the solve
    only if the preconditioner is the inverse of the operator (the caller checks).
    """
    if not xs:
        return True
    kind = pc.getType()
    if kind == PETSc.PC.Type.PYTHON:
        many = getattr(pc.getPythonContext(), "apply_many", None)
        return bool(many is not None and many(xs, ys))
    if kind in (PETSc.PC.Type.LU, PETSc.PC.Type.CHOLESKY) and \
            pc.getFactorSolverType() == "mumps":
        sol = factor_solve_many(pc.getFactorMatrix(), xs[0],
                                [x.getArray(readonly=True) for x in xs], pc.comm)
        for y, s in zip(ys, sol):
            y.getArray(readonly=False)[:] = s
        return True
    return False


def same_nonzero_pattern(A: PETSc.Mat, B: PETSc.Mat) -> bool:
    """True if the distributed AIJ matrices A and B (same layout) store the same entries
    (row pointers and column indices of every rank's rows; collective)."""
    ai, aj, _ = A.getValuesCSR()
    bi, bj, _ = B.getValuesCSR()
    same = bool(np.array_equal(ai, bi) and np.array_equal(aj, bj))
    return bool(A.getComm().tompi4py().allreduce(same, op=MPI.LAND))


def rigid_body_modes(comm, x: np.ndarray) -> PETSc.NullSpace:
    """Near-null space of a vector Laplacian/elasticity block with vertex-interlaced dofs at
    points ``x`` (n, gdim): gdim translations and the gdim(gdim−1)/2 rotations, orthonormalised
    (collective)."""
    n, d = x.shape
    xc = x - comm.allreduce(x.sum(axis=0)) / max(comm.allreduce(n), 1)
    modes = []
    for k in range(d):
        m = np.zeros((n, d))
        m[:, k] = 1.0
        modes.append(m)
    if d == 2:
        modes.append(np.stack([-xc[:, 1], xc[:, 0]], axis=1))
    else:
        for (i, j) in ((0, 1), (1, 2), (2, 0)):
            m = np.zeros((n, d))
            m[:, i], m[:, j] = -xc[:, j], xc[:, i]
            modes.append(m)
    # modified Gram-Schmidt (global dot products)
    basis = []
    for m in modes:
        v = m.ravel().copy()
        for b in basis:
            v -= comm.allreduce(float(v @ b)) * b
        nrm = np.sqrt(comm.allreduce(float(v @ v)))
        basis.append(v / nrm)
    vecs = []
    for b in basis:
        vec = PETSc.Vec().createMPI((n * d, PETSc.DECIDE), bsize=d, comm=comm)
        vec.setArray(b)
        vecs.append(vec)
    return PETSc.NullSpace().create(vectors=vecs, comm=comm)


def add_nodal_residual(b: PETSc.Vec, terms):
    """Add nodal residual entries into the owned part of ``b`` (after the ghost update)."""
    if terms.dofs.size == 0:
        return
    dofs = terms.dofs.ravel()
    vals = terms.residual.ravel()
    keep = dofs >= 0
    arr = b.getArray(readonly=False)
    np.add.at(arr, dofs[keep], vals[keep])


def add_nodal_jacobian(A: PETSc.Mat, terms, bc_marker: np.ndarray):
    """Add nodal blocks to ``A`` before the UFL assembly; Dirichlet rows/columns masked."""
    if terms.jacobian is None or terms.dofs.shape[0] == 0:
        return
    rows = terms.dofs.astype(np.int32).copy()
    rows[rows >= 0] = np.where(bc_marker[rows[rows >= 0]], -1, rows[rows >= 0])
    active = np.any(rows >= 0, axis=1)
    if not np.any(active):
        return  # never call setValuesLocalRCV with zero rows (SIGFPE)
    rows = np.ascontiguousarray(rows[active])
    vals = np.ascontiguousarray(terms.jacobian[active]).reshape(rows.shape[0], -1)
    A.setValuesLocalRCV(rows, rows, vals, addv=PETSc.InsertMode.ADD_VALUES)
