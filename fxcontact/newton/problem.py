"""All PETSc insertion of fxcontact: UFL residual/Jacobian assembly plus nodal terms, for SNES.

Order of operations (dolfinx 0.5.2; see docs/architecture.md, platform notes):

* residual: assemble the UFL vector, apply lifting, reverse ghost update, **then** add the nodal
  residual entries to owned rows, **then** ``set_bc``;
* Jacobian: ``zeroEntries``, add the nodal blocks with one ``setValuesLocalRCV`` (never with zero
  rows: that kills the process), **then** ``assemble_matrix`` (which ends by *inserting* the BC
  diagonal), then the final ``assemble()``.

Nodal terms never touch Dirichlet rows/columns in the matrix (they are masked to −1, which PETSc
ignores) and only owned rows, so each vertex is counted once under MPI.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field
from typing import Dict, List, Optional, Sequence

import dolfinx.fem
import dolfinx.fem.petsc
import numpy as np
import ufl
from mpi4py import MPI
from petsc4py import PETSc

from fxcontact import compat
from fxcontact.collective import together
from fxcontact.la import add_nodal_jacobian, add_nodal_residual, rigid_body_modes

__all__ = ["NodalTerms", "NodalNonlinearProblem", "NonlinearProblem", "ContactProblem", "Timers",
           "add_nodal_residual", "add_nodal_jacobian", "ContributorError", "lifting_needed",
           "LINEAR_SOLVERS"]

log = logging.getLogger(__name__)


class ContributorError(RuntimeError):
    """A nodal contributor refused the current iterate (e.g. a node deep inside a tool)."""


@dataclass
class NodalTerms:
    """Per-node residual entries and Jacobian blocks on velocity dofs.

    Attributes:
        dofs: (N, bs) local dof indices in W (owned rows only); −1 entries are skipped.
        residual: (N, bs) entries added to the residual.
        jacobian: (N, bs, bs) blocks added to the Jacobian, or None.
    """

    dofs: np.ndarray
    residual: np.ndarray
    jacobian: Optional[np.ndarray] = None

    @staticmethod
    def empty(bs: int) -> "NodalTerms":
        return NodalTerms(np.zeros((0, bs), np.int32), np.zeros((0, bs)), np.zeros((0, bs, bs)))


@dataclass
class Timers:
    """Accumulated wall times of named phases (seconds)."""

    times: Dict[str, float] = field(default_factory=dict)

    def add(self, name: str, dt: float):
        self.times[name] = self.times.get(name, 0.0) + dt

    def get(self, name: str) -> float:
        return self.times.get(name, 0.0)

    def reset(self):
        self.times.clear()

    class _Ctx:
        def __init__(self, timers, names):
            self.timers, self.names = timers, names

        def __enter__(self):
            self.t0 = time.perf_counter()

        def __exit__(self, *exc):
            dt = time.perf_counter() - self.t0
            for name in self.names:
                self.timers.add(name, dt)

    def __call__(self, *names: str):
        """Context manager adding its wall time to every one of ``names`` (e.g. a phase and
        its sub-phase)."""
        return Timers._Ctx(self, names)


def lifting_needed(bcs, x0: PETSc.Vec, work: PETSc.Vec, bc_owned: np.ndarray, comm) -> bool:
    """False if ``x0`` equals the prescribed value at every owned Dirichlet dof of every rank,
    bitwise (collective): the lifting ``A (g − x0)`` of the residual is then exactly zero.

    ``work`` is a scratch vector of the layout of ``x0``; ``bc_owned`` the owned Dirichlet dofs
    (local indices). A NaN in ``x0`` counts as a difference."""
    diff = dirichlet_offset(bcs, x0, work, bc_owned)
    return bool(comm.allreduce(bool(np.any(diff != 0.0)), op=MPI.LOR))


def dirichlet_offset(bcs, x0: PETSc.Vec, work: PETSc.Vec, bc_owned: np.ndarray) -> np.ndarray:
    """``g − x0`` at the owned Dirichlet dofs ``bc_owned`` (local indices), computed in the
    scratch vector ``work`` (the layout of ``x0``) by dolfinx's ``set_bc``."""
    with work.localForm() as wl:
        wl.set(0.0)
    dolfinx.fem.petsc.set_bc(work, bcs, x0, 1.0)       # work[bc] = g − x0
    return work.getArray(readonly=True)[bc_owned]


def assemble_residual_with_terms(b: PETSc.Vec, L, a, bcs, x0: PETSc.Vec, terms, timers,
                                 constraints=(), w=None, lift: bool = True):
    """The residual sequence (PLATFORM order): UFL vector, lifting, reverse ghost update, THEN
    the nodal entries of ``terms`` (None: a contributor refused the iterate → NaN residual),
    THEN ``set_bc``; ``constraints`` (symmetry planes) record the residual before the BCs and
    project it after them. ``lift=False`` skips the lifting (only when it is exactly zero:
    :func:`lifting_needed`)."""
    with timers("assembly", "assembly_residual"):
        with b.localForm() as bl:
            bl.set(0.0)
        dolfinx.fem.petsc.assemble_vector(b, L)
        if lift:
            # x0 must have current ghost values: use the (scattered) solution vector
            dolfinx.fem.petsc.apply_lifting(b, [a], bcs=[bcs], x0=[x0], scale=-1.0)
        b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
    if terms is None:  # a contributor refused this iterate: poison the residual
        b.set(np.nan)
        return
    with timers("contact"):
        for t in terms:
            add_nodal_residual(b, t)
    with timers("assembly", "assembly_residual"):
        for c in constraints:
            c.record_residual(b)
        dolfinx.fem.petsc.set_bc(b, bcs, x0, -1.0)
        for c in constraints:
            c.apply_residual(b, w)


def assemble_jacobian_with_terms(A: PETSc.Mat, a, bcs, terms, bc_marker, timers,
                                 constraints=(), element=None):
    """The Jacobian sequence (PLATFORM order): ``zeroEntries``, the nodal blocks, THEN the UFL
    matrix (which inserts the BC diagonal), THEN the final ``assemble()``; ``constraints``
    project the assembled matrix. ``element``: a
    :class:`~fxcontact.element.jacobian.CondensedJacobian`, which assembles the condensed
    system in its own matrix instead (``A`` is not used)."""
    if element is not None:
        element.assemble(terms, timers)
        return
    A.zeroEntries()
    if terms:
        with timers("contact"):
            for t in terms:
                add_nodal_jacobian(A, t, bc_marker)
    with timers("assembly", "assembly_jacobian"):
        dolfinx.fem.petsc.assemble_matrix(A, a, bcs=bcs)
        A.assemble()
        for c in constraints:
            c.apply_jacobian(A)


class NodalNonlinearProblem:
    """Residual/Jacobian callbacks for SNES: a UFL problem plus nodal contributors.

    (Named apart from dolfinx's ``NonlinearProblem``; ``NonlinearProblem`` stays an alias.)

    Args:
        F: UFL residual form in ``w``.
        w: the unknown Function (mixed space).
        bcs: Dirichlet conditions.
        J: UFL Jacobian (default: Gâteaux derivative of F).
        contributors: objects with ``evaluate(w, jacobian: bool) -> NodalTerms`` called with the
            current iterate (after the ghost update) before every residual/Jacobian assembly.
        jit_params: passed to the form compiler.
        constraints: linear constraints that project the Newton system after the assembly
            (:class:`~fxcontact.symmetry.SymmetryPlanes`: ``setup(bc_marker)``,
            ``record_residual(b)`` before and ``apply_residual(b, w)`` after ``set_bc``,
            ``apply_jacobian(A)`` after the final assembly).
        schur_weight: optional UFL linear form in the pressure test function, e.g.
            ``(1/η(v)) q dx``: its pressure rows are the lumped, inverse-viscosity-weighted
            pressure mass that the condensed iterative solver uses to precondition the Schur
            complement (:mod:`fxcontact.element.assembled`); None: not available.
        augment: optional UFL bilinear form on the velocity, e.g. ``(2/3) η div(δv) div(w) dx``,
            added (with the Dirichlet rows and columns removed and projected like the
            Jacobian) to the velocity block of the condensed iterative solver's
            *preconditioning* matrix only: the Norton–Hoff tangent acts on the deviator of the
            strain rate, so its velocity block alone is singular for a dilatation that the
            velocity conditions leave free (the pressure fixes it in the whole system), and a
            Schur field split needs an invertible velocity block. None: no augmentation.
    """

    #: skip the lifting of the residual when it is exactly zero (the iterate holds the
    #: Dirichlet values bitwise): the lifting runs the Jacobian kernel on every cell with a
    #: Dirichlet dof, ~3× the cost of the residual vector itself on the wire drawing
    #: (``benchmarks/bench_assembly.py``); False: always lift (dolfinx's sequence)
    skip_zero_lifting: bool = True

    def __init__(self, F, w, bcs=(), J=None, contributors: Sequence = (), jit_params=None,
                 constraints: Sequence = (), schur_weight=None, augment=None):
        self.w = w
        self.bcs = list(bcs)
        if J is None:
            J = ufl.derivative(F, w, ufl.TrialFunction(w.function_space))
        self.L = compat.form(F, jit_params=jit_params)
        self.a = compat.form(J, jit_params=jit_params)
        self.schur_weight = (None if schur_weight is None
                             else compat.form(schur_weight, jit_params=jit_params))
        self._augment_ufl, self._augment, self._jit_params = augment, None, jit_params
        self.contributors = list(contributors)
        self.timers = Timers()
        self.comm = w.function_space.mesh.comm
        V = w.function_space
        n_local = V.dofmap.index_map.size_local + V.dofmap.index_map.num_ghosts
        self.bc_marker = np.zeros(n_local * V.dofmap.index_map_bs, dtype=bool)
        for bc in self.bcs:
            self.bc_marker[bc.dof_indices()[0]] = True
        self.constraints = list(constraints)
        for c in self.constraints:
            c.setup(self.bc_marker)
        self.error: Optional[str] = None
        self._cache_terms: Optional[List[NodalTerms]] = None
        nown = V.dofmap.index_map.size_local * V.dofmap.index_map_bs
        self._bc_owned = np.flatnonzero(self.bc_marker[:nown]).astype(np.int32)
        self._lift_work: Optional[PETSc.Vec] = None
        #: residual evaluations that skipped / did the lifting (see skip_zero_lifting)
        self.liftings = {"skipped": 0, "done": 0}
        #: objects told of each Newton solve's start, ``begin(x)`` (the initial guess), and
        #: of each accepted iterate, ``accept(x)``, by :class:`~fxcontact.newton.solver.NewtonSolver`
        #: (e.g. :class:`~fxcontact.element.dual.DualStress`)
        self.iterate_hooks: list = []
        #: optional callable ``(layout) -> element-tensor source`` of this problem's Jacobian
        #: faster than its FFCx kernel (:class:`~fxcontact.element.jacobian.CondensedJacobian`;
        #: e.g. the hand-written Norton–Hoff kernel), or None
        self.element_tensors = None

    @property
    def augment(self):
        """The compiled ``augment`` form (compiled on first use), or None."""
        if self._augment is None and self._augment_ufl is not None:
            self._augment = compat.form(self._augment_ufl, jit_params=self._jit_params)
        return self._augment

    def create_vector(self) -> PETSc.Vec:
        return dolfinx.fem.petsc.create_vector(self.L)

    def create_matrix(self) -> PETSc.Mat:
        return dolfinx.fem.petsc.create_matrix(self.a)

    # ------------------------------------------------------------------------------------
    def _update(self, x: PETSc.Vec):
        # x may be a line-search work vector: copy into the solution function first.
        if x.handle != self.w.vector.handle:
            x.copy(self.w.vector)
        self.w.x.scatter_forward()

    def _evaluate_contributors(self, jacobian: bool) -> Optional[List[NodalTerms]]:
        """Evaluate every contributor; errors are made collective (never a hang under MPI)."""
        terms, msg = [], None
        with self.timers("contact"):
            try:
                for c in self.contributors:
                    terms.append(c.evaluate(self.w, jacobian))
            except ContributorError as e:
                msg = str(e)
        msgs = self.comm.allgather(msg)
        bad = [m for m in msgs if m is not None]
        if bad:
            self.error = bad[0]
            return None
        return terms

    def _lift(self) -> bool:
        """Whether the residual needs its lifting ``A (g − x0)`` at the current iterate
        (collective): not when :attr:`skip_zero_lifting` and the iterate holds the prescribed
        values exactly, which every Newton iterate does once the first one does (the
        Dirichlet rows of the step are ``x0 − g = 0``)."""
        if not (self.skip_zero_lifting and self.bcs):
            return bool(self.bcs)
        with self.timers("assembly", "assembly_residual"):
            need = lifting_needed(self.bcs, self.w.vector, self._bc_work(), self._bc_owned,
                                  self.comm)
        self.liftings["done" if need else "skipped"] += 1
        return need

    def _bc_work(self) -> PETSc.Vec:
        """Scratch vector of the Dirichlet checks (created once)."""
        if self._lift_work is None:
            self._lift_work = self.w.vector.duplicate()
        return self._lift_work

    def exact_dirichlet_step(self, x: PETSc.Vec, y: PETSc.Vec) -> bool:
        """Set the Newton step ``y`` to ``x − g`` at the owned Dirichlet dofs, bitwise (what the
        identity rows of the Jacobian give; collective). A direct solve already gives exactly
        that; an iterative one only to its tolerance, which would leave every later iterate
        off the prescribed values by round-off: their residuals would all need the lifting
        (``skip_zero_lifting``), about twice the residual's cost. Returns whether ``y``
        changed on some rank."""
        if not self.bcs:
            return False
        exact = -dirichlet_offset(self.bcs, x, self._bc_work(), self._bc_owned)   # x − g
        ya = y.getArray(readonly=False)
        changed = bool(np.any(ya[self._bc_owned] != exact))
        if changed:
            ya[self._bc_owned] = exact
        del ya
        return bool(self.comm.allreduce(changed, op=MPI.LOR))

    def residual(self, snes, x: PETSc.Vec, b: PETSc.Vec):
        """SNES residual callback."""
        self._update(x)
        terms = self._evaluate_contributors(jacobian=False) if self.contributors else []
        assemble_residual_with_terms(b, self.L, self.a, self.bcs, self.w.vector, terms,
                                     self.timers, self.constraints, self.w, lift=self._lift())

    def jacobian(self, snes, x: PETSc.Vec, A: PETSc.Mat, P: PETSc.Mat, element=None):
        """SNES Jacobian callback; ``element``: a
        :class:`~fxcontact.element.jacobian.CondensedJacobian` of this problem, which assembles
        the condensed system instead of the MINI matrix."""
        self._update(x)
        terms = self._evaluate_contributors(jacobian=True) if self.contributors else []
        assemble_jacobian_with_terms(A, self.a, self.bcs, terms, self.bc_marker, self.timers,
                                     self.constraints, element)
        if terms is None:
            raise ContributorError(self.error)

    def assemble_residual(self, b: Optional[PETSc.Vec] = None) -> PETSc.Vec:
        """Residual at the current ``w`` (for diagnostics/tests)."""
        if b is None:
            b = self.create_vector()
        self.residual(None, self.w.vector, b)
        return b

    def assemble_jacobian(self, A: Optional[PETSc.Mat] = None) -> PETSc.Mat:
        if A is None:
            A = self.create_matrix()
        self.jacobian(None, self.w.vector, A, A)
        return A


def mumps_null_pivots(ksp: PETSc.KSP) -> Optional[int]:
    """Number of null pivots MUMPS found in the last factorisation of ``ksp``'s preconditioner
    (INFOG(28), with null-pivot detection ICNTL(24) = 1, the presets' setting), or None when
    the preconditioner holds no MUMPS factorisation. Looks through the python PCs of fxcontact
    (the condensed system's inner KSP, the bordered system's inner PC). Local call (INFOG is
    the same on every rank)."""
    try:
        pc = ksp.getPC()
    except PETSc.Error:
        return None
    return _pc_null_pivots(pc, depth=0)


def _pc_null_pivots(pc: PETSc.PC, depth: int) -> Optional[int]:
    if depth > 4:
        return None
    kind = pc.getType()
    if kind in ("lu", "cholesky"):
        if pc.getFactorSolverType() != "mumps":
            return None
        try:
            F = pc.getFactorMatrix()
            return int(F.getMumpsInfog(28))
        except PETSc.Error:   # not factorised yet
            return None
    if kind == "python":
        ctx = pc.getPythonContext()
        inner = getattr(ctx, "ksp", None)
        if isinstance(inner, PETSc.KSP):
            return _pc_null_pivots(inner.getPC(), depth + 1)
        inner = getattr(ctx, "inner", None)
        if isinstance(inner, PETSc.PC):
            return _pc_null_pivots(inner, depth + 1)
    return None


def owned_sum(comm: MPI.Comm, value) -> float:
    return comm.allreduce(value, op=MPI.SUM)


#: the former name of :class:`NodalNonlinearProblem` (the same class)
NonlinearProblem = NodalNonlinearProblem


#: kinds of :meth:`ContactProblem.use_linear_solver`
LINEAR_SOLVERS = ("auto", "direct", "iterative")


class ContactProblem(dolfinx.fem.petsc.NonlinearProblem):
    """dolfinx's ``NonlinearProblem`` plus fxcontact's nodal terms: contact in your own solver.

    A drop-in replacement of ``dolfinx.fem.petsc.NonlinearProblem(F, u, bcs, J)`` (same
    constructor, plus ``contributors``) for dolfinx's ``NewtonSolver``, with petsc4py SNES
    callbacks too. At every residual/Jacobian evaluation the contributors (e.g. a
    :class:`~fxcontact.contact.nodal.NodalContact` with ``formulation="displacement"`` on the
    space of ``u``) are evaluated at the current iterate — the contact is re-projected at every
    Newton iteration — and their terms are added in the order of this module's docstring.

    Load steps: call :meth:`begin_step` before each solve (the tools are taken at the step's end
    time). The active-set convergence check (THEORY §3.6): Newton may only stop at an iterate
    whose contact state equals that of the previous iterate.

    * dolfinx ``NewtonSolver``: ``problem.set_solver(solver)``; the solver's tolerances are then
      held at 0 (no convergence) at the iterates where the active set changed, and restored at
      the next stable iterate (dolfinx 0.5 has no user convergence test).
    * SNES: ``snes.setFunction(problem.snes_residual, b)``,
      ``snes.setJacobian(problem.snes_jacobian, A)`` and
      ``snes.setConvergenceTest(problem.snes_converged)`` (the SNES tolerances plus the stable
      active set); :meth:`snes_callbacks` returns the three.
    * The linear solver stays the user's: the problem never changes a KSP by itself.
      :meth:`use_linear_solver` is the opt-in set-up for displacement problems (MUMPS, or CG +
      GAMG with the rigid-body near-null space for large ones).

    ``timers``: wall times of the ``assembly`` (UFL residuals and Jacobians), the ``contact``
    (the contributors' evaluations and insertion) and the ``linear_solve`` (from the end of each
    Jacobian to the next residual: the solver's linear solve and update).

    Args:
        F, u, bcs, J, form_compiler_params, jit_params: as dolfinx's ``NonlinearProblem``.
        contributors: nodal contributors (``evaluate(u, jacobian) -> NodalTerms``, ``stable()``,
            optional ``begin_step(t, dt, u)``, ``begin_solve()``, ``end_step(u)``).
    """

    #: unknowns from which ``use_linear_solver(kind="auto")`` picks CG + GAMG (see there)
    ITERATIVE_FROM_DOFS = 30_000

    def __init__(self, F, u, bcs=None, J=None, contributors: Sequence = (),
                 form_compiler_params=None, jit_params=None):
        super().__init__(F, u, bcs=list(bcs or []), J=J,
                         form_compiler_params=dict(form_compiler_params or {}),
                         jit_params=compat.jit_params(jit_params))
        self.u = u
        self.contributors = list(contributors)
        self.comm = u.function_space.mesh.comm
        self.timers = Timers()
        V = u.function_space
        n_local = V.dofmap.index_map.size_local + V.dofmap.index_map.num_ghosts
        self.bc_marker = np.zeros(n_local * V.dofmap.index_map_bs, dtype=bool)
        for bc in self.bcs:
            self.bc_marker[bc.dof_indices()[0]] = True
        self.t = 0.0
        self.error: Optional[str] = None
        self.stable_iterate = False
        self.iterations_unstable = 0
        self._solver = None
        self._tolerances = None
        self._started = False
        self._near_null = None
        self._jacobian_done = None
        self._reuse_ksp = self._ksp = None
        #: factorisations done / reused by the ``"direct"`` linear solver
        self.factorisations = [0, 0]
        #: Krylov iterations summed over the linear solves (after :meth:`use_linear_solver`)
        self.krylov_iterations = 0

    # ------------------------------------------------------------------ load steps
    def begin_step(self, t: Optional[float] = None):
        """Start a load step ending at time ``t`` (default: the previous time + 1, a load-step
        counter for static tools): the contributors take the current ``u`` as the step's
        start and the tools at ``t``. Collective."""
        t_new = self.t + 1.0 if t is None else float(t)
        dt = t_new - self.t
        if not dt > 0:
            raise ValueError(f"begin_step: the time must increase (from {self.t} to {t_new})")
        if self._started:
            self.end_step()
        self.u.x.scatter_forward()
        for c in self.contributors:
            if hasattr(c, "begin_step"):
                c.begin_step(self.t, dt, self.u)
            elif hasattr(c, "begin_solve"):
                c.begin_solve()
        self.t = t_new
        self.stable_iterate = False
        self.error = None
        self._started = True

    def end_step(self):
        """Close the current load step (penetration diagnostics; also done by the next
        :meth:`begin_step`)."""
        for c in self.contributors:
            if hasattr(c, "end_step"):
                c.end_step(self.u)
        self._started = False

    def stable(self) -> bool:
        """Ask every contributor whether its state is unchanged since its previous call
        (collective; once per Newton iteration)."""
        return all([c.stable() for c in self.contributors])

    # ------------------------------------------------------------------ shared assembly
    def _sync(self, x: PETSc.Vec):
        if x.handle != self.u.vector.handle:  # a line-search work vector (SNES)
            x.copy(self.u.vector)
        self.u.x.scatter_forward()

    def _evaluate(self, jacobian: bool) -> Optional[List[NodalTerms]]:
        if not self._started and self.contributors:
            raise RuntimeError("ContactProblem: call begin_step() before solving (it starts the "
                               "load step of the contact)")
        terms, msg = [], None
        with self.timers("contact"):
            try:
                for c in self.contributors:
                    terms.append(c.evaluate(self.u, jacobian))
            except ContributorError as e:
                msg = str(e)
        bad = [m for m in self.comm.allgather(msg) if m is not None]
        if bad:
            self.error = bad[0]
            return None
        return terms

    def _residual(self, x: PETSc.Vec, b: PETSc.Vec):
        if self._jacobian_done is not None:   # the linear solve since the last Jacobian
            self.timers.add("linear_solve", time.perf_counter() - self._jacobian_done)
            self._jacobian_done = None
            if self._ksp is not None:
                self.krylov_iterations += self._ksp.getIterationNumber()
        self._sync(x)
        terms = self._evaluate(jacobian=False)
        assemble_residual_with_terms(b, self.L, self.a, self.bcs, self.u.vector, terms,
                                     self.timers)

    def _jacobian(self, x: PETSc.Vec, A: PETSc.Mat):
        self._sync(x)
        terms = self._evaluate(jacobian=True)
        assemble_jacobian_with_terms(A, self.a, self.bcs, terms, self.bc_marker, self.timers)
        if self._near_null is not None:
            A.setNearNullSpace(self._near_null)
        if self._reuse_ksp is not None:
            self._reuse_factorisation(self._reuse_ksp)
        if terms is None:
            raise ContributorError(self.error)
        self._jacobian_done = time.perf_counter()

    # ------------------------------------------------------------------ linear solver (opt-in)
    #: Krylov iterations of a solve preconditioned by an older factorisation above which the
    #: next Jacobian is factorised again (``use_linear_solver(kind="direct")``)
    REUSE_MAX_ITS = 10

    def _reuse_factorisation(self, ksp: PETSc.KSP):
        """Keep the last factorisation as the preconditioner of this Jacobian if the contact's
        active set did not change at this iterate and the last Krylov solve needed few
        iterations (the same decision on every rank; never under ``preonly``)."""
        reuse = (self.factorisations[0] > 0 and self.stable_iterate and
                 ksp.getType() != PETSc.KSP.Type.PREONLY and ksp.getConvergedReason() > 0 and
                 ksp.getIterationNumber() <= self.REUSE_MAX_ITS)
        ksp.getPC().setReusePreconditioner(reuse)
        self.factorisations[1 if reuse else 0] += 1

    def use_linear_solver(self, solver, kind: str = "auto", rtol: float = 1e-8):
        """Set up the linear solver of ``solver`` for this displacement problem (opt-in: the
        problem never changes a KSP by itself). Collective.

        Args:
            solver: a dolfinx ``NewtonSolver`` (its ``krylov_solver``), a petsc4py ``SNES`` (its
                KSP) or a ``KSP``.
            kind: ``"direct"`` (MUMPS LU; the factorisation of the previous Newton iteration is
                kept as the preconditioner of GMRES while the contact's active set is unchanged
                and GMRES needs at most :attr:`REUSE_MAX_ITS` iterations), ``"iterative"`` (CG
                + GAMG with the rigid-body modes of ``u``'s space as near-null space, relative
                tolerance ``rtol``; needs ``u`` in a vector P1 space
                ``VectorFunctionSpace(msh, ("Lagrange", 1))``) or
                ``"auto"``: iterative from :attr:`ITERATIVE_FROM_DOFS` unknowns on a vector P1
                space, direct otherwise.
            rtol: relative tolerance of the iterative solve (the Newton step's accuracy).

        The settings are written into PETSc's options database under the KSP's prefix (they
        replace what was there, e.g. dolfinx's ``nls_solve_ksp_type preonly``) and applied with
        ``ksp.setFromOptions()``: to change one, set it after the call and call
        ``ksp.setFromOptions()`` again. With dolfinx's
        ``NewtonSolver`` (which does not check the Krylov solve) a Krylov solve that does not
        converge is an error. Returns the kind chosen.

        Measured (``benchmarks/README.md``, ``bench_anyfem_hertz.py``): on the Hertz sphere in
        P1 elasticity CG + GAMG takes the Newton iterations of MUMPS with 25–65 Krylov
        iterations, and its cost grows linearly with the unknowns where MUMPS's factorisation
        (at every Newton iteration: the contact changes the matrix) grows about as their
        square. Its Chebyshev smoothers estimate their own spectrum (with a random vector): the
        penalty's nodal blocks lie outside the estimate GAMG passes on, which made the
        preconditioner indefinite.
        """
        V = self.u.function_space
        bs = V.dofmap.index_map_bs
        size = V.dofmap.index_map.size_global * bs
        vector_p1 = (V.ufl_element().family() in ("Lagrange", "P", "Q") and
                     V.ufl_element().degree() == 1 and bs == V.mesh.geometry.dim and
                     V.num_sub_spaces == bs)
        with together(self.comm, "ContactProblem.use_linear_solver()", kind=kind, rtol=rtol):
            if kind not in LINEAR_SOLVERS:
                raise ValueError(f"use_linear_solver: unknown kind {kind!r}; choose one of "
                                 f"{LINEAR_SOLVERS}")
            if not (np.isfinite(rtol) and 0 < rtol < 1):
                raise ValueError(f"use_linear_solver: rtol must be in (0, 1), got {rtol!r}")
            if kind == "iterative" and not vector_p1:
                raise ValueError("use_linear_solver: kind='iterative' (GAMG with rigid-body "
                                 "modes) needs u in a vector P1 space VectorFunctionSpace(msh, "
                                 "('Lagrange', 1)); use kind='direct' for this space")
            if isinstance(solver, PETSc.KSP):
                ksp = solver
            elif isinstance(solver, PETSc.SNES):
                ksp = solver.getKSP()
            elif isinstance(getattr(solver, "krylov_solver", None), PETSc.KSP):
                ksp = solver.krylov_solver
            else:
                raise ValueError(f"use_linear_solver: solver must be a dolfinx NewtonSolver, a "
                                 f"petsc4py SNES or KSP, got {type(solver).__name__}")
        if kind == "auto":
            kind = "iterative" if vector_p1 and size >= self.ITERATIVE_FROM_DOFS else "direct"
        self._near_null = self._reuse_ksp = None
        self._ksp = ksp
        if kind == "direct":
            defaults = {"ksp_type": "gmres", "ksp_rtol": 1e-10, "ksp_max_it": 50,
                        "pc_type": "lu", "pc_factor_mat_solver_type": "mumps"}
            self._reuse_ksp = ksp
        else:
            defaults = {"ksp_type": "cg", "ksp_rtol": rtol, "ksp_max_it": 1000,
                        "pc_type": "gamg", "pc_gamg_use_sa_esteig": False,
                        "mg_levels_ksp_chebyshev_esteig_noisy": True}
            x = V.tabulate_dof_coordinates()[:V.dofmap.index_map.size_local, :bs]
            self._near_null = rigid_body_modes(self.comm, np.ascontiguousarray(x))
        ksp.setErrorIfNotConverged(kind == "iterative" and
                                   not isinstance(solver, (PETSc.KSP, PETSc.SNES)))
        opts, prefix = PETSc.Options(), ksp.getOptionsPrefix() or ""
        for key, value in defaults.items():
            opts[prefix + key] = value
        ksp.setFromOptions()
        return kind

    # ------------------------------------------------------------------ dolfinx NewtonSolver
    def set_solver(self, solver):
        """Let the active-set check act on a dolfinx ``NewtonSolver`` built on this problem."""
        self._solver = solver
        self._tolerances = None

    def F(self, x: PETSc.Vec, b: PETSc.Vec):
        """Residual for dolfinx's ``NewtonSolver`` (called once per Newton iteration, just
        before its convergence test): UFL residual plus the nodal terms at the iterate."""
        self._residual(x, b)
        self.stable_iterate = self.stable() if self.contributors else True
        s = self._solver
        if s is None:
            return
        if not self.stable_iterate:
            self.iterations_unstable += 1
            if self._tolerances is None:
                self._tolerances = (s.atol, s.rtol)
            s.atol, s.rtol = 0.0, 0.0      # the test of this iterate cannot pass
        elif self._tolerances is not None:
            s.atol, s.rtol = self._tolerances
            self._tolerances = None

    def J(self, x: PETSc.Vec, A: PETSc.Mat):
        """Jacobian for dolfinx's ``NewtonSolver``: nodal blocks, then the UFL assembly."""
        self._jacobian(x, A)

    def restore_tolerances(self):
        """Give the solver back its tolerances (if a solve ended while they were held)."""
        if self._solver is not None and self._tolerances is not None:
            self._solver.atol, self._solver.rtol = self._tolerances
            self._tolerances = None

    # ------------------------------------------------------------------ petsc4py SNES
    def snes_residual(self, snes, x: PETSc.Vec, b: PETSc.Vec):
        """SNES residual callback."""
        self._residual(x, b)

    def snes_jacobian(self, snes, x: PETSc.Vec, A: PETSc.Mat, P: PETSc.Mat):
        """SNES Jacobian callback."""
        self._jacobian(x, A)

    def snes_converged(self, snes, it: int, norms):
        """SNES convergence test: the SNES tolerances (``snes.getTolerances()``: rtol on the
        residual, atol, stol on the step, max_it) and a stable contact state."""
        xnorm, snorm, fnorm = norms
        rtol, atol, stol, max_it = snes.getTolerances()
        if not np.isfinite(fnorm):
            return PETSc.SNES.ConvergedReason.DIVERGED_FNORM_NAN
        if it == 0:
            self._f0 = fnorm
        stable = self.stable() if self.contributors else True
        self.stable_iterate = stable
        if stable:
            if fnorm <= atol:
                return PETSc.SNES.ConvergedReason.CONVERGED_FNORM_ABS
            if it > 0 and fnorm <= rtol * self._f0:
                return PETSc.SNES.ConvergedReason.CONVERGED_FNORM_RELATIVE
            if it > 0 and snorm <= stol * max(xnorm, 1e-300):
                return PETSc.SNES.ConvergedReason.CONVERGED_SNORM_RELATIVE
        else:
            self.iterations_unstable += 1
        if it >= max_it:
            return PETSc.SNES.ConvergedReason.DIVERGED_MAX_IT
        return PETSc.SNES.ConvergedReason.ITERATING

    def snes_callbacks(self):
        """(residual, jacobian, convergence test) for ``snes.setFunction``,
        ``snes.setJacobian`` and ``snes.setConvergenceTest``."""
        return self.snes_residual, self.snes_jacobian, self.snes_converged
