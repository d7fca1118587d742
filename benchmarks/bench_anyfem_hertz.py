"""Hertz sphere at equal accuracy: fxcontact P1 displacement, fxcontact mixed (MINI) and a plain
integrated-UFL-penalty P1 script, one process, one after the other on the same machine.

Each method runs on the graded quarter block of ``demos/demo_hertz_sphere.py`` for each
``h_fine`` of ``--sizes``; the table gives the force and p_max errors against Hertz, dofs,
Newton iterations and wall time (mesh generation, form compilation from a warm cache, solve);
the summary picks for each method the fastest run whose p_max is within ``--target`` (2 %) of
Hertz. Writes ``results/bench_anyfem_hertz.csv``.

Run: ``python benchmarks/bench_anyfem_hertz.py --sizes 0.025,0.018,0.0125``
"""

from __future__ import annotations

import argparse
import csv
import importlib.util
import os
from pathlib import Path

from mpi4py import MPI

ROOT = Path(__file__).resolve().parents[1]


def _load(name, path):
    spec = importlib.util.spec_from_file_location(name, str(path))
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="0.025,0.018,0.0125")
    ap.add_argument("--methods", default="p1,ufl,mixed")
    ap.add_argument("--mixed-sizes", default="0.025",
                    help="h_fine values of the (slow) mixed runs")
    ap.add_argument("--target", type=float, default=0.02)
    ap.add_argument("--output", default="results")
    args = ap.parse_args()
    comm = MPI.COMM_WORLD
    demo = _load("demo_hertz_sphere", ROOT / "demos" / "demo_hertz_sphere.py")
    ufl_script = _load("hertz_ufl_penalty", ROOT / "benchmarks" / "hertz_ufl_penalty.py")
    sizes = [float(s) for s in args.sizes.split(",")]
    rows = []
    for method in args.methods.split(","):
        hs = [float(s) for s in args.mixed_sizes.split(",")] if method == "mixed" else sizes
        for h in hs:
            if method == "ufl":
                try:
                    r = ufl_script.run(h)
                except RuntimeError as e:  # Newton failure of the penalty script
                    if comm.rank == 0:
                        print(f"ufl h_fine={h}: {e}", flush=True)
                    continue
            else:
                r = demo.run(h_fine=h, formulation=method, output_dir=None, picture=False,
                             progress=False)
            row = {"method": method, "h_fine": h, "dofs": r["dofs"],
                   "force_err": r["force"] / r["hertz_force"] - 1,
                   "p_max_err": r["p_max"] / r["hertz_p_max"] - 1,
                   "newton": r["newton_iterations"], "wall_time": r["wall_time"]}
            rows.append(row)
            if comm.rank == 0:
                print(f"{method:6s} h_fine={h:<7g} dofs={row['dofs']:8d} force "
                      f"{row['force_err']:+7.2%} p_max {row['p_max_err']:+7.2%} Newton "
                      f"{row['newton']:3d} {row['wall_time']:8.1f} s", flush=True)
    if comm.rank == 0:
        os.makedirs(args.output, exist_ok=True)
        with open(os.path.join(args.output, "bench_anyfem_hertz.csv"), "w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=list(rows[0]))
            w.writeheader()
            w.writerows(rows)
        print(f"fastest run with |p_max error| <= {args.target:.0%}:")
        for method in args.methods.split(","):
            ok = [r for r in rows if r["method"] == method and abs(r["p_max_err"]) <= args.target]
            if ok:
                best = min(ok, key=lambda r: r["wall_time"])
                print(f"  {method:6s} h_fine={best['h_fine']:g}: {best['wall_time']:.1f} s "
                      f"(p_max {best['p_max_err']:+.2%}, force {best['force_err']:+.2%})")
            else:
                print(f"  {method:6s} none of the sizes run")


if __name__ == "__main__":
    main()
