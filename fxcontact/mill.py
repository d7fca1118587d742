"""Ring-rolling mill: tools driven by a controller, idle tools, centring of the ring.

A radial ring-rolling mill (THEORY §5, §12.1, §14.4) has a *driven* main roll (prescribed rpm),
a mandrel fed towards it whose rotation is *idle* (it turns freely: zero torque about its own
axis), and guide (centring) rolls that keep the ring on the mill line. This module provides:

* :class:`ControlledMotion` — a rigid motion whose translation velocity and rotation speed are
  piecewise constant and set by a controller at the start of each increment (integrated
  exactly; any analytic or faceted tool moved by it through :class:`~fxcontact.tools.MovedTool`).
* :class:`IdleRotation` — the rotation speed ω of an idle tool, found at each increment such that
  the torque of the contact and friction forces about the tool's own axis vanishes.
* :class:`RingCentring` — guide rolls that follow the growing ring (control of the ring's centre
  on the mill line) and the cylindrical configuration update about the ring's current centre.
* :class:`RingAxisUpdate` — the cylindrical update of THEORY §5 about an axis re-set at each
  increment (the ring's centre moves as the ring grows).
* :class:`AxialRolls` — idle, frictionless axial (cone) rolls of a radial–axial mill whose apex
  follows the ring's centre on the mill line, moving along the ring axis at a given speed.

Every controller (and :class:`ControlledMotion`) saves what changes during a run with
``checkpoint_state()`` and gets it back with ``restore_state()`` (checkpoints of
:class:`~fxcontact.Simulation`).

Controllers are registered with :meth:`fxcontact.Simulation.add_controller`; they act at the
start of each increment (before the contributors project on the tools) and, for
:class:`IdleRotation`, around the Newton solve.

**Idle tool: design.** Three ways were considered: (a) an outer scalar iteration on the torque
T(ω) = 0 per increment, each evaluation a Newton solve warm-started from the previous one;
(b) ω as an extra unknown of a bordered Newton system; (c) ω*(v) eliminated locally with the
rank-one Jacobian correction. Solving ω from T = 0 inside each residual evaluation without the
coupling term (a crude (c)) diverges as soon as nodes stick: the torque is then a very steep
function of ω (slope ~ μ p S R² / v₀ with the slip regularisation v₀) and the lagged ω
oscillates. (a) is used here: it needs no change of the Newton solver, the torque is a global
sum (``allreduce``) so every rank takes the same decisions, and each evaluation is an ordinary,
converged increment. T(ω) is decreasing (a tool that turns slower than the ring's surface is
dragged forward). The first evaluation is at the previous increment's ω, the second at the
rolling-without-slip speed ω_free of the converged field (least-squares rotation of the contact
nodes' velocities about the tool axis), then secant steps, Illinois (modified regula falsi)
once the root is bracketed. Convergence: |T| ≤ ``torque_rtol`` · |F| · R̄ (|F| the tool's
contact force, R̄ the mean lever arm of its contact nodes) with ``torque_rtol`` not below 10×
the Newton tolerance. Measured on the ring-rolling demo: 6–9 Newton solves per increment
(the first a full solve, the next ones warm-started), 4–8× the cost of a driven-only increment.

**Frictionless idle tool**: the torque is zero for every ω (normal forces pass through the
axis), ω is undetermined and has no effect; it is set after the solve to ω_free (the ring's
surface speed over the lever arm) for the outputs, and the solve is done once.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field
from typing import Dict, Optional, Sequence

import numpy as np
from mpi4py import MPI

from fxcontact.contact.friction import LAW_NONE
from fxcontact.tools.base import RigidMotion, Tool, unit_vector

__all__ = ["ControlledMotion", "IdleRotation", "RingCentring", "RingAxisUpdate",
           "rolling_speed", "AxialRolls"]

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class ControlledMotion(RigidMotion):
    """Rigid motion with piecewise-constant rates set by a controller (integrated exactly).

    Args:
        velocity: initial translation velocity (3-vector).
        angular_velocity: initial rotation speed ω [rad/s] about ``axis``.
        axis_point, axis: rotation axis at ``t = 0`` (it translates with the tool).

    :meth:`set_rates` starts a new stage of constant rates at time t (the start of an
    increment); called again at the same t (another trial of the same increment, a cut-back)
    it overwrites that stage's rates. Rates are right-continuous: at a stage start the new
    rates apply (what the explicit schemes take at the start of the increment).
    """

    _st: dict = field(init=False, repr=False, compare=False)

    def __post_init__(self):
        v0 = np.asarray(self.velocity, dtype=np.float64).reshape(-1)
        if callable(self.velocity) or callable(self.angular_velocity):
            raise ValueError("ControlledMotion takes constant initial rates (a controller sets "
                             "them per increment)")
        w0 = float(self.angular_velocity)
        if v0.shape != (3,) or not np.all(np.isfinite(v0)) or not math.isfinite(w0):
            raise ValueError(f"velocity must be a finite 3-vector and angular_velocity finite, "
                             f"got {self.velocity!r}, {self.angular_velocity!r}")
        object.__setattr__(self, "_st", {"t": [0.0], "c": [np.zeros(3)], "th": [0.0],
                                         "v": [v0], "w": [w0]})
        object.__setattr__(self, "velocity", lambda s: self._st["v"][self._stage(s)].copy())
        object.__setattr__(self, "angular_velocity",
                           lambda s: float(self._st["w"][self._stage(s)]))
        super().__post_init__()

    def _stage(self, t: float) -> int:
        ts = self._st["t"]
        tol = 1e-12 * max(1.0, abs(ts[-1]))
        k = int(np.searchsorted(np.asarray(ts), float(t) + tol, side="right")) - 1
        return max(k, 0)

    def set_rates(self, t: float, velocity=None, angular_velocity: Optional[float] = None):
        """Rates from time ``t`` on (``None`` keeps the current one)."""
        st = self._st
        t = float(t)
        last = st["t"][-1]
        tol = 1e-12 * max(1.0, abs(last))
        if t < last - tol:
            raise ValueError(f"cannot set the rates at t = {t:.6g}, before the current stage "
                             f"(started at t = {last:.6g})")
        v = st["v"][-1] if velocity is None else np.asarray(velocity, dtype=np.float64)
        w = st["w"][-1] if angular_velocity is None else float(angular_velocity)
        if v.shape != (3,) or not np.all(np.isfinite(v)) or not math.isfinite(w):
            raise ValueError(f"rates must be a finite 3-vector and a finite ω, got {velocity!r}, "
                             f"{angular_velocity!r}")
        if t <= last + tol:
            st["v"][-1], st["w"][-1] = v.copy(), w
            return
        d = t - last
        st["c"].append(st["c"][-1] + st["v"][-1] * d)
        st["th"].append(st["th"][-1] + st["w"][-1] * d)
        st["t"].append(t)
        st["v"].append(v.copy())
        st["w"].append(w)

    @property
    def is_static(self) -> bool:
        return False

    @property
    def rotates(self) -> bool:
        return True

    def translation(self, t: float) -> np.ndarray:
        k = self._stage(t)
        st = self._st
        return st["c"][k] + st["v"][k] * (float(t) - st["t"][k])

    def angle(self, t: float) -> float:
        k = self._stage(t)
        st = self._st
        return float(st["th"][k] + st["w"][k] * (float(t) - st["t"][k]))

    def current_angular_velocity(self) -> float:
        return float(self._st["w"][-1])

    def checkpoint_state(self) -> dict:
        """The stages of rates set so far (plain numbers and lists): what a resumed run needs
        to place the tool where the checkpointed run had it (:mod:`fxcontact.checkpoint`)."""
        st = self._st
        return {"t": [float(x) for x in st["t"]], "th": [float(x) for x in st["th"]],
                "w": [float(x) for x in st["w"]],
                "c": np.asarray(st["c"], dtype=np.float64).tolist(),
                "v": np.asarray(st["v"], dtype=np.float64).tolist()}

    def restore_state(self, state: dict):
        """Restore the stages of :meth:`checkpoint_state` (ValueError if malformed)."""
        try:
            t = np.asarray(state["t"], dtype=np.float64).reshape(-1)
            th = np.asarray(state["th"], dtype=np.float64).reshape(-1)
            w = np.asarray(state["w"], dtype=np.float64).reshape(-1)
            c = np.asarray(state["c"], dtype=np.float64).reshape(-1, 3)
            v = np.asarray(state["v"], dtype=np.float64).reshape(-1, 3)
        except (KeyError, TypeError, ValueError) as e:
            raise ValueError(f"not a ControlledMotion state ({e}): {state!r:.200}") from None
        n = len(t)
        if n == 0 or not (len(th) == len(w) == len(c) == len(v) == n) or \
                np.any(np.diff(t) <= 0) or not all(np.all(np.isfinite(a))
                                                   for a in (t, th, w, c, v)):
            raise ValueError(f"not a ControlledMotion state: {n} stage times, {len(th)} angles, "
                             f"{len(w)} rotation speeds, {len(c)} positions, {len(v)} "
                             f"velocities (the same number > 0, finite, increasing times)")
        st = self._st
        st["t"], st["th"], st["w"] = [float(x) for x in t], [float(x) for x in th], \
            [float(x) for x in w]
        st["c"], st["v"] = [x.copy() for x in c], [x.copy() for x in v]


def _controlled(tool: Tool) -> ControlledMotion:
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
    sel = (contact._tool == k) & (contact._h > 0)
    e = unit_vector(tool.motion.axis, "tool axis")
    t = contact.t + contact.dt
    a = tool.motion.axis_point_at(t)
    num = den = 0.0
    if np.any(sel):
        v = np.zeros((int(np.sum(sel)), 3))
        v[:, : contact.gdim] = contact.boundary.velocities(w_function)[sel]
        arm = contact._point[sel] - a
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
    sel = (contact._tool == k) & (contact._h > 0)
    e = unit_vector(tool.motion.axis, "tool axis")
    a = tool.motion.axis_point_at(contact.t + contact.dt)
    s = n = 0.0
    if np.any(sel):
        arm = contact._point[sel] - a
        arm -= np.outer(arm @ e, e)
        s, n = float(np.sum(np.linalg.norm(arm, axis=1))), float(np.sum(sel))
    s, n = contact.boundary.comm.allreduce(np.array([s, n]), op=MPI.SUM)
    return float(np.linalg.norm(F)), (s / n if n > 0 else 0.0)


class IdleRotation:
    """An idle tool: its rotation speed is found at each increment from zero torque about its
    own axis (the mandrel and the guide rolls of a ring mill). See the module docstring for the
    method (outer secant/Illinois iteration on T(ω), warm-started Newton solves).

    Args:
        contact: the :class:`~fxcontact.contact.NodalContact` holding the tool.
        tool: the idle tool (one of ``contact.tools``), moved by a :class:`ControlledMotion`.
        torque_rtol: convergence |T| ≤ torque_rtol·|F|·R̄ (raised to 10× the Newton rtol if
            smaller).
        max_evaluations: Newton solves per increment before the increment is declared failed
            (and cut back).

    History columns: ``{tool}_omega`` (rad/s), ``{tool}_idle_torque`` (the torque at the
    accepted solve), ``{tool}_idle_tolerance``, ``{tool}_idle_solves`` and ``{tool}_surface_
    slip`` (ω R̄ − ω_free R̄: the tool's surface speed minus the body's rolling speed).
    """

    def __init__(self, contact, tool: Tool, torque_rtol: float = 1e-6,
                 max_evaluations: int = 12):
        if tool not in contact.tools:
            raise ValueError(f"tool '{tool.name}' is not one of the contact's tools "
                             f"{[t.name for t in contact.tools]}")
        self.motion = _controlled(tool)
        if not (math.isfinite(torque_rtol) and torque_rtol > 0):
            raise ValueError(f"torque_rtol must be > 0, got {torque_rtol!r}")
        if not (isinstance(max_evaluations, int) and max_evaluations >= 2):
            raise ValueError(f"max_evaluations must be an integer >= 2, got {max_evaluations!r}")
        self.contact = contact
        self.tool = tool
        self.k = contact.tools.index(tool)
        self.frictionless = contact.friction[self.k].code == LAW_NONE
        self.torque_rtol = float(torque_rtol)
        self.max_evaluations = int(max_evaluations)
        self.omega = self.motion.current_angular_velocity()
        self._row: Dict[str, float] = {}
        self._t = 0.0
        self._trial = None

    def begin_increment(self, sim, t: float, dt: float, x_t):
        self._t = t
        # the trial ω of the current evaluation (solve()), else the previous increment's
        om = self.omega if self._trial is None else self._trial
        self.motion.set_rates(t, angular_velocity=om)

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

    def solve(self, sim, begin):
        """The increment's Newton solve(s) (called by the Simulation)."""
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
                "idle_solves": n_eval}

    def end_increment(self, sim, dt: float):
        pass

    def diagnostics(self) -> Dict[str, float]:
        n = self.tool.name
        w_free = rolling_speed(self.contact, self.k, self.contact.sim.w)
        _, R = _lever_arm_and_force(self.contact, self.k)
        out = {f"{n}_{k}": v for k, v in self._row.items()}
        out[f"{n}_omega_free"] = w_free
        out[f"{n}_surface_slip"] = (self.omega - w_free) * R
        return out

    def checkpoint_state(self) -> dict:
        """ω of the last increment (the first trial of the next one) and the tool's motion."""
        return {"tool": self.tool.name, "omega": float(self.omega),
                "motion": self.motion.checkpoint_state()}

    def restore_state(self, state: dict):
        if state.get("tool") != self.tool.name:
            raise ValueError(f"the checkpoint's idle rotation is of tool {state.get('tool')!r}, "
                             f"this one of '{self.tool.name}'")
        self.omega = float(state["omega"])
        self.motion.restore_state(state["motion"])


class RingAxisUpdate:
    """Cylindrical configuration update (THEORY §5) about the axis through a centre that is
    re-set at the start of each increment (:meth:`set_center`), e.g. the ring's centroid. The
    contact condition and the mesh update use the same map within an increment."""

    def __init__(self, center=(0.0, 0.0, 0.0), axis=(0.0, 0.0, 1.0)):
        self.axis = unit_vector(axis, "ring axis")
        self.set_center(center)

    def set_center(self, center):
        c = np.asarray(center, dtype=np.float64).reshape(-1)
        if c.shape != (3,) or not np.all(np.isfinite(c)):
            raise ValueError(f"center must be a finite 3-vector, got {center!r}")
        self.center = c

    def derivatives(self, x, v, dt):
        from fxcontact.cylindrical import cylindrical_update
        return cylindrical_update(x, v, dt, self.center, self.axis, derivatives=True)

    def positions(self, x, v, dt):
        from fxcontact.cylindrical import cylindrical_update
        return cylindrical_update(x, v, dt, self.center, self.axis, derivatives=False)[0]

    def checkpoint_state(self) -> dict:
        return {"center": self.center.copy(), "axis": self.axis.copy()}

    def restore_state(self, state: dict):
        axis = unit_vector(state["axis"], "ring axis")
        if not np.allclose(axis, self.axis, rtol=0.0, atol=1e-12):
            raise ValueError(f"the checkpoint's ring axis {axis.tolist()} is not this update's "
                             f"{self.axis.tolist()}")
        self.set_center(state["center"])


class RingCentring:
    """Centring of a ring on the mill line by guide rolls that follow its growth.

    At the start of each increment the ring's centroid c and its mean outer radius R (area-
    weighted over the outer-surface nodes) are measured; the centre's nominal position is the
    projection c* of c on the mill line. Each guide roll k (radius R_g, at the angle φ_k from the
    line's direction about the ring axis) is moved, during the increment, to
    c* + (R + R_g + clearance)(cos φ_k e + sin φ_k a × e): with zero clearance it touches the
    ring where a centred ring is, and pushes it back (penalty contact) when the ring drifts off
    the line. This is the position control of the centring arms of a radial–axial mill; the
    guide rolls act only against a drift (their force is recorded).

    Args:
        outer: a :class:`~fxcontact.contact.ContactBoundary` of the ring's outer surface (used
            to measure R).
        guides: the guide-roll tools (each moved by a :class:`ControlledMotion`, axis ∥ ring
            axis).
        radii: guide-roll radii.
        angles: φ_k [rad] of each guide roll.
        line_point, line_direction: the mill line (through the main roll's and the mandrel's
            axes), in the plane normal to ``axis``.
        axis: ring axis.
        clearance: radial clearance between a centred ring and the guide rolls (negative: a
            small interference, the guide rolls press on the ring — a preload that gives the
            centre's drift a penalty stiffness from the first increment on).
        update: a :class:`RingAxisUpdate` whose centre is set to the centroid each increment
            (optional: the cylindrical configuration update about the current centre).

    History columns: ``ring_center_x/_y/_z``, ``ring_outer_radius``, ``ring_center_offset``
    (distance of the centroid from the mill line).
    """

    def __init__(self, outer, guides: Sequence[Tool] = (), radii: Sequence[float] = (),
                 angles: Sequence[float] = (), line_point=(0.0, 0.0, 0.0),
                 line_direction=(1.0, 0.0, 0.0), axis=(0.0, 0.0, 1.0), clearance: float = 0.0,
                 update: Optional[RingAxisUpdate] = None):
        self.outer = outer
        self.guides = list(guides)
        self.motions = [_controlled(g) for g in self.guides]
        if not (len(radii) == len(angles) == len(self.guides)):
            raise ValueError(f"give one radius and one angle per guide roll "
                             f"({len(self.guides)} rolls, {len(radii)} radii, "
                             f"{len(angles)} angles)")
        self.radii = [float(r) for r in radii]
        if any(not (math.isfinite(r) and r > 0) for r in self.radii):
            raise ValueError(f"guide-roll radii must be > 0, got {radii!r}")
        self.angles = [float(a) for a in angles]
        self.axis = unit_vector(axis, "ring axis")
        e = np.asarray(line_direction, dtype=np.float64)
        e = e - (e @ self.axis) * self.axis
        self.e = unit_vector(e, "mill line direction (normal to the axis)")
        self.p0 = np.asarray(line_point, dtype=np.float64).reshape(3)
        if not math.isfinite(clearance):
            raise ValueError(f"clearance must be finite, got {clearance!r}")
        self.clearance = float(clearance)
        self.update = update
        self._forms = None
        self.center = None
        self.radius = None

    def measure(self, sim):
        """(centroid, mean outer radius) of the current configuration (collective)."""
        import dolfinx.fem
        import ufl
        from fxcontact import compat
        if self._forms is None:
            x = ufl.SpatialCoordinate(sim.mesh)
            self._forms = [compat.form(x[i] * sim.space.dx) for i in range(3)]
        V = sim.volume()
        c = np.array([sim.comm.allreduce(dolfinx.fem.assemble_scalar(f), op=MPI.SUM)
                      for f in self._forms]) / V
        b = self.outer
        x = sim.vertex_positions()[b.vertices]
        d = x - c
        d -= np.outer(d @ self.axis, self.axis)
        num = float(np.sum(b.areas * np.linalg.norm(d, axis=1)))
        den = float(np.sum(b.areas))
        num, den = sim.comm.allreduce(np.array([num, den]), op=MPI.SUM)
        return c, num / den

    def begin_increment(self, sim, t: float, dt: float, x_t):
        self._sim = sim
        c, R = self.measure(sim)
        self.center, self.radius = c, R
        if self.update is not None:
            self.update.set_center(c)
        cs = self.p0 + ((c - self.p0) @ self.e) * self.e + ((c - self.p0) @ self.axis) * self.axis
        f = np.cross(self.axis, self.e)
        for mot, Rg, phi in zip(self.motions, self.radii, self.angles):
            target = cs + (R + Rg + self.clearance) * (math.cos(phi) * self.e + math.sin(phi) * f)
            now = mot.axis_point_at(t)
            mot.set_rates(t, velocity=(target - now) / dt)

    def end_increment(self, sim, dt: float):
        pass

    def diagnostics(self) -> Dict[str, float]:
        c, R = self.measure(sim=self._sim)   # after the geometry update
        self.center, self.radius = c, R
        d = c - self.p0
        off = d - (d @ self.e) * self.e - (d @ self.axis) * self.axis
        return {"ring_center_x": float(c[0]), "ring_center_y": float(c[1]),
                "ring_center_z": float(c[2]), "ring_outer_radius": float(self.radius),
                "ring_center_offset": float(np.linalg.norm(off))}

    def checkpoint_state(self) -> dict:
        """The guide rolls' motions and the last measured centre and outer radius."""
        return {"guides": [g.name for g in self.guides],
                "center": None if self.center is None else np.asarray(self.center).tolist(),
                "radius": None if self.radius is None else float(self.radius),
                "motions": [m.checkpoint_state() for m in self.motions]}

    def restore_state(self, state: dict):
        names = [g.name for g in self.guides]
        if state.get("guides") != names:
            raise ValueError(f"the checkpoint's centring guides {state.get('guides')} are not "
                             f"these {names}")
        self.center = None if state["center"] is None else np.asarray(state["center"], float)
        self.radius = None if state["radius"] is None else float(state["radius"])
        for m, st in zip(self.motions, state["motions"]):
            m.restore_state(st)


class AxialRolls:
    """Axial (cone) rolls of a radial–axial ring mill: their apex follows the ring's centre on
    the mill line, they move along the ring axis at given speeds, and they are idle.

    Each cone (any tool, usually an analytic :class:`~fxcontact.Cone` whose lower generatrix
    lies in the face of the ring it rolls) moves with a :class:`ControlledMotion`. At the start
    of each increment its apex is sent, within the increment, to the projection c* of the
    ring's centroid on the mill line (measured by ``centring``): the cones retreat along the
    line as the ring grows, and with the apex on the ring's axis a cone's surface speed
    ω s sin α equals the face's speed ω_ring ρ at every radius (rolling without slip). Along
    the ring axis each cone moves at its own constant speed (``axial_speeds``; positive along
    ``centring.axis``). The cones must be frictionless: their torque about their own axis is
    then zero for any ω, which is undetermined and has no effect on the solution; it is set
    after the solve to the rolling speed ω_free of the contact nodes (:func:`rolling_speed`),
    for the outputs and the drawing.

    Args:
        contact: the :class:`~fxcontact.contact.NodalContact` holding the cones.
        cones: the cone tools (each moved by a :class:`ControlledMotion`, apex = its
            ``axis_point`` at t = 0).
        centring: the :class:`RingCentring` of the mill (mill line, ring axis, centroid).
        axial_speeds: speed of each cone along the ring axis [length/time].

    History columns: ``{cone}_apex_line`` (apex position along the mill line from its
    ``line_point``), ``{cone}_apex_axial`` (along the ring axis) and ``{cone}_omega``.
    """

    def __init__(self, contact, cones: Sequence[Tool], centring: "RingCentring",
                 axial_speeds: Sequence[float]):
        self.contact = contact
        self.cones = list(cones)
        if not self.cones:
            raise ValueError("give at least one cone")
        if len(axial_speeds) != len(self.cones):
            raise ValueError(f"give one axial speed per cone ({len(self.cones)} cones, "
                             f"{len(axial_speeds)} speeds)")
        self.speeds = [float(v) for v in axial_speeds]
        if not all(math.isfinite(v) for v in self.speeds):
            raise ValueError(f"axial speeds must be finite, got {axial_speeds!r}")
        self.motions = [_controlled(c) for c in self.cones]
        self.k = []
        for c in self.cones:
            if c not in contact.tools:
                raise ValueError(f"cone '{c.name}' is not one of the contact's tools "
                                 f"{[t.name for t in contact.tools]}")
            k = contact.tools.index(c)
            if contact.friction[k].code != LAW_NONE:
                raise ValueError(f"cone '{c.name}' must be frictionless (its ω is then free); "
                                 f"a cone with friction needs the zero-torque condition of "
                                 f"IdleRotation")
            self.k.append(k)
        self.centring = centring
        self.omega = [m.current_angular_velocity() for m in self.motions]
        self._t = 0.0

    def _apex(self, m: ControlledMotion, t: float) -> np.ndarray:
        return m.axis_point_at(t)

    def begin_increment(self, sim, t: float, dt: float, x_t):
        self._t = t
        c, _ = self.centring.measure(sim)
        cz = self.centring
        target = cz.p0 + ((c - cz.p0) @ cz.e) * cz.e
        for m, v, w in zip(self.motions, self.speeds, self.omega):
            now = self._apex(m, t)
            d = target - now
            d -= (d @ cz.axis) * cz.axis
            m.set_rates(t, velocity=d / dt + v * cz.axis, angular_velocity=w)

    def end_increment(self, sim, dt: float):
        for i, (m, k) in enumerate(zip(self.motions, self.k)):
            self.omega[i] = rolling_speed(self.contact, k, sim.w)
            m.set_rates(self._t, angular_velocity=self.omega[i])

    def diagnostics(self) -> Dict[str, float]:
        cz = self.centring
        t = self.contact.t + self.contact.dt
        out = {}
        for cone, m, w in zip(self.cones, self.motions, self.omega):
            a = self._apex(m, t) - cz.p0
            out[f"{cone.name}_apex_line"] = float(a @ cz.e)
            out[f"{cone.name}_apex_axial"] = float(a @ cz.axis)
            out[f"{cone.name}_omega"] = float(w)
        return out

    def checkpoint_state(self) -> dict:
        return {"cones": [c.name for c in self.cones], "omega": list(self.omega),
                "motions": [m.checkpoint_state() for m in self.motions]}

    def restore_state(self, state: dict):
        names = [c.name for c in self.cones]
        if state.get("cones") != names:
            raise ValueError(f"the checkpoint's cones {state.get('cones')} are not these {names}")
        self.omega = [float(w) for w in state["omega"]]
        for m, st in zip(self.motions, state["motions"]):
            m.restore_state(st)
