"""The Newton solver's nodal hook: nodal springs equal the same springs written as a UFL form."""

import numpy as np
import pytest
import ufl
from mpi4py import MPI

import dolfinx

from petsc4py import PETSc

import dolfinx.fem.petsc
import dolfinx.nls.petsc

from fxcontact import compat
from fxcontact.contact.boundary import ContactBoundary
from fxcontact.materials import NortonHoff
from fxcontact.simulation import Simulation
from fxcontact.spaces import MixedSpace, velocity_bc
from fxcontact.contact.springs import NodalSprings, spring_kernel, spring_kernel_numpy

from helpers import box_mesh


def _mesh_and_tags(comm):
    msh = box_mesh(comm, (1.0, 0.7, 0.5), (4, 3, 3), perturb=0.2, seed=1)
    fdim = 2
    fb = dolfinx.mesh.locate_entities_boundary(msh, fdim, lambda x: np.isclose(x[2], 0.0))
    fs = dolfinx.mesh.locate_entities_boundary(msh, fdim, lambda x: np.isclose(x[0], 1.0))
    ftop = dolfinx.mesh.locate_entities_boundary(msh, fdim, lambda x: np.isclose(x[1], 0.7))
    idx = np.r_[fb, fs]
    val = np.r_[np.full(len(fb), 1, np.int32), np.full(len(fs), 2, np.int32)]
    order = np.argsort(idx)
    tags = dolfinx.mesh.meshtags(msh, fdim, idx[order], val[order])
    return msh, tags, fb, fs, ftop


MAT = NortonHoff(K=2.0, m=0.3, regularization=1e-6)
PULL = np.array([0.3, 0.2, -0.1])


class _ReferenceSprings(dolfinx.fem.petsc.NonlinearProblem):
    """Independent path: facet areas from cross products, a P1 vector for the MPI sum,
    global-index insertion, dolfinx's own NewtonSolver."""

    def __init__(self, F, w, bcs, space, facets, k, c, v0):
        super().__init__(F, w, bcs)
        self.w = w
        msh = space.mesh
        msh.topology.create_connectivity(2, 0)
        f2v = msh.topology.connectivity(2, 0)
        fv = np.array([f2v.links(f) for f in facets], dtype=np.int32).reshape(-1, 3)
        x = msh.geometry.x[space.vertex_geometry]
        area = 0.5 * np.linalg.norm(np.cross(x[fv[:, 1]] - x[fv[:, 0]],
                                             x[fv[:, 2]] - x[fv[:, 0]]), axis=1)
        Q1 = dolfinx.fem.FunctionSpace(msh, ("Lagrange", 1))
        qa = dolfinx.fem.Function(Q1)
        c2v = compat.cell_vertices(msh)
        v2q = np.empty(len(x), np.int32)
        v2q[c2v.ravel()] = compat.dofmap_array(Q1)[:, :4].ravel()
        np.add.at(qa.x.array, v2q[fv.ravel()], np.repeat(area / 3.0, 3))
        qa.vector.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        qa.x.scatter_forward()
        S = qa.x.array[v2q]
        own = np.flatnonzero((S > 0) & space.vertex_owned)
        self.S, self.dofs = S[own], space.vertex_dofs[own]
        self.k, self.c, self.v0 = k, c, v0
        self.bcdofs = np.concatenate([bc.dof_indices()[0] for bc in bcs])
        imap = space.W.dofmap.index_map
        self.l2g = imap.local_to_global(np.arange(imap.size_local + imap.num_ghosts,
                                                  dtype=np.int32))

    def F(self, x, b):
        super().F(x, b)  # includes set_bc last: springs are never on Dirichlet rows here
        v = self.w.x.array[self.dofs] - self.v0
        s2 = np.sum(v * v, axis=1)
        r = self.S[:, None] * (self.k + self.c * s2)[:, None] * v
        arr = b.getArray(readonly=False)
        free = ~np.isin(self.dofs, self.bcdofs)
        arr[self.dofs[free]] += r[free]

    def J(self, x, A):
        A.zeroEntries()
        v = self.w.x.array[self.dofs] - self.v0
        for n in range(len(self.S)):
            d = v[n]
            Kn = self.S[n] * ((self.k + self.c * d @ d) * np.eye(3) + 2 * self.c * np.outer(d, d))
            g = self.l2g[self.dofs[n]].astype(PETSc.IntType)
            if np.any(np.isin(self.dofs[n], self.bcdofs)):
                continue
            A.setValues(g, g, Kn.ravel(), addv=PETSc.InsertMode.ADD_VALUES)
        dolfinx.fem.petsc.assemble_matrix(A, self.a, bcs=self.bcs)
        A.assemble()


def _fxcontact_run(comm, k, c, v0, dt, mesh_data=None):
    msh, tags, fb, fs, ftop = mesh_data or _mesh_and_tags(comm)
    space = MixedSpace(msh)
    sim = Simulation(space, MAT, progress=False)
    sim.add_velocity_bc(fb, np.zeros(3))
    sim.add_velocity_bc(ftop, PULL)
    sim.add_contributor(NodalSprings(ContactBoundary(space, tags, 2), k, v0, cubic=c))
    sim.step(dt)
    return sim


def _reference_run(comm, k, c, v0, dt, guess, mesh_data):
    msh, tags, fb, fs, ftop = mesh_data
    space = MixedSpace(msh)
    w = dolfinx.fem.Function(space.W)
    v, p = ufl.split(w)
    wt, q = ufl.TestFunctions(space.W)
    F = MAT.residual(v, p, wt, q, space.dx, dt)
    bcs = [velocity_bc(space, fb, np.zeros(3))[0], velocity_bc(space, ftop, PULL)[0]]
    prob = _ReferenceSprings(F, w, bcs, space, fs, k, c, v0)
    solver = dolfinx.nls.petsc.NewtonSolver(comm, prob)
    solver.rtol, solver.atol, solver.max_it = 1e-12, 1e-13, 50
    ksp = solver.krylov_solver
    ksp.setType("preonly")
    ksp.getPC().setType("lu")
    ksp.getPC().setFactorSolverType("mumps")
    # plain Newton (no line search) needs a start near the solution; it converges to the root of
    # *its own* residual, so starting from a perturbed fxcontact solution keeps it independent
    w.x.array[:] = guess * (1.0 + 1e-3 * np.sin(np.arange(guess.size)))
    dolfinx.fem.petsc.set_bc(w.vector, bcs)
    w.x.scatter_forward()
    n, conv = solver.solve(w)
    assert conv and n >= 2
    return space, w


@pytest.mark.parametrize("c", [0.0, 5.0])
def test_springs_match_independent_assembly(c):
    comm = MPI.COMM_WORLD
    k, v0, dt = 3.0, np.array([0.05, -0.02, 0.01]), 0.01
    # same mesh object (same partition and dof layout); its geometry is restored after the
    # fxcontact increment moved it
    md = _mesh_and_tags(comm)
    x0 = md[0].geometry.x.copy()
    sim = _fxcontact_run(comm, k, c, v0, dt, md)
    md[0].geometry.x[:] = x0
    space, w = _reference_run(comm, k, c, v0, dt, sim.w.x.array.copy(), md)
    own = space.vertex_owned
    a = sim.w.x.array[sim.space.vertex_dofs[sim.space.vertex_owned]]
    b = w.x.array[space.vertex_dofs[own]]
    scale = comm.allreduce(np.max(np.abs(b)), op=MPI.MAX)
    err = comm.allreduce(np.max(np.abs(a - b)) if a.size else 0.0, op=MPI.MAX)
    assert err <= 1e-9 * scale, err / scale
    # the springs carry load: without them the answer is different
    sim0 = _fxcontact_run(comm, 0.0, 0.0, v0, dt)
    a0 = sim0.w.x.array[sim0.space.vertex_dofs[sim0.space.vertex_owned]]
    diff = comm.allreduce(np.max(np.abs(a0 - a)) if a.size else 0.0, op=MPI.MAX)
    assert diff > 1e-3 * scale


def test_spring_kernel_twin():
    rng = np.random.default_rng(1)
    for d in (2, 3):
        S = rng.random(20)
        v = rng.normal(size=(20, d))
        v0 = rng.normal(size=d)
        r1, K1 = spring_kernel(S, v, v0, 2.0, 3.0, True)
        r2, K2 = spring_kernel_numpy(S, v, v0, 2.0, 3.0, True)
        assert np.allclose(r1, r2, rtol=1e-14, atol=1e-14)
        assert np.allclose(K1, K2, rtol=1e-14, atol=1e-14)
        # Jacobian = finite difference of the residual
        h = 1e-6
        for a in range(d):
            dv = np.zeros_like(v)
            dv[:, a] = h
            fd = (spring_kernel_numpy(S, v + dv, v0, 2.0, 3.0, False)[0]
                  - spring_kernel_numpy(S, v - dv, v0, 2.0, 3.0, False)[0]) / (2 * h)
            assert np.allclose(fd, K1[:, :, a], rtol=1e-7, atol=1e-8)


def test_contact_boundary_areas_and_ownership():
    """Each boundary vertex is owned by exactly one rank; the areas sum to the face area."""
    comm = MPI.COMM_WORLD
    msh = box_mesh(comm, (1.0, 0.7, 0.5), (4, 3, 3), perturb=0.2, seed=1)
    space = MixedSpace(msh)
    cb = ContactBoundary(space)  # whole exterior
    assert abs(cb.total_area() - 2 * (0.7 + 0.35 + 0.5)) < 1e-12
    n = comm.allreduce(len(cb), op=MPI.SUM)
    # number of boundary vertices of a 5x4x4 vertex grid
    assert n == 5 * 4 * 4 - 3 * 2 * 2
    with pytest.raises(ValueError, match="tags"):
        ContactBoundary(space, None, 3)
    with pytest.raises(ValueError, match="mini|P1"):
        ContactBoundary(MixedSpace(msh, "taylor-hood"))
