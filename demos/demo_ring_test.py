# ---
# jupyter:
#   jupytext:
#     text_representation:
#       extension: .py
#       format_name: percent
# ---

# %% [markdown]
# # Ring compression test: friction calibration curves against Avitzur's upper bound
#
# A flat ring (outer diameter 60, inner diameter 30, height 20 mm: the 6:3:2 ring) is compressed
# between two flat dies with Tresca friction ``τ = m̄ k`` (THEORY §9; k = σ₀/√3 of the
# Norton–Hoff law at the node's strain rate). With little friction all the material flows
# outwards and the hole grows; with much friction the material near the bore flows inwards and
# the hole shrinks. The change of the inner diameter against the height reduction, for a range
# of m̄, is the classical calibration chart of the ring test; here the FE curves are put next to
# Avitzur's upper-bound curves (THEORY §14.5,
# :func:`fxcontact.theory.forming.ring_compression_upper_bound`).
#
# **Model.** One eighth of the ring (:func:`fxcontact.meshing.ring`, ``sector="eighth"``): a
# quarter in plan (symmetry planes x = 0 and y = 0) and the upper half in height (the mid-plane
# z = 0 is a symmetry plane, u_z = 0). The upper die is a rigid
# :class:`~fxcontact.tools.analytic.Plane` moving down at half the closing speed; the lower
# die is its mirror image. Nodal penalty contact (implicit scheme, implicit friction) on the
# top face; frictionless contact with the same plane on the bore and the outer surface, which
# fold over onto the die at large reductions (in one contact with the top face, the lumped
# area of an edge node would include its share of the lateral surface and inflate its
# friction force). Norton–Hoff ``K = 50 MPa·s^m``, ``m = 0.15`` (as the upsetting demo), MINI
# elements, updated Lagrangian.
#
# **Start-up increment.** The nodal shear flow stress k of the Tresca law is taken from the
# increment's predictor, the previous increment's velocity; the first increment starts from rest
# and gets k at the material's regularisation strain rate (a quarter of the process's k here).
# So the run starts with a short increment (``STARTUP`` = 5 % of the others; its force is not
# reported); the following increments take k from its velocity. (Starting instead from the
# homogeneous field as predictor gives the right k, but Newton's iteration then stalls where
# the slip must reverse, at the neutral radius.)
#
# **Slip regularisation.** The contact's default ``v₀ = 10⁻³ ×`` the process speed of the
# increment (THEORY §9: 10⁻³–10⁻² of the sliding speed); ``slip_velocity`` sets it. Its effect
# on the curves is small (see the results).
#
# **Measured.** The bore is not straight once the ring barrels: with low friction it bulges
# outwards (smallest at the die faces), with high friction inwards (smallest at mid-height).
# Three inner diameters are tracked: the **minimum** over the bore (the one the calibration
# chart uses and the one plotted: it is what a gauge measures), the one at mid-height (the
# nodes of the bore on the mid-plane) and the one at the die face (the bore nodes on the die).
# Each is the mean radius of its nodes (minimum: the smallest node radius), as % change of the
# initial diameter. The die force is reported as ``F/(σ₀ A₀)`` (A₀ the initial annulus, σ₀ at
# the mean strain rate v/T of the current height T) next to the upper bound's ``J/(v σ₀ A₀)``.
#
# **What to expect.** The upper bound assumes a velocity field without barrelling; at low m̄
# the FE ring barrels little and the curves should be close, at high m̄ the FE bore bulges
# inwards and the FE (and measured) curves are known to leave the upper-bound ones. The FE
# force is expected below the upper bound (an upper bound on the power, §14.1).
#
# Run: ``python demos/demo_ring_test.py`` (serial) or ``mpirun -n 2 python demos/...``;
# ``--size`` sets the element size, ``--reduction`` the final height reduction, ``--mbar`` the
# list of friction factors. Outputs in ``results/ring_test``: ``ring_test.png`` (calibration
# chart and forces), ``ring_test.csv`` (FE and upper-bound curves), per m̄ a CSV history and a
# VTK series (``mbar_<m̄>/``).

# %%
from __future__ import annotations

import argparse
import csv
import os
import time

import numpy as np
from mpi4py import MPI

from fxcontact.console import add_verbosity_arguments, configure_logging
from fxcontact.contact.boundary import ContactBoundary
from fxcontact.contact.friction import Tresca
from fxcontact.contact.nodal import NodalContact
from fxcontact.theory.forming import flow_stress, ring_compression_upper_bound
from fxcontact.materials import NortonHoff
from fxcontact.meshing import RING_TAGS, ring
from fxcontact.simulation import Simulation
from fxcontact.newton.solver import SolverOptions
from fxcontact.spaces import MixedSpace
from fxcontact.tools.analytic import Plane

#: default friction factors of the chart
MBARS = (0.0, 0.1, 0.2, 0.4, 0.7, 1.0)
#: length of the start-up increment, as a fraction of the others (see the notes)
STARTUP = 0.05


# %% [markdown]
# ## One ring

# %%
def run_ring(mbar: float, *, outer_radius, inner_radius, height, h, K, m, speed, reduction,
             n_steps, slip_velocity, line_search, output_dir, progress, comm) -> dict:
    """Compress the eighth ring with Tresca friction ``mbar``; returns the tracked curves."""
    Ro, Ri, H = outer_radius, inner_radius, height
    msh, _, ft = ring(comm, Ro, Ri, H, h, sector="eighth")
    space = MixedSpace(msh)
    name = f"mbar_{mbar:g}"
    sim = Simulation(space, NortonHoff(K=K, m=m, regularization=1e-4 * speed / H),
                     solver_options=SolverOptions(line_search=line_search),
                     output_dir=None if output_dir is None else os.path.join(output_dir, name),
                     name=name, progress=progress)
    sim.add_velocity_bc(sim.facets(ft, RING_TAGS["symmetry_x"]), 0.0, 0)
    sim.add_velocity_bc(sim.facets(ft, RING_TAGS["symmetry_y"]), 0.0, 1)
    sim.add_velocity_bc(sim.facets(ft, RING_TAGS["mid_plane"]), 0.0, 2)
    die = Plane(point=(0.0, 0.0, 0.5 * H), normal=(0.0, 0.0, -1.0),
                velocity=(0.0, 0.0, -0.5 * speed), name="die")
    sim.add_contributor(NodalContact(ContactBoundary(space, ft, RING_TAGS["top"]), die,
                                     scheme="implicit", friction=Tresca(mbar),
                                     slip_velocity=slip_velocity, name="contact"))
    # fold-over of the bore and the outer surface onto the die: frictionless contact with the
    # same plane (see the notes)
    fold = Plane(die.point, die.normal, velocity=(0.0, 0.0, -0.5 * speed), name="die_fold")
    sim.add_contributor(NodalContact(ContactBoundary(space, ft, [RING_TAGS["inner"],
                                                                 RING_TAGS["outer"]]),
                                     fold, scheme="implicit", name="fold"))
    bore = ContactBoundary(space, ft, RING_TAGS["inner"]).vertices   # owned bore vertices
    tol = 1e-3 * h

    def measure():
        x = sim.vertex_positions()
        top = comm.allreduce(np.max(x[:, 2], initial=-np.inf), op=MPI.MAX)
        xb = x[bore]
        rb = np.hypot(xb[:, 0], xb[:, 1])
        mid = np.abs(xb[:, 2]) < tol
        face = xb[:, 2] > top - tol

        def mean(sel):
            s = comm.allreduce(np.array([np.sum(rb[sel]), np.sum(sel)], float), op=MPI.SUM)
            return s[0] / s[1] if s[1] > 0 else np.nan

        return (comm.allreduce(np.min(rb, initial=np.inf), op=MPI.MIN), mean(mid), mean(face),
                sim.t)

    rows = [measure()]
    t_end = reduction * H / speed
    dt = t_end / n_steps
    # start-up increment (its nodal Tresca limits come from the rest state), then n_steps
    sim.run(STARTUP * dt, STARTUP * dt, close=False, callback=lambda s, res: rows.append(measure()))
    sim.run(t_end, dt, callback=lambda s, res: rows.append(measure()))
    rows = np.array(rows)
    hist = sim.history
    T = H - speed * rows[:, 3]          # current height (die position)
    # force on the dies (full ring: 4 quarters; the half height carries the whole force) on
    # each increment's initial geometry (updated Lagrangian)
    F = np.array([4.0 * (row["die_force_z"] + row["die_fold_force_z"]) for row in hist])
    A0 = np.pi * (Ro ** 2 - Ri ** 2)
    force = np.r_[np.nan, F / (flow_stress(K, m, speed / T[:-1]) * A0)]
    force[1] = np.nan   # the start-up increment (friction limits at the rest state's rate)
    return {"mbar": mbar, "reduction": 1.0 - T / H,
            "id_min": 100.0 * (rows[:, 0] / Ri - 1.0), "id_mid": 100.0 * (rows[:, 1] / Ri - 1.0),
            "id_face": 100.0 * (rows[:, 2] / Ri - 1.0),
            # the force of increment k acts on the geometry at the start of the increment
            "force_reduction": np.r_[np.nan, 1.0 - T[:-1] / H], "force": force,
            "history": hist, "newton_iterations": int(sum(r["newton_iterations"] for r in hist)),
            "cutbacks": int(sum(r["cutbacks"] for r in hist))}


# %% [markdown]
# ## The chart

# %%
def run(outer_radius=30.0, inner_radius=15.0, height=20.0, h=2.5, K=50.0, m=0.15, speed=10.0,
        reduction=0.5, n_steps=25, mbars=MBARS, slip_velocity=None, line_search="bt",
        output_dir="results/ring_test", picture=True, progress=True,
        comm=MPI.COMM_WORLD) -> dict:
    """FE ring-compression curves for each m̄ of ``mbars`` and Avitzur's upper-bound curves.

    Args:
        outer_radius, inner_radius, height: the ring [mm] (default the 6:3:2 ring 60:30:20).
        h: element size [mm].
        K [MPa·s^m], m: Norton–Hoff parameters.
        speed: closing speed of the dies [mm/s] (each die moves at half of it).
        reduction: final height reduction (fraction); n_steps: increments.
        mbars: Tresca friction factors in [0, 1].
        slip_velocity: regularisation v₀ of the slip speed [mm/s] (default: the contact's,
            10⁻³ × the process speed of the increment).
        line_search: Newton line search (``"bt"``: backtracking, ``"basic"``: full steps).
        output_dir: where the outputs go (None: nothing written).
    Returns:
        dict with ``fe`` (per m̄: ``reduction``, ``id_min``, ``id_mid``, ``id_face`` (% change
        of the inner diameter: minimum over the bore, at mid-height, at the die face),
        ``force_reduction``, ``force`` (F/(σ₀A₀)), history, Newton iterations, cut-backs,
        wall time), ``ub`` (per m̄: the upper bound at the FE reductions: ``id_change``,
        ``neutral_radius``, ``pressure`` and ``force`` = J/(vσ₀A₀)), ``diff`` (per m̄: FE − UB
        of the minimum inner diameter change, in percentage points, and of the force), the
        ``table`` rows written to the CSV, and the output paths ``csv``, ``png``.
    """
    if not (0 < inner_radius < outer_radius and height > 0 and h > 0 and speed > 0):
        raise ValueError("need 0 < inner_radius < outer_radius, height > 0, h > 0, speed > 0")
    if not (0 < reduction < 0.8 and n_steps >= 1):
        raise ValueError("need 0 < reduction < 0.8 and n_steps >= 1")
    mbars = [float(x) for x in mbars]
    if not mbars or any(not 0.0 <= x <= 1.0 for x in mbars):
        raise ValueError(f"mbars must be friction factors in [0, 1], got {mbars!r}")
    if output_dir is not None and comm.rank == 0:
        os.makedirs(output_dir, exist_ok=True)
    common = dict(outer_radius=outer_radius, inner_radius=inner_radius, height=height, h=h, K=K,
                  m=m, speed=speed, reduction=reduction, n_steps=n_steps,
                  slip_velocity=slip_velocity, line_search=line_search, output_dir=output_dir,
                  progress=progress, comm=comm)
    fe, ub, diff, table = {}, {}, {}, []
    A0 = np.pi * (outer_radius ** 2 - inner_radius ** 2)
    for mb in mbars:
        t0 = time.perf_counter()
        r = run_ring(mb, **common)
        r["wall_time"] = comm.allreduce(time.perf_counter() - t0, op=MPI.MAX)
        fe[mb] = r
        u = ring_compression_upper_bound(outer_radius, inner_radius, height, mb, r["reduction"])
        # force of increment k: on the geometry at the start of the increment (point k − 1)
        J = u["pressure"] * np.pi * (u["outer_radius"] ** 2 - u["inner_radius"] ** 2) / A0
        u["force"] = np.r_[np.nan, J[:-1]]
        ub[mb] = u
        diff[mb] = {"id_min": r["id_min"] - u["id_change"], "force": r["force"] - u["force"]}
        for k in range(len(r["reduction"])):
            table.append({"mbar": mb, "reduction": r["reduction"][k],
                          "id_min_fe": r["id_min"][k], "id_mid_fe": r["id_mid"][k],
                          "id_face_fe": r["id_face"][k], "id_ub": u["id_change"][k],
                          "neutral_radius_ub": u["neutral_radius"][k],
                          "force_reduction": r["force_reduction"][k], "force_fe": r["force"][k],
                          "force_ub": u["force"][k]})
    out = {"fe": fe, "ub": ub, "diff": diff, "table": table, "csv": None, "png": None,
           "parameters": {k: v for k, v in common.items() if k != "comm"}}
    if output_dir is not None and comm.rank == 0:
        out["csv"] = os.path.join(output_dir, "ring_test.csv")
        with open(out["csv"], "w", newline="") as fh:
            w = csv.DictWriter(fh, fieldnames=list(table[0].keys()))
            w.writeheader()
            w.writerows(table)
        if picture:
            out["png"] = plot_chart(fe, ub, os.path.join(output_dir, "ring_test.png"),
                                    (outer_radius, inner_radius, height))
    return out


def plot_chart(fe: dict, ub: dict, path: str, ring_size) -> str:
    """Calibration chart (% change of the minimum inner diameter vs % height reduction) and the
    die force, FE (solid, markers) and upper bound (dashed, same colour) for each m̄."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.lines import Line2D

    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(13, 5.5))
    colors = plt.get_cmap("tab10").colors
    keys = list(fe)
    for i, mb in enumerate(keys):
        c = colors[i % len(colors)]
        r, u = fe[mb], ub[mb]
        ax1.plot(100 * r["reduction"], r["id_min"], "-o", color=c, ms=3.5, lw=1.6,
                 label=f"m̄ = {mb:g}")
        ax1.plot(100 * r["reduction"], u["id_change"], "--", color=c, lw=1.4)
        ax2.plot(100 * r["force_reduction"], r["force"], "-o", color=c, ms=3.5, lw=1.6,
                 label=f"m̄ = {mb:g}")
        ax2.plot(100 * r["force_reduction"], u["force"], "--", color=c, lw=1.4)
    Ro, Ri, H = ring_size
    ax1.axhline(0.0, color="0.5", lw=0.8)
    ax1.set_xlabel("height reduction [%]")
    ax1.set_ylabel("change of the minimum inner diameter [%]")
    ax1.set_title(f"Ring test {2 * Ro:g}:{2 * Ri:g}:{H:g} mm, Tresca friction m̄")
    ax2.set_xlabel("height reduction [%]")
    ax2.set_ylabel(r"die force $F/(\sigma_0 A_0)$")
    ax2.set_title(r"Die force ($\sigma_0$ at $\dot{\bar\varepsilon}=v/T$, $A_0$ initial annulus)")
    style = [Line2D([], [], color="k", marker="o", ms=3.5, label="FE"),
             Line2D([], [], color="k", ls="--", label="upper bound (Avitzur)")]
    for ax in (ax1, ax2):
        ax.grid(alpha=0.3)
        h, lab = ax.get_legend_handles_labels()
        ax.legend(handles=h + style, fontsize=8.5, loc="best", ncol=2)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


# %% [markdown]
# ## Results (measured, serial, Debian 12 / dolfinx 0.5.2, 2-core machine)
#
# Defaults (h = 2.5 mm, 25 increments of 2 % after the start-up, the contact's default v₀ =
# 10⁻³ × the process speed): 7 min for the six m̄ on a loaded machine (57–88 s each, 77–214
# Newton iterations, no cut-back). Change of the minimum inner
# diameter, FE / upper bound [%], at 10–50 % height reduction; at 50 %: the FE diameter at
# mid-height and at the die face; the last increment's die force F/(σ₀A₀) (at 48 %), FE /
# upper bound:
#
# | m̄ | 10 % | 20 % | 30 % | 40 % | 50 % | 50 %: mid, face | force |
# |---|---|---|---|---|---|---|---|
# | 0 | 5.3/5.4 | 11.6/11.8 | 19.1/19.5 | 28.5/29.1 | 40.4/41.4 | 40.4, 40.4 | 1.901/1.927 |
# | 0.1 | 3.0/3.3 | 6.1/6.7 | 9.1/10.0 | 11.6/12.7 | 12.6/13.6 | 15.3, 13.0 | 2.165/2.196 |
# | 0.2 | 0.7/1.2 | 0.7/1.5 | 0.7/1.0 | −0.6/−0.8 | −4.2/−4.8 | −2.6, −3.6 | 2.345/2.392 |
# | 0.4 | −1.4/−1.4 | −4.1/−3.6 | −8.3/−7.1 | −14.7/−12.7 | −24.6/−21.9 | −23.4, −13.7 | 2.622/2.758 |
# | 0.7 | −4.1/−3.0 | −9.9/−7.1 | −17.7/−13.0 | −28.1/−21.8 | −43.7/−35.8 | −41.2, −18.3 | 2.905/3.297 |
# | 1 | −5.1/−3.9 | −12.0/−9.1 | −21.1/−16.5 | −33.5/−27.3 | −52.3/−44.7 | −49.7, −17.6 | 3.056/3.835 |
#
# **Reading.**
#
# * m̄ = 0: the ring stays straight (mid-height = die face) and the hole grows like the
#   homogeneous field's, 40.4 % at 50 % against the exact 41.4 %. The 1-point gap is the
#   explicit (forward Euler) geometry update of the updated Lagrangian scheme: per increment of
#   height strain a, a radius grows by (1 + a/2) instead of (1 − a)^(−1/2); 25 increments lose
#   2.5 % of the change (halving the increments halves it). The die force is within 1.3 % of the
#   bound (σ₀ at v/T), which is exact here.
# * m̄ ≤ 0.2: FE and upper bound within 1.1 points of diameter change over the whole chart
#   (the size of the m̄ = 0 time-integration error), the FE below; the FE bore bulges outwards
#   at m̄ = 0.1 (the minimum is at the die faces), which the bound ignores.
# * m̄ ≥ 0.4: the FE hole shrinks faster than the bound's (−24.6 % vs −21.9 % at m̄ = 0.4,
#   −52 % vs −45 % at m̄ = 1, 50 % reduction) and the bore barrels inwards (at m̄ = 1 the die
#   face diameter changes by −18 %, mid-height by −50 %): the bound's field has no barrelling,
#   as expected from the analysis (THEORY §14.5) and as calibration charts computed by FE or
#   measured are known to do.
# * The FE die force stays below the upper bound everywhere (1–2 % at m̄ ≤ 0.2, 20 % at
#   m̄ = 1 and 48 %).
# * Sensitivity (50 % reduction, minimum ID change; measured with v₀ = 0.05 mm/s, which gives
#   −24.66 % at m̄ = 0.4 and −52.11 % at m̄ = 1 against −24.60 % and −52.32 % with the default
#   v₀): v₀ = 0.01 mm/s, m̄ = 0.4: −24.60 %; mesh h = 2.0 instead of 2.5 mm: m̄ = 0.4 −24.82 %,
#   m̄ = 1 −51.75 %; 50 increments instead of 25: m̄ = 0 40.87 % (the Euler error halves: first
#   order), m̄ = 1 −53.51 %. The time step is the largest error at high friction (≈ 1.4 points
#   at 25 increments, first order, so about 1.4 more towards dt → 0); the mesh and v₀ are
#   below 0.4 points.

# %% [markdown]
# ## Script

# %%
def main(argv=None):
    ap = argparse.ArgumentParser(description="Ring compression test against Avitzur's bound")
    ap.add_argument("--size", type=float, default=2.5, help="element size [mm]")
    ap.add_argument("--reduction", type=float, default=0.5, help="final height reduction")
    ap.add_argument("--steps", type=int, default=25, help="increments")
    ap.add_argument("--mbar", type=float, nargs="+", default=list(MBARS),
                    help="Tresca friction factors")
    ap.add_argument("--output", default="results/ring_test")
    add_verbosity_arguments(ap)
    a = ap.parse_args(argv)
    configure_logging(a.verbose, a.quiet)
    res = run(h=a.size, reduction=a.reduction, n_steps=a.steps, mbars=a.mbar,
              output_dir=a.output)
    if MPI.COMM_WORLD.rank == 0:
        print("% change of the inner diameter (FE minimum / mid-height / die face; upper bound)"
              " and die force F/(sigma0 A0) (FE; upper bound)")
        for mb, r in res["fe"].items():
            u = res["ub"][mb]
            print(f"m = {mb:g}: {r['newton_iterations']} Newton iterations, {r['cutbacks']} "
                  f"cut-backs, {r['wall_time']:.0f} s")
            for k in range(0, len(r["reduction"]), max(1, len(r["reduction"]) // 5)):
                print(f"  {100 * r['reduction'][k]:5.1f} %: ID {r['id_min'][k]:7.2f} "
                      f"{r['id_mid'][k]:7.2f} {r['id_face'][k]:7.2f}; UB {u['id_change'][k]:7.2f}"
                      f" | force {r['force'][k]:.3f}; UB {u['force'][k]:.3f}")
            print(f"  {100 * r['reduction'][-1]:5.1f} %: ID {r['id_min'][-1]:7.2f} "
                  f"{r['id_mid'][-1]:7.2f} {r['id_face'][-1]:7.2f}; UB {u['id_change'][-1]:7.2f}"
                  f" | force {r['force'][-1]:.3f}; UB {u['force'][-1]:.3f}")
        print(f"outputs: {res['csv']}, {res['png']}")
    return res


if __name__ == "__main__":
    main()
