"""What a :class:`~fxcontact.contact.NodalContact` gives out and takes back: the per-node view
of its state (:attr:`~NodalContactIO.nodes`), history columns, tool forces and torques, VTK
fields, its line of the run's summary, the message naming what changes over a Newton cycle or
how to turn a misplaced tool, the checkpoint state and the set-up signature, and the state
carried to a new mesh of the body (``remesh``).

:class:`NodalContactIO` is a mixin of :class:`~fxcontact.contact.NodalContact`: its methods read
the contact's state of the last evaluation (``_h``, ``_tool``, ``_r``, ``_rf``, ``_tau`` …);
code outside :mod:`fxcontact.contact` reads it through :attr:`~NodalContactIO.nodes`.
"""

from __future__ import annotations

import logging
from typing import Dict

import dolfinx.fem
import numpy as np
from mpi4py import MPI
from scipy.spatial import cKDTree

from fxcontact import compat
from fxcontact.collective import describe
from fxcontact.contact.friction import LAW_NONE
from fxcontact.contact.view import ContactNodes
from fxcontact.io.keys import CheckpointError, PerVertex
from fxcontact.kinematics import pad3
from fxcontact.tools.base import unit_vector

log = logging.getLogger("fxcontact.contact")

__all__ = ["NodalContactIO", "STICK_FACTOR"]

#: a node sticks if its slip speed |Δv_t| is below this many v₀ (diagnostics only)
STICK_FACTOR = 3.0


def flip_hint(tool) -> str:
    """How to turn a tool's surface the other way (:meth:`NodalContact._check_placement`)."""
    base = getattr(tool, "tool", tool)   # a MovedTool's tool
    if hasattr(base, "normal") and not hasattr(base, "inside"):
        return (f"flip the normal (normal={tuple(0.0 - float(v) for v in base.normal)}: it must "
                f"point out of the tool, towards the body)")
    if hasattr(base, "inside"):
        return f"set inside={not base.inside} (inside=True: the body is inside the surface)"
    return "flip the orientation of its surface (its normals must point towards the body)"


class NodalContactIO:
    """Outputs, messages and checkpoints of a nodal contact (mixin of ``NodalContact``)."""

    # ------------------------------------------------------------------ diagnostics / output
    @property
    def nodes(self) -> ContactNodes:
        """The contact nodes this rank owns and their state at the last evaluation: positions,
        gaps (mm, negative: penetration), normals, closest points on the tools, normal and
        friction forces per node (N), tools, nodal areas (mm²) — a
        :class:`~fxcontact.contact.view.ContactNodes` of read-only arrays (no copy)."""
        return self._nodes

    def pressures(self) -> np.ndarray:
        """(N,) nodal contact pressures ρ[h]₊ of the last evaluation."""
        if self.rho is None:  # before the first increment resolves ρ from β
            return np.zeros_like(self._h)
        return self.rho * self.penalty_scale * np.maximum(self._h, 0.0)

    def diagnostics(self) -> Dict[str, float]:
        comm = self.boundary.comm
        b = self.boundary
        act = self._h > 0
        pmax = comm.allreduce(float(np.max(self.dt * self._h, initial=-np.inf)), op=MPI.MAX)
        tpen = comm.allreduce(getattr(self, "_true_pen", -np.inf), op=MPI.MAX)
        out = {f"{self.name}_penetration_predicted": max(pmax, 0.0),
               f"{self.name}_penetration_true": max(tpen, 0.0),
               f"{self.name}_nodes": comm.allreduce(int(np.sum(act)), op=MPI.SUM),
               f"{self.name}_area": comm.allreduce(float(np.sum(b.areas[act])), op=MPI.SUM),
               f"{self.name}_pressure_max": comm.allreduce(
                   float(np.max(self.pressures(), initial=0.0)), op=MPI.MAX),
               # projections that fell back to the flat facet (faceted Nagata tools): at the
               # accepted iterate, and summed over every evaluation of the increment
               f"{self.name}_fallbacks": comm.allreduce(self._fallbacks, op=MPI.SUM),
               f"{self.name}_fallbacks_all": comm.allreduce(self._fallbacks_all, op=MPI.SUM)}
        # a run in which no node ever touched a tool is said in the summary
        self._increments_seen = getattr(self, "_increments_seen", 0) + 1
        self._ever_touched = getattr(self, "_ever_touched", False) or out[f"{self.name}_nodes"] > 0
        for k, tool in enumerate(self.tools):
            F = self.tool_force(k)
            for j, c in enumerate("xyz"[: self.gdim]):
                out[f"{tool.name}_force_{c}"] = float(F[j])
            if self.has_friction:
                Ff = self.tool_force(k, friction_only=True)
                for j, c in enumerate("xyz"[: self.gdim]):
                    out[f"{tool.name}_friction_{c}"] = float(Ff[j])
                out[f"{tool.name}_torque"] = self.tool_torque(k)
        if self.has_friction:
            on = self._branch > 0
            slip = np.linalg.norm(self._dvt, axis=1)
            stick = on & (slip < STICK_FACTOR * self.slip_velocity)
            out[f"{self.name}_stick"] = comm.allreduce(int(np.sum(stick)), op=MPI.SUM)
            out[f"{self.name}_slip"] = comm.allreduce(int(np.sum(on & ~stick)), op=MPI.SUM)
            # power dissipated by friction Σ S τ·(−Δv_t) = Σ r_f·Δv_t ≥ 0
            out[f"{self.name}_friction_power"] = comm.allreduce(
                float(np.sum(self._rf * self._dvt)), op=MPI.SUM)
            out[f"{self.name}_slip_velocity"] = float(self.slip_velocity)
        return out

    def node_friction_power(self) -> np.ndarray:
        """(n,) friction power r_f·Δv_t of each contact node at the last evaluation [N mm/s]
        (≥ 0; zeros without friction), in the order of ``nodes.vertices``."""
        if not self.has_friction:
            return np.zeros(len(self._r))
        return np.sum(self._rf * self._dvt, axis=1)

    def tool_force(self, k: int = 0, friction_only: bool = False) -> np.ndarray:
        """Force on tool k (gdim,) from the last evaluation, summed over ranks: contact plus
        friction (= −the force on the body), or the friction part only."""
        sel = self._tool == k
        r = self._rf if friction_only else self._r + self._rf
        return self.boundary.comm.allreduce(
            np.sum(r[sel], axis=0) if np.any(sel) else np.zeros(self.gdim), op=MPI.SUM)

    def tool_torque(self, k: int = 0) -> float:
        """Torque on tool k about its own (rotation) axis from the last evaluation, summed over
        ranks: w · Σ (P_n − a) × f_n with f_n the nodal force on the tool (contact + friction)
        at the projection point P_n. For a roll this is the driving torque (sign: the torque
        the body exerts on the tool, right-hand rule about the axis)."""
        tool = self.tools[k]
        sel = self._tool == k
        t = self.t if self.scheme == "explicit" else self.t + self.dt
        w = unit_vector(tool.motion.axis, "tool axis")
        a = tool.motion.axis_point_at(t)
        M = 0.0
        if np.any(sel):
            f = np.zeros((int(np.sum(sel)), 3))
            f[:, : self.gdim] = (self._r + self._rf)[sel]
            arm = self._point[sel] - a
            M = float(np.sum(np.cross(arm, f) @ w))
        return self.boundary.comm.allreduce(M, op=MPI.SUM)

    def output_fields(self):
        if self._fields is None:
            b = self.boundary
            Q1 = compat.function_space(b.mesh, ("Lagrange", 1))
            p = dolfinx.fem.Function(Q1, name=f"{self.name}_pressure")
            s = dolfinx.fem.Function(Q1, name=f"{self.name}_status")
            self._fields = (p, s)
            if self.has_friction:
                V1 = compat.vector_function_space(b.mesh, "Lagrange", 1)
                self._fields += (dolfinx.fem.Function(V1, name=f"{self.name}_friction_stress"),)
        return list(self._fields)

    def update_output_fields(self):
        fields = self.output_fields()
        p, s = fields[:2]
        q = self.boundary.q1_dofs(p.function_space)
        p.x.array[:] = 0.0
        s.x.array[:] = 0.0
        p.x.array[q] = self.pressures()
        s.x.array[q] = (self._h > 0).astype(float)
        if self.has_friction:
            f = fields[2]
            f.x.array[:] = 0.0
            qv = self.boundary.q1_dofs(f.function_space)   # block dofs of the vertices
            f.x.array.reshape(-1, self.gdim)[qv] = self._tau
        for fn in fields:
            fn.x.scatter_forward()

    def summary(self) -> str:
        """The contact's line of the run's summary: scheme, the penalty as resolved, and per
        tool with friction its law and which shear flow stress k the law uses."""
        text = f"contact '{self.name}': {self.scheme}, {self.penalty.summary()}"
        laws = [f"'{tool.name}' {law.describe()}" for tool, law in zip(self.tools, self.friction)
                if law.code != LAW_NONE]
        if laws:
            text += "; friction " + "; ".join(laws)
        if getattr(self, "_increments_seen", 0) and not self._ever_touched:
            warning = (f"no node ever touched {', '.join(repr(t.name) for t in self.tools)} in "
                       f"{self._increments_seen} increment(s): the forces are zero — check the "
                       f"tools' positions and motions against the body (units: mm)")
            if self.boundary.comm.rank == 0 and not getattr(self, "_warned", False):
                log.warning("contact '%s': %s", self.name, warning)   # once, where it is seen
                self._warned = True
            text += f"; WARNING: {warning}"
        return text

    # ------------------------------------------------------------------ messages
    def _check_placement(self, x_body: np.ndarray, t: float):
        """ValueError (on every rank) if a tool holds the whole body at the first increment:
        every vertex of the body is on the tool's side of its surface, none further out than
        the burial limit and some deeper in than it (a Plane whose normal points into the body,
        a curved tool with the wrong ``inside``). The contact could never act: no node would
        ever be in contact, the force would stay 0."""
        lim = self.max_initial_penetration
        comm = self.boundary.comm
        for tool in self.tools:
            gap = tool.project(pad3(x_body), t, hessian=False).gap
            hi = comm.allreduce(float(np.max(gap, initial=-np.inf)), op=MPI.MAX)
            lo = comm.allreduce(float(np.min(gap, initial=np.inf)), op=MPI.MIN)
            if hi <= lim and lo < -lim:
                raise ValueError(
                    f"tool '{tool.name}' of contact '{self.name}' holds the whole body at t = "
                    f"{t:.6g}: every node of the body is on the tool's side of its surface (down "
                    f"to {-lo:.3g} deep), so the contact could never act (no contact node, zero "
                    f"force). The tool's surface is turned the wrong way: "
                    f"{flip_hint(tool)}")
        self._placement_checked = True

    def cycle_hint(self, period: int = 1) -> str:
        """What changes over a cycle of ``period`` Newton iterations (counted over the whole
        cycle, each node once), and the usual cure: nodes entering and leaving contact,
        switching between tools, between facets/features of one tool, or between the smooth
        projection and its flat fall-back; or nothing (a residual that stagnates)."""
        recent = list(self._recent)[-(period + 1):]
        comm = self.boundary.comm
        n = np.zeros(4, dtype=np.int64)
        if len(recent) > 1:
            act, tool, feat, fb = (np.array([r[k] for r in recent]) for k in range(4))
            enter = np.any(act != act[-1], axis=0)
            both = np.all(act, axis=0)
            tools = both & np.any(tool != tool[-1], axis=0)
            feats = both & ~tools & np.any(feat != feat[-1], axis=0)
            fall = ~enter & ~tools & ~feats & np.any(fb != fb[-1], axis=0)
            n = np.array([np.sum(enter), np.sum(tools), np.sum(feats), np.sum(fall)])
        n_in, n_tool, n_feat, n_fall = (int(k) for k in comm.allreduce(n, op=MPI.SUM))
        who = f"contact '{self.name}'"
        parts = []
        if n_in:
            parts.append(f"{n_in} node(s) enter and leave contact")
        if n_tool:
            names = " and ".join(f"'{t.name}'" for t in self.tools)
            parts.append(f"{n_tool} node(s) switch between the tools {names} (where the tools "
                         f"meet or overlap)")
        if n_feat:
            parts.append(f"{n_feat} node(s) switch between facets/features of their tool "
                         f"(facet switching, THEORY §6)")
        if n_fall:
            parts.append(f"{n_fall} node(s) switch between the smooth projection and its flat "
                         f"fall-back (a hole or a sharp edge of the faceted tool)")
        if not parts:
            return (f"{who}: no node changes its contact status, tool, facet or projection "
                    f"over the cycle: the residual stagnates, not the contact state")
        cures = []
        if n_feat or n_fall:
            cures.append("smooth the faceted tool (mode='nagata') or repair its surface")
        if n_tool:
            cures.append("round or separate the tools where they meet")
        cures.append(self._dt_advice())
        return f"{who}: " + "; ".join(parts) + " over the cycle: " + ", or ".join(cures)

    def _dt_advice(self) -> str:
        """"reduce dt", unless dt is already so small that the gap's round-off ε|X|/dt is
        more than 1e-6 of the nodes' speeds (collective values of the last iterate)."""
        comm = self.boundary.comm
        x_t = getattr(self, "x_t", np.zeros((0, self.gdim)))
        X = comm.allreduce(float(np.max(np.abs(x_t), initial=0.0)), op=MPI.MAX)
        v = comm.allreduce(float(np.max(np.linalg.norm(self._v_last, axis=1), initial=0.0)),
                           op=MPI.MAX)
        eps = np.finfo(float).eps
        if v > 0 and eps * X / self.dt > 1e-6 * v:
            return (f"a larger dt: dt = {self.dt:.3g} is so small that the positions x + dt v "
                    f"(|x| up to {X:.3g}, |v| up to {v:.3g}) keep fewer than 6 digits of the "
                    f"motion; dt >= {1e6 * eps * X / v:.3g} keeps them")
        return "reduce dt (cut-back)"

    # ------------------------------------------------------------------ checkpoint
    def checkpoint_state(self) -> dict:
        """What a resumed run needs (:mod:`fxcontact.checkpoint`): the penalty resolved from β
        at the first increment, the representative strain rate, the slip regularisation and the
        nodal pressures of the last converged increment (explicit friction). The tools are
        immutable and move as functions of time: restoring t restores their positions, except
        for motions whose rates are set during the run (:class:`fxcontact.idle.ControlledMotion`:
        their ``checkpoint_state()`` is saved too, under ``motions``)."""
        return {"name": self.name, "scheme": self.scheme,
                "tools": [t.name for t in self.tools],
                "motions": [t.motion.checkpoint_state()
                            if hasattr(getattr(t, "motion", None), "checkpoint_state") else None
                            for t in self.tools],
                **self.penalty.state(), "slip_velocity": self.slip_velocity,
                "p_prev": PerVertex(self.boundary.vertices, self._p_prev)}

    def setup_signature(self) -> dict:
        """The contact's parameters as given (not those resolved during the run): a checkpoint
        is resumed only with the same (:meth:`Simulation.resume
        <fxcontact.simulation.Simulation.resume>` names the one that differs)."""
        tools = []
        for t in self.tools:
            base = getattr(t, "tool", t)   # a MovedTool's tool
            geometry = base._repr_fields() if hasattr(base, "_repr_fields") else repr(base)
            tools.append({"type": type(t).__name__, "name": t.name,
                          "geometry": type(base).__name__ if " at 0x" in geometry else geometry,
                          "motion": describe(t.motion)})
        return {"name": self.name, "scheme": self.scheme, "formulation": self.formulation,
                **self.penalty.signature(), "sticky_gap": self.sticky_gap, "friction": describe(self.friction),
                "friction_mode": self.friction_mode, "slip_velocity": self._slip_velocity_user,
                "tools": tools}

    def restore_state(self, state: dict):
        mine = {"name": self.name, "scheme": self.scheme, "tools": [t.name for t in self.tools]}
        theirs = {k: state.get(k) for k in mine}
        if theirs != mine:
            raise CheckpointError(f"the checkpoint's contact {theirs} is not this contact {mine}")
        if self.penalty.fixed_rho is None and self.penalty.gap_stiffness is None:
            self.rho = state["penalty"]   # resolved from beta
        self.penalty.restore(state)
        if self._slip_velocity_user is None:
            self.slip_velocity = state["slip_velocity"]
        self._p_prev = np.asarray(state["p_prev"].at(self.boundary.vertices), dtype=np.float64)
        for t, m in zip(self.tools, state.get("motions") or [None] * len(self.tools)):
            has = hasattr(getattr(t, "motion", None), "restore_state")
            if (m is None) == has:
                raise CheckpointError(f"the checkpoint's motion of tool '{t.name}' "
                                      f"({'none' if m is None else 'rates set during the run'}) "
                                      f"does not fit this tool's {type(t.motion).__name__}")
            if m is not None:
                t.motion.restore_state(m)

    def remesh(self, space, facet_tags):
        """Rebind to a new mesh of the body (:meth:`Simulation.remesh
        <fxcontact.simulation.Simulation.remesh>`; collective): the contact boundary is
        selected again by the same tags in the new ``facet_tags``
        (:meth:`ContactBoundary.remeshed`); tools, friction laws, the penalty (as resolved,
        with the element size of the set-up) and the slip regularisation are kept; the
        pressures of the last increment (explicit friction) go to the nearest new node."""
        if self.formulation != "velocity":
            raise ValueError(f"contact '{self.name}': only the velocity formulation "
                             f"(Simulation) can be remeshed")
        old = self.boundary
        comm = old.comm
        x_old = np.concatenate(comm.allgather(old.mesh_positions()))
        p_old = np.concatenate(comm.allgather(self._p_prev))
        self.boundary = old.remeshed(space, facet_tags)
        self._reset_nodes(len(self.boundary))
        if len(x_old) and len(self.boundary):
            self._p_prev = p_old[cKDTree(x_old).query(self.boundary.mesh_positions())[1]]
        self._fields = None
