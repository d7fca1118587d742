"""The thesis's three ring-rolling variants on the same ring (THEORY §12.3, academic case 1):

* explicit contact + faceted tools (flat facets), Cartesian update — Forge's "standard";
* explicit contact + analytic tools, Cartesian update;
* implicit contact + analytic tools, cylindrical update (THEORY §5) — the thesis's proposal;

plus the implicit variant at twice the time step (dt-sensitivity of its penetration). Measured:
max true penetration (end-of-increment nodes against the tools), max equivalent strain and strain
rate, volume drift per revolution (no volume correction), Newton iterations, wall time per
revolution with its split (assembly, linear solve, contact), and the CPU time per revolution
summed over the ranks (``time.process_time``: less sensitive than the wall time to other jobs
on the machine), with the ratio of each variant's CPU time to the explicit + faceted one (the
thesis: implicit + analytic ≈ 0.7× the standard's time). Reduced size (coarse structured ring, a fraction of a revolution): the figures are
relative, the demo (``demos/demo_ring_rolling.py``) has the full run.

Run: ``python benchmarks/bench_thesis_ring_rolling.py [--revolutions 0.3] [--case 1]``
(serially or with ``mpirun -n 2``); prints a markdown table.
"""

from __future__ import annotations

import argparse
import os
import sys
import time

from mpi4py import MPI

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "demos"))
import demo_ring_rolling as demo  # noqa: E402

from fxcontact.console import add_verbosity_arguments, configure_logging  # noqa: E402

VARIANTS = [
    ("explicit + faceted, Cartesian", dict(scheme="explicit", tools="faceted",
                                           update="cartesian")),
    ("explicit + analytic, Cartesian", dict(scheme="explicit", tools="analytic",
                                            update="cartesian")),
    ("implicit + analytic, cylindrical", dict(scheme="implicit", tools="analytic",
                                              update="cylindrical")),
    ("implicit + analytic, cylindrical, dt x 2", dict(scheme="implicit", tools="analytic",
                                                      update="cylindrical", dt_factor=2)),
]


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--case", type=int, default=1, choices=(1, 2))
    ap.add_argument("--revolutions", type=float, default=0.3)
    ap.add_argument("--n_theta", type=int, default=100)
    ap.add_argument("--increments_per_rev", type=int, default=50)
    ap.add_argument("--gap_stiffness", type=float, default=None,
                    help="penalty as a gap stiffness k [MPa/mm] (rho = k dt: the penalty "
                         "penetration p/k does not depend on dt); default: the demo's beta")
    add_verbosity_arguments(ap)
    a = ap.parse_args(argv)
    configure_logging(verbose=a.verbose, quiet=a.quiet)
    rows = []
    for label, kw in VARIANTS:
        kw = dict(kw)
        ipr = a.increments_per_rev // kw.pop("dt_factor", 1)
        cpu0 = time.process_time()
        res = demo.run(**{**demo.QUICK, "case": a.case, "n_theta": a.n_theta,
                          "increments_per_rev": ipr, "revolutions": a.revolutions,
                          "gap_stiffness": a.gap_stiffness,
                          "output_dir": None, "pictures": False, **kw})
        res["cpu"] = MPI.COMM_WORLD.allreduce(time.process_time() - cpu0, op=MPI.SUM)
        for part in ("assembly", "linear_solve", "contact"):
            res[f"wall_{part}"] = sum(q.get(f"wall_{part}", 0.0) for q in res["sim_history"])
        rows.append((label, ipr, res))
        if MPI.COMM_WORLD.rank == 0:
            print(f"{label}: {res['status']} {res['message'][:200]}", flush=True)
    if MPI.COMM_WORLD.rank == 0:
        print(f"\ncase {a.case}, ring {demo.QUICK['n_theta'] if a.n_theta is None else a.n_theta}"
              f" x {demo.QUICK['n_r']} x {demo.QUICK['n_z']}, {a.revolutions} revolution(s), "
              f"{MPI.COMM_WORLD.size} rank(s), gap stiffness {a.gap_stiffness}\n")
        print("| variant | incr./rev | revs done | max penetration mm | max strain | "
              "max strain rate 1/s | volume drift %/rev | Newton its/incr. | wall s/rev "
              "(assembly / linear / contact) | CPU s/rev (all ranks) | CPU / explicit + faceted |")
        print("|---|---|---|---|---|---|---|---|---|---|---|")
        ref = None
        for label, ipr, r in rows:
            if not r.get("increments"):
                print(f"| {label} | {ipr} | failed | | | | | | | | |")
                continue
            revs = max(r["revolutions"], 1e-300)
            cpu_rev = r["cpu"] / revs
            if ref is None and label.startswith("explicit + faceted"):
                ref = cpu_rev
            ratio = f"{cpu_rev / ref:.2f}" if ref else "—"
            print(f"| {label} | {ipr} | {r['revolutions']:.3f} | {r['max_penetration']:.4f} | "
                  f"{r['max_strain']:.3f} | {r['max_strain_rate']:.3f} | "
                  f"{100 * r['volume_drift_per_rev']:.3f} | {r['newton_mean']:.1f} | "
                  f"{r['wall_per_rev']:.0f} ({r['wall_assembly'] / revs:.0f} / "
                  f"{r['wall_linear_solve'] / revs:.0f} / {r['wall_contact'] / revs:.0f}) | "
                  f"{cpu_rev:.0f} | {ratio} |")


if __name__ == "__main__":
    main()
