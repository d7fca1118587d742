# ---
# jupyter:
#   jupytext:
#     text_representation:
#       extension: .py
#       format_name: percent
# ---

# %% [markdown]
# # Hertz line contact: a rigid cylinder pressed on an elastic block (plane strain)
#
# A rigid cylinder of radius R = 5 mm, long enough for plane strain, is pressed on the flat
# top face of a steel block (E = 200 GPa, ν = 0.3) by 14.5 µm. Hertz's solution for an
# elastic half-space: the contact is a strip of half-width a, the pressure over it a
# half-ellipse, and for a load P per unit length
#
# $$a = \sqrt{4PR/(\pi E^*)},\qquad p_0 = 2P/(\pi a),\qquad p(x) = p_0\sqrt{1-x^2/a^2},
# \qquad E^* = E/(1-\nu^2).$$
#
# Unlike the sphere (`demo_hertz_sphere.py`), the indentation is not a property of the contact
# here: under a line load the displacement of a half-space grows logarithmically with the
# distance, so it depends on the size of the block. The test therefore takes the load P from
# the model (twice the tool force of the half model) and compares the half-width and the
# pressure with Hertz *for that load* (THEORY §11.2).
#
# The model (`fxcontact.processes.hertz_cylinder`): the half block [0, 10] × [-10, 0] mm
# (symmetry on x = 0, a frictionless roller on the bottom), linear elastic, small strain, MINI
# velocity–pressure triangles, frictionless nodal penalty contact (THEORY §2). The cylinder
# touches the block at x = 0 and moves down in a few increments.
#
# Run: `python demos/demo_hertz_cylinder.py` (seconds; or under `mpirun -n 2`), `--quick`
# (the reduced size of the tests), `--size` the element size under the tool. Outputs in
# `results/hertz_cylinder` (`--output-dir`).

# %%
import argparse
import os

from mpi4py import MPI

from fxcontact.console import add_verbosity_arguments, configure_logging
from fxcontact.processes import hertz_cylinder

ap = argparse.ArgumentParser(description="Hertz line contact (plane strain)")
ap.add_argument("--quick", action="store_true",
                help="reduced size of the tests: h_fine 0.02 mm, 2 increments")
ap.add_argument("--size", type=float, default=None,
                help="fine element size h_fine [mm] (default 0.008, 0.02 with --quick)")
ap.add_argument("--scheme", default="implicit", help="contact scheme")
ap.add_argument("--output-dir", "--output", dest="output_dir",
                default="results/hertz_cylinder",
                help="where the results go (default results/hertz_cylinder)")
add_verbosity_arguments(ap)
args = ap.parse_args()
configure_logging(args.verbose, args.quiet)
rank0 = MPI.COMM_WORLD.rank == 0

# %% [markdown]
# ## The mesh
#
# The element size is `h_fine` in a 0.4 mm square under the tool and grows to 1 mm far away.
# The block, 10 mm wide, is about 60 times the half-width a ≈ 0.17 mm (THEORY §11.2 asks for
# at least 10–20 a). The grading is steep and stiffens the far field: that changes the load for
# the given indentation, but not the comparison, made for the model's own load. The default
# 8 µm puts 22 nodes on the contact; `--quick` (20 µm) 10.

# %%
size = args.size if args.size is not None else (0.02 if args.quick else 0.008)
steps = 2 if args.quick else 4

# %% [markdown]
# ## The run

# %%
res = hertz_cylinder.run(h_fine=size, n_steps=steps, scheme=args.scheme,
                         output_dir=args.output_dir)

# %% [markdown]
# ## Comparison with Hertz
#
# The nodal pressure `p_n` is known at the contact nodes only, so the edge of the contact lies
# somewhere between the last active node and the first inactive one. Near the edge of a smooth
# frictionless contact the pressure behaves like √(a − x): p² is linear in x, and the FEM
# half-width is where the line through the last two active nodes' p² vanishes
# (`hertz_cylinder.contact_edge`). The simpler Σ S_n over the active nodes (their lumped
# lengths) is printed too. Measured: p_max −0.28 % against p0 and the half-width −0.5 % at
# the default size; at `--quick` −0.50 % and +1.5 % (0.13 of an element). The bottom
# reaction equals the load: the half model is in equilibrium.

# %%
if rank0:
    a, p0 = res["hertz_half_width"], res["hertz_p_max"]
    lo, hi = res["contact_half_width_bounds"]
    print(f"mesh: {res['cells']} triangles, {res['dofs']} dofs, h_fine = {res['h_fine']} mm, "
          f"{res['nodes_on_half_width']} active nodes; {res['wall_time']:.1f} s")
    print(f"load P = {res['force']:.2f} N/mm (bottom reaction {res['bottom_reaction']:.2f})")
    print(f"{'':22s}{'FEM':>12s}{'Hertz':>12s}{'error':>10s}")
    print(f"{'half-width a [mm]':22s}{res['contact_half_width']:12.5f}{a:12.5f}"
          f"{res['contact_half_width'] / a - 1:10.2%}")
    print(f"  (active edge between nodes {lo:.5f} and {hi:.5f}; sum S_n = "
          f"{res['contact_half_width_area']:.5f})")
    print(f"{'p_max [MPa]':22s}{res['p_max']:12.1f}{p0:12.1f}{res['p_max'] / p0 - 1:10.2%}")
    print(f"a/R = {a / res['radius']:.3f} (small: the half-space theory holds)")

# %% [markdown]
# ## What was written
#
# In the output directory: the VTK series and the CSV history of the increments
# (`hertz_cylinder.pvd`, `hertz_cylinder_history.csv`), the nodal pressure profile
# `profile.csv` (x, p, S) and `hertz_cylinder.png`: the nodal pressures over p0 against x/a,
# on the Hertz ellipse, with the FEM half-width.

# %%
if rank0:
    print(f"outputs: {res['png']} (in {os.path.abspath(args.output_dir)})")
