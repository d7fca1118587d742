# ---
# jupyter:
#   jupytext:
#     text_representation:
#       extension: .py
#       format_name: percent
# ---

# %% [markdown]
# # Radial ring rolling: driven main roll, idle mandrel fed towards it, guide rolls
#
# The academic cases of the thesis (THEORY §12.1, Annex A1), on a mill of industrial proportion
# (the example of THEORY §14.4, the thesis gives no dimensions): main roll R₁ = 150 mm (driven,
# fixed axis), mandrel R₂ = 40 mm (idle, fed towards the main roll), ring R = 100, r = 60,
# H = 40 mm, two guide rolls R_g = 40 mm.
#
# * **case 1**: Norton–Hoff K = 1900 MPa·s^m, m = 0.14 (as printed; K only scales the forces:
#   with Norton, Tresca-limited Coulomb and β-scaled penalties the velocity field does not depend
#   on K); main roll: viscoplastic friction α_f = 0.5, q = 0.15; mandrel frictionless; main roll
#   20 rpm; mandrel feed 1.5 mm/s (3.0 mm per ring revolution); frictionless axial cone
#   rolls whose gap opens at 0.4 mm/s (``--cones``, see below; off by default, see why).
# * **case 2**: the same material; Coulomb μ = 0.3 limited by Tresca m̄ = 0.6 on the main roll
#   and the mandrel; 60 rpm; feed 1.5 mm/s (1.0 mm per revolution).
#
# **Model.** The upper half of the ring in height (mid-plane z = 0, ``v_z = 0``), the whole plan.
# Tools are analytic cylinders (``--tools faceted``: Nagata-free flat facets of the same
# cylinders, the thesis's "standard"). The main roll's axis is at x = R + R₁, the mandrel's at
# x = r − R₂ + v_f t; the ring turns anticlockwise. The mandrel is an **idle** tool
# (:class:`fxcontact.IdleRotation`): its rotation speed is found at each increment from zero
# torque about its axis (case 2); frictionless (case 1), its ω is undetermined and set to the
# bore's rolling speed for the outputs. **Centring**: two frictionless guide rolls at ±60° from
# the mill line on the main-roll side follow the growing ring (:class:`fxcontact.RingCentring`:
# placed each increment where the outer surface of a ring centred on the mill line is, with the
# measured mean outer radius); they act only against a drift of the centre off the mill line.
# **Configuration update**: ``--update cylindrical`` (default; about the ring's centroid, re-set
# each increment, THEORY §5) or ``cartesian``. The volume correction of the incompressibility
# equation is off by default (``--volume_correction none``) so that the volume drift of each
# update is seen (``global`` hides it).
#
# **Outputs** (``results/ring_rolling``): ``ring_rolling_case{n}.csv`` per increment: outer and
# inner diameters (area means of the surface nodes about the centroid), height (twice the mean z
# of the top face), mean diameter and its volume-constancy prediction V/(πHB), main-roll and
# mandrel forces (whole ring: twice the half model) and torques, the ring's rotation speed, the
# mandrel's ω, its torque and the bore's rolling speed, max penetration, contact nodes per tool,
# Newton iterations, wall time, volume change, ring centre; VTK series with the equivalent
# strain and strain rate (``--vtk_every``); PNGs: top view at four times, diameters and forces
# against time.
#
# Run: ``python demos/demo_ring_rolling.py --case 2`` (two revolutions at the default mesh
# 160 × 4 × 2), ``--quick`` (the short, coarse version of the tests), ``--help`` for the rest;
# on 2 ranks with ``mpirun -n 2``; ``--checkpoint_every n`` writes checkpoints (with the mill's
# controllers) and ``--resume`` continues from the newest one (the demo's CSV and pictures then
# hold the resumed part; ``res["sim_history"]`` and the Simulation's CSV hold all). The
# thesis's three variants (explicit + faceted, explicit + analytic, implicit + analytic with
# the cylindrical update) are compared by
# ``benchmarks/bench_thesis_ring_rolling.py`` (table in ``benchmarks/README.md``).
#
# **Results** (coarse ring 100 × 3 × 1, 30 increments per revolution, one rank on a shared
# machine; K = 1900 MPa as printed, so the forces are ~20× those of a hot steel of σ₀ ≈ 200 MPa):
#
# * case 1, ``--case 1 --n_theta 100 --n_r 3 --n_z 1 --increments_per_rev 30 --revolutions 2``:
#   60 increments, 1.97 revolutions of the nominal ring speed (one increment was cut back;
#   the loop now runs to the requested time), 2439 s. Volume change −0.32 % (cylindrical update,
#   no correction), mean diameter against V/(πHB) within 0.10 % at every increment, outer
#   diameter +4.0 %; main roll radial force (second half) 4236 kN = 1.19 × 2kHLQ (3550 kN);
#   frictionless idle mandrel: torque 2e-8 N mm, its ω set to the bore's rolling speed; centre
#   at most 0.77 mm off the mill line (circumferential spacing 6.3 mm); guide rolls ~10 % of the
#   roll force; max penetration 0.21 mm (β = 1000: penalty compliance), max strain 0.36, max
#   strain rate 3.1 1/s; 30 Newton iterations per increment on average (these figures with the
#   consistent Norton–Hoff tangent; with the primal–dual one, the default since, ``--quick``
#   takes 17.7 instead of 23.8, the same main-roll force). The ring's rotation
#   speed oscillates by ±1–2 % from one increment to the next (the bite holds 2–4 nodes).
# * case 2, ``--case 2 --n_theta 100 --n_r 3 --n_z 1 --increments_per_rev 30 --revolutions
#   0.34``: 11 increments, 0.33 revolution (the idle mandrel with Coulomb friction costs 6–9
#   Newton solves per increment, 1644 s), volume change 1e-10, idle torque ≤ 28 N mm against a
#   tolerance of 89 N mm, mandrel surface / bore speed 0.997, surface slip ≤ 1.2 mm/s (v₀ =
#   0.94 mm/s), main roll force 0.66 × 2kHLQ (still rising), centre ≤ 0.32 mm off the line.
# * case 2 over **two revolutions at the default mesh** 160 × 4 × 2 (``mpirun -n 2 python
#   demos/demo_ring_rolling.py --case 2``, bordered idle mandrel, 60 increments per revolution):
#   120 increments, no failure, 4028 s wall on 2 ranks of a loaded machine (2014 s per
#   revolution), 25.0 Newton iterations per increment (max 39). Volume change −0.036 %
#   (−0.018 %/rev, cylindrical update, no correction); mean diameter against V/(πHB) within
#   0.03 %; outer diameter +1.47 %; main roll radial force (second half) 3413 kN = 1.20 ×
#   2kHLQ (2849 kN); idle mandrel torque ≤ 1e-6 N mm (tolerance up to 148), surface slip
#   ≤ 0.82 mm/s, mandrel surface / bore speed 1.0006; max penetration 0.13 mm (β = 1000),
#   centre ≤ 0.49 mm off the mill line (smallest edge 2.43 mm); max strain 0.17, max strain
#   rate 7.1 1/s.
# * idle mandrel: the case-2 figures above are those of the outer iteration
#   (``--idle_method outer``); the default now eliminates ω inside Newton (``bordered``): one
#   Newton solve per increment, 1.3–2.7× fewer Newton iterations, the same ω and forces
#   (``benchmarks/README.md``). ``--idle_guides`` makes the guide rolls idle with friction too.
#
# **Axial cone rolls** (``--cones`` / ``cones=True``; case 1; case 2 has none, ``--cone_speed``
# adds them to it). The thesis's table gives "ring/cone: sliding (frictionless) contact" and
# "cone: translation along z, 0.4 mm/s", and says the cones are there to stop the material
# rising ("empêcher la matière de remonter"; without them the computed ring rises too much).
# **Interpretation**: the cones hold the height, they do not feed it: the upper cone moves up
# at 0.4 mm/s with the lower one fixed, so the axial gap opens at ``cone_speed`` = 0.4 mm/s
# and the cones limit the height wherever the ring grows faster than that (a negative
# ``cone_speed`` is an axial feed that closes the gap). In the half model the mid-plane is
# the symmetry plane: one cone on the top face, rising at ``cone_speed``/2 (the lower cone
# is its mirror image). Geometry, from the ring's (not tuned to the default ring): an analytic
# cone (:class:`fxcontact.Cone`) of half-angle ``cone_half_angle`` (30°), axis in the
# vertical plane of the mill line inclined by the half-angle so that its lower generatrix
# lies in the top face, apex on the mill line at the ring's centre and pointing away from the
# main roll (the far side); with the apex on the ring's axis a cone turning at ω_ring/sin α
# rolls without slip at every radius. At t = 0 the cone is ``initial_bite`` into the face like
# the radial rolls (the gap is H − 2·initial_bite). The cone is idle and frictionless: its ω
# has no effect and is set after each solve to the rolling speed of its contact nodes;
# :class:`fxcontact.mill.AxialRolls` moves its apex, within each increment, to the projection
# of the ring's centroid on the mill line (the cones retreat as the ring grows). The cone is
# analytic also with ``--tools faceted``. Outputs: ``cone_force`` (axial force of one cone),
# ``nodes_cone``, ``cone_penetration``, ``cone_gap``, ``height_max``, and the estimate
# ``cone_force_estimate`` = 2k·B·L_a of ring-rolling theory with the axial contact length
# L_a = √(2δR_c) (δ the reduction of the half height under the cone less the penalty
# penetration, R_c = s tan α the cone's radius of curvature across the generatrix at the
# mid-wall, k at the axial bite's strain rate). L_a (~1 mm) is much shorter than an element
# (6 mm around on the quick mesh, 4 mm on the default one): the cone bears on one row of
# nodes, and its force is set by the mesh resolution and the penalty more than by L_a.
#
# Measured (one rank on a shared machine; the commands are those of the Run line plus
# ``--cones``):
#
# * ``--quick --case 1 --cones --revolutions 1.2``: 60 increments, no cut-back, Newton 29.6
#   iterations per increment on average (the same as without cones), 1405 s. The cone bears on
#   the face during the initial bite only: 4 increments (0.08 rev), 4 contact nodes, axial
#   force 614 → 135 kN = 6.1, 4.2, 2.6, 1.1 × 2kBL_a as the interference decreases, penetration
#   ≤ 0.035 mm. It then lifts off for good: the gap opens at 0.4 mm/s while the ring's mean
#   height grows at about 0.2 mm/s (40.50 mm at 1.2 rev against a gap of 40.86 mm; the
#   highest top-face node, 41.5 mm, is not under the cone). Volume −0.10 %, outer diameter
#   +2.2 %, main roll force 1.05 × 2kHLQ over the second half.
# * default mesh 160 × 4 × 2, ``--case 1 --cones --revolutions 0.0667``: 4 increments, no
#   cut-back, 18–31 Newton iterations, 5–10 cone contact nodes, axial force 354, 214, 324,
#   187 kN = 2.0, 1.2, 5.7, 2.0 × 2kBL_a, penetration ≤ 0.028 mm.
#
# The cones are **off by default**: with the thesis's opening gap they act only during the
# first 0.08 revolution of these meshes (the modelled ring rises more slowly than 0.4 mm/s),
# the full two revolutions with cones were not run at the default size, and the recorded
# case-1 results and the benchmark of the three contact variants stay those of the radial
# mill.
#
# Not modelled: temperature. With this coarse mesh the bite (L = 15.5 mm in case 1, 8.9 mm in
# case 2) holds only a few nodes around.

# %%
from __future__ import annotations

import argparse
import csv
import logging
import math
import os
import time

import numpy as np
from mpi4py import MPI

import fxcontact as fx
from fxcontact import forming
from fxcontact.console import add_verbosity_arguments, configure_logging

log = logging.getLogger("fxcontact.demo.ring_rolling")
from fxcontact.mill import (AxialRolls, ControlledMotion, IdleRotation, RingAxisUpdate,
                            RingCentring)

#: the thesis's academic cases (THEORY §12.1): lengths mm, stresses MPa, times s
CASES = {1: dict(rpm=20.0, feed_speed=1.5, main_friction=("norton", 0.5, 0.15),
                 mandrel_friction=None, cone_speed=0.4),
         2: dict(rpm=60.0, feed_speed=1.5, main_friction=("coulomb", 0.3, 0.6),
                 mandrel_friction=("coulomb", 0.3, 0.6), cone_speed=None)}

DEFAULTS = dict(case=2, R1=150.0, R2=40.0, R=100.0, r=60.0, H=40.0, Rg=40.0, guide_angle=60.0,
                K=1900.0, m=0.14, n_theta=160, n_r=4, n_z=2, initial_bite=0.05,
                gap_stiffness=None, sticky_gap=0.0, max_it=60, guide_clearance=0.3,
                increments_per_rev=60, revolutions=2.0, update="cylindrical",
                scheme="implicit", tools="analytic", facet_size=None, volume_correction="none",
                mu_bite=0.3, max_increments=100000, output_dir="results/ring_rolling", name=None,
                pictures=True, vtk_every=0, checkpoint_every=0, resume=None,
                cones=False, cone_half_angle=30.0, cone_speed=None, comm=None)
#: how the idle mandrel's rotation speed is found (fxcontact.IdleRotation's method)
DEFAULTS["idle_method"] = "auto"
#: the guide rolls with the mandrel's friction, idle too (one IdleRotation for all idle tools)
DEFAULTS["idle_guides"] = False
#: Newton's relative residual tolerance (SolverOptions.rtol; ‖R‖/‖R₀‖, R₀ that of the
#: increment's predictor: from rest it is large, so a tighter one may be needed to compare
#: runs to 1e-8)
DEFAULTS["newton_rtol"] = 1e-9

#: the reduced size of the tests: coarse ring, a quarter of a revolution
QUICK = dict(n_theta=100, n_r=3, n_z=1, increments_per_rev=50, revolutions=0.2,
             pictures=False)


def _friction(spec):
    if spec is None:
        return fx.Frictionless()
    kind, a, b = spec
    return fx.Norton(alpha_f=a, q=b) if kind == "norton" else fx.Coulomb(a, mbar=b)


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


# %% [markdown]
# ## The run

# %%
def run(**parameters) -> dict:
    """Roll the ring; returns the result dict (``history``: one dict per increment, the
    theory figures, the acceptance measures and the paths of the outputs)."""
    unknown = set(parameters) - set(DEFAULTS)
    if unknown:
        raise ValueError(f"unknown parameter(s) {sorted(unknown)}; known: {sorted(DEFAULTS)}")
    P = {**DEFAULTS, **parameters}
    if P["case"] not in CASES:
        raise ValueError(f"case must be 1 or 2, got {P['case']!r}")
    for key in ("R1", "R2", "R", "r", "H", "Rg", "K", "revolutions"):
        if not (isinstance(P[key], (int, float)) and math.isfinite(P[key]) and P[key] > 0):
            raise ValueError(f"{key} must be a finite number > 0, got {P[key]!r}")
    if not P["R2"] < P["r"] < P["R"]:
        raise ValueError(f"need mandrel R2 < bore r < outer R, got {P['R2']}, {P['r']}, "
                         f"{P['R']}")
    if P["update"] not in ("cylindrical", "cartesian"):
        raise ValueError(f"update must be 'cylindrical' or 'cartesian', got {P['update']!r}")
    if P["tools"] not in ("analytic", "faceted"):
        raise ValueError(f"tools must be 'analytic' or 'faceted', got {P['tools']!r}")
    if not (isinstance(P["cone_half_angle"], (int, float)) and
            0.0 < P["cone_half_angle"] < 60.0):
        raise ValueError(f"cone_half_angle must be in (0, 60) degrees, got "
                         f"{P['cone_half_angle']!r}")
    comm = P["comm"] or MPI.COMM_WORLD
    case = CASES[P["case"]]
    cone_speed = case["cone_speed"] if P["cone_speed"] is None else P["cone_speed"]
    if P["cones"] and cone_speed is None:
        raise ValueError(f"case {P['case']} has no axial rolls: give cone_speed (the opening "
                         f"speed of the axial gap) to add them")
    if P["cones"] and not (isinstance(cone_speed, (int, float)) and math.isfinite(cone_speed)):
        raise ValueError(f"cone_speed must be a finite number, got {cone_speed!r}")
    R1, R2, R, r, H, Rg = (float(P[k]) for k in ("R1", "R2", "R", "r", "H", "Rg"))
    w1 = case["rpm"] * 2.0 * math.pi / 60.0          # main roll, rad/s
    v_s = w1 * R1                                      # its surface speed
    t_rev = 2.0 * math.pi * R / v_s                    # one ring revolution (no slip)
    v_f = case["feed_speed"]
    dh = v_f * t_rev                                   # feed per revolution
    window = forming.ring_rolling_feed_window(R1, R2, R, r, P["mu_bite"])
    L = forming.ring_rolling_contact_length(dh, R1, R2, R, r)
    B0 = R - r
    # representative strain rate of the bite: wall strain dh/B over the bite time L/v_s
    rate = dh / B0 * v_s / L
    mat = fx.NortonHoff(K=P["K"], m=P["m"], regularization=1e-3 * rate)
    sigma0 = float(forming.flow_stress(P["K"], P["m"], rate))
    force_est = forming.ring_rolling_force(sigma0 / math.sqrt(3.0), H, L, B0)
    dt = t_rev / int(P["increments_per_rev"])
    n_inc = int(math.ceil(P["revolutions"] * P["increments_per_rev"] - 1e-9))
    n_inc = min(n_inc, int(P["max_increments"]))
    name = P["name"] or f"ring_rolling_case{P['case']}"
    out = P["output_dir"]

    # ---- ring, upper half (mid-plane z = 0)
    msh, _, ft = fx.structured_ring(comm, R, r, H, int(P["n_theta"]), int(P["n_r"]),
                                    int(P["n_z"]), sector="upper")
    h_theta = 2.0 * math.pi * R / int(P["n_theta"])
    sp = fx.MixedSpace(msh)
    update = RingAxisUpdate((0.0, 0.0, 0.0)) if P["update"] == "cylindrical" else None
    files = bool(P["vtk_every"] or P["checkpoint_every"] or P["resume"])
    sim = fx.Simulation(sp, mat, solver_options=fx.SolverOptions(max_it=int(P["max_it"]),
                                                                 rtol=float(P["newton_rtol"])),
                        kinematics=update,
                        output_dir=out if files else None, name=name,
                        output_every=max(1, int(P["vtk_every"] or 10 ** 9)), progress=False,
                        volume_correction=P["volume_correction"],
                        checkpoint_every=int(P["checkpoint_every"]),
                        overwrite=not P["resume"])
    sim.add_velocity_bc(sim.facets(ft, fx.RING_TAGS["mid_plane"]), 0.0, component=2)

    # ---- tools: main roll (driven, clockwise), mandrel (idle, fed), guide rolls (idle)
    fs = P["facet_size"] or h_theta
    # both rolls start `initial_bite` into the ring (the first increment is the bite-in)
    e0 = float(P["initial_bite"])
    xm = (R + R1 - e0, 0.0, 0.0)
    main = _tool(P["tools"], "main_roll", R1, xm, H,
                 fx.RigidMotion(angular_velocity=-w1, axis_point=xm), fs)
    w2 = v_s * r / (R * R2)                             # bore speed / R2
    xd = (r - R2 + e0, 0.0, 0.0)
    mandrel = _tool(P["tools"], "mandrel", R2, xd, H,
                    ControlledMotion(velocity=(v_f, 0.0, 0.0), angular_velocity=w2,
                                     axis_point=xd), fs)
    phi = math.radians(P["guide_angle"])
    guides = []
    for k, s in enumerate((1.0, -1.0)):
        c = ((R + Rg) * math.cos(phi), s * (R + Rg) * math.sin(phi), 0.0)
        guides.append(_tool(P["tools"], f"guide{k + 1}", Rg, c, H,
                            ControlledMotion(axis_point=c), fs))
    tools = [main, mandrel] + guides
    cone_geo = None
    if P["cones"]:
        # upper axial roll: apex on the mill line at the ring's centre, lower generatrix in the
        # top face (z = H/2, less the initial bite), pointing away from the main roll; the lower
        # axial roll is its mirror image in the mid-plane (the symmetry of the half model)
        alpha = math.radians(P["cone_half_angle"])
        apex = (0.0, 0.0, 0.5 * H - e0)
        w_axis = (-math.cos(alpha), 0.0, math.sin(alpha))
        # rolling without slip on the face: ω_cone sin α = ω_ring (apex on the ring axis)
        w_cone = v_s / R / math.sin(alpha)
        cone = fx.MovedTool(fx.Cone(apex, w_axis, alpha, name="cone"),
                            ControlledMotion(velocity=(0.0, 0.0, 0.5 * cone_speed),
                                             angular_velocity=w_cone, axis_point=apex,
                                             axis=w_axis), name="cone")
        tools.append(cone)
        cone_geo = dict(alpha=alpha, s0=0.5 * r, s1=R + 0.5 * (R - r))
    # the exact (analytic) surfaces of the same tools, moved by the same motions: the true
    # penetration is measured against them for every variant (a faceted tool's vertices lie on
    # them, its flat facets cut inside by up to the sagitta s²/8R)
    exact = [_tool("analytic", t.name, rad, t.motion.axis_point, H, t.motion, fs)
             for t, rad in zip(tools, [R1, R2, Rg, Rg])] + tools[4:]
    friction = {"main_roll": _friction(case["main_friction"])}
    if case["mandrel_friction"] is not None:
        friction["mandrel"] = _friction(case["mandrel_friction"])
        if P["idle_guides"]:
            friction.update({g.name: _friction(case["mandrel_friction"]) for g in guides})
    tags = [fx.RING_TAGS["outer"], fx.RING_TAGS["inner"]]
    if P["cones"]:
        tags.append(fx.RING_TAGS["top"])
    contact = fx.NodalContact(fx.ContactBoundary(sp, ft, tags), tools, scheme=P["scheme"],
                              friction=friction, slip_velocity=1e-3 * v_s, name="mill",
                              gap_stiffness=P["gap_stiffness"],
                              sticky_gap=P["sticky_gap"])
    outer = fx.ContactBoundary(sp, ft, fx.RING_TAGS["outer"])
    inner = fx.ContactBoundary(sp, ft, fx.RING_TAGS["inner"])
    top = fx.ContactBoundary(sp, ft, fx.RING_TAGS["top"])
    centring = RingCentring(outer, guides, [Rg, Rg], [phi, -phi], update=update,
                            clearance=P["guide_clearance"])
    sim.add_controller(centring)
    idle = IdleRotation(contact, [mandrel] + guides if P["idle_guides"] else mandrel,
                        method=P["idle_method"])
    sim.add_controller(idle)
    axial = None
    if P["cones"]:
        # the half model's cone rises at half the opening speed of the axial gap
        axial = sim.add_controller(AxialRolls(contact, [cone], centring, [0.5 * cone_speed]))
    sim.add_contributor(contact)
    if P["resume"]:
        # the state of a checkpoint (True: the newest of this run): fields, geometry, contact,
        # the controllers (guide-roll and mandrel motions, ω, ring centre) and the history
        sim.resume(None if P["resume"] is True else P["resume"])
    V0 = sim.initial_volume
    if not P["resume"]:
        # first guess: the ring turning rigidly at the main roll's surface speed
        x0 = sim.vertex_positions()
        v0 = np.zeros_like(x0)
        v0[:, 0], v0[:, 1] = -x0[:, 1] * v_s / R, x0[:, 0] * v_s / R
        sim.w_prev.x.array[sp.vertex_dofs] = v0
        sim.w_prev.x.scatter_forward()

    def surface_radius(b, c):
        x = sim.vertex_positions()[b.vertices] - c
        num = float(np.sum(b.areas * np.hypot(x[:, 0], x[:, 1])))
        num, den = comm.allreduce(np.array([num, float(np.sum(b.areas))]), op=MPI.SUM)
        return num / den

    def cone_depth():
        """Largest depth of the top-face vertices inside the cone (all ranks)."""
        X = sim.vertex_positions()[top.vertices]
        d = float(np.max(-cone.project(X, sim.t, hessian=False).gap)) if len(X) else 0.0
        return comm.allreduce(d, op=MPI.MAX)

    def top_height(c):
        z = sim.vertex_positions()[top.vertices][:, 2]
        num, den = comm.allreduce(np.array([float(np.sum(top.areas * z)),
                                            float(np.sum(top.areas))]), op=MPI.SUM)
        return 2.0 * num / den

    def ring_omega(c):
        """Least-squares rotation rate of the vertices about the ring axis through c."""
        x = sim.vertex_positions()
        nown = msh.topology.index_map(0).size_local
        v = sim.w.x.array[sp.vertex_dofs][:nown]
        d = x[:nown] - c
        num = float(np.sum(d[:, 0] * v[:, 1] - d[:, 1] * v[:, 0]))
        den = float(np.sum(d[:, 0] ** 2 + d[:, 1] ** 2))
        num, den = comm.allreduce(np.array([num, den]), op=MPI.SUM)
        return num / den

    def exact_depth():
        """Largest depth of the ring's surface vertices inside the exact tools (all ranks)."""
        d = 0.0
        for b in (outer, inner):
            X = sim.vertex_positions()[b.vertices]
            for tool in exact:
                if len(X):
                    d = max(d, float(np.max(-tool.project(X, sim.t, hessian=False).gap)))
        return comm.allreduce(d, op=MPI.MAX)

    def nodes_on(k):
        return comm.allreduce(int(np.sum((contact._tool == k) & (contact._h > 0))), op=MPI.SUM)

    rows, snaps = [], []
    snap_at = sorted(set(int(round(f * n_inc)) for f in (0.0, 1 / 3, 2 / 3, 1.0)))
    c0, _ = centring.measure(sim)
    if 0 in snap_at:
        snaps.append(_snapshot(comm, sim, outer, inner, tools, sim.t, c0))
    wall0 = time.perf_counter()
    status, message = "done", ""
    t_end = P["revolutions"] * t_rev
    for it in range(int(P["max_increments"])):
        if sim.t >= t_end * (1.0 - 1e-9):
            break
        try:
            res = sim.step(min(dt, t_end - sim.t))
        except fx.IncrementError as e:
            status, message = "failed", str(e)
            break
        q = res.row
        c = np.array([q["ring_center_x"], q["ring_center_y"], q["ring_center_z"]])
        Ro, Ri = surface_radius(outer, c), surface_radius(inner, c)
        Hm = top_height(c)
        V = sim.volume()
        w_ring = ring_omega(c)
        row = dict(increment=q["increment"], time=sim.t,
                   revolutions=sim.t / t_rev,
                   outer_diameter=2 * Ro, inner_diameter=2 * Ri, height=Hm,
                   mean_diameter=Ro + Ri,
                   mean_diameter_volume=float(forming.ring_rolling_mean_diameter(
                       2.0 * V, Hm, Ro - Ri)),
                   main_force_x=2 * q["main_roll_force_x"], main_force_y=2 * q["main_roll_force_y"],
                   main_torque=2 * q.get("main_roll_torque", 0.0),
                   mandrel_force_x=2 * q["mandrel_force_x"],
                   mandrel_force_y=2 * q["mandrel_force_y"],
                   mandrel_torque=2 * q.get("mandrel_torque", 0.0),
                   guide_force=2 * math.hypot(q["guide1_force_x"], q["guide1_force_y"])
                   + 2 * math.hypot(q["guide2_force_x"], q["guide2_force_y"]),
                   ring_omega=w_ring, ring_omega_nominal=v_s / Ro,
                   mandrel_omega=q["mandrel_omega"],
                   mandrel_angle=mandrel.motion.angle(sim.t),
                   mandrel_omega_free=q["mandrel_omega_free"],
                   mandrel_idle_torque=2 * q["mandrel_idle_torque"],
                   mandrel_idle_tolerance=2 * q["mandrel_idle_tolerance"],
                   mandrel_surface_slip=q["mandrel_surface_slip"],
                   mandrel_solves=q["mandrel_idle_solves"],
                   bore_speed=w_ring * Ri,
                   penetration=q["mill_penetration_true"],
                   penetration_exact=exact_depth(),
                   nodes_main=nodes_on(0), nodes_mandrel=nodes_on(1),
                   nodes_guides=nodes_on(2) + nodes_on(3),
                   height_max=2 * comm.allreduce(float(np.max(
                       sim.vertex_positions()[top.vertices][:, 2], initial=-np.inf)),
                       op=MPI.MAX),
                   newton_iterations=q["newton_iterations_all"], cutbacks=q["cutbacks"],
                   wall=q["wall_increment_all"], wall_assembly=q["wall_assembly"],
                   wall_linear_solve=q["wall_linear_solve"], wall_contact=q["wall_contact"],
                   volume_change=V / V0 - 1.0,
                   center_x=c[0], center_y=c[1], center_offset=q["ring_center_offset"],
                   max_strain=comm.allreduce(float(np.max(sim.strain.x.array, initial=0.0)),
                                             op=MPI.MAX),
                   max_strain_rate=comm.allreduce(
                       float(np.max(sim.strain_rate.x.array, initial=0.0)), op=MPI.MAX),
                   min_quality=q["min_quality"])
        if P["cones"]:
            row.update(_cone_row(q, nodes_on(4), cone_depth(), Hm, Ro, Ri, w_ring, cone_geo,
                                 P["K"], P["m"]))
        rows.append(row)
        # progress of a long run (one line per increment, rank 0; --quiet hides it)
        if comm.rank == 0:
            log.info("ring rolling: %.3f / %.2f rev, outer D %.2f mm, main force %.4g N, "
                     "%d Newton its, %.1f s", row["revolutions"], P["revolutions"],
                     row["outer_diameter"], math.hypot(row["main_force_x"], row["main_force_y"]),
                     row["newton_iterations"], row["wall"])
        if (it + 1 in snap_at and it + 1 < n_inc) or sim.t >= t_end * (1.0 - 1e-9):
            snaps.append(_snapshot(comm, sim, outer, inner, tools, sim.t, c))
    sim.close()
    wall = time.perf_counter() - wall0

    res = dict(status=status, message=message, parameters={k: v for k, v in P.items()
                                                           if k != "comm"},
               history=rows, t_rev=t_rev, dt=dt, feed_per_rev=dh, feed_speed=v_f,
               window=window, contact_length=L, strain_rate_bite=rate, sigma0=sigma0,
               force_estimate=force_est["force"], Q=force_est["Q"], wall=wall,
               volume_initial=2.0 * V0, h_theta=h_theta, sim_history=list(sim.history),
               cone_geometry=cone_geo, cone_speed=cone_speed if P["cones"] else None)
    res.update(_summary(res, comm, msh))
    paths = {}
    if comm.rank == 0 and out:
        os.makedirs(out, exist_ok=True)
        paths["csv"] = os.path.join(out, f"{name}.csv")
        if rows:
            with open(paths["csv"], "w", newline="") as fh:
                wr = csv.DictWriter(fh, fieldnames=list(rows[0]))
                wr.writeheader()
                wr.writerows(rows)
        if P["pictures"] and rows:
            paths.update(_pictures(res, snaps, out, name))
    res["paths"] = comm.bcast(paths, root=0)
    return res


def _cone_row(q, nodes, depth, Hm, Ro, Ri, w_ring, geo, K, m) -> dict:
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
    est = L_a = k = 0.0
    if delta > 0 and d_eff > 0 and nodes > 0:
        L_a = math.sqrt(2.0 * d_eff * Rc)
        rate = d_eff / (0.5 * Hm) * abs(w_ring) * s_m / L_a
        k = float(forming.flow_stress(K, m, rate)) / math.sqrt(3.0)
        est = 2.0 * k * (Ro - Ri) * L_a
    return dict(cone_force=q["cone_force_z"], cone_force_line=q["cone_force_x"],
                nodes_cone=nodes, cone_penetration=depth, cone_gap=2.0 * za,
                cone_apex_x=q["cone_apex_line"], cone_omega=q["cone_omega"],
                cone_reduction=delta, cone_contact_length=L_a, cone_force_estimate=est)


def _summary(res, comm, msh) -> dict:
    rows = res["history"]
    if not rows:
        return {}
    last = rows[-1]
    n = len(rows)
    second = [q for q in rows if q["revolutions"] > 0.5 * rows[-1]["revolutions"]] or rows
    h_min = comm.allreduce(float(np.min(_edge_lengths(msh), initial=np.inf)), op=MPI.MIN)
    return dict(
        increments=n, revolutions=last["revolutions"],
        volume_change=last["volume_change"],
        volume_drift_per_rev=last["volume_change"] / max(last["revolutions"], 1e-300),
        diameter_volume_error=max(abs(q["mean_diameter"] / q["mean_diameter_volume"] - 1)
                                  for q in rows),
        max_penetration=max(q["penetration"] for q in rows),
        max_penetration_exact=max(q["penetration_exact"] for q in rows),
        max_center_offset=max(q["center_offset"] for q in rows),
        min_edge=h_min,
        max_strain=last["max_strain"], max_strain_rate=max(q["max_strain_rate"] for q in rows),
        newton_mean=float(np.mean([q["newton_iterations"] for q in rows])),
        newton_max=int(max(q["newton_iterations"] for q in rows)),
        main_force_mean=float(np.mean([q["main_force_x"] for q in second])),
        mandrel_torque_max=max(abs(q["mandrel_idle_torque"]) for q in rows),
        mandrel_torque_tol_max=max(q["mandrel_idle_tolerance"] for q in rows),
        mandrel_slip_max=max(abs(q["mandrel_surface_slip"]) for q in rows),
        mandrel_speed_ratio=float(np.mean([q["mandrel_omega"] * res["parameters"]["R2"]
                                           / q["bore_speed"] for q in second])),
        outer_growth=last["outer_diameter"] / (2 * res["parameters"]["R"]) - 1.0,
        **(_cone_summary(rows) if "cone_force" in last else {}),
        wall_per_rev=res["wall"] / max(last["revolutions"], 1e-300))


def _cone_summary(rows) -> dict:
    est = [q for q in rows if q["cone_force_estimate"] > 0 and q["nodes_cone"] > 0]
    return dict(
        cone_force_max=max(q["cone_force"] for q in rows),
        cone_nodes_mean=float(np.mean([q["nodes_cone"] for q in rows])),
        cone_penetration_max=max(q["cone_penetration"] for q in rows),
        cone_force_ratio=(float(np.mean([q["cone_force"] / q["cone_force_estimate"]
                                         for q in est])) if est else float("nan")),
        height_max=max(q["height_max"] for q in rows),
        cone_gap_last=rows[-1]["cone_gap"])


def _edge_lengths(msh):
    from fxcontact import compat
    c2v = compat.cell_vertices(msh)
    x = msh.geometry.x
    e = [np.linalg.norm(x[c2v[:, i]] - x[c2v[:, j]], axis=1)
         for i in range(4) for j in range(i + 1, 4)]
    return np.concatenate(e) if len(c2v) else np.zeros(0)


# %% [markdown]
# ## Pictures

# %%
def _snapshot(comm, sim, outer, inner, tools, t, c):
    """Top-face outline (outer and inner surface nodes, z ≥ 90 % of the top) and the tool
    circles at time t (gathered on rank 0)."""
    X = sim.vertex_positions()
    zmax = comm.allreduce(float(np.max(X[:, 2], initial=-np.inf)), op=MPI.MAX)
    pts = []
    for b in (outer, inner):
        x = X[b.vertices]
        x = x[x[:, 2] > 0.9 * zmax]
        pts.append(np.concatenate(comm.allgather(x[:, :2])))
    circ = []
    for tl in tools:
        a = tl.motion.axis_point_at(t)
        base = getattr(tl, "tool", tl)
        rad = getattr(base, "radius", None)
        if rad is None:
            rad = float(np.max(np.abs(base.vertices[:, 0] - base.vertices[:, 0].mean()))) \
                if hasattr(base, "vertices") else 0.0
        circ.append((tl.name, a[0], a[1], rad, tl.motion.angle(t)))
    return dict(t=t, outer=pts[0], inner=pts[1], tools=circ, center=np.array(c))


def _pictures(res, snaps, out, name) -> dict:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    P = res["parameters"]
    paths = {}
    radii = {"main_roll": P["R1"], "mandrel": P["R2"], "guide1": P["Rg"], "guide2": P["Rg"]}
    n = len(snaps)
    nc = 2 if n > 1 else 1
    nr = (n + nc - 1) // nc
    fig, axs = plt.subplots(nr, nc, figsize=(6.2 * nc, 4.4 * nr), squeeze=False)
    for ax in axs.ravel()[n:]:
        ax.axis("off")
    for ax, s in zip(axs.ravel(), snaps):
        for key, col in (("outer", "C0"), ("inner", "C0")):
            p = s[key]
            if len(p):
                ang = np.arctan2(p[:, 1] - s["center"][1], p[:, 0] - s["center"][0])
                o = np.argsort(ang)
                q = np.vstack([p[o], p[o][:1]])
                ax.plot(q[:, 0], q[:, 1], "-", color=col, lw=1.2)
        for nm, x, y, _, ang in s["tools"]:
            if nm == "cone":
                g = res["cone_geometry"]
                # the upper cone seen from above: its footprint from s0 to s1 along the line
                # (half-opening α about the generatrix), hatched, apex marked
                th = math.atan(math.tan(g["alpha"]) * math.cos(g["alpha"]))
                px = [x - g["s0"] * math.cos(th), x - g["s1"] * math.cos(th),
                      x - g["s1"] * math.cos(th), x - g["s0"] * math.cos(th)]
                py = [y + g["s0"] * math.sin(th), y + g["s1"] * math.sin(th),
                      y - g["s1"] * math.sin(th), y - g["s0"] * math.sin(th)]
                ax.fill(px, py, facecolor="tab:orange", alpha=0.25, edgecolor="tab:orange",
                        hatch="//", lw=1.0, label="cone (above the ring)")
                ax.plot([x, x - g["s1"] * math.cos(th)], [y, y], color="tab:orange", lw=1.2,
                        ls="--")
                ax.plot(x, y, marker="^", color="tab:orange", ms=7)
                continue
            rad = radii.get(nm, 10.0)
            th = np.linspace(0, 2 * np.pi, 200)
            ax.fill(x + rad * np.cos(th), y + rad * np.sin(th), color="0.75", alpha=0.6)
            ax.plot([x, x + rad * math.cos(ang)], [y, y + rad * math.sin(ang)], "k-", lw=0.8)
        ax.plot(*s["center"][:2], "r+", ms=8)
        if any(tl[0] == "cone" for tl in s["tools"]):
            ax.legend(loc="lower left", fontsize=7)
        ax.set_aspect("equal")
        ax.set_xlim(-1.35 * P["R"] - 20, P["R"] + 2 * P["R1"] + 10)
        ax.set_ylim(-1.6 * P["R"], 1.6 * P["R"])
        ax.set_title(f"t = {s['t']:.2f} s ({s['t'] / res['t_rev']:.2f} rev)", fontsize=10)
        ax.tick_params(labelsize=8)
    fig.suptitle(f"ring rolling case {P['case']}: top view (ring top face, tools grey, "
                 f"black line = tool angle"
                 + (", upper cone orange, apex ▲" if res.get("cone_geometry") else "") + ")",
                 fontsize=10)
    fig.tight_layout()
    paths["top_view"] = os.path.join(out, f"{name}_top.png")
    fig.savefig(paths["top_view"], dpi=100)
    plt.close(fig)
    paths["curves"] = curves_png(res, os.path.join(out, f"{name}_curves.png"))
    return paths


def curves_png(res, path) -> str:
    """Diameters, roll forces and rotation speeds against time (also from a saved CSV:
    ``res = {"history": rows, "parameters": {...}, "force_estimate": F}``)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    P = res["parameters"]
    h = res["history"]
    t = np.array([q["time"] for q in h])
    fig, axs = plt.subplots(1, 3, figsize=(15, 4.3))
    ax = axs[0]
    q0 = h[0]
    for key, lab, st in (("outer_diameter", "outer D", "-"), ("inner_diameter", "inner d", "-"),
                         ("mean_diameter", "mean (D+d)/2", "-"),
                         ("mean_diameter_volume", "mean, volume constancy V/(πHB)", "k--")):
        ax.plot(t, [q[key] - q0[key] for q in h], st, label=lab)
    ax.set_xlabel("t [s]")
    ax.set_ylabel("change since the first increment [mm]")
    ax.legend(fontsize=8)
    ax.set_title(f"diameters (initial D = {q0['outer_diameter']:.1f}, "
                 f"d = {q0['inner_diameter']:.1f} mm)", fontsize=10)
    ax = axs[1]
    ax.plot(t, [q["main_force_x"] / 1e3 for q in h], label="main roll, radial")
    ax.plot(t, [-q["mandrel_force_x"] / 1e3 for q in h], label="mandrel, radial")
    ax.plot(t, [q["guide_force"] / 1e3 for q in h], label="guide rolls (sum |F|)")
    if "cone_force" in q0:
        ax.plot(t, [q["cone_force"] / 1e3 for q in h], label="upper cone, axial")
        ax.plot(t, [q["cone_force_estimate"] / 1e3 for q in h], ":",
                label="cone, 2kBL_a estimate")
    ax.axhline(res["force_estimate"] / 1e3, color="k", ls="--", label="2kHLQ estimate")
    ax.set_xlabel("t [s]")
    ax.set_ylabel("force [kN] (whole ring)")
    ax.legend(fontsize=8)
    ax.set_title("roll forces")
    ax = axs[2]
    ax.plot(t, [q["ring_omega"] for q in h], label="ring ω")
    ax.plot(t, [q["ring_omega_nominal"] for q in h], "k--", label="main roll speed / R")
    ax.plot(t, [q["mandrel_omega"] * P["R2"] / max(q["inner_diameter"] / 2, 1e-9) for q in h],
            ":", label="mandrel ω R₂ / r")
    ax.set_xlabel("t [s]")
    ax.set_ylabel("rad/s")
    ax.legend(fontsize=8)
    ax.set_title("rotation speeds")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


# %% [markdown]
# ## Report

# %%
def report(res) -> str:
    P = res["parameters"]
    w = res["window"]
    lines = [
        f"case {P['case']}: ring R = {P['R']}, r = {P['r']}, H = {P['H']} mm; main roll R1 = "
        f"{P['R1']} at {CASES[P['case']]['rpm']:g} rpm, mandrel R2 = {P['R2']} fed at "
        f"{res['feed_speed']} mm/s; mesh {P['n_theta']} x {P['n_r']} x {P['n_z']} (outer "
        f"spacing {res['h_theta']:.2f} mm), {P['update']} update, {P['scheme']} "
        f"contact, {P['tools']} tools",
        f"one ring revolution {res['t_rev']:.3f} s; feed per revolution {res['feed_per_rev']:.3f}"
        f" mm; window (Hawkyard penetration, bite-in with mu = {P['mu_bite']}): "
        f"{w['min']:.3f} - {w['max']:.3f} mm/rev -> "
        f"{'inside' if w['min'] <= res['feed_per_rev'] <= w['max'] else 'OUTSIDE'}",
        f"bite contact length L = {res['contact_length']:.2f} mm, strain rate ~ "
        f"{res['strain_rate_bite']:.3g} 1/s, sigma0 = {res['sigma0']:.0f} MPa, "
        f"2kHLQ = {res['force_estimate'] / 1e3:.1f} kN (Q = {res['Q']:.3f})",
        f"status {res['status']} {res['message']}"]
    if res.get("increments"):
        lines += [
            f"{res['increments']} increments, {res['revolutions']:.2f} revolutions, wall "
            f"{res['wall']:.0f} s ({res['wall_per_rev']:.0f} s/rev); Newton mean "
            f"{res['newton_mean']:.1f} max {res['newton_max']}",
            f"volume change {100 * res['volume_change']:.3f} % "
            f"({100 * res['volume_drift_per_rev']:.3f} %/rev); mean diameter vs V/(pi H B): "
            f"max |error| {100 * res['diameter_volume_error']:.2f} %; outer D growth "
            f"{100 * res['outer_growth']:.2f} %",
            f"main roll radial force (second half mean) {res['main_force_mean'] / 1e3:.1f} kN ="
            f" {res['main_force_mean'] / res['force_estimate']:.2f} x 2kHLQ",
            f"mandrel: max |torque| {res['mandrel_torque_max']:.3g} N mm (tolerance up to "
            f"{res['mandrel_torque_tol_max']:.3g}); surface slip max {res['mandrel_slip_max']:.3g}"
            f" mm/s; mandrel surface / bore speed {res['mandrel_speed_ratio']:.4f}",
            *([f"cones (gap opening {res['cone_speed']} mm/s): axial force max "
               f"{res['cone_force_max'] / 1e3:.1f} kN, {res['cone_nodes_mean']:.1f} contact "
               f"nodes on average, max penetration {res['cone_penetration_max']:.4f} mm, "
               f"force / 2kBL_a {res['cone_force_ratio']:.2f}; max height "
               f"{res['height_max']:.3f} mm, final cone gap {res['cone_gap_last']:.3f} mm"]
              if "cone_force_max" in res else []),
            f"max penetration {res['max_penetration']:.4f} mm; centre off the mill line max "
            f"{res['max_center_offset']:.4f} mm (smallest edge {res['min_edge']:.2f} mm); max "
            f"strain {res['max_strain']:.3f}, max strain rate {res['max_strain_rate']:.3f} 1/s"]
    return "\n".join(lines)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--quick", action="store_true", help="the reduced size of the tests")
    ap.add_argument("--case", type=int, choices=(1, 2))
    for k in ("R1", "R2", "R", "r", "H", "Rg", "K", "m", "revolutions", "facet_size",
              "gap_stiffness",
              "guide_angle", "mu_bite"):
        ap.add_argument(f"--{k}", type=float)
    for k in ("increments_per_rev", "n_theta", "n_r", "n_z"):
        ap.add_argument(f"--{k}", type=int)
    ap.add_argument("--vtk_every", type=int)
    ap.add_argument("--cones", action=argparse.BooleanOptionalAction, default=None,
                    help="axial (cone) rolls (case 1; case 2 needs --cone_speed)")
    ap.add_argument("--cone_half_angle", type=float, help="degrees")
    ap.add_argument("--cone_speed", type=float, help="opening speed of the axial gap, mm/s")
    ap.add_argument("--checkpoint_every", type=int)
    ap.add_argument("--resume", action="store_true", default=None,
                    help="resume from the newest checkpoint of the run in --output-dir")
    ap.add_argument("--update", choices=("cylindrical", "cartesian"))
    ap.add_argument("--scheme", choices=("implicit", "implicit-exact", "quasi-implicit",
                                         "explicit"))
    ap.add_argument("--tools", choices=("analytic", "faceted"))
    ap.add_argument("--volume_correction", choices=("none", "global"))
    ap.add_argument("--idle_method", choices=("auto", "bordered", "outer"),
                    help="idle mandrel: omega eliminated inside Newton, or the outer iteration")
    ap.add_argument("--idle_guides", action="store_true",
                    help="guide rolls with the mandrel's friction, idle too (bordered method)")
    ap.add_argument("--output-dir", dest="output_dir")
    add_verbosity_arguments(ap)
    a = ap.parse_args(argv)
    configure_logging(verbose=a.verbose, quiet=a.quiet)
    kw = dict(QUICK) if a.quick else {}
    kw.update({k: v for k, v in vars(a).items() if k in DEFAULTS and v is not None})
    res = run(**kw)
    if MPI.COMM_WORLD.rank == 0:
        print(report(res))
        for k, p in res["paths"].items():
            print(f"{k}: {p}")
    return res


if __name__ == "__main__":
    main()
