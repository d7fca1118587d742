"""Parallel scaling 1 → N ranks of a contact problem, per part of the increment.

Usage::

    python benchmarks/bench_scaling.py                               # Hertz sphere, h_fine 0.05
    python benchmarks/bench_scaling.py --h-fine 0.03 --solvers condensed-mumps,condensed-amg
    python benchmarks/bench_scaling.py --table                       # print stored rows

Problem: the Hertz sphere of ``fxcontact.processes.hertz_sphere`` (quarter block, MINI, linear
elasticity in velocity form, analytic sphere, implicit nodal contact, β = 10⁴), with the mesh
refined to ``--h-fine`` under the sphere. For every linear solver and rank count a fresh
process (``mpirun -n N``) runs ``--steps`` increments; the first one (numba compilation,
symbolic factorisation, AMG set-up) is left out, and the wall times of the others are summed:

* ``assembly``: UFL residual + Jacobian assembly (``SolveInfo.times["assembly"]``),
* ``contact``: the contact contributor (projection, kernels, insertion),
* ``linear``: linear solve (``SolveInfo.times["linear_solve"]``: from the end of each Jacobian
  callback to the line search, the condensation and the inner Krylov solve included),
* ``increment``: the whole ``Simulation.step`` (geometry update, outputs off).

Times are the maximum over ranks. The speed-up is ``t(1 rank) / t(N ranks)``, the parallel
efficiency ``speed-up / N``. The script also checks that N ranks give the serial answer: the
largest difference of the vertex velocities (relative to their maximum) and of the contact
force. Rows go to ``benchmarks/results/scaling.csv``.
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import subprocess
import sys
import tempfile
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
sys.path.insert(0, ROOT)
sys.path.insert(0, HERE)

RESULTS = os.path.join(HERE, "results")
PARTS = ("assembly", "contact", "linear", "increment")
FIELDS = (["solver", "ranks", "dofs", "h_fine", "steps_timed", "newton_its", "newton_its_all",
           "krylov_its"]
          + [f"{p}_s" for p in PARTS] + ["force", "max_dv_rel", "force_rel_diff"])


def worker(args):
    """One run on MPI.COMM_WORLD; rank 0 writes times and the vertex solution to args.out."""
    from mpi4py import MPI

    from fxcontact.contact.boundary import ContactBoundary
    from fxcontact.contact.nodal import NodalContact, penalty_from_beta
    from fxcontact.materials import LinearElastic
    from fxcontact.meshing import BLOCK_TAGS
    from fxcontact.newton.solver import SolverOptions
    from fxcontact.processes import hertz
    from fxcontact.simulation import Simulation
    from fxcontact.spaces import MixedSpace

    comm = MPI.COMM_WORLD
    radius, E, nu, delta, beta = 5.0, 2e5, 0.3, 0.0133, 1e4
    msh, _, ft = hertz.graded_block(comm, 80.0, 80.0, args.h_fine, 0.4, 0.15, 16.0)
    space = MixedSpace(msh)
    mat = LinearElastic(E, nu)
    sim = Simulation(space, mat, progress=False,
                     solver_options=SolverOptions(linear_solver=args.solver))
    sim.add_velocity_bc(sim.facets(ft, BLOCK_TAGS["xmin"]), 0.0, 0)
    sim.add_velocity_bc(sim.facets(ft, BLOCK_TAGS["ymin"]), 0.0, 1)
    sim.add_velocity_bc(sim.facets(ft, BLOCK_TAGS["zmin"]), 0.0, 2)
    dt = 1.0 / args.steps
    tool, _ = hertz.make_tool("analytic", radius, delta, 1.0, "nvv")
    penalty = penalty_from_beta(mat, beta, args.h_fine, dt=dt)
    sim.add_contributor(NodalContact(ContactBoundary(space, ft, BLOCK_TAGS["zmax"]), tool,
                                     scheme="implicit", penalty=penalty,
                                     element_size=args.h_fine))
    own = space.vertex_owned
    x0 = space.vertex_positions()[own]
    walls = []
    for _ in range(args.steps):
        comm.barrier()
        t0 = time.perf_counter()
        sim.step(dt, max_cutbacks=0)
        walls.append(comm.allreduce(time.perf_counter() - t0, op=MPI.MAX))
    hist = sim.history[1:]
    tmax = lambda key: comm.allreduce(sum(r[key] for r in hist), op=MPI.MAX)  # noqa: E731
    pc = sim.solver._condensed_pc
    ksp = pc.ksp if pc is not None else sim.solver.snes.getKSP()
    direct = ksp.getType() == "preonly"
    row = {"solver": sim.solver.options.linear_solver if args.solver == "auto" else args.solver,
           "ranks": comm.size, "dofs": space.global_dofs(), "h_fine": args.h_fine,
           "steps_timed": len(hist), "newton_its": sum(r["newton_iterations"] for r in hist),
           # Newton iterations including failed attempts (fallback line search, cut-backs)
           "newton_its_all": sum(r.get("newton_iterations_all", r["newton_iterations"])
                                 for r in hist),
           # Krylov iterations of all increments (iterative solvers; "" for direct ones)
           "krylov_its": "" if direct else (pc.inner_iterations if pc is not None
                                            else sim.solver.snes.getLinearSolveIterations()),
           "assembly_s": tmax("wall_assembly"), "contact_s": tmax("wall_contact"),
           "linear_s": tmax("wall_linear_solve"), "increment_s": float(sum(walls[1:])),
           "force": 4.0 * sim.history[-1]["sphere_force_z"]}
    xs = comm.gather(x0, root=0)
    vs = comm.gather(sim.w.x.array[space.vertex_dofs[own]], root=0)
    if comm.rank == 0:
        np.savez(args.out, x=np.concatenate(xs), v=np.concatenate(vs), row=json.dumps(row))
    sim.solver.destroy()


def _by_position(x, v):
    key = np.round(x, 9)
    order = np.lexsort(key.T[::-1])
    return key[order], v[order]


def run_case(solver, ranks, args):
    """Run one (solver, ranks) case in a fresh process; returns (row, x, v)."""
    with tempfile.TemporaryDirectory() as tmp:
        out = os.path.join(tmp, "case.npz")
        cmd = [sys.executable, os.path.abspath(__file__), "--worker", "--solver", solver,
               "--h-fine", str(args.h_fine), "--steps", str(args.steps), "--out", out]
        if ranks > 1 or args.mpirun_serial:
            cmd = ["mpirun", "-n", str(ranks)] + (["--oversubscribe"] if ranks > 1 else []) \
                + cmd
        env = dict(os.environ, OPENBLAS_NUM_THREADS="1")
        t0 = time.perf_counter()
        res = subprocess.run(cmd, env=env, capture_output=True, text=True)
        if res.returncode != 0 or not os.path.exists(out):
            raise RuntimeError(f"{' '.join(cmd)} failed:\n{res.stderr[-3000:]}")
        d = np.load(out)
        row = json.loads(str(d["row"]))
        print(f"  {solver} on {ranks} rank(s): {row['dofs']} dofs, {row['newton_its']} Newton "
              f"its ({row['newton_its_all']} with failed attempts) in the timed increments, "
              f"{time.perf_counter() - t0:.0f} s", flush=True)
        return row, d["x"], d["v"]


def store(rows):
    os.makedirs(RESULTS, exist_ok=True)
    path = os.path.join(RESULTS, "scaling.csv")
    old = []
    if os.path.exists(path):
        with open(path, newline="") as f:
            old = list(csv.DictReader(f))
    key = lambda r: (str(r["solver"]), str(r["ranks"]), str(r["dofs"]))  # noqa: E731
    new = {key(r) for r in rows}
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=FIELDS, extrasaction="ignore")
        w.writeheader()
        for r in [r for r in old if key(r) not in new] + rows:
            w.writerow(r)
    return path


def table(rows, markdown=False):
    """Speed-up and efficiency of every N-rank row against the 1-rank row of its case."""
    base = {(r["solver"], str(r["dofs"])): r for r in rows if int(r["ranks"]) == 1}
    lines = []
    head = ["solver", "dofs", "ranks", "Newton its", "Krylov its"] + \
        [f"{p} s (speed-up, eff.)" for p in PARTS] + ["max |Δv|/|v|", "Δforce"]
    if markdown:
        lines.append("| " + " | ".join(head) + " |")
        lines.append("|" + "---|" * len(head))
    else:
        lines.append("  ".join(head))
    for r in rows:
        b = base.get((r["solver"], str(r["dofs"])))
        n = int(r["ranks"])
        cells = [r["solver"], str(r["dofs"]), str(n), str(r["newton_its"]), str(r["krylov_its"])]
        for p in PARTS:
            t = float(r[f"{p}_s"])
            if b is not None and n > 1 and t > 0:
                s = float(b[f"{p}_s"]) / t
                cells.append(f"{t:.2f} ({s:.2f}, {s / n:.2f})")
            else:
                cells.append(f"{t:.2f}")
        cells += [f"{float(r['max_dv_rel']):.1e}" if r.get("max_dv_rel") not in ("", None)
                  else "–",
                  f"{float(r['force_rel_diff']):.1e}" if r.get("force_rel_diff") not in ("", None)
                  else "–"]
        lines.append(("| " + " | ".join(cells) + " |") if markdown else "  ".join(cells))
    return "\n".join(lines)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--solvers", default="mumps,condensed-mumps,condensed-amg",
                    help="comma-separated SolverOptions.linear_solver values")
    ap.add_argument("--ranks", default="1,2", help="comma-separated rank counts (first = base)")
    ap.add_argument("--h-fine", type=float, default=0.05, help="element size under the sphere")
    ap.add_argument("--steps", type=int, default=3, help="increments (the first is not timed)")
    ap.add_argument("--mpirun-serial", action="store_true", help="run 1 rank under mpirun too")
    ap.add_argument("--table", action="store_true", help="print the stored rows and exit")
    ap.add_argument("--markdown", action="store_true")
    ap.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    ap.add_argument("--solver", default="mumps", help=argparse.SUPPRESS)
    ap.add_argument("--out", default="", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.steps < 2:
        ap.error("--steps must be >= 2 (the first increment is not timed)")
    if args.worker:
        worker(args)
        return
    if args.table:
        with open(os.path.join(RESULTS, "scaling.csv"), newline="") as f:
            print(table(list(csv.DictReader(f)), args.markdown))
        return
    ranks = [int(r) for r in args.ranks.split(",")]
    rows = []
    for solver in args.solvers.split(","):
        ref = None
        for n in ranks:
            row, x, v = run_case(solver, n, args)
            xs, vs = _by_position(x, v)
            if ref is None:
                ref = (xs, vs, row["force"])
                row["max_dv_rel"], row["force_rel_diff"] = 0.0, 0.0
            else:
                if xs.shape != ref[0].shape or not np.allclose(xs, ref[0]):
                    raise RuntimeError("the vertex sets of the runs differ")
                row["max_dv_rel"] = float(np.abs(vs - ref[1]).max() / np.abs(ref[1]).max())
                row["force_rel_diff"] = abs(row["force"] / ref[2] - 1.0)
            rows.append(row)
    path = store(rows)
    print(table(rows, args.markdown))
    print(f"rows stored in {path}")


if __name__ == "__main__":
    main()
