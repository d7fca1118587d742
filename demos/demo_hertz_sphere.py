# ---
# jupyter:
#   jupytext:
#     text_representation:
#       extension: .py
#       format_name: percent
# ---

# %% [markdown]
# # Hertz point contact: a rigid sphere indenting an elastic block
#
# A rigid sphere of radius R = 5 mm indents the flat top face of a steel block (E = 200 GPa,
# ν = 0.3) by δ = 13.3 µm. Hertz (1882) solved this contact for an elastic half-space: the
# contact zone is a disc of radius a, the pressure over it is a half-ellipsoid, and
#
# $$P = \tfrac43 E^* R^{1/2}\delta^{3/2},\qquad a = \sqrt{R\delta},\qquad
# p_0 = \frac{3P}{2\pi a^2},\qquad p(r) = p_0\sqrt{1-r^2/a^2},\qquad E^* = E/(1-\nu^2).$$
#
# The load grows like δ^{3/2} because the contact disc grows with the indentation. In 3D the
# indentation of a half-space is well defined, so δ drives the test and the load, the contact
# radius and the peak pressure are all compared with Hertz (THEORY §11.1–11.2).
#
# The model (`fxcontact.processes.hertz_sphere`): a quarter of the block (symmetry planes
# x = 0 and y = 0, a frictionless roller on the bottom), linear elastic, small strain, MINI
# velocity–pressure elements; frictionless nodal penalty contact (THEORY §2); the sphere
# touches the block at the origin and moves down in a few increments.
#
# Run: `python demos/demo_hertz_sphere.py` (about a minute; or under `mpirun -n 2`),
# `--quick` (the reduced size of the tests, seconds), `--size` the element size under the
# sphere. `--formulation p1|both` solves the same test as a plain P1-displacement dolfinx
# problem; `--tool nagata|flat` and `--compare` replace the exact sphere by a coarse faceted
# one. Outputs in `results/hertz_sphere` (`--output-dir`).

# %%
import argparse
import os

from mpi4py import MPI

from fxcontact.console import add_verbosity_arguments, configure_logging
from fxcontact.processes import hertz, hertz_sphere

ap = argparse.ArgumentParser(description="Hertz point contact (rigid sphere)")
ap.add_argument("--quick", action="store_true",
                help="reduced size of the tests: h_fine 0.05 mm, 20 mm block, 2 increments")
ap.add_argument("--size", type=float, default=None,
                help="fine element size h_fine [mm] (default 0.025, 0.05 with --quick)")
ap.add_argument("--scheme", default=None,
                help="contact scheme (default: implicit; implicit-exact in P1)")
ap.add_argument("--tool", default="analytic", choices=hertz.TOOLS,
                help="indenter: exact sphere or faceted sphere (Nagata / flat)")
ap.add_argument("--tool-facet-size", type=float, default=1.0,
                help="faceted tool: edge length at the lowest vertex [mm]")
ap.add_argument("--tool-normals", default="nvv", choices=("nvv", "exact", "angle", "area"),
                help="nodal normals of the Nagata patches")
ap.add_argument("--compare", action="store_true",
                help="run the analytic, Nagata and flat tools and compare them")
ap.add_argument("--formulation", default="mixed", choices=("mixed", "p1", "both"),
                help="MINI velocity-pressure (fxcontact Simulation), P1 displacement (a "
                     "dolfinx problem + ContactProblem), or both side by side")
ap.add_argument("--output-dir", "--output", dest="output_dir", default="results/hertz_sphere",
                help="where the results go (default results/hertz_sphere)")
add_verbosity_arguments(ap)
args = ap.parse_args()
configure_logging(args.verbose, args.quiet)
rank0 = MPI.COMM_WORLD.rank == 0

# %% [markdown]
# ## The reference
#
# For the default case Hertz gives about 1 kN on a disc of radius a ≈ 0.26 mm, five hundredths
# of R (small: the half-space theory holds), with a peak pressure above 7 GPa. (A real steel
# block would yield long before; the test checks the contact, not the material.)

# %%
E, nu, R, delta = 2e5, 0.3, 5.0, 0.0133
P_h, a_h, p0_h = hertz.hertz_sphere(delta, R, E / (1 - nu**2))
if rank0:
    print(f"Hertz at delta = {1e3 * delta:.1f} um: P = {P_h:.1f} N, a = {a_h:.4f} mm, "
          f"p0 = {p0_h:.0f} MPa")

# %% [markdown]
# ## The mesh and its size knob
#
# The far field of a point load decays like 1/r, and the half-space is infinite: the block
# must be large (a finite block on a rigid base is too stiff, by ≈ 1.5 % at 10 mm, ∝ 1/H)
# while its elements near the contact must be small. `hertz.graded_block` meshes an 80 mm
# quarter block (≈ 300 a) whose element size is `h_fine` within 0.4 mm of the first contact
# point and then grows linearly with the distance, with slope `growth` = 0.15: the cost of the
# large block is then logarithmic. The model is stiffer than Hertz for three reasons: the
# finite block (≈ +0.3 % here), the growth of the elements (∝ growth², ≈ +1.3 % at 0.2) and
# the resolution of the contact zone (≈ +2 % at h_fine = 50 µm, +1 % at 25 µm).
#
# `--quick` takes a coarse 20 mm block (h_fine = 50 µm, growth 0.3, two increments): the
# force is then ≈ 5 % too high, enough to see the physics in seconds.

# %%
size = args.size if args.size is not None else (0.05 if args.quick else 0.025)
params = dict(h_fine=size, scheme=args.scheme, tool_facet_size=args.tool_facet_size,
              tool_normals=args.tool_normals, output_dir=args.output_dir)
if args.quick:
    params.update(growth=0.3, width=20.0, height=20.0, h=4.0, n_steps=2)

# %% [markdown]
# ## The faceted tool (`--tool nagata|flat`, `--compare`)
#
# A tool given as a triangulated surface instead of an exact sphere: `hertz.make_tool` builds
# an *octahedral sphere* (each octant face of an octahedron split into n² triangles), exactly
# symmetric about the planes of the quarter model, whose lowest vertex sits where the exact
# sphere first touches. With the default 1 mm edges (512 triangles) the whole contact zone lies
# on the 4 facets around that vertex.
#
# * **Flat facets** form a shallow square pyramid there: a conical indenter. Expect a smaller
#   contact, a far smaller load (≈ −78 %) and a pressure peak at the tip that grows as the
#   block mesh is refined (the cone pressure is log-singular).
# * **Nagata patches** (curved triangles through the vertices and their normals) restore the
#   curvature: their gap error over the contact zone is below 0.05 µm against the 6.6 µm sphere
#   gap at r = a. Measured at the default size: p_max within 0.3 % of the exact sphere's, the
#   same 4 Newton iterations per increment, no fallback to the flat facet.
#
# ## The run

# %%
if args.compare:
    res = hertz_sphere.compare_tools(**params)
    if rank0:
        print(res["table"])
        print(f"pictures: {res['png']}")
elif args.formulation == "both":
    res = hertz_sphere.compare_formulations(tool=args.tool, **params)
    if rank0:
        print(res["table"])
else:
    res = hertz_sphere.run(tool=args.tool, formulation=args.formulation, **params)

# %% [markdown]
# ## Comparison with Hertz
#
# The force is the quarter model's tool force × 4 (the bottom reaction checks it); the FEM
# contact radius is that of the disc with the active nodes' area, `sqrt(4 Σ S_n / π)`, and the
# radii of the last active and the first inactive node bracket the edge. Measured at the
# default size (25 µm, 128k dofs): P = 1027.6 N (+2.2 %), p_max = 7328 MPa (+1.6 %),
# a = 0.261 mm. In P1 displacement (`--formulation p1`, 21k dofs) the same mesh gives +2.8 %
# and +4.5 %: P1 tetrahedra are stiffer than MINI.

# %%
if rank0 and not args.compare and args.formulation != "both":
    lo, hi = res["contact_radius_bounds"]
    print(f"mesh: {res['cells']} tetrahedra, {res['dofs']} dofs, h_fine = {res['h_fine']} "
          f"mm, {res['active_nodes']} active nodes; {res['wall_time']:.1f} s "
          f"({res['formulation']}, {res['newton_iterations']} Newton iterations)")
    if res["tool"] != "analytic":
        print(f"tool: {res['tool']}, {res['tool_triangles']} triangles, edge "
              f"{res['tool_facet_size']:.3f} mm at the lowest vertex; Nagata fallbacks "
              f"{res['fallbacks']}")
    print(f"bottom reaction {res['bottom_reaction']:.2f} N")
    print(f"{'':22s}{'FEM':>12s}{'Hertz':>12s}{'error':>10s}")
    for name, k, kh in (("force P [N]", "force", "hertz_force"),
                        ("radius a [mm]", "contact_radius", "hertz_contact_radius"),
                        ("p_max [MPa]", "p_max", "hertz_p_max")):
        print(f"{name:22s}{res[k]:12.5g}{res[kh]:12.5g}{res[k] / res[kh] - 1:10.2%}")
    print(f"active/inactive node radii {lo:.4f}..{hi:.4f}; a/R = "
          f"{res['hertz_contact_radius'] / res['radius']:.3f}")

# %% [markdown]
# ## What was written
#
# In the output directory: the VTK series and the CSV history of the increments
# (`hertz_sphere.pvd`, `hertz_sphere_history.csv`), the nodal pressure profile
# `profile.csv` (r, p, S), `hertz_sphere.png` (the nodal pressures against the Hertz ellipse:
# they follow it closely up to the edge, where a node is either in or out) and
# `hertz_sphere_3d.png` (the contact zone seen on the symmetry plane, displacements ×20,
# coloured by the equivalent strain: its maximum lies below the surface, under the centre of
# the contact, as in Hertz's solution). In P1: `profile_p1.csv`, `hertz_sphere_p1.png`; with `--compare` one
# subdirectory per tool and `hertz_sphere_tools.png`, the three profiles against Hertz.

# %%
if rank0 and not args.compare and args.formulation != "both":
    written = [res["png"], res["png_deformed"]]
    print("outputs:", ", ".join(p for p in written if p) or "none",
          f"(in {os.path.abspath(args.output_dir)})")
