"""Friction at contact nodes (THEORY §9): kernel twin and finite-difference checks of every law on
both Coulomb–Tresca branches (explicit and implicit), the same through NodalContact for moving and
rotating tools, and bad input."""

import numpy as np
import pytest
from mpi4py import MPI

from fxcontact.contact.friction import (LAW_COULOMB, LAW_NORTON, LAW_TRESCA, Coulomb,
                                        Frictionless, Norton, ShearLimit, Tresca,
                                        friction_kernel, friction_kernel_numpy)
from fxcontact.contact.nodal import NodalContact
from fxcontact.theory.forming import flow_stress
from fxcontact.kinematics import CartesianUpdate
from fxcontact.materials import LinearElastic, NortonHoff
from fxcontact.tools.analytic import Cylinder, Plane, Sphere

from helpers import FakeBoundary as _FakeBoundary


def _random_case(n, law, seed=0, d=3):
    rng = np.random.default_rng(seed)
    nrm = rng.normal(size=(n, d))
    nrm /= np.linalg.norm(nrm, axis=1)[:, None]
    S = 0.5 + rng.random(n)
    codes = np.full(n, law, dtype=np.int64)
    mu = 0.1 + 0.5 * rng.random(n)
    pn = 1.0 + 2.0 * rng.random(n)
    # half the nodes on the Coulomb branch (μ p < m̄k), half on the Tresca limit
    tau_max = np.where(np.arange(n) % 2 == 0, 2.0 * mu * pn, 0.5 * mu * pn)
    visc = 0.5 + rng.random(n)
    q = 0.1 + 0.8 * rng.random(n)
    dv = rng.normal(size=(n, d))
    active = np.ones(n, dtype=bool)
    active[-1] = False
    return S, codes, mu, tau_max, visc, q, pn, dv, nrm, active


@pytest.mark.parametrize("law", [LAW_COULOMB, LAW_TRESCA, LAW_NORTON])
@pytest.mark.parametrize("implicit", [False, True])
def test_kernel_twin(law, implicit):
    S, codes, mu, tau_max, visc, q, pn, dv, nrm, active = _random_case(9, law)
    dpn = np.random.default_rng(1).normal(size=dv.shape) if implicit else np.zeros((0, 3))
    a = friction_kernel(S, codes, mu, tau_max, visc, q, pn, dpn, dv, nrm, 0.3, active, True)
    b = friction_kernel_numpy(S, codes, mu, tau_max, visc, q, pn, dpn, dv, nrm, 0.3, active,
                              True)
    for x, y in zip(a, b):
        assert np.allclose(x, y, rtol=1e-13, atol=1e-14)
    if law == LAW_COULOMB:   # both branches present
        assert set(a[3][:-1].tolist()) == {1, 2}


@pytest.mark.parametrize("law", [LAW_COULOMB, LAW_TRESCA, LAW_NORTON])
def test_kernel_gradient_of_potential(law):
    """Explicit friction (fixed threshold): r = ∂Ψ/∂v, K = ∂r/∂v (central differences)."""
    S, codes, mu, tau_max, visc, q, pn, dv, nrm, active = _random_case(8, law, seed=2)
    v0 = 0.2
    empty = np.zeros((0, 3))

    def potential(dvx):
        vn = np.einsum("ni,ni->n", dvx, nrm)
        dvt = dvx - vn[:, None] * nrm
        s = np.sqrt(np.einsum("ni,ni->n", dvt, dvt) + v0**2)
        if law == LAW_NORTON:
            psi = S * visc / (q + 1) * s ** (q + 1)
        else:
            tl = np.minimum(mu * pn, tau_max) if law == LAW_COULOMB else tau_max
            psi = S * tl * s
        return np.where(active, psi, 0.0)

    r, K, tau, _ = friction_kernel(S, codes, mu, tau_max, visc, q, pn, empty, dv, nrm, v0,
                                   active, True)
    assert np.allclose(r, -S[:, None] * tau)
    assert np.allclose(np.einsum("ni,ni->n", tau, nrm), 0.0, atol=1e-14)  # tangential
    eps = 1e-6
    g_fd = np.zeros_like(dv)
    K_fd = np.zeros_like(K)
    for a in range(3):
        e = np.zeros_like(dv)
        e[:, a] = eps
        g_fd[:, a] = (potential(dv + e) - potential(dv - e)) / (2 * eps)
        rp = friction_kernel(S, codes, mu, tau_max, visc, q, pn, empty, dv + e, nrm, v0,
                             active, False)[0]
        rm = friction_kernel(S, codes, mu, tau_max, visc, q, pn, empty, dv - e, nrm, v0,
                             active, False)[0]
        K_fd[:, :, a] = (rp - rm) / (2 * eps)
    assert np.linalg.norm(r - g_fd) <= 1e-8 * np.linalg.norm(r)
    assert np.linalg.norm(K - K_fd) <= 1e-7 * np.linalg.norm(K)
    assert np.allclose(K, np.transpose(K, (0, 2, 1)))   # explicit: symmetric


def test_kernel_implicit_coulomb_jacobian():
    """Implicit Coulomb: p_n = ρ[h(v)]₊ with h linear in v; the non-symmetric term makes K the
    exact derivative of r on the Coulomb branch and vanishes on the Tresca branch."""
    S, codes, mu, tau_max, visc, q, _, dv, nrm, active = _random_case(10, LAW_COULOMB, seed=4)
    rng = np.random.default_rng(5)
    rho, v0 = 3.0, 0.1
    gh = rng.normal(size=dv.shape)          # ∇h
    h0 = 0.5 + rng.random(len(S))
    tau_max = np.where(np.arange(len(S)) % 2 == 0, 1e3, 0.05)   # Coulomb / Tresca branches

    def terms(dvx, jac):
        h = h0 + np.einsum("ni,ni->n", gh, dvx - dv)
        pn = rho * np.maximum(h, 0.0)
        dpn = rho * (h > 0)[:, None] * gh
        return friction_kernel(S, codes, mu, tau_max, visc, q, pn, dpn, dvx, nrm, v0, active,
                               jac)

    r, K, _, branch = terms(dv, True)
    assert set(branch[:-1].tolist()) == {1, 2}
    eps = 1e-6
    K_fd = np.zeros_like(K)
    for a in range(3):
        e = np.zeros_like(dv)
        e[:, a] = eps
        K_fd[:, :, a] = (terms(dv + e, False)[0] - terms(dv - e, False)[0]) / (2 * eps)
    assert np.linalg.norm(K - K_fd) <= 1e-7 * np.linalg.norm(K)
    coul = branch == 1
    asym = np.linalg.norm(K - np.transpose(K, (0, 2, 1)), axis=(1, 2))
    assert np.all(asym[coul] > 1e-3) and np.allclose(asym[~coul], 0.0)


# ------------------------------------------------------------------ through NodalContact
class _FakeSim:
    def __init__(self, material, w):
        self.kinematics = CartesianUpdate()
        self.material = material
        self.w = w
        self.w_prev = type("F", (), {"x": type("X", (), {"array": w})()})()


TOOLS = {
    "plane": lambda: Plane((0, 0, 1.0), (0.2, -0.1, -1.0), velocity=(0.4, 0, -0.3)),
    "rolling-cylinder": lambda: Cylinder((0, 0, 3.0), (1, 0.2, 0), 2.0,
                                         velocity=(0.1, 0.0, -0.2), angular_velocity=0.7),
    "spinning-sphere": lambda: Sphere((0.2, 0.1, 3.0), 2.0, velocity=(0, 0, -0.2),
                                      angular_velocity=1.3, axis=(0.3, 1.0, 0.2)),
}

LAWS = {
    "coulomb": Coulomb(0.3, mbar=0.8, shear_limit=0.9),   # both branches appear
    "pure-coulomb": Coulomb(0.4),
    "tresca": Tresca(0.6, shear_limit=1.5),
    "norton": Norton(0.5, 0.2, K=2.0),
}


def _contact_case(tool, law, scheme, mode, seed=3):
    rng = np.random.default_rng(seed)
    n = 14
    t0, dt = 0.3, 0.1
    tl = TOOLS[tool]()
    y = rng.uniform(-1.0, 1.0, (n, 3)) + np.array([1.5, 0.3, 0.9])
    pr = tl.project(y, t0)
    s = np.linspace(-0.25, 0.1, n)
    x = pr.point + s[:, None] * pr.normal
    v = rng.normal(scale=0.5, size=(n, 3))
    b = _FakeBoundary(n)
    # penalty small enough that implicit Coulomb pressures straddle the Tresca limit
    c = NodalContact(b, tl, scheme=scheme, penalty=1.0, max_initial_penetration=10.0,
                     friction=law, friction_mode=mode, slip_velocity=0.05,
                     friction_tangent="consistent")
    sim = _FakeSim(LinearElastic(1.0, 0.3), v.ravel())
    c.begin_increment(sim, t0, dt, x)
    if mode == "explicit":  # pressures of a "previous increment"
        c._p_prev = np.where(np.arange(n) % 3 == 0, 0.0, 0.5 + 5.0 * rng.random(n))
    c.begin_solve()
    return c, v


def _assert_jacobian_fd(c, v, K, eps=1e-6):
    """K equals the central finite difference of the contact + friction residual at the nodes
    away from the contact kink h = 0."""
    K_fd = np.zeros_like(K)
    for a in range(3):
        e = np.zeros_like(v)
        e[:, a] = eps
        K_fd[:, :, a] = (c.evaluate((v + e).ravel(), False).residual
                         - c.evaluate((v - e).ravel(), False).residual) / (2 * eps)
    c.evaluate(v.ravel(), False)
    far = np.abs(c._h) > 1e-3
    assert np.linalg.norm((K - K_fd)[far]) <= 1e-6 * np.linalg.norm(K[far])


@pytest.mark.parametrize("mode", ["explicit", "implicit"])
@pytest.mark.parametrize("law", list(LAWS))
@pytest.mark.parametrize("tool", list(TOOLS))
def test_contact_friction_jacobian_fd(tool, law, mode):
    """Explicit contact scheme (normal and projection fixed in the increment): the Jacobian of
    contact + friction is the exact derivative of the residual for moving and rotating tools,
    with implicit (non-symmetric Coulomb term) and explicit friction."""
    c, v = _contact_case(tool, LAWS[law], "explicit", mode)
    terms = c.evaluate(v.ravel(), True)
    r, K = terms.residual, terms.jacobian
    assert np.any(c._branch > 0)
    if law == "coulomb":
        assert {1, 2} <= set(c._branch.tolist())
    _assert_jacobian_fd(c, v, K)
    # friction force tangential to the tool, against the slip relative to the tool surface
    nrm = c._cur_proj.normal
    assert np.allclose(np.einsum("ni,ni->n", c._rf, nrm), 0.0, atol=1e-12)
    assert np.all(np.einsum("ni,ni->n", c._rf, c._dvt) >= 0.0)


@pytest.mark.parametrize("law", ["coulomb", "norton"])
def test_implicit_scheme_plane_fd(law):
    """Implicit contact scheme on a plane (normal independent of the iterate): exact Jacobian
    of contact + implicit friction."""
    c, v = _contact_case("plane", LAWS[law], "implicit", "implicit", seed=7)
    K = c.evaluate(v.ravel(), True).jacobian
    _assert_jacobian_fd(c, v, K)


def test_rotating_tool_slip_velocity():
    """The slip is measured against the tool's material velocity: a node moving with the
    surface of a spinning roll does not slip (no friction force beyond the regularisation)."""
    roll = Cylinder((0, 0, 3.0), (0, 1, 0), 2.0, angular_velocity=2.0)
    b = _FakeBoundary(1)
    x = np.array([[0.3, 0.0, 1.0]])
    pr = roll.project(x, 0.0)
    x = pr.point - 0.01 * pr.normal                  # slightly inside the roll, below its axis
    c = NodalContact(b, roll, scheme="implicit", penalty=10.0, friction=Coulomb(0.3),
                     slip_velocity=1e-3)
    p = roll.project(x, 0.0).point
    v_surf = roll.velocity(p, 0.0)
    c.begin_increment(_FakeSim(LinearElastic(1.0, 0.3), v_surf.ravel()), 0.0, 1e-6, x)
    c.begin_solve()
    c.evaluate(v_surf.ravel(), False)
    assert np.linalg.norm(c._dvt) < 1e-6
    # moving at the opposite speed: full Coulomb force, directed along the surface velocity
    c.evaluate((-v_surf).ravel(), False)
    f_body = -c._rf[0]
    pn = c.pressures()[0]
    assert np.isclose(np.linalg.norm(f_body), 0.3 * pn * b.areas[0], rtol=1e-6)
    assert np.dot(f_body, v_surf[0]) > 0


# ------------------------------------------------------------------ bad input
@pytest.mark.parametrize("make, words", [
    (lambda: Coulomb(-0.1), "mu"),
    (lambda: Coulomb(0.3, mbar=1.5), "mbar"),
    (lambda: Tresca(-0.2), "mbar"),
    (lambda: Tresca(float("nan")), "mbar"),
    (lambda: Norton(0.3, 0.0), "q"),
    (lambda: Norton(-1.0, 0.2), "alpha_f"),
    (lambda: Tresca(0.5, shear_limit=0.0), "shear_limit"),
    (lambda: Norton(0.3, 0.2, K=-5.0), "K"),
])
def test_bad_law_parameters(make, words):
    with pytest.raises(ValueError, match=words):
        make()


def test_bad_friction_specification():
    die = Plane((0, 0, 1), (0, 0, -1), name="die")
    b = _FakeBoundary(3)
    with pytest.raises(ValueError, match="not one of this contact's tools"):
        NodalContact(b, die, penalty=1.0, friction={"roll": Coulomb(0.3)})
    other = Plane((0, 0, 0), (0, 0, 1), name="anvil")
    with pytest.raises(ValueError, match="not one of this contact's tools"):
        NodalContact(b, die, penalty=1.0, friction={other: Coulomb(0.3)})
    with pytest.raises(ValueError, match="friction law"):
        NodalContact(b, die, penalty=1.0, friction=0.3)
    with pytest.raises(ValueError, match="2 laws for 1 tools"):
        NodalContact(b, die, penalty=1.0, friction=[Coulomb(0.3), Frictionless()])
    with pytest.raises(ValueError, match="slip_velocity"):
        NodalContact(b, die, penalty=1.0, friction=Coulomb(0.3), slip_velocity=0.0)
    with pytest.raises(ValueError, match="friction_mode"):
        NodalContact(b, die, penalty=1.0, friction=Coulomb(0.3), friction_mode="lagged")


@pytest.mark.parametrize("law, words", [(Tresca(0.5), "shear_limit"),
                                        (Coulomb(0.3, mbar=0.5), "shear_limit"),
                                        (Norton(0.3, 0.2), "K=")])
def test_elastic_body_needs_material_data(law, words):
    die = Plane((0, 0, 1), (0, 0, -1), velocity=(0, 0, -1), name="die")
    b = _FakeBoundary(3)
    c = NodalContact(b, die, penalty=1.0, friction=law)
    x = np.array([[0.0, 0.0, 0.5], [0.3, 0.0, 0.5], [0.0, 0.3, 0.5]])
    with pytest.raises(ValueError, match=words):
        c.begin_increment(_FakeSim(LinearElastic(1.0, 0.3), np.zeros(9)), 0.0, 0.1, x)


def test_slip_velocity_needs_a_speed():
    die = Plane((0, 0, 1), (0, 0, -1), name="die")          # static tool, body at rest
    b = _FakeBoundary(3)
    c = NodalContact(b, die, penalty=1.0, friction=Coulomb(0.3))
    x = np.array([[0.0, 0.0, 0.5], [0.3, 0.0, 0.5], [0.0, 0.3, 0.5]])
    with pytest.raises(ValueError, match="slip_velocity"):
        c.begin_increment(_FakeSim(NortonHoff(1.0, 0.2), np.zeros(9)), 0.0, 0.1, x)


def test_shear_limit_sources():
    """A law says which k its Tresca limit uses: the local nodal rate (default), the material at
    a given strain rate (the same k at every node, the material's k at that rate), or a given
    k (a number and ShearLimit.given are the same law)."""
    mat = NortonHoff(K=2.0, m=0.2, regularization=1e-9)
    assert Tresca(0.5).k_source.kind == "local rate"
    assert Tresca(0.5, shear_limit=1.5) == Tresca(0.5, ShearLimit.given(1.5))
    assert Tresca(0.5, ShearLimit.local_rate()) == Tresca(0.5)
    at = ShearLimit.at_strain_rate(0.3)
    assert Coulomb(0.3, 0.5, shear_limit=at).k_source.kind == "strain rate"
    assert at.k(mat) == pytest.approx(flow_stress(2.0, 0.2, 0.3) / np.sqrt(3.0), rel=1e-9)
    # through the contact: the Tresca threshold m̄ k of every node is the material's k at the
    # rate, and the terms equal those of the same k given as a number
    die = Plane((0, 0, 1), (0, 0, -1), velocity=(0.5, 0, -0.2), name="die")
    x = np.array([[0.0, 0.0, 0.98], [0.3, 0.0, 0.99], [0.0, 0.3, 1.02]])
    v = np.array([0.1, 0.0, -0.3, 0.0, 0.2, -0.1, 0.0, 0.0, 0.0])
    terms = []
    for law in (Tresca(0.5, at), Tresca(0.5, shear_limit=float(at.k(mat)))):
        c = NodalContact(_FakeBoundary(3), die, penalty=1.0, friction=law, slip_velocity=0.05)
        c.begin_increment(_FakeSim(mat, v), 0.0, 0.1, x)
        c.begin_solve()
        t = c.evaluate(v.reshape(-1, 3), True)
        terms.append((t.residual, t.jacobian))
        h, g, _, tool, _, _ = c._constraint(v.reshape(-1, 3), False)
        assert np.all(c.friction_arguments(h, g, tool)["tau_max"] == 0.5 * at.k(mat))
    assert np.array_equal(terms[0][0], terms[1][0]) and np.array_equal(terms[0][1], terms[1][1])
    assert "k of the material at the strain rate 0.3 1/s" in \
        NodalContact(_FakeBoundary(3), die, penalty=1.0, friction=Tresca(0.5, at)).summary()


def test_run_summary_names_the_penalty_and_the_shear_limit(caplog):
    """The run's summary line gives each contact's penalty as resolved (β at the estimated
    strain rate) and, per tool with friction, the law and the k it uses."""
    import logging

    from fxcontact.contact.boundary import ContactBoundary
    from fxcontact.meshing import BLOCK_TAGS, block
    from fxcontact.simulation import Simulation
    from fxcontact.spaces import MixedSpace

    msh, _, ft = block(MPI.COMM_WORLD, (0, 0, 0), (1, 1, 1), 0.5)
    sp = MixedSpace(msh)
    sim = Simulation(sp, NortonHoff(K=10.0, m=0.2), progress=False)
    f = {k: sim.facets(ft, v) for k, v in BLOCK_TAGS.items()}
    for key, comp in (("xmin", 0), ("ymin", 1), ("zmin", 2)):
        sim.add_velocity_bc(f[key], 0.0, comp)
    die = Plane((0, 0, 1.0), (0, 0, -1), velocity=(0, 0, -1.0), name="die")
    sim.add_contributor(NodalContact(ContactBoundary(sp, ft, BLOCK_TAGS["zmax"]), die,
                                     friction=Tresca(0.3)))
    with caplog.at_level(logging.INFO, logger="fxcontact.simulation"):
        sim.run(0.02, 0.02)
    text = caplog.text
    assert "contact 'contact': implicit, penalty rho = " in text
    assert "beta = 1000 at the representative strain rate" in text
    assert "friction 'die' Tresca(mbar=0.3), k of the material at each node's local strain " \
           "rate" in text
