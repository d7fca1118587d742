"""The ring mill's own controllers (THEORY §12.1, §14.4), used by
:mod:`fxcontact.processes.ring_rolling`:

* :class:`RingCentring` — guide rolls that follow the growing ring (control of the ring's centre
  on the mill line) and the re-set of the cylindrical update's centre
  (:class:`fxcontact.kinematics.RingAxisUpdate`);
* :class:`AxialRolls` — idle, frictionless axial (cone) rolls of a radial–axial mill whose apex
  follows the ring's centre on the mill line, moving along the ring axis at a given speed;
* :func:`cone_row` — the upper cone's outputs and its axial-force estimate.
* :class:`BiteZones` — the zones of a remesh (:meth:`fxcontact.Simulation.set_remeshing`): the
  ring's wall, or its rolled surfaces, in front of each roll gap, placed again at each remesh
  (:func:`set_ring_remeshing`: the remeshing of ``RingRollingCase(remesh=True)``, with the
  zones' size from the bite's length :func:`bite_length` when ``remesh_min_across`` is set);
  :func:`bite_coverage` — the elements across each bite, measured.

They are registered with :meth:`fxcontact.Simulation.add_controller`, save what changes with
``checkpoint_state()`` and get it back with ``restore_state()``. The tool motions they drive
(:class:`fxcontact.tools.base.ControlledMotion`) and idle tools
(:class:`fxcontact.idle.IdleRotation`) are not specific to rings and stay in
:mod:`fxcontact.idle` (which still exports these two names as aliases).
"""

from __future__ import annotations

import math
from typing import Dict, Optional, Sequence

import dolfinx.fem
import numpy as np
import ufl
from mpi4py import MPI
from scipy.spatial import cKDTree

from fxcontact import compat
from fxcontact.contact.friction import LAW_NONE, Coulomb, Frictionless, Norton
from fxcontact.contact.penalty import Penalty
from fxcontact.idle import controlled_motion, rolling_speed
from fxcontact.kinematics import RingAxisUpdate
from fxcontact.processes.contact_laws import Former, ToolLaws, contact_friction
from fxcontact.processes.monitor import is_number
from fxcontact.remesh.criteria import RemeshCriteria
from fxcontact.remesh.remeshing import mean_edge_length
from fxcontact.remesh.volume import SizeZone
from fxcontact.theory import forming
from fxcontact.tools.base import ControlledMotion, Tool, unit_vector

__all__ = ["RingCentring", "AxialRolls", "cone_row", "BiteZones", "set_ring_remeshing",
           "bite_length", "bite_coverage", "BITE_MARGIN", "FRICTIONS", "friction_spec",
           "friction_law", "MILL_TOOLS", "DEFAULT_FRICTION", "FORMER", "mill_friction"]


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


#: the tools of the mill (the keys of ``RingRollingCase.friction``)
MILL_TOOLS = ("main_roll", "mandrel", "guide1", "guide2", "cone")
#: the friction of ``RingRollingCase``: Coulomb μ = 0.3 limited by m̄ = 0.6 on both rolls
DEFAULT_FRICTION = ToolLaws(main_roll=Coulomb(0.3, mbar=0.6), mandrel=Coulomb(0.3, mbar=0.6))


def _friction_of(case, v: dict) -> ToolLaws:
    """The laws of the former ``main_friction``, ``mandrel_friction`` (:func:`friction_spec`;
    a frictionless mandrel is left out)."""
    main = friction_spec("main_friction", v["main_friction"])
    mandrel = friction_spec("mandrel_friction", v["mandrel_friction"])
    laws = {"main_roll": friction_law(main)}
    if mandrel is not None:
        laws["mandrel"] = friction_law(mandrel)
    return ToolLaws(laws)


def _spec_of(law):
    if isinstance(law, Norton):
        return ("norton", law.alpha_f, law.q)
    if isinstance(law, Coulomb) and law.mbar is not None:
        return ("coulomb", law.mu, law.mbar)
    return None


def _friction_values(case, laws) -> Optional[dict]:
    if not isinstance(laws, dict):
        return None
    return {"main_friction": _spec_of(laws.get("main_roll")),
            "mandrel_friction": _spec_of(laws.get("mandrel"))}


#: the former spellings of ``RingRollingCase``'s friction (``main_friction``,
#: ``mandrel_friction``: ``(law, a, b)``, "law,a,b" or None) and penalty (``gap_stiffness``)
FORMER = (Former("friction", {"main_friction": ("coulomb", 0.3, 0.6),
                              "mandrel_friction": ("coulomb", 0.3, 0.6)},
                 _friction_of, _friction_values),
          Former("penalty", {"gap_stiffness": None},
                 lambda case, v: Penalty(gap_stiffness=v["gap_stiffness"]),
                 lambda case, p: {"gap_stiffness": p.gap_stiffness}))


def mill_friction(friction, guides: Sequence[str], idle_guides: bool):
    """The friction of the mill's contact: ``friction`` (a law, or a mapping tool name →
    law), with the guide rolls it leaves out given the mandrel's law when they are idle."""
    laws = contact_friction(friction)
    if isinstance(laws, dict) and idle_guides and "mandrel" in laws:
        for name in guides:
            laws.setdefault(name, laws["mandrel"])
    return laws


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
        self.motions = [controlled_motion(g) for g in self.guides]
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
        self.motions = [controlled_motion(c) for c in self.cones]
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
    """The refinement of a ring's remesh: the ring in front of each roll gap over the arc
    ``arc`` (upstream: the material that the ring's rotation brings into the gap) and
    ``downstream`` past it, meshed with size ``h``. A callable ``zones(sim) -> [SizeZone]``
    (:meth:`fxcontact.Simulation.set_remeshing`): evaluated at each remesh on the ring as it is
    then (its centre from ``centring``, its radii and height from its vertices), since the ring
    turns under the fixed gaps: each remesh puts the fine arc back in front of the gaps.

    Each zone is a :class:`~fxcontact.remesh.volume.SizeZone` of points spaced by about ``h``
    (gmsh's Distance field to them): with ``surfaces=False`` they fill the whole wall over the
    arc; with ``surfaces=True`` they lie on the surfaces the rolls touch only — the outer
    surface and the bore at a radial gap (the main roll and the mandrel), the top face at an
    axial gap (the cones) — and the size grows by ``grading`` per unit depth below them (the
    bites refined at a fraction of the whole wall's cells).

    Args:
        centring: the mill's :class:`RingCentring` (ring axis, mill line, centre).
        h: the element size in the zones.
        angles: the radial gaps' angles [rad] about the ring axis from the mill line's
            direction (the main roll and the mandrel: 0).
        arc: the arc [rad] refined upstream of each gap; ``downstream`` past it.
        sense: the ring's sense of rotation about the axis (+1: counterclockwise).
        axial: the axial gaps' angles [rad] (the cones of a radial-axial mill: π).
        surfaces: points on the rolled surfaces only (see above) instead of the whole wall.
        grading: the zones' growth of the size per unit distance.
    """

    def __init__(self, centring: RingCentring, h: float, angles: Sequence[float] = (0.0,),
                 arc: float = 0.5 * math.pi, downstream: float = 0.1, sense: float = 1.0,
                 axial: Sequence[float] = (), surfaces: bool = False, grading: float = 0.3):
        self.centring = centring
        self.h, self.angles = float(h), [float(a) for a in angles]
        self.axial = [float(a) for a in axial]
        self.arc, self.downstream, self.sense = float(arc), float(downstream), float(sense)
        self.surfaces, self.grading = bool(surfaces), float(grading)
        if not (math.isfinite(self.h) and self.h > 0 and self.arc > 0 and self.grading >= 0):
            raise ValueError(f"BiteZones: need h > 0, arc > 0 and grading >= 0, got h = {h!r}, "
                             f"arc = {arc!r}, grading = {grading!r}")

    @staticmethod
    def _levels(lo: float, hi: float, h: float) -> np.ndarray:
        return np.linspace(lo, hi, max(2, int(math.ceil((hi - lo) / h)) + 1))

    def __call__(self, sim) -> list:
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
        radii = self._levels(lo[0], hi[0], h)
        heights = self._levels(lo[1], hi[1], h)
        zones = []
        for phi, radial in [(p, True) for p in self.angles] + [(p, False) for p in self.axial]:
            if self.surfaces:
                rs, zs = ((np.array([lo[0], hi[0]]), heights) if radial else
                          (radii, np.array([hi[1]])))
            else:
                rs, zs = radii, heights
            pts = []
            for rr in rs:   # about h apart along the arc at each radius
                n = max(2, int(math.ceil((self.arc + self.downstream) * rr / h)) + 1)
                th = phi + self.sense * np.linspace(-self.arc, self.downstream, n)
                T, Z = np.meshgrid(th, zs, indexing="ij")
                pts.append(c + np.outer(rr * np.cos(T.ravel()), e)
                           + np.outer(rr * np.sin(T.ravel()), f) + np.outer(Z.ravel(), a))
            zones.append(SizeZone(h=h, points=np.concatenate(pts), grading=self.grading))
        return zones


#: with ``remesh_min_across`` = n, the bite zones' size is L / (BITE_MARGIN n), L the contact
#: length of the pass's theory (:func:`bite_length`). The contact zones of the nodes are longer
#: than L (1.3–1.7 L measured for the main roll and the mandrel of the quick ring with a steady
#: bite: the penalty lets the nodes touch a little before and after the theory's bite), so 1
#: gives the n elements with some room (3.7–5.2 measured for n = 3 by :func:`bite_coverage`)
BITE_MARGIN = 1.0


def bite_length(case) -> float:
    """The steady bite's contact length L = √(2Δh/Σ) of a ring-rolling case (THEORY §14.4):
    Δh the feed per revolution at the main roll's surface speed."""
    dh = case.feed_speed * 2.0 * math.pi * case.R / (case.omega_main * case.R1)
    return forming.ring_rolling_contact_length(dh, case.R1, case.R2, case.R, case.r)


def set_ring_remeshing(sim, centring: RingCentring, case, h_theta: float, start: bool = False):
    """The remeshing of a :class:`~fxcontact.processes.ring_rolling.RingRollingCase` with
    ``remesh=True`` (its ``remesh_*`` fields): size the initial mean edge length, the
    :class:`BiteZones` over ``remesh_arc`` in front of the radial gap (and of the axial one with
    cones); a remesh when the ring has turned (at the nominal speed) by 3/4 of that arc, or by
    the arc less the bite's angle at the bore if that is less (``RemeshCriteria.every``), when
    a cell's quality falls below ``remesh_min_quality``, and when the main roll's or the
    mandrel's bite is spanned by fewer than ``remesh_min_across`` elements.

    Without ``remesh_min_across`` the zones fill the wall with size ``remesh_zone_h`` (default
    ``h_theta``). With it (n elements across each bite asked for) they lie on the rolled
    surfaces (``BiteZones(surfaces=True)``), of size ``remesh_zone_h`` or by default
    L / (:data:`BITE_MARGIN` n) (L: :func:`bite_length`; not above ``h_theta``), and, with
    ``start``, the ring is remeshed before the first increment (its bite refined from the
    start). The bite's length is the steady one: while the bite grows (the first revolution
    from a small ``initial_bite``) it is spanned by fewer elements."""
    c = case
    n = c.remesh_min_across
    across = None if n is None else dict.fromkeys(("main_roll", "mandrel"), n)
    L = bite_length(c)
    h = c.remesh_zone_h or (h_theta if not n else min(h_theta, L / (BITE_MARGIN * n)))
    arc = math.radians(c.remesh_arc)
    turn = 2.0 * math.pi / c.increments_per_rev          # per increment
    every = max(1, int(min(0.75 * arc, arc - L / c.r) / turn + 1e-9))
    zones = BiteZones(centring, h, [0.0], arc, axial=[math.pi] if c.cones else [],
                      surfaces=bool(n))
    size = mean_edge_length(sim)
    sim.set_remeshing(RemeshCriteria(min_quality=c.remesh_min_quality, every=every,
                                     min_elements_across=across), size=size, zones=zones)
    if n and start:
        sim.remesh(reason="the bites refined before the first increment")
    return zones


def bite_coverage(sim, contact, center, tools=("main_roll", "mandrel"), axis=(0.0, 0.0, 1.0)):
    """Elements across the bite of each of ``tools`` now (collective; the same on every rank):
    the contact zone's arc (the extreme angles of the tool's contact nodes about the ring's
    ``center`` times their mean distance from the axis) over the mean edge length of the
    boundary facets whose three vertices are contact nodes of that tool. ``{tool: (arc, mean
    edge, elements across)}``; (0, nan, 0) for a tool with fewer than 3 contact nodes. An
    independent measure of what ``RemeshCriteria.min_elements_across`` checks (that one: the
    width 2√3σ of the nodes' spread, over the facets around them)."""
    comm, b = sim.comm, contact.boundary
    msh = sim.mesh
    fdim = msh.topology.dim - 1
    msh.topology.create_connectivity(fdim, 0)
    f2v = np.asarray(msh.topology.connectivity(fdim, 0).array).reshape(-1, fdim + 1)
    owned = b.facets[b.facets < msh.topology.index_map(fdim).size_local]
    X = sim.vertex_positions()
    a = unit_vector(axis, "ring axis")
    out = {}
    for name in tools:
        k = [t.name for t in contact.tools].index(name)
        mine = X[b.vertices[contact.nodes.active & (contact.nodes.tool == k)]]
        P = np.concatenate(comm.allgather(mine)) if comm.size > 1 else mine
        if len(P) < 3:
            out[name] = (0.0, math.nan, 0.0)
            continue
        d = P - np.asarray(center, dtype=float)
        d -= np.outer(d @ a, a)
        u = d / np.linalg.norm(d, axis=1)[:, None]
        m = u.sum(axis=0)                      # the zone's mean direction: angles from it
        m /= np.linalg.norm(m)
        th = np.arctan2(np.cross(m, u) @ a, u @ m)
        arc = float((th.max() - th.min()) * np.mean(np.linalg.norm(d, axis=1)))
        F = X[f2v[owned]]
        hit = cKDTree(P).query(F.reshape(-1, 3), distance_upper_bound=1e-9)[0]
        F = F[np.all(np.isfinite(hit).reshape(-1, 3), axis=1)]
        s = sum(float(np.sum(np.linalg.norm(F[:, i] - F[:, j], axis=1)))
                for i, j in ((0, 1), (1, 2), (0, 2)))
        s, n = comm.allreduce(np.array([s, 3.0 * len(F)]), op=MPI.SUM)
        h = s / n if n else math.nan
        out[name] = (arc, h, arc / h if n else 0.0)
    return out
