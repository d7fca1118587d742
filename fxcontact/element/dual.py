"""Primal–dual Newton for the Norton–Hoff law: the deviatoric stress as a dual variable at the
quadrature points (THEORY §1.1, ``SolverOptions(material_tangent="primal-dual")``).

With m ≪ 1 the consistent tangent of s = 2K z^(m−1) e is 2K z^(m−1) [P_dev − 2(1−m)/z² e⊗e]:
along the current strain-rate direction it is m times the secant one, and a Newton step that
turns the strain-rate direction of a cell overshoots (in one dimension a step from s ≈ ε̇₀
lands on −s). Newton on the dual relation z^(1−m) s − 2K e = 0, with s carried from iteration
to iteration at each quadrature point, replaces the primal stress in the tangent's rank-one term
by the dual one (the primal–dual Newton of total-variation denoising, Chan, Golub & Mulet
1999): where the direction turns, the dual stress still points the old way and the tangent
stays stiff. The residual is the primal one, so the converged solution is the same; at
convergence the dual stress equals the primal one and the tangent is the consistent one.

:class:`DualStress` keeps the dual stress (a quadrature function of the integrals' degree,
set from :meth:`~fxcontact.materials.NortonHoff.dual_update_ufl` with
``dolfinx.fem.Expression.eval``: dolfinx 0.5 cannot interpolate into quadrature spaces), gives
the primal–dual tangent form (or its correction to the consistent Jacobian), and is called by
the Newton solver at the start of each solve (``begin``: the primal stress of the initial
guess) and at each accepted iterate (``accept``).
A Jacobian assembled outside a Newton solve uses the last dual stress (before the first solve
the dual stress is zero, and the tangent is the secant one, 2K z^(m−1) P_dev).

If a Newton attempt with it fails, :class:`~fxcontact.simulation.Simulation` retries the same
time step with the consistent tangent (``DualStress.active = False``) before its line-search
fallback and the cut-back: the primal–dual direction is not always a descent direction of the
residual norm that the line search backtracks on (measured: the first increment of the ring
rolling with axial cones).
"""

from __future__ import annotations

import basix
import dolfinx
import numpy as np
import ufl
from petsc4py import PETSc

from fxcontact import compat

__all__ = ["DualStress"]


class DualStress:
    """Dual stress of the primal–dual Newton on a mixed (velocity, pressure) space.

    Args:
        material: a material with ``stress_ufl``, ``dual_tangent_ufl``,
            ``dual_tangent_correction_ufl`` and ``dual_update_ufl``
            (:class:`~fxcontact.materials.NortonHoff`).
        W: the mixed function space (velocity first).
        quadrature_degree: degree of the integrals the dual stress enters (``dx``'s).
    """

    def __init__(self, material, W, quadrature_degree: int):
        for name in ("stress_ufl", "dual_tangent_ufl", "dual_tangent_correction_ufl",
                     "dual_update_ufl"):
            if not hasattr(material, name):
                raise ValueError(f"the primal-dual Newton needs a Norton-Hoff material; "
                                 f"{type(material).__name__} has no {name}")
        self.material = material
        msh = W.mesh
        d = msh.geometry.dim
        Qe = ufl.TensorElement("Quadrature", msh.ufl_cell(), int(quadrature_degree),
                               quad_scheme="default", shape=(d, d))
        self.Q = dolfinx.fem.FunctionSpace(msh, Qe)
        #: the dual stress at the quadrature points
        self.s = dolfinx.fem.Function(self.Q, name="dual_stress")
        self._w_old = dolfinx.fem.Function(W)
        self._w_new = dolfinx.fem.Function(W)
        cell = basix.cell.string_to_type(msh.topology.cell_type.name)
        pts, _ = basix.make_quadrature(cell, int(quadrature_degree))
        eps_old = ufl.sym(ufl.grad(ufl.split(self._w_old)[0]))
        eps_new = ufl.sym(ufl.grad(ufl.split(self._w_new)[0]))
        jit = compat.jit_params()   # -fno-math-errno: the repeated pow calls merged
        self._primal = dolfinx.fem.Expression(material.stress_ufl(eps_new), pts,
                                              jit_params=jit)
        self._update = dolfinx.fem.Expression(
            material.dual_update_ufl(eps_old, eps_new, self.s), pts, jit_params=jit)
        tdim = msh.topology.dim
        imap = msh.topology.index_map(tdim)
        self._cells = np.arange(imap.size_local + imap.num_ghosts, dtype=np.int32)
        dm = np.asarray(self.Q.dofmap.list.array, dtype=np.int64)
        self._blocks = dm.reshape(len(self._cells), -1).ravel()
        self._bs = self.Q.dofmap.index_map_bs
        #: number of dual updates since construction
        self.updates = 0
        #: False: the dual stress follows the primal one (``accept`` sets it to the primal
        #: stress of the iterate), so the Jacobian is the consistent one (to round-off); the
        #: simulation's retry after a failed primal-dual attempt
        self.active = True

    def jacobian_correction(self, v, dv, wt, dx):
        """The UFL bilinear form to add to the consistent Jacobian (``v`` the velocity of the
        iterate, ``dv`` the trial and ``wt`` the test velocity): ``ufl.derivative(F, w, dw) +
        jacobian_correction(...)`` is the primal–dual Jacobian of any residual F holding the
        material's stress term."""
        return self.material.dual_tangent_correction_ufl(
            ufl.sym(ufl.grad(v)), self.s, ufl.sym(ufl.grad(dv)), ufl.sym(ufl.grad(wt))) * dx

    def tangent_form(self, v, dv, wt, dx):
        """The primal–dual tangent of the stress term ∫ s(ε̇(v)) : ε̇(wt) as a UFL bilinear form:
        it replaces that term's ``ufl.derivative`` (the same matrix as the derivative plus
        :meth:`jacobian_correction`, to round-off, at about 60 % of the kernel cost)."""
        return self.material.dual_tangent_ufl(
            ufl.sym(ufl.grad(v)), self.s, ufl.sym(ufl.grad(dv)), ufl.sym(ufl.grad(wt))) * dx

    #: the numba update (:mod:`fxcontact.element.dual_kernel`), or None: the UFL expressions
    kernel = None

    def use_kernel(self, space) -> bool:
        """Update the dual stress by the numba loop of :mod:`fxcontact.element.dual_kernel` (the same
        values, a fraction of the cost) where it applies: NortonHoff's own law on the MINI space
        of affine tetrahedra (``space``: the :class:`~fxcontact.spaces.MixedSpace`). Returns
        whether it is used."""
        from fxcontact.element.dual_kernel import DualUpdateKernel, kernel_applies
        if self.kernel is None and kernel_applies(self.material, space):
            self.kernel = DualUpdateKernel(self, space)
        return self.kernel is not None

    def _set(self, expr):
        if self.kernel is not None:
            self.kernel(0 if expr is self._primal else 1, self._w_old.x.array,
                        self._w_new.x.array)
            return
        vals = expr.eval(self._cells)
        arr = self.s.x.array.reshape(-1, self._bs)
        arr[self._blocks] = vals.reshape(-1, self._bs)

    def _load(self, x: PETSc.Vec):
        x.copy(self._w_new.vector)
        self._w_new.x.scatter_forward()

    def begin(self, x: PETSc.Vec):
        """Start of a Newton solve from ``x``: the dual stress is the primal one."""
        self._load(x)
        self._set(self._primal)
        self._w_old.x.array[:] = self._w_new.x.array

    def accept(self, x: PETSc.Vec):
        """A Newton iterate ``x`` was accepted: update the dual stress along the step."""
        self._load(x)
        if self.active:
            self._set(self._update)
            self.updates += 1
        else:
            self._set(self._primal)
        self._w_old.x.array[:] = self._w_new.x.array
