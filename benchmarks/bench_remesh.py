"""Cost of one remesh of a running simulation, phase by phase, against one of its increments.

Usage::

    python benchmarks/bench_remesh.py                       # ~8k and ~140k MINI dofs
    mpirun -n 2 python benchmarks/bench_remesh.py --sizes 1.55
    python benchmarks/bench_remesh.py --sizes 1.55 --profile    # where the remesh goes
    python benchmarks/bench_remesh.py --sizes 1.55 0.8 --generate   # gmsh's fields vs callback

Problem: the quarter billet of ``fxcontact.meshing.cylinder_billet`` (R 10, H 15, element size
h) upset by a flat die (5 mm/s, Tresca m̄ 0.3, dt 0.06 s) with its symmetry planes, a velocity
condition and a reaction, as in ``tests/test_remesh_simulation.py``. Two increments (the first
builds the forms and makes the start-up solve), a third one timed, then ``Simulation.remesh()``
at the same size h, then two more increments timed. Printed (max over the ranks): the remesh's
phases (``RemeshRecord.phases``: ``boundary`` gathered on rank 0, ``generate`` gmsh,
``distribute`` the new mesh, ``spaces``, ``transfer`` of the state, ``rebind`` conditions and
contributors, ``setup`` forms and solver), the increments before and after it (wall, Newton
iterations), and the remesh's cost in increments. ``--profile``: the remesh under cProfile
(rank 0), the functions with the largest cumulative time. ``--generate``: after the run, the
new mesh's boundary remeshed by ``volume_mesh`` with two size zones at the top (h/2 at the die's
edge, points on the circle r = R·1.05, z = H at that time, and h/2 in a box 1.5h thick under the
die), alternately with gmsh's fields, with the Python size callback and without the surface
smoothing, twice each: the ``generate`` times (median) and cells; then the same for a ring
rolling remesh (the whole ring 100/70 × 40, upper half, h 8, the points of a bite zone of size
3.9 over 90° in front of the gap, as ``ring_mill.BiteZones`` makes). Timings are printed only.
"""

from __future__ import annotations

import argparse
import cProfile
import io
import pstats
import time

from mpi4py import MPI

import fxcontact as fx

DT = 0.06


def upsetting(comm, h):
    """The billet upset by a flat die (the set-up of tests/test_remesh_simulation.py)."""
    msh, _, ft = fx.cylinder_billet(comm, radius=10.0, height=15.0, h=h)
    space = fx.MixedSpace(msh)
    sim = fx.Simulation(space, fx.NortonHoff(K=50.0, m=0.15), name="upset", progress=False)
    f = {k: sim.facets(ft, v) for k, v in fx.BILLET_TAGS.items()}
    sim.add_velocity_bc(f["symmetry_x"], 0.0, component=0)
    sim.add_symmetry_plane(f["symmetry_y"], (0, 1, 0), name="sym_y")
    sim.add_velocity_bc(f["bottom"], 0.0, component=2)
    sim.add_reaction("bottom", f["bottom"])
    die = fx.Plane(point=(0, 0, 15.0), normal=(0, 0, -1), velocity=(0, 0, -5.0), name="die")
    sim.add_contributor(fx.NodalContact(fx.ContactBoundary(space, ft, fx.BILLET_TAGS["top"]),
                                        die, friction=fx.Tresca(0.3)))
    return sim


def run(comm, h, profile=False):
    say = print if comm.rank == 0 else (lambda *a, **k: None)
    sim = upsetting(comm, h)
    dofs0 = sim.space.global_dofs()
    for _ in range(2):
        sim.step(DT)

    def increment():
        comm.barrier()
        t0 = time.perf_counter()
        row = sim.step(DT).row
        return comm.allreduce(time.perf_counter() - t0, op=MPI.MAX), row["newton_iterations"]

    before = increment()
    prof = cProfile.Profile() if profile and comm.rank == 0 else None
    comm.barrier()
    t0 = time.perf_counter()
    if prof is not None:
        prof.enable()
    rec = sim.remesh(size=h)
    if prof is not None:
        prof.disable()
    wall = comm.allreduce(time.perf_counter() - t0, op=MPI.MAX)
    phases = {k: comm.allreduce(v, op=MPI.MAX) for k, v in rec.phases.items()}
    after = [increment() for _ in range(2)]
    say(f"h = {h:g}: {dofs0} dofs, {rec.cells_before} cells -> {sim.space.global_dofs()} "
        f"dofs, {rec.cells_after} cells, {comm.size} rank(s)")
    say(f"  increment before: {before[0]:.2f} s ({before[1]} Newton its); after: "
        + ", ".join(f"{w:.2f} s ({n} its)" for w, n in after))
    say(f"  remesh {wall:.2f} s = {wall / before[0]:.2f} increments: "
        + ", ".join(f"{k} {v:.2f}" for k, v in phases.items())
        + f" (other {wall - sum(phases.values()):.2f})")
    if prof is not None:
        out = io.StringIO()
        pstats.Stats(prof, stream=out).sort_stats("cumulative").print_stats(25)
        say(out.getvalue())
    return sim


def generate_variants(comm, surface, h, zones, label, repeat=2):
    """The ``generate`` time of ``volume_mesh`` on ``surface`` with ``zones``: gmsh's fields,
    the Python size callback, the fields without the surface smoothing (``--generate``)."""
    import numpy as np

    from fxcontact.remesh import volume
    say = print if comm.rank == 0 else (lambda *a, **k: None)
    variants = {"fields": (False, True), "callback": (True, True),
                "fields, no smoothing": (False, False)}
    times = {k: [] for k in variants}
    cells = {}
    for _ in range(repeat):
        for name, (callback, smooth) in variants.items():
            volume.SIZE_CALLBACK = callback
            t = {}
            msh, _, _ = volume.volume_mesh(comm, surface, h, zones, times=t, smooth=smooth)
            times[name].append(comm.allreduce(t["generate"], op=MPI.MAX))
            cells[name] = msh.topology.index_map(3).size_global
    volume.SIZE_CALLBACK = False
    say(f"  {label}, generate: " + ", ".join(
        f"{k} {np.median(v):.2f} s ({cells[k]} cells)" for k, v in times.items()))


def billet_zones(comm, sim, h):
    """The boundary of the simulation's mesh and two zones at the die: h/2 at its edge (points
    on r = 10.5 at the top) and h/2 in a box 1.5 h thick under it."""
    import numpy as np

    from fxcontact.remesh.surface import gather_boundary
    from fxcontact.remesh.volume import SizeZone
    surface = gather_boundary(sim.mesh, sim.contributors[0].boundary.facet_tags)
    top = comm.allreduce(float(sim.mesh.geometry.x[:, 2].max()), op=MPI.MAX)
    th = np.linspace(0.0, np.pi / 2, 60)
    rim = np.c_[10.5 * np.cos(th), 10.5 * np.sin(th), np.full_like(th, top)]
    return surface, [SizeZone(h=h / 2, points=rim, grading=0.3),
                     SizeZone(h=h / 2, box=([0, 0, top - 1.5 * h], [12, 12, top]), grading=0.3)]


def ring_zones(comm, h=8.0, h_zone=3.9):
    """A ring rolling remesh's set-up: the whole ring (radii 100 and 70, height 40, the upper
    half), size h, and the points of a ring_mill.BiteZones over the 90° arc in front of the gap
    (a grid of spacing h_zone through the wall)."""
    import numpy as np

    from fxcontact.remesh.surface import gather_boundary
    from fxcontact.remesh.volume import SizeZone
    msh, _, ft = fx.ring(comm, 100.0, 70.0, 40.0, h, sector="upper")
    th = np.linspace(-0.5 * np.pi, 0.1, int(np.ceil((0.5 * np.pi + 0.1) * 100 / h_zone)) + 1)
    r = np.linspace(70.0, 100.0, int(np.ceil(30 / h_zone)) + 1)
    z = np.linspace(0.0, 20.0, int(np.ceil(20 / h_zone)) + 1)
    T, P, Z = np.meshgrid(th, r, z, indexing="ij")
    pts = np.c_[(P * np.cos(T)).ravel(), (P * np.sin(T)).ravel(), Z.ravel()]
    return gather_boundary(msh, ft), [SizeZone(h=h_zone, points=pts)]


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sizes", type=float, nargs="+", default=[1.55, 0.54],
                    help="element sizes (1.55: 7,851 dofs, 0.54: 138,736 dofs)")
    ap.add_argument("--profile", action="store_true", help="cProfile of the remesh (rank 0)")
    ap.add_argument("--generate", action="store_true",
                    help="then volume_mesh with zones: gmsh's fields vs the size callback")
    args = ap.parse_args()
    comm = MPI.COMM_WORLD
    for h in args.sizes:
        sim = run(comm, h, args.profile)
        if args.generate:
            surface, zones = billet_zones(comm, sim, h)
            generate_variants(comm, surface, h, zones, "volume_mesh with 2 zones (h/2)")
    if args.generate:
        surface, zones = ring_zones(comm)
        generate_variants(comm, surface, 8.0, zones,
                          f"ring 100/70 x 40 (upper half), h 8, bite zone h 3.9 "
                          f"({len(zones[0].points)} points)")


if __name__ == "__main__":
    main()
