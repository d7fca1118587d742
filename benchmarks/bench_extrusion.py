"""Forward extrusion (:mod:`fxcontact.processes.extrusion`) against its classical band, and the
container given as a tool of its own against one profile.

1. **Band**: the steady punch pressure for two die angles and two reductions (the quick size of
   the tests: R₀ = 5 mm, h = 1 mm, Tresca m̄ 0.1 on the die and 0.3 on the container, k of the
   container's friction from the local strain rate), against the ideal work and 1.1 × (Avitzur's
   die bound + the container friction 2 m̄ k L_c/R₀ at the steady window's L_c).
2. **Given k**: with ``container_shear_limit`` = σ₀/√3 the container's axial force over
   2 m̄ k L_c/R₀ × A₀ (the tests require 1 ± 3 %).
3. **Tools**: the container and the die as two tools of one contact (``container="separate"``)
   against one profile (``"profile"``), the same friction on both: Newton iterations per
   increment and cut-backs.

Run from the repository root::

    OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/bench_extrusion.py
    mpirun -n 2 .venv/bin/python benchmarks/bench_extrusion.py --parts band
"""

from __future__ import annotations

import argparse
import math
import time

from mpi4py import MPI

from fxcontact.processes import ExtrusionCase, run_extrusion

#: (die semi-angle in degrees, exit radius) of the band: two angles, two reductions (51 %, 36 %)
BAND_CASES = ((20.0, 3.5), (30.0, 3.5), (20.0, 4.0), (30.0, 4.0))


def band(cases=BAND_CASES, comm=None) -> list:
    """One row per (alpha, R1): the steady punch pressure and the band."""
    rows = []
    for alpha, R1 in cases:
        t0 = time.perf_counter()
        res = run_extrusion(ExtrusionCase.quick(alpha=alpha, R1=R1), comm=comm, pictures=False)
        th = res.theory
        rows.append(dict(alpha=alpha, R1=R1, status=res.status, steady=res.punch_pressure,
                         ideal=th["ideal"], upper=th["upper"], avitzur=th["avitzur"],
                         container=th["container"], die=res.die_pressure,
                         power_balance=res.power_balance, dV=res.max_volume_change,
                         quality=res.min_quality, newton=res.newton_mean, cutbacks=res.cutbacks,
                         increments=res.increments, dofs=res.dofs,
                         wall=time.perf_counter() - t0))
    return rows


def given_k(comm=None) -> dict:
    """The container force with k given (σ₀/√3 at the die's mean rate)."""
    k = ExtrusionCase.quick().theory()["shear_yield"]
    res = run_extrusion(ExtrusionCase.quick(container_shear_limit=k), comm=comm, pictures=False)
    return dict(k=k, ratio=res.container_ratio, steady=res.punch_pressure,
                upper=res.theory["upper"], status=res.status)


def tools(comm=None, t_end=0.3) -> list:
    """Separate tools against one profile, m̄ 0.1 on both."""
    rows = []
    for container in ("separate", "profile"):
        res = run_extrusion(ExtrusionCase.quick(container=container, mbar_container=0.1,
                                                stop_at_steady=False, t_end=t_end),
                            comm=comm, pictures=False)
        rows.append(dict(container=container, newton=res.newton_mean, newton_max=res.newton_max,
                         cutbacks=res.cutbacks, increments=res.increments,
                         last=res.history[-1]["punch_pressure"]))
    return rows


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--parts", nargs="+", default=["band", "given_k", "tools"],
                    choices=["band", "given_k", "tools"])
    a = ap.parse_args(argv)
    say = print if MPI.COMM_WORLD.rank == 0 else (lambda *x: None)
    if "band" in a.parts:
        rows = band()
        say("\n| α | R₁ | dofs | incr. | p MPa | ideal | 1.1 × upper (Avitzur + container) | "
            "p / upper | die p / Avitzur | power bal. | max ΔV/V | min q | Newton | cut-backs "
            "| wall s |")
        say("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
        for r in rows:
            p = r["steady"] if r["steady"] is not None else math.nan
            die = r["die"] if r["die"] is not None else math.nan
            say(f"| {r['alpha']:g}° | {r['R1']:g} | {r['dofs']} | {r['increments']} | {p:.1f} | "
                f"{r['ideal']:.1f} | {1.1 * r['upper']:.1f} ({r['avitzur']:.1f} + "
                f"{r['container']:.1f}) | {p / r['upper']:.3f} | {die / r['avitzur']:.3f} | "
                f"{100 * r['power_balance']:.1f} % | {r['dV']:.1e} | {r['quality']:.2f} | "
                f"{r['newton']:.1f} | {r['cutbacks']} | {r['wall']:.0f} |")
    if "given_k" in a.parts:
        r = given_k()
        say(f"\ncontainer force with k given ({r['k']:.2f} MPa): force / (2 m̄ k L_c/R₀ A₀) = "
            f"{r['ratio']:.4f}; punch pressure {r['steady']:.1f} MPa (upper {r['upper']:.1f})")
    if "tools" in a.parts:
        say("\n| container | Newton its / increment (max) | cut-backs | increments | last p MPa |")
        say("|---|---|---|---|---|")
        for r in tools():
            say(f"| {r['container']} | {r['newton']:.2f} ({r['newton_max']}) | {r['cutbacks']} | "
                f"{r['increments']} | {r['last']:.4f} |")


if __name__ == "__main__":
    main()
