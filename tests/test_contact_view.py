"""The public per-node view of a contact (``NodalContact.nodes``, :class:`ContactNodes`): the
contact's own arrays of the last evaluation, read-only, rank-local, consistent with the history
columns (tool forces, penetrations), a snapshot that later evaluations do not change."""

import numpy as np
import pytest
from mpi4py import MPI

import fxcontact as fx
from fxcontact.contact.boundary import ContactBoundary
from fxcontact.contact.friction import Coulomb
from fxcontact.contact.nodal import NodalContact
from fxcontact.contact.view import ContactNodes
from fxcontact.materials import NortonHoff
from fxcontact.meshing import BLOCK_TAGS, block
from fxcontact.simulation import Simulation
from fxcontact.spaces import MixedSpace
from fxcontact.tools.analytic import Plane

from helpers import gather_by_position

ARRAYS = ("vertices", "dofs", "area", "positions", "point", "normal", "h", "grad_h", "force",
          "friction_force", "tool", "gap", "active", "pressure")


def _pressed_block(comm):
    """A Norton–Hoff block (2D, 4 × 2 mm) pressed by a plane die at 0.5 mm/s, with Coulomb
    friction on the die."""
    msh, _, ft = block(comm, [0.0, 0.0], [4.0, 2.0], 0.4, dim=2)
    sp = MixedSpace(msh)
    sim = Simulation(sp, NortonHoff(10.0, 0.3, regularization=1e-4), progress=False)
    sim.add_velocity_bc(sim.facets(ft, BLOCK_TAGS["ymin"]), 0.0, 1)
    sim.add_velocity_bc(sim.facets(ft, BLOCK_TAGS["xmin"]), 0.0, 0)
    die = Plane((0.0, 2.0, 0.0), (0.0, -1.0, 0.0), velocity=(0.0, -0.5, 0.0), name="die")
    c = sim.add_contributor(NodalContact(ContactBoundary(sp, ft, BLOCK_TAGS["ymax"]), die,
                                         penalty=1e3, friction=Coulomb(0.2),
                                         slip_velocity=0.05))
    return sim, c


def test_contact_view_is_the_contact_state():
    comm = MPI.COMM_WORLD
    sim, c = _pressed_block(comm)
    # before the first evaluation: the nodes, zero state
    nv0 = c.nodes
    assert isinstance(nv0, ContactNodes) and len(nv0) == len(c.boundary)
    assert not np.any(nv0.h) and not np.any(nv0.force) and not np.any(nv0.active)
    sim.step(0.1)
    first = c.nodes
    h_first = first.h.copy()
    row = sim.step(0.1).row
    nv = c.nodes
    assert nv is c.nodes and nv is not first
    # the contact's own arrays, not copies, and the boundary's nodes in its order
    for name, own in (("h", c._h), ("grad_h", c._g), ("tool", c._tool), ("point", c._point),
                      ("force", c._r), ("friction_force", c._rf),
                      ("vertices", c.boundary.vertices), ("dofs", c.boundary.dofs),
                      ("area", c.boundary.areas)):
        arr = getattr(nv, name)
        assert arr.shape == own.shape and np.shares_memory(arr, own), name
        assert np.array_equal(arr, own), name
    assert np.array_equal(nv.pressure, c.pressures())
    assert nv.tool_names == ("die",) and nv.dt == 0.1
    # read-only, the contact's arrays still writable (the library writes its own state)
    for name in ARRAYS:
        arr = getattr(nv, name)
        assert not arr.flags.writeable, name
        with pytest.raises(ValueError, match="read-only"):
            arr[...] = 0
    assert c._h.flags.writeable and c._r.flags.writeable
    with pytest.raises(AttributeError):
        nv.h = np.zeros(3)
    # a snapshot: the second increment did not change the first one's view
    assert np.array_equal(first.h, h_first) and not np.array_equal(first.h, nv.h)

    # forces: the history's die force is the sum of the nodal forces over the ranks
    act = nv.active
    assert comm.allreduce(int(np.sum(act)), op=MPI.SUM) == row["contact_nodes"] > 0
    F = comm.allreduce(np.sum(nv.force + nv.friction_force, axis=0), op=MPI.SUM)
    Ff = comm.allreduce(np.sum(nv.friction_force, axis=0), op=MPI.SUM)
    for j, x in enumerate("xy"):
        assert abs(F[j] - row[f"die_force_{x}"]) <= 1e-12 * np.linalg.norm(F), (x, F, row)
        assert abs(Ff[j] - row[f"die_friction_{x}"]) <= 1e-12 * np.linalg.norm(F), (x, Ff)
    assert F[1] > 0 and np.linalg.norm(Ff) > 0       # the body pushes the die up, and slides
    # the normal force is −S p n, zero out of contact; the friction force is tangential
    assert np.allclose(nv.force, -(nv.area * nv.pressure)[:, None] * nv.normal,
                       rtol=1e-13, atol=1e-13 * abs(F[1]))
    assert not np.any(nv.force[~act]) and not np.any(nv.friction_force[~act])
    assert np.allclose(np.einsum("ni,ni->n", nv.friction_force, nv.normal), 0.0,
                       atol=1e-12 * abs(F[1]))
    assert np.allclose(nv.normal, [0.0, -1.0])
    # gaps (mm, negative: penetration): −dt h, the distance to the die along its normal at
    # the end-of-increment positions, which the accepted increment gave the mesh
    assert np.array_equal(act, nv.gap < 0) and np.array_equal(nv.gap, -0.1 * nv.h)
    X = sim.vertex_positions()[nv.vertices]
    scale = 1e-12 * 4.0
    assert np.allclose(nv.positions, X, rtol=0.0, atol=scale)
    assert np.allclose(nv.point[:, 1], 2.0 - 0.2 * 0.5, rtol=0.0, atol=scale)   # die at t + dt
    assert np.allclose(nv.point[:, :2] + nv.gap[:, None] * nv.normal, nv.positions,
                       rtol=0.0, atol=scale)
    pen = comm.allreduce(float(np.max(-nv.gap, initial=-np.inf)), op=MPI.MAX)
    assert pen == row["contact_penetration_predicted"] > 0
    assert abs(pen - row["contact_penetration_true"]) <= 1e-9 * pen
    # rank-local: every contact vertex in the view of exactly one rank
    n_all = comm.allreduce(len(nv), op=MPI.SUM)
    assert n_all == len(gather_by_position(comm, nv.positions, nv.h)[0])
    assert "die" in repr(nv) and fx.ContactNodes is ContactNodes
