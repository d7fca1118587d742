"""Nodal springs on boundary vertices: the simplest nodal contributor.

Each contact vertex n gets the nodal force ``-r_n`` with

    r_n = S_n [k (v_n − v₀) + c |v_n − v₀|² (v_n − v₀)],
    K_n = S_n [k I + c (|d|² I + 2 d ⊗ d)],  d = v_n − v₀,

i.e. the gradient and Hessian of ``Σ S_n (k/2 |d|² + c/4 |d|⁴)``. It is used to validate the
nodal hook of the Newton solver (it equals a boundary integral with a vertex quadrature rule) and
can serve as a viscous support (a Winkler-type foundation in velocity).
"""

from __future__ import annotations

import numba
import numpy as np

from fxcontact.contact.boundary import ContactBoundary
from fxcontact.io.keys import CheckpointError
from fxcontact.newton.problem import NodalTerms

__all__ = ["NodalSprings", "spring_kernel", "spring_kernel_numpy"]


@numba.njit(cache=True)
def spring_kernel(S, v, v0, k, c, jacobian):
    n, d = v.shape
    r = np.empty((n, d))
    K = np.zeros((n, d, d)) if jacobian else np.zeros((0, d, d))
    for i in range(n):
        dd = v[i] - v0
        s2 = 0.0
        for a in range(d):
            s2 += dd[a] * dd[a]
        for a in range(d):
            r[i, a] = S[i] * (k + c * s2) * dd[a]
        if jacobian:
            for a in range(d):
                for b in range(d):
                    K[i, a, b] = S[i] * 2.0 * c * dd[a] * dd[b]
                K[i, a, a] += S[i] * (k + c * s2)
    return r, K


def spring_kernel_numpy(S, v, v0, k, c, jacobian):
    """Reference implementation of :func:`spring_kernel`, for testing only."""
    d = v - v0
    s2 = np.sum(d * d, axis=1)
    r = S[:, None] * (k + c * s2)[:, None] * d
    if not jacobian:
        return r, np.zeros((0, v.shape[1], v.shape[1]))
    eye = np.eye(v.shape[1])
    K = S[:, None, None] * ((k + c * s2)[:, None, None] * eye + 2.0 * c * d[:, :, None]
                            * d[:, None, :])
    return r, K


class NodalSprings:
    """Nodal (velocity) springs on a :class:`ContactBoundary`.

    Args:
        boundary: the vertices that carry springs.
        stiffness: k ≥ 0 [stress / velocity].
        reference_velocity: v₀ (gdim,).
        cubic: c ≥ 0, coefficient of the cubic term.
    """

    def __init__(self, boundary: ContactBoundary, stiffness: float, reference_velocity=None,
                 cubic: float = 0.0):
        if not (np.isfinite(stiffness) and stiffness >= 0):
            raise ValueError(f"stiffness must be finite and >= 0, got {stiffness!r}")
        if not (np.isfinite(cubic) and cubic >= 0):
            raise ValueError(f"cubic must be finite and >= 0, got {cubic!r}")
        self.boundary = boundary
        self.k = float(stiffness)
        self.c = float(cubic)
        gdim = boundary.gdim
        v0 = np.zeros(gdim) if reference_velocity is None else np.asarray(
            reference_velocity, dtype=np.float64)
        if v0.shape != (gdim,):
            raise ValueError(f"reference_velocity must have shape ({gdim},)")
        self.v0 = v0
        self.kernel = spring_kernel

    def evaluate(self, w, jacobian: bool) -> NodalTerms:
        b = self.boundary
        v = np.ascontiguousarray(b.velocities(w))
        r, K = self.kernel(b.areas, v, self.v0, self.k, self.c, jacobian)
        return NodalTerms(b.dofs, r, K if jacobian else None)

    def stable(self) -> bool:
        return True

    def remesh(self, space, facet_tags):
        """Rebind to a new mesh of the body: the same selection of its boundary
        (:meth:`ContactBoundary.remeshed`; collective)."""
        self.boundary = self.boundary.remeshed(space, facet_tags)

    def checkpoint_state(self) -> dict:
        """Springs keep no state between increments: their parameters are saved so that a
        resumed run with other springs is refused."""
        return {"stiffness": self.k, "cubic": self.c, "reference_velocity": self.v0}

    def restore_state(self, state: dict):
        if not (state["stiffness"] == self.k and state["cubic"] == self.c
                and np.array_equal(state["reference_velocity"], self.v0)):
            raise CheckpointError(f"the checkpoint's springs (k = {state['stiffness']}, c = "
                                  f"{state['cubic']}, v0 = {state['reference_velocity']}) are not "
                                  f"these (k = {self.k}, c = {self.c}, v0 = {self.v0})")
