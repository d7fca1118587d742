"""Common interface of rigid tools: projection result, rigid motion, tool base class.

Conventions (THEORY §0.2): the gap ``d`` is the signed distance to the tool surface, positive in
free space and negative inside the tool; ``normal`` is the *outward tool normal* ``∇d`` at the
closest point; ``hessian`` is ``∇²d`` (symmetric, annihilates the normal).

A tool is described in its *reference frame* (its position at ``t = 0``). Its position at time
``t`` is given by a :class:`RigidMotion`: a translation ``c(t) = ∫₀ᵗ v`` and a rotation by the
angle ``θ(t) = ∫₀ᵗ ω`` about an axis through ``axis_point + c(t)``. Concrete tools only implement
:meth:`Tool._project_reference`; the base class maps points to the reference frame and the
results back.
"""

from __future__ import annotations

import abc
import math
from dataclasses import dataclass, field
from typing import Callable, Optional, Union

import numpy as np
from scipy.integrate import quad

__all__ = ["ControlledMotion", "MovedTool", "Projection", "RigidMotion", "StagedMotion", "Tool",
           "as_points"]

VectorOrCallable = Union[np.ndarray, tuple, list, Callable[[float], np.ndarray]]
ScalarOrCallable = Union[float, Callable[[float], float]]


def as_points(x) -> np.ndarray:
    """Return ``x`` as a C-contiguous float64 (N, 3) array, with a clear error otherwise."""
    a = np.ascontiguousarray(x, dtype=np.float64)
    if a.ndim == 1 and a.shape[0] == 3:
        a = a.reshape(1, 3)
    if a.ndim != 2 or a.shape[1] != 3:
        raise ValueError(f"points must have shape (N, 3), got {np.shape(x)}")
    if not np.all(np.isfinite(a)):
        bad = np.flatnonzero(~np.all(np.isfinite(a), axis=1))
        raise ValueError(f"points contain NaN/inf at rows {bad[:10].tolist()}")
    return a


@dataclass
class Projection:
    """Result of projecting N points on a tool.

    Attributes:
        gap: (N,) signed distance, positive in free space.
        normal: (N, 3) outward unit tool normal at the closest point (``∇gap``).
        point: (N, 3) closest point on the tool surface.
        hessian: (N, 3, 3) Hessian of the gap, or ``None`` where the tool does not provide it.
        feature: (N,) integer id of the surface feature the point projects on (facet, patch,
            analytic region), used to detect feature switching between Newton iterations.
        flag: (N,) integer status, 0 = normal; tools document other values (e.g. fall-back to
            the flat projection for Nagata patches = 1).
    """

    gap: np.ndarray
    normal: np.ndarray
    point: np.ndarray
    hessian: Optional[np.ndarray] = None
    feature: Optional[np.ndarray] = None
    flag: Optional[np.ndarray] = None

    def __len__(self) -> int:
        return self.gap.shape[0]

    def take(self, idx) -> "Projection":
        """Sub-selection of the points ``idx``."""

        def sel(a):
            return None if a is None else a[idx]

        return Projection(self.gap[idx], self.normal[idx], self.point[idx], sel(self.hessian),
                          sel(self.feature), sel(self.flag))


def _vector_function(value: VectorOrCallable, name: str) -> Callable[[float], np.ndarray]:
    if callable(value):
        def f(t, _v=value):
            out = np.asarray(_v(t), dtype=np.float64).reshape(-1)
            if out.shape != (3,) or not np.all(np.isfinite(out)):
                raise ValueError(f"{name}({t}) must return a finite 3-vector, got {out}")
            return out
        return f
    v = np.asarray(value, dtype=np.float64).reshape(-1)
    if v.shape != (3,) or not np.all(np.isfinite(v)):
        raise ValueError(f"{name} must be a finite 3-vector or a function of t, got {value!r}")
    return lambda t, _v=v: _v.copy()


def _scalar_function(value: ScalarOrCallable, name: str) -> Callable[[float], float]:
    if callable(value):
        def f(t, _v=value):
            out = float(_v(t))
            if not np.isfinite(out):
                raise ValueError(f"{name}({t}) is not finite")
            return out
        return f
    w = float(value)
    if not np.isfinite(w):
        raise ValueError(f"{name} must be finite, got {value!r}")
    return lambda t, _w=w: _w


def unit_vector(v, name: str) -> np.ndarray:
    """Normalised copy of a 3-vector; ValueError if it is zero or not finite."""
    a = np.asarray(v, dtype=np.float64).reshape(-1)
    if a.shape != (3,) or not np.all(np.isfinite(a)):
        raise ValueError(f"{name} must be a finite 3-vector, got {v!r}")
    n = np.linalg.norm(a)
    if n < 1e-300:
        raise ValueError(f"{name} must be non-zero, got {v!r}")
    return a / n


@dataclass(frozen=True)
class RigidMotion:
    """Rigid motion of a tool: translation plus rotation about one axis.

    Args:
        velocity: translation velocity, a constant 3-vector or a function ``v(t)``.
        angular_velocity: rotation speed ω [rad/s] about ``axis`` (right-hand rule), constant or
            a function ``ω(t)``.
        axis_point: a point of the rotation axis at ``t = 0`` (it translates with the tool).
        axis: direction of the rotation axis.

    Constant rates are integrated exactly; callables are integrated with ``scipy.integrate.quad``
    (the last 16 times are cached: a Newton solve projects many times at the same t); across a
    jump of the rate quad is accurate to about 1e-10 relative.
    """

    velocity: VectorOrCallable = (0.0, 0.0, 0.0)
    angular_velocity: ScalarOrCallable = 0.0
    axis_point: tuple = (0.0, 0.0, 0.0)
    axis: tuple = (0.0, 0.0, 1.0)
    _v: Callable = field(init=False, repr=False, compare=False)
    _w: Callable = field(init=False, repr=False, compare=False)
    _a0: np.ndarray = field(init=False, repr=False, compare=False)
    _ax: np.ndarray = field(init=False, repr=False, compare=False)
    _cache: dict = field(init=False, repr=False, compare=False)

    def __post_init__(self):
        object.__setattr__(self, "_v", _vector_function(self.velocity, "velocity"))
        object.__setattr__(self, "_w", _scalar_function(self.angular_velocity, "angular_velocity"))
        a0 = np.asarray(self.axis_point, dtype=np.float64).reshape(-1)
        if a0.shape != (3,) or not np.all(np.isfinite(a0)):
            raise ValueError(f"axis_point must be a finite 3-vector, got {self.axis_point!r}")
        object.__setattr__(self, "_a0", a0)
        object.__setattr__(self, "_ax", unit_vector(self.axis, "rotation axis"))
        object.__setattr__(self, "_cache", {})

    def _cached(self, key: str, t: float, fn):
        c = self._cache
        k = (key, float(t))
        if k not in c:
            if len(c) >= 16:
                c.pop(next(iter(c)))
            c[k] = fn()
        return c[k]

    @property
    def is_static(self) -> bool:
        return (not callable(self.velocity) and not np.any(self._v(0.0))
                and not callable(self.angular_velocity) and self._w(0.0) == 0.0)

    @property
    def rotates(self) -> bool:
        return callable(self.angular_velocity) or self._w(0.0) != 0.0

    def translation(self, t: float) -> np.ndarray:
        """Displacement c(t) = ∫₀ᵗ v(s) ds of the tool."""
        if not callable(self.velocity):
            return self._v(0.0) * t
        return self._cached("c", t, lambda: np.array(
            [quad(lambda s, k=k: self._v(s)[k], 0.0, t, limit=200)[0] for k in range(3)])).copy()

    def angle(self, t: float) -> float:
        """Rotation angle θ(t) = ∫₀ᵗ ω(s) ds."""
        if not callable(self.angular_velocity):
            return self._w(0.0) * t
        return self._cached("a", t, lambda: quad(self._w, 0.0, t, limit=200)[0])

    def rotation(self, t: float) -> np.ndarray:
        """Rotation matrix Q(t) (Rodrigues) about the axis."""
        th = self.angle(t)
        if th == 0.0:
            return np.eye(3)
        w = self._ax
        W = np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])
        return np.eye(3) + np.sin(th) * W + (1.0 - np.cos(th)) * (W @ W)

    def axis_point_at(self, t: float) -> np.ndarray:
        return self._a0 + self.translation(t)

    def to_reference(self, x: np.ndarray, t: float) -> np.ndarray:
        """Map current positions to the reference (t = 0) frame: Qᵀ(x − a(t)) + a₀."""
        a = self.axis_point_at(t)
        Q = self.rotation(t)
        return (x - a) @ Q + self._a0

    def from_reference(self, y: np.ndarray, t: float) -> np.ndarray:
        """Map reference positions to the current frame: Q(y − a₀) + a(t)."""
        return (y - self._a0) @ self.rotation(t).T + self.axis_point_at(t)

    def point_velocity(self, p: np.ndarray, t: float) -> np.ndarray:
        """Material velocity of the tool at current points p: v(t) + ω(t) w × (p − a(t))."""
        p = as_points(p)
        v = np.broadcast_to(self._v(t), p.shape).copy()
        w = self._w(t)
        if w != 0.0:
            v += w * np.cross(self._ax, p - self.axis_point_at(t))
        return v


@dataclass(frozen=True)
class StagedMotion(RigidMotion):
    """Rigid motion made of consecutive stages of constant velocity and rotation speed,
    integrated exactly (no quadrature): approach, then work stroke, then rest, ...

    Args:
        stages: sequence of ``(duration, velocity, angular_velocity)``: ``duration > 0`` [s],
            ``velocity`` a 3-vector, ``angular_velocity`` ω [rad/s] about ``axis``. The first
            stage starts at ``t = 0``; after the last one the tool is at rest.
        axis_point, axis: rotation axis at ``t = 0`` (it translates with the tool).

    The rates are right-continuous: at a stage boundary (to a relative 1e-12) the rates of the
    next stage apply, so an increment starting at a boundary sees the new stage's velocity
    (what the explicit schemes take). Example: press down by 0.1 in 2 s, then turn 90° in 10 s::

        StagedMotion(stages=((2.0, (0, 0, -0.05), 0.0), (10.0, (0, 0, 0), np.pi / 20)),
                     axis_point=(0, 0, 5), axis=(0, 1, 0))
    """

    stages: tuple = ()
    _t: np.ndarray = field(init=False, repr=False, compare=False)
    _sv: np.ndarray = field(init=False, repr=False, compare=False)
    _sw: np.ndarray = field(init=False, repr=False, compare=False)
    _c: np.ndarray = field(init=False, repr=False, compare=False)
    _th: np.ndarray = field(init=False, repr=False, compare=False)

    def __post_init__(self):
        if len(self.stages) == 0:
            raise ValueError("StagedMotion needs at least one (duration, velocity, "
                             "angular_velocity) stage")
        d, vs, ws = [], [], []
        for k, st in enumerate(self.stages):
            try:
                dur, v, w = st
                dur, w = float(dur), float(w)
                v = np.asarray(v, dtype=np.float64).reshape(-1)
            except (TypeError, ValueError):
                raise ValueError(f"stage {k} must be (duration, 3-vector velocity, angular "
                                 f"velocity), got {st!r}") from None
            if not (np.isfinite(dur) and dur > 0):
                raise ValueError(f"stage {k}: duration must be finite and > 0, got {dur!r}")
            if v.shape != (3,) or not np.all(np.isfinite(v)) or not np.isfinite(w):
                raise ValueError(f"stage {k}: velocity must be a finite 3-vector and the "
                                 f"angular velocity finite, got {st!r}")
            d.append(dur)
            vs.append(v)
            ws.append(w)
        # start times of the stages, plus a stage at rest after the last one
        d = np.array(d)
        t = np.concatenate([[0.0], np.cumsum(d)])
        sv = np.vstack(vs + [np.zeros(3)])
        sw = np.array(ws + [0.0])
        c = np.vstack([np.zeros(3), np.cumsum(sv[:-1] * d[:, None], axis=0)])
        th = np.concatenate([[0.0], np.cumsum(sw[:-1] * d)])
        for name, val in (("_t", t), ("_sv", sv), ("_sw", sw), ("_c", c), ("_th", th)):
            object.__setattr__(self, name, val)
        object.__setattr__(self, "velocity", lambda s: self._sv[self._stage(s, True)].copy())
        object.__setattr__(self, "angular_velocity",
                           lambda s: float(self._sw[self._stage(s, True)]))
        super().__post_init__()

    def _stage(self, t: float, rates: bool = False) -> int:
        """Index of the stage holding ``t``; for the rates (``rates=True``) a time within a
        relative 1e-12 of a stage start belongs to that stage (right-continuous rates)."""
        tol = 1e-12 * max(1.0, self._t[-1]) if rates else 0.0
        k = np.searchsorted(self._t, float(t) + tol, side="right") - 1
        return int(min(max(k, 0), len(self._t) - 1))

    @property
    def duration(self) -> float:
        """End time of the last stage."""
        return float(self._t[-1])

    @property
    def is_static(self) -> bool:
        return not (np.any(self._sv) or np.any(self._sw))

    @property
    def rotates(self) -> bool:
        return bool(np.any(self._sw))

    def translation(self, t: float) -> np.ndarray:
        k = self._stage(t)
        return self._c[k] + self._sv[k] * (float(t) - self._t[k])

    def angle(self, t: float) -> float:
        k = self._stage(t)
        return float(self._th[k] + self._sw[k] * (float(t) - self._t[k]))


@dataclass(frozen=True)
class ControlledMotion(RigidMotion):
    """Rigid motion with piecewise-constant rates set by a controller (integrated exactly).

    Args:
        velocity: initial translation velocity (3-vector).
        angular_velocity: initial rotation speed ω [rad/s] about ``axis``.
        axis_point, axis: rotation axis at ``t = 0`` (it translates with the tool).

    :meth:`set_rates` starts a new stage of constant rates at time t (the start of an
    increment); called again at the same t (another trial of the same increment, a cut-back)
    it overwrites that stage's rates. Rates are right-continuous: at a stage start the new
    rates apply (what the explicit schemes take at the start of the increment).
    """

    _st: dict = field(init=False, repr=False, compare=False)

    def __post_init__(self):
        v0 = np.asarray(self.velocity, dtype=np.float64).reshape(-1)
        if callable(self.velocity) or callable(self.angular_velocity):
            raise ValueError("ControlledMotion takes constant initial rates (a controller sets "
                             "them per increment)")
        w0 = float(self.angular_velocity)
        if v0.shape != (3,) or not np.all(np.isfinite(v0)) or not math.isfinite(w0):
            raise ValueError(f"velocity must be a finite 3-vector and angular_velocity finite, "
                             f"got {self.velocity!r}, {self.angular_velocity!r}")
        object.__setattr__(self, "_st", {"t": [0.0], "c": [np.zeros(3)], "th": [0.0],
                                         "v": [v0], "w": [w0]})
        object.__setattr__(self, "velocity", lambda s: self._st["v"][self._stage(s)].copy())
        object.__setattr__(self, "angular_velocity",
                           lambda s: float(self._st["w"][self._stage(s)]))
        super().__post_init__()

    def _stage(self, t: float) -> int:
        ts = self._st["t"]
        tol = 1e-12 * max(1.0, abs(ts[-1]))
        k = int(np.searchsorted(np.asarray(ts), float(t) + tol, side="right")) - 1
        return max(k, 0)

    def set_rates(self, t: float, velocity=None, angular_velocity: Optional[float] = None):
        """Rates from time ``t`` on (``None`` keeps the current one)."""
        st = self._st
        t = float(t)
        last = st["t"][-1]
        tol = 1e-12 * max(1.0, abs(last))
        if t < last - tol:
            raise ValueError(f"cannot set the rates at t = {t:.6g}, before the current stage "
                             f"(started at t = {last:.6g})")
        v = st["v"][-1] if velocity is None else np.asarray(velocity, dtype=np.float64)
        w = st["w"][-1] if angular_velocity is None else float(angular_velocity)
        if v.shape != (3,) or not np.all(np.isfinite(v)) or not math.isfinite(w):
            raise ValueError(f"rates must be a finite 3-vector and a finite ω, got {velocity!r}, "
                             f"{angular_velocity!r}")
        if t <= last + tol:
            st["v"][-1], st["w"][-1] = v.copy(), w
            return
        d = t - last
        st["c"].append(st["c"][-1] + st["v"][-1] * d)
        st["th"].append(st["th"][-1] + st["w"][-1] * d)
        st["t"].append(t)
        st["v"].append(v.copy())
        st["w"].append(w)

    @property
    def is_static(self) -> bool:
        return False

    @property
    def rotates(self) -> bool:
        return True

    def translation(self, t: float) -> np.ndarray:
        k = self._stage(t)
        st = self._st
        return st["c"][k] + st["v"][k] * (float(t) - st["t"][k])

    def angle(self, t: float) -> float:
        k = self._stage(t)
        st = self._st
        return float(st["th"][k] + st["w"][k] * (float(t) - st["t"][k]))

    def current_angular_velocity(self) -> float:
        return float(self._st["w"][-1])

    def checkpoint_state(self) -> dict:
        """The stages of rates set so far (plain numbers and lists): what a resumed run needs
        to place the tool where the checkpointed run had it (:mod:`fxcontact.checkpoint`)."""
        st = self._st
        return {"t": [float(x) for x in st["t"]], "th": [float(x) for x in st["th"]],
                "w": [float(x) for x in st["w"]],
                "c": np.asarray(st["c"], dtype=np.float64).tolist(),
                "v": np.asarray(st["v"], dtype=np.float64).tolist()}

    def restore_state(self, state: dict):
        """Restore the stages of :meth:`checkpoint_state` (ValueError if malformed)."""
        try:
            t = np.asarray(state["t"], dtype=np.float64).reshape(-1)
            th = np.asarray(state["th"], dtype=np.float64).reshape(-1)
            w = np.asarray(state["w"], dtype=np.float64).reshape(-1)
            c = np.asarray(state["c"], dtype=np.float64).reshape(-1, 3)
            v = np.asarray(state["v"], dtype=np.float64).reshape(-1, 3)
        except (KeyError, TypeError, ValueError) as e:
            raise ValueError(f"not a ControlledMotion state ({e}): {state!r:.200}") from None
        n = len(t)
        if n == 0 or not (len(th) == len(w) == len(c) == len(v) == n) or \
                np.any(np.diff(t) <= 0) or not all(np.all(np.isfinite(a))
                                                   for a in (t, th, w, c, v)):
            raise ValueError(f"not a ControlledMotion state: {n} stage times, {len(th)} angles, "
                             f"{len(w)} rotation speeds, {len(c)} positions, {len(v)} "
                             f"velocities (the same number > 0, finite, increasing times)")
        st = self._st
        st["t"], st["th"], st["w"] = [float(x) for x in t], [float(x) for x in th], \
            [float(x) for x in w]
        st["c"], st["v"] = [x.copy() for x in c], [x.copy() for x in v]


class Tool(abc.ABC):
    """A rigid tool. Subclasses implement :meth:`_project_reference` in the reference frame.

    Attributes:
        motion: the tool's :class:`RigidMotion`.
        name: a label used in histories and outputs.
    """

    motion: RigidMotion
    name: str = "tool"
    #: True if the tool provides the gap Hessian (needed by the ``implicit-exact`` scheme).
    has_hessian: bool = True

    @abc.abstractmethod
    def _project_reference(self, y: np.ndarray, hessian: bool) -> Projection:
        """Project (N, 3) points given in the reference frame; results in the reference frame.

        ``hessian=False`` allows the tool to skip the Hessian (return ``None``)."""

    def project(self, x, t: float = 0.0, hessian: bool = True) -> Projection:
        """Project (N, 3) points on the tool at its position at time ``t``.

        Args:
            x: (N, 3) points in the current frame.
            t: time at which the tool position is taken.
            hessian: whether the gap Hessian is needed (tools may skip computing it).

        Returns:
            A :class:`Projection` in the current frame.
        """
        x = as_points(x)
        if self.motion.is_static:
            pr = self._project_reference(x, hessian)
            if not hessian:
                pr.hessian = None
            return pr
        y = self.motion.to_reference(x, t)
        pr = self._project_reference(y, hessian)
        Q = self.motion.rotation(t)
        pr.normal = pr.normal @ Q.T
        pr.point = self.motion.from_reference(pr.point, t)
        if hessian and pr.hessian is not None:
            pr.hessian = np.einsum("ij,njk,lk->nil", Q, pr.hessian, Q, optimize=True)
        else:
            pr.hessian = None
        return pr

    def velocity(self, p, t: float = 0.0) -> np.ndarray:
        """Material velocity of the tool at current points ``p`` (N, 3)."""
        return self.motion.point_velocity(p, t)


class MovedTool(Tool):
    """A tool given at its position at ``t = 0`` (static), moved by any :class:`RigidMotion`
    (e.g. a :class:`StagedMotion`): analytic or faceted alike.

    Args:
        tool: a static tool (its own motion must be at rest).
        motion: the rigid motion applied to it.
        name: label (default: the tool's).
    """

    def __init__(self, tool: Tool, motion: RigidMotion, name: Optional[str] = None):
        if not isinstance(tool, Tool):
            raise ValueError(f"tool must be a Tool, got {type(tool).__name__}")
        if not isinstance(motion, RigidMotion):
            raise ValueError(f"motion must be a RigidMotion, got {type(motion).__name__}")
        if not tool.motion.is_static:
            raise ValueError(f"MovedTool needs a static tool; '{tool.name}' already moves")
        self.tool = tool
        self.motion = motion
        self.name = tool.name if name is None else str(name)
        self.has_hessian = tool.has_hessian

    def _project_reference(self, y: np.ndarray, hessian: bool) -> Projection:
        return self.tool._project_reference(y, hessian)

    def __repr__(self) -> str:
        return f"MovedTool({self.tool!r}, {self.motion!r})"
