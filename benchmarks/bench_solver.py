"""Newton cost per iteration (assembly, linear solve) versus dofs, element, linear solver, ranks.

Usage::

    python benchmarks/bench_solver.py                          # 20k and 80k dofs, all cases
    python benchmarks/bench_solver.py --large                  # adds the ~300k-dof cases
    mpirun -n 2 python benchmarks/bench_solver.py [--large]    # 2 ranks -> solver_np2.csv
    python benchmarks/bench_solver.py --compare                # speed-up / parallel efficiency

Problem: the Norton–Hoff upsetting of :mod:`fxcontact.processes.upsetting_dies` (quarter
billet R = 10 mm, H = 15 mm, sticking dies, K = 50, m = 0.15, die speed 5 mm/s, dt = 0.06 s,
updated Lagrangian).
For every case (element × linear solver × size) a fresh simulation runs ``--increments``
increments (default 2). The first increment contains the Newtonian start-up solve and the first
(symbolic) factorisation / preconditioner set-up; the timings reported are those of the **last**
increment, divided by its number of Newton iterations:

* ``asm/it``  : UFL residual + Jacobian assembly (all residual evaluations of the increment,
  line search included, plus one Jacobian per iteration), ``SolveInfo.times["assembly"]``;
* ``lin/it``  : linear solve (PETSc KSPSolve + PCSetUp events), ``SolveInfo.times["linear_solve"]``;
* ``ksp/it``  : Krylov iterations per Newton iteration (``snes.getLinearSolveIterations()``);
* ``F``, ``J``: one residual / one Jacobian assembly timed standalone after the run (best of 3).

Times are the maximum over ranks. Each size is given as a target number of dofs; the element
size h is derived per element from a calibration of this geometry (``dofs ≈ C / h³``) so that MINI
and Taylor–Hood get roughly the same number of dofs; the actual count is printed.

Rows are appended to (or replace rows of the same case in) ``benchmarks/results/solver.csv``
(1 rank) or ``benchmarks/results/solver_np{N}.csv`` (N ranks); a failed case (e.g. out of memory
in MUMPS, or a diverged Krylov solve) is written with ``converged = 0`` and its message.
"""

from __future__ import annotations

import argparse
import csv
import os
import sys
import time
from typing import Dict, List

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.dirname(HERE))

from _common import best_time, read_csv  # noqa: E402

from fxcontact.materials import NortonHoff  # noqa: E402
from fxcontact.meshing import BILLET_TAGS, cylinder_billet  # noqa: E402
from fxcontact.newton.solver import SolverOptions  # noqa: E402
from fxcontact.simulation import Simulation  # noqa: E402
from fxcontact.spaces import MixedSpace  # noqa: E402

RESULTS = os.path.join(HERE, "results")

#: dofs ≈ C / h³ for the quarter billet R = 10, H = 15 (first guess; C drifts by ~10 % between
#: h = 1 and h = 0.4, so run_case re-meshes until 0.97 target <= dofs <= 1.16 target)
DOF_CONSTANT = {"mini": 23100.0, "taylor-hood": 28800.0}
ELEMENT_LABEL = {"mini": "MINI", "taylor-hood": "TH"}

#: Linear solver variants: name -> (SolverOptions.linear_solver, SolverOptions.petsc_options).
#: Field-split variants go through the "fieldsplit" preset plus overrides in petsc_options
#: (Simulation only builds the velocity/pressure index sets when linear_solver == "fieldsplit";
#: a dict with pc_type=fieldsplit raises "the field-split linear solver needs the ... ISs").
_HYPRE_3D = {"fieldsplit_u_pc_hypre_boomeramg_strong_threshold": 0.5,
             "fieldsplit_u_pc_hypre_boomeramg_coarsen_type": "HMIS",
             "fieldsplit_u_pc_hypre_boomeramg_interp_type": "ext+i",
             "fieldsplit_u_pc_hypre_boomeramg_P_max": 4,
             "fieldsplit_u_pc_hypre_boomeramg_agg_nl": 1}
VARIANTS: Dict[str, tuple] = {
    "mumps": ("mumps", {}),
    # the library preset as is
    "fieldsplit": ("fieldsplit", {}),
    # preset + Eisenstat–Walker inexact Newton (KSP tolerance adapted to the Newton residual)
    "fs-ew": ("fieldsplit", {"snes_ksp_ew": True}),
    # preset + 3D-tuned BoomerAMG for the velocity block
    "fs-amg3d": ("fieldsplit", dict(_HYPRE_3D)),
    # both
    "fs-ew-amg3d": ("fieldsplit", {"snes_ksp_ew": True, **_HYPRE_3D}),
    # MINI bubble condensed element by element (fxcontact.element.assembled), P1/P1 system by MUMPS
    "cmumps": ("condensed-mumps", {}),
    # condensed, iterative: Schur field split, GAMG (bs 3, rigid-body modes), Schur
    # preconditioned by the condensed pressure block + inverse-viscosity pressure mass
    "camg": ("condensed-amg", {}),
    "camg-ew": ("condensed-amg", {"snes_ksp_ew": True}),
}
DEFAULT_VARIANTS = ["mumps", "fieldsplit"]

FIELDS = ["ranks", "element", "solver", "size", "h", "cells", "dofs", "mode",
          "newton_its", "residual_evals", "ksp_its", "ksp_per_newton", "assembly_per_it",
          "linear_per_it", "total_per_it", "assembly_s", "linear_s", "linear_lib_s", "analysis_s", "contact_s",
          "other_s", "total_s", "F_asm_s", "J_asm_s", "first_increment_s", "setup_s", "peak_mem_mb", "mumps_mem_mb",
          "converged", "message"]


def parse_size(s: str) -> int:
    s = s.strip().lower()
    mult = 1
    if s.endswith("k"):
        mult, s = 1000, s[:-1]
    elif s.endswith("m"):
        mult, s = 1000000, s[:-1]
    return int(float(s) * mult)


def size_label(n: int) -> str:
    return f"{n // 1000}k" if n % 1000 == 0 else str(n)


def reset_peak_rss():
    """Reset the kernel's peak-RSS counter of this process (Linux >= 4.0)."""
    try:
        with open("/proc/self/clear_refs", "w") as f:
            f.write("5")
    except OSError:
        pass


def peak_rss_mb() -> float:
    try:
        with open("/proc/self/status") as f:
            for line in f:
                if line.startswith("VmHWM:"):
                    return float(line.split()[1]) / 1024.0
    except OSError:
        pass
    return float("nan")


def run_case(comm, element: str, variant: str, target: int, h: float, increments: int,
             case_id: int, verbose: bool, options: Dict[str, str] = None,
             newton_cap: int = 0, fixed_h: bool = False) -> dict:
    """Build the upsetting problem and time its increments; returns one CSV row."""
    reset_peak_rss()
    comm.barrier()
    t0 = time.perf_counter()
    for attempt in range(4):
        msh, _, ft = cylinder_billet(comm, 10.0, 15.0, h, quarter=True)
        space = MixedSpace(msh, element)
        ratio = space.global_dofs() / target
        if fixed_h or 0.97 <= ratio <= 1.16 or attempt == 3:
            break
        # gmsh does not follow dofs ∝ h⁻³ exactly: re-mesh (aiming at 1.05 target)
        h *= (ratio / 1.05) ** (1.0 / 3.0)
        del msh, space, ft
    lin, extra = VARIANTS[variant]
    extra = {**extra, **(options or {})}
    # one options prefix per case, so that the PETSc objects of a case are easy to tell apart
    # in -log_view output
    opts = SolverOptions(linear_solver=lin, petsc_options=dict(extra), prefix=f"b{case_id}_",
                         **({"max_it": newton_cap} if newton_cap else {}))
    height, speed = 15.0, 5.0
    sim = Simulation(space, NortonHoff(K=50.0, m=0.15, regularization=1e-4 * speed / height),
                     solver_options=opts, output_dir=None, progress=False)
    f = {k: sim.facets(ft, v) for k, v in BILLET_TAGS.items()}
    sim.add_velocity_bc(f["symmetry_x"], 0.0, 0)
    sim.add_velocity_bc(f["symmetry_y"], 0.0, 1)
    sim.add_velocity_bc(f["bottom"], np.zeros(3))
    sim.add_velocity_bc(f["top"], np.array([0.0, 0.0, -speed]))
    sim._build()  # JIT and solver set-up outside the timed increments
    setup = comm.allreduce(time.perf_counter() - t0, op=MPI.MAX)
    row = {"ranks": comm.size, "element": ELEMENT_LABEL[element], "solver": variant,
           "size": size_label(target), "h": round(h, 4),
           "cells": msh.topology.index_map(3).size_global, "dofs": space.global_dofs(),
           "mode": f"cap{newton_cap}" if newton_cap else f"inc{increments}", "setup_s": setup,
           "converged": 0, "message": ""}
    if comm.rank == 0 and verbose:
        print(f"  [{row['element']} {variant} {row['size']}: h = {h:.3f}, "
              f"{row['cells']} cells, {row['dofs']} dofs, set-up {setup:.1f} s]", flush=True)
    dt = 0.3 * height / speed / 15
    info, ev = None, {}
    events = {n: PETSc.Log.Event(n) for n in ("SNESSolve", "SNESFunctionEval",
                                               "SNESJacobianEval", "MatLUFactorSym")}
    # PETSc event times of the main Newton solve only (not of the start-up solve)
    solve = sim.solver.solve

    def timed_solve():
        ev0 = {n: e.getPerfInfo()["time"] for n, e in events.items()}
        out = solve()
        ev.update({n: e.getPerfInfo()["time"] - ev0[n] for n, e in events.items()})
        return out

    sim.solver.solve = timed_solve
    try:
        for k in range(1 if newton_cap else increments):
            comm.barrier()
            t1 = time.perf_counter()
            if newton_cap:
                # start-up solve + the first `newton_cap` power-law Newton iterations only
                info = sim._try_increment(dt)
                if not info.converged and info.reason != PETSc.SNES.ConvergedReason.DIVERGED_MAX_IT:
                    raise RuntimeError(info.message)
            else:
                info = sim.step(dt, max_cutbacks=0).info
            wall = comm.allreduce(time.perf_counter() - t1, op=MPI.MAX)
            if k == 0:
                row["first_increment_s"] = wall
            if comm.rank == 0 and verbose:
                print(f"    increment {k + 1}: {info.iterations} Newton its, "
                      f"{info.linear_iterations} KSP its, {wall:.2f} s", flush=True)
        row["converged"] = 1
    except Exception as e:  # noqa: BLE001 - a failed case is a result too
        row["message"] = str(e).replace("\n", " ")[:200]
        if comm.rank == 0:
            print(f"    FAILED: {row['message']}", flush=True)
    if info is not None and row["converged"]:
        its = max(info.iterations, 1)
        t = {k: comm.allreduce(info.times.get(k, 0.0), op=MPI.MAX)
             for k in ("assembly", "linear_solve", "contact", "other", "total")}
        # Krylov iterations (the inner ones of a condensed solver: its outer KSP is preonly)
        # (sim.solver.snes, not a reference kept from before: a failed solve -- the cap --
        # rebuilds the SNES)
        snes = sim.solver.snes
        ksp = info.linear_iterations
        # linear solve = SNESSolve minus the residual/Jacobian callbacks (the library's
        # KSPSolve + PCSetUp sum counts the sub-PC set-ups of a field split twice), minus the
        # one-off symbolic factorisation (reported apart; zero once the pattern is analysed)
        sym = comm.allreduce(ev["MatLUFactorSym"], op=MPI.MAX)
        lin = comm.allreduce(ev["SNESSolve"] - ev["SNESFunctionEval"] - ev["SNESJacobianEval"]
                             - ev["MatLUFactorSym"], op=MPI.MAX)
        row.update(newton_its=info.iterations, residual_evals=snes.getFunctionEvaluations(),
                   ksp_its=ksp, ksp_per_newton=ksp / its,
                   assembly_per_it=t["assembly"] / its, linear_per_it=lin / its,
                   total_per_it=(t["total"] - sym) / its, assembly_s=t["assembly"],
                   linear_s=lin, linear_lib_s=t["linear_solve"], analysis_s=sym,
                   contact_s=t["contact"], other_s=t["other"], total_s=t["total"])
        pc = snes.getKSP().getPC()
        if pc.getType() in ("lu", "cholesky"):
            try:  # MUMPS INFOG(22): memory effectively used by the factorisation, all ranks
                row["mumps_mem_mb"] = pc.getFactorMatrix().getMumpsInfog(22)
            except PETSc.Error:
                pass
        prob = sim.problem
        b = prob.create_vector()

        def timed(fn):
            comm.barrier()
            return comm.allreduce(best_time(fn), op=MPI.MAX)

        row["F_asm_s"] = timed(lambda: prob.assemble_residual(b))
        row["J_asm_s"] = timed(lambda: prob.assemble_jacobian(sim.solver.A))
        b.destroy()
    row["peak_mem_mb"] = comm.allreduce(peak_rss_mb(), op=MPI.SUM)
    sim.solver.destroy()
    if sim._startup is not None:
        sim._startup.destroy()
    return row


# ------------------------------------------------------------------------------ CSV / tables
def key(r) -> tuple:
    return (str(r["ranks"]), r["element"], r["solver"], r["size"], r["mode"])


def upsert_csv(path: str, row: dict):
    rows = [r for r in read_csv(path) if key(r) != key({k: str(v) for k, v in row.items()})]
    rows.append(row)
    os.makedirs(os.path.dirname(path), exist_ok=True)
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=FIELDS, extrasaction="ignore")
        w.writeheader()
        for r in rows:
            w.writerow(r)


def _f(r, k, fmt):
    try:
        v = float(r.get(k, ""))
    except (TypeError, ValueError):
        return "-"
    return "-" if not np.isfinite(v) else format(v, fmt)


def print_table(rows: List[dict], markdown: bool = False):
    cols = [("ranks", "ranks", "", 5), ("element", "element", "", 7), ("solver", "solver", "", 12),
            ("size", "size", "", 5), ("dofs", "dofs", "", 7), ("mode", "mode", "", 5),
            ("newton_its", "Newton", "", 6), ("assembly_per_it", "asm s/it", ".3f", 8),
            ("linear_per_it", "lin s/it", ".3f", 8), ("total_per_it", "tot s/it", ".3f", 8),
            ("ksp_per_newton", "KSP/it", ".1f", 6), ("total_s", "incr s", ".1f", 7),
            ("F_asm_s", "F s", ".3f", 6), ("J_asm_s", "J s", ".3f", 6),
            ("peak_mem_mb", "RSS MB", ".0f", 6), ("mumps_mem_mb", "LU MB", ".0f", 6)]
    sep = " | " if markdown else " "
    head = sep.join(f"{h:>{w}}" for _, h, _, w in cols)
    if markdown:
        print("| " + head + " | note |")
        print("|" + "|".join("-" * (w + 2) for *_, w in cols) + "|------|")
    else:
        print(head + "  note")
        print("-" * (len(head) + 6))
    for r in rows:
        ok = str(r.get("converged")) == "1"
        cells = []
        for k, _, fmt, w in cols:
            v = (_f(r, k, fmt) if fmt else str(r.get(k, ""))) if ok or not fmt else "-"
            cells.append(f"{v:>{w}}")
        note = "" if ok else "FAILED: " + r.get("message", "")
        print(("| " + sep.join(cells) + f" | {note} |") if markdown
              else sep.join(cells) + "  " + note)


def compare(paths: List[str]):
    """Speed-up and parallel efficiency of the per-iteration times between CSV files."""
    rows = [r for p in paths for r in read_csv(p)]
    if not rows:
        print("no rows in", paths)
        return
    ok = [r for r in rows if str(r.get("converged")) == "1"]
    base = {key(r)[1:]: r for r in ok if str(r["ranks"]) == "1"}
    print_table(rows)
    print()
    head = (f"{'element':>7} {'solver':>12} {'size':>5} {'ranks':>5} | {'asm s/it':>17} "
            f"{'speed-up':>8} {'eff':>5} | {'lin s/it':>17} {'speed-up':>8} {'eff':>5} | "
            f"{'tot s/it':>17} {'speed-up':>8} {'eff':>5}")
    print("per Newton iteration: 1 rank -> N ranks (efficiency = speed-up / N)")
    print(head)
    print("-" * len(head))
    for r in ok:
        n = int(r["ranks"])
        b = base.get(key(r)[1:])
        if n == 1 or b is None:
            continue
        cells = []
        for k in ("assembly_per_it", "linear_per_it", "total_per_it"):
            t1, tn = float(b[k]), float(r[k])
            s = t1 / tn if tn > 0 else float("nan")
            cells.append(f"{t1:8.3f}→{tn:8.3f} {s:8.2f} {s / n:5.2f}")
        # Krylov solvers: the iteration count changes with the partition (hypre, Jacobi
        # blocks), so also compare the linear-solve time per Krylov iteration
        k1, kn = float(b["ksp_its"]), float(r["ksp_its"])
        extra = ""
        if k1 > float(b["newton_its"]) and kn > 0:
            s = (float(b["linear_s"]) / k1) / (float(r["linear_s"]) / kn)
            extra = (f" | per KSP it: speed-up {s:5.2f}, eff {s / n:4.2f} (KSP/it "
                     f"{float(b['ksp_per_newton']):.0f}→{float(r['ksp_per_newton']):.0f})")
        print(f"{r['element']:>7} {r['solver']:>12} {r['size']:>5} {n:>5} | " + " | ".join(cells)
              + extra)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sizes", default="20k,80k",
                    help="target dof counts, comma separated (default 20k,80k)")
    ap.add_argument("--large", action="store_true", help="add the 300k-dof size")
    ap.add_argument("--elements", default="mini,taylor-hood",
                    help="comma separated: mini, taylor-hood")
    ap.add_argument("--solvers", default=",".join(DEFAULT_VARIANTS),
                    help=f"comma separated variants among {sorted(VARIANTS)}")
    ap.add_argument("--increments", type=int, default=2,
                    help="increments per case; the last one is timed (default 2)")
    ap.add_argument("--newton-cap", type=int, default=0, metavar="N",
                    help="time only the first N Newton iterations of increment 1 (after the "
                         "start-up solve) instead of whole increments: for very costly cases")
    ap.add_argument("--h", type=float, default=None,
                    help="use this element size instead of the dof targets")
    ap.add_argument("--csv", default=None, help="output CSV (default results/solver[_npN].csv)")
    ap.add_argument("--compare", nargs="*", metavar="CSV", default=None,
                    help="print speed-up/efficiency from CSVs (default solver.csv solver_np2.csv)")
    ap.add_argument("--option", action="append", default=[], metavar="KEY=VALUE",
                    help="extra PETSc option (no prefix, no dash) for every case; repeatable")
    ap.add_argument("--label", default=None, help="solver name in the CSV (with --option)")
    ap.add_argument("--table", nargs="*", metavar="CSV", default=None,
                    help="print the rows of CSV files (default solver.csv) and exit")
    ap.add_argument("--markdown", action="store_true", help="--table as a Markdown table")
    ap.add_argument("--quiet", action="store_true")
    a = ap.parse_args()

    comm = MPI.COMM_WORLD
    if a.compare is not None:
        if comm.rank == 0:
            compare(a.compare or [os.path.join(RESULTS, "solver.csv"),
                                  os.path.join(RESULTS, "solver_np2.csv")])
        return
    if a.table is not None:
        if comm.rank == 0:
            print_table([r for p in (a.table or [os.path.join(RESULTS, "solver.csv")])
                         for r in read_csv(p)], a.markdown)
        return
    elements = [e.strip() for e in a.elements.split(",") if e.strip()]
    solvers = [s.strip() for s in a.solvers.split(",") if s.strip()]
    for e in elements:
        if e not in DOF_CONSTANT:
            ap.error(f"unknown element {e!r}")
    for s in solvers:
        if s not in VARIANTS:
            ap.error(f"unknown solver variant {s!r}; choose among {sorted(VARIANTS)}")
    if a.increments < 1:
        ap.error("--increments must be >= 1")
    sizes = [parse_size(s) for s in a.sizes.split(",") if s.strip()]
    if a.large and 300000 not in sizes:
        sizes.append(300000)
    path = a.csv or os.path.join(RESULTS, "solver.csv" if comm.size == 1
                                 else f"solver_np{comm.size}.csv")
    if comm.rank == 0:
        print(f"bench_solver: {comm.size} MPI rank(s), PETSc {PETSc.Sys.getVersion()}, "
              f"OPENBLAS_NUM_THREADS={os.environ.get('OPENBLAS_NUM_THREADS', 'unset')}; "
              f"CSV -> {path}", flush=True)
    options = dict(o.split("=", 1) for o in a.option)
    done = []
    case_id = 0
    for target in sizes:
        for e in elements:
            h = a.h if a.h is not None else (DOF_CONSTANT[e] / target) ** (1.0 / 3.0)
            for s in solvers:
                case_id += 1
                row = run_case(comm, e, s, target, h, a.increments, case_id, not a.quiet,
                               options, a.newton_cap, a.h is not None)
                if a.label:
                    row["solver"] = a.label if len(solvers) == 1 else f"{s}+{a.label}"
                if comm.rank == 0:
                    upsert_csv(path, row)
                done.append(row)
    if comm.rank == 0:
        print()
        print(f"per Newton iteration of the last increment (of {a.increments}), "
              f"max over {comm.size} rank(s); F/J: one residual/Jacobian assembly")
        print_table([{k: str(v) for k, v in r.items()} for r in done])


if __name__ == "__main__":
    main()
