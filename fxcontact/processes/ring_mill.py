"""The ring mill's own controllers (THEORY §12.1, §14.4), used by
:mod:`fxcontact.processes.ring_rolling`:

* :class:`RingCentring` — guide rolls that follow the growing ring (control of the ring's centre
  on the mill line) and the re-set of the cylindrical update's centre
  (:class:`fxcontact.kinematics.RingAxisUpdate`);
* :class:`AxialRolls` — idle, frictionless axial (cone) rolls of a radial–axial mill whose apex
  follows the ring's centre on the mill line, moving along the ring axis at a given speed;
* :func:`cone_row` — the upper cone's outputs and its axial-force estimate.
* :class:`BiteZones` — the zones of a remesh (:meth:`fxcontact.Simulation.set_remeshing`): the
  ring's wall in front of each roll gap, placed again at each remesh
  (:func:`set_ring_remeshing`: the remeshing of ``RingRollingCase(remesh=True)``).

They are registered with :meth:`fxcontact.Simulation.add_controller`, save what changes with
``checkpoint_state()`` and get it back with ``restore_state()``. The tool motions they drive
(:class:`fxcontact.tools.base.ControlledMotion`) and idle tools (:class:`fxcontact.mill.IdleRotation`)
are not specific to rings and stay in :mod:`fxcontact.mill` (which still exports these two
names as aliases).
"""

from __future__ import annotations

import math
from typing import Dict, Optional, Sequence

import numpy as np
from mpi4py import MPI

from fxcontact import forming
from fxcontact.contact.friction import LAW_NONE, Coulomb, Frictionless, Norton
from fxcontact.kinematics import RingAxisUpdate
from fxcontact.mill import _controlled, rolling_speed
from fxcontact.processes.monitor import is_number
from fxcontact.tools.base import ControlledMotion, Tool, unit_vector

__all__ = ["RingCentring", "AxialRolls", "cone_row", "BiteZones", "set_ring_remeshing",
           "FRICTIONS", "friction_spec", "friction_law"]


#: the friction laws of a tool: ``(law, a, b)``: ("coulomb", μ, m̄) or ("norton", α_f, q)
FRICTIONS = ("coulomb", "norton")


def friction_spec(name, spec):
    """``None``/"none", a tuple ``(law, a, b)`` or the string "law,a,b" → a tuple or None."""
    if spec is None or (isinstance(spec, str) and spec.strip().lower() in ("none", "")):
        return None
    if isinstance(spec, str):
        parts = [p.strip() for p in spec.split(",")]
        try:
            spec = (parts[0].lower(), *map(float, parts[1:]))
        except ValueError:
            spec = tuple(parts)
    ok = (isinstance(spec, tuple) and len(spec) == 3 and spec[0] in FRICTIONS
          and all(is_number(x) and x >= 0 for x in spec[1:]))
    if not ok:
        raise ValueError(f"{name} must be None or (law, a, b) with law in {FRICTIONS} "
                         f"(\"coulomb\": mu, mbar; \"norton\": alpha_f, q), e.g. "
                         f"(\"coulomb\", 0.3, 0.6) or \"coulomb,0.3,0.6\"; got {spec!r}")
    return (spec[0], float(spec[1]), float(spec[2]))


def friction_law(spec):
    """A tool's friction law from its :func:`friction_spec` tuple (None: frictionless)."""
    if spec is None:
        return Frictionless()
    kind, a, b = spec
    return Norton(alpha_f=a, q=b) if kind == "norton" else Coulomb(a, mbar=b)


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

    def remesh(self, space, facet_tags):
        """A new mesh of the ring (``Simulation.remesh``): the outer surface selected again by
        its tags, the centroid's forms made again; the guide rolls' motions are kept."""
        self.outer = self.outer.remeshed(space, facet_tags)
        self._forms = None

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

    def remesh(self, space, facet_tags):
        """Nothing of the mesh is kept here (the contact and the centring rebind
        themselves)."""

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


def cone_row(q, nodes, depth, Hm, Ro, Ri, w_ring, geo, K, m) -> dict:
    """The upper cone's outputs and the axial-force estimate of ring-rolling theory.

    The cone reduces the half height Hm/2 of the arriving ring to its apex level z_a: the
    reduction δ = Hm/2 − z_a, less the penalty penetration of the nodes (δ_eff = δ − depth),
    is taken by a flat face under a cone whose normal radius of curvature across the
    generatrix is R_c = s tan α at the mid-wall s = (R + r)/2 from the apex: contact length
    L_a = √(2 δ_eff R_c) (THEORY §14.4 with Σ = 1/R_c), force ≈ 2k B L_a with B the wall and
    k = σ₀/√3 at the axial bite's strain rate (δ_eff/(Hm/2)) · ω_ring s / L_a. The factor Q
    of the radial estimate is not applied: Hm/L_a is far above its range (the cone does not
    penetrate the height plastically; for such shallow bites the mean pressure lies between
    2k and the indentation value (2 + π)k)."""
    za = q["cone_apex_axial"]
    s_m = 0.5 * (Ro + Ri)
    Rc = s_m * math.tan(geo["alpha"])
    delta = 0.5 * Hm - za
    depth = max(depth, 0.0)             # < 0: the cone is off the face by −depth
    d_eff = delta - depth
    est = L_a = 0.0
    if delta > 0 and d_eff > 0 and nodes > 0:
        L_a = math.sqrt(2.0 * d_eff * Rc)
        rate = d_eff / (0.5 * Hm) * abs(w_ring) * s_m / L_a
        k = float(forming.flow_stress(K, m, rate)) / math.sqrt(3.0)
        est = 2.0 * k * (Ro - Ri) * L_a
    return dict(cone_force=q["cone_force_z"], cone_force_line=q["cone_force_x"],
                nodes_cone=nodes, cone_penetration=depth, cone_gap=2.0 * za,
                cone_apex_x=q["cone_apex_line"], cone_omega=q["cone_omega"],
                cone_reduction=delta, cone_contact_length=L_a, cone_force_estimate=est)


class BiteZones:
    """The refinement of a ring's remesh: the ring's wall over the arc ``arc`` in front of each
    roll gap (upstream: the material that the ring's rotation brings into the gap) and
    ``downstream`` past it, meshed with size ``h``. A callable ``zones(sim) -> [SizeZone]``
    (:meth:`fxcontact.Simulation.set_remeshing`): evaluated at each remesh on the ring as it is
    then (its centre from ``centring``, its radii and height from its vertices), since the ring
    turns under the fixed gaps: each remesh puts the fine arc back in front of the gaps.

    Args:
        centring: the mill's :class:`RingCentring` (ring axis, mill line, centre).
        h: the element size in the zones.
        angles: the gaps' angles [rad] about the ring axis from the mill line's direction
            (radial rolling: 0; the axial gap of the cones: π).
        arc: the arc [rad] refined upstream of each gap; ``downstream`` past it.
        sense: the ring's sense of rotation about the axis (+1: counterclockwise).
    """

    def __init__(self, centring: RingCentring, h: float, angles: Sequence[float] = (0.0,),
                 arc: float = 0.5 * math.pi, downstream: float = 0.1, sense: float = 1.0):
        self.centring = centring
        self.h, self.angles = float(h), [float(a) for a in angles]
        self.arc, self.downstream, self.sense = float(arc), float(downstream), float(sense)

    def __call__(self, sim) -> list:
        from fxcontact.remesh.volume import SizeZone
        cz = self.centring
        c, _ = cz.measure(sim)
        a, e = cz.axis, cz.e
        f = np.cross(a, e)
        d = sim.vertex_positions() - c
        z = d @ a
        rho = np.linalg.norm(d - np.outer(z, a), axis=1)
        lo = [sim.comm.allreduce(float(np.min(v, initial=np.inf)), op=MPI.MIN) for v in (rho, z)]
        hi = [sim.comm.allreduce(float(np.max(v, initial=-np.inf)), op=MPI.MAX) for v in (rho, z)]
        h = self.h
        radii = np.linspace(lo[0], hi[0], max(2, int(math.ceil((hi[0] - lo[0]) / h)) + 1))
        heights = np.linspace(lo[1], hi[1], max(2, int(math.ceil((hi[1] - lo[1]) / h)) + 1))
        zones = []
        for phi in self.angles:
            span = self.arc + self.downstream
            n = max(2, int(math.ceil(span * hi[0] / h)) + 1)
            th = phi + self.sense * np.linspace(-self.arc, self.downstream, n)
            T, P, Z = np.meshgrid(th, radii, heights, indexing="ij")
            pts = (c + np.outer(P.ravel() * np.cos(T.ravel()), e)
                   + np.outer(P.ravel() * np.sin(T.ravel()), f) + np.outer(Z.ravel(), a))
            zones.append(SizeZone(h=h, points=pts))
        return zones


def set_ring_remeshing(sim, centring: RingCentring, case, h_theta: float):
    """The remeshing of a :class:`~fxcontact.processes.ring_rolling.RingRollingCase` with
    ``remesh=True`` (its ``remesh_*`` fields): size the initial mean edge length, the
    :class:`BiteZones` of size ``remesh_zone_h`` (default ``h_theta``) over ``remesh_arc``
    in front of the radial gap (and of the axial one with cones); a remesh when the ring has
    turned by 3/4 of that arc (``RemeshCriteria.every``, at the nominal speed), when a cell's
    quality falls below ``remesh_min_quality``, and when the main roll's or the mandrel's bite
    is spanned by fewer than ``remesh_min_across`` elements (None: not checked)."""
    from fxcontact.remesh.criteria import RemeshCriteria
    from fxcontact.remesh.simulation import mean_edge_length
    c = case
    across = None if c.remesh_min_across is None else \
        dict.fromkeys(("main_roll", "mandrel"), c.remesh_min_across)
    every = max(1, int(0.75 * c.remesh_arc / 360.0 * c.increments_per_rev))
    zones = BiteZones(centring, c.remesh_zone_h or h_theta, [0.0, math.pi] if c.cones else [0.0],
                      math.radians(c.remesh_arc))
    sim.set_remeshing(RemeshCriteria(min_quality=c.remesh_min_quality, every=every,
                                     min_elements_across=across),
                      size=mean_edge_length(sim), zones=zones)
