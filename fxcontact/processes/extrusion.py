"""Forward extrusion through a conical die (THEORY §14.2): the case, the set-up and the run.

A billet of radius R₀ in a container is pushed by a punch (a velocity condition on its back
face, reaction ``punch``) through a conical die to the radius R₁; one sector about the axis is
modelled, with symmetry planes like the drawing. The billet is meshed with a nose already
through the die (:func:`fxcontact.processes.die.nose_layout`: the die's entry is at the
container's radius; the corner where the container meets the cone is rounded by an arc of
radius ``entry_fillet``). Tresca friction on the die and on the container (``friction``).

**Tools** (``container``): ``"separate"`` (default) — the container is its own tool, a
:class:`~fxcontact.RevolvedProfile` of one straight line at R₀ (an infinite bore), and the die
another (its entry face perpendicular to the axis at the container's end, the entry fillet, the
cone, the fillet, the land and the exit relief), two tools of one
:class:`~fxcontact.NodalContact`, each with its own friction law; the container's force is then
a history column of its own. ``"profile"`` — one profile: the container's segment followed by
the die's (one tool, one friction law: the two friction factors must then be equal). How a node
chooses among the tools of one contact (``NodalContact._project_all``): every node is projected
on every tool and keeps the tool with the **smallest signed gap** (the deepest penetration, or
the nearest surface), the first tool on a tie; its friction law is that tool's. For a node
outside the tools this is the distance to the union of the two bodies, as for one profile of
both; for a penetrated node it is the deepest penetration into either body, here the depth below
the union's surface except for a node less than its depth p past the container's end: there the
die's entry face (inside the union) is nearer than its fillet, and the container's bore
continued past its end measures the node, shallower than the fillet of radius R_f by about
δ²/2(R_f + p) at δ past the end (5e-7 mm at the quick case's p = 7.5e-4 mm). Away from that band
both descriptions give the same iterates, bitwise; a node inside it moves the history a little,
by 2e-5 of the punch force in the quick case (``tests/test_extrusion.py``;
``benchmarks/bench_extrusion.py`` compares the Newton iterations of longer runs). Two tools that
coincide over a stretch (a die continued backwards along the container's radius) would leave the
choice there to round-off: the die here starts with its entry face, so the container is strictly
the nearer tool upstream.

**Which k the Tresca friction uses.** τ = m̄ k with k = K (√3 ε̄̇)^m taken at each contact
node from its own strain rate (averaged over the adjacent cells, with the material's
regularisation) — on the container wall the billet moves rigidly, so k there is far below the
k = σ₀/√3 of the die's mean strain rate that the theory uses. ``container_shear_limit`` gives
the container's law a fixed k (``friction={"container": Tresca(m̄, shear_limit=k), ...}``):
the container force must then equal 2 m̄ k L_c/R₀ times the punch area (the check of the tests).

Measured per increment: punch force and pressure F/A₀, the container's axial force and its
theory, the die pressure (punch minus container), penetration, contact nodes, the power
balance, Newton iterations, volume change and element quality. Steady state on the die
pressure (the container's share falls as the billet shortens).

**Hot extrusion** (``material``, ``heat``): a flow stress σ₀(ε̄, ε̄̇, T)
(:class:`~fxcontact.Viscoplastic`) instead of K, m — the theory's σ₀ is then its mean over the
ideal strain ln(A₀/A₁) at the die's mean strain rate — and a :class:`~fxcontact.HeatSetup`: air on
the billet's lateral surface (where no tool touches it) and its front, the tools ``container`` and
``die`` (the one profile: ``die``); the back face under the punch (a velocity condition, not a
contact) and the symmetry planes are insulated. The rows then carry the heat's ``heat_*``
columns.

Example::

    from fxcontact.processes import ExtrusionCase, run_extrusion
    res = run_extrusion(ExtrusionCase.quick(alpha=30.0))
    print(res.report())
"""

from __future__ import annotations

import dataclasses
import logging
import math
import os
import time
from dataclasses import InitVar, dataclass
from typing import Optional

import numpy as np
from mpi4py import MPI

from fxcontact.contact.boundary import ContactBoundary
from fxcontact.contact.friction import Frictionless, ShearLimit, Tresca
from fxcontact.contact.nodal import SCHEMES, NodalContact
from fxcontact.contact.penalty import Penalty
from fxcontact.io.series import pyplot
from fxcontact.meshing import DRAWING_BAR_TAGS
from fxcontact.newton.solver import SolverOptions
from fxcontact.power import PowerBalance
from fxcontact.materials import Viscoplastic
from fxcontact.processes.common import check_output_dir
from fxcontact.processes.common import (CaseBase, ProcessResult, check_material_heat,
                                        finish_run, heat_columns, heat_lines, material_text,
                                        mean_norton_hoff, meridian_section, numerics_columns,
                                        plot_curves, plot_sections, run_increments, run_summary,
                                        steady_values, theory_temperature, vertex_field)
from fxcontact.processes.contact_laws import (UNSET, Former, Friction, ToolLaws, contact_friction,
                                              former_beta_gap_penalty, gap_penalty, law_text)
from fxcontact.processes.die import bar_simulation, die_profile_tool, die_radius, nose_layout
from fxcontact.remesh.criteria import RemeshCriteria
from fxcontact.remesh.volume import SizeZone
from fxcontact.simulation import Simulation
from fxcontact.theory import forming
from fxcontact.thermal import HeatSetup
from fxcontact.tools.revolved import RevolvedProfile

__all__ = ["ExtrusionCase", "ExtrusionSetup", "ExtrusionResult", "CONTAINERS", "build", "run"]

log = logging.getLogger("fxcontact.processes.extrusion")

#: the container as a tool of its own, or the first segment of the die's profile
CONTAINERS = ("separate", "profile")


def _friction_of(case, v: dict):
    """The laws of the former ``mbar_die``, ``mbar_container``, ``container_shear_limit``:
    Tresca on each tool (none if both factors are 0); one law for the one profile."""
    for key in ("mbar_die", "mbar_container"):
        if not 0 <= v[key] <= 1:
            raise ValueError(f"{key} must be in [0, 1], got {v[key]}")
    k_c = v["container_shear_limit"]
    if k_c is not None and not (isinstance(k_c, (int, float)) and math.isfinite(k_c)
                                and k_c > 0):
        raise ValueError(f"container_shear_limit must be a finite number > 0, got {k_c!r}")
    if case.container == "profile":
        if v["mbar_die"] != v["mbar_container"] or k_c is not None:
            raise ValueError("container 'profile' is one tool with one friction law: give "
                             "mbar_die == mbar_container and no container_shear_limit, or "
                             "container='separate'")
        return Tresca(v["mbar_die"]) if v["mbar_die"] > 0 else Frictionless()
    if v["mbar_die"] > 0 or v["mbar_container"] > 0:
        return ToolLaws(container=Tresca(v["mbar_container"], k_c), die=Tresca(v["mbar_die"]))
    return Frictionless()


def _friction_values(case, friction) -> Optional[dict]:
    laws = {t: (friction if not isinstance(friction, dict) else
                friction.get(t, Frictionless())) for t in ("container", "die")}
    if not all(isinstance(law, (Tresca, Frictionless)) for law in laws.values()):
        return None
    k = getattr(laws["container"], "shear_limit", None)
    return {"mbar_die": getattr(laws["die"], "mbar", 0.0),
            "mbar_container": getattr(laws["container"], "mbar", 0.0),
            "container_shear_limit": k}


@dataclass(frozen=True)
class ExtrusionCase(CaseBase):
    """A forward-extrusion case: lengths mm, stresses MPa, times s, angles degrees.

    Defaults: a hot aluminium billet R₀ 10 → 6 mm (64 % reduction, extrusion ratio 2.8)
    through a 20° die, Norton–Hoff K = 40 MPa·s^m, m = 0.1 (σ₀ ≈ 80 MPa at the die's rate),
    punch at 10 mm/s, Tresca m̄ 0.1 on the die and 0.3 on the container, one quarter.
    :meth:`quick` is the reduced size of the tests. Bad values raise ``ValueError`` naming the
    field.

    **Contact** (on the billet's lateral surface; tools ``"container"`` and ``"die"``, or the
    one profile named ``"die"``):

    * ``penalty`` (:class:`fxcontact.Penalty`): by default ``Penalty(beta=100.0, gap=True)``,
      as the drawing: k = ρ(β)/dt [MPa/mm = N/mm³], ρ(β) = β η(ε̄̇)/h [MPa·s/mm] with η the
      secant viscosity [MPa·s] at the die's mean strain rate, h [mm] and dt [s] of the case
      (unless the Penalty gives them); ρ = k·dt at each increment. ``Penalty(beta=β)``: ρ at
      the strain rate estimated at the first increment and the contact's element size.
    * ``friction``: ``{"container": Tresca(0.3), "die": Tresca(0.1)}`` by default (m̄
      dimensionless in [0, 1], τ = m̄ k with k [MPa] the shear flow stress at each node's
      strain rate, or given: ``Tresca(m̄, shear_limit=k)``); one law for both tools; Tresca
      or ``Frictionless()`` (the theory's m̄). With ``container="profile"`` the two laws must
      be equal.
    * Former spellings, accepted for one release with a ``DeprecationWarning``:
      ``mbar_die``, ``mbar_container``, ``container_shear_limit`` for ``friction`` (Tresca on
      each tool, none if both are 0), ``beta`` for ``penalty``.

    **How a penalty or a friction coefficient reaches its kernel.** ``case.penalty`` →
    :func:`build` (:func:`~fxcontact.processes.contact_laws.gap_penalty`: the die's mean
    strain rate, h, dt) → ``NodalContact(penalty=)`` → ``Penalty.rho(material, dt, rate)`` at
    each ``begin_increment`` → ``penalty_kernel(S, rho, ...)``: four hops. ``case.friction``
    → ``NodalContact(friction=)`` (one law per tool) → ``friction_arguments`` at each
    evaluation (per node: law code, m̄ k with k from ``begin_increment``) →
    ``friction_kernel(...)``: three hops."""

    # geometry: billet, container, die
    R0: float = 10.0                 #: billet and container radius
    R1: float = 6.0                  #: die exit (bearing) radius
    length: float = 30.0             #: billet length (back face to the nose's front face)
    sector: float = 90.0             #: modelled sector about the axis (degrees)
    alpha: float = 20.0              #: die cone semi-angle (degrees, < 90)
    land: float = 1.0                #: bearing land length
    fillet: float = 1.0              #: cone–land fillet radius (0: sharp)
    relief_angle: float = 20.0       #: exit relief semi-angle (0: no relief)
    relief_length: float = 1.0
    nose_ratio: float = 0.96         #: nose radius over R1
    entry_fillet: float = 1.0        #: radius rounding the container–die corner (0: sharp)
    container: str = "separate"      #: "separate" tools or one "profile"
    # material (Norton–Hoff)
    K: float = 40.0
    m: float = 0.1
    #: a flow stress σ₀(ε̄, ε̄̇, T) (:class:`~fxcontact.Viscoplastic`, e.g. a hardening law)
    #: instead of K, m; the theory's σ₀ is then its mean over the ideal strain ln(A₀/A₁) at the
    #: die's mean strain rate and the initial temperature
    material: Optional[Viscoplastic] = None
    #: heat (:class:`~fxcontact.HeatSetup`: the billet's thermal material and temperature, air
    #: on the lateral surface and the front, the tools ``container`` and ``die``), or None
    heat: Optional[HeatSetup] = None
    #: the friction laws (Tresca): ``{"container": law, "die": law}`` or one law for both
    friction: Friction = ToolLaws(container=Tresca(0.3), die=Tresca(0.1))
    # kinematics
    speed: float = 10.0              #: punch speed
    dt: float = 0.025
    t_end: float = 1.0
    # numerics
    h: float = 1.0
    scheme: str = "implicit"
    #: the contact penalty: a gap stiffness k = ρ(β)/dt [MPa/mm] (as the drawing)
    penalty: Penalty = Penalty(beta=100.0, gap=True)
    max_it: int = 60
    max_cutbacks: int = 4
    # steady state of the die pressure: two windows of `window` mm of punch travel agree within
    # steady_tol, after `settle` mm (default 2 elements)
    window: float = 1.5
    steady_tol: float = 0.02
    settle: Optional[float] = None
    stop_at_steady: bool = False
    # remeshing (off by default): a new mesh of size h when a cell's quality falls below
    # remesh_min_quality (and before an inverting cell stops the run), finer (remesh_zone_h)
    # in a box around the die
    remesh: bool = False
    remesh_min_quality: float = 0.2
    remesh_zone_h: Optional[float] = None
    # former spellings of friction and penalty (one release)
    mbar_die: InitVar[Optional[float]] = UNSET
    mbar_container: InitVar[Optional[float]] = UNSET
    container_shear_limit: InitVar[Optional[float]] = UNSET
    beta: InitVar[Optional[float]] = UNSET

    FRICTION_TOOLS = ("container", "die")
    FORMER = (Former("friction", {"mbar_die": 0.1, "mbar_container": 0.3,
                                  "container_shear_limit": None},
                     _friction_of, _friction_values),
              former_beta_gap_penalty(100.0))

    #: the reduced size of the tests: R₀ 5 → 3.5 mm, h = 1 mm, a short billet
    QUICK = dict(R0=5.0, R1=3.5, length=14.0, h=1.0, land=0.5, fillet=0.5, relief_length=0.5,
                 entry_fillet=0.5, t_end=0.6, window=1.0, stop_at_steady=True)

    def __post_init__(self, mbar_die, mbar_container, container_shear_limit, beta):
        self.resolve_contact_laws(mbar_die=mbar_die, mbar_container=mbar_container,
                                  container_shear_limit=container_shear_limit, beta=beta)
        self.check_positive(("R0", "R1", "length", "K", "speed", "alpha", "land", "h", "dt",
                             "t_end", "window", "steady_tol", "sector"))
        self.check_bar_and_die(alpha_max=90.0)
        self.check_increment(self.speed * (self.R0 / self.R1) ** 2, self.h,
                             "the extruded product (punch speed × R0²/R1²)")
        if not (math.isfinite(self.entry_fillet) and self.entry_fillet >= 0):
            raise ValueError(f"entry_fillet must be finite and >= 0, got {self.entry_fillet}")
        laws = [self.tool_friction(t) for t in ("container", "die")]
        if not all(isinstance(law, (Tresca, Frictionless)) for law in laws):
            raise ValueError(f"friction must be Tresca or Frictionless laws (the theory's m̄), "
                             f"got {self.friction!r}")
        if self.container not in CONTAINERS:
            raise ValueError(f"container must be one of {CONTAINERS}, got {self.container!r}")
        if self.container == "profile" and laws[0] != laws[1]:
            raise ValueError("container 'profile' is one tool with one friction law: give "
                             "one law (friction=Tresca(m)), or container='separate'")
        self.check_remesh_fields()
        if self.scheme not in SCHEMES:
            raise ValueError(f"scheme must be one of {SCHEMES}, got {self.scheme!r}")
        check_material_heat(self.material, self.heat)
        self.die_profile()      # the billet must hold the nose, the cone the fillets

    def layout(self):
        """The nose and die placement (:class:`~fxcontact.processes.die.NoseLayout`); the
        die's entry at the container's radius R₀."""
        return nose_layout(self.R0, self.R1, self.alpha, self.land, self.fillet,
                           self.relief_angle, self.relief_length, self.nose_ratio, self.h, self.h,
                           self.length, self.sector, entry_radius=self.R0)

    def die_profile(self):
        """``(points, arcs)`` of the die's meridian profile (:func:`fxcontact.die_profile`
        placed by :meth:`layout`), its sharp entry corner at (s₀, R₀) rounded by an arc of
        radius ``entry_fillet`` tangent to the container's line and to the cone (the die's
        profile then starts parallel to the container)."""
        g = self.layout()
        die = die_profile_tool(g, self.R1, self.alpha, self.land, self.fillet,
                               self.relief_length)
        pts = np.asarray(die.points, float)
        arcs = list(die.arcs or [None] * (len(pts) - 1))
        if self.entry_fillet > 0:
            a = math.radians(self.alpha)
            t = self.entry_fillet * math.tan(0.5 * a)       # tangent length
            if t >= np.hypot(*(pts[1] - pts[0])):
                raise ValueError(f"entry_fillet {self.entry_fillet} is too large for the die's "
                                 f"cone: give a smaller entry_fillet")
            start = [pts[0, 0] - t, self.R0]
            end = [pts[0, 0] + t * math.cos(a), self.R0 - t * math.sin(a)]
            pts = np.vstack([start, end, pts[1:]])
            arcs = [-self.entry_fillet] + arcs              # clockwise: towards the axis
        return pts, arcs

    def friction_factors(self) -> dict:
        """The theory's friction: ``mbar_die``, ``mbar_container`` (0 frictionless) and
        ``container_shear_limit``, the k [MPa] given in the container's law (None: k from the
        strain rate)."""
        die, cont = self.tool_friction("die"), self.tool_friction("container")
        src = cont.k_source if isinstance(cont, Tresca) else ShearLimit()
        return dict(mbar_die=getattr(die, "mbar", 0.0), mbar_container=getattr(cont, "mbar", 0.0),
                    container_shear_limit=src.value)

    def flow_K_m(self):
        """(K, m) of the theory: the case's, or with a ``material`` those of the Norton–Hoff
        law whose flow stress at the die's mean strain rate is the material's mean over the
        ideal strain ln(A₀/A₁) (:func:`~fxcontact.processes.common.mean_norton_hoff`) at the
        heat's initial temperature (else the material's)."""
        if self.material is None:
            return self.K, self.m
        rate = forming.drawing_mean_strain_rate(self.R0, self.R1, math.radians(self.alpha),
                                                self.speed)
        return mean_norton_hoff(self.material, 2.0 * math.log(self.R0 / self.R1), rate,
                                theory_temperature(self))

    def theory(self, container_length: float = 0.0) -> dict:
        """:func:`fxcontact.theory.forming.extrusion_theory` for ``container_length`` L_c of billet
        in the container (k of the container's friction: the k given in its law, else σ₀/√3
        at the die's mean rate), σ₀ of :meth:`flow_K_m`."""
        f = self.friction_factors()
        K, m = self.flow_K_m()
        return forming.extrusion_theory(K, m, self.R0, self.R1,
                                        math.radians(self.alpha), self.speed, f["mbar_die"],
                                        f["mbar_container"], container_length, self.land,
                                        shear_yield=f["container_shear_limit"])


@dataclass
class ExtrusionSetup:
    """A ready extrusion :class:`~fxcontact.Simulation` and its handles."""

    case: ExtrusionCase
    sim: Simulation
    contact: NodalContact
    tools: list                  #: [container, die] or [profile]
    profile: RevolvedProfile     #: container + die as one profile (the outline, pictures)
    corner: float                #: axial position where the container ends (the die begins)
    facet_tags: object
    layout: object
    dofs: int


def _profile(case, g, name="die") -> RevolvedProfile:
    """The container (a line at R₀ from behind the billet) and the die as one profile."""
    pts, arcs = case.die_profile()
    return RevolvedProfile(np.vstack([[g.s0 - case.length - 2.0 * case.h, case.R0], pts]),
                           [None] + arcs, inside=True, name=name)


def build(case: ExtrusionCase, comm=None, output_dir: Optional[str] = None,
          vtk_every: int = 0, name: str = "extrusion") -> ExtrusionSetup:
    """Mesh the billet, make the tools, the contact and the :class:`~fxcontact.Simulation`
    (not run): symmetry planes ``sym0``/``sym1``, the punch (velocity of the back face,
    reaction ``punch``), the contact ``contact`` on the lateral surface."""
    comm = comm or MPI.COMM_WORLD
    g = case.layout()
    th = case.theory()
    sim, ft, f, mat = bar_simulation(case, g, comm, th["strain_rate"],
                                     SolverOptions(max_it=int(case.max_it)), "back", "punch",
                                     output_dir, vtk_every, name)
    space = sim.space
    profile = _profile(case, g)
    if case.container == "separate":
        container = RevolvedProfile(profile.points[:2], inside=True, name="container")
        # the die's own profile starts with its entry face, perpendicular to the axis at the
        # container's end: upstream of it the container is strictly the nearer tool (no tie
        # between the container and a die extended backwards along R₀)
        pts, arcs = case.die_profile()
        die = RevolvedProfile(np.vstack([[pts[0, 0], 1.5 * case.R0], pts]), [None] + arcs,
                              inside=True, name="die")
        tools = [container, die]
        friction = contact_friction(case.friction)
    else:
        tools = [profile]
        friction = case.tool_friction("die")
    # the drawing's penalty: by default a gap stiffness k = ρ(β)/dt at the die's mean strain
    # rate
    penalty = gap_penalty(case.penalty, th["strain_rate"], g.h, case.dt)
    contact = NodalContact(ContactBoundary(space, ft, DRAWING_BAR_TAGS["lateral"]), tools,
                           scheme=case.scheme, friction=friction, name="contact",
                           penalty=penalty)
    sim.add_contributor(contact)
    if case.heat is not None:   # the side and the front are free; the back face under the
        # punch and the symmetry planes: insulated
        case.heat.attach(sim, ft, [DRAWING_BAR_TAGS[k] for k in ("lateral", "front")],
                         [t.name for t in contact.tools])
    if case.remesh:
        sim.set_remeshing(RemeshCriteria(min_quality=case.remesh_min_quality), size=case.h,
                          zones=_die_zone(case))
    dofs = space.W.dofmap.index_map.size_global * space.W.dofmap.index_map_bs
    return ExtrusionSetup(case, sim, contact, tools, profile, float(profile.points[1, 0]),
                          ft, g, dofs)


def _die_zone(case: ExtrusionCase) -> list:
    """The box around the die (entry to exit, the whole section) meshed with
    ``remesh_zone_h`` (none without it)."""
    if case.remesh_zone_h is None:
        return []
    pts, _ = case.die_profile()
    r = 1.2 * case.R0
    return [SizeZone(h=case.remesh_zone_h, box=([-r, -r, pts[0, 0] - 2.0 * case.h],
                                                [r, r, pts[-1, 0] + case.h]))]


def _follow_remesh(s: ExtrusionSetup, seen: list):
    """After a remesh: the facet tags of the new mesh."""
    if len(s.sim.remeshes) != seen[0]:
        seen[0] = len(s.sim.remeshes)
        s.facet_tags = s.sim._remesh_facet_tags


@dataclass
class ExtrusionResult(ProcessResult):
    """The outcome of :func:`run` (:class:`~fxcontact.processes.common.ProcessResult`) and
    the extrusion's own values, over the steady window (None without one). ``theory`` is
    :meth:`ExtrusionCase.theory` at the window's mean container length."""

    case: Optional[ExtrusionCase] = None
    A0: float = math.nan
    max_penetration: float = math.nan
    punch_pressure: Optional[float] = None     #: F/A₀
    die_pressure: Optional[float] = None       #: (F − container force)/A₀
    container_length: Optional[float] = None   #: L_c
    container_ratio: Optional[float] = None    #: container force / 2 m̄ k L_c A₀/R₀
    steady_oscillation: Optional[float] = None

    def report(self) -> str:
        """A summary for the console."""
        c, th = self.case, self.theory
        f = c.friction_factors()
        k_c = ("given k = %.4g MPa" % f["container_shear_limit"] if f["container_shear_limit"]
               else "k from the local nodal strain rate")
        lines = [
            f"forward extrusion R0 {c.R0:g} -> {c.R1:g} mm (reduction "
            f"{100 * th['reduction']:.1f} %, ratio {th['extrusion_ratio']:.2f}), alpha "
            f"{c.alpha:g} deg, mbar die {f['mbar_die']:g} / container {f['mbar_container']:g} "
            f"({k_c}), tools {c.container}; {material_text(c, 'billet')}; h {self.h:.3g} mm, "
            f"{self.dofs} dofs, {self.ranks} rank(s)",
            f"status: {self.status} {self.message}; {self.increments} increments of {c.dt:g} s "
            f"to t = {self.time:.4g} s ({c.speed * self.time:.3g} mm of punch travel)",
            f"theory (THEORY 14.2): sigma0 = {th['sigma0']:.1f} MPa at the die's mean strain "
            f"rate {th['strain_rate']:.3f} 1/s; ideal {th['ideal']:.1f}, Avitzur (die) "
            f"{th['avitzur']:.1f}, container 2 mbar k Lc/R0 {th['container']:.1f} MPa "
            f"(Lc {self.container_length or 0.0:.3g} mm, k {th['shear_yield']:.1f}); upper "
            f"{th['upper']:.1f} (1.1 x {1.1 * th['upper']:.1f})"]
        if self.punch_pressure is not None:
            lines.append(
                f"steady punch pressure {self.punch_pressure:.1f} MPa: / ideal "
                f"{self.punch_pressure / th['ideal']:.3f}, / upper "
                f"{self.punch_pressure / th['upper']:.3f}; die pressure {self.die_pressure:.1f}"
                f" MPa (/ Avitzur {self.die_pressure / th['avitzur']:.3f}), oscillation "
                f"+-{100 * self.steady_oscillation:.1f} %"
                + (f"; container force / theory {self.container_ratio:.3f}"
                   if self.container_ratio is not None else ""))
        else:
            last = self.history[-1]["punch_pressure"] if self.history else float("nan")
            lines.append(f"no steady state detected; last punch pressure {last:.1f} MPa")
        if self.history:
            lines.append(f"max penetration {self.max_penetration:.3g} mm")
            lines += heat_lines(self.history, c.heat, "billet") + self.numerics_lines()
        return self.report_text(lines)


def run(case: ExtrusionCase, comm=None, output_dir: Optional[str] = None,
        pictures: bool = True, vtk_every: int = 0) -> ExtrusionResult:
    """Extrude to ``case.t_end`` (or to steady state with ``case.stop_at_steady``). With
    ``output_dir``: ``extrusion_diagnostics.csv``, the pictures (``extrusion_flow.png``: the
    axial velocity and the strain rate on the θ = 0 section, the dead-metal zone;
    ``extrusion_pressure.png``) and, with ``vtk_every``, the VTK series ``extrusion.pvd``."""
    comm = comm or MPI.COMM_WORLD
    check_output_dir(output_dir, comm)
    s = build(case, comm, output_dir, vtk_every)
    sim, contact, g = s.sim, s.contact, s.layout
    balance = PowerBalance(sim, [contact])
    k_c = case.theory()["shear_yield"]
    mbar_container = case.friction_factors()["mbar_container"]
    separate = case.container == "separate"

    remeshes = [0]

    def row(r):
        _follow_remesh(s, remeshes)
        # the punch's force: the back face's reaction (its rim's nodes are driven by the punch
        # and slide on the container: the reaction takes the container's friction there)
        F = r["punch_z"]
        Lc = max(s.corner - case.speed * r["time"], 0.0)
        Fc = r["container_force_z"] if separate else math.nan
        Fc_th = mbar_container * k_c * math.radians(case.sector) * case.R0 * Lc
        return dict(
            increment=r["increment"], time=r["time"], dt=r["dt"], punch_force=F,
            punch_pressure=F / g.A0, container_length=Lc, container_force=Fc,
            container_force_theory=Fc_th,
            die_pressure=(F - Fc) / g.A0 if separate else F / g.A0,
            penetration=r["contact_penetration_true"], contact_nodes=r["contact_nodes"],
            remesh=r["remesh"],
            **numerics_columns(r), **balance(r, F * case.speed), **heat_columns(r))

    def progress(q):
        if comm.rank == 0:
            log.info("extrusion: t = %.4g / %.4g s, p = %.1f MPa, %d Newton its, %.1f s",
                     q["time"], case.t_end, q["punch_pressure"], q["newton_iterations"],
                     q["wall"])

    win = max(3, int(math.ceil(case.window / (case.speed * case.dt) - 1e-9)))
    settle = case.settle if case.settle is not None else 2.0 * g.h
    wall0 = time.perf_counter()
    rows, status, message, steady = run_increments(
        sim, case.dt, case.t_end, case.max_cutbacks, row, ("die_pressure",), win,
        case.steady_tol, lambda t: case.speed * t >= settle, case.stop_at_steady, progress)
    out = ExtrusionResult(case=case, status=status, message=message, history=rows,
                          theory=case.theory(), dofs=s.dofs, h=g.h, A0=g.A0,
                          wall=time.perf_counter() - wall0, time=sim.t, ranks=comm.size,
                          increments=len(rows))
    if rows:
        out = dataclasses.replace(out, max_penetration=max(q["penetration"] for q in rows),
                                  theory=case.theory(rows[-1]["container_length"]),
                                  container_length=rows[-1]["container_length"],
                                  power_balance=rows[-1]["power_balance"],
                                  power_balance_penalty=rows[-1]["power_balance_penalty"],
                                  **run_summary(rows))
    if steady is not None:
        first, last = steady
        st = steady_values(rows, first, last, ("punch_pressure", "die_pressure",
                                               "container_length", "power_balance",
                                               "power_balance_penalty"))
        sel = rows[first:last + 1]
        ratio = None
        if separate and mbar_container > 0:
            ratio = float(np.mean([q["container_force"] / q["container_force_theory"]
                                   for q in sel]))
        out = dataclasses.replace(
            out, steady_from=first, steady_to=last, steady_time=st["steady_time"],
            theory=case.theory(st["container_length"]), punch_pressure=st["punch_pressure"],
            die_pressure=st["die_pressure"], container_length=st["container_length"],
            container_ratio=ratio, steady_oscillation=st["die_pressure_oscillation"],
            power_balance=st["power_balance"],
            power_balance_penalty=st["power_balance_penalty"])
    return finish_run(comm, sim, out, output_dir, "extrusion", pictures, vtk_every,
                      lambda: _pictures(comm, s, out, output_dir))


def _pictures(comm, s: ExtrusionSetup, res: ExtrusionResult, out: str):
    """The axial velocity over the punch speed and the equivalent strain rate on the θ = 0
    section (the dead-metal zone: the still corner between the container and the die); the
    punch and die pressures against the band (rank 0 draws; every rank returns the paths)."""
    sim, c = s.sim, res.case
    vz = vertex_field(sim, sim.w.x.array[sim.space.vertex_dofs][:, 2] / c.speed)
    zr, (v, rate) = meridian_section(comm, sim, s.facet_tags, DRAWING_BAR_TAGS["symmetry_0"],
                                     (vz, sim.strain_rate))
    f1 = os.path.join(out, "extrusion_flow.png")
    f2 = os.path.join(out, "extrusion_pressure.png")
    if comm.rank != 0:
        return [f1, f2]
    th = res.theory
    sz = np.linspace(zr[..., 0].min() - 1, zr[..., 0].max() + 1, 800)
    plot_sections(f1, zr, [(v, "axial velocity / punch speed", "turbo",
                            (0.0, th["extrusion_ratio"])),
                           (rate, "equivalent strain rate [1/s]", "magma")],
                  outline=(sz, die_radius(s.profile, sz), "container and die"),
                  r_max=1.3 * c.R0, xlabel="z [mm] (extrusion direction →)",
                  title=f"Extrusion R₀ {c.R0:g} → {c.R1:g} mm, α = {c.alpha:g}°, "
                        f"{law_text(c.friction)}, t = {res.time:.3g}"
                        f" s: θ = 0 section; the slow corner between the container and the die: "
                        f"dead-metal zone")
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(8, 4.5))
    hist = res.history
    t = [q["time"] for q in hist]
    upper = [c.theory(q["container_length"])["upper"] for q in hist]
    plot_curves(ax, t, [([q["punch_pressure"] for q in hist], "b.-", "FE punch pressure F/A₀"),
                        ([q["die_pressure"] for q in hist], "g.-", "FE die pressure"),
                        (upper, "k-", "Avitzur + container friction (L_c(t))")],
                [(th["ideal"], "--", f"ideal {th['ideal']:.0f} MPa"),
                 (th["avitzur"], "-.", f"Avitzur (die) {th['avitzur']:.0f} MPa")],
                window=res.steady_time, ylabel="pressure [MPa]",
                ylim=(0, 1.3 * max(upper)))
    fig.tight_layout()
    fig.savefig(f2, dpi=110)
    plt.close(fig)
    return [f1, f2]
