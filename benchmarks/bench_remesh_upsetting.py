"""Upsetting a cylinder with sticking dies to 70 % height reduction, with and without remeshing
(``UpsettingCase(remesh=...)``).

Usage::

    python benchmarks/bench_remesh_upsetting.py                      # the quick billet
    mpirun -n 2 python benchmarks/bench_remesh_upsetting.py --R0 10 --h 1.5

The billet (R₀, H₀/D₀ = 1.5, a 45° sector, half the height, element size h) between sticking
flat dies (Tresca m̄ = 1): without remeshing the free surface folding onto the die flattens the
elements at the die's edge and the run stops (``MeshInversionError``, or Newton failing on
them); with remeshing (a new mesh when a cell's quality falls below ``--quality``, finer at the
folding edge) the same mesh size goes on to the target reduction. Printed per run: the
reduction reached, the remeshes, the smallest element quality, the volume change, the die
pressure against the band σ₀ π r_c² ≤ F ≤ σ₀ A_h (1 + d_h/(3√3 h)) per increment, the die
contact, end-face and free-surface radii at the end, the wall time. Nothing is asserted.
"""

from __future__ import annotations

import argparse

from mpi4py import MPI

from fxcontact.processes import UpsettingCase, run_upsetting


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--R0", type=float, default=5.0)
    ap.add_argument("--h", type=float, default=1.25)
    ap.add_argument("--dt", type=float, default=0.05)
    ap.add_argument("--reduction", type=float, default=0.7)
    ap.add_argument("--quality", type=float, default=0.2, help="remesh_min_quality")
    ap.add_argument("--skip-plain", action="store_true")
    ap.add_argument("--output-dir", default=None, help="pictures of the remeshed run")
    a = ap.parse_args()
    comm = MPI.COMM_WORLD
    say = print if comm.rank == 0 else (lambda *x, **k: None)
    base = UpsettingCase.quick(R0=a.R0, h=a.h, dt=a.dt, reduction=a.reduction,
                               remesh_min_quality=a.quality)
    for remesh in ([True] if a.skip_plain else [False, True]):
        res = run_upsetting(base.replace(remesh=remesh), comm,
                            output_dir=a.output_dir if remesh else None)
        rows = res.history
        say(f"\n{'with' if remesh else 'without'} remeshing: {res.status}, height reduction "
            f"{100 * res.reduction:.1f} % in {res.increments} increments, {res.remeshes} "
            f"remeshes, {res.wall:.0f} s; {res.dofs} dofs initially, {comm.size} rank(s)")
        if res.status != "completed":
            say(f"  stopped: {res.message[:240]}")
        if not rows:
            continue
        say(f"  min element quality {res.min_quality:.3f}, max |V/V0 - 1| "
            f"{res.max_volume_change:.2e}, Newton its mean {res.newton_mean:.1f} max "
            f"{res.newton_max}, cut-backs {res.cutbacks}")
        say(f"  radii at the end: die contact {res.radii['contact']:.2f}, end face "
            f"{res.radii['face']:.2f}, free surface {res.radii['free']:.2f} mm "
            f"(homogeneous {rows[-1]['r_homogeneous']:.2f})")
        say(f"  increments out of the band: {res.out_of_band or 'none'}")
        say("  reduction %: " + ", ".join(f"{100 * q['reduction']:.0f}" for q in rows))
        say("  lower/p/upper: " + ", ".join(f"{q['lower']:.2f}/{q['p_mean']:.3f}/"
                                             f"{q['upper']:.2f}" for q in rows))
        say("  r contact: " + ", ".join(f"{q['r_contact']:.2f}" for q in rows))
        say("  min quality: " + ", ".join(f"{q['min_quality']:.2f}" for q in rows))
        say("  remesh count: " + "".join(str(q["remesh"]) for q in rows))
        if res.pictures:
            say("  pictures: " + ", ".join(res.pictures))


if __name__ == "__main__":
    main()
