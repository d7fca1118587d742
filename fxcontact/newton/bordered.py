"""Bordered Newton systems (:meth:`fxcontact.newton.solver.ContactNewtonSolver.set_border`): a
contributor may eliminate k scalar unknowns locally at each residual evaluation (the rotation
speeds of idle tools, :class:`~fxcontact.idle.IdleRotation`); the Newton matrix is then the
assembled J plus a rank-k term, J̃ = J − U D⁻¹ G (U = ∂R/∂ω, G = ∂T/∂v, D = ∂T/∂ω, k×k). The
SNES Jacobian becomes a shell J̃ (its product is exact, so the line search's slope and any Krylov
method see J̃), the linear solver's own preconditioner P ≈ J⁻¹ (MUMPS, the condensed PC, a field
split) is wrapped by :class:`BorderedPC`, which applies the Woodbury formula
J̃⁻¹ = J⁻¹ + Z (D − G Z)⁻¹ G J⁻¹ with Z = P⁻¹ U: k extra applications of P per Newton iteration
(with a factorisation, k extra triangular solves, no new factorisation), exact when P is.
"""

from __future__ import annotations

from typing import List

import numpy as np
from petsc4py import PETSc

from fxcontact.la import pc_apply_many

__all__ = ["BorderedOperator", "BorderedPC"]


class BorderedPC:
    """petsc4py python PC: a preconditioner P ≈ J⁻¹ of the assembled matrix J, corrected for a
    rank-k term of the operator, J̃ = J − U D⁻¹ G, by the Woodbury formula

        J̃⁻¹ x = y + Z (D − G Z)⁻¹ G y,   y = P x,   Z = P U.

    Args:
        inner: the PC of J (set up here with the outer PC's preconditioning matrix).
        border: an object with ``vectors()`` returning ``(U, G, D)`` (two lists of k PETSc
            vectors of the problem's layout and a k×k array) or None (no border: P alone).
    """

    def __init__(self, inner: PETSc.PC, border):
        self.inner = inner
        self.border = border
        self._Z: List[PETSc.Vec] = []
        self._G: List[PETSc.Vec] = []
        self._M = None

    def setUp(self, pc):
        _, P = pc.getOperators()
        self.inner.setOperators(P, P)
        self.inner.setUp()
        for z in self._Z:
            z.destroy()
        self._Z, self._G, self._M = [], [], None
        vec = self.border.vectors()
        if vec is None or not len(vec[0]):
            return
        U, G, D = vec
        for u in U:
            z = u.duplicate()
            self.inner.apply(u, z)
            self._Z.append(z)
        self._G = list(G)
        k = len(U)
        M = np.array(D, dtype=np.float64).reshape(k, k).copy()
        for i in range(k):
            for j in range(k):
                M[i, j] -= G[i].dot(self._Z[j])
        self._M = M

    def apply(self, pc, x, y):
        self.inner.apply(x, y)
        if self._M is not None:
            self._correct(y)

    def _correct(self, y):
        """y += Z (D − G Z)⁻¹ G y."""
        c = np.array([g.dot(y) for g in self._G])
        s = np.linalg.solve(self._M, c)
        for z, sj in zip(self._Z, s):
            y.axpy(float(sj), z)

    def apply_many(self, xs, ys) -> bool:
        """:meth:`apply` to several vectors, the inner preconditioner applied to all of them at
        once where it can be (:func:`~fxcontact.la.pc_apply_many`); returns False
        (nothing done) where it cannot."""
        if not pc_apply_many(self.inner, xs, ys):
            return False
        if self._M is not None:
            for y in ys:
                self._correct(y)
        return True

    def view(self, pc, viewer=None):
        self.inner.view(viewer)

    def destroy(self, pc=None):
        for z in self._Z:
            z.destroy()
        self._Z, self._G = [], []
        if self.inner is not None:
            self.inner.destroy()
            self.inner = None


class BorderedOperator:
    """petsc4py python Mat: the product with J̃ = J − U D⁻¹ G (J assembled, U, G, D from the
    border's ``vectors()``)."""

    def __init__(self, A: PETSc.Mat, border):
        self.A = A
        self.border = border

    def mult(self, mat, x, y):
        self.A.mult(x, y)
        vec = self.border.vectors()
        if vec is None or not len(vec[0]):
            return
        U, G, D = vec
        t = np.linalg.solve(np.asarray(D, dtype=np.float64).reshape(len(U), len(U)),
                            np.array([g.dot(x) for g in G]))
        for u, tj in zip(U, t):
            y.axpy(-float(tj), u)

    def createVecs(self, mat):
        return self.A.createVecs()
