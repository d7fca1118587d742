"""Tools driven by a controller, idle tools (any process: the ring mill's mandrel and guide rolls,
the idle rolls of a rolling stand).

A radial ring-rolling mill (THEORY §5, §12.1, §14.4) has a *driven* main roll (prescribed rpm),
a mandrel fed towards it whose rotation is *idle* (it turns freely: zero torque about its own
axis), and guide (centring) rolls that keep the ring on the mill line. This module provides:

* :class:`ControlledMotion` — a rigid motion whose translation velocity and rotation speed are
  piecewise constant and set by a controller at the start of each increment (integrated
  exactly; any analytic or faceted tool moved by it through :class:`~fxcontact.tools.MovedTool`;
  defined in :mod:`fxcontact.tools.base` with the other motions).
* :class:`IdleRotation` — the rotation speed ω of an idle tool, found at each increment such that
  the torque of the contact and friction forces about the tool's own axis vanishes.
* the ring mill's own controllers, :class:`~fxcontact.processes.ring_rolling.mill.RingCentring`
  (guide rolls following the growing ring) and
  :class:`~fxcontact.processes.ring_rolling.mill.AxialRolls` (cone rolls), live with the ring
  rolling process; the cylindrical update about the ring's current centre,
  :class:`~fxcontact.kinematics.RingAxisUpdate`, with the other configuration updates.

Every controller (and :class:`ControlledMotion`) saves what changes during a run with
``checkpoint_state()`` and gets it back with ``restore_state()`` (checkpoints of
:class:`~fxcontact.Simulation`).

Controllers are registered with :meth:`fxcontact.Simulation.add_controller`; they act at the
start of each increment (before the contributors project on the tools) and, for
:class:`IdleRotation`, around the Newton solve.

**Idle tool: design.** Three ways were considered: (a) an outer scalar iteration on the torque
T(ω) = 0 per increment, each evaluation a Newton solve warm-started from the previous one;
(b) ω as an extra unknown of a bordered Newton system; (c) ω*(v) eliminated locally with the
rank-one Jacobian correction. Solving ω from T = 0 inside each residual evaluation *without*
the coupling term (a crude (c)) diverges as soon as nodes stick: the torque is then a very
steep function of ω (slope ~ μ p S R² / v₀ with the slip regularisation v₀) and the lagged ω
oscillates. Two methods are implemented (``IdleRotation(..., method=...)``):

* ``"bordered"`` — the exact (c), the default when it applies (tools of revolution about
  their rotation axes, implicit contact). For such a tool its surface does not move when ω
  changes: only the friction depends on ω, through the slip against the tool's surface
  velocity ω e × (P − a) + translation. At every contact evaluation inside Newton (residual,
  line search, Jacobian) ω*(v) is solved from T(v, ω) = 0 at the current projection: T is
  a global sum Σ r_f·(e × (P − a)) over the tool's friction nodes, strictly decreasing in ω,
  and a safeguarded scalar Newton (bracketing, bisection; the kernel on the tool's nodes and
  one ``allreduce`` per step, so every rank takes the same steps) converges to a step below
  1e-13 v₀/R̄ in a few iterations from the previous ω. The residual is then R(v, ω*(v)) with
  T = 0 to round-off, and its Jacobian is J − u D⁻¹ gᵀ with u = ∂R/∂ω (on the tool's contact
  nodes), g = ∂T/∂v, D = ∂T/∂ω (< 0): the block elimination of the bordered system (b) with
  the torque equation always satisfied, so Newton's line search and convergence test see the
  torque equation exactly. The friction kernel gives the blocks ∂r_f/∂Δv (with and without
  the implicit Coulomb ∂p_n/∂v term): u = −K m, g = K_vᵀ m, D = −Σ mᵀ K m with
  m = e × (P − a), in the friction tangent the contact's Jacobian uses. The linear solve is
  that of the solver's options wrapped by :class:`fxcontact.newton.solver.BorderedPC` (Woodbury:
  one more application of the preconditioner per idle tool, i.e. one more pair of
  triangular solves with MUMPS, no new factorisation; a second Krylov solve with an
  iterative one), the SNES operator being the exact product with the corrected matrix. Several
  idle tools (mandrel and guide rolls) are k borders: their ω are independent (a node touches
  one tool), D is diagonal, the correction needs k more applications and a k×k solve; give
  them all to one ``IdleRotation(contact, [mandrel, guide1, guide2])`` (one controller may
  take over the solve). Not handled (→ ``"outer"``): faceted tools (their facets turn with
  ω), explicit and quasi-implicit contact (the tool velocity frozen per increment), inclined
  symmetry planes (projected Newton systems).
* ``"outer"`` — (a): no change of the Newton solver, the torque a global sum so every rank
  takes the same decisions, each evaluation an ordinary, converged increment. T(ω) is
  decreasing (a tool that turns slower than the ring's surface is dragged forward). The first
  evaluation is at the previous increment's ω, the second at the rolling-without-slip speed
  ω_free of the converged field (least-squares rotation of the contact nodes' velocities
  about the tool axis), then secant steps, Illinois (modified regula falsi) once the root is
  bracketed. Convergence: |T| ≤ ``torque_rtol`` · |F| · R̄ (|F| the tool's contact force, R̄
  the mean lever arm of its contact nodes) with ``torque_rtol`` not below 10× the Newton
  tolerance. One tool per controller.

Measured (the ring-rolling process, ``idle_method="outer"`` against ``"bordered"``;
``benchmarks/README.md``): the same mandrel ω to 1e-9–1e-7 relative (the outer method's torque
tolerance), 1.3–2.7× fewer Newton iterations and about half the CPU time with the bordered one.

**Frictionless idle tool**: the torque is zero for every ω (normal forces pass through the
axis), ω is undetermined and has no effect; it is set after the solve to ω_free (the ring's
surface speed over the lever arm) for the outputs, and the solve is done once.
"""

from __future__ import annotations

import logging
import math
from typing import Dict

import numpy as np
from mpi4py import MPI

from fxcontact.contact.friction import LAW_NONE
from fxcontact.newton.problem import ContributorError
from fxcontact.tools.analytic import Cone, Cylinder, Sphere
from fxcontact.tools.base import ControlledMotion, MovedTool, Tool, unit_vector
from fxcontact.tools.revolved import RevolvedProfile

__all__ = ["IDLE_METHODS", "ControlledMotion", "IdleRotation", "controlled_motion", "rolling_speed"]

log = logging.getLogger(__name__)


def controlled_motion(tool: Tool) -> ControlledMotion:
    if not isinstance(getattr(tool, "motion", None), ControlledMotion):
        raise ValueError(f"tool '{getattr(tool, 'name', tool)}' must move with a "
                         f"ControlledMotion (use MovedTool(static_tool, ControlledMotion(...)))")
    return tool.motion


def rolling_speed(contact, k: int, w_function) -> float:
    """Rolling-without-slip speed ω_free of tool ``k`` of ``contact`` (collective): the
    least-squares rotation rate about the tool's axis of the velocities of the contact nodes
    in contact with it, ω = Σ S (e × (P − a))·v / Σ S |P⊥ − a|², from ``w_function``
    (0 when no node touches the tool)."""
    tool = contact.tools[k]
    nv = contact.nodes
    sel = (nv.tool == k) & nv.active
    e = unit_vector(tool.motion.axis, "tool axis")
    t = contact.t + contact.dt
    a = tool.motion.axis_point_at(t)
    num = den = 0.0
    if np.any(sel):
        v = np.zeros((int(np.sum(sel)), 3))
        v[:, : contact.gdim] = contact.boundary.velocities(w_function)[sel]
        arm = nv.point[sel] - a
        arm -= np.outer(arm @ e, e)
        S = contact.boundary.areas[sel]
        num = float(np.sum(S * np.einsum("ni,ni->n", np.cross(e, arm), v)))
        den = float(np.sum(S * np.einsum("ni,ni->n", arm, arm)))
    comm = contact.boundary.comm
    num, den = comm.allreduce(np.array([num, den]), op=MPI.SUM)
    return num / den if den > 0 else 0.0


def _lever_arm_and_force(contact, k: int):
    """(|F|, mean lever arm) of tool k from the last evaluation (collective)."""
    tool = contact.tools[k]
    F = contact.tool_force(k)
    nv = contact.nodes
    sel = (nv.tool == k) & nv.active
    e = unit_vector(tool.motion.axis, "tool axis")
    a = tool.motion.axis_point_at(contact.t + contact.dt)
    s = n = 0.0
    if np.any(sel):
        arm = nv.point[sel] - a
        arm -= np.outer(arm @ e, e)
        s, n = float(np.sum(np.linalg.norm(arm, axis=1))), float(np.sum(sel))
    s, n = contact.boundary.comm.allreduce(np.array([s, n]), op=MPI.SUM)
    return float(np.linalg.norm(F)), (s / n if n > 0 else 0.0)


#: methods of :class:`IdleRotation`
IDLE_METHODS = ("auto", "bordered", "outer")


def _revolves_about_own_axis(tool: Tool) -> bool:
    """True if ``tool`` is an analytic surface of revolution (cylinder, cone, sphere, revolved
    profile) whose axis is its motion's rotation axis: turning it about that axis leaves its
    surface in place, so its geometry does not depend on its rotation speed."""
    base = tool.tool if isinstance(tool, MovedTool) else tool
    e = unit_vector(tool.motion.axis, "tool axis")
    a0 = np.asarray(tool.motion.axis_point, dtype=np.float64)
    if isinstance(base, Sphere):
        p = np.asarray(base.center, dtype=np.float64)
    elif isinstance(base, (Cylinder, Cone, RevolvedProfile)):
        if abs(abs(float(np.dot(base.axis, e))) - 1.0) > 1e-12:
            return False
        p = np.asarray(base.apex if isinstance(base, Cone) else
                       base.axis_point if isinstance(base, RevolvedProfile) else base.point,
                       dtype=np.float64)
    else:
        return False
    d = p - a0
    d -= (d @ e) * e
    scale = max(1.0, float(np.linalg.norm(p)), float(np.linalg.norm(a0)))
    return float(np.linalg.norm(d)) <= 1e-12 * scale


class _EliminatedContact:
    """Stands for the contact in the Newton problem during a bordered solve: each evaluation
    first eliminates the idle tools' rotation speeds (:meth:`IdleRotation._eliminate`)."""

    def __init__(self, idle: "IdleRotation"):
        self._idle = idle

    def evaluate(self, w, jacobian: bool):
        return self._idle._eliminate(w, jacobian)

    def stable(self) -> bool:        # with evaluate(): a fxcontact.protocols.Contributor
        return self._idle.contact.stable()

    def __getattr__(self, name):     # fingerprint(), begin_solve(), ...
        return getattr(self._idle.contact, name)


class _Border:
    """The border (U, G, D) of the Newton matrix, filled at the Jacobian evaluations
    (:meth:`fxcontact.newton.solver.ContactNewtonSolver.set_border`)."""

    def __init__(self):
        self.current = None

    def vectors(self):
        return self.current


class IdleRotation:
    """Idle tools: their rotation speeds are found at each increment from zero torque about
    their own axes (the mandrel and the guide rolls of a ring mill). See the module docstring
    for the methods.

    Args:
        contact: the :class:`~fxcontact.contact.NodalContact` holding the tools.
        tool: the idle tool (one of ``contact.tools``) moved by a :class:`ControlledMotion`, or
            a sequence of such tools (``method="bordered"`` only: one controller for every idle
            tool of the contact).
        torque_rtol: convergence |T| ≤ torque_rtol·|F|·R̄ (raised to 10× the Newton rtol if
            smaller); with the bordered method the torque is eliminated to round-off at every
            evaluation and this is a check of the accepted solution.
        max_evaluations: Newton solves per increment of the outer method before the increment
            is declared failed (and cut back).
        method: ``"bordered"`` (the rotation speeds eliminated inside Newton, one Newton solve
            per increment; needs tools of revolution about their rotation axes and an
            implicit contact scheme in the velocity formulation), ``"outer"`` (a secant /
            Illinois iteration of Newton solves on T(ω) = 0; one tool; any tool and scheme) or
            ``"auto"`` (default: bordered when it applies, else outer).

    History columns (per tool): ``{tool}_omega`` (rad/s), ``{tool}_idle_torque`` (the torque
    at the accepted solve), ``{tool}_idle_tolerance``, ``{tool}_idle_solves`` (Newton solves of
    the increment), ``{tool}_idle_local_iterations`` (bordered: scalar iterations of the
    elimination, summed over the increment's evaluations) and ``{tool}_surface_slip``
    (ω R̄ − ω_free R̄: the tool's surface speed minus the body's rolling speed).
    """

    def __init__(self, contact, tool, torque_rtol: float = 1e-6,
                 max_evaluations: int = 12, method: str = "auto"):
        tools = [tool] if isinstance(tool, Tool) else list(tool)
        if not tools or not all(isinstance(t, Tool) for t in tools):
            raise ValueError(f"tool must be a Tool or a non-empty sequence of Tools, got "
                             f"{tool!r}")
        for t in tools:
            if not any(t is c for c in contact.tools):
                raise ValueError(f"tool '{t.name}' is not one of the contact's tools "
                                 f"{[c.name for c in contact.tools]}")
        if len({id(t) for t in tools}) != len(tools):
            raise ValueError(f"an idle tool is given twice: {[t.name for t in tools]}")
        self.motions = [controlled_motion(t) for t in tools]
        if not (math.isfinite(torque_rtol) and torque_rtol > 0):
            raise ValueError(f"torque_rtol must be > 0, got {torque_rtol!r}")
        if not (isinstance(max_evaluations, int) and max_evaluations >= 2):
            raise ValueError(f"max_evaluations must be an integer >= 2, got {max_evaluations!r}")
        if method not in IDLE_METHODS:
            raise ValueError(f"unknown idle-rotation method {method!r}; choose one of "
                             f"{IDLE_METHODS}")
        revolved = [_revolves_about_own_axis(t) for t in tools]
        implicit = (contact.scheme in ("implicit", "implicit-exact")
                    and getattr(contact, "formulation", "velocity") == "velocity")
        if method == "auto":
            method = "bordered" if all(revolved) and implicit else "outer"
        if method == "bordered":
            if not all(revolved):
                bad = [t.name for t, r in zip(tools, revolved) if not r]
                raise ValueError(f"the bordered idle rotation needs tools of revolution about "
                                 f"their rotation axes (analytic cylinder, cone, sphere or "
                                 f"revolved profile); {bad} are not: use method='outer'")
            if not implicit:
                raise ValueError(f"the bordered idle rotation needs the implicit contact "
                                 f"schemes in the velocity formulation (the tool velocity at "
                                 f"every evaluation), got scheme '{contact.scheme}': use "
                                 f"method='outer'")
        elif len(tools) > 1:
            raise ValueError("the outer idle iteration handles one tool; several idle tools "
                             "need method='bordered'")
        self.method = method
        self.contact = contact
        self.tools = tools
        self.ks = [next(k for k, c in enumerate(contact.tools) if c is t) for t in tools]
        self.frictionless_tools = [contact.friction[k].code == LAW_NONE for k in self.ks]
        # the first tool under the names of the single-tool interface
        self.tool, self.k, self.motion = tools[0], self.ks[0], self.motions[0]
        self.frictionless = self.frictionless_tools[0]
        self.torque_rtol = float(torque_rtol)
        self.max_evaluations = int(max_evaluations)
        self.omegas = [m.current_angular_velocity() for m in self.motions]
        self._rows: list = [{} for _ in tools]
        self._t = 0.0
        self._trial = None
        self._border = _Border()
        self._wrapper = _EliminatedContact(self)
        self._U = self._G = None
        self._local_its = [0] * len(tools)

    @property
    def omega(self) -> float:
        """Rotation speed of the (first) idle tool at the last accepted increment."""
        return self.omegas[0]

    @omega.setter
    def omega(self, value: float):
        self.omegas[0] = float(value)

    @property
    def _row(self) -> Dict[str, float]:
        return self._rows[0]

    @_row.setter
    def _row(self, value: Dict[str, float]):
        self._rows[0] = value

    def begin_increment(self, sim, t: float, dt: float, x_t):
        self._t = t
        # the trial ω of the current evaluation (outer solve()), else the previous increment's
        for j, mot in enumerate(self.motions):
            om = self.omegas[j] if (self._trial is None or j > 0) else self._trial
            mot.set_rates(t, angular_velocity=om)
        self._local_its = [0] * len(self.tools)

    # ------------------------------------------------------------------ bordered method
    def _tool_nodes(self, j: int, args: dict, v: np.ndarray, t1: float):
        """The friction nodes of tool j at the current projection: (sel, m, dv0) with
        m = e × (P − a) (the tool's surface velocity per unit ω) and dv0 the velocity relative
        to the tool's material point with ω = 0 (the slip is dv0 − ω m)."""
        c = self.contact
        d = c.gdim
        k = self.ks[j]
        nv = c.nodes
        sel = (nv.tool == k) & args["active"] & (args["law"] != LAW_NONE)
        if not np.any(sel):
            return sel, np.zeros((0, d)), np.zeros((0, d))
        tool = c.tools[k]
        e = unit_vector(tool.motion.axis, "tool axis")
        P = nv.point[sel]
        m = np.cross(e, P - tool.motion.axis_point_at(t1))[:, :d]
        w_now = tool.motion.angular_velocity(t1)
        dv0 = v[sel] - (tool.velocity(P, t1)[:, :d] - w_now * m)
        return sel, np.ascontiguousarray(m), np.ascontiguousarray(dv0)

    @staticmethod
    def _subset(args: dict, sel: np.ndarray, dpn: bool) -> tuple:
        """Kernel arguments of the nodes ``sel`` (without ``dv``, ``jacobian``, ``theta``)."""
        d = args["nrm"].shape[1]
        pick = lambda key: np.ascontiguousarray(args[key][sel])   # noqa: E731
        dp = pick("dpn") if (dpn and args["dpn"].shape[0] == len(sel)) else np.zeros((0, d))
        return (pick("S"), pick("law"), pick("mu"), pick("tau_max"), pick("visc"), pick("q"),
                pick("pn"), dp)

    def _friction_torque(self, sub, args, sel, m, dv, theta: float):
        """Local friction torque Σ r_f·m, its ω-derivative −Σ mᵀ(∂r_f/∂Δv)m, and the blocks
        ∂r_f/∂Δv (N, d, d) of the nodes ``sel`` at the slip ``dv``."""
        c = self.contact
        S, law, mu, tau_max, visc, q, pn, dp = sub
        act = np.ones(len(S), dtype=bool)
        nrm = np.ascontiguousarray(args["nrm"][sel])
        rf, K, _, _ = c.friction_kernel(S, law, mu, tau_max, visc, q, pn, dp,
                                        np.ascontiguousarray(dv), nrm, args["v0"], act, True,
                                        theta)
        T = float(np.sum(rf * m))
        dT = -float(np.einsum("ni,nij,nj->", m, K, m))
        return T, dT, K

    def border_terms(self, w) -> list:
        """The border of the Newton matrix at the contact's last evaluation (for each tool of
        this controller with friction nodes, else None): ``(dofs, u, g, D)`` with ``dofs``
        (n, d) the local velocity dofs of its friction nodes, ``u`` = ∂R/∂ω and ``g`` = ∂T/∂v
        on them (the friction tangent the contact's Jacobian uses: ∂r_f/∂Δv with and without
        the implicit Coulomb ∂p_n/∂v term) and D = ∂T/∂ω (summed over ranks). Collective."""
        c = self.contact
        t1 = c.t + c.dt
        v = np.ascontiguousarray(c.boundary.velocities(w))
        nv = c.nodes
        args = c.friction_arguments(nv.h, nv.grad_h, nv.tool)
        out, Ds = [], np.zeros(len(self.tools))
        for j in range(len(self.tools)):
            if self.frictionless_tools[j]:
                out.append(None)
                continue
            sel, m, dv0 = self._tool_nodes(j, args, v, t1)
            om = self.tools[j].motion.angular_velocity(t1)
            dv = dv0 - om * m
            d = c.gdim
            if np.any(sel):
                _, dT, K = self._friction_torque(self._subset(args, sel, False), args, sel, m,
                                                 dv, args["theta"])
                nrm = np.ascontiguousarray(args["nrm"][sel])
                S, law, mu, tau_max, visc, q, pn, dp = self._subset(args, sel, True)
                _, Kv, _, _ = c.friction_kernel(S, law, mu, tau_max, visc, q, pn, dp,
                                                np.ascontiguousarray(dv), nrm, args["v0"],
                                                np.ones(len(S), dtype=bool), True,
                                                args["theta"])
                u = -np.einsum("nij,nj->ni", K, m)
                g = np.einsum("nji,nj->ni", Kv, m)
                Ds[j] = dT
                out.append((c.boundary.dofs[sel], u, g))
            else:
                out.append((np.zeros((0, d), dtype=np.int32), np.zeros((0, d)),
                            np.zeros((0, d))))
        Ds = c.boundary.comm.allreduce(Ds, op=MPI.SUM)
        return [None if o is None or Ds[j] == 0.0 else (*o, float(Ds[j]))
                for j, o in enumerate(out)]

    def _collective(self, fn):
        """Run ``fn()`` and raise its ContributorError on every rank if it failed on any."""
        msg, res = None, None
        try:
            res = fn()
        except ContributorError as e:
            msg = str(e)
        msgs = [m for m in self.contact.boundary.comm.allgather(msg) if m is not None]
        if msgs:
            raise ContributorError(msgs[0])
        return res

    #: the elimination's Newton iteration stops when its step is below this fraction of the
    #: slip regularisation over the lever arm, v₀/R̄ (the friction forces then move by ~1e-13
    #: of their size)
    ELIMINATION_STEP_TOL = 1e-13
    ELIMINATION_MAX_IT = 100

    def _solve_speeds(self, w) -> None:
        """ω_j* with T_j(v, ω_j*) = 0 at the current iterate v and projection, for every tool
        with friction nodes (the ω_j are independent: a node touches one tool); sets the
        motions' rates. Safeguarded Newton on each T_j(ω), which is decreasing (collective,
        every rank takes the same steps: T and its derivative are global sums)."""
        c = self.contact
        comm = c.boundary.comm
        t1 = c.t + c.dt
        v = np.ascontiguousarray(c.boundary.velocities(w))
        nv = c.nodes
        args = c.friction_arguments(nv.h, nv.grad_h, nv.tool)
        n = len(self.tools)
        nodes, base = [], np.zeros((n, 3))
        for j in range(n):
            if self.frictionless_tools[j]:
                nodes.append(None)
                continue
            k = self.ks[j]
            sel, m, dv0 = self._tool_nodes(j, args, v, t1)
            tool = c.tools[k]
            e = unit_vector(tool.motion.axis, "tool axis")
            a = tool.motion.axis_point_at(t1)
            on = nv.tool == k
            # torque of the normal forces (zero for a tool of revolution, kept for the sum)
            f = np.zeros((int(np.sum(on)), 3))
            f[:, : c.gdim] = nv.force[on]
            arm = nv.point[on] - a
            base[j, 0] = float(np.sum(np.cross(arm, f) @ e)) if len(f) else 0.0
            armt = m          # |e × arm| = the lever arm
            base[j, 1] = float(np.sum(np.linalg.norm(armt, axis=1)))
            base[j, 2] = float(np.sum(sel))
            nodes.append((sel, m, dv0, self._subset(args, sel, False)))
        base = comm.allreduce(base, op=MPI.SUM)
        om = np.array([mot.angular_velocity(t1) for mot in self.motions])
        todo = [j for j in range(n) if nodes[j] is not None and base[j, 2] > 0]
        if not todo:
            return
        scale = np.array([c.slip_velocity / (base[j, 1] / base[j, 2]) if base[j, 2] > 0
                          else 1.0 for j in range(n)])
        lo = np.full(n, -np.inf)
        hi = np.full(n, np.inf)
        cap = 10.0 * scale
        for it in range(self.ELIMINATION_MAX_IT):
            TdT = np.zeros((n, 2))
            for j in todo:
                sel, m, dv0, sub = nodes[j]
                if np.any(sel):
                    T, dT, _ = self._friction_torque(sub, args, sel, m, dv0 - om[j] * m,
                                                     1.0)
                    TdT[j] = T, dT
            TdT = comm.allreduce(TdT, op=MPI.SUM)
            left = []
            for j in todo:
                self._local_its[j] += 1
                T = TdT[j, 0] + base[j, 0]
                dT = TdT[j, 1]
                if T == 0.0:
                    continue
                if T > 0:       # T decreases with ω: the root is above
                    lo[j] = om[j]
                else:
                    hi[j] = om[j]
                step = -T / dT if dT < 0 else math.copysign(cap[j], T)
                if abs(step) <= self.ELIMINATION_STEP_TOL * scale[j]:
                    om[j] += step
                    continue
                new = om[j] + step
                if math.isfinite(lo[j]) and math.isfinite(hi[j]):
                    if not lo[j] < new < hi[j]:
                        new = 0.5 * (lo[j] + hi[j])
                    if hi[j] - lo[j] <= self.ELIMINATION_STEP_TOL * scale[j]:
                        om[j] = new
                        continue
                elif abs(step) > cap[j]:         # no bracket on that side yet: expand
                    new = om[j] + math.copysign(cap[j], step)
                    cap[j] *= 2.0
                om[j] = new
                left.append(j)
            todo = left
            if not todo:
                break
        else:
            log.debug("idle rotation: the elimination of ω did not converge in %d iterations",
                      self.ELIMINATION_MAX_IT)
        for j, mot in enumerate(self.motions):
            if nodes[j] is not None and base[j, 2] > 0:
                mot.set_rates(self._t, angular_velocity=float(om[j]))

    def _eliminate(self, w, jacobian: bool):
        """The contact's terms at the current iterate with every idle tool at the speed that
        zeroes its torque, ω*(v); with ``jacobian``, also the border of the Newton matrix."""
        c = self.contact
        self._collective(lambda: c.evaluate(w, False))    # the projection (ω-independent)
        self._solve_speeds(w)
        terms = self._collective(lambda: c.evaluate(w, jacobian))
        if jacobian:
            self._fill_border(w)
        return terms

    def _fill_border(self, w):
        sim = self.contact.sim
        prob = sim.problem
        bt = self.border_terms(w)
        if self._U is None:
            self._U = [prob.create_vector() for _ in self.tools]
            self._G = [prob.create_vector() for _ in self.tools]
        U, G, D = [], [], []
        for j, b in enumerate(bt):
            if b is None:
                continue
            dofs, u, g, Dj = b
            for vec, val in ((self._U[j], u), (self._G[j], g)):
                vec.set(0.0)
                # taken for writing on every rank, also one without contact nodes: the
                # vector's state must change everywhere, or a rank keeps the cached norm of
                # ``set`` and skips the reduction of the next norm (the ranks hang)
                arr = vec.getArray(readonly=False)
                if dofs.size:
                    dd = dofs.ravel()
                    vv = val.ravel().copy()
                    keep = dd >= 0
                    dd, vv = dd[keep], vv[keep]
                    vv[prob.bc_marker[dd]] = 0.0     # Dirichlet rows and columns
                    np.add.at(arr, dd, vv)
                del arr
            U.append(self._U[j])
            G.append(self._G[j])
            D.append(Dj)
        self._border.current = (U, G, np.diag(D)) if U else None

    def _solve_bordered(self, sim, begin):
        prob = sim.problem
        if any(len(getattr(cn, "inclined", ())) for cn in prob.constraints):
            raise ValueError("the bordered idle rotation does not handle inclined symmetry "
                             "planes (projected Newton systems): use method='outer'")
        idx = [i for i, cn in enumerate(prob.contributors) if cn is self.contact]
        if len(idx) != 1:
            raise ValueError(f"the idle tools' contact '{self.contact.name}' must be "
                             f"registered once with add_contributor")
        sim.solver.set_border(self._border)
        self._border.current = None
        prob.contributors[idx[0]] = self._wrapper
        try:
            info = sim.solver.solve()
            if info.converged:
                # the speeds and the terms of the converged field
                self._eliminate(sim.w, False)
        finally:
            prob.contributors[idx[0]] = self.contact
            self._border.current = None
        if not info.converged:
            return info
        rtol = max(self.torque_rtol, 10.0 * sim.solver_options.rtol)
        c = self.contact
        t1 = c.t + c.dt
        bad = []
        for j, (tool, k, mot) in enumerate(zip(self.tools, self.ks, self.motions)):
            T = c.tool_torque(k)
            F, R = _lever_arm_and_force(c, k)
            tol = rtol * F * R
            n_fr = c.boundary.comm.allreduce(
                int(np.sum((c.nodes.tool == k) & c.nodes.active)), op=MPI.SUM)
            if self.frictionless_tools[j]:
                om = rolling_speed(c, k, sim.w)    # 0 without contact, as the outer method
                mot.set_rates(self._t, angular_velocity=om)
                tol = 0.0
            else:
                om = mot.angular_velocity(t1)
                if abs(T) > tol and n_fr:
                    bad.append(f"'{tool.name}': torque {T:.3e} above {tol:.3e}")
            self.omegas[j] = float(om)
            self._rows[j] = {"omega": float(om), "idle_torque": T, "idle_tolerance": tol,
                             "idle_solves": 1, "idle_local_iterations": self._local_its[j]}
        if bad:
            info.converged = False
            info.message = "idle tools: " + "; ".join(bad)
        return info

    def solve(self, sim, begin):
        """The increment's Newton solve(s) (called by the Simulation)."""
        if self.method == "bordered":
            return self._solve_bordered(sim, begin)
        return self._solve_outer(sim, begin)

    def _evaluate(self, sim, begin, omega: float, w_pred, w_warm):
        """One Newton solve with the tool at ω; returns (info, torque, |F|, R̄)."""
        self._trial = omega
        sim.w.x.array[:] = w_pred
        sim.w.x.scatter_forward()
        try:
            begin()     # restarts the contributors (and this controller, at ω = omega)
        finally:
            self._trial = None
        if w_warm is not None:
            sim.w.x.array[:] = w_warm
            sim.w.x.scatter_forward()
        info = sim.solver.solve()
        if not info.converged:
            return info, math.nan, 0.0, 0.0
        self.contact.evaluate(sim.w, False)     # the terms of the converged field
        T = self.contact.tool_torque(self.k)
        F, R = _lever_arm_and_force(self.contact, self.k)
        log.debug("idle %s: omega = %.10g -> torque %.6e (|F| %.4e, arm %.4g, %d Newton its)",
                  self.tool.name, omega, T, F, R, info.iterations)
        return info, T, F, R

    def _solve_outer(self, sim, begin):
        """Outer secant / Illinois iteration of Newton solves on T(ω) = 0 (one tool)."""
        w_pred = sim.w.x.array.copy()
        rtol = max(self.torque_rtol, 10.0 * sim.solver_options.rtol)
        its, times, n_eval = 0, {}, 0

        def add(info):
            nonlocal its, n_eval
            its += info.iterations
            n_eval += 1
            for key, val in info.times.items():
                times[key] = times.get(key, 0.0) + val

        if self.frictionless:
            info, T, F, R = self._evaluate(sim, begin, self.omega, w_pred, None)
            add(info)
            if info.converged:
                self.omega = rolling_speed(self.contact, self.k, sim.w)
                self.motion.set_rates(self._t, angular_velocity=self.omega)
                self._row = self._diagnostics(T, 0.0, n_eval, 0.0)
            return info
        pts = []              # (ω, T) of every evaluation
        brk = None            # Illinois bracket [a, Ta, b, Tb], b the latest, Ta Tb < 0
        w_warm = None
        om = self.omega
        info = None
        tol = math.inf
        for it in range(self.max_evaluations):
            info, T, F, R = self._evaluate(sim, begin, om, w_pred, w_warm)
            add(info)
            if not info.converged:
                info.message = (f"idle tool '{self.tool.name}': Newton failed at ω = {om:.6g} "
                                f"(evaluation {it + 1}): {info.message}")
                break
            w_warm = sim.w.x.array.copy()
            tol = rtol * F * R
            pts.append((om, T))
            if abs(T) <= tol or (brk is not None and abs(brk[2] - brk[0]) <=
                                 1e-13 * max(abs(brk[0]), abs(brk[2]), 1e-300)):
                self.omega = om
                self._row = self._diagnostics(T, tol, n_eval, R)
                info.iterations, info.times = its, times
                return info
            if brk is not None:
                a, Ta, b, Tb = brk
                if T * Tb < 0:
                    a, Ta = b, Tb
                else:
                    Ta *= 0.5
                brk = [a, Ta, om, T]
            else:
                opp = [p for p in pts[:-1] if p[1] * T < 0]
                if opp:
                    brk = [opp[-1][0], opp[-1][1], om, T]
            if brk is not None:
                a, Ta, b, Tb = brk
                new = (a * Tb - b * Ta) / (Tb - Ta)
            elif len(pts) == 1:
                # rolling without slip on the converged field
                new = rolling_speed(self.contact, self.k, sim.w)
                if new == om:   # nudge by the slip regularisation over the lever arm
                    v0 = self.contact.slip_velocity or 1e-6
                    new = om - np.sign(T) * (v0 / max(R, 1e-300))
            else:
                (o1, T1), (o2, T2) = pts[-2], pts[-1]
                new = o2 - T2 * (o2 - o1) / (T2 - T1) if T2 != T1 else o2
                # do not extrapolate further than 4× the last step
                step = 4.0 * abs(o2 - o1)
                new = min(max(new, o2 - step), o2 + step)
            # the root lies near the rolling speed of the contact nodes: stay within a factor 2
            wf = rolling_speed(self.contact, self.k, sim.w)
            if wf != 0.0:
                lo_, hi_ = sorted((0.5 * wf, 2.0 * wf))
                new = min(max(new, lo_), hi_)
            om = float(new)
        if info is not None and info.converged:
            info.converged = False
            info.message = (f"idle tool '{self.tool.name}': torque {pts[-1][1]:.3e} not below "
                            f"{tol:.3e} after {n_eval} Newton solves (ω = {pts[-1][0]:.6g})")
        info.iterations, info.times = its, times
        return info

    def _diagnostics(self, T, tol, n_eval, R) -> Dict[str, float]:
        return {"omega": self.omega, "idle_torque": T, "idle_tolerance": tol,
                "idle_solves": n_eval, "idle_local_iterations": 0}

    def end_increment(self, sim, dt: float):
        pass

    def diagnostics(self) -> Dict[str, float]:
        out = {}
        for j, (tool, k) in enumerate(zip(self.tools, self.ks)):
            n = tool.name
            w_free = rolling_speed(self.contact, k, self.contact.sim.w)
            _, R = _lever_arm_and_force(self.contact, k)
            out.update({f"{n}_{key}": v for key, v in self._rows[j].items()})
            out[f"{n}_omega_free"] = w_free
            out[f"{n}_surface_slip"] = (self.omegas[j] - w_free) * R
        return out

    def remesh(self, space, facet_tags):
        """A new mesh of the body (``Simulation.remesh``): the border vectors of the old
        system are dropped (made again at the next solve); ω and the motions are kept."""
        for v in (self._U or []) + (self._G or []):
            v.destroy()
        self._U = self._G = None
        self._border.current = None

    def checkpoint_state(self) -> dict:
        """ω of the last increment (the first trial of the next one) and the motion of each
        idle tool."""
        return {"tools": [t.name for t in self.tools], "omegas": [float(w) for w in self.omegas],
                "motions": [m.checkpoint_state() for m in self.motions]}

    def restore_state(self, state: dict):
        names = state.get("tools")
        if names != [t.name for t in self.tools]:
            raise ValueError(f"the checkpoint's idle rotation is of tools {names!r}, this one "
                             f"of {[t.name for t in self.tools]}")
        self.omegas = [float(w) for w in state["omegas"]]
        for m, ms in zip(self.motions, state["motions"]):
            m.restore_state(ms)

