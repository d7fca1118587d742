"""Newton iterations of the wire drawing with the MINI bubble condensed after the assembly
(:class:`fxcontact.element.assembled.CondensedPC`) and in the element matrices
(:mod:`fxcontact.element.jacobian`), in one run.

Usage (from the repository root)::

    mpirun -n 2 .venv/bin/python benchmarks/bench_element_newton.py             # thesis size
    .venv/bin/python benchmarks/bench_element_newton.py --size 0.5 --t_end 0.0125

Case: the wire drawing of ``fxcontact.processes.drawing`` (``demos/demo_wire_drawing.py``) at ``--size`` (1: the thesis's 0.75 mm elements,
150,948 MINI dofs), ``linear_solver="condensed-mumps"``, the first ``--t_end`` of process (``--variants``: also MUMPS on the whole MINI system). The
first increment (JIT and numba compilation, start-up solve) is not counted. Per Newton
iteration: the whole increment, the assembly (residual and Jacobian: for the element variant the
element kernel, its condensation and the insertion), the linear solve (condensation of the
assembled matrix, MUMPS factorisation and solves), contact and the rest (the dual stress
update, the geometry update, the line search); and the largest relative difference of the
drawing stress from the first variant (the same Newton iteration: round-off; the Newton
tolerance for the variants that reuse the factorisation, ``SolverOptions.reuse_factorisation``).
Also, over the whole run (first increment included): the Newton and Krylov iterations and the
MUMPS factorisations (PETSc's log events of the numeric factorisation, LU and Cholesky).

    mpirun -n 2 .venv/bin/python benchmarks/bench_element_newton.py --size 0.5 \
        --variants element "element, reused factorisation"
"""

from __future__ import annotations

import argparse

from mpi4py import MPI
from petsc4py import PETSc

from fxcontact.processes import DrawingCase, run_drawing

#: name -> DrawingCase settings
VARIANTS = {
    "algebraic (CondensedPC)": dict(linear_solver="condensed-mumps", element_condensation=False,
                                    reuse_factorisation=False),
    "element": dict(linear_solver="condensed-mumps", element_condensation=True,
                    reuse_factorisation=False),
    "MUMPS on the MINI system": dict(linear_solver="mumps", element_condensation=False,
                                     reuse_factorisation=False),
    "element, reused factorisation": dict(linear_solver="condensed-mumps",
                                          element_condensation=True, reuse_factorisation=True),
    "element, reused, no prediction": dict(linear_solver="condensed-mumps",
                                           element_condensation=True, reuse_factorisation=True,
                                           active_set_prediction=False),
}
#: PETSc log events of a numeric factorisation
FACTOR_EVENTS = ("MatLUFactorNum", "MatCholFctrNum")


def factorisations() -> int:
    """Numeric factorisations so far in this process (PETSc's event log)."""
    return sum(PETSc.Log.Event(e).getPerfInfo()["count"] for e in FACTOR_EVENTS)


def run_variant(settings, size: float, t_end: float, comm):
    PETSc.Log.begin()
    f0 = factorisations()
    res = run_drawing(DrawingCase(size=size, t_end=t_end, **settings),
                      output_dir=None, pictures=False)
    res = {"history": res.history, "dofs": res.dofs, "factorisations": factorisations() - f0,
           "newton": sum(q["newton_iterations"] for q in res.history),
           "krylov": sum(q["linear_iterations"] for q in res.history)}
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
    ap.add_argument("--variants", nargs="*", choices=list(VARIANTS),
                    default=list(VARIANTS)[:2])
    a = ap.parse_args(argv)
    comm = MPI.COMM_WORLD
    out = {name: run_variant(VARIANTS[name], a.size, a.t_end, comm) for name in a.variants}
    first = next(iter(out.values()))
    ref = [q["drawing_stress"] for q in first[0]["history"]]
    if comm.rank == 0:
        print(f"wire drawing, size {a.size} ({first[0]['dofs']} MINI dofs), {comm.size} "
              f"rank(s), t_end {a.t_end}")
        print(f"{'variant':31s} {'incr':>5s} {'its':>5s} {'s/it':>7s} {'s/incr':>7s} "
              f"{'assembly':>9s} {'linear':>7s} {'contact':>8s} {'other':>7s}  max |dσ_d|/σ_d"
              f"  | whole run: Newton its, Krylov its, factorisations")
        for name, (res, its, n, sp) in out.items():
            sd = [q["drawing_stress"] for q in res["history"]]
            m = min(len(sd), len(ref))
            diff = max(abs(x - y) / max(abs(y), 1e-300) for x, y in zip(sd[:m], ref[:m]))
            per = {k: v / max(its, 1) for k, v in sp.items()}
            print(f"{name:31s} {n:5d} {its:5d} {per['total']:7.3f} "
                  f"{sp['total'] / max(n, 1):7.3f} {per['assembly']:9.3f} "
                  f"{per['linear_solve']:7.3f} {per['contact']:8.3f} {per['other']:7.3f}  "
                  f"{diff:.1e}  | {res['newton']} {res['krylov']} {res['factorisations']}")
        if "element" in out:
            e_ = out["element"]
            for name, r in out.items():
                if name != "element":
                    print(f"s per Newton iteration: element / {name} = "
                          f"{(e_[3]['total'] / e_[1]) / (r[3]['total'] / r[1]):.2f}")


if __name__ == "__main__":
    main()
