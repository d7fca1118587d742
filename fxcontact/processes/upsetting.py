"""Upsetting a cylinder between flat dies (THEORY §14.1, §14.5): the case, the set-up and the
run, with remeshing on by default.

A billet of radius R₀ and height H₀ (``aspect`` = H₀/D₀, 1.5 by default) is compressed between
two flat dies closing at ``speed``, each die moving at ``speed``/2 towards the mid-plane. One
sector about the axis is modelled (symmetry planes ``sym0``/``sym1``, a quarter by default) and,
with ``half=True`` (default), one half of the height: the mid-plane z = 0 is a symmetry plane
(a velocity condition v_z = 0) and the upper die, a :class:`~fxcontact.tools.analytic.Plane`
at z = H/2, is the only tool. The half-height symmetry is exact: both dies move towards the
mid-plane at the same speed with the same friction, so the problem is symmetric about it (a
die held still instead changes the solution by a rigid translation only, which neither the
material nor the friction, a function of the slip against each die, sees). A symmetric model
cannot buckle: for h/d ≤ 2 the billet does not. ``half=False`` models the whole height
with the two dies (the body held by them only): the same pressure and radii to discretisation
accuracy (``tests/test_upsetting.py``).

**Friction** on the dies (``friction``): Tresca τ = m̄ k (``Tresca(mbar)``; m̄ = 1, the
default, is sticking friction: the friction stress reaches the shear flow stress k = σ₀/√3 of
each node's strain rate), or Coulomb τ = μ p_n limited by m̄ k (``Coulomb(mu, mbar)``; mbar
None: no cap). The contact covers the end
face and the lateral surface: with sticking dies the end face hardly spreads, the free surface
barrels and **folds onto the die** (the lateral surface becomes die contact); the folded part
keeps its friction. The run reports the **contact radius** (the largest radius of the nodes on
the die), the radius of the original end face (the nodes of the end face's tag on the die; the
fold is the ring between the two) and the **free-surface radius** (the bulge).

**Theory band** of the mean die pressure p̄ = F/A_h (F the die force on the whole billet,
A_h = V/h the end face of the homogeneous billet of the same volume V at the current height h:
the current diameter d_h = 2√(V/(πh)) from volume constancy, barrelling aside), over σ₀ =
√3 K (√3 ε̄̇)^m at the mean strain rate ε̄̇ = speed/h: lower edge π r_c²/A_h, σ₀ over the
actual die contact of radius r_c (a barrelled billet touches the die on less than A_h: the
frictionless homogeneous p̄ = σ₀ on A_h is not a lower edge for it, the FE dips below 1 there
after a remesh), upper edge the upper bound ``1 + m̄ d_h/(3√3 h)``
(:func:`fxcontact.theory.forming.upsetting_upper_bound`; with Tresca friction the slab method gives
the same number) for Tresca dies, and for Coulomb dies the slab estimate ``2(eˣ − x − 1)/x²``,
x = 2μR_h/h (:func:`fxcontact.theory.forming.upsetting_slab_coulomb`), or the upper bound of the cap
m̄ if lower. Force, height and strain rate are taken at the start of each increment (the
configuration its equilibrium is written on). The time step is ``dt`` × h/H₀ (increments of
the same height strain), after a start-up increment of ``startup`` × dt.

**Remeshing** (``remesh=True``, default): a new mesh of size ``h`` when a cell's quality falls
below ``remesh_min_quality`` (and before an inverting cell stops the run), finer
(``remesh_zone_h``, default h/2) around the edge of the die contact where the free surface
folds onto the die (a :class:`~fxcontact.remesh.volume.SizeZone` of points on that circle,
placed at each remesh).

Example::

    from fxcontact.processes import UpsettingCase, run_upsetting
    res = run_upsetting(UpsettingCase.quick())
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

import dolfinx.mesh
import numpy as np
from mpi4py import MPI

from fxcontact.contact.boundary import ContactBoundary
from fxcontact.contact.friction import Coulomb, Frictionless, Tresca
from fxcontact.contact.nodal import SCHEMES, NodalContact
from fxcontact.contact.penalty import Penalty
from fxcontact.io.series import pyplot
from fxcontact.materials import NortonHoff, Viscoplastic
from fxcontact.meshing import DRAWING_BAR_TAGS, drawing_bar, sector_plane_normals
from fxcontact.newton.solver import SolverOptions
from fxcontact.power import PowerBalance
from fxcontact.processes.common import check_output_dir
from fxcontact.processes.common import (CaseBase, ProcessResult, finish_run, meridian_section,
                                        numerics_columns, plot_curves, run_summary)
from fxcontact.processes.contact_laws import (UNSET, Former, Friction, contact_friction,
                                              former_beta_gap_penalty, gap_penalty, law_text)
from fxcontact.remesh.criteria import RemeshCriteria
from fxcontact.remesh.volume import SizeZone
from fxcontact.simulation import IncrementError, Simulation
from fxcontact.spaces import MixedSpace
from fxcontact.theory import forming
from fxcontact.thermal import HeatSetup
from fxcontact.tools.analytic import Plane

__all__ = ["UpsettingCase", "UpsettingSetup", "UpsettingResult", "build", "run"]

log = logging.getLogger("fxcontact.processes.upsetting")

#: a node is on a die when its gap to it is below this fraction of h (penalty penetration
#: counts as contact; a node about to touch does not)
ON_DIE = 0.02


def _friction_of(case, v: dict):
    """The dies' law of the former ``mbar``, ``mu``: Coulomb μ limited by m̄ (None: no cap),
    else Tresca m̄ (none if 0)."""
    mbar, mu = v["mbar"], v["mu"]
    if mbar is not None and not 0 <= mbar <= 1:
        raise ValueError(f"mbar must be in [0, 1] (or None with mu), got {mbar}")
    if mu is None and mbar is None:
        raise ValueError("mbar=None (no Tresca cap) needs a Coulomb mu: give mu or mbar")
    if mu is not None and not (math.isfinite(mu) and mu >= 0):
        raise ValueError(f"mu must be a finite number >= 0, got {mu}")
    if mu is not None:
        return Coulomb(mu, mbar)
    return Tresca(mbar) if mbar > 0 else Frictionless()


def _friction_values(case, law) -> Optional[dict]:
    if isinstance(law, Coulomb):
        return {"mu": law.mu, "mbar": law.mbar}
    if isinstance(law, (Tresca, Frictionless)):
        return {"mu": None, "mbar": getattr(law, "mbar", 0.0)}
    return None


@dataclass(frozen=True)
class UpsettingCase(CaseBase):
    """An upsetting case: lengths mm, stresses MPa, times s, angles degrees.

    Defaults: a hot steel billet R₀ = 10 mm, H₀/D₀ = 1.5 (H₀ = 30 mm), Norton–Hoff
    K = 50 MPa·s^m, m = 0.15, sticking dies (Tresca m̄ = 1), closing at 10 mm/s to 70 % height
    reduction, one quarter and one half of the height, remeshing on. :meth:`quick` is the
    reduced size of the tests. Bad values raise ``ValueError`` naming the field.

    **Contact** (on the end face(s) and the lateral surface; the dies are the tools ``"die"``
    and, with ``half=False``, ``"base"``):

    * ``penalty`` (:class:`fxcontact.Penalty`): by default ``Penalty(beta=100.0, gap=True)``,
      a gap stiffness k = ρ(β)/dt [MPa/mm = N/mm³], ρ(β) = β η(ε̄̇)/h [MPa·s/mm] with η the
      secant viscosity [MPa·s] at the mean strain rate speed/H₀ at the start, h [mm] and the
      first ``dt`` [s] (unless the Penalty gives them); ρ = k·dt at each increment (dt × h/H₀,
      the start-up increment: the penetration stays that of k). ``Penalty(beta=β)``: ρ at the
      strain rate estimated at the first increment and the contact's element size.
    * ``friction``: the dies' law, ``Tresca(1.0)`` (sticking) by default; ``Tresca(mbar)``
      (m̄ in [0, 1], τ = m̄ k, k [MPa] the shear flow stress at each node's strain rate),
      ``Coulomb(mu, mbar)`` (μ dimensionless, capped by m̄ k, None: no cap) or
      ``Frictionless()``; or ``{"die": law, "base": law}``. The theory reads the upper die's.
    * Former spellings, accepted for one release with a ``DeprecationWarning``: ``mbar``,
      ``mu`` (Coulomb μ capped by m̄ if ``mu`` is given, else Tresca m̄) for ``friction``,
      ``beta`` for ``penalty``.

    **How a penalty or a friction coefficient reaches its kernel.** ``case.penalty`` →
    :func:`build` (:func:`~fxcontact.processes.contact_laws.gap_penalty`: speed/H₀, h, dt) →
    ``NodalContact(penalty=)`` → ``Penalty.rho(material, dt, rate)`` at each
    ``begin_increment`` → ``penalty_kernel(S, rho, ...)``: four hops. ``case.friction`` →
    ``NodalContact(friction=)`` (one law per die) → ``friction_arguments`` at each evaluation
    (per node: law code, μ, m̄ k with k from ``begin_increment``) → ``friction_kernel(...)``:
    three hops."""

    # geometry
    R0: float = 10.0                 #: billet radius
    aspect: float = 1.5              #: H₀/D₀
    sector: float = 90.0             #: modelled sector about the axis (degrees)
    half: bool = True                #: one half of the height (mid-plane symmetry)
    # material (Norton–Hoff)
    K: float = 50.0
    m: float = 0.15
    #: a flow stress σ₀(ε̄, ε̄̇, T) (:class:`~fxcontact.Viscoplastic`) instead of K, m; the
    #: theory's σ₀ is then the law's at the homogeneous strain ln(H₀/h), the rate v/h and the
    #: billet's mean temperature
    material: Optional[Viscoplastic] = None
    #: heat (:class:`~fxcontact.HeatSetup`: the billet's thermal material and temperature, air
    #: on the free surface, the tools ``die`` and ``base``), or None
    heat: Optional[HeatSetup] = None
    #: the dies' friction law: Tresca m̄, or Coulomb μ capped by m̄ k (sticking by default)
    friction: Friction = Tresca(1.0)
    # kinematics
    speed: float = 10.0              #: closing speed of the dies (each moves at speed/2)
    reduction: float = 0.7           #: final height reduction 1 − h/H₀
    dt: float = 0.05                 #: time step at the start (then dt × h/H₀)
    startup: float = 0.05            #: first increment, a fraction of dt (friction's k)
    # numerics
    h: float = 2.0
    scheme: str = "implicit"
    #: the contact penalty: a gap stiffness k = ρ(β)/dt [MPa/mm]
    penalty: Penalty = Penalty(beta=100.0, gap=True)
    max_it: int = 60
    max_cutbacks: int = 4
    # remeshing
    remesh: bool = True
    remesh_min_quality: float = 0.2
    remesh_zone_h: Optional[float] = None   #: size at the folding edge (None: h/2)
    # former spellings of friction and penalty (one release)
    mbar: InitVar[Optional[float]] = UNSET
    mu: InitVar[Optional[float]] = UNSET
    beta: InitVar[Optional[float]] = UNSET

    FRICTION_TOOLS = ("die", "base")
    FORMER = (Former("friction", {"mbar": 1.0, "mu": None}, _friction_of, _friction_values),
              former_beta_gap_penalty(100.0))

    #: the reduced size of the tests: R₀ = 5 mm (H₀ = 15 mm), h = 1.25 mm, a 45° sector
    QUICK = dict(R0=5.0, h=1.25, dt=0.05, sector=45.0)

    def __post_init__(self, mbar, mu, beta):
        self.resolve_contact_laws(mbar=mbar, mu=mu, beta=beta)
        if not isinstance(self.tool_friction("die"), (Coulomb, Tresca, Frictionless)):
            raise ValueError(f"friction of the dies must be Coulomb, Tresca or Frictionless "
                             f"(the theory's mu or mbar), got {self.friction!r}")
        self.check_positive(("R0", "aspect", "sector", "K", "speed", "dt", "startup", "h",
                             "reduction", "remesh_min_quality"))
        if not 0 < self.m <= 1:
            raise ValueError(f"m must be in (0, 1], got {self.m}")
        if self.material is not None and not isinstance(self.material, Viscoplastic):
            raise ValueError(f"material must be a fxcontact.Viscoplastic (a flow stress; "
                             f"plain Norton-Hoff: K and m), got {self.material!r}")
        if self.heat is not None and not isinstance(self.heat, HeatSetup):
            raise ValueError(f"heat must be a fxcontact.HeatSetup, got {self.heat!r}")
        if not 0 < self.sector <= 90:
            raise ValueError(f"sector must be in (0, 90] degrees (a sector with its two "
                             f"symmetry planes), got {self.sector}")
        if not self.reduction < 0.95:
            raise ValueError(f"reduction (1 - h/H0) must be in (0, 0.95), got {self.reduction}")
        if not self.startup <= 1:
            raise ValueError(f"startup (a fraction of dt) must be in (0, 1], got {self.startup}")
        self.check_remesh_fields()
        if self.scheme not in SCHEMES:
            raise ValueError(f"scheme must be one of {SCHEMES}, got {self.scheme!r}")

    @property
    def H0(self) -> float:
        """Initial height."""
        return 2.0 * self.aspect * self.R0

    @property
    def t_end(self) -> float:
        return self.reduction * self.H0 / self.speed

    def increment_dt(self, t: float) -> float:
        """The time step at time t: ``dt`` × h/H₀, increments of the same height strain
        (the fold's landing nodes and the thinning billet ask for shorter ones at the end)."""
        return self.dt * (self.H0 - self.speed * t) / self.H0

    def friction_coefficients(self):
        """(μ, m̄) of the upper die's law for the theory: Coulomb (μ, its cap or None),
        Tresca (None, m̄), none (None, 0)."""
        law = self.tool_friction("die")
        if isinstance(law, Coulomb):
            return law.mu, law.mbar
        return None, getattr(law, "mbar", 0.0)

    def flow_stress(self, rate: float, height: float, temperature: Optional[float] = None):
        """σ₀ [MPa] of the theory at the strain rate ``rate`` [1/s]: Norton–Hoff's, or the
        ``material``'s at the homogeneous strain ln(H₀/h) and ``temperature`` [°C] (default:
        the heat's initial temperature, else the material's)."""
        if self.material is None:
            return float(forming.flow_stress(self.K, self.m, rate))
        if temperature is None:
            temperature = (self.heat.initial_temperature if self.heat is not None
                           else self.material.temperature)
        return float(self.material.flow.sigma0(math.log(self.H0 / height), rate,
                                               20.0 if temperature is None else temperature))

    def theory(self, height: float, volume: Optional[float] = None,
               contact_radius: Optional[float] = None,
               temperature: Optional[float] = None) -> dict:
        """The band of p̄/σ₀ at the current ``height`` (module docstring) for the billet's
        ``volume`` (default the initial one) and die ``contact_radius`` r_c (default d_h/2),
        σ₀ of :meth:`flow_stress` at the billet's mean ``temperature``:
        ``sigma0``, ``strain_rate``, ``area`` A_h, ``diameter`` d_h, ``lower`` (π r_c²/A_h),
        ``upper_bound`` (m̄; NaN for pure Coulomb), ``slab`` (Coulomb; NaN for Tresca) and
        ``upper`` (the band's upper edge)."""
        V = volume if volume is not None else math.pi * self.R0 ** 2 * self.H0
        area = V / height
        d = 2.0 * math.sqrt(area / math.pi)
        rate = self.speed / height
        mu, mbar = self.friction_coefficients()
        ub = forming.upsetting_upper_bound(mbar, d, height) if mbar is not None else math.nan
        slab = forming.upsetting_slab_coulomb(mu, 0.5 * d, height) if mu is not None \
            else math.nan
        upper = ub if mu is None else float(np.nanmin([slab, ub]))
        return dict(sigma0=self.flow_stress(rate, height, temperature), strain_rate=rate,
                    area=area, diameter=d, height=height,
                    lower=math.pi * contact_radius ** 2 / area if contact_radius else 1.0,
                    upper_bound=ub, slab=slab, upper=upper)


@dataclass
class UpsettingSetup:
    """A ready upsetting :class:`~fxcontact.Simulation` and its handles."""

    case: UpsettingCase
    sim: Simulation
    contact: NodalContact
    dies: list                   #: [upper die] or [upper die, lower die]
    facet_tags: object
    scale: float                 #: whole billet / model: forces (the sector)
    volume_scale: float          #: whole billet / model: volume (the sector, the half)
    dofs: int


def _die_z(case: UpsettingCase, t: float) -> float:
    """Height of the upper die at time t; the model spans [0, that] with ``half=True`` (z = 0
    the mid-plane), [H₀ − that, that] between the two dies with ``half=False``."""
    return (0.5 if case.half else 1.0) * case.H0 - 0.5 * case.speed * t


def build(case: UpsettingCase, comm=None, output_dir: Optional[str] = None,
          vtk_every: int = 0, name: str = "upsetting") -> UpsettingSetup:
    """Mesh the billet (or its sector and half), make the dies, the contact and the
    :class:`~fxcontact.Simulation` (not run): symmetry planes ``sym0``/``sym1``, the
    mid-plane (``half``), the contact ``contact`` on the end face(s) and the lateral surface,
    remeshing (``case.remesh``)."""
    comm = comm or MPI.COMM_WORLD
    H = case.H0 if not case.half else 0.5 * case.H0
    msh, _, ft = drawing_bar(comm, case.R0, H, case.h, sector=case.sector)
    rate = case.speed / case.H0
    mat = (case.material if case.material is not None
           else NortonHoff(K=case.K, m=case.m, regularization=1e-3 * rate))
    sim = Simulation(MixedSpace(msh), mat, solver_options=SolverOptions(max_it=int(case.max_it)),
                     output_dir=output_dir if vtk_every else None, name=name,
                     output_every=max(1, int(vtk_every or 1)), progress=False)
    tags = DRAWING_BAR_TAGS
    normals = sector_plane_normals(case.sector)
    for k, key in enumerate(("symmetry_0", "symmetry_1")):
        sim.add_symmetry_plane(sim.facets(ft, tags[key]), normals[key], name=f"sym{k}")
    v = 0.5 * case.speed
    dies = [Plane(point=(0.0, 0.0, H), normal=(0.0, 0.0, -1.0), velocity=(0.0, 0.0, -v),
                  name="die")]
    faces = [tags["front"], tags["lateral"]]
    if case.half:
        sim.add_velocity_bc(sim.facets(ft, tags["back"]), 0.0, 2)
    else:
        dies.append(Plane(point=(0.0, 0.0, 0.0), normal=(0.0, 0.0, 1.0),
                          velocity=(0.0, 0.0, v), name="base"))
        faces.append(tags["back"])
    # by default a gap stiffness k = ρ(β)/dt at the mean strain rate of the start
    penalty = gap_penalty(case.penalty, rate, case.h, case.dt)
    contact = NodalContact(ContactBoundary(sim.space, ft, faces), dies, scheme=case.scheme,
                           friction=contact_friction(case.friction), name="contact",
                           penalty=penalty)
    sim.add_contributor(contact)
    if case.heat is not None:   # the end face(s) and the side are free (symmetry: insulated)
        case.heat.attach(sim, ft, faces, [d.name for d in dies])
    s = UpsettingSetup(case, sim, contact, dies, ft, 360.0 / case.sector,
                       360.0 / case.sector * (2.0 if case.half else 1.0),
                       sim.space.W.dofmap.index_map.size_global * sim.space.W.dofmap.index_map_bs)
    if case.remesh:
        sim.set_remeshing(RemeshCriteria(min_quality=case.remesh_min_quality), size=case.h,
                          zones=lambda _sim: _edge_zones(s))
    return s


def _local_radii(s: UpsettingSetup):
    """(r, on the die, on the end face's tag) of the local vertices (the upper die; the model
    is symmetric)."""
    sim, c = s.sim, s.case
    x = sim.vertex_positions()
    r = np.hypot(x[:, 0], x[:, 1])
    on = _die_z(c, sim.t) - x[:, 2] < ON_DIE * c.h
    ft = getattr(sim, "_remesh_facet_tags", s.facet_tags)   # the new mesh's after a remesh
    msh = sim.mesh
    face = dolfinx.mesh.compute_incident_entities(
        msh, ft.indices[ft.values == DRAWING_BAR_TAGS["front"]], msh.topology.dim - 1, 0)
    top = np.zeros(len(x), bool)
    top[face[face < len(x)]] = True
    return r, on, top


def radii(s: UpsettingSetup) -> dict:
    """``contact``: the largest radius of the nodes on the upper die; ``face``: of those of
    the original end face (its tag) on the die — the fold is the ring between the two;
    ``free``: the largest radius of the body (the bulge) (collective)."""
    r, on, top = _local_radii(s)
    loc = np.array([np.max(r[on], initial=0.0), np.max(r[on & top], initial=0.0),
                    np.max(r, initial=0.0)])
    out = np.max(s.sim.comm.allgather(loc), axis=0)
    return dict(contact=float(out[0]), face=float(out[1]), free=float(out[2]))


def _edge_zones(s: UpsettingSetup) -> list:
    """The circle where the free surface meets the die (at the contact radius; the end face's
    radius before contact), meshed with ``remesh_zone_h`` (collective)."""
    c = s.case
    rc = radii(s)["contact"] or c.R0
    th = np.radians(np.linspace(0.0, c.sector, max(8, int(c.sector / 3))))
    z = _die_z(c, s.sim.t)
    zs = [z] if c.half else [z, c.H0 - z]
    pts = np.array([[rc * math.cos(a), rc * math.sin(a), z] for z in zs for a in th])
    return [SizeZone(h=c.remesh_zone_h or 0.5 * c.h, points=pts)]


@dataclass
class UpsettingResult(ProcessResult):
    """The outcome of :func:`run` (:class:`~fxcontact.processes.common.ProcessResult`) and the
    upsetting's own values. The rows have per increment the height reduction and height at its
    start, the die force ``force`` (whole billet, N), ``p_mean`` = p̄/σ₀ on the homogeneous
    end face A_h, ``p_face`` = F/(π r_contact² σ₀) on the die contact at the start, the band
    ``lower``/``upper`` and ``in_band``, the radii ``r_contact``/``r_face``/``r_free`` at its
    end and the numerics."""

    case: Optional[UpsettingCase] = None
    reduction: float = 0.0             #: height reduction reached
    radii: dict = dataclasses.field(default_factory=dict)   #: at the end (:func:`radii`)
    remeshes: int = 0
    band_from: Optional[int] = None    #: first row from which every row is in the band
    out_of_band: list = dataclasses.field(default_factory=list)   #: rows out of it

    def report(self) -> str:
        """A summary for the console."""
        c = self.case
        fr = ("sticking (Tresca mbar 1)" if c.friction == Tresca(1.0)
              else law_text(c.friction))
        lines = [
            f"upsetting R0 {c.R0:g} mm, H0/D0 {c.aspect:g} (H0 {c.H0:g} mm), {fr} dies closing "
            f"at {c.speed:g} mm/s, {_material_text(c)}; {'half height, ' if c.half else ''}"
            f"sector {c.sector:g} deg; h {self.h:.3g} mm, {self.dofs} dofs, {self.ranks} "
            f"rank(s), remeshing {'on' if c.remesh else 'off'}",
            f"status: {self.status} {self.message[:200]}; {self.increments} increments to "
            f"t = {self.time:.4g} s: height reduction {100 * self.reduction:.1f} % "
            f"(target {100 * c.reduction:.0f} %), {self.remeshes} remesh(es)"]
        if self.history:
            q = self.history[-1]
            rd = self.radii
            lines += [
                f"last increment (from {100 * q['reduction']:.1f} %): die force "
                f"{q['force'] / 1e3:.2f} kN, p/sigma0 {q['p_mean']:.3f} (homogeneous face "
                f"d_h {q['diameter']:.2f} mm; on the contact {q['p_face']:.3f}), band "
                f"[{q['lower']:.3f}, {q['upper']:.3f}]",
                f"radii at the end: die contact {rd['contact']:.2f} mm, original end face "
                f"{rd['face']:.2f} mm (fold {rd['contact'] - rd['face']:.2f} mm), free surface "
                f"{rd['free']:.2f} mm; homogeneous {self.history[-1]['r_homogeneous']:.2f} mm",
                "in the band " + (f"from increment {self.band_from}" if self.band_from is not None
                                  else "never to the end") +
                (f"; out of it: {self.out_of_band}" if self.out_of_band else "")]
            if "heat_T_mean" in q:
                tot = {k: sum(r[f"heat_{k}"] for r in self.history) / 1e3
                       for k in ("generated", "friction", "tools", "air", "radiation",
                                 "stored", "residual")}
                lines.append(
                    f"temperature at the end: {q['heat_T_min']:.0f} (chilled at the die) / mean "
                    f"{q['heat_T_mean']:.0f} / max {q['heat_T_max']:.0f} °C; heat of the model "
                    f"[J]: plastic work {tot['generated']:.3g} + friction {tot['friction']:.3g} "
                    f"+ tools {tot['tools']:.3g} + air {tot['air'] + tot['radiation']:.3g} = "
                    f"stored {tot['stored']:.3g} (balance residual {tot['residual']:.1e})")
            lines += self.numerics_lines()
        return self.report_text(lines)


def run(case: UpsettingCase, comm=None, output_dir: Optional[str] = None,
        pictures: bool = True, vtk_every: int = 0) -> UpsettingResult:
    """Upset to ``case.reduction`` (a start-up increment of ``startup`` × dt first: the
    Tresca k of the nodes comes from the increment's predictor, the rest state in the first
    increment). With ``output_dir``: ``upsetting_diagnostics.csv``, the pictures
    (``upsetting_section.png``: the deformed θ = 0 section, equivalent strain, the fold on the
    die; ``upsetting_pressure.png``: p̄/σ₀ against the band and the radii) and, with
    ``vtk_every``, the VTK series ``upsetting.pvd``."""
    comm = comm or MPI.COMM_WORLD
    check_output_dir(output_dir, comm)
    s = build(case, comm, output_dir, vtk_every)
    sim, contact = s.sim, s.contact
    balance = PowerBalance(sim, [contact])
    volume = [sim.volume()]

    def row(r):
        t0 = r["time"] - r["dt"]
        h0 = case.H0 - case.speed * t0
        F = s.scale * r["die_force_z"]
        rc0 = radii_start[-1]
        T = temperature[-1]
        temperature.append(r.get("heat_T_mean"))
        th = case.theory(h0, s.volume_scale * volume[-1], rc0, T)
        p = F / th["area"] / th["sigma0"]
        rd = radii(s)
        radii_start.append(rd["contact"])
        volume.append(sim.volume())
        p_in = (r["die_force_z"] - r.get("base_force_z", 0.0)) * 0.5 * case.speed
        return dict(
            increment=r["increment"], time=r["time"], dt=r["dt"], reduction=1.0 - h0 / case.H0,
            height=h0, force=F, p_mean=p,
            p_face=F / (math.pi * rc0 ** 2) / th["sigma0"] if rc0 > 0 else math.nan,
            sigma0=th["sigma0"], diameter=th["diameter"], lower=th["lower"], upper=th["upper"],
            in_band=bool(th["lower"] <= p <= th["upper"]),
            r_contact=rd["contact"],
            r_face=rd["face"], r_free=rd["free"],
            r_homogeneous=math.sqrt(s.volume_scale * volume[-1] / (math.pi * _height(case, r["time"]))),
            penetration=r["contact_penetration_true"], contact_nodes=r["contact_nodes"],
            remesh=r["remesh"], **numerics_columns(r), **balance(r, p_in),
            **{k: v for k, v in r.items() if k.startswith("heat_")})

    def progress(q):
        if comm.rank == 0:
            log.info("upsetting: %.1f %%, p/sigma0 %.3f in [%g, %.3f], r contact %.2f / free "
                     "%.2f mm, %d Newton its, %d remeshes", 100 * q["reduction"], q["p_mean"],
                     q["lower"], q["upper"], q["r_contact"], q["r_free"],
                     q["newton_iterations"], q["remesh"])

    radii_start = [case.R0]
    temperature = [None]     # the billet's mean temperature at each increment's start
    wall0 = time.perf_counter()
    rows, status, message = [], "completed", ""
    dt = case.startup * case.dt
    while sim.t < case.t_end - 1e-9 * case.dt:
        left = case.t_end - sim.t
        try:
            res = sim.step(left if left < 1.5 * dt else dt, max_cutbacks=int(case.max_cutbacks))
        except IncrementError as err:   # MeshInversionError included
            status, message = "failed", str(err)
            break
        rows.append(row(res.row))
        progress(rows[-1])
        dt = case.increment_dt(sim.t)
    out = UpsettingResult(case=case, status=status, message=message, history=rows,
                          dofs=s.dofs, h=case.h, wall=time.perf_counter() - wall0, time=sim.t,
                          ranks=comm.size, increments=len(rows),
                          reduction=1.0 - _height(case, sim.t) / case.H0, radii=radii(s),
                          remeshes=len(sim.remeshes))
    if rows:
        out_band = [i for i, q in enumerate(rows) if not q["in_band"]]
        out = dataclasses.replace(
            out, theory=case.theory(rows[-1]["height"]), out_of_band=out_band,
            band_from=(out_band[-1] + 1 if out_band else 0)
            if not out_band or out_band[-1] + 1 < len(rows) else None,
            power_balance=rows[-1]["power_balance"],
            power_balance_penalty=rows[-1]["power_balance_penalty"], **run_summary(rows))
    return finish_run(comm, sim, out, output_dir, "upsetting", pictures, vtk_every,
                      lambda: _pictures(comm, s, out, output_dir))


def _material_text(c: UpsettingCase) -> str:
    if c.material is None:
        return f"K {c.K:g} m {c.m:g}"
    heat = "" if c.heat is None else (f", billet at {c.heat.initial_temperature:g} °C, "
                                      f"tools {sorted(c.heat.tools or {})}")
    return f"{type(c.material.flow).__name__} flow stress{heat}"


def _height(case: UpsettingCase, t: float) -> float:
    return case.H0 - case.speed * t


def _pictures(comm, s: UpsettingSetup, res: UpsettingResult, out: str):
    """The deformed θ = 0 section (equivalent strain; with heat, the temperature too) with the
    die, the initial outline and the fold (the free surface folded onto the die, between the
    original end face's radius and the contact radius); p̄/σ₀ against the band and the radii
    over the reduction (rank 0 draws; every rank returns the paths)."""
    sim, c = s.sim, res.case
    ft = getattr(sim, "_remesh_facet_tags", s.facet_tags)
    fields = [sim.strain]
    if sim.cell_temperature is not None:
        T = dolfinx.fem.Function(sim.space.DG0, name="temperature")
        T.x.array[:] = sim.cell_temperature
        fields.append(T)
    zr, values = meridian_section(comm, sim, ft, DRAWING_BAR_TAGS["symmetry_0"], tuple(fields))
    names = ["upsetting_section.png", "upsetting_temperature.png"][: len(fields)]
    paths = [os.path.join(out, n) for n in names] + [os.path.join(out, "upsetting_pressure.png")]
    if comm.rank != 0:
        return paths
    plt = pyplot()
    for k, (vals, path) in enumerate(zip(values, paths)):
        _section_picture(plt, c, res, s, zr, vals, path, temperature=k == 1)
    _pressure_picture(plt, c, res, paths[-1])
    return paths


def _section_picture(plt, c, res, s, zr, vals, path, temperature=False):
    from matplotlib.collections import PolyCollection
    sim = s.sim
    rd, zd = res.radii, _die_z(c, sim.t)
    z0 = 0.0 if c.half else c.H0 - zd
    rz = zr[..., ::-1]
    H = 0.5 * c.H0 if c.half else c.H0
    xr, yr = 1.25 * rd["free"], (z0 - 0.5, max(zd, H) + 0.25 * (zd - z0) + 1.5)
    fig, ax = plt.subplots(figsize=(9, 0.75 * 9 * (yr[1] - yr[0]) / xr + 1.2))
    pc = PolyCollection(rz, array=vals, cmap="inferno" if temperature else "viridis",
                        edgecolors="k", linewidths=0.15)
    ax.add_collection(pc)
    fig.colorbar(pc, ax=ax, label="temperature [°C]" if temperature else "equivalent strain",
                 fraction=0.04, pad=0.01)
    ax.plot([0, c.R0, c.R0, 0], [H, H, 0, 0], "k--", lw=1,
            label=f"initial billet (H0/D0 {c.aspect:g})")
    tools = (c.heat.tools or {}) if c.heat is not None else {}
    for z, name in ([(zd, "die")] if c.half else [(zd, "die"), (z0, "base")]):
        tool = f"{name}" + (f" at {tools[name].temperature:g} °C" if name in tools else "")
        ax.plot([0, 1.2 * rd["free"]], [z, z], "k-", lw=2.5)
        ax.annotate(tool, (1.2 * rd["free"], z), (1.0 * rd["free"], z + 0.3), fontsize=8)
        ax.plot([rd["face"], rd["contact"]], [z, z], "r-", lw=5, solid_capstyle="butt",
                label="free surface folded onto the die" if z == zd else None)
    ax.annotate(f"end face r = {rd['face']:.1f}", (rd["face"], zd), (rd["face"] * 0.4,
                zd + 0.06 * (zd - z0) + 0.5), arrowprops=dict(arrowstyle="->"), fontsize=8)
    ax.annotate(f"contact r = {rd['contact']:.1f}", (rd["contact"], zd),
                (rd["contact"] * 0.75, zd + 0.12 * (zd - z0) + 1.0),
                arrowprops=dict(arrowstyle="->"), fontsize=8)
    ax.set_xlim(0, xr)
    ax.set_ylim(*yr)
    ax.set_aspect("equal")
    ax.set_xlabel("r [mm]")
    ax.set_ylabel("z [mm]" + (" (mid-plane z = 0)" if c.half else ""))
    ax.legend(loc="upper right", fontsize=8)
    what = (f"temperature {np.min(vals):.0f}–{np.max(vals):.0f} °C (billet at "
            f"{c.heat.initial_temperature:g} °C)" if temperature else "equivalent strain")
    ax.set_title(f"Upsetting to {100 * res.reduction:.0f} % height reduction, "
                 f"{'sticking' if c.friction == Tresca(1.0) else 'friction'} dies, "
                 f"{res.remeshes} remeshes\nθ = 0 section, {what}; free-surface "
                 f"radius {rd['free']:.1f} mm", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def _pressure_picture(plt, c, res, f2):
    hist = res.history
    red = [100 * q["reduction"] for q in hist]
    red_end = [100 * (1.0 - _height(c, q["time"]) / c.H0) for q in hist]
    fig, (a1, a2) = plt.subplots(2, 1, figsize=(8, 8))
    plot_curves(a1, red, [([q["p_mean"] for q in hist], "b.-", "FE p̄/σ₀ (homogeneous face)"),
                          ([q["p_face"] for q in hist], "c.:", "FE F/(π r_contact² σ₀)"),
                          ([q["upper"] for q in hist], "k-", "upper bound (d_h, h)"),
                          ([q["lower"] for q in hist], "k--",
                           "lower: σ₀ on the die contact")], ylabel="p̄ / σ₀")
    plot_curves(a2, red_end, [([q["r_contact"] for q in hist], "r.-", "die contact radius"),
                          ([q["r_face"] for q in hist], "m.-", "original end face"),
                          ([q["r_free"] for q in hist], "g.-", "free surface (bulge)"),
                          ([q["r_homogeneous"] for q in hist], "k:", "homogeneous")],
                ylabel="radius [mm]")
    for i, q in enumerate(hist[1:], 1):
        if q["remesh"] != hist[i - 1]["remesh"]:      # after the increment i − 1
            a1.axvline(red[i], color="0.7", lw=0.8)
            a2.axvline(red_end[i - 1], color="0.7", lw=0.8)
    a1.set_xlabel("height reduction at the increment's start [%] (grey: remeshes)")
    a2.set_xlabel("height reduction [%]")
    fig.tight_layout()
    fig.savefig(f2, dpi=110)
    plt.close(fig)
