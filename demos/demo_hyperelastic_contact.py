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
# strain, ``NonlinearProblem`` + ``NewtonSolver``) — and wants to press a rigid tool into it.
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
# The contact is re-projected on the sphere at every Newton iteration (scheme
# ``implicit-exact``: exact gap gradient and Hessian), the gap is written on the positions
# X = X_ref + u at the end of each load step, and the penalty is the gap stiffness
# k = β E*/h_e (β = 100). The same problem is also solved with a petsc4py SNES using
# :meth:`fxcontact.ContactProblem.snes_callbacks`, and with fxcontact's own Newton solver: the
# three give the same answer (printed table).
#
# **Problem.** Block [-1, 1]² × [0, 1] on a fixed base, compressible neo-Hookean
# (E = 10 MPa, ν = 0.3: ψ = μ/2 (I_C − 3) − μ ln J + λ/2 (ln J)²), pressed by a rigid
# frictionless sphere of radius 0.6 down to ``depth`` = 0.3 (30 % of the height), in
# ``n_steps`` load steps. Outputs (``results/hyperelastic_contact``): the deformed block coloured
# by J = det F (PNG), the ball force against the indentation (PNG, CSV).
#
# Run: ``python demos/demo_hyperelastic_contact.py`` (or under ``mpirun -n 2``);
# ``--size n`` sets the mesh (n × n × n/2 boxes of 6 tetrahedra), ``--steps`` the load steps.

# %%
from __future__ import annotations

import argparse
import os
import time

import numpy as np
import ufl
from mpi4py import MPI
from petsc4py import PETSc

import dolfinx
import dolfinx.fem
import dolfinx.fem.petsc
import dolfinx.mesh
import dolfinx.nls.petsc

import fxcontact as fx
from fxcontact.console import add_verbosity_arguments, configure_logging

TOP = 2
R_BALL = 0.6


# %% [markdown]
# ## The dolfinx problem (no fxcontact in here)

# %%
def hyperelastic_problem(comm, n: int = 12, E: float = 10.0, nu: float = 0.3):
    """Mesh, P1 displacement space, unknown, residual (neo-Hookean) and BCs, written as in the
    dolfinx hyperelasticity demo. Returns ``(msh, facet_tags, V, u, F, bcs)``."""
    msh = dolfinx.mesh.create_box(comm, [[-1.0, -1.0, 0.0], [1.0, 1.0, 1.0]],
                                  [n, n, max(n // 2, 2)], dolfinx.mesh.CellType.tetrahedron)
    V = dolfinx.fem.VectorFunctionSpace(msh, ("Lagrange", 1))

    def bottom(x):
        return np.isclose(x[2], 0.0)

    def top(x):
        return np.isclose(x[2], 1.0)

    fdim = msh.topology.dim - 1
    bottom_facets = dolfinx.mesh.locate_entities_boundary(msh, fdim, bottom)
    top_facets = dolfinx.mesh.locate_entities_boundary(msh, fdim, top)
    marked = np.hstack([bottom_facets, top_facets])
    values = np.hstack([np.full_like(bottom_facets, 1), np.full_like(top_facets, TOP)])
    order = np.argsort(marked)
    facet_tags = dolfinx.mesh.meshtags(msh, fdim, marked[order], values[order])

    u_bc = np.array((0,) * 3, dtype=PETSc.ScalarType)
    bcs = [dolfinx.fem.dirichletbc(u_bc, dolfinx.fem.locate_dofs_topological(
        V, fdim, facet_tags.find(1)), V)]

    v = ufl.TestFunction(V)
    u = dolfinx.fem.Function(V, name="displacement")
    d = len(u)
    I = ufl.variable(ufl.Identity(d))
    Fg = ufl.variable(I + ufl.grad(u))
    C = ufl.variable(Fg.T * Fg)
    Ic = ufl.variable(ufl.tr(C))
    J = ufl.variable(ufl.det(Fg))
    mu = dolfinx.fem.Constant(msh, PETSc.ScalarType(E / (2 * (1 + nu))))
    lmbda = dolfinx.fem.Constant(msh, PETSc.ScalarType(E * nu / ((1 + nu) * (1 - 2 * nu))))
    psi = (mu / 2) * (Ic - 3) - mu * ufl.ln(J) + (lmbda / 2) * (ufl.ln(J)) ** 2
    P = ufl.diff(psi, Fg)
    dx = ufl.Measure("dx", domain=msh, metadata={"quadrature_degree": 2})
    F = ufl.inner(ufl.grad(v), P) * dx
    return msh, facet_tags, V, u, F, bcs


# %% [markdown]
# ## The fxcontact lines, and three ways to solve

# %%
def add_contact(V, facet_tags, E: float, nu: float, depth: float, scheme="implicit-exact",
                beta: float = 100.0):
    """The rigid ball and the nodal contact on the top face (displacement form)."""
    ball = fx.Sphere(center=(0.0, 0.0, 1.0 + R_BALL), radius=R_BALL,
                     velocity=(0.0, 0.0, -depth), name="ball")
    return fx.NodalContact(fx.ContactBoundary(V, facet_tags, TOP), ball, scheme=scheme,
                           formulation="displacement", beta=beta, modulus=E / (1 - nu**2))


def _lu(prefix: str):
    opts = PETSc.Options()
    for key, val in {"ksp_type": "preonly", "pc_type": "lu",
                     "pc_factor_mat_solver_type": "mumps"}.items():
        opts[prefix + key] = val


def run(driver: str = "newton", n: int = 12, n_steps: int = 6, depth: float = 0.3,
        E: float = 10.0, nu: float = 0.3, scheme: str = "implicit-exact",
        comm=MPI.COMM_WORLD, linear_solver=None) -> dict:
    """Press the ball in ``n_steps`` load steps with ``driver``: ``"newton"`` (dolfinx's
    NewtonSolver), ``"snes"`` (a petsc4py SNES with ContactProblem's callbacks) or
    ``"fxcontact"`` (fxcontact's ContactNewtonSolver on a NodalNonlinearProblem).
    ``linear_solver``: None (the user's MUMPS LU) or a kind of
    :meth:`fxcontact.ContactProblem.use_linear_solver` (``"newton"`` and ``"snes"``)."""
    t0 = time.perf_counter()
    msh, facet_tags, V, u, F, bcs = hyperelastic_problem(comm, n, E, nu)
    contact = add_contact(V, facet_tags, E, nu, depth, scheme)
    problem = fx.ContactProblem(F, u, bcs, contributors=[contact])
    if driver == "newton":
        solver = dolfinx.nls.petsc.NewtonSolver(comm, problem)
        solver.atol, solver.rtol = 1e-12, 1e-10
        solver.convergence_criterion = "incremental"
        problem.set_solver(solver)
        ksp = solver.krylov_solver
        _lu(ksp.getOptionsPrefix())
        ksp.setFromOptions()
        if linear_solver is not None:
            problem.use_linear_solver(solver, linear_solver)

        def solve():
            return solver.solve(u)[0]
    elif driver == "snes":
        b = dolfinx.fem.petsc.create_vector(problem.L)
        A = dolfinx.fem.petsc.create_matrix(problem.a)
        snes = PETSc.SNES().create(comm)
        snes.setOptionsPrefix("hyper_")
        _lu("hyper_")
        PETSc.Options()["hyper_snes_linesearch_type"] = "basic"
        residual, jacobian, converged = problem.snes_callbacks()
        snes.setFunction(residual, b)
        snes.setJacobian(jacobian, A, A)
        snes.setConvergenceTest(converged)
        snes.setTolerances(rtol=1e-10, atol=1e-12, stol=1e-10, max_it=50)
        snes.setFromOptions()
        if linear_solver is not None:
            problem.use_linear_solver(snes, linear_solver)

        def solve():
            x = u.vector.copy()
            snes.solve(None, x)
            if snes.getConvergedReason() <= 0:
                raise RuntimeError(f"SNES did not converge ({snes.getConvergedReason()})")
            x.copy(u.vector)
            u.x.scatter_forward()
            x.destroy()
            return snes.getIterationNumber()
    elif driver == "fxcontact":
        fprob = fx.NodalNonlinearProblem(F, u, bcs, contributors=[contact])
        fsolver = fx.ContactNewtonSolver(fprob, fx.SolverOptions(
            rtol=1e-10, atol=1e-12, stol=1e-10, max_it=50, prefix="hyper_fx_"))

        def solve():
            info = fsolver.solve()
            if not info.converged:
                raise RuntimeError(info.message)
            return info.iterations
    else:
        raise ValueError(f"driver must be 'newton', 'snes' or 'fxcontact', got {driver!r}")
    rows = []
    for step in range(1, n_steps + 1):
        problem.begin_step(step / n_steps)
        its = solve()
        d = contact.diagnostics()
        rows.append({"step": step, "indentation": depth * step / n_steps,
                     "force": float(d["ball_force_z"]), "contact_nodes": d["contact_nodes"],
                     "pressure_max": d["contact_pressure_max"], "newton": int(its)})
    problem.end_step()
    umin = comm.allreduce(float(np.min(u.x.array.reshape(-1, 3)[:, 2], initial=0.0)),
                          op=MPI.MIN)
    return {"driver": driver, "rows": rows, "force": rows[-1]["force"], "u_z_min": umin,
            "penetration": contact.diagnostics()["contact_penetration_true"],
            "newton": sum(r["newton"] for r in rows), "held": problem.iterations_unstable,
            "dofs": V.dofmap.index_map.size_global * 3, "wall_time": time.perf_counter() - t0,
            "times": dict(problem.timers.times), "krylov": problem.krylov_iterations,
            "msh": msh, "u": u, "V": V, "contact": contact}


# %% [markdown]
# ## Pictures (collective)

# %%
def render(res: dict, path: str, depth: float):
    """The deformed block (true scale) coloured by J = det F, with the ball."""
    from fxcontact import compat
    from fxcontact.contact.boundary import vertex_dof_map

    msh, u, V = res["msh"], res["u"], res["V"]
    nv = msh.topology.index_map(0).size_local + msh.topology.index_map(0).num_ghosts
    geo = compat.entities_to_geometry(msh, 0, np.arange(nv, dtype=np.int32)).ravel()
    vd, _ = vertex_dof_map(V, msh)
    Q = dolfinx.fem.FunctionSpace(msh, ("DG", 0))
    Jf = dolfinx.fem.Function(Q)
    Jf.interpolate(dolfinx.fem.Expression(ufl.det(ufl.Identity(3) + ufl.grad(u)),
                                          Q.element.interpolation_points()))
    # the half y > 0 (seen on the symmetry plane y = 0: the pit under the ball)
    ncell = msh.topology.index_map(3).size_local
    mid = dolfinx.mesh.compute_midpoints(msh, 3, np.arange(ncell, dtype=np.int32))
    cells = np.flatnonzero(mid[:, 1] > 0.0).astype(np.int32)
    sub, cmap, _, gmap = dolfinx.mesh.create_submesh(msh, 3, cells)
    disp = np.zeros_like(msh.geometry.x)
    disp[geo, :3] = u.x.array[vd]
    sub.geometry.x[:, :3] += disp[np.asarray(gmap), :3]
    nsub = sub.topology.index_map(3).size_local
    th, ph = np.meshgrid(np.linspace(0, np.pi, 25), np.linspace(0, np.pi, 25))
    c = np.array([0.0, 0.0, 1.0 + R_BALL - depth])
    P = np.c_[(R_BALL * np.sin(th) * np.cos(ph)).ravel(), (R_BALL * np.sin(th) * np.sin(ph))
              .ravel(), (R_BALL * np.cos(th)).ravel()] + c
    ni, nj = th.shape
    idx = np.arange(ni * nj).reshape(ni, nj)
    tri = np.r_[np.c_[idx[:-1, :-1].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel()],
                np.c_[idx[:-1, :-1].ravel(), idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()]]
    ok = fx.render_png(sub, path, Jf.x.array[np.asarray(cmap)[:nsub]], "J = det F",
                       extra_meshes=[(P, tri)],
                       title=f"neo-Hookean block pressed {depth:g} by a rigid ball, half y > 0 "
                             f"(P1 displacement, dolfinx NewtonSolver + fxcontact)",
                       camera="xz")
    return path if ok else None


def plot_force(results, path: str):
    with fx.figure(path, figsize=(6.5, 4.2)) as (fig, ax):
        for res, mk in zip(results, ("o-", "s--", "^:")):
            r = res["rows"]
            ax.plot([0] + [x["indentation"] for x in r], [0] + [x["force"] for x in r], mk,
                    mfc="none", label=f"{res['driver']}: {res['newton']} Newton its, "
                                      f"{res['wall_time']:.1f} s")
        ax.set_xlabel("indentation [mm]")
        ax.set_ylabel("ball force [N]")
        ax.set_title("Rubber block pressed by a rigid ball: three solvers, one answer")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    return path


# %%
if __name__ == "__main__":
    ap = argparse.ArgumentParser(description="neo-Hookean block pressed by a rigid ball")
    ap.add_argument("--size", type=int, default=12, help="boxes per unit length")
    ap.add_argument("--steps", type=int, default=6, help="load steps")
    ap.add_argument("--depth", type=float, default=0.3, help="final indentation")
    ap.add_argument("--output", default="results/hyperelastic_contact")
    add_verbosity_arguments(ap)
    args = ap.parse_args()
    configure_logging(args.verbose, args.quiet)
    comm = MPI.COMM_WORLD
    results = [run(d, args.size, args.steps, args.depth) for d in ("newton", "snes",
                                                                   "fxcontact")]
    ref = results[0]
    os.makedirs(args.output, exist_ok=True)
    png = render(ref, os.path.join(args.output, "hyperelastic_contact.png"), args.depth)
    if comm.rank == 0:
        print(f"{ref['dofs']} dofs, {args.steps} load steps, indentation {args.depth}")
        print(f"{'driver':10s}{'force [N]':>12s}{'rel. diff':>11s}{'min u_z':>10s}"
              f"{'Newton':>8s}{'held':>6s}{'time [s]':>9s}")
        for r in results:
            print(f"{r['driver']:10s}{r['force']:12.6f}{r['force'] / ref['force'] - 1:11.2e}"
                  f"{r['u_z_min']:10.4f}{r['newton']:8d}{r['held']:6d}{r['wall_time']:9.1f}")
        print(f"penetration (penalty) {ref['penetration']:.2e} at indentation {args.depth}")
        with open(os.path.join(args.output, "force.csv"), "w") as f:
            f.write("indentation,force_newton,force_snes,force_fxcontact\n")
            for k, row in enumerate(ref["rows"]):
                f.write(f"{row['indentation']},"
                        + ",".join(f"{r['rows'][k]['force']:.10g}" for r in results) + "\n")
        print("outputs:", plot_force(results, os.path.join(args.output, "force.png")), png)
