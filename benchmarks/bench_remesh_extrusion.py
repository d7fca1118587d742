"""Forward extrusion through a wide die, with and without remeshing (``ExtrusionCase(remesh=True)``).

Usage::

    python benchmarks/bench_remesh_extrusion.py                 # alpha 45 deg, the quick billet
    mpirun -n 2 python benchmarks/bench_remesh_extrusion.py --alpha 40 --stroke 6

The reduced billet of the tests (``ExtrusionCase.quick``: R0 5 -> 3.5 mm, h = 1 mm) through a
die of semi-angle ``alpha``: without remeshing an element at the die's entry inverts after a
short punch stroke and the run stops (``MeshInversionError``); with remeshing (a new mesh when
a cell's quality falls below ``remesh_min_quality``, and before an inverting cell stops the
run) the same mesh size goes on to ``--stroke`` mm. Printed: the stroke each run reaches, the
remeshes (when, why, cells, the volume change each made), the punch pressure around each remesh
(its jump against the oscillation of the increments before it), the volume change over the run,
the wall time. Nothing is asserted.
"""

from __future__ import annotations

import argparse
import time

from mpi4py import MPI

from fxcontact.processes import ExtrusionCase, run_extrusion


def measure(case, comm):
    t0 = time.perf_counter()
    res = run_extrusion(case, comm, pictures=False)
    stroke = case.speed * res.time
    return res, stroke, time.perf_counter() - t0


def pressure_jumps(rows):
    """Per remesh: (|p after − p before|, the largest |Δp| between consecutive increments of the
    3 increments before it) of the punch pressure."""
    out = []
    for i in range(1, len(rows)):
        if rows[i]["remesh"] != rows[i - 1]["remesh"] and i >= 4:
            p = [q["punch_pressure"] for q in rows[i - 4: i + 1]]
            out.append((abs(p[-1] - p[-2]), max(abs(a - b) for a, b in zip(p[1:-1], p[:-2])),
                        p[-2]))
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--alpha", type=float, default=45.0)
    ap.add_argument("--stroke", type=float, default=5.0, help="punch stroke of the remeshed run")
    ap.add_argument("--quality", type=float, default=0.2, help="remesh_min_quality")
    ap.add_argument("--zone-h", type=float, default=None, help="remesh_zone_h (the die's box)")
    ap.add_argument("--skip-plain", action="store_true")
    a = ap.parse_args()
    comm = MPI.COMM_WORLD
    base = ExtrusionCase.quick(alpha=a.alpha, stop_at_steady=False, t_end=a.stroke / 10.0,
                               max_cutbacks=4)
    say = print if comm.rank == 0 else (lambda *x, **k: None)
    plain = None
    if not a.skip_plain:
        res, stroke, wall = measure(base, comm)
        plain = stroke
        say(f"without remeshing: {res.status}, punch stroke {stroke:.3g} mm in "
            f"{res.increments} increments, {wall:.0f} s; {res.message[:160]}")
    case = ExtrusionCase.quick(alpha=a.alpha, stop_at_steady=False, t_end=a.stroke / 10.0,
                               max_cutbacks=4, remesh=True, remesh_min_quality=a.quality,
                               remesh_zone_h=a.zone_h)
    res, stroke, wall = measure(case, comm)
    rows = res.history
    say(f"with remeshing: {res.status}, punch stroke {stroke:.3g} mm"
        + (f" ({stroke / plain:.1f} x)" if plain else "")
        + f" in {res.increments} increments, {rows[-1]['remesh'] if rows else 0} remeshes, "
          f"{wall:.0f} s; h {case.h:g} mm, {res.dofs} dofs initially, {comm.size} rank(s)")
    say(f"volume change over the run: max |V/V0 - 1| = "
        f"{max(abs(q['volume_change']) for q in rows):.2e}")
    for jump, osc, p in pressure_jumps(rows):
        say(f"  remesh: punch pressure {p:.1f} MPa, jump {jump:.2f} MPa against "
            f"{osc:.2f} MPa between the increments before")
    say("punch pressure: " + ", ".join(f"{q['punch_pressure']:.0f}" for q in rows))
    say("min quality: " + ", ".join(f"{q['min_quality']:.2f}" for q in rows))
    say("remesh count: " + "".join(str(q["remesh"]) for q in rows))


if __name__ == "__main__":
    main()
