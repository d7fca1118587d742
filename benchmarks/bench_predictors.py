"""Predictors and end-game variants for Newton at m = 0.016 (what was tried against the goal of
at most 6 Newton iterations per increment; none is in the library).

Case: the test-size drawing of ``tests/test_rigid_plastic.py`` (``drawing_case.py``: quarter
bar R₀ = 5 mm, 15 % reduction, 10° die, K = 445 MPa·s^m, m = 0.016, 10 mm/s, frictionless
implicit contact, β = 1e3, ε̇₀ = 1e-6 1/s, MINI, 2.5k dofs, h = 1.25 mm at the die), dt =
0.025 s, ``--increments`` increments from the start-up guess with the library's defaults (bt,
active-set prediction, primal–dual tangent, ``max_it`` 30, no cut-back allowed). Variants:

* ``previous``: the library's predictor (the previous increment's velocity at each node);
* ``extrapolated``: 2 v_n − v_(n−1) (linear extrapolation in time of each node's velocity);
* ``convected``: the previous velocity field (P1 part) evaluated at x + v dt on the updated
  mesh, i.e. the velocity the node meets downstream if the flow is steady (nodes whose point
  leaves the mesh keep their own velocity; serial: the point location is rank-local);
* ``projected``: nodes of the contact boundary whose predicted end position x + v dt is inside
  the die get the velocity that puts them on its surface (closest point);
* ``consistent-end``: the consistent tangent (dual stress := primal stress) once the residual
  is below 1e-3 of the first and the contact set is stable (the primal–dual tangent before);
* ``basic``: full Newton steps (``line_search="basic"``).

Reports the Newton iterations per increment, their mean, and the drawing force (the same in
every variant: the converged solution does not depend on the predictor).

Run from the repository root::

    OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/bench_predictors.py
"""

from __future__ import annotations

import argparse
import os
import sys

import numpy as np
from mpi4py import MPI

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import dolfinx.geometry  # noqa: E402
from drawing_case import drawing_simulation  # noqa: E402

from fxcontact.newton.solver import ContactNewtonSolver, SolverOptions  # noqa: E402

CASE = dict(R0=5.0, reduction=0.15, half_angle_deg=10.0, h=2.5, h_die=1.25, K=445.0,
            m=0.016, speed=10.0)
DT = 0.025
VARIANTS = ("previous", "extrapolated", "convected", "projected", "consistent-end", "basic")


def _convected(sim, dt):
    """Vertex velocities of ``sim.w_prev`` replaced by the P1 interpolant of the same field at
    x + v dt (barycentric coordinates in the cell that holds the point)."""
    sp, msh = sim.space, sim.mesh
    tdim = msh.topology.dim
    imap = msh.topology.index_map(tdim)
    cv = msh.topology.connectivity(tdim, 0).array.reshape(imap.size_local + imap.num_ghosts,
                                                          tdim + 1)
    X = msh.geometry.x[sp.vertex_geometry, :3]
    v = sim.w_prev.x.array[sp.vertex_dofs]
    pts = X.copy()
    pts[:, : sp.gdim] += dt * v
    tree = dolfinx.geometry.BoundingBoxTree(msh, tdim)
    cells = dolfinx.geometry.compute_colliding_cells(
        msh, dolfinx.geometry.compute_collisions(tree, pts), pts)
    new = v.copy()
    for i in range(len(pts)):
        links = cells.links(i)
        if len(links) == 0:
            continue
        vs = cv[links[0]]
        P = X[vs]
        lam = np.linalg.solve((P[1:] - P[0]).T, pts[i] - P[0])
        new[i] = np.r_[1.0 - lam.sum(), lam] @ v[vs]
    sim.w_prev.x.array[sp.vertex_dofs] = new


def _projected(sim, die, contact, dt):
    b = contact.boundary
    X = sim.mesh.geometry.x[b.geometry_nodes, :3]
    v = sim.w_prev.x.array[b.dofs]
    pr = die.project(X + dt * v, sim.t + dt, hessian=False)
    inside = pr.gap < 0.0
    v[inside] = (pr.point[inside] - X[inside]) / dt
    sim.w_prev.x.array[b.dofs] = v


def run(variant: str, n_inc: int):
    opts = SolverOptions(max_it=30, line_search="basic" if variant == "basic" else "bt")
    sim, die, contact = drawing_simulation(MPI.COMM_WORLD, solver_options=opts, **CASE)
    original = ContactNewtonSolver._converged
    if variant == "consistent-end":
        def converged(self, snes, it, norms):
            if sim.dual is not None:
                if it == 0:
                    sim.dual.active = True
                elif norms[2] < 1e-3 * self._f0 and self._last_stable:
                    sim.dual.active = False
            return original(self, snes, it, norms)
        ContactNewtonSolver._converged = converged
    old = None
    try:
        for _ in range(n_inc):
            sim.step(DT, max_cutbacks=0)
            cur = sim.w_prev.x.array.copy()
            if variant == "extrapolated" and old is not None:
                sim.w_prev.x.array[:] = 2.0 * cur - old
            elif variant == "convected":
                _convected(sim, DT)
            elif variant == "projected":
                _projected(sim, die, contact, DT)
            old = cur
    finally:
        ContactNewtonSolver._converged = original
    its = [r["newton_iterations_all"] for r in sim.history]
    return its, 4.0 * sim.history[-1]["front_z"]


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--variants", nargs="+", choices=VARIANTS, default=list(VARIANTS))
    ap.add_argument("--increments", type=int, default=5)
    args = ap.parse_args()
    if MPI.COMM_WORLD.size > 1:
        raise SystemExit("serial only (the convected predictor locates points on one rank)")
    print("| predictor / variant | Newton its per increment | mean | force at the last increment N |")
    print("|---|---|---|---|")
    for v in args.variants:
        its, force = run(v, args.increments)
        print(f"| {v} | {', '.join(map(str, its))} | {np.mean(its):.1f} | {force:.1f} |",
              flush=True)


if __name__ == "__main__":
    main()
