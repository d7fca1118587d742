"""Analytic rigid tools: plane, sphere, cylinder and cone (THEORY §4).

Every tool returns, in its reference frame, the signed distance ``d`` (positive in free space),
the outward tool normal ``n = ∇d``, the closest point ``P = x − d n`` and the Hessian ``∇²d``
(table of THEORY §4.1). Translation and rotation are handled by :class:`~fxcontact.tools.base.Tool`.

Backends:
    Each tool takes ``backend="numba"`` (default: one ``@numba.njit(cache=True)`` kernel looping
    over the points) or ``backend="numpy"``: a vectorised numpy twin (``_plane_numpy``,
    ``_sphere_numpy``, ``_cylinder_numpy``, ``_cone_numpy``). The twins are reference
    implementations, for testing only; both backends agree to rounding (~1e-15 relative).

Projection flags and features:
    ``feature`` is 0 everywhere except on the cone, where 0 = nappe and 1 = apex region (the foot
    point of the nappe formula would lie beyond the apex, the closest point is the apex).
    ``flag`` is 0 for a regular point and 2 for a *singular* point, where the closest point is not
    unique and the normal is undefined:

    * sphere: ``|x − c| ≤ AXIS_TOL·R`` (the centre);
    * cylinder: ``ρ ≤ AXIS_TOL·R`` (the axis);
    * cone, nappe region: ``ρ ≤ AXIS_TOL·|x − A|`` (the axis in front of the apex);
    * cone, apex region: ``x`` numerically equal to the apex ``A`` (``|x − A|`` evaluates to 0).

    At a singular point the result is finite and deterministic: the radial direction ``e_r`` (the
    direction ``e = (x − c)/|x − c|`` for the sphere) is replaced by the tool's fixed
    perpendicular :attr:`e_fixed` — the Cartesian basis vector least aligned with the axis (lowest
    index on ties), made orthogonal to the axis and normalised; for the sphere the spin axis is
    used, so the default ``axis=(0, 0, 1)`` gives ``e = (1, 0, 0)``. The gap keeps its true value
    (``ρ − R``, ``|x − c| − R``, ``ρ cos α − s sin α``, ...), the point is ``x − d n``, and in the
    Hessian ``1/ρ`` (``1/|x − c|`` for the sphere) is replaced by ``1/(AXIS_TOL·L)`` with
    ``L = R`` (sphere, cylinder) or ``L = |x − A|`` (cone): finite, but huge. At the cone apex
    itself the normal is ``∓w`` (``−w`` for the solid cone, ``+w`` for the conical bore, the
    axis of the normal cone of the apex) and the Hessian is zero.

Cone apex region:
    The tool ``Cone(inside=False)`` is the solid, convex cone ``{s ≥ 0, ρ ≤ s tan α}``;
    ``Cone(inside=True)`` is its complement. Both share the same surface, so the signed distance of
    the bore is exactly minus that of the solid cone. With ``τ = s cos α + ρ sin α`` (the position
    of the foot point along the generator), ``τ > 0`` projects on the nappe and ``τ ≤ 0`` on the
    apex, for both variants: for the solid cone the apex region is free space
    (``d = |x − A|``, ``n = e``), for the bore it is inside the tool behind the apex
    (``d = −|x − A|``, ``n = −e``, ``∇²d = −(I − e⊗e)/|x − A|``). Since the solid cone is convex,
    the projection of every point of the bore's tool side (including behind the apex and on the
    negative axis) is unique; the only singular points of the bore are on the positive axis, in
    free space.
"""

from __future__ import annotations

import logging
import math
from typing import Callable, Tuple

import numba
import numpy as np

from fxcontact.tools.base import Projection, RigidMotion, Tool, as_points, unit_vector

__all__ = ["AXIS_TOL", "Plane", "Sphere", "Cylinder", "Cone", "AnalyticTool", "finite_vector",
           "check_flag", "readonly_copy", "fixed_perpendicular", "float_tuple"]

logger = logging.getLogger(__name__)

#: Relative distance to the axis / centre below which a point is flagged singular (flag = 2).
AXIS_TOL = 1e-12

_BACKENDS = ("numba", "numpy")

_Arrays = Tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]


# --------------------------------------------------------------------------------------------
# helpers
# --------------------------------------------------------------------------------------------

def finite_vector(value, name: str) -> np.ndarray:
    """``value`` as a float64 3-vector; ValueError naming ``name`` if it is not a finite
    3-vector."""
    a = np.asarray(value, dtype=np.float64).reshape(-1)
    if a.shape != (3,) or not np.all(np.isfinite(a)):
        raise ValueError(f"{name} must be a finite 3-vector, got {value!r}")
    return a


def _positive_length(value, name: str) -> float:
    try:
        r = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a positive finite number, got {value!r}") from None
    if not (np.isfinite(r) and r > 0.0):
        raise ValueError(f"{name} must be a positive finite number, got {value!r}")
    return r


def check_flag(value, name: str) -> bool:
    """``value`` as a bool; ValueError naming ``name`` if it is not a bool."""
    if not isinstance(value, (bool, np.bool_)):
        raise ValueError(f"{name} must be a bool, got {value!r}")
    return bool(value)


def _check_backend(backend) -> str:
    if backend not in _BACKENDS:
        raise ValueError(f"backend must be one of {_BACKENDS}, got {backend!r}")
    return backend


def _check_name(name) -> str:
    if not isinstance(name, str):
        raise ValueError(f"name must be a string, got {name!r}")
    return name


def readonly_copy(a: np.ndarray) -> np.ndarray:
    """A read-only float64 copy of ``a`` (the geometry arrays of an immutable tool)."""
    a = np.array(a, dtype=np.float64)
    a.flags.writeable = False
    return a


def fixed_perpendicular(w: np.ndarray) -> np.ndarray:
    """Deterministic unit vector orthogonal to the unit vector ``w``.

    The Cartesian basis vector with the smallest ``|w_k|`` (lowest index on ties), made orthogonal
    to ``w`` (Gram–Schmidt) and normalised. For ``w = ±e_z`` this is ``e_x``.
    """
    k = int(np.argmin(np.abs(w)))
    e = np.zeros(3)
    e[k] = 1.0
    e -= (e @ w) * w
    return e / np.linalg.norm(e)


def _allocate(n: int, want_h: bool) -> _Arrays:
    return (np.empty(n), np.empty((n, 3)), np.empty((n, 3)),
            np.empty((n, 3, 3) if want_h else (0, 3, 3)),
            np.zeros(n, dtype=np.int64), np.zeros(n, dtype=np.int64))


# --------------------------------------------------------------------------------------------
# numba kernels (one loop over the points each)
# --------------------------------------------------------------------------------------------

@numba.njit(cache=True)
def _plane_kernel(y, p0, n0, want_h, gap, nrm, pt, hes, feat, flag):  # pragma: no cover - JIT
    for i in range(y.shape[0]):
        d = (y[i, 0] - p0[0]) * n0[0] + (y[i, 1] - p0[1]) * n0[1] + (y[i, 2] - p0[2]) * n0[2]
        gap[i] = d
        for k in range(3):
            nrm[i, k] = n0[k]
            pt[i, k] = y[i, k] - d * n0[k]
        if want_h:
            for k in range(3):
                for m in range(3):
                    hes[i, k, m] = 0.0
        feat[i] = 0
        flag[i] = 0


@numba.njit(cache=True)
def _sphere_kernel(y, c, radius, sgn, efix, tol, want_h,
                   gap, nrm, pt, hes, feat, flag):  # pragma: no cover - JIT
    e = np.empty(3)
    for i in range(y.shape[0]):
        u0 = y[i, 0] - c[0]
        u1 = y[i, 1] - c[1]
        u2 = y[i, 2] - c[2]
        r = math.sqrt(u0 * u0 + u1 * u1 + u2 * u2)
        if r > tol * radius:
            e[0] = u0 / r
            e[1] = u1 / r
            e[2] = u2 / r
            rinv = 1.0 / r
            flag[i] = 0
        else:
            e[0] = efix[0]
            e[1] = efix[1]
            e[2] = efix[2]
            rinv = 1.0 / (tol * radius)
            flag[i] = 2
        d = sgn * (r - radius)
        gap[i] = d
        for k in range(3):
            nrm[i, k] = sgn * e[k]
            pt[i, k] = y[i, k] - d * nrm[i, k]
        if want_h:
            f = sgn * rinv
            for k in range(3):
                for m in range(3):
                    hes[i, k, m] = -f * e[k] * e[m]
                hes[i, k, k] += f
        feat[i] = 0


@numba.njit(cache=True)
def _cylinder_kernel(y, a, w, radius, sgn, efix, tol, want_h,
                     gap, nrm, pt, hes, feat, flag):  # pragma: no cover - JIT
    er = np.empty(3)
    et = np.empty(3)
    r = np.empty(3)
    for i in range(y.shape[0]):
        u0 = y[i, 0] - a[0]
        u1 = y[i, 1] - a[1]
        u2 = y[i, 2] - a[2]
        s = u0 * w[0] + u1 * w[1] + u2 * w[2]
        r[0] = u0 - s * w[0]
        r[1] = u1 - s * w[1]
        r[2] = u2 - s * w[2]
        rho = math.sqrt(r[0] * r[0] + r[1] * r[1] + r[2] * r[2])
        if rho > tol * radius:
            for k in range(3):
                er[k] = r[k] / rho
            rinv = 1.0 / rho
            flag[i] = 0
        else:
            for k in range(3):
                er[k] = efix[k]
            rinv = 1.0 / (tol * radius)
            flag[i] = 2
        d = sgn * (rho - radius)
        gap[i] = d
        for k in range(3):
            nrm[i, k] = sgn * er[k]
            pt[i, k] = y[i, k] - d * nrm[i, k]
        if want_h:
            et[0] = w[1] * er[2] - w[2] * er[1]
            et[1] = w[2] * er[0] - w[0] * er[2]
            et[2] = w[0] * er[1] - w[1] * er[0]
            f = sgn * rinv
            for k in range(3):
                for m in range(3):
                    hes[i, k, m] = f * et[k] * et[m]
        feat[i] = 0


@numba.njit(cache=True)
def _cone_kernel(y, apex, w, ca, sa, sgn, efix, tol, want_h,
                 gap, nrm, pt, hes, feat, flag):  # pragma: no cover - JIT
    er = np.empty(3)
    et = np.empty(3)
    r = np.empty(3)
    n0 = np.empty(3)
    for i in range(y.shape[0]):
        u0 = y[i, 0] - apex[0]
        u1 = y[i, 1] - apex[1]
        u2 = y[i, 2] - apex[2]
        s = u0 * w[0] + u1 * w[1] + u2 * w[2]
        r[0] = u0 - s * w[0]
        r[1] = u1 - s * w[1]
        r[2] = u2 - s * w[2]
        rho = math.sqrt(r[0] * r[0] + r[1] * r[1] + r[2] * r[2])
        dist = math.sqrt(u0 * u0 + u1 * u1 + u2 * u2)
        tau = s * ca + rho * sa
        if tau > 0.0:
            # nappe
            if rho > tol * dist:
                for k in range(3):
                    er[k] = r[k] / rho
                rinv = 1.0 / rho
                flag[i] = 0
            else:
                for k in range(3):
                    er[k] = efix[k]
                rinv = 1.0 / (tol * dist)
                flag[i] = 2
            d0 = rho * ca - s * sa
            for k in range(3):
                n0[k] = ca * er[k] - sa * w[k]
            d = sgn * d0
            gap[i] = d
            for k in range(3):
                nrm[i, k] = sgn * n0[k]
                pt[i, k] = y[i, k] - d * nrm[i, k]
            if want_h:
                et[0] = w[1] * er[2] - w[2] * er[1]
                et[1] = w[2] * er[0] - w[0] * er[2]
                et[2] = w[0] * er[1] - w[1] * er[0]
                f = sgn * ca * rinv
                for k in range(3):
                    for m in range(3):
                        hes[i, k, m] = f * et[k] * et[m]
            feat[i] = 0
        else:
            # apex region: distance to the apex point
            if dist > 0.0:
                n0[0] = u0 / dist
                n0[1] = u1 / dist
                n0[2] = u2 / dist
                f = sgn / dist
                flag[i] = 0
            else:
                for k in range(3):
                    n0[k] = -w[k]
                f = 0.0
                flag[i] = 2
            d = sgn * dist
            gap[i] = d
            for k in range(3):
                nrm[i, k] = sgn * n0[k]
                pt[i, k] = y[i, k] - d * nrm[i, k]
            if want_h:
                for k in range(3):
                    for m in range(3):
                        hes[i, k, m] = -f * n0[k] * n0[m]
                    hes[i, k, k] += f
            feat[i] = 1


# --------------------------------------------------------------------------------------------
# numpy twins: reference implementations, for testing only
# --------------------------------------------------------------------------------------------

def _plane_numpy(y, p0, n0, want_h) -> _Arrays:
    """Plane projection, vectorised numpy. Reference implementation, for testing only."""
    n = y.shape[0]
    gap = (y - p0) @ n0
    nrm = np.broadcast_to(n0, (n, 3)).copy()
    pt = y - gap[:, None] * nrm
    hes = np.zeros((n, 3, 3)) if want_h else np.empty((0, 3, 3))
    return gap, nrm, pt, hes, np.zeros(n, np.int64), np.zeros(n, np.int64)


def _sphere_numpy(y, c, radius, sgn, efix, tol, want_h) -> _Arrays:
    """Sphere / spherical cavity projection, vectorised numpy. Reference, for testing only."""
    n = y.shape[0]
    u = y - c
    r = np.sqrt(np.einsum("ni,ni->n", u, u))
    ok = r > tol * radius
    rs = np.where(ok, r, 1.0)
    e = np.where(ok[:, None], u / rs[:, None], efix)
    rinv = np.where(ok, 1.0 / rs, 1.0 / (tol * radius))
    gap = sgn * (r - radius)
    nrm = sgn * e
    pt = y - gap[:, None] * nrm
    if want_h:
        hes = (sgn * rinv)[:, None, None] * (np.eye(3) - e[:, :, None] * e[:, None, :])
    else:
        hes = np.empty((0, 3, 3))
    flag = np.where(ok, 0, 2).astype(np.int64)
    return gap, nrm, pt, hes, np.zeros(n, np.int64), flag


def _axial(y, a, w):
    """Axial coordinate s, radial vector r, radius ρ and |y − a| of points about an axis."""
    u = y - a
    s = u @ w
    r = u - s[:, None] * w
    rho = np.sqrt(np.einsum("ni,ni->n", r, r))
    dist = np.sqrt(np.einsum("ni,ni->n", u, u))
    return u, s, r, rho, dist


def _cylinder_numpy(y, a, w, radius, sgn, efix, tol, want_h) -> _Arrays:
    """Cylinder / bore projection, vectorised numpy. Reference implementation, for testing only."""
    n = y.shape[0]
    _, _, r, rho, _ = _axial(y, a, w)
    ok = rho > tol * radius
    rs = np.where(ok, rho, 1.0)
    er = np.where(ok[:, None], r / rs[:, None], efix)
    rinv = np.where(ok, 1.0 / rs, 1.0 / (tol * radius))
    gap = sgn * (rho - radius)
    nrm = sgn * er
    pt = y - gap[:, None] * nrm
    if want_h:
        et = np.cross(w, er)
        hes = (sgn * rinv)[:, None, None] * et[:, :, None] * et[:, None, :]
    else:
        hes = np.empty((0, 3, 3))
    flag = np.where(ok, 0, 2).astype(np.int64)
    return gap, nrm, pt, hes, np.zeros(n, np.int64), flag


def _cone_numpy(y, apex, w, ca, sa, sgn, efix, tol, want_h) -> _Arrays:
    """Cone / conical bore projection, vectorised numpy. Reference, for testing only."""
    u, s, r, rho, dist = _axial(y, apex, w)
    nappe = s * ca + rho * sa > 0.0
    # nappe region
    ok_n = rho > tol * dist
    rs = np.where(ok_n, rho, 1.0)
    er = np.where(ok_n[:, None], r / rs[:, None], efix)
    with np.errstate(divide="ignore"):
        rinv_n = np.where(ok_n, 1.0 / rs, 1.0 / (tol * dist))
    d_n = rho * ca - s * sa
    n_n = ca * er - sa * w
    # apex region
    ok_a = dist > 0.0
    ds = np.where(ok_a, dist, 1.0)
    e = np.where(ok_a[:, None], u / ds[:, None], -w)
    f_a = np.where(ok_a, 1.0 / ds, 0.0)

    gap = sgn * np.where(nappe, d_n, dist)
    nrm = sgn * np.where(nappe[:, None], n_n, e)
    pt = y - gap[:, None] * nrm
    if want_h:
        et = np.cross(w, er)
        h_n = (ca * np.where(nappe, rinv_n, 0.0))[:, None, None] * et[:, :, None] * et[:, None, :]
        h_a = f_a[:, None, None] * (np.eye(3) - e[:, :, None] * e[:, None, :])
        hes = sgn * np.where(nappe[:, None, None], h_n, h_a)
    else:
        hes = np.empty((0, 3, 3))
    flag = np.where(nappe, np.where(ok_n, 0, 2), np.where(ok_a, 0, 2)).astype(np.int64)
    feat = np.where(nappe, 0, 1).astype(np.int64)
    return gap, nrm, pt, hes, feat, flag


def _numba_caller(kernel: Callable, zero_hessian: bool = False) -> Callable:
    """Wrap a kernel as ``f(y, *params, want_h) -> arrays`` (allocating the outputs).

    ``zero_hessian``: the Hessian is identically zero (plane); it is allocated with ``np.zeros``
    (lazily zeroed pages) instead of being written by the kernel.
    """

    def run(y, *args) -> _Arrays:
        want_h = bool(args[-1])
        out = _allocate(y.shape[0], want_h and not zero_hessian)
        if zero_hessian and want_h:
            out = out[:3] + (np.zeros((y.shape[0], 3, 3)),) + out[4:]
            want_h = False
        kernel(y, *args[:-1], want_h, *out)
        return out

    run.__name__ = kernel.__name__.replace("_kernel", "_numba")
    return run


_IMPLEMENTATIONS = {
    "plane": {"numba": _numba_caller(_plane_kernel, zero_hessian=True), "numpy": _plane_numpy},
    "sphere": {"numba": _numba_caller(_sphere_kernel), "numpy": _sphere_numpy},
    "cylinder": {"numba": _numba_caller(_cylinder_kernel), "numpy": _cylinder_numpy},
    "cone": {"numba": _numba_caller(_cone_kernel), "numpy": _cone_numpy},
}


# --------------------------------------------------------------------------------------------
# tool classes
# --------------------------------------------------------------------------------------------

class AnalyticTool(Tool):
    """Immutable analytic tool: attributes are read-only once the constructor has run."""

    _kind: str = ""
    _frozen: bool = False

    def __setattr__(self, key, value):
        if self._frozen:
            raise AttributeError(f"{type(self).__name__} is immutable (cannot set {key!r})")
        object.__setattr__(self, key, value)

    def __delattr__(self, key):
        raise AttributeError(f"{type(self).__name__} is immutable (cannot delete {key!r})")

    def _init_common(self, name, backend, motion: RigidMotion):
        self.name = _check_name(name)
        self.backend = _check_backend(backend)
        self.motion = motion

    def _params(self) -> tuple:  # pragma: no cover - abstract
        raise NotImplementedError

    def _project_reference(self, y: np.ndarray, hessian: bool) -> Projection:
        """Project (N, 3) reference-frame points (see the module docstring for flags)."""
        y = as_points(y)
        impl = _IMPLEMENTATIONS[self._kind][self.backend]
        gap, nrm, pt, hes, feat, flag = impl(y, *self._params(), bool(hessian))
        if logger.isEnabledFor(logging.DEBUG):
            n_sing = int(np.count_nonzero(flag == 2))
            if n_sing:
                logger.debug("%s: %d singular point(s) (flag = 2, on the axis / centre)",
                             self.name, n_sing)
        return Projection(gap, nrm, pt, hes if hessian else None, feat, flag)

    def _repr_fields(self) -> str:  # pragma: no cover - overridden
        return ""

    def __repr__(self) -> str:
        return (f"{type(self).__name__}({self._repr_fields()}, name={self.name!r}, "
                f"backend={self.backend!r})")


def float_tuple(a: np.ndarray) -> tuple:
    """The entries of ``a`` as a tuple of Python floats (motions, representations)."""
    return tuple(float(v) for v in a)


class Plane(AnalyticTool):
    """Half-space tool bounded by a plane.

    The tool occupies the side opposite to ``normal``: ``d = (x − p₀)·n₀``, ``∇²d = 0``.

    Args:
        point: a point ``p₀`` of the plane (at ``t = 0``).
        normal: outward tool normal ``n₀`` (points into free space); normalised here.
        velocity: translation velocity, constant 3-vector or function ``v(t)``.
        name: label of the tool.
        backend: ``"numba"`` (default) or ``"numpy"`` (reference twin, for testing only).

    Raises:
        ValueError: non-finite point, zero or non-finite normal, bad backend.
    """

    _kind = "plane"

    def __init__(self, point, normal, velocity=(0.0, 0.0, 0.0), name: str = "plane",
                 backend: str = "numba"):
        self.point = readonly_copy(finite_vector(point, "Plane point"))
        self.normal = readonly_copy(unit_vector(normal, "Plane normal"))
        self._init_common(name, backend,
                          RigidMotion(velocity=velocity, angular_velocity=0.0,
                                      axis_point=float_tuple(self.point),
                                      axis=float_tuple(self.normal)))
        self._frozen = True

    def _params(self):
        return (self.point, self.normal)

    def _repr_fields(self):
        return f"point={float_tuple(self.point)}, normal={float_tuple(self.normal)}"


class Sphere(AnalyticTool):
    """Ball tool or spherical cavity.

    ``inside=False``: the tool is the ball, ``d = |x − c| − R``. ``inside=True``: spherical cavity
    (the body is inside the sphere, the tool outside), ``d = R − |x − c|``.

    Args:
        center: centre ``c`` at ``t = 0``.
        radius: ``R > 0``.
        inside: cavity instead of ball.
        velocity: translation velocity, constant or ``v(t)``.
        angular_velocity: spin ω about ``axis`` through the centre (constant or ``ω(t)``); it does
            not move the surface but enters :meth:`velocity`.
        axis: spin axis (default ``e_z``); also defines :attr:`e_fixed`, the direction used at
            the centre.
        name: label of the tool.
        backend: ``"numba"`` (default) or ``"numpy"`` (reference twin, for testing only).

    Raises:
        ValueError: on invalid arguments.
    """

    _kind = "sphere"

    def __init__(self, center, radius, inside: bool = False, velocity=(0.0, 0.0, 0.0),
                 angular_velocity=0.0, axis=(0.0, 0.0, 1.0), name: str = "sphere",
                 backend: str = "numba"):
        self.center = readonly_copy(finite_vector(center, "Sphere center"))
        self.radius = _positive_length(radius, "Sphere radius")
        self.inside = check_flag(inside, "inside")
        self.axis = readonly_copy(unit_vector(axis, "Sphere spin axis"))
        self.e_fixed = readonly_copy(fixed_perpendicular(self.axis))
        self._init_common(name, backend,
                          RigidMotion(velocity=velocity, angular_velocity=angular_velocity,
                                      axis_point=float_tuple(self.center),
                                      axis=float_tuple(self.axis)))
        self._frozen = True

    def _params(self):
        return (self.center, self.radius, -1.0 if self.inside else 1.0, self.e_fixed, AXIS_TOL)

    def _repr_fields(self):
        return f"center={float_tuple(self.center)}, radius={self.radius}, inside={self.inside}"


class Cylinder(AnalyticTool):
    """Infinite circular cylinder (roll, mandrel) or bore.

    ``inside=False``: the tool is the solid cylinder, ``d = ρ − R``; ``inside=True``: bore (the
    body is inside), ``d = R − ρ``, with ``ρ`` the distance to the axis.

    Args:
        point: a point ``a`` of the axis at ``t = 0``.
        axis: axis direction ``w`` (normalised here).
        radius: ``R > 0``.
        inside: bore instead of solid cylinder.
        velocity: translation velocity, constant or ``v(t)``.
        angular_velocity: rotation ω about the cylinder's own axis (constant or ``ω(t)``); it does
            not move the surface but enters :meth:`velocity`.
        name: label of the tool.
        backend: ``"numba"`` (default) or ``"numpy"`` (reference twin, for testing only).

    Raises:
        ValueError: on invalid arguments.
    """

    _kind = "cylinder"

    def __init__(self, point, axis, radius, inside: bool = False, velocity=(0.0, 0.0, 0.0),
                 angular_velocity=0.0, name: str = "cylinder", backend: str = "numba"):
        self.point = readonly_copy(finite_vector(point, "Cylinder point"))
        self.axis = readonly_copy(unit_vector(axis, "Cylinder axis"))
        self.radius = _positive_length(radius, "Cylinder radius")
        self.inside = check_flag(inside, "inside")
        self.e_fixed = readonly_copy(fixed_perpendicular(self.axis))
        self._init_common(name, backend,
                          RigidMotion(velocity=velocity, angular_velocity=angular_velocity,
                                      axis_point=float_tuple(self.point),
                                      axis=float_tuple(self.axis)))
        self._frozen = True

    def _params(self):
        return (self.point, self.axis, self.radius, -1.0 if self.inside else 1.0, self.e_fixed,
                AXIS_TOL)

    def _repr_fields(self):
        return (f"point={float_tuple(self.point)}, axis={float_tuple(self.axis)}, "
                f"radius={self.radius}, inside={self.inside}")


class Cone(AnalyticTool):
    """Infinite single-nappe circular cone (axial roll) or conical bore (drawing die).

    ``inside=False``: the tool is the solid cone ``{s ≥ 0, ρ ≤ s tan α}``; on the nappe
    ``d = ρ cos α − s sin α``, and beyond the apex (``s cos α + ρ sin α ≤ 0``) ``d = |x − A|``.
    ``inside=True``: the complement (the body is inside the cone), ``d`` is exactly the opposite.
    See the module docstring for the apex region (``feature = 1``) and the axis (``flag = 2``).

    Args:
        apex: apex ``A`` at ``t = 0``.
        axis: direction ``w`` from the apex towards the opening (normalised here).
        half_angle: ``α`` in radians, ``0 < α < π/2``.
        inside: conical bore instead of solid cone.
        velocity: translation velocity, constant or ``v(t)``.
        angular_velocity: rotation ω about the cone's own axis (constant or ``ω(t)``).
        name: label of the tool.
        backend: ``"numba"`` (default) or ``"numpy"`` (reference twin, for testing only).

    Raises:
        ValueError: on invalid arguments.
    """

    _kind = "cone"

    def __init__(self, apex, axis, half_angle, inside: bool = False, velocity=(0.0, 0.0, 0.0),
                 angular_velocity=0.0, name: str = "cone", backend: str = "numba"):
        self.apex = readonly_copy(finite_vector(apex, "Cone apex"))
        self.axis = readonly_copy(unit_vector(axis, "Cone axis"))
        try:
            alpha = float(half_angle)
        except (TypeError, ValueError):
            raise ValueError(f"Cone half_angle must be a number, got {half_angle!r}") from None
        if not (np.isfinite(alpha) and 0.0 < alpha < 0.5 * np.pi):
            raise ValueError(f"Cone half_angle must satisfy 0 < α < π/2 (radians), "
                             f"got {half_angle!r}")
        self.half_angle = alpha
        self.inside = check_flag(inside, "inside")
        self.e_fixed = readonly_copy(fixed_perpendicular(self.axis))
        self._init_common(name, backend,
                          RigidMotion(velocity=velocity, angular_velocity=angular_velocity,
                                      axis_point=float_tuple(self.apex),
                                      axis=float_tuple(self.axis)))
        self._frozen = True

    def _params(self):
        return (self.apex, self.axis, math.cos(self.half_angle), math.sin(self.half_angle),
                -1.0 if self.inside else 1.0, self.e_fixed, AXIS_TOL)

    def _repr_fields(self):
        return (f"apex={float_tuple(self.apex)}, axis={float_tuple(self.axis)}, "
                f"half_angle={self.half_angle}, inside={self.inside}")
