"""Newton solver (petsc4py SNES) for a UFL problem with nodal contributors.

Options live under a prefix (default ``fxc_``), never in the global database unprefixed. The
convergence test requires, besides a small residual or step, that every contributor reports a
stable state (e.g. an unchanged contact active set, THEORY §3.6).

A Newton iteration that cycles — the contributors' state (contact active set, facets) and the
residual norm repeating with a period of 2 to 4 iterations, twice over — never converges: it is
stopped at once (instead of running to ``max_it``) with a message naming what switches (nodes
entering and leaving contact, or nodes switching between the facets of a faceted tool), so that
the cut-back starts early and a final failure says why.

After a failed solve (no convergence, a linear-solver failure, a NaN residual, an error raised
inside a callback) the SNES with its KSP/PC and work vectors is rebuilt
(:meth:`NewtonSolver.reset`): a failed MUMPS factorisation would otherwise stay in the PC (its
numeric phase is skipped at every later set-up), and every cut-back attempt would fail at
iteration 0.

**Bordered systems** (:meth:`NewtonSolver.set_border`, :mod:`fxcontact.newton.bordered`): a
contributor may eliminate k scalar unknowns locally at each residual evaluation (the rotation
speeds of idle tools); the Newton matrix is then J plus a rank-k term, preconditioned by the
Woodbury formula.
"""

from __future__ import annotations

import dataclasses
import inspect
import logging
import math
import time
from typing import Dict, List, Optional

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from fxcontact.collective import RanksDisagree, check_decision
from fxcontact.element.assembled import CondensationLayout, CondensedPC
from fxcontact.element.jacobian import (CondensedJacobian, ElementCondensedPC,
                                        element_condensation_supported, jacobian_shell)
from fxcontact.newton.bordered import BorderedOperator, BorderedPC
from fxcontact.newton.options import (LINE_SEARCHES, LINEAR_SOLVERS, MATERIAL_TANGENTS, SolveInfo,
                                      SolverOptions, globalization_options)
from fxcontact.newton.prediction import ActiveSetPrediction
from fxcontact.newton.problem import NonlinearProblem, mumps_null_pivots

__all__ = ["ContactNewtonSolver", "NewtonSolver", "SolveInfo", "SolverOptions", "LINEAR_SOLVERS",
           "choose_linear_solver", "BorderedPC", "MATERIAL_TANGENTS"]

log = logging.getLogger(__name__)

#: What a singular Newton matrix at a converged solution means (:attr:`SolveInfo.null_pivots`)
NULL_PIVOT_HINT = (
    "a motion is held by nothing - a body free to translate or rotate (no velocity condition or "
    "symmetry plane on that component, held only by a contact that is not made, or by "
    "frictionless contact only) or an unknown that no equation reaches. MUMPS picks one "
    "solution of the singular system, so the velocities along that motion are arbitrary "
    "(forces and stresses may still be right). Add the missing velocity condition or symmetry "
    "plane; friction or a contact made in the first increment also removes it")

#: Automatic choice (``linear_solver="auto"``, the default), from the figures of
#: ``benchmarks/README.md`` (sections "Condensed solvers" and ``bench_element_newton.py``):
#: spaces without cell-interior dofs (Taylor–Hood) always get ``"mumps"``; MINI problems below
#: AUTO_CONDENSED_MIN_DOFS global dofs get ``"mumps"`` (the plain path), up to
#: AUTO_ITERATIVE_MIN_DOFS ``"condensed-mumps"``, above it ``"condensed-amg"`` (the condensed
#: direct solver: 0.69× of MUMPS on MINI per Newton iteration at 5.9k dofs, 0.53× at 12k,
#: about the same at 2–3k). Module attributes a user can move; an explicit
#: ``linear_solver`` is never overridden.
AUTO_CONDENSED_MIN_DOFS = 5_000
AUTO_ITERATIVE_MIN_DOFS = 300_000


def choose_linear_solver(W) -> str:
    """The preset that ``linear_solver="auto"`` picks for the mixed space ``W`` (collective)."""
    tdim = W.mesh.topology.dim
    n_int = W.mesh.comm.allreduce(len(W.dofmap.dof_layout.entity_dofs(tdim, 0)), op=MPI.MAX)
    ndofs = W.dofmap.index_map.size_global * W.dofmap.index_map_bs
    if n_int == 0 or W.dofmap.index_map_bs != 1 or ndofs < AUTO_CONDENSED_MIN_DOFS:
        return "mumps"
    if ndofs < AUTO_ITERATIVE_MIN_DOFS:
        return "condensed-mumps"
    return "condensed-amg"


#: initial trust radius of ``line_search="trust-region"`` for a solve that starts from x = 0
#: (PETSc's radius is relative to ‖x‖ otherwise): large, so that the first step is the full
#: Newton step (:meth:`NewtonSolver._trust_region_from_rest`)
TRUST_RADIUS_FROM_REST = 1e10
#: PETSc's default δ₀ of ``newtontr``, restored after a solve from rest
_PETSC_TR_DELTA0 = 0.2

#: ``reuse_factorisation``: the Jacobian of an iterate keeps the last factorisation if Newton's
#: residual contracted by at least this factor at that iterate with the contributors' state
#: unchanged (the first Jacobian of a solve is always factorised: the previous increment's
#: factorisation took more Krylov iterations than it saved, benchmarks/README.md)
REUSE_CONTRACTION = 0.25

#: PETSc option keys (without prefix) written by the last solver created under each prefix
_WRITTEN_OPTIONS: Dict[str, set] = {}


def force_scale(contributors) -> float:
    """ℓ² norm of the contributors' nodal forces (``force_norm()``): ``SolverOptions.ftol``'s
    scale."""
    return math.sqrt(sum(c.force_norm() ** 2 for c in contributors if hasattr(c, "force_norm")))


def warn_unscaled_ftol(contributors, ftol: float) -> bool:
    """Warn (this module's logger) when ``ftol`` is set and no contributor reports
    ``force_norm()``; returns whether it warned."""
    if ftol > 0 and not any(hasattr(c, "force_norm") for c in contributors):
        log.warning(
            "ftol = %g has no effect: no contributor reports force_norm() (the nodal contact "
            "does); Newton stops on rtol, atol and stol only", ftol)
        return True
    return False


class ContactNewtonSolver:
    """SNES Newton with line search, prefixed options and a contributor-aware convergence test.

    (Named apart from dolfinx's ``NewtonSolver``; ``NewtonSolver`` stays an alias.)

    Args:
        problem: the :class:`~fxcontact.newton.problem.NonlinearProblem`.
        options: :class:`SolverOptions`.
        fieldsplit_is: optional (velocity IS, pressure IS) for the field-split preconditioner.
    """

    #: Krylov iterations of the steps solved again with a new factorisation (this solve)
    _resolved_its = 0
    #: the next Jacobian may keep the factorisation (see :meth:`_converged`)
    _reuse_ok = False
    _ftol_warned = False
    _disagreement = None   #: a RanksDisagree raised inside the SNES (raised again after it)

    def __init__(self, problem: NonlinearProblem, options: Optional[SolverOptions] = None,
                 fieldsplit_is=None):
        self.problem = problem
        options = options or SolverOptions()
        #: the linear solver was picked by ``"auto"`` (then :meth:`fall_back_to_direct` may
        #: replace an iterative choice that failed)
        self.auto_chosen = options.linear_solver == "auto"
        if self.auto_chosen:
            options = dataclasses.replace(
                options, linear_solver=choose_linear_solver(problem.w.function_space))
            log.info("linear solver (auto): %s", options.linear_solver)
        self.options = options
        self.comm = problem.comm
        if self.options.uses_fieldsplit and fieldsplit_is is None:
            raise ValueError("the field-split linear solver needs the velocity/pressure ISs")
        self._fieldsplit_is = fieldsplit_is
        self._layout = None
        self._condensed_pc = None
        #: the Jacobian's bubble condensed element by element
        #: (:class:`~fxcontact.element.jacobian.CondensedJacobian`, ``element_condensation``),
        #: or None
        self.element = None
        #: border of the Newton matrix (:meth:`set_border`), or None
        self.border = None
        self._J_shell = self._J_element = None
        if self.options.uses_condensation:
            self._layout = CondensationLayout(problem.w.function_space)
        self._enable_element_condensation()
        #: the assembled Newton matrix (None with the element condensation: its own matrix)
        self.A = problem.create_matrix() if self.element is None else None
        self.b = None
        self.snes = None
        self._create_snes()
        self._norms: List[float] = []
        self._f0 = None
        self._states: list = []
        self._last_it, self._last_stable = -1, False
        self._cycle_message = ""
        self._rtol = options.rtol
        #: number of times the SNES/KSP/PC objects were rebuilt after a failed solve
        self.resets = 0
        #: wall time and number of calls of the SNES callbacks (residual, Jacobian, convergence
        #: test) since the solver was built
        self.callback_times = {"residual": 0.0, "jacobian": 0.0, "test": 0.0}
        self.callback_calls = {"residual": 0, "jacobian": 0, "test": 0}
        #: wall time of the linear solves since the solver was built (see :meth:`solve`)
        self.linear_time = 0.0
        #: converged solves whose last Newton matrix was singular (MUMPS null pivots)
        self.singular_solves = 0
        self._linear_start: Optional[float] = None
        #: the active-set prediction of the Newton steps (None when off); its ``stats``
        self.prediction = None
        self._set_prediction()
        #: factorisations made since the solver was built (one per Jacobian but the kept ones)
        self.factorisations = 0
        PETSc.Log.begin()   # PETSc's event log on (benchmarks read its events)

    def _enable_element_condensation(self):
        """The element condensation of the Jacobian when the options ask for it (sets
        :attr:`element`; collective)."""
        self.element = None
        want = self.options.element_condensation
        if not (self.options.uses_condensation and want is not False):
            return
        why = element_condensation_supported(self.problem)
        if why is None and float(self.options.linear_options().get(
                "condensed_augment_scale", 0.0)) != 0.0:
            why = "the preconditioner's augmentation (condensed_augment_scale) needs it"
        whys = [w for w in self.comm.allgather(why) if w is not None]
        if whys:
            if want is True:
                raise ValueError(f"element_condensation=True: {whys[0]}")
            log.info("bubble condensed after the assembly (%s)", whys[0])
            return
        self.element = CondensedJacobian(self.problem, fast_tensors=getattr(
            self.problem, "element_tensors", None))

    def _write_options(self):
        """Write this solver's options under its prefix (those of an earlier solver under the
        same prefix that this one does not set are removed: e.g. a field-split option left over
        when this solver uses MUMPS); options the user set (command line, PETSc.Options) are
        left alone unless the presets override them."""
        opts = PETSc.Options()
        all_opts = {"snes_max_it": self.options.max_it, "snes_max_funcs": 100000}
        all_opts.update(globalization_options(self.options.line_search))
        all_opts.update(self.options.linear_options())
        p = self.options.prefix
        for key in _WRITTEN_OPTIONS.pop(p, set()):
            if key not in all_opts:
                opts.delValue(p + key)
        for k, v in all_opts.items():
            opts[p + k] = v
        _WRITTEN_OPTIONS[p] = set(all_opts)

    def _create_snes(self):
        """(Re)build the SNES with its KSP/PC and residual vector from this solver's options."""
        self._write_options()
        self.b = self.problem.create_vector()
        snes = PETSc.SNES().create(self.comm)
        snes.setOptionsPrefix(self.options.prefix)
        snes.setFunction(self._residual, self.b)
        for M in (self._J_shell, self._J_element):
            if M is not None:
                M.destroy()
        self._J_shell = self._J_element = None
        op = P = self.A
        if self.element is not None:
            # the condensed system in the element's matrix; the product with the Newton matrix
            # (line search slope, Krylov, border) from the kept cell matrices
            op = P = self._J_element = jacobian_shell(self.element)
        if self.border is not None:
            m, n = op.getSizes()
            op = self._J_shell = PETSc.Mat().createPython(
                (m, n), BorderedOperator(op, self.border), comm=self.comm)
            op.setUp()
        if op is self.A:
            snes.setJacobian(self._jacobian, self.A, self.A)
        else:
            def jacobian(snes_, x, J_, P_):
                self._jacobian(snes_, x, P_, P_)
                # a new state for each operator: a preconditioner is set up again only for a
                # matrix whose state changed (a shell's changes at its assemble())
                J_.assemble()
                if P_.handle != J_.handle:
                    P_.assemble()
            snes.setJacobian(jacobian, op, P)
        snes.setConvergenceTest(self._converged_timed)
        snes.setFromOptions()
        # the linear solve runs between the end of the Jacobian callback and the line search's
        # pre-check (KSPSetOperators, PC set-up, KSPSolve): its wall time is taken there
        snes.setLineSearchPreCheck(self._precheck)
        ksp = snes.getKSP()
        pc_fs = ksp.getPC()
        if self.border is not None:
            # the options' preconditioner, built on the assembled matrix, wrapped below
            pc_fs = PETSc.PC().create(self.comm)
            pc_fs.setOptionsPrefix(self.options.prefix)
            pc_fs.setFromOptions()
        if self.options.uses_fieldsplit:
            pc_fs.setFieldSplitIS(("u", self._fieldsplit_is[0]),
                                  ("p", self._fieldsplit_is[1]))
        ksp.setFromOptions()
        if self._layout is not None:
            if self._condensed_pc is not None:
                self._condensed_pc.destroy()
            if self.element is not None:
                self._condensed_pc = ElementCondensedPC(
                    self.options.prefix + "condensed_", self.element,
                    getattr(self.problem, "schur_weight", None), problem=self.problem)
            else:
                self._condensed_pc = CondensedPC(self._layout,
                                                 self.options.prefix + "condensed_",
                                                 getattr(self.problem, "schur_weight", None),
                                                 problem=self.problem)
            if snes.getUseEW():   # Eisenstat–Walker: the inner solve follows the forcing term
                self._condensed_pc.follow_rtol_of = ksp
            pc = pc_fs
            pc.setType(PETSc.PC.Type.PYTHON)
            pc.setPythonContext(self._condensed_pc)
        if self.border is not None:
            pc = ksp.getPC()
            pc.setType(PETSc.PC.Type.PYTHON)
            pc.setPythonContext(BorderedPC(pc_fs, self.border))
        #: factorise at the next Jacobian (``reuse_factorisation``): no factorisation yet,
        #: or the last Krylov solve took too many iterations
        self._refactor_next = True
        self.snes = snes

    def set_border(self, border):
        """Solve bordered Newton systems from now on (see the module docstring): ``border``
        has ``vectors()`` returning ``(U, G, D)`` — lists of k PETSc vectors (the problem's
        layout, filled by the contributors during the Jacobian evaluation) and the k×k
        array D — or None when there is no border at the current iterate; ``None`` switches
        back to the plain system. Rebuilds the SNES (collective)."""
        if border is self.border:
            return
        self.border = border
        self.reset()

    def reset(self):
        """Rebuild the SNES, its KSP/PC (factorisation), residual and work vectors (collective).

        Called after every failed solve, so that nothing of a failed attempt reaches the next
        one: a failed MUMPS factorisation is otherwise kept by the PC (its numeric phase is then
        skipped at every later setup, so every retry fails at iteration 0), and an error raised
        inside a callback can leave SNES work vectors locked. (The Jacobian matrix is kept: it
        is zeroed at every assembly.)"""
        old_snes, old_b = self.snes, self.b
        self._create_snes()
        old_snes.destroy()
        old_b.destroy()
        self.resets += 1

    # -- SNES callbacks, timed and counted; the linear solve ends at the pre-check -------
    def _timed(self, key, fn, *args):
        t0 = time.perf_counter()
        try:
            return fn(*args)
        finally:
            self.callback_times[key] += time.perf_counter() - t0
            self.callback_calls[key] += 1

    def _residual(self, snes, x, b):
        # the trust region (newtontr) has no line-search pre-check: its linear solve ends at
        # the next residual evaluation (a no-op after the line search's pre-check)
        self._end_linear()
        self._timed("residual", self.problem.residual, snes, x, b)

    def _jacobian(self, snes, x, A, P):
        try:
            if self.element is None:
                self._timed("jacobian", self.problem.jacobian, snes, x, A, P)
            else:
                self._timed("jacobian", self.problem.jacobian, snes, x, A, P, self.element)
        finally:
            self._linear_start = time.perf_counter()
        self._keep_factorisation(self._reuse_ok and not self._refactor_next)

    def _keep_factorisation(self, keep: bool):
        """Whether the coming PC set-up keeps the last factorisation (``reuse_factorisation``;
        without it every Jacobian is factorised)."""
        keep = keep and self.options.reuses_factorisation
        if not keep:
            self.factorisations += 1
            self._refactor_next = False
        if self._condensed_pc is not None:
            self._condensed_pc.reuse = keep

    def _krylov_check(self, ksp: PETSc.KSP) -> bool:
        """After the linear solve of a Newton step (``reuse_factorisation``): factorise at the
        next Jacobian if it took more than ``reuse_max_krylov`` Krylov iterations; returns
        False if the Krylov solve did not converge. Collective (the ranks' inputs checked
        to agree: :func:`~fxcontact.collective.check_decision`)."""
        if not self.options.reuses_factorisation:
            return True
        its, reason = ksp.getIterationNumber(), ksp.getConvergedReason()
        log.debug("Newton step: %d Krylov iterations (reason %d)", its, reason)
        try:
            check_decision(self.comm, "the Newton step with the kept factorisation",
                           kept=bool(getattr(self._condensed_pc, "reuse", False)),
                           krylov_iterations=its, krylov_reason=reason)
        except RanksDisagree as e:   # (through PETSc: raised again after the SNES)
            self._disagreement = e
            raise
        if reason <= 0 or 2 * its > self.options.reuse_max_krylov:
            self._refactor_next = True
        return reason > 0

    def _solve_again(self, y: PETSc.Vec):
        """The Newton step whose Krylov solve with a kept factorisation did not converge,
        solved again with a new factorisation (collective)."""
        ksp = self.snes.getKSP()
        self._keep_factorisation(False)
        op, P = ksp.getOperators()
        op.assemble()   # a new state: the PCs are set up again
        if P.handle != op.handle:
            P.assemble()
        ksp.setOperators(op, P)
        ksp.solve(self.snes.getFunction()[0], y)
        self._resolved_its += ksp.getIterationNumber()
        if not self._krylov_check(ksp):
            raise RuntimeError(f"the linear solve of the Newton step failed with a new "
                               f"factorisation (KSP reason {ksp.getConvergedReason()})")

    def _precheck(self, x, y):
        """Line-search pre-check: the linear solve ends here; the step's Dirichlet entries
        are made exact (``NonlinearProblem.exact_dirichlet_step``: an iterative linear solve
        leaves them within its tolerance)."""
        converged = self._end_linear()
        changed = False
        if not converged:
            t0 = time.perf_counter()
            try:
                self._solve_again(y)
            finally:
                self.linear_time += time.perf_counter() - t0
            changed = True
        if self.prediction is not None:
            # more linear solves (with the same factorisation/preconditioner): linear time
            t0 = time.perf_counter()
            try:
                changed = self.prediction.correct(self.snes.getKSP(), y)
            finally:
                self.linear_time += time.perf_counter() - t0
            self._predicted.append(changed)
        fix = getattr(self.problem, "exact_dirichlet_step", None)
        fixed = bool(fix(x, y)) if fix is not None else False
        return changed or fixed

    def _end_linear(self) -> bool:
        """The linear solve of a Newton step ended (its wall time, the Krylov check of
        ``reuse_factorisation``); returns False when its Krylov solve did not converge."""
        if self._linear_start is None:
            return True
        self.linear_time += time.perf_counter() - self._linear_start
        self._linear_start = None
        return self._krylov_check(self.snes.getKSP())

    def _converged_timed(self, snes, it, norms):
        return self._timed("test", self._converged, snes, it, norms)

    def _converged(self, snes, it, norms):
        xnorm, snorm, fnorm = norms
        if not np.isfinite(fnorm):
            return PETSc.SNES.ConvergedReason.DIVERGED_FNORM_NAN
        contributors = self.problem.contributors
        o = self.options
        if it > 0 and it == self._last_it:
            # newtontr re-tests the same iterate after a rejected step: no new history entry,
            # no cycle, and the contributors keep their verdict for this iterate
            stable = self._last_stable
            period = 0
        else:
            if it == 0:
                self._ftol_warned = self._ftol_warned or warn_unscaled_ftol(contributors, o.ftol)
                self._f0 = fnorm
                self._norms = [fnorm]
                self._states = []
            else:
                self._norms.append(fnorm)
                if snes is not None:   # the factorisation that gave the step to this iterate
                    self._pivots.append(mumps_null_pivots(snes.getKSP()))
                for h in getattr(self.problem, "iterate_hooks", ()):
                    h.accept(snes.getSolution())
            # every contributor must report a stable state at this (accepted) iterate
            # (called at every iteration, including 0, so each contributor takes its snapshot)
            stable = all([c.stable() for c in contributors])
            period = self._cycle_period(contributors, fnorm)
            # the Jacobian may keep the factorisation (reuse_factorisation) where Newton
            # contracts fast with an unchanged contact state and no null pivot (a Krylov solve
            # preconditioned by a singular factorisation may move far along the null space)
            self._reuse_ok = (it > 0 and stable
                              and fnorm <= REUSE_CONTRACTION * self._norms[-2]
                              and not (self._pivots and self._pivots[-1]))
        self._last_it, self._last_stable = it, stable
        log.debug("Newton it %d: |R| = %.3e  |dx| = %.3e  stable=%s", it, fnorm, snorm, stable)
        if stable and it > 0 and fnorm <= self._residual_floor(contributors):
            # as small as the round-off of the contact gaps allows (a tiny dt): converged
            log.debug("Newton it %d: |R| = %.3e at the contributors' round-off floor", it, fnorm)
            return PETSc.SNES.ConvergedReason.CONVERGED_FNORM_ABS
        if period:
            self._cycle_message = self._describe_cycle(contributors, period, fnorm)
            log.debug(self._cycle_message)
            return PETSc.SNES.ConvergedReason.DIVERGED_DTOL
        if stable:
            if fnorm <= o.atol:
                return PETSc.SNES.ConvergedReason.CONVERGED_FNORM_ABS
            if it > 0 and fnorm <= self._rtol * self._f0:
                return PETSc.SNES.ConvergedReason.CONVERGED_FNORM_RELATIVE
            if it > 0 and o.ftol > 0 and fnorm <= o.ftol * force_scale(contributors):
                return PETSc.SNES.ConvergedReason.CONVERGED_FNORM_ABS
            if it > 0 and snorm <= o.stol * max(xnorm, 1e-300):
                return PETSc.SNES.ConvergedReason.CONVERGED_SNORM_RELATIVE
        if it >= o.max_it:
            return PETSc.SNES.ConvergedReason.DIVERGED_MAX_IT
        return PETSc.SNES.ConvergedReason.ITERATING

    @staticmethod
    def _residual_floor(contributors) -> float:
        """The round-off level of the residual norm that the contributors report
        (``residual_floor()``, e.g. the contact's ε|X|/dt gap error): Newton cannot go below."""
        return math.sqrt(sum(c.residual_floor() ** 2 for c in contributors
                             if hasattr(c, "residual_floor")))

    def _describe_cycle(self, contributors, period: int, fnorm: float) -> str:
        """The message of a Newton iteration stopped by the cycle detection: what changes over
        the cycle (the contributors' ``cycle_hint(period)``), or a residual that stagnates
        with an unchanged state."""
        window = self._states[-2 * period:]
        if all(st[0] == window[-1][0] for st in window):
            target = max(self.options.atol, self._rtol * self._f0)
            head = (f"Newton stagnates: the residual stays at {fnorm:.3e} (initial "
                    f"{self._f0:.3e}, converged below {target:.3e}) with the same contact "
                    f"state at every iteration")
            floor = self._residual_floor(contributors)
            if fnorm <= max(self.ROUNDOFF_MARGIN * floor, np.sqrt(np.finfo(float).eps) * self._f0):
                return (f"{head}: the tolerance is below the accuracy the residual can be "
                        f"computed to (raise atol, or rtol)")
            pred = len(self._predicted) >= 2 * period and all(self._predicted[-2 * period:])
            return (f"{head}, far above the round-off of the residual (contact floor "
                    f"{floor:.1e}): the line search finds no decrease along the Newton steps, "
                    f"which are not descent directions (" + ("the active-set prediction "
                    "corrected each of them: SolverOptions.active_set_prediction=False turns "
                    "it off; or " if pred else "") + "an inconsistent Jacobian)")
        hints = [c.cycle_hint(period) if inspect.signature(c.cycle_hint).parameters
                 else c.cycle_hint() for c in contributors if hasattr(c, "cycle_hint")]
        return (f"Newton iterates cycle with period {period} (the same contact state and "
                f"residual {fnorm:.3e} every {period} iterations, twice over): "
                + ("; ".join(hints) if hints else "reduce dt"))

    #: periods looked for by the cycle detection, and the residual match that defines a repeat
    CYCLE_PERIODS = (2, 3, 4)
    CYCLE_RTOL = 1e-6
    #: a residual that stagnates above this multiple of the contributors' round-off floor and
    #: above √ε × the initial residual is not held up by round-off (:meth:`_describe_cycle`)
    ROUNDOFF_MARGIN = 1e3

    def _cycle_period(self, contributors, fnorm: float) -> int:
        """Period p of a cycle of the Newton iterates (0 if none): the contributors' state
        (e.g. the contact active set and facets) and the residual norm equal those of p
        iterations earlier, at 2p consecutive iterations (the orbit went round twice). Such an
        iteration never converges; stopping it early saves the remaining iterations before
        the cut-back."""
        fp = tuple(c.fingerprint() for c in contributors if hasattr(c, "fingerprint"))
        states = self._states
        states.append((fp, fnorm))
        k = len(states) - 1
        for p in self.CYCLE_PERIODS:
            n = 2 * p
            if k < p + n - 1:
                continue
            if all(states[j][0] == states[j - p][0]
                   and abs(states[j][1] - states[j - p][1])
                   <= self.CYCLE_RTOL * max(states[j][1], 1e-300)
                   for j in range(k - n + 1, k + 1)):
                return p
        return 0

    def _set_prediction(self):
        """Create (or drop) the active-set prediction for the current options."""
        if self.options.predicts_active_set:
            if self.prediction is None:
                self.prediction = ActiveSetPrediction(
                    self.problem, self.comm, max_nodes=self.options.prediction_max_nodes)
        else:
            self.prediction = None

    def fall_back_to_direct(self) -> bool:
        """After a failed iterative solve: if ``"auto"`` chose ``"condensed-amg"``, switch this
        solver to ``"condensed-mumps"`` for good (rebuilds the SNES; collective) and return
        True; otherwise change nothing and return False. (The iterative preset does not
        converge on every problem: see benchmarks/README.md, the wire-drawing case.)"""
        if not (self.auto_chosen and self.options.linear_solver == "condensed-amg"):
            return False
        self.options = dataclasses.replace(self.options, linear_solver="condensed-mumps")
        self._set_prediction()
        self.reset()
        return True

    def _trust_region_from_rest(self, x: PETSc.Vec) -> bool:
        """Before a trust-region solve from x = 0 (a body at rest driven by its tools only,
        whose start-up guess is zero): PETSc's initial radius is δ₀‖x‖, or δ₀ = 0.2 in the
        units of x when ‖x‖ = 0, so the steps would be cut to 0.2 and the radius doubled at
        each iteration until it reached the solution's size (16 iterations of the bar rolling's
        first increment). Then the radius starts at :data:`TRUST_RADIUS_FROM_REST` (the first
        step is the full Newton step; a rejected step shrinks it by δ₁ = 0.3). A
        ``snes_tr_delta0`` of the user's is kept. Returns whether the radius was set
        (collective)."""
        if self.snes.getType() != PETSc.SNES.Type.NEWTONTR or x.norm() != 0.0:
            return False
        key = self.options.prefix + "snes_tr_delta0"
        if PETSc.Options().hasName(key):
            return False
        self._set_trust_radius(TRUST_RADIUS_FROM_REST)
        return True

    def _set_trust_radius(self, delta0: float):
        """Set the trust region's δ₀ of this SNES (through its options: petsc4py 3.18 has no
        setter), leaving no option behind."""
        opts = PETSc.Options()
        key = self.options.prefix + "snes_tr_delta0"
        opts[key] = delta0
        self.snes.setFromOptions()
        opts.delValue(key)

    def set_line_search(self, kind: str):
        """Switch the SNES line search (e.g. for a fallback attempt); ``kind`` as in
        :data:`LINE_SEARCHES`."""
        if kind not in LINE_SEARCHES:
            raise ValueError(f"unknown line search {kind!r}; choose one of {LINE_SEARCHES}")
        # petsc4py 3.18 has no SNESLineSearch object: go through the prefixed options
        opts = PETSc.Options()
        for key, val in globalization_options(kind).items():
            opts[self.options.prefix + key] = val
            _WRITTEN_OPTIONS.setdefault(self.options.prefix, set()).add(key)
        self.snes.setFromOptions()

    def solve(self) -> SolveInfo:
        """Solve from the current content of ``problem.w`` (the initial guess); with
        ``penalty_continuation``, a softened first stage then the full problem."""
        f = self.options.penalty_continuation
        soft = [c for c in self.problem.contributors if hasattr(c, "scale_penalty")]
        if f is None or not soft:
            return self._solve()
        w0 = self.problem.w.x.array.copy()
        try:
            for c in soft:
                c.scale_penalty(f)
            self._rtol = self.options.continuation_rtol
            first = self._solve()
        finally:
            for c in soft:
                c.scale_penalty(1.0)
            self._rtol = self.options.rtol
        if not first.converged:
            log.debug("penalty continuation: the softened stage failed (%s); full problem from "
                      "the predictor", first.message)
            self.problem.w.x.array[:] = w0
            self.problem.w.x.scatter_forward()
        info = self._solve()
        info.iterations += first.iterations
        info.linear_iterations += first.linear_iterations
        info.factorisations += first.factorisations
        for key, val in first.times.items():
            info.times[key] = info.times.get(key, 0.0) + val
        for key, val in first.evaluations.items():
            info.evaluations[key] = info.evaluations.get(key, 0) + val
        info.stage_iterations = (first.iterations, info.iterations - first.iterations)
        return info

    def _solve(self) -> SolveInfo:
        prob = self.problem
        prob.error = None
        prob.timers.reset()
        for c in prob.contributors:
            if hasattr(c, "begin_solve"):
                c.begin_solve()
        w = prob.w
        x = w.vector.copy()
        for h in getattr(prob, "iterate_hooks", ()):
            h.begin(x)
        self._cycle_message = ""
        self._last_it = -1
        self._pivots = []
        self._predicted = []   # per Newton step: corrected by the active-set prediction
        self._resolved_its = 0
        fact0 = self.factorisations
        calls0 = dict(self.callback_calls)
        lin0 = self.linear_time
        self._linear_start = None
        t0 = time.perf_counter()
        cpc = self._condensed_pc
        inner0 = cpc.inner_iterations if cpc is not None else 0
        cond0 = cpc.times["condense"] if cpc is not None else 0.0
        fac0 = cpc.times["inner_setup"] if cpc is not None else 0.0
        if cpc is not None:
            cpc.error = None
        from_rest = self._trust_region_from_rest(x)
        try:
            self.snes.solve(None, x)
            self._end_linear()   # a failed linear solve stops the SNES before the line search
            reason = self.snes.getConvergedReason()
            its = self.snes.getIterationNumber()
            # in words, before a failed SNES is rebuilt (its KSP tells why a solve failed)
            msg, fail = "", "" if reason > 0 else self._failure_message(reason, its)
        except Exception as e:  # a contributor error raised through PETSc (collective)
            self._end_linear()
            reason, its = -100, self.snes.getIterationNumber()
            fail = ""
            msg = prob.error or (f"PETSc error inside the Newton solve ({e}; see the PETSc "
                                 f"traceback on stderr)")
        finally:
            if from_rest:
                self._set_trust_radius(_PETSC_TR_DELTA0)
        if self._disagreement is not None:   # not a failed solve: raised again, never retried
            err, self._disagreement = self._disagreement, None
            self.reset()
            raise err
        wall = time.perf_counter() - t0
        if prob.error and not msg:
            msg = prob.error
        if cpc is not None and cpc.error:
            msg = cpc.error
        if self._cycle_message and not msg:
            msg = self._cycle_message
        converged = reason > 0
        if converged:
            x.copy(w.vector)
            w.x.scatter_forward()
        x.destroy()
        if cpc is not None:
            lin_its = cpc.inner_iterations - inner0
            cond = cpc.times["condense"] - cond0
        if cpc is None or self.options.reuses_factorisation:   # the Krylov iterations
            lin_its = self.snes.getLinearSolveIterations() + self._resolved_its
        if not converged:
            # a failed attempt must not poison the next one (factorisation, locked vectors)
            self.reset()
        # linear solve: from the end of each Jacobian callback to the line search's pre-check
        # (or the SNES's end after a failed linear solve): KSPSetOperators, the PC set-up, the
        # Krylov iterations or triangular solves (not PETSc's log events: a solve nested under
        # a python PC counts in both, an error inside an event leaves it open for good).
        # "other": the SNES's vector operations, the callbacks' Python glue, collective waits.
        lin = self.linear_time - lin0
        times = {"assembly": prob.timers.get("assembly"), "contact": prob.timers.get("contact"),
                 "linear_solve": lin}
        times["other"] = max(wall - sum(times.values()), 0.0)
        times["total"] = wall
        if cpc is not None:  # parts of linear_solve: the condensed system, its factorisation
            times["condensation"] = cond
            times["factorisation"] = cpc.times["inner_setup"] - fac0
        # sub-parts of "assembly"
        times["assembly_residual"] = prob.timers.get("assembly_residual")
        times["assembly_jacobian"] = prob.timers.get("assembly_jacobian")
        if not converged and not msg:
            msg = fail or f"SNES diverged: {_reason_name(reason)} after {its} iterations"
        evals = {k: self.callback_calls[k] - calls0[k] for k in ("residual", "jacobian")}
        pivots = list(self._pivots)
        if converged and pivots and (pivots[-1] or 0) > 0:
            self._warn_singular(pivots[-1])
        return SolveInfo(converged, its, reason, list(self._norms), msg, times, lin_its,
                         evaluations=evals, null_pivots=pivots,
                         factorisations=self.factorisations - fact0)

    def _failure_message(self, reason: int, its: int) -> str:
        """Why a Newton solve stopped without converging, in words, with the residual reached
        and the SNES reason in brackets: the iteration cap, a failed linear solve (and the
        Krylov solver's reason), a line search without decrease, a NaN residual."""
        R = PETSc.SNES.ConvergedReason
        norms = self._norms
        res = ""
        if norms:
            target = max(self.options.atol, self._rtol * norms[0])
            res = (f", residual {norms[-1]:.3e} (initial {norms[0]:.3e}, converged below "
                   f"{target:.3e})")
        if reason == R.DIVERGED_MAX_IT:
            text = f"Newton iteration cap (max_it={self.options.max_it}) reached{res}"
        elif reason == R.DIVERGED_LINEAR_SOLVE:
            ksp = self.snes.getKSP()
            why = _reason_name(ksp.getConvergedReason(), PETSc.KSP.ConvergedReason)
            text = (f"the linear solve failed at Newton iteration {its} (Krylov solver: {why}; "
                    f"a NaN/inf or singular Newton matrix, or too little MUMPS memory){res}")
        elif reason == R.DIVERGED_LINE_SEARCH:
            text = (f"the line search found no decrease of the residual at Newton iteration "
                    f"{its}{res}")
        elif reason == R.DIVERGED_FNORM_NAN:
            text = f"the residual is NaN/inf at Newton iteration {its}"
        else:
            text = f"Newton stopped at iteration {its}{res}"
        return f"{text} [SNES {_reason_name(reason)}]"

    def _warn_singular(self, n: int):
        """A solve converged with a singular Newton matrix at its last iteration: warn (in
        full the first time, in one line after that)."""
        self.singular_solves += 1
        if self.singular_solves == 1:
            log.warning("the Newton matrix is singular at the converged solution (MUMPS found "
                        "%d null pivot(s)): %s", n, NULL_PIVOT_HINT)
        else:
            log.info("singular Newton matrix again (%d null pivot(s); %d solves so far)", n,
                     self.singular_solves)

    def destroy(self):
        if self._condensed_pc is not None:
            self._condensed_pc.destroy()
        self.snes.destroy()
        for M in (self._J_shell, self._J_element, self.A):
            if M is not None:
                M.destroy()
        if self.element is not None:
            self.element.destroy()
        self.b.destroy()


#: the former name of :class:`ContactNewtonSolver` (the same class)
NewtonSolver = ContactNewtonSolver


def _reason_name(reason: int, kind=PETSc.SNES.ConvergedReason) -> str:
    for k, v in kind.__dict__.items():
        if isinstance(v, int) and v == reason and not k.startswith("_"):
            return k
    return str(reason)
