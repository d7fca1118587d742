"""Share of the contact work in a Newton iteration: Hertz sphere (analytic tool), 3D.

Usage::

    python benchmarks/bench_contact.py                       # ~200k dofs, implicit + explicit
    python benchmarks/bench_contact.py --h-fine 0.05 --schemes implicit   # quick, ~40k dofs
    mpirun -n 2 python benchmarks/bench_contact.py           # -> results/contact_np2.csv

Problem: ``fxcontact.processes.hertz_sphere`` (rigid sphere R = 5 pressed into an elastic
quarter block, radially graded mesh, MINI, MUMPS). The mesh is refined with ``--h-fine`` /
``--growth`` until the dof count reaches the target. For each contact scheme the run takes
``--steps`` increments; per increment the library records (``Simulation.history``, max over
ranks):

* ``contact``: everything the contact contributor does inside Newton — projections on the tool
  at every residual/Jacobian evaluation, penalty kernels, insertion of the nodal terms into the
  PETSc vector and matrix (``NonlinearProblem.timers["contact"]``);
* ``assembly``: UFL residual and Jacobian assembly; ``linear``: KSP solve + PC set-up;
* ``total``: the whole Newton solve.

The share is ``contact / total`` summed over the increments after the first (the first one holds
the MUMPS analysis and numba compilation), and also ``contact / (contact + assembly)`` (the share
of the non-solver work, which does not depend on the linear solver). Rows are appended to
``benchmarks/results/contact.csv`` (``contact_npN.csv`` on N ranks).
"""

from __future__ import annotations

import argparse
import csv
import os
import time

from mpi4py import MPI

from fxcontact.processes import hertz_sphere

HERE = os.path.dirname(os.path.abspath(__file__))
RESULTS = os.path.join(HERE, "results")
FIELDS = ["ranks", "scheme", "h_fine", "growth", "dofs", "cells", "contact_nodes", "active_nodes",
          "increments", "newton_its", "contact_s", "assembly_s", "linear_s", "total_s",
          "contact_per_it", "assembly_per_it", "linear_per_it", "total_per_it", "share_total",
          "share_nonsolver", "force_err", "wall_s"]


def run_case(comm, scheme: str, h_fine: float, growth: float, steps: int) -> dict:
    t0 = time.perf_counter()
    res = hertz_sphere.run(h_fine=h_fine, growth=growth, scheme=scheme, n_steps=steps,
                           output_dir=None, picture=False, progress=False, comm=comm)
    wall = comm.allreduce(time.perf_counter() - t0, op=MPI.MAX)
    hist = res["history"][1:] if len(res["history"]) > 1 else res["history"]
    sums = {}
    for k in ("contact", "assembly", "linear_solve", "total"):
        local = float(sum(r[f"wall_{k}"] for r in hist))
        sums[k] = comm.allreduce(local, op=MPI.MAX)
    its = max(sum(int(r["newton_iterations"]) for r in hist), 1)
    row = {"ranks": comm.size, "scheme": scheme, "h_fine": h_fine, "growth": growth,
           "dofs": res["dofs"], "cells": res["cells"],
           "contact_nodes": int(len(res["r"])), "active_nodes": res["active_nodes"],
           "increments": len(hist), "newton_its": its,
           "contact_s": sums["contact"], "assembly_s": sums["assembly"],
           "linear_s": sums["linear_solve"], "total_s": sums["total"],
           "contact_per_it": sums["contact"] / its, "assembly_per_it": sums["assembly"] / its,
           "linear_per_it": sums["linear_solve"] / its, "total_per_it": sums["total"] / its,
           "share_total": sums["contact"] / sums["total"],
           "share_nonsolver": sums["contact"] / (sums["contact"] + sums["assembly"]),
           "force_err": res["force"] / res["hertz_force"] - 1.0, "wall_s": wall}
    return row


def write_rows(path: str, rows):
    new = not os.path.exists(path)
    os.makedirs(os.path.dirname(path), exist_ok=True)
    with open(path, "a", newline="") as f:
        w = csv.DictWriter(f, fieldnames=FIELDS)
        if new:
            w.writeheader()
        for r in rows:
            w.writerow(r)


def print_table(rows):
    head = (f"{'ranks':>5} {'scheme':>15} {'dofs':>8} {'nodes':>6} {'act':>5} {'its':>4} "
            f"{'contact/it':>10} {'asm/it':>8} {'lin/it':>8} {'tot/it':>8} "
            f"{'share':>7} {'c/(c+asm)':>9} {'F err':>7}")
    print(head)
    print("-" * len(head))
    for r in rows:
        print(f"{r['ranks']:>5} {r['scheme']:>15} {r['dofs']:>8} {r['contact_nodes']:>6} "
              f"{r['active_nodes']:>5} {r['newton_its']:>4} {r['contact_per_it']:>10.4f} "
              f"{r['assembly_per_it']:>8.3f} {r['linear_per_it']:>8.3f} "
              f"{r['total_per_it']:>8.3f} {100 * r['share_total']:>6.2f}% "
              f"{100 * r['share_nonsolver']:>8.2f}% {100 * r['force_err']:>6.2f}%")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--h-fine", type=float, default=0.015,
                    help="element size at the contact [mm] (default 0.015: ~200k dofs)")
    ap.add_argument("--growth", type=float, default=0.15, help="mesh size gradient")
    ap.add_argument("--steps", type=int, default=3, help="increments (the first is not timed)")
    ap.add_argument("--schemes", default="implicit,explicit,implicit-exact",
                    help="comma separated contact schemes")
    ap.add_argument("--csv", default=None)
    a = ap.parse_args()
    if a.steps < 2:
        ap.error("--steps must be >= 2 (the first increment is not timed)")
    comm = MPI.COMM_WORLD
    path = a.csv or os.path.join(RESULTS, "contact.csv" if comm.size == 1
                                 else f"contact_np{comm.size}.csv")
    rows = []
    for s in [s.strip() for s in a.schemes.split(",") if s.strip()]:
        row = run_case(comm, s, a.h_fine, a.growth, a.steps)
        rows.append(row)
        if comm.rank == 0:
            print_table([row])
            write_rows(path, [row])
    if comm.rank == 0:
        print(f"\ncontact work per Newton iteration, increments 2..{a.steps}, max over "
              f"{comm.size} rank(s); CSV -> {path}")
        print_table(rows)


if __name__ == "__main__":
    main()
