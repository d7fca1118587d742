"""Tests of the analytic tools (fxcontact.tools.analytic) against brute-force references.

The brute-force reference is independent of the closed forms: the tool surface is parametrised,
sampled densely, the best sample is refined by solving the stationarity condition
``∂P/∂q · (P(q) − x) = 0`` with ``scipy.optimize.root``, and the sign of the gap comes from an
inside/outside test of the tool solid.
"""

import math

import numpy as np
import pytest
from scipy.optimize import root
from scipy.spatial.transform import Rotation

from fxcontact.tools.analytic import AXIS_TOL, Cone, Cylinder, Plane, Sphere
from fxcontact.tools.base import Tool

BACKENDS = ("numba", "numpy")

PLANE = dict(point=(0.3, -0.2, 0.5), normal=(1.0, 2.0, 2.0))
SPHERE = dict(center=(0.1, 0.2, -0.3), radius=1.3)
CYLINDER = dict(point=(0.2, -0.1, 0.4), axis=(1.0, -2.0, 0.5), radius=0.8)
CONE = dict(apex=(-0.2, 0.1, 0.3), axis=(0.3, 1.0, -0.4), half_angle=0.6)

CASES = [("plane", False), ("sphere", False), ("sphere", True), ("cylinder", False),
         ("cylinder", True), ("cone", False), ("cone", True)]
CASE_IDS = [f"{k}-{'inside' if i else 'outside'}" for k, i in CASES]


def make_tool(kind, inside=False, backend="numba", **kw):
    if kind == "plane":
        return Plane(**{**PLANE, **kw}, backend=backend)
    data = {"sphere": SPHERE, "cylinder": CYLINDER, "cone": CONE}[kind]
    cls = {"sphere": Sphere, "cylinder": Cylinder, "cone": Cone}[kind]
    return cls(**{**data, **kw}, inside=inside, backend=backend)


def unit(v):
    v = np.asarray(v, dtype=float)
    return v / np.linalg.norm(v)


def frame(w):
    """Orthonormal (u, v, w) built from the SVD null space of w (independent of the library)."""
    w = unit(w)
    _, _, vt = np.linalg.svd(w[None, :])
    return vt[1], vt[2], w


# --------------------------------------------------------------------------------------------
# random points per tool
# --------------------------------------------------------------------------------------------

def _radial_samples(rng, n, lo, hi, R):
    """Half wide-range radii, half within ±[1e-4, 1e-2]·R of the surface."""
    wide = rng.uniform(lo, hi, n - n // 2)
    near = R * (1.0 + rng.choice([-1.0, 1.0], n // 2) * 10 ** rng.uniform(-4, -2, n // 2))
    return np.concatenate([wide, near])


def sample_points(kind, inside, n=40, seed=0):
    rng = np.random.default_rng(seed + 17 * CASES.index((kind, inside)))
    if kind == "plane":
        nrm = unit(PLANE["normal"])
        x = rng.uniform(-2, 2, (n, 3))
        m = n // 4  # a quarter of the points within ±[1e-4, 1e-2] of the plane
        x[:m] -= ((x[:m] - PLANE["point"]) @ nrm)[:, None] * nrm
        x[:m] += rng.choice([-1, 1], (m, 1)) * 10 ** rng.uniform(-4, -2, (m, 1)) * nrm
        return x
    if kind == "sphere":
        R = SPHERE["radius"]
        r = _radial_samples(rng, n, 0.55 * R, (1.6 if inside else 2.0) * R, R)
        d = rng.normal(size=(n, 3))
        return np.asarray(SPHERE["center"]) + r[:, None] * d / np.linalg.norm(d, axis=1)[:, None]
    if kind == "cylinder":
        R = CYLINDER["radius"]
        u, v, w = frame(CYLINDER["axis"])
        rho = _radial_samples(rng, n, 0.55 * R, (1.6 if inside else 2.0) * R, R)
        s = rng.uniform(-2, 2, n)
        phi = rng.uniform(0, 2 * np.pi, n)
        return (np.asarray(CYLINDER["point"]) + s[:, None] * w
                + rho[:, None] * (np.cos(phi)[:, None] * u + np.sin(phi)[:, None] * v))
    # cone: (s, ρ) in a box around the apex, away from the axis and from the nappe/apex switch
    al = CONE["half_angle"]
    u, v, w = frame(CONE["axis"])
    pts = []
    while len(pts) < n:
        if rng.random() < 0.3:  # close to the nappe
            t = rng.uniform(0.2, 2.5)
            off = rng.choice([-1.0, 1.0]) * 10 ** rng.uniform(-4, -2)
            s, rho = t * math.cos(al) - off * math.sin(al), t * math.sin(al) + off * math.cos(al)
        else:
            s, rho = rng.uniform(-1.5, 2.5), rng.uniform(0.0, 2.5)
        dist = math.hypot(s, rho)
        tau = s * math.cos(al) + rho * math.sin(al)
        if rho < 0.25 * max(s, 0.0) * math.tan(al) or abs(tau) < 0.05 * dist or dist < 0.05:
            continue
        phi = rng.uniform(0, 2 * np.pi)
        pts.append(np.asarray(CONE["apex"]) + s * w + rho * (math.cos(phi) * u + math.sin(phi) * v))
    return np.array(pts)


# --------------------------------------------------------------------------------------------
# brute-force reference
# --------------------------------------------------------------------------------------------

def _refine(x, P, dP, q0):
    """Solve dPᵀ(P − x) = 0 from q0 (superlinear, to rounding)."""
    sol = root(lambda q: dP(q).T @ (P(q) - x), q0, method="hybr", options={"xtol": 1e-14})
    return sol.x


def _sphere_param(c, R, b):
    """Sphere parametrised by latitude/longitude in a frame whose equator contains b."""
    v, w, b = frame(b)  # b: unit vector of the equator's origin, v and w orthogonal to it

    def P(q):
        return c + R * (math.cos(q[0]) * (math.cos(q[1]) * b + math.sin(q[1]) * v)
                        + math.sin(q[0]) * w)

    def dP(q):
        d0 = -math.sin(q[0]) * (math.cos(q[1]) * b + math.sin(q[1]) * v) + math.cos(q[0]) * w
        d1 = math.cos(q[0]) * (-math.sin(q[1]) * b + math.cos(q[1]) * v)
        return R * np.stack([d0, d1], axis=1)

    return P, dP


def brute_force(kind, inside, x):
    """Closest surface point and signed gap of each row of x, by sampling + refinement."""
    x = np.atleast_2d(x)
    P_out, g_out = np.empty_like(x), np.empty(len(x))
    if kind == "plane":
        p0, nrm = np.asarray(PLANE["point"]), unit(PLANE["normal"])
        t1, t2, _ = frame(nrm)
        for i, xi in enumerate(x):
            # linear least squares on the parametrisation p0 + a t1 + b t2
            A = np.stack([t1, t2], axis=1)
            ab = np.linalg.lstsq(A, xi - p0, rcond=None)[0]
            P_out[i] = p0 + A @ ab
        inside_tool = (x - p0) @ nrm < 0
    elif kind == "sphere":
        c, R = np.asarray(SPHERE["center"]), SPHERE["radius"]
        k = np.arange(20000) + 0.5
        z = 1 - 2 * k / k.size
        ph = np.pi * (1 + 5**0.5) * k
        samp = c + R * np.stack([np.sqrt(1 - z**2) * np.cos(ph), np.sqrt(1 - z**2) * np.sin(ph),
                                 z], axis=1)
        for i, xi in enumerate(x):
            b = samp[np.argmin(np.linalg.norm(samp - xi, axis=1))] - c
            P, dP = _sphere_param(c, R, b)
            P_out[i] = P(_refine(xi, P, dP, np.zeros(2)))
        inside_tool = np.linalg.norm(x - c, axis=1) < R
        if inside:
            inside_tool = ~inside_tool
    elif kind == "cylinder":
        a, R = np.asarray(CYLINDER["point"]), CYLINDER["radius"]
        u, v, w = frame(CYLINDER["axis"])

        def P(q):
            return a + q[0] * w + R * (math.cos(q[1]) * u + math.sin(q[1]) * v)

        def dP(q):
            return np.stack([w, R * (-math.sin(q[1]) * u + math.cos(q[1]) * v)], axis=1)

        ss = np.linspace(((x - a) @ w).min() - 2, ((x - a) @ w).max() + 2, 300)
        pp = np.linspace(0, 2 * np.pi, 300, endpoint=False)
        S, F = np.meshgrid(ss, pp, indexing="ij")
        q_s = np.stack([S.ravel(), F.ravel()], axis=1)
        samp = a + q_s[:, :1] * w + R * (np.cos(q_s[:, 1:]) * u + np.sin(q_s[:, 1:]) * v)
        for i, xi in enumerate(x):
            q0 = q_s[np.argmin(np.linalg.norm(samp - xi, axis=1))]
            P_out[i] = P(_refine(xi, P, dP, q0))
        inside_tool = np.linalg.norm(np.cross(x - a, w), axis=1) < R
        if inside:
            inside_tool = ~inside_tool
    else:
        A, al = np.asarray(CONE["apex"]), CONE["half_angle"]
        u, v, w = frame(CONE["axis"])

        def gen(f):
            return math.cos(al) * w + math.sin(al) * (math.cos(f) * u + math.sin(f) * v)

        def P(q):
            return A + q[0] * gen(q[1])

        def dP(q):
            dg = math.sin(al) * (-math.sin(q[1]) * u + math.cos(q[1]) * v)
            return np.stack([gen(q[1]), q[0] * dg], axis=1)

        tt = np.linspace(0.0, np.linalg.norm(x - A, axis=1).max() + 1.0, 400)
        pp = np.linspace(0, 2 * np.pi, 300, endpoint=False)
        T, F = np.meshgrid(tt, pp, indexing="ij")
        q_s = np.stack([T.ravel(), F.ravel()], axis=1)
        gens = (math.cos(al) * w + math.sin(al) * (np.cos(q_s[:, 1:]) * u
                                                    + np.sin(q_s[:, 1:]) * v))
        samp = A + q_s[:, :1] * gens
        for i, xi in enumerate(x):
            j = np.argmin(np.linalg.norm(samp - xi, axis=1))
            best = A.copy()  # the apex is always a candidate (boundary t = 0 of the domain)
            if q_s[j, 0] > 0:
                q = _refine(xi, P, dP, q_s[j])
                if q[0] > 0 and np.linalg.norm(P(q) - xi) < np.linalg.norm(best - xi):
                    best = P(q)
            P_out[i] = best
        xa = x - A
        cosang = (xa @ w) / np.linalg.norm(xa, axis=1)
        inside_tool = cosang > math.cos(al)  # inside the solid cone
        if inside:
            inside_tool = ~inside_tool
    dist = np.linalg.norm(x - P_out, axis=1)
    g_out = np.where(inside_tool, -dist, dist)
    return P_out, g_out


# --------------------------------------------------------------------------------------------
# projection vs brute force
# --------------------------------------------------------------------------------------------

@pytest.mark.parametrize("kind,inside", CASES, ids=CASE_IDS)
def test_projection_matches_brute_force(kind, inside):
    x = sample_points(kind, inside)
    P_ref, g_ref = brute_force(kind, inside, x)
    pr = make_tool(kind, inside).project(x)
    # both free space and penetrated points are exercised
    assert np.any(g_ref > 0) and np.any(g_ref < 0)
    assert np.any(np.abs(g_ref) < 1e-2)
    np.testing.assert_allclose(pr.point, P_ref, atol=1e-10)
    np.testing.assert_allclose(pr.gap, g_ref, atol=1e-10)
    assert np.all(np.sign(pr.gap) == np.sign(g_ref))
    n_ref = (x - P_ref) / g_ref[:, None]
    np.testing.assert_allclose(pr.normal, n_ref, atol=1e-10 / np.abs(g_ref).min() + 1e-12)
    assert np.all(pr.flag == 0)


def apex_region_points(n, seed):
    """Points strictly behind the cone apex: angle with w larger than π/2 + α + 0.05."""
    A, al = np.asarray(CONE["apex"]), CONE["half_angle"]
    w = unit(CONE["axis"])
    rng = np.random.default_rng(seed)
    pts = []
    while len(pts) < n:
        d = unit(rng.normal(size=3))
        if d @ w < math.cos(0.5 * np.pi + al + 0.05):
            pts.append(A + rng.uniform(0.01, 2.0) * d)
    return np.array(pts)


def test_cone_apex_region_brute_force():
    """Points behind the apex: the closest point is the apex (feature 1), both variants."""
    A = np.asarray(CONE["apex"])
    x = apex_region_points(20, 5)
    for inside in (False, True):
        P_ref, g_ref = brute_force("cone", inside, x)
        np.testing.assert_allclose(P_ref, np.broadcast_to(A, x.shape), atol=1e-14)
        for backend in BACKENDS:
            pr = make_tool("cone", inside, backend).project(x)
            assert np.all(pr.feature == 1) and np.all(pr.flag == 0)
            np.testing.assert_allclose(pr.point, P_ref, atol=1e-12)
            np.testing.assert_allclose(pr.gap, g_ref, atol=1e-12)
            assert np.all(np.sign(pr.gap) == (-1 if inside else 1))
            np.testing.assert_allclose(pr.normal, (x - P_ref) / g_ref[:, None], atol=1e-12)


def test_cone_features_both_regions_present():
    for inside in (False, True):
        x = sample_points("cone", inside)
        f = make_tool("cone", inside).project(x).feature
        assert set(np.unique(f)) == {0, 1}


# --------------------------------------------------------------------------------------------
# derivatives by finite differences (Richardson-extrapolated central differences)
# --------------------------------------------------------------------------------------------

def _richardson(f, x, h):
    """Richardson extrapolation of central differences of f at x along the 3 axes.

    Returns an array of shape f(x).shape + (3,) (last index = derivative direction)."""
    cols = []
    for k in range(3):
        e = np.zeros(3)
        e[k] = 1.0

        def cd(hh):
            return (f(x + hh * e) - f(x - hh * e)) / (2 * hh)

        cols.append((4 * cd(h / 2) - cd(h)) / 3)
    return np.stack(cols, axis=-1)


def _fd_step(kind, x):
    """A step well inside the smooth region of each point."""
    if kind == "plane":
        return 1e-2
    if kind == "sphere":
        return 1e-3 * min(1.0, np.linalg.norm(x - SPHERE["center"]))
    if kind == "cylinder":
        return 1e-3 * min(1.0, np.linalg.norm(np.cross(x - CYLINDER["point"],
                                                       unit(CYLINDER["axis"]))))
    xa = x - CONE["apex"]
    rho = np.linalg.norm(np.cross(xa, unit(CONE["axis"])))
    return 1e-3 * min(rho if rho > 0 else 1.0, np.linalg.norm(xa))


@pytest.mark.parametrize("kind,inside", CASES, ids=CASE_IDS)
@pytest.mark.parametrize("backend", BACKENDS)
def test_gradient_and_hessian_by_finite_differences(kind, inside, backend):
    tool = make_tool(kind, inside, backend)
    x = sample_points(kind, inside, n=16, seed=3)
    if kind == "cone":
        x = np.vstack([x, apex_region_points(6, 9)])
        assert np.sum(tool.project(x).feature == 1) >= 6
    pr = tool.project(x)
    for i, xi in enumerate(x):
        h = _fd_step(kind, xi)
        grad = _richardson(lambda y: tool.project(y).gap[0], xi, h)
        np.testing.assert_allclose(grad, pr.normal[i], atol=1e-6)
        hfd = _richardson(lambda y: tool.project(y).normal[0], xi, h)
        H = pr.hessian[i]
        err = np.linalg.norm(hfd - H)
        scale = np.linalg.norm(H)
        if kind == "plane":
            assert err < 1e-12
        else:
            assert err < 1e-6 * scale, (i, err, scale)


# --------------------------------------------------------------------------------------------
# invariants, backends, options
# --------------------------------------------------------------------------------------------

@pytest.mark.parametrize("kind,inside", CASES, ids=CASE_IDS)
@pytest.mark.parametrize("backend", BACKENDS)
def test_invariants(kind, inside, backend):
    tool = make_tool(kind, inside, backend)
    assert tool.has_hessian and isinstance(tool, Tool)
    x = np.random.default_rng(11).uniform(-3, 3, (500, 3))
    pr = tool.project(x)
    assert pr.gap.shape == (500,) and pr.normal.shape == (500, 3) and pr.point.shape == (500, 3)
    assert pr.hessian.shape == (500, 3, 3)
    assert pr.feature.shape == (500,) and pr.flag.shape == (500,)
    np.testing.assert_allclose(np.linalg.norm(pr.normal, axis=1), 1.0, atol=1e-14)
    np.testing.assert_allclose(pr.point + pr.gap[:, None] * pr.normal, x, atol=1e-13)
    hs = np.abs(pr.hessian).max(axis=(1, 2))[:, None] + 1e-300
    np.testing.assert_allclose(pr.hessian / hs[:, :, None],
                               pr.hessian.transpose(0, 2, 1) / hs[:, :, None], atol=1e-14)
    hn = np.einsum("nij,nj->ni", pr.hessian, pr.normal)
    np.testing.assert_allclose(hn / hs, 0.0, atol=1e-14)
    # the closest point lies on the surface: its own gap is zero
    np.testing.assert_allclose(tool.project(pr.point).gap, 0.0, atol=1e-13)
    assert np.all(np.isfinite(pr.hessian))


@pytest.mark.parametrize("kind,inside", CASES, ids=CASE_IDS)
def test_backends_agree(kind, inside):
    x = np.random.default_rng(12).uniform(-3, 3, (2000, 3))
    x = np.vstack([x, sample_points(kind, inside)])
    a = make_tool(kind, inside, "numba").project(x)
    b = make_tool(kind, inside, "numpy").project(x)
    np.testing.assert_allclose(a.gap, b.gap, rtol=1e-13, atol=1e-13)
    np.testing.assert_allclose(a.normal, b.normal, rtol=1e-13, atol=1e-13)
    np.testing.assert_allclose(a.point, b.point, rtol=1e-13, atol=1e-13)
    hs = np.abs(a.hessian).max(axis=(1, 2))[:, None, None] + 1e-300
    np.testing.assert_allclose(a.hessian / hs, b.hessian / hs, atol=1e-13)
    np.testing.assert_array_equal(a.feature, b.feature)
    np.testing.assert_array_equal(a.flag, b.flag)


@pytest.mark.parametrize("kind,inside", CASES, ids=CASE_IDS)
@pytest.mark.parametrize("backend", BACKENDS)
def test_hessian_false_and_single_point(kind, inside, backend):
    tool = make_tool(kind, inside, backend)
    x = np.array([1.1, -0.7, 2.2])
    full = tool.project(x)
    light = tool.project(x, hessian=False)
    assert light.hessian is None
    np.testing.assert_array_equal(full.gap, light.gap)
    np.testing.assert_array_equal(full.normal, light.normal)
    assert len(full) == 1
    empty = tool.project(np.empty((0, 3)))
    assert len(empty) == 0 and empty.hessian.shape == (0, 3, 3)


def test_closed_forms_spot_values():
    """Hand-computed values with axis-aligned data."""
    pr = Sphere((0, 0, 0), 2.0).project([[0, 3, 0]])
    np.testing.assert_allclose(pr.gap, [1.0])
    np.testing.assert_allclose(pr.hessian[0], np.diag([1, 0, 1]) / 3.0)
    pr = Sphere((0, 0, 0), 2.0, inside=True).project([[0, 3, 0]])
    np.testing.assert_allclose(pr.gap, [-1.0])
    np.testing.assert_allclose(pr.normal, [[0, -1, 0]])
    pr = Cylinder((0, 0, 0), (0, 0, 5), 1.0).project([[2, 0, 7]])
    np.testing.assert_allclose(pr.gap, [1.0])
    np.testing.assert_allclose(pr.point, [[1, 0, 7]])
    np.testing.assert_allclose(pr.hessian[0], np.diag([0, 0.5, 0]))
    pr = Cylinder((0, 0, 0), (0, 0, 1), 1.0, inside=True).project([[2, 0, 7]])
    np.testing.assert_allclose(pr.hessian[0], np.diag([0, -0.5, 0]))
    al = np.pi / 4
    pr = Cone((0, 0, 0), (0, 0, 1), al).project([[2, 0, 0]])  # on the nappe side
    np.testing.assert_allclose(pr.gap, [2 * math.cos(al)])
    np.testing.assert_allclose(pr.point, [[1, 0, 1]], atol=1e-15)
    pr = Cone((0, 0, 0), (0, 0, 1), al).project([[0.5, 0, -1]])  # behind the apex
    np.testing.assert_allclose(pr.gap, [math.hypot(0.5, 1)])
    np.testing.assert_allclose(pr.point, [[0, 0, 0]], atol=1e-15)
    assert pr.feature[0] == 1
    pr = Plane((0, 0, 1), (0, 0, -3)).project([[5, 5, 0]])
    np.testing.assert_allclose(pr.gap, [1.0])
    np.testing.assert_allclose(pr.normal, [[0, 0, -1]])


# --------------------------------------------------------------------------------------------
# singular points
# --------------------------------------------------------------------------------------------

@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("inside", [False, True])
def test_singular_points_are_finite_and_flagged(backend, inside):
    # axis-aligned data: on-axis points are exactly on the axis, e_fixed = e_x
    cyl = Cylinder((1, 2, 3), (0, 0, 2), 0.5, inside=inside, backend=backend)
    pr = cyl.project([[1, 2, -4.0], [1, 2, 3.0]])
    assert np.all(pr.flag == 2)
    np.testing.assert_array_equal(cyl.e_fixed, [1, 0, 0])
    sg = -1 if inside else 1
    np.testing.assert_allclose(pr.normal, sg * np.array([[1, 0, 0], [1, 0, 0]]))
    np.testing.assert_allclose(pr.gap, [-0.5 * sg] * 2)
    np.testing.assert_allclose(pr.point, [[1.5, 2, -4], [1.5, 2, 3]])
    assert np.all(np.isfinite(pr.hessian))
    np.testing.assert_allclose(pr.hessian[0], sg * np.diag([0, 1, 0]) / (AXIS_TOL * 0.5))

    sph = Sphere((1, 2, 3), 0.5, inside=inside, backend=backend)
    pr = sph.project([[1, 2, 3]])
    assert pr.flag[0] == 2 and np.all(np.isfinite(pr.hessian))
    np.testing.assert_allclose(pr.normal, sg * np.array([[1, 0, 0]]))
    np.testing.assert_allclose(pr.gap, [-0.5 * sg])

    cone = Cone((1, 2, 3), (0, 0, 1), 0.3, inside=inside, backend=backend)
    pr = cone.project([[1, 2, 5.0], [1, 2, 3.0], [1, 2, 1.0]])
    # on the axis in front of the apex: flag 2 on the nappe
    assert pr.flag[0] == 2 and pr.feature[0] == 0
    np.testing.assert_allclose(pr.gap[0], -sg * 2 * math.sin(0.3))
    np.testing.assert_allclose(pr.normal[0], sg * np.array([math.cos(0.3), 0, -math.sin(0.3)]))
    # at the apex: flag 2, feature 1, normal ∓w, zero Hessian
    assert pr.flag[1] == 2 and pr.feature[1] == 1
    np.testing.assert_allclose(pr.gap[1], 0.0)
    np.testing.assert_allclose(pr.normal[1], [0, 0, -sg])
    np.testing.assert_array_equal(pr.hessian[1], 0.0)
    # on the axis behind the apex: regular (unique closest point: the apex)
    assert pr.flag[2] == 0 and pr.feature[2] == 1
    np.testing.assert_allclose(pr.gap[2], sg * 2.0)
    np.testing.assert_allclose(pr.normal[2], [0, 0, -sg])
    assert np.all(np.isfinite(pr.hessian)) and np.all(np.isfinite(pr.normal))


@pytest.mark.parametrize("backend", BACKENDS)
def test_singular_general_axis_and_threshold(backend):
    w = unit(CYLINDER["axis"])
    cyl = make_tool("cylinder", backend=backend)
    a = np.asarray(CYLINDER["point"])
    x = np.array([a + 0.7 * w, a - 3 * w + 1e-14 * cyl.e_fixed, a + 1e-6 * cyl.e_fixed])
    pr = cyl.project(x)
    np.testing.assert_array_equal(pr.flag, [2, 2, 0])
    assert np.all(np.isfinite(pr.hessian)) and np.all(np.isfinite(pr.normal))
    np.testing.assert_allclose(pr.normal[:2], np.tile(cyl.e_fixed, (2, 1)))
    assert abs(cyl.e_fixed @ w) < 1e-15 and abs(np.linalg.norm(cyl.e_fixed) - 1) < 1e-15
    cone = make_tool("cone", backend=backend)
    wc = unit(CONE["axis"])
    pr = cone.project(np.array([CONE["apex"] + 1.3 * wc, CONE["apex"]]))
    np.testing.assert_array_equal(pr.flag, [2, 2])
    assert np.all(np.isfinite(pr.hessian))


# --------------------------------------------------------------------------------------------
# moving tools
# --------------------------------------------------------------------------------------------

def _assert_same_projection(a, b, atol=1e-12):
    np.testing.assert_allclose(a.gap, b.gap, atol=atol)
    np.testing.assert_allclose(a.normal, b.normal, atol=atol)
    np.testing.assert_allclose(a.point, b.point, atol=atol)
    np.testing.assert_allclose(a.hessian, b.hessian, rtol=1e-9, atol=atol)
    np.testing.assert_array_equal(a.feature, b.feature)
    np.testing.assert_array_equal(a.flag, b.flag)


_ANCHOR = {"plane": "point", "sphere": "center", "cylinder": "point", "cone": "apex"}
_DATA = {"plane": PLANE, "sphere": SPHERE, "cylinder": CYLINDER, "cone": CONE}


@pytest.mark.parametrize("kind,inside", CASES, ids=CASE_IDS)
def test_translated_tool_constant_and_callable_velocity(kind, inside):
    x = sample_points(kind, inside, n=30, seed=7)
    key = _ANCHOR[kind]
    p0 = np.asarray(_DATA[kind][key])
    V = np.array([0.3, -0.5, 0.2])
    t = 1.7
    moving = make_tool(kind, inside, velocity=V)
    static = make_tool(kind, inside, **{key: p0 + V * t})
    _assert_same_projection(moving.project(x + V * t, t), static.project(x + V * t))
    np.testing.assert_allclose(moving.velocity(x, t), np.tile(V, (len(x), 1)))

    def vfun(s):
        return np.array([math.sin(s), s, 1.0])

    shift = np.array([1 - math.cos(t), t**2 / 2, t])  # ∫₀ᵗ v
    moving = make_tool(kind, inside, velocity=vfun)
    static = make_tool(kind, inside, **{key: p0 + shift})
    _assert_same_projection(moving.project(x + shift, t), static.project(x + shift), atol=1e-10)
    np.testing.assert_allclose(moving.velocity(x, t), np.tile(vfun(t), (len(x), 1)))


@pytest.mark.parametrize("kind,inside", [c for c in CASES if c[0] != "plane"],
                         ids=[i for c, i in zip(CASES, CASE_IDS) if c[0] != "plane"])
def test_rotating_tool(kind, inside):
    """Rotation about the own axis (+ translation) moves the surface like the translation only;
    velocity() equals the derivative of a material point's trajectory."""
    x = sample_points(kind, inside, n=30, seed=8)
    key = _ANCHOR[kind]
    p0 = np.asarray(_DATA[kind][key])
    w = unit(_DATA[kind].get("axis", (0, 0, 1)))
    om, V, t = 2.5, np.array([0.1, 0.0, -0.4]), 0.9
    rot_only = make_tool(kind, inside, angular_velocity=om)
    _assert_same_projection(rot_only.project(x, t), make_tool(kind, inside).project(x))
    moving = make_tool(kind, inside, angular_velocity=om, velocity=V)
    static = make_tool(kind, inside, **{key: p0 + V * t})
    _assert_same_projection(moving.project(x, t), static.project(x))

    # material point trajectory, built independently with scipy's Rotation
    y = make_tool(kind, inside).project(x).point  # material points (reference positions)

    def traj(s):
        Q = Rotation.from_rotvec(om * s * w).as_matrix()
        return p0 + V * s + (y - p0) @ Q.T

    hs = 1e-4
    fd = (traj(t + hs) - traj(t - hs)) / (2 * hs)
    Pt = traj(t)
    vel = moving.velocity(Pt, t)
    np.testing.assert_allclose(vel, fd, rtol=1e-7, atol=1e-7)
    np.testing.assert_allclose(vel, V + om * np.cross(w, Pt - (p0 + V * t)), atol=1e-13)
    # rotation only: ω w × (P − a), tangent to the surface
    vr = rot_only.velocity(y, 0.0)
    np.testing.assert_allclose(vr, om * np.cross(w, y - p0), atol=1e-13)
    n = make_tool(kind, inside).project(x).normal
    np.testing.assert_allclose(np.einsum("ni,ni->n", vr, n), 0.0, atol=1e-12)


def test_rotating_callable_angular_velocity():
    cyl = make_tool("cylinder", angular_velocity=lambda s: 1.0 + s)
    a, w = np.asarray(CYLINDER["point"]), unit(CYLINDER["axis"])
    y = a + 0.8 * frame(w)[0]
    t, hs = 0.6, 1e-4

    def traj(s):
        return cyl.motion.from_reference(y[None, :], s)[0]

    fd = (traj(t + hs) - traj(t - hs)) / (2 * hs)
    np.testing.assert_allclose(cyl.velocity(traj(t), t)[0], fd, rtol=1e-7)
    np.testing.assert_allclose(np.linalg.norm(np.cross(traj(t) - a, w)), 0.8, atol=1e-12)


# --------------------------------------------------------------------------------------------
# validation and immutability
# --------------------------------------------------------------------------------------------

@pytest.mark.parametrize("build", [
    lambda: Sphere((0, 0, 0), 0.0),
    lambda: Sphere((0, 0, 0), -1.0),
    lambda: Sphere((0, 0, 0), float("nan")),
    lambda: Sphere((0, 0, 0), float("inf")),
    lambda: Sphere((0, float("nan"), 0), 1.0),
    lambda: Sphere((0, 0), 1.0),
    lambda: Sphere((0, 0, 0), "big"),
    lambda: Sphere((0, 0, 0), 1.0, inside="yes"),
    lambda: Sphere((0, 0, 0), 1.0, axis=(0, 0, 0)),
    lambda: Cylinder((0, 0, 0), (0, 0, 0), 1.0),
    lambda: Cylinder((0, 0, 0), (0, 0, float("inf")), 1.0),
    lambda: Cylinder((0, 0, 0), (0, 0, 1), -2.0),
    lambda: Cylinder((0, 0, float("inf")), (0, 0, 1), 1.0),
    lambda: Cylinder((0, 0, 0), (0, 0, 1), 1.0, backend="fortran"),
    lambda: Cone((0, 0, 0), (0, 0, 1), 0.0),
    lambda: Cone((0, 0, 0), (0, 0, 1), np.pi / 2),
    lambda: Cone((0, 0, 0), (0, 0, 1), -0.3),
    lambda: Cone((0, 0, 0), (0, 0, 1), 2.0),
    lambda: Cone((0, 0, 0), (0, 0, 1), float("nan")),
    lambda: Cone((0, 0, 0), (0, 0, 0), 0.3),
    lambda: Cone((0, 0, float("nan")), (0, 0, 1), 0.3),
    lambda: Plane((0, 0, 0), (0, 0, 0)),
    lambda: Plane((0, 0, 0), (0, float("nan"), 1)),
    lambda: Plane((0, 0, float("inf")), (0, 0, 1)),
    lambda: Plane((0, 0, 0), (0, 0, 1), velocity=(1, 2)),
    lambda: Plane((0, 0, 0), (0, 0, 1), name=3),
    lambda: Cylinder((0, 0, 0), (0, 0, 1), 1.0, angular_velocity=float("nan")),
])
def test_bad_constructor_arguments(build):
    with pytest.raises(ValueError):
        build()


@pytest.mark.parametrize("kind,inside", CASES, ids=CASE_IDS)
def test_bad_points(kind, inside):
    tool = make_tool(kind, inside)
    for bad in (np.zeros((4, 2)), np.zeros((2, 3, 3)), np.zeros(4),
                np.array([[0.0, np.nan, 1.0]]), np.array([[np.inf, 0, 0]])):
        with pytest.raises(ValueError):
            tool.project(bad)
        with pytest.raises(ValueError):
            tool._project_reference(bad, True)


def test_tools_are_immutable():
    cyl = make_tool("cylinder")
    with pytest.raises(AttributeError):
        cyl.radius = 2.0
    with pytest.raises(AttributeError):
        del cyl.radius
    with pytest.raises(ValueError):
        cyl.axis[0] = 1.0  # read-only array
    assert "Cylinder(" in repr(cyl) and "radius=0.8" in repr(cyl)


def test_rigid_motion_callable_rates_integrated_and_cached():
    """∫v for a rate with a jump (exact 1.1 at t = 0.8), ∫ω (0.15 t²); cached values are
    copies (mutating a result does not change the next one) and distinct times differ."""
    from fxcontact.tools.base import RigidMotion

    m = RigidMotion(velocity=lambda t: (1.0 if t < 0.5 else 2.0, -t, 0.0),
                    angular_velocity=lambda t: 0.3 * t)
    for _ in range(2):
        c = m.translation(0.8)
        assert np.allclose(c, [1.1, -0.32, 0.0], rtol=1e-9, atol=1e-12)
        c[0] = 99.0
    for t in np.linspace(0.0, 3.0, 40):  # more times than the cache holds
        assert abs(m.angle(t) - 0.15 * t**2) <= 1e-12 * max(1.0, t**2)
    assert abs(m.translation(0.3)[0] - 0.3) < 1e-12


def test_staged_motion_exact_and_equal_to_quadrature():
    """Piecewise-constant rates: the exact integrals equal the quadrature of the same rates
    given as functions (RigidMotion), inside stages, at the boundaries and after the end (at
    rest); the rates are right-continuous at the stage boundaries."""
    from fxcontact.tools.base import RigidMotion, StagedMotion

    stages = ((2.0, (0.0, 0.0, -0.05), 0.0), (3.0, (0.4, 0.1, 0.0), 0.25),
              (1.5, (0.0, 0.0, 0.0), -0.1))
    m = StagedMotion(stages=stages, axis_point=(1.0, 0.0, 5.0), axis=(0.0, 1.0, 0.0))
    ends = np.cumsum([s[0] for s in stages])

    def v(t):
        k = int(np.searchsorted(ends, t, side="right"))
        return np.array(stages[k][1]) if k < len(stages) else np.zeros(3)

    def w(t):
        k = int(np.searchsorted(ends, t, side="right"))
        return stages[k][2] if k < len(stages) else 0.0

    ref = RigidMotion(velocity=v, angular_velocity=w, axis_point=(1.0, 0.0, 5.0),
                      axis=(0.0, 1.0, 0.0))
    for t in (0.0, 0.7, 2.0, 3.3, 5.0, 5.9, 6.5, 9.0):  # quad across jumps: ~1e-10 relative
        assert np.allclose(m.translation(t), ref.translation(t), rtol=0, atol=1e-8), t
        assert abs(m.angle(t) - ref.angle(t)) <= 1e-8, t
        assert np.allclose(m.rotation(t), ref.rotation(t), atol=1e-8)
    assert np.allclose(m.translation(5.0), [1.2, 0.3, -0.1], atol=1e-15)
    assert m.angle(9.0) == pytest.approx(0.75 - 0.15, abs=1e-15)
    # right-continuous rates: an increment starting at a boundary sees the next stage
    assert np.array_equal(m.velocity(2.0), [0.4, 0.1, 0.0])
    assert np.array_equal(m.velocity(2.0 * (1 - 1e-14)), [0.4, 0.1, 0.0])
    assert np.array_equal(m.velocity(1.9), [0.0, 0.0, -0.05])
    assert m.angular_velocity(5.0) == -0.1 and m.angular_velocity(6.5) == 0.0
    p = np.array([[1.0, 0.0, 5.0]])
    assert np.allclose(m.point_velocity(p, 3.0), ref.point_velocity(p, 3.0), atol=1e-8)
    # exact inside a stage: c(3.3) = (0, 0, -0.1) + 1.3 (0.4, 0.1, 0), θ(3.3) = 1.3 · 0.25
    assert np.allclose(m.translation(3.3), [0.52, 0.13, -0.1], rtol=0, atol=1e-15)
    assert m.angle(3.3) == pytest.approx(0.325, abs=1e-15)
    assert m.rotates and not m.is_static and m.duration == 6.5
    still = StagedMotion(stages=((1.0, (0.0, 0.0, 0.0), 0.0),))
    assert still.is_static and not still.rotates


@pytest.mark.parametrize("stages", [(), ((0.0, (0, 0, 1), 0.0),), ((-1.0, (0, 0, 1), 0.0),),
                                    ((1.0, (0, 1), 0.0),), ((1.0, (0, np.nan, 1), 0.0),),
                                    ((1.0, (0, 0, 1), np.inf),), ((1.0, (0, 0, 1)),)])
def test_staged_motion_bad_stages(stages):
    from fxcontact.tools.base import StagedMotion

    with pytest.raises(ValueError, match="stage"):
        StagedMotion(stages=stages)


@pytest.mark.parametrize("kind,inside", CASES, ids=CASE_IDS)
def test_moved_tool_equals_tool_with_its_own_motion(kind, inside):
    """A static tool moved by a one-stage StagedMotion projects like the same tool built with
    that constant velocity and rotation speed (gap, normal, point, Hessian)."""
    from fxcontact.tools.base import MovedTool, RigidMotion, StagedMotion

    v, om = (0.3, -0.2, 0.1), 0.4
    static = make_tool(kind, inside)
    ax_pt, ax = (0.1, 0.2, -0.3), (0.0, 0.6, 0.8)
    moved = MovedTool(static, StagedMotion(stages=((10.0, v, om),), axis_point=ax_pt, axis=ax))
    ref = MovedTool(static, RigidMotion(velocity=v, angular_velocity=om, axis_point=ax_pt,
                                        axis=ax))
    x = np.random.default_rng(3).uniform(-1.5, 1.5, (50, 3))
    for t in (0.0, 0.4, 2.5):
        a, b = moved.project(x, t), ref.project(x, t)
        for k in ("gap", "normal", "point", "hessian"):
            assert np.allclose(getattr(a, k), getattr(b, k), rtol=0, atol=1e-12), (k, t)
    assert moved.name == static.name and moved.has_hessian == static.has_hessian
    with pytest.raises(ValueError, match="static"):
        MovedTool(ref, StagedMotion(stages=((1.0, v, 0.0),)))
    with pytest.raises(ValueError, match="RigidMotion"):
        MovedTool(static, (0.0, 0.0, 1.0))
