"""Quadrature degree of the MINI space: the wire drawing at each degree, side by side.

Runs the wire drawing of :mod:`fxcontact.processes` (MINI, Norton–Hoff m = 0.016, library defaults) once per
MINI quadrature degree, the degrees in turn ``--repeat`` times (each figure: the fastest run),
and prints one table: quadrature points per tetrahedron, Newton iterations per increment,
wall time and its split (assembly, linear solve, other), and the drawing stress of every
increment compared with the first degree's (largest relative difference). The accuracy side
of the choice (errors against an exact Poiseuille flow) is ``tests/test_quadrature.py``.

Run from the repository root (the figures of ``benchmarks/README.md``)::

    mpirun -n 2 .venv/bin/python benchmarks/bench_quadrature.py --size 0.7 --t_end 0.03
"""

from __future__ import annotations

import argparse

import numpy as np
from mpi4py import MPI

from fxcontact import spaces
from fxcontact.processes import DrawingCase, run_drawing


def run_at(degree: int, size: float, t_end: float) -> dict:
    """The drawing at ``size`` to ``t_end`` with MINI quadrature ``degree`` (the default of
    :class:`~fxcontact.spaces.MixedSpace` set for the run, then restored)."""
    old = spaces.DEFAULT_QUADRATURE["mini"]
    spaces.DEFAULT_QUADRATURE["mini"] = degree
    try:
        return run_drawing(DrawingCase(size=size, t_end=t_end), pictures=False)
    finally:
        spaces.DEFAULT_QUADRATURE["mini"] = old


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--size", type=float, default=0.4, help="demo size (0.4: 12.4k dofs)")
    ap.add_argument("--t_end", type=float, default=0.03, help="process time [s]")
    ap.add_argument("--degrees", type=int, nargs="+", default=[6, 5, 4],
                    help="MINI quadrature degrees (the first is the reference)")
    ap.add_argument("--repeat", type=int, default=2, help="rounds (the fastest run kept)")
    a = ap.parse_args(argv)
    bad = [d for d in a.degrees if d < spaces.MINI_MIN_QUADRATURE]
    if bad:
        ap.error(f"MINI needs quadrature degrees >= {spaces.MINI_MIN_QUADRATURE}, got {bad}")
    if a.repeat < 1:
        ap.error("--repeat must be >= 1")
    best = {}
    for r in range(a.repeat):
        for d in a.degrees:
            res = run_at(d, a.size, a.t_end)
            if res.status != "completed":
                raise SystemExit(f"degree {d}: the run stopped ({res.status}: {res.message})")
            if d not in best or res.wall_split["total"] < best[d].wall_split["total"]:
                best[d] = res
    if MPI.COMM_WORLD.rank:
        return best
    import basix
    ref = np.array([q["drawing_stress"] for q in best[a.degrees[0]].history])
    r0 = best[a.degrees[0]]
    print(f"\nwire drawing, size {a.size} ({r0.dofs} dofs), t_end {a.t_end} s "
          f"({r0.increments} increments), {r0.ranks} rank(s), fastest of {a.repeat}")
    print("\n| degree | points | Newton its/incr (max) | wall s | assembly s | linear s | "
          "other s | last σ_d MPa | max Δσ_d vs degree " f"{a.degrees[0]} |")
    print("|---|---|---|---|---|---|---|---|---|")
    for d in a.degrees:
        res = best[d]
        nq = len(basix.make_quadrature(basix.CellType.tetrahedron, d)[1])
        sd = np.array([q["drawing_stress"] for q in res.history])
        dev = float(np.max(np.abs(sd - ref) / np.abs(ref))) if sd.shape == ref.shape else np.nan
        ws = res.wall_split
        print(f"| {d} | {nq} | {res.newton_mean:.1f} ({res.newton_max}) | "
              f"{ws['total']:.1f} | {ws['assembly']:.1f} | {ws['linear_solve']:.1f} | "
              f"{ws['other']:.1f} | {sd[-1]:.1f} | {100 * dev:.2f} % |")
    return best


if __name__ == "__main__":
    main()
