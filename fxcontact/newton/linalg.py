"""Several right-hand sides in one solve: a MUMPS factorisation applied to k vectors at once
(``MatMatSolve``: the factors are read once for all of them, instead of k back-substitutions),
and preconditioners that can do the same (``apply_many(xs, ys) -> bool``: the condensed
preconditioner, the bordered one).

Used by the active-set prediction (:mod:`fxcontact.newton.prediction`), whose Woodbury correction
needs one solve per contact node that changes status.
"""

from __future__ import annotations

from typing import List

from petsc4py import PETSc

__all__ = ["direct_mumps", "factor_solve_many", "pc_apply_many"]


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
