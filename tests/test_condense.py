"""Static condensation of the MINI bubble (fxcontact.element.assembled) and the condensed solvers.

The condensed Newton step is an exact block elimination: solved by MUMPS it must equal the
uncondensed MUMPS step to round-off, on a problem where every term that could break the cell
structure of the bubble block is present: implicit nodal contact, two inclined symmetry planes
(the projection of the Newton system, THEORY §1.6), Dirichlet rows; for the Norton–Hoff power
law and for linear elasticity (velocity form). Both run serially and on 2 ranks (each run
compares the two solvers on the same communicator).
"""

import numpy as np
import pytest
from mpi4py import MPI
from petsc4py import PETSc

import dolfinx

import fxcontact as fx
from fxcontact.element.assembled import CondensationLayout
from fxcontact.newton.solver import NewtonSolver, SolverOptions
from helpers import gather_by_position, vertex_velocities_by_position

ANGLE = np.radians(30.0)
ROT = np.array([[np.cos(ANGLE), -np.sin(ANGLE), 0], [np.sin(ANGLE), np.cos(ANGLE), 0],
                [0, 0, 1.0]])


def pressed_block(material, n=4, beta=100.0, solver="mumps", prefix="fxc_", petsc_options=None,
                  contact=True, friction=None):
    """A unit cube rotated by 30° about z (its faces x'=0, y'=0 are inclined symmetry planes),
    fixed vertically at the bottom, pressed by a descending rigid plane (implicit contact).
    ``contact=False``: the top face is moved down at the die's speed instead (a velocity
    condition) and the bottom is free (no contributor: a dilatation about the top face's
    corner on the axis is then free for the velocity block)."""
    comm = MPI.COMM_WORLD
    msh = dolfinx.mesh.create_box(comm, [[0, 0, 0], [1, 1, 1]], [n, n, n],
                                  dolfinx.mesh.CellType.tetrahedron)
    loc = dolfinx.mesh.locate_entities_boundary
    faces = {1: loc(msh, 2, lambda x: np.isclose(x[0], 0.0)),
             2: loc(msh, 2, lambda x: np.isclose(x[1], 0.0)),
             3: loc(msh, 2, lambda x: np.isclose(x[2], 0.0)),
             4: loc(msh, 2, lambda x: np.isclose(x[2], 1.0))}
    idx = np.concatenate(list(faces.values()))
    val = np.concatenate([np.full(len(f), k, np.int32) for k, f in faces.items()])
    o = np.argsort(idx)
    ft = dolfinx.mesh.meshtags(msh, 2, idx[o].astype(np.int32), val[o])
    msh.geometry.x[:] = msh.geometry.x @ ROT.T
    space = fx.MixedSpace(msh)
    sim = fx.Simulation(space, material, progress=False,
                        solver_options=SolverOptions(linear_solver=solver, prefix=prefix,
                                                     petsc_options=dict(petsc_options or {})))
    sim.add_symmetry_plane(sim.facets(ft, 1), ROT @ [-1.0, 0, 0], name="p1")
    sim.add_symmetry_plane(sim.facets(ft, 2), ROT @ [0, -1.0, 0], name="p2")
    if not contact:
        sim.add_velocity_bc(sim.facets(ft, 4), -0.1, 2)
        return sim
    sim.add_velocity_bc(sim.facets(ft, 3), 0.0, 2)
    die = fx.Plane((0, 0, 1.0), (0, 0, -1), velocity=(0, 0, -0.1), name="die")
    sim.add_contributor(fx.NodalContact(fx.ContactBoundary(space, ft, 4), die, beta=beta,
                                        scheme="implicit", friction=friction))
    return sim


MATERIALS = {
    "norton-hoff": lambda: fx.NortonHoff(K=1.0, m=0.3, regularization=1e-3),
    "elastic": lambda: fx.LinearElastic(E=1.0, nu=0.3),
}


def _solve_with(prob, A, b, linear_solver, prefix, factorisations=None):
    """The step A x = b with a fresh solver; ``factorisations`` (a dict) receives the
    condensed PC's count of set-ups per factorisation kind."""
    ns = NewtonSolver(prob, SolverOptions(linear_solver=linear_solver, prefix=prefix,
                                          element_condensation=False))
    ksp = ns.snes.getKSP()
    ksp.setOperators(A, A)
    x = A.createVecRight()
    ksp.solve(b, x)
    assert ksp.getConvergedReason() > 0
    if factorisations is not None and ns._condensed_pc is not None:
        factorisations.update(ns._condensed_pc.factorisations)
    ns.destroy()
    return x


@pytest.mark.parametrize("material,symmetric", [(m, s) for m in sorted(MATERIALS)
                                                for s in (True, False)])
def test_condensed_step_equals_full_step(material, symmetric):
    """The condensed (MUMPS on P1/P1) and the uncondensed (MUMPS on MINI) Newton steps agree
    to 1e-10 (relative) at a perturbed iterate with active contact and inclined planes. The
    symmetric matrix is factorised as L D Lᵀ; with a non-symmetric term added to a vertex
    block (``symmetric=False``, as implicit friction would) the condensed solve switches to
    LU and still gives the full step."""
    sim = pressed_block(MATERIALS[material]())
    sim.run(0.1, 0.1)
    comm = sim.comm
    prob = sim.problem
    terms = prob._evaluate_contributors(True)
    n_active = comm.allreduce(int(sum(np.count_nonzero(np.abs(t.jacobian).sum(axis=(1, 2)))
                                      for t in terms)))
    assert n_active > 0                                    # contact terms in the Jacobian
    rng = np.random.default_rng(comm.rank)
    nown = sim.space.num_owned_dofs
    scale = np.abs(sim.w.x.array[:nown]).max(initial=0.0)
    sim.w.x.array[:nown] += 1e-2 * comm.allreduce(scale, op=MPI.MAX) * rng.normal(size=nown)
    sim.w.x.scatter_forward()
    A = prob.assemble_jacobian()
    b = prob.assemble_residual()
    if not symmetric:
        # one velocity–velocity entry of every owned free vertex (in the pattern: the
        # vertex's own 3×3 block), a tenth of the diagonal, below the diagonal only
        vd = sim.space.vertex_dofs[sim.space.vertex_owned]
        r0 = A.getOwnershipRange()[0]
        diag = A.getDiagonal()
        for i, j in zip(vd[:, 1], vd[:, 0]):
            if not prob.bc_marker[i] and not prob.bc_marker[j]:
                A.setValue(r0 + i, r0 + j, 0.1 * diag.getValue(r0 + i),
                           addv=PETSc.InsertMode.ADD_VALUES)
        A.assemble()
        diag.destroy()
    x_full = _solve_with(prob, A, b, "mumps", "tfull_")
    kinds = {}
    x_cond = _solve_with(prob, A, b, "condensed-mumps", "tcond_", kinds)
    assert kinds == ({"cholesky": 1} if symmetric else {"lu": 1}), kinds
    diff = (x_full - x_cond).norm() / x_full.norm()
    assert diff < 1e-10, diff
    # the step solves the full system (not only the condensed one)
    r = b.duplicate()
    A.mult(x_cond, r)
    r.axpy(-1.0, b)
    assert r.norm() < 1e-10 * b.norm()
    for v in (A, b, x_full, x_cond, r):
        v.destroy()


def test_condensed_newton_same_solution():
    """Two increments with the condensed and the uncondensed direct solver: the same Newton
    iterations and the same converged velocity/pressure (the iterates differ by round-off)."""
    out = {}
    for solver in ("mumps", "condensed-mumps"):
        sim = pressed_block(MATERIALS["norton-hoff"](), solver=solver,
                            prefix=f"s{solver.replace('-', '')}_")
        sp = sim.space
        own = sp.vertex_owned
        x0 = sp.vertex_positions()[own]
        sim.run(0.2, 0.1)
        # vertex velocities by initial position (the two meshes may be partitioned apart)
        _, v = gather_by_position(sim.comm, x0, sim.w.x.array[sp.vertex_dofs[own]])
        out[solver] = (v, [r["newton_iterations"] for r in sim.history])
        sim.solver.destroy()
    (w0, its0), (w1, its1) = out["mumps"], out["condensed-mumps"]
    assert its0 == its1
    assert np.linalg.norm(w0 - w1) < 1e-9 * np.linalg.norm(w0)


def test_layout_counts_and_errors():
    """Bubble dofs: gdim per cell, all owned by the cell's owner; the condensed system keeps
    the (gdim + 1) dofs per vertex; Taylor–Hood (no interior dofs) is refused."""
    comm = MPI.COMM_WORLD
    msh = dolfinx.mesh.create_box(comm, [[0, 0, 0], [1, 1, 1]], [3, 3, 3],
                                  dolfinx.mesh.CellType.tetrahedron)
    lay = CondensationLayout(fx.MixedSpace(msh).W)
    nc = msh.topology.index_map(3).size_global
    nv = msh.topology.index_map(0).size_global
    full, cond = lay.num_global()
    assert full - cond == 3 * nc
    assert cond == 4 * nv
    assert lay.vel_nodes is not None                     # vertex-interlaced velocity split
    assert comm.allreduce(lay.vel_nodes.shape[0]) == nv
    with pytest.raises(ValueError, match="no cell-interior"):
        CondensationLayout(fx.MixedSpace(msh, "taylor-hood").W)


def _newton_krylov(beta):
    sim = pressed_block(MATERIALS["norton-hoff"](), n=5, beta=beta, solver="condensed-amg",
                        prefix=f"it{int(beta)}_")
    sim.run(0.2, 0.1)
    its = sum(r["newton_iterations"] for r in sim.history)
    return sim, sim.solver._condensed_pc.inner_iterations / its


def test_iterative_condensed_stiff_penalty():
    """The condensed iterative solver (Schur field split, GAMG with rigid-body modes, Schur
    preconditioned by the condensation block + inverse-viscosity mass) converges with a
    contact penalty β = 10⁴ and its Krylov iterations per Newton iteration do not grow by more
    than 1.5× from β = 10² to β = 10⁴; the converged solution equals the direct one to the
    Newton tolerance."""
    sim2, k2 = _newton_krylov(1e2)
    sim4, k4 = _newton_krylov(1e4)
    assert all(r["newton_iterations"] > 0 for r in sim4.history)
    assert k4 <= 1.5 * k2, (k2, k4)
    ref = pressed_block(MATERIALS["norton-hoff"](), n=5, beta=1e4, prefix="itref_")
    ref.run(0.2, 0.1)
    vel = [vertex_velocities_by_position(s) for s in (ref, sim4)]
    err = np.linalg.norm(vel[0] - vel[1]) / np.linalg.norm(vel[0])
    assert err < 1e-6, err


def test_auto_choice(monkeypatch):
    """linear_solver="auto" (default): MUMPS for small problems and for spaces without
    interior dofs, the condensed direct then iterative solver above the thresholds; an
    explicit choice is kept."""
    import fxcontact.newton.solver as solver_mod

    comm = MPI.COMM_WORLD
    msh = dolfinx.mesh.create_box(comm, [[0, 0, 0], [1, 1, 1]], [2, 2, 2],
                                  dolfinx.mesh.CellType.tetrahedron)
    mini, th = fx.MixedSpace(msh).W, fx.MixedSpace(msh, "taylor-hood").W
    n = mini.dofmap.index_map.size_global
    assert SolverOptions().linear_solver == "auto"
    assert solver_mod.choose_linear_solver(mini) == "mumps"
    monkeypatch.setattr(solver_mod, "AUTO_CONDENSED_MIN_DOFS", n)
    assert solver_mod.choose_linear_solver(mini) == "condensed-mumps"
    assert solver_mod.choose_linear_solver(th) == "mumps"
    monkeypatch.setattr(solver_mod, "AUTO_ITERATIVE_MIN_DOFS", n)
    assert solver_mod.choose_linear_solver(mini) == "condensed-amg"
    sim = pressed_block(MATERIALS["norton-hoff"](), n=2, solver="auto", prefix="tauto_")
    sim._build()
    assert sim.solver.options.linear_solver == "condensed-amg"
    assert sim.solver_options.linear_solver == "auto"
    sim.solver.destroy()
    sim = pressed_block(MATERIALS["norton-hoff"](), n=2, solver="mumps", prefix="tauto_")
    sim._build()
    assert sim.solver.options.linear_solver == "mumps"
    with pytest.raises(ValueError, match="unknown linear solver"):
        SolverOptions(linear_solver="condensed")


def test_inner_failure_is_reported_and_reset():
    """A failed inner (condensed) Krylov solve fails the Newton solve with a message naming it;
    the solver is rebuilt, and with a working inner solver the same increment converges."""
    sim = pressed_block(MATERIALS["norton-hoff"](), n=3, solver="condensed-amg", prefix="tfail_")
    sim.solver_options.petsc_options["condensed_ksp_max_it"] = 2
    sim._build()
    info = sim._try_increment(0.1)
    assert not info.converged
    assert "condensed linear solve failed" in info.message
    assert sim.solver.resets == 1
    sim.solver.options.petsc_options["condensed_ksp_max_it"] = 300
    sim.solver.reset()
    info = sim._try_increment(0.1)
    assert info.converged, info.message
    assert info.linear_iterations > 0


def test_auto_iterative_failure_falls_back_to_direct(monkeypatch):
    """When ``"auto"`` chose the iterative solver and its inner solve fails, the increment is
    retried at the same dt with condensed MUMPS (no cut-back) and the direct solver is kept;
    an explicit ``"condensed-amg"`` is never replaced."""
    import fxcontact.newton.solver as solver_mod
    monkeypatch.setattr(solver_mod, "AUTO_CONDENSED_MIN_DOFS", 0)
    monkeypatch.setattr(solver_mod, "AUTO_ITERATIVE_MIN_DOFS", 0)
    sim = pressed_block(MATERIALS["norton-hoff"](), n=3, solver="auto", prefix="tfb_",
                        petsc_options={"condensed_ksp_max_it": 2})
    res = sim.step(0.1, max_cutbacks=0)
    assert sim.solver.options.linear_solver == "condensed-mumps"
    assert res.row["cutbacks"] == 0
    ref = pressed_block(MATERIALS["norton-hoff"](), n=3, solver="condensed-mumps",
                        prefix="tfb_")
    ref.step(0.1, max_cutbacks=0)
    vel = [vertex_velocities_by_position(s) for s in (ref, sim)]
    assert np.linalg.norm(vel[0] - vel[1]) <= 1e-8 * np.linalg.norm(vel[0])
    explicit = pressed_block(MATERIALS["norton-hoff"](), n=3, solver="condensed-amg",
                             prefix="tfb_", petsc_options={"condensed_ksp_max_it": 2})
    with pytest.raises(Exception, match="condensed linear solve failed"):
        explicit.step(0.1, max_cutbacks=0)
    assert explicit.solver.options.linear_solver == "condensed-amg"


@pytest.mark.serial   # dense eigenvalues of the gathered blocks: one rank
def test_augmented_velocity_block_removes_the_free_dilatation():
    """The Norton–Hoff tangent acts on the strain-rate deviator, so the velocity block alone is
    singular when the velocity conditions leave a dilatation free: here the start-up problem
    of the pressed block (no contact yet; v_z = 0 at the bottom and the two planes through the
    z axis leave v = c x free), the mode that stalls the Schur field split of the wire drawing
    (benchmarks/README.md). With ``condensed_augment_scale = 1`` the preconditioning matrix's
    velocity block gets (2/3) η div div and is positive definite; the operator is unchanged
    and the converged solution is the direct solver's."""
    import scipy.linalg as la
    sim = pressed_block(MATERIALS["norton-hoff"](), n=2, solver="condensed-amg", prefix="taug_",
                        petsc_options={"condensed_augment_scale": 1.0}, contact=False)
    sim.step(0.1, max_cutbacks=0)
    cpc = sim.solver._condensed_pc
    iu = cpc._iu.getIndices()

    def uu(M):
        ai, aj, av = M.getValuesCSR()
        import scipy.sparse as sps
        A = sps.csr_matrix((av, aj, ai), shape=M.getSize()).toarray()
        return A[np.ix_(iu, iu)]

    A, Aa = uu(cpc._mats["S"]), uu(cpc._mats["Saug"])
    w, V = la.eigh(0.5 * (A + A.T))
    wa = la.eigvalsh(0.5 * (Aa + Aa.T))
    assert w[0] < 1e-10 * w[-1] and w[1] > 1e-4 * w[-1], w[:3]    # one zero mode ...
    # ... a dilatation about the corner of the top face on the axis (the matrix is that of the
    # start of the increment: the vertices have moved by dt v since)
    x = cpc.lay.node_coordinates() - ROT @ [0.0, 0.0, 1.0]
    mode = V[:, 0].reshape(-1, 3)
    c = np.sum(mode * x) / np.sum(x * x)
    assert np.linalg.norm(mode - c * x) < 0.05 * np.linalg.norm(mode)
    assert wa[0] > 1e-3 * wa[-1], (wa[0], wa[-1])           # gone with the augmentation
    ref = pressed_block(MATERIALS["norton-hoff"](), n=2, prefix="taug_", contact=False)
    ref.step(0.1, max_cutbacks=0)
    vel = [vertex_velocities_by_position(s) for s in (ref, sim)]
    assert np.linalg.norm(vel[0] - vel[1]) <= 1e-6 * np.linalg.norm(vel[0])
