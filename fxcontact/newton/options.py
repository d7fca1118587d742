"""Settings of the Newton solver (:class:`SolverOptions`) and the linear-solver presets
(:data:`LINEAR_SOLVERS`); the solver itself is :class:`fxcontact.newton.solver.ContactNewtonSolver`."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Dict, List, Optional

import numpy as np

__all__ = ["SolverOptions", "SolveInfo", "LINEAR_SOLVERS", "LINE_SEARCHES", "MATERIAL_TANGENTS",
           "globalization_options"]

#: Linear solver presets (PETSc options without prefix).
LINEAR_SOLVERS: Dict[str, Dict[str, object]] = {
    "mumps": {"ksp_type": "preonly", "pc_type": "lu", "pc_factor_mat_solver_type": "mumps",
              "mat_mumps_icntl_14": 200, "mat_mumps_icntl_24": 1},
    # Schur-complement field split (velocity block: hypre AMG; Schur: pressure mass-like
    # preconditioner from the selfp approximation), flexible GMRES outside.
    "fieldsplit": {"ksp_type": "fgmres", "ksp_rtol": 1e-10, "ksp_atol": 1e-14,
                   "ksp_max_it": 500, "ksp_gmres_restart": 200,
                   "pc_type": "fieldsplit", "pc_fieldsplit_type": "schur",
                   "pc_fieldsplit_schur_fact_type": "upper",
                   "pc_fieldsplit_schur_precondition": "selfp",
                   "fieldsplit_u_ksp_type": "preonly", "fieldsplit_u_pc_type": "hypre",
                   "fieldsplit_p_ksp_type": "preonly", "fieldsplit_p_pc_type": "jacobi"},
    # MINI bubble condensed element by element (fxcontact.element.assembled.CondensedPC, an exact block
    # elimination), the P1/P1 system solved by MUMPS under the prefix "condensed_"
    "condensed-mumps": {"ksp_type": "preonly", "pc_type": "python",
                        "condensed_ksp_type": "preonly", "condensed_pc_type": "lu",
                        "condensed_pc_factor_mat_solver_type": "mumps",
                        "condensed_mat_mumps_icntl_14": 200, "condensed_mat_mumps_icntl_24": 1,
                        # L D Lᵀ when the condensed matrix is symmetric (fxcontact.element.assembled)
                        "condensed_factor_symmetric": 1},
    # condensed P1/P1 system solved iteratively: FGMRES, Schur field split (full
    # factorisation), GAMG on the velocity block (block size gdim, rigid-body near-null space,
    # unsmoothed aggregation, one Chebyshev/Jacobi sweep per level),
    # Schur preconditioned by the condensed pressure block + the inverse-viscosity lumped
    # pressure mass (Jacobi); the Newton step to rtol 1e-8 (snes_ksp_ew: Eisenstat–Walker)
    "condensed-amg": {"ksp_type": "preonly", "pc_type": "python",
                      "condensed_ksp_type": "fgmres", "condensed_ksp_rtol": 1e-8,
                      # 500: the Hertz sphere at 807k dofs takes ~250 iterations per Newton
                      # iteration with this preset (benchmarks/README.md)
                      "condensed_ksp_atol": 1e-50, "condensed_ksp_max_it": 500,
                      "condensed_ksp_gmres_restart": 100,
                      "condensed_pc_type": "fieldsplit",
                      "condensed_pc_fieldsplit_type": "schur",
                      "condensed_pc_fieldsplit_schur_fact_type": "full",
                      "condensed_pc_fieldsplit_schur_precondition": "user",
                      "condensed_fieldsplit_u_ksp_type": "preonly",
                      "condensed_fieldsplit_u_pc_type": "gamg",
                      "condensed_fieldsplit_u_pc_gamg_threshold": 0.02,
                      "condensed_fieldsplit_u_pc_gamg_square_graph": 1,
                      # plain (unsmoothed) aggregation and one Chebyshev sweep per level:
                      # more Krylov iterations, cheaper set-up and V-cycle (per Newton
                      # iteration 1.16x faster at 300k dofs, 1.42x at 1M; benchmarks/README.md)
                      "condensed_fieldsplit_u_pc_gamg_agg_nsmooths": 0,
                      "condensed_fieldsplit_u_mg_levels_ksp_type": "chebyshev",
                      "condensed_fieldsplit_u_mg_levels_ksp_max_it": 1,
                      "condensed_fieldsplit_u_mg_levels_pc_type": "jacobi",
                      "condensed_fieldsplit_p_ksp_type": "preonly",
                      "condensed_fieldsplit_p_pc_type": "jacobi"},
}
# the same for the hard cases (nearly rigid-plastic flow with a free dilatation, large
# viscosity contrasts: the wire drawing at m = 0.016, benchmarks/README.md): the velocity
# block of the preconditioning matrix augmented by (2/3) η div div (fxcontact.element.assembled), the
# Schur complement preconditioned by A11 − A10 diag(A00)⁻¹ A01 (selfp, GAMG), and the velocity
# block solved by up to 20 GAMG-preconditioned GMRES iterations (relative 1e-2) inside the
# outer FGMRES; several times the cost of "condensed-amg" where that one converges
LINEAR_SOLVERS["condensed-amg-robust"] = {
    **LINEAR_SOLVERS["condensed-amg"],
    "condensed_augment_scale": 1.0,
    "condensed_pc_fieldsplit_schur_precondition": "selfp",
    "condensed_fieldsplit_p_pc_type": "gamg",
    "condensed_fieldsplit_u_ksp_type": "gmres",
    "condensed_fieldsplit_u_ksp_max_it": 20,
    "condensed_fieldsplit_u_ksp_rtol": 1e-2,
}

#: relative tolerance of the Krylov solve of a Newton step preconditioned by a kept
#: factorisation (``SolverOptions.reuse_factorisation``)
REUSE_KRYLOV_RTOL = 1e-4


def _reuse_options(max_krylov: int) -> Dict[str, object]:
    """PETSc options (without prefix) of ``SolverOptions.reuse_factorisation``: FGMRES (right
    preconditioning: the true residual of the Newton system) on the Newton matrix, stopped at
    2 × ``max_krylov`` iterations without failing the Newton solve (the solver then factorises
    again and solves the step anew)."""
    return {"ksp_type": "fgmres", "ksp_rtol": REUSE_KRYLOV_RTOL, "ksp_atol": 1e-50,
            "ksp_max_it": max_krylov, "ksp_gmres_restart": max_krylov,
            "snes_max_linear_solve_fail": 1000000}


#: PETSc SNES line searches accepted by :class:`SolverOptions`
#: globalisations of the Newton step: PETSc's line searches (SNES ``newtonls``) and
#: ``"trust-region"`` (SNES ``newtontr``: dogleg steps inside a trust region, no line search)
LINE_SEARCHES = ("bt", "basic", "l2", "cp", "nleqerr", "trust-region")
#: values of ``SolverOptions.material_tangent``
MATERIAL_TANGENTS = ("auto", "consistent", "primal-dual")


@dataclass
class SolverOptions:
    """Newton settings, validated at construction.

    Attributes:
        rtol: relative residual tolerance ‖R‖/‖R₀‖.
        atol: absolute residual tolerance.
        stol: relative step tolerance ‖Δx‖/‖x‖ (a converged Newton step).
        ftol: force-scaled tolerance: converged when ‖R‖ ≤ ftol × the ℓ² norm of the
            contributors' nodal forces (``force_norm()``, the contact forces) with their state
            stable; 0 (default) leaves it off. Unlike ``rtol`` it does not depend on how good
            the increment's predictor was: ‖R₀‖ varies by 100× between similar increments of
            a process, so ``rtol`` alone asks for a different accuracy each time.
        max_it: maximum Newton iterations per solve.
        line_search: globalisation of the Newton step: a PETSc SNES line search ("bt",
            "basic", "l2", "cp", "nleqerr") or ``"trust-region"`` (SNES ``newtontr``). On a
            nearly rigid-plastic material with a stiff contact penalty the full Newton step
            overshoots (the power-law tangent along the flow is m times the secant one) and
            the backtracking line search then creeps with 1–10 % steps; the trust region takes
            fewer iterations there (figures in ``benchmarks/README.md``, section "Newton at
            m = 0.016").
        line_search_fallback: line search of a second attempt at the same time step when the
            first one fails to converge (before any cut-back), or None. Backtracking on the
            residual norm can stall when contact nodes open and close and friction nodes pass
            between stick and slip in the same iteration (tiny accepted steps, or a 2-cycle);
            full Newton steps then converge in a few iterations. Default ``"auto"``:
            ``"basic"`` after a line search, ``"bt"`` after the trust region.
        linear_solver: ``"auto"`` (default: :func:`~fxcontact.newton.solver.choose_linear_solver`
            picks a preset from the space and its size when the solver is built), a key of
            :data:`LINEAR_SOLVERS` (``"mumps"``: MUMPS on the whole system;
            ``"condensed-mumps"``: the MINI bubble condensed element by element, MUMPS on the
            P1/P1 system; ``"condensed-amg"``: the condensed system by a Schur field split
            with algebraic multigrid, :mod:`fxcontact.element.assembled`; ``"condensed-amg-robust"``:
            the same made to converge on the hard cases — nearly rigid-plastic flow with a
            free dilatation, the wire drawing — at several times the cost; ``"fieldsplit"``)
            or a dict of PETSc options.
        penalty_continuation: continuation in the contact penalty, a factor f in (0, 1), or
            None (default, off). Each Newton solve then runs in two stages: the contributors
            that have ``scale_penalty`` (:class:`~fxcontact.contact.NodalContact`) get ρ·f
            and Newton stops at ``continuation_rtol``; from there, the full penalty to the
            usual tolerances. With a nearly rigid-plastic material and a stiff penalty the
            second stage takes 3–6 iterations and the soft first stage converges much faster
            than the stiff problem from the predictor (figures in ``benchmarks/README.md``,
            section "Newton at m = 0.016"). If the first stage fails, the second starts from
            the predictor. The result is the full-penalty solution either way.
        continuation_rtol: relative residual tolerance of the softened first stage.
        active_set_prediction: correct each Newton step for the contact status changes it
            predicts (:mod:`fxcontact.newton.prediction`): the step of the linear system of the
            predicted penalty branch, by the Woodbury identity, one extra linear solve
            (back-substitution with a direct solver) per node that changes status. Line
            searches only (the trust region has no pre-check in petsc4py 3.18). ``"auto"``
            (default): on with a direct linear solver (``ksp_type preonly``, the condensed
            one's too), off with an iterative one (each extra solve would be a Krylov solve);
            True / False force it. Figures in ``benchmarks/README.md`` ("active-set
            prediction"): 1.4–2.5× fewer Newton iterations where nodes enter and leave
            contact (ironing, grooves, Hertz, nearly rigid-plastic drawing with a stiff
            penalty), no change where friction sets the count.
        prediction_max_nodes: the step is left uncorrected at an iteration where more nodes
            than this change status (the cost is one linear solve per node).
        material_tangent: ``"auto"`` (default: ``"primal-dual"`` for a Norton–Hoff
            material with m < 1, else ``"consistent"``), ``"consistent"`` or
            ``"primal-dual"``: the Norton–Hoff tangent of the primal–dual Newton
            (:mod:`fxcontact.element.dual`: the deviatoric stress kept as a dual variable at the
            quadrature points; same residual, same solution). Read by
            :class:`~fxcontact.simulation.Simulation` (a problem of your own adds
            :meth:`fxcontact.element.dual.DualStress.jacobian_correction` to its Jacobian and the
            :class:`~fxcontact.element.dual.DualStress` to ``NonlinearProblem.iterate_hooks``).
        element_condensation: with a condensed linear solver, condense the bubble in the
            element matrices before they are assembled (:mod:`fxcontact.element.jacobian`:
            the same Newton step at a fraction of the assembly and condensation cost) instead
            of condensing the assembled MINI matrix (:class:`~fxcontact.element.assembled.CondensedPC`).
            ``"auto"`` (default): wherever the Jacobian allows it (cell integrals over the whole
            mesh); True: required (ValueError otherwise); False: the algebraic condensation.
        reuse_factorisation: keep the factorisation of an earlier Newton iteration as the
            preconditioner of a Krylov solve (FGMRES to the relative tolerance
            :data:`REUSE_KRYLOV_RTOL`, an inexact Newton step) of the Newton step with the exact
            Newton matrix. Kept at the iterates where Newton contracts fast with an unchanged
            contact state (:data:`fxcontact.newton.solver.REUSE_CONTRACTION`; the first Jacobian of a
            solve is always factorised); factorised again at the next iteration after a step
            that took more than half of ``reuse_max_krylov`` Krylov iterations, and at once
            (the step solved again) when the Krylov solve does not converge within them. The
            condensed direct linear solver only (``"condensed-mumps"``). Same residual, same
            converged solution; fewer factorisations, some Krylov iterations (one triangular
            solve and one product with the Newton matrix each). False (default), ``"auto"``
            (on with ``"condensed-mumps"``; the wire-drawing case's default: 1.8x faster per
            Newton iteration at the thesis size on 2 ranks, equal at 22k dofs), True (with
            another linear solver: ValueError). A factorisation in which MUMPS found null
            pivots is never kept (a Krylov solve preconditioned by it may move far along the
            null space). Not the default: the inexact steps can take Newton to another
            solution where the contact state is fragile. The quick ring rolling's increment 2
            took 26 Newton iterations instead of 16 and converged where contact was lost (2 null
            pivots, a rigid motion left free), and the next check found an inverted element
            (cut back). Figures in ``benchmarks/README.md`` (``bench_element_newton.py``).
        reuse_max_krylov: see ``reuse_factorisation``.
        prefix: PETSc options prefix.
        petsc_options: extra PETSc options (without prefix) that override the presets.
    """

    rtol: float = 1e-9
    atol: float = 1e-10
    stol: float = 1e-9
    ftol: float = 0.0
    max_it: int = 30
    line_search: str = "bt"
    line_search_fallback: Optional[str] = "auto"
    linear_solver: object = "auto"
    penalty_continuation: Optional[float] = None
    continuation_rtol: float = 1e-3
    active_set_prediction: object = "auto"
    prediction_max_nodes: int = 200
    material_tangent: str = "auto"
    element_condensation: object = "auto"
    reuse_factorisation: object = False
    reuse_max_krylov: int = 10
    prefix: str = "fxc_"
    petsc_options: Dict[str, object] = field(default_factory=dict)

    def __post_init__(self):
        for name in ("rtol", "atol", "stol", "ftol"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v >= 0):
                raise ValueError(f"{name} must be a finite number >= 0, got {v!r}")
        if not (isinstance(self.max_it, (int, np.integer)) and self.max_it >= 1):
            raise ValueError(f"max_it must be an integer >= 1, got {self.max_it!r}")
        if self.line_search_fallback == "auto":
            self.line_search_fallback = "bt" if self.line_search == "trust-region" else "basic"
        for name in ("line_search", "line_search_fallback"):
            ls = getattr(self, name)
            if ls not in LINE_SEARCHES and not (name == "line_search_fallback" and ls is None):
                raise ValueError(f"unknown {name.replace('_', ' ')} {ls!r}; choose one of "
                                 f"{LINE_SEARCHES}")
        if isinstance(self.linear_solver, str) and self.linear_solver not in LINEAR_SOLVERS \
                and self.linear_solver != "auto":
            raise ValueError(f"unknown linear solver {self.linear_solver!r}; choose 'auto', one "
                             f"of {sorted(LINEAR_SOLVERS)} or pass a dict of PETSc options")
        if not isinstance(self.linear_solver, (str, dict)):
            raise ValueError("linear_solver must be a preset name or a dict of PETSc options")
        pc = self.penalty_continuation
        if pc is not None and not (isinstance(pc, (int, float)) and 0.0 < pc < 1.0):
            raise ValueError(f"penalty_continuation must be None or a factor in (0, 1), got "
                             f"{pc!r}")
        if not (isinstance(self.active_set_prediction, (bool, np.bool_))
                or self.active_set_prediction == "auto"):
            raise ValueError(f"active_set_prediction must be 'auto', True or False, got "
                             f"{self.active_set_prediction!r}")
        if not (isinstance(self.prediction_max_nodes, (int, np.integer))
                and self.prediction_max_nodes >= 1):
            raise ValueError(f"prediction_max_nodes must be an integer >= 1, got "
                             f"{self.prediction_max_nodes!r}")
        if self.material_tangent not in MATERIAL_TANGENTS:
            raise ValueError(f"unknown material tangent {self.material_tangent!r}; choose one "
                             f"of {MATERIAL_TANGENTS}")
        if not (isinstance(self.element_condensation, (bool, np.bool_))
                or self.element_condensation == "auto"):
            raise ValueError(f"element_condensation must be 'auto', True or False, got "
                             f"{self.element_condensation!r}")
        if not (isinstance(self.reuse_factorisation, (bool, np.bool_))
                or self.reuse_factorisation == "auto"):
            raise ValueError(f"reuse_factorisation must be 'auto', True or False, got "
                             f"{self.reuse_factorisation!r}")
        if not (isinstance(self.reuse_max_krylov, (int, np.integer))
                and self.reuse_max_krylov >= 1):
            raise ValueError(f"reuse_max_krylov must be an integer >= 1, got "
                             f"{self.reuse_max_krylov!r}")
        if self.reuse_factorisation is True and self.linear_solver != "auto" \
                and not self._reusable():
            raise ValueError(f"reuse_factorisation=True needs the condensed direct linear "
                             f"solver ('condensed-mumps'), not {self.linear_solver!r}: use "
                             f"reuse_factorisation=False or 'auto'")
        if not (np.isfinite(self.continuation_rtol) and 0.0 < self.continuation_rtol < 1.0):
            raise ValueError(f"continuation_rtol must be in (0, 1), got "
                             f"{self.continuation_rtol!r}")

    def linear_options(self) -> Dict[str, object]:
        """PETSc options of the linear solver: the preset (or dict), the Krylov solve of
        ``reuse_factorisation`` and ``petsc_options`` (``"auto"``, not resolved yet: the
        ``petsc_options`` alone)."""
        reuse = _reuse_options(self.reuse_max_krylov) if self.reuses_factorisation else {}
        lin = self._preset_options()
        return {**lin, **reuse, **{k: lin[k] for k in self.petsc_options}}

    def _preset_options(self) -> Dict[str, object]:
        """The preset (or dict) with ``petsc_options``, without ``reuse_factorisation``."""
        if self.linear_solver == "auto":
            lin = {}
        else:
            lin = (LINEAR_SOLVERS[self.linear_solver] if isinstance(self.linear_solver, str)
                   else self.linear_solver)
        return {**lin, **self.petsc_options}

    @property
    def reuses_factorisation(self) -> bool:
        """``reuse_factorisation`` resolved: ``"auto"`` means with ``"condensed-mumps"``; never
        with an iterative linear solver, nor while the linear solver is ``"auto"``, not
        resolved yet."""
        if self.reuse_factorisation == "auto":
            on = self.linear_solver == "condensed-mumps"
        else:
            on = bool(self.reuse_factorisation) and self.linear_solver != "auto"
        return on and self._reusable()

    def _reusable(self) -> bool:
        """A factorisation that ``reuse_factorisation`` can keep: the condensed system's, solved
        by a direct solver (the condensed PC decides at each set-up; PETSc's SNES resets the
        reuse flag of its own KSP's PC after every Jacobian)."""
        return self.uses_condensation and self.uses_direct_solver

    @property
    def uses_fieldsplit(self) -> bool:
        """True if the preconditioner is a field split (it needs velocity/pressure ISs)."""
        return self._preset_options().get("pc_type") == "fieldsplit"

    @property
    def uses_direct_solver(self) -> bool:
        """True if the linear solve is a direct one (``ksp_type preonly``, and so is the
        condensed system's solve): extra solves with its factorisation are cheap."""
        lin = self._preset_options()
        if lin.get("ksp_type") != "preonly":
            return False
        return not self.uses_condensation or lin.get("condensed_ksp_type") == "preonly"

    @property
    def predicts_active_set(self) -> bool:
        """Whether the Newton steps get the active-set prediction (``active_set_prediction``
        resolved: ``"auto"`` means with a direct linear solver)."""
        if self.active_set_prediction == "auto":
            return self.linear_solver != "auto" and self.uses_direct_solver
        return bool(self.active_set_prediction)

    @property
    def uses_condensation(self) -> bool:
        """True if the linear solver condenses the cell-interior (bubble) dofs
        (:class:`~fxcontact.element.assembled.CondensedPC`: ``pc_type python`` without a
        ``pc_python_type``)."""
        lin = self._preset_options()
        return lin.get("pc_type") == "python" and "pc_python_type" not in lin


def globalization_options(kind: str) -> Dict[str, str]:
    """SNES options (without prefix) of a :data:`LINE_SEARCHES` entry."""
    if kind == "trust-region":
        return {"snes_type": "newtontr"}
    return {"snes_type": "newtonls", "snes_linesearch_type": kind}


@dataclass
class SolveInfo:
    """Outcome of one Newton solve."""

    converged: bool
    iterations: int
    reason: int
    residual_norms: List[float]
    message: str = ""
    times: Dict[str, float] = field(default_factory=dict)
    #: Krylov iterations of the solve (inner iterations of a condensed solver), summed over
    #: the Newton iterations
    linear_iterations: int = 0
    #: Newton iterations of the softened and of the full stage (penalty continuation), or None
    stage_iterations: Optional[tuple] = None
    #: number of residual and Jacobian evaluations (SNES callbacks) of the solve: one
    #: residual at the start plus one per line-search trial, one Jacobian per iteration
    evaluations: Dict[str, int] = field(default_factory=dict)
    #: null pivots of the MUMPS factorisation of each Newton iteration's matrix (INFOG(28);
    #: None with a solver that is not MUMPS): a positive count means a singular Newton matrix,
    #: a motion that nothing holds (see :data:`fxcontact.newton.solver.NULL_PIVOT_HINT`)
    null_pivots: List[Optional[int]] = field(default_factory=list)
    #: factorisations of the Newton matrix made during the solve (one per Newton iteration
    #: unless ``SolverOptions.reuse_factorisation`` keeps them)
    factorisations: int = 0
