"""The increment loop: updated-Lagrangian (or small-strain) time stepping with cut-back.

One increment ``t → t + dt`` (THEORY §1.5): boundary values and tools are taken at ``t + dt``,
contributors prepare (explicit projections…), Newton starts from the previous increment's velocity
(predictor), and on success the geometry (or the displacement), the cumulative equivalent strain,
the history and the outputs are updated. A failed Newton solve is retried with ``dt`` halved, at
most ``max_cutbacks`` times, then :class:`IncrementError` names the time; everything written so far
stays on disk. A converged increment whose geometry update would invert a cell is treated as a
failed one (:class:`MeshInversionError` if it persists); the mesh quality is a history column.
Checkpoints (every n increments and at a failed increment) let a killed run be resumed
(:meth:`Simulation.resume`, :mod:`fxcontact.checkpoint`).

:class:`Simulation` keeps the set-up (conditions, contributors, forms), one increment (``step``:
predictor, Newton, commit) and ``run``; it composes one object per other concern, each in its
own module: :class:`~fxcontact.newton.retry.RetryLadder` (fall-backs and cut-backs),
:class:`~fxcontact.io.outputs.Outputs` (CSV history, VTK series),
:class:`~fxcontact.mesh_health.MeshHealth` (initial mesh, quality, inversion) and
:class:`~fxcontact.checkpoint.Checkpoints`. The contracts of contributors and controllers are the
protocols of :mod:`fxcontact.protocols`.
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass
from typing import Callable, Dict, List, Optional

import dolfinx
import dolfinx.fem
import dolfinx.fem.petsc
import numpy as np
import ufl
from mpi4py import MPI
from petsc4py import PETSc
from tqdm import tqdm

from fxcontact import compat, console
from fxcontact.checkpoint import Checkpoints
from fxcontact.collective import check_together, digest, digest_parameters, together
from fxcontact.element.dual import DualStress
from fxcontact.element.tensors import NortonHoffElementTensors
from fxcontact.io.outputs import (OutputError, Outputs, format_iteration_split, format_wall_split,
                                  output_dir_problem, wall_split)
from fxcontact.kinematics import CartesianUpdate
from fxcontact.la import add_nodal_residual
from fxcontact.materials import Material
from fxcontact.materials.local import Viscoplastic
from fxcontact.materials.forms import (equivalent_strain_rate_ufl, primal_dual_jacobian,
                                       shear_viscosity_ufl, standard_norton_hoff, uses_dual_stress,
                                       volumetric_augment_ufl)
from fxcontact.mesh_health import MeshHealth
from fxcontact.newton.problem import ContributorError, NodalNonlinearProblem
from fxcontact.newton.retry import IncrementError, MeshInversionError, RetryLadder
from fxcontact.newton.solver import ContactNewtonSolver, SolveInfo, SolverOptions
from fxcontact.protocols import (BeginsIncrement, CommitsIncrement, Contributor, EndsIncrement,
                                 HasDiagnostics, HasSummary, SolvesIncrement)
from fxcontact.registration import (VelocityCondition as _BC, bc_label as _bc_label,
                                    check_added_once as _check_added_once,
                                    column_labels as _column_labels, label as _label,
                                    merge_columns as _merge_columns, time_value as _time_value)
from fxcontact.remesh.criteria import RemeshCriteria
from fxcontact.remesh.remeshing import Remeshing, remesh_simulation
from fxcontact.remesh.selection import FacetSelection, remembered
from fxcontact.spaces import (MixedSpace, checked_facets, facets_with_tags, set_function_value,
                              velocity_bc)
from fxcontact.symmetry import SymmetryPlanes, unit_normal

__all__ = ["Simulation", "IncrementError", "MeshInversionError", "OutputError", "IncrementResult",
           "VOLUME_CORRECTIONS", "wall_split", "format_wall_split",
           "format_iteration_split"]

#: incompressibility corrections of the accumulated volume error (``Simulation``)
VOLUME_CORRECTIONS = ("global", "none")

log = logging.getLogger(__name__)


@dataclass
class IncrementResult:
    """Outcome of one accepted increment (also one row of the history)."""

    row: Dict[str, float]
    info: SolveInfo


class Simulation:
    """Time stepping of a forming problem with nodal contributors (contact, springs…).

    Args:
        space: the :class:`MixedSpace`.
        material: a :class:`~fxcontact.materials.Material`.
        solver_options: Newton settings.
        kinematics: configuration update (Cartesian by default; cylindrical for rings).
        extra_residual: optional ``f(v, p, w, q) -> ufl.Form`` added to the residual
            (tractions, body forces).
        output_dir: where the VTK series, the CSV history and pictures go (None: no files).
        name: basename of the outputs.
        output_every: write the VTK series every n increments.
        progress: show a tqdm progress bar (rank 0 only), unless the console was set up quiet
            (:func:`fxcontact.console.configure_logging`).
        checkpoint_every: write a checkpoint every n accepted increments (and when an increment
            fails for good) into ``output_dir/checkpoints/`` (0: never); see :meth:`resume`.
        checkpoint_keep: how many of the newest checkpoints are kept.
        check_inversion: reject an increment whose geometry update would invert an element
            (updated Lagrangian): it is cut back like a failed Newton solve and, if it persists,
            stops with a :class:`MeshInversionError` naming the cell, the time and the increment.
        volume_correction: updated-Lagrangian runs only (ignored for small-strain materials).
            The geometry update ``x += dt v`` of an incompressible flow changes the volume at
            second order in dt (``det(I + dt ∇v) = 1 + O(dt²)``), and the error accumulates
            over the increments. With ``"global"`` (default) the incompressibility equation is
            written ``div v + ln(V / V⁰) / dt = 0`` with the current and initial volumes of the
            body: the volume lost or gained so far is given back in the next increment, so the
            error stays at one increment's O(dt²) and no longer accumulates (THEORY §1.5).
            ``"none"``: the plain ``div v = 0``. History columns: ``volume_change``
            (``V/V⁰ − 1``) and ``volume_restore_rate`` (``−V ln(V/V⁰)/dt``, which ``div_v``,
            the integral of ``div v``, equals to the solver tolerance).
        overwrite: a new run (not :meth:`resume`-d) in an ``output_dir`` that holds checkpoints
            of a run of the same ``name`` stops with a :class:`~fxcontact.checkpoint.
            CheckpointError` before writing anything (its outputs would mix with that run's);
            ``overwrite=True`` removes those checkpoints (with a warning) and starts afresh.
    """

    def __init__(self, space: MixedSpace, material: Material,
                 solver_options: Optional[SolverOptions] = None, kinematics=None,
                 extra_residual: Optional[Callable] = None, output_dir: Optional[str] = None,
                 name: str = "result", output_every: int = 1, progress: bool = True,
                 checkpoint_every: int = 0, checkpoint_keep: int = 2,
                 check_inversion: bool = True, volume_correction: str = "global",
                 overwrite: bool = False):
        # the same checks on every rank, raised on every rank (fxcontact.collective)
        with together(getattr(getattr(space, "mesh", None), "comm", MPI.COMM_WORLD),
                      "Simulation()", name=name, output_dir=output_dir):
            if not isinstance(material, Material):
                raise ValueError(f"material must be a fxcontact material, got {material!r}")
            if output_every < 1:
                raise ValueError("output_every must be >= 1")
            if not (isinstance(checkpoint_every, (int, np.integer)) and checkpoint_every >= 0):
                raise ValueError(f"checkpoint_every must be an integer >= 0, got "
                                 f"{checkpoint_every!r}")
            if checkpoint_every and output_dir is None:
                raise ValueError("checkpoint_every needs an output_dir (checkpoints are written to "
                                 "output_dir/checkpoints)")
            if not (isinstance(checkpoint_keep, (int, np.integer)) and checkpoint_keep >= 1):
                raise ValueError(f"checkpoint_keep must be an integer >= 1, got "
                                 f"{checkpoint_keep!r}")
            if volume_correction not in VOLUME_CORRECTIONS:
                raise ValueError(f"unknown volume_correction {volume_correction!r}; choose one of "
                                 f"{VOLUME_CORRECTIONS}")
            problem = output_dir_problem(output_dir)
            if problem:
                raise ValueError(f"output_dir {output_dir!r} {problem}: give a directory path")
        #: the Viscoplastic material given (its flow stress depends on the state), or None;
        #: ``material`` is then its Norton–Hoff law on the current mesh
        self.law = material if isinstance(material, Viscoplastic) else None
        #: cell temperatures [°C] (DG0 order) set by a heat controller, or None
        self.cell_temperature = None
        self.material = material
        self.solver_options = solver_options or SolverOptions()
        self.kinematics = kinematics or CartesianUpdate()
        self.extra_residual = extra_residual
        self.output_dir = output_dir
        self.name = name
        self.output_every = int(output_every)
        self.progress = progress
        self.volume_correction = "none" if material.small_strain else volume_correction
        self.t = 0.0
        self.increment = 0
        self.contributors: List = []
        self.history: List[Dict[str, float]] = []
        self.overwrite = bool(overwrite)
        self._labels: Dict[str, str] = {}   # history-column labels -> what they label
        self.checkpoint_every = int(checkpoint_every)
        self.checkpoint_keep = int(checkpoint_keep)
        self.check_inversion = bool(check_inversion)
        self.controllers: List = []
        #: the remeshes so far (:class:`~fxcontact.remesh.remeshing.RemeshRecord`)
        self.remeshes: List = []
        self._remeshing = None
        self._bind_space(space)   # checks the initial mesh (on every rank)
        # the other concerns, one object each
        self._outputs = Outputs(self)
        self._checkpoints = Checkpoints(self)
        self._retry = RetryLadder(self)

    def _bind_space(self, space: MixedSpace):
        """What belongs to the mesh (at the set-up, and again on a remesh): the space, the
        solution and output fields, the (empty) conditions, the mesh health."""
        self.space = space
        self.mesh = space.mesh
        self.comm = space.mesh.comm   # the mesh's own: freed with it
        if self.law is not None:
            self.material = self.law.on(space)
        self._bcs: List[_BC] = []
        self._reactions: Dict[str, np.ndarray] = {}
        self._symmetry = None
        self._plane_bcs: List = []
        self._built = False
        W = space.W
        self.w = dolfinx.fem.Function(W, name="solution")
        self.w_prev = dolfinx.fem.Function(W)
        self.dt_c = dolfinx.fem.Constant(self.mesh, PETSc.ScalarType(1.0))
        small = self.material.small_strain
        self.u = dolfinx.fem.Function(space.V, name="displacement") if small else None
        # output fields
        self.velocity = dolfinx.fem.Function(space.P1, name="velocity")
        self.pressure = dolfinx.fem.Function(space.Q, name="pressure")
        self.strain = dolfinx.fem.Function(space.DG0, name="equivalent_strain")
        self.strain_rate = dolfinx.fem.Function(space.DG0, name="equivalent_strain_rate")
        self.displacement_out = dolfinx.fem.Function(space.P1, name="displacement") \
            if small else None
        self._x_ref = self.mesh.geometry.x.copy()
        self._w2v = None   # W dof -> V dof (small strain), made on first use
        self._mesh_health = MeshHealth(self)

    # ------------------------------------------------------------------------ set-up
    def facets(self, facet_tags, tags) -> FacetSelection:
        """Local indices of the facets carrying any of ``tags`` in this mesh's ``facet_tags``
        (ValueError on every rank for an empty tag list, a missing tag or the facet tags of
        another mesh); they remember their tags, so that a :meth:`remesh` selects them again."""
        return FacetSelection(facets_with_tags(self.mesh, facet_tags, tags,
                                               "Simulation.facets(facet_tags)"), facet_tags, tags)

    @remembered
    def add_velocity_bc(self, facets: np.ndarray, value, component: Optional[int] = None):
        """Prescribe the velocity (or one component) on facets.

        ``value`` is a constant (scalar for a component, gdim-vector otherwise), a function of
        time ``f(t)``, a function of space ``f(x)`` (dolfinx interpolation signature) or of both
        ``f(x, t)``; it is evaluated at the end of each increment (t + dt).
        """
        self._check_not_built()
        v0 = _time_value(value, 0.0)
        bc, g = velocity_bc(self.space, facets, v0, component, what="add_velocity_bc")
        self._bcs.append(_BC(bc, g, value, self.space.gdim if component is None else None,
                             _bc_label(self, len(self._bcs), facets, component)))
        return bc

    @remembered
    def add_reaction(self, name: str, facets: np.ndarray):
        """Record, each increment, the force exerted on the body through the Dirichlet dofs of
        ``facets`` (history columns ``{name}_x``, ``{name}_y``, ``{name}_z``), computed on the
        configuration of the increment (before the geometry update)."""
        facets = checked_facets(self.mesh, facets, "add_reaction(facets)", name=name)
        with together(self.comm, "add_reaction()", name=name):
            self._claim_labels({name: f"reaction '{name}'"})
        self._reactions[name] = facets

    @remembered
    def add_symmetry_plane(self, facets: np.ndarray, normal, name: str = "symmetry"):
        """Symmetry plane through ``facets``: the normal velocity ``v·n`` vanishes there.

        A normal along a coordinate axis gives a velocity condition on that component (as
        :meth:`add_velocity_bc`); any other normal (the 120° plane of a one-third model) is
        imposed exactly by a projection of the Newton system
        (:class:`~fxcontact.symmetry.SymmetryPlanes`, THEORY §1.6), including at vertices on
        two planes (a sector's axis: only the axial velocity stays free) and at vertices that
        also carry velocity conditions. The force the plane exerts on the body is recorded in
        the history columns ``{name}_x``, ``{name}_y``, ``{name}_z``.

        Raises ValueError if the facets do not lie on one plane of normal ``normal``.
        """
        self._check_not_built()
        facets = checked_facets(self.mesh, facets, "add_symmetry_plane(facets)", exterior=True,
                                name=name, normal=digest(np.asarray(normal, dtype=float)))
        n = unit_normal(normal, self.space.gdim)
        axis = np.flatnonzero(np.abs(n) > 1e-12)
        if self._symmetry is None:
            self._symmetry = SymmetryPlanes(self.space)
        with together(self.comm, "add_symmetry_plane()", name=name):
            self._claim_labels({name: f"symmetry plane '{name}'"})
        if len(axis) == 1:  # a coordinate plane: a velocity condition, reaction from here
            self._symmetry.add(name, facets, n, via_bc=True)
            bc = self.add_velocity_bc(facets, 0.0, component=int(axis[0]))
            self._plane_bcs.append(bc)
        else:
            self._symmetry.add(name, facets, n)

    def add_contributor(self, contributor):
        """Register a nodal contributor: a :class:`~fxcontact.protocols.Contributor`
        (``evaluate``, ``stable``) with the optional hooks of :mod:`fxcontact.protocols`
        (``begin_increment``, ``end_increment``, ``diagnostics``, ``output_fields``, …)."""
        self._check_not_built()
        with together(self.comm, "add_contributor()", contributor=digest_parameters(contributor)):
            if not isinstance(contributor, Contributor):
                raise ValueError(f"add_contributor(contributor): {_label(contributor)} is not a "
                                 f"contributor: it needs the methods evaluate(w, jacobian) -> "
                                 f"NodalTerms and stable() -> bool (fxcontact.protocols."
                                 f"Contributor); a controller of the tools goes to "
                                 f"add_controller()")
            _check_added_once(contributor, self.contributors, "contributor")
            self._claim_labels(_column_labels(contributor))
        self.contributors.append(contributor)
        return contributor

    def add_controller(self, controller):
        """Register a controller of the tools (:mod:`fxcontact.idle`): an object with optional
        ``begin_increment(sim, t, dt, x_t)`` (called at the start of each increment, before the
        contributors), ``solve(sim, begin)`` (replaces the increment's Newton solve: it may
        solve several times, calling ``begin()`` to restart the contributors; at most one
        controller may have it), ``end_increment(sim, dt)`` and ``diagnostics()``.

        Checkpoints: a controller that keeps a state between increments (rates it has set, a
        measured centre…) saves it with ``checkpoint_state() -> dict`` (plain numbers, lists,
        dicts, numpy arrays) and gets it back with ``restore_state(dict)``; the kinematics
        (e.g. :class:`~fxcontact.idle.RingAxisUpdate`) may have the same two methods. A
        checkpoint is resumed only with the same controllers (number, types, order)."""
        self._check_not_built()
        with together(self.comm, "add_controller()", controller=digest_parameters(controller)):
            _check_added_once(controller, self.controllers, "controller")
            if isinstance(controller, SolvesIncrement) and any(
                    isinstance(c, SolvesIncrement) for c in self.controllers):
                raise ValueError("only one controller may take over the Newton solve (solve()); "
                                 "several idle tools go to one IdleRotation(contact, [tool1, "
                                 "tool2, ...])")
        self.controllers.append(controller)
        return controller

    def _check_setup_together(self):
        """Before the first increment: what must be the same on every rank (material, solver
        options, kinematics, the number and kind of the velocity conditions, reactions,
        symmetry planes, contributors with their names, parameters and tools, controllers),
        compared on every rank together. A set-up that differs between ranks (a contributor
        added on one rank only, a tool with other parameters) then raises a ValueError on every
        rank saying what differs and where, instead of a hang in the first collective operation
        that one rank never reaches."""
        items = {"material": digest(self.material),
                 "solver_options": digest(self.solver_options),
                 "kinematics": digest_parameters(self.kinematics),
                 "the number of velocity conditions (add_velocity_bc)": len(self._bcs),
                 "the reactions (add_reaction)": tuple(self._reactions),
                 "the symmetry planes (add_symmetry_plane)":
                     tuple(self._symmetry.names) if self._symmetry is not None else (),
                 "the number of contributors (add_contributor)": len(self.contributors),
                 "the number of controllers (add_controller)": len(self.controllers)}
        for k, b in enumerate(self._bcs):
            items[f"velocity condition #{k}"] = (
                f"{b.label}, value {'function' if callable(b.value) else digest(b.value)}")
        for k, c in enumerate(self.contributors):
            items[f"contributor #{k}"] = digest_parameters(c)
        for k, c in enumerate(self.controllers):
            items[f"controller #{k}"] = digest_parameters(c)
        check_together(self.comm, "the set-up of the first increment (Simulation.run/step)",
                       None, **items)

    def _claim_labels(self, labels: Dict[str, str]):
        """Reserve the labels that start history columns (``{label}_x``, ``{label}_force_x``…):
        a ValueError names a label that another contributor, tool, reaction or symmetry plane
        already has (their columns would overwrite each other)."""
        for label, what in labels.items():
            if label in self._labels:
                raise ValueError(f"the name '{label}' of {what} is already the name of "
                                 f"{self._labels[label]}: their history columns ('{label}_...') "
                                 f"would overwrite each other; pass a distinct name= to one of "
                                 f"them")
        self._labels.update(labels)

    def _check_not_built(self):
        if self._built:
            raise RuntimeError("the simulation is already set up: add conditions before run()")

    def _build(self):
        if self._built:
            return
        self._check_setup_together()
        sp = self.space
        v, p = ufl.split(self.w)
        wt, q = ufl.TestFunctions(sp.W)
        F_mat = self.material.residual(v, p, wt, q, sp.dx, self.dt_c, self.u)
        extras = [f for f in (None if self.extra_residual is None else
                              self.extra_residual(v, p, wt, q),
                              self._volume_correction_term(q)) if f is not None]
        F = sum(extras, F_mat)
        self.F_ufl = F
        cons = [self._symmetry] if self._symmetry is not None and len(self._symmetry) else []
        self._constraints = cons
        if cons:  # dofs of the velocity conditions that are not symmetry planes
            imap = sp.W.dofmap.index_map
            other = np.zeros((imap.size_local + imap.num_ghosts) * sp.W.dofmap.index_map_bs,
                             dtype=bool)
            for b in self._bcs:
                if not any(b.bc is pb for pb in self._plane_bcs):
                    other[b.bc.dof_indices()[0]] = True
            self._symmetry.set_prescribed(other)
        eta = shear_viscosity_ufl(self.material, v, self.dt_c)
        schur_weight = None if eta is None else q / eta * sp.dx
        J = None
        #: the dual stress of the primal–dual Newton (``material_tangent``), or None
        self.dual = None
        if uses_dual_stress(self.material, self.solver_options.material_tangent):
            self.dual = DualStress(self.material, sp.W, sp.quadrature_degree)
            self.dual.use_kernel(sp)
            log.debug("Newton with the primal-dual Norton-Hoff tangent (fxcontact.element.dual)")
            J = primal_dual_jacobian(self.material, self.dual, F, extras, self.w, v, wt, q, sp.dx)
        self.problem = NodalNonlinearProblem(F, self.w, [b.bc for b in self._bcs], J=J,
                                             contributors=self.contributors, constraints=cons,
                                             schur_weight=schur_weight,
                                             augment=volumetric_augment_ufl(self.material, eta,
                                                                            sp.W, wt, sp.dx))
        if self.dual is not None:
            self.problem.iterate_hooks.append(self.dual)
        self._use_hand_kernel(self.problem, self.material, self.dual)
        fs_is = self.fieldsplit_is() if self.solver_options.uses_fieldsplit else None
        self.solver = ContactNewtonSolver(self.problem, self.solver_options, fs_is)
        # start-up problem: the linearised material without contributors gives the first guess
        # when there is no previous velocity (a power law from v = 0 converges badly)
        lin_mat = self.material.linearized()
        self._startup = None
        if lin_mat is not self.material:
            F0 = sum(extras, lin_mat.residual(v, p, wt, q, sp.dx, self.dt_c, self.u))
            # (no contributors there: no force scale for ftol)
            opts = SolverOptions(**{**self.solver_options.__dict__, "ftol": 0.0, "prefix":
                                    self.solver_options.prefix + "startup_"})
            eta0 = shear_viscosity_ufl(lin_mat, v, self.dt_c)
            prob0 = NodalNonlinearProblem(
                F0, self.w, [b.bc for b in self._bcs], constraints=cons,
                schur_weight=None if eta0 is None else q / eta0 * sp.dx,
                augment=volumetric_augment_ufl(lin_mat, eta0, sp.W, wt, sp.dx))
            self._use_hand_kernel(prob0, lin_mat, None)
            self._startup = ContactNewtonSolver(prob0, opts, fs_is)
        # cell averages of the strain rate, volume
        q0 = ufl.TestFunction(sp.DG0)
        epsd = equivalent_strain_rate_ufl(v, sp.gdim)
        self._rate_form = compat.form(epsd * q0 * sp.dx)
        self._cellvol_form = compat.form(q0 * sp.dx)
        self._volume_form = compat.form(dolfinx.fem.Constant(self.mesh, 1.0) * sp.dx)
        self._div_form = compat.form(ufl.div(v) * sp.dx)
        self._mean_rate_form = compat.form(epsd * sp.dx)
        if self._log_volume is not None:
            self._restore_form = compat.form(-self._log_volume / self.dt_c * sp.dx)
        self._built = True
        self._volume_initial = self.volume()
        if self.output_dir is not None:
            self._outputs.open()

    def _use_hand_kernel(self, problem, material, dual):
        """Give ``problem`` the hand-written Norton–Hoff kernel of its condensed Jacobian if
        ``material`` is NortonHoff's own law (fxcontact.element.jacobian checks it against the
        problem's own Jacobian before using it)."""
        if standard_norton_hoff(material):
            problem.element_tensors = lambda layout: NortonHoffElementTensors(
                layout, self.space, material, self.w, dual)

    def _volume_correction_term(self, q):
        """``-q ln(V/V⁰)/dt dx`` added to the incompressibility equation ``-q div v dx``
        (None without correction); ``ln(V/V⁰)`` is updated after each geometry update."""
        self._log_volume = None
        if self.volume_correction == "none":
            return None
        self._log_volume = dolfinx.fem.Constant(self.mesh, PETSc.ScalarType(0.0))
        return -q * self._log_volume / self.dt_c * self.space.dx

    def _update_volume_correction(self):
        if self._log_volume is not None:
            self._log_volume.value = math.log(self.volume() / self._volume_initial)

    def fieldsplit_is(self):
        sp = self.space
        nown = sp.num_owned_dofs
        imap = sp.W.dofmap.index_map
        def to_is(dofs):
            dofs = dofs[dofs < nown]
            return PETSc.IS().createGeneral(
                (imap.local_range[0] + np.sort(dofs)).astype(np.int32), comm=self.comm)
        return to_is(sp.V_to_W), to_is(sp.Q_to_W)

    # ------------------------------------------------------------------------ state
    def vertex_positions(self) -> np.ndarray:
        """(num_local_vertices, gdim) vertex positions at the start of the increment."""
        sp = self.space
        x = self.mesh.geometry.x[sp.vertex_geometry, : sp.gdim].copy()
        if self.u is not None:
            x += self._vertex_displacement()
        return x

    def _vertex_displacement(self) -> np.ndarray:
        sp = self.space
        vd = sp.vertex_dofs
        # u lives on the collapsed velocity space: map W dofs -> V dofs
        W_to_V = self._W_to_V()
        return self.u.x.array[W_to_V[vd]]

    def _W_to_V(self) -> np.ndarray:
        if self._w2v is None:
            sp = self.space
            n = sp.W.dofmap.index_map.size_local + sp.W.dofmap.index_map.num_ghosts
            m = np.full(n, -1, dtype=np.int64)
            m[sp.V_to_W] = np.arange(len(sp.V_to_W))
            self._w2v = m
        return self._w2v

    def volume(self) -> float:
        self._build()
        return self.comm.allreduce(dolfinx.fem.assemble_scalar(self._volume_form), op=MPI.SUM)

    @property
    def initial_volume(self) -> float:
        """Volume of the body at t = 0 (also after :meth:`resume`)."""
        self._build()
        return self._volume_initial

    def mean_strain_rate(self) -> float:
        """Volume average of the (un-regularised) equivalent strain rate of the current w."""
        self._build()
        num = self.comm.allreduce(dolfinx.fem.assemble_scalar(self._mean_rate_form), op=MPI.SUM)
        return num / self.volume()

    def divergence_integral(self) -> float:
        """∫ div v dx of the current solution (discrete incompressibility check)."""
        self._build()
        return self.comm.allreduce(dolfinx.fem.assemble_scalar(self._div_form), op=MPI.SUM)

    def reaction_force(self, facets: np.ndarray) -> np.ndarray:
        """Force exerted *on the body* through the Dirichlet dofs of ``facets`` (gdim,): the sum
        of the bc-free residual entries (internal forces and the contributors' nodal terms, e.g.
        of a contact node under the condition) at the velocity dofs of the facets, owned dofs
        only, summed over ranks (collective), on the *current* geometry (use
        :meth:`add_reaction` for the value on the increment's configuration)."""
        self._build()
        sp = self.space
        b = dolfinx.fem.petsc.assemble_vector(self.problem.L)
        b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        terms = self.problem._evaluate_contributors(False) if self.contributors else []
        if terms is None:       # on every rank
            raise ContributorError(self.problem.error)
        for t in terms:
            add_nodal_residual(b, t)
        arr = b.getArray(readonly=True)
        fdim = self.mesh.topology.dim - 1
        out = np.zeros(sp.gdim)
        nown = sp.num_owned_dofs
        for k in range(sp.gdim):
            Wk = sp.W.sub(0).sub(k)
            Vk, _ = compat.collapse(Wk)
            dofs = compat.locate_dofs_topological((Wk, Vk), fdim, facets)[0]
            dofs = dofs[dofs < nown]
            out[k] = np.sum(arr[dofs])
        b.destroy()
        return self.comm.allreduce(out, op=MPI.SUM)

    # ------------------------------------------------------------------------ stepping
    def _set_bc_values(self, t: float):
        for b in self._bcs:   # an error (wrong shape) is raised on every rank, naming the BC
            set_function_value(b.g, _time_value(b.value, t), b.gdim, f"{b.label} at t = {t:.6g}")
        # a user function that returns NaN/inf would poison Newton: say which and when
        bad = [k for k, b in enumerate(self._bcs) if not np.all(np.isfinite(b.g.x.array))]
        bad = sorted(set(k for ks in self.comm.allgather(bad) for k in ks))
        if bad:
            raise ValueError(f"velocity boundary condition(s) #{bad} (numbered in the order they "
                             f"were added) give non-finite values (NaN/inf) at t = {t:.6g}: "
                             f"check the value function")

    def _update_law(self):   # a Viscoplastic's pieces from the increment's start (THEORY §15)
        if self.law is not None:
            self.material.update(self.strain.x.array, self.cell_temperature)

    def _try_increment(self, dt: float) -> SolveInfo:
        t_new = self.t + dt
        self.dt_c.value = dt
        self._set_bc_values(t_new)
        self._update_law()
        # predictor: previous increment's velocity, with the new boundary values
        self.w.x.array[:] = self.w_prev.x.array
        dolfinx.fem.petsc.set_bc(self.w.vector, self.problem.bcs)
        self.w.x.scatter_forward()
        for c in self._constraints:
            c.project(self.w)
        if self._startup is not None and not np.any(self.w_prev.x.array):
            self.comm.barrier()
            info0 = self._startup.solve()
            log.log(logging.DEBUG if info0.converged else logging.INFO,
                    "start-up (linearised material) solve: %d iterations, converged=%s",
                    info0.iterations, info0.converged)
            if not info0.converged:  # keep the zero guess
                self.w.x.array[:] = 0.0
                dolfinx.fem.petsc.set_bc(self.w.vector, self.problem.bcs)
                self.w.x.scatter_forward()
        x_t = self.vertex_positions()

        def begin():
            for c in self.controllers + self.contributors:
                if isinstance(c, BeginsIncrement):
                    c.begin_increment(self, self.t, dt, x_t)
        begin()
        for c in self.controllers:
            if isinstance(c, SolvesIncrement):
                return c.solve(self, begin)
        return self.solver.solve()

    def _commit(self, dt: float, info: SolveInfo) -> Dict[str, float]:
        sp = self.space
        w = self.w
        w.x.scatter_forward()
        x_t = self.vertex_positions()
        v_vert = w.x.array[sp.vertex_dofs]
        # cumulative strain and strain rate (cell averages, before the geometry moves)
        rate = self._cell_average(self._rate_form)
        self.strain_rate.x.array[:] = rate
        self.strain.x.array[:] += dt * rate
        reactions = {name: self.reaction_force(f) for name, f in self._reactions.items()}
        for c in self.controllers:   # on the configuration of the increment (heat, THEORY §16)
            if isinstance(c, CommitsIncrement):
                c.commit_increment(self, dt)
        div_v = self.divergence_integral()
        restore = (self.comm.allreduce(dolfinx.fem.assemble_scalar(self._restore_form),
                                       op=MPI.SUM) if self._log_volume is not None else 0.0)
        # geometry / displacement update with the same map as the contact condition
        X = self.kinematics.positions(x_t, v_vert, dt)
        if self.u is None:
            g = self.mesh.geometry.x
            g[sp.vertex_geometry, : sp.gdim] = X
            self._update_volume_correction()
        else:
            self.u.x.array[:] += dt * w.x.array[sp.V_to_W]
            self.u.x.scatter_forward()
        self.t += dt
        self.increment += 1
        self.w_prev.x.array[:] = w.x.array
        row = {"increment": self.increment, "time": self.t, "dt": dt,
               "remesh": len(self.remeshes),   # remeshes before this increment
               "newton_iterations": info.iterations,
               "linear_iterations": info.linear_iterations,
               "residual": info.residual_norms[-1] if info.residual_norms else float("nan")}
        for k in ("assembly", "linear_solve", "contact", "other", "total", "factorisation"):
            row[f"wall_{k}"] = info.times.get(k, 0.0)
        row["volume"] = self.volume()
        row["volume_change"] = row["volume"] / self._volume_initial - 1.0
        row["div_v"] = div_v
        # the volume rate asked for by the correction (∫ div v equals it, to the solver tol.)
        row["volume_restore_rate"] = restore
        for c in self._constraints:
            reactions.update(c.forces())
            if c.active:
                row["symmetry_violation"] = c.max_violation(w)
        for name, F in reactions.items():
            for k, c in enumerate("xyz"[: sp.gdim]):
                row[f"{name}_{c}"] = F[k]
        for c in self.contributors + self.controllers:
            if isinstance(c, EndsIncrement):
                c.end_increment(self, dt)
            if isinstance(c, HasDiagnostics):
                _merge_columns(row, c.diagnostics(), c)
        return row

    def _cell_average(self, frm) -> np.ndarray:
        b1 = dolfinx.fem.petsc.assemble_vector(frm)
        b2 = dolfinx.fem.petsc.assemble_vector(self._cellvol_form)
        for b in (b1, b2):
            b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
            b.ghostUpdate(addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)
        with b1.localForm() as l1, b2.localForm() as l2:
            out = l1.array / l2.array
        b1.destroy()
        b2.destroy()
        return out

    def step(self, dt: float, max_cutbacks: int = 5, min_dt: float = 0.0) -> IncrementResult:
        """Advance by one increment of (at most) ``dt``, halving it on Newton failure (at most
        ``max_cutbacks`` times, and never below ``min_dt``)."""
        with together(self.comm, "Simulation.step()", dt=dt, max_cutbacks=max_cutbacks,
                      min_dt=min_dt, t=self.t):
            if not (isinstance(dt, (int, float, np.floating)) and math.isfinite(dt) and dt > 0):
                raise ValueError(f"dt must be a finite number > 0, got {dt!r}")
            if max_cutbacks < 0:
                raise ValueError("max_cutbacks must be >= 0")
        self._build()
        self._outputs.reopen()
        row, info = self._retry.step(dt, max_cutbacks, min_dt)
        if self._remeshing is not None:
            self._remeshing.after_increment(self)
        return IncrementResult(row, info)

    # ------------------------------------------------------------------------ remeshing
    def set_remeshing(self, criteria: Optional[RemeshCriteria] = RemeshCriteria(),
                      size: Optional[float] = None, zones=(), feature_angle: float = 40.0,
                      rescue: bool = True):
        """Remesh automatically when one of the ``criteria`` fires after an increment, and
        (``rescue``) before an increment whose cut-backs all invert a cell is given up; the
        arguments: :class:`~fxcontact.remesh.remeshing.Remeshing`."""
        self._remeshing = Remeshing(self, criteria, size, zones, feature_angle, rescue)

    def remesh(self, size: Optional[float] = None, zones=None, reason: str = "on demand"):
        """Mesh the current body again and carry the state, the conditions and the
        contributors over (collective; :func:`~fxcontact.remesh.remeshing.remesh_simulation`).
        Returns the :class:`~fxcontact.remesh.remeshing.RemeshRecord`."""
        return remesh_simulation(self, size=size, zones=zones, reason=reason)

    def _record(self, row):
        """An accepted increment's row: mesh health, history, outputs, checkpoint."""
        row.update(self.mesh_health())
        self.history.append(row)
        self._outputs.write(row)
        if self.checkpoint_every and self.increment % self.checkpoint_every == 0:
            self.write_checkpoint()

    def output_functions(self) -> list:
        """The functions of each VTK step (:meth:`Outputs.functions
        <fxcontact.io.outputs.Outputs.functions>`)."""
        return self._outputs.functions()

    def run(self, t_end: float, dt: float, max_cutbacks: int = 5,
            callback: Optional[Callable] = None, close: bool = True) -> List[Dict[str, float]]:
        """Advance to ``t_end`` with increments ``dt`` (cut back on failure, then grown back).

        An increment that fails is retried with dt halved, at most ``max_cutbacks`` times and
        never below ``dt / 2**max_cutbacks``: a run whose sub-increments keep failing stops with
        an :class:`IncrementError` instead of creeping on with ever smaller steps.

        Returns the history (one dict per increment). Outputs are flushed after each increment
        and closed on error, and at the end unless ``close=False`` (to continue with another
        ``run``).
        """
        with together(self.comm, "Simulation.run()", t_end=t_end, dt=dt,
                      max_cutbacks=max_cutbacks, t=self.t):
            if not (math.isfinite(t_end) and t_end > self.t):
                raise ValueError(f"t_end must be > current time {self.t}, got {t_end!r}")
            if not (isinstance(dt, (int, float, np.floating)) and math.isfinite(dt) and dt > 0):
                raise ValueError(f"dt must be a finite number > 0, got {dt!r}")
        self._build()
        bar = None
        if self.progress and console.progress_enabled() and self.comm.rank == 0:
            bar = tqdm(total=t_end - self.t, desc=self.name, unit="s", leave=False,
                       bar_format="{l_bar}{bar}| {n:.4g}/{total:.4g} s "
                                  "[{elapsed}<{remaining}{postfix}]")
        n0, t0, wall0 = len(self.history), self.t, time.perf_counter()
        cur = dt
        if self._checkpoints.resume_step is not None:   # the step a resumed run takes next
            cur = min(dt, self._checkpoints.resume_step)
            self._checkpoints.resume_step = None
        eps = 1e-9 * dt
        try:
            while self.t < t_end - eps:
                step = min(cur, t_end - self.t)
                res = self.step(step, max_cutbacks, min_dt=dt * 0.5 ** max_cutbacks)
                if bar is not None:  # one refresh per increment (set_postfix would add one)
                    bar.set_postfix(newton=res.info.iterations, refresh=False)
                    bar.update(res.row["dt"])
                # after a cut-back, grow back towards the nominal dt
                cur = min(dt, 2.0 * res.row["dt"]) if res.row["cutbacks"] else dt
                if callback is not None:
                    callback(self, res)
        except BaseException:
            self.close()
            raise
        finally:
            if bar is not None:
                bar.close()
        rows = self.history[n0:]
        log.info("%s: t = %.4g -> %.4g in %d increments (%d cut-backs), %d Newton iterations, "
                 "%.1f s%s", self.name, t0, self.t, len(rows), sum(r["cutbacks"] for r in rows),
                 sum(r["newton_iterations_all"] for r in rows), time.perf_counter() - wall0,
                 "".join(f"\n  {c.summary()}" for c in self.contributors
                         if isinstance(c, HasSummary))
                 + "".join(f"\n  {r.line()}" for r in self.remeshes))
        if close:
            self.close()
        return self.history

    def close(self):
        """Close the CSV history and the VTK series (a later ``run()`` continues them)."""
        self._outputs.close()

    def mesh_health(self) -> Dict[str, float]:
        """Mesh quality of the current configuration (collective): ``min_quality`` (shape
        quality, negative for an inverted cell) and ``min_volume_ratio`` (signed cell volume
        over its initial volume) — history columns of every increment."""
        return self._mesh_health.columns()

    # ------------------------------------------------------------------------ checkpoints
    @property
    def checkpoint_dir(self) -> str:
        """``output_dir/checkpoints`` (ValueError without an ``output_dir``)."""
        return self._checkpoints.directory

    def write_checkpoint(self, path: Optional[str] = None) -> str:
        """Write a checkpoint of the current (accepted) state (collective); returns its path.

        Default path: ``output_dir/checkpoints/<name>_<increment>``; older ones beyond
        ``checkpoint_keep`` are removed.
        """
        return self._checkpoints.write(path)

    def resume(self, path: Optional[str] = None) -> str:
        """Restore the state of a checkpoint, before :meth:`run` (collective).

        Set the simulation up exactly as for the first run (same mesh, space, material, BCs and
        contributors, added in the same order), then call ``resume()``; ``run(t_end, dt)``
        continues from the checkpoint's time. ``path``: a checkpoint directory, or a directory
        of checkpoints (the newest is taken); default: the newest one of this run in
        ``output_dir/checkpoints``. The CSV history and the VTK series are continued (rows and
        steps after the checkpoint, from a run that was killed, are dropped). Works on any
        number of ranks. Raises :class:`~fxcontact.checkpoint.CheckpointError` (a ValueError)
        for a missing checkpoint, another format or package version, another mesh, another
        set-up or other controllers (:meth:`add_controller`), and for a corrupted checkpoint (a
        truncated or altered file, e.g. a disk that failed): ``resume()`` does not fall back to
        an older checkpoint by itself; the message names the newest intact one, to resume
        from with ``resume(path=...)``.
        """
        return self._checkpoints.resume(path)
