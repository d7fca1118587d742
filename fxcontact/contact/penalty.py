"""The penalty of nodal contact (THEORY §2.2, §2.5): :class:`Penalty`, and the nodal penalty
kernel, numba-compiled, with its numpy reference twin.

For each contact node, with the velocity-scaled constraint ``h`` (admissible iff h ≤ 0), its
gradient ``g = ∇h`` and Hessian ``Hh = ∇²h`` with respect to the nodal velocity::

    p = ρ [h]₊,   r = S ρ [h]₊ g,   K = S ρ (A g ⊗ g + [h]₊ Hh)

where ``A`` is the active flag used in the tangent: ``H(h)``, or 1 for a node kept active by the
active-set stabilisation of THEORY §3.6 (the residual is unchanged by it).

The penalty is one concept given one of four ways (:class:`Penalty`): ρ itself
[stress/velocity], the dimensionless β of THEORY §2.5, a gap stiffness k [stress/length]
(ρ = k·dt), or a gap stiffness from β (k = ρ(β)/dt_ref, ``gap=True``); :meth:`Penalty.rho`
resolves it for an increment, in one place.
"""

from __future__ import annotations

import logging
import math
from typing import Callable, Optional

import numba
import numpy as np

from fxcontact.materials import LinearElastic, NortonHoff

__all__ = ["Penalty", "penalty_from_beta", "DEFAULT_BETA", "penalty_kernel",
           "penalty_kernel_numpy"]

log = logging.getLogger(__name__)

#: β used when neither ``penalty``, ``beta`` nor ``gap_stiffness`` is given (THEORY §2.5
#: recommends 1e2–1e4).
DEFAULT_BETA = 1e3


def penalty_from_beta(material, beta: float, element_size: float, strain_rate: float = None,
                      dt: float = None) -> float:
    """Penalty ρ from the dimensionless β of THEORY §2.5.

    Norton–Hoff: ρ = β η / h_e with η = K (√3 ε̄̇)^(m-1) at a representative ``strain_rate``.
    Linear elastic: ρ = β dt E* / h_e (β_el of §2.5), E* = E/(1-ν²).
    """
    if not (beta > 0 and element_size > 0):
        raise ValueError("beta and element_size must be > 0")
    if isinstance(material, NortonHoff):
        if strain_rate is None or not strain_rate > 0:
            raise ValueError("a representative strain_rate > 0 is needed for a Norton-Hoff "
                             "penalty from beta")
        return beta * material.viscosity(strain_rate) / element_size
    if isinstance(material, LinearElastic):
        if dt is None or not dt > 0:
            raise ValueError("dt > 0 is needed for an elastic penalty from beta")
        return beta * dt * material.plane_strain_modulus / element_size
    raise ValueError(f"no beta rule for material {material!r}")


class Penalty:
    """The penalty of a :class:`~fxcontact.contact.NodalContact`, given one of four ways.

    Args:
        penalty: ρ [stress/velocity] (velocity form), or the gap stiffness k [stress/length]
            (displacement form).
        beta: dimensionless β (THEORY §2.5): ρ = β η(ε̄̇)/h_e for Norton–Hoff (at
            ``strain_rate``, estimated at the first increment if not given), ρ = β dt E*/h_e for
            linear elasticity, k = β E*/h_e in displacement form (``modulus`` = E*). The
            default when nothing is given: :data:`DEFAULT_BETA`.
        gap_stiffness: k [stress/length] on the end-of-increment gap: ρ = k·dt.
        strain_rate: representative strain rate [1/time] of a Norton–Hoff β.
        element_size: h_e [length] of β (default: the contact's, from its nodal areas or its
            ``element_size``).
        gap: β as a gap stiffness (velocity form): k = ρ(β)/dt_ref [stress/length], ρ(β) the
            penalty of β above at the reference time step dt_ref, resolved once; then
            ρ = k·dt at each increment (the penalty penetration does not depend on dt).
        reference_dt: dt_ref [time] of ``gap`` (implies it); default: the first increment's.

    Raises ValueError (``penalty``, ``beta``, ``gap_stiffness``, ``element_size`` or
    ``reference_dt`` not finite and > 0; a gap stiffness with another of them; ``gap`` with
    ``penalty`` or ``gap_stiffness``). :meth:`bind` then fixes the formulation and the element
    size (a displacement-form β without ``modulus`` is refused there). Two penalties given
    alike are equal (:meth:`__eq__`, on the values as given).
    """

    def __init__(self, penalty: Optional[float] = None, beta: Optional[float] = None,
                 gap_stiffness: Optional[float] = None, strain_rate: Optional[float] = None,
                 *, element_size: Optional[float] = None, gap: bool = False,
                 reference_dt: Optional[float] = None):
        gap = bool(gap) or reference_dt is not None
        if gap and (penalty is not None or gap_stiffness is not None):
            raise ValueError("a gap stiffness from beta (gap=True, reference_dt) takes beta, "
                             "not penalty or gap_stiffness")
        if gap_stiffness is not None:
            if penalty is not None or beta is not None:
                raise ValueError("give only one of penalty, beta and gap_stiffness")
            if not (math.isfinite(gap_stiffness) and gap_stiffness > 0):
                raise ValueError(f"gap_stiffness must be finite and > 0, got {gap_stiffness!r}")
        elif penalty is None and beta is None:
            beta = DEFAULT_BETA
        elif penalty is not None and beta is not None:
            raise ValueError(f"give only one of penalty (rho = {penalty!r}, the value used) and "
                             f"beta (= {beta!r}, rho scaled by the material): both were given")
        if penalty is not None and not (math.isfinite(penalty) and penalty > 0):
            raise ValueError(f"penalty must be finite and > 0, got {penalty!r}")
        if beta is not None and not (math.isfinite(beta) and beta > 0):
            raise ValueError(f"beta must be finite and > 0, got {beta!r}")
        for key, value in (("element_size", element_size), ("reference_dt", reference_dt)):
            if value is not None and not (math.isfinite(value) and value > 0):
                raise ValueError(f"{key} must be finite and > 0, got {value!r}")
        #: the values as given (``beta``: :data:`DEFAULT_BETA` when nothing was given)
        self.given, self.beta, self.gap_stiffness = penalty, beta, gap_stiffness
        #: β as a gap stiffness k = ρ(β)/dt_ref
        self.gap = gap
        self._as_given = dict(penalty=penalty, beta=beta, gap_stiffness=gap_stiffness,
                              strain_rate=strain_rate, element_size=element_size, gap=gap,
                              reference_dt=reference_dt)
        #: representative strain rate of a Norton–Hoff β (given, or estimated at the first
        #: increment)
        self.strain_rate = strain_rate
        #: dt_ref of ``gap`` (given, or the first increment's)
        self.reference_dt = reference_dt
        #: ρ when fixed: given, or resolved from a Norton–Hoff β at the first increment
        self.fixed_rho = penalty
        #: the gap stiffness k of ρ = k·dt (``gap_stiffness``; ``gap`` once resolved; in
        #: displacement form always)
        self.stiffness = None if gap_stiffness is None else gap_stiffness
        self.formulation, self.element_size = "velocity", element_size

    @classmethod
    def of(cls, penalty=None, beta: Optional[float] = None,
           gap_stiffness: Optional[float] = None, strain_rate: Optional[float] = None):
        """The penalty of a contact's arguments: ``penalty`` a :class:`Penalty` (a fresh copy:
        a contact resolves its own; then none of the others may be given) or a number ρ
        (:class:`Penalty` of the four)."""
        if not isinstance(penalty, Penalty):
            return cls(penalty, beta, gap_stiffness, strain_rate)
        extra = [k for k, v in (("beta", beta), ("gap_stiffness", gap_stiffness),
                                ("strain_rate", strain_rate)) if v is not None]
        if extra:
            raise ValueError(f"penalty is a Penalty: give {extra} to the Penalty, not beside it")
        return penalty.completed(strain_rate=penalty.strain_rate)

    def completed(self, strain_rate: Optional[float] = None,
                  element_size: Optional[float] = None,
                  reference_dt: Optional[float] = None) -> "Penalty":
        """A fresh copy (unresolved) with the values it leaves open set: the representative
        ``strain_rate`` and the ``element_size`` of a β, the ``reference_dt`` of a gap
        stiffness from β (each only where the penalty has none; a process gives its own, e.g.
        the die's mean strain rate)."""
        kw = dict(self._as_given)
        if self.given is None and self.gap_stiffness is None:       # a β
            for key, value in (("strain_rate", strain_rate), ("element_size", element_size),
                               ("reference_dt", reference_dt if self.gap else None)):
                if kw[key] is None and value is not None:
                    kw[key] = float(value)
        return Penalty(**kw)

    def as_given(self) -> dict:
        """The arguments as given (``beta``: :data:`DEFAULT_BETA` when nothing was given): the
        same penalty is ``Penalty(**p.as_given())``."""
        return dict(self._as_given)

    def __eq__(self, other):
        if not isinstance(other, Penalty):
            return NotImplemented
        return self._as_given == other._as_given

    def __hash__(self):
        return hash(tuple(self._as_given.items()))

    def __repr__(self):
        args = ", ".join(f"{k}={v!r}" for k, v in self._as_given.items()
                         if v is not None and v is not False)
        return f"Penalty({args})"

    def bind(self, formulation: str, element_size: float, modulus: Optional[float] = None):
        """Fix the formulation and the element size h_e (known once the contact nodes are; a
        given ``element_size`` is kept): in displacement form the penalty is a gap stiffness
        k, ``penalty``, ``gap_stiffness`` or β E*/h_e (``modulus`` = E*)."""
        given_size = self._as_given["element_size"]
        self.formulation = formulation
        self.element_size = float(element_size if given_size is None else given_size)
        if formulation == "displacement":
            if self.gap:
                raise ValueError("a gap stiffness from beta (gap=True) is for the velocity "
                                 "formulation: in displacement form beta= gives the gap "
                                 "stiffness k = beta E*/h_e itself")
            if self.gap_stiffness is not None or self.given is not None:
                self.stiffness = float(self.gap_stiffness if self.gap_stiffness is not None
                                       else self.given)
            else:
                if modulus is None or not (math.isfinite(modulus) and modulus > 0):
                    raise ValueError("the displacement formulation needs the gap stiffness: give "
                                     "penalty= (k, stress/length) or beta= with modulus= (E*, "
                                     f"k = beta E*/h_e); got modulus={modulus!r}")
                self.stiffness = self.beta * float(modulus) / self.element_size
            self.fixed_rho = None

    def rho(self, material, dt: float, representative_rate: Callable[[], float],
            name: str = "contact") -> float:
        """ρ of an increment of ``dt`` for the body's ``material`` (the one place where the
        penalty is resolved). ``representative_rate()`` estimates the strain rate of a
        Norton–Hoff β when it is not given (called once, at the first increment)."""
        if self.stiffness is not None:
            return self.stiffness * dt
        if self.fixed_rho is not None:
            return self.fixed_rho
        if isinstance(material, NortonHoff) and self.strain_rate is None:
            self.strain_rate = representative_rate()
            log.info("%s: representative strain rate %.4g 1/s", name, self.strain_rate)
        if self.gap:
            # k = ρ(β)/dt_ref, once; then ρ = k·dt
            if self.reference_dt is None:
                self.reference_dt = float(dt)
            rho_ref = penalty_from_beta(material, self.beta, self.element_size,
                                        self.strain_rate, self.reference_dt)
            self.stiffness = rho_ref / self.reference_dt
            log.info("%s: gap stiffness k = %.4g (beta = %g, rho(beta) = %.4g over dt_ref = "
                     "%.4g)", name, self.stiffness, self.beta, rho_ref, self.reference_dt)
            return self.stiffness * dt
        if isinstance(material, NortonHoff):
            self.fixed_rho = penalty_from_beta(material, self.beta, self.element_size,
                                               self.strain_rate)
            log.info("%s: penalty rho = %.4g (beta = %g)", name, self.fixed_rho, self.beta)
            return self.fixed_rho
        return penalty_from_beta(material, self.beta, self.element_size, None, dt)

    def signature(self) -> dict:
        """The penalty as given, for a checkpoint's set-up signature."""
        out = {"penalty": self.given, "beta": self.beta, "gap_stiffness": self.gap_stiffness}
        if self.gap:
            out.update(gap=True, reference_dt=self._as_given["reference_dt"])
        if self._as_given["element_size"] is not None:
            out["element_size"] = self._as_given["element_size"]
        return out

    def state(self) -> dict:
        """What a resumed run needs: ρ resolved from β and the representative strain rate (and
        the reference dt of a gap stiffness from β)."""
        out = {"penalty": self.fixed_rho, "strain_rate": self.strain_rate}
        if self.gap:
            out["reference_dt"] = self.reference_dt
        return out

    def restore(self, state: dict):
        if self.fixed_rho is None and self.gap_stiffness is None:   # resolved from β
            self.fixed_rho = state["penalty"]
        if self.strain_rate is None:
            self.strain_rate = state["strain_rate"]
        if self.gap and self.reference_dt is None:
            self.reference_dt = state.get("reference_dt")

    def summary(self) -> str:
        """How the penalty was given and what it resolved to."""
        if self.formulation == "displacement":
            how = ("given" if self.gap_stiffness is not None or self.given is not None
                   else f"beta = {self.beta:g} x E*/h_e")
            return f"gap stiffness k = {self.stiffness:.4g} ({how}; rho = k dt)"
        if self.gap:
            if self.stiffness is None:
                return (f"gap stiffness from beta = {self.beta:g} (k = rho(beta)/dt_ref, "
                        f"rho = k dt)")
            rate = ("" if self.strain_rate is None
                    else f" at the strain rate {self.strain_rate:.4g} 1/s")
            return (f"gap stiffness k = {self.stiffness:.4g} (beta = {self.beta:g}{rate}, "
                    f"h_e = {self.element_size:.4g}, over dt_ref = {self.reference_dt:.4g}; "
                    f"rho = k dt)")
        if self.gap_stiffness is not None:
            return f"gap stiffness k = {self.gap_stiffness:.4g} (rho = k dt)"
        if self.given is not None:
            return f"penalty rho = {self.given:.4g} (given)"
        if self.fixed_rho is not None:
            return (f"penalty rho = {self.fixed_rho:.4g} (beta = {self.beta:g} at the "
                    f"representative strain rate {self.strain_rate:.4g} 1/s)")
        return f"penalty from beta = {self.beta:g} (rho = beta dt E*/h_e at each increment)"


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
