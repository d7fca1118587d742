# ---
# jupyter:
#   jupytext:
#     text_representation:
#       extension: .py
#       format_name: percent
# ---

# %% [markdown]
# # Upsetting a Norton–Hoff cylinder between two flat dies
#
# A hot billet (radius R = 10 mm, height H = 15 mm) is squashed between two flat dies: the
# upper one comes down at 5 mm/s, the lower one stays put. The material is incompressible
# Norton–Hoff viscoplastic, ``s = 2K (√3 ε̄̇)^(m-1) ε̇`` (K = 50 MPa·s^m, m = 0.15), with MINI
# elements (P1+bubble / P1) on a quarter of the billet (symmetry planes x = 0 and y = 0); the
# geometry is updated after each increment and the equivalent strain accumulated per cell.
#
# **How the billet meets the dies** is the whole story (``--dies``):
#
# * ``sticking`` (default): the end faces cannot move sideways (a velocity condition). They
#   stay at R while the middle bulges: **barrelling**.
# * ``sliding``: the end faces slide freely: the billet stays a cylinder (homogeneous
#   deformation), of radius R√(H/h) at height h.
# * ``tresca``: the dies are rigid planes with nodal penalty contact and Tresca friction
#   ``τ = m̄ k`` (``--mbar``; k = σ₀/√3 of the node's strain rate). The side surface may fold
#   onto a die: frictionless contact there.
# * ``coulomb``: the same planes with Coulomb friction ``τ = μ p_n`` (``--mu``, no Tresca cap).
#
# **What we compare.** The mean die pressure ``p̄ = F/A_h`` (A_h = V/h the end face of the
# homogeneous billet of the same volume) over the flow stress σ₀ at the mean strain rate v/h,
# against the upper bound ``1 + m̄ d/(3√3 h)`` (m̄ = 1 for sticking, 0 for sliding dies) and,
# for Coulomb dies, the slab estimate ``2(eˣ − x − 1)/x²``, x = 2μR_h/h (THEORY §14.5). The FE
# solution minimises the power over a space that holds the bound's homogeneous field: it must
# come out **below** the bound. The pressure on the actual end face is printed too.
#
# **Volume.** Updating the geometry with ``x += dt v`` loses volume at second order in dt, and
# the loss accumulates: at the default size (``--size 2``, 15 increments, 30 % reduction) the
# billet loses 0.52 % of its volume with sticking dies and 0.63 % with sliding dies. The
# default volume correction (THEORY §1.5: the incompressibility equation gives back the volume
# lost so far) brings this to 0.039 % and 0.059 %; the die force rises by 0.5–0.6 % and the
# sliding radius goes from 11.917 to 11.951 mm (homogeneous: 11.952 mm). Compare with
# ``--volume-correction none``.
#
# Run: ``python demos/demo_upsetting.py`` (serial) or ``mpirun -n 2 python demos/...``;
# ``--quick`` is a coarse few-second run (h = 4 mm, 20 % in 4 increments). ``--size`` sets the
# element size, ``--dies`` the dies (``--mbar``, ``--mu``), ``--checkpoint-every`` /
# ``--resume`` continue a killed run. Outputs in ``--output-dir`` (``results/upsetting``): the
# VTK series ``upsetting.pvd`` (ParaView), the CSV history ``upsetting_history.csv``, the
# pressure table ``upsetting_pressure.csv`` and the picture ``upsetting.png``.
#
# The model lives in :mod:`fxcontact.processes.upsetting_dies` (``run_upsetting_dies``). The
# taller billet upset to 70 % with remeshing, where the side folds onto the die, is
# ``demos/demo_upsetting_folding.py`` (:mod:`fxcontact.processes.upsetting`).

# %%
import argparse
import csv
import os

import numpy as np
from mpi4py import MPI

from fxcontact.console import add_verbosity_arguments, configure_logging
from fxcontact.processes.upsetting_dies import DIES
from fxcontact.processes.upsetting_dies import run as run_upsetting_dies

# %% [markdown]
# ## The set-up, written out
#
# ``run_upsetting_dies`` meshes the quarter billet, makes the Simulation and the dies:
#
# ```python
# msh, _, ft = cylinder_billet(comm, R, H, h, quarter=True)
# sim = Simulation(MixedSpace(msh), NortonHoff(K=50, m=0.15, regularization=...))
# sim.add_velocity_bc(facets["symmetry_x"], 0.0, 0)
# sim.add_velocity_bc(facets["symmetry_y"], 0.0, 1)
# # sticking: sim.add_velocity_bc(facets["top"], (0, 0, -v)); bottom (0, 0, 0)
# # sliding:  only the z component on top (-v) and bottom (0)
# # tresca / coulomb: two Plane tools, friction on the end faces, none on the side
# die = Plane(point=(0, 0, H), normal=(0, 0, -1), velocity=(0, 0, -v))
# base = Plane(point=(0, 0, 0), normal=(0, 0, 1))
# sim.add_contributor(NodalContact(ContactBoundary(space, ft, [top, bottom]), [die, base],
#                                  scheme="implicit", friction=Tresca(mbar)))
# ```
#
# With friction a short start-up increment (5 % of dt) comes first: the nodal Tresca limit k
# is taken from the increment's predictor, which is the rest state in the first increment.

# %% [markdown]
# ## Results with friction (measured, serial, Debian 12 / dolfinx 0.5.2, 2-core machine)
#
# ``python demos/demo_upsetting.py --dies ...`` (h = 2 mm, 30 % in 15 increments; d/h = 1.33 at
# the start). p̄/σ₀ of the last increment (28 % reduction, h = 10.8 mm) on the homogeneous end
# face, next to the bound; radius at mid-height / on the end faces (homogeneous 11.95 mm):
#
# | dies | p̄/σ₀ FE | upper bound / slab | FE − bound | r_mid / r_end [mm] | wall |
# |---|---|---|---|---|---|
# | sliding (BC) | 1.0000 | 1 | 0 | 11.92 / 11.92 | 9 s |
# | Tresca m̄ = 0.1 | 1.0387 | 1.0419 | −0.3 % | 11.99 / 11.81 | 11 s |
# | Tresca m̄ = 0.3 | 1.0994 | 1.1256 | −2.3 % | 12.12 / 11.60 | 13 s |
# | Tresca m̄ = 1 | 1.1960 | 1.4189 | −15.7 % | 12.36 / 10.97 | 25 s |
# | sticking (BC) | 1.2049 | 1.4181 (m̄ = 1) | −15.0 % | 12.50 / 10.00 | 16 s |
# | Coulomb μ = 0.1 | 1.0635 | 1.0767 (slab) | −1.2 % | 12.04 / 11.75 | 17 s |
# | Coulomb μ = 0.3 | 1.1647 | 1.2584 (slab) | −7.4 % | 12.23 / 11.38 | 20 s |
#
# * The FE pressure is below the upper bound for every m̄, close to it at low friction (the
#   bound's homogeneous field is nearly right) and 16 % below with sticking friction, where the
#   billet barrels and the end faces spread less (r_end 10.97 mm against 11.95 mm).
# * Tresca m̄ = 1 dies carry 0.7 % less than the no-slip velocity condition (they may slip at
#   the cost of k; the edge nodes do).
# * Coulomb (no Tresca limit, like the slab): below the slab estimate, which ignores
#   barrelling; the gap grows with μ.
# * The radius of the sliding billet is 11.92 mm, not the homogeneous 11.95 mm: the explicit
#   geometry update (r ← r(1 + a/2) per increment of height strain a).
# * The start-up increment (first row of the printed table) has too little friction (k at the
#   rest state's strain rate): p̄/σ₀ = 1.006 for m̄ = 0.1 against 1.024 for the next increment.

# %% [markdown]
# ## The script
#
# A volume-preserving homogeneous upsetting gives ``R √(H/h)`` everywhere; sticking dies keep
# the end faces near ``R`` and bulge the middle. The table below has one row per increment.

# %%
#: the reduced run (--quick): coarse mesh, 20 % in 4 increments
QUICK = dict(h=4.0, reduction=0.2, n_steps=4)


def write_pressure_table(res, path):
    """p̄/σ₀ per increment next to the bounds, as CSV (rank 0)."""
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["reduction", "p_mean", "p_face", "sigma0", "upper_bound", "slab"])
        for row in zip(res["reduction"], res["p_mean"], res["p_face"], res["sigma0"],
                       res["upper_bound"], res["slab"]):
            w.writerow([f"{v:.8g}" for v in row])


def main(argv=None):
    ap = argparse.ArgumentParser(description="Upsetting a Norton-Hoff cylinder between flat "
                                             "dies (see the header).")
    ap.add_argument("--quick", action="store_true",
                    help="coarse few-second run (h = 4 mm, 20 %% in 4 increments)")
    ap.add_argument("--size", type=float, default=None, help="element size [mm] (default 2)")
    ap.add_argument("--dies", default="sticking", choices=DIES)
    ap.add_argument("--mbar", type=float, default=0.3, help="Tresca factor (--dies tresca)")
    ap.add_argument("--mu", type=float, default=0.1, help="Coulomb coefficient (--dies coulomb)")
    ap.add_argument("--output-dir", "--output", dest="output_dir", default="results/upsetting")
    ap.add_argument("--checkpoint-every", type=int, default=5,
                    help="write a checkpoint every n increments (0: never)")
    ap.add_argument("--resume", action="store_true",
                    help="continue a killed run from its newest checkpoint")
    ap.add_argument("--volume-correction", default="global", choices=["global", "none"])
    add_verbosity_arguments(ap)
    a = ap.parse_args(argv)
    configure_logging(a.verbose, a.quiet)
    size = dict(QUICK) if a.quick else dict(h=2.0)
    if a.size is not None:
        size["h"] = a.size
    res = run_upsetting_dies(dies=a.dies, mbar=a.mbar, mu=a.mu, output_dir=a.output_dir,
                             checkpoint_every=a.checkpoint_every, resume=a.resume,
                             volume_correction=a.volume_correction, **size)
    if MPI.COMM_WORLD.rank == 0:
        table = os.path.join(a.output_dir, "upsetting_pressure.csv")
        write_pressure_table(res, table)
        homog = 10.0 * np.sqrt(15.0 / res["height"])
        print(f"final height {res['height']:.3f} mm, die force (full billet) "
              f"{-res['die_force'] / 1e3:.2f} kN, max equivalent strain {res['max_strain']:.3f}")
        print(f"radius at mid-height {res['radius_mid']:.3f} mm, at the end faces "
              f"{res['radius_end']:.3f} mm (homogeneous: {homog:.3f} mm)")
        print(f"volume change {100 * res['volume_change']:.3f} %")
        print("mean die pressure over sigma0 (homogeneous end face / actual end face), "
              "Tresca upper bound, Coulomb slab:")
        for row in zip(res["reduction"], res["p_mean"], res["p_face"], res["upper_bound"],
                       res["slab"]):
            print("  reduction {:5.1%}: p/s0 = {:.4f} / {:.4f}, upper bound {:.4f}, "
                  "slab {:.4f}".format(*row))
        print(f"outputs: {res['vtk']}, {res['png']}, {table}")
    return res


if __name__ == "__main__":
    main()
