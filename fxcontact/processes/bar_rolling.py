"""Three-roll rolling of a round bar to steady state (long-product rolling, THEORY §12.2).

The bar axis is z, rolling towards +z. The roll axes lie in the exit plane z = z_r; roll k sits
at the angle θ_k about the bar axis, its axis along ``(−sin θ_k, cos θ_k, 0)`` at the distance
``d`` from the bar axis, turning so that its surface nearest the bar moves towards +z.

**The pass.** Each roll is a :meth:`fxcontact.RevolvedProfile.grooved_roll`: a barrel with a
circular groove of radius ``r_g = R1`` spanning ±β (``groove_angle``) about the roll's
direction, its centre on the bar axis (``d = R_w + r_g``, ``R_w`` the groove-bottom radius
``roll_radius``): the inscribed radius of the roll gap is R1. Beside the grooves the barrel
shoulders of two rolls meet at the corner radius ``r_c = 2 r_g cos β``; the pass area is
``A_pass = 3 [β r_g² + p² (tan 60° − tan β)]`` with ``p = r_g cos β`` (with rounded groove
edges, ``edge_radius``, it is computed from the rolls' outline). The rolling speed is the
peripheral speed at the groove bottom.

**Models.** ``model="third"``: the sector 0 ≤ θ ≤ 120° with the roll at 60° and two inclined
symmetry planes (the third holds one whole roll: per-roll values are the third's, the stand's
torque and power 3 ×); ``"full"``: the whole bar and three rolls. ``mesh="symmetric"`` meshes
the third mirror-symmetric and the whole bar of its turned copies (the two models then have the
same discrete solution); ``"gmsh"``: plain meshes.

**Start.** The bar's front is shaped to the pass (``nose`` × the bite length inside the bite); a
pusher moves it until the rolls grip it (:class:`~fxcontact.processes.monitor.SteadyMonitor`).
The first increment is solved with the strain-rate sensitivity ``m_start`` (Newton from rest
with m = 0.03 stalls), the following ones with m.

**Hot rolling** (``material``, ``heat``): a flow stress σ₀(ε̄, ε̄̇, T)
(:class:`~fxcontact.Viscoplastic`, its regularisation as given) instead of K, m — solved from the
first increment with its own rate sensitivity (no ``m_start``: its pieces are per cell and set
from the state before each increment) — and a :class:`~fxcontact.HeatSetup`: air on the bar's
lateral surface (where no roll touches it), its front and back, the tools ``roll0`` (…) and
``pusher``; the symmetry planes of the third are insulated. :meth:`BarRollingCase.theory`: the
pass's homogeneous strain ln(A0/A_pass), σ0 (the material's mean over it) and the ideal work of
the stand.

Measured per increment: per roll the radial force, axial force and torque, the exit section's
area (exact plane cut of the tetrahedra ``exit_offset`` × the bite length past the roll axes),
the power balance. At steady state: the fill of the pass and the exit section's outline.
"""

from __future__ import annotations

import csv
import dataclasses
import math
import os
from dataclasses import InitVar, dataclass, field
from typing import List, Optional

import dolfinx.fem
import numpy as np
from mpi4py import MPI

import fxcontact as fx
from fxcontact import compat
from fxcontact.io.series import pyplot
from fxcontact.meshing import DRAWING_BAR_TAGS, drawing_bar, sector_plane_normals
from fxcontact.power import PowerBalance
from fxcontact.processes.common import check_output_dir
from fxcontact.processes.common import (check_material_heat, gather, heat_columns, heat_lines,
                                        material_text, mean_norton_hoff, theory_temperature)
from fxcontact.processes.contact_laws import UNSET, Former, Friction, contact_friction
from fxcontact.processes.monitor import (RunNumerics, SteadyMonitor, SteadyRun, StopRules,
                                         is_number, window_increments)

__all__ = ["BarRollingCase", "BarRollingSetup", "BarRollingResult", "build", "run", "compare",
           "pass_geometry", "stand_pass", "make_rolls", "pass_outline", "pass_outline_of_rolls",
           "pass_radius", "polygon_area", "section_area", "section_outline", "N_ROLLS"]

N_ROLLS = 3

#: the reduced size of the tests: coarse elements, large increments, a short bar
QUICK = dict(h=16.0, dt=20.0e-3, length_factor=2.6, settle=0.6, window=0.5)


def _positive_field(name, value):
    if not (_number(value) and value > 0):
        raise ValueError(f"{name} must be a finite number > 0, got {value!r}")


def _friction_of(case, v: dict):
    """The rolls' law of the former ``alpha_f``, ``q``: Norton (K of the material)."""
    _positive_field("alpha_f", v["alpha_f"])
    return fx.Norton(v["alpha_f"], v["q"])


def _friction_values(case, law) -> Optional[dict]:
    if isinstance(law, fx.Norton) and law.K is None:
        return {"alpha_f": law.alpha_f, "q": law.q}
    return None


def _penalty_of(case, v: dict):
    _positive_field("beta", v["beta"])
    return fx.Penalty(beta=v["beta"])


def _penalty_values(case, p) -> Optional[dict]:
    return {"beta": p.beta} if p.beta is not None else None


@dataclass(frozen=True)
class BarRollingCase(RunNumerics):
    """One pass of a three-roll stand; the defaults are the thesis case (lengths mm, stresses
    MPa, times s): a round bar R0 = 58 → R1 = 48 mm, groove half-angle 50°, groove-bottom roll
    radius 180 mm, groove edges rounded 5 mm; Norton–Hoff K = 50 MPa·s^m, m = 0.03; Norton
    friction α_f = 0.3, q = 0.15; 100 mm/s; 9 mm elements, dt = 1 ms. :meth:`quick` is the
    reduced size of the tests.

    **Contact** (the rolls ``"roll0"`` (… ``"roll2"`` in the full model) on the bar's lateral
    surface, the pusher on its back face):

    * ``penalty`` (:class:`fxcontact.Penalty`), of both contacts: ``Penalty(beta=10.0)`` by
      default: ρ = β η(ε̄̇)/h [MPa·s/mm = N·s/mm³] (THEORY §2.5), η the secant viscosity
      [MPa·s] at the bite's representative strain rate (v_R/L) ln(A₀/A_pass) unless the
      Penalty gives ``strain_rate``, h [mm] the element size; ``Penalty(penalty=ρ)``,
      ``Penalty(gap_stiffness=k)`` (k [MPa/mm], ρ = k·dt) as given.
    * ``friction``: ``Norton(0.3, 0.15)`` on every roll by default (τ = α_f K s^q, α_f
      dimensionless, K [MPa·s^q/mm^q] the material's, s the slip speed [mm/s]); any law, or
      ``{"roll0": law, ...}``. ``slip_velocity`` regularises the slip speed.
    * Former spellings, accepted for one release with a ``DeprecationWarning``: ``alpha_f``,
      ``q`` (Norton) for ``friction``, ``beta`` for ``penalty``.

    **How a penalty or a friction coefficient reaches its kernel.** ``case.penalty`` →
    :func:`build` (``Penalty.completed(strain_rate=...)``: the bite's rate) →
    ``NodalContact(penalty=, element_size=h)`` → ``Penalty.rho(material, dt, rate)`` at each
    ``begin_increment`` (ρ fixed at the first) → ``penalty_kernel(S, rho, ...)``: four hops.
    ``case.friction`` → ``NodalContact(friction=)`` (one law per roll) →
    ``friction_arguments`` at each evaluation (per node: law code, α_f K, q) →
    ``friction_kernel(...)``: three hops."""

    # the pass
    R0: float = 58.0                #: incoming bar radius
    R1: float = 48.0                #: inscribed radius of the pass (= groove radius)
    groove_angle: float = 50.0      #: groove half-angle β [degrees], < 60
    roll_radius: float = 180.0      #: groove-bottom (working) radius R_w
    edge_radius: float = 5.0        #: rounding of the groove's edges (0: sharp)
    # the material
    K: float = 50.0
    m: float = 0.03
    regularization: float = 1e-3    #: × the bite's strain rate
    #: a flow stress σ₀(ε̄, ε̄̇, T) (:class:`~fxcontact.Viscoplastic`, its own regularisation)
    #: instead of K, m (and m_start, regularization); the theory's σ0 is its mean over the
    #: pass's strain ln(A0/A_pass)
    material: Optional[fx.Viscoplastic] = None
    #: heat (:class:`~fxcontact.HeatSetup`: the bar's thermal material and temperature, air on
    #: its free surface, the tools ``roll0`` (…) and ``pusher``), or None
    heat: Optional[fx.HeatSetup] = None
    #: the rolls' friction law (Norton, K of the material), or ``{roll name: law}``
    friction: Friction = fx.Norton(0.3, 0.15)
    slip_velocity: float = 1e-3     #: × v_roll
    # the kinematics
    v_roll: float = 100.0           #: peripheral speed at the groove bottom
    nose: float = 0.3               #: fraction of the bite filled at the start
    push_ratio: float = 0.9         #: pusher speed / ideal entry speed v_R A_pass / A0
    grip_travel: float = 0.6        #: push (× the bite length) before the bar is refused
    # the numerics
    dt: float = 1.0e-3
    h: float = 9.0                  #: element size
    length_factor: float = 3.0      #: bar length, × the bite length
    settle: float = 0.8             #: the front this far past the exit (× L) before the windows
    window: float = 0.5             #: roll travel per steady window, × L
    steady_tol: float = 0.02
    exit_offset: float = 0.5        #: the exit section this far past the roll axes, × L
    #: the penalty of the rolls' and the pusher's contacts (β dimensionless, THEORY §2.5)
    penalty: fx.Penalty = fx.Penalty(beta=10.0)
    m_start: float = 0.1            #: strain-rate sensitivity of the first increment
    model: str = "third"            #: "third" (symmetry planes) or "full"
    mesh: str = "symmetric"         #: "symmetric" or "gmsh"
    # RunNumerics, with Newton's trust region (fewer iterations and cut-backs here)
    line_search: str = "trust-region"
    max_increments: int = 5000
    # former spellings of friction and penalty (one release)
    alpha_f: InitVar[Optional[float]] = UNSET
    q: InitVar[Optional[float]] = UNSET
    beta: InitVar[Optional[float]] = UNSET

    FRICTION_TOOLS = ("roll0", "roll1", "roll2")
    FORMER = (Former("friction", {"alpha_f": 0.3, "q": 0.15}, _friction_of, _friction_values),
              Former("penalty", {"beta": 10.0}, _penalty_of, _penalty_values))

    def __post_init__(self, alpha_f, q, beta):
        super().__post_init__()
        self.resolve_contact_laws(alpha_f=alpha_f, q=q, beta=beta)
        if not (_number(self.edge_radius) and self.edge_radius >= 0):
            raise ValueError(f"edge_radius must be >= 0, got {self.edge_radius!r}")
        for key in ("R0", "R1", "roll_radius", "K", "v_roll", "dt", "h", "length_factor",
                    "push_ratio", "window", "exit_offset", "regularization",
                    "slip_velocity", "m_start", "grip_travel", "steady_tol"):
            if not (_number(getattr(self, key)) and getattr(self, key) > 0):
                raise ValueError(f"{key} must be a finite number > 0, got "
                                 f"{getattr(self, key)!r}")
        if not self.m_start <= 1.0:
            raise ValueError(f"m_start must be in (0, 1], got {self.m_start!r}")
        if not (_number(self.m) and 0.0 < self.m <= 1.0):
            raise ValueError(f"m (strain-rate sensitivity) must be in (0, 1], got {self.m!r}")
        if not 0.0 < self.R1 < self.R0:
            raise ValueError(f"need 0 < R1 < R0 (a reduction), got R0 = {self.R0!r}, "
                             f"R1 = {self.R1!r}")
        if not self.R0 - self.R1 < self.roll_radius:
            raise ValueError("the draft R0 - R1 must be smaller than the roll radius")
        if not (_number(self.nose) and 0.0 < self.nose < 1.0):
            raise ValueError(f"nose (fraction of the bite initially filled) must be in (0, 1), "
                             f"got {self.nose!r}")
        if not (_number(self.settle) and self.settle >= 0):
            raise ValueError(f"settle must be a finite number >= 0, got {self.settle!r}")
        if self.model not in ("third", "full"):
            raise ValueError(f"model must be 'third' or 'full', got {self.model!r}")
        if self.mesh not in ("symmetric", "gmsh"):
            raise ValueError(f"mesh must be 'symmetric' or 'gmsh', got {self.mesh!r}")
        check_material_heat(self.material, self.heat)
        pass_geometry(self.R1, self.groove_angle, self.roll_radius)   # checks groove_angle

    def quick(self) -> "BarRollingCase":
        """This pass at the reduced size of the tests: 16 mm elements, dt = 20 ms, a short
        bar."""
        return dataclasses.replace(self, **QUICK)

    @property
    def bite_length(self) -> float:
        """Bite length at the groove bottom ``√(R_w² − (R_w − (R0 − R1))²)``."""
        Rw = float(self.roll_radius)
        return math.sqrt(Rw**2 - (Rw - (float(self.R0) - float(self.R1))) ** 2)

    def theory(self, geo: Optional[dict] = None) -> dict:
        """The pass's homogeneous strain ``strain`` = ln(A0/A_pass) (``geo``: the
        :func:`stand_pass`, computed if not given), the bite's representative rate
        ``strain_rate`` = (v_R/L) ln(A0/A_pass) [1/s], ``sigma0`` [MPa] there (Norton–Hoff's, or
        the ``material``'s mean over the strain at the heat's initial temperature, else the
        material's) with its Norton–Hoff ``K``, ``m``, and the ideal work: ``ideal_work`` σ0 ε
        per unit volume [MPa] and ``ideal_power`` [N mm/s] of the stand at the entry speed
        ``entry_speed`` v_R A_pass/A0 (a lower bound of the stand's power at steady state)."""
        geo = geo or stand_pass(self)
        A0 = math.pi * float(self.R0) ** 2
        eps = math.log(A0 / geo["A_pass"])
        rate = float(self.v_roll) / self.bite_length * eps
        K, m = (self.K, self.m) if self.material is None else mean_norton_hoff(
            self.material, eps, rate, theory_temperature(self))
        s0 = fx.NortonHoff(K=K, m=m).flow_stress(rate)
        v0 = float(self.v_roll) * geo["A_pass"] / A0
        return dict(strain=eps, strain_rate=rate, sigma0=s0, K=K, m=m, ideal_work=s0 * eps,
                    entry_speed=v0, ideal_power=s0 * eps * A0 * v0)


_number = is_number


# ---- the pass and the rolls

def pass_geometry(R1, groove_angle_deg, roll_radius, n_rolls=N_ROLLS) -> dict:
    """Groove and roll-gap design with sharp groove edges: the groove radius ``r_g`` (= R1),
    depth ``h_g``, half-width ``b``, barrel radius ``R_b``, working radius ``R_w``, roll-axis
    distance ``d``, shoulder distance ``p``, corner radius ``r_c``, the pass area ``A_pass``
    and the inscribed circle's ``A_inscribed``."""
    beta = math.radians(groove_angle_deg)
    half = math.pi / n_rolls
    if not 0.0 < beta < half:
        raise ValueError(f"groove_angle must be in (0, {math.degrees(half):g}) degrees (the "
                         f"grooves of {n_rolls} rolls must not overlap), got {groove_angle_deg!r}")
    rg = float(R1)
    hg = rg * (1.0 - math.cos(beta))
    Rw = float(roll_radius)
    p = rg * math.cos(beta)
    return dict(r_g=rg, h_g=hg, b=rg * math.sin(beta), R_w=Rw, R_b=Rw + hg, d=Rw + rg, p=p,
                beta=beta, r_c=p / math.cos(half),
                A_pass=n_rolls * (beta * rg * rg + p * p * (math.tan(half) - math.tan(beta))),
                A_inscribed=math.pi * rg * rg)


def stand_pass(case: BarRollingCase) -> dict:
    """:func:`pass_geometry` of the case; with rounded groove edges the pass area is that of
    the rolls' outline (``outline``; ``A_pass_sharp``: the sharp pass's area)."""
    geo = pass_geometry(case.R1, case.groove_angle, case.roll_radius)
    if case.edge_radius > 0:     # the rounded edges open the pass: its area from the rolls
        outline = pass_outline_of_rolls(make_rolls(geo, 0.0, 0.0, [60.0, 180.0, 300.0],
                                                   case.edge_radius), 0.0, 2.0 * geo["r_c"])
        geo = {**geo, "A_pass_sharp": geo["A_pass"], "A_pass": polygon_area(outline),
               "outline": outline}
    return geo


def make_rolls(geo, z_r, omega, thetas_deg, edge_radius=0.0):
    """One :class:`fxcontact.RevolvedProfile` grooved roll per angle (names roll0, roll1, …),
    the groove's edges rounded with ``edge_radius``."""
    rolls = []
    for k, th in enumerate(thetas_deg):
        t = math.radians(th)
        rolls.append(fx.RevolvedProfile.grooved_roll(
            barrel_radius=geo["R_b"], barrel_width=4.0 * geo["b"], groove_radius=geo["r_g"],
            groove_depth=geo["h_g"], edge_radius=edge_radius,
            axis_point=(geo["d"] * math.cos(t), geo["d"] * math.sin(t), z_r),
            axis=(-math.sin(t), math.cos(t), 0.0), angular_velocity=omega, name=f"roll{k}"))
    return rolls


def pass_outline(geo, n_rolls=N_ROLLS, first_deg=60.0, n=200):
    """Closed outline (x, y) of the sharp pass in the exit plane: groove arcs and shoulders."""
    pts = []
    half = math.pi / n_rolls
    for k in range(n_rolls):
        c = math.radians(first_deg) + 2 * half * k
        phi = np.linspace(-half, half, n)
        r = np.where(np.abs(phi) <= geo["beta"], geo["r_g"], geo["p"] / np.cos(phi))
        pts.append(np.stack([r * np.cos(c + phi), r * np.sin(c + phi)], 1))
    P = np.concatenate(pts)
    return np.vstack([P, P[:1]])


def pass_outline_of_rolls(rolls, z, r_max, n=3600):
    """Closed outline (x, y) of the pass left by ``rolls`` in the plane z, sampled at n + 1
    angles (θ = 0 included: the roll gaps of the default stand) by :func:`pass_radius`."""
    th = np.linspace(0.0, 2.0 * np.pi, n + 1)
    r = pass_radius(rolls, th, np.full_like(th, z), r_max, tol=1e-12)
    return np.stack([r * np.cos(th), r * np.sin(th)], 1)


def polygon_area(P):
    """Area of a closed polygon (first point repeated last)."""
    return 0.5 * abs(float(np.dot(P[:-1, 0], P[1:, 1]) - np.dot(P[:-1, 1], P[1:, 0])))


def pass_radius(rolls, theta, z, r_max, tol=1e-9):
    """Largest radius r ≤ r_max along the ray (θ, z) from the bar axis with the point outside
    every roll (bisection on the smallest gap; rays that stay outside up to r_max give r_max)."""
    theta, z = np.asarray(theta, float), np.asarray(z, float)

    def gap(r):
        P = np.stack([r * np.cos(theta), r * np.sin(theta), z], 1)
        return np.min([roll.project(P, 0.0, hessian=False).gap for roll in rolls], axis=0)

    lo = np.zeros_like(z)
    hi = np.full_like(z, r_max)
    free = gap(hi) >= 0.0
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        ok = gap(mid) >= 0.0
        lo = np.where(ok, mid, lo)
        hi = np.where(ok, hi, mid)
        if np.max(hi - lo, initial=0.0) < tol * r_max:
            break
    return np.where(free, r_max, lo)


# ---- the exit cross-section: exact plane cut of the tetrahedra

_EDGES = np.array([(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)])


def section_area(X, cells, z):
    """Area of the section of the tetrahedra ``cells`` (vertex indices into X) by the plane
    z = const (the cut polygons: triangles or quadrilaterals)."""
    d = X[cells, 2] - z                                   # (nc, 4)
    below = d < 0.0
    nb = below.sum(axis=1)
    cut = (nb > 0) & (nb < 4)
    area = 0.0
    for c, dc in zip(cells[cut], d[cut]):
        pts = []
        for i, j in _EDGES:
            if (dc[i] < 0.0) != (dc[j] < 0.0):
                s = dc[i] / (dc[i] - dc[j])
                pts.append(X[c[i], :2] + s * (X[c[j], :2] - X[c[i], :2]))
        P = np.array(pts)
        ctr = P.mean(axis=0)
        P = P[np.argsort(np.arctan2(P[:, 1] - ctr[1], P[:, 0] - ctr[0]))]
        area += 0.5 * abs(np.dot(P[:, 0], np.roll(P[:, 1], -1))
                          - np.dot(P[:, 1], np.roll(P[:, 0], -1)))
    return area


def section_outline(X, facets, z):
    """Segments (m, 2, 2) of the cut of the boundary triangles ``facets`` by the plane z."""
    d = X[facets, 2] - z
    segs = []
    for f, df in zip(facets, d):
        pts = []
        for i, j in ((0, 1), (1, 2), (0, 2)):
            if (df[i] < 0.0) != (df[j] < 0.0):
                s = df[i] / (df[i] - df[j])
                pts.append(X[f[i], :2] + s * (X[f[j], :2] - X[f[i], :2]))
        if len(pts) == 2:
            segs.append(pts)
    return np.array(segs).reshape(-1, 2, 2)


# ---- the set-up

class _StartupNortonHoff(fx.NortonHoff):
    """Norton–Hoff law whose exponent in the residual is a mesh Constant (``exponent``), set to
    ``m_start`` for the first increment and then to m. The float ``m`` (penalty scaling, flow
    stress) is the material's."""

    def bind(self, mesh, m_value):
        object.__setattr__(self, "exponent", dolfinx.fem.Constant(mesh, float(m_value)))

    def exponent_ufl(self):
        return self.exponent


@dataclass
class BarRollingSetup:
    """A set-up pass: the simulation and its handles (what :func:`run` measures)."""

    case: BarRollingCase
    sim: object                   #: the :class:`fxcontact.Simulation`
    rolls: list                   #: the rolls of the model (roll0, …)
    material: object              #: Norton–Hoff with the start-up exponent, or the case's
    pass_geometry: dict           #: :func:`stand_pass`
    bite_length: float
    omega: float
    z_r: float                    #: the exit plane (roll axes)
    thetas: list                  #: the rolls' angles about the bar axis [degrees]
    v_push: float                 #: the pusher's speed until the grip
    facet_tags: object = None     #: the bar's facet tags (:data:`DRAWING_BAR_TAGS`)
    roll_contact: object = None   #: one :class:`fxcontact.NodalContact` for the rolls
    pusher_contact: object = None
    t_release: float = math.inf

    @property
    def factor(self) -> float:
        """Model → whole stand (3 for the third)."""
        return 3.0 if self.case.model == "third" else 1.0

    def pusher_speed(self, t: float) -> float:
        return self.v_push if t <= self.t_release else 0.0

    def release(self, t: float) -> None:
        self.t_release = t


def build(case: BarRollingCase, comm=None) -> BarRollingSetup:
    """The pass set up: the bar (a third or whole) with its front shaped to the pass, the
    rolls with Norton friction, the pusher, the symmetry planes of the third."""
    comm = comm or MPI.COMM_WORLD
    R0, v_R = float(case.R0), float(case.v_roll)
    geo = pass_geometry(case.R1, case.groove_angle, case.roll_radius)
    L = case.bite_length
    omega = v_R / geo["R_w"]
    third = case.model == "third"
    # the bar: front `nose` L inside the bite
    length = case.length_factor * L
    z_r = length + (1.0 - case.nose) * L
    sym = case.mesh == "symmetric"
    if third:
        msh, _, ft = drawing_bar(comm, R0, length, case.h, sector=120.0, symmetric_mesh=sym)
        thetas = [60.0]
    else:
        msh, _, ft = drawing_bar(comm, R0, length, case.h, sector=120.0 if sym else None,
                                 replicate=sym)
        thetas = [60.0, 180.0, 300.0]
    rolls = make_rolls(geo, z_r, omega, thetas, case.edge_radius)
    geo = stand_pass(case)
    # the nose: the lateral surface of the front part moved onto the rolls (radial scaling)
    g = msh.geometry.x
    th = np.arctan2(g[:, 1], g[:, 0])
    rs = pass_radius(rolls, th, g[:, 2], R0)
    g[:, :2] *= (rs / R0)[:, None]
    # representative strain rate of the bite: (v_R / L) ln(A0 / A_pass)
    rate = v_R / L * math.log(math.pi * R0**2 / geo["A_pass"])
    if case.material is None:
        mat = _StartupNortonHoff(K=case.K, m=case.m, regularization=case.regularization * rate)
        mat.bind(msh, case.m_start)
    else:   # per-cell pieces from the state: no start-up exponent (the first increment from
        # rest starts from the linearised material's solve, then Newton with the law's own m)
        mat = case.material
    sp = fx.MixedSpace(msh)
    sim = fx.Simulation(sp, mat, solver_options=case.solver_options(), progress=False)
    if third:
        normals = sector_plane_normals(120.0)
        for k, name in (("symmetry_0", "sym0"), ("symmetry_1", "sym1")):
            sim.add_symmetry_plane(sim.facets(ft, DRAWING_BAR_TAGS[k]), normals[k], name=name)
    # β at the bite's strain rate (unless the case's Penalty gives one)
    penalty = dict(scheme=case.scheme, penalty=case.penalty.completed(strain_rate=rate),
                   element_size=case.h)
    rc = fx.NodalContact(fx.ContactBoundary(sp, ft, DRAWING_BAR_TAGS["lateral"]), rolls,
                         friction=contact_friction(case.friction),
                         slip_velocity=case.slip_velocity * v_R,
                         name="roll_contact", **penalty)
    A0 = math.pi * R0**2
    setup = BarRollingSetup(case, sim, rolls, mat, geo, L, omega, z_r, thetas,
                            case.push_ratio * v_R * geo["A_pass"] / A0, facet_tags=ft,
                            roll_contact=rc)
    pusher = fx.Plane((0.0, 0.0, 0.0), (0.0, 0.0, 1.0),
                      velocity=lambda t: (0.0, 0.0, setup.pusher_speed(t)), name="pusher")
    setup.pusher_contact = fx.NodalContact(
        fx.ContactBoundary(sp, ft, DRAWING_BAR_TAGS["back"]), pusher, name="pusher_contact",
        **penalty)
    sim.add_contributor(rc)
    sim.add_contributor(setup.pusher_contact)
    if case.heat is not None:   # the symmetry planes of the third insulated
        case.heat.attach(sim, ft, [DRAWING_BAR_TAGS[k] for k in ("lateral", "front", "back")],
                         [t.name for c in (rc, setup.pusher_contact) for t in c.tools])
    return setup


# ---- one row per increment

class _Measure:
    """The per-increment row: per-roll radial and axial force and torque, exit area, power
    balance."""

    def __init__(self, setup: BarRollingSetup):
        self.s = s = setup
        sim, case = s.sim, s.case
        msh = sim.mesh
        self.power = PowerBalance(sim, [s.roll_contact, s.pusher_contact])
        self.V0 = sim.volume()
        self.nc = msh.topology.index_map(3).size_local
        self.c2v = compat.cell_vertices(msh)[:self.nc]
        msh.topology.create_connectivity(2, 0)
        f2v = msh.topology.connectivity(2, 0)
        ft = s.facet_tags
        lat = ft.indices[ft.values == DRAWING_BAR_TAGS["lateral"]]
        lat = lat[lat < msh.topology.index_map(2).size_local]
        self.lat_v = np.array([f2v.links(i) for i in lat], dtype=np.int64).reshape(-1, 3)
        self.e_r = [np.array([math.cos(math.radians(t)), math.sin(math.radians(t)), 0.0])
                    for t in s.thetas]
        self.z_exit = s.z_r + case.exit_offset * s.bite_length

    def __call__(self, res) -> dict:
        s, case = self.s, self.s.case
        sim, comm, rolls = s.sim, s.sim.comm, s.rolls
        rr = res.row
        X = sim.vertex_positions()
        front = comm.allreduce(float(np.max(X[:, 2], initial=-np.inf)), op=MPI.MAX)
        tail = comm.allreduce(float(np.min(X[:, 2], initial=np.inf)), op=MPI.MIN)
        Fr = [float(np.array([rr[f"{roll.name}_force_{c}"] for c in "xyz"]) @ e)
              for roll, e in zip(rolls, self.e_r)]
        Fz = [rr[f"{roll.name}_force_z"] for roll in rolls]
        # driving torque of each roll (the history's torque is the one the bar exerts on it)
        M = [-rr[f"{roll.name}_torque"] for roll in rolls]
        P_roll = sum(M) * s.omega
        P_push = -rr["pusher_force_z"] * s.pusher_speed(sim.t)
        pw = self.power(rr, P_roll + P_push)
        row = dict(increment=rr["increment"], time=sim.t, front=front - s.z_r,
                   tail=tail - s.z_r, roll_force=float(np.mean(Fr)),
                   roll_force_axial=float(np.mean(Fz)), roll_torque=float(np.mean(M)),
                   roll_force_spread=float(np.ptp(Fr) / abs(np.mean(Fr))) if np.mean(Fr) else 0.0,
                   contact_nodes=rr["roll_contact_nodes"], contact_area=rr["roll_contact_area"],
                   penetration=rr["roll_contact_penetration_true"],
                   pusher_force=-rr["pusher_force_z"], pusher_nodes=rr["pusher_contact_nodes"],
                   newton_iterations=rr["newton_iterations_all"], cutbacks=rr["cutbacks"],
                   wall=rr["wall_increment_all"], wall_assembly=rr["wall_assembly"],
                   wall_linear_solve=rr["wall_linear_solve"], wall_contact=rr["wall_contact"],
                   volume_change=rr["volume"] / self.V0 - 1.0,
                   min_quality=rr["min_quality"], dissipation=pw["dissipation"],
                   friction_power=pw["friction_power"], roll_power=P_roll, pusher_power=P_push,
                   penalty_power=pw["penalty_power"], power_balance=pw["power_balance"],
                   power_balance_penalty=pw["power_balance_penalty"], **heat_columns(rr))
        for k, roll in enumerate(rolls):
            row[f"{roll.name}_radial_force"] = Fr[k]
            row[f"{roll.name}_torque"] = M[k]
        if front > self.z_exit + 0.25 * case.h:
            row["exit_area"] = s.factor * comm.allreduce(
                section_area(X, self.c2v, self.z_exit), op=MPI.SUM)
        else:
            row["exit_area"] = math.nan
        return row


# ---- the result

#: the quantities averaged over the steady window
STEADY_KEYS = ("roll_force", "roll_force_axial", "roll_torque", "contact_area", "penetration",
               "power_balance", "power_balance_penalty", "dissipation", "friction_power",
               "roll_power", "penalty_power", "exit_area")

_NAN = math.nan


@dataclass
class BarRollingResult(SteadyRun):
    """A pass rolled (:func:`run`): the run, the pass, and at steady state the window means of
    :data:`STEADY_KEYS` (per roll: radial force N, axial force, torque N mm), the stand's
    torque, power and contact area, the fill of the pass and the exit section's outline."""

    case: Optional[BarRollingCase] = None
    pass_geometry: dict = field(default_factory=dict)
    bite_length: float = _NAN          #: at the groove bottom [mm]
    omega: float = _NAN                #: the rolls' angular velocity [1/s]
    z_r: float = _NAN                  #: the exit plane (roll axes) [mm]
    cells: int = 0                     #: of the model
    dofs: int = 0
    factor: float = 1.0                #: model → whole stand
    n_model_rolls: float = 1.0         #: rolls in the model
    roll_force: float = _NAN           #: radial (separating) force per roll [N]
    roll_force_axial: float = _NAN     #: axial force per roll [N]
    roll_torque: float = _NAN          #: driving torque per roll [N mm]
    contact_area: float = _NAN         #: of the model [mm²]
    penetration: float = _NAN          #: true penetration [mm]
    roll_power: float = _NAN           #: M ω of the model's rolls [N mm/s]
    exit_area: float = _NAN            #: of the whole bar's exit section [mm²]
    stand_torque: float = _NAN         #: [N mm]
    stand_power: float = _NAN          #: [N mm/s]
    stand_contact_area: float = _NAN   #: [mm²]
    force_oscillation: float = _NAN
    fill: float = _NAN                 #: exit area / pass area
    fill_inscribed: float = _NAN
    outline: Optional[np.ndarray] = None
    radius_gap: float = _NAN           #: the section's radius at the roll gaps [mm]
    radius_min: float = _NAN
    radius_max: float = _NAN
    pictures: List[str] = field(default_factory=list)

    @property
    def max_penetration(self) -> float:
        return max(q["penetration"] for q in self.history)

    def report(self) -> str:
        """The summary a process engineer reads."""
        geo, c = self.pass_geometry, self.case
        lines = [f"status: {self.status}: {self.message} (model: {c.model}, h = {c.h:g} mm, "
                 f"dt = {c.dt:g} s, {self.cells} cells, {self.dofs} dofs)",
                 f"pass: groove r_g = {geo['r_g']:g} mm, half-angle {math.degrees(geo['beta']):g}"
                 f" deg, depth {geo['h_g']:.2f} mm, roll R_w = {geo['R_w']:g} (barrel "
                 f"{geo['R_b']:.2f}) mm, corner r_c = {geo['r_c']:.2f} mm; A_pass = "
                 f"{geo['A_pass']:.0f} mm2 (inscribed circle {geo['A_inscribed']:.0f}); bite "
                 f"length {self.bite_length:.1f} mm"]
        th = c.theory(geo)
        lines.append(f"material {material_text(c, 'bar')}: sigma0 = {th['sigma0']:.1f} MPa "
                     f"over the strain ln(A0/A_pass) = {th['strain']:.3f} at "
                     f"{th['strain_rate']:.3f} 1/s; ideal stand power "
                     f"{th['ideal_power'] / 1e6:.2f} kW")
        if self.steady:
            lines += [
                f"steady from increment {self.steady_from} of {self.increments} (gripped at "
                f"t = {self.gripped_at:.4g} s)",
                f"per roll: radial force {self.roll_force / 1e3:.2f} kN (oscillation "
                f"+-{100 * self.force_oscillation:.1f} %), axial force "
                f"{self.roll_force_axial / 1e3:.2f} kN, torque {self.roll_torque / 1e6:.3f} kN m;"
                f" stand torque {self.stand_torque / 1e6:.3f} kN m, stand power "
                f"{self.stand_power / 1e6:.3f} kW",
                f"exit area {self.exit_area:.0f} mm2: fill of the pass {100 * self.fill:.2f} %"
                f" (underfill {100 * (1 - self.fill):.2f} %), / inscribed circle "
                f"{self.fill_inscribed:.3f}; radius min {self.radius_min:.2f}, at the roll gap "
                f"{self.radius_gap:.2f} (corner {geo['r_c']:.2f}) mm",
                f"contact area (stand) {self.stand_contact_area:.0f} mm2; true penetration "
                f"{self.penetration:.3g} mm",
                f"power balance (M w + P_push)/(D + P_f) - 1 = {100 * self.power_balance:.2f} %"
                f" (with the penalty work {100 * self.power_balance_penalty:.3f} %); stand "
                f"power / ideal {self.stand_power / th['ideal_power']:.3f}"]
        lines += heat_lines(self.history, c.heat, "bar")
        lines += [f"max penetration {self.max_penetration:.3g} mm", self.run_summary()]
        return "\n".join(lines)


def run(case: BarRollingCase, comm=None, output_dir: Optional[str] = None,
        pictures: bool = True) -> BarRollingResult:
    """Roll the bar to steady state (or say why not). With ``output_dir`` (the same on every
    rank; None writes nothing) the rows go to ``bar_rolling_{model}_diagnostics.csv`` and, at
    steady state with ``pictures``, the exit section to ``exit_section_{model}.png``."""
    comm = comm or MPI.COMM_WORLD
    check_output_dir(output_dir, comm)
    s = build(case, comm)
    sim, L = s.sim, s.bite_length
    measure = _Measure(s)

    def before_step(it):
        if it == 1 and case.material is None:
            s.material.exponent.value = case.m    # after the start-up increment

    length = case.length_factor * L
    rules = StopRules(
        ("roll_force", "roll_torque"),
        window_increments(case.window * L, case.v_roll, case.dt, 3), case.steady_tol,
        settle=case.settle * L, max_increments=int(case.max_increments),
        grip_travel=case.grip_travel * L, front_start=length - s.z_r,
        tail_limit=-L - 0.5 * case.h, body="bar", zone="bite",
        hints={"no steady state": "raise length_factor"})
    out = SteadyMonitor(sim, case.dt, measure, rules, release=s.release,
                        before_step=before_step, name="bar rolling").run()
    sim.close()
    imap = sim.space.W.dofmap.index_map
    res = BarRollingResult(**out.run_fields(), case=case, pass_geometry=s.pass_geometry,
                           bite_length=L, omega=s.omega, z_r=s.z_r,
                           cells=comm.allreduce(measure.nc, op=MPI.SUM),
                           dofs=imap.size_global * sim.space.W.dofmap.index_map_bs,
                           factor=s.factor, n_model_rolls=float(len(s.rolls)))
    if res.steady:
        _steady_values(res, s, measure)
    if comm.rank == 0 and output_dir:
        os.makedirs(output_dir, exist_ok=True)
        with open(os.path.join(output_dir, f"bar_rolling_{case.model}_diagnostics.csv"), "w",
                  newline="") as fh:
            wr = csv.DictWriter(fh, fieldnames=list(res.history[0]))
            wr.writeheader()
            wr.writerows(res.history)
    if res.steady and pictures and output_dir and comm.rank == 0:
        res.pictures = [_section_picture(res, output_dir)]
    return res


def _steady_values(res: BarRollingResult, s: BarRollingSetup, measure: _Measure) -> None:
    geo = res.pass_geometry
    for k, v in res.means(STEADY_KEYS).items():
        setattr(res, k, v)
    res.stand_torque = 3.0 * res.roll_torque
    res.stand_power = res.factor * res.roll_power
    res.stand_contact_area = res.factor * res.contact_area
    res.force_oscillation = res.oscillation("roll_force")
    res.fill = res.exit_area / geo["A_pass"]
    res.fill_inscribed = res.exit_area / geo["A_inscribed"]
    # the section outline at the end and its radii
    X = s.sim.vertex_positions()
    segs = gather(s.sim.comm, section_outline(X, measure.lat_v, measure.z_exit))
    res.outline = segs
    pts = segs.reshape(-1, 2)
    rad = np.hypot(pts[:, 0], pts[:, 1])
    ang = np.degrees(np.arctan2(pts[:, 1], pts[:, 0])) % 120.0
    near = np.minimum(ang, 120.0 - ang) < 3.0              # at a roll gap
    res.radius_gap = float(np.max(rad[near])) if np.any(near) else math.nan
    res.radius_min = float(np.min(rad))
    res.radius_max = float(np.max(rad))


def _section_picture(res: BarRollingResult, out: str) -> str:
    """The exit section (the modelled part and its turned copies) in the pass, with the
    incoming bar and the inscribed circle."""
    plt = pyplot()
    geo, c = res.pass_geometry, res.case
    fig, ax = plt.subplots(figsize=(7.5, 7.5))
    P = geo["outline"] if "outline" in geo else pass_outline(geo)
    ax.fill(P[:, 0], P[:, 1], color="0.92", zorder=0, label=f"pass (A = {geo['A_pass']:.0f} mm²)")
    ax.plot(P[:, 0], P[:, 1], "k-", lw=1.2)
    t = np.linspace(0, 2 * np.pi, 361)
    ax.plot(c.R0 * np.cos(t), c.R0 * np.sin(t), color="tab:gray", ls="--", lw=1,
            label=f"incoming bar R0 = {c.R0:g} mm")
    ax.plot(geo["r_g"] * np.cos(t), geo["r_g"] * np.sin(t), color="tab:green", ls=":", lw=1,
            label=f"inscribed circle R1 = {geo['r_g']:g} mm")
    third = c.model == "third"
    for k in range(3 if third else 1):
        a = math.radians(120.0 * k)
        rot = np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])
        for j, seg in enumerate(res.outline @ rot.T):
            ax.plot(seg[:, 0], seg[:, 1], color="tab:red" if k == 0 else "salmon", lw=2.0,
                    label=(("exit section, modelled third" if third else "exit section")
                           if (j == 0 and k == 0) else
                           ("exit section, turned copies" if (j == 0 and k == 1) else None)))
    for th in (60.0, 180.0, 300.0):
        a = math.radians(th)
        ax.annotate("roll", (1.35 * geo["r_g"] * math.cos(a), 1.35 * geo["r_g"] * math.sin(a)),
                    ha="center", va="center", fontsize=11, color="0.3")
    ax.set_aspect("equal")
    lim = 1.2 * max(c.R0, geo["r_c"])
    ax.set_xlim(-lim, lim)
    ax.set_ylim(-lim, lim)
    ax.grid(alpha=0.3)
    ax.set_xlabel("x [mm]")
    ax.set_ylabel("y [mm]")
    ax.set_title(f"Three-roll pass R0 {c.R0:g} → R1 {c.R1:g} mm: exit section at "
                 f"{c.exit_offset:g} L past the roll axes\nA_exit = {res.exit_area:.0f} "
                 f"mm², fill of the pass {100 * res.fill:.1f} %, "
                 f"radius at the roll gap {res.radius_gap:.1f} mm (corner {geo['r_c']:.1f})",
                 fontsize=10)
    ax.legend(loc="lower left", fontsize=8)
    fig.tight_layout()
    path = os.path.join(out, f"exit_section_{c.model}.png")
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def compare(case: BarRollingCase, n_increments: int = 4, comm=None) -> dict:
    """The third and the whole model of ``case`` over ``n_increments`` increments: the
    results of both and the largest relative difference of the per-roll radial force and
    torque (each of the whole model's three rolls against the third's roll)."""
    kw = dict(max_increments=int(n_increments))
    a = run(dataclasses.replace(case, model="third", **kw), comm, pictures=False)
    b = run(dataclasses.replace(case, model="full", **kw), comm, pictures=False)
    diffs = {}
    for key in ("radial_force", "torque"):
        d = 0.0
        for qa, qb in zip(a.history, b.history):
            ref = qa[f"roll0_{key}"]
            for k in range(3):
                d = max(d, abs(qb[f"roll{k}_{key}"] - ref) / abs(ref))
        diffs[key] = d
    return dict(third=a, full=b, max_rel_diff=diffs)
