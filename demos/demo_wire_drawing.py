# ---
# jupyter:
#   jupytext:
#     text_representation:
#       extension: .py
#       format_name: percent
# ---

# %% [markdown]
# # Wire (bar) drawing through a conical die — the thesis's headline case
#
# The case of THEORY §12.2 (Annex A2.1 of the thesis): a round bar of length L = 38 mm is drawn
# from R₀ = 10 mm to R = 7.5 mm (43.75 % reduction of area) at 100 mm/s, frictionless, one
# third of the bar modelled (symmetry planes at θ = 0° and θ = 120° about the axis: the second
# one is inclined, imposed exactly by :meth:`fxcontact.Simulation.add_symmetry_plane`),
# Norton–Hoff K = 445 MPa·s^m, m = 0.016 (a nearly rigid-plastic aluminium alloy). **The
# thesis's material is elasto-viscoplastic (E = 73 GPa, ν = 0.3); the elastic part is left out
# here** (rigid-viscoplastic Norton–Hoff): the drawing stress is then the plastic one, without
# the elastic unloading at the exit. Bar elements 0.75 mm, die facets 0.5 mm, dt = 2.5 ms,
# 0.37 s of process (37 mm of pull) at the thesis size (``size = 1``).
#
# **Die (not in the thesis: our choice).** The thesis gives no die angle. We take a standard
# drawing die: entry cone of semi-angle **α = 10°** (within the usual 6–12° of bar and wire
# drawing), a fillet of radius 2 mm between the cone and the bearing, a **bearing land of
# 2 mm** at R = 7.5 mm and a 20° exit relief (1 mm long) so that the drawn bar does not rub on
# an endless land. The die is the analytic surface of revolution :class:`fxcontact.RevolvedProfile`
# (``--die exact``), or the same surface triangulated on its 120° sector with facets of
# ≈ 0.5 mm (vertices on the exact surface) and projected on the flat facets (``--die flat``,
# Forge's standard) or on Nagata patches (``--die nagata``). The triangulation is by default
# an unstructured gmsh mesh of the revolved profile (``--die_mesh gmsh``, as a die from a CAD
# mesher: its edges cross the paths of the bar's nodes), or the structured, mirror-symmetric
# sector of :meth:`fxcontact.FacetedTool.from_revolved` (``--die_mesh structured``: its edges
# run along the generators and rings, and on a cone its quads are planar, so a node sliding
# down a generator meets no facet edge — the explicit scheme then hardly errs, see
# ``benchmarks/README.md``).
#
# **Start.** The bar is meshed with a pointed nose already through the die: the conical
# transition of the bar has the die's angle and lies 2 % of an element behind the die's cone
# (along the axis), the nose (radius 0.96 R) passes through the bearing and the relief. The
# front face of the nose is pulled at 100 mm/s along +z (the drawing direction is z here, x in
# the thesis); the back face is free (no back tension).
#
# **Contact.** Nodal penalty. ``--penalty gap`` (default): a stiffness on the end-of-increment
# gap, k = ρ(β)/dt_ref with ρ(β) = β η(ε̄̇)/h (THEORY §2.5, η the secant viscosity at the
# die's mean strain rate, dt_ref = ``penalty_dt``, default the run's dt): the penalty
# penetration p/k does not depend on the time step, as in the thesis, whose implicit
# penetration is the same at dt and 4 dt. **β = 100** (not the library's 1e3): a penalty
# penetration of ≈ 0.2 % of h at the reduced size (the thesis's implicit runs penetrate
# 0.0067 mm, 0.9 % of its 0.75 mm elements) for fewer Newton iterations with m = 0.016
# (reduced case, 6 increments: β = 1e3 36 iterations per increment, 2.9e-4 mm; β = 100 21,
# 2.8e-3 mm; identical drawing force to 0.1 %). ``--penalty velocity``: the library's
# default velocity penalty ρ from β (its penetration p dt/ρ grows with dt). Contact
# scheme ``--scheme explicit | quasi-implicit | implicit | implicit-exact`` (the last needs the
# gap Hessian: exact die or Nagata). Friction is optional: ``--mbar`` (Tresca m̄) and/or
# ``--mu`` (Coulomb μ limited by Tresca m̄, default m̄ = 1 then).
#
# **Newton.** Backtracking line search (``--line_search bt``, the default) with the library's
# defaults for m = 0.016: the primal–dual Norton–Hoff tangent (``--material_tangent``,
# :mod:`fxcontact.dual`; the stress as a dual variable at the quadrature points, whose tangent
# stays stiff where a step turns the strain rate) and the active-set prediction of the Newton
# step (``--active_set_prediction``, THEORY §3.6; the grazing contact nodes). Main demo on 2
# ranks, same drawing stress 504.5 MPa: 6.3 Newton iterations per increment (max 11), 31 s
# (21 s since the primal–dual Jacobian is written out, 20 s and 6.4 iterations with the MINI
# quadrature of degree 5, benchmarks/README.md),
# against 9.6 (max 23), 34 s, with the former default (trust region, consistent tangent) and
# 7.9 with the trust region and the primal–dual tangent (the trust region cannot take the
# prediction). ``--quick``: 9.2 against 13.0. ``--penalty_continuation f`` is another option
# (SolverOptions), not better here.
#
# **Measured per increment** (``wire_drawing_diagnostics.csv`` and the result dict): drawing force
# (reaction on the pulled face along z), the **true maximum penetration** (depth of the lateral
# nodes inside the exact die, measured with the analytic profile for every die variant), the
# penetration against the die actually used, contact nodes, Newton iterations, wall time split
# into UFL assembly / linear solve / contact, volume change, smallest element quality.
# **Steady state**: after ``settle`` mm of pull (default one element), the mean drawing force
# over the last window of ``window`` mm of pull and over the window before differ by less than
# ``steady_tol`` (two windows, not the range in one: the nodal force oscillates by a few % as
# the nodes pass the die's kinks; the oscillation is reported); the steady drawing stress
# σ_d = F/A₁ (A₁ the exit area of the modelled third) is the last window's mean, compared
# with the classical band of THEORY §14.2
# computed here with :mod:`fxcontact.forming`: the ideal work σ₀ ln(A₀/A₁) (a lower bound),
# Sachs (with friction) and Avitzur's upper bound, σ₀ = √3 K (√3 ε̄̇)^m at the die's mean
# strain rate. Pictures: the equivalent strain and strain rate on the longitudinal section
# (the θ = 0 symmetry plane) and the contact zone; VTK series of the fields (``--vtk_every``).
#
# **Results** (implicit scheme, exact die, frictionless; σ_d = F/A₁ against the band [ideal,
# Avitzur] computed by the demo; reproduced by the commands in brackets with
# ``--line_search bt --material_tangent consistent``, the former Newton, except the first two
# rows):
#
# | case | dofs | σ_d MPa | / ideal | / Avitzur | osc. | max pen. mm | Newton mean/max |
# |---|---|---|---|---|---|---|---|
# | thesis size, h = 0.75 mm, 0.37 s, 2 ranks (the defaults: 25 min 26 s wall on the idle machine; the former defaults, trust region and consistent tangent: 14.8 / 80, 65 min; see benchmarks/README.md) | 150948 | 499.8 | 1.098 | 0.889 | ±1.1 % | 6.7e-4 | 6.9 / 16 |
# | thesis bar, h = 1.9 mm, 0.1 s, 2 ranks (``--size 0.4 --t_end 0.1``, the main demo, the defaults: 31 s wall, 21 s with the primal–dual Jacobian written out; trust region and consistent tangent 9.6 / 23, 34 s; bt and consistent tangent 13.3 / 47) | 12398 | 504.5 | 1.108 | 0.897 | ±1.3 % | 1.1e-3 | 6.3 / 11 |
# | thesis bar, h = 3 mm, 0.1 s, 2 ranks (``--size 0.25 --t_end 0.1``, 43 s wall) | 3608 | 496.3 | 1.090 | 0.883 | ±7 % | 1.1e-3 | 11.9 / 46 |
# | R₀ 5 → 3.75, h = 1.5 mm (``--quick``) | 3434 | 508.9 | 1.106 | 0.895 | ±3.3 % | 2.8e-3 | 21.3 / 32 |
# | R₀ 5 → 4.25, α = 15° (``--quick --R1 4.25 --alpha 15``) | 3771 | 363.9 | 1.388 | 0.853 | ±6.6 % | 4.2e-3 | 19.1 / 37 |
#
# With friction (``--quick --t_end 0.01``, 2 increments, not yet steady): Tresca m̄ = 0.1
# gives 657 MPa (ideal 460, Avitzur 744), Coulomb μ = 0.05 605 MPa (Sachs 545, Avitzur with
# m̄ = √3 μ 720).
#
# The FE drawing stress is 9–39 % above the ideal work and 11–15 % below Avitzur's bound
# (upper bounds are typically 5–10 % above FE at small angles, THEORY §14.2; these meshes are
# coarse, 3 elements over the radius). The nodal force oscillates by a few % as the nodes pass
# the die's profile points. See ``benchmarks/README.md`` for the scheme/die comparison with
# the thesis's tables and what it shows.
#
# Run: ``python demos/demo_wire_drawing.py`` (thesis size: 25 min on 2 ranks), ``--size 0.4``
# (h = 1.9 mm), ``--quick`` (the reduced size of the tests), ``--die``, ``--scheme``,
# ``--alpha``, ``--R0``, ``--R1`` … (``--help``); on 2 ranks with ``mpirun -n 2``. Outputs in
# ``results/wire_drawing``. The main demo (``bash scripts/setup.sh --demo``) runs
# ``--size 0.4 --t_end 0.1 --vtk_every 10`` on 2 ranks (the thesis size: see benchmarks/README.md).

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
from fxcontact import compat, forming
from fxcontact.console import add_verbosity_arguments, auto_on_off, configure_logging
from fxcontact.simulation import format_wall_split, wall_split
from fxcontact.steady import steady_window
from fxcontact.solver import LINEAR_SOLVERS

log = logging.getLogger("fxcontact.demo.wire_drawing")

#: the thesis case (lengths mm, stresses MPa, times s) and our die
DEFAULTS = dict(R0=10.0, R1=7.5, length=38.0, sector=120.0, K=445.0, m=0.016, speed=100.0,
                alpha=10.0, land=2.0, fillet=2.0, relief_angle=20.0, relief_length=1.0,
                nose_ratio=0.96, h=0.75, facet=0.5, size=1.0, dt=2.5e-3, t_end=0.37,
                die="exact", die_mesh="gmsh", scheme="implicit", penalty="gap", beta=100.0, penalty_dt=None,
                mu=0.0, mbar=0.0, max_it=60, line_search="bt", penalty_continuation=None,
                active_set_prediction="auto", material_tangent="auto",
                linear_solver="auto",
                window=3.0, steady_tol=0.02, settle=None, stop_at_steady=False,
                output_dir="results/wire_drawing", pictures=True, vtk_every=0,
                max_cutbacks=4, comm=None)

#: the reduced size of the tests: R₀ 5 → 3.75 mm (same reduction), h = 1.5 mm, a short bar,
#: 5 ms increments, stop at steady state
QUICK = dict(R0=5.0, R1=3.75, length=18.0, h=1.5, facet=1.0, dt=5e-3, t_end=0.1, land=1.0,
             fillet=1.0, relief_length=0.5, window=1.5, steady_tol=0.02, stop_at_steady=True)

DIES = ("exact", "flat", "nagata")


# %% [markdown]
# ## Geometry: the bar with its nose and the die

# %%
def geometry(P: dict) -> dict:
    """Element size, nose and die placement from the parameters (all ranks alike)."""
    R0, R1 = float(P["R0"]), float(P["R1"])
    a = math.radians(P["alpha"])
    h = P["h"] / P["size"]
    facet = P["facet"] / P["size"]
    nose_r = P["nose_ratio"] * R1
    L_tr = (R0 - nose_r) / math.tan(a)
    relief = math.radians(P["relief_angle"]) if P["relief_angle"] else None
    # the nose must pass the bearing (land, fillet tangent length) and the relief, plus h
    tl = P["fillet"] * math.tan(0.5 * a)
    nose_len = P["land"] + tl + (P["relief_length"] if relief else 0.0) + 1.5 * h \
        - (R1 - nose_r) / math.tan(a)
    nose_len = max(nose_len, 1.5 * h)
    if nose_len + L_tr >= 0.8 * P["length"]:
        raise ValueError(f"the bar (length {P['length']}) is too short for the nose "
                         f"({nose_len:.3g} mm) and the transition ({L_tr:.3g} mm)")
    z_body = P["length"] - nose_len - L_tr
    clearance = 0.02 * h                       # axial gap between the bar's cone and the die's
    entry_radius = R0 + 0.1 * R0
    s0 = z_body + clearance - (entry_radius - R0) / math.tan(a)
    return dict(h=h, facet=facet, nose_radius=nose_r, nose_length=nose_len, L_tr=L_tr,
                z_body=z_body, s0=s0, entry_radius=entry_radius, relief=relief,
                A0=math.radians(P["sector"]) / 2 * R0 ** 2,
                A1=math.radians(P["sector"]) / 2 * R1 ** 2)


def gmsh_die_sector(exact, sector_deg: float, facet: float, extension: float, comm):
    """The die's sector meshed by gmsh (unstructured triangles, size ``facet``): each profile
    segment (entry cone with ``extension`` before it, fillet arc, land, relief with
    ``extension`` after it) revolved by ``sector_deg`` about the axis with OpenCASCADE and
    meshed by the frontal-Delaunay mesher — the triangles are not aligned with the generators
    (as a die from a CAD mesher; the structured :func:`fxcontact.faceted_revolved` sector has
    its edges along the generators and rings). The vertices are moved onto the exact surface;
    the triangles are oriented towards free space. Built on rank 0, broadcast."""
    V = T = None
    if comm.rank == 0:
        pts = np.asarray(exact.points, float)
        arcs = exact.arcs or (None,) * (len(pts) - 1)
        with fx.gmsh_session("die") as gmsh:
            occ = gmsh.model.occ
            curves = []
            n = len(pts) - 1
            for i in range(n):
                p0, p1 = pts[i].copy(), pts[i + 1].copy()
                if arcs[i] is None:
                    u = (p1 - p0) / np.linalg.norm(p1 - p0)
                    if i == 0:
                        p0 = p0 - extension * u
                    if i == n - 1:
                        p1 = p1 + extension * u
                    a = occ.addPoint(p0[1], 0.0, p0[0])
                    b = occ.addPoint(p1[1], 0.0, p1[0])
                    curves.append(occ.addLine(a, b))
                else:   # arc of signed radius r: centre on the left of the chord if r > 0
                    r = arcs[i]
                    c = p1 - p0
                    half = 0.5 * np.linalg.norm(c)
                    left = np.array([-c[1], c[0]]) / (2 * half)
                    ctr = 0.5 * (p0 + p1) + np.sign(r) * math.sqrt(r * r - half * half) * left
                    a = occ.addPoint(p0[1], 0.0, p0[0])
                    b = occ.addPoint(p1[1], 0.0, p1[0])
                    o = occ.addPoint(ctr[1], 0.0, ctr[0])
                    curves.append(occ.addCircleArc(a, o, b))
            occ.revolve([(1, c) for c in curves], 0, 0, 0, 0, 0, 1,
                        math.radians(sector_deg))
            occ.removeAllDuplicates()
            occ.synchronize()
            gmsh.option.setNumber("Mesh.CharacteristicLengthMax", facet)
            gmsh.option.setNumber("Mesh.CharacteristicLengthMin", 0.5 * facet)
            gmsh.option.setNumber("Mesh.Algorithm", 6)
            gmsh.model.mesh.generate(2)
            tags, X, _ = gmsh.model.mesh.getNodes()
            index = {int(t): k for k, t in enumerate(tags)}
            V = X.reshape(-1, 3).copy()
            tri = []
            for et, _, conn in zip(*gmsh.model.mesh.getElements(2)):
                if et == 2:
                    tri.append(np.array([index[int(t)] for t in conn]).reshape(-1, 3))
            T = np.concatenate(tri)
        used = np.unique(T)
        remap = -np.ones(len(V), int)
        remap[used] = np.arange(len(used))
        V, T = V[used], remap[T]
        V = exact.project(V, 0.0, hessian=False).point          # onto the exact surface
        nrm = np.cross(V[T[:, 1]] - V[T[:, 0]], V[T[:, 2]] - V[T[:, 0]])
        free = exact.project(V[T].mean(axis=1), 0.0, hessian=False).normal
        flip = np.einsum("ij,ij->i", nrm, free) < 0
        T[flip] = T[flip][:, [0, 2, 1]]
    return comm.bcast(V, root=0), comm.bcast(T, root=0)


def make_die(P: dict, g: dict, comm=MPI.COMM_WORLD):
    """(exact die, die used, facet sag) — the die used is the exact one or its faceted sector."""
    a = math.radians(P["alpha"])
    exact = fx.RevolvedProfile.die(entry_radius=g["entry_radius"], exit_radius=P["R1"],
                                   half_angle=a, land_length=P["land"],
                                   fillet_radius=P["fillet"], relief_angle=g["relief"],
                                   relief_length=P["relief_length"] if g["relief"] else 0.0,
                                   s0=g["s0"], name="die")
    if P["die"] == "exact":
        return exact, exact, 0.0
    if P["die"] not in DIES:
        raise ValueError(f"die must be one of {DIES}, got {P['die']!r}")
    if P["die_mesh"] == "gmsh":
        V, T = gmsh_die_sector(exact, P["sector"], g["facet"], 2.0 * g["h"], comm)
        tool = fx.FacetedTool(V, T, mode=P["die"], name="die")
        e = np.linalg.norm(V[T[:, 1]] - V[T[:, 0]], axis=1)
        sag = float(np.max(e)) ** 2 / (8.0 * P["R1"])
        return exact, tool, sag
    r_mid = 0.5 * (P["R0"] + P["R1"])
    n_theta = max(2, int(math.ceil(math.radians(P["sector"]) * r_mid / g["facet"])))
    tool = fx.FacetedTool.from_revolved(exact, n_theta, sector=(0.0, P["sector"]),
                                        ds=g["facet"], extension=2.0 * g["h"],
                                        max_angle=g["facet"] / max(P["fillet"], 1e-9)
                                        if P["fillet"] else math.radians(10.0),
                                        mode=P["die"])
    sag = P["R0"] * (1.0 - math.cos(0.5 * math.radians(P["sector"]) / n_theta))
    return exact, tool, sag


# %% [markdown]
# ## Gathered nodal data and pictures

# %%
def _gather(comm, arr):
    parts = comm.allgather(np.asarray(arr))
    return np.concatenate(parts) if parts else np.asarray(arr)


def _true_penetration(comm, exact, contact, sim):
    """Largest depth of the lateral nodes inside the exact die at the current time (all
    ranks; 0 if none is inside)."""
    b = contact.boundary
    X = sim.vertex_positions()[b.vertices]
    gap = exact.project(X, sim.t, hessian=False).gap if len(X) else np.zeros(0)
    pen = comm.allreduce(float(np.max(-gap, initial=-np.inf)), op=MPI.MAX)
    return max(pen, 0.0)


def _section(comm, sim, ft, tag):
    """Triangles of the θ = 0 symmetry face (the longitudinal section): (z, r) of their
    vertices and the strain and strain rate of the cell behind each (gathered)."""
    msh = sim.mesh
    facets = ft.indices[ft.values == tag]
    msh.topology.create_connectivity(2, 3)
    f2c = msh.topology.connectivity(2, 3)
    tri = compat.entities_to_geometry(msh, 2, facets)
    x = msh.geometry.x
    cells = np.array([f2c.links(f)[0] for f in facets], dtype=np.int64)
    zr = np.stack([x[tri][..., 2], np.hypot(x[tri][..., 0], x[tri][..., 1])], -1)
    return (_gather(comm, zr.reshape(-1, 3, 2)), _gather(comm, sim.strain.x.array[cells]),
            _gather(comm, sim.strain_rate.x.array[cells]))


def _pictures(comm, sim, ft, contact, exact, res, out):
    zr, eps, rate = _section(comm, sim, ft, fx.DRAWING_BAR_TAGS["symmetry_0"])
    b = contact.boundary
    X = _gather(comm, sim.vertex_positions()[b.vertices])
    p = _gather(comm, contact.pressures())
    if comm.rank != 0:
        return None
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.collections import PolyCollection

    P = res["parameters"]
    s = np.linspace(zr[..., 0].min() - 2, zr[..., 0].max() + 2, 800)
    die_r = _die_radius(exact, s)
    fig, axs = plt.subplots(2, 1, figsize=(11, 6.4), sharex=True)
    for ax, val, lab, cmap in ((axs[0], eps, "equivalent strain", "viridis"),
                               (axs[1], rate, "equivalent strain rate [1/s]", "magma")):
        pc = PolyCollection(zr, array=val, cmap=cmap, edgecolors="face", linewidths=0.2)
        ax.add_collection(pc)
        fig.colorbar(pc, ax=ax, label=lab, fraction=0.05, pad=0.01)
        ax.plot(s, die_r, "k-", lw=1.5, label="die (exact profile)")
        ax.set_ylim(0, 1.25 * P["R0"])
        ax.set_aspect("equal")
        ax.set_ylabel("r [mm]")
        ax.legend(loc="upper left", fontsize=8)
    axs[0].set_xlim(zr[..., 0].min() - 1, zr[..., 0].max() + 1)
    axs[1].set_xlabel("z [mm] (drawing direction →)")
    th = res["theory"]
    sd = res["steady_stress"] if res["steady_stress"] is not None else float("nan")
    axs[0].set_title(f"Drawing R₀ {P['R0']:g} → {P['R1']:g} mm, α = {P['alpha']:g}°, "
                     f"t = {res['time']:.3f} s, die {P['die']}, {P['scheme']}: θ = 0 section; "
                     f"σ_d = {sd:.0f} MPa "
                     f"(ideal {th['ideal']:.0f}, Avitzur {th['avitzur']:.0f})", fontsize=9)
    fig.tight_layout()
    f1 = os.path.join(out, "wire_drawing_strain.png")
    fig.savefig(f1, dpi=120)
    plt.close(fig)
    # contact zone: unrolled lateral surface (z, θ) coloured by the pressure, and the force
    fig, axs = plt.subplots(1, 2, figsize=(12, 4.2))
    act = p > 0
    th_deg = np.degrees(np.arctan2(X[:, 1], X[:, 0]))
    axs[0].scatter(X[~act, 2], th_deg[~act], s=3, c="0.8", label="lateral nodes")
    sc = axs[0].scatter(X[act, 2], th_deg[act], s=14, c=p[act], cmap="plasma",
                        label="contact nodes")
    fig.colorbar(sc, ax=axs[0], label="contact pressure [MPa]")
    zc = exact.points[:, 0]
    for zz in zc:
        axs[0].axvline(zz, color="k", lw=0.5, ls=":")
    lo = max(X[act, 2].min() - 3 * res["h"], X[:, 2].min()) if np.any(act) else X[:, 2].min()
    hi = min(X[act, 2].max() + 3 * res["h"], X[:, 2].max()) if np.any(act) else X[:, 2].max()
    axs[0].set_xlim(lo, hi)
    axs[0].set_xlabel("z [mm] (dotted: die profile points)")
    axs[0].set_ylabel("θ [deg]")
    axs[0].set_title(f"contact zone at t = {res['time']:.3f} s ({int(np.sum(act))} nodes)",
                     fontsize=9)
    hist = res["history"]
    t = [q["time"] for q in hist]
    axs[1].plot(t, [q["drawing_stress"] for q in hist], "b.-", label="FE σ_d = F/A₁")
    for key, ls in (("ideal", "--"), ("avitzur", "-.")):
        axs[1].axhline(th[key], color="k", ls=ls, label=f"{key} {th[key]:.0f} MPa")
    if th["mu_ref"] > 0:
        axs[1].axhline(th["sachs"], color="g", ls=":", label=f"Sachs {th['sachs']:.0f} MPa")
    if res.get("steady_from") is not None:
        axs[1].axvspan(hist[res["steady_from"]]["time"], hist[res["steady_to"]]["time"],
                       color="y", alpha=0.3, label="steady window")
    axs[1].set_xlabel("t [s]")
    axs[1].set_ylabel("drawing stress [MPa]")
    axs[1].set_ylim(0, 1.3 * th["avitzur"])
    axs[1].legend(fontsize=8, loc="lower right")
    axs[1].grid(alpha=0.3)
    fig.tight_layout()
    f2 = os.path.join(out, "wire_drawing_contact.png")
    fig.savefig(f2, dpi=110)
    plt.close(fig)
    return [f1, f2]


def _die_radius(exact, s):
    """Radius of the die surface at axial positions s (nearest surface point on rays from
    the axis, by projection of points on the axis side)."""
    pts = np.zeros((len(s), 3))
    pts[:, 0] = 1e-3
    pts[:, 2] = s
    # march outwards: the radius r where the signed distance along the radial line vanishes
    lo, hi = np.full(len(s), 1e-3), np.full(len(s), 3.0 * exact.points[:, 1].max())
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        pts[:, 0] = mid
        g = exact.project(pts, 0.0, hessian=False).gap
        inside = g > 0
        lo = np.where(inside, mid, lo)
        hi = np.where(inside, hi, mid)
    return 0.5 * (lo + hi)


# %% [markdown]
# ## The run

# %%
def _check(P):
    for key in ("R0", "R1", "length", "K", "speed", "alpha", "land", "h", "facet", "size",
                "dt", "t_end", "window", "steady_tol", "sector"):
        v = P[key]
        if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
            raise ValueError(f"{key} must be a finite number > 0, got {v!r}")
    if not P["R1"] < P["R0"]:
        raise ValueError(f"R1 ({P['R1']}) must be smaller than R0 ({P['R0']})")
    if not 0 < P["alpha"] < 45:
        raise ValueError(f"alpha (die semi-angle, degrees) must be in (0, 45), got {P['alpha']}")
    if not 0 < P["nose_ratio"] < 1:
        raise ValueError(f"nose_ratio must be in (0, 1), got {P['nose_ratio']}")
    if not 0 < P["m"] <= 1:
        raise ValueError(f"m must be in (0, 1], got {P['m']}")
    if P["die"] not in DIES:
        raise ValueError(f"die must be one of {DIES}, got {P['die']!r}")
    if P["die_mesh"] not in ("structured", "gmsh"):
        raise ValueError(f"die_mesh must be 'structured' or 'gmsh', got {P['die_mesh']!r}")
    if P["scheme"] not in fx.SCHEMES:
        raise ValueError(f"scheme must be one of {fx.SCHEMES}, got {P['scheme']!r}")
    if P["scheme"] == "implicit-exact" and P["die"] == "flat":
        raise ValueError("implicit-exact needs the gap Hessian: die 'exact' or 'nagata'")
    if P["penalty"] not in ("gap", "velocity"):
        raise ValueError(f"penalty must be 'gap' or 'velocity', got {P['penalty']!r}")
    if not (P["beta"] > 0 and (P["penalty_dt"] is None or P["penalty_dt"] > 0)):
        raise ValueError(f"need beta > 0 and penalty_dt > 0 (or None), got {P['beta']}, "
                         f"{P['penalty_dt']}")
    if P["mu"] < 0 or not 0 <= P["mbar"] <= 1:
        raise ValueError(f"need mu >= 0 and 0 <= mbar <= 1, got {P['mu']}, {P['mbar']}")


def run(**parameters) -> dict:
    """Draw the bar; returns the result dict.

    Keys: ``history`` (one dict per increment), ``theory`` (the band of THEORY §14.2),
    ``steady_stress`` (σ_d = F/A₁ over the steady window, None if no steady state), ratios
    to the ideal work and to Avitzur's bound, ``max_penetration`` (true, against the exact
    die, over the run), ``contact_nodes_0.1`` (at t = 0.1 s, or the last increment before),
    Newton and wall-time figures, ``max_volume_change``, ``min_quality``, the outputs."""
    unknown = set(parameters) - set(DEFAULTS)
    if unknown:
        raise ValueError(f"unknown parameter(s) {sorted(unknown)}; known: {sorted(DEFAULTS)}")
    P = {**DEFAULTS, **parameters}
    _check(P)
    comm = P["comm"] or MPI.COMM_WORLD
    g = geometry(P)
    a = math.radians(P["alpha"])
    # the friction of the references: Sachs needs a Coulomb μ, Avitzur a Tresca m̄; the other
    # one is converted with the pressure p ≈ σ₀ in the die (τ = μp = m̄σ₀/√3: an approximation,
    # stated in the report): Coulomb μ gives m̄ = min(m̄_cap, √3 μ), Tresca m̄ gives μ = m̄/√3
    if P["mu"] > 0:
        mu_ref, mbar_ref = P["mu"], min(P["mbar"] or 1.0, math.sqrt(3) * P["mu"])
    else:
        mu_ref, mbar_ref = P["mbar"] / math.sqrt(3), P["mbar"]
    theory = forming.drawing_theory(P["K"], P["m"], P["R0"], P["R1"], a, P["speed"],
                                    mu=mu_ref, mbar=mbar_ref, land_length=P["land"])
    theory.update(mu_ref=mu_ref, mbar_ref=mbar_ref)
    mat = fx.NortonHoff(K=P["K"], m=P["m"], regularization=1e-3 * theory["strain_rate"])
    msh, _, ft = fx.drawing_bar(comm, P["R0"], P["length"], g["h"],
                                nose_length=g["nose_length"], nose_radius=g["nose_radius"],
                                nose_angle=P["alpha"], sector=P["sector"])
    space = fx.MixedSpace(msh)
    out = P["output_dir"]
    opts = fx.SolverOptions(max_it=int(P["max_it"]), line_search=P["line_search"],
                            active_set_prediction=P["active_set_prediction"],
                            material_tangent=P["material_tangent"],
                            penalty_continuation=P["penalty_continuation"],
                            linear_solver=P["linear_solver"])
    sim = fx.Simulation(space, mat, solver_options=opts,
                        output_dir=out if P["vtk_every"] else None, name="wire_drawing",
                        output_every=max(1, int(P["vtk_every"] or 1)), progress=False)
    f = {k: sim.facets(ft, v) for k, v in fx.DRAWING_BAR_TAGS.items()}
    normals = fx.sector_plane_normals(P["sector"])
    sim.add_symmetry_plane(f["symmetry_0"], normals["symmetry_0"], name="sym0")
    sim.add_symmetry_plane(f["symmetry_1"], normals["symmetry_1"], name="sym1")
    sim.add_velocity_bc(f["front"], P["speed"], 2)
    sim.add_reaction("pull", f["front"])
    exact, die, sag = make_die(P, g, comm)
    friction = None
    if P["mu"] > 0:
        friction = fx.Coulomb(P["mu"], mbar=P["mbar"] or 1.0)
    elif P["mbar"] > 0:
        friction = fx.Tresca(P["mbar"])
    if P["penalty"] == "gap":
        # a stiffness on the end-of-increment gap, k = ρ(β)/dt_ref: the penalty penetration
        # p/k does not depend on dt (the thesis's implicit penetration does not change with
        # 4 dt); ρ(β) = β η(ε̄̇_mean)/h (THEORY §2.5) at the die's mean strain rate
        rho = fx.penalty_from_beta(mat, float(P["beta"]), g["h"],
                                   strain_rate=theory["strain_rate"])
        kw = {"gap_stiffness": rho / float(P["penalty_dt"] or P["dt"])}
    else:
        kw = {"beta": float(P["beta"])}
    contact = fx.NodalContact(fx.ContactBoundary(space, ft, fx.DRAWING_BAR_TAGS["lateral"]),
                              die, scheme=P["scheme"], friction=friction, name="contact", **kw)
    sim.add_contributor(contact)
    dofs = space.W.dofmap.index_map.size_global * space.W.dofmap.index_map_bs
    win = max(3, int(math.ceil(P["window"] / (P["speed"] * P["dt"]) - 1e-9)))
    settle = P["settle"] if P["settle"] is not None else g["h"]
    rows = []
    steady_from = steady_to = None
    wall0 = time.perf_counter()
    status = "completed"
    message = ""
    while sim.t < P["t_end"] - 1e-9 * P["dt"]:
        try:
            res = sim.step(min(P["dt"], P["t_end"] - sim.t),
                           max_cutbacks=int(P["max_cutbacks"]))
        except fx.IncrementError as err:   # MeshInversionError included
            status, message = "failed", str(err)
            break
        r = res.row
        Fz = r["pull_z"]
        rows.append(dict(
            increment=r["increment"], time=r["time"], dt=r["dt"], drawing_force=Fz,
            drawing_stress=Fz / g["A1"],
            penetration_true=_true_penetration(comm, exact, contact, sim),
            penetration_tool=r["contact_penetration_true"], contact_nodes=r["contact_nodes"],
            newton_iterations=r["newton_iterations_all"], cutbacks=r["cutbacks"],
            # Krylov iterations of the converged attempt (over its Newton iterations)
            linear_iterations=r["linear_iterations"],
            newton_iterations_converged=r["newton_iterations"],
            wall=r["wall_increment_all"], wall_assembly=r["wall_assembly"],
            wall_linear_solve=r["wall_linear_solve"], wall_contact=r["wall_contact"],
            volume_change=r["volume_change"], min_quality=r["min_quality"],
            symmetry_violation=r.get("symmetry_violation", 0.0)))
        if comm.rank == 0:   # progress of a long run (--quiet hides it)
            log.info("wire drawing: t = %.4g / %.4g s, F/A1 = %.1f MPa, %d Newton its, %.1f s",
                     sim.t, P["t_end"], rows[-1]["drawing_stress"], rows[-1]["newton_iterations"],
                     rows[-1]["wall"])
        # steady state: two consecutive windows of `window` mm of pull with the same mean force
        # (each window spans element passages: the nodal force oscillates with them)
        travel = P["speed"] * sim.t
        if steady_from is None and travel >= settle:
            steady_from = steady_window(rows, ("drawing_force",), win, P["steady_tol"])
            if steady_from is not None:
                steady_to = len(rows) - 1
                if P["stop_at_steady"]:
                    break
    wall = time.perf_counter() - wall0
    result = dict(status=status, message=message, history=rows, theory=theory,
                  parameters={k: v for k, v in P.items() if k != "comm"}, dofs=dofs,
                  h=g["h"], facet=g["facet"], facet_sag=sag, A1=g["A1"], wall=wall,
                  increments=len(rows), time=sim.t, ranks=comm.size)
    if rows:
        result.update(
            max_penetration=max(q["penetration_true"] for q in rows),
            max_penetration_tool=max(q["penetration_tool"] for q in rows),
            max_volume_change=max(abs(q["volume_change"]) for q in rows),
            min_quality=min(q["min_quality"] for q in rows),
            newton_mean=float(np.mean([q["newton_iterations"] for q in rows])),
            newton_max=int(max(q["newton_iterations"] for q in rows)),
            cutbacks=int(sum(q["cutbacks"] for q in rows)),
            wall_split=wall_split(rows))
        before = [q for q in rows if q["time"] <= 0.1 + 1e-9]
        result["contact_nodes_0.1"] = (before or rows)[-1]["contact_nodes"]
        result["time_0.1"] = (before or rows)[-1]["time"]
    result["steady_from"], result["steady_to"] = steady_from, steady_to
    if steady_from is not None:
        sel = rows[steady_from:steady_to + 1]
        sd = float(np.mean([q["drawing_stress"] for q in sel]))
        result.update(steady_stress=sd, steady_force=sd * g["A1"],
                      ratio_ideal=sd / theory["ideal"], ratio_avitzur=sd / theory["avitzur"],
                      steady_oscillation=float(np.ptp([q["drawing_stress"] for q in sel])
                                               / (2.0 * sd)),
                      steady_time=(sel[0]["time"], sel[-1]["time"]))
    else:
        result.update(steady_stress=None, steady_force=None, ratio_ideal=None,
                      ratio_avitzur=None)
    if comm.rank == 0 and out and rows:
        os.makedirs(out, exist_ok=True)
        with open(os.path.join(out, "wire_drawing_diagnostics.csv"), "w", newline="") as fh:
            wr = csv.DictWriter(fh, fieldnames=list(rows[0]))
            wr.writeheader()
            wr.writerows(rows)
    if P["pictures"] and out and rows:
        result["pictures"] = _pictures(comm, sim, ft, contact, exact, result, out)
    if P["vtk_every"] and out:
        result["vtk"] = os.path.join(out, "wire_drawing.pvd")
    sim.close()
    return result


# %% [markdown]
# ## Report

# %%
def report(res) -> str:
    P, th = res["parameters"], res["theory"]
    lines = [
        f"wire drawing R0 {P['R0']:g} -> {P['R1']:g} mm (reduction {100 * th['reduction']:.2f} "
        f"%), alpha {P['alpha']:g} deg, land {P['land']:g} mm, die {P['die']}, scheme "
        f"{P['scheme']}, mu {P['mu']:g}, mbar {P['mbar']:g}; h {res['h']:.3g} mm, facets "
        f"{res['facet']:.3g} mm, {res['dofs']} dofs, {res['ranks']} rank(s)",
        f"status: {res['status']} {res['message']}; {res['increments']} increments of "
        f"{P['dt']:g} s to t = {res['time']:.4g} s",
        f"theory (THEORY 14.2): sigma0 = {th['sigma0']:.1f} MPa at the die's mean strain rate "
        f"{th['strain_rate']:.3f} 1/s; ideal {th['ideal']:.1f}, Sachs {th['sachs']:.1f}, "
        f"Avitzur {th['avitzur']:.1f} MPa (1.1 x Avitzur {1.1 * th['avitzur']:.1f})"
        + (f"; friction of the references mu {th['mu_ref']:.3g} (Sachs), mbar "
           f"{th['mbar_ref']:.3g} (Avitzur), converted with p = sigma0"
           if th["mu_ref"] > 0 else "")]
    if res["steady_stress"] is not None:
        t0, t1 = res["steady_time"]
        lines.append(f"steady drawing stress F/A1 = {res['steady_stress']:.1f} MPa (t {t0:.3f}-"
                     f"{t1:.3f} s): / ideal {res['ratio_ideal']:.3f}, / Avitzur "
                     f"{res['ratio_avitzur']:.3f}; force on the third {res['steady_force']:.0f} N, "
                     f"oscillation +-{100 * res['steady_oscillation']:.1f} %")
    else:
        last = res["history"][-1]["drawing_stress"] if res["history"] else float("nan")
        lines.append(f"no steady state detected; last drawing stress {last:.1f} MPa")
    if res["history"]:
        ws = res["wall_split"]
        lines += [
            f"max true penetration (exact die) {res['max_penetration']:.3g} mm, against the die "
            f"used {res['max_penetration_tool']:.3g} mm (facet sag {res['facet_sag']:.2g}); "
            f"contact nodes at t = {res['time_0.1']:.3g} s: {res['contact_nodes_0.1']}",
            f"Newton its mean {res['newton_mean']:.1f} max {res['newton_max']}, cut-backs "
            f"{res['cutbacks']}; wall {res['wall']:.0f} s: {format_wall_split(ws)}",
            f"max |dV/V| {res['max_volume_change']:.2e}; min element quality "
            f"{res['min_quality']:.3f}"]
    if res.get("pictures"):
        lines.append("pictures: " + ", ".join(res["pictures"]))
    return "\n".join(lines)


def main(argv=None):
    ap = argparse.ArgumentParser(description="Wire drawing, the thesis case (see the module "
                                 "docstring).")
    ap.add_argument("--quick", action="store_true", help="the reduced size of the tests")
    for k in ("R0", "R1", "length", "K", "m", "speed", "alpha", "land", "fillet", "h",
              "facet", "size", "dt", "t_end", "mu", "mbar", "beta", "penalty_dt", "window",
              "steady_tol"):
        ap.add_argument(f"--{k}", type=float)
    ap.add_argument("--die", choices=DIES)
    ap.add_argument("--die_mesh", choices=("structured", "gmsh"))
    ap.add_argument("--scheme", choices=fx.SCHEMES)
    ap.add_argument("--penalty", choices=("gap", "velocity"))
    ap.add_argument("--max_it", type=int)
    ap.add_argument("--line_search", choices=fx.LINE_SEARCHES,
                    help="globalisation of Newton (default bt, with the active-set prediction "
                    "and the primal-dual tangent; see benchmarks/README.md)")
    ap.add_argument("--linear_solver", choices=sorted(LINEAR_SOLVERS) + ["auto"],
                    help="linear solver preset (default auto: by the problem's size, see "
                    "fxcontact.solver.choose_linear_solver)")
    ap.add_argument("--active_set_prediction", type=auto_on_off,
                    help="correct each Newton step for the contact status changes it "
                    "predicts (fxcontact.prediction; default auto: with a direct linear "
                    "solver; line searches only, not the trust region)")
    ap.add_argument("--material_tangent", choices=fx.MATERIAL_TANGENTS,
                    help="Norton-Hoff tangent of Newton (default auto: primal-dual for m < 1, "
                    "the stress as a dual variable at the quadrature points, fxcontact.dual)")
    ap.add_argument("--penalty_continuation", type=float,
                    help="factor f in (0, 1): each Newton solve first with the penalty x f "
                    "(see fxcontact.SolverOptions); beta x f about 10-30 helps at m = 0.016")
    ap.add_argument("--vtk_every", type=int)
    ap.add_argument("--stop_at_steady", action="store_true", default=None)
    ap.add_argument("--no-pictures", dest="pictures", action="store_false", default=None)
    ap.add_argument("--output-dir", dest="output_dir")
    add_verbosity_arguments(ap)
    a = ap.parse_args(argv)
    configure_logging(verbose=a.verbose, quiet=a.quiet)
    kw = dict(QUICK) if a.quick else {}
    kw.update({k: v for k, v in vars(a).items() if k in DEFAULTS and v is not None})
    res = run(**kw)
    if MPI.COMM_WORLD.rank == 0:
        print(report(res))
    return res


if __name__ == "__main__":
    main()
