"""Hertz sphere at equal accuracy: fxcontact P1 displacement, fxcontact mixed (MINI) and a plain
integrated-UFL-penalty P1 script, one process, one after the other on the same machine.

Each method runs on the graded quarter block of ``fxcontact.processes.hertz_sphere`` for each
``h_fine`` of ``--sizes`` (or of ``--sizes-of METHOD=SIZES``); the table gives the force and
p_max errors against Hertz, dofs, Newton and Krylov iterations, MUMPS factorisations, the wall
time (mesh generation, form compilation from a warm cache, solve) and its split: assembly (UFL
residuals and Jacobians), contact (fxcontact's nodal terms), linear solve, other (mesh, set-up,
outputs, Newton's updates). The summary picks for each method the fastest run whose p_max is
within ``--target`` of Hertz and compares it with the UFL script's. Writes
``results/bench_anyfem_hertz.csv``.

Methods: ``p1`` (the defaults: ``implicit-exact``, ``ContactProblem.use_linear_solver("auto")``:
MUMPS kept while the active set holds below 30k unknowns, CG + GAMG above), ``p1-direct`` and
``p1-iterative`` (one kind forced), ``p1-mumps`` (the earlier set-up: ``implicit`` and a plain
MUMPS LU at every Newton iteration), ``ufl`` (``hertz_ufl_penalty.py``), ``mixed`` (MINI).

Run: ``python benchmarks/bench_anyfem_hertz.py --sizes 0.025,0.018,0.0125``
"""

from __future__ import annotations

import argparse
import csv
import importlib.util
import os
from pathlib import Path

from mpi4py import MPI

from fxcontact.processes import hertz_sphere

ROOT = Path(__file__).resolve().parents[1]


def _load(name, path):
    spec = importlib.util.spec_from_file_location(name, str(path))
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


#: hertz_sphere.run arguments of the fxcontact methods
METHODS = {"p1": dict(formulation="p1"),
           "p1-direct": dict(formulation="p1", linear_solver="direct"),
           "p1-iterative": dict(formulation="p1", linear_solver="iterative"),
           "p1-mumps": dict(formulation="p1", scheme="implicit", linear_solver="mumps"),
           "mixed": dict(formulation="mixed")}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="0.025,0.018,0.0125")
    ap.add_argument("--methods", default="p1,ufl,mixed")
    ap.add_argument("--sizes-of", action="append", default=[], metavar="METHOD=SIZES",
                    help="h_fine values of one method (e.g. mixed=0.025: the slow runs)")
    ap.add_argument("--target", type=float, default=0.02)
    ap.add_argument("--output", default="results")
    args = ap.parse_args()
    comm = MPI.COMM_WORLD
    ufl_script = _load("hertz_ufl_penalty", ROOT / "benchmarks" / "hertz_ufl_penalty.py")
    sizes = [float(s) for s in args.sizes.split(",")]
    sizes_of = {m: [float(s) for s in v.split(",")]
                for m, v in (item.split("=", 1) for item in args.sizes_of)}
    methods = args.methods.split(",")
    rows = []
    for method in methods:
        for h in sizes_of.get(method, sizes):
            if method == "ufl":
                try:
                    r = ufl_script.run(h)
                except RuntimeError as e:  # Newton failure of the penalty script
                    if comm.rank == 0:
                        print(f"ufl h_fine={h}: {e}", flush=True)
                    continue
            else:
                r = hertz_sphere.run(h_fine=h, output_dir=None, picture=False, progress=False,
                                     **METHODS[method])
            t = r.get("times", {})
            split = {k: t.get(k, float("nan")) for k in ("assembly", "contact", "linear_solve")}
            if method == "ufl":
                split["contact"] = 0.0       # the penalty integral is in the assembly
            row = {"method": method, "h_fine": h, "dofs": r["dofs"],
                   "force_err": r["force"] / r["hertz_force"] - 1,
                   "p_max_err": r["p_max"] / r["hertz_p_max"] - 1,
                   "newton": r["newton_iterations"], "krylov": t.get("krylov_iterations", ""),
                   "factorisations": t.get("factorisations", ""),
                   "wall_time": r["wall_time"], **split,
                   "other": r["wall_time"] - sum(split.values())}
            rows.append(row)
            if comm.rank == 0:
                print(f"{method:12s} h_fine={h:<7g} dofs={row['dofs']:8d} force "
                      f"{row['force_err']:+7.2%} p_max {row['p_max_err']:+7.2%} Newton "
                      f"{row['newton']:3d} Krylov {row['krylov']!s:>5s} LU "
                      f"{row['factorisations']!s:>3s} {row['wall_time']:8.1f} s (assembly "
                      f"{row['assembly']:.1f}, contact {row['contact']:.1f}, linear "
                      f"{row['linear_solve']:.1f}, other {row['other']:.1f})", flush=True)
    if comm.rank == 0:
        os.makedirs(args.output, exist_ok=True)
        with open(os.path.join(args.output, "bench_anyfem_hertz.csv"), "w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=list(rows[0]))
            w.writeheader()
            w.writerows(rows)
        print(f"fastest run with |p_max error| <= {args.target:.1%}:")
        best = {}
        for method in methods:
            ok = [r for r in rows if r["method"] == method and abs(r["p_max_err"]) <= args.target]
            if ok:
                best[method] = min(ok, key=lambda r: r["wall_time"])
                b = best[method]
                print(f"  {method:12s} h_fine={b['h_fine']:g}: {b['wall_time']:.1f} s "
                      f"(p_max {b['p_max_err']:+.2%}, force {b['force_err']:+.2%})")
            else:
                print(f"  {method:12s} none of the sizes run")
        if "ufl" in best:
            for method, b in best.items():
                if method != "ufl":
                    print(f"  ufl / {method}: {best['ufl']['wall_time'] / b['wall_time']:.1f}x")


if __name__ == "__main__":
    main()
