"""The ring-rolling case (THEORY §12.1, §14.4): the ring, the mill, the material, the friction
per tool, the kinematics and the numerics of :mod:`fxcontact.processes.ring_rolling`, and the
theory of its pass.

**Material.** The thesis's academic cases print Norton–Hoff K = 1900 MPa·s^m, m = 0.14 for a
hot-rolled 42CrMo4 ring (:data:`K_THESIS`). Taken literally that is σ₀ ≈ 4070 MPa at the
bite's strain rate (~2.6 1/s in case 2): the strength of a hardened steel at room temperature,
not of a steel rolled hot. Hot compression tests of 42CrMo (Quan, Tong, Luo & Zhou, Comput.
Mater. Sci. 2010, doi:10.1016/j.commatsci.2010.07.021: 850–1075 °C, 0.01–10 1/s; Metals 11
(2021) 1614, doi:10.3390/met11101614: 1200–1350 °C) put its flow stress at hot-rolling
temperatures and rates in the order of 100 MPa, not thousands. :data:`K_HOT` = 50 MPa·s^m (the
same m; a value of that order, not a fit to those data) gives σ₀ ≈ 107 MPa at the bite of
case 2 and is the default of
:class:`RingRollingCase`; the named constructors :meth:`RingRollingCase.case1` and
:meth:`~RingRollingCase.case2` keep the thesis's K for the comparison with the thesis. With
Norton and Tresca-limited Coulomb friction and β-scaled penalties the velocity field does not
depend on K: K scales the forces and torques only.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import InitVar, dataclass
from typing import Optional

import numpy as np

from fxcontact.contact.friction import Norton
from fxcontact.contact.penalty import Penalty
from fxcontact.idle import IDLE_METHODS
from fxcontact.materials import Viscoplastic
from fxcontact.processes.contact_laws import UNSET, Friction
from fxcontact.processes.monitor import RunNumerics, is_number
from fxcontact.processes.common import mean_norton_hoff
from fxcontact.processes.ring_rolling import mill as ring_mill
from fxcontact.theory import forming
from fxcontact.thermal import HeatSetup

__all__ = ["RingRollingCase", "theory", "K_THESIS", "K_HOT", "QUICK", "TOOLS", "UPDATES"]


#: the thesis's Norton–Hoff consistency [MPa s^m] as printed (σ₀ ≈ 4070 MPa: implausible hot)
K_THESIS = 1900.0
#: a hot-working consistency of 42CrMo4 at about 1100 °C [MPa s^m] (σ₀ ≈ 107 MPa, case 2)
K_HOT = 50.0
#: the tools' discretisation: analytic cylinders, or flat facets of the same cylinders
TOOLS = ("analytic", "faceted")
#: the configuration updates
UPDATES = ("cylindrical", "cartesian")
#: the reduced size of the tests: a coarse ring, a fifth of a revolution
QUICK = dict(n_theta=100, n_r=3, n_z=1, increments_per_rev=50, revolutions=0.2)


@dataclass(frozen=True)
class RingRollingCase(RunNumerics):
    """Radial ring rolling (lengths mm, stresses MPa, times s). The defaults: the thesis's
    case 2 on a mill of industrial proportion (THEORY §14.4) with a hot-working flow stress
    (:data:`K_HOT`, see the module): ring R = 100, r = 60, H = 40; main roll R₁ = 150 at
    60 rpm, mandrel R₂ = 40 fed at 1.5 mm/s (1 mm per revolution), guide rolls R_g = 40 at
    ±60°; Coulomb μ = 0.3 limited by Tresca m̄ = 0.6 on the main roll and the mandrel; mesh
    160 × 4 × 2, 60 increments per revolution, two revolutions. :meth:`case1`, :meth:`case2`:
    the thesis's cases with its K; :meth:`quick`: the reduced size of the tests.

    **Contact** ``"mill"``: ``penalty`` ρ [MPa·s/mm] (β = 1e3; was ``gap_stiffness`` k [MPa/mm]);
    ``friction`` tool → law (μ, m̄, α_f dimensionless; was ``main_friction``, ``mandrel_friction``).
    **How a penalty or a friction coefficient reaches its kernel**: case → ``NodalContact`` →
    ``Penalty.rho`` / the per-node law arrays → ``penalty_kernel`` / ``friction_kernel``."""

    # the ring
    R: float = 100.0                #: outer radius
    r: float = 60.0                 #: bore radius
    H: float = 40.0                 #: height
    # the mill
    R1: float = 150.0               #: main roll radius
    R2: float = 40.0                #: mandrel radius
    Rg: float = 40.0                #: guide roll radius
    guide_angle: float = 60.0       #: the guide rolls' angle from the mill line [degrees]
    guide_clearance: float = 0.3    #: gap kept between a guide roll and the ring
    initial_bite: float = 0.05      #: both rolls start this far into the ring
    # the material (Norton–Hoff)
    K: float = K_HOT
    m: float = 0.14
    #: a flow stress σ₀(ε̄, ε̄̇, T) (:class:`~fxcontact.Viscoplastic`: hardening, temperature,
    #: a table) in place of K, m; None: Norton–Hoff K, m
    material: Optional[Viscoplastic] = None
    #: heat (:class:`~fxcontact.HeatSetup`: the ring's thermal material and temperature, air
    #: on its outer, bore and top faces, ``tools`` by name: main_roll, mandrel, guide1, guide2,
    #: cone); None: isothermal
    heat: Optional[HeatSetup] = None
    friction: Friction = ring_mill.DEFAULT_FRICTION     #: tool name -> law
    mu_bite: float = 0.3            #: μ of the bite-in limit of the feed window
    # the kinematics
    rpm: float = 60.0               #: main roll speed
    feed_speed: float = 1.5         #: mandrel feed [mm/s]
    idle_method: str = "auto"       #: how the idle ω is found (IdleRotation: bordered, outer)
    idle_guides: bool = False       #: the guide rolls idle too, with the mandrel's friction
    cones: bool = False             #: axial cone rolls
    cone_half_angle: float = 30.0   #: [degrees]
    cone_speed: Optional[float] = None   #: opening speed of the axial gap [mm/s]
    # the numerics
    n_theta: int = 160              #: elements around
    n_r: int = 4                    #: across the wall
    n_z: int = 2                    #: through the half height
    increments_per_rev: int = 60
    revolutions: float = 2.0
    update: str = "cylindrical"     #: one of :data:`UPDATES`
    tools: str = "analytic"         #: one of :data:`TOOLS`
    facet_size: Optional[float] = None   #: faceted tools: facet width (default: the spacing)
    volume_correction: str = "none"
    penalty: Penalty = Penalty()     #: the contact's (β = 1e3 by default)
    sticky_gap: float = 0.0
    max_it: int = 60                #: Newton iterations per solve
    newton_rtol: float = 1e-9       #: Newton's relative residual tolerance
    # remeshing (off by default; ring_mill.set_ring_remeshing): a new mesh, finer over the arc
    # remesh_arc [degrees] in front of each gap (ring_mill.BiteZones), made when the ring has
    # turned by about 3/4 of it or a cell's quality falls below remesh_min_quality; with
    # remesh_min_across = n also when a bite is spanned by fewer than n elements, the zones then on
    # the rolled surfaces of size L/n (the bite's length) and the ring remeshed at the start
    remesh: bool = False
    remesh_min_quality: float = 0.15
    remesh_min_across: Optional[float] = None
    remesh_zone_h: Optional[float] = None
    remesh_arc: float = 90.0
    # (RunNumerics: scheme, line_search, penalty_continuation, active_set_prediction,
    # newton_ftol, max_increments)
    main_friction: InitVar[Optional[tuple]] = UNSET     # former spellings (one release)
    mandrel_friction: InitVar[Optional[tuple]] = UNSET
    gap_stiffness: InitVar[Optional[float]] = UNSET
    FRICTION_TOOLS, FORMER = ring_mill.MILL_TOOLS, ring_mill.FORMER

    def __post_init__(self, main_friction, mandrel_friction, gap_stiffness):
        super().__post_init__()
        self.resolve_contact_laws(main_friction=main_friction, gap_stiffness=gap_stiffness,
                                  mandrel_friction=mandrel_friction)
        for key in ("R", "r", "H", "R1", "R2", "Rg", "K", "revolutions", "rpm", "mu_bite"):
            v = getattr(self, key)
            if not (is_number(v) and v > 0):
                raise ValueError(f"{key} must be a finite number > 0, got {v!r}")
        if not self.R2 < self.r < self.R:
            raise ValueError(f"need mandrel R2 < bore r < outer R, got {self.R2}, {self.r}, "
                             f"{self.R}")
        if not (is_number(self.m) and 0.0 < self.m <= 1.0):
            raise ValueError(f"m (strain-rate sensitivity) must be in (0, 1], got {self.m!r}")
        if not is_number(self.feed_speed):
            raise ValueError(f"feed_speed must be a finite number, got {self.feed_speed!r}")
        for key in ("n_theta", "n_r", "n_z", "increments_per_rev", "max_it"):
            v = getattr(self, key)
            if not (isinstance(v, (int, np.integer)) and v >= 1):
                raise ValueError(f"{key} must be an integer >= 1, got {v!r}")
        if self.update not in UPDATES:
            raise ValueError(f"update must be one of {UPDATES}, got {self.update!r}")
        if self.tools not in TOOLS:
            raise ValueError(f"tools must be one of {TOOLS}, got {self.tools!r}")
        if self.idle_method not in IDLE_METHODS:
            raise ValueError(f"idle_method must be one of {IDLE_METHODS}, got "
                             f"{self.idle_method!r}")
        if not (is_number(self.cone_half_angle) and 0.0 < self.cone_half_angle < 60.0):
            raise ValueError(f"cone_half_angle must be in (0, 60) degrees, got "
                             f"{self.cone_half_angle!r}")
        if self.cones and self.cone_speed is None:
            raise ValueError("cones need cone_speed (the opening speed of the axial gap, mm/s; "
                             "case1() has 0.4)")
        if not (0 < self.remesh_min_quality < 1 and 0 < self.remesh_arc < 360
                and (self.remesh_min_across or 0) >= 0
                and (self.remesh_zone_h is None or self.remesh_zone_h > 0)):
            raise ValueError("remesh_min_quality must be in (0, 1), remesh_arc in (0, 360) "
                             "degrees, remesh_min_across >= 0 and remesh_zone_h > 0 (or None)")
        if self.material is not None and not isinstance(self.material, Viscoplastic):
            raise ValueError(f"material must be a fxcontact.Viscoplastic (a flow stress; "
                             f"plain Norton-Hoff: K and m), got {self.material!r}")
        if self.heat is not None and not isinstance(self.heat, HeatSetup):
            raise ValueError(f"heat must be a fxcontact.HeatSetup, got {self.heat!r}")
        if self.cone_speed is not None and not is_number(self.cone_speed):
            raise ValueError(f"cone_speed must be a finite number, got {self.cone_speed!r}")

    @classmethod
    def case1(cls, **changes) -> "RingRollingCase":
        """The thesis's case 1 (its K = 1900 literally): viscoplastic friction α_f = 0.5,
        q = 0.15 on the main roll, frictionless mandrel, 20 rpm, feed 1.5 mm/s (3 mm per
        revolution), cone rolls opening at 0.4 mm/s (when ``cones=True``)."""
        return cls(K=K_THESIS, rpm=20.0, friction={"main_roll": Norton(0.5, 0.15)},
                   cone_speed=0.4).replace(**changes)

    @classmethod
    def case2(cls, **changes) -> "RingRollingCase":
        """The thesis's case 2 (its K = 1900 literally): Coulomb μ = 0.3 limited by Tresca
        m̄ = 0.6 on the main roll and the mandrel, 60 rpm, feed 1.5 mm/s (1 mm per
        revolution)."""
        return cls(**{**dict(K=K_THESIS), **changes})

    def quick(self) -> "RingRollingCase":
        """This case at the reduced size of the tests: ring 100 × 3 × 1, 50 increments per
        revolution, 0.2 revolution."""
        return dataclasses.replace(self, **QUICK)

    @property
    def omega_main(self) -> float:
        """The main roll's angular speed [rad/s]."""
        return self.rpm * 2.0 * math.pi / 60.0

    @property
    def t_rev(self) -> float:
        """One ring revolution at the main roll's surface speed (no slip) [s]."""
        return 2.0 * math.pi * self.R / (self.omega_main * self.R1)

    @property
    def thesis_flow_stress_note(self) -> str:
        """A warning when K is the thesis's printed value (implausible for a hot ring)."""
        if self.material is None and self.K >= 0.5 * K_THESIS:
            return (f"K = {self.K:g} MPa s^m is the thesis's value taken literally: hot "
                    f"42CrMo4 (1050-1150 C) flows at about 80-130 MPa (K = K_HOT = "
                    f"{K_HOT:g}); the forces scale with K")
        return ""


def theory(case: RingRollingCase) -> dict:
    """The ring-rolling theory of the pass (:mod:`fxcontact.theory.forming`, THEORY §14.4): the feed
    per revolution and its window, the bite's contact length, its strain rate, σ₀ there and the
    2kHLQ radial force estimate."""
    v_s = case.omega_main * case.R1
    dh = case.feed_speed * case.t_rev
    L = forming.ring_rolling_contact_length(dh, case.R1, case.R2, case.R, case.r)
    B0 = case.R - case.r
    # representative strain rate of the bite: wall strain dh/B over the bite time L/v_s
    rate = dh / B0 * v_s / L
    # plane-strain thinning of the wall: the equivalent strain of one revolution
    strain_rev = 2.0 / math.sqrt(3.0) * math.log(B0 / (B0 - dh)) if dh < B0 else math.inf
    K, m = case.K, case.m
    if case.material is not None:   # the mean flow stress over the run's strain at the bite
        T = case.heat.initial_temperature if case.heat is not None else None
        K, m = mean_norton_hoff(case.material, max(strain_rev * case.revolutions, 1e-6),
                                rate, T)
    sigma0 = float(forming.flow_stress(K, m, rate))
    est = forming.ring_rolling_force(sigma0 / math.sqrt(3.0), case.H, L, B0)
    return dict(feed_per_rev=dh, window=forming.ring_rolling_feed_window(
        case.R1, case.R2, case.R, case.r, case.mu_bite), contact_length=L,
        strain_rate_bite=rate, sigma0=sigma0, force_estimate=est["force"], Q=est["Q"],
        K=K, m=m, strain_per_rev=strain_rev)
