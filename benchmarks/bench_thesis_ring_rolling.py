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
relative, the process (``fxcontact.processes.ring_rolling``, told by
``demos/demo_ring_rolling.py``) has the full run.

Run: ``python benchmarks/bench_thesis_ring_rolling.py [--revolutions 0.3] [--case 1]``
(serially or with ``mpirun -n 2``); prints a markdown table.
"""

from __future__ import annotations

import argparse
import time
from dataclasses import replace

from mpi4py import MPI

from fxcontact.console import add_verbosity_arguments, configure_logging
from fxcontact.processes import RingRollingCase, ring_rolling

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
                         "penetration p/k does not depend on dt); default: the case's beta")
    add_verbosity_arguments(ap)
    a = ap.parse_args(argv)
    configure_logging(verbose=a.verbose, quiet=a.quiet)
    base = getattr(RingRollingCase, f"case{a.case}")().quick()
    base = replace(base, n_theta=a.n_theta, revolutions=a.revolutions,
                   gap_stiffness=a.gap_stiffness)
    rows = []
    for label, kw in VARIANTS:
        kw = dict(kw)
        ipr = a.increments_per_rev // kw.pop("dt_factor", 1)
        cpu0 = time.process_time()
        res = ring_rolling.run(replace(base, increments_per_rev=ipr, **kw))
        cpu = MPI.COMM_WORLD.allreduce(time.process_time() - cpu0, op=MPI.SUM)
        rows.append((label, ipr, res, cpu))
        if MPI.COMM_WORLD.rank == 0:
            print(f"{label}: {res.status} {res.message[:200]}", flush=True)
    if MPI.COMM_WORLD.rank == 0:
        print(f"\ncase {a.case}, ring {base.n_theta} x {base.n_r} x {base.n_z}, "
              f"{a.revolutions} revolution(s), "
              f"{MPI.COMM_WORLD.size} rank(s), gap stiffness {a.gap_stiffness}\n")
        print("| variant | incr./rev | revs done | max penetration mm | max strain | "
              "max strain rate 1/s | volume drift %/rev | Newton its/incr. | wall s/rev "
              "(assembly / linear / contact) | CPU s/rev (all ranks) | CPU / explicit + faceted |")
        print("|---|---|---|---|---|---|---|---|---|---|---|")
        ref = None
        for label, ipr, r, cpu in rows:
            if not r.history:
                print(f"| {label} | {ipr} | failed | | | | | | | | |")
                continue
            revs = max(r.revolutions, 1e-300)
            cpu_rev = cpu / revs
            w = r.wall_split
            if ref is None and label.startswith("explicit + faceted"):
                ref = cpu_rev
            ratio = f"{cpu_rev / ref:.2f}" if ref else "—"
            print(f"| {label} | {ipr} | {r.revolutions:.3f} | {r.max_penetration:.4f} | "
                  f"{r.max_strain:.3f} | {r.max_strain_rate:.3f} | "
                  f"{100 * r.volume_drift_per_rev:.3f} | {r.newton_mean:.1f} | "
                  f"{r.wall_per_rev:.0f} ({w['assembly'] / revs:.0f} / "
                  f"{w['linear_solve'] / revs:.0f} / {w['contact'] / revs:.0f}) | "
                  f"{cpu_rev:.0f} | {ratio} |")


if __name__ == "__main__":
    main()
