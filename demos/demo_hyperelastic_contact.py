# ---
# jupyter:
#   jupytext:
#     text_representation:
#       extension: .py
#       format_name: percent
# ---

# %% [markdown]
# # Contact in your own dolfinx problem: a rubber block pressed by a sphere
#
# A FEniCSx user has a working displacement-based problem written the dolfinx way — here the
# compressible neo-Hookean block of the dolfinx hyperelasticity demo (P1 displacement, large
# strain, `NonlinearProblem` + `NewtonSolver`) — and wants to press a rigid tool into it.
# fxcontact's nodal contact plugs into that problem as it is: the diff between the problem
# without contact and with contact is these lines
#
# ```diff
# +import fxcontact as fx
# +ball = fx.Sphere(center=(0, 0, 1 + R), radius=R, velocity=(0, 0, -depth), name="ball")
# +contact = fx.NodalContact(fx.ContactBoundary(V, facet_tags, TOP), ball,
# +                          formulation="displacement", beta=100.0, modulus=E / (1 - nu**2))
# -problem = dolfinx.fem.petsc.NonlinearProblem(F, u, bcs)
# +problem = fx.ContactProblem(F, u, bcs, contributors=[contact])
#  solver = dolfinx.nls.petsc.NewtonSolver(msh.comm, problem)
# +problem.set_solver(solver)          # Newton may stop only on an unchanged active set
#  for step in range(1, n_steps + 1):
# +    problem.begin_step(step / n_steps)  # the ball at t = step/n: depth·step/n down
#      n, converged = solver.solve(u)
# ```
#
# The code is in `fxcontact.processes.hyperelastic`: `hyperelastic_problem` is the plain
# dolfinx problem (no fxcontact in it), `add_contact` the lines above, `run` the load steps.
#
# **Problem.** Block [-1, 1]² × [0, 1] on a fixed base, compressible neo-Hookean
# (E = 10 MPa, ν = 0.3: ψ = μ/2 (I_C − 3) − μ ln J + λ/2 (ln J)²), pressed by a rigid
# frictionless sphere of radius 0.6 down to `depth` = 0.3 (30 % of the height) in `n_steps`
# load steps. Large strain: the top face sinks by 30 % of the height under the ball, where
# the rubber loses about a fifth of its volume (J ≈ 0.8).
#
# Run: `python demos/demo_hyperelastic_contact.py` (or under `mpirun -n 2`); `--size n` sets
# the mesh (n × n × n/2 boxes of 6 tetrahedra), `--steps` the load steps, `--depth` the final
# indentation, `--quick` the reduced size of the tests. Outputs in
# `results/hyperelastic_contact` (`--output-dir`).

# %%
import argparse
import os

from mpi4py import MPI

from fxcontact.console import add_verbosity_arguments, configure_logging
from fxcontact.processes import hyperelastic

ap = argparse.ArgumentParser(description="neo-Hookean block pressed by a rigid ball")
ap.add_argument("--quick", action="store_true",
                help="reduced size of the tests: --size 6 --steps 3")
ap.add_argument("--size", type=int, default=None, help="boxes per unit length (default 12)")
ap.add_argument("--steps", type=int, default=None, help="load steps (default 6)")
ap.add_argument("--depth", type=float, default=0.3, help="final indentation")
ap.add_argument("--output-dir", "--output", dest="output_dir",
                default="results/hyperelastic_contact",
                help="where the results go (default results/hyperelastic_contact)")
add_verbosity_arguments(ap)
args = ap.parse_args()
configure_logging(args.verbose, args.quiet)
comm = MPI.COMM_WORLD
size = args.size if args.size is not None else (6 if args.quick else 12)
steps = args.steps if args.steps is not None else (3 if args.quick else 6)

# %% [markdown]
# ## The contact
#
# The contact is re-projected on the sphere at every Newton iteration (scheme
# `implicit-exact`: exact gap gradient and Hessian, hence quadratic convergence once the
# active set holds), the gap is written on the positions X = X_ref + u at the end of each load
# step, and the penalty is the gap stiffness k = β E*/h_e (β = 100): the penetration stays a
# small fraction of the indentation (printed below).
#
# ## Three ways to solve, one answer
#
# The same problem, the same contact object, three nonlinear solvers:
#
# * `newton`: dolfinx's own `NewtonSolver` on `fx.ContactProblem` (the diff above);
# * `snes`: a petsc4py SNES with `residual, jacobian, test = problem.snes_callbacks()`;
# * `fxcontact`: fxcontact's `ContactNewtonSolver` on a `NodalNonlinearProblem`.
#
# All three use MUMPS LU for the linear systems and stop only on an unchanged active set
# ("held": the iterations at which `ContactProblem` held dolfinx's or SNES's tolerance
# because the set changed; fxcontact's solver applies the same rule by itself).

# %%
results = [hyperelastic.run(d, size, steps, args.depth) for d in hyperelastic.DRIVERS]
ref = results[0]
if comm.rank == 0:
    print(f"{ref['dofs']} dofs, {steps} load steps, indentation {args.depth}")
    print(f"{'driver':10s}{'force [N]':>12s}{'rel. diff':>11s}{'min u_z':>10s}"
          f"{'Newton':>8s}{'held':>6s}{'time [s]':>9s}")
    for r in results:
        print(f"{r['driver']:10s}{r['force']:12.6f}{r['force'] / ref['force'] - 1:11.2e}"
              f"{r['u_z_min']:10.4f}{r['newton']:8d}{r['held']:6d}{r['wall_time']:9.1f}")
    print(f"penetration (penalty) {ref['penetration']:.2e} at indentation {args.depth}")

# %% [markdown]
# The forces agree to the Newton tolerance (about 1e-9 relative: the drivers solve the same
# equations). The lowest point of the top face has gone down by the indentation (`min u_z`),
# less the small penalty penetration.
#
# ## What was written
#
# `hyperelastic_contact.png`: the deformed half block y > 0 (true scale) seen on the plane
# y = 0, coloured by J = det F, with the ball: the pit and the compressed rubber (J < 1)
# under the ball. `force.png` and `force.csv`: the ball force against the indentation for
# the three drivers — stiffening as the contact area grows.

# %%
os.makedirs(args.output_dir, exist_ok=True)
png = hyperelastic.render(ref, os.path.join(args.output_dir, "hyperelastic_contact.png"),
                          args.depth)
if comm.rank == 0:
    with open(os.path.join(args.output_dir, "force.csv"), "w") as f:
        f.write("indentation,force_newton,force_snes,force_fxcontact\n")
        for k, row in enumerate(ref["rows"]):
            f.write(f"{row['indentation']},"
                    + ",".join(f"{r['rows'][k]['force']:.10g}" for r in results) + "\n")
    print("outputs:", hyperelastic.plot_force(results, os.path.join(args.output_dir,
                                                                    "force.png")), png)
