"""Krylov iterations per Newton iteration of a linear-solver variant on the pressed block.

Usage::

    python benchmarks/bench_condensed_variants.py --n 8
    python benchmarks/bench_condensed_variants.py --n 8 --option condensed_fieldsplit_u_pc_type=lu
    python benchmarks/bench_condensed_variants.py --n 14 --solver condensed-mumps

The problem is the one of ``tests/test_condense.py`` (``pressed_block``): a unit cube rotated by
30° about z with two inclined symmetry planes, fixed vertically at the bottom, pressed by a
rigid plane (implicit contact), Norton–Hoff (K = 1, ``--m``), ``--n`` cells per edge (×6
tetrahedra). Three increments of dt = 0.1; the first (start-up solve, set-ups) is not counted.
``--option key=value`` adds PETSc options (without prefix) on top of the ``--solver`` preset.
"""

from __future__ import annotations

import argparse
import os
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.dirname(HERE))
sys.path.insert(0, os.path.join(os.path.dirname(HERE), "tests"))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--n", type=int, default=8, help="cells per edge of the cube")
    ap.add_argument("--m", type=float, default=0.15, help="Norton–Hoff rate sensitivity")
    ap.add_argument("--beta", type=float, default=1e3, help="contact penalty β")
    ap.add_argument("--solver", default="condensed-amg", help="SolverOptions.linear_solver")
    ap.add_argument("--option", action="append", default=[], metavar="KEY=VALUE")
    args = ap.parse_args()
    from mpi4py import MPI
    from test_condense import pressed_block

    import fxcontact as fx

    extra = {}
    for kv in args.option:
        if "=" not in kv:
            ap.error(f"--option needs key=value, got {kv!r}")
        k, v = kv.split("=", 1)
        extra[k] = v
    sim = pressed_block(fx.NortonHoff(K=1.0, m=args.m, regularization=1e-3), n=args.n,
                        beta=args.beta, solver=args.solver)
    sim.solver_options.petsc_options.update(extra)
    sim.run(0.1, 0.1)
    pc = sim.solver._condensed_pc
    k0 = pc.inner_iterations if pc is not None else 0
    t0 = time.perf_counter()
    sim.run(0.3, 0.1)
    wall = MPI.COMM_WORLD.allreduce(time.perf_counter() - t0, op=MPI.MAX)
    its = sum(r["newton_iterations"] for r in sim.history[1:])
    if MPI.COMM_WORLD.rank == 0:
        kry = (pc.inner_iterations - k0) / its if pc is not None else float("nan")
        print(f"dofs {sim.space.global_dofs()}  solver {sim.solver.options.linear_solver}  "
              f"Newton its {[r['newton_iterations'] for r in sim.history]}  "
              f"Krylov/Newton it {kry:.1f}  wall/Newton it {wall / its:.3f} s  options {extra}")


if __name__ == "__main__":
    main()
