"""Newton iterations of the wire drawing with the MINI bubble condensed after the assembly
(:class:`fxcontact.condense.CondensedPC`) and in the element matrices
(:mod:`fxcontact.element_jacobian`), in one run.

Usage (from the repository root)::

    mpirun -n 2 .venv/bin/python benchmarks/bench_element_newton.py             # thesis size
    .venv/bin/python benchmarks/bench_element_newton.py --size 0.5 --t_end 0.0125

Case: ``demos/demo_wire_drawing.py`` at ``--size`` (1: the thesis's 0.75 mm elements,
150,948 MINI dofs), ``linear_solver="condensed-mumps"``, the first ``--t_end`` of process. The
first increment (JIT and numba compilation, start-up solve) is not counted. Per Newton
iteration: the whole increment, the assembly (residual and Jacobian: for the element variant the
element kernel, its condensation and the insertion), the linear solve (condensation of the
assembled matrix, MUMPS factorisation and solves), contact and the rest (the dual stress
update, the geometry update, the line search); and the largest relative difference of the
drawing stress from the algebraic variant (the two are the same Newton iteration: round-off).
"""

from __future__ import annotations

import argparse
import os
import sys

import numpy as np
from mpi4py import MPI

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(os.path.dirname(HERE), "demos"))

import demo_wire_drawing as demo  # noqa: E402

import fxcontact as fx  # noqa: E402

VARIANTS = {"algebraic (CondensedPC)": False, "element": True}


def run_variant(flag: bool, size: float, t_end: float, comm):
    real = fx.SolverOptions

    def options(*a, **k):
        return real(*a, **{**k, "element_condensation": flag})
    fx.SolverOptions = options
    try:
        res = demo.run(size=size, t_end=t_end, linear_solver="condensed-mumps",
                       output_dir=None, pictures=False, stop_at_steady=False)
    finally:
        fx.SolverOptions = real
    rows = res["history"][1:]
    its = sum(q["newton_iterations"] for q in rows)
    split = {k: sum(q.get(f"wall_{k}", 0.0) for q in rows)
             for k in ("assembly", "linear_solve", "contact")}
    split["total"] = sum(q.get("wall_increment_all", q.get("wall", 0.0)) for q in rows)
    split["other"] = split["total"] - sum(split[k] for k in ("assembly", "linear_solve",
                                                             "contact"))
    return res, its, len(rows), split


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=float, default=1.0)
    ap.add_argument("--t_end", type=float, default=0.015)
    a = ap.parse_args(argv)
    comm = MPI.COMM_WORLD
    out = {}
    for name, flag in VARIANTS.items():
        out[name] = run_variant(flag, a.size, a.t_end, comm)
    ref = [q["drawing_stress"] for q in out["algebraic (CondensedPC)"][0]["history"]]
    if comm.rank == 0:
        dofs = out["element"][0].get("dofs", "?")
        print(f"wire drawing, size {a.size} ({dofs} MINI dofs), {comm.size} rank(s), "
              f"t_end {a.t_end}")
        print(f"{'variant':26s} {'incr':>5s} {'its':>5s} {'s/it':>7s} {'assembly':>9s} "
              f"{'linear':>7s} {'contact':>8s} {'other':>7s}  max |dσ_d|/σ_d")
        for name, (res, its, n, sp) in out.items():
            sd = [q["drawing_stress"] for q in res["history"]]
            m = min(len(sd), len(ref))
            diff = max(abs(x - y) / max(abs(y), 1e-300) for x, y in zip(sd[:m], ref[:m]))
            per = {k: v / max(its, 1) for k, v in sp.items()}
            print(f"{name:26s} {n:5d} {its:5d} {per['total']:7.3f} {per['assembly']:9.3f} "
                  f"{per['linear_solve']:7.3f} {per['contact']:8.3f} {per['other']:7.3f}  "
                  f"{diff:.1e}")
        a_, e_ = out["algebraic (CondensedPC)"], out["element"]
        print(f"s per Newton iteration: element / algebraic = "
              f"{(e_[3]['total'] / e_[1]) / (a_[3]['total'] / a_[1]):.2f}")


if __name__ == "__main__":
    main()
