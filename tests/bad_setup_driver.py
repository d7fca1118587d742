"""Set-ups that used to crash (SIGSEGV in the assembly) or hang (one rank raising, the other
waiting), run as a subprocess (serial or under mpirun) by ``test_bad_inputs.py``.

    python bad_setup_driver.py CASE OUT

Each rank writes ``OUT/rank<r>.txt``: ``<exception class>: <message>`` (or ``none`` if nothing
was raised), and the process ends normally; a crash or a hang is seen by the test.
"""

import os
import sys

import numpy as np
from mpi4py import MPI

import dolfinx

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import fxcontact as fx  # noqa: E402
from helpers import box_mesh  # noqa: E402

COMM = MPI.COMM_WORLD
RANK = COMM.rank


def _cube(n=2):
    """A unit cube with its faces z = 0 (tag 3) and z = 1 (tag 4) tagged."""
    msh = box_mesh(COMM, n=(n, n, n))
    loc = dolfinx.mesh.locate_entities_boundary
    f3 = loc(msh, 2, lambda x: np.isclose(x[2], 0.0))
    f4 = loc(msh, 2, lambda x: np.isclose(x[2], 1.0))
    idx = np.r_[f3, f4]
    val = np.r_[np.full(len(f3), 3, np.int32), np.full(len(f4), 4, np.int32)]
    order = np.argsort(idx)
    return msh, dolfinx.mesh.meshtags(msh, 2, idx[order].astype(np.int32), val[order])


def _die(vz=-0.1):
    return fx.Plane((0, 0, 1.0), (0, 0, -1), velocity=(0, 0, vz), name="die")


def _sim(msh):
    return fx.Simulation(fx.MixedSpace(msh), fx.NortonHoff(1.0, 0.2), progress=False)


def _pressed(msh, ft, sim=None):
    sim = sim or _sim(msh)
    sim.add_velocity_bc(sim.facets(ft, 3), 0.0)
    return sim


def case(name):
    msh, ft = _cube()
    other, ft_other = _cube(5)          # a finer mesh: more facets than this one
    if name == "contact-facet-tags-of-another-mesh":
        fx.ContactBoundary(fx.MixedSpace(msh), ft_other, 4)
    elif name == "facets-tags-of-another-mesh":
        _sim(msh).facets(ft_other, 4)
    elif name == "bc-facets-of-another-mesh":
        _sim(msh).add_velocity_bc(ft_other.indices, 0.0, 2)
    elif name == "reaction-facets-of-another-mesh":
        _sim(msh).add_reaction("base", ft_other.indices)
    elif name == "symmetry-plane-interior-facets":
        msh.topology.create_connectivity(2, 3)
        ext = dolfinx.mesh.exterior_facet_indices(msh.topology)
        n = msh.topology.index_map(2).size_local
        inner = np.setdiff1d(np.arange(n, dtype=np.int32), ext)
        _sim(msh).add_symmetry_plane(inner, (1.0, 0.0, 0.0), name="sym")
    # set-ups that differ between ranks
    elif name == "contributor-added-on-one-rank":
        sim = _pressed(msh, ft)
        contact = fx.NodalContact(fx.ContactBoundary(sim.space, ft, 4), _die(), penalty=10.0)
        if RANK == 0:
            sim.add_contributor(contact)
        sim.run(0.1, 0.1)
    elif name == "contact-created-on-one-rank":
        sim = _pressed(msh, ft)
        if RANK == 0:
            sim.add_contributor(fx.NodalContact(fx.ContactBoundary(sim.space, ft, 4), _die(),
                                                penalty=10.0))
        sim.run(0.1, 0.1)
    elif name == "tool-none-on-one-rank":
        sim = _pressed(msh, ft)
        fx.NodalContact(fx.ContactBoundary(sim.space, ft, 4), _die() if RANK == 0 else None)
    elif name == "tool-parameters-differ":
        sim = _pressed(msh, ft)
        sim.add_contributor(fx.NodalContact(fx.ContactBoundary(sim.space, ft, 4),
                                            _die(-0.1 - 0.1 * RANK), penalty=10.0))
        sim.run(0.1, 0.1)
    elif name == "dt-differs":
        _pressed(msh, ft).run(0.2, 0.1 / (1 + RANK))
    elif name == "bc-added-on-one-rank":
        sim = _pressed(msh, ft)
        if RANK == 0:
            sim.add_velocity_bc(sim.facets(ft, 4), -0.1, 2)
        sim.run(0.1, 0.1)
    else:
        raise SystemExit(f"unknown case {name}")


if __name__ == "__main__":
    try:
        case(sys.argv[1])
        out = "none"
    except Exception as e:  # noqa: BLE001 - the test checks the class and the message
        out = f"{type(e).__name__}: {e}"
    with open(os.path.join(sys.argv[2], f"rank{RANK}.txt"), "w") as fh:
        fh.write(out)
