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
# A round bar of length L = 38 mm is drawn from R₀ = 10 mm to R₁ = 7.5 mm (43.75 % reduction
# of area) at 100 mm/s through a conical die (THEORY §12.2, Annex A2.1 of the thesis). The
# material is Norton–Hoff, K = 445 MPa·s^m, m = 0.016: a nearly rigid-plastic aluminium alloy.
# **The thesis's material is elasto-viscoplastic (E = 73 GPa); the elastic part is left out
# here**: the drawing stress is the plastic one, without the elastic unloading at the exit.
#
# **The die (our choice: the thesis gives no angle).** An entry cone of semi-angle α = 10°
# (bar and wire dies use 6–12°), a 2 mm fillet, a 2 mm bearing land at R₁ and a 20° exit
# relief, so that the drawn bar does not rub on an endless land. It is the analytic surface of
# revolution `fx.RevolvedProfile.die`, or the same surface triangulated on its sector and
# projected on flat facets (Forge's standard) or Nagata patches (`--die flat|nagata`).
#
# **Symmetry.** One third of the bar is modelled: symmetry planes at θ = 0° and θ = 120°; the
# second one is inclined, and `Simulation.add_symmetry_plane` imposes it exactly.
#
# **Start.** The bar is meshed with a pointed nose already through the die; its front face is
# pulled along +z, its back face is free (no back tension).
#
# **What we compare.** The steady drawing stress σ_d = F/A₁ against the classical band of
# THEORY §14.2 (`fxcontact.theory.forming`): the ideal work σ₀ ln(A₀/A₁), a lower bound, and
# Avitzur's upper bound; σ₀ = √3 K (√3 ε̄̇)^m at the die's mean strain rate. The measured
# figures (thesis size, the main demo's size, the test size) are in `docs/validation.md`.
#
# Run: `python demos/demo_wire_drawing.py --quick` (the test size, seconds),
# `mpirun -n 2 python demos/demo_wire_drawing.py --size 0.4 --t_end 0.1` (the main demo) or
# without options (the thesis size; on 2 ranks, idle, 7 min 45 s with `--newton_ftol 1e-3` and
# 6 min 29 s – 7 min 24 s with `--newton_ftol 1e-2`, against Forge3's 7 min 12 s; benchmarks/README.md).
# Outputs in `results/wire_drawing`.

# %%
import argparse

import fxcontact as fx
from fxcontact.console import auto_on_off
from fxcontact.processes import DrawingCase, run_drawing
from fxcontact.processes.common import script_main
from fxcontact.processes.die import DIE_MESHES, DIES

# %% [markdown]
# ## The case
#
# Everything that defines the process is a field of a frozen dataclass: geometry (R₀, R₁, the
# die's angle, land, fillet, relief), material (K, m), friction (Tresca m̄ or Coulomb μ),
# kinematics (speed, dt, t_end) and numerics (element size, die representation, contact
# scheme, penalty, Newton). `DrawingCase.quick()` is the reduced size of the tests:
# R₀ 5 → 3.75 mm (the same reduction), h = 1.5 mm. Another die is one field away:
# `DrawingCase.quick(alpha=15.0, R1=4.25)`.

# %% [markdown]
# ## The set-up, written out
#
# `build_drawing` returns a ready `Simulation` and its handles. What it does, in the library's
# own words (see `fxcontact/processes/drawing.py`):
#
# ```python
# msh, _, ft = fx.drawing_bar(comm, R0, length, h, nose_length=..., nose_radius=...,
#                             nose_angle=alpha, sector=120)
# sim = fx.Simulation(fx.MixedSpace(msh), fx.NortonHoff(K, m, regularization=...))
# f = {k: sim.facets(ft, v) for k, v in fx.DRAWING_BAR_TAGS.items()}
# n = fx.sector_plane_normals(120)
# sim.add_symmetry_plane(f["symmetry_0"], n["symmetry_0"], name="sym0")
# sim.add_symmetry_plane(f["symmetry_1"], n["symmetry_1"], name="sym1")   # inclined: exact
# sim.add_velocity_bc(f["front"], speed, 2)                                # the pull
# sim.add_reaction("pull", f["front"])
# die = fx.RevolvedProfile.die(entry_radius=1.1 * R0, exit_radius=R1, half_angle=alpha,
#                              land_length=land, fillet_radius=fillet, ...)
# contact = fx.NodalContact(fx.ContactBoundary(space, ft, fx.DRAWING_BAR_TAGS["lateral"]),
#                           die, scheme="implicit", friction=case.friction,
#                           penalty=fx.Penalty(beta=100.0, gap=True, strain_rate=rate_die,
#                                              element_size=h, reference_dt=dt))
# sim.add_contributor(contact)
# ```
#
# **Contact.** Nodal penalty on the end-of-increment gap with the stiffness k = ρ(β)/dt_ref
# (the case's `penalty`, `Penalty(beta=100.0, gap=True)`; `--beta`, `--penalty_dt` set it),
# ρ(β) = β η(ε̄̇)/h (THEORY §2.5, η the secant viscosity at the die's mean strain rate): the
# penalty penetration does not depend on the time step, as in the thesis. β = 100 (not the
# library's 1e3): a penetration of ≈ 0.2 % of h for far fewer Newton iterations at m = 0.016,
# the same drawing force to 0.1 %.
#
# **Newton.** Backtracking line search with the primal–dual Norton–Hoff tangent
# (`fxcontact.element.dual`) and the active-set prediction of the Newton step (THEORY §3.6), the
# library's defaults for m < 1.
#
# **Steady state.** After one element of pull, the mean drawing force over the last 3 mm of
# pull and over the 3 mm before agree within 2 % (`fxcontact.steady.steady_window`): window
# means, because the nodal force oscillates by a few % as the nodes pass the die's kinks.


# %% [markdown]
# ## The run and the comparison with theory
#
# `run_drawing` steps the simulation, measures per increment the drawing force, the true
# penetration against the exact die (also for a faceted die), the contact nodes, the power
# balance F v = ∫ s:D dV + friction, Newton iterations and wall time, volume change and
# element quality, and stops at steady state with `stop_at_steady`. Its result prints the
# comparison (`report()`) and holds the history.

# %%
def main(argv=None):
    ap = argparse.ArgumentParser(description="Wire drawing, the thesis case (see the header).")
    for k in ("R0", "R1", "length", "K", "m", "speed", "alpha", "land", "fillet", "h",
              "facet", "size", "dt", "t_end", "mu", "mbar", "beta", "penalty_dt", "window",
              "steady_tol", "penalty_continuation", "newton_rtol", "newton_ftol"):
        ap.add_argument(f"--{k}", type=float)
    ap.add_argument("--die", choices=DIES)
    ap.add_argument("--die_mesh", choices=DIE_MESHES)
    ap.add_argument("--scheme", choices=fx.SCHEMES)
    ap.add_argument("--penalty", choices=("gap", "velocity"))
    ap.add_argument("--max_it", type=int)
    ap.add_argument("--line_search", choices=fx.LINE_SEARCHES)
    ap.add_argument("--linear_solver")
    ap.add_argument("--active_set_prediction", type=auto_on_off)
    ap.add_argument("--reuse_factorisation", type=auto_on_off)
    ap.add_argument("--material_tangent", choices=fx.MATERIAL_TANGENTS)
    ap.add_argument("--stop_at_steady", action="store_true", default=None)
    return script_main(ap, DrawingCase, run_drawing, argv=argv,
                       output_dir="results/wire_drawing")


# %% [markdown]
# ## What to look at
#
# * `wire_drawing_strain.png`: the equivalent strain and strain rate on the θ = 0 section,
#   with the die's profile: the deformation zone between the entry and exit of the cone, the
#   strain growing from the axis to the surface (redundant shear).
# * `wire_drawing_contact.png`: the contact nodes on the unrolled lateral surface coloured by
#   the pressure, and the drawing stress against the band with the steady window shaded.
#
# At the thesis size the FE drawing stress lies 10 % above the ideal work and 11 % below
# Avitzur's bound (`docs/validation.md`).

# %%
if __name__ == "__main__":
    main()
