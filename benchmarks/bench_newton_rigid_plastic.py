"""Newton on a nearly rigid-plastic Norton–Hoff material: drawing through a smooth conical die.

Case (``drawing_case.py``): quarter bar R₀ = 5 mm, 15 % area reduction, die semi-angle 10°,
fillet 4 mm, K = 445 MPa·s^m, m = 0.016 (cold drawing), pulled at 10 mm/s, frictionless
implicit nodal contact, MINI elements. Each variant runs ``--increments`` increments of ``--dt``
from the start-up (Newtonian) guess and reports per increment the Newton iterations (accepted
attempt and all attempts), the cut-backs, the wall time, the drawing force and the true
penetration; then the mean/max of the iterations over the increments after the first (the first
starts from the rigid Newtonian guess, which goes through the die) and over all increments.

Variants (``--variants``; each is a set of options of the library, nothing else changes; all
but the ``pred`` ones without the active-set prediction, which the library now uses by default
with a direct solver, and all but the ``pd`` ones with the consistent Norton–Hoff tangent, where
the library's default is now the primal–dual one):

* ``default``: the defaults without the prediction (ε̇₀ = 1e-6 1/s, β = 1e3, bt line search);
* ``reg1e-3``: regularisation ε̇₀ = 1e-3 × the die's mean strain rate (THEORY §14.2);
* ``beta1e2``, ``beta1e1``: penalty β = 1e2 / 1e1 (THEORY §2.5 scales ρ with the secant
  viscosity; the tangent along the flow is m times smaller);
* ``maxit100``: today's defaults with ``max_it = 100`` (no cut-back needed);
* ``beta1e1+reg1e-3``, ``beta1e1+reg1e-2``: β = 1e1 and ε̇₀ = 1e-3 / 1e-2 × the mean rate;
* ``tr``: the trust-region Newton (``line_search="trust-region"``, fallback bt), ``max_it`` 100;
* ``cont0.03``: penalty continuation (``penalty_continuation=0.03``: β·0.03 = 30 first, to a
  relative residual of 1e-3, then β = 1e3), ``max_it`` 100;
* ``cont0.03+reg1e-3``, ``tr+reg1e-3`` (``max_it`` 100), ``beta1e1+reg1e-3+tr``: combinations;
* ``pred``: the active-set prediction of the Newton step (``active_set_prediction=True``,
  :mod:`fxcontact.newton.prediction`), bt, ``max_it`` 100; ``pred+maxit30`` at the default ``max_it``;
  ``pred+reg1e-3``, ``pred+beta1e1+reg1e-3``: with the other settings;
* ``pd``: the primal–dual Norton–Hoff tangent (``material_tangent="primal-dual"``,
  :mod:`fxcontact.element.dual`), bt, ``max_it`` 100; ``pred+pd``, ``pred+pd+reg1e-3``: with the
  prediction (and ε̇₀).

Run from the repository root::

    OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/bench_newton_rigid_plastic.py
    .venv/bin/python benchmarks/bench_newton_rigid_plastic.py --variants default beta1e1 --h 2
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np
from mpi4py import MPI

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from drawing_case import drawing_simulation, mean_strain_rate  # noqa: E402

from fxcontact.newton.solver import SolverOptions  # noqa: E402
from fxcontact.simulation import IncrementError  # noqa: E402

R0, REDUCTION, ALPHA, SPEED = 5.0, 0.15, np.radians(10.0), 10.0
RATE = mean_strain_rate(R0, REDUCTION, ALPHA, SPEED * (1.0 - REDUCTION))

#: variant name -> (drawing_simulation keywords, SolverOptions keywords)
VARIANTS = {
    "default": ({}, {}),
    "reg1e-3": ({"regularization": 1e-3 * RATE}, {}),
    "beta1e2": ({"beta": 1e2}, {}),
    "beta1e1": ({"beta": 1e1}, {}),
    "maxit100": ({}, {"max_it": 100}),
    "beta1e1+reg1e-3": ({"beta": 1e1, "regularization": 1e-3 * RATE}, {}),
    "beta1e1+reg1e-2": ({"beta": 1e1, "regularization": 1e-2 * RATE}, {}),
    "tr": ({}, {"max_it": 100, "line_search": "trust-region", "line_search_fallback": "bt"}),
    "cont0.03": ({}, {"max_it": 100, "penalty_continuation": 0.03}),
    "cont0.03+reg1e-3": ({"regularization": 1e-3 * RATE},
                         {"max_it": 100, "penalty_continuation": 0.03}),
    "tr+reg1e-3": ({"regularization": 1e-3 * RATE},
                   {"max_it": 100, "line_search": "trust-region", "line_search_fallback": "bt"}),
    "beta1e1+reg1e-3+tr": ({"beta": 1e1, "regularization": 1e-3 * RATE},
                           {"line_search": "trust-region", "line_search_fallback": "bt"}),
    "pred": ({}, {"max_it": 100, "active_set_prediction": True}),
    "pred+maxit30": ({}, {"active_set_prediction": True}),
    "pred+reg1e-3": ({"regularization": 1e-3 * RATE},
                     {"max_it": 100, "active_set_prediction": True}),
    "pred+beta1e1+reg1e-3": ({"beta": 1e1, "regularization": 1e-3 * RATE},
                             {"active_set_prediction": True}),
    "pd": ({}, {"max_it": 100, "material_tangent": "primal-dual"}),
    "pred+pd": ({}, {"max_it": 100, "active_set_prediction": True,
                     "material_tangent": "primal-dual"}),
    "pred+pd+reg1e-3": ({"regularization": 1e-3 * RATE},
                        {"max_it": 100, "active_set_prediction": True,
                         "material_tangent": "primal-dual"}),
}


def run(variant: str = "default", h: float = 1.6, h_die: float = 0.8, dt: float = 0.015,
        increments: int = 5, max_it: int = 30, max_cutbacks: int = 4, comm=MPI.COMM_WORLD,
        verbose: bool = True):
    """Run one variant; returns a dict of figures (one row per increment in ``rows``)."""
    sim_kw, opt_kw = VARIANTS[variant]
    # the variants without "pred" run the plain Newton step (the prediction off, as before it
    # existed); the library default (``"auto"``) turns it on with the direct solver used here
    # and the variants without "pd" the consistent Norton–Hoff tangent (the library's
    # default, "auto", is the primal–dual one for m < 1)
    opts = SolverOptions(**{"max_it": max_it, "active_set_prediction": False,
                            "material_tangent": "consistent", **opt_kw})
    sim, die, contact = drawing_simulation(comm, R0=R0, reduction=REDUCTION,
                                           half_angle_deg=np.degrees(ALPHA), h=h, h_die=h_die,
                                           speed=SPEED, solver_options=opts, **sim_kw)
    rows, error = [], ""
    for i in range(increments):
        t0 = time.perf_counter()
        try:
            res = sim.step(dt, max_cutbacks=max_cutbacks)
        except IncrementError as e:
            error = str(e)
            break
        r = res.row
        rows.append({"increment": i + 1, "its": r["newton_iterations"],
                     "its_all": r["newton_iterations_all"], "cutbacks": r["cutbacks"],
                     "wall": time.perf_counter() - t0, "force": 4.0 * r["front_z"],
                     "penetration": r["contact_penetration_true"],
                     "residuals": res.info.residual_norms,
                     "linear": res.info.times.get("linear_solve", 0.0)})
        if verbose and comm.rank == 0:
            print(f"  {variant:>16s} inc {i + 1}: {r['newton_iterations']:3d} its "
                  f"({r['newton_iterations_all']} with cut-backs, {r['cutbacks']} cut-backs), "
                  f"{rows[-1]['wall']:.2f} s, force {rows[-1]['force']:.1f} N, "
                  f"penetration {r['contact_penetration_true']:.2e} mm", flush=True)
    its = np.array([r["its_all"] for r in rows])
    out = {"variant": variant, "dofs": sim.space.global_dofs(), "rows": rows, "error": error,
           "mean_all": its.mean() if len(its) else np.nan,
           "max_all": its.max() if len(its) else 0,
           "mean_steady": its[1:].mean() if len(its) > 1 else np.nan,
           "max_steady": its[1:].max() if len(its) > 1 else 0,
           "cutbacks": sum(r["cutbacks"] for r in rows),
           "wall_per_increment": np.mean([r["wall"] for r in rows]) if rows else np.nan}
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--variants", nargs="+", default=list(VARIANTS), choices=list(VARIANTS))
    ap.add_argument("--h", type=float, default=1.6, help="element size away from the die [mm]")
    ap.add_argument("--h-die", type=float, default=0.8, help="element size at the die [mm]")
    ap.add_argument("--dt", type=float, default=0.015, help="time step [s] (0.15 mm of pull)")
    ap.add_argument("--increments", type=int, default=5)
    ap.add_argument("--max-it", type=int, default=30)
    a = ap.parse_args()
    comm = MPI.COMM_WORLD
    results = []
    for v in a.variants:
        results.append(run(v, a.h, a.h_die, a.dt, a.increments, a.max_it, comm=comm))
    if comm.rank == 0:
        print(f"\n{comm.size} rank(s), {results[0]['dofs']} dofs, dt = {a.dt}, max_it = "
              f"{a.max_it}; Newton iterations per increment (all attempts)")
        print(f"| variant | mean (all) | max (all) | mean (2nd..) | max (2nd..) | cut-backs | "
              f"s/increment | final force N | failed |")
        print("|---|---|---|---|---|---|---|---|---|")
        for r in results:
            f = r["rows"][-1]["force"] if r["rows"] else np.nan
            print(f"| {r['variant']} | {r['mean_all']:.1f} | {r['max_all']} | "
                  f"{r['mean_steady']:.1f} | {r['max_steady']} | {r['cutbacks']} | "
                  f"{r['wall_per_increment']:.1f} | {f:.0f} | "
                  f"{'yes' if r['error'] else 'no'} |")


if __name__ == "__main__":
    main()
