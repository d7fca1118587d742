"""Tests of the configuration updates and of the fully implicit gap composition."""

import math

import numpy as np
import pytest

from fxcontact.kinematics import cartesian_update, cylindrical_update, gap_derivatives
from fxcontact.tools.analytic import Cone, Cylinder, Sphere

BACKENDS = ("numba", "numpy")
CENTER = np.array([0.4, -0.3, 0.2])
AXIS = np.array([0.2, -0.1, 1.0])


def unit(v):
    v = np.asarray(v, dtype=float)
    return v / np.linalg.norm(v)


def ring_nodes(n, seed, rmin=1.0, rmax=2.0, center=CENTER, axis=AXIS):
    """Random nodes of an annulus about (center, axis)."""
    rng = np.random.default_rng(seed)
    w = unit(axis)
    _, _, vt = np.linalg.svd(w[None, :])
    u, v = vt[1], vt[2]
    r = rng.uniform(rmin, rmax, n)
    th = rng.uniform(0, 2 * np.pi, n)
    z = rng.uniform(-0.5, 0.5, n)
    return center + z[:, None] * w + r[:, None] * (np.cos(th)[:, None] * u
                                                   + np.sin(th)[:, None] * v)


def radius(x, center=CENTER, axis=AXIS):
    return np.linalg.norm(np.cross(x - center, unit(axis)), axis=1)


def richardson_v(f, v, h):
    """d f(v)/d v_a for every node at once (f acts node-wise): shape f(v).shape + (3,)."""
    cols = []
    for a in range(3):
        e = np.zeros_like(v)
        e[:, a] = 1.0

        def cd(hh):
            return (f(v + hh * e) - f(v - hh * e)) / (2 * hh)

        cols.append((4 * cd(h / 2) - cd(h)) / 3)
    return np.stack(cols, axis=-1)


@pytest.mark.parametrize("backend", BACKENDS)
def test_rigid_rotation_preserves_radius(backend):
    x = ring_nodes(200, 0, rmin=0.5, rmax=3.0)
    om, dt = 5.0, 0.1  # ω·dt = 0.5
    w = unit(AXIS)
    v = om * np.cross(w, x - CENTER)
    X, _, _ = cylindrical_update(x, v, dt, CENTER, AXIS, backend=backend)
    r0 = radius(x)
    np.testing.assert_allclose(radius(X), r0, rtol=1e-14)
    np.testing.assert_allclose((X - CENTER) @ w, (x - CENTER) @ w, atol=1e-14)
    # the rotation angle is exactly ω·dt
    cosang = np.einsum("ni,ni->n", np.cross(w, np.cross(x - CENTER, w)),
                       np.cross(w, np.cross(X - CENTER, w))) / r0**2
    np.testing.assert_allclose(cosang, math.cos(om * dt), atol=1e-14)
    # the Cartesian update drifts by r(√(1+(ω dt)²) − 1)
    Xc, _, _ = cartesian_update(x, v, dt)
    np.testing.assert_allclose(radius(Xc) - r0, r0 * (math.sqrt(1 + (om * dt) ** 2) - 1),
                               rtol=1e-12)
    assert np.all(radius(Xc) - r0 > 0.1 * r0)


@pytest.mark.parametrize("backend", BACKENDS)
def test_cylindrical_jacobian_and_second_derivatives_by_fd(backend):
    x = ring_nodes(50, 1)
    rng = np.random.default_rng(2)
    dt = 0.05
    v = 6.0 * np.cross(unit(AXIS), x - CENTER) + rng.normal(size=x.shape)
    X, J, d2X = cylindrical_update(x, v, dt, CENTER, AXIS, backend=backend)
    h = 1e-3
    Jfd = richardson_v(lambda vv: cylindrical_update(vv * 0 + x, vv, dt, CENTER, AXIS,
                                                     derivatives=False)[0], v, h)
    np.testing.assert_array_less(np.linalg.norm(Jfd - J, axis=(1, 2)),
                                 1e-6 * np.linalg.norm(J, axis=(1, 2)))
    Hfd = richardson_v(lambda vv: cylindrical_update(x, vv, dt, CENTER, AXIS,
                                                     backend=backend)[1], v, h)
    err = np.linalg.norm((Hfd - d2X).reshape(len(x), -1), axis=1)
    scale = np.linalg.norm(d2X.reshape(len(x), -1), axis=1)
    np.testing.assert_array_less(err, 1e-6 * scale)
    # symmetry in (a, b)
    np.testing.assert_allclose(d2X, d2X.transpose(0, 1, 3, 2), atol=1e-15)


def test_thesis_iii39_derivatives():
    """∂r'/∂v_x = dt cos θ and ∂θ'/∂v_x = −dt sin θ / r at v = 0 (axis z, THEORY §5)."""
    c = np.zeros(3)
    th = np.linspace(0.1, 6.0, 7)
    r = 1.7
    x = np.stack([r * np.cos(th), r * np.sin(th), np.zeros_like(th)], axis=1)
    dt = 0.01
    _, J, _ = cylindrical_update(x, np.zeros_like(x), dt, c, (0, 0, 1))
    # r' = |X_xy|, θ' = atan2: their gradients follow from J by the chain rule at v = 0
    er = x / r
    et = np.stack([-np.sin(th), np.cos(th), np.zeros_like(th)], axis=1)
    dr_dv = np.einsum("ni,nia->na", er, J)
    dth_dv = np.einsum("ni,nia->na", et, J) / r
    np.testing.assert_allclose(dr_dv[:, 0], dt * np.cos(th), atol=1e-15)
    np.testing.assert_allclose(dth_dv[:, 0], -dt * np.sin(th) / r, atol=1e-15)


def test_backends_agree():
    x = ring_nodes(500, 3, rmin=0.01, rmax=5.0)
    v = np.random.default_rng(4).normal(size=x.shape) * 3
    a = cylindrical_update(x, v, 0.07, CENTER, AXIS, backend="numba")
    b = cylindrical_update(x, v, 0.07, CENTER, AXIS, backend="numpy")
    for p, q in zip(a, b):
        np.testing.assert_allclose(p, q, rtol=1e-13, atol=1e-13 * np.abs(q).max())
    xa, _, _ = cylindrical_update(x, v, 0.07, CENTER, AXIS, derivatives=False, backend="numpy")
    np.testing.assert_allclose(xa, a[0], rtol=1e-13, atol=1e-13)


def test_cartesian_update():
    rng = np.random.default_rng(5)
    x, v = rng.normal(size=(7, 3)), rng.normal(size=(7, 3))
    X, J, d2X = cartesian_update(x, v, 0.3)
    np.testing.assert_allclose(X, x + 0.3 * v)
    np.testing.assert_array_equal(J, np.broadcast_to(0.3 * np.eye(3), (7, 3, 3)))
    assert d2X.shape == (7, 3, 3, 3) and not np.any(d2X)
    X2, J2, d2 = cartesian_update(x, v, 0.3, derivatives=False)
    assert J2 is None and d2 is None
    np.testing.assert_array_equal(X2, X)


@pytest.mark.parametrize("backend", BACKENDS)
def test_derivatives_false(backend):
    x = ring_nodes(5, 6)
    X, J, d2X = cylindrical_update(x, x * 0.1, 0.1, CENTER, AXIS, derivatives=False,
                                   backend=backend)
    assert J is None and d2X is None and X.shape == (5, 3)


# --------------------------------------------------------------------------------------------
# fully implicit composition h(v) = −d(X(v))/dt
# --------------------------------------------------------------------------------------------

def _tools():
    return {
        "mandrel": Cylinder((0.5, -0.2, 0.0), (0.05, 0.02, 1.0), 0.6,
                            velocity=(0.3, 0.1, 0.0), angular_velocity=4.0),
        "bore": Cylinder((0.4, -0.3, 0.0), (0.0, 0.0, 1.0), 2.3, inside=True),
        "cone": Cone((0.2, 0.0, -2.5), (0.1, -0.2, 1.0), 0.5, velocity=(0.0, 0.0, 0.4)),
        "cone-inside": Cone((0.2, 0.0, -2.5), (0.1, -0.2, 1.0), 0.5, inside=True),
        "sphere": Sphere((0.1, 0.2, 0.0), 0.4),
    }


@pytest.mark.parametrize("update", ["cylindrical", "cartesian"])
@pytest.mark.parametrize("name", ["mandrel", "bore", "cone", "cone-inside", "sphere"])
def test_gap_composition_by_fd(name, update):
    tool = _tools()[name]
    x = ring_nodes(40, 7, rmin=1.0, rmax=2.0)
    rng = np.random.default_rng(8)
    dt, t = 0.05, 0.3
    v = 6.0 * np.cross(unit(AXIS), x - CENTER) + 2 * rng.normal(size=x.shape)

    def X_of(vv, derivatives=False):
        if update == "cylindrical":
            return cylindrical_update(x, vv, dt, CENTER, AXIS, derivatives=derivatives)
        return cartesian_update(x, vv, dt, derivatives=derivatives)

    def h_of(vv):
        return -tool.project(X_of(vv)[0], t + dt, hessian=False).gap / dt

    def grad_of(vv):
        X, J, d2X = X_of(vv, True)
        return gap_derivatives(tool.project(X, t + dt), J, d2X, dt)[1]

    X, J, d2X = X_of(v, True)
    pr = tool.project(X, t + dt)
    assert np.all(pr.flag == 0)
    h, gh, Hh = gap_derivatives(pr, J, d2X, dt)
    np.testing.assert_allclose(h, h_of(v), rtol=1e-15)
    step = 1e-3
    # stay inside one smooth region of the tool under the FD perturbations
    for s in (-step, step):
        for a in range(3):
            e = np.zeros(3)
            e[a] = s
            np.testing.assert_array_equal(tool.project(X_of(v + e)[0], t + dt).feature,
                                          pr.feature)
    gfd = richardson_v(h_of, v, step)
    np.testing.assert_array_less(np.linalg.norm(gfd - gh, axis=1),
                                 1e-6 * np.linalg.norm(gh, axis=1))
    Hfd = richardson_v(grad_of, v, step)
    err = np.linalg.norm(Hfd - Hh, axis=(1, 2))
    np.testing.assert_array_less(err, 1e-6 * np.linalg.norm(Hh, axis=(1, 2)))
    np.testing.assert_allclose(Hh, Hh.transpose(0, 2, 1), atol=1e-12 * np.abs(Hh).max())
    if update == "cartesian":
        np.testing.assert_allclose(gh, -pr.normal, atol=1e-15)
        np.testing.assert_allclose(Hh, -dt * pr.hessian, rtol=1e-14, atol=1e-14)
        _, _, Hn = gap_derivatives(pr, J, None, dt)
        np.testing.assert_allclose(Hn, Hh, rtol=1e-14, atol=1e-14)


# --------------------------------------------------------------------------------------------
# validation
# --------------------------------------------------------------------------------------------

@pytest.mark.parametrize("backend", BACKENDS)
def test_node_on_axis_raises_with_index(backend):
    x = ring_nodes(6, 9)
    x[3] = CENTER + 1.5 * unit(AXIS)
    with pytest.raises(ValueError, match="node 3"):
        cylindrical_update(x, np.zeros_like(x), 0.1, CENTER, AXIS, backend=backend)
    x[3] = CENTER
    x[1] = CENTER - 0.2 * unit(AXIS)
    with pytest.raises(ValueError, match="node 1"):
        cylindrical_update(x, np.zeros_like(x), 0.1, CENTER, AXIS, backend=backend)


@pytest.mark.parametrize("kwargs", [
    dict(dt=0.0), dict(dt=-0.1), dict(dt=float("nan")), dict(dt=float("inf")), dict(dt="x"),
    dict(axis=(0, 0, 0)), dict(axis=(0, float("nan"), 1)), dict(center=(0, 0)),
    dict(center=(0, 0, float("inf"))), dict(backend="cuda"),
    dict(x=np.zeros((4, 2))), dict(v=np.zeros((3, 3))),
    dict(v=np.full((4, 3), np.nan)),
])
def test_bad_inputs(kwargs):
    args = dict(x=ring_nodes(4, 10), v=np.zeros((4, 3)), dt=0.1, center=CENTER, axis=AXIS)
    args.update(kwargs)
    with pytest.raises(ValueError):
        cylindrical_update(**args)
    if set(kwargs) <= {"dt", "x", "v"}:
        with pytest.raises(ValueError):
            cartesian_update(args["x"], args["v"], args["dt"])


def test_gap_derivatives_validation():
    tool = Sphere((0, 0, 0), 0.4)
    x = ring_nodes(4, 11)
    X, J, d2X = cartesian_update(x, np.zeros_like(x), 0.1)
    with pytest.raises(ValueError, match="Hessian"):
        gap_derivatives(tool.project(X, hessian=False), J, d2X, 0.1)
    pr = tool.project(X)
    with pytest.raises(ValueError):
        gap_derivatives(pr, J[:3], d2X, 0.1)
    with pytest.raises(ValueError):
        gap_derivatives(pr, J, d2X[:, 0], 0.1)
    with pytest.raises(ValueError):
        gap_derivatives(pr, J, d2X, 0.0)
