"""Ring rolling over several revolutions with remeshing whose refinement follows the bite.

Usage::

    python benchmarks/bench_remesh_ring.py                     # the defaults below, 5 revolutions
    python benchmarks/bench_remesh_ring.py --revolutions 0.3   # the cost per revolution first
    python benchmarks/bench_remesh_ring.py --remesh_min_across 0 ...   # no coverage asked

Any field of ``RingRollingCase`` is an option (``--n_theta 120 --H 30 ...``). The defaults:
``RingRollingCase().quick()`` (ring 100 × 3 × 1 elements, 50 increments per revolution) with
``remesh=True``, ``remesh_min_across=3`` (each bite spanned by 3 elements: bite zones on the
rolled surfaces of size L/(1.3 × 3), remeshed before the first increment, then when the ring has
turned by the zone's arc less the bite, or when a bite is spanned by fewer than 3 elements),
``remesh_arc=30``, ``initial_bite=0.5`` (the rolls start a steady bite into the ring: the wall
reduction Δh = 1 mm of one revolution, so that the bite has its steady length from the first
increment) and 5 revolutions.

Measured at each increment (``fxcontact.processes.ring_rolling.mill.bite_coverage``, before the
increment's remesh check): the elements across the main roll's and the mandrel's bites (the
contact nodes' arc over the mean edge of the facets between them), the criterion's own measure
(``elements_across_*`` of the simulation's history); the main roll's force (whole ring), the
volume change, the smallest cell quality, the cells, the wall. Printed: one line per increment,
then the summary (revolutions, remeshes, elements across min/median per tool, the force jumps
at the remeshes against the largest change between two increments without a remesh in the
second half, volume, quality, wall per revolution and in the remeshes). Written to
``--output-dir`` (default ``benchmarks/results/remesh_ring``): ``remesh_ring.csv`` and
``remesh_ring.png`` (the mesh of the top face at the last remesh near the gap, the force with
the remeshes marked, the elements across the bites, volume and quality).
"""

from __future__ import annotations

import csv
import math
import os
import time

import numpy as np
from mpi4py import MPI

from fxcontact.console import case_parser, parse_case
from fxcontact.processes import RingRollingCase, ring_mill
from fxcontact.processes import ring_rolling as rr

DEFAULTS = dict(remesh=True, remesh_min_across=3.0, remesh_arc=30.0, initial_bite=0.5,
                revolutions=5.0)


def top_mesh(s):
    """The triangles of the ring's top face (z = max) now, gathered on every rank."""
    import fxcontact as fx
    sim = s.sim
    msh = sim.mesh
    ft = sim._remesh_facet_tags
    fdim = msh.topology.dim - 1
    msh.topology.create_connectivity(fdim, 0)
    f2v = np.asarray(msh.topology.connectivity(fdim, 0).array).reshape(-1, fdim + 1)
    n_own = msh.topology.index_map(fdim).size_local
    top = ft.indices[(ft.values == fx.RING_TAGS["top"]) & (ft.indices < n_own)]
    T = sim.vertex_positions()[f2v[top]][:, :, :2]
    return np.concatenate(sim.comm.allgather(T))


def run(case, comm, out):
    say = print if comm.rank == 0 else (lambda *a, **k: None)
    t0 = time.perf_counter()
    s = rr.build(case, comm)
    sim = s.sim
    probe = []
    rm = sim._remeshing
    if rm is not None:   # the bites measured before each increment's remesh check
        check = rm.after_increment

        def measured_then_checked(sim_):
            probe.append(ring_mill.bite_coverage(sim_, s.contact, s.centring.center))
            check(sim_)
        rm.after_increment = measured_then_checked
    measure = rr._Measure(s)
    rows, mesh_pic = [], None
    t_end = case.revolutions * case.t_rev
    say(f"bite L = {ring_mill.bite_length(case):.2f} mm, h_theta = {s.h_theta:.2f} mm, "
        f"build {time.perf_counter() - t0:.1f} s, cells "
        f"{sim.mesh.topology.index_map(3).size_global}", flush=True)
    while sim.t < t_end * (1 - 1e-9) and len(rows) < case.max_increments:
        w0 = time.perf_counter()
        n_remesh = len(sim.remeshes)
        inc = sim.step(min(s.dt, t_end - sim.t))
        wall = comm.allreduce(time.perf_counter() - w0, op=MPI.MAX)
        if len(sim.remeshes) != measure.remeshes:
            measure = rr._Measure(s, measure.power)   # the boundaries of the new mesh
        row = measure(inc)
        q = sim.history[-1]
        cov = probe[-1] if probe else {}
        row.update(cells=sim.mesh.topology.index_map(3).size_global, wall_total=wall,
                   remeshed=len(sim.remeshes) - n_remesh, remesh=q["remesh"])
        for k in ("main_roll", "mandrel"):
            row[f"across_{k}"] = cov.get(k, (0, 0, math.nan))[2]
            row[f"arc_{k}"] = cov.get(k, (math.nan,))[0]
            row[f"criterion_across_{k}"] = q.get(f"elements_across_{k}", math.nan)
        rows.append(row)
        say(f"{row['revolutions']:.3f} rev: F {row['main_force_x'] / 1e3:.2f} kN, across "
            f"{row['across_main_roll']:.2f}/{row['across_mandrel']:.2f} (criterion "
            f"{row['criterion_across_main_roll']:.2f}/{row['criterion_across_mandrel']:.2f}), "
            f"arcs {row['arc_main_roll']:.2f}/{row['arc_mandrel']:.2f} mm, dV "
            f"{row['volume_change']:.2e}, q {row['min_quality']:.3f}, cells {row['cells']}, "
            f"remeshes {len(sim.remeshes)}, {row['newton_iterations']} its, {wall:.1f} s",
            flush=True)
        if row["remeshed"] or mesh_pic is None:
            mesh_pic = (top_mesh(s), s.centring.center.copy(), sim.t)
    wall = time.perf_counter() - t0
    summary = summarize(case, rows, sim.remeshes, wall)
    if comm.rank == 0:
        for line in summary:
            print(line)
        os.makedirs(out, exist_ok=True)
        with open(os.path.join(out, "remesh_ring.csv"), "w", newline="") as fh:
            wr = csv.DictWriter(fh, fieldnames=list(rows[0]))
            wr.writeheader()
            wr.writerows(rows)
        picture(case, rows, sim.remeshes, mesh_pic, s, os.path.join(out, "remesh_ring.png"))
        print("written", out)
    sim.close()
    return rows


def summarize(case, rows, remeshes, wall):
    revs = rows[-1]["revolutions"]
    lines = [f"{len(rows)} increments, {revs:.3f} revolutions, {len(remeshes)} remeshes "
             f"({sum(r.reason.startswith('the bites') for r in remeshes)} at the start, "
             f"{sum('spanned by' in r.reason for r in remeshes)} on the coverage, "
             f"{sum('quality' in r.reason for r in remeshes)} on the quality, "
             f"{sum('inver' in r.reason for r in remeshes)} rescues), cells after a remesh "
             f"{min(r.cells_after for r in remeshes) if remeshes else 0}–"
             f"{max(r.cells_after for r in remeshes) if remeshes else 0}"]
    for k in ("main_roll", "mandrel"):
        a = np.array([q[f"across_{k}"] for q in rows])
        c = np.array([q[f"criterion_across_{k}"] for q in rows])
        arc = np.array([q[f"arc_{k}"] for q in rows])
        lines.append(f"{k}: elements across the bite min {np.nanmin(a):.2f}, median "
                     f"{np.nanmedian(a):.2f} (criterion's measure min {np.nanmin(c):.2f}, "
                     f"median {np.nanmedian(c):.2f}); contact arc median {np.nanmedian(arc):.2f} "
                     f"mm (L = {ring_mill.bite_length(case):.2f})")
    F = np.array([abs(q["main_force_x"]) for q in rows])
    rem = np.array([q["remesh"] for q in rows])
    second = np.array([q["revolutions"] > 0.5 * revs for q in rows])
    jump = np.abs(np.diff(F))
    at = rem[1:] != rem[:-1]
    quiet = ~at & second[1:]
    at2 = at & second[1:]
    if quiet.any() and at2.any():
        lines.append(f"main roll force, second half: mean {np.mean(F[second]) / 1e3:.2f} kN; "
                     f"change between two increments without a remesh max "
                     f"{np.max(jump[quiet]) / 1e3:.2f} kN (median "
                     f"{np.median(jump[quiet]) / 1e3:.2f}); at a remesh max "
                     f"{np.max(jump[at2]) / 1e3:.2f} kN (median {np.median(jump[at2]) / 1e3:.2f})")
    lines.append(f"volume change: last {rows[-1]['volume_change']:.2e}, max |.| "
                 f"{max(abs(q['volume_change']) for q in rows):.2e}; min quality "
                 f"{min(q['min_quality'] for q in rows):.3f}; remesh volume change max "
                 f"{max((abs(r.volume_change) for r in remeshes), default=0):.1e}")
    lines.append(f"wall {wall:.0f} s = {wall / max(revs, 1e-9):.0f} s per revolution; "
                 f"remeshes {sum(r.wall for r in remeshes):.0f} s "
                 f"({np.mean([r.wall for r in remeshes]) if remeshes else 0:.1f} s each); "
                 f"Newton its per increment {np.mean([q['newton_iterations'] for q in rows]):.1f}")
    return lines


def picture(case, rows, remeshes, mesh_pic, s, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.collections import PolyCollection
    rev = np.array([q["revolutions"] for q in rows])
    rem = np.array([q["remesh"] for q in rows])
    at = [rev[i] for i in range(1, len(rows)) if rem[i] != rem[i - 1]]
    fig = plt.figure(figsize=(14, 9))
    ax = fig.add_subplot(2, 2, 1)
    T, c, t = mesh_pic
    ax.add_collection(PolyCollection(T, facecolor="none", edgecolor="C0", linewidth=0.3))
    for tl, rad in zip(s.tools[:4], (case.R1, case.R2, case.Rg, case.Rg)):
        x, y = tl.motion.axis_point_at(t)[:2]
        th = np.linspace(0, 2 * np.pi, 400)
        ax.fill(x + rad * np.cos(th), y + rad * np.sin(th), color="0.7", alpha=0.6)
        if tl.name in ("main_roll", "mandrel"):
            ax.annotate(tl.name.replace("_", " "), (min(x - 0.5 * rad, c[0] + 1.2 * case.R),
                                                    y + 0.3 * rad), fontsize=8)
    ax.plot(*c[:2], "r+")
    ax.set_xlim(c[0] - 1.1 * case.R, c[0] + 1.5 * case.R)
    ax.set_ylim(c[1] - 1.1 * case.R, c[1] + 1.1 * case.R)
    ax.set_aspect("equal")
    ax.set_title(f"top face after the last remesh (t = {t:.2f} s, {t / case.t_rev:.2f} rev):\n"
                 f"the ring turns counterclockwise, the fine arc lies in front of the gap",
                 fontsize=9)
    ax.set_xlabel("x [mm] (mill line)", fontsize=8)
    ax = fig.add_subplot(2, 2, 2)
    ax.plot(rev, [q["main_force_x"] / 1e3 for q in rows], ".-", ms=3, lw=0.8,
            label="main roll radial force")
    for r in at:
        ax.axvline(r, color="0.8", lw=0.5, zorder=0)
    ax.set_xlabel("revolutions")
    ax.set_ylabel("force [kN] (whole ring)")
    ax.set_title("main roll force; grey lines: remeshes", fontsize=9)
    lo, hi = np.percentile([q["main_force_x"] / 1e3 for q in rows], [1, 100])
    ax.set_ylim(lo - 0.1 * (hi - lo), hi + 0.1 * (hi - lo))   # the first increment's peak
    # (the initial bite pressed out) may lie above
    ax.legend(fontsize=8)
    ax = fig.add_subplot(2, 2, 3)
    for k, st in (("main_roll", "C0"), ("mandrel", "C1")):
        ax.plot(rev, [q[f"across_{k}"] for q in rows], ".-", color=st, ms=3, lw=0.8,
                label=f"{k.replace('_', ' ')}: contact arc / mean edge")
        ax.plot(rev, [q[f"criterion_across_{k}"] for q in rows], ":", color=st, lw=0.8,
                label=f"{k.replace('_', ' ')}: the criterion's 2√3σ / mean edge")
    if case.remesh_min_across:
        ax.axhline(case.remesh_min_across, color="k", ls="--", lw=0.8, label="asked for")
    ax.set_xlabel("revolutions")
    ax.set_ylabel("elements across the bite")
    ax.set_ylim(bottom=0)
    ax.legend(fontsize=7)
    ax = fig.add_subplot(2, 2, 4)
    ax.plot(rev, [100 * q["volume_change"] for q in rows], "-", label="V/V0 - 1 [%]")
    ax.plot(rev, [q["min_quality"] for q in rows], "-", label="min cell quality")
    ax.plot(rev, [q["cells"] / 1e4 for q in rows], "-", label="cells / 10^4")
    ax.set_xlabel("revolutions")
    ax.legend(fontsize=8)
    ax.set_title(f"{len(remeshes)} remeshes", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def main():
    parser = case_parser(RingRollingCase, __doc__.split("\n")[0], "benchmarks/results/remesh_ring")
    parser.set_defaults(quick=True)
    case, args = parse_case(parser, RingRollingCase)
    given = {k: v for k, v in DEFAULTS.items() if getattr(args, k) is None}
    import dataclasses
    case = dataclasses.replace(case, **given)
    if not case.remesh_min_across:
        case = dataclasses.replace(case, remesh_min_across=None)
    run(case, MPI.COMM_WORLD, args.output_dir)


if __name__ == "__main__":
    main()
