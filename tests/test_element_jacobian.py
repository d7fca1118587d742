"""The Newton matrix with the MINI bubble condensed element by element
(fxcontact.element.jacobian) against the plain MINI system.

* the numba cell kernels equal their numpy twins;
* at a perturbed iterate with active contact (with and without Tresca friction), inclined
  symmetry planes and a Dirichlet face, the exact product J' x from the condensed matrix and the
  kept cell matrices equals the product with the assembled MINI Jacobian, and the Newton step of
  the element condensation equals the step of MUMPS on the MINI system, both to 1e-10;
* whole increments (Simulation) give the same solution with the element condensation and with
  the algebraic one, also with an idle tool eliminated by the bordered Newton matrix (ring
  rolling) — serially and on 2 ranks.
"""

import numpy as np
import pytest
from helpers import assert_newton_counts_match, vertex_velocities_by_position
from mpi4py import MPI
from petsc4py import PETSc
from test_condense import MATERIALS, pressed_block

import fxcontact as fx
from fxcontact.element import jacobian as ej
from fxcontact.element.cell import condense_matrix, condense_matrix_numpy
from fxcontact.element.jacobian import CondensedJacobian
from fxcontact.newton.solver import NewtonSolver, SolverOptions


def test_cell_condensation_equals_numpy():
    rng = np.random.default_rng(0)
    A = rng.normal(size=(19, 19)) + 19 * np.eye(19)
    lpos = np.array([[3 * i, 3 * i + 1, 3 * i + 2, 15 + i] for i in range(4)]).ravel()
    bpos = np.array([12, 13, 14])
    out = (np.zeros((16, 16)), np.zeros((3, 16)), np.zeros((16, 3)), np.zeros((3, 3)),
           np.zeros((3, 3)))
    assert condense_matrix(A, lpos, bpos, *out)
    for got, ref in zip(out, condense_matrix_numpy(A, lpos, bpos)):
        assert np.allclose(got, ref, rtol=1e-13, atol=1e-13)
    A[np.ix_(bpos, bpos)] = 0.0                     # singular bubble block: reported
    assert not condense_matrix(A, lpos, bpos, *out)


def test_cell_system_condensation_equals_numpy():
    """The condensation of an element system (A, b) of the P1/P1 assembly against its twin."""
    from fxcontact.element.cell import condense_system, condense_system_numpy
    rng = np.random.default_rng(1)
    A = rng.normal(size=(19, 19)) + 19 * np.eye(19)
    b = rng.normal(size=19)
    lpos = np.array([[3 * i, 3 * i + 1, 3 * i + 2, 15 + i] for i in range(4)]).ravel()
    bpos = np.array([12, 13, 14])
    out = (np.zeros((16, 16)), np.zeros(16), np.zeros((3, 16)), np.zeros(3))
    assert condense_system(A, b, lpos, bpos, *out)
    for got, ref in zip(out, condense_system_numpy(A, b, lpos, bpos)):
        assert np.allclose(got, ref, rtol=1e-12, atol=1e-12)
    A[np.ix_(bpos, bpos)] = 0.0                     # singular bubble block: reported
    assert not condense_system(A, b, lpos, bpos, *out)


@pytest.mark.parametrize("k", [2, 3])
def test_bubble_inverse_and_schur_equal_numpy(k):
    """The cell kernels' A_bb⁻¹ (cofactors for three bubble unknowns, Gauss–Jordan otherwise)
    and Schur complement against numpy; a singular or non-finite block is reported."""
    from fxcontact.element.cell import bubble_inverse, schur
    rng = np.random.default_rng(k)
    n = 12 + k
    A = rng.normal(size=(n, n)) + n * np.eye(n)
    bpos = np.arange(12, 12 + k)
    lpos = np.arange(12)
    Binv, X, S = np.zeros((k, k)), np.zeros((k, 12)), np.zeros((12, 12))
    assert bubble_inverse(A, bpos, Binv)
    ref = np.linalg.inv(A[np.ix_(bpos, bpos)])
    assert np.allclose(Binv, ref, rtol=1e-13, atol=1e-14)
    schur(A, lpos, bpos, Binv, X, S)
    assert np.allclose(X, ref @ A[np.ix_(bpos, lpos)], rtol=1e-13, atol=1e-14)
    assert np.allclose(S, A[np.ix_(lpos, lpos)] - A[np.ix_(lpos, bpos)] @ X,
                       rtol=1e-13, atol=1e-13)
    B = A.copy()
    B[bpos[-1], bpos] = B[bpos[0], bpos]            # two equal rows: singular
    assert not bubble_inverse(B, bpos, Binv)
    B = A.copy()
    B[bpos[0], bpos[0]] = np.nan
    assert not bubble_inverse(B, bpos, Binv)


def test_vector_kernels_equal_numpy():
    rng = np.random.default_rng(1)
    nc, nl, k = 7, 16, 3
    n = 40 + nc * k
    w_l = rng.integers(0, 40, size=(nc, nl)).astype(np.int32)
    w_b = (40 + np.arange(nc * k).reshape(nc, k)).astype(np.int32)
    X, Y = rng.normal(size=(nc, k, nl)), rng.normal(size=(nc, nl, k))
    B, Abb = rng.normal(size=(nc, k, k)), rng.normal(size=(nc, k, k))
    f, u = rng.normal(size=n), rng.normal(size=n)
    a, b = np.zeros(n), np.zeros(n)
    ej._add_Y(f, w_l, w_b, Y, a)
    ej.add_Y_numpy(f, w_l, w_b, Y, b)
    assert np.allclose(a, b, rtol=1e-13, atol=1e-13)
    a, b = f.copy(), f.copy()
    ej._bubble_solve(f, u, w_l, w_b, X, B, a)
    ej.bubble_solve_numpy(f, u, w_l, w_b, X, B, b)
    assert np.allclose(a, b, rtol=1e-13, atol=1e-13)
    a_b, a_l, b_b, b_l = f.copy(), np.zeros(n), f.copy(), np.zeros(n)
    ej._bubble_product(f, u, w_l, w_b, X, Y, Abb, a_b, a_l)
    ej.bubble_product_numpy(f, u, w_l, w_b, X, Y, Abb, b_b, b_l)
    assert np.allclose(a_b, b_b, rtol=1e-13, atol=1e-13)
    assert np.allclose(a_l, b_l, rtol=1e-13, atol=1e-13)


@pytest.fixture(scope="module", params=["norton-hoff", "elastic", "norton-hoff-friction"])
def iterate(request):
    """A pressed block after one increment, its iterate perturbed (same on any partition up
    to the random perturbation, which is per rank)."""
    name = request.param
    material = MATERIALS[name.replace("-friction", "")]()
    friction = fx.Tresca(mbar=0.5) if name.endswith("friction") else None
    sim = pressed_block(material, solver="condensed-mumps", prefix=f"tej_{name}_",
                        friction=friction)
    sim.run(0.1, 0.1)
    comm = sim.comm
    rng = np.random.default_rng(comm.rank + 7)
    nown = sim.space.num_owned_dofs
    scale = comm.allreduce(np.abs(sim.w.x.array[:nown]).max(initial=0.0), op=MPI.MAX)
    sim.w.x.array[:nown] += 1e-2 * scale * rng.normal(size=nown)
    sim.w.x.scatter_forward()
    return sim


def test_element_newton_is_used(iterate):
    assert iterate.solver.element is not None
    assert iterate.solver.element.kernel in ("ffcx", "hand")


def test_startup_solve_uses_the_hand_kernel(iterate):
    """The start-up solve (the linearised law's first guess) of a Norton–Hoff simulation
    condenses with the hand kernel too (its Jacobian form has no coefficient)."""
    startup = getattr(iterate, "_startup", None)
    if startup is None:
        pytest.skip("no start-up solve for this material")
    el = startup.element
    assert el is not None
    startup.problem.jacobian(None, startup.problem.w.vector, None, None, element=el)
    assert el.assemblies > 0 and el.kernel == "hand"


def _product_error(sim) -> float:
    """‖J' x − A x‖ / ‖A x‖ of the problem's element-condensed Jacobian (FFCx kernels) against
    its assembled MINI Jacobian A, for a random x."""
    prob = sim.problem
    A_full = prob.assemble_jacobian()
    el = CondensedJacobian(prob)
    prob.jacobian(None, prob.w.vector, None, None, element=el)
    assert el.kernel == "ffcx"
    x = A_full.createVecRight()
    rng = np.random.default_rng(3 + sim.comm.rank)
    x.setArray(rng.normal(size=x.getLocalSize()))
    y_full, y_el = x.duplicate(), x.duplicate()
    A_full.mult(x, y_full)
    el.mult(x, y_el)
    y_el.axpy(-1.0, y_full)
    return y_el.norm() / y_full.norm()


def test_product_equals_assembled_jacobian(iterate):
    assert _product_error(iterate) <= 1e-10


def test_unknown_tensor_source_refused(iterate):
    class Source:
        tab = staticmethod(lambda data, c, A, b: None)
    with pytest.raises(ValueError, match="FFCxElementTensors or NortonHoffElementTensors"):
        CondensedJacobian(iterate.problem, tensors=Source())


def test_ffcx_loop_compiled_once_for_every_form():
    """The FFCx kernels are numba first-class functions of one type: the loop over the cells
    is compiled once for the forms of both materials (before: once per form, 2–3 s at every
    new problem and remesh), and each problem gets its own element matrices."""
    for name in ("elastic", "norton-hoff"):
        sim = pressed_block(MATERIALS[name](), solver="condensed-mumps", prefix=f"tej_once_{name}_")
        sim.run(0.1, 0.1)
        assert _product_error(sim) <= 1e-10
    assert len(ej._jacobian_loop_ffcx.signatures) == 1


@pytest.mark.parametrize("bubbles", [True, False], ids=["full", "no-bubble-entries"])
def test_many_right_hand_sides_equal_one_by_one(iterate, bubbles):
    """The condensed right-hand sides of several vectors at once (the active-set prediction's
    columns) equal those of one vector at a time, with bubble entries and without (the
    contact columns: the condensed right-hand side is then their vertex entries)."""
    prob = iterate.problem
    el = CondensedJacobian(prob)
    prob.jacobian(None, prob.w.vector, None, None, element=el)
    rng = np.random.default_rng(5 + iterate.comm.rank)
    fs = []
    for _ in range(3):
        f = prob.w.vector.copy()
        f.setArray(rng.normal(size=f.getLocalSize()))
        if not bubbles:
            f.getArray(readonly=False)[np.unique(el.layout.w_b)] = 0.0
        fs.append(f)
    many = el.condensed_rhs_many(fs)
    xc = el.S.createVecRight()
    for f, rc_many in zip(fs, many):
        el.condensed_rhs(f, xc)
        one = xc.getArray(readonly=True)
        assert np.allclose(rc_many, one, rtol=1e-12, atol=1e-12 * np.abs(one).max())


def test_step_equals_full_mumps_step(iterate):
    """The element-condensed Newton step (its own solver: shell J', ElementCondensedPC) equals
    MUMPS on the MINI Jacobian, and solves the full system."""
    prob = iterate.problem
    A_full = prob.assemble_jacobian()
    b = prob.assemble_residual()
    ksp = PETSc.KSP().create(iterate.comm)
    ksp.setOperators(A_full)
    ksp.setType("preonly")
    ksp.getPC().setType("lu")
    ksp.getPC().setFactorSolverType("mumps")
    x_full = b.duplicate()
    ksp.solve(b, x_full)
    ns = NewtonSolver(prob, SolverOptions(linear_solver="condensed-mumps", prefix="tej_step_"))
    assert ns.element is not None
    assert ns.A is None                     # no MINI matrix: the P1/P1 one only
    ns._jacobian(ns.snes, prob.w.vector, None, None)
    J, P = ns.snes.getKSP().getOperators()
    ns.snes.getKSP().setOperators(J, P)
    x_el = b.duplicate()
    ns.snes.getKSP().solve(b, x_el)
    assert ns.snes.getKSP().getConvergedReason() > 0
    r = b.duplicate()
    A_full.mult(x_el, r)
    r.axpy(-1.0, b)
    assert r.norm() <= 1e-10 * b.norm()
    x_el.axpy(-1.0, x_full)
    assert x_el.norm() <= 1e-10 * x_full.norm()
    ns.destroy()
    ksp.destroy()


@pytest.mark.parametrize("material", ["norton-hoff", "elastic"])
def test_increments_equal_algebraic_condensation(material):
    """Two increments with the element condensation and with the algebraic one: the same
    vertex velocities to 1e-8 and the same Newton iteration counts (within one)."""
    runs = {}
    for flag in (True, False):
        sim = pressed_block(MATERIALS[material](), solver="condensed-mumps",
                            prefix=f"tej_inc_{flag}_")
        sim.solver_options.element_condensation = flag
        sim.run(0.2, 0.1)
        assert (sim.solver.element is not None) == flag
        # by vertex position: two meshes made one after the other may be partitioned
        # differently on 2 ranks
        runs[flag] = (vertex_velocities_by_position(sim),
                      [r["newton_iterations"] for r in sim.history])
    a, b = runs[True][0], runs[False][0]
    assert np.linalg.norm(a - b) <= 1e-8 * np.linalg.norm(b)
    assert len(runs[True][1]) == len(runs[False][1])
    for n_el, n_alg in zip(runs[True][1], runs[False][1]):
        assert_newton_counts_match(n_el, n_alg, bitwise=False)


@pytest.mark.slow
def test_ring_idle_tool_bordered_equals_algebraic(monkeypatch):
    """One ring-rolling increment with the idle mandrel eliminated by the bordered Newton
    matrix (friction on both rolls): element and algebraic condensation agree to 1e-8."""
    from dataclasses import replace

    from fxcontact.processes import RingRollingCase, ring_rolling
    one = RingRollingCase.case2(idle_method="bordered").quick()
    one = replace(one, revolutions=1.0 / one.increments_per_rev)
    res = {}
    for flag in (True, False):
        def options(*a, _flag=flag, **k):
            return SolverOptions(*a, linear_solver="condensed-mumps",
                                 element_condensation=_flag, prefix=f"tej_ring_{_flag}_", **k)
        monkeypatch.setattr(fx, "SolverOptions", options)
        res[flag] = ring_rolling.run(one).history[0]
    a, b = res[True], res[False]
    for k in ("main_force_x", "main_torque", "mandrel_force_x", "mandrel_omega", "ring_omega"):
        assert abs(a[k] - b[k]) <= 1e-8 * abs(b[k]), (k, a[k], b[k])
    assert abs(a["newton_iterations"] - b["newton_iterations"]) <= 1


def test_facet_term_keeps_the_algebraic_condensation(caplog):
    """A residual with a facet term (a traction on the top face) is not condensed element by
    element (the FFCx source needs whole-mesh cell integrals): the solver says why, keeps the
    algebraic condensation, and the increment converges to the answer of MUMPS on the MINI
    system."""
    import logging

    import ufl

    def traction(v, p, w, q):
        msh = w.ufl_domain()
        return 0.05 * ufl.inner(ufl.as_vector((1.0, 0.0, 0.0)), w) * ufl.ds(domain=msh)

    runs = {}
    for solver in ("condensed-mumps", "mumps"):
        sim = pressed_block(MATERIALS["norton-hoff"](), solver=solver, prefix=f"tej_ds_{solver}_")
        sim.extra_residual = traction
        with caplog.at_level(logging.INFO, logger="fxcontact.newton.solver"):
            sim.run(0.1, 0.1)
        runs[solver] = vertex_velocities_by_position(sim)
        if solver == "condensed-mumps":
            assert sim.solver.element is None
            assert sim.solver._condensed_pc is not None
            assert "exterior facet integrals" in caplog.text
    a, b = runs["condensed-mumps"], runs["mumps"]
    assert np.linalg.norm(a - b) <= 1e-8 * np.linalg.norm(b)
