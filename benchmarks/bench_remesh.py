"""Cost of one remesh: boundary gather, mesh generation + distribution, field transfer.

Usage::

    python benchmarks/bench_remesh.py                  # ~10k and ~150k MINI dofs
    mpirun -n 2 python benchmarks/bench_remesh.py --sizes 2.0

Problem: the quarter billet of ``fxcontact.meshing.cylinder_billet`` (R 10, H 15) barrelled and
sheared, remeshed at the same element size h with a zone of size h/2 under the top die. Timed
(max over ranks): ``boundary`` (:func:`fxcontact.remesh.boundary.gather_boundary`), ``mesh``
(:func:`fxcontact.remesh.volume.volume_mesh`: gmsh on rank 0 and the distribution),
``spaces`` (the new ``MixedSpace``), ``transfer`` (the Simulation state: MINI velocity,
pressure, strain and strain rate, :func:`fxcontact.remesh.state.transfer_simulation_state`,
without the JIT compilation of the old Simulation's forms). Timings are printed only.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from mpi4py import MPI

import fxcontact as fx
from fxcontact.remesh.boundary import gather_boundary
from fxcontact.remesh.state import transfer_simulation_state
from fxcontact.remesh.volume import SizeZone, volume_mesh


def deformed_billet(comm, h):
    msh, _, ft = fx.cylinder_billet(comm, radius=10.0, height=15.0, h=h)
    x = msh.geometry.x
    z = x[:, 2].copy()
    s = 1.0 + 0.15 * np.sin(np.pi * z / 15.0)
    x[:, 0] = s * x[:, 0] + 0.08 * z
    x[:, 1] *= s
    x[:, 2] = 0.8 * z
    return msh, ft


def run(comm, h):
    msh, ft = deformed_billet(comm, h)
    sim = fx.Simulation(fx.MixedSpace(msh), fx.NortonHoff(K=50.0, m=0.15), progress=False)
    sim.initial_volume   # the forms compiled here, not in the timing
    sp = sim.space
    sim.w_prev.x.array[:] = np.sin(np.arange(len(sim.w_prev.x.array)))
    sim.strain.x.array[:] = 1.0
    times = {}

    def timed(name, fn):
        comm.barrier()
        t0 = time.perf_counter()
        out = fn()
        times[name] = comm.allreduce(time.perf_counter() - t0, op=MPI.MAX)
        return out

    surface = timed("boundary", lambda: gather_boundary(msh, ft))
    zone = SizeZone(h=0.5 * h, box=([0.0, 0.0, 11.0], [14.0, 14.0, 12.5]), grading=0.3)
    new, _, _ = timed("mesh", lambda: volume_mesh(comm, surface, h=h, zones=[zone]))
    space = timed("spaces", lambda: fx.MixedSpace(new))
    timed("transfer", lambda: transfer_simulation_state(sim, space))
    if comm.rank == 0:
        print(f"h = {h:g}: old {sp.global_dofs()} dofs, new {space.global_dofs()} dofs, "
              f"{comm.size} rank(s): " + ", ".join(f"{k} {v:.2f} s" for k, v in times.items()),
              flush=True)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sizes", type=float, nargs="+", default=[1.55, 0.62],
                    help="element sizes (1.55: ~10k dofs, 0.62: ~150k dofs)")
    args = ap.parse_args()
    for h in args.sizes:
        run(MPI.COMM_WORLD, h)


if __name__ == "__main__":
    main()
