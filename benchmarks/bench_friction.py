"""Cost of friction in a Newton iteration, and Newton iterations with implicit vs explicit
friction.

Usage::

    python benchmarks/bench_friction.py                 # both cases, default sizes
    python benchmarks/bench_friction.py --h-fine 0.06   # finer roll case
    mpirun -n 2 python benchmarks/bench_friction.py

Cases (each run frictionless, then with friction, implicit and explicit):

* ``roll``: an elastic block (6 × 1 × 1, half model) held at its base, pressed by a roll of
  radius 2 that turns at ω = 1 rad/s (it slips over the block everywhere: the Coulomb branch);
  Coulomb μ = 0.3, and Coulomb μ = 1 limited by Tresca (m̄ = 1, k = 1.5);
* ``upsetting``: a Norton–Hoff quarter billet (R 10, H 15, K 50, m 0.15) between two flat
  `Plane` dies with Tresca friction m̄ = 0.3 (k from the material at the nodes).

Per case: Newton iterations per increment (mean and max over the increments after the first,
including failed attempts), wall time per Newton iteration of the contact work (projections,
penalty and friction kernels, insertion: ``wall_contact``) and of the whole iteration
(``wall_total``), and the contact share. Friction's extra cost is the contact time per iteration
with friction over the frictionless one. Rows are printed and appended to
``benchmarks/results/friction.csv``.
"""

from __future__ import annotations

import argparse
import csv
import os

import numpy as np
from mpi4py import MPI

import fxcontact as fx

HERE = os.path.dirname(os.path.abspath(__file__))
RESULTS = os.path.join(HERE, "results")
FIELDS = ["ranks", "case", "friction", "mode", "dofs", "contact_nodes", "increments",
          "newton_mean", "newton_max", "cutbacks", "contact_ms_per_it", "total_ms_per_it",
          "contact_share"]


def roll_case(law, mode, h_fine, comm):
    msh, _, ft = fx.block(comm, (0, 0, 0), (6, 1, 1), 0.4,
                          refine_box=((2.75, 0, 0.85), (3.25, 1, 1)), h_fine=h_fine)
    sp = fx.MixedSpace(msh)
    sim = fx.Simulation(sp, fx.LinearElastic(1000.0, 0.3), progress=False)
    f = {k: sim.facets(ft, v) for k, v in fx.BLOCK_TAGS.items()}
    sim.add_velocity_bc(f["ymin"], 0.0, 1)
    sim.add_velocity_bc(f["zmin"], np.zeros(3))
    roll = fx.Cylinder((3.0, 0.0, 3.0), (0, 1, 0), 2.0,
                       velocity=lambda t: (0.0, 0.0, -0.006 if t < 1.0 else 0.0),
                       angular_velocity=1.0, name="roll")
    c = fx.NodalContact(fx.ContactBoundary(sp, ft, fx.BLOCK_TAGS["zmax"]), roll, friction=law,
                        friction_mode=mode)
    sim.add_contributor(c)
    sim.run(1.0, 0.5, close=False)
    sim.run(1.05, 0.01)
    return sim


def upsetting_case(law, mode, h, comm):
    msh, _, ft = fx.cylinder_billet(comm, 10.0, 15.0, h, quarter=True)
    sp = fx.MixedSpace(msh)
    sim = fx.Simulation(sp, fx.NortonHoff(K=50.0, m=0.15, regularization=1e-4 / 3.0),
                        progress=False)
    f = {k: sim.facets(ft, v) for k, v in fx.BILLET_TAGS.items()}
    sim.add_velocity_bc(f["symmetry_x"], 0.0, 0)
    sim.add_velocity_bc(f["symmetry_y"], 0.0, 1)
    dies = [fx.Plane((0, 0, 15.0), (0, 0, -1), velocity=(0, 0, -5.0), name="die"),
            fx.Plane((0, 0, 0), (0, 0, 1), name="anvil")]
    tags = [fx.BILLET_TAGS["top"], fx.BILLET_TAGS["bottom"]]
    c = fx.NodalContact(fx.ContactBoundary(sp, ft, tags), dies, friction=law,
                        friction_mode=mode)
    sim.add_contributor(c)
    sim.run(0.6, 0.06)
    return sim


def summarise(sim, case, law, mode):
    rows = sim.history[1:]
    its = np.array([r["newton_iterations_all"] for r in rows], float)
    acc = np.array([r["newton_iterations"] for r in rows], float)
    wc = sum(r["wall_contact"] for r in rows)
    wt = sum(r["wall_total"] for r in rows)
    comm = sim.comm
    wc, wt = comm.allreduce(wc, op=MPI.MAX), comm.allreduce(wt, op=MPI.MAX)
    name = "none" if law is None else repr(law)
    return {"ranks": comm.size, "case": case, "friction": name,
            "mode": mode or "-", "dofs": sim.space.global_dofs(),
            "contact_nodes": rows[-1]["contact_nodes"], "increments": len(rows),
            "newton_mean": its.mean(), "newton_max": int(its.max()),
            "cutbacks": int(sum(r["cutbacks"] for r in rows)),
            "contact_ms_per_it": 1e3 * wc / acc.sum(), "total_ms_per_it": 1e3 * wt / acc.sum(),
            "contact_share": wc / wt}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--h-fine", type=float, default=0.08, help="roll case: fine element size")
    ap.add_argument("--h", type=float, default=2.0, help="upsetting case: element size")
    ap.add_argument("--cases", default="roll,upsetting")
    a = ap.parse_args()
    comm = MPI.COMM_WORLD
    runs = []
    if "roll" in a.cases:
        for law, mode in ((None, None), (fx.Coulomb(0.3), "implicit"),
                          (fx.Coulomb(0.3), "explicit"),
                          (fx.Coulomb(1.0, mbar=1.0, shear_limit=1.5), "implicit"),
                          (fx.Coulomb(1.0, mbar=1.0, shear_limit=1.5), "explicit")):
            runs.append(summarise(roll_case(law, mode, a.h_fine, comm), "roll", law, mode))
    if "upsetting" in a.cases:
        for law, mode in ((None, None), (fx.Tresca(0.3), "implicit"),
                          (fx.Tresca(0.3), "explicit")):
            runs.append(summarise(upsetting_case(law, mode, a.h, comm), "upsetting", law, mode))
    if comm.rank == 0:
        base = {r["case"]: r["contact_ms_per_it"] for r in runs if r["friction"] == "none"}
        print(f"{'case':10s} {'friction':44s} {'mode':8s} {'dofs':>7s} {'its':>5s} {'max':>4s} "
              f"{'cut':>3s} {'contact ms/it':>13s} {'x frictionless':>14s} {'total ms/it':>11s} "
              f"{'share':>6s}")
        for r in runs:
            print(f"{r['case']:10s} {r['friction'][:44]:44s} {r['mode']:8s} {r['dofs']:7d} "
                  f"{r['newton_mean']:5.2f} {r['newton_max']:4d} {r['cutbacks']:3d} "
                  f"{r['contact_ms_per_it']:13.2f} "
                  f"{r['contact_ms_per_it'] / base[r['case']]:14.2f} "
                  f"{r['total_ms_per_it']:11.1f} {100 * r['contact_share']:5.2f}%")
        os.makedirs(RESULTS, exist_ok=True)
        path = os.path.join(RESULTS, "friction.csv" if comm.size == 1
                            else f"friction_np{comm.size}.csv")
        new = not os.path.exists(path)
        with open(path, "a", newline="") as fh:
            w = csv.DictWriter(fh, FIELDS)
            if new:
                w.writeheader()
            w.writerows(runs)


if __name__ == "__main__":
    main()
