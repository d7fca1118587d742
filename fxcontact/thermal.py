"""Heat in a simulation: the workpiece's temperature computed with the mechanics, staggered per
increment (THEORY §16.6).

:class:`WorkpieceHeat` is a controller (``Simulation.add_controller``). At each accepted
increment, before the geometry moves, it hands the heat problem
(:class:`~fxcontact.heat.HeatProblem`) the sources of that increment on the configuration that
produced them: the plastic power η_q s:ε̇ per cell, and at each contact node in contact the
exchange with its tool (h_c, the tool's temperature, the contact's own nodal area S_n) and the
workpiece's share β_f = b_w/(b_w + b_t) of the node's friction power r_f·Δv_t. The temperature
it returns is the next increment's: the flow stress of a :class:`~fxcontact.materials.
Viscoplastic` material reads the cell averages (``Simulation.cell_temperature``), explicit in
the state as ε̄ is (THEORY §15).

Units: N, mm, s, °C; ρc in N/(mm² K), k in N/(s K), h in N/(mm s K), heat in N mm (= mJ).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Dict, Optional

import dolfinx
import numpy as np
import ufl
from mpi4py import MPI
from petsc4py import PETSc

from fxcontact import compat
from fxcontact.collective import describe, digest, together
from fxcontact.heat import HeatProblem, ThermalMaterial
from fxcontact.io.keys import CheckpointError, PerVertex
from fxcontact.remesh.transfer import interpolate_from

__all__ = ["HeatSetup", "ToolHeat", "WorkpieceHeat"]


@dataclass(frozen=True)
class ToolHeat:
    """A rigid tool's thermal data (the tool keeps its temperature).

    Args:
        temperature: the tool's temperature [°C].
        h_c: the contact heat-transfer coefficient [N/(mm s K)] (= 10⁻³ × W/(m² K): a die in good
            contact 5–20).
        effusivity: the tool's b_t = √(k ρc) [N/(mm s^½ K)] that shares the friction heat,
            β_f = b_w/(b_w + b_t); None: the workpiece's own (β_f = ½).
    """

    temperature: float
    h_c: float
    effusivity: Optional[float] = None

    def __post_init__(self):
        for name, value, unit in (("temperature", self.temperature, "°C"),
                                  ("h_c", self.h_c, "N/(mm s K)")):
            if not (isinstance(value, (int, float, np.floating, np.integer))
                    and math.isfinite(value)):
                raise ValueError(f"ToolHeat.{name} must be a finite number in {unit}, got "
                                 f"{value!r}")
        if self.h_c < 0:
            raise ValueError(f"ToolHeat.h_c must be >= 0 N/(mm s K), got {self.h_c!r}")
        if self.temperature < -273.15:
            raise ValueError(f"ToolHeat.temperature {self.temperature} °C is below absolute "
                             f"zero: temperatures are in °C")
        if self.effusivity is not None and not (math.isfinite(self.effusivity)
                                                and self.effusivity >= 0):
            raise ValueError(f"ToolHeat.effusivity must be finite and >= 0 "
                             f"N/(mm s^½ K), got {self.effusivity!r}")


@dataclass(frozen=True)
class HeatSetup:
    """A process case's thermal set-up (``heat=`` of the cases of :mod:`fxcontact.processes`):
    what :class:`WorkpieceHeat` needs but the mesh.

    Args:
        thermal: the workpiece's :class:`~fxcontact.heat.ThermalMaterial`.
        initial_temperature: T⁰ of the workpiece [°C].
        air: the :class:`~fxcontact.heat.AirExchange` of the free surface (the process says
            which faces are free: symmetry planes stay insulated), or None (insulated).
        tools: {tool name: :class:`ToolHeat`}; a tool's name is the process's (``die``,
            ``base``, ``roll``, ...): an unknown name is refused when the process builds.
        probes: {label: (x, y, z)} material points [mm] whose temperature the history follows
            (``heat_T_at_{label}``; see :class:`WorkpieceHeat`).
    """

    thermal: ThermalMaterial
    initial_temperature: float
    air: object = None
    tools: Optional[Dict[str, ToolHeat]] = None
    probes: Optional[Dict[str, tuple]] = None

    def __post_init__(self):
        if not isinstance(self.thermal, ThermalMaterial):
            raise ValueError(f"HeatSetup.thermal must be a fxcontact.ThermalMaterial, got "
                             f"{self.thermal!r}")
        T0 = self.initial_temperature
        if not (isinstance(T0, (int, float, np.floating, np.integer)) and math.isfinite(T0)
                and T0 >= -273.15):
            raise ValueError(f"HeatSetup.initial_temperature must be a temperature in °C, got "
                             f"{T0!r}")

    def attach(self, sim, facet_tags, free_tags, tool_names) -> "WorkpieceHeat":
        """The :class:`WorkpieceHeat` of this set-up on ``sim``, added as its controller:
        ``free_tags`` the facet tags of the free surface (air), ``tool_names`` the process's
        tools (a ValueError names an entry of ``tools`` that is none of them)."""
        unknown = sorted(set(self.tools or {}) - set(tool_names))
        if unknown:
            raise ValueError(f"HeatSetup.tools names {unknown}, which are not tools of this "
                             f"process: {sorted(tool_names)}")
        air = None if self.air is None else {int(t): self.air for t in free_tags}
        heat = WorkpieceHeat(sim, self.thermal, float(self.initial_temperature), air=air,
                             facet_tags=facet_tags if air is not None else None,
                             tools=self.tools, probes=self.probes)
        sim.add_controller(heat)
        return heat


class WorkpieceHeat:
    """The workpiece's temperature in a :class:`~fxcontact.simulation.Simulation` (a controller:
    ``sim.add_controller(WorkpieceHeat(sim, ...))``; THEORY §16).

    Args:
        sim: the simulation (an updated-Lagrangian material: heat on a small-strain material is
            refused).
        thermal: the workpiece's :class:`~fxcontact.heat.ThermalMaterial` (ρc, k, η_q).
        initial_temperature: T⁰ [°C], a number or a function of the points (as
            :class:`~fxcontact.heat.HeatProblem`).
        air: the free surface's :class:`~fxcontact.heat.AirExchange`, or {facet tag:
            AirExchange} with ``facet_tags``; None: insulated.
        facet_tags: the body's facet tags (for ``air`` by tag).
        tools: {tool name: :class:`ToolHeat`} for the tools of the simulation's contacts; a
            tool without an entry exchanges no heat (its friction heat still enters the body,
            shared half-half).
        solver: the heat problem's linear solver ("cg": CG + AMG with a direct fall-back,
            "direct").
        name: the prefix of the history columns.
        probes: {label: (x, y, z)} material points [mm] followed through the run: each is the
            body's vertex nearest to the point when the heat is set up, followed as the mesh
            moves (and, after a remesh, the new mesh's vertex nearest to where it had gone);
            its temperature is the history column ``{name}_T_at_{label}`` [°C] — the T(t)
            curve of a thermocouple in the part.

    History columns (per increment): ``{name}_T_min``, ``_T_mean``, ``_T_max`` [°C] and the
    increment's heat balance [N mm]: ``_stored``, ``_generated`` (plastic work × η_q),
    ``_friction`` (the body's share), ``_air``, ``_radiation``, ``_tools`` (all flows > 0 into
    the body) and ``_residual`` (stored minus their sum: the linear solver's tolerance);
    ``_wall`` the heat step's wall time [s] (sources, solve, cell temperatures).
    """

    def __init__(self, sim, thermal: ThermalMaterial, initial_temperature, air=None,
                 facet_tags=None, tools: Optional[Dict[str, ToolHeat]] = None,
                 solver: str = "cg", name: str = "heat", probes=None):
        T0 = initial_temperature
        # the same checks on every rank, raised on every rank; the thermal set-up compared
        # between ranks (a rank with other values would compute another heat silently)
        with together(sim.comm, "WorkpieceHeat()", name=name, thermal=digest(thermal),
                      air=digest(air), tools=digest(tools), probes=digest(probes),
                      initial_temperature=digest(T0) if not callable(T0) else "function"):
            if sim.material.small_strain:
                raise ValueError("heat needs an updated-Lagrangian material (Norton-Hoff, "
                                 "Viscoplastic): a small-strain material has no heat coupling")
            if not isinstance(thermal, ThermalMaterial):
                raise ValueError(f"thermal must be a fxcontact.ThermalMaterial, got "
                                 f"{thermal!r}")
            for k, v in dict(tools or {}).items():
                if not isinstance(v, ToolHeat):
                    raise ValueError(f"tools[{k!r}] must be a fxcontact.ToolHeat, got {v!r}")
            if any(isinstance(c, WorkpieceHeat) for c in sim.controllers):
                raise ValueError("the simulation already has a WorkpieceHeat: one heat "
                                 "problem per workpiece")
            probes = _checked_probes(probes, sim.space.gdim)
        tools = dict(tools or {})
        self.thermal = thermal
        self.air = air
        self.tools = tools
        self.solver = solver
        self.name = name
        self.balance: Dict[str, float] = {}
        self._sim = sim
        self._probe_points = probes       # label -> where the followed point is now [mm]
        self._bind(sim.space, facet_tags, initial_temperature)

    # ---------------------------------------------------------------------------- binding
    def _bind(self, space, facet_tags, T0):
        sim = self._sim
        self._facet_tags = facet_tags
        self.problem = HeatProblem(space.mesh, self.thermal, T0, air=self.air,
                                   facet_tags=facet_tags, solver=self.solver)
        q0 = ufl.TestFunction(space.DG0)
        eps = ufl.sym(ufl.grad(ufl.split(sim.w)[0]))
        self._power_form = compat.form(ufl.inner(sim.material.stress_ufl(eps), eps) * q0
                                       * space.dx)
        self._volume_form = compat.form(q0 * space.dx)
        msh = space.mesh
        imap = msh.topology.index_map(msh.topology.dim)
        ncells = imap.size_local + imap.num_ghosts
        self._dg0_dofs = np.asarray(space.DG0.dofmap.list.array).reshape(ncells, -1)[:, 0]
        self._cell_T_dofs = compat.dofmap_array(self.problem.V)[:ncells]
        self._set_cell_temperature()
        self._locate_probes()

    def _locate_probes(self):
        """Each probe's vertex: the owned P1 dof nearest to its point, on the rank nearest
        (ties to the lowest rank; collective)."""
        p, comm = self.problem, self._sim.comm
        X = p.dof_coordinates()[:p.n_owned]
        self._probe_dofs = {}
        for label, point in self._probe_points.items():
            P = np.asarray(point, float)[:3]
            d = np.linalg.norm(X[:, :len(P)] - P, axis=1) if len(X) else np.zeros(0)
            k = int(np.argmin(d)) if len(d) else -1
            best = comm.allreduce((float(d[k]) if k >= 0 else math.inf, comm.rank),
                                  op=MPI.MIN)
            if best[1] == comm.rank and k >= 0:
                self._probe_dofs[label] = k

    def remesh(self, space, facet_tags):
        """Rebind to the new mesh (``Simulation.remesh``): the temperature interpolated from the
        old mesh (collective)."""
        old = self.problem
        self._probe_values()       # where the probes are now, to find them on the new mesh
        self._bind(space, facet_tags if self._facet_tags is not None else None,
                   float(old.mean_temperature()))
        interpolate_from(old.T, self.problem.T)
        old.close()
        self._set_cell_temperature()

    def _set_cell_temperature(self):
        T = self.problem.T.x.array
        cell = np.empty(len(self._dg0_dofs))
        cell[self._dg0_dofs] = T[self._cell_T_dofs].mean(axis=1)
        self._sim.cell_temperature = cell

    @property
    def temperature(self):
        """The P1 temperature Function [°C] on the current mesh."""
        return self.problem.T

    # ---------------------------------------------------------------------- the increment
    def _plastic_power(self) -> np.ndarray:
        """s:ε̇ per cell [N/(mm² s)] of the converged increment (cell averages)."""
        out = []
        for frm in (self._power_form, self._volume_form):
            b = dolfinx.fem.petsc.assemble_vector(frm)
            b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
            b.ghostUpdate(addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)
            with b.localForm() as loc:
                out.append(loc.array.copy())
            b.destroy()
        return out[0] / out[1]

    def _contact_terms(self, sim):
        """(contact entries by tool, friction heat (dofs, Q)) of the contacts' last state."""
        entries, fdofs, fq = {}, [], []
        heat = self.problem
        for c in sim.contributors:
            nodes = getattr(c, "nodes", None)
            if nodes is None or not hasattr(c, "tools"):
                continue
            active = np.asarray(nodes.active, dtype=bool)
            dofs = heat.dofs_of_vertices(nodes.vertices)
            fp = c.node_friction_power() if getattr(c, "has_friction", False) else None
            for k, tool in enumerate(c.tools):
                spec = self.tools.get(tool.name)
                sel = active & (np.asarray(nodes.tool) == k)
                if spec is not None:
                    entries[tool.name] = (dofs[sel], spec.h_c, spec.temperature,
                                          np.asarray(nodes.area)[sel])
                if fp is not None:
                    share = 0.5 if spec is None or spec.effusivity is None else \
                        self.thermal.heat_share(spec.effusivity)
                    fdofs.append(dofs[sel])
                    fq.append(share * fp[sel])
        nodal = (np.concatenate(fdofs), np.concatenate(fq)) if fdofs else None
        return entries, nodal

    def commit_increment(self, sim, dt: float):
        """The heat step of an accepted increment, on its configuration (collective)."""
        if sum(isinstance(c, WorkpieceHeat) for c in sim.controllers) > 1:
            raise ValueError("the simulation has several WorkpieceHeat controllers: one heat "
                             "problem per workpiece (each would add the same heat)")
        t0 = time.perf_counter()
        source = self.thermal.taylor_quinney * self._plastic_power()
        entries, nodal = self._contact_terms(sim)
        for name in self.tools:
            entries.setdefault(name, (np.zeros(0, dtype=np.int64), 0.0, 0.0, np.zeros(0)))
        bal = self.problem.step(dt, source=source, contact=entries or None, nodal_heat=nodal)
        self._set_cell_temperature()
        tools = sum(bal.get("tools", {}).values())
        self.balance = {"stored": bal["stored"], "generated": bal["generated"],
                        "friction": bal["nodal"], "air": bal["air"],
                        "radiation": bal["radiation"], "tools": tools,
                        "residual": bal["residual"], "wall": time.perf_counter() - t0}

    def diagnostics(self) -> Dict[str, float]:
        p = self.problem
        out = {f"{self.name}_T_min": p.min_temperature(), f"{self.name}_T_mean":
               p.mean_temperature(), f"{self.name}_T_max": p.max_temperature()}
        out.update({f"{self.name}_{k}": v for k, v in self.balance.items()})
        out.update(self._probe_values())
        return out

    def _probe_values(self) -> Dict[str, float]:
        """T at the probes, and where they are now (kept for a remesh; collective)."""
        if not self._probe_points:
            return {}
        labels = list(self._probe_points)
        X = self.problem.dof_coordinates()
        buf = np.zeros((len(labels), 4))
        for i, label in enumerate(labels):
            k = self._probe_dofs.get(label)
            if k is not None:
                buf[i] = (self.problem.T.x.array[k], *X[k, :3])
        buf = self._sim.comm.allreduce(buf, op=MPI.SUM)
        self._probe_points = {label: tuple(buf[i, 1:]) for i, label in enumerate(labels)}
        return {f"{self.name}_T_at_{label}": float(buf[i, 0]) for i, label in enumerate(labels)}

    # ------------------------------------------------------------------------ checkpoints
    def checkpoint_state(self) -> dict:
        """The temperature of the owned vertices (:mod:`fxcontact.checkpoint`)."""
        p = self.problem
        v2d = np.asarray(p.vertex_to_dof)
        owned = np.flatnonzero(v2d < p.n_owned)
        return {"name": self.name, "T": PerVertex(owned, p.T.x.array[v2d[owned]].copy())}

    def restore_state(self, state: dict):
        if state.get("name") != self.name:
            raise CheckpointError(f"the checkpoint's heat is '{state.get('name')}', this one "
                                  f"'{self.name}'")
        p = self.problem
        v2d = np.asarray(p.vertex_to_dof)
        p.T.x.array[v2d] = state["T"].at(np.arange(len(v2d)))
        p.T.x.scatter_forward()
        self._set_cell_temperature()

    def setup_signature(self) -> dict:
        """The thermal parameters as given: a checkpoint is resumed only with the same."""
        return {"name": self.name, "thermal": describe(self.thermal),
                "air": describe(self.air), "tools": describe(self.tools)}

    def output_fields(self) -> list:
        return [self.problem.T]

    def summary(self) -> str:
        p = self.problem
        return (f"heat: T {p.min_temperature():.1f}..{p.max_temperature():.1f} °C (mean "
                f"{p.mean_temperature():.1f}), heat stored {p.energy():.4g} N mm")


def _checked_probes(probes, gdim: int) -> Dict[str, tuple]:
    """{label: point} checked: labels are names (letters, digits, ``_``), points finite
    [mm] in the mesh's dimension."""
    out = {}
    if probes is None:
        return out
    if not isinstance(probes, dict):
        raise ValueError(f"probes must be a dict {{label: (x, y, z) in mm}}, got {probes!r}")
    for label, point in probes.items():
        if not (isinstance(label, str) and label.replace("_", "a").isalnum()):
            raise ValueError(f"a probe's label must be a name of letters, digits and '_' (it "
                             f"becomes a history column), got {label!r}")
        try:
            x = np.asarray(point, dtype=float).ravel()
        except (TypeError, ValueError):
            x = np.zeros(0)
        if x.shape != (gdim,) or not np.all(np.isfinite(x)):
            raise ValueError(f"probes[{label!r}] must be a finite point of {gdim} coordinates "
                             f"in mm, got {point!r}")
        out[label] = tuple(float(v) for v in x)
    return out
