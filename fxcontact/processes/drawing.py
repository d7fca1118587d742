"""Wire (bar) drawing through a conical die (THEORY §12.2, §14.2): the case, the set-up and the
run to steady state.

A round bar (one sector about its axis, symmetry planes at θ = 0 and θ = ``sector``, the second
one inclined and imposed exactly) with a pointed nose already through the die is pulled at its
front face along +z; the back face is free (no back tension). The die is the analytic surface
of revolution :class:`fxcontact.RevolvedProfile` (entry cone, fillet, bearing land, exit
relief), or its sector triangulated and projected on flat facets or Nagata patches. Nodal
penalty contact on the lateral surface (``penalty``), optional Tresca or Coulomb friction
(``friction``).

Measured per increment: the drawing force (reaction on the pulled face) and stress F/A₁, the
true penetration against the exact die, contact nodes, the power balance, Newton iterations,
wall time, volume change and element quality. Steady state: after ``settle`` mm of pull, the
mean drawing force over the last ``window`` mm of pull and over the window before agree within
``steady_tol`` (:func:`fxcontact.steady.steady_window`). The steady drawing stress is compared
with the band of :func:`fxcontact.theory.forming.drawing_theory` (ideal work, Sachs, Avitzur).

Example::

    from fxcontact.processes import DrawingCase, run_drawing
    res = run_drawing(DrawingCase.quick(alpha=15.0))
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
from fxcontact.contact.friction import Coulomb, Frictionless, Tresca
from fxcontact.contact.nodal import SCHEMES, NodalContact
from fxcontact.contact.penalty import Penalty
from fxcontact.io.series import pyplot
from fxcontact.meshing import DRAWING_BAR_TAGS
from fxcontact.newton.solver import SolverOptions
from fxcontact.power import PowerBalance
from fxcontact.processes.common import check_output_dir
from fxcontact.processes.common import (CaseBase, ProcessResult, finish_run, gather,
                                        mean_norton_hoff, meridian_section, numerics_columns,
                                        plot_curves, plot_sections, run_increments, run_summary,
                                        steady_values)
from fxcontact.processes.contact_laws import (UNSET, Former, Friction, contact_friction,
                                              gap_penalty, law_text)
from fxcontact.processes.die import (DIE_MESHES, DIES, bar_simulation, die_profile_tool, die_radius,
                                     die_tool, nose_layout, true_penetration)
from fxcontact.simulation import Simulation
from fxcontact.materials import Viscoplastic
from fxcontact.theory import forming
from fxcontact.thermal import HeatSetup

__all__ = ["DrawingCase", "DrawingSetup", "DrawingResult", "build", "run"]

log = logging.getLogger("fxcontact.processes.drawing")


def _friction_of(case, v: dict):
    """The die's law of the former ``mu``, ``mbar``: Coulomb μ limited by m̄ (1 if 0), else
    Tresca m̄, else none."""
    mu, mbar = v["mu"], v["mbar"]
    if mu < 0 or not 0 <= mbar <= 1:
        raise ValueError(f"need mu >= 0 and 0 <= mbar <= 1, got {mu}, {mbar}")
    if mu > 0:
        return Coulomb(mu, mbar=mbar or 1.0)
    return Tresca(mbar) if mbar > 0 else Frictionless()


def _friction_values(case, law) -> Optional[dict]:
    if isinstance(law, Coulomb) and law.mbar is not None:
        return {"mu": law.mu, "mbar": law.mbar}
    if isinstance(law, (Tresca, Frictionless)):
        return {"mu": 0.0, "mbar": getattr(law, "mbar", 0.0)}
    return None


def _penalty_of(case, v: dict) -> Penalty:
    """The penalty of the former ``penalty`` ("gap": a gap stiffness from β over
    ``penalty_dt``, "velocity": β), ``beta``, ``penalty_dt``."""
    kind, beta, dt = v["penalty"], v["beta"], v["penalty_dt"]
    if kind not in ("gap", "velocity"):
        raise ValueError(f"penalty must be a fxcontact.Penalty (or, formerly, 'gap' or "
                         f"'velocity'), got {kind!r}")
    if not (beta > 0 and (dt is None or dt > 0)):
        raise ValueError(f"need beta > 0 and penalty_dt > 0 (or None), got {beta}, {dt}")
    if kind == "gap":
        return Penalty(beta=float(beta), gap=True,
                       reference_dt=None if dt is None else float(dt))
    return Penalty(beta=float(beta))


def _penalty_values(case, p: Penalty) -> Optional[dict]:
    a = p.as_given()
    if a["beta"] is None:
        return None
    return {"penalty": "gap" if a["gap"] else "velocity", "beta": a["beta"],
            "penalty_dt": a["reference_dt"]}


@dataclass(frozen=True)
class DrawingCase(CaseBase):
    """A wire-drawing case: lengths mm, stresses MPa, times s, angles degrees.

    The defaults are the thesis's case (Annex A2.1: R₀ 10 → 7.5 mm, L = 38 mm, one third,
    Norton–Hoff K = 445 MPa·s^m, m = 0.016 without the thesis's elastic part, frictionless,
    100 mm/s) with our die (10° cone, 2 mm fillet, 2 mm land, 20° relief 1 mm long).
    :meth:`quick` is the reduced size of the tests. Bad values raise ``ValueError`` naming the
    field.

    **Contact** (on the bar's lateral surface, the die its one tool, named ``"die"``):

    * ``penalty`` (:class:`fxcontact.Penalty`): by default ``Penalty(beta=100.0, gap=True)``,
      a stiffness on the end-of-increment gap k = ρ(β)/dt_ref [MPa/mm = N/mm³] with
      ρ(β) = β η(ε̄̇)/h_e [MPa·s/mm] (THEORY §2.5; η the secant viscosity [MPa·s] at the die's
      mean strain rate, h_e = ``h``/``size`` [mm], dt_ref = ``dt`` [s] unless the Penalty
      gives ``reference_dt``); then ρ = k·dt at each increment, so that the penalty
      penetration does not depend on dt. ``Penalty(beta=β)``: ρ = β η/h_e [MPa·s/mm] at the
      representative strain rate estimated at the first increment and the contact's element
      size; ``Penalty(penalty=ρ)``, ``Penalty(gap_stiffness=k)`` as given.
    * ``friction``: the die's law, ``Frictionless()`` (default), ``Coulomb(mu, mbar=...)``
      (μ dimensionless, limited by the Tresca m̄ k) or ``Tresca(mbar)`` (m̄ in [0, 1], k the
      shear flow stress [MPa] at each node); or ``{"die": law}``. The references convert it
      (:meth:`friction_references`).
    * Former spellings, accepted for one release with a ``DeprecationWarning``: ``mu``,
      ``mbar`` (Coulomb μ limited by m̄, 1 if 0; else Tresca m̄) for ``friction``;
      ``penalty="gap"|"velocity"``, ``beta``, ``penalty_dt`` for ``penalty`` (``"gap"``:
      ``Penalty(beta=beta, gap=True, reference_dt=penalty_dt)``).

    **How a penalty or a friction coefficient reaches its kernel.** ``case.penalty`` →
    :func:`build` (a gap stiffness from β takes the die's mean strain rate, h_e and dt:
    :func:`~fxcontact.processes.contact_laws.gap_penalty`) → ``NodalContact(penalty=)`` (its
    own copy, bound to the formulation) → ``Penalty.rho(material, dt, rate)`` at each
    ``begin_increment`` (k resolved once, ρ = k·dt) → ``penalty_kernel(S, rho, ...)``: four
    hops. ``case.friction`` → ``NodalContact(friction=)`` (one law per tool) →
    ``friction_arguments`` at each evaluation (per node: law code, μ, m̄ k with k from
    ``begin_increment``) → ``friction_kernel(...)``: three hops."""

    # geometry: bar and die
    R0: float = 10.0                 #: bar radius
    R1: float = 7.5                  #: die exit (bearing) radius
    length: float = 38.0             #: bar length (back face to the nose's front face)
    sector: float = 120.0            #: modelled sector about the axis (degrees)
    alpha: float = 10.0              #: die cone semi-angle (degrees, < 45)
    land: float = 2.0                #: bearing land length
    fillet: float = 2.0              #: cone–land fillet radius (0: sharp)
    relief_angle: float = 20.0       #: exit relief semi-angle (0: no relief)
    relief_length: float = 1.0       #: exit relief axial length
    nose_ratio: float = 0.96         #: nose radius over R1
    # material (Norton–Hoff)
    K: float = 445.0
    m: float = 0.016
    #: a flow stress σ₀(ε̄, ε̄̇, T) (:class:`~fxcontact.Viscoplastic`, e.g. a hardening law)
    #: instead of K, m; the theory's σ₀ is then its mean over the ideal strain 2 ln(R₀/R₁) at
    #: the die's mean strain rate and the initial temperature
    material: Optional[Viscoplastic] = None
    #: heat (:class:`~fxcontact.HeatSetup`: the bar's thermal material and temperature, air on
    #: the free surface, the tool ``die``), or None
    heat: Optional[HeatSetup] = None
    #: the die's friction law (or ``{"die": law}``)
    friction: Friction = Frictionless()
    # kinematics
    speed: float = 100.0             #: pulling speed of the front face
    dt: float = 2.5e-3
    t_end: float = 0.37
    # numerics
    h: float = 0.75                  #: bar element size (divided by size)
    facet: float = 0.5               #: faceted die's facet size (divided by size)
    size: float = 1.0
    die: str = "exact"               #: "exact", "flat" or "nagata"
    die_mesh: str = "gmsh"           #: faceted die: "gmsh" (unstructured) or "structured"
    scheme: str = "implicit"
    #: the contact penalty: a gap stiffness k = ρ(β)/dt [MPa/mm] from β = 100 by default
    penalty: Penalty = Penalty(beta=100.0, gap=True)
    max_it: int = 60
    #: Newton's relative tolerance on the residual (``SolverOptions.rtol``); 1e-6 instead of
    #: 1e-9 saves 15 % of the Newton iterations at size 0.4 with the drawing stress within
    #: 5e-8 at every increment (5.4e-6 at the quick size; benchmarks/README.md)
    newton_rtol: float = 1e-9
    #: Newton's force-scaled tolerance (``SolverOptions.ftol``): converged at ‖R‖ ≤ ftol ×
    #: the ℓ² norm of the die's nodal forces; 0 (default): off. At 1e-3 the thesis-size
    #: drawing takes 4.8 Newton iterations per increment instead of 6.1 (rtol 1e-6) and
    #: 10 min 41 s instead of 12 min 22 s, the drawing stress within 1.5e-5 at every increment
    #: (3.9e-4 at the quick size); off by default because the
    #: power identity with the penalty work then closes only to the Newton residual
    #: (3.9e-4 at the quick size, against 1e-10; benchmarks/README.md)
    newton_ftol: float = 0.0
    line_search: str = "bt"
    penalty_continuation: Optional[float] = None
    active_set_prediction: object = "auto"
    material_tangent: str = "auto"
    linear_solver: str = "auto"
    element_condensation: object = "auto"   #: SolverOptions.element_condensation
    reuse_factorisation: object = "auto"    #: SolverOptions.reuse_factorisation
    max_cutbacks: int = 4
    # steady state: two windows of `window` mm of pull agree within steady_tol, after `settle`
    # mm (default one element)
    window: float = 3.0
    steady_tol: float = 0.02
    settle: Optional[float] = None
    stop_at_steady: bool = False
    # former spellings of friction and penalty (one release)
    mu: InitVar[Optional[float]] = UNSET
    mbar: InitVar[Optional[float]] = UNSET
    beta: InitVar[Optional[float]] = UNSET
    penalty_dt: InitVar[Optional[float]] = UNSET

    FRICTION_TOOLS = ("die",)
    FORMER = (Former("friction", {"mu": 0.0, "mbar": 0.0}, _friction_of, _friction_values),
              Former("penalty", {"penalty": "gap", "beta": 100.0, "penalty_dt": None},
                     _penalty_of, _penalty_values))

    #: the reduced size of the tests: R₀ 5 → 3.75 mm (same reduction), h = 1.5 mm, a short bar,
    #: 5 ms increments, stop at steady state
    QUICK = dict(R0=5.0, R1=3.75, length=18.0, h=1.5, facet=1.0, dt=5e-3, t_end=0.1, land=1.0,
                 fillet=1.0, relief_length=0.5, window=1.5, steady_tol=0.02,
                 stop_at_steady=True)

    def __post_init__(self, mu, mbar, beta, penalty_dt):
        self.resolve_contact_laws(mu=mu, mbar=mbar, beta=beta, penalty_dt=penalty_dt)
        if not isinstance(self.tool_friction("die"), (Coulomb, Tresca, Frictionless)):
            raise ValueError(f"friction of the die must be Coulomb, Tresca or Frictionless (the "
                             f"references need mu or mbar), got {self.friction!r}")
        self.check_positive(("R0", "R1", "length", "K", "speed", "alpha", "land", "h", "facet",
                             "size", "dt", "t_end", "window", "steady_tol", "sector"))
        self.check_bar_and_die(alpha_max=45.0)
        self.check_increment(self.speed, self.h / self.size, "the drawn bar")
        if self.die not in DIES:
            raise ValueError(f"die must be one of {DIES}, got {self.die!r}")
        if self.die_mesh not in DIE_MESHES:
            raise ValueError(f"die_mesh must be 'structured' or 'gmsh', got {self.die_mesh!r}")
        if self.scheme not in SCHEMES:
            raise ValueError(f"scheme must be one of {SCHEMES}, got {self.scheme!r}")
        if self.scheme == "implicit-exact" and self.die == "flat":
            raise ValueError("implicit-exact needs the gap Hessian: die 'exact' or 'nagata'")
        if not 0.0 < self.newton_rtol < 1.0:
            raise ValueError(f"newton_rtol must be in (0, 1), got {self.newton_rtol!r}")
        if not 0.0 <= self.newton_ftol < 1.0:
            raise ValueError(f"newton_ftol must be in [0, 1), got {self.newton_ftol!r}")
        if self.material is not None and not isinstance(self.material, Viscoplastic):
            raise ValueError(f"material must be a fxcontact.Viscoplastic (a flow stress; "
                             f"plain Norton-Hoff: K and m), got {self.material!r}")
        if self.heat is not None and not isinstance(self.heat, HeatSetup):
            raise ValueError(f"heat must be a fxcontact.HeatSetup, got {self.heat!r}")
        self.layout()       # the bar must hold the nose

    def layout(self):
        """The nose and die placement (:class:`~fxcontact.processes.die.NoseLayout`)."""
        return nose_layout(self.R0, self.R1, self.alpha, self.land, self.fillet,
                           self.relief_angle, self.relief_length, self.nose_ratio,
                           self.h / self.size, self.facet / self.size, self.length, self.sector)

    def friction_references(self):
        """(μ, m̄) of the references: Sachs needs a Coulomb μ, Avitzur a Tresca m̄; the other
        one is converted with the pressure p ≈ σ₀ in the die (τ = μp = m̄σ₀/√3, an
        approximation): Coulomb μ gives m̄ = min(m̄_cap, √3 μ) (m̄_cap 1 without a cap),
        Tresca m̄ gives μ = m̄/√3."""
        law = self.tool_friction("die")
        mu = law.mu if isinstance(law, Coulomb) else 0.0
        if mu > 0:
            cap = law.mbar if law.mbar is not None else 1.0
            return mu, min(cap, math.sqrt(3) * mu)
        mbar = law.mbar if isinstance(law, Tresca) else 0.0
        return mbar / math.sqrt(3), mbar

    def theory(self) -> dict:
        """The band of THEORY §14.2 (:func:`fxcontact.theory.forming.drawing_theory`) with the
        reference friction (``mu_ref``, ``mbar_ref``)."""
        mu_ref, mbar_ref = self.friction_references()
        K, m = self.K, self.m
        if self.material is not None:   # the mean flow stress over the ideal strain
            rate = forming.drawing_theory(1.0, 1.0, self.R0, self.R1, math.radians(self.alpha),
                                          self.speed)["strain_rate"]
            K, m = mean_norton_hoff(self.material, 2.0 * math.log(self.R0 / self.R1), rate,
                                    self.heat.initial_temperature if self.heat else None)
        th = forming.drawing_theory(K, m, self.R0, self.R1, math.radians(self.alpha),
                                    self.speed, mu=mu_ref, mbar=mbar_ref,
                                    land_length=self.land)
        th.update(mu_ref=mu_ref, mbar_ref=mbar_ref)
        return th

    def solver_options(self) -> SolverOptions:
        return SolverOptions(max_it=int(self.max_it), rtol=float(self.newton_rtol),
                             ftol=float(self.newton_ftol), line_search=self.line_search,
                             active_set_prediction=self.active_set_prediction,
                             material_tangent=self.material_tangent,
                             penalty_continuation=self.penalty_continuation,
                             linear_solver=self.linear_solver,
                             element_condensation=self.element_condensation,
                             reuse_factorisation=self.reuse_factorisation)


@dataclass
class DrawingSetup:
    """A ready drawing :class:`~fxcontact.Simulation` and its handles."""

    case: DrawingCase
    sim: Simulation
    contact: NodalContact
    exact_die: object            #: the analytic die (the true penetration is measured on it)
    die: object                  #: the die used (the exact one or a faceted sector)
    facet_sag: float
    facet_tags: object
    layout: object
    theory: dict
    dofs: int


def build(case: DrawingCase, comm=None, output_dir: Optional[str] = None,
          vtk_every: int = 0, name: str = "wire_drawing") -> DrawingSetup:
    """Mesh the bar, make the die, the contact and the :class:`~fxcontact.Simulation` (not
    run): symmetry planes ``sym0``/``sym1``, the pulled front face (reaction ``pull``), the
    contact ``contact`` on the lateral surface. The VTK series is written every ``vtk_every``
    increments into ``output_dir`` (0: none)."""
    comm = comm or MPI.COMM_WORLD
    g = case.layout()
    theory = case.theory()
    sim, ft, f, mat = bar_simulation(case, g, comm, theory["strain_rate"],
                                     case.solver_options(), "front", "pull", output_dir,
                                     vtk_every, name)
    space = sim.space
    exact = die_profile_tool(g, case.R1, case.alpha, case.land, case.fillet,
                             case.relief_length)
    die, sag = die_tool(exact, case.die, case.die_mesh, case.sector, g.facet, g.h, case.R0,
                        case.R1, case.fillet, comm)
    # by default a stiffness on the end-of-increment gap, k = ρ(β)/dt_ref: the penalty
    # penetration p/k does not depend on dt (the thesis's implicit penetration does not change
    # with 4 dt); ρ(β) = β η(ε̄̇_mean)/h (THEORY §2.5) at the die's mean strain rate
    penalty = gap_penalty(case.penalty, theory["strain_rate"], g.h, case.dt)
    contact = NodalContact(ContactBoundary(space, ft, DRAWING_BAR_TAGS["lateral"]), die,
                           scheme=case.scheme, friction=contact_friction(case.friction),
                           name="contact", penalty=penalty)
    sim.add_contributor(contact)
    if case.heat is not None:   # the side and the end faces are free; symmetry: insulated
        case.heat.attach(sim, ft, [DRAWING_BAR_TAGS[k] for k in ("lateral", "front", "back")],
                         [t.name for t in contact.tools])
    dofs = space.W.dofmap.index_map.size_global * space.W.dofmap.index_map_bs
    return DrawingSetup(case, sim, contact, exact, die, sag, ft, g, theory, dofs)


@dataclass
class DrawingResult(ProcessResult):
    """The outcome of :func:`run` (:class:`~fxcontact.processes.common.ProcessResult`) and the
    drawing's own values; the steady ones are None without a steady state."""

    case: Optional[DrawingCase] = None
    facet: float = math.nan
    facet_sag: float = 0.0
    A1: float = math.nan
    max_penetration: float = math.nan       #: true, against the exact die, over the run
    max_penetration_tool: float = math.nan  #: against the die used
    contact_nodes_01: int = -1              #: at t = 0.1 s (or the last increment before)
    time_01: float = math.nan
    steady_stress: Optional[float] = None   #: σ_d = F/A₁ over the steady window
    steady_force: Optional[float] = None
    steady_oscillation: Optional[float] = None
    ratio_ideal: Optional[float] = None
    ratio_avitzur: Optional[float] = None

    def report(self) -> str:
        """A summary for the console."""
        c, th = self.case, self.theory
        lines = [
            f"wire drawing R0 {c.R0:g} -> {c.R1:g} mm (reduction {100 * th['reduction']:.2f} "
            f"%), alpha {c.alpha:g} deg, land {c.land:g} mm, die {c.die}, scheme {c.scheme}, "
            f"{law_text(c.friction)}; h {self.h:.3g} mm, facets {self.facet:.3g} mm, "
            f"{self.dofs} dofs, {self.ranks} rank(s)",
            f"status: {self.status} {self.message}; {self.increments} increments of "
            f"{c.dt:g} s to t = {self.time:.4g} s",
            f"theory (THEORY 14.2): sigma0 = {th['sigma0']:.1f} MPa at the die's mean strain "
            f"rate {th['strain_rate']:.3f} 1/s; ideal {th['ideal']:.1f}, Sachs "
            f"{th['sachs']:.1f}, Avitzur {th['avitzur']:.1f} MPa (1.1 x Avitzur "
            f"{1.1 * th['avitzur']:.1f})"
            + (f"; friction of the references mu {th['mu_ref']:.3g} (Sachs), mbar "
               f"{th['mbar_ref']:.3g} (Avitzur), converted with p = sigma0"
               if th["mu_ref"] > 0 else "")]
        if self.steady_stress is not None:
            t0, t1 = self.steady_time
            lines.append(f"steady drawing stress F/A1 = {self.steady_stress:.1f} MPa (t "
                         f"{t0:.3f}-{t1:.3f} s): / ideal {self.ratio_ideal:.3f}, / Avitzur "
                         f"{self.ratio_avitzur:.3f}; force on the sector "
                         f"{self.steady_force:.0f} N, oscillation "
                         f"+-{100 * self.steady_oscillation:.1f} %")
        else:
            last = self.history[-1]["drawing_stress"] if self.history else float("nan")
            lines.append(f"no steady state detected; last drawing stress {last:.1f} MPa")
        if self.history:
            lines += [
                f"max true penetration (exact die) {self.max_penetration:.3g} mm, against the "
                f"die used {self.max_penetration_tool:.3g} mm (facet sag "
                f"{self.facet_sag:.2g}); contact nodes at t = {self.time_01:.3g} s: "
                f"{self.contact_nodes_01}"] + _heat_line(self) + self.numerics_lines()
        return self.report_text(lines)


def _heat_line(res) -> list:
    """The bar's temperature at the end against the adiabatic rise of the steady drawing
    work, η_q σ_d/ρc (σ_d = the work per unit volume drawn), if the run has heat."""
    q = res.history[-1] if res.history else {}
    if "heat_T_max" not in q:
        return []
    heat = res.case.heat
    sd = res.steady_stress if res.steady_stress is not None else q["drawing_stress"]
    rise = heat.thermal.taylor_quinney * sd / float(heat.thermal.rho_c)
    return [f"bar temperature at the end: min {q['heat_T_min']:.1f} / mean {q['heat_T_mean']:.1f}"
            f" / max {q['heat_T_max']:.1f} °C (from {heat.initial_temperature:g}); adiabatic "
            f"rise of the drawing work eta_q sigma_d / rho c = {rise:.1f} K"]


def run(case: DrawingCase, comm=None, output_dir: Optional[str] = None, pictures: bool = True,
        vtk_every: int = 0) -> DrawingResult:
    """Draw the bar to ``case.t_end`` (or to steady state with ``case.stop_at_steady``).
    With ``output_dir``: ``wire_drawing_diagnostics.csv``, the pictures
    (``wire_drawing_strain.png``, ``wire_drawing_contact.png``) and, with ``vtk_every``, the
    VTK series ``wire_drawing.pvd``."""
    comm = comm or MPI.COMM_WORLD
    check_output_dir(output_dir, comm)
    s = build(case, comm, output_dir, vtk_every)
    sim, contact, g = s.sim, s.contact, s.layout
    balance = PowerBalance(sim, [contact])
    win = max(3, int(math.ceil(case.window / (case.speed * case.dt) - 1e-9)))
    settle = case.settle if case.settle is not None else g.h

    def row(r):
        # the pull: the front face's reaction (with the die's force on the face's rim, nil
        # while the nose does not touch the die)
        Fz = r["pull_z"]
        return dict(
            increment=r["increment"], time=r["time"], dt=r["dt"], drawing_force=Fz,
            drawing_stress=Fz / g.A1,
            penetration_true=true_penetration(comm, s.exact_die, contact, sim),
            penetration_tool=r["contact_penetration_true"], contact_nodes=r["contact_nodes"],
            **numerics_columns(r), **balance(r, Fz * case.speed),
            **{k: v for k, v in r.items() if k.startswith("heat_")})

    def progress(q):
        if comm.rank == 0:   # progress of a long run
            log.info("wire drawing: t = %.4g / %.4g s, F/A1 = %.1f MPa, %d Newton its, %.1f s",
                     q["time"], case.t_end, q["drawing_stress"], q["newton_iterations"],
                     q["wall"])

    wall0 = time.perf_counter()
    # steady state: two consecutive windows of `window` mm of pull with the same mean force
    # (each window spans element passages: the nodal force oscillates with them)
    rows, status, message, steady = run_increments(
        sim, case.dt, case.t_end, case.max_cutbacks, row, ("drawing_force",), win,
        case.steady_tol, lambda t: case.speed * t >= settle, case.stop_at_steady, progress)
    out = DrawingResult(case=case, status=status, message=message, history=rows,
                        theory=s.theory, dofs=s.dofs, h=g.h, facet=g.facet,
                        facet_sag=s.facet_sag, A1=g.A1, wall=time.perf_counter() - wall0,
                        time=sim.t, ranks=comm.size, increments=len(rows))
    if rows:
        before = [q for q in rows if q["time"] <= 0.1 + 1e-9] or rows
        out = dataclasses.replace(
            out, max_penetration=max(q["penetration_true"] for q in rows),
            max_penetration_tool=max(q["penetration_tool"] for q in rows),
            contact_nodes_01=before[-1]["contact_nodes"], time_01=before[-1]["time"],
            power_balance=rows[-1]["power_balance"],
            power_balance_penalty=rows[-1]["power_balance_penalty"], **run_summary(rows))
    if steady is not None:
        st = steady_values(rows, *steady,
                           ("drawing_stress", "power_balance", "power_balance_penalty"))
        sd = st["drawing_stress"]
        out = dataclasses.replace(
            out, steady_from=st["steady_from"], steady_to=st["steady_to"],
            steady_time=st["steady_time"], steady_stress=sd, steady_force=sd * g.A1,
            ratio_ideal=sd / s.theory["ideal"], ratio_avitzur=sd / s.theory["avitzur"],
            steady_oscillation=st["drawing_stress_oscillation"],
            power_balance=st["power_balance"],
            power_balance_penalty=st["power_balance_penalty"])
    return finish_run(comm, sim, out, output_dir, "wire_drawing", pictures, vtk_every,
                      lambda: _pictures(comm, s, out, output_dir))


def _pictures(comm, s: DrawingSetup, res: DrawingResult, out: str):
    """The strain and strain rate on the θ = 0 section; the contact zone and the drawing
    stress against the band (rank 0 draws; every rank returns the paths)."""
    sim, contact, exact = s.sim, s.contact, s.exact_die
    zr, (eps, rate) = meridian_section(comm, sim, s.facet_tags,
                                       DRAWING_BAR_TAGS["symmetry_0"],
                                       (sim.strain, sim.strain_rate))
    X = gather(comm, sim.vertex_positions()[contact.boundary.vertices])
    p = gather(comm, contact.pressures())
    f1 = os.path.join(out, "wire_drawing_strain.png")
    f2 = os.path.join(out, "wire_drawing_contact.png")
    if comm.rank != 0:
        return [f1, f2]
    c, th = res.case, res.theory
    sz = np.linspace(zr[..., 0].min() - 2, zr[..., 0].max() + 2, 800)
    sd = res.steady_stress if res.steady_stress is not None else float("nan")
    plot_sections(f1, zr, [(eps, "equivalent strain", "viridis"),
                           (rate, "equivalent strain rate [1/s]", "magma")],
                  outline=(sz, die_radius(exact, sz), "die (exact profile)"),
                  r_max=1.25 * c.R0, xlabel="z [mm] (drawing direction →)",
                  title=f"Drawing R₀ {c.R0:g} → {c.R1:g} mm, α = {c.alpha:g}°, t = "
                        f"{res.time:.3f} s, die {c.die}, {c.scheme}: θ = 0 section; σ_d = "
                        f"{sd:.0f} MPa (ideal {th['ideal']:.0f}, Avitzur {th['avitzur']:.0f})")
    plt = pyplot()
    fig, axs = plt.subplots(1, 2, figsize=(12, 4.2))
    act = p > 0
    th_deg = np.degrees(np.arctan2(X[:, 1], X[:, 0]))
    axs[0].scatter(X[~act, 2], th_deg[~act], s=3, c="0.8", label="lateral nodes")
    sc = axs[0].scatter(X[act, 2], th_deg[act], s=14, c=p[act], cmap="plasma",
                        label="contact nodes")
    fig.colorbar(sc, ax=axs[0], label="contact pressure [MPa]")
    for zz in exact.points[:, 0]:
        axs[0].axvline(zz, color="k", lw=0.5, ls=":")
    lo = max(X[act, 2].min() - 3 * res.h, X[:, 2].min()) if np.any(act) else X[:, 2].min()
    hi = min(X[act, 2].max() + 3 * res.h, X[:, 2].max()) if np.any(act) else X[:, 2].max()
    axs[0].set_xlim(lo, hi)
    axs[0].set_xlabel("z [mm] (dotted: die profile points)")
    axs[0].set_ylabel("θ [deg]")
    axs[0].set_title(f"contact zone at t = {res.time:.3f} s ({int(np.sum(act))} nodes)",
                     fontsize=9)
    hist = res.history
    bands = [(th["ideal"], "--", f"ideal {th['ideal']:.0f} MPa"),
             (th["avitzur"], "-.", f"avitzur {th['avitzur']:.0f} MPa")]
    if th["mu_ref"] > 0:
        bands.append((th["sachs"], ":", f"Sachs {th['sachs']:.0f} MPa"))
    plot_curves(axs[1], [q["time"] for q in hist],
                [([q["drawing_stress"] for q in hist], "b.-", "FE σ_d = F/A₁")], bands,
                window=res.steady_time, ylabel="drawing stress [MPa]",
                ylim=(0, 1.3 * th["avitzur"]))
    fig.tight_layout()
    fig.savefig(f2, dpi=110)
    plt.close(fig)
    return [f1, f2]
