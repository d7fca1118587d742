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
"""

from __future__ import annotations

import logging
import math
import os
import shutil
import time
from dataclasses import dataclass
from typing import Callable, Dict, List, Optional

import numpy as np
import ufl
from mpi4py import MPI
from petsc4py import PETSc

import dolfinx
import dolfinx.fem
import dolfinx.fem.petsc

from fxcontact import compat, console
from fxcontact.collective import check_together, digest, together
from fxcontact.kinematics import CartesianUpdate
from fxcontact.materials import LinearElastic, Material, NortonHoff
from fxcontact.petsc import NonlinearProblem
from fxcontact.solver import NewtonSolver, SolveInfo, SolverOptions
from fxcontact.spaces import (MixedSpace, checked_facets, facets_with_tags, set_function_value,
                              velocity_bc)

__all__ = ["Simulation", "IncrementError", "MeshInversionError", "OutputError", "IncrementResult",
           "VOLUME_CORRECTIONS", "wall_split", "format_wall_split"]

#: incompressibility corrections of the accumulated volume error (``Simulation``)
VOLUME_CORRECTIONS = ("global", "none")

log = logging.getLogger(__name__)


class IncrementError(RuntimeError):
    """Newton failed at some time even after the allowed cut-backs."""

    def __init__(self, t: float, dt: float, message: str):
        super().__init__(f"increment starting at t = {t:.6g} failed (last dt = {dt:.3g}): "
                         f"{message}. Results up to t = {t:.6g} are written.")
        self.t = t
        self.dt = dt


class MeshInversionError(IncrementError):
    """An element would invert (signed volume ≤ 0) even after the allowed cut-backs."""


class OutputError(OSError):
    """Writing the outputs (CSV history, VTK series) failed, e.g. on a full disk."""


#: message prefix of an increment rejected because an element would invert
_INVERSION = "element inverted"


@dataclass
class IncrementResult:
    """Outcome of one accepted increment (also one row of the history)."""

    row: Dict[str, float]
    info: SolveInfo


#: parts of an increment's wall time measured by the solver (``wall_<part>`` in the history)
WALL_PARTS = ("assembly", "linear_solve", "contact")


def wall_split(rows) -> dict:
    """Wall time of a run by part, summed over its increments.

    ``rows``: :attr:`Simulation.history` or a demo's per-increment rows with the keys
    ``wall_assembly``, ``wall_linear_solve``, ``wall_contact`` and the increment's whole wall time
    (``wall_increment_all``, or ``wall``). Returns ``{"assembly", "linear_solve", "contact",
    "other", "total"}`` in seconds; ``other`` is the rest of the increments (geometry update,
    outputs, the failed attempts of cut-backs and fall-backs)."""
    rows = list(rows)
    out = {k: float(sum(q.get(f"wall_{k}", 0.0) for q in rows)) for k in WALL_PARTS}
    out["total"] = float(sum(q.get("wall_increment_all", q.get("wall", 0.0)) for q in rows))
    out["other"] = max(out["total"] - sum(out[k] for k in WALL_PARTS), 0.0)
    return out


def format_wall_split(split: dict) -> str:
    """``"assembly 120 s (41 %), linear solve ..., contact ..., other ..."`` of :func:`wall_split`."""
    tot = split["total"] or float("nan")
    return ", ".join(f"{k.replace('_', ' ')} {split[k]:.0f} s ({100 * split[k] / tot:.1f} %)"
                     for k in WALL_PARTS + ("other",))


@dataclass
class _BC:
    bc: object
    g: object
    value: object
    gdim: Optional[int]
    #: how the messages name it: number, component, facets
    label: str = "velocity boundary condition"


def _bc_label(sim, k: int, facets, component) -> str:
    """``velocity boundary condition #k (component c, on n facets)`` (collective)."""
    fdim = sim.mesh.topology.dim - 1
    owned = sim.mesh.topology.index_map(fdim).size_local
    n = sim.comm.allreduce(int(np.sum(np.asarray(facets) < owned)), op=MPI.SUM)
    comp = "all components" if component is None else f"component {component}"
    return f"velocity boundary condition #{k} ({comp}, on {n} facets)"


def _describe(obj) -> str:
    """A contributor or controller as compared between ranks: its type, its scalar
    parameters and its tools (:func:`fxcontact.collective.digest`), not its rank-local data."""
    from fxcontact.tools import Tool
    if not hasattr(obj, "__dict__"):
        return type(obj).__name__
    out = {}
    for k, v in sorted(vars(obj).items()):
        if k.startswith("_"):
            continue
        if v is None or isinstance(v, (bool, int, float, str, np.integer, np.floating)):
            out[k] = v
        elif isinstance(v, Tool) or (isinstance(v, (list, tuple)) and v
                                     and all(isinstance(t, Tool) for t in v)):
            out[k] = v
    return type(obj).__name__ + digest(out, depth=6)


def _time_value(value, t):
    """A BC value at time t: constants pass through, f(t) is called, f(x) (vectorised) too."""
    if callable(value):
        try:
            import inspect
            params = inspect.signature(value).parameters
        except (TypeError, ValueError):
            params = {}
        if "t" in params and len(params) == 1:
            return value(t)
        if "t" in params:
            return lambda x: value(x, t)
        return value
    return value


def _attempts(msgs) -> str:
    """The reasons of the failed attempts at one dt (fall-backs, then the last), each once."""
    msgs = list(dict.fromkeys(msgs))
    if len(msgs) == 1:
        return msgs[0]
    return f"{len(msgs)} attempts: " + " | ".join(msgs)


def _plain_state(value):
    """A controller's state as plain JSON values (numpy arrays and scalars to lists/numbers)."""
    if isinstance(value, dict):
        return {str(k): _plain_state(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain_state(v) for v in value]
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    if value is None or isinstance(value, (bool, int, float, str)):
        return value
    raise ValueError(f"a controller's checkpoint_state() must hold plain numbers, strings, "
                     f"lists, dicts or numpy arrays, got {type(value).__name__}")


def _output_dir_problem(path) -> Optional[str]:
    """Why ``path`` cannot be the output directory (a file is in the way, not writable), or
    None (None also for ``path=None``: no outputs)."""
    if path is None:
        return None
    p = os.path.abspath(str(path))
    if os.path.exists(p) and not os.path.isdir(p):
        return "is a file, not a directory"
    while not os.path.exists(p):
        p = os.path.dirname(p)
    if not os.path.isdir(p):
        return f"cannot be created: {p!r} is a file"
    if not os.access(p, os.W_OK | os.X_OK):
        return f"cannot be written: no write permission in {p!r}"
    return None


def _label(obj) -> str:
    """``NodalContact 'die'``: a registered object in messages."""
    name = getattr(obj, "name", None)
    return type(obj).__name__ + (f" '{name}'" if isinstance(name, str) else "")


def _column_labels(contributor) -> Dict[str, str]:
    """The labels that start a contributor's history columns, with what each labels: its name
    (a contact's ``{name}_nodes``…) and its tools' names (``{tool}_force_x``…)."""
    out = {}
    for tool in getattr(contributor, "tools", None) or []:
        if isinstance(getattr(tool, "name", None), str):
            out[tool.name] = f"tool '{tool.name}' of {_label(contributor)}"
    if hasattr(contributor, "diagnostics") and isinstance(getattr(contributor, "name", None),
                                                           str):
        out[contributor.name] = _label(contributor)
    return out


def _check_added_once(obj, registered, what: str):
    """ValueError if ``obj`` (the same object) is already registered."""
    if any(r is obj for r in registered):
        raise ValueError(f"{what} {_label(obj)} is already added to this simulation: added "
                         f"twice, it would act twice (its forces counted twice, its history "
                         f"columns wrong); add it once")


def _merge_columns(row: dict, columns: dict, owner):
    """Add ``columns`` to a history row; ValueError if one is already there (two contributors
    or controllers writing the same column would overwrite each other)."""
    clash = sorted(set(row) & set(columns))
    if clash:
        raise ValueError(f"history column(s) {clash} of {_label(owner)} are already written "
                         f"by another contributor, reaction or symmetry plane: pass a distinct "
                         f"name= to one of them")
    row.update(columns)


def _initial_mesh_error(msh, X, c2v_owned, vol0, q0) -> Optional[str]:
    """What is wrong with the initial mesh, or None (collective; the message is local):
    degenerate cells (:func:`~fxcontact.mesh_health.degenerate_cells`) or a tangled mesh
    (cells turned inside out, overlapping a neighbour: :func:`~fxcontact.mesh_health.
    overlapping_facets`)."""
    from fxcontact.mesh_health import (DEGENERATE_QUALITY, DEGENERATE_VOLUME, degenerate_cells,
                                       overlapping_facets)
    comm = msh.comm
    tdim = msh.topology.dim
    msh.topology.create_connectivity(tdim - 1, tdim)   # collective: before any local return
    msh.topology.create_connectivity(tdim - 1, 0)
    n = comm.allreduce(len(vol0), op=MPI.SUM)
    mean = comm.allreduce(float(np.sum(np.abs(vol0))), op=MPI.SUM) / max(n, 1)
    bad = np.flatnonzero(degenerate_cells(vol0, q0, mean))
    if len(bad):
        c = X[c2v_owned[bad[0]]].mean(axis=0)
        return (f"the mesh has {len(bad)} degenerate (zero-volume) cell(s) (volume below "
                f"{DEGENERATE_VOLUME:g} x the mean cell volume or shape quality below "
                f"{DEGENERATE_QUALITY:g}), e.g. with centroid {np.array2string(c, precision=4)}: "
                f"remesh")
    f2c = msh.topology.connectivity(tdim - 1, tdim)
    nf = msh.topology.index_map(tdim - 1).size_local
    inner = np.flatnonzero(np.diff(f2c.offsets)[:nf] == 2)
    fc = f2c.array[f2c.offsets[inner][:, None] + np.arange(2)]
    fv = msh.topology.connectivity(tdim - 1, 0).array.reshape(-1, tdim)[inner]
    over = overlapping_facets(X, compat.cell_vertices(msh), fv, fc)
    if np.any(over):
        c = X[fv[np.argmax(over)]].mean(axis=0)
        return (f"the mesh is tangled: {int(np.sum(over))} facet(s) have both their cells on "
                f"the same side (cells turned inside out, overlapping their neighbour), e.g. the "
                f"facet with centroid {np.array2string(c, precision=4)}: fix or remesh the mesh "
                f"(check the node order of its cells)")
    return None


def _shear_viscosity_ufl(material, v, dt):
    """Secant shear viscosity of the velocity tangent (UFL) for the Schur preconditioner of
    the condensed iterative solver (:mod:`fxcontact.condense`), or None if unknown:
    ``K z^(m-1)`` for Norton–Hoff, ``μ dt`` for the velocity form of linear elasticity."""
    if isinstance(material, NortonHoff):
        return material.K * material.z_ufl(ufl.sym(ufl.grad(v))) ** (material.m - 1.0)
    if isinstance(material, LinearElastic):
        return material.mu * dt
    return None


def _uses_dual_stress(material, material_tangent: str) -> bool:
    """Whether ``SolverOptions.material_tangent`` asks for the primal–dual Newton with this
    material (``"auto"``: a material that has it, nonlinear)."""
    if material_tangent == "primal-dual":
        return True
    return (material_tangent == "auto" and hasattr(material, "dual_update_ufl")
            and getattr(material, "m", 1.0) < 1.0)


def _standard_norton_hoff(material) -> bool:
    """Whether the material's residual is NortonHoff's own (stress, z and residual not
    redefined by a subclass), so that its primal–dual Jacobian can be written out."""
    return isinstance(material, NortonHoff) and all(
        getattr(type(material), name) is getattr(NortonHoff, name)
        for name in ("stress_ufl", "z_ufl", "residual", "incompressibility_ufl"))


def _volumetric_augment_ufl(material, eta, W, wt, dx):
    """``(2/3) η div(δv) div(w) dx`` (η the secant viscosity of :func:`_shear_viscosity_ufl`)
    for a material whose velocity tangent sees only the strain-rate deviator (Norton–Hoff):
    with it the velocity block of the condensed iterative solver's preconditioner is that of
    the full strain rate (``NonlinearProblem(augment=)``); None for the other materials."""
    if not isinstance(material, NortonHoff):
        return None
    du, _ = ufl.split(ufl.TrialFunction(W))
    return (2.0 / 3.0) * eta * ufl.div(du) * ufl.div(wt) * dx


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
            problem = _output_dir_problem(output_dir)
            if problem:
                raise ValueError(f"output_dir {output_dir!r} {problem}: give a directory path")
        self.space = space
        self.mesh = space.mesh
        self.comm = space.mesh.comm
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
        self._bcs: List[_BC] = []
        self.contributors: List = []
        self.history: List[Dict[str, float]] = []
        self._built = False
        W = space.W
        self.w = dolfinx.fem.Function(W, name="solution")
        self.w_prev = dolfinx.fem.Function(W)
        self.dt_c = dolfinx.fem.Constant(self.mesh, PETSc.ScalarType(1.0))
        self.u = dolfinx.fem.Function(space.V, name="displacement") if material.small_strain \
            else None
        # output fields
        self.velocity = dolfinx.fem.Function(space.P1, name="velocity")
        self.pressure = dolfinx.fem.Function(space.Q, name="pressure")
        self.strain = dolfinx.fem.Function(space.DG0, name="equivalent_strain")
        self.strain_rate = dolfinx.fem.Function(space.DG0, name="equivalent_strain_rate")
        self.displacement_out = dolfinx.fem.Function(space.P1, name="displacement") \
            if material.small_strain else None
        self._p1_vertex = self._p1_vertex_dofs()
        self._x_ref = self.mesh.geometry.x.copy()
        self._writer = None
        self._history_writer = None
        self.overwrite = bool(overwrite)
        self._outputs_opened = False
        self._reactions: Dict[str, np.ndarray] = {}
        self._labels: Dict[str, str] = {}   # history-column labels -> what they label
        self.checkpoint_every = int(checkpoint_every)
        self.checkpoint_keep = int(checkpoint_keep)
        self.check_inversion = bool(check_inversion)
        self._resumed: Optional[dict] = None
        self._resumed_from: Optional[str] = None   # the directory of the resumed checkpoint
        self._resume_step: Optional[float] = None
        self._ckpt_keys = None
        self._init_mesh_health()
        self._symmetry = None
        self._plane_bcs: List = []
        self.controllers: List = []

    # ------------------------------------------------------------------------ set-up
    def _p1_vertex_dofs(self) -> np.ndarray:
        c2v = compat.cell_vertices(self.mesh)
        d = compat.dofmap_array(self.space.P1)
        out = np.empty(self.space.vertex_dofs.shape[0], dtype=np.int32)
        out[c2v.ravel()] = d[:, : c2v.shape[1]].ravel()
        return out

    def facets(self, facet_tags, tags) -> np.ndarray:
        """Local indices of the facets carrying any of ``tags`` in this mesh's ``facet_tags``
        (ValueError on every rank for an empty tag list, a missing tag or the facet tags of
        another mesh)."""
        return facets_with_tags(self.mesh, facet_tags, tags, "Simulation.facets(facet_tags)")

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

    def add_reaction(self, name: str, facets: np.ndarray):
        """Record, each increment, the force exerted on the body through the Dirichlet dofs of
        ``facets`` (history columns ``{name}_x``, ``{name}_y``, ``{name}_z``), computed on the
        configuration of the increment (before the geometry update)."""
        facets = checked_facets(self.mesh, facets, "add_reaction(facets)", name=name)
        with together(self.comm, "add_reaction()", name=name):
            self._claim_labels({name: f"reaction '{name}'"})
        self._reactions[name] = facets

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
        from fxcontact.symmetry import SymmetryPlanes, _unit_normal
        facets = checked_facets(self.mesh, facets, "add_symmetry_plane(facets)", exterior=True,
                                name=name, normal=digest(np.asarray(normal, dtype=float)))
        n = _unit_normal(normal, self.space.gdim)
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
        """Register a nodal contributor (``evaluate``, ``stable``; optional ``begin_increment``,
        ``end_increment``, ``diagnostics``, ``output_fields``)."""
        self._check_not_built()
        with together(self.comm, "add_contributor()", contributor=_describe(contributor)):
            _check_added_once(contributor, self.contributors, "contributor")
            self._claim_labels(_column_labels(contributor))
        self.contributors.append(contributor)
        return contributor

    def add_controller(self, controller):
        """Register a controller of the tools (:mod:`fxcontact.mill`): an object with optional
        ``begin_increment(sim, t, dt, x_t)`` (called at the start of each increment, before the
        contributors), ``solve(sim, begin)`` (replaces the increment's Newton solve: it may
        solve several times, calling ``begin()`` to restart the contributors; at most one
        controller may have it), ``end_increment(sim, dt)`` and ``diagnostics()``.

        Checkpoints: a controller that keeps a state between increments (rates it has set, a
        measured centre…) saves it with ``checkpoint_state() -> dict`` (plain numbers, lists,
        dicts, numpy arrays) and gets it back with ``restore_state(dict)``; the kinematics
        (e.g. :class:`~fxcontact.mill.RingAxisUpdate`) may have the same two methods. A
        checkpoint is resumed only with the same controllers (number, types, order)."""
        self._check_not_built()
        with together(self.comm, "add_controller()", controller=_describe(controller)):
            _check_added_once(controller, self.controllers, "controller")
            if hasattr(controller, "solve") and any(hasattr(c, "solve")
                                                    for c in self.controllers):
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
                 "kinematics": _describe(self.kinematics),
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
            items[f"contributor #{k}"] = _describe(c)
        for k, c in enumerate(self.controllers):
            items[f"controller #{k}"] = _describe(c)
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
        eta = _shear_viscosity_ufl(self.material, v, self.dt_c)
        schur_weight = None if eta is None else q / eta * sp.dx
        J = None
        #: the dual stress of the primal–dual Newton (``material_tangent``), or None
        self.dual = None
        if _uses_dual_stress(self.material, self.solver_options.material_tangent):
            from fxcontact.dual import DualStress
            self.dual = DualStress(self.material, sp.W, sp.quadrature_degree)
            self.dual.use_kernel(sp)
            log.debug("Newton with the primal-dual Norton-Hoff tangent (fxcontact.dual)")
            # the material's Jacobian written out (the primal-dual tangent and the bilinear
            # pressure terms) rather than ufl.derivative + correction: the same matrix at
            # about 60 % of the kernel cost; the other terms by ufl.derivative
            # (a subclass that redefines the stress or the residual gets the derivative)
            dw = ufl.TrialFunction(sp.W)
            dv, dp = ufl.split(dw)
            if _standard_norton_hoff(self.material):
                J = sum((ufl.derivative(f, self.w, dw) for f in extras),
                        self.dual.tangent_form(v, dv, wt, sp.dx)
                        + self.material.incompressibility_ufl(dv, dp, wt, q, sp.dx))
            else:
                J = ufl.derivative(F, self.w, dw) + self.dual.jacobian_correction(
                    v, dv, wt, sp.dx)
        self.problem = NonlinearProblem(F, self.w, [b.bc for b in self._bcs], J=J,
                                        contributors=self.contributors, constraints=cons,
                                        schur_weight=schur_weight,
                                        augment=_volumetric_augment_ufl(self.material, eta,
                                                                        sp.W, wt, sp.dx))
        if self.dual is not None:
            self.problem.iterate_hooks.append(self.dual)
        if _standard_norton_hoff(self.material):
            # the hand-written kernel of the condensed Jacobian (fxcontact.element_jacobian
            # checks it against the problem's own Jacobian before using it)
            from fxcontact.element_condense import NortonHoffElementTensors
            self.problem.element_tensors = lambda layout: NortonHoffElementTensors(
                layout, sp, self.material, self.w, self.dual)
        fs_is = self.fieldsplit_is() if self.solver_options.uses_fieldsplit else None
        self.solver = NewtonSolver(self.problem, self.solver_options, fs_is)
        # start-up problem: the linearised material without contributors gives the first guess
        # when there is no previous velocity (a power law from v = 0 converges badly)
        lin_mat = self.material.linearized()
        self._startup = None
        if lin_mat is not self.material:
            F0 = sum(extras, lin_mat.residual(v, p, wt, q, sp.dx, self.dt_c, self.u))
            opts = SolverOptions(**{**self.solver_options.__dict__, "prefix":
                                    self.solver_options.prefix + "startup_"})
            eta0 = _shear_viscosity_ufl(lin_mat, v, self.dt_c)
            self._startup = NewtonSolver(NonlinearProblem(
                F0, self.w, [b.bc for b in self._bcs], constraints=cons,
                schur_weight=None if eta0 is None else q / eta0 * sp.dx,
                augment=_volumetric_augment_ufl(lin_mat, eta0, sp.W, wt, sp.dx)), opts, fs_is)
        # cell averages of the strain rate, volume
        q0 = ufl.TestFunction(sp.DG0)
        epsd = self._strain_rate_expr(v)
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
            self._open_writers()

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

    def _strain_rate_expr(self, v):
        e = ufl.sym(ufl.grad(v))
        d = self.space.gdim
        de = e - ufl.tr(e) / d * ufl.Identity(d)
        return ufl.sqrt(2.0 / 3.0 * ufl.inner(de, de))

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
        if not hasattr(self, "_w2v"):
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
        """Force exerted *on the body* through the Dirichlet dofs of ``facets`` (gdim,).

        Computed as the sum of the (bc-free) UFL residual entries (internal forces) at the
        velocity dofs of the facets, owned dofs only, summed over ranks, on the *current*
        geometry (use :meth:`add_reaction` for the value on the increment's configuration).
        """
        self._build()
        sp = self.space
        b = dolfinx.fem.petsc.assemble_vector(self.problem.L)
        b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
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

    def _try_increment(self, dt: float) -> SolveInfo:
        t_new = self.t + dt
        self.dt_c.value = dt
        self._set_bc_values(t_new)
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
                if hasattr(c, "begin_increment"):
                    c.begin_increment(self, self.t, dt, x_t)
        begin()
        for c in self.controllers:
            if hasattr(c, "solve"):
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
               "newton_iterations": info.iterations,
               "linear_iterations": info.linear_iterations,
               "residual": info.residual_norms[-1] if info.residual_norms else float("nan")}
        for k in ("assembly", "linear_solve", "contact", "other", "total"):
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
            if hasattr(c, "end_increment"):
                c.end_increment(self, dt)
            if hasattr(c, "diagnostics"):
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
        self._reopen_outputs()
        trial = float(dt)
        msg = ""
        msgs: List[str] = []
        failed_its = 0
        t_first = time.perf_counter()
        for k in range(max_cutbacks + 1):
            if k > 0 and trial < min_dt * (1.0 - 1e-12):
                msg += f"; dt would fall below the smallest allowed {min_dt:.3g}"
                break
            t0 = time.perf_counter()
            first = len(msgs)   # the attempts at this dt, for the cut-back warning
            info = self._try_increment(trial)
            if not info.converged and "condensed linear solve failed" in info.message \
                    and self.solver.fall_back_to_direct():
                # "auto" chose the iterative solver and it failed: the direct one from now on,
                # the same dt again
                log.warning("t = %.6g: %s; the linear solver chosen by 'auto' is switched from "
                            "condensed-amg to condensed-mumps", self.t, info.message)
                if self._startup is not None:
                    self._startup.fall_back_to_direct()
                failed_its += info.iterations
                msgs.append(info.message)
                info = self._try_increment(trial)
            dual_off = False
            if not info.converged and self.dual is not None and self.dual.active \
                    and not self.problem.error:
                # second attempt at the same dt with the consistent tangent (the primal-dual
                # direction is not always a descent direction of the residual norm), and the
                # line-search fallback below with it too
                log.info("t = %.6g: Newton failed with the primal-dual tangent (%s); retrying "
                         "dt = %.3g with the consistent tangent", self.t, info.message, trial)
                failed_its += info.iterations
                msgs.append(info.message)
                self.dual.active, dual_off = False, True
            try:
                if dual_off:
                    info = self._try_increment(trial)
                fb = self.solver_options.line_search_fallback
                if not info.converged and fb and fb != self.solver_options.line_search \
                        and not self.problem.error:
                    # another attempt at the same dt with the fallback line search
                    log.info("t = %.6g: Newton failed with the %s line search (%s); retrying "
                             "dt = %.3g with the %s line search", self.t,
                             self.solver_options.line_search, info.message, trial, fb)
                    failed_its += info.iterations
                    msgs.append(info.message)
                    self.solver.set_line_search(fb)
                    try:
                        info = self._try_increment(trial)
                    finally:
                        self.solver.set_line_search(self.solver_options.line_search)
            finally:
                if dual_off:
                    self.dual.active = True
            if info.converged and self._accept_geometry(trial, info):
                row = self._commit(trial, info)
                row["cutbacks"] = k
                # Newton iterations of the accepted attempt plus those of the failed attempts
                row["newton_iterations_all"] = info.iterations + failed_its
                row["wall_increment"] = time.perf_counter() - t0
                row["wall_increment_all"] = time.perf_counter() - t_first
                self._record(row)
                return IncrementResult(row, info)
            msg = info.message
            msgs.append(msg)
            failed_its += info.iterations
            log.warning("t = %.6g: Newton failed with dt = %.3g (%s); retrying with dt/2",
                        self.t, trial, _attempts(msgs[first:]))
            trial *= 0.5
        earlier = [m for m in dict.fromkeys(msgs[:-1]) if m != msgs[-1]] if msgs else []
        if earlier:
            msg += f" (earlier attempts: {' | '.join(earlier)})"
        raise self._increment_failure(trial * 2, msg)

    def _record(self, row):
        row.update(self.mesh_health())
        self.history.append(row)
        self._write_outputs(row)
        if self.checkpoint_every and self.increment % self.checkpoint_every == 0:
            self.write_checkpoint()

    def _update_output_fields(self):
        sp = self.space
        gd = sp.gdim
        varr = self.velocity.x.array.reshape(-1, gd)
        varr[self._p1_vertex] = self.w.x.array[sp.vertex_dofs]
        self.pressure.x.array[:] = self.w.x.array[sp.Q_to_W]
        if self.u is not None:
            self.displacement_out.x.array.reshape(-1, gd)[self._p1_vertex] = \
                self._vertex_displacement()

    def output_functions(self) -> list:
        fields = [self.velocity, self.pressure, self.strain, self.strain_rate]
        if self.displacement_out is not None:
            fields.append(self.displacement_out)
        for c in self.contributors:
            if hasattr(c, "output_fields"):
                fields.extend(c.output_fields())
        return fields

    def _write_fields(self):
        self._update_output_fields()
        for c in self.contributors:
            if hasattr(c, "update_output_fields"):
                c.update_output_fields()
        self._writer.write(self.output_functions(), self.t)

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
            from tqdm import tqdm
            bar = tqdm(total=t_end - self.t, desc=self.name, unit="s", leave=False,
                       bar_format="{l_bar}{bar}| {n:.4g}/{total:.4g} s "
                                  "[{elapsed}<{remaining}{postfix}]")
        n0, t0, wall0 = len(self.history), self.t, time.perf_counter()
        cur = dt
        if self._resume_step is not None:  # the step a resumed run would have taken next
            cur = min(dt, self._resume_step)
            self._resume_step = None
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
                 "%.1f s", self.name, t0, self.t, len(rows), sum(r["cutbacks"] for r in rows),
                 sum(r["newton_iterations_all"] for r in rows), time.perf_counter() - wall0)
        if close:
            self.close()
        return self.history

    def close(self):
        if self._writer is not None:
            self._writer.close()
            self._writer = None
        if self._history_writer is not None:
            self._history_writer.close()
            self._history_writer = None

    # ------------------------------------------------------------------------ outputs
    def _open_writers(self):
        from fxcontact.io import HistoryWriter, SeriesWriter
        if self._resumed is not None and not self._outputs_opened:
            self._drop_later_checkpoints()
        elif self._resumed is None and not self._outputs_opened:
            self._claim_output_dir()
        # a resumed run, or a run whose outputs an earlier run() closed: continue the outputs
        resumed = self._resumed is not None or self._outputs_opened
        self._outputs_opened = True
        self._writer = SeriesWriter(self.comm, self.output_dir, self.name,
                                    resume_time=self.t if resumed else None)
        self._history_writer = HistoryWriter(self.comm, self.output_dir, self.name,
                                             rows=self.history if resumed else None)
        if not resumed:
            self._write_fields()

    def _reopen_outputs(self):
        """Continue the CSV history and the VTK series that an earlier :meth:`run` closed (a
        second ``run()`` to a later ``t_end``)."""
        if self._outputs_opened and self._writer is None and self._history_writer is None:
            log.info("%s: continuing the outputs in %s from t = %.6g", self.name,
                     self.output_dir, self.t)
            self._open_writers()

    def _claim_output_dir(self):
        """Before a new run writes anything: the checkpoints of another run of the same name in
        ``output_dir`` are refused (CheckpointError on every rank), or removed with
        ``overwrite=True``."""
        from fxcontact.checkpoint import CheckpointError, list_checkpoints
        old = list_checkpoints(self.checkpoint_dir, self.name) if self.comm.rank == 0 else None
        old = self.comm.bcast(old, root=0)
        if not old:
            return
        if not self.overwrite:
            raise CheckpointError(
                f"{self.checkpoint_dir} holds checkpoints of another run named '{self.name}' "
                f"({', '.join(os.path.basename(p) for p in old)}): a new run would mix its outputs "
                f"and checkpoints with them. Continue that run with resume(), or start this one "
                f"in another output_dir or with another name, or pass overwrite=True to remove "
                f"them")
        log.warning("%s: overwrite=True: removing the checkpoints of the previous run %s",
                    self.name, ", ".join(os.path.basename(p) for p in old))
        self._remove_checkpoints(old)

    def _drop_later_checkpoints(self):
        """A run resumed from a checkpoint older than the newest: the later checkpoints (of
        the run that was then killed) are removed, with a warning, as its later CSV rows and VTK
        steps are dropped; otherwise the next resume() would take one of them."""
        from fxcontact.checkpoint import list_checkpoints
        if self._resumed_from != os.path.abspath(self.checkpoint_dir):
            return
        later = [p for p in list_checkpoints(self.checkpoint_dir, self.name)
                 if int(p.rsplit("_", 1)[1]) > self.increment] if self.comm.rank == 0 else None
        later = self.comm.bcast(later, root=0)
        if later:
            log.warning("%s: resumed at increment %d: removing the later checkpoints %s",
                        self.name, self.increment, ", ".join(os.path.basename(p) for p in later))
            self._remove_checkpoints(later)

    def _remove_checkpoints(self, paths):
        if self.comm.rank == 0:
            for p in paths:
                shutil.rmtree(p, ignore_errors=True)
        self.comm.barrier()

    def _write_outputs(self, row):
        """CSV row and VTK step of an accepted increment; a failed write (full disk…) stops the
        run on every rank with an :class:`OutputError`, the files written so far untouched."""
        err = None
        try:
            if self._history_writer is not None:
                self._history_writer.write(row)
            if self._writer is not None and self.increment % self.output_every == 0:
                self._write_fields()
        except OSError as e:
            err = f"{type(e).__name__}: {e}"
        errs = [e for e in self.comm.allgather(err) if e]
        if errs:
            where = os.path.join(self.output_dir, self.name) if self.output_dir else self.name
            raise OutputError(
                f"writing the outputs of increment {self.increment} (t = {self.t:.6g}) failed "
                f"({errs[0]}); what was written before is intact ({where}_history.csv, "
                f"{where}.pvd). Free disk space and resume from the last checkpoint")

    # ------------------------------------------------------------------------ mesh health
    def _init_mesh_health(self):
        """Owned cells' vertices and their signed measures on the initial geometry."""
        tdim = self.mesh.topology.dim
        nown = self.mesh.topology.index_map(tdim).size_local
        self._c2v_owned = compat.cell_vertices(self.mesh)[:nown]
        X = self.space.vertex_positions()
        vol0, q0 = self._cell_measures(X)
        msg = _initial_mesh_error(self.mesh, X, self._c2v_owned, vol0, q0)
        msgs = [m for m in self.comm.allgather(msg) if m]   # raised on every rank
        if msgs:
            raise ValueError(msgs[0])
        self._vol0 = vol0

    def _cell_measures(self, X: np.ndarray):
        """Signed measure and shape quality of the owned cells for the vertex positions X
        (:func:`fxcontact.mesh_health.simplex_measures`)."""
        from fxcontact.mesh_health import simplex_measures
        return simplex_measures(X[self._c2v_owned])

    def _health(self, X: np.ndarray):
        """(min signed quality, min volume ratio, local index of the worst cell) (local)."""
        vol, q = self._cell_measures(X)
        ratio = vol / self._vol0
        qs = np.sign(ratio) * q
        if len(ratio) == 0:
            return math.inf, math.inf, -1
        i = int(np.argmin(ratio))
        return float(np.min(qs)), float(ratio[i]), i

    def mesh_health(self) -> Dict[str, float]:
        """Mesh quality of the current configuration (collective): ``min_quality`` (shape
        quality, negative for an inverted cell) and ``min_volume_ratio`` (signed cell volume
        over its initial volume) — history columns of every increment."""
        q, r, _ = self._health(self.vertex_positions())
        q = self.comm.allreduce(q, op=MPI.MIN)
        r = self.comm.allreduce(r, op=MPI.MIN)
        return {"min_quality": q, "min_volume_ratio": r}

    def _accept_geometry(self, dt: float, info: SolveInfo) -> bool:
        """Check the geometry the converged increment would give before accepting it: an
        inverted cell marks the attempt failed (cut-back) with a message saying where and when."""
        if not self.check_inversion or self.u is not None:
            return True
        sp = self.space
        self.w.x.scatter_forward()
        x_t = self.vertex_positions()
        X = self.kinematics.positions(x_t, self.w.x.array[sp.vertex_dofs], dt)
        _, r, i = self._health(X)
        # the cell is located by its centroid at the start of the increment (the last output)
        worst = self.comm.allgather((r, None if i < 0 else x_t[self._c2v_owned[i]].mean(axis=0)))
        r_min, c = min(worst, key=lambda a: a[0])
        if r_min > 0.0:
            return True
        info.converged = False
        info.message = (f"{_INVERSION}: the cell with centroid {np.array2string(c, precision=4)} "
                        f"would turn inside out (signed volume / initial volume = {r_min:.3g}) at "
                        f"t = {self.t + dt:.6g} (increment {self.increment + 1}, dt = {dt:.3g}); "
                        f"the velocity field is too distorted for this step: reduce dt or remesh")
        log.warning("t = %.6g: %s", self.t, info.message)
        return False

    def _increment_failure(self, dt: float, msg: str) -> IncrementError:
        """The error of an increment that failed for good; a checkpoint of the last accepted
        state is written first (when checkpoints are on) so the run can be resumed from it."""
        if self.checkpoint_every:
            path = self._checkpoint_path()
            try:
                if not os.path.isdir(path):
                    self.write_checkpoint()
            except OSError as e:
                log.warning("checkpoint at the failed increment not written: %s", e)
        cls = MeshInversionError if msg.startswith(_INVERSION) else IncrementError
        return cls(self.t, dt, msg)

    # ------------------------------------------------------------------------ checkpoints
    @property
    def checkpoint_dir(self) -> str:
        if self.output_dir is None:
            raise ValueError("checkpoints need an output_dir")
        return os.path.join(self.output_dir, "checkpoints")

    def _checkpoint_path(self, increment: Optional[int] = None) -> str:
        inc = self.increment if increment is None else increment
        return os.path.join(self.checkpoint_dir, f"{self.name}_{inc:06d}")

    def _checkpoint_keys(self):
        """Partition-independent keys of the saved arrays (computed once)."""
        if self._ckpt_keys is None:
            from fxcontact.checkpoint import dof_keys, vertex_keys
            sp, msh = self.space, self.mesh
            n = len(self.w.x.array)
            leaves = [(k, sp.W.sub(0).sub(k)) for k in range(sp.gdim)] + [(sp.gdim, sp.W.sub(1))]
            wk = dof_keys(msh, leaves, n)
            ck = dof_keys(msh, [(0, sp.DG0)], len(self.strain.x.array))
            xk = np.asarray(msh.geometry.input_global_indices, dtype=np.int64)[:, None]
            tdim = msh.topology.dim
            own = (sp.num_owned_dofs, msh.topology.index_map(tdim).size_local,
                   msh.geometry.index_map().size_local)
            self._ckpt_keys = dict(w=wk, c=ck, x=xk, own=own, v=vertex_keys(msh))
        return self._ckpt_keys

    def _setup_signature(self) -> dict:
        """What a checkpoint is resumed only with (as read back from JSON): the space, the
        material and its parameters, the velocity conditions, the contributors and their
        parameters (``setup_signature()``, e.g. a contact's penalty, friction and tools)."""
        import json
        from fxcontact.checkpoint import _json_default, describe
        sp = self.space
        sig = {"element": sp.element, "gdim": sp.gdim, "dofs": sp.global_dofs(),
               "material": type(self.material).__name__,
               "small_strain": bool(self.material.small_strain),
               "contributors": [type(c).__name__ for c in self.contributors],
               "material_parameters": describe(self.material),
               "volume_correction": self.volume_correction,
               "velocity_bcs": [describe(b.value) for b in self._bcs],
               "contributor_parameters": [c.setup_signature() if hasattr(c, "setup_signature")
                                          else None for c in self.contributors]}
        return json.loads(json.dumps(sig, default=_json_default))

    def write_checkpoint(self, path: Optional[str] = None) -> str:
        """Write a checkpoint of the current (accepted) state (collective); returns its path.

        Default path: ``output_dir/checkpoints/<name>_<increment>``; older ones beyond
        ``checkpoint_keep`` are removed.
        """
        from fxcontact import __version__
        from fxcontact import checkpoint as ck
        self._build()
        keys = self._checkpoint_keys()
        now, ncown, nxown = keys["own"]
        sp = self.space
        arrays = {"w_key": keys["w"][:now], "w_prev": self.w_prev.x.array[:now],
                  "c_key": keys["c"][:ncown], "strain": self.strain.x.array[:ncown],
                  "strain_rate": self.strain_rate.x.array[:ncown],
                  "x_key": keys["x"][:nxown], "x": self.mesh.geometry.x[:nxown]}
        if self.u is not None:
            uW = np.zeros(len(self.w.x.array))
            uW[sp.V_to_W] = self.u.x.array
            arrays["u"] = uW[:now]
        states = []
        for i, c in enumerate(self.contributors):
            st = {}
            if hasattr(c, "checkpoint_state"):
                for k, val in c.checkpoint_state().items():
                    if isinstance(val, ck.PerVertex):
                        arrays[f"c{i}.{k}.key"] = keys["v"][np.asarray(val.vertices)][:, None]
                        arrays[f"c{i}.{k}.val"] = np.asarray(val.values)
                        st[k] = {"per_vertex": True}
                    else:
                        st[k] = {"value": val.tolist() if isinstance(val, np.ndarray) else val,
                                 "array": isinstance(val, np.ndarray)}
            elif not getattr(self, "_warned_stateless", False):
                log.warning("contributor %s has no checkpoint_state(): it is assumed to keep "
                            "no state between increments", type(c).__name__)
            states.append(st)
        self._warned_stateless = True
        controllers = [{"type": type(c).__name__,
                        "state": _plain_state(c.checkpoint_state())
                        if hasattr(c, "checkpoint_state") else None}
                       for c in self.controllers]
        kin = self.kinematics
        last = self.history[-1] if self.history else None
        manifest = {"format": ck.FORMAT_VERSION, "fxcontact": __version__, "name": self.name,
                    "t": self.t, "increment": self.increment, "history": self.history,
                    "next_step": (2.0 * last["dt"] if last is not None and last.get("cutbacks")
                                  else None),
                    "mesh": ck.mesh_fingerprint(self.mesh, self._x_ref),
                    "setup": self._setup_signature(), "contributors": states,
                    "controllers": controllers,
                    "kinematics": (_plain_state(kin.checkpoint_state())
                                   if hasattr(kin, "checkpoint_state") else None),
                    "volume_initial": self._volume_initial}
        path = path or self._checkpoint_path()
        if self.comm.rank == 0:
            os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
        try:
            ck.write(self.comm, path, manifest, arrays)
        except OSError as e:
            prev = ck.latest_checkpoint(os.path.dirname(os.path.abspath(path)), self.name)
            raise OutputError(f"{e} (increment {self.increment}, t = {self.t:.6g}); the previous "
                              f"checkpoint {prev} is intact") from e
        if self.output_dir is not None and path == self._checkpoint_path():
            ck.prune(self.comm, self.checkpoint_dir, self.name, self.checkpoint_keep)
        self.comm.barrier()
        log.info("checkpoint written: %s", path)
        return path

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
        from fxcontact import __version__
        from fxcontact import checkpoint as ck
        from fxcontact.checkpoint import CheckpointError
        if self._built:
            raise RuntimeError("resume() must be called after the set-up and before the first "
                               "step()/run()")
        if path is None:
            path = ck.latest_checkpoint(self.checkpoint_dir, self.name)
            if path is None:
                raise CheckpointError(f"no checkpoint of run '{self.name}' in "
                                      f"{self.checkpoint_dir}")
        elif not os.path.isfile(os.path.join(path, "manifest.json")) and \
                ck.latest_checkpoint(path) is not None:
            path = ck.latest_checkpoint(path)
        # a truncated or altered file: refused, naming the newest intact checkpoint
        ck.check_intact(self.comm, path, self.name)
        man = ck.read_manifest(path)
        if man.get("format") != ck.FORMAT_VERSION or man.get("fxcontact") != __version__:
            raise CheckpointError(
                f"checkpoint {path} was written by another version (checkpoint format "
                f"{man.get('format')}, fxcontact {man.get('fxcontact')}; this is format "
                f"{ck.FORMAT_VERSION}, fxcontact {__version__}): restart the run from t = 0")
        fp = ck.mesh_fingerprint(self.mesh, self._x_ref)
        if man.get("mesh") != fp:
            raise CheckpointError(
                f"checkpoint {path} was written for a different mesh ({man.get('mesh')}; this "
                f"mesh: {fp}): build the same initial mesh as the checkpointed run")
        saved = [c["type"] for c in man.get("controllers", [])]
        mine = [type(c).__name__ for c in self.controllers]
        if saved != mine:
            raise CheckpointError(f"checkpoint {path} was written with the controllers {saved}; "
                                  f"this simulation has {mine}: register the same controllers "
                                  f"(add_controller), in the same order, as the checkpointed run")
        for i, (c, e) in enumerate(zip(self.controllers, man.get("controllers", []))):
            if e["state"] is not None and not hasattr(c, "restore_state"):
                raise CheckpointError(f"checkpoint {path} holds a state for controller "
                                      f"{type(c).__name__} #{i}, which cannot restore it")
            if e["state"] is None and hasattr(c, "restore_state"):
                raise CheckpointError(f"checkpoint {path} holds no state for controller "
                                      f"{type(c).__name__} #{i}")
        # after the controllers: their message is the more specific
        sig = self._setup_signature()
        if man.get("setup") != sig:
            diff = ck.signature_differences(man.get("setup") or {}, sig)
            raise CheckpointError(f"checkpoint {path} was written for a different set-up: "
                                  f"{'; '.join(diff)}. Resume with the set-up of the "
                                  f"checkpointed run, or start a new run (another output_dir "
                                  f"or name, or overwrite=True)")
        arrays = ck.read_arrays(path, int(man["nranks"]))
        keys = self._checkpoint_keys()
        sp = self.space
        tw = ck.KeyTable(arrays["w_key"], arrays["w_prev"])
        self.w_prev.x.array[:] = tw.lookup(keys["w"], "the solution")
        self.w.x.array[:] = self.w_prev.x.array
        tc = ck.KeyTable(arrays["c_key"], np.c_[arrays["strain"], arrays["strain_rate"]])
        sc = tc.lookup(keys["c"], "the strain")
        self.strain.x.array[:] = sc[:, 0]
        self.strain_rate.x.array[:] = sc[:, 1]
        tx = ck.KeyTable(arrays["x_key"], arrays["x"])
        self.mesh.geometry.x[:] = tx.lookup(keys["x"], "the geometry")
        if self.u is not None:
            tu = ck.KeyTable(arrays["w_key"], arrays["u"])
            self.u.x.array[:] = tu.lookup(keys["w"], "the displacement")[sp.V_to_W]
        for i, (c, st) in enumerate(zip(self.contributors, man["contributors"])):
            if not st:
                continue
            if not hasattr(c, "restore_state"):
                raise CheckpointError(f"checkpoint {path} holds a state for contributor "
                                      f"{type(c).__name__} #{i}, which cannot restore it")
            state = {}
            for k, e in st.items():
                if e.get("per_vertex"):
                    table = ck.KeyTable(arrays[f"c{i}.{k}.key"], arrays[f"c{i}.{k}.val"])
                    state[k] = ck.VertexLookup(table, keys["v"][:, None],
                                               f"{type(c).__name__}.{k}")
                else:
                    state[k] = np.asarray(e["value"]) if e.get("array") else e["value"]
            c.restore_state(state)
        for i, (c, e) in enumerate(zip(self.controllers, man.get("controllers", []))):
            if e["state"] is not None:
                try:
                    c.restore_state(e["state"])
                except (KeyError, TypeError, ValueError) as err:
                    raise CheckpointError(f"checkpoint {path}: the state of controller "
                                          f"{type(c).__name__} #{i} does not fit this one: "
                                          f"{err}") from None
        kin = man.get("kinematics")
        if kin is not None and hasattr(self.kinematics, "restore_state"):
            self.kinematics.restore_state(kin)
        self.t = float(man["t"])
        self.increment = int(man["increment"])
        self.history = [dict(r) for r in man["history"]]
        self._resume_step = man.get("next_step")
        self._resumed = man
        self._resumed_from = os.path.dirname(os.path.abspath(path))
        self._build()
        # the volume correction is relative to the initial volume of the body, not to the
        # volume at the checkpoint
        if man.get("volume_initial") is not None:
            self._volume_initial = float(man["volume_initial"])
            self._update_volume_correction()
        log.info("resumed %s from %s: t = %.6g, increment %d", self.name, path, self.t,
                 self.increment)
        return path
