"""Primal–dual Newton for the Norton–Hoff law (fxcontact.element.dual): the dual update and tangent
against their numpy twins and the linearisation of the dual relation, the Jacobian equal to
the consistent one when the dual stress is the primal one, and the m = 0.016 drawing through a
smooth die (benchmarks/drawing_case.py) against the consistent Newton: same solution, fewer
iterations, the same on 1 and 2 ranks."""

from pathlib import Path

import numpy as np
import pytest
from mpi4py import MPI

from helpers import load_file

drawing = load_file("drawing_case", Path(__file__).resolve().parents[1] / "benchmarks" /
                    "drawing_case.py")

#: the test size of tests/test_rigid_plastic.py: 2.5k dofs, m = 0.016, β = 1e3
CASE = dict(R0=5.0, reduction=0.15, half_angle_deg=10.0, h=2.5, h_die=1.25, K=445.0, m=0.016,
            speed=10.0)
DT = 0.025


def _material(m=0.016, reg=1e-3):
    from fxcontact.materials import NortonHoff
    return NortonHoff(K=445.0, m=m, regularization=reg)


def _random_rates(rng, n, scale=1.0):
    a = rng.normal(size=(n, 3, 3)) * scale
    return 0.5 * (a + np.swapaxes(a, 1, 2))


def _dual_relation(mat, eps, s):
    """G(s, ε̇) = z^(1−m) s − 2K dev ε̇, zero for the primal stress."""
    from fxcontact.materials.laws import deviator_np
    return mat._z(eps)[:, None, None] ** (1.0 - mat.m) * s - 2.0 * mat.K * deviator_np(eps)


def test_dual_update_is_the_newton_step_of_the_dual_relation():
    """From the primal stress, the update satisfies the dual relation at the new strain rate to
    second order in the step (the Newton linearisation): G/|Δε̇| falls linearly with |Δε̇|."""
    mat = _material()
    rng = np.random.default_rng(0)
    eps = _random_rates(rng, 50)
    d = _random_rates(rng, 50)
    ratios = []
    for h in (1e-2, 5e-3):
        new = eps + h * d
        s = mat.dual_update(eps, new, mat.stress(eps))
        ratios.append(np.max(np.abs(_dual_relation(mat, new, s))) / h)
    assert ratios[1] < 0.6 * ratios[0]
    # and the primal stress is a fixed point: a zero step returns it
    np.testing.assert_allclose(mat.dual_update(eps, eps, mat.stress(eps)), mat.stress(eps),
                               rtol=1e-13, atol=1e-10)


def test_dual_update_is_capped_by_the_primal_stress():
    mat = _material()
    rng = np.random.default_rng(1)
    eps = _random_rates(rng, 200)
    new = eps + _random_rates(rng, 200, 3.0)
    s = mat.dual_update(eps, new, mat.stress(eps) * rng.uniform(0.0, 1.0, (200, 1, 1)))
    n = np.sqrt(np.einsum("nij,nij->n", s, s))
    sp = mat.stress(new)
    assert np.all(n <= np.sqrt(np.einsum("nij,nij->n", sp, sp)) * (1 + 1e-12))


def test_dual_tangent_is_consistent_at_the_primal_stress_and_definite():
    """With the dual stress equal to the primal one the primal–dual tangent is the consistent
    one; with any dual stress no larger than the primal one it stays positive definite on
    deviatoric increments, its smallest eigenvalue at least 2 m η (η = K z^(m−1))."""
    mat = _material()
    rng = np.random.default_rng(2)
    for eps in _random_rates(rng, 20):
        np.testing.assert_allclose(mat.dual_tangent(eps, mat.stress(eps)), mat.tangent(eps),
                                   rtol=1e-12, atol=1e-9 * np.abs(mat.tangent(eps)).max())
        s = _random_rates(rng, 1)[0]
        s -= np.trace(s) / 3 * np.eye(3)
        sp = mat.stress(eps)
        s *= rng.uniform(0.0, 1.0) * np.linalg.norm(sp) / np.linalg.norm(s)
        T = mat.dual_tangent(eps, s).reshape(9, 9)
        # a basis of the symmetric deviatoric tensors
        B = []
        for i, j in ((0, 1), (0, 2), (1, 2)):
            E = np.zeros((3, 3))
            E[i, j] = E[j, i] = 1 / np.sqrt(2)
            B.append(E.ravel())
        B.append(np.diag([1, -1, 0]).ravel() / np.sqrt(2))
        B.append(np.diag([1, 1, -2]).ravel() / np.sqrt(6))
        B = np.array(B).T
        lam = np.linalg.eigvalsh(0.5 * (B.T @ (T + T.T) @ B))
        eta = mat.K * mat._z(eps[None])[0] ** (mat.m - 1.0)
        assert lam.min() >= 2.0 * mat.m * eta * (1 - 1e-9)


def _unit_cube_space():
    import dolfinx

    from fxcontact.spaces import MixedSpace
    msh = dolfinx.mesh.create_unit_cube(MPI.COMM_WORLD, 3, 3, 3)
    return MixedSpace(msh)


def test_dual_stress_expressions_match_the_numpy_twin():
    """DualStress.begin and .accept on linear velocity fields (constant strain rates) give the
    numpy primal stress and dual update at every quadrature point."""
    from fxcontact.element.dual import DualStress
    sp = _unit_cube_space()
    mat = _material()
    ds = DualStress(mat, sp.W, sp.quadrature_degree)
    rng = np.random.default_rng(4)
    L0, L1 = rng.normal(size=(3, 3)), rng.normal(size=(3, 3))
    w = __import__("dolfinx").fem.Function(sp.W)

    def load(L):
        V, dofs = sp.W.sub(0).collapse()
        f = __import__("dolfinx").fem.Function(V)
        f.interpolate(lambda x: L @ x)
        w.x.array[np.asarray(dofs)] = f.x.array
        w.x.scatter_forward()
        return w.vector

    ds.begin(load(L0))
    e0, e1 = 0.5 * (L0 + L0.T), 0.5 * (L1 + L1.T)
    s = ds.s.x.array.reshape(-1, 3, 3)
    np.testing.assert_allclose(s, np.broadcast_to(mat.stress(e0[None])[0], s.shape),
                               rtol=1e-10, atol=1e-8)
    ds.accept(load(L1))
    s = ds.s.x.array.reshape(-1, 3, 3)
    ref = mat.dual_update(e0[None], e1[None], mat.stress(e0[None]))[0]
    np.testing.assert_allclose(s, np.broadcast_to(ref, s.shape), rtol=1e-10, atol=1e-8)
    assert ds.updates == 1


def test_primal_dual_jacobian_equals_the_consistent_one_at_the_primal_stress():
    """Assembled on a unit cube with a nonlinear velocity field: the primal–dual Jacobian as the
    Simulation builds it (DualStress.tangent_form + the pressure terms) is the consistent one
    (ufl.derivative of the residual) when the dual stress is the primal stress, and for another
    dual stress equals ufl.derivative + DualStress.jacobian_correction (an independent
    composition: UFL's derivative of the stress plus the rank-one difference)."""
    import dolfinx
    import ufl

    from fxcontact import compat
    from fxcontact.element.dual import DualStress
    sp = _unit_cube_space()
    mat = _material()
    w = dolfinx.fem.Function(sp.W)
    V, dofs = sp.W.sub(0).collapse()
    f = dolfinx.fem.Function(V)
    f.interpolate(lambda x: np.vstack([x[0] ** 2 + x[1], x[1] * x[2], np.sin(x[2] + x[0])]))
    w.x.array[np.asarray(dofs)] = f.x.array
    w.x.array[np.asarray(sp.W.sub(1).collapse()[1])] = 0.3
    w.x.scatter_forward()
    v, p = ufl.split(w)
    wt, q = ufl.TestFunctions(sp.W)
    F = mat.residual(v, p, wt, q, sp.dx, 1.0)
    dw = ufl.TrialFunction(sp.W)
    dv, dp = ufl.split(dw)
    ds = DualStress(mat, sp.W, sp.quadrature_degree)
    J0 = compat.form(ufl.derivative(F, w, dw))
    J1 = compat.form(ds.tangent_form(v, dv, wt, sp.dx)
                     + mat.incompressibility_ufl(dv, dp, wt, q, sp.dx))
    Jc = compat.form(ufl.derivative(F, w, dw) + ds.jacobian_correction(v, dv, wt, sp.dx))

    def assemble(form):
        A = dolfinx.fem.petsc.assemble_matrix(form)
        A.assemble()
        return A

    ds.begin(w.vector)
    A0 = assemble(J0)
    for form in (J1, Jc):
        A = assemble(form)
        A.axpy(-1.0, A0)
        assert A.norm() <= 1e-12 * A0.norm()
    ds.s.x.array[:] *= 0.5
    A1, Ac = assemble(J1), assemble(Jc)
    A1.axpy(-1.0, Ac)
    assert A1.norm() <= 1e-12 * Ac.norm()
    Ac.axpy(-1.0, A0)
    assert Ac.norm() > 1e-3 * A0.norm()


def _drawing(material_tangent, n_inc=3, line_search="bt"):
    from fxcontact.newton.solver import SolverOptions
    sim, _, _ = drawing.drawing_simulation(MPI.COMM_WORLD, solver_options=SolverOptions(
        max_it=100, line_search=line_search, line_search_fallback=None,
        material_tangent=material_tangent), **CASE)
    for _ in range(n_inc):
        sim.step(DT, max_cutbacks=0)
    its = [r["newton_iterations_all"] for r in sim.history]
    return [4.0 * r["front_z"] for r in sim.history], its, sim


@pytest.fixture(scope="module")
def consistent_run():
    return _drawing("consistent")


@pytest.mark.slow
def test_primal_dual_same_drawing_fewer_newton_iterations(consistent_run):
    """m = 0.016, β = 1e3, ε̇₀ = 1e-6 1/s, the active-set prediction on (the default with the
    direct solver): the same drawing forces to 1e-7, at most half the Newton iterations.
    Measured (2.5k dofs, dt = 0.025 s): consistent 36, 12, 12; primal–dual 10, 6, 11."""
    f0, its0, _ = consistent_run
    f1, its1, sim = _drawing("primal-dual")
    print("Newton iterations: consistent", its0, "primal-dual", its1)
    assert sim.dual is not None and sim.dual.updates > 0
    np.testing.assert_allclose(f1, f0, rtol=1e-7)
    assert sum(its1) <= 0.5 * sum(its0)
    assert max(its1) <= 15


def test_auto_material_tangent():
    """"auto" is the primal–dual tangent for Norton–Hoff with m < 1 and the consistent one
    otherwise; a bad value and a material without the dual law are refused clearly."""
    from fxcontact.materials import LinearElastic
    from fxcontact.materials.forms import uses_dual_stress
    from fxcontact.newton.solver import SolverOptions
    assert uses_dual_stress(_material(), "auto")
    assert not uses_dual_stress(_material(m=1.0), "auto")
    assert not uses_dual_stress(_material(), "consistent")
    assert not uses_dual_stress(LinearElastic(E=1.0, nu=0.3), "auto")
    with pytest.raises(ValueError, match="material tangent"):
        SolverOptions(material_tangent="dual")
    from fxcontact.element.dual import DualStress
    sp = _unit_cube_space()
    with pytest.raises(ValueError, match="Norton-Hoff"):
        DualStress(LinearElastic(E=1.0, nu=0.3), sp.W, sp.quadrature_degree)


def test_written_out_jacobian_only_for_the_plain_norton_hoff_residual():
    """Simulation writes the primal–dual Jacobian out only when the material's residual is
    NortonHoff's own: a subclass that redefines the stress gets ufl.derivative + the
    correction (its tangent is not the one written out); one that only changes the exponent
    (``exponent_ufl``, the bar-rolling demo's start-up) keeps the written-out form, which
    uses it."""
    import ufl

    from fxcontact.materials import NortonHoff
    from fxcontact.materials.forms import standard_norton_hoff

    class OwnStress(NortonHoff):
        def stress_ufl(self, eps):
            return 2.0 * super().stress_ufl(eps)

    class OwnExponent(NortonHoff):
        def exponent_ufl(self):
            return 0.5 * self.m

    assert standard_norton_hoff(_material())
    assert not standard_norton_hoff(OwnStress(K=100.0, m=0.1))
    assert standard_norton_hoff(OwnExponent(K=100.0, m=0.1))
    # the written-out tangent follows exponent_ufl: at the primal stress it is the derivative
    # of OwnExponent's stress
    mat = OwnExponent(K=100.0, m=0.1)
    eps = ufl.as_matrix(np.array([[0.3, 0.1, 0.0], [0.1, -0.2, 0.05], [0.0, 0.05, -0.1]]))
    E = ufl.variable(eps)
    de = ufl.as_matrix(np.array([[0.0, 1.0, 0.0], [1.0, 0.5, 0.0], [0.0, 0.0, -0.5]]))
    ew = ufl.as_matrix(np.array([[1.0, 0.0, 0.2], [0.0, -1.0, 0.0], [0.2, 0.0, 0.0]]))
    ref = ufl.inner(ufl.diff(mat.stress_ufl(E), E), ufl.outer(ew, de))
    val = mat.dual_tangent_ufl(eps, mat.stress_ufl(eps), de, ew)
    from ufl.algorithms import expand_derivatives
    a = float(expand_derivatives(ref)(()))   # constant expressions: evaluated in Python
    b = float(val(()))
    assert abs(a - b) <= 1e-12 * abs(a)


def _ufl_and_kernel_duals(m):
    """A distorted box's MINI space: the material, layout, a state function, and two dual
    stresses, by the UFL expressions and by the numba kernel."""
    import dolfinx
    from fxcontact import MixedSpace
    from fxcontact.element.dual import DualStress
    from fxcontact.element.tensors import P1P1Layout
    from helpers import box_mesh
    sp = MixedSpace(box_mesh(MPI.COMM_WORLD, n=(3, 3, 3), perturb=0.25))
    mat = _material(m=m, reg=1e-2)
    lay = P1P1Layout(sp.W)
    w = dolfinx.fem.Function(sp.W)
    ref = DualStress(mat, sp.W, sp.quadrature_degree)
    fast = DualStress(mat, sp.W, sp.quadrature_degree)
    assert fast.use_kernel(sp)
    return mat, lay, w, ref, fast


@pytest.mark.parametrize("m", [0.016, 0.3])
def test_dual_kernel_equals_the_expressions_and_the_numpy_twin(m):
    """The numba dual update (fxcontact.element.dual) against dolfinx's evaluation of the UFL
    expressions, on a distorted mesh with a nonlinear velocity field and bubbles, over a
    primal start and three updates (each with another field), and against its numpy twin; the
    cap of the update is reached on some points."""
    from fxcontact.element.dual import dual_update_numpy
    from test_element_condense import set_state
    mat, lay, w, ref, fast = _ufl_and_kernel_duals(m)
    kern = fast.kernel
    ncell = lay.num_cells
    capped = 0
    for k, phase in enumerate([0.0, 0.4, 1.1, -0.7]):
        set_state(lay, w, phase)
        s_before = fast.s.x.array.copy()
        w_before = fast._w_new.x.array.copy()
        for ds in (ref, fast):
            (ds.begin if k == 0 else ds.accept)(w.vector)
        a = fast.s.x.array.reshape(-1, 3, 3)
        b = ref.s.x.array.reshape(-1, 3, 3)
        scale = np.abs(b).max()
        assert np.abs(a - b).max() <= 1e-11 * scale
        # numpy twin on the owned cells
        cells = np.arange(ncell)
        coords = kern._x[kern._xdofs[cells]]
        blocks = kern._sdofs[cells]
        tw = dual_update_numpy(coords, w_before[kern._wdofs[cells]],
                               w.x.array[kern._wdofs[cells]],
                               s_before.reshape(-1, 3, 3)[blocks], mat.K, mat.m,
                               mat.regularization, kern.g1, kern.gb, kern.share,
                               0 if k == 0 else 1)
        assert np.abs(tw - a[blocks]).max() <= 1e-11 * scale
        if k:
            sp_new = dual_update_numpy(coords, w_before[kern._wdofs[cells]],
                                       w.x.array[kern._wdofs[cells]], None, mat.K, mat.m,
                                       mat.regularization, kern.g1, kern.gb, kern.share, 0)
            capped += int(np.count_nonzero(np.isclose(
                np.linalg.norm(a[blocks], axis=(2, 3)), np.linalg.norm(sp_new, axis=(2, 3)),
                rtol=1e-12)))
    assert MPI.COMM_WORLD.allreduce(capped) > 0


def test_dual_kernel_kept_coefficients_follow_state_and_geometry():
    """The kernel keeps the coefficient 2K z^(m−1) of the last state and reads it in the next
    update when that update starts from the same state on the same geometry. It must not read it
    after the mesh moved or from another starting state: each update equals the UFL
    expressions, and the kept values are used only where they apply."""
    from fxcontact.element.dual import dual_update_numpy
    from test_element_condense import set_state
    mat, lay, w, ref, fast = _ufl_and_kernel_duals(0.016)
    kern = fast.kernel

    def check(step):
        for ds in (ref, fast):
            step(ds)
        a, b = fast.s.x.array, ref.s.x.array
        assert np.abs(a - b).max() <= 1e-11 * np.abs(b).max()

    set_state(lay, w, 0.3)
    check(lambda ds: ds.begin(w.vector))
    set_state(lay, w, 0.9)
    check(lambda ds: ds.accept(w.vector))
    assert kern.cache_hits == 1          # the update from the state of the primal start
    # the mesh moves (a configuration update): the kept values are stale
    x = lay.W.mesh.geometry.x
    x[:, :3] += 0.02 * np.sin(3.0 * x[:, [1, 2, 0]])
    set_state(lay, w, -0.4)
    check(lambda ds: ds.accept(w.vector))
    assert kern.cache_hits == 1
    set_state(lay, w, 1.7)
    check(lambda ds: ds.accept(w.vector))
    assert kern.cache_hits == 2
    # an update from a state other than the last one: computed afresh (numpy twin)
    w_a = w.x.array.copy()
    set_state(lay, w, 0.1)
    w_b = w.x.array.copy()
    w_a[kern._wdofs[:, 0]] *= 1.5
    s_before = fast.s.x.array.copy()
    kern(1, w_a, w_b)
    assert kern.cache_hits == 2
    cells = np.arange(lay.num_cells)
    blocks = kern._sdofs[cells]
    tw = dual_update_numpy(kern._x[kern._xdofs[cells]], w_a[kern._wdofs[cells]],
                           w_b[kern._wdofs[cells]], s_before.reshape(-1, 3, 3)[blocks],
                           mat.K, mat.m, mat.regularization, kern.g1, kern.gb, kern.share, 1)
    a = fast.s.x.array.reshape(-1, 3, 3)[blocks]
    assert np.abs(tw - a).max() <= 1e-11 * np.abs(tw).max()
