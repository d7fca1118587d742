"""Contact on any P1 vector field of a dolfinx problem: displacement-form nodal contact
(finite-difference checks of every scheme, numba = numpy twin), ContactBoundary on plain and
sub-spaces (areas, dof maps, clear error for P2), ContactProblem with dolfinx's NewtonSolver,
with a petsc4py SNES and with fxcontact's ContactNewtonSolver (same answer), 1 vs 2 ranks."""

import numpy as np
import pytest
import ufl
from mpi4py import MPI
from petsc4py import PETSc

import dolfinx
import dolfinx.fem.petsc
import dolfinx.nls.petsc

import fxcontact as fx
from fxcontact import compat
from fxcontact.contact.nodal import NodalContact
from fxcontact.processes import hyperelastic

from helpers import box_mesh, gather_by_position


# ----------------------------------------------------------------------------- unit level
class _FakeBoundary:
    """Duck-typed ContactBoundary on plain arrays (reference positions given)."""

    def __init__(self, x_ref, seed=0):
        rng = np.random.default_rng(seed)
        n, d = x_ref.shape
        self.comm = MPI.COMM_SELF
        self.gdim = d
        self.areas = 0.5 + rng.random(n)
        self.vertices = np.arange(n)
        self.dofs = np.arange(n * d).reshape(n, d)
        self._x = x_ref

    def __len__(self):
        return len(self.areas)

    def velocities(self, w):
        return w.x.array[self.dofs]

    def mesh_positions(self):
        return self._x.copy()

    def update_areas(self):
        pass


class _Vec:
    """Stands for a Function: ``.x.array``."""

    def __init__(self, a):
        self.x = type("X", (), {"array": np.asarray(a, dtype=np.float64).ravel()})()


def _energy(c, u):
    """Σ S k [−gap(X_ref + u)]₊²/2 with the scheme's gap (linearised for explicit schemes)."""
    v = (u.reshape(-1, 3) - c._u_t) / c.dt
    h = c._constraint(v, False)[0]          # h = −gap/dt
    k = c.rho / c.dt
    return 0.5 * k * np.sum(c.boundary.areas * np.maximum(h * c.dt, 0.0) ** 2)


TOOLS = {
    "plane": lambda: fx.Plane((0, 0, 1.0), (0.2, -0.1, -1.0), velocity=(0.1, 0, -0.3)),
    "sphere": lambda: fx.Sphere((0.2, 0.1, 3.0), 2.0, velocity=(0, 0, -0.2)),
    "cylinder": lambda: fx.Cylinder((0, 0, 3.0), (1, 0.2, 0), 2.0, velocity=(0, 0.1, -0.2),
                                    angular_velocity=0.7),
}


def _displacement_case(scheme, tool, backend="numba", seed=3):
    """A contact in displacement form after one load step, at a perturbed iterate."""
    rng = np.random.default_rng(seed)
    n = 12
    t0, dt = 0.3, 0.1
    tl = TOOLS[tool]()
    y = rng.uniform(-1.0, 1.0, (n, 3)) + np.array([1.5, 0.3, 0.9])
    pr = tl.project(y, t0)
    s = np.linspace(-0.15, 0.15, n)
    x_t = pr.point + s[:, None] * pr.normal          # positions at the start of the step
    u_prev = rng.normal(scale=0.05, size=(n, 3))     # displacement of the previous step
    u_t = rng.normal(scale=0.05, size=(n, 3))
    x_ref = x_t - u_t
    b = _FakeBoundary(x_ref)
    c = NodalContact(b, tl, scheme=scheme, penalty=7.0, max_initial_penetration=10.0,
                     formulation="displacement", backend=backend)
    c.begin_step(t0 - dt, dt, _Vec(u_prev))          # a first step: sets the predictor rate
    c.begin_step(t0, dt, _Vec(u_t))
    u = u_t + dt * rng.normal(scale=0.5, size=(n, 3))
    return c, u


@pytest.mark.parametrize("scheme", list(fx.SCHEMES))
@pytest.mark.parametrize("tool", list(TOOLS))
def test_displacement_form_residual_and_jacobian_fd(scheme, tool):
    """r = ∇Φ(u) for every scheme (FD of the energy); K = ∇r (FD of the residual) for all but
    the Gauss–Newton 'implicit'; the residual entries are the nodal forces S k [−gap]₊ n."""
    c, u = _displacement_case(scheme, tool)
    n = len(u)
    c.evaluate(_Vec(u), False)
    c.stable()
    assert c.stable()
    terms = c.evaluate(_Vec(u), True)
    assert np.any(c._h > 0) and np.any(c._h <= 0)
    r, K = terms.residual, terms.jacobian
    # the penalty is the gap stiffness k = 7 per unit length: forces S k pen
    pen = np.maximum(c._h * c.dt, 0.0)
    assert np.allclose(np.linalg.norm(r, axis=1), c.boundary.areas * 7.0 * pen, rtol=1e-12,
                       atol=1e-14)
    eps = 1e-7
    g_fd = np.zeros_like(u)
    K_fd = np.zeros((n, 3, 3))
    for a in range(3):
        du = np.zeros_like(u)
        du[:, a] = eps
        for i in range(n):
            e = np.zeros_like(u)
            e[i, a] = eps
            g_fd[i, a] = (_energy(c, (u + e).ravel()) - _energy(c, (u - e).ravel())) / (2 * eps)
        rp = c.evaluate(_Vec(u + du), False).residual
        rm = c.evaluate(_Vec(u - du), False).residual
        K_fd[:, :, a] = (rp - rm) / (2 * eps)
    assert np.linalg.norm(r - g_fd) <= 1e-6 * np.linalg.norm(r)
    if scheme == "implicit":
        return
    c.evaluate(_Vec(u), False)
    far = np.abs(c._h * c.dt) > 1e-4
    assert np.linalg.norm((K - K_fd)[far]) <= 1e-6 * np.linalg.norm(K[far])


@pytest.mark.parametrize("scheme", list(fx.SCHEMES))
def test_displacement_form_twin(scheme):
    """numba kernels = numpy twin in the displacement formulation."""
    out = []
    for backend in ("numba", "numpy"):
        c, u = _displacement_case(scheme, "sphere", backend)
        c.evaluate(_Vec(u), False)
        c.stable()
        c.stable()
        t = c.evaluate(_Vec(u), True)
        out.append((t.residual, t.jacobian))
    assert np.allclose(out[0][0], out[1][0], rtol=1e-13, atol=1e-14)
    assert np.allclose(out[0][1], out[1][1], rtol=1e-13, atol=1e-14)


def test_displacement_form_equals_velocity_form():
    """Same step, same tool: the displacement form's residual equals the velocity form's with
    v = (u − uᵗ)/dt and ρ = k dt; its Jacobian is the velocity form's divided by dt."""
    c, u = _displacement_case("implicit-exact", "cylinder")
    b = c.boundary
    cv = NodalContact(b, c.tools, scheme="implicit-exact", penalty=7.0 * c.dt,
                      max_initial_penetration=10.0)
    sim = type("S", (), {"kinematics": fx.CartesianUpdate(),
                         "material": fx.LinearElastic(1.0, 0.3),
                         "w_prev": _Vec(np.zeros(u.size))})()
    cv.begin_increment(sim, c.t, c.dt, b.mesh_positions() + c._u_t)
    v = (u - c._u_t) / c.dt
    for cc, w in ((c, _Vec(u)), (cv, _Vec(v))):
        cc.evaluate(w, False)
        cc.stable()
        cc.stable()
    td, tv = c.evaluate(_Vec(u), True), cv.evaluate(_Vec(v), True)
    assert np.allclose(td.residual, tv.residual, rtol=1e-13, atol=1e-15)
    assert np.allclose(td.jacobian * c.dt, tv.jacobian, rtol=1e-13, atol=1e-15)


def _branch_model_error(c, w, step):
    """Relative difference between the contact residual and Jacobian at ``w + step`` and the
    active-set prediction's model of the branch the step lands on (``w``: the nodal values,
    displacements or velocities): ``r + K δ + U (dc Uᵀδ + o)`` and ``K + U dc Uᵀ``."""
    n, d = w.shape
    c.evaluate(_Vec(w), False)
    c.stable()
    t0 = c.evaluate(_Vec(w), True)
    dofs, g, dc, o = c.active_set_prediction(step.ravel())
    nodes = dofs[:, 0] // d
    r_model = t0.residual + np.einsum("nij,nj->ni", t0.jacobian, step)
    K_model = t0.jacobian.copy()
    for j, i in enumerate(nodes):
        r_model[i] += g[j] * (dc[j] * (g[j] @ step[i]) + o[j])
        K_model[i] += dc[j] * np.outer(g[j], g[j])
    t1 = c.evaluate(_Vec(w + step), True)
    return (len(nodes), np.linalg.norm(t1.residual - r_model) / np.linalg.norm(t1.residual),
            np.linalg.norm(t1.jacobian - K_model) / np.linalg.norm(t1.jacobian))


@pytest.mark.parametrize("scheme", list(fx.SCHEMES))
def test_active_set_prediction_is_the_branch_of_the_step(scheme):
    """The active-set prediction's columns, stiffness changes and offsets (THEORY §3.6) are the
    penalty's branch at the end of the step, in both formulations: against a plane the penalty
    force is piecewise linear, so the contact residual and Jacobian at u + δ are exactly the
    model's, for a step δ that takes every node in contact out and every free node in. In
    displacement form they were the velocity form's, 1/dt too stiff (dt = 0.1 here), which
    stalled Newton on the neo-Hookean block (:func:`test_hyperelastic_fxcontact_driver_with_
    the_prediction`)."""
    c, u = _displacement_case(scheme, "plane")
    cv = NodalContact(c.boundary, c.tools, scheme=scheme, penalty=7.0 * c.dt,
                      max_initial_penetration=10.0)
    sim = type("S", (), {"kinematics": fx.CartesianUpdate(),
                         "material": fx.LinearElastic(1.0, 0.3),
                         "w_prev": _Vec(np.zeros(u.size))})()
    cv.begin_increment(sim, c.t, c.dt, c.boundary.mesh_positions() + c._u_t)
    v = (u - c._u_t) / c.dt
    for cc, w, unit in ((c, u, c.dt), (cv, v, 1.0)):
        cc.evaluate(_Vec(w), False)
        h, n = cc._h, -cc._g
        assert np.any(h > 0) and np.any(h <= 0)
        # every node across the plane: 1 mm/s (× dt in displacement form) past it
        step = ((np.where(h > 0, -1.0, 1.0) - h) * unit)[:, None] * -n
        k, err_r, err_K = _branch_model_error(cc, w, step)
        assert k == len(h), cc.formulation
        assert err_r < 1e-10 and err_K < 1e-10, (cc.formulation, err_r, err_K)


def test_displacement_form_bad_input():
    b = _FakeBoundary(np.zeros((2, 3)))
    tool = fx.Plane((0, 0, 0), (0, 0, 1))
    with pytest.raises(ValueError, match="formulation"):
        NodalContact(b, tool, penalty=1.0, formulation="lagrangian")
    with pytest.raises(ValueError, match="gap stiffness.*modulus"):
        NodalContact(b, tool, formulation="displacement")
    with pytest.raises(ValueError, match="modulus is for the displacement"):
        NodalContact(b, tool, beta=10.0, modulus=1.0)
    c = NodalContact(b, tool, beta=10.0, modulus=200.0, element_size=0.5,
                     formulation="displacement")
    assert c.stiffness == pytest.approx(10.0 * 200.0 / 0.5)
    with pytest.raises(RuntimeError, match="begin_step"):
        c.evaluate(_Vec(np.zeros(6)), False)
    with pytest.raises(ValueError, match="shear_limit"):
        NodalContact(b, tool, penalty=1.0, formulation="displacement",
                     friction=fx.Tresca(0.5)).begin_step(0.0, 1.0, _Vec(np.zeros(6)))


# ----------------------------------------------------------------------------- boundaries
def test_boundary_on_any_p1_space():
    """Vector P1, the P1 sub-space of a P1-P1 mixed space and MINI's velocity: the same
    contact vertices, the same areas, dofs that hold the vertex values; P2 and scalar spaces
    are refused with the reason."""
    comm = MPI.COMM_WORLD
    msh = box_mesh(comm, n=(3, 4, 2), perturb=0.2)
    ft = _top_tags(msh)
    sp = fx.MixedSpace(msh)
    cell = msh.ufl_cell()
    P1 = ufl.FiniteElement("Lagrange", cell, 1)
    V = dolfinx.fem.VectorFunctionSpace(msh, ("Lagrange", 1))
    W = dolfinx.fem.FunctionSpace(msh, ufl.MixedElement([P1, ufl.VectorElement(P1)]))
    ref = fx.ContactBoundary(sp, ft, 7)
    for space, parent in ((V, V), (W.sub(1), W), (sp.W.sub(0), sp.W)):
        b = fx.ContactBoundary(space, ft, 7)
        assert np.array_equal(b.vertices, ref.vertices)
        assert np.allclose(b.areas, ref.areas, rtol=1e-13)
        assert b.total_area() == pytest.approx(1.0, rel=1e-12)
        # the dofs carry the vertex coordinates of an interpolated x
        f = dolfinx.fem.Function(parent)
        if parent is V:
            f.interpolate(lambda x: x)
        else:
            sub = parent.sub(1) if parent is W else parent.sub(0)
            Vc, m = compat.collapse(sub)
            g = dolfinx.fem.Function(Vc)
            g.interpolate(lambda x: x)
            f.x.array[m] = g.x.array
        assert np.allclose(b.values(f), b.mesh_positions(), atol=1e-14)
    V2 = dolfinx.fem.VectorFunctionSpace(msh, ("Lagrange", 2))
    with pytest.raises(ValueError, match="P1 trace.*degree 2.*edge/face nodes"):
        fx.ContactBoundary(V2, ft, 7)
    with pytest.raises(ValueError, match="vector field"):
        fx.ContactBoundary(dolfinx.fem.FunctionSpace(msh, ("Lagrange", 1)), ft, 7)
    with pytest.raises(ValueError, match="MixedSpace or a dolfinx FunctionSpace"):
        fx.ContactBoundary("P1", ft, 7)


def _top_tags(msh, z=1.0):
    fdim = msh.topology.dim - 1
    f = dolfinx.mesh.locate_entities_boundary(msh, fdim, lambda x: np.isclose(x[2], z))
    return dolfinx.mesh.meshtags(msh, fdim, f, np.full(len(f), 7, dtype=np.int32))


# ----------------------------------------------------------------------------- user solvers
E, NU = 1000.0, 0.3


def _elastic_problem(comm, n=(5, 5, 4), scheme="implicit-exact"):
    """Unit cube on a fixed base, pressed on its top by a descending sphere (P1 displacement,
    compressible neo-Hookean, written the dolfinx way); ``scheme=None``: the contact's
    default."""
    msh = box_mesh(comm, n=n)
    V = dolfinx.fem.VectorFunctionSpace(msh, ("Lagrange", 1))
    u = dolfinx.fem.Function(V)
    v = ufl.TestFunction(V)
    d = len(u)
    I = ufl.Identity(d)
    F_ = ufl.variable(I + ufl.grad(u))
    C = F_.T * F_
    J = ufl.det(F_)
    mu = dolfinx.fem.Constant(msh, PETSc.ScalarType(E / (2 * (1 + NU))))
    lmbda = dolfinx.fem.Constant(msh, PETSc.ScalarType(E * NU / ((1 + NU) * (1 - 2 * NU))))
    psi = (mu / 2) * (ufl.tr(C) - 3) - mu * ufl.ln(J) + (lmbda / 2) * ufl.ln(J) ** 2
    P = ufl.diff(psi, F_)
    F = ufl.inner(ufl.grad(v), P) * ufl.dx(metadata={"quadrature_degree": 2})
    fdim = msh.topology.dim - 1
    bottom = dolfinx.mesh.locate_entities_boundary(msh, fdim, lambda x: np.isclose(x[2], 0.0))
    bc = dolfinx.fem.dirichletbc(np.zeros(3, dtype=PETSc.ScalarType),
                                 dolfinx.fem.locate_dofs_topological(V, fdim, bottom), V)
    ft = _top_tags(msh)
    sphere = fx.Sphere((0.5, 0.5, 1.6), 0.6, velocity=(0.0, 0.0, -0.05), name="ball")
    contact = fx.NodalContact(fx.ContactBoundary(V, ft, 7), sphere, scheme=scheme,
                              formulation="displacement", beta=100.0, modulus=E / (1 - NU**2))
    return msh, V, u, F, bc, contact


def _run(comm, driver, steps=3, linear_solver=None):
    """Press the cube in ``steps`` load steps with ``driver``; ``linear_solver``: a kind of
    ``ContactProblem.use_linear_solver`` (None: the user's own MUMPS LU)."""
    msh, V, u, F, bc, contact = _elastic_problem(comm)
    problem = fx.ContactProblem(F, u, [bc], contributors=[contact])
    if driver == "newton":
        solver = dolfinx.nls.petsc.NewtonSolver(comm, problem)
        solver.rtol, solver.atol = 1e-10, 1e-12
        solver.convergence_criterion = "residual"
        problem.set_solver(solver)
        ksp = solver.krylov_solver
        if linear_solver is None:
            opts = PETSc.Options()
            pfx = ksp.getOptionsPrefix()
            opts[f"{pfx}ksp_type"] = "preonly"
            opts[f"{pfx}pc_type"] = "lu"
            opts[f"{pfx}pc_factor_mat_solver_type"] = "mumps"
            ksp.setFromOptions()
        else:
            problem.use_linear_solver(solver, linear_solver)
        solve = lambda: solver.solve(u)  # noqa: E731
    elif driver == "snes":
        b = dolfinx.fem.petsc.create_vector(problem.L)
        A = dolfinx.fem.petsc.create_matrix(problem.a)
        snes = PETSc.SNES().create(comm)
        snes.setOptionsPrefix("anyfem_")
        opts = PETSc.Options()
        for k, val in {"snes_type": "newtonls", "snes_linesearch_type": "basic",
                       "ksp_type": "preonly", "pc_type": "lu",
                       "pc_factor_mat_solver_type": "mumps"}.items():
            opts[f"anyfem_{k}"] = val
        res, jac, conv = problem.snes_callbacks()
        snes.setFunction(res, b)
        snes.setJacobian(jac, A, A)
        snes.setConvergenceTest(conv)
        snes.setTolerances(rtol=1e-10, atol=1e-12, stol=0.0, max_it=30)
        snes.setFromOptions()
        if linear_solver is not None:
            problem.use_linear_solver(snes, linear_solver)

        def solve():
            x = u.vector.copy()
            snes.solve(None, x)
            assert snes.getConvergedReason() > 0, snes.getConvergedReason()
            x.copy(u.vector)
            u.x.scatter_forward()
            return snes.getIterationNumber(), True
    else:  # fxcontact's own ContactNewtonSolver on a NodalNonlinearProblem
        fprob = fx.NodalNonlinearProblem(F, u, [bc], contributors=[contact])
        fsolver = fx.ContactNewtonSolver(
            fprob, fx.SolverOptions(rtol=1e-10, atol=1e-12, stol=0.0, line_search="basic",
                                    prefix="anyfem_fx_"))

        def solve():
            info = fsolver.solve()
            assert info.converged, info.message
            return info.iterations, True
    its = []
    for k in range(1, steps + 1):
        problem.begin_step(float(k))
        n, ok = solve()
        assert ok
        its.append(n)
    problem.end_step()
    force = contact.tool_force(0)
    b = contact.boundary
    x, uu = gather_by_position(comm, b.mesh_positions(), b.values(u))
    return force, x, uu, its, contact, problem


def test_user_newton_snes_and_fxcontact_agree():
    """dolfinx's NewtonSolver, a petsc4py SNES and fxcontact's ContactNewtonSolver give the same
    contact forces and nodal displacements (to the Newton tolerance); large deformation:
    the ball pushes the top 15 % of the cube's height down."""
    comm = MPI.COMM_WORLD
    out = {d: _run(comm, d) for d in ("newton", "snes", "fxcontact")}
    f0, x0, u0 = out["newton"][:3]
    assert f0[2] > 0  # the body pushes the ball up (force on the tool)
    assert np.max(-u0[:, 2]) > 0.1
    for d in ("snes", "fxcontact"):
        f, x, uu = out[d][:3]
        assert np.allclose(x, x0)
        assert np.linalg.norm(f - f0) <= 1e-8 * np.linalg.norm(f0), d
        assert np.max(np.abs(uu - u0)) <= 1e-8 * np.max(np.abs(u0)), d
    # the active-set check held at least one converged-looking iterate back (or none changed)
    c, p = out["newton"][4], out["newton"][5]
    assert p.stable_iterate
    # penetration is the penalty's: force / (k * area) order, far below the indentation
    assert c._true_pen < 0.05 * 0.15


def test_ranks_agree():
    """1 vs 2 ranks (run under mpirun -n 2): the same forces and displacements to 1e-8."""
    comm = MPI.COMM_WORLD
    f1, x1, u1 = _run(comm, "newton", steps=2)[:3]
    f2, x2, u2 = _run(MPI.COMM_SELF, "newton", steps=2)[:3]
    assert np.allclose(x1, x2, atol=1e-12)
    assert np.linalg.norm(f1 - f2) <= 1e-8 * np.linalg.norm(f2)
    assert np.max(np.abs(u1 - u2)) <= 1e-8 * np.max(np.abs(u2))


def test_hyperelastic_demo_small():
    """The neo-Hookean block of :mod:`fxcontact.processes.hyperelastic` (the demo's) at a small
    size: dolfinx's NewtonSolver and the SNES callbacks give the same ball force (1e-8), the
    block is pressed 30 % of its height, the ball force grows with the indentation, and the
    penalty penetration stays below 2 % of the indentation."""
    r1 = hyperelastic.run("newton", n=6, n_steps=3)
    r2 = hyperelastic.run("snes", n=6, n_steps=3)
    assert abs(r2["force"] / r1["force"] - 1.0) <= 1e-8
    assert r1["u_z_min"] < -0.28
    forces = [row["force"] for row in r1["rows"]]
    assert forces[0] > 0 and np.all(np.diff(forces) > 0)
    assert r1["penetration"] < 0.02 * 0.3


def test_hyperelastic_fxcontact_driver_with_the_prediction(monkeypatch):
    """The demo's neo-Hookean block at its default size (n = 12, 6 load steps of dt = 1/6)
    with fxcontact's ContactNewtonSolver, whose active-set prediction is on by default (MUMPS):
    it converges, to the ball force and displacements of the same solver without the
    prediction (1e-8), in fewer Newton iterations, with corrected steps among them. Measured
    (1 and 2 ranks): 27 iterations (4, 4, 5, 5, 4, 5) against 32. With the prediction's
    displacement-form weights 1/dt too stiff Newton stagnated in the first load step, at a
    residual 4.8e-2 of an initial 10 (:func:`test_active_set_prediction_is_the_branch_of_the_
    step`)."""
    import fxcontact.newton.prediction as P

    corrected = []
    correct = P.ActiveSetPrediction.correct

    def spy(self, ksp, y):
        corrected.append(correct(self, ksp, y))
        return corrected[-1]

    monkeypatch.setattr(P.ActiveSetPrediction, "correct", spy)
    pred = hyperelastic.run("fxcontact")
    options = hyperelastic.SolverOptions
    monkeypatch.setattr(hyperelastic, "SolverOptions",
                        lambda **kw: options(**kw, active_set_prediction=False))
    plain = hyperelastic.run("fxcontact")
    assert sum(corrected) > 0 and len(corrected) == pred["newton"]
    assert abs(pred["force"] / plain["force"] - 1.0) <= 1e-8

    def top(r):    # the top face's displacements by position (the partitions may differ)
        b = r["contact"].boundary
        return gather_by_position(MPI.COMM_WORLD, b.mesh_positions(), b.values(r["u"]))

    (x1, u1), (x0, u0) = top(pred), top(plain)
    assert np.allclose(x1, x0, atol=1e-12)
    assert np.max(np.abs(u1 - u0)) <= 1e-8 * np.max(np.abs(u0))
    assert pred["newton"] < plain["newton"], (pred["newton"], plain["newton"])


# ----------------------------------------------------------------------------- fast defaults
def test_linear_solver_helper_agrees_with_mumps():
    """``ContactProblem.use_linear_solver``: ``"iterative"`` (CG + GAMG with the rigid-body
    modes, with dolfinx's NewtonSolver and with a SNES) and ``"direct"`` (MUMPS kept while
    the active set holds) give the answer of the user's plain MUMPS LU to the solver tolerance;
    under ``mpirun -n 2`` the two-rank solves are compared with a serial MUMPS run."""
    comm = MPI.COMM_WORLD
    f0, x0, u0 = _run(MPI.COMM_SELF, "newton", steps=2)[:3]
    for driver, kind in (("newton", "iterative"), ("snes", "iterative"), ("newton", "direct")):
        f, x, uu, its, contact, problem = _run(comm, driver, steps=2, linear_solver=kind)
        assert np.allclose(x, x0, atol=1e-12)
        assert np.linalg.norm(f - f0) <= 1e-7 * np.linalg.norm(f0), (driver, kind)
        assert np.max(np.abs(uu - u0)) <= 1e-7 * np.max(np.abs(u0)), (driver, kind)
        if kind == "iterative":   # Krylov iterations, not one exact solve per Newton step
            assert problem.krylov_iterations > 2 * sum(its), (driver, its)
        else:                     # the factorisation was kept at some stable iterate
            assert problem.factorisations[1] > 0 and problem.factorisations[0] > 0


def test_linear_solver_helper_sets_the_ksp_and_leaves_a_users_ksp_alone():
    """The helper sets CG + GAMG and the near-null space (6 rigid-body modes) on the Jacobian;
    without it the problem keeps the user's KSP as it is (here GMRES + Jacobi)."""
    comm = MPI.COMM_WORLD
    msh, V, u, F, bc, contact = _elastic_problem(comm)
    problem = fx.ContactProblem(F, u, [bc], contributors=[contact])
    solver = dolfinx.nls.petsc.NewtonSolver(comm, problem)
    assert problem.use_linear_solver(solver, "auto") == "direct"   # small: MUMPS
    assert problem.use_linear_solver(solver, "iterative") == "iterative"
    ksp = solver.krylov_solver
    assert (ksp.getType(), ksp.getPC().getType()) == ("cg", "gamg")
    problem.begin_step(1.0)
    problem.J(u.vector, solver.A)
    assert solver.A.getNearNullSpace() is not None
    assert len(solver.A.getNearNullSpace().getVecs()) == 6
    # a user's own KSP is left as it is
    problem2 = fx.ContactProblem(F, u, [bc], contributors=[contact])
    solver2 = dolfinx.nls.petsc.NewtonSolver(comm, problem2)
    problem2.set_solver(solver2)
    ksp2 = solver2.krylov_solver
    ksp2.setType("gmres")
    ksp2.getPC().setType("jacobi")
    problem2.begin_step(1.0)
    problem2.F(u.vector, solver2.b)
    problem2.J(u.vector, solver2.A)
    assert (ksp2.getType(), ksp2.getPC().getType()) == ("gmres", "jacobi")
    assert problem2.krylov_iterations == 0 and problem2.factorisations == [0, 0]


def _residual_history(scheme, steps=2):
    """‖F‖ at each Newton iterate of the last of ``steps`` load steps (dolfinx NewtonSolver,
    MUMPS) and whether the contact's active set was stable there."""
    comm = MPI.COMM_WORLD
    msh, V, u, F, bc, contact = _elastic_problem(comm, scheme=scheme)
    problem = fx.ContactProblem(F, u, [bc], contributors=[contact])
    solver = dolfinx.nls.petsc.NewtonSolver(comm, problem)
    solver.rtol, solver.atol, solver.max_it = 0.0, 1e-9, 12
    solver.convergence_criterion = "residual"
    problem.set_solver(solver)
    problem.use_linear_solver(solver, "direct")
    hist = []

    def F_(x, b):
        problem.F(x, b)
        hist.append((b.norm(), problem.stable_iterate))

    solver.setF(F_, solver.b)
    for k in range(1, steps + 1):
        problem.begin_step(float(k))
        hist.clear()
        try:
            solver.solve(u)
        except RuntimeError:   # the iteration cap (the Gauss-Newton tangent's linear rate)
            pass
    return contact, hist


def test_implicit_exact_is_the_displacement_default_and_converges_quadratically():
    """The displacement form's default scheme is ``implicit-exact``: on the neo-Hookean cube
    pressed by a ball its residuals fall quadratically once the active set holds,
    e_{k+1} <= 1e3 e_k² (e = ‖F‖/‖F₀‖, above the round-off floor), where the Gauss–Newton
    ``implicit`` scheme converges linearly (the same bound fails)."""
    def worst(hist):
        r0 = hist[0][0]
        e = [r / r0 for r, stable in hist if stable and r > 1e-9]
        assert len(e) >= 3, hist
        return max(b / a**2 for a, b in zip(e, e[1:]))

    contact, exact = _residual_history(None)
    assert contact.scheme == "implicit-exact"
    assert worst(exact) <= 1e3, exact
    contact, gn = _residual_history("implicit")
    assert worst(gn) > 1e3, gn
