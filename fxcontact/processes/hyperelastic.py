"""Contact in a user's own dolfinx problem: a neo-Hookean block pressed by a rigid ball.

The problem is written the dolfinx way, as in the dolfinx hyperelasticity demo, with no
fxcontact in it (:func:`hyperelastic_problem`): block [-1, 1]² × [0, 1] on a fixed base,
compressible neo-Hookean, ψ = μ/2 (I_C − 3) − μ ln J + λ/2 (ln J)², P1 displacement, large
strain. :func:`add_contact` adds the rigid frictionless ball (radius :data:`R_BALL`) and the
nodal contact on the top face in displacement form: re-projected on the sphere at every Newton
iteration (scheme ``implicit-exact``: exact gap gradient and Hessian), the gap written on the
positions X = X_ref + u at the end of each load step, the gap stiffness k = β E*/h_e (β = 100).

:func:`run` presses the ball in load steps with one of three drivers, which give the same
answer: dolfinx's ``NewtonSolver`` on a :class:`~fxcontact.newton.problem.ContactProblem`, a
petsc4py SNES with :meth:`~fxcontact.newton.problem.ContactProblem.snes_callbacks`, or
fxcontact's own :class:`~fxcontact.newton.solver.ContactNewtonSolver` on a
:class:`~fxcontact.newton.problem.NodalNonlinearProblem`. Pictures: :func:`render` (the
deformed block coloured by J = det F) and :func:`plot_force` (ball force against indentation).

Units: consistent, the block's height is 1 (E = 10 MPa with lengths in mm: forces in N).
:func:`run` and :func:`render` are collective; :func:`plot_force` draws on the calling rank.
"""

from __future__ import annotations

import time

import dolfinx
import dolfinx.fem
import dolfinx.fem.petsc
import dolfinx.mesh
import dolfinx.nls.petsc
import numpy as np
import ufl
from mpi4py import MPI
from petsc4py import PETSc

from fxcontact import compat
from fxcontact.contact.boundary import ContactBoundary, vertex_dof_map
from fxcontact.contact.nodal import NodalContact
from fxcontact.io import figure, render_png
from fxcontact.newton.problem import ContactProblem, NodalNonlinearProblem
from fxcontact.newton.solver import ContactNewtonSolver, SolverOptions
from fxcontact.tools.analytic import Sphere

__all__ = ["TOP", "R_BALL", "DRIVERS", "hyperelastic_problem", "add_contact", "run", "render",
           "plot_force"]

#: facet tag of the block's top face (the contact boundary); the bottom face is tagged 1
TOP = 2
#: radius of the rigid ball
R_BALL = 0.6
#: the solvers of :func:`run`
DRIVERS = ("newton", "snes", "fxcontact")


# ------------------------------------------------------------------ the dolfinx problem

def hyperelastic_problem(comm, n: int = 12, E: float = 10.0, nu: float = 0.3):
    """Mesh, P1 displacement space, unknown, residual (neo-Hookean) and BCs, written as in the
    dolfinx hyperelasticity demo.

    Args:
        comm: the communicator of the mesh.
        n: boxes per unit length: n × n × max(n//2, 2) boxes of 6 tetrahedra on
            [-1, 1]² × [0, 1].
        E: Young's modulus [MPa]; nu: Poisson's ratio.
    Returns:
        ``(msh, facet_tags, V, u, F, bcs)``: the bottom face (tag 1) fixed, the top face
        tagged :data:`TOP`.
    """
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


# ------------------------------------------------------------------ the contact and the solvers

def add_contact(V, facet_tags, E: float, nu: float, depth: float, scheme="implicit-exact",
                beta: float = 100.0):
    """The rigid ball (radius :data:`R_BALL`, touching the top face at t = 0 and moving down
    by ``depth`` per unit time) and the frictionless nodal contact on the top face in
    displacement form, with the gap stiffness β E*/h_e (E* = E/(1 − ν²) [MPa])."""
    ball = Sphere(center=(0.0, 0.0, 1.0 + R_BALL), radius=R_BALL,
                  velocity=(0.0, 0.0, -depth), name="ball")
    return NodalContact(ContactBoundary(V, facet_tags, TOP), ball, scheme=scheme,
                        formulation="displacement", beta=beta, modulus=E / (1 - nu**2))


def _lu(prefix: str):
    """MUMPS LU for the KSP of options prefix ``prefix`` (the user's linear solver)."""
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
    :meth:`fxcontact.ContactProblem.use_linear_solver` (``"newton"`` and ``"snes"``).

    Args:
        n: mesh size knob of :func:`hyperelastic_problem`; n_steps: load steps.
        depth: final indentation of the ball (the block is 1 high).
        E [MPa], nu: the material; scheme: the contact scheme.
    Returns:
        dict with ``rows`` (per step: ``indentation``, the ball ``force`` [N],
        ``contact_nodes``, ``pressure_max`` [MPa], ``newton`` iterations), the final
        ``force``, the lowest vertical displacement ``u_z_min``, the true ``penetration``,
        the total ``newton`` iterations, ``held`` (iterations the solver was held because the
        active set changed), ``dofs``, ``wall_time`` and ``times`` [s], ``krylov``
        iterations, and the ``msh``, ``u``, ``V``, ``contact`` objects (for :func:`render`).
    """
    t0 = time.perf_counter()
    msh, facet_tags, V, u, F, bcs = hyperelastic_problem(comm, n, E, nu)
    contact = add_contact(V, facet_tags, E, nu, depth, scheme)
    problem = ContactProblem(F, u, bcs, contributors=[contact])
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
        fprob = NodalNonlinearProblem(F, u, bcs, contributors=[contact])
        fsolver = ContactNewtonSolver(fprob, SolverOptions(
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


# ------------------------------------------------------------------ pictures

def render(res: dict, path: str, depth: float):
    """The deformed half y > 0 of the block (true scale) of a :func:`run` result, coloured by
    J = det F, with the ball at ``depth``, seen on the plane y = 0. Collective; returns
    ``path``, or None without a renderer."""
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
    ok = render_png(sub, path, Jf.x.array[np.asarray(cmap)[:nsub]], "J = det F",
                    extra_meshes=[(P, tri)],
                    title=f"neo-Hookean block pressed {depth:g} by a rigid ball, half y > 0 "
                          f"(P1 displacement, dolfinx NewtonSolver + fxcontact)",
                    camera="xz")
    return path if ok else None


def plot_force(results, path: str):
    """The ball force against the indentation for each :func:`run` result of ``results``;
    writes the PNG ``path`` and returns it (matplotlib: call on one rank)."""
    with figure(path, figsize=(6.5, 4.2)) as (fig, ax):
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

