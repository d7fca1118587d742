"""The Hertz sphere as a FEniCSx user writes it today: P1 displacement, linear elasticity and an
integrated UFL penalty on the exact sphere gap — no fxcontact contact.

    F = ∫ σ(u):ε(v) dx − ∫_top k [−g(x + u)]₊ n_s(x + u)·v ds,
    g(X) = |X − c| − R,  n_s = (X − c)/|X − c|,

solved with dolfinx's NewtonSolver (MUMPS) in load steps (the sphere centre c moves down), on
the same graded quarter block as the Hertz sphere (``fxcontact.processes.hertz.graded_block``),
penalty k = β E*/h_fine with β = 1e3 (with the nodal contact's β = 1e4 this Newton iteration
cycles: quadrature points enter and leave contact at every iteration; 1e3 keeps the penetration
below 1e-3 δ). The penalty integral uses quadrature degree ``quad`` on the facets (the
estimated default degree for the square root of the gap is far higher and slower). The nodal
pressure is the lumped L2 projection of k [−g]₊ on P1 over the top face (∫ p N_n ds / ∫ N_n ds):
the vertices of a P1 surface pressed by a convex tool may stay outside it while the facet
interiors penetrate, so vertex values of the gap miss the pressure, and the quadrature-point
values (also returned) oscillate.

Run: ``python benchmarks/hertz_ufl_penalty.py --size 0.025``.
"""

from __future__ import annotations

import argparse
import math
import time

import dolfinx
import dolfinx.fem
import dolfinx.fem.petsc
import dolfinx.nls.petsc
import numpy as np
import ufl
from mpi4py import MPI
from petsc4py import PETSc


class _TimedProblem(dolfinx.fem.petsc.NonlinearProblem):
    """dolfinx's NonlinearProblem with the wall times of the assembly (residuals, Jacobians;
    the penalty integral included) and of the linear solve (end of each Jacobian to the next
    residual), as ``fxcontact.ContactProblem.timers`` measures them."""

    def __init__(self, *args, **kw):
        super().__init__(*args, **kw)
        self.times = {"assembly": 0.0, "linear_solve": 0.0}
        self._jacobian_done = None

    def F(self, x, b):
        t = time.perf_counter()
        if self._jacobian_done is not None:
            self.times["linear_solve"] += t - self._jacobian_done
            self._jacobian_done = None
        super().F(x, b)
        self.times["assembly"] += time.perf_counter() - t

    def J(self, x, A):
        t = time.perf_counter()
        super().J(x, A)
        self._jacobian_done = time.perf_counter()
        self.times["assembly"] += self._jacobian_done - t


def run(h_fine=0.025, radius=5.0, E=2e5, nu=0.3, indentation=0.0133, beta=1e3, n_steps=3,
        quad=2, h=16.0, width=80.0, height=80.0, refine=0.4, growth=0.15,
        comm=MPI.COMM_WORLD) -> dict:
    from fxcontact.meshing import BLOCK_TAGS
    from fxcontact.processes.hertz import graded_block

    t0 = time.perf_counter()
    msh, _, ft = graded_block(comm, width, height, h_fine, refine, growth, h)
    V = dolfinx.fem.VectorFunctionSpace(msh, ("Lagrange", 1))
    u, v = dolfinx.fem.Function(V), ufl.TestFunction(V)
    mu, lmbda = E / (2 * (1 + nu)), E * nu / ((1 + nu) * (1 - 2 * nu))
    eps = lambda w: ufl.sym(ufl.grad(w))  # noqa: E731
    sigma = 2 * mu * eps(u) + lmbda * ufl.tr(eps(u)) * ufl.Identity(3)
    E_star = E / (1 - nu**2)
    k = beta * E_star / h_fine
    zc = dolfinx.fem.Constant(msh, PETSc.ScalarType(radius))    # sphere centre height
    x = ufl.SpatialCoordinate(msh)
    X = x + u
    d = X - ufl.as_vector((0.0, 0.0, zc))
    dist = ufl.sqrt(ufl.dot(d, d))
    gap = dist - radius
    ppos = lambda a: (a + abs(a)) / 2  # noqa: E731
    ds = ufl.Measure("ds", domain=msh, subdomain_data=ft,
                     metadata={"quadrature_degree": quad})
    top = BLOCK_TAGS["zmax"]
    F = ufl.inner(sigma, eps(v)) * ufl.dx - k * ppos(-gap) * ufl.dot(d / dist, v) * ds(top)
    bcs = []
    for name, comp in (("xmin", 0), ("ymin", 1), ("zmin", 2)):
        dofs = dolfinx.fem.locate_dofs_topological(V.sub(comp), 2,
                                                   ft.indices[ft.values == BLOCK_TAGS[name]])
        bcs.append(dolfinx.fem.dirichletbc(PETSc.ScalarType(0.0), dofs, V.sub(comp)))
    problem = _TimedProblem(F, u, bcs)
    solver = dolfinx.nls.petsc.NewtonSolver(comm, problem)
    solver.convergence_criterion = "incremental"
    solver.rtol, solver.atol, solver.max_it = 1e-9, 1e-14, 50
    ksp = solver.krylov_solver
    opts, pfx = PETSc.Options(), ksp.getOptionsPrefix()
    for key, val in {"ksp_type": "preonly", "pc_type": "lu",
                     "pc_factor_mat_solver_type": "mumps"}.items():
        opts[pfx + key] = val
    ksp.setFromOptions()
    newton = 0
    t_newton = time.perf_counter()
    for step in range(1, n_steps + 1):
        zc.value = radius - indentation * step / n_steps
        newton += solver.solve(u)[0]
    times = {**problem.times, "newton": time.perf_counter() - t_newton}
    # force on the sphere (quarter model x 4)
    force = 4 * comm.allreduce(dolfinx.fem.assemble_scalar(dolfinx.fem.form(
        k * ppos(-gap) * (-d[2] / dist) * ds(top))), op=MPI.SUM)
    # nodal pressure: lumped L2 projection of k [−g]₊ on P1 over the top face,
    # p_n = ∫ p N_n ds / ∫ N_n ds (a nodal force over a nodal area, as the nodal contact's);
    # and the largest value at the quadrature points (where the integral applies it)
    Q = dolfinx.fem.FunctionSpace(msh, ("Lagrange", 1))
    q = ufl.TestFunction(Q)
    vecs = []
    for form in (k * ppos(-gap) * q * ds(top), q * ds(top)):
        b = dolfinx.fem.petsc.assemble_vector(dolfinx.fem.form(form))
        b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        vecs.append(b.getArray(readonly=True).copy())
        b.destroy()
    on = vecs[1] > 0
    p_max = comm.allreduce(float(np.max(vecs[0][on] / vecs[1][on], initial=0.0)), op=MPI.MAX)
    from fxcontact import compat
    from fxcontact.contact.boundary import vertex_dof_map
    fdim = 2
    msh.topology.create_connectivity(fdim, 0)
    f2v = msh.topology.connectivity(fdim, 0)
    facets = ft.indices[ft.values == top]
    facets = facets[facets < msh.topology.index_map(fdim).size_local]
    tri = np.array([f2v.links(f) for f in facets], dtype=np.int32).reshape(-1, 3)
    vd, _ = vertex_dof_map(V, msh)
    nv = msh.topology.index_map(0).size_local + msh.topology.index_map(0).num_ghosts
    geo = compat.entities_to_geometry(msh, 0, np.arange(nv, dtype=np.int32)).ravel()
    Xv = msh.geometry.x[geo, :3] + u.x.array[vd]
    lam = np.array([[2 / 3, 1 / 6, 1 / 6], [1 / 6, 2 / 3, 1 / 6], [1 / 6, 1 / 6, 2 / 3]]) \
        if quad == 2 else np.array([[1 / 3, 1 / 3, 1 / 3]])
    Xq = np.einsum("qk,fkd->fqd", lam, Xv[tri]).reshape(-1, 3)
    c = np.array([0.0, 0.0, float(zc.value)])
    pq = k * np.maximum(radius - np.linalg.norm(Xq - c, axis=1), 0.0)
    p_max_qp = comm.allreduce(float(np.max(pq, initial=0.0)), op=MPI.MAX)
    P_h = 4.0 / 3.0 * E_star * math.sqrt(radius) * indentation**1.5
    a_h = math.sqrt(radius * indentation)
    p0 = 3 * P_h / (2 * math.pi * a_h**2)
    return {"force": force, "p_max": p_max, "hertz_force": P_h, "hertz_p_max": p0,
            "p_max_quadrature_point": p_max_qp, "quadrature_degree": quad,
            "dofs": V.dofmap.index_map.size_global * 3, "newton_iterations": newton,
            "h_fine": h_fine, "wall_time": time.perf_counter() - t0, "formulation": "ufl",
            "times": times}


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=float, default=0.025)
    ap.add_argument("--quad", type=int, default=2)
    args = ap.parse_args()
    r = run(args.size, quad=args.quad)
    if MPI.COMM_WORLD.rank == 0:
        print(f"h_fine {r['h_fine']}: {r['dofs']} dofs, force {r['force']:.2f} N "
              f"({r['force'] / r['hertz_force'] - 1:+.2%}), p_max {r['p_max']:.0f} MPa "
              f"({r['p_max'] / r['hertz_p_max'] - 1:+.2%}; at quadrature points "
              f"{r['p_max_quadrature_point'] / r['hertz_p_max'] - 1:+.2%}), "
              f"{r['newton_iterations']} Newton "
              f"iterations, {r['wall_time']:.1f} s")
