# ---
# jupyter:
#   jupytext:
#     text_representation:
#       extension: .py
#       format_name: percent
# ---

# %% [markdown]
# # Forward extrusion through a conical die — and its dead-metal zone
#
# A round billet sits in a container; a punch pushes it through a conical die in the
# container's end, and it leaves the die as a bar of smaller radius. Forward extrusion is
# drawing's sibling: the die does the same work, but the billet is pushed, not pulled, and it
# also slides along the container wall, which costs friction as long as the billet is long.
#
# **The case.** An aluminium billet R₀ = 10 mm extruded to R₁ = 6 mm (64 % reduction of area,
# extrusion ratio 2.8) through a **45° die** (a wide die, where the material no longer follows
# the die face: it makes its own cone of flow and leaves a **dead-metal zone** in the corner
# between the container and the die), hot Norton–Hoff material K = 40 MPa·s^m, m = 0.1, the
# punch at 10 mm/s, Tresca friction m̄ = 0.3 on the die and on the container. The run covers
# the first millimetre of the punch's travel: enough for the flow field, not for a steady
# state (on this coarse mesh, 7 elements over the radius, a longer run through a die of 35°
# or more inverts the elements that the corner shears, after 1–2 mm: it needs remeshing).
# The steady comparison with theory is made on 20° and 30° dies (`--quick`, the tests and
# `benchmarks/bench_extrusion.py`).
# One quarter of the billet is modelled, with two symmetry planes.
#
# **What we compare.** The punch pressure p = F/A₀ against the classical band (THEORY §14.2,
# `fxcontact.theory.forming.extrusion_theory`): the ideal work σ₀ ln(R₀²/R₁²), a lower bound, and
# Avitzur's upper bound of the die (the drawing bound: internal deformation, the two shear
# surfaces, friction on the cone and the land) plus the container friction 2 m̄ k L_c/R₀, with
# L_c the billet length still in the container. σ₀ = √3 K (√3 ε̄̇)^m at the die's mean strain
# rate. The measured figures are in `docs/validation.md`.
#
# Run: `mpirun -n 2 python demos/demo_extrusion.py` (100 s on 2 ranks of a busy machine),
# `--quick` (the test size: R₀ = 5 mm, h = 1 mm, a 20° die, to steady state in a minute),
# `--alpha`, `--R1`, `--mbar_die`, ... (`--help`). Outputs in `results/extrusion`.

# %%
import argparse

from fxcontact import Tresca
from fxcontact.processes import ExtrusionCase, run_extrusion
from fxcontact.processes.common import script_main
from fxcontact.processes.extrusion import CONTAINERS

# %% [markdown]
# ## The case
#
# Every parameter is a field of `ExtrusionCase`, a frozen dataclass checked when it is made
# (a bad value raises a `ValueError` naming the field). The demo's case is the default one
# with a 45° die, more friction on it (`friction`: one Tresca law per tool; the command line's
# `--mbar_die`, `--mbar_container` set them), a coarser mesh and a short run:

# %%
CASE = ExtrusionCase(alpha=45.0, friction={"container": Tresca(0.3), "die": Tresca(0.3)},
                     h=1.5, entry_fillet=1.5, t_end=0.1)

# %% [markdown]
# ## The set-up, written out
#
# `fxcontact.processes.build_extrusion(case)` returns a ready `Simulation` and its handles.
# What it does (see `fxcontact/processes/extrusion.py`):
#
# ```python
# msh, _, ft = fx.drawing_bar(comm, R0, length, h, nose_length=..., nose_radius=...,
#                             nose_angle=alpha, sector=90)      # the billet, its nose in the die
# sim = fx.Simulation(fx.MixedSpace(msh), fx.NortonHoff(K, m, regularization=...))
# f = {k: sim.facets(ft, v) for k, v in fx.DRAWING_BAR_TAGS.items()}
# n = fx.sector_plane_normals(90)
# sim.add_symmetry_plane(f["symmetry_0"], n["symmetry_0"], name="sym0")
# sim.add_symmetry_plane(f["symmetry_1"], n["symmetry_1"], name="sym1")
# sim.add_velocity_bc(f["back"], speed, 2)                      # the punch
# sim.add_reaction("punch", f["back"])
# container = fx.RevolvedProfile([[z_a, R0], [z_b, R0]], inside=True, name="container")
# die = fx.RevolvedProfile(die_points, die_arcs, inside=True, name="die")  # face, cone, land
# contact = fx.NodalContact(fx.ContactBoundary(space, ft, fx.DRAWING_BAR_TAGS["lateral"]),
#                           [container, die], scheme="implicit",
#                           penalty=fx.Penalty(beta=100.0, gap=True, strain_rate=rate_die,
#                                              element_size=h, reference_dt=dt),
#                           friction={"container": fx.Tresca(0.3), "die": fx.Tresca(0.3)})
# sim.add_contributor(contact)
# ```
#
# **Two tools, one contact.** Each contact node is projected on both tools and keeps the one
# with the smallest gap: that is the exact distance to the container and the die together, so
# the answer (and every Newton iterate) is that of a single profile with the container as its
# first segment (`container="profile"`); the two tools carry their own friction and their own
# force columns in the history (`container_force_z`, `die_force_z`).
#
# **Which k?** Tresca friction τ = m̄ k takes k from the strain rate at each node. On the
# container wall the billet moves as a rigid body, so k there is well below σ₀/√3 of the
# die's mean strain rate: the container costs about two thirds of the theory's 2 m̄ k L_c/R₀.
# `container_shear_limit=k` fixes k in the container's law; the container force then equals
# the theory within 1 % (`tests/test_extrusion.py`).

# %% [markdown]
# ## The run and the comparison
#
# `run_extrusion` steps to `t_end` and finds the steady window of the **die pressure** (punch
# minus container, the part that does not fall as the billet shortens). The report compares
# the steady punch pressure with the band at the window's L_c, and gives the power balance
# F v = ∫ s:D dV + friction power, the volume change and the element quality.

# %%
def main(argv=None):
    ap = argparse.ArgumentParser(description="Forward extrusion (see the header).")
    for k in ("R0", "R1", "length", "alpha", "entry_fillet", "K", "m", "mbar_die",
              "mbar_container", "container_shear_limit", "speed", "dt", "t_end", "h"):
        ap.add_argument(f"--{k}", type=float)
    ap.add_argument("--container", choices=CONTAINERS)
    return script_main(ap, ExtrusionCase, run_extrusion, default=CASE, argv=argv,
                       output_dir="results/extrusion")


# %% [markdown]
# ## The picture: the dead-metal zone
#
# `extrusion_flow.png` shows the θ = 0 section at the end of the run: the axial velocity over
# the punch speed (top) and the equivalent strain rate (bottom), with the container and die
# outline. Upstream the billet moves as a block at the punch speed, downstream as a bar at
# A₀/A₁ times it. In the corner between the container and the 45° die a wedge of material
# lags: it moves at about half the punch speed with hardly any strain rate, while the strain
# rate concentrates on the surface between it and the flowing core, a cone steeper than the
# die: the material begins to make its own die — the dead-metal zone, resolved here by two
# elements (a finer mesh shows it still). `extrusion_pressure.png` plots the punch and die
# pressures against the band: at 1 mm of travel the punch pressure (175 MPa, 2 ranks) lies
# between the ideal work (86) and Avitzur's bound plus the container friction (219).

# %%
if __name__ == "__main__":
    main()
