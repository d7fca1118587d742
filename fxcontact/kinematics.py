"""Configuration updates X(v) of the nodes over one increment, and the mesh motion.

``CartesianUpdate`` is X = x + dt v. ``CylindricalUpdate`` is the ring-rolling update of THEORY §5
(radius preserved for a rigid rotation about the ring axis). The contact condition and the mesh
motion use the **same** map (THEORY §5, last property).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["CartesianUpdate", "CylindricalUpdate"]


def _pad3(x: np.ndarray) -> np.ndarray:
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
        from fxcontact.cylindrical import cylindrical_update
        if x.shape[1] != 3:
            raise ValueError("the cylindrical update needs 3D coordinates")
        return cylindrical_update(x, v, dt, self._c, self._w, derivatives=True)

    def positions(self, x: np.ndarray, v: np.ndarray, dt: float) -> np.ndarray:
        from fxcontact.cylindrical import cylindrical_update
        if x.shape[1] != 3:
            raise ValueError("the cylindrical update needs 3D coordinates")
        return cylindrical_update(x, v, dt, self._c, self._w, derivatives=False)[0]
