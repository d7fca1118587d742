"""Nodal penalty kernel (THEORY §2.2), numba-compiled, with its numpy reference twin.

For each contact node, with the velocity-scaled constraint ``h`` (admissible iff h ≤ 0), its
gradient ``g = ∇h`` and Hessian ``Hh = ∇²h`` with respect to the nodal velocity::

    p = ρ [h]₊,   r = S ρ [h]₊ g,   K = S ρ (A g ⊗ g + [h]₊ Hh)

where ``A`` is the active flag used in the tangent: ``H(h)``, or 1 for a node kept active by the
active-set stabilisation of THEORY §3.6 (the residual is unchanged by it).
"""

from __future__ import annotations

import numba
import numpy as np

__all__ = ["penalty_kernel", "penalty_kernel_numpy"]


@numba.njit(cache=True)
def penalty_kernel(S, rho, h, g, Hh, active, jacobian):
    """Residual (N, d) and Jacobian blocks (N, d, d) of the nodal penalty.

    Args:
        S: (N,) nodal areas.
        rho: penalty coefficient.
        h: (N,) constraint values.
        g: (N, d) ∇h.
        Hh: (N, d, d) ∇²h, or an array of shape (0, d, d) when identically zero.
        active: (N,) bool, tangent activity (``h > 0`` or kept active).
        jacobian: whether to compute the blocks.
    """
    n, d = g.shape
    r = np.zeros((n, d))
    K = np.zeros((n if jacobian else 0, d, d))
    has_h = Hh.shape[0] == n
    for i in range(n):
        hp = h[i] if h[i] > 0.0 else 0.0
        c = S[i] * rho * hp
        for a in range(d):
            r[i, a] = c * g[i, a]
        if jacobian:
            ca = S[i] * rho if active[i] else 0.0
            for a in range(d):
                for b in range(d):
                    K[i, a, b] = ca * g[i, a] * g[i, b]
                    if has_h:
                        K[i, a, b] += c * Hh[i, a, b]
    return r, K


def penalty_kernel_numpy(S, rho, h, g, Hh, active, jacobian):
    """Reference implementation of :func:`penalty_kernel`, for testing only."""
    hp = np.maximum(h, 0.0)
    c = S * rho * hp
    r = c[:, None] * g
    if not jacobian:
        return r, np.zeros((0, g.shape[1], g.shape[1]))
    K = (S * rho * active)[:, None, None] * g[:, :, None] * g[:, None, :]
    if Hh.shape[0] == g.shape[0]:
        K = K + c[:, None, None] * Hh
    return r, K
