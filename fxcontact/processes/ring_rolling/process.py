"""Radial ring rolling (THEORY §12.1, §14.4): a driven main roll, an idle mandrel fed towards
it, two guide rolls that centre the growing ring, optional axial cone rolls.

The upper half of the ring in height (mid-plane z = 0, ``v_z = 0``), the whole plan. The
main roll's axis is at x = R + R₁ (driven, turning clockwise at ``rpm``), the mandrel's at
x = r − R₂ + v_f t (fed at ``feed_speed``, idle: its ω is found at each increment from zero
torque about its axis, :class:`fxcontact.IdleRotation`); both start ``initial_bite`` into the
ring. Two frictionless guide rolls at ± ``guide_angle`` from the mill line on the main-roll side
follow the growing ring (:class:`~fxcontact.processes.ring_rolling.mill.RingCentring`).
Forces and torques are those of the whole ring (twice the half model's). The configuration
update is cylindrical about the ring's centroid (:class:`~fxcontact.kinematics.RingAxisUpdate`,
THEORY §5) or cartesian.

The case, its material and the theory of the pass: :mod:`~fxcontact.processes.ring_rolling.case`.

:class:`RingRollingCase` is the ring, the mill, the material, the friction per tool, the
kinematics and the numerics; :func:`build` returns the ready :class:`fxcontact.Simulation` with
its handles (:class:`RingRollingSetup`); :func:`run` rolls the ring for ``revolutions`` and
returns a :class:`RingRollingResult` (forces, torques, mandrel speed, diameter growth against
volume constancy, the theory of :mod:`fxcontact.theory.forming` (feed window, contact length,
2kHLQ), volume, quality, pictures, ``report()``).
"""

from __future__ import annotations

import csv
import logging
import math
import os
import time
from dataclasses import dataclass, field
from typing import Dict, List, Optional

import numpy as np
from mpi4py import MPI

import fxcontact as fx
from fxcontact import compat
from fxcontact.idle import ControlledMotion, IdleRotation
from fxcontact.kinematics import RingAxisUpdate
from fxcontact.power import PowerBalance, delivered_power
from fxcontact.processes.common import check_output_dir
from fxcontact.processes.contact_laws import law_text
from fxcontact.processes.monitor import SteadyRun, contact_lines
from fxcontact.processes.ring_rolling import heat as ring_heat, mill as ring_mill
from fxcontact.processes.ring_rolling import pictures as ring_pictures
from fxcontact.processes.ring_rolling.case import RingRollingCase, theory
from fxcontact.processes.ring_rolling.mill import (AxialRolls, RingCentring, cone_row,
                                                   set_ring_remeshing)
from fxcontact.theory import forming

__all__ = ["RingRollingSetup", "RingRollingResult", "build", "run"]

log = logging.getLogger("fxcontact.processes")

def _tool(kind, name, radius, point, height, motion, facet_size, n_theta=None):
    """Analytic cylinder, or its faceted version (flat facets), moved by ``motion``."""
    if kind == "analytic":
        base = fx.Cylinder(point, (0.0, 0.0, 1.0), radius, name=name)
    else:
        rev = fx.RevolvedProfile.grooved_roll(radius, 3.0 * height, s0=-1.5 * height,
                                              axis_point=point, axis=(0.0, 0.0, 1.0), name=name)
        n = n_theta or max(12, int(math.ceil(2 * math.pi * radius / facet_size)))
        base = fx.FacetedTool.from_revolved(rev, n, ds=facet_size, mode="flat")
    return fx.MovedTool(base, motion, name=name)


# ---- the set-up

@dataclass
class RingRollingSetup:
    """A set-up mill: the simulation, its tools and controllers, the theory of the pass."""

    case: RingRollingCase
    sim: object                     #: the :class:`fxcontact.Simulation`
    contact: object                 #: the :class:`fxcontact.NodalContact` of every tool
    tools: list                     #: main roll, mandrel, guide rolls (, cone)
    exact: list                     #: the analytic tools (the true penetration)
    outer: object                   #: ContactBoundary of the outer surface
    inner: object                   #: ... of the bore
    top: object                     #: ... of the top face
    centring: object                #: :class:`~fxcontact.processes.ring_rolling.mill.RingCentring`
    idle: object                    #: :class:`fxcontact.IdleRotation`
    #: :class:`~fxcontact.processes.ring_rolling.mill.AxialRolls` (cones)
    axial: object = None
    update: object = None           #: :class:`~fxcontact.kinematics.RingAxisUpdate` or None
    theory: dict = field(default_factory=dict)   #: feed window, L, rate, σ₀, 2kHLQ
    dt: float = math.nan
    n_increments: int = 0
    h_theta: float = math.nan       #: circumferential spacing at the outer surface
    cone_geometry: Optional[dict] = None

    @property
    def main(self):
        return self.tools[0]

    @property
    def mandrel(self):
        return self.tools[1]

    @property
    def guides(self):
        return self.tools[2:4]

    @property
    def cone(self):
        return self.tools[4] if len(self.tools) > 4 else None


def build(case: RingRollingCase, comm=None, output_dir: Optional[str] = None,
          vtk_every: int = 0, checkpoint_every: int = 0, resume=None,
          name: str = "ring_rolling") -> RingRollingSetup:
    """The mill set up: the upper half ring, MINI space, Norton–Hoff, the mid-plane condition,
    the tools with their motions and friction, the centring, the idle mandrel (and the cones),
    the ring turning rigidly at the main roll's speed as the first guess. ``vtk_every``,
    ``checkpoint_every`` write into ``output_dir``; ``resume`` (True: the newest checkpoint of
    this run, or a path) restores a checkpoint."""
    comm = comm or MPI.COMM_WORLD
    c = case
    th = theory(c)
    R1, R2, R, r, H, Rg = (float(x) for x in (c.R1, c.R2, c.R, c.r, c.H, c.Rg))
    w1 = c.omega_main
    v_s = w1 * R1
    mat = (c.material if c.material is not None else
           fx.NortonHoff(K=c.K, m=c.m, regularization=1e-3 * th["strain_rate_bite"]))
    dt = c.t_rev / int(c.increments_per_rev)
    n_inc = min(int(math.ceil(c.revolutions * c.increments_per_rev - 1e-9)),
                int(c.max_increments))

    # ---- ring, upper half (mid-plane z = 0)
    msh, _, ft = fx.structured_ring(comm, R, r, H, int(c.n_theta), int(c.n_r), int(c.n_z),
                                    sector="upper")
    h_theta = 2.0 * math.pi * R / int(c.n_theta)
    sp = fx.MixedSpace(msh)
    update = RingAxisUpdate((0.0, 0.0, 0.0)) if c.update == "cylindrical" else None
    files = bool(vtk_every or checkpoint_every or resume)
    sim = fx.Simulation(sp, mat, solver_options=fx.SolverOptions(
        max_it=int(c.max_it), rtol=float(c.newton_rtol), ftol=float(c.newton_ftol),
        line_search=c.line_search,
        active_set_prediction=c.active_set_prediction,
        penalty_continuation=c.penalty_continuation),
        kinematics=update, output_dir=output_dir if files else None, name=name,
        output_every=max(1, int(vtk_every or 10 ** 9)), progress=False,
        volume_correction=c.volume_correction, checkpoint_every=int(checkpoint_every),
        overwrite=not resume)
    sim.add_velocity_bc(sim.facets(ft, fx.RING_TAGS["mid_plane"]), 0.0, component=2)

    # ---- tools: main roll (driven, clockwise), mandrel (idle, fed), guide rolls (idle)
    fs = c.facet_size or h_theta
    e0 = float(c.initial_bite)
    xm = (R + R1 - e0, 0.0, 0.0)
    main = _tool(c.tools, "main_roll", R1, xm, H,
                 fx.RigidMotion(angular_velocity=-w1, axis_point=xm), fs)
    w2 = v_s * r / (R * R2)                             # bore speed / R2
    xd = (r - R2 + e0, 0.0, 0.0)
    mandrel = _tool(c.tools, "mandrel", R2, xd, H,
                    ControlledMotion(velocity=(c.feed_speed, 0.0, 0.0), angular_velocity=w2,
                                     axis_point=xd), fs)
    phi = math.radians(c.guide_angle)
    guides = []
    for k, s in enumerate((1.0, -1.0)):
        xg = ((R + Rg) * math.cos(phi), s * (R + Rg) * math.sin(phi), 0.0)
        guides.append(_tool(c.tools, f"guide{k + 1}", Rg, xg, H,
                            ControlledMotion(axis_point=xg), fs))
    tools = [main, mandrel] + guides
    cone_geo = None
    if c.cones:
        # upper axial roll: apex on the mill line at the ring's centre, lower generatrix in the
        # top face (z = H/2, less the initial bite), pointing away from the main roll; the lower
        # axial roll is its mirror image in the mid-plane (the symmetry of the half model)
        alpha = math.radians(c.cone_half_angle)
        apex = (0.0, 0.0, 0.5 * H - e0)
        w_axis = (-math.cos(alpha), 0.0, math.sin(alpha))
        # rolling without slip on the face: ω_cone sin α = ω_ring (apex on the ring axis)
        w_cone = v_s / R / math.sin(alpha)
        cone = fx.MovedTool(fx.Cone(apex, w_axis, alpha, name="cone"),
                            ControlledMotion(velocity=(0.0, 0.0, 0.5 * c.cone_speed),
                                             angular_velocity=w_cone, axis_point=apex,
                                             axis=w_axis), name="cone")
        tools.append(cone)
        cone_geo = dict(alpha=alpha, s0=0.5 * r, s1=R + 0.5 * (R - r))
    # the exact (analytic) surfaces of the same tools, moved by the same motions: the true
    # penetration is measured against them for every variant (a faceted tool's vertices lie on
    # them, its flat facets cut inside by up to the sagitta s²/8R)
    exact = [_tool("analytic", t.name, rad, t.motion.axis_point, H, t.motion, fs)
             for t, rad in zip(tools, [R1, R2, Rg, Rg])] + tools[4:]
    friction = ring_mill.mill_friction(c.friction, [g.name for g in guides], c.idle_guides)
    tags = [fx.RING_TAGS["outer"], fx.RING_TAGS["inner"]]
    if c.cones:
        tags.append(fx.RING_TAGS["top"])
    contact = fx.NodalContact(fx.ContactBoundary(sp, ft, tags), tools, scheme=c.scheme,
                              friction=friction, slip_velocity=1e-3 * v_s, name="mill",
                              penalty=c.penalty, sticky_gap=c.sticky_gap)
    outer = fx.ContactBoundary(sp, ft, fx.RING_TAGS["outer"])
    inner = fx.ContactBoundary(sp, ft, fx.RING_TAGS["inner"])
    top = fx.ContactBoundary(sp, ft, fx.RING_TAGS["top"])
    centring = RingCentring(outer, guides, [Rg, Rg], [phi, -phi], update=update,
                            clearance=c.guide_clearance)
    sim.add_controller(centring)
    idle = IdleRotation(contact, [mandrel] + guides if c.idle_guides else mandrel,
                        method=c.idle_method)
    sim.add_controller(idle)
    axial = None
    if c.cones:
        # the half model's cone rises at half the opening speed of the axial gap
        axial = sim.add_controller(AxialRolls(contact, [tools[4]], centring,
                                              [0.5 * c.cone_speed]))
    sim.add_contributor(contact)
    if c.heat is not None:   # air on the outer, bore and top faces; the mid-plane: insulated
        c.heat.attach(sim, ft, [fx.RING_TAGS[k] for k in ("outer", "inner", "top")],
                      [t.name for t in tools])
    if c.remesh:
        set_ring_remeshing(sim, centring, c, h_theta, start=not resume)
    if resume:
        # the state of a checkpoint (True: the newest of this run): fields, geometry, contact,
        # the controllers (guide-roll and mandrel motions, ω, ring centre) and the history
        sim.resume(None if resume is True else resume)
    else:
        # first guess: the ring turning rigidly at the main roll's surface speed
        x0 = sim.vertex_positions()
        v0 = np.zeros_like(x0)
        v0[:, 0], v0[:, 1] = -x0[:, 1] * v_s / R, x0[:, 0] * v_s / R
        sim.w_prev.x.array[sim.space.vertex_dofs] = v0
        sim.w_prev.x.scatter_forward()
    return RingRollingSetup(c, sim, contact, tools, exact, outer, inner, top, centring, idle,
                            axial, update, th, dt, n_inc, h_theta, cone_geo)


# ---- one row per increment

class _Measure:
    """The per-increment row of the mill (diameters, height, forces and torques of the whole
    ring, ring and mandrel speeds, penetrations, contact nodes per tool, volume, cones)."""

    def __init__(self, s: RingRollingSetup, power: Optional[PowerBalance] = None):
        self.s = s
        self.comm = s.sim.comm
        self.V0 = s.sim.initial_volume   # kept by a remesh
        if s.outer is not s.centring.outer:   # after a remesh: the boundaries of the new mesh
            ft = s.sim._remesh_facet_tags
            s.outer, s.inner, s.top = (s.centring.outer, s.inner.remeshed(s.sim.space, ft),
                                       s.top.remeshed(s.sim.space, ft))
        self.nown = s.sim.mesh.topology.index_map(0).size_local
        self.power = power or PowerBalance(s.sim, [s.contact])   # one over the remeshes
        self.remeshes = len(s.sim.remeshes)

    def _sum(self, *values):
        return self.comm.allreduce(np.array(values, dtype=float), op=MPI.SUM)

    def _max(self, x):
        return self.comm.allreduce(float(x), op=MPI.MAX)

    def surface_radius(self, b, c):
        x = self.s.sim.vertex_positions()[b.vertices] - c
        num, den = self._sum(float(np.sum(b.areas * np.hypot(x[:, 0], x[:, 1]))),
                             float(np.sum(b.areas)))
        return num / den

    def top_height(self):
        top = self.s.top
        z = self.s.sim.vertex_positions()[top.vertices][:, 2]
        num, den = self._sum(float(np.sum(top.areas * z)), float(np.sum(top.areas)))
        return 2.0 * num / den

    def ring_omega(self, c):
        """Least-squares rotation rate of the vertices about the ring axis through c."""
        sim, n = self.s.sim, self.nown
        x = sim.vertex_positions()
        v = sim.w.x.array[sim.space.vertex_dofs][:n]
        d = x[:n] - c
        num, den = self._sum(float(np.sum(d[:, 0] * v[:, 1] - d[:, 1] * v[:, 0])),
                             float(np.sum(d[:, 0] ** 2 + d[:, 1] ** 2)))
        return num / den

    def exact_depth(self):
        """Largest depth of the ring's surface vertices inside the exact tools."""
        s, d = self.s, 0.0
        for b in (s.outer, s.inner):
            X = s.sim.vertex_positions()[b.vertices]
            for tool in s.exact:
                if len(X):
                    d = max(d, float(np.max(-tool.project(X, s.sim.t, hessian=False).gap)))
        return self._max(d)

    def cone_depth(self):
        """Largest depth of the top-face vertices inside the cone."""
        s = self.s
        X = s.sim.vertex_positions()[s.top.vertices]
        d = float(np.max(-s.cone.project(X, s.sim.t, hessian=False).gap)) if len(X) else 0.0
        return self._max(d)

    def nodes_on(self, k):
        nodes = self.s.contact.nodes
        return self.comm.allreduce(int(np.sum((nodes.tool == k) & nodes.active)), op=MPI.SUM)

    def power_columns(self, q) -> dict:
        """The power balance of the increment, whole ring (THEORY §14.5): what each tool
        delivers (−Σ f·v_tool at the contact points: the main roll's is its torque × ω, the
        idle mandrel's its feed force × feed speed, its rotation's ≈ 0), the dissipation on the
        increment's start configuration, the friction and penalty powers
        (:class:`fxcontact.power.PowerBalance` with the velocities turned by the cylindrical
        update)."""
        s = self.s
        ended = s.sim.space is not self.power._space   # by a remesh: the contact was reset
        pw = self.power(q)
        P = [math.nan if ended else 2 * delivered_power(s.contact, s.sim.t, k)
             for k in range(len(s.tools))]
        return dict(main_power=P[0], mandrel_power=P[1], guide_power=P[2] + P[3],
                    cone_power=sum(P[4:]),
                    mandrel_rotation_power=-2 * q.get("mandrel_torque", 0.0) * q["mandrel_omega"],
                    power_in=math.nan if ended else 2 * pw["power_in"],
                    dissipation=2 * pw["dissipation"],
                    friction_power=2 * pw["friction_power"],
                    penalty_power=2 * pw["penalty_power"], power_balance=pw["power_balance"],
                    power_balance_penalty=pw["power_balance_penalty"])

    def __call__(self, res) -> dict:
        s = self.s
        sim, c, t_rev = s.sim, s.case, s.case.t_rev
        q = res.row
        power = self.power_columns(q)
        ctr = np.array([q["ring_center_x"], q["ring_center_y"], q["ring_center_z"]])
        Ro, Ri = self.surface_radius(s.outer, ctr), self.surface_radius(s.inner, ctr)
        Hm = self.top_height()
        V = sim.volume()
        w_ring = self.ring_omega(ctr)
        v_s = c.omega_main * c.R1
        row = dict(increment=q["increment"], time=sim.t, revolutions=sim.t / t_rev,
                   outer_diameter=2 * Ro, inner_diameter=2 * Ri, height=Hm,
                   mean_diameter=Ro + Ri,
                   mean_diameter_volume=float(forming.ring_rolling_mean_diameter(
                       2.0 * V, Hm, Ro - Ri)),
                   main_force_x=2 * q["main_roll_force_x"],
                   main_force_y=2 * q["main_roll_force_y"],
                   main_torque=2 * q.get("main_roll_torque", 0.0),
                   mandrel_force_x=2 * q["mandrel_force_x"],
                   mandrel_force_y=2 * q["mandrel_force_y"],
                   mandrel_torque=2 * q.get("mandrel_torque", 0.0),
                   guide_force=2 * math.hypot(q["guide1_force_x"], q["guide1_force_y"])
                   + 2 * math.hypot(q["guide2_force_x"], q["guide2_force_y"]),
                   ring_omega=w_ring, ring_omega_nominal=v_s / Ro,
                   mandrel_omega=q["mandrel_omega"],
                   mandrel_angle=s.mandrel.motion.angle(sim.t),
                   mandrel_omega_free=q["mandrel_omega_free"],
                   mandrel_idle_torque=2 * q["mandrel_idle_torque"],
                   mandrel_idle_tolerance=2 * q["mandrel_idle_tolerance"],
                   mandrel_surface_slip=q["mandrel_surface_slip"],
                   mandrel_solves=q["mandrel_idle_solves"],
                   bore_speed=w_ring * Ri,
                   penetration=q["mill_penetration_true"],
                   penetration_exact=self.exact_depth(),
                   nodes_main=self.nodes_on(0), nodes_mandrel=self.nodes_on(1),
                   nodes_guides=self.nodes_on(2) + self.nodes_on(3),
                   height_max=2 * self._max(np.max(
                       sim.vertex_positions()[s.top.vertices][:, 2], initial=-np.inf)),
                   newton_iterations=q["newton_iterations_all"], cutbacks=q["cutbacks"],
                   wall=q["wall_increment_all"], wall_assembly=q["wall_assembly"],
                   wall_linear_solve=q["wall_linear_solve"], wall_contact=q["wall_contact"],
                   volume_change=V / self.V0 - 1.0,
                   center_x=ctr[0], center_y=ctr[1], center_offset=q["ring_center_offset"],
                   max_strain=self._max(np.max(sim.strain.x.array, initial=0.0)),
                   max_strain_rate=self._max(np.max(sim.strain_rate.x.array, initial=0.0)),
                   min_quality=q["min_quality"], **power,
                   **{k: v for k, v in q.items() if k.startswith("heat_")})
        if c.cones:
            row.update(cone_row(q, self.nodes_on(4), self.cone_depth(), Hm, Ro, Ri, w_ring,
                                 s.cone_geometry, s.theory["K"], s.theory["m"]))
        return row


# ---- the result

_NAN = math.nan


@dataclass
class RingRollingResult(SteadyRun):
    """A ring rolled (:func:`run`; ``status`` "done" or "failed"): the history (one row per
    increment: diameters, forces and torques of the whole ring in N and N mm, speeds,
    penetrations, powers), the theory of the pass and the summary. The power balance of
    :class:`~fxcontact.processes.monitor.SteadyRun` holds the second half's means (whole ring):
    ``power_balance = P_in / (D + P_f) − 1`` and ``power_balance_penalty`` with the penalty
    work, from the means of the powers. With the penalty work the balance is the discrete
    virtual-power identity (Newton's tolerance); without it, it closes only when a node takes
    many increments to cross the bite: the penalty work Σ r_n · (v − v_tool) is the
    penetration's change of the nodes as they enter and leave the bite, not zero when each
    increment turns the ring by a good part of the bite's length (``bite_increments``)."""

    case: Optional[RingRollingCase] = None
    t_rev: float = _NAN                #: one ring revolution [s]
    dt: float = _NAN
    h_theta: float = _NAN              #: circumferential spacing at the outer surface [mm]
    feed_per_rev: float = _NAN         #: feed per ring revolution [mm]
    feed_window: dict = field(default_factory=dict)   #: Hawkyard / bite-in window [mm/rev]
    contact_length: float = _NAN       #: the bite's L [mm]
    strain_rate_bite: float = _NAN     #: its representative strain rate [1/s]
    sigma0: float = _NAN               #: flow stress there [MPa]
    force_estimate: float = _NAN       #: 2kHLQ [N]
    Q: float = _NAN
    volume_initial: float = _NAN       #: the whole ring's [mm³]
    sim_history: list = field(default_factory=list)   #: the Simulation's rows
    cone_geometry: Optional[dict] = None
    revolutions: float = _NAN          #: done
    bite_increments: float = _NAN      #: increments a point of the ring takes to cross the bite
    power_in: float = _NAN             #: what the tools deliver, second-half mean [N mm/s]
    main_power: float = _NAN           #: ... the main roll (torque × ω)
    mandrel_power: float = _NAN        #: ... the mandrel (feed force × feed speed)
    mandrel_rotation_power_max: float = _NAN   #: max |torque × ω| of the idle mandrel
    volume_change: float = _NAN        #: at the end
    volume_drift_per_rev: float = _NAN
    diameter_volume_error: float = _NAN   #: max |mean D / V/(πHB) − 1|
    max_penetration: float = _NAN
    max_penetration_exact: float = _NAN   #: against the exact (analytic) tools
    max_center_offset: float = _NAN
    min_edge: float = _NAN
    max_strain: float = _NAN
    max_strain_rate: float = _NAN
    main_force_mean: float = _NAN      #: main roll radial force, second-half mean [N]
    main_torque_mean: float = _NAN     #: main roll torque, second-half mean [N mm]
    mandrel_force_mean: float = _NAN   #: mandrel radial force, second-half mean [N]
    mandrel_torque_max: float = _NAN
    mandrel_torque_tol_max: float = _NAN
    mandrel_slip_max: float = _NAN
    mandrel_speed_ratio: float = _NAN  #: mandrel surface / bore speed, second-half mean
    outer_growth: float = _NAN         #: outer diameter / 2R − 1
    wall_per_rev: float = _NAN
    cone: dict = field(default_factory=dict)   #: the cones' summary (with cones)
    remeshes: list = field(default_factory=list)   #: the RemeshRecords (``remesh=True``)
    #: with heat: the run's heat terms and temperatures against the estimate
    #: (:func:`~fxcontact.processes.ring_rolling.heat.summary`)
    heat: dict = field(default_factory=dict)
    pictures: Dict[str, str] = field(default_factory=dict)

    def second_half(self) -> List[dict]:
        """The rows of the second half of the run (the bite-in left out)."""
        h = self.history
        return [q for q in h if q["revolutions"] > 0.5 * h[-1]["revolutions"]] or h

    def report(self) -> str:
        """The summary a process engineer reads."""
        c, w = self.case, self.feed_window
        inside = w["min"] <= self.feed_per_rev <= w["max"]
        fr = {k: law_text(c.tool_friction(t)) for k, t in (("main", "main_roll"), ("mandrel",) * 2)}
        lines = [
            f"ring R = {c.R:g}, r = {c.r:g}, H = {c.H:g} mm; main roll R1 = {c.R1:g} at "
            f"{c.rpm:g} rpm ({fr['main']}), mandrel R2 = {c.R2:g} fed at {c.feed_speed:g} mm/s "
            f"({fr['mandrel']}); mesh {c.n_theta} x {c.n_r} x {c.n_z} (outer spacing "
            f"{self.h_theta:.2f} mm), {c.update} update, {c.scheme} contact, {c.tools} tools",
            f"one ring revolution {self.t_rev:.3f} s; feed per revolution "
            f"{self.feed_per_rev:.3f} mm; window (Hawkyard penetration, bite-in with mu = "
            f"{c.mu_bite}): {w['min']:.3f} - {w['max']:.3f} mm/rev -> "
            f"{'inside' if inside else 'OUTSIDE'}",
            f"bite contact length L = {self.contact_length:.2f} mm, strain rate ~ "
            f"{self.strain_rate_bite:.3g} 1/s, sigma0 = {self.sigma0:.0f} MPa ("
            + (f"K = {c.K:g}, m = {c.m:g}" if c.material is None else
               f"{type(c.material.flow).__name__}: its mean over the run's strain at "
               + (f"{c.heat.initial_temperature:g} °C" if c.heat is not None
                  else f"{c.material.temperature} °C"))
            + f"), 2kHLQ = {self.force_estimate / 1e3:.1f} kN (Q = {self.Q:.3f})"]
        if c.thesis_flow_stress_note:
            lines.append(f"note: {c.thesis_flow_stress_note}")
        lines.append(f"status {self.status} {self.message}")
        if not self.history:
            return "\n".join(lines)
        lines += [
            f"{self.increments} increments, {self.revolutions:.2f} revolutions "
            f"({self.wall_per_rev:.0f} s/rev)",
            f"volume change {100 * self.volume_change:.3f} % "
            f"({100 * self.volume_drift_per_rev:.3f} %/rev); mean diameter vs V/(pi H B): max "
            f"|error| {100 * self.diameter_volume_error:.2f} %; outer D growth "
            f"{100 * self.outer_growth:.2f} %",
            f"main roll radial force (second half mean) {self.main_force_mean / 1e3:.1f} kN = "
            f"{self.main_force_mean / self.force_estimate:.2f} x 2kHLQ; torque "
            f"{self.main_torque_mean / 1e6:.2f} kN m",
            f"mandrel: radial force {self.mandrel_force_mean / 1e3:.1f} kN; max |torque| "
            f"{self.mandrel_torque_max:.3g} N mm (tolerance up to "
            f"{self.mandrel_torque_tol_max:.3g}); surface slip max {self.mandrel_slip_max:.3g} "
            f"mm/s; mandrel surface / bore speed {self.mandrel_speed_ratio:.4f}",
            *([f"cones (gap opening {c.cone_speed} mm/s): axial force max "
               f"{self.cone['force_max'] / 1e3:.1f} kN, {self.cone['nodes_mean']:.1f} contact "
               f"nodes on average, max penetration {self.cone['penetration_max']:.4f} mm, "
               f"force / 2kBL_a {self.cone['force_ratio']:.2f}; max height "
               f"{self.cone['height_max']:.3f} mm, final cone gap {self.cone['gap_last']:.3f} "
               f"mm"] if self.cone else []),
            f"max penetration {self.max_penetration:.4f} mm; centre off the mill line max "
            f"{self.max_center_offset:.4f} mm (smallest edge {self.min_edge:.2f} mm); max "
            f"strain {self.max_strain:.3f}, max strain rate {self.max_strain_rate:.3f} 1/s"]
        lines.append(
            f"power (second half mean, whole ring): tools {self.power_in / 1e6:.4g} kW = main "
            f"roll {self.main_power / 1e6:.4g} + mandrel feed {self.mandrel_power / 1e6:.4g} "
            f"(idle rotation max {self.mandrel_rotation_power_max / 1e3:.2g} W) + guides/cones; "
            f"dissipation {self.dissipation / 1e6:.4g} kW, friction {self.friction_power / 1e6:.4g}"
            f" kW, penalty {self.penalty_power / 1e6:.4g} kW; balance P_in/(D + P_f) - 1 = "
            f"{100 * self.power_balance:.1f} % (with the penalty work "
            f"{self.power_balance_penalty:.1e}; the bite is crossed in "
            f"{self.bite_increments:.2g} increments)")
        lines += ring_heat.report_lines(self)
        return "\n".join(lines + [self.run_summary()])


def _summarize(res: RingRollingResult, comm, msh) -> None:
    rows = res.history
    last = rows[-1]
    second = res.second_half()
    h_min = comm.allreduce(float(np.min(_edge_lengths(msh), initial=np.inf)), op=MPI.MIN)
    mean = {k: float(np.mean([q[k] for q in second]))
            for k in ("main_force_x", "main_torque", "mandrel_force_x")}
    res.revolutions = last["revolutions"]
    res.volume_change = last["volume_change"]
    res.volume_drift_per_rev = last["volume_change"] / max(last["revolutions"], 1e-300)
    res.diameter_volume_error = max(abs(q["mean_diameter"] / q["mean_diameter_volume"] - 1)
                                    for q in rows)
    res.max_penetration = max(q["penetration"] for q in rows)
    res.max_penetration_exact = max(q["penetration_exact"] for q in rows)
    res.max_center_offset = max(q["center_offset"] for q in rows)
    res.min_edge = h_min
    res.max_strain = last["max_strain"]
    res.max_strain_rate = max(q["max_strain_rate"] for q in rows)
    res.main_force_mean = mean["main_force_x"]
    res.main_torque_mean = mean["main_torque"]
    res.mandrel_force_mean = -mean["mandrel_force_x"]
    res.mandrel_torque_max = max(abs(q["mandrel_idle_torque"]) for q in rows)
    res.mandrel_torque_tol_max = max(q["mandrel_idle_tolerance"] for q in rows)
    res.mandrel_slip_max = max(abs(q["mandrel_surface_slip"]) for q in rows)
    res.mandrel_speed_ratio = float(np.mean([q["mandrel_omega"] * res.case.R2 / q["bore_speed"]
                                             for q in second]))
    res.outer_growth = last["outer_diameter"] / (2 * res.case.R) - 1.0
    if "cone_force" in last:
        est = [q for q in rows if q["cone_force_estimate"] > 0 and q["nodes_cone"] > 0]
        res.cone = dict(
            force_max=max(q["cone_force"] for q in rows),
            nodes_mean=float(np.mean([q["nodes_cone"] for q in rows])),
            penetration_max=max(q["cone_penetration"] for q in rows),
            force_ratio=(float(np.mean([q["cone_force"] / q["cone_force_estimate"]
                                        for q in est])) if est else math.nan),
            height_max=max(q["height_max"] for q in rows), gap_last=rows[-1]["cone_gap"])
    res.wall_per_rev = res.wall / max(last["revolutions"], 1e-300)
    pw = {k: float(np.nanmean([q[k] for q in second]))   # NaN: an increment ended by a remesh
          for k in ("power_in", "main_power", "mandrel_power", "dissipation", "friction_power",
                    "penalty_power")}
    for k, v in pw.items():
        setattr(res, k, v)
    out = pw["dissipation"] + pw["friction_power"]
    res.power_balance = pw["power_in"] / out - 1.0 if out > 0 else math.nan
    res.power_balance_penalty = (pw["power_in"] / (out + pw["penalty_power"]) - 1.0
                                 if out > 0 else math.nan)
    res.mandrel_rotation_power_max = max(abs(q["mandrel_rotation_power"]) for q in rows)
    res.bite_increments = res.contact_length / (res.case.omega_main * res.case.R1 * res.dt)


def _edge_lengths(msh):
    c2v = compat.cell_vertices(msh)
    x = msh.geometry.x
    e = [np.linalg.norm(x[c2v[:, i]] - x[c2v[:, j]], axis=1)
         for i in range(4) for j in range(i + 1, 4)]
    return np.concatenate(e) if len(c2v) else np.zeros(0)


def run(case: RingRollingCase, comm=None, output_dir: Optional[str] = None,
        pictures: bool = True, vtk_every: int = 0, checkpoint_every: int = 0, resume=None,
        name: str = "ring_rolling") -> RingRollingResult:
    """Roll the ring for ``case.revolutions`` (``status`` "done", or "failed" with the history
    up to the failed increment). With ``output_dir`` (the same on every rank; None writes
    nothing) the rows go to ``{name}.csv`` and, with ``pictures``, the top view at four times
    and the curves to ``{name}_top.png``, ``{name}_curves.png``; ``vtk_every``,
    ``checkpoint_every`` and ``resume`` as in :func:`build` (a resumed run's rows and pictures
    hold the resumed part; ``sim_history`` holds all)."""
    comm = comm or MPI.COMM_WORLD
    check_output_dir(output_dir, comm)
    s = build(case, comm, output_dir, vtk_every, checkpoint_every, resume, name)
    sim, th = s.sim, s.theory
    measure = _Measure(s)
    rows, snaps = [], []
    n_inc = s.n_increments
    snap_at = sorted(set(int(round(f * n_inc)) for f in (0.0, 1 / 3, 2 / 3, 1.0)))
    c0, _ = s.centring.measure(sim)
    if 0 in snap_at:
        snaps.append(ring_pictures.snapshot(s, c0))
    wall0 = time.perf_counter()
    status, message = "done", ""
    t_end = case.revolutions * case.t_rev
    for it in range(int(case.max_increments)):
        if sim.t >= t_end * (1.0 - 1e-9):
            break
        try:
            inc = sim.step(min(s.dt, t_end - sim.t))
        except fx.IncrementError as e:            # raised on every rank: no hang
            status, message = "failed", str(e)
            break
        if len(sim.remeshes) != measure.remeshes:
            measure = _Measure(s, measure.power)
        row = measure(inc)
        rows.append(row)
        if comm.rank == 0:   # progress of a long run (one line per increment; --quiet hides it)
            log.info("ring rolling: %.3f / %.2f rev, outer D %.2f mm, main force %.4g N, "
                     "%d Newton its, %.1f s", row["revolutions"], case.revolutions,
                     row["outer_diameter"], math.hypot(row["main_force_x"], row["main_force_y"]),
                     row["newton_iterations"], row["wall"])
        if (it + 1 in snap_at and it + 1 < n_inc) or sim.t >= t_end * (1.0 - 1e-9):
            snaps.append(ring_pictures.snapshot(s, np.array([row["center_x"], row["center_y"],
                                                             0.0])))
    sim.close()
    res = RingRollingResult(
        status, message, rows, None, None, time.perf_counter() - wall0, case=case,
        t_rev=case.t_rev, dt=s.dt, h_theta=s.h_theta, feed_per_rev=th["feed_per_rev"],
        feed_window=th["window"], contact_length=th["contact_length"],
        strain_rate_bite=th["strain_rate_bite"], sigma0=th["sigma0"],
        force_estimate=th["force_estimate"], Q=th["Q"], volume_initial=2.0 * measure.V0,
        sim_history=list(sim.history), cone_geometry=s.cone_geometry,
        remeshes=list(sim.remeshes), contacts=contact_lines(sim))
    if rows:
        _summarize(res, comm, sim.mesh)
        res.heat = ring_heat.summary(res, th)
    paths = {}
    if comm.rank == 0 and output_dir:
        os.makedirs(output_dir, exist_ok=True)
        if rows:
            paths["csv"] = os.path.join(output_dir, f"{name}.csv")
            with open(paths["csv"], "w", newline="") as fh:
                wr = csv.DictWriter(fh, fieldnames=list(rows[0]))
                wr.writeheader()
                wr.writerows(rows)
            if pictures:
                paths.update(ring_pictures.pictures(res, snaps, output_dir, name))
    res.pictures = comm.bcast(paths, root=0)
    return res
