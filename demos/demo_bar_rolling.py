# ---
# jupyter:
#   jupytext:
#     text_representation:
#       extension: .py
#       format_name: percent
# ---

# %% [markdown]
# # Three-roll rolling of a round bar (long-product rolling)
#
# The thesis's long-product case (THEORY §12.2): a round bar R0 = 58 mm is rolled to R1 = 48 mm
# in one pass through a stand of **three** grooved rolls at 120°; Norton–Hoff K = 50 MPa·s^m,
# m = 0.03; viscoplastic (Norton) friction α_f = 0.3, q = 0.15 (THEORY §9, K of the material);
# pusher and rolling speed 100 mm/s; bar elements about 9 mm; dt = 1 ms.
#
# **Axes.** The bar axis is z, rolling towards +z. The roll axes lie in the plane z = z_r (the
# exit plane of the stand); roll k sits at the angle θ_k about the bar axis (θ from +x towards
# +y), its axis along the tangent ``(−sin θ_k, cos θ_k, 0)`` at the distance ``d`` from the bar
# axis, turning at ω > 0 so that its surface nearest the bar moves towards +z.
#
# **Pass design (groove and roll gap).** Each roll is a :class:`fxcontact.RevolvedProfile`
# (``RevolvedProfile.grooved_roll``, body outside): a cylindrical barrel of radius R_b with a
# circular groove of radius r_g and depth h_g. In the exit plane the groove's arc is a circle
# of radius r_g about the groove's centre; the roll is placed so that this centre lies **on
# the bar axis**: ``d = R_w + r_g`` with ``R_w = R_b − h_g`` the groove-bottom (working) radius.
# With ``r_g = R1 = 48 mm`` the three grooves are arcs of the circle of radius 48 mm, so the
# **inscribed radius of the roll gap is R1 = 48 mm** exactly. The groove spans ±β about the
# roll's direction (``h_g = r_g (1 − cos β)``, half-width ``r_g sin β``); β < 60° leaves a
# roll gap: beside the groove the barrel shoulders of two neighbouring rolls (straight lines at the
# distance ``p = r_g cos β`` from the axis in the exit plane) meet on the plane between them at
# the corner radius ``r_c = p / cos 60° = 2 r_g cos β``. Default β = 50°: h_g = 17.15 mm,
# r_c = 61.7 mm > R0 (the incoming bar does not reach the corners: the shoulders form open
# "ears" beside each groove, where the spread goes). The groove's edges are rounded with
# ``edge_radius`` = 5 mm (``grooved_roll(..., edge_radius=)``: arcs tangent to the barrel and
# the groove; a sharp edge made an element turn inside out at h = 12 mm, see the results).
# The **groove's opening area** (the pass, enclosed by the three rolls in the exit plane) is
# ``A_pass = 3 [β r_g² + p² (tan 60° − tan β)]`` = 7575 mm² with sharp edges (7579 mm² with
# the 5 mm edge radius: computed from the outline of the rolls, ``pass_outline_of_rolls``)
# against π R1² = 7238 mm² for the inscribed circle. Roll: groove-bottom
# radius **R_w = 180 mm** (barrel radius R_b = R_w + h_g = 197.15 mm); the rolling speed is the
# peripheral speed at the groove bottom, ω = 100/180 rad/s. Bite length at the groove bottom
# ``L_b = √(R_w² − (R_w − (R0 − R1))²)`` = 59.2 mm.
#
# **Models.** ``model="third"`` (default): the sector 0 ≤ θ ≤ 120° of the bar with the roll at
# θ = 60° and the two inclined symmetry planes θ = 0° and θ = 120° (``Simulation.
# add_symmetry_plane``, exact; THEORY §1.6). **Symmetry factors**: the third holds one whole
# roll (its groove and both shoulders lie between the planes), so the force and torque of one
# roll are the third's (factor 1); the whole stand's torque, drive power, axial force and
# pusher force are 3 × the third's. ``model="full"``: the whole bar and the three rolls at 60°,
# 180°, 300°, no symmetry plane. ``mesh="symmetric"`` (default): the third is meshed
# mirror-symmetric about the roll's plane θ = 60° (``drawing_bar(..., symmetric_mesh=True)``)
# and the whole bar is made of three turned copies of it (``replicate=True``): the whole mesh
# has the symmetries of the stand, so the whole model's discrete solution has them too, and
# the third with its symmetry planes must give the same discrete solution (checked to solver
# precision: the test of the inclined planes with contact and friction). ``mesh="gmsh"``:
# plain gmsh meshes of the third and of the whole bar, which differ (the difference of the
# two models is then a discretisation difference).
#
# **Start.** The bar (``drawing_bar``, radius R0, length ``length_factor`` × L_b) is placed with
# its front ``nose`` × L_b inside the bite, and its front part is shaped to the pass (each
# vertex moved radially so that the lateral surface lies on the rolls: the nose, as in the flat
# rolling demo). A rigid :class:`fxcontact.Plane` pusher on the back face moves at
# ``push_ratio`` × the ideal entry speed ``v_R A_pass / A0`` until the bar runs away from it (no
# pusher contact node for two increments: **gripped**); it then stops and the rolls alone drive
# the bar. ``status``: "refused" (not gripped after a push of ``grip_travel`` × L_b), "lost" (no
# roll contact after the release), "no steady state" (tail at the bite, or
# ``max_increments``), "steady" (the front ``settle`` × L_b past the exit and the roll force and
# torque means of two consecutive windows of ``window`` × L_b of roll travel within
# ``steady_tol``; the steady values are the last window's means), "failed" (an increment
# failed after its cut-backs, or an element would invert: the message says which; the history
# up to there is kept and written).
#
# **Measured per increment** (``bar_rolling_{model}_diagnostics.csv`` and the result dict): per
# roll the radial (separating) force ``F·e_r``, the axial force and the torque; contact area, true
# penetration, Newton iterations, wall time, relative volume change, smallest element quality,
# the exit cross-section (area and radii of the bar's section by the plane ``z_r + exit_offset
# × L_b``: exact plane cut of the tetrahedra), plastic dissipation ∫ s:D dV (minus the pressure
# work of the volume correction, THEORY §1.5), friction power and the power balance
# ``(M ω + P_pusher)/(D + P_friction) − 1`` (without the penalty work; ``power_balance_penalty``
# with it). At steady state: the exit section against the pass (fill = A_exit / A_pass, the
# "ears" left open at the roll gaps: the underfill) as a PNG ``exit_section.png``.
#
# Run: ``python demos/demo_bar_rolling.py`` (the thesis size), ``--quick`` (the reduced size of
# the tests), ``--model full``, ``--h``, ``--dt``, ``--compare`` (third and full at the same
# size, a few increments) … (``--help``); on 2 ranks with ``mpirun -n 2``. Outputs in
# ``results/bar_rolling``.
#
# **Results** (implicit scheme, β = 10, third model; serial on a shared, loaded 2-core
# machine, so the wall times are 2–4× those of an idle one; the first two rows in one session):
#
# | size (command) | per roll: radial force / torque | stand torque / power | exit area, fill of the pass (radius at the roll gap) | power bal. | max \|ΔV/V\| | penetration | Newton mean/max | wall |
# |---|---|---|---|---|---|---|---|---|
# | h 16 mm, dt 20 ms, 912 cells, 3868 dofs, edges rounded 5 mm (``--quick``) | 616.9 kN (± 6.8 %) / 21.38 kN m | 64.15 kN m / 35.64 kW | 7512 mm², 99.12 % (57.75 of 61.7 mm) | −1.09 % | 3.2e-5 | 0.12 mm | 19.2 / 153 | 151 s, 88 incr. |
# | same, Newton with bt (``--quick --line_search bt``, the former default) | 616.7 kN (± 5.8 %) / 21.31 kN m | 63.94 kN m / 35.52 kW | 7513 mm², 99.13 % (57.9 of 61.7 mm) | −1.33 % | 3.2e-5 | 0.119 mm | 25.7 / 156 | 221 s, 94 incr. |
# | h 16 mm, dt 20 ms, 912 cells, 3868 dofs, sharp groove edges, m_start 0.3, bt (``--quick --edge_radius 0 --m_start 0.3 --line_search bt``) | 624.8 kN (± 4.5 %) / 21.45 kN m | 64.35 kN m / 35.75 kW | 7569 mm², 99.92 % (60.4 of 61.7 mm) | −0.30 % | 3.4e-5 | 0.136 mm | 30.1 / 166 | 1212 s, 82 incr. |
#
# Default (rounded edges): steady from increment 73 (gripped at t = 0.3025 s; with bt from
# increment 79, gripped at t = 0.315 s, the front 0.8 L_b past the roll axes); contact area of the
# stand 18 862 mm² (bt 18 659); net axial force of the rolls 0 (the bar's ends are free); smallest
# element quality 0.094 (that of the shaped nose at the start). The exit section
# (``results/bar_rolling/exit_section_third.png``) fills the inscribed circle and the grooves and
# spreads into the ears beside the grooves to 57.8 mm of the 61.7 mm corner radius: the
# **underfill** is 0.88 % of the pass area (bt 0.87 %) (the bar lying 0.12 mm inside the rolls
# adds about 0.5 %). With sharp edges the ears filled further (60.4 mm, underfill 0.08 %). The
# expected underfill is the open tip of the ears only, between 0 and the ears' share of the pass
# (4.5 %) — the slow test asserts A_inscribed/A_pass < fill < 1 + perimeter × penetration /
# A_pass.
#
# **Third against the whole model** (``--quick --compare 3``): on the symmetric meshes (the
# default) the per-roll radial force and torque of the third and of each of the whole model's
# three rolls agree to 2e-8 (the solver tolerance) at every increment — far within the 1 %
# acceptance; with independent gmsh meshes of the third and of the whole bar
# (``--quick --compare 3 --mesh gmsh``, 16 mm elements, the first three increments of the
# pusher phase) each roll of the whole model differs from the third's by up to 8.5 % in force
# and 13 % in torque; the three rolls of the whole model differ among themselves by up to 7 %
# in force and their mean differs from the third's by 4–5 %: a discretisation difference
# (16–18 contact nodes per roll at that size), which the symmetric meshes remove.
#
# **Not reached: the thesis size to steady state** (9 mm elements, dt = 1 ms: 4864 cells and 19
# 452 dofs in the third; 0.1 mm of roll travel per increment, ~1600 increments to steady state).
# Measured with bt on its first four increments (``run(max_increments=4)``): 13–20 Newton
# iterations and 15–29 s per increment on the loaded machine, true penetration 0.004 mm, radial
# force 233 kN per roll in the pusher phase — about 10 h to steady state here, so not run.
# Re-measured with the trust region on 2 ranks of the idle machine (``run(max_increments=12)``
# under ``mpirun -n 2``): 6–30 Newton iterations, 1.2–5.7 s per increment (2.9 s on average;
# assembly 51 %, linear solve 40 %, contact 1.3 %), one bt fall-back. At that rate 1600 increments
# take about 1.3 h, but only the pusher phase was timed: once the bar is in the bite, more
# nodes are in contact and the rate may be slower. (With
# ``m_start = 0.3`` its second increment failed after all cut-backs; 0.1, the default since,
# passes; with dt = 5 ms the four increments took 17–28 iterations.) At the test size an increment
# cost ~15 s with 30 Newton iterations on average (bt, more loaded): Newton is the bottleneck of
# this case (m = 0.03: the tangent along the flow is 2 m η, nodes enter the bite at nearly every
# increment, Norton friction with q = 0.15); ``slip_velocity`` and ``regularization`` 10× larger
# did not reduce the iterations (measured over 14 increments).
# **Newton's tangent.** The figures in this docstring were measured with the consistent
# Norton–Hoff tangent; the library's default since is the primal–dual one
# (``SolverOptions.material_tangent``, :mod:`fxcontact.dual`): on ``--quick`` 14.8 Newton
# iterations per increment (max 64) instead of 17.5 (max 116), radial force 617.9 against
# 616.5 kN (±6.8 % oscillation). With bt instead of the trust region it takes 21.4. Since the
# start-up exponent ``m_start`` enters the primal–dual tangent and dual update
# (``NortonHoff.exponent_ufl``) and the trust region starts from rest with the full Newton step
# (``fxcontact.solver.TRUST_RADIUS_FROM_REST``; it used to be cut to 0.2 mm/s and doubled per
# iteration): ``--quick`` 14.4 per increment (max 104), 85 increments in 48 s (1 rank, idle),
# radial force 616.85 kN (±6.7 %), torque 21.36 kN m, fill 99.13 %; the first increment of
# the test size takes 14 iterations instead of 25–29 (``tests/test_bar_rolling.py``).
# **Newton's trust region** (``line_search="trust-region"``, fallback bt; the default): on
# ``--quick`` 19.2 iterations per increment instead of 25.7, 11 cut-backs instead of 25, 151 s
# instead of 221 s, the steady force, torque and exit area within 0.3 % of bt's (far within the ±
# 6 % oscillation); the gain is in the grip and the filling of the bite. Penalty continuation
# (``--penalty_continuation``) does not help here (β = 10 is already soft: f = 0.1 took 2.3× bt's
# iterations over 15 increments); figures in benchmarks/README.md.
#
# **Known problem: sharp groove edges.** With sharp edges (``--edge_radius 0``) and 12 mm
# elements (``--quick --h 12 --edge_radius 0``) the run stopped at t = 0.72 s (increment 41):
# an element at the groove's edge in the bite (centroid r = 46.7 mm, θ = 11°, 51 mm before
# the roll axes) would have turned inside out (``MeshInversionError``; no remeshing in this
# library). The rounded edges (5 mm, the default now) remove the kink the material flows
# around; the 12 mm run was not repeated with them.

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
from fxcontact import compat
from fxcontact.console import add_verbosity_arguments, auto_on_off, configure_logging
from fxcontact.meshing import DRAWING_BAR_TAGS, drawing_bar, sector_plane_normals
from fxcontact.power import (PlasticDissipation, PressurePower, on_configuration,
                             penalty_power)
from fxcontact.simulation import format_wall_split, wall_split
from fxcontact.steady import steady_window

log = logging.getLogger("fxcontact.demo.bar_rolling")

#: the thesis case (lengths mm, stresses MPa, times s)
DEFAULTS = dict(R0=58.0, R1=48.0, groove_angle=50.0, roll_radius=180.0, edge_radius=5.0,
                K=50.0, m=0.03,
                alpha_f=0.3, q=0.15, v_roll=100.0, dt=1.0e-3, h=9.0, length_factor=3.0,
                nose=0.3, push_ratio=0.9, grip_travel=0.6, settle=0.8, window=0.5,
                steady_tol=0.02, exit_offset=0.5, beta=10.0, regularization=1e-3, m_start=0.1,
                slip_velocity=1e-3, model="third", mesh="symmetric",
                scheme="implicit", line_search="trust-region", penalty_continuation=None,
                active_set_prediction="auto",
                max_increments=5000,
                output_dir="results/bar_rolling", pictures=True, comm=None)

#: the reduced size of the tests: coarse elements, large increments, a short bar
QUICK = dict(h=16.0, dt=20.0e-3, length_factor=2.6, settle=0.6, window=0.5)

N_ROLLS = 3


# %% [markdown]
# ## The pass and the rolls

# %%
def pass_geometry(R1, groove_angle_deg, roll_radius, n_rolls=N_ROLLS):
    """Groove and roll-gap design (see the module text): a dict with the groove radius ``r_g``
    (= R1), depth ``h_g``, half-width ``b``, barrel radius ``R_b``, working radius ``R_w``,
    the roll-axis distance ``d``, the shoulder distance ``p``, the corner radius ``r_c`` and
    the pass area ``A_pass``."""
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
    """Closed outline (x, y) of the pass in the exit plane: groove arcs and shoulder lines."""
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


# %% [markdown]
# ## Start-up increment
#
# Newton from the bar at rest with m = 0.03 stalls or needs many cut-backs in the first
# increment (the tangent along the flow is 2 m η, THEORY §1.1, against a penalty and a friction
# tangent sized on the secant; the start-up Newtonian solve does not see the rolls and gives
# the bar at rest). The first increment is therefore solved with the strain-rate sensitivity
# ``m_start`` (0.3), and the following ones, starting from its velocity, with m: the exponent is
# a ``dolfinx.fem.Constant`` in the residual. This changes only the first increment of the
# pusher phase (``m_start = m`` switches it off).

# %%
class _StartupNortonHoff(fx.NortonHoff):
    """Norton–Hoff law whose exponent in the residual is a mesh Constant (``exponent``), set to
    ``m_start`` for the first increment and then to m. The float ``m`` (penalty scaling,
    flow stress) is the material's."""

    def bind(self, mesh, m_value):
        import dolfinx.fem
        object.__setattr__(self, "exponent", dolfinx.fem.Constant(mesh, float(m_value)))

    def exponent_ufl(self):
        return self.exponent


# %% [markdown]
# ## The exit cross-section: exact plane cut of the tetrahedra

# %%
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


def _gather(comm, arr):
    parts = comm.allgather(np.asarray(arr))
    return np.concatenate(parts) if parts else np.asarray(arr)


# %% [markdown]
# ## The run

# %%
def _check(P):
    unknown = set(P) - set(DEFAULTS)
    if unknown:
        raise ValueError(f"unknown parameter(s) {sorted(unknown)}; known: {sorted(DEFAULTS)}")
    P = {**DEFAULTS, **P}
    if not (math.isfinite(P["edge_radius"]) and P["edge_radius"] >= 0):
        raise ValueError(f"edge_radius must be >= 0, got {P['edge_radius']!r}")
    for key in ("R0", "R1", "roll_radius", "K", "v_roll", "dt", "h", "length_factor",
                "alpha_f", "push_ratio", "window", "exit_offset", "beta", "regularization",
                "slip_velocity", "m_start"):
        if not (isinstance(P[key], (int, float)) and math.isfinite(P[key]) and P[key] > 0):
            raise ValueError(f"{key} must be a finite number > 0, got {P[key]!r}")
    if not P["m_start"] <= 1.0:
        raise ValueError(f"m_start must be in (0, 1], got {P['m_start']!r}")
    if not 0.0 < P["R1"] < P["R0"]:
        raise ValueError(f"need 0 < R1 < R0 (a reduction), got R0 = {P['R0']!r}, "
                         f"R1 = {P['R1']!r}")
    if not P["R0"] - P["R1"] < P["roll_radius"]:
        raise ValueError("the draft R0 - R1 must be smaller than the roll radius")
    if not 0.0 < P["nose"] < 1.0:
        raise ValueError(f"nose (fraction of the bite initially filled) must be in (0, 1), "
                         f"got {P['nose']!r}")
    if P["model"] not in ("third", "full"):
        raise ValueError(f"model must be 'third' or 'full', got {P['model']!r}")
    if P["mesh"] not in ("symmetric", "gmsh"):
        raise ValueError(f"mesh must be 'symmetric' or 'gmsh', got {P['mesh']!r}")
    return P


def run(**parameters) -> dict:
    """Roll the bar to steady state (or report why not); returns the result dict.

    Keys: ``status``, ``message``, ``history`` (one dict per increment), the pass geometry
    (``pass_``), and at steady state the window means (``roll_force``, ``roll_torque``,
    ``stand_torque``, ``exit_area``, ``fill``, ``power_balance`` …) and the outputs' paths."""
    P = _check(parameters)
    comm = P["comm"] or MPI.COMM_WORLD
    R0, R1, v_R = float(P["R0"]), float(P["R1"]), float(P["v_roll"])
    geo = pass_geometry(R1, P["groove_angle"], P["roll_radius"])
    Rw = geo["R_w"]
    L = math.sqrt(Rw**2 - (Rw - (R0 - R1)) ** 2)           # bite length at the groove bottom
    omega = v_R / Rw
    third = P["model"] == "third"
    # ---- the bar: front `nose` L inside the bite
    length = P["length_factor"] * L
    z_r = length + (1.0 - P["nose"]) * L
    sym = P["mesh"] == "symmetric"
    if third:
        msh, _, ft = drawing_bar(comm, R0, length, P["h"], sector=120.0, symmetric_mesh=sym)
        thetas = [60.0]
    else:
        msh, _, ft = drawing_bar(comm, R0, length, P["h"], sector=120.0 if sym else None,
                                 replicate=sym)
        thetas = [60.0, 180.0, 300.0]
    rolls = make_rolls(geo, z_r, omega, thetas, P["edge_radius"])
    if P["edge_radius"] > 0:     # the rounded edges open the pass: its area from the rolls
        outline = pass_outline_of_rolls(make_rolls(geo, 0.0, 0.0, [60.0, 180.0, 300.0],
                                                   P["edge_radius"]), 0.0, 2.0 * geo["r_c"])
        geo = {**geo, "A_pass_sharp": geo["A_pass"], "A_pass": polygon_area(outline),
               "outline": outline}
    # the nose: the lateral surface of the front part moved onto the rolls (radial scaling)
    g = msh.geometry.x
    th = np.arctan2(g[:, 1], g[:, 0])
    rs = pass_radius(rolls, th, g[:, 2], R0)
    g[:, :2] *= (rs / R0)[:, None]
    # representative strain rate of the bite: (v_R / L) ln(A0 / A_pass)
    rate = v_R / L * math.log(math.pi * R0**2 / geo["A_pass"])
    mat = _StartupNortonHoff(K=P["K"], m=P["m"], regularization=P["regularization"] * rate)
    mat.bind(msh, P["m_start"])
    sp = fx.MixedSpace(msh)
    out = P["output_dir"]
    opts = fx.SolverOptions(line_search=P["line_search"],
                            active_set_prediction=P["active_set_prediction"],
                            penalty_continuation=P["penalty_continuation"])
    sim = fx.Simulation(sp, mat, solver_options=opts,
                        progress=False)
    if third:
        f = {k: sim.facets(ft, DRAWING_BAR_TAGS[k]) for k in ("symmetry_0", "symmetry_1")}
        normals = sector_plane_normals(120.0)
        sim.add_symmetry_plane(f["symmetry_0"], normals["symmetry_0"], name="sym0")
        sim.add_symmetry_plane(f["symmetry_1"], normals["symmetry_1"], name="sym1")
    friction = {roll.name: fx.Norton(P["alpha_f"], P["q"]) for roll in rolls}
    rc = fx.NodalContact(fx.ContactBoundary(sp, ft, DRAWING_BAR_TAGS["lateral"]), rolls,
                         scheme=P["scheme"], friction=friction,
                         slip_velocity=P["slip_velocity"] * v_R,
                         beta=P["beta"], strain_rate=rate, element_size=P["h"],
                         name="roll_contact")
    A0 = math.pi * R0**2
    v_push = P["push_ratio"] * v_R * geo["A_pass"] / A0
    state = {"t_release": math.inf}
    pusher = fx.Plane((0.0, 0.0, 0.0), (0.0, 0.0, 1.0),
                      velocity=lambda t: (0.0, 0.0, v_push if t <= state["t_release"] else 0.0),
                      name="pusher")
    pc = fx.NodalContact(fx.ContactBoundary(sp, ft, DRAWING_BAR_TAGS["back"]), pusher,
                         scheme=P["scheme"], beta=P["beta"], strain_rate=rate, element_size=P["h"],
                         name="pusher_contact")
    sim.add_contributor(rc)
    sim.add_contributor(pc)
    dissipation = PlasticDissipation(sim)
    pressure_power = PressurePower(sim)
    V0 = sim.volume()
    nc = msh.topology.index_map(3).size_local
    c2v = compat.cell_vertices(msh)[:nc]
    msh.topology.create_connectivity(2, 0)
    f2v = msh.topology.connectivity(2, 0)
    lat = ft.indices[ft.values == DRAWING_BAR_TAGS["lateral"]]
    lat = lat[lat < msh.topology.index_map(2).size_local]
    lat_v = np.array([f2v.links(i) for i in lat], dtype=np.int64).reshape(-1, 3)
    e_r = [np.array([math.cos(math.radians(t)), math.sin(math.radians(t)), 0.0])
           for t in thetas]
    z_exit = z_r + P["exit_offset"] * L
    n_model = 1.0 if third else 3.0            # rolls in the model
    factor = 3.0 if third else 1.0             # model -> whole stand

    rows, status, message = [], "rolling", ""
    gripped_at, steady_from = None, None
    wall0 = time.perf_counter()
    win = max(3, int(math.ceil(P["window"] * L / (v_R * P["dt"]))))
    for it in range(int(P["max_increments"])):
        if it == 1:
            mat.exponent.value = P["m"]    # after the start-up increment
        try:
            res = sim.step(P["dt"])
        except fx.IncrementError as err:   # raised on every rank: no hang
            status, message = "failed", str(err)
            break
        rr = res.row
        X = sim.vertex_positions()
        v = sim.w.x.array[sp.vertex_dofs]
        D = on_configuration(sim, X - rr["dt"] * v, dissipation)
        D -= on_configuration(sim, X - rr["dt"] * v, pressure_power)
        P_pen = penalty_power(rc, v, sim.t) + penalty_power(pc, v, sim.t)
        front = comm.allreduce(float(np.max(X[:, 2], initial=-np.inf)), op=MPI.MAX)
        tail = comm.allreduce(float(np.min(X[:, 2], initial=np.inf)), op=MPI.MIN)
        Fr = [float(np.array([rr[f"{roll.name}_force_{c}"] for c in "xyz"]) @ e)
              for roll, e in zip(rolls, e_r)]
        Fz = [rr[f"{roll.name}_force_z"] for roll in rolls]
        # driving torque of each roll (the history's torque is the one the bar exerts on it)
        M = [-rr[f"{roll.name}_torque"] for roll in rolls]
        Pf = rr.get("roll_contact_friction_power", 0.0)
        P_roll = sum(M) * omega
        P_push = -rr["pusher_force_z"] * (v_push if sim.t <= state["t_release"] else 0.0)
        row = dict(increment=rr["increment"], time=sim.t, front=front - z_r, tail=tail - z_r,
                   roll_force=float(np.mean(Fr)), roll_force_axial=float(np.mean(Fz)),
                   roll_torque=float(np.mean(M)),
                   roll_force_spread=float(np.ptp(Fr) / abs(np.mean(Fr))) if np.mean(Fr) else 0.0,
                   contact_nodes=rr["roll_contact_nodes"], contact_area=rr["roll_contact_area"],
                   penetration=rr["roll_contact_penetration_true"],
                   pusher_force=-rr["pusher_force_z"], pusher_nodes=rr["pusher_contact_nodes"],
                   newton_iterations=rr["newton_iterations_all"], cutbacks=rr["cutbacks"],
                   wall=rr["wall_increment_all"], wall_assembly=rr["wall_assembly"],
                   wall_linear_solve=rr["wall_linear_solve"], wall_contact=rr["wall_contact"],
                   volume_change=rr["volume"] / V0 - 1.0,
                   min_quality=rr["min_quality"], dissipation=D, friction_power=Pf,
                   roll_power=P_roll, pusher_power=P_push, penalty_power=P_pen,
                   power_balance=(P_roll + P_push) / (D + Pf) - 1.0 if D + Pf > 0 else math.nan,
                   power_balance_penalty=(P_roll + P_push) / (D + Pf + P_pen) - 1.0
                   if D + Pf > 0 else math.nan)
        for k, roll in enumerate(rolls):
            row[f"{roll.name}_radial_force"] = Fr[k]
            row[f"{roll.name}_torque"] = M[k]
        if front > z_exit + 0.25 * P["h"]:
            row["exit_area"] = factor * comm.allreduce(section_area(X, c2v, z_exit),
                                                       op=MPI.SUM)
        else:
            row["exit_area"] = math.nan
        rows.append(row)
        if comm.rank == 0:   # progress of a long run (--quiet hides it)
            log.info("bar rolling: t = %.4g s, front %.1f mm, roll force %.4g N, %d Newton its, %.1f s",
                     sim.t, row["front"], row["roll_force"], row["newton_iterations"], row["wall"])
        # ---- grip: the bar runs away from the pusher
        if gripped_at is None:
            if len(rows) >= 2 and rows[-1]["pusher_nodes"] == 0 and rows[-2]["pusher_nodes"] == 0:
                gripped_at = sim.t
                state["t_release"] = sim.t
            elif front - length > P["grip_travel"] * L:
                status = "refused"
                message = (f"the bar refuses to enter: not gripped after a push of "
                           f"{front - length:.3g} mm ({P['grip_travel']} L)")
                break
            continue
        if row["contact_nodes"] == 0:
            status = "lost"
            message = (f"the bar left the rolls at t = {sim.t:.4g} after the pusher let go")
            break
        if tail > z_r - L - 0.5 * P["h"]:
            status = "no steady state"
            message = (f"the bar's tail reached the bite at t = {sim.t:.4g} before a steady "
                       f"state: lengthen the bar (length_factor)")
            break
        steady_from = steady_window(rows, ("roll_force", "roll_torque"), win, P["steady_tol"],
                                    ready=lambda q: q["front"] > P["settle"] * L)
        if steady_from is not None:
            status = "steady"
            break
    else:
        status, message = "no steady state", "max_increments reached"
    wall = time.perf_counter() - wall0
    sim.close()
    if not rows:
        raise RuntimeError(f"bar rolling: no increment converged: {message}")

    result = dict(status=status, message=message, history=rows, pass_=geo, bite_length=L,
                  omega=omega, z_r=z_r, gripped_at=gripped_at, wall=wall,
                  wall_split=wall_split(rows), increments=len(rows),
                  parameters={k: v for k, v in P.items() if k != "comm"},
                  cells=comm.allreduce(nc, op=MPI.SUM), factor=factor, n_model_rolls=n_model,
                  dofs=sp.W.dofmap.index_map.size_global * sp.W.dofmap.index_map_bs,
                  max_volume_change=max(abs(q["volume_change"]) for q in rows),
                  min_quality=min(q["min_quality"] for q in rows),
                  max_penetration=max(q["penetration"] for q in rows),
                  newton_mean=float(np.mean([q["newton_iterations"] for q in rows])),
                  newton_max=int(max(q["newton_iterations"] for q in rows)))
    if status == "steady":
        last = rows[steady_from:]
        mean = {k: float(np.mean([q[k] for q in last])) for k in (
            "roll_force", "roll_force_axial", "roll_torque", "contact_area", "penetration",
            "power_balance", "power_balance_penalty", "dissipation", "friction_power",
            "roll_power", "penalty_power", "exit_area")}
        result.update(mean)
        result["steady_from"] = steady_from
        result["stand_torque"] = 3.0 * mean["roll_torque"]
        result["stand_power"] = factor * mean["roll_power"]
        result["stand_contact_area"] = factor * mean["contact_area"]
        Fw = np.array([q["roll_force"] for q in last])
        result["force_oscillation"] = float(np.ptp(Fw) / (2.0 * np.mean(Fw)))
        result["fill"] = mean["exit_area"] / geo["A_pass"]
        result["fill_inscribed"] = mean["exit_area"] / geo["A_inscribed"]
        # the section outline at the end and its radii
        segs = _gather(comm, section_outline(X, lat_v, z_exit))
        result["outline"] = segs
        pts = segs.reshape(-1, 2)
        rad = np.hypot(pts[:, 0], pts[:, 1])
        ang = np.degrees(np.arctan2(pts[:, 1], pts[:, 0])) % 120.0
        near = np.minimum(ang, 120.0 - ang) < 3.0              # at a roll gap
        result["radius_gap"] = float(np.max(rad[near])) if np.any(near) else math.nan
        result["radius_min"] = float(np.min(rad))
        result["radius_max"] = float(np.max(rad))
    if comm.rank == 0 and out:
        os.makedirs(out, exist_ok=True)
        with open(os.path.join(out, f"bar_rolling_{P['model']}_diagnostics.csv"), "w",
                  newline="") as fh:
            wr = csv.DictWriter(fh, fieldnames=list(rows[0]))
            wr.writeheader()
            wr.writerows(rows)
    if status == "steady" and P["pictures"] and out and comm.rank == 0:
        result["pictures"] = [_section_picture(result, out)]
    return result


# %% [markdown]
# ## Picture of the exit section

# %%
def _section_picture(res, out):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    geo = res["pass_"]
    p = res["parameters"]
    fig, ax = plt.subplots(figsize=(7.5, 7.5))
    P = geo["outline"] if "outline" in geo else pass_outline(geo)
    ax.fill(P[:, 0], P[:, 1], color="0.92", zorder=0, label=f"pass (A = {geo['A_pass']:.0f} mm²)")
    ax.plot(P[:, 0], P[:, 1], "k-", lw=1.2)
    t = np.linspace(0, 2 * np.pi, 361)
    ax.plot(p["R0"] * np.cos(t), p["R0"] * np.sin(t), color="tab:gray", ls="--", lw=1,
            label=f"incoming bar R0 = {p['R0']:g} mm")
    ax.plot(geo["r_g"] * np.cos(t), geo["r_g"] * np.sin(t), color="tab:green", ls=":", lw=1,
            label=f"inscribed circle R1 = {geo['r_g']:g} mm")
    segs = res["outline"]
    third = p["model"] == "third"
    for k in range(3 if third else 1):
        a = math.radians(120.0 * k)
        rot = np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])
        S = segs @ rot.T
        for j, s in enumerate(S):
            ax.plot(s[:, 0], s[:, 1], color="tab:red" if k == 0 else "salmon", lw=2.0,
                    label=(("exit section, modelled third" if third else "exit section")
                           if (j == 0 and k == 0) else
                           ("exit section, turned copies" if (j == 0 and k == 1) else None)))
    for th in (60.0, 180.0, 300.0):
        a = math.radians(th)
        ax.annotate("roll", (1.35 * geo["r_g"] * math.cos(a), 1.35 * geo["r_g"] * math.sin(a)),
                    ha="center", va="center", fontsize=11, color="0.3")
    ax.set_aspect("equal")
    lim = 1.2 * max(p["R0"], geo["r_c"])
    ax.set_xlim(-lim, lim)
    ax.set_ylim(-lim, lim)
    ax.grid(alpha=0.3)
    ax.set_xlabel("x [mm]")
    ax.set_ylabel("y [mm]")
    ax.set_title(f"Three-roll pass R0 {p['R0']:g} → R1 {p['R1']:g} mm: exit section at "
                 f"{p['exit_offset']:g} L past the roll axes\nA_exit = {res['exit_area']:.0f} "
                 f"mm², fill of the pass {100 * res['fill']:.1f} %, "
                 f"radius at the roll gap {res['radius_gap']:.1f} mm (corner {geo['r_c']:.1f})",
                 fontsize=10)
    ax.legend(loc="lower left", fontsize=8)
    fig.tight_layout()
    path = os.path.join(out, f"exit_section_{p['model']}.png")
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


# %% [markdown]
# ## Report

# %%
def report(res) -> str:
    geo = res["pass_"]
    p = res["parameters"]
    lines = [f"status: {res['status']} {res['message']} (model: {p['model']}, h = {p['h']:g} mm,"
             f" dt = {p['dt']:g} s, {res['cells']} cells, {res['dofs']} dofs)",
             f"pass: groove r_g = {geo['r_g']:g} mm, half-angle {math.degrees(geo['beta']):g}"
             f" deg, depth {geo['h_g']:.2f} mm, roll R_w = {geo['R_w']:g} (barrel "
             f"{geo['R_b']:.2f}) mm, corner r_c = {geo['r_c']:.2f} mm; A_pass = "
             f"{geo['A_pass']:.0f} mm2 (inscribed circle {geo['A_inscribed']:.0f}); bite "
             f"length {res['bite_length']:.1f} mm"]
    if res["status"] == "steady":
        lines += [
            f"steady from increment {res['steady_from']} of {res['increments']} (gripped at "
            f"t = {res['gripped_at']:.4g} s)",
            f"per roll: radial force {res['roll_force'] / 1e3:.2f} kN (oscillation "
            f"+-{100 * res['force_oscillation']:.1f} %), axial force "
            f"{res['roll_force_axial'] / 1e3:.2f} kN, torque {res['roll_torque'] / 1e6:.3f} kN m;"
            f" stand torque {res['stand_torque'] / 1e6:.3f} kN m, stand power "
            f"{res['stand_power'] / 1e6:.3f} kW",
            f"exit area {res['exit_area']:.0f} mm2: fill of the pass {100 * res['fill']:.2f} %"
            f" (underfill {100 * (1 - res['fill']):.2f} %), / inscribed circle "
            f"{res['fill_inscribed']:.3f}; radius min {res['radius_min']:.2f}, at the roll gap "
            f"{res['radius_gap']:.2f} (corner {geo['r_c']:.2f}) mm",
            f"contact area (stand) {res['stand_contact_area']:.0f} mm2; true penetration "
            f"{res['penetration']:.3g} mm",
            f"power balance (M w + P_push)/(D + P_f) - 1 = {100 * res['power_balance']:.2f} %"
            f" (with the penalty work {100 * res['power_balance_penalty']:.3f} %)"]
    lines += [f"Newton its mean {res['newton_mean']:.1f} max {res['newton_max']}; wall "
              f"{res['wall']:.0f} s for {res['increments']} increments; max |dV/V| "
              f"{res['max_volume_change']:.2e}; max penetration {res['max_penetration']:.3g} mm;"
              f" min quality {res['min_quality']:.3f}",
              f"wall by part: {format_wall_split(res['wall_split'])}"]
    return "\n".join(lines)


def compare(n_increments=4, **parameters) -> dict:
    """The third and the full model at the same size over ``n_increments`` increments: the
    per-roll radial force, axial force and torque of each increment and their relative
    differences (the full model's three rolls, each, against the third's roll)."""
    kw = {**parameters, "max_increments": n_increments, "pictures": False}
    a = run(**{**kw, "model": "third"})
    b = run(**{**kw, "model": "full"})
    diffs = {}
    for key in ("radial_force", "torque"):
        d = 0.0
        for qa, qb in zip(a["history"], b["history"]):
            ref = qa[f"roll0_{key}"]
            for k in range(3):
                d = max(d, abs(qb[f"roll{k}_{key}"] - ref) / abs(ref))
        diffs[key] = d
    return dict(third=a, full=b, max_rel_diff=diffs)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--quick", action="store_true", help="the reduced size of the tests")
    ap.add_argument("--compare", type=int, default=0, metavar="N",
                    help="third against full model over N increments")
    for k in ("R0", "R1", "groove_angle", "roll_radius", "edge_radius", "m_start", "alpha_f",
              "q", "v_roll", "dt", "h",
              "length_factor", "nose", "settle", "window"):
        ap.add_argument(f"--{k}", type=float)
    ap.add_argument("--max_increments", type=int)
    ap.add_argument("--model", choices=("third", "full"))
    ap.add_argument("--mesh", choices=("symmetric", "gmsh"))
    ap.add_argument("--scheme")
    ap.add_argument("--line_search", choices=fx.LINE_SEARCHES,
                    help="Newton's line search (trust-region: fallback bt)")
    ap.add_argument("--active_set_prediction", type=auto_on_off,
                    help="correct each Newton step for the contact status changes it "
                    "predicts (fxcontact.prediction; default auto: with a direct linear "
                    "solver; line searches only, not the trust region)")
    ap.add_argument("--penalty_continuation", type=float, metavar="F",
                    help="solve first with the contact penalty x F, then with the penalty "
                    "(see fxcontact.SolverOptions)")
    ap.add_argument("--output-dir", dest="output_dir")
    add_verbosity_arguments(ap)
    a = ap.parse_args(argv)
    configure_logging(verbose=a.verbose, quiet=a.quiet)
    kw = dict(QUICK) if a.quick else {}
    kw.update({k: v for k, v in vars(a).items() if k in DEFAULTS and v is not None})
    if a.compare:
        res = compare(a.compare, **kw)
        if MPI.COMM_WORLD.rank == 0:
            for k, v in res["max_rel_diff"].items():
                print(f"third vs full: max relative difference of the per-roll {k}: {v:.2e}")
            for qa, qb in zip(res["third"]["history"], res["full"]["history"]):
                print(f"t = {qa['time']:.4g}: radial force third {qa['roll_force']:.6g} full "
                      f"{qb['roll_force']:.6g} N; torque third {qa['roll_torque']:.6g} full "
                      f"{qb['roll_torque']:.6g} N mm")
        return res
    res = run(**kw)
    if MPI.COMM_WORLD.rank == 0:
        print(report(res))
    return res


if __name__ == "__main__":
    main()
