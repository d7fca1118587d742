"""Tests of the revolved-profile tool (fxcontact.tools.revolved).

The brute-force reference is independent of the library's 2-D reduction: the profile is
rebuilt here from its points and signed radii as parametrised curves (with their tangent
extensions), the 3-D surface ``P(u, θ)`` is sampled densely (profile × angles), the best sample
of every piece is refined by solving the stationarity condition ``∂P/∂(u, θ) · (P − x) = 0``
with ``scipy.optimize.root``, the end circles of every piece are candidates too, and the sign of
the gap comes from a point-in-polygon test (matplotlib) of the tool region, closed above the
profile for ``inside=True`` (walking towards +s) and below it for ``inside=False``.
"""

import math

import numpy as np
import pytest
from matplotlib.path import Path
from scipy.optimize import root
from scipy.spatial.transform import Rotation

from fxcontact.tools.analytic import AXIS_TOL, Cone, Cylinder, Sphere
from fxcontact.tools.base import MovedTool, Tool
from fxcontact.tools.faceted import FacetedTool
from fxcontact.tools.revolved import (
    RevolvedProfile,
    die_profile,
    faceted_revolved,
    grooved_roll_profile,
)

BACKENDS = ("numba", "numpy")
AXIS_POINT = np.array([0.3, -0.2, 0.5])
AXIS = np.array([1.0, -2.0, 0.5]) / np.linalg.norm([1.0, -2.0, 0.5])

DIE = die_profile(1.6, 1.0, math.radians(10.0), 0.5, fillet_radius=0.4,
                  relief_angle=math.radians(30.0), relief_length=0.3)
ROLL = grooved_roll_profile(2.0, 3.0, groove_radius=0.6, groove_depth=0.4, flange_height=0.6,
                            flange_width=0.4, fillet_radius=0.15)
# from the axis (apex), a concave arc, a concave kink, a convex arc ending with a tangent ray;
# arcs turning both ways
MIXED = (np.array([(0.0, 0.0), (0.6, 0.8), (1.4, 1.0), (1.9, 0.7), (2.9, 1.1)]),
         [None, -1.2, None, 0.9])
# a closed profile: the sphere of radius 1.2 (an arc centred on the axis)
SPHERE_PROFILE = (np.array([(-1.2, 0.0), (1.2, 0.0)]), [-1.2])

PROFILES = {"die": DIE, "roll": ROLL, "mixed": MIXED, "sphere": SPHERE_PROFILE}
CASES = [("die", True), ("roll", False), ("mixed", False), ("mixed", True), ("sphere", False),
         ("sphere", True)]
CASE_IDS = [f"{k}-{'inside' if i else 'outside'}" for k, i in CASES]


def make(kind, inside, backend="numba", **kw):
    pts, arcs = PROFILES[kind]
    kw.setdefault("axis_point", AXIS_POINT)
    kw.setdefault("axis", AXIS)
    return RevolvedProfile(pts, arcs, inside=inside, backend=backend, **kw)


def frame(w):
    """Orthonormal (u, v, w) from the SVD null space of w (independent of the library)."""
    w = np.asarray(w, float) / np.linalg.norm(w)
    _, _, vt = np.linalg.svd(w[None, :])
    return vt[1], vt[2], w


E1, E2, _ = frame(AXIS)


def to3d(q, phi):
    q = np.atleast_2d(q)
    return (AXIS_POINT + q[:, :1] * AXIS
            + q[:, 1:2] * (np.cos(phi)[:, None] * E1 + np.sin(phi)[:, None] * E2))


# --------------------------------------------------------------------------------------------
# independent profile model: pieces c(u), u ∈ [0, 1], with derivatives
# --------------------------------------------------------------------------------------------

FAR = 20.0


def pieces(kind):
    """List of (c(u) -> (2,), c'(u) -> (2,), open_start, open_end) of the profile with its
    tangent extensions (rays of length FAR), rebuilt from the points and signed radii."""
    pts, arcs = PROFILES[kind]
    out = []
    for i in range(len(pts) - 1):
        A, B = np.asarray(pts[i], float), np.asarray(pts[i + 1], float)
        R = arcs[i]
        if R is None:
            out.append((lambda u, A=A, B=B: A + u * (B - A), lambda u, A=A, B=B: B - A))
            continue
        c = np.linalg.norm(B - A)
        m = 0.5 * (A + B)
        n = np.array([-(B - A)[1], (B - A)[0]]) / c
        o = m + math.copysign(math.sqrt(R * R - c * c / 4), R) * n
        a0 = math.atan2(*(A - o)[::-1])
        a1 = math.atan2(*(B - o)[::-1])
        sweep = (a1 - a0) % (2 * math.pi)
        if R < 0:
            sweep -= 2 * math.pi
        r = abs(R)

        def cf(u, o=o, a0=a0, sw=sweep, r=r):
            return o + r * np.array([math.cos(a0 + u * sw), math.sin(a0 + u * sw)])

        def dc(u, a0=a0, sw=sweep, r=r):
            return r * sw * np.array([-math.sin(a0 + u * sw), math.cos(a0 + u * sw)])

        out.append((cf, dc))
    res = []
    # tangent extensions of ends off the axis
    c0, d0 = out[0]
    if pts[0][1] > 0:
        t = d0(0.0) / np.linalg.norm(d0(0.0))
        P0 = c0(0.0)
        res.append((lambda u, P0=P0, t=t: P0 - FAR * (1 - u) * t, lambda u, t=t: FAR * t))
    res += out
    c1, d1 = out[-1]
    if pts[-1][1] > 0:
        t = d1(1.0) / np.linalg.norm(d1(1.0))
        P1 = c1(1.0)
        res.append((lambda u, P1=P1, t=t: P1 + FAR * u * t, lambda u, t=t: FAR * t))
    return res


def tool_polygon(kind, inside):
    """Tool region of the meridian half-plane as a closed polygon (independent encoding of the
    side rule: walking towards +s, the tool is above for inside=True, below otherwise)."""
    ps = pieces(kind)
    q = np.vstack([np.array([c(u) for u in np.linspace(0, 1, 4001)]) for c, _ in ps])
    if q[-1, 0] < q[0, 0]:
        q = q[::-1]
    big = 10 * FAR
    if inside:
        start = [(q[0, 0], big)] if q[0, 1] > 1e-9 else [(-big, big), (-big, 0.0)]
        end = [(q[-1, 0], big)] if q[-1, 1] > 1e-9 else [(big, 0.0), (big, big)]
    else:
        start = [(q[0, 0], -1.0)]
        end = [(q[-1, 0], -1.0)]
    return Path(np.vstack([start, q, end]), closed=False)


def brute_force(kind, inside, x):
    """Closest surface point and signed gap of each row of x, by sampling + refinement."""
    ps = pieces(kind)
    uu = np.linspace(0, 1, 300)
    th = np.linspace(0, 2 * np.pi, 120, endpoint=False)
    U, TH = np.meshgrid(uu, th, indexing="ij")
    allc = [[] for _ in range(len(x))]  # candidate closest points of every row

    def P3(c, u, t):
        q = c(u)
        return AXIS_POINT + q[0] * AXIS + q[1] * (math.cos(t) * E1 + math.sin(t) * E2)

    def cands(c, dc, xi, u0, t0):
        out = []

        def F(z):
            u, t = z
            q, dq = c(u), dc(u)
            er = math.cos(t) * E1 + math.sin(t) * E2
            et = -math.sin(t) * E1 + math.cos(t) * E2
            P = AXIS_POINT + q[0] * AXIS + q[1] * er
            return [(dq[0] * AXIS + dq[1] * er) @ (P - xi), q[1] * (et @ (P - xi))]

        sol = root(F, [u0, t0], method="hybr", options={"xtol": 1e-14})
        if 0.0 < sol.x[0] < 1.0 and np.max(np.abs(F(sol.x))) < 1e-10:
            out.append(P3(c, *sol.x))
        for ue in (0.0, 1.0):  # end circles
            q = c(ue)
            t = math.atan2((xi - AXIS_POINT) @ E2, (xi - AXIS_POINT) @ E1)
            if q[1] > 0:
                sol = root(lambda z: [q[1] * ((-math.sin(z[0]) * E1 + math.cos(z[0]) * E2)
                                              @ (P3(c, ue, z[0]) - xi))], [t])
                t = sol.x[0]
            out.append(P3(c, ue, t))
        return out

    # best sample of every piece; a piece can hold the closest point only if its best sample
    # minus its sample spacing is not farther than the best sample of all pieces
    near = []
    for c, dc in ps:
        Q = np.array([c(u) for u in uu])
        S = (AXIS_POINT + Q[:, None, 0, None] * AXIS
             + Q[:, None, 1, None] * (np.cos(th)[None, :, None] * E1
                                      + np.sin(th)[None, :, None] * E2)).reshape(-1, 3)
        spacing = math.hypot(np.max(np.linalg.norm(np.diff(Q, axis=0), axis=1)),
                             np.max(Q[:, 1]) * (th[1] - th[0]))
        D = np.sqrt(np.maximum((x * x).sum(1)[:, None] + (S * S).sum(1)[None, :]
                               - 2 * x @ S.T, 0.0))
        k = np.argmin(D, axis=1)
        near.append((c, dc, k, D[np.arange(len(x)), k], spacing))
    dmin = np.min([n[3] for n in near], axis=0)
    for c, dc, k, dk, spacing in near:
        for i in np.flatnonzero(dk - spacing <= dmin + 1e-9):
            allc[i] += cands(c, dc, x[i], U.ravel()[k[i]], TH.ravel()[k[i]])
    best_P = np.empty_like(x)
    best_d = np.empty(len(x))
    margin = np.empty(len(x))
    for i, xi in enumerate(x):
        C = np.array(allc[i])
        d = np.linalg.norm(C - xi, axis=1)
        k = np.argmin(d)
        best_P[i], best_d[i] = C[k], d[k]
        other = np.linalg.norm(C - C[k], axis=1) > 1e-6
        margin[i] = (d[other].min() if np.any(other) else np.inf) - d[k]
    u = x - AXIS_POINT
    s = u @ AXIS
    rho = np.linalg.norm(u - s[:, None] * AXIS, axis=1)
    in_tool = tool_polygon(kind, inside).contains_points(np.stack([s, rho], axis=1))
    return best_P, np.where(in_tool, -best_d, best_d), margin


def sample_points(kind, n, seed, wedges=True):
    """Meridian points: near every piece (both sides, 1e-4 .. 0.3), near every profile point
    (kinks), along the pseudo-normals of the vertices (``wedges``; some of these lie exactly on
    a region boundary), and wide; mapped to 3-D at random angles."""
    rng = np.random.default_rng(seed)
    ps = pieces(kind)
    pts = PROFILES[kind][0]
    q = []
    for c, dc in ps:
        for _ in range(n):
            u = rng.uniform(0.02, 0.98) if np.linalg.norm(dc(0.5)) < 50 else rng.uniform(0.95, 1)
            t = dc(u) / np.linalg.norm(dc(u))
            off = rng.choice([-1, 1]) * 10 ** rng.uniform(-4, -0.5)
            q.append(c(u) + off * np.array([-t[1], t[0]]))
    for p in pts:
        for _ in range(n // 2):
            q.append(np.asarray(p) + 10 ** rng.uniform(-3, -0.7) * rng.normal(size=2))
    # around the pseudo-normal of every vertex, both ways (kink wedges, apex region)
    for i, m, _ in make(kind, True).profile.verts if wedges else []:
        for sg in (-1, 1):
            for a in (-0.25, 0.0, 0.25):
                d = sg * np.array([m[0] * math.cos(a) - m[1] * math.sin(a),
                                   m[0] * math.sin(a) + m[1] * math.cos(a)])
                q += [pts[i] + 0.05 * d, pts[i] + 0.3 * d]
    lo = np.min(pts, axis=0) - 0.5
    hi = np.max(pts, axis=0) + 0.5
    q += list(rng.uniform(lo, hi, (2 * n, 2)))
    q = np.array(q)
    q = q[q[:, 1] > 0.05]
    return to3d(q, rng.uniform(0, 2 * np.pi, len(q)))


# --------------------------------------------------------------------------------------------
# projection vs brute force
# --------------------------------------------------------------------------------------------

@pytest.mark.parametrize("kind,inside", CASES, ids=CASE_IDS)
def test_projection_matches_brute_force(kind, inside):
    x = sample_points(kind, 6, 1 + CASES.index((kind, inside)))
    P_ref, g_ref, margin = brute_force(kind, inside, x)
    tool = make(kind, inside)
    pr = tool.project(x)
    assert np.any(g_ref > 0) and np.any(g_ref < 0) and np.any(np.abs(g_ref) < 1e-2)
    np.testing.assert_allclose(pr.gap, g_ref, atol=1e-10)
    assert np.all(np.sign(pr.gap) == np.sign(g_ref))
    unique = margin > 1e-7  # away from medial axes (non-unique closest point)
    assert unique.sum() > 0.9 * len(x)
    np.testing.assert_allclose(pr.point[unique], P_ref[unique], atol=1e-9)
    n_ref = (x - P_ref) / g_ref[:, None]
    ok = unique & (np.abs(g_ref) > 1e-5)
    np.testing.assert_allclose(pr.normal[ok], n_ref[ok], atol=1e-9 / np.abs(g_ref[ok]).min())
    assert np.all(pr.flag == 0)
    # every feature of the profile is met
    assert set(np.unique(pr.feature)) >= {f for f, nm in tool.feature_names.items()
                                          if not ("tangent junction" in nm or "pole" in nm)}


# --------------------------------------------------------------------------------------------
# derivatives by finite differences
# --------------------------------------------------------------------------------------------

def _richardson(tool, x, h):
    """Richardson-extrapolated central differences of the gap and of the normal at every row
    of x along the 3 axes (one projection call): (N, 3) gradient, (N, 3, 3) Hessian (last
    index = derivative direction), and whether the feature is the same on the whole stencil."""
    E = np.eye(3)
    offs = np.concatenate([s * hh * E for hh in (h, h / 2) for s in (1, -1)])  # (12, 3)
    pr = tool.project((x[:, None, :] + offs[None]).reshape(-1, 3))
    g = pr.gap.reshape(len(x), 2, 2, 3)  # [row, step, sign, direction]
    n = pr.normal.reshape(len(x), 2, 2, 3, 3)  # [..., direction, component]
    cd_g = (g[:, :, 0] - g[:, :, 1]) / (2 * np.array([h, h / 2]))[None, :, None]
    cd_n = (n[:, :, 0] - n[:, :, 1]) / (2 * np.array([h, h / 2]))[None, :, None, None]
    grad = (4 * cd_g[:, 1] - cd_g[:, 0]) / 3
    hess = ((4 * cd_n[:, 1] - cd_n[:, 0]) / 3).transpose(0, 2, 1)
    same = np.all(pr.feature.reshape(len(x), 12) == tool.project(x).feature[:, None], axis=1)
    return grad, hess, same


@pytest.mark.parametrize("kind,inside", CASES, ids=CASE_IDS)
@pytest.mark.parametrize("backend", BACKENDS)
def test_gradient_and_hessian_by_finite_differences(kind, inside, backend):
    tool = make(kind, inside, backend)
    x = sample_points(kind, 3, 40 + CASES.index((kind, inside)))
    pr = tool.project(x)
    grad, hfd, same = _richardson(tool, x, 1e-4)
    # skip stencils crossing a region boundary (kink wedge, medial axis)
    np.testing.assert_allclose(grad[same], pr.normal[same], atol=1e-8)
    H = pr.hessian[same]
    err = np.linalg.norm(hfd[same] - H, axis=(1, 2))
    scale = np.maximum(np.linalg.norm(H, axis=(1, 2)), 1.0)
    assert np.all(err < 1e-6 * scale), (err / scale).max()
    assert set(pr.feature[same]) >= {f for f, nm in tool.feature_names.items()
                                     if not ("tangent junction" in nm or "pole" in nm)}


# --------------------------------------------------------------------------------------------
# invariants, backends
# --------------------------------------------------------------------------------------------

@pytest.mark.parametrize("kind,inside", CASES, ids=CASE_IDS)
def test_numba_equals_numpy_twin_and_invariants(kind, inside):
    rng = np.random.default_rng(5)
    pts = PROFILES[kind][0]
    lo, hi = np.min(pts, axis=0) - 1.0, np.max(pts, axis=0) + 1.0
    q = rng.uniform(lo, hi, (3000, 2))
    q[:, 1] = np.abs(q[:, 1])
    x = to3d(q, rng.uniform(0, 2 * np.pi, len(q)))
    a = make(kind, inside, "numba").project(x)
    b = make(kind, inside, "numpy").project(x)
    for k in ("gap", "normal", "point"):
        np.testing.assert_allclose(getattr(a, k), getattr(b, k), rtol=0, atol=1e-12)
    sc = np.maximum(np.abs(a.hessian).max(axis=(1, 2)), 1.0)[:, None, None]
    np.testing.assert_allclose(a.hessian / sc, b.hessian / sc, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(a.feature, b.feature)
    np.testing.assert_array_equal(a.flag, b.flag)
    tool = make(kind, inside)
    assert tool.has_hessian and isinstance(tool, Tool)
    np.testing.assert_allclose(np.linalg.norm(a.normal, axis=1), 1.0, atol=1e-14)
    np.testing.assert_allclose(a.point + a.gap[:, None] * a.normal, x, atol=1e-13)
    np.testing.assert_allclose(a.hessian / sc, a.hessian.transpose(0, 2, 1) / sc, atol=1e-14)
    # ∇²d n = 0; e_r = r/ρ carries a relative rounding error ~1e-16 |x − a|/ρ near the axis
    hn = np.abs(np.einsum("nij,nj->ni", a.hessian, a.normal) / sc[:, :, 0]).max(axis=1)
    assert np.all(hn <= 1e-14 * np.maximum(1.0, 10 / q[:, 1])), hn.max()
    # closest points are on the surface
    np.testing.assert_allclose(tool.project(a.point).gap, 0.0, atol=1e-12)
    assert tool.project(x, hessian=False).hessian is None


# --------------------------------------------------------------------------------------------
# equivalence with Cone, Cylinder and Sphere
# --------------------------------------------------------------------------------------------

def _same(a, b, atol=1e-12):
    np.testing.assert_allclose(a.gap, b.gap, rtol=0, atol=atol)
    np.testing.assert_allclose(a.normal, b.normal, rtol=0, atol=atol)
    np.testing.assert_allclose(a.point, b.point, rtol=0, atol=atol)
    sc = np.maximum(np.abs(b.hessian).max(axis=(1, 2)), 1.0)[:, None, None]
    np.testing.assert_allclose(a.hessian / sc, b.hessian / sc, rtol=0, atol=atol)


@pytest.mark.parametrize("inside", [False, True])
@pytest.mark.parametrize("backend", BACKENDS)
def test_line_profiles_equal_cone_and_cylinder(inside, backend):
    rng = np.random.default_rng(2)
    x = rng.uniform(-3, 3, (2000, 3))
    apex, al = np.array([-0.2, 0.1, 0.3]), 0.6
    w = np.array([0.3, 1.0, -0.4])
    # cone: one line from the apex (on the axis), any length; both point orders
    ref = Cone(apex, w, al, inside=inside).project(x)
    for pts, apex_id in (([(0, 0), (2 * math.cos(al), 2 * math.sin(al))], 1),
                         ([(0.7 * math.cos(al), 0.7 * math.sin(al)), (0, 0)], 2)):
        rp = RevolvedProfile(pts, inside=inside, axis_point=apex, axis=w, backend=backend)
        a = rp.project(x)
        _same(a, ref)
        # Cone: 0 nappe, 1 apex; here 0 the segment, n + i the profile point i (the apex)
        np.testing.assert_array_equal(a.feature, np.where(ref.feature == 1, apex_id, 0))
    # cylinder: a line parallel to the axis (extended both ways)
    a0, R = np.array([0.2, -0.1, 0.4]), 0.8
    rp = RevolvedProfile([(-1.0, R), (0.5, R)], inside=inside, axis_point=a0 + 0.3 * w,
                         axis=w, backend=backend)
    _same(rp.project(x), Cylinder(a0, w, R, inside=inside).project(x))
    # sphere: a half circle centred on the axis, both ends on the axis
    c = np.array([0.1, 0.2, -0.3])
    rp = RevolvedProfile(*SPHERE_PROFILE, inside=inside, axis_point=c, axis=w, backend=backend)
    _same(rp.project(x), Sphere(c, 1.2, inside=inside, axis=w).project(x))


@pytest.mark.parametrize("backend", BACKENDS)
def test_axis_and_singular_points(backend):
    w = np.array([0.0, 0.0, 1.0])
    die = RevolvedProfile.die(1.6, 1.0, math.radians(10), 0.5, backend=backend)
    # on the axis: the closest points form a circle: flag 2, finite, e_fixed used
    pr = die.project([[0, 0, 1.0], [0, 0, 20.0]])
    np.testing.assert_array_equal(pr.flag, [2, 2])
    assert np.all(np.isfinite(pr.hessian)) and np.all(np.isfinite(pr.normal))
    np.testing.assert_allclose(pr.gap[1], 1.0)
    np.testing.assert_allclose(pr.normal[1], [-1, 0, 0])
    np.testing.assert_allclose(pr.hessian[1], -np.diag([0, 1, 0]) / (AXIS_TOL * die.length_scale))
    # cone apex: on the axis behind it regular (unique), at it flag 2 with normal ∓w
    for inside in (False, True):
        cone = RevolvedProfile([(0, 0), (1, 1)], inside=inside, backend=backend)
        sg = -1 if inside else 1
        pr = cone.project([[0, 0, -1.0], [0, 0, 0.0], [0, 0, 2.0]])
        np.testing.assert_array_equal(pr.flag, [0, 2, 2])
        np.testing.assert_array_equal(pr.feature, [1, 1, 0])
        np.testing.assert_allclose(pr.normal[:2], [[0, 0, -sg], [0, 0, -sg]])
        np.testing.assert_allclose(pr.gap[:2], [sg, 0.0])
        np.testing.assert_allclose(pr.hessian[0], sg * np.diag([1, 1, 0]))
    # sphere made of an arc centred on the axis: on the axis regular, at the centre flag 2
    sph = RevolvedProfile(*SPHERE_PROFILE, inside=False, backend=backend)
    pr = sph.project([[0, 0, 0.5], [0, 0, 3.0], [0, 0, 0.0]])
    np.testing.assert_array_equal(pr.flag, [0, 0, 2])
    np.testing.assert_allclose(pr.gap, [-0.7, 1.8, -1.2])
    np.testing.assert_allclose(pr.normal[:2], [w, w])
    # exactly on a kink circle: gap 0, the pseudo-normal, flag 2
    kink = die.points[1]
    pr = die.project([[kink[1], 0, kink[0]]])
    assert pr.flag[0] == 2 and pr.feature[0] == die.profile.n + 1 and pr.gap[0] == 0.0
    al = math.radians(10)
    m = np.array([-math.cos(al) - 1.0, 0.0, -math.sin(al)])
    np.testing.assert_allclose(pr.normal[0], m / np.linalg.norm(m), atol=1e-14)


# --------------------------------------------------------------------------------------------
# profiles
# --------------------------------------------------------------------------------------------

def test_standard_profiles_geometry():
    al, rf, Re, Rf = math.radians(10.0), 0.4, 1.6, 1.0
    die = make("die", True)
    w = AXIS
    # fillet tangent to cone and land: the profile is smooth there; the relief kink is convex
    names = die.feature_names
    assert "tangent junction" in names[die.profile.n + 1]
    assert "tangent junction" in names[die.profile.n + 2]
    assert "kink" in names[die.profile.n + 3]
    pts = die.points
    np.testing.assert_allclose(pts[0], [0, Re])
    np.testing.assert_allclose(pts[2:4, 1], [Rf, Rf])
    np.testing.assert_allclose(pts[3, 0] - pts[2, 0], 0.5)
    # fillet centre at distance rf from the cone line and at Rf + rf
    o = np.array([pts[2, 0], Rf + rf])
    nc = np.array([math.sin(al), math.cos(al)])
    assert abs((o - pts[0]) @ nc - rf) < 1e-13
    # gaps of points of the wire axis region: inside the die (free space) d > 0
    x = AXIS_POINT + 0.9 * E1 + 4.0 * w  # ρ = 0.9 < Rf somewhere along the land
    assert die.project(x).gap[0] > 0
    # the roll: barrel, groove bottom, flange top
    roll = make("roll", False)
    for s, rho, g in ((0.0, 1.6 + 0.1, 0.1), (1.0, 2.0 - 0.05, -0.05), (-1.7, 2.6 + 0.2, 0.2)):
        np.testing.assert_allclose(roll.project(to3d([(s, rho)], np.array([0.3]))).gap, [g],
                                   atol=1e-14)


@pytest.mark.parametrize("build,match", [
    (lambda: RevolvedProfile([(0, 1)], inside=True), "shape"),
    (lambda: RevolvedProfile([(0, 1, 2), (1, 1, 2)], inside=True), "shape"),
    (lambda: RevolvedProfile([(0, 1), (1, np.nan)], inside=True), "not finite"),
    (lambda: RevolvedProfile([(0, 1), (1, -0.5)], inside=True), "point 1 .* < 0"),
    (lambda: RevolvedProfile([(0, 1), (1, 0), (2, 1)], inside=True), "point 1 lies on the axis"),
    (lambda: RevolvedProfile([(0, 1), (1, 1), (1, 1), (2, 1)], inside=True),
     "segment 1 .* zero length"),
    (lambda: RevolvedProfile([(0, 1), (1, 1), (2, 1)], [None, 0.3], inside=True),
     "segment 1: arc radius 0.3 is smaller than half its chord"),
    (lambda: RevolvedProfile([(0, 1), (1, 1)], [None, 1.0], inside=True), "one entry"),
    (lambda: RevolvedProfile([(0, 1), (1, 1)], ["big"], inside=True), "segment 0: arc radius"),
    (lambda: RevolvedProfile([(0, 0.5), (2, 0.5)], [1.0], inside=True),
     "segment 0: the arc reaches the axis"),
    (lambda: RevolvedProfile([(0, 1), (2, 1), (1, 1), (3, 1)], inside=True), "cusp"),
    (lambda: RevolvedProfile([(0, 1), (2, 1), (1, 3), (1, 0.5), (3, 0.5)], inside=True),
     r"intersects itself: segment 0 \(line\) and segment 2 \(line\) meet at \(s, ρ\) = \(1, 1\)"),
    (lambda: RevolvedProfile([(0, 1.6), (2.5, 1.6), (2.5, 2.5), (2, 2), (3, 2)],
                             [None, None, None, 0.5], inside=True),
     r"intersects itself: segment 0 \(line\) and segment 3 \(arc\)"),
    (lambda: RevolvedProfile([(0, 2), (1, 1), (2, 2), (2.5, 1)], inside=True),
     "last profile point's tangent extension would approach the axis"),
    (lambda: RevolvedProfile([(0, 0.5), (1, 1)], inside=False),
     "first profile point's tangent extension would approach the axis"),
    (lambda: RevolvedProfile([(0, 2), (1, 1), (2, 1), (1.5, 1.3)], inside=True),
     r"segment 0 \(line\) and segment 2 \(line\) meet at \(s, ρ\) = \(-0.5, 2.5\)"),
    (lambda: RevolvedProfile([(0, 1), (1, 2), (0, 3)], inside=True), "same s"),
    (lambda: RevolvedProfile([(0, 0), (1, 0)], inside=True), "segment 0 lies on the axis"),
    (lambda: RevolvedProfile([(0, 0), (2, 0.0)], [1.0], inside=True), "reaches the axis"),
    (lambda: RevolvedProfile([(0, 0), (1, 1)], [1.0], inside=False), "does not leave the axis"),
    (lambda: RevolvedProfile([(0, 1), (1, 1)], inside="yes"), "inside"),
    (lambda: RevolvedProfile([(0, 1), (1, 1)], inside=True, axis=(0, 0, 0)), "axis"),
    (lambda: RevolvedProfile([(0, 1), (1, 1)], inside=True, backend="c"), "backend"),
    (lambda: die_profile(1.0, 1.6, 0.2, 0.5), "entry_radius"),
    (lambda: die_profile(1.6, 1.0, 0.2, 0.5, fillet_radius=50.0), "too large"),
    (lambda: die_profile(1.6, 1.0, 2.0, 0.5), "half_angle"),
    (lambda: grooved_roll_profile(2.0, 3.0, 0.5, 0.6), "must not exceed groove_radius"),
    (lambda: grooved_roll_profile(2.0, 1.0, 1.0, 0.9), "do not fit"),
    (lambda: grooved_roll_profile(2.0, 3.0, flange_height=0.5), "flange_width"),
])
def test_bad_profiles(build, match):
    with pytest.raises(ValueError, match=match):
        build()


def test_immutable_and_repr():
    die = RevolvedProfile.die(1.6, 1.0, 0.2, 0.5)
    with pytest.raises(AttributeError):
        die.inside = False
    with pytest.raises(ValueError):
        die.points[0, 0] = 1.0  # read-only array
    assert repr(die).startswith("RevolvedProfile(") and "inside=True" in repr(die)
    assert die.name == "die" and RevolvedProfile.grooved_roll(2.0, 3.0).name == "roll"


def test_inside_is_required_and_point_order_does_not_matter():
    with pytest.raises(TypeError):
        RevolvedProfile([(0, 1), (1, 1)])
    pts, arcs = DIE
    x = sample_points("die", 3, 9)
    a = RevolvedProfile(pts, arcs, inside=True).project(x)
    rev_arcs = [None if r is None else -r for r in arcs[::-1]]
    b = RevolvedProfile(pts[::-1], rev_arcs, inside=True).project(x)
    _same(a, b, atol=1e-13)
    # a die has the tool at large ρ, a roll at small ρ, whatever the point order
    die = RevolvedProfile.die(1.6, 1.0, 0.2, 0.5)
    roll = RevolvedProfile.grooved_roll(2.0, 3.0)
    far = np.array([[50.0, 0.0, 2.0]])
    assert die.project(far).gap[0] < 0 and roll.project(far).gap[0] > 0
    near_axis = np.array([[0.1, 0.0, 2.0]])
    assert die.project(near_axis).gap[0] > 0 and roll.project(near_axis).gap[0] < 0


# --------------------------------------------------------------------------------------------
# moving tools
# --------------------------------------------------------------------------------------------

def test_translated_and_rotating_tool():
    x = sample_points("roll", 3, 11, wedges=False)
    V, om, t = np.array([0.3, -0.5, 0.2]), 2.5, 0.9
    static_moved = make("roll", False, axis_point=AXIS_POINT + V * t)
    moving = make("roll", False, velocity=V, angular_velocity=om)
    a, b = moving.project(x, t), static_moved.project(x)
    _same(a, b, atol=1e-12)
    np.testing.assert_array_equal(a.feature, b.feature)
    # rotation only does not move the surface
    a, b = make("roll", False, angular_velocity=om).project(x, t), make("roll", False).project(x)
    _same(a, b)
    np.testing.assert_array_equal(a.feature, b.feature)
    # material velocity: derivative of a material point's trajectory (scipy Rotation)
    y = make("roll", False).project(x).point

    def traj(s):
        Q = Rotation.from_rotvec(om * s * AXIS).as_matrix()
        return AXIS_POINT + V * s + (y - AXIS_POINT) @ Q.T

    hs = 1e-4
    fd = (traj(t + hs) - traj(t - hs)) / (2 * hs)
    Pt = traj(t)
    vel = moving.velocity(Pt, t)
    np.testing.assert_allclose(vel, fd, rtol=1e-7, atol=1e-7)
    np.testing.assert_allclose(vel, V + om * np.cross(AXIS, Pt - (AXIS_POINT + V * t)),
                               atol=1e-13)
    # a general rigid motion (MovedTool): results are those of the static tool in the moved
    # frame: d(x) = d_ref(Qᵀ(x − c)), n = Q n_ref, H = Q H_ref Qᵀ
    from fxcontact.tools.base import RigidMotion
    mot = RigidMotion(velocity=(0.1, 0.2, -0.3), angular_velocity=0.7, axis_point=(1, 0, 0),
                      axis=(0.2, 0.5, 1.0))
    mt = MovedTool(make("mixed", False), mot)
    pr = mt.project(x, 1.3)
    ref = make("mixed", False).project(mot.to_reference(x, 1.3))
    Q = mot.rotation(1.3)
    np.testing.assert_allclose(pr.gap, ref.gap, atol=1e-12)
    np.testing.assert_allclose(pr.normal, ref.normal @ Q.T, atol=1e-12)
    np.testing.assert_allclose(pr.hessian, np.einsum("ij,njk,lk->nil", Q, ref.hessian, Q),
                               atol=1e-10)


# --------------------------------------------------------------------------------------------
# triangulation
# --------------------------------------------------------------------------------------------

def _sagitta(tool, V, nt, span, max_angle):
    """Largest deviation of a facet from the surface: angular chord of the largest ring plus
    the chord of the largest arc piece."""
    rmax = np.max(np.linalg.norm(np.cross(V - AXIS_POINT, AXIS), axis=1))
    sag = rmax * (1 - math.cos(0.5 * span / nt))
    rarc = max([abs(r) for r in (tool.arcs or []) if r is not None] + [0.0])
    return sag + rarc * (1 - math.cos(0.5 * max_angle))


@pytest.mark.parametrize("kind,inside", [("die", True), ("roll", False), ("mixed", False)])
def test_faceted_revolved_matches_analytic(kind, inside):
    tool = make(kind, inside)
    nt, ma = 48, math.radians(6.0)
    V, T = faceted_revolved(tool, nt, ds=0.1, max_angle=ma, extension=0.3)
    # vertices on the exact surface
    np.testing.assert_allclose(tool.project(V).gap, 0.0, atol=1e-13)
    ft = FacetedTool(V, T, mode="flat", axis_point=AXIS_POINT, axis=AXIS)
    # orientation: facet normals point to free space (analytic normal at the centroid)
    c = V[T].mean(axis=1)
    nf = np.cross(V[T[:, 1]] - V[T[:, 0]], V[T[:, 2]] - V[T[:, 0]])
    assert np.all(np.einsum("ij,ij->i", nf, tool.project(c).normal) > 0)
    # points near the surface, offset along the exact normal from points of the profile
    # pieces away from kinks: flat gap within the chord error of the exact one
    rng = np.random.default_rng(4)
    prs = tool.project(c[rng.choice(len(c), 400, replace=False)])
    delta = rng.uniform(-0.02, 0.02, len(prs))
    x = prs.point + delta[:, None] * prs.normal
    d = tool.project(x).gap
    sag = _sagitta(tool, V, nt, 2 * np.pi, ma)
    dev = 0.5 * math.pi / nt + 0.5 * ma  # angle between a facet and the surface normal
    err = np.abs(ft.project(x).gap - d)
    bound = sag + np.abs(d) * (1 - math.cos(dev)) + 1e-12
    assert np.all(err <= bound), (err.max(), sag)
    assert err.max() > 0.05 * sag  # the bound is not vacuous
    # whole turn with the same motion: MovedTool of a FacetedTool gives the same gaps moving
    mot = make(kind, inside, velocity=(0.0, 0.1, 0.2)).motion
    mt = MovedTool(FacetedTool(V, T, mode="flat"), mot)
    xm = mot.from_reference(x, 0.7)
    np.testing.assert_allclose(mt.project(xm, 0.7).gap, ft.project(x).gap, atol=1e-12)


@pytest.mark.parametrize("nt", [6, 7])
@pytest.mark.parametrize("kind,inside", [("die", True), ("mixed", False), ("sphere", False)])
def test_faceted_sector_is_mirror_symmetric(kind, inside, nt):
    from scipy.spatial import cKDTree

    tool = make(kind, inside)
    th0, th1 = 0.3, 1.2
    V, T = faceted_revolved(tool, nt, sector=(th0, th1), ds=0.2, extension=0.2)
    np.testing.assert_allclose(tool.project(V).gap, 0.0, atol=1e-13)
    # reflection about the plane containing the axis at the mid-angle
    tm = 0.5 * (th0 + th1)
    e1 = tool.e_fixed
    e2 = np.cross(tool.axis, e1)
    nrm = -math.sin(tm) * e1 + math.cos(tm) * e2  # normal of the mid-plane
    Vr = V - 2 * ((V - AXIS_POINT) @ nrm)[:, None] * nrm
    dist, idx = cKDTree(V).query(Vr)
    assert dist.max() < 1e-12
    Tm = np.sort(idx[T], axis=1)
    key = {tuple(t) for t in np.sort(T, axis=1)}
    assert {tuple(t) for t in Tm} == key
    # the sector spans [θ0, θ1]
    ang = np.arctan2((V - AXIS_POINT) @ e2, (V - AXIS_POINT) @ e1)
    off = np.linalg.norm(np.cross(V - AXIS_POINT, tool.axis), axis=1) > 1e-9
    assert abs(ang[off].min() - th0) < 1e-12 and abs(ang[off].max() - th1) < 1e-12
    FacetedTool(V, T, mode="flat", axis_point=AXIS_POINT, axis=AXIS)  # accepted as a tool


def test_faceted_bad_arguments():
    tool = make("die", True)
    for kw in (dict(n_theta=2), dict(n_theta=2.5), dict(n_theta=4, sector=(0, 7)),
               dict(n_theta=4, sector=(1, 1)), dict(n_theta=4, ds=0.0),
               dict(n_theta=4, extension=-1.0)):
        with pytest.raises(ValueError):
            faceted_revolved(tool, **kw)
    with pytest.raises(ValueError, match="RevolvedProfile"):
        faceted_revolved(Cylinder((0, 0, 0), (0, 0, 1), 1.0), 8)


# --------------------------------------------------------------------------------------------
# a contact run
# --------------------------------------------------------------------------------------------

def test_contact_implicit_exact_same_as_cylinder_and_cone():
    """A Norton–Hoff block (2-D) pressed by a roll with the implicit-exact scheme: a
    RevolvedProfile made of one line parallel to the axis (cylinder) or from the axis (cone, whose
    section by the plane z = 0 is a circle) converges like the equivalent Cylinder / Cone, with
    the same tool force to 1e-8 (relative) and the same Newton iteration counts."""
    from mpi4py import MPI

    from fxcontact.contact.boundary import ContactBoundary
    from fxcontact.contact.nodal import NodalContact
    from fxcontact.materials import NortonHoff
    from fxcontact.meshing import BLOCK_TAGS, block
    from fxcontact.simulation import Simulation
    from fxcontact.spaces import MixedSpace

    comm = MPI.COMM_WORLD
    al = 0.5
    apex = (0.0, 3.0 - 0.05, -3.0 / math.tan(al))  # radius 3 at z = 0
    vel = (0.0, -0.5, 0.0)
    pairs = {
        "cylinder": (Cylinder((0.0, 2.95, 0.0), (0, 0, 1), 3.0, velocity=vel, name="roll"),
                     RevolvedProfile([(-1.0, 3.0), (1.0, 3.0)], inside=False,
                                     axis_point=(0.0, 2.95, 0.0), velocity=vel, name="roll")),
        "cone": (Cone(apex, (0, 0, 1), al, velocity=vel, name="roll"),
                 RevolvedProfile([(0.0, 0.0), (math.cos(al), math.sin(al))], inside=False,
                                 axis_point=apex, velocity=vel, name="roll")),
    }
    for kind, tools in pairs.items():
        out = []
        for tool in tools:
            msh, _, ft = block(comm, [-4.0, -2.0], [4.0, 0.0], 0.5, dim=2)
            sp = MixedSpace(msh)
            sim = Simulation(sp, NortonHoff(10.0, 0.3, regularization=1e-4), progress=False)
            sim.add_velocity_bc(sim.facets(ft, BLOCK_TAGS["ymin"]), np.array([0.0, 0.0]))
            sim.add_contributor(NodalContact(ContactBoundary(sp, ft, BLOCK_TAGS["ymax"]), tool,
                                             scheme="implicit-exact", penalty=1e3))
            res = [sim.step(0.1, max_cutbacks=0) for _ in range(2)]  # no cut-back allowed
            assert all(r.info.converged for r in res)
            its = [r.info.iterations for r in res]
            out.append((its, sim.history[-1]["roll_force_y"], sim.history[-1]["contact_nodes"]))
        (it_ref, f_ref, n_ref), (it, f, n) = out
        assert n_ref > 0 and f_ref > 0, (kind, out)
        assert it == it_ref and n == n_ref, (kind, out)
        assert abs(f - f_ref) <= 1e-8 * abs(f_ref), (kind, f, f_ref)
