"""Friction at contact nodes (THEORY §9): laws, and the nodal kernel with its numpy twin.

Slip velocity and regularised slip speed of a contact node, with ``n`` the tool normal at the
node's projection (frozen within a Newton iteration) and ``P_t = I − n ⊗ n``::

    Δv_t = P_t (v_n − v_tool(P)),     s = √(|Δv_t|² + v₀²)

``v_tool(P)`` is the tool's material velocity at the projection point (translation plus rotation
about its own axis). Laws (``τ`` = tangential stress on the workpiece, ``k`` = shear flow stress
σ₀/√3 at the node, ``K`` = Norton–Hoff consistency)::

    Coulomb(μ, m̄)   τ = −min(μ p_n, m̄ k) Δv_t / s      (Coulomb limited by Tresca)
    Tresca(m̄)       τ = −m̄ k Δv_t / s
    Norton(α_f, q)  τ = −α_f K s^(q−1) Δv_t            (viscoplastic friction)

Below the slip speed ``v₀`` every law becomes viscous, which approximates sticking. Nodal
residual ``r = −S τ`` (the gradient of the nodal friction potential for a fixed threshold) and
its 3×3 Jacobian block (THEORY §9)::

    Norton:             K = S α_f K s^(q−1) [P_t + (q−1) Δv_t⊗Δv_t / s²]
    threshold τ_lim:    K = S τ_lim (P_t − Δv_t⊗Δv_t / s²) / s
    implicit Coulomb:   K += S (Δv_t / s) ⊗ μ ∂p_n/∂v     (on the Coulomb branch only)

With ``theta = 0`` the slip-direction terms (``(q−1)/s²``, ``−1/s²``) are dropped: the secant
tangent, used by :class:`~fxcontact.contact.nodal.NodalContact` until the stick/slip state of
the nodes settles within a Newton solve (the consistent tangent of a node slipping at
|Δv_t| ≫ v₀ vanishes along the slip, and Newton steps from a slipping guess towards a sticking
solution overshoot by orders of magnitude). The last term is non-symmetric: it appears with *implicit* friction (``p_n = ρ[h]₊`` of the
current iterate) when the Coulomb branch is active. With *explicit* friction ``p_n`` and the
contact status come from the previous converged increment, the threshold is fixed and the
Jacobian symmetric. The dependence of ``n`` and ``v_tool(P)`` on the iterate through the
projection is neglected (frozen per iteration), as is that of ``k`` (evaluated once per
increment from the predictor's strain rate).

**Which shear flow stress k** a Tresca limit uses is said by the law (``shear_limit=``, the
law's :attr:`FrictionLaw.k_source`, a :class:`ShearLimit`) and printed in the run's summary:
the local nodal strain rate (the default), the material at a given strain rate, or a given k.

Parameter ranges (checked, ``ValueError`` otherwise): ``μ ≥ 0`` (``μ`` up to 1 and beyond is
allowed: industrial hot rolling uses μ = 1), ``0 ≤ m̄ ≤ 1`` (m̄ = 1 is full sticking friction
``τ = k``), ``α_f ≥ 0``, ``0 < q ≤ 1``, shear limits and ``K`` finite and > 0.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import List, Optional, Union

import numba
import numpy as np

from fxcontact.tools.base import Tool

__all__ = ["FrictionLaw", "Frictionless", "Coulomb", "Tresca", "Norton", "ShearLimit",
           "shear_flow_stress", "laws_per_tool", "friction_kernel", "friction_kernel_numpy",
           "LAW_NONE", "LAW_COULOMB", "LAW_TRESCA", "LAW_NORTON"]

LAW_NONE, LAW_COULOMB, LAW_TRESCA, LAW_NORTON = 0, 1, 2, 3


def _finite(name: str, value, lo: float = -math.inf, hi: float = math.inf,
            lo_open: bool = False) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a number, got {value!r}") from None
    ok = math.isfinite(v) and (v > lo if lo_open else v >= lo) and v <= hi
    if not ok:
        lo_s = "(" if lo_open else "["
        raise ValueError(f"{name} must be finite and in {lo_s}{lo:g}, {hi:g}], got {value!r}")
    return v


def _optional_positive(name: str, value) -> Optional[float]:
    if value is None:
        return None
    return _finite(name, value, 0.0, lo_open=True)


def shear_flow_stress(material, strain_rate):
    """Shear flow stress k = K z^m of a Norton–Hoff ``material`` at an equivalent strain rate
    (a number or an array), z = √(3 ε̄̇² + 3 ε̇₀²) regularised like the material."""
    z = np.sqrt(3.0 * strain_rate**2 + 3.0 * material.regularization**2)
    return material.K * z**material.m


@dataclass(frozen=True)
class ShearLimit:
    """Which shear flow stress k the Tresca limit m̄ k of a law uses (its ``shear_limit=``).

    * :meth:`local_rate` (the default, ``shear_limit=None``): k of the Norton–Hoff material at
      each node, k = K (√3 ε̄̇)^m with the node's strain rate of the increment's predictor (a
      lumped average over its cells). Near a static tool (an extrusion container) the local
      rate, hence k, is well below those at the process's mean rate.
    * :meth:`at_strain_rate`: k of the material at one given equivalent strain rate (e.g. a
      die's mean rate, :func:`fxcontact.theory.forming.drawing_mean_strain_rate`), at every node.
    * :meth:`given` (or a number, ``shear_limit=k``): k [stress] itself; the only choice for a
      body that is not Norton–Hoff.
    """

    value: Optional[float] = None
    strain_rate: Optional[float] = None

    def __post_init__(self):
        if self.value is not None and self.strain_rate is not None:
            raise ValueError("ShearLimit: give the shear limit k (value=) or the strain rate at "
                             "which the material gives it (strain_rate=), not both")
        object.__setattr__(self, "value", _optional_positive("shear_limit", self.value))
        object.__setattr__(self, "strain_rate",
                           _optional_positive("ShearLimit strain_rate", self.strain_rate))

    @classmethod
    def local_rate(cls) -> "ShearLimit":
        return cls()

    @classmethod
    def at_strain_rate(cls, strain_rate: float) -> "ShearLimit":
        return cls(strain_rate=strain_rate)

    @classmethod
    def given(cls, k: float) -> "ShearLimit":
        return cls(value=k)

    @property
    def kind(self) -> str:
        """``"given"``, ``"strain rate"`` or ``"local rate"``."""
        return ("given" if self.value is not None else
                "strain rate" if self.strain_rate is not None else "local rate")

    def k(self, material) -> float:
        """k for a body of ``material``, the same at every node; NaN for the local rate."""
        if self.value is not None:
            return self.value
        if self.strain_rate is not None:
            return float(shear_flow_stress(material, self.strain_rate))
        return math.nan

    def describe(self) -> str:
        if self.value is not None:
            return f"k = {self.value:.4g} given"
        if self.strain_rate is not None:
            return f"k of the material at the strain rate {self.strain_rate:.4g} 1/s"
        return "k of the material at each node's local strain rate"


def _shear_limit(law):
    """A law's ``shear_limit`` checked: a number (k), None (the local rate) or a ShearLimit at a
    strain rate (a given k and the local rate are kept as a number and None)."""
    value = law.shear_limit
    if isinstance(value, ShearLimit):
        if value.kind != "strain rate":
            value = value.value
        else:
            return value
    return _optional_positive("shear_limit", value)


class FrictionLaw:
    """Base class of the friction laws (one law per tool–body pair)."""

    code: int = LAW_NONE

    #: True if the law needs the shear flow stress k of the body (Tresca limit)
    needs_shear_limit: bool = False
    #: True if the law needs the body's consistency K (viscoplastic friction)
    needs_consistency: bool = False

    @property
    def k_source(self) -> ShearLimit:
        """Which shear flow stress k the law uses (:class:`ShearLimit`)."""
        value = getattr(self, "shear_limit", None)
        return value if isinstance(value, ShearLimit) else ShearLimit(value=value)

    def describe(self) -> str:
        """The law and, for a Tresca limit, which k it uses (the run's summary)."""
        fields = ", ".join(f"{k}={v:g}" for k, v in vars(self).items()
                           if isinstance(v, (int, float)) and k not in ("shear_limit", "K"))
        text = f"{type(self).__name__}({fields})"
        if self.needs_shear_limit:
            text += f", {self.k_source.describe()}"
        if self.needs_consistency:
            K = getattr(self, "K", None)
            text += ", K given" if K is not None else ", K of the material"
        return text


def laws_per_tool(friction, tools) -> List[FrictionLaw]:
    """One law per tool from a law, a ``{tool or tool name: law}`` dict (tools left out are
    frictionless) or a sequence aligned with ``tools`` (ValueError otherwise)."""

    def check(law, where):
        if not isinstance(law, FrictionLaw):
            raise ValueError(f"friction {where} must be a friction law (Coulomb, Tresca, "
                             f"Norton, Frictionless), got {law!r}")
        return law
    if friction is None:
        return [Frictionless() for _ in tools]
    if isinstance(friction, FrictionLaw):
        return [friction for _ in tools]
    if isinstance(friction, dict):
        names = [t.name for t in tools]
        out = [Frictionless() for _ in tools]
        for key, law in friction.items():
            if isinstance(key, Tool):
                idx = [k for k, t in enumerate(tools) if t is key]
                label = key.name
            elif isinstance(key, str):
                idx = [k for k, nm in enumerate(names) if nm == key]
                label = key
            else:
                raise ValueError(f"friction keys must be tools or tool names, got {key!r}")
            if not idx:
                raise ValueError(f"friction given for tool '{label}', which is not one of "
                                 f"this contact's tools {names}")
            if len(idx) > 1:
                raise ValueError(f"friction key '{label}' matches several tools: give the "
                                 f"tools distinct names")
            out[idx[0]] = check(law, f"for tool '{label}'")
        return out
    if isinstance(friction, (list, tuple)):
        if len(friction) != len(tools):
            raise ValueError(f"friction sequence has {len(friction)} laws for "
                             f"{len(tools)} tools")
        return [check(law, f"[{k}]") for k, law in enumerate(friction)]
    raise ValueError(f"friction must be a friction law, a dict or a sequence, "
                     f"got {friction!r}")


@dataclass(frozen=True)
class Frictionless(FrictionLaw):
    """No tangential stress (the default)."""

    code = LAW_NONE


@dataclass(frozen=True)
class Coulomb(FrictionLaw):
    """Coulomb friction limited by Tresca: ``τ = min(μ p_n, m̄ k)`` along −Δv_t/s.

    Args:
        mu: Coulomb coefficient μ ≥ 0.
        mbar: Tresca factor m̄ in [0, 1] limiting the shear stress to m̄ k; None: pure Coulomb.
        shear_limit: the body's shear flow stress k of the limit (:class:`ShearLimit`): a
            number k [stress], ``ShearLimit.at_strain_rate(rate)``, or None (default): the
            Norton–Hoff material at each node (k = K (√3 ε̄̇)^m, the local strain rate);
            a number is required for other materials when ``mbar`` is given.
    """

    mu: float
    mbar: Optional[float] = None
    shear_limit: Union[float, ShearLimit, None] = None
    code = LAW_COULOMB

    def __post_init__(self):
        object.__setattr__(self, "mu", _finite("Coulomb mu", self.mu, 0.0))
        if self.mbar is not None:
            object.__setattr__(self, "mbar", _finite("Coulomb mbar (Tresca limit)", self.mbar,
                                                     0.0, 1.0))
        object.__setattr__(self, "shear_limit", _shear_limit(self))

    @property
    def needs_shear_limit(self) -> bool:
        return self.mbar is not None


@dataclass(frozen=True)
class Tresca(FrictionLaw):
    """Tresca (friction factor) law: ``τ = m̄ k`` along −Δv_t/s.

    Args:
        mbar: friction factor m̄ in [0, 1] (1: the shear flow stress, full sticking friction).
        shear_limit: k [stress], ``ShearLimit.at_strain_rate(rate)``, or None (default): the
            Norton–Hoff material at each node's local strain rate (:class:`ShearLimit`); a
            number is required for other materials.
    """

    mbar: float
    shear_limit: Union[float, ShearLimit, None] = None
    code = LAW_TRESCA
    needs_shear_limit = True

    def __post_init__(self):
        object.__setattr__(self, "mbar", _finite("Tresca mbar", self.mbar, 0.0, 1.0))
        object.__setattr__(self, "shear_limit", _shear_limit(self))


@dataclass(frozen=True)
class Norton(FrictionLaw):
    """Viscoplastic (Norton) friction: ``τ = −α_f K s^(q−1) Δv_t``.

    Args:
        alpha_f: friction coefficient α_f ≥ 0.
        q: slip-rate sensitivity, 0 < q ≤ 1 (often q = m of the material).
        K: consistency [stress·time^q/length^q]; default the Norton–Hoff material's K; required
            for other materials.
    """

    alpha_f: float
    q: float
    K: Optional[float] = None
    code = LAW_NORTON
    needs_consistency = True

    def __post_init__(self):
        object.__setattr__(self, "alpha_f", _finite("Norton alpha_f", self.alpha_f, 0.0))
        object.__setattr__(self, "q", _finite("Norton q", self.q, 0.0, 1.0, lo_open=True))
        object.__setattr__(self, "K", _optional_positive("Norton K", self.K))


# --------------------------------------------------------------------------------------------
# nodal kernel
# --------------------------------------------------------------------------------------------

@numba.njit(cache=True)
def friction_kernel(S, law, mu, tau_max, visc, q, pn, dpn, dv, nrm, v0, active, jacobian,
                    theta=1.0):
    """Nodal friction residual, Jacobian blocks, stress and branch.

    Args:
        S: (N,) nodal areas.
        law: (N,) int law code per node (``LAW_*``).
        mu: (N,) Coulomb coefficients.
        tau_max: (N,) Tresca thresholds m̄k (``inf``: pure Coulomb).
        visc: (N,) α_f K of viscoplastic friction.
        q: (N,) slip-rate sensitivities.
        pn: (N,) contact pressures entering Coulomb.
        dpn: (N, d) ∂p_n/∂v (implicit friction), or shape (0, d) (explicit: p_n fixed).
        dv: (N, d) velocity relative to the tool's material point.
        nrm: (N, d) unit tool normals.
        v0: slip-speed regularisation (> 0).
        active: (N,) bool, nodes that carry friction (in contact).
        jacobian: whether to compute the blocks.
        theta: weight of the slip-direction term of the tangent: 1 = consistent tangent, 0 =
            secant tangent ``S c P_t`` (positive definite in the tangent plane; it does not
            vanish along the slip of a node that slips at |Δv_t| ≫ v₀, so a body held by
            friction alone keeps a non-singular tangent while stick and slip settle).

    Returns:
        r (N, d) residual entries, K (N, d, d) blocks (or (0, d, d)), tau (N, d) tangential
        stress on the body, branch (N,) int8: 0 none, 1 Coulomb, 2 Tresca limit, 3 Norton.
    """
    n, d = dv.shape
    r = np.zeros((n, d))
    K = np.zeros((n if jacobian else 0, d, d))
    tau = np.zeros((n, d))
    branch = np.zeros(n, dtype=np.int8)
    has_dp = dpn.shape[0] == n
    dvt = np.zeros(d)
    for i in range(n):
        if not active[i] or law[i] == 0:
            continue
        vn = 0.0
        for a in range(d):
            vn += dv[i, a] * nrm[i, a]
        s2 = v0 * v0
        for a in range(d):
            dvt[a] = dv[i, a] - vn * nrm[i, a]
            s2 += dvt[a] * dvt[a]
        s = math.sqrt(s2)
        coulomb = False
        if law[i] == 3:
            c = visc[i] * s ** (q[i] - 1.0)          # τ = −c Δv_t
            e = (q[i] - 1.0) / s2                     # K = S c (P_t + e Δv_t⊗Δv_t)
            branch[i] = 3
        else:
            if law[i] == 1 and mu[i] * pn[i] < tau_max[i]:
                tl = mu[i] * pn[i]
                coulomb = True
                branch[i] = 1
            else:
                tl = tau_max[i]
                branch[i] = 2
            c = tl / s
            e = -1.0 / s2
        for a in range(d):
            tau[i, a] = -c * dvt[a]
            r[i, a] = S[i] * c * dvt[a]
        if jacobian:
            sc = S[i] * c
            for a in range(d):
                for b in range(d):
                    pt = (1.0 if a == b else 0.0) - nrm[i, a] * nrm[i, b]
                    K[i, a, b] = sc * (pt + theta * e * dvt[a] * dvt[b])
            if coulomb and has_dp:
                for a in range(d):
                    for b in range(d):
                        K[i, a, b] += S[i] * dvt[a] / s * mu[i] * dpn[i, b]
    return r, K, tau, branch


def friction_kernel_numpy(S, law, mu, tau_max, visc, q, pn, dpn, dv, nrm, v0, active, jacobian,
                          theta=1.0):
    """Reference implementation of :func:`friction_kernel`, for testing only."""
    n, d = dv.shape
    on = active & (law != LAW_NONE)
    vn = np.einsum("ni,ni->n", dv, nrm)
    dvt = dv - vn[:, None] * nrm
    s2 = np.einsum("ni,ni->n", dvt, dvt) + v0**2
    s = np.sqrt(s2)
    norton = law == LAW_NORTON
    coul = (law == LAW_COULOMB) & (mu * pn < tau_max)
    branch = np.where(norton, 3, np.where(coul, 1, 2)).astype(np.int8)
    branch[~on] = 0
    tl = np.where(coul, mu * pn, tau_max)
    with np.errstate(invalid="ignore", divide="ignore"):
        c = np.where(norton, visc * s ** (q - 1.0), tl / s)
    e = np.where(norton, (q - 1.0) / s2, -1.0 / s2)
    c = np.where(on, c, 0.0)
    tau = -c[:, None] * dvt
    r = (S * c)[:, None] * dvt
    if not jacobian:
        return r, np.zeros((0, d, d)), tau, branch
    Pt = np.eye(d)[None] - nrm[:, :, None] * nrm[:, None, :]
    K = (S * c)[:, None, None] * (Pt + theta * e[:, None, None] * dvt[:, :, None]
                                  * dvt[:, None, :])
    if dpn.shape[0] == n:
        sel = on & coul
        K[sel] += (S * mu / s)[sel, None, None] * dvt[sel, :, None] * dpn[sel, None, :]
    return r, K, tau, branch
