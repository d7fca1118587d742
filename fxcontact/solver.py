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

**Bordered systems** (:meth:`NewtonSolver.set_border`): a contributor may eliminate k scalar
unknowns locally at each residual evaluation (the rotation speeds of idle tools,
:class:`~fxcontact.mill.IdleRotation`); the Newton matrix is then the assembled J plus a rank-k
term, J̃ = J − U D⁻¹ G (U = ∂R/∂ω, G = ∂T/∂v, D = ∂T/∂ω, k×k). The SNES Jacobian becomes a
shell J̃ (its product is exact, so the line search's slope and any Krylov method see J̃), the
linear solver's own preconditioner P ≈ J⁻¹ (MUMPS, the condensed PC, a field split) is wrapped
by :class:`BorderedPC`, which applies the Woodbury formula J̃⁻¹ = J⁻¹ + Z (D − G Z)⁻¹ G J⁻¹ with
Z = P⁻¹ U: k extra applications of P per Newton iteration (with a factorisation, k extra
triangular solves, no new factorisation), exact when P is.
"""

from __future__ import annotations

import dataclasses
import inspect
import logging
import math
import time
from dataclasses import dataclass, field
from typing import Dict, List, Optional

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from fxcontact.petsc import NonlinearProblem, mumps_null_pivots

__all__ = ["ContactNewtonSolver", "NewtonSolver", "SolveInfo", "SolverOptions", "LINEAR_SOLVERS",
           "choose_linear_solver", "BorderedPC", "MATERIAL_TANGENTS"]

log = logging.getLogger(__name__)

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
    # MINI bubble condensed element by element (fxcontact.condense.CondensedPC, an exact block
    # elimination), the P1/P1 system solved by MUMPS under the prefix "condensed_"
    "condensed-mumps": {"ksp_type": "preonly", "pc_type": "python",
                        "condensed_ksp_type": "preonly", "condensed_pc_type": "lu",
                        "condensed_pc_factor_mat_solver_type": "mumps",
                        "condensed_mat_mumps_icntl_14": 200, "condensed_mat_mumps_icntl_24": 1,
                        # L D Lᵀ when the condensed matrix is symmetric (fxcontact.condense)
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
# block of the preconditioning matrix augmented by (2/3) η div div (fxcontact.condense), the
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

#: What a singular Newton matrix at a converged solution means (:attr:`SolveInfo.null_pivots`)
NULL_PIVOT_HINT = (
    "a motion is held by nothing - a body free to translate or rotate (no velocity condition or "
    "symmetry plane on that component, held only by a contact that is not made, or by "
    "frictionless contact only) or an unknown that no equation reaches. MUMPS picks one "
    "solution of the singular system, so the velocities along that motion are arbitrary "
    "(forces and stresses may still be right). Add the missing velocity condition or symmetry "
    "plane; friction or a contact made in the first increment also removes it")

#: Automatic choice (``linear_solver="auto"``, the default), from the figures of
#: ``benchmarks/README.md`` (section "Condensed solvers"): spaces without cell-interior dofs
#: (Taylor–Hood) always get ``"mumps"``; MINI problems below AUTO_CONDENSED_MIN_DOFS global
#: dofs get ``"mumps"`` (the plain path: both direct solvers take well under a second there),
#: up to AUTO_ITERATIVE_MIN_DOFS ``"condensed-mumps"``, above it ``"condensed-amg"``. Module
#: attributes, so a user can move them; an explicit ``linear_solver`` is never overridden.
AUTO_CONDENSED_MIN_DOFS = 20_000
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

#: PETSc SNES line searches accepted by :class:`SolverOptions`
#: globalisations of the Newton step: PETSc's line searches (SNES ``newtonls``) and
#: ``"trust-region"`` (SNES ``newtontr``: dogleg steps inside a trust region, no line search)
LINE_SEARCHES = ("bt", "basic", "l2", "cp", "nleqerr", "trust-region")
#: values of ``SolverOptions.material_tangent``
MATERIAL_TANGENTS = ("auto", "consistent", "primal-dual")

#: PETSc option keys (without prefix) written by the last solver created under each prefix
_WRITTEN_OPTIONS: Dict[str, set] = {}


@dataclass
class SolverOptions:
    """Newton settings, validated at construction.

    Attributes:
        rtol: relative residual tolerance ‖R‖/‖R₀‖.
        atol: absolute residual tolerance.
        stol: relative step tolerance ‖Δx‖/‖x‖ (a converged Newton step).
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
        linear_solver: ``"auto"`` (default: :func:`choose_linear_solver` picks a preset from
            the space and its size when the solver is built), a key of
            :data:`LINEAR_SOLVERS` (``"mumps"``: MUMPS on the whole system;
            ``"condensed-mumps"``: the MINI bubble condensed element by element, MUMPS on the
            P1/P1 system; ``"condensed-amg"``: the condensed system by a Schur field split
            with algebraic multigrid, :mod:`fxcontact.condense`; ``"condensed-amg-robust"``:
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
            predicts (:mod:`fxcontact.prediction`): the step of the linear system of the
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
            (:mod:`fxcontact.dual`: the deviatoric stress kept as a dual variable at the
            quadrature points; same residual, same solution). Read by
            :class:`~fxcontact.simulation.Simulation` (a problem of your own adds
            :meth:`fxcontact.dual.DualStress.jacobian_correction` to its Jacobian and the
            :class:`~fxcontact.dual.DualStress` to ``NonlinearProblem.iterate_hooks``).
        element_condensation: with a condensed linear solver, condense the bubble in the
            element matrices before they are assembled (:mod:`fxcontact.element_jacobian`:
            the same Newton step at a fraction of the assembly and condensation cost) instead
            of condensing the assembled MINI matrix (:class:`~fxcontact.condense.CondensedPC`).
            ``"auto"`` (default): wherever the Jacobian allows it (cell integrals over the whole
            mesh); True: required (ValueError otherwise); False: the algebraic condensation.
        prefix: PETSc options prefix.
        petsc_options: extra PETSc options (without prefix) that override the presets.
    """

    rtol: float = 1e-9
    atol: float = 1e-10
    stol: float = 1e-9
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
    prefix: str = "fxc_"
    petsc_options: Dict[str, object] = field(default_factory=dict)

    def __post_init__(self):
        for name in ("rtol", "atol", "stol"):
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
        if not (np.isfinite(self.continuation_rtol) and 0.0 < self.continuation_rtol < 1.0):
            raise ValueError(f"continuation_rtol must be in (0, 1), got "
                             f"{self.continuation_rtol!r}")

    def linear_options(self) -> Dict[str, object]:
        """PETSc options of the linear solver: the preset (or dict) with ``petsc_options``
        (``"auto"``, not resolved yet: the ``petsc_options`` alone)."""
        if self.linear_solver == "auto":
            lin = {}
        else:
            lin = (LINEAR_SOLVERS[self.linear_solver] if isinstance(self.linear_solver, str)
                   else self.linear_solver)
        return {**lin, **self.petsc_options}

    @property
    def uses_fieldsplit(self) -> bool:
        """True if the preconditioner is a field split (it needs velocity/pressure ISs)."""
        return self.linear_options().get("pc_type") == "fieldsplit"

    @property
    def uses_direct_solver(self) -> bool:
        """True if the linear solve is a direct one (``ksp_type preonly``, and so is the
        condensed system's solve): extra solves with its factorisation are cheap."""
        lin = self.linear_options()
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
        (:class:`~fxcontact.condense.CondensedPC`: ``pc_type python`` without a
        ``pc_python_type``)."""
        lin = self.linear_options()
        return lin.get("pc_type") == "python" and "pc_python_type" not in lin


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
    #: a motion that nothing holds (see :data:`NULL_PIVOT_HINT`)
    null_pivots: List[Optional[int]] = field(default_factory=list)


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
        if self._M is None:
            return
        c = np.array([g.dot(y) for g in self._G])
        s = np.linalg.solve(self._M, c)
        for z, sj in zip(self._Z, s):
            y.axpy(float(sj), z)

    def view(self, pc, viewer=None):
        self.inner.view(viewer)

    def destroy(self, pc=None):
        for z in self._Z:
            z.destroy()
        self._Z, self._G = [], []
        if self.inner is not None:
            self.inner.destroy()
            self.inner = None


class _BorderedOperator:
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


class ContactNewtonSolver:
    """SNES Newton with line search, prefixed options and a contributor-aware convergence test.

    (Named apart from dolfinx's ``NewtonSolver``; ``NewtonSolver`` stays an alias.)

    Args:
        problem: the :class:`~fxcontact.petsc.NonlinearProblem`.
        options: :class:`SolverOptions`.
        fieldsplit_is: optional (velocity IS, pressure IS) for the field-split preconditioner.
    """

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
        #: (:class:`~fxcontact.element_jacobian.CondensedJacobian`, ``element_condensation``),
        #: or None
        self.element = None
        #: border of the Newton matrix (:meth:`set_border`), or None
        self.border = None
        self._J_shell = self._J_element = None
        if self.options.uses_condensation:
            from fxcontact.condense import CondensationLayout
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
        PETSc.Log.begin()   # PETSc's event log on (benchmarks read its events)

    def _enable_element_condensation(self):
        """The element condensation of the Jacobian when the options ask for it (sets
        :attr:`element`; collective)."""
        from fxcontact.element_jacobian import CondensedJacobian, element_condensation_supported
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
        all_opts.update(_globalization_options(self.options.line_search))
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
            from fxcontact.element_jacobian import jacobian_shell
            op = P = self._J_element = jacobian_shell(self.element)
        if self.border is not None:
            m, n = op.getSizes()
            op = self._J_shell = PETSc.Mat().createPython(
                (m, n), _BorderedOperator(op, self.border), comm=self.comm)
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
            from fxcontact.condense import CondensedPC
            if self._condensed_pc is not None:
                self._condensed_pc.destroy()
            if self.element is not None:
                from fxcontact.element_jacobian import ElementCondensedPC
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

    def _precheck(self, x, y):
        """Line-search pre-check: the linear solve ends here; the step's Dirichlet entries
        are made exact (``NonlinearProblem.exact_dirichlet_step``: an iterative linear solve
        leaves them within its tolerance)."""
        self._end_linear()
        changed = False
        if self.prediction is not None:
            # more linear solves (with the same factorisation/preconditioner): linear time
            t0 = time.perf_counter()
            try:
                changed = self.prediction.correct(self.snes.getKSP(), y)
            finally:
                self.linear_time += time.perf_counter() - t0
        fix = getattr(self.problem, "exact_dirichlet_step", None)
        fixed = bool(fix(x, y)) if fix is not None else False
        return changed or fixed

    def _end_linear(self):
        if self._linear_start is not None:
            self.linear_time += time.perf_counter() - self._linear_start
            self._linear_start = None

    def _converged_timed(self, snes, it, norms):
        return self._timed("test", self._converged, snes, it, norms)

    def _converged(self, snes, it, norms):
        xnorm, snorm, fnorm = norms
        if not np.isfinite(fnorm):
            return PETSc.SNES.ConvergedReason.DIVERGED_FNORM_NAN
        contributors = self.problem.contributors
        o = self.options
        if it > 0 and it == self._last_it:
            # the trust region re-tests the same iterate after a rejected step (newtontr calls
            # the test again with the iteration number and residual unchanged): not a new
            # iterate, so no new entry in the history and no cycle (the repeats would look like
            # one), and the contributors keep the verdict they gave for this iterate
            stable = self._last_stable
            period = 0
        else:
            if it == 0:
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
            return (f"Newton stagnates: the residual stays at {fnorm:.3e} (initial "
                    f"{self._f0:.3e}, converged below {target:.3e}) with the same contact "
                    f"state at every iteration: the tolerance is below the accuracy the "
                    f"residual can be computed to (raise atol, or rtol)")
        hints = [c.cycle_hint(period) if inspect.signature(c.cycle_hint).parameters
                 else c.cycle_hint() for c in contributors if hasattr(c, "cycle_hint")]
        return (f"Newton iterates cycle with period {period} (the same contact state and "
                f"residual {fnorm:.3e} every {period} iterations, twice over): "
                + ("; ".join(hints) if hints else "reduce dt"))

    #: periods looked for by the cycle detection, and the residual match that defines a repeat
    CYCLE_PERIODS = (2, 3, 4)
    CYCLE_RTOL = 1e-6

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
                from fxcontact.prediction import ActiveSetPrediction
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
        for key, val in _globalization_options(kind).items():
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
        calls0 = dict(self.callback_calls)
        lin0 = self.linear_time
        self._linear_start = None
        t0 = time.perf_counter()
        cpc = self._condensed_pc
        inner0 = cpc.inner_iterations if cpc is not None else 0
        cond0 = cpc.times["condense"] if cpc is not None else 0.0
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
        else:
            lin_its = self.snes.getLinearSolveIterations()
        if not converged:
            # a failed attempt must not poison the next one (factorisation, locked vectors)
            self.reset()
        # linear solve: from the end of each Jacobian callback to the line search's pre-check
        # (or the end of the SNES after a failed linear solve): KSPSetOperators, the PC set-up
        # (MUMPS factorisation; condensation and inner set-up), the Krylov iterations or
        # triangular solves. (Not the PETSc KSPSolve/PCSetUp log events: a nested solve under
        # a python PC is counted in both, and an error raised inside an event leaves it open,
        # so that it is never timed again.) "other": the SNES's vector updates and norms, the
        # callbacks' Python glue (iterate copy, ghost update, convergence test) and, in
        # parallel, the waits in their collectives.
        lin = self.linear_time - lin0
        times = {"assembly": prob.timers.get("assembly"), "contact": prob.timers.get("contact"),
                 "linear_solve": lin}
        times["other"] = max(wall - sum(times.values()), 0.0)
        times["total"] = wall
        if cpc is not None:  # part of linear_solve: forming the condensed system
            times["condensation"] = cond
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
                         evaluations=evals, null_pivots=pivots)

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


def _globalization_options(kind: str) -> Dict[str, str]:
    """SNES options (without prefix) of a :data:`LINE_SEARCHES` entry."""
    if kind == "trust-region":
        return {"snes_type": "newtontr"}
    return {"snes_type": "newtonls", "snes_linesearch_type": kind}


def _reason_name(reason: int, kind=PETSc.SNES.ConvergedReason) -> str:
    for k, v in kind.__dict__.items():
        if isinstance(v, int) and v == reason and not k.startswith("_"):
            return k
    return str(reason)
