# ---
# jupyter:
#   jupytext:
#     text_representation:
#       extension: .py
#       format_name: percent
# ---

# %% [markdown]
# # Upsetting with sticking dies to 70 %: the free surface folds onto the die
#
# A hot steel cylinder, as tall as one and a half diameters, is squashed between two flat dies
# to 30 % of its height. The dies are rough: the material sticks to them, so the end faces
# hardly spread, the middle bulges (barrelling), and the bulging side surface rolls over onto
# the dies — the **fold**: a ring of the die contact that was free surface before. At the
# die's edge the elements are sheared flat as the surface turns, and an updated-Lagrangian run
# on one mesh stops there; the run below **remeshes** the body whenever an element gets too
# flat, finer where the surface folds.
#
# **The case.** R₀ = 10 mm, H₀ = 30 mm (H₀/D₀ = 1.5), Norton–Hoff K = 50 MPa·s^m, m = 0.15,
# the dies closing at 10 mm/s, Tresca friction m̄ = 1 (sticking: the friction stress is the
# shear flow stress k of each node), 70 % height reduction, elements of 1.5 mm (0.75 mm at the
# folding edge). A 45° sector of the billet and half its height are modelled: both dies move
# towards the mid-plane at the same speed with the same friction, so the mid-plane is a
# symmetry plane (a die held still would only add a rigid translation).
#
# **What we compare.** The mean die pressure p̄ = F/A_h, with A_h = V/h the end face of the
# homogeneous billet of the same volume (diameter d_h from volume constancy, barrelling aside),
# over σ₀ = √3 K (√3 ε̄̇)^m at the mean strain rate ε̄̇ = v/h, against the band (THEORY §14.5,
# `fxcontact.theory.forming`): above σ₀ on the actual die contact (π r_c²/A_h: the barrelled billet
# touches the die on less than A_h) and below the upper bound 1 + m̄ d_h/(3√3 h) (for Tresca
# friction the slab method gives the same number). The run also reports the die contact
# radius, the radius of the original end face and the free-surface radius; the measured
# figures are in `docs/validation.md`.
#
# Run: `mpirun -n 2 python demos/demo_upsetting_folding.py` (minutes), `--quick` (the tests'
# billet, R₀ = 5 mm, h = 1.25 mm, under a minute), `--no-remesh` (the same mesh without
# remeshing: it stops early), `--mbar`, `--mu`, `--aspect`, ... (`--help`). Outputs in
# `results/upsetting`.

# %%
import argparse

from fxcontact.processes import UpsettingCase, run_upsetting
from fxcontact.processes.common import script_main

# %% [markdown]
# ## The case
#
# Every parameter is a field of `UpsettingCase`, a frozen dataclass checked when it is made (a
# bad value raises a `ValueError` naming the field). The demo's case is the default one on a
# 45° sector with 1.5 mm elements:

# %%
CASE = UpsettingCase(sector=45.0, h=1.5)

# %% [markdown]
# ## The set-up, written out
#
# `fxcontact.processes.build_upsetting(case)` returns a ready `Simulation` and its handles.
# What it does (see `fxcontact/processes/upsetting.py`):
#
# ```python
# msh, _, ft = fx.drawing_bar(comm, R0, H0 / 2, h, sector=45)   # a plain cylinder sector
# sim = fx.Simulation(fx.MixedSpace(msh), fx.NortonHoff(K, m, regularization=...))
# n = fx.sector_plane_normals(45)
# sim.add_symmetry_plane(sim.facets(ft, TAGS["symmetry_0"]), n["symmetry_0"], name="sym0")
# sim.add_symmetry_plane(sim.facets(ft, TAGS["symmetry_1"]), n["symmetry_1"], name="sym1")
# sim.add_velocity_bc(sim.facets(ft, TAGS["back"]), 0.0, 2)   # the mid-plane
# die = fx.Plane(point=(0, 0, H0 / 2), normal=(0, 0, -1), velocity=(0, 0, -v / 2), name="die")
# contact = fx.NodalContact(fx.ContactBoundary(space, ft, [TAGS["front"], TAGS["lateral"]]),
#                           die, friction=fx.Tresca(1.0),      # case.friction
#                           penalty=fx.Penalty(beta=100.0, gap=True, strain_rate=v / H0,
#                                              element_size=h, reference_dt=dt))  # k = ρ(β)/dt
# sim.add_contributor(contact)
# sim.set_remeshing(RemeshCriteria(min_quality=0.2), size=h,
#                   zones=lambda sim: [SizeZone(h / 2, points=circle_at_the_die_edge)])
# ```
#
# **One contact for the end face and the side.** The side surface is in the die's contact
# from the start: where it folds onto the die it touches it and sticks like the end face. The
# facet tags of a new mesh are those of the old facets it replaces, so the folded surface keeps
# its tag `lateral` after a remesh: the fold is the ring of die contact outside the end face's
# tag.
#
# **Remeshing.** After an increment where an element's quality falls below 0.2 (and before an
# increment whose cut-backs all invert an element is given up), gmsh meshes the deformed
# boundary again (the die face and the symmetry planes stay planar), with a size zone on the
# circle where the free surface meets the die, placed again at each remesh; velocity,
# pressure, equivalent strain and the volume correction's reference are carried over. The
# time step shrinks with the height (`dt` × h/H₀: increments of the same height strain), so
# the nodes landing on the die at the fold flatten their elements over several increments.

# %% [markdown]
# ## The run and the comparison
#
# `run_upsetting` steps to the target reduction (a short start-up increment first: the Tresca
# k of each node comes from the increment's predictor). The report gives the die force and
# p̄/σ₀ against the band at the last increment, the increments out of the band, the radii,
# the remeshes, the volume change, the smallest element quality and the power balance.

# %%
def main(argv=None):
    ap = argparse.ArgumentParser(description="Upsetting with sticking dies (see the header).")
    for k in ("R0", "aspect", "sector", "K", "m", "mbar", "mu", "speed", "reduction", "dt",
              "h", "remesh_min_quality", "remesh_zone_h"):
        ap.add_argument(f"--{k}", type=float)
    ap.add_argument("--no-remesh", dest="remesh", action="store_false", default=None)
    return script_main(ap, UpsettingCase, run_upsetting, default=CASE, argv=argv,
                       output_dir="results/upsetting")


# %% [markdown]
# ## The picture: the fold
#
# `upsetting_section.png` shows the θ = 0 section at the end (equivalent strain): the
# initial billet dashed, the die, and in red the part of the die contact that was free
# surface — from the original end face's radius to the contact radius. The strain is largest
# at the centre of the mid-plane and in the fold next to the end face's edge (material that
# turned the corner), smallest under the die's centre, where the sticking die holds the
# material still (the dead zone). `upsetting_pressure.png` plots p̄/σ₀ against the band and
# the three radii against the reduction, with the remeshes: the fold starts at about 40 %.

# %%
if __name__ == "__main__":
    main()
