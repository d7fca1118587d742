"""A small forming run for the checkpoint tests, run as a subprocess (serial or under mpirun).

    python checkpoint_driver.py OUT MODE [--pause-after N]

MODE ``full`` runs to the end; ``resume`` resumes from the newest checkpoint in OUT first. With
``--pause-after N`` the run writes ``OUT/paused`` after increment N and sleeps (the test kills it
there); with ``--die-writing N`` it kills itself (SIGKILL) while writing its N-th checkpoint. At the end, rank 0 writes ``OUT/final.npz``: the vertex velocities, pressures and
positions keyed by the initial vertex positions, the cell strains keyed by the initial cell
centroids.

The problem: a Norton–Hoff block pressed by a plane die with explicit Coulomb friction
(pressures of the previous increment), a penalty resolved from β at the first increment, nodal
springs on a side face, checkpoints every 2 increments, an increment cut back once.
"""

import argparse
import os
import sys
import time

import numpy as np
from mpi4py import MPI

import dolfinx

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import fxcontact as fx  # noqa: E402
import fxcontact.compat  # noqa: E402,F401
from helpers import box_mesh  # noqa: E402


class CutOnce:
    """Stateless contributor that refuses increment 3 with the full dt: the run cuts back there,
    so the step-size state after a cut-back is checkpointed too."""

    def __init__(self):
        self.sim, self.dt = None, 0.0

    def begin_increment(self, sim, t, dt, x):
        self.sim, self.dt = sim, dt

    def evaluate(self, w, jacobian):
        if self.sim.increment == 2 and self.dt > 0.06:
            raise fx.ContributorError("increment 3 refused with dt > 0.06")
        return fx.NodalTerms.empty(3)

    def stable(self):
        return True

    def checkpoint_state(self):
        return {}


def build(out, comm=MPI.COMM_WORLD, perturb=0.1):
    L = (1.0, 1.0, 1.0)
    msh = box_mesh(comm, L, (3, 3, 3), perturb=perturb)
    fdim = 2
    loc = dolfinx.mesh.locate_entities_boundary
    faces = {1: loc(msh, fdim, lambda x: np.isclose(x[0], 0.0)),
             2: loc(msh, fdim, lambda x: np.isclose(x[1], 0.0)),
             3: loc(msh, fdim, lambda x: np.isclose(x[2], 0.0)),
             4: loc(msh, fdim, lambda x: np.isclose(x[2], 1.0)),
             5: loc(msh, fdim, lambda x: np.isclose(x[0], 1.0))}
    idx = np.concatenate(list(faces.values()))
    val = np.concatenate([np.full(len(f), k, np.int32) for k, f in faces.items()])
    order = np.argsort(idx)
    ft = dolfinx.mesh.meshtags(msh, fdim, idx[order].astype(np.int32), val[order])
    space = fx.MixedSpace(msh)
    sim = fx.Simulation(space, fx.NortonHoff(K=10.0, m=0.2, regularization=1e-4),
                        output_dir=out, name="press", progress=False, checkpoint_every=2,
                        solver_options=fx.SolverOptions(max_it=12))
    sim.add_velocity_bc(sim.facets(ft, 1), 0.0, 0)
    sim.add_velocity_bc(sim.facets(ft, 2), 0.0, 1)
    sim.add_velocity_bc(sim.facets(ft, 3), 0.0, 2)
    die = fx.Plane((0, 0, 1.0), (0, 0, -1), velocity=(0.02, 0, -0.2), name="die")
    sim.add_contributor(fx.NodalContact(fx.ContactBoundary(space, ft, 4), die, beta=100.0,
                                        scheme="implicit", friction=fx.Coulomb(0.2),
                                        friction_mode="explicit"))
    sim.add_contributor(fx.NodalSprings(fx.ContactBoundary(space, ft, 5), stiffness=0.5))
    sim.add_contributor(CutOnce())
    return sim


def dump(sim, path):
    sp = sim.space
    own = sp.vertex_owned
    x0 = sim._x_ref[sp.vertex_geometry][own]
    c2v = fx.compat.cell_vertices(sim.mesh)
    v2p = np.empty(len(own), dtype=np.int64)   # vertex -> W dof of the pressure
    v2p[c2v.ravel()] = fx.compat.dofmap_array(sp.W.sub(1))[:, : c2v.shape[1]].ravel()
    vals = np.c_[sim.w.x.array[sp.vertex_dofs[own]], sim.w.x.array[v2p[own]],
                 sim.vertex_positions()[own]]
    nc = sim.mesh.topology.index_map(3).size_local
    c0 = sim._x_ref[:, :3][dolfinx.cpp.mesh.entities_to_geometry(
        sim.mesh._mesh, 3, np.arange(nc, dtype=np.int32), False)].mean(axis=1)
    cv = sim.strain.x.array[:nc]
    data = sim.comm.gather((x0, vals, c0, cv), root=0)
    if sim.comm.rank == 0:
        x0, vals, c0, cv = (np.concatenate([d[k] for d in data]) for k in range(4))
        o1 = np.lexsort(np.round(x0, 9).T[::-1])
        o2 = np.lexsort(np.round(c0, 9).T[::-1])
        np.savez(path, x0=x0[o1], vertex=vals[o1], c0=c0[o2], strain=cv[o2],
                 history=np.array([[r[k] for k in sorted(r)] for r in sim.history]),
                 keys=np.array(sorted(sim.history[-1])))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("out")
    ap.add_argument("mode", choices=["full", "resume"])
    ap.add_argument("--pause-after", type=int, default=0)
    ap.add_argument("--die-writing", type=int, default=0)
    a = ap.parse_args()
    if a.die_writing:
        # SIGKILL this process in the middle of writing checkpoint number N: its rank file is
        # in the temporary directory, the manifest and the rename are not done
        import signal
        import fxcontact.checkpoint as ck
        savez, count = np.savez, []

        def savez_and_die(fh, **arrays):
            savez(fh, **arrays)
            count.append(1)
            if len(count) == a.die_writing:
                fh.flush()
                os.kill(os.getpid(), signal.SIGKILL)

        ck.np.savez = savez_and_die
    sim = build(a.out)
    if a.mode == "resume":
        sim.resume()

    def pause(s, res):
        if a.pause_after and s.increment == a.pause_after:
            s.comm.barrier()
            if s.comm.rank == 0:
                open(os.path.join(a.out, "paused"), "w").close()
            time.sleep(600)

    sim.run(0.8, 0.1, max_cutbacks=3, callback=pause)
    dump(sim, os.path.join(a.out, "final.npz"))


if __name__ == "__main__":
    main()
