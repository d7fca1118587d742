"""Flat rolling of a strip to steady state (THEORY §14.3), one quarter of the strip.

x is the rolling direction, y across the width, z through the thickness; the quarter
``[x_back, x_front] × [0, b0/2] × [0, h0/2]`` has the width mid-plane y = 0 and the thickness
mid-plane z = 0 as symmetry planes. The upper roll (axis along y through ``(0, 0, h1/2 + R)``,
the exit plane is x = 0) turns at ω = v_R/R; the force and torque of one roll per unit width are
the quarter's divided by the mean half-width ``(b0 + b1)/4``. The strip's front is shaped to the
roll (a nose) ``nose`` × L inside the bite (L = √(RΔh)); a rigid pusher moves it at
``push_ratio`` × the ideal entry speed until the roll grips it, then stops. The strip's tail
face carries a lagged dashpot ``c (v − v̄_prev)``, ``c = tail_damping σ0 / v_R`` (a
pseudo-inertia: without it the quasi-static strip has a free x-translation once released, and
Newton may find the strip thrown out of the bite); its power is in the power balance.

:class:`FlatRollingCase` is the pass, the material, the friction, the kinematics and the
numerics; :func:`build` returns the ready :class:`fxcontact.Simulation` with its handles;
:func:`run` rolls to steady state (:class:`~fxcontact.processes.monitor.SteadyMonitor`) and
returns a :class:`FlatRollingResult` (steady means, the classical band of
:func:`fxcontact.theory.flat_rolling.theory_band`, forward slip, spread, power balance, pictures).

**Hot rolling** (``material``, ``heat``): a flow stress σ₀(ε̄, ε̄̇, T)
(:class:`~fxcontact.Viscoplastic`, its regularisation as given) instead of K, m — the theory's
σ0 is then its mean over the plane-strain strain (2/√3) ln(h0/h1) at the bite's mean strain rate
(:meth:`FlatRollingCase.flow_stress`) — and a :class:`~fxcontact.HeatSetup`: air on the strip's
top (where the roll does not touch it), its side, front and tail, the tools ``roll`` and
``pusher``; the two symmetry planes are insulated. The rows then carry the heat's ``heat_*``
columns.
"""

from __future__ import annotations

import csv
import dataclasses
import math
import os
from dataclasses import InitVar, dataclass, field
from typing import List, Optional

import dolfinx
import dolfinx.mesh
import numpy as np
from mpi4py import MPI

import fxcontact as fx
from fxcontact import compat
from fxcontact.io.series import pyplot
from fxcontact.power import PowerBalance
from fxcontact.processes.common import check_output_dir
from fxcontact.processes.common import (check_material_heat, gather, heat_columns, heat_lines,
                                        material_text, mean_norton_hoff, theory_temperature)
from fxcontact.processes.contact_laws import UNSET, Former, Friction, contact_friction, law_text
from fxcontact.processes.monitor import (RunNumerics, SteadyMonitor, SteadyRun, StopRules,
                                         is_number, window_increments)
from fxcontact.theory import flat_rolling as rolling

__all__ = ["FlatRollingCase", "FlatRollingSetup", "FlatRollingResult", "build", "run",
           "strip_mesh", "faceted_roll", "ROLLS"]

#: the roll's discretisation: the analytic cylinder, or a faceted one (closest facet, Nagata)
ROLLS = ("analytic", "flat", "nagata")

#: the reduced size of the tests: a coarse mesh, larger increments, a short strip
QUICK = dict(h_x=7.5, ny=3, nz=2, dt=3.0e-3, length_factor=2.2, settle=0.3, window=0.35,
             steady_tol=0.02)


def _friction_of(case, v: dict):
    """The roll's law of the former ``mu``, ``mbar``: Coulomb μ limited by Tresca m̄."""
    if not (_number(v["mu"]) and v["mu"] >= 0):
        raise ValueError(f"mu (Coulomb) must be a finite number >= 0, got {v['mu']!r}")
    if not (_number(v["mbar"]) and 0.0 <= v["mbar"] <= 1.0):
        raise ValueError(f"mbar (Tresca factor) must be in [0, 1], got {v['mbar']!r}")
    return fx.Coulomb(v["mu"], mbar=v["mbar"])


def _friction_values(case, law) -> Optional[dict]:
    if isinstance(law, fx.Coulomb) and law.mbar is not None:
        return {"mu": law.mu, "mbar": law.mbar}
    return None


@dataclass(frozen=True)
class FlatRollingCase(RunNumerics):
    """One pass of flat rolling; the defaults are the thesis case (lengths mm, stresses MPa,
    times s): a strip 100 mm wide, 25 → 18 mm (28 %), rolls R = 300 mm at 500 mm/s,
    Norton–Hoff K = 30 MPa·s^m, m = 0.3, Coulomb μ = 0.3 limited by Tresca m̄ = 1; the mesh
    and dt of the thesis (3 mm along the strip, 8 × 4 elements across the quarter section,
    dt = 0.75 ms). :meth:`quick` is the reduced size of the tests.

    **Contact** (the roll on the strip's top face, the tool ``"roll"``; the pusher on its tail
    face, frictionless):

    * ``penalty`` (:class:`fxcontact.Penalty`), of both contacts: ``Penalty()`` by default,
      β = 1e3 (THEORY §2.5): ρ = β η(ε̄̇)/h_e [MPa·s/mm = N·s/mm³], η the secant viscosity
      [MPa·s] at the representative strain rate estimated at the first increment, h_e [mm]
      from the contact's nodal areas; or ``Penalty(beta=..., strain_rate=...)``,
      ``Penalty(penalty=ρ)``, ``Penalty(gap_stiffness=k)`` (k [MPa/mm], ρ = k·dt).
    * ``friction``: the roll's law, ``Coulomb(0.3, mbar=1.0)`` by default (μ dimensionless,
      limited by the Tresca m̄ k, k [MPa] the shear flow stress at each node's strain rate);
      ``Tresca(mbar)``, ``Frictionless()``; or ``{"roll": law}``. The slab theory reads its μ
      and m̄ (:meth:`friction_coefficients`). ``slip_ratio`` regularises the slip speed.
    * Former spellings, accepted for one release with a ``DeprecationWarning``: ``mu``,
      ``mbar`` (Coulomb μ limited by m̄) for ``friction``.

    **How a penalty or a friction coefficient reaches its kernel.** ``case.penalty`` →
    ``NodalContact(penalty=)`` (each contact its own copy) → ``Penalty.rho(material, dt,
    rate)`` at each ``begin_increment`` (β resolved once, at the first increment's
    representative strain rate) → ``penalty_kernel(S, rho, ...)``: three hops.
    ``case.friction`` → ``NodalContact(friction=)`` (one law per tool) →
    ``friction_arguments`` at each evaluation (per node: law code, μ, m̄ k with k from
    ``begin_increment``) → ``friction_kernel(...)``: three hops."""

    # the pass
    R: float = 300.0                #: roll radius
    h0: float = 25.0                #: entry thickness
    reduction: float = 0.28         #: (h0 − h1)/h0
    width: float = 100.0            #: strip width b0
    # the material
    K: float = 30.0                 #: Norton–Hoff consistency
    m: float = 0.3                  #: strain-rate sensitivity
    #: a flow stress σ₀(ε̄, ε̄̇, T) (:class:`~fxcontact.Viscoplastic`) instead of K, m; the
    #: theory's σ0 is then its mean over the strain (:meth:`flow_stress`)
    material: Optional[fx.Viscoplastic] = None
    #: heat (:class:`~fxcontact.HeatSetup`: the strip's thermal material and temperature, air
    #: on its free faces, the tools ``roll`` and ``pusher``), or None
    heat: Optional[fx.HeatSetup] = None
    #: the roll's friction law (Coulomb limited by Tresca, k from the material at the nodes)
    friction: Friction = fx.Coulomb(0.3, mbar=1.0)
    slip_ratio: float = 1e-3        #: regularisation velocity of the law / v_roll
    # the kinematics
    v_roll: float = 500.0           #: peripheral speed of the rolls
    nose: float = 0.3               #: fraction of the bite filled at the start
    push_ratio: float = 0.9         #: pusher speed / ideal entry speed v_R h1/h0
    grip_travel: float = 0.6        #: push (× L) allowed before the strip is refused
    tail_damping: float = 2.0       #: the tail's pseudo-inertia, × σ0 / v_R (0: none)
    # the numerics
    dt: float = 0.75e-3
    h_x: float = 3.0                #: element size along the strip
    ny: int = 8                     #: elements across the half-width
    nz: int = 4                     #: elements through the half-thickness
    length_factor: float = 3.2      #: strip length beyond the nose, × L
    settle: float = 0.8             #: the front this far past the exit (× L) before the windows
    window: float = 0.6             #: roll travel per steady window, × L
    steady_tol: float = 0.03        #: relative change of the window means
    roll: str = "analytic"          #: one of :data:`ROLLS`
    facet_size: Optional[float] = None   #: faceted roll: facet width (default h_x/2)
    #: the penalty of the roll's and the pusher's contacts
    penalty: fx.Penalty = fx.Penalty()
    # (RunNumerics: scheme, line_search, penalty_continuation, active_set_prediction,
    # newton_ftol, max_increments)
    # former spellings of friction (one release)
    mu: InitVar[Optional[float]] = UNSET
    mbar: InitVar[Optional[float]] = UNSET

    FRICTION_TOOLS = ("roll",)
    FORMER = (Former("friction", {"mu": 0.3, "mbar": 1.0}, _friction_of, _friction_values),)

    def __post_init__(self, mu, mbar):
        super().__post_init__()
        self.resolve_contact_laws(mu=mu, mbar=mbar)
        if not isinstance(self.tool_friction("roll"), (fx.Coulomb, fx.Tresca, fx.Frictionless)):
            raise ValueError(f"friction of the roll must be Coulomb, Tresca or Frictionless (the "
                             f"slab theory's mu and mbar), got {self.friction!r}")
        for key in ("R", "h0", "width", "K", "v_roll", "dt", "h_x", "length_factor",
                    "slip_ratio", "push_ratio", "grip_travel", "window", "steady_tol"):
            _positive(key, getattr(self, key))
        if not (_number(self.tail_damping) and self.tail_damping >= 0):
            raise ValueError(f"tail_damping must be a finite number >= 0, got "
                             f"{self.tail_damping!r}")
        if not (_number(self.reduction) and 0.0 < self.reduction < 0.8):
            raise ValueError(f"reduction must be in (0, 0.8), got {self.reduction!r}")
        if not (_number(self.nose) and 0.0 < self.nose < 1.0):
            raise ValueError(f"nose (fraction of the bite initially filled) must be in (0, 1), "
                             f"got {self.nose!r}")
        if not (_number(self.m) and 0.0 < self.m <= 1.0):
            raise ValueError(f"m (strain-rate sensitivity) must be in (0, 1], got {self.m!r}")
        if not (_number(self.settle) and self.settle >= 0):
            raise ValueError(f"settle must be a finite number >= 0, got {self.settle!r}")
        for key in ("ny", "nz"):
            if not (isinstance(getattr(self, key), (int, np.integer)) and getattr(self, key) >= 1):
                raise ValueError(f"{key} must be an integer >= 1, got {getattr(self, key)!r}")
        if self.roll not in ROLLS:
            raise ValueError(f"roll must be one of {ROLLS}, got {self.roll!r}")
        if self.facet_size is not None:
            _positive("facet_size", self.facet_size)
        check_material_heat(self.material, self.heat)

    def quick(self) -> "FlatRollingCase":
        """This pass at the reduced size of the tests: 7.5 mm elements, 3 × 2 across the
        quarter section, dt = 3 ms, a short strip and short steady windows."""
        return dataclasses.replace(self, **QUICK)

    def friction_coefficients(self):
        """(μ, m̄) of the roll's law for the slab theory
        (:func:`fxcontact.theory.flat_rolling.slab`: μ None is Tresca alone, m̄ None pure
        Coulomb): Coulomb (μ, m̄), Tresca (None, m̄), none (0, None)."""
        law = self.tool_friction("roll")
        if isinstance(law, fx.Coulomb):
            return law.mu, law.mbar
        if isinstance(law, fx.Tresca):
            return None, law.mbar
        return 0.0, None

    @property
    def h1(self) -> float:
        return self.h0 * (1.0 - self.reduction)

    @property
    def bite(self) -> rolling.BiteGeometry:
        return rolling.bite(float(self.R), float(self.h0), self.h1)

    @property
    def mean_strain_rate(self) -> float:
        """(v_R / L) ln(h0/h1) [1/s] (:func:`fxcontact.theory.flat_rolling.mean_strain_rate`)."""
        return rolling.mean_strain_rate(float(self.R), float(self.h0), self.h1,
                                        float(self.v_roll))

    def flow_stress(self) -> float:
        """σ0 [MPa] of the theory at the bite's mean strain rate: Norton–Hoff's, or the
        ``material``'s mean over the plane-strain equivalent strain (2/√3) ln(h0/h1)
        (:func:`~fxcontact.processes.common.mean_norton_hoff`) at the heat's initial
        temperature (else the material's)."""
        rate = self.mean_strain_rate
        if self.material is None:
            return fx.NortonHoff(K=self.K, m=self.m).flow_stress(rate)
        K, m = mean_norton_hoff(self.material, 2.0 / math.sqrt(3.0) * math.log(self.h0 / self.h1),
                                rate, theory_temperature(self))
        return fx.NortonHoff(K=K, m=m).flow_stress(rate)


_number = is_number


def _positive(name, x):
    if not (_number(x) and x > 0):
        raise ValueError(f"{name} must be a finite number > 0, got {x!r}")


# ---- the strip and the roll

def strip_mesh(comm, x_back, x_front, half_width, half_h0, nx, ny, nz, roll_z, R):
    """Quarter strip ``[x_back, x_front] × [0, half_width] × [0, half_h0]`` (a box of
    ``nx × ny × nz`` hexahedra split in 6), its top lowered onto the roll's circle
    ``z = roll_z − √(R² − x²)`` where that is below ``half_h0`` (the nose). Returns
    ``(mesh, facet_tags)`` with :data:`fxcontact.BLOCK_TAGS`."""
    msh = dolfinx.mesh.create_box(comm, [np.zeros(3), np.array([nx, ny, nz], float)],
                                  [nx, ny, nz], dolfinx.mesh.CellType.tetrahedron)
    fdim = 2
    ext = (nx, ny, nz)
    idx, val = [], []
    for k, c in enumerate("xyz"):
        for side, where in (("min", 0.0), ("max", float(ext[k]))):
            f = dolfinx.mesh.locate_entities_boundary(
                msh, fdim, lambda x, k=k, w=where: np.abs(x[k] - w) < 1e-9)
            idx.append(f)
            val.append(np.full(len(f), fx.BLOCK_TAGS[f"{c}{side}"], dtype=np.int32))
    idx, val = np.concatenate(idx), np.concatenate(val)
    order = np.argsort(idx, kind="stable")
    ft = dolfinx.mesh.meshtags(msh, fdim, idx[order].astype(np.int32), val[order])
    g = msh.geometry.x
    x = x_back + g[:, 0] / nx * (x_front - x_back)
    top = np.minimum(half_h0, roll_z - np.sqrt(np.maximum(R * R - x * x, 0.0)))
    g[:, 2] = g[:, 2] / nz * top
    g[:, 1] = g[:, 1] / ny * half_width
    g[:, 0] = x
    return msh, ft


def faceted_roll(R, centre, y_range, facet_size, mode, omega):
    """The whole roll circle triangulated (``round(2πR / facet_size)`` generators, vertices on
    the circle, layers along the axis about as long as the facets are wide, at most 40), built
    at rest and turned about the roll's axis by a :class:`fxcontact.RigidMotion`. Returns the
    :class:`fxcontact.MovedTool` and the facets' sag ``R (1 − cos(π/n))``."""
    n = max(8, int(round(2.0 * math.pi * R / facet_size)))
    ny = min(40, max(1, int(round((y_range[1] - y_range[0]) / facet_size))))
    th = 2.0 * math.pi * np.arange(n) / n
    ys = np.linspace(y_range[0], y_range[1], ny + 1)
    T, Y = np.meshgrid(th, ys, indexing="ij")
    V = np.stack([centre[0] + R * np.sin(T), Y, centre[2] - R * np.cos(T)], -1).reshape(-1, 3)
    i, j = np.meshgrid(np.arange(n), np.arange(ny), indexing="ij")
    a = (i * (ny + 1) + j).ravel()
    b = (((i + 1) % n) * (ny + 1) + j).ravel()
    c, d = b + 1, a + 1
    tri = np.concatenate([np.stack([a, c, b], 1), np.stack([a, d, c], 1)])
    tool = fx.FacetedTool(V, tri, mode=mode, name="roll")
    below = tool.project(np.array([[centre[0], 0.5 * sum(y_range), centre[2] - R - 1.0]]),
                         0.0, hessian=False).gap
    if not below[0] > 0.5:
        raise RuntimeError("faceted roll oriented inward")
    motion = fx.RigidMotion(angular_velocity=omega, axis_point=tuple(centre),
                            axis=(0.0, -1.0, 0.0))
    return fx.MovedTool(tool, motion), R * (1.0 - math.cos(math.pi / n))


# ---- the set-up

@dataclass
class FlatRollingSetup:
    """A set-up pass: the simulation and its handles (what :func:`run` measures)."""

    case: FlatRollingCase
    sim: object                   #: the :class:`fxcontact.Simulation`
    material: object
    theory: dict                  #: :func:`fxcontact.theory.flat_rolling.theory_band` of the pass
    sigma0: float                 #: flow stress at the bite's mean strain rate
    mean_strain_rate: float
    omega: float                  #: the roll's angular velocity
    x_entry: float                #: the entry plane (x < 0)
    x_front: float                #: the front at the start
    v_push: float                 #: the pusher's speed until the grip
    facet_sag: float = 0.0        #: a faceted roll's sag
    roll_contact: object = None   #: :class:`fxcontact.NodalContact` of the roll
    pusher_contact: object = None  #: :class:`fxcontact.NodalContact` of the pusher
    tail: object = None           #: the tail face's :class:`fxcontact.ContactBoundary`
    damper: object = None         #: the tail's :class:`fxcontact.NodalSprings` (or None)
    t_release: float = math.inf   #: the time the pusher stopped (set at the grip)

    def pusher_speed(self, t: float) -> float:
        return self.v_push if t <= self.t_release else 0.0

    def release(self, t: float) -> None:
        self.t_release = t


def build(case: FlatRollingCase, comm=None, output_dir: Optional[str] = None,
          vtk_every: int = 0) -> FlatRollingSetup:
    """The pass set up: mesh with its nose, MINI space, Norton–Hoff, the symmetry conditions,
    the roll (analytic or faceted) with Coulomb–Tresca friction, the pusher, the tail's
    dashpot. ``vtk_every`` > 0 writes the VTK series into ``output_dir`` every so many
    increments."""
    comm = comm or MPI.COMM_WORLD
    R, h0, v_R = float(case.R), float(case.h0), float(case.v_roll)
    h1 = case.h1
    geo = rolling.bite(R, h0, h1)
    L, alpha = geo.contact_length, geo.bite_angle
    x_entry = -R * math.sin(alpha)
    omega = v_R / R
    rate = rolling.mean_strain_rate(R, h0, h1, v_R)
    if case.material is None:
        mat = fx.NortonHoff(K=case.K, m=case.m, regularization=1e-4 * v_R / L)
        sigma0 = mat.flow_stress(rate)
    else:       # the flow stress with its own regularisation; σ0 its mean over the strain
        mat, sigma0 = case.material, case.flow_stress()
    theory = rolling.theory_band(R, h0, h1, sigma0, *case.friction_coefficients(),
                                 b0=case.width)
    # the mesh: front `nose` L inside the bite, length from the travel needed
    x_front = x_entry + case.nose * abs(x_entry)
    length = case.length_factor * L + abs(x_front)
    nx = max(4, int(round(length / case.h_x)))
    msh, ft = strip_mesh(comm, x_front - length, x_front, 0.5 * case.width, 0.5 * h0, nx,
                         int(case.ny), int(case.nz), 0.5 * h1 + R, R)
    sp = fx.MixedSpace(msh)
    sim = fx.Simulation(sp, mat, solver_options=case.solver_options(),
                        output_dir=output_dir if vtk_every else None, name="flat_rolling",
                        output_every=max(1, int(vtk_every or 1)), progress=False)
    f = {k: sim.facets(ft, v) for k, v in fx.BLOCK_TAGS.items()}
    sim.add_velocity_bc(f["ymin"], 0.0, 1)
    sim.add_velocity_bc(f["zmin"], 0.0, 2)
    sag = 0.0
    centre = (0.0, 0.0, 0.5 * h1 + R)
    if case.roll == "analytic":
        roll = fx.Cylinder(centre, (0.0, -1.0, 0.0), R, angular_velocity=omega, name="roll")
    else:
        roll, sag = faceted_roll(R, centre, (-0.1 * case.width, 0.7 * case.width),
                                 case.facet_size or 0.5 * case.h_x, case.roll, omega)
    rc = fx.NodalContact(fx.ContactBoundary(sp, ft, fx.BLOCK_TAGS["zmax"]), roll,
                         scheme=case.scheme, friction=contact_friction(case.friction),
                         slip_velocity=case.slip_ratio * v_R, name="roll_contact",
                         penalty=case.penalty)
    setup = FlatRollingSetup(case, sim, mat, theory, sigma0, rate, omega, x_entry, x_front,
                             case.push_ratio * v_R * h1 / h0, facet_sag=sag, roll_contact=rc)
    pusher = fx.Plane((x_front - length, 0.0, 0.0), (1.0, 0.0, 0.0),
                      velocity=lambda t: (setup.pusher_speed(t), 0.0, 0.0), name="pusher")
    setup.pusher_contact = fx.NodalContact(
        fx.ContactBoundary(sp, ft, fx.BLOCK_TAGS["xmin"]), pusher, scheme=case.scheme,
        name="pusher_contact", penalty=case.penalty)
    sim.add_contributor(rc)
    sim.add_contributor(setup.pusher_contact)
    if case.heat is not None:   # the symmetry planes y = 0 and z = 0 insulated
        case.heat.attach(sim, ft, [fx.BLOCK_TAGS[k] for k in ("zmax", "ymax", "xmax", "xmin")],
                         [t.name for c in (rc, setup.pusher_contact) for t in c.tools])
    # the tail's pseudo-inertia: c (v − v̄_prev), v̄_prev its mean velocity of the last increment
    setup.tail = fx.ContactBoundary(sp, ft, fx.BLOCK_TAGS["xmin"])
    c_tail = case.tail_damping * sigma0 / v_R
    if c_tail > 0:
        setup.damper = fx.NodalSprings(setup.tail, c_tail)
        sim.add_contributor(setup.damper)
    return setup


# ---- one row per increment

def contact_arc(contact, sim):
    """(positions, pressure, friction stress on the strip along x) of a contact's nodes,
    gathered on every rank."""
    comm = contact.boundary.comm
    b = contact.boundary
    x = sim.vertex_positions()[b.vertices]
    tau_x = -contact.nodes.friction_force[:, 0] / np.maximum(b.areas, 1e-300)
    return gather(comm, x), gather(comm, contact.pressures()), gather(comm, tau_x)


class _Measure:
    """The per-increment row of a pass (forces per unit width, forward slip, spread, contact
    length, penetrations, power balance)."""

    def __init__(self, setup: FlatRollingSetup):
        self.s = setup
        sim, case = setup.sim, setup.case
        self.power = PowerBalance(sim, [setup.roll_contact, setup.pusher_contact])
        self.V0 = sim.volume()
        pos0 = sim.vertex_positions()
        self.side = np.abs(pos0[:, 1] - 0.5 * case.width) < 1e-9 * case.width   # y = b0/2
        msh = sim.mesh
        self.nown = msh.topology.index_map(0).size_local
        self.ncell = msh.topology.index_map(3).size_local
        self.L = case.bite.contact_length

    def _damper_power(self, v):
        s = self.s
        if s.damper is None:
            return 0.0
        comm, tail, damper = s.sim.comm, s.tail, s.damper
        vt = v[tail.vertices]
        P = comm.allreduce(float(np.sum(tail.areas[:, None] * damper.k
                                        * (vt - damper.v0) * vt)), op=MPI.SUM)
        n_t = comm.allreduce(len(vt), op=MPI.SUM)
        damper.v0 = comm.allreduce(np.sum(vt, axis=0), op=MPI.SUM) / max(n_t, 1)
        return P

    def __call__(self, res) -> dict:
        s, case, L = self.s, self.s.case, self.L
        sim, rc = s.sim, s.roll_contact
        comm = sim.comm
        r = res.row
        X = sim.vertex_positions()
        v = sim.w.x.array[sim.space.vertex_dofs]
        P_roll = -r["roll_torque"] * s.omega
        P_push = -r["pusher_force_x"] * s.pusher_speed(sim.t)
        P_damp = self._damper_power(v)
        pw = self.power(r, P_roll + P_push, absorbed=P_damp)
        own = np.arange(len(X)) < self.nown
        front = comm.allreduce(float(np.max(X[:, 0], initial=-np.inf)), op=MPI.MAX)
        tail = comm.allreduce(float(np.min(X[:, 0], initial=np.inf)), op=MPI.MIN)
        exitz = own & (X[:, 0] > 0.3 * L) & (X[:, 0] < 1.2 * L)
        n_ex = comm.allreduce(int(np.sum(exitz)), op=MPI.SUM)
        vx = comm.allreduce(float(np.sum(v[exitz, 0])), op=MPI.SUM) / max(n_ex, 1)
        sx = exitz & self.side
        n_sx = comm.allreduce(int(np.sum(sx)), op=MPI.SUM)
        y_mean = comm.allreduce(float(np.sum(X[sx, 1])), op=MPI.SUM) / max(n_sx, 1)
        y_max = comm.allreduce(float(np.max(X[sx, 1], initial=-np.inf)), op=MPI.MAX)
        eps_max = comm.allreduce(float(np.max(sim.strain.x.array[:self.ncell], initial=0.0)),
                                 op=MPI.MAX)
        # distances of the roll's boundary nodes to the true cylinder (whatever the roll's
        # discretisation): the largest penetration, and the largest gap of the nodes in contact
        xb = X[rc.boundary.vertices]
        dist = np.hypot(xb[:, 0], xb[:, 2] - (0.5 * case.h1 + case.R)) - case.R
        pen_cyl = comm.allreduce(float(np.max(-dist, initial=0.0)), op=MPI.MAX)
        gap_cyl = comm.allreduce(float(np.max(dist[rc.pressures() > 0], initial=0.0)),
                                 op=MPI.MAX)
        xa, pa, _ = contact_arc(rc, sim)
        act = pa > 0
        clen = float(np.ptp(xa[act, 0])) if np.any(act) else 0.0
        half_w = 0.5 * (0.5 * case.width + (y_mean if n_sx else 0.5 * case.width))
        return dict(increment=r["increment"], time=sim.t, front=front, tail=tail,
                    force_per_width=r["roll_force_z"] / half_w,
                    torque_per_width=-r["roll_torque"] / half_w,
                    forward_slip=(vx / case.v_roll - 1.0) if n_ex else math.nan,
                    half_width_exit=y_mean if n_sx else math.nan,
                    half_width_exit_max=y_max if n_sx else math.nan,
                    contact_length=clen, contact_nodes=r["roll_contact_nodes"],
                    penetration=r["roll_contact_penetration_true"],
                    penetration_cylinder=pen_cyl, contact_gap_cylinder=gap_cyl,
                    pusher_force=-r["pusher_force_x"], pusher_nodes=r["pusher_contact_nodes"],
                    newton_iterations=r["newton_iterations_all"], cutbacks=r["cutbacks"],
                    wall=r["wall_increment_all"], wall_assembly=r["wall_assembly"],
                    wall_linear_solve=r["wall_linear_solve"], wall_contact=r["wall_contact"],
                    volume_change=r["volume"] / self.V0 - 1.0,
                    min_quality=r["min_quality"], max_strain=eps_max,
                    dissipation=pw["dissipation"], friction_power=pw["friction_power"],
                    roll_power=P_roll, pusher_power=P_push, penalty_power=pw["penalty_power"],
                    damper_power=P_damp, power_balance=pw["power_balance"],
                    power_balance_penalty=pw["power_balance_penalty"],
                    stick=r.get("roll_contact_stick", 0), slip=r.get("roll_contact_slip", 0),
                    **heat_columns(r))


# ---- the result

#: the quantities averaged over the steady window
STEADY_KEYS = ("force_per_width", "torque_per_width", "forward_slip", "half_width_exit",
               "half_width_exit_max", "contact_length", "power_balance",
               "power_balance_penalty", "penetration", "dissipation", "friction_power",
               "roll_power", "penalty_power", "damper_power")

_NAN = math.nan


@dataclass
class FlatRollingResult(SteadyRun):
    """A pass rolled (:func:`run`): the run (status, message, history, steady window), the
    theory band of the pass and, at steady state, the window means of :data:`STEADY_KEYS`
    (forces and torque per unit width of one roll, N/mm and N mm/mm), ratios to the theories,
    spread, neutral point, power balance; ``pictures``: the PNG paths."""

    case: Optional[FlatRollingCase] = None
    theory: dict = field(default_factory=dict)
    sigma0: float = _NAN               #: flow stress at the bite's mean strain rate [MPa]
    mean_strain_rate: float = _NAN     #: (v_R / L) ln(h0 / h1) [1/s]
    h1: float = _NAN                   #: exit thickness [mm]
    contact_length_theory: float = _NAN  #: L = √(R Δh) [mm]
    bite_angle: float = _NAN           #: α [rad]
    facet_sag: float = 0.0             #: a faceted roll's sag [mm]
    force_per_width: float = _NAN      #: roll separating force per unit width [N/mm]
    torque_per_width: float = _NAN     #: driving torque of one roll per width [N mm/mm]
    forward_slip: float = _NAN         #: exit speed / roll speed − 1
    half_width_exit: float = _NAN      #: mean half-width past the exit [mm]
    half_width_exit_max: float = _NAN  #: largest half-width past the exit [mm]
    contact_length: float = _NAN       #: x-extent of the contact nodes [mm]
    penetration: float = _NAN          #: true penetration [mm]
    roll_power: float = _NAN           #: −M ω of the quarter [N mm/s]
    damper_power: float = _NAN         #: the tail's pseudo-inertia [N mm/s]
    force_oscillation: float = _NAN
    force_ratio_band: tuple = (_NAN, _NAN)
    force_ratio_slab: float = _NAN
    torque_ratio_slab: float = _NAN
    forward_slip_ratio_slab: float = _NAN
    spread: float = _NAN
    spread_hill: float = _NAN
    arc: dict = field(default_factory=dict)
    neutral_x: float = _NAN
    neutral_angle: float = _NAN
    pictures: List[str] = field(default_factory=list)

    def report(self) -> str:
        """The summary a process engineer reads."""
        th, c = self.theory, self.case
        lines = [f"status: {self.status}: {self.message} (roll: {c.roll}, scheme: {c.scheme})",
                 f"sigma0 = {self.sigma0:.2f} MPa at the mean strain rate "
                 f"{self.mean_strain_rate:.3f} 1/s; L = {self.contact_length_theory:.2f} mm, "
                 f"tan(alpha) = {th['tan_bite_angle']:.4f}",
                 f"theory P/w [N/mm]: slab {th['slab_force']:.1f}, Sims {th['sims_force']:.1f}, "
                 f"Ford-Alexander {th['ford_alexander_force']:.1f}; slab forward slip "
                 f"{100 * th['slab_forward_slip']:.2f} %, neutral angle "
                 f"{th['slab_neutral_angle']:.4f}; Hill spread "
                 f"{100 * (th['hill_width'] / c.width - 1):.2f} %"]
        if c.material is not None:
            lines.append(f"material: {material_text(c, 'strip')}; sigma0 its mean over the "
                         f"strain (2/sqrt 3) ln(h0/h1) = "
                         f"{2 / math.sqrt(3) * math.log(c.h0 / self.h1):.3f}")
        if self.steady:
            lines += [
                f"steady from increment {self.steady_from} of {self.increments} "
                f"(gripped at t = {self.gripped_at:.4g} s)",
                f"FE P/w = {self.force_per_width:.1f} N/mm: / band min "
                f"{self.force_ratio_band[0]:.3f}, / band max {self.force_ratio_band[1]:.3f}, "
                f"/ slab {self.force_ratio_slab:.3f}",
                f"FE torque/w = {self.torque_per_width:.0f} N mm/mm, / slab "
                f"{self.torque_ratio_slab:.3f}",
                f"forward slip FE {100 * self.forward_slip:.2f} % (/ slab "
                f"{self.forward_slip_ratio_slab:.2f}); neutral angle FE "
                f"{self.neutral_angle:.4f} (bite {self.bite_angle:.4f})",
                f"spread FE {100 * self.spread:.2f} % (Hill {100 * self.spread_hill:.2f} %)",
                f"contact length FE {self.contact_length:.1f} mm (theory "
                f"{self.contact_length_theory:.1f}); penetration {self.penetration:.3g} mm",
                f"power balance (-M w + P_push)/(D + P_f + P_damper) - 1 = "
                f"{100 * self.power_balance:.2f} % (with the penalty work "
                f"{100 * self.power_balance_penalty:.2f} %); force oscillation "
                f"+-{100 * self.force_oscillation:.1f} %"]
        lines += heat_lines(self.history, c.heat, "strip")
        return "\n".join(lines + [self.run_summary()])


def _stations(x, gap):
    """Rows of contact nodes across the width: consecutive sorted x closer than ``gap``."""
    order = np.argsort(x)
    cut = np.nonzero(np.diff(x[order]) > gap)[0] + 1
    return np.split(order, cut)


def _neutral_x(x, tau, gap):
    """x where the friction stress changes sign (+ towards the exit in the entry zone, − after):
    the sign change of the station (row) means, interpolated linearly."""
    if len(x) < 3:
        return math.nan
    st = _stations(x, gap)
    xs = np.array([np.mean(x[i]) for i in st])
    tm = np.array([np.mean(tau[i]) for i in st])
    s = np.nonzero((tm[:-1] > 0) & (tm[1:] <= 0))[0]
    if len(s) == 0:
        return math.nan
    j = int(s[-1])
    return float(xs[j] + (xs[j + 1] - xs[j]) * tm[j] / (tm[j] - tm[j + 1]))


def run(case: FlatRollingCase, comm=None, output_dir: Optional[str] = None,
        pictures: bool = True, vtk_every: int = 0) -> FlatRollingResult:
    """Roll the strip to steady state (or say why not: ``status`` "refused", "lost", "no steady
    state", "failed"). With ``output_dir`` (the same on every rank; None writes nothing) the
    per-increment rows go to ``flat_rolling_diagnostics.csv`` and, at steady state with
    ``pictures``, the PNGs of the arc of contact and of the strain."""
    comm = comm or MPI.COMM_WORLD
    check_output_dir(output_dir, comm)
    s = build(case, comm, output_dir, vtk_every)
    sim, L = s.sim, case.bite.contact_length
    rules = StopRules(
        ("force_per_width", "torque_per_width"),
        window_increments(case.window * L, case.v_roll, case.dt, 4), case.steady_tol,
        settle=case.settle * L, max_increments=int(case.max_increments),
        grip_travel=case.grip_travel * L, front_start=s.x_front,
        tail_limit=s.x_entry - 0.5 * case.h_x, body="strip", zone="bite",
        hints={"refused": f"{law_text(case.friction)} against the bite condition tan(alpha) = "
                          f"{case.bite.max_draft_ratio:.4f}",
               "lost": "with friction alone holding it along x the quasi-static strip has a "
                       "free rigid translation, and this increment converged to the ejected "
                       "solution; reduce dt, refine the bite or raise tail_damping",
               "no steady state": "raise length_factor"})
    out = SteadyMonitor(sim, case.dt, _Measure(s), rules, release=s.release,
                        name="flat rolling").run()
    sim.close()
    res = FlatRollingResult(**out.run_fields(), case=case, theory=s.theory, sigma0=s.sigma0,
                            mean_strain_rate=s.mean_strain_rate, h1=case.h1,
                            contact_length_theory=L, bite_angle=case.bite.bite_angle,
                            facet_sag=s.facet_sag)
    if res.steady:
        _steady_values(res, s)
    rows = res.history
    if comm.rank == 0 and output_dir:
        os.makedirs(output_dir, exist_ok=True)
        with open(os.path.join(output_dir, "flat_rolling_diagnostics.csv"), "w",
                  newline="") as fh:
            wr = csv.DictWriter(fh, fieldnames=list(rows[0]))
            wr.writeheader()
            wr.writerows(rows)
    if res.steady and pictures and output_dir:
        res.pictures = _pictures(comm, sim, res, output_dir)
    return res


def _steady_values(res: FlatRollingResult, s: FlatRollingSetup) -> None:
    th, case = res.theory, res.case
    mean = res.means(STEADY_KEYS)
    for k, v in mean.items():
        setattr(res, k, v)
    res.force_oscillation = res.oscillation("force_per_width")
    res.force_ratio_band = (res.force_per_width / th["force_min"],
                            res.force_per_width / th["force_max"])
    res.force_ratio_slab = res.force_per_width / th["slab_force"]
    res.torque_ratio_slab = res.torque_per_width / th["slab_torque"]
    res.forward_slip_ratio_slab = res.forward_slip / th["slab_forward_slip"]
    res.spread = 2.0 * res.half_width_exit / case.width - 1.0
    res.spread_hill = th["hill_width"] / case.width - 1.0
    # the neutral point: where the friction stress along x changes sign (last increment)
    xa, pa, ta = contact_arc(s.roll_contact, s.sim)
    act = pa > 0
    res.arc = dict(x=xa[act, 0], y=xa[act, 1], p=pa[act], tau=ta[act])
    res.neutral_x = _neutral_x(xa[act, 0], ta[act], 0.25 * case.h_x)
    res.neutral_angle = (math.asin(min(1.0, max(-1.0, -res.neutral_x / case.R)))
                         if math.isfinite(res.neutral_x) else math.nan)


def _pictures(comm, sim, res: FlatRollingResult, out: str):
    """The pressure and friction stress along the arc of contact against the slab solution,
    with the neutral points (``arc_of_contact.png``); the equivalent strain and strain rate near
    the width mid-plane (``strain.png``). Collective; the paths on rank 0."""
    msh = sim.mesh
    nc = msh.topology.index_map(3).size_local
    c2v = compat.cell_vertices(msh)[:nc]
    cen = gather(comm, sim.vertex_positions()[c2v].mean(axis=1))
    eps = gather(comm, sim.strain.x.array[:nc])
    rate = gather(comm, sim.strain_rate.x.array[:nc])
    if comm.rank != 0:
        return []
    plt = pyplot()
    a, c = res.arc, res.case
    slab = rolling.slab(c.R, c.h0, res.h1, res.sigma0, *c.friction_coefficients())
    fig, ax = plt.subplots(figsize=(8, 5))
    xs = -c.R * np.sin(slab.phi)
    ax.plot(xs, slab.pressure, "k-", label="slab pressure (same law)")
    ax.plot(xs, slab.shear, "k--", label="slab friction stress")
    ax.scatter(a["x"], a["p"], s=10, c="tab:blue", alpha=0.5,
               label="FE nodal pressure (every node across the width)")
    ax.scatter(a["x"], a["tau"], s=10, c="tab:red", marker="s", alpha=0.5,
               label="FE nodal friction stress along x")
    sel = _stations(a["x"], 0.25 * c.h_x)
    xs_fe = [np.mean(a["x"][m]) for m in sel]
    ax.plot(xs_fe, [np.mean(a["p"][m]) for m in sel], "o-", c="tab:blue", ms=4,
            label="FE pressure, mean across the width")
    ax.plot(xs_fe, [np.mean(a["tau"][m]) for m in sel], "s-", c="tab:red", ms=4,
            label="FE friction stress, mean across the width")
    ax.axvline(-c.R * math.sin(slab.neutral_angle), color="k", ls=":",
               label="slab neutral point")
    if math.isfinite(res.neutral_x):
        ax.axvline(res.neutral_x, color="tab:red", ls=":", label="FE neutral point")
    ax.axhline(0.0, color="0.6", lw=0.5)
    ax.set_xlabel("x [mm] (exit plane at 0, rolling direction →)")
    ax.set_ylabel("stress on the strip [MPa]")
    ax.set_title(f"Flat rolling at steady state: R = {c.R:g}, {c.h0:g} → {res.h1:.3g} mm, "
                 f"{law_text(c.friction)}")
    ax.legend(fontsize=7, loc="upper left", ncol=2)
    ax.set_ylim(top=1.35 * max(np.max(a["p"]), np.max(slab.pressure)))
    ax.grid(alpha=0.3)
    fig.tight_layout()
    f1 = os.path.join(out, "arc_of_contact.png")
    fig.savefig(f1, dpi=110)
    plt.close(fig)
    fig, axs = plt.subplots(2, 1, figsize=(10, 5), sharex=True)
    near = cen[:, 1] < 0.25 * c.width / 2 + 1e-9        # the cells near the width mid-plane
    for axx, val, lab in ((axs[0], eps, "equivalent strain"),
                          (axs[1], rate, "equivalent strain rate [1/s]")):
        sc = axx.scatter(cen[near, 0], cen[near, 2], c=val[near], s=30, marker="s",
                         cmap="viridis")
        fig.colorbar(sc, ax=axx, label=lab)
        axx.set_ylabel("z [mm] (z = 0: mid-thickness)")
    axs[1].set_xlabel("x [mm] (cells near the width mid-plane, centroids)")
    axs[0].set_title("Equivalent strain and strain rate (quarter strip, side view)")
    fig.tight_layout()
    f2 = os.path.join(out, "strain.png")
    fig.savefig(f2, dpi=110)
    plt.close(fig)
    return [f1, f2]
