"""Configuration updates X(v) of the nodes over one increment, the mesh motion, and the fully
implicit gap composition (THEORY §3.4, §5): the kinematics of fxcontact in one module.

* :class:`CartesianUpdate`: X = x + dt v (J = dt I, ∂²X = 0);
* :class:`CylindricalUpdate`: the ring-rolling update of THEORY §5 about a fixed axis (radius
  preserved for a rigid rotation about the ring axis);
* :class:`RingAxisUpdate`: the same about an axis through a centre re-set at each increment
  (the ring's centroid: the centre moves as the ring grows);

and the maps behind them, with the signature ``(x, v, dt) -> (X, J, d2X)``:

* :func:`cartesian_update`: ``X = x + dt·v`` (``J = dt·I``, ``d2X = 0``);
* :func:`cylindrical_update`: the cylindrical update of rotating rings about an axis
  ``(c, w)``, exact for rigid rotation (no radial drift).

``J[n, i, a] = ∂X_i/∂v_a`` and ``d2X[n, i, a, b] = ∂²X_i/∂v_a∂v_b`` for node ``n``.
:func:`gap_derivatives` composes a tool projection at ``X(v)`` with these derivatives to give the
fully implicit constraint ``h(v) = −d(X(v))/dt`` and its gradient and Hessian. The contact
condition and the mesh motion use the **same** map (THEORY §5, last property).

Backends: ``backend="numba"`` (default) runs one ``@numba.njit(cache=True)`` loop over the nodes;
``backend="numpy"`` runs ``_cylindrical_numpy``, a vectorised reference implementation, for
testing only. (``fxcontact.kinematics`` is the former name of the maps' module, kept as an
alias.)
"""


from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field
from typing import Optional, Tuple

import numba
import numpy as np

from fxcontact.tools.base import Projection, unit_vector

__all__ = ["CartesianUpdate", "CylindricalUpdate", "RingAxisUpdate", "AXIS_TOL",
           "cartesian_update", "cylindrical_update", "gap_derivatives", "pad3"]

logger = logging.getLogger(__name__)

#: A node with ``r ≤ AXIS_TOL·|x − c|`` is considered on the ring axis (ValueError).
AXIS_TOL = 1e-12

_Update = Tuple[np.ndarray, Optional[np.ndarray], Optional[np.ndarray]]


def _nodes(a, name: str) -> np.ndarray:
    out = np.ascontiguousarray(a, dtype=np.float64)
    if out.ndim == 1 and out.shape[0] == 3:
        out = out.reshape(1, 3)
    if out.ndim != 2 or out.shape[1] != 3:
        raise ValueError(f"{name} must have shape (N, 3), got {np.shape(a)}")
    if not np.all(np.isfinite(out)):
        bad = np.flatnonzero(~np.all(np.isfinite(out), axis=1))
        raise ValueError(f"{name} contains NaN/inf at rows {bad[:10].tolist()}")
    return out


def _check_common(x, v, dt) -> Tuple[np.ndarray, np.ndarray, float]:
    x = _nodes(x, "x")
    v = _nodes(v, "v")
    if x.shape != v.shape:
        raise ValueError(f"x and v must have the same shape, got {x.shape} and {v.shape}")
    try:
        dt = float(dt)
    except (TypeError, ValueError):
        raise ValueError(f"dt must be a positive finite number, got {dt!r}") from None
    if not (np.isfinite(dt) and dt > 0.0):
        raise ValueError(f"dt must be a positive finite number, got {dt!r}")
    return x, v, dt


def cartesian_update(x, v, dt: float, derivatives: bool = True) -> _Update:
    """Cartesian end-of-increment positions ``X = x + dt·v``.

    Args:
        x: (N, 3) positions at the start of the increment.
        v: (N, 3) nodal velocities.
        dt: time step (> 0).
        derivatives: whether to return ``J`` and ``d2X``.

    Returns:
        ``(X, J, d2X)``: (N, 3) positions, (N, 3, 3) ``J = dt·I`` and (N, 3, 3, 3) zeros, or
        ``(X, None, None)`` if ``derivatives`` is False.

    Raises:
        ValueError: bad shapes, non-finite values or ``dt ≤ 0``.
    """
    x, v, dt = _check_common(x, v, dt)
    X = x + dt * v
    if not derivatives:
        return X, None, None
    n = x.shape[0]
    J = np.zeros((n, 3, 3))
    J[:, 0, 0] = J[:, 1, 1] = J[:, 2, 2] = dt
    return X, J, np.zeros((n, 3, 3, 3))


@numba.njit(cache=True)
def _cylindrical_kernel(x, v, dt, c, w, tol, want_d, X, J, d2X):  # pragma: no cover - JIT
    """Cylindrical update loop; returns the index of the first node on the axis, or -1."""
    er = np.empty(3)
    et = np.empty(3)
    er2 = np.empty(3)
    et2 = np.empty(3)
    for n in range(x.shape[0]):
        y0 = x[n, 0] - c[0]
        y1 = x[n, 1] - c[1]
        y2 = x[n, 2] - c[2]
        z = y0 * w[0] + y1 * w[1] + y2 * w[2]
        er[0] = y0 - z * w[0]
        er[1] = y1 - z * w[1]
        er[2] = y2 - z * w[2]
        r = math.sqrt(er[0] * er[0] + er[1] * er[1] + er[2] * er[2])
        if not r > tol * math.sqrt(y0 * y0 + y1 * y1 + y2 * y2):
            return n
        for k in range(3):
            er[k] /= r
        et[0] = w[1] * er[2] - w[2] * er[1]
        et[1] = w[2] * er[0] - w[0] * er[2]
        et[2] = w[0] * er[1] - w[1] * er[0]
        vr = v[n, 0] * er[0] + v[n, 1] * er[1] + v[n, 2] * er[2]
        vt = v[n, 0] * et[0] + v[n, 1] * et[1] + v[n, 2] * et[2]
        vz = v[n, 0] * w[0] + v[n, 1] * w[1] + v[n, 2] * w[2]
        r2 = r + dt * vr
        dth = dt * vt / r
        z2 = z + dt * vz
        cs = math.cos(dth)
        sn = math.sin(dth)
        for k in range(3):
            er2[k] = cs * er[k] + sn * et[k]
            et2[k] = -sn * er[k] + cs * et[k]
            X[n, k] = c[k] + z2 * w[k] + r2 * er2[k]
        if want_d:
            q = r2 / r
            f1 = dt * dt / r
            f2 = dt * dt * r2 / (r * r)
            for i in range(3):
                for a in range(3):
                    J[n, i, a] = dt * (er2[i] * er[a] + q * et2[i] * et[a] + w[i] * w[a])
                    for b in range(3):
                        d2X[n, i, a, b] = (f1 * et2[i] * (er[a] * et[b] + et[a] * er[b])
                                           - f2 * er2[i] * et[a] * et[b])
    return -1


def _cylindrical_numpy(x, v, dt, c, w, tol, want_d):
    """Cylindrical update, vectorised numpy. Reference implementation, for testing only.

    Returns ``(X, J, d2X, bad)`` with ``bad`` the index of the first node on the axis or -1.
    """
    y = x - c
    z = y @ w
    rv = y - z[:, None] * w
    r = np.sqrt(np.einsum("ni,ni->n", rv, rv))
    on_axis = ~(r > tol * np.sqrt(np.einsum("ni,ni->n", y, y)))
    if np.any(on_axis):
        return None, None, None, int(np.flatnonzero(on_axis)[0])
    er = rv / r[:, None]
    et = np.cross(w, er)
    vr = np.einsum("ni,ni->n", v, er)
    vt = np.einsum("ni,ni->n", v, et)
    vz = v @ w
    r2 = r + dt * vr
    dth = dt * vt / r
    z2 = z + dt * vz
    cs = np.cos(dth)[:, None]
    sn = np.sin(dth)[:, None]
    er2 = cs * er + sn * et
    et2 = -sn * er + cs * et
    X = c + z2[:, None] * w + r2[:, None] * er2
    if not want_d:
        return X, None, None, -1
    q = (r2 / r)[:, None, None]
    J = dt * (er2[:, :, None] * er[:, None, :] + q * et2[:, :, None] * et[:, None, :]
              + np.outer(w, w))
    sym = er[:, :, None] * et[:, None, :] + et[:, :, None] * er[:, None, :]
    tt = et[:, :, None] * et[:, None, :]
    d2X = ((dt * dt / r)[:, None, None, None] * et2[:, :, None, None] * sym[:, None, :, :]
           - (dt * dt * r2 / r**2)[:, None, None, None] * er2[:, :, None, None] * tt[:, None])
    return X, J, d2X, -1


def cylindrical_update(x, v, dt: float, center, axis, derivatives: bool = True,
                       backend: str = "numba") -> _Update:
    """Cylindrical end-of-increment positions of nodes of a ring rotating about ``(c, w)``.

    With ``y = x − c``, ``z = y·w``, ``r = |P_w y|``, ``e_r``, ``e_θ = w × e_r`` and the velocity
    components ``v_r, v_θ, v_z``: ``r' = r + dt·v_r``, ``Δθ = dt·v_θ/r``, ``z' = z + dt·v_z`` and
    ``X = c + z'w + r'(cos Δθ e_r + sin Δθ e_θ)`` (THEORY §5). Rigid rotation about the axis is
    reproduced exactly (the radius is preserved).

    Args:
        x: (N, 3) node positions at the start of the increment.
        v: (N, 3) nodal velocities.
        dt: time step (> 0).
        center: a point ``c`` of the ring axis.
        axis: ring axis direction ``w`` (normalised here).
        derivatives: whether to return ``J`` and ``d2X``.
        backend: ``"numba"`` (default) or ``"numpy"`` (reference twin, for testing only).

    Returns:
        ``(X, J, d2X)``: (N, 3) positions, (N, 3, 3) ``J[n, i, a] = ∂X_i/∂v_a`` and
        (N, 3, 3, 3) ``d2X[n, i, a, b] = ∂²X_i/∂v_a∂v_b``; ``(X, None, None)`` if
        ``derivatives`` is False.

    Raises:
        ValueError: bad shapes or values, ``dt ≤ 0``, zero axis, or a node on the ring axis
            (``r ≤ AXIS_TOL·|x − c|``, the message names the first such node).
    """
    x, v, dt = _check_common(x, v, dt)
    c = np.asarray(center, dtype=np.float64).reshape(-1)
    if c.shape != (3,) or not np.all(np.isfinite(c)):
        raise ValueError(f"center must be a finite 3-vector, got {center!r}")
    w = unit_vector(axis, "ring axis")
    want_d = bool(derivatives)
    if backend == "numba":
        n = x.shape[0]
        X = np.empty((n, 3))
        J = np.empty((n, 3, 3) if want_d else (0, 3, 3))
        d2X = np.empty((n, 3, 3, 3) if want_d else (0, 3, 3, 3))
        bad = _cylindrical_kernel(x, v, dt, c, w, AXIS_TOL, want_d, X, J, d2X)
    elif backend == "numpy":
        X, J, d2X, bad = _cylindrical_numpy(x, v, dt, c, w, AXIS_TOL, want_d)
    else:
        raise ValueError(f"backend must be 'numba' or 'numpy', got {backend!r}")
    if bad >= 0:
        raise ValueError(f"cylindrical_update: node {bad} at {x[bad].tolist()} lies on the ring "
                         f"axis (r = 0); the cylindrical update is undefined there")
    if not want_d:
        return X, None, None
    return X, J, d2X


def gap_derivatives(proj: Projection, J: np.ndarray, d2X: Optional[np.ndarray],
                    dt: float) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Fully implicit constraint ``h(v) = δ(X(v))/dt = −d(X(v))/dt`` and its derivatives.

    ``∇h = −Jᵀn/dt`` and ``∇²h = −(Jᵀ ∇²d J + Σᵢ nᵢ ∇²Xᵢ)/dt`` (THEORY §3.4), vectorised over
    the nodes.

    Args:
        proj: projection of the end-of-increment positions ``X(v)`` on the tool at ``t + dt``,
            with its Hessian.
        J: (N, 3, 3) ``∂X/∂v`` from :func:`cartesian_update` or :func:`cylindrical_update`.
        d2X: (N, 3, 3, 3) second derivatives, or ``None`` for a linear map (Cartesian).
        dt: time step (> 0).

    Returns:
        ``(h, grad_h, hess_h)`` of shapes (N,), (N, 3), (N, 3, 3).

    Raises:
        ValueError: missing Hessian, inconsistent shapes or ``dt ≤ 0``.
    """
    dt = float(dt)
    if not (np.isfinite(dt) and dt > 0.0):
        raise ValueError(f"dt must be a positive finite number, got {dt!r}")
    if proj.hessian is None:
        raise ValueError("gap_derivatives needs the gap Hessian: project with hessian=True")
    n = len(proj)
    J = np.asarray(J, dtype=np.float64)
    if J.shape != (n, 3, 3):
        raise ValueError(f"J must have shape ({n}, 3, 3), got {J.shape}")
    if d2X is not None:
        d2X = np.asarray(d2X, dtype=np.float64)
        if d2X.shape != (n, 3, 3, 3):
            raise ValueError(f"d2X must have shape ({n}, 3, 3, 3), got {d2X.shape}")
    nrm = proj.normal
    h = -proj.gap / dt
    grad = -np.einsum("nia,ni->na", J, nrm) / dt
    JT = J.transpose(0, 2, 1)
    hess = JT @ proj.hessian @ J
    if d2X is not None:
        hess += np.einsum("ni,niab->nab", nrm, d2X)
    hess *= -1.0 / dt
    return h, grad, hess


# ---- the updates as objects (Simulation(kinematics=...), NodalContact)

def pad3(x: np.ndarray) -> np.ndarray:
    """(N, d) points (d <= 3) as a C-contiguous float64 (N, 3) array, zero in the missing
    columns (the points of a 2D problem for the tools' 3D projections)."""
    if x.shape[1] == 3:
        return np.ascontiguousarray(x, dtype=np.float64)
    out = np.zeros((x.shape[0], 3))
    out[:, : x.shape[1]] = x
    return out


@dataclass(frozen=True)
class CartesianUpdate:
    """X = x + dt v (J = dt I, ∂²X = 0)."""

    def positions(self, x: np.ndarray, v: np.ndarray, dt: float) -> np.ndarray:
        return x + dt * v

    def derivatives(self, x: np.ndarray, v: np.ndarray, dt: float):
        """(X, J, d2X) with J (N,d,d) and d2X (N,d,d,d) (``None`` when identically zero)."""
        n, d = x.shape
        J = np.broadcast_to(dt * np.eye(d), (n, d, d))
        return x + dt * v, J, None


@dataclass(frozen=True)
class CylindricalUpdate:
    """Cylindrical update about the axis (center, axis) — ring rolling (THEORY §5). 3D only."""

    center: tuple
    axis: tuple = (0.0, 0.0, 1.0)
    _c: np.ndarray = field(init=False, repr=False, compare=False)
    _w: np.ndarray = field(init=False, repr=False, compare=False)

    def __post_init__(self):
        c = np.asarray(self.center, dtype=np.float64).reshape(-1)
        w = np.asarray(self.axis, dtype=np.float64).reshape(-1)
        if c.shape != (3,) or w.shape != (3,) or not np.all(np.isfinite(np.r_[c, w])):
            raise ValueError("center and axis must be finite 3-vectors")
        nw = np.linalg.norm(w)
        if nw == 0:
            raise ValueError("axis must be non-zero")
        object.__setattr__(self, "_c", c)
        object.__setattr__(self, "_w", w / nw)

    def derivatives(self, x: np.ndarray, v: np.ndarray, dt: float):
        if x.shape[1] != 3:
            raise ValueError("the cylindrical update needs 3D coordinates")
        return cylindrical_update(x, v, dt, self._c, self._w, derivatives=True)

    def positions(self, x: np.ndarray, v: np.ndarray, dt: float) -> np.ndarray:
        if x.shape[1] != 3:
            raise ValueError("the cylindrical update needs 3D coordinates")
        return cylindrical_update(x, v, dt, self._c, self._w, derivatives=False)[0]


class RingAxisUpdate:
    """Cylindrical configuration update (THEORY §5) about the axis through a centre that is
    re-set at the start of each increment (:meth:`set_center`), e.g. the ring's centroid. The
    contact condition and the mesh update use the same map within an increment."""

    def __init__(self, center=(0.0, 0.0, 0.0), axis=(0.0, 0.0, 1.0)):
        self.axis = unit_vector(axis, "ring axis")
        self.set_center(center)

    def set_center(self, center):
        c = np.asarray(center, dtype=np.float64).reshape(-1)
        if c.shape != (3,) or not np.all(np.isfinite(c)):
            raise ValueError(f"center must be a finite 3-vector, got {center!r}")
        self.center = c

    def derivatives(self, x, v, dt):
        return cylindrical_update(x, v, dt, self.center, self.axis, derivatives=True)

    def positions(self, x, v, dt):
        return cylindrical_update(x, v, dt, self.center, self.axis, derivatives=False)[0]

    def checkpoint_state(self) -> dict:
        return {"center": self.center.copy(), "axis": self.axis.copy()}

    def restore_state(self, state: dict):
        axis = unit_vector(state["axis"], "ring axis")
        if not np.allclose(axis, self.axis, rtol=0.0, atol=1e-12):
            raise ValueError(f"the checkpoint's ring axis {axis.tolist()} is not this update's "
                             f"{self.axis.tolist()}")
        self.set_center(state["center"])
