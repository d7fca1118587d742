"""Classical theories of flat rolling (THEORY §14.3), pure numpy/scipy.

Plane-strain flat rolling of a strip from thickness ``h0`` to ``h1`` between two rigid rolls of
radius ``R`` (symmetric: one roll per side). Angles ``φ`` are measured from the line of roll
centres (``φ = 0`` at the exit plane, ``φ = α`` at the entry); the local thickness is
``h(φ) = h1 + 2R(1 − cos φ)``. The flow stress ``σ0`` (von Mises, plane strain yield
``2k = 2σ0/√3``) is a constant here: for a Norton–Hoff material take it at the mean strain rate
of the bite (:func:`mean_strain_rate`, ``NortonHoff.flow_stress``, THEORY §14.1).

* :func:`bite` — contact length ``L = √(RΔh)``, bite angle, unaided-bite condition
  ``μ ≥ tan α``, mean strain rate ``(v_R/L) ln(h0/h1)``.
* :func:`slab` — Orowan/von Kármán slab with the Coulomb law limited by Tresca,
  ``τ = min(μp, m̄k)`` (the law of :class:`fxcontact.Coulomb`): the pressure hill is integrated
  from the entry and from the exit (``σ_x = 0`` at both, no strip tensions) and the neutral angle
  is where the two branches meet. Roll force, torque, forward slip.
* :func:`sims` — Sims's closed form (sticking friction).
* :func:`ford_alexander` — Ford–Alexander's slip-line fit.
* :func:`hill_spread` — Hill's spread formula.
* :func:`theory_band` — all of them for one pass (what the rolling demo compares against).

Units are consistent (e.g. mm, MPa, N, s): forces per unit width are N/mm.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.integrate import solve_ivp

__all__ = ["BiteGeometry", "SlabSolution", "bite", "mean_strain_rate", "slab", "sims",
           "ford_alexander", "hill_spread", "theory_band"]


def _positive(name, value):
    if not (isinstance(value, (int, float, np.floating, np.integer)) and math.isfinite(value)
            and value > 0):
        raise ValueError(f"{name} must be a finite number > 0, got {value!r}")
    return float(value)


def _pass(R, h0, h1):
    R, h0, h1 = _positive("roll radius R", R), _positive("entry thickness h0", h0), \
        _positive("exit thickness h1", h1)
    if not h1 < h0:
        raise ValueError(f"the exit thickness h1 = {h1} must be smaller than the entry "
                         f"thickness h0 = {h0}")
    if h0 - h1 >= 2.0 * R:
        raise ValueError(f"the draft h0 - h1 = {h0 - h1} must be smaller than the roll "
                         f"diameter 2R = {2 * R}")
    return R, h0, h1


@dataclass(frozen=True)
class BiteGeometry:
    """Geometry of the roll gap (THEORY §14.3)."""

    R: float
    h0: float
    h1: float
    draft: float           #: Δh = h0 − h1
    reduction: float       #: r = Δh / h0
    contact_length: float  #: L = √(R Δh) (projected arc of contact)
    bite_angle: float      #: α = arccos(1 − Δh / 2R)
    max_draft_ratio: float  #: tan α: the smallest μ that bites unaided

    def bites(self, mu: float) -> bool:
        """Unaided bite: μ ≥ tan α."""
        return mu >= self.max_draft_ratio


def bite(R: float, h0: float, h1: float) -> BiteGeometry:
    """Contact length, bite angle and the unaided-bite friction ``tan α`` of a pass."""
    R, h0, h1 = _pass(R, h0, h1)
    dh = h0 - h1
    alpha = math.acos(1.0 - dh / (2.0 * R))
    return BiteGeometry(R, h0, h1, dh, dh / h0, math.sqrt(R * dh), alpha, math.tan(alpha))


def mean_strain_rate(R: float, h0: float, h1: float, roll_speed: float) -> float:
    """Mean equivalent strain rate of the bite, ``(v_R / L) ln(h0/h1)`` (THEORY §14.3).

    (The plane-strain equivalent rate carries a further factor 2/√3; the classical estimate
    is kept as written, its use is to pick ``σ0`` of a rate-sensitive material.)"""
    g = bite(R, h0, h1)
    return _positive("roll peripheral speed", roll_speed) / g.contact_length \
        * math.log(h0 / h1)


@dataclass(frozen=True)
class SlabSolution:
    """Slab (Orowan) solution of one pass, per unit width and per roll."""

    phi: np.ndarray        #: angles from exit (0) to entry (α)
    pressure: np.ndarray   #: normal roll pressure p(φ) (the lower of the two branches)
    shear: np.ndarray      #: friction stress on the strip, > 0 towards the exit (φ > φn)
    h: np.ndarray          #: thickness h(φ)
    neutral_angle: float   #: φn
    force: float           #: roll separating force per unit width, R ∫ p dφ (classical)
    force_vertical: float  #: R ∫ (p cos φ + τ sin φ) dφ: with the friction's vertical part
    torque: float          #: roll torque per unit width (one roll), R² ∫ ±τ dφ
    forward_slip: float    #: h_n cos φn / h1 − 1
    mean_pressure: float   #: force / L
    k: float               #: shear flow stress σ0/√3


def _check_friction(mu, mbar):
    if mu is not None:
        if not (math.isfinite(mu) and mu >= 0):
            raise ValueError(f"mu must be >= 0 (or None for Tresca only), got {mu!r}")
    if mbar is not None:
        if not (math.isfinite(mbar) and 0 <= mbar <= 1):
            raise ValueError(f"mbar (Tresca factor) must be in [0, 1], got {mbar!r}")
    if mu is None and mbar is None:
        raise ValueError("give mu (Coulomb) and/or mbar (Tresca limit)")


def slab(R: float, h0: float, h1: float, sigma0: float, mu=0.3, mbar=1.0,
         n: int = 4001) -> SlabSolution:
    """Slab (von Kármán/Orowan) solution with the Coulomb–Tresca law ``τ = min(μp, m̄k)``.

    With ``x`` the distance from the exit plane towards the entry (``x = R sin φ``, ``dh/dx =
    2 tan φ``) and ``F = σ_x h`` (σ_x tensile > 0), the equilibrium of a vertical slice (roll
    pressure ``p`` and friction ``τ`` on both faces) reads ``dF/dx = −2p tan φ ± 2τ``: ``+``
    between the neutral point and the entry (the rolls drag the strip forward), ``−`` between
    the exit and the neutral point; plane-strain yield ``p = 2k − σ_x`` (THEORY §14.3). Both
    branches are integrated (in ``φ``, scipy's RK45 to 1e-10) from ``σ_x = 0`` at their end;
    the pressure is the lower branch and the neutral angle ``φn`` is where they cross.

    ``mu=None`` gives Tresca friction ``m̄k`` alone; ``mbar=None`` pure Coulomb; ``mbar=1`` with a
    large ``mu`` is sticking friction.

    Raises:
        ValueError: bad input, or no neutral point: the friction cannot drive a strip that
            fills the bite (roughly ``μ < α/2``, half the unaided-bite value ``tan α``).
    """
    R, h0, h1 = _pass(R, h0, h1)
    sigma0 = _positive("flow stress sigma0", sigma0)
    _check_friction(mu, mbar)
    g = bite(R, h0, h1)
    k = sigma0 / math.sqrt(3.0)
    mu_ = math.inf if mu is None else float(mu)
    lim = math.inf if mbar is None else float(mbar) * k

    def hh(phi):
        return h1 + 2.0 * R * (1.0 - np.cos(phi))

    def tau(p):
        return np.minimum(mu_ * p if math.isfinite(mu_) else lim, lim)

    def rhs(sign):
        def f(phi, F):
            p = 2.0 * k - F[0] / hh(phi)
            return [R * (-2.0 * p * math.sin(phi) + sign * 2.0 * tau(p) * math.cos(phi))]
        return f

    phi = np.linspace(0.0, g.bite_angle, n)
    kw = dict(method="RK45", rtol=1e-10, atol=1e-10 * k * h0, max_step=g.bite_angle / 200)
    ex = solve_ivp(rhs(-1.0), (0.0, g.bite_angle), [0.0], t_eval=phi, **kw)
    en = solve_ivp(rhs(+1.0), (g.bite_angle, 0.0), [0.0], t_eval=phi[::-1], **kw)
    F_ex, F_en = ex.y[0], en.y[0][::-1]
    h = hh(phi)
    p_ex, p_en = 2.0 * k - F_ex / h, 2.0 * k - F_en / h
    d = p_en - p_ex          # > 0 near the exit, < 0 near the entry if the branches cross
    if not (d[0] > 0 and d[-1] < 0):
        raise ValueError(f"no neutral point: the friction (mu = {mu}, mbar = {mbar}) cannot "
                         f"drive a strip that fills the bite (unaided bite needs mu >= "
                         f"tan(alpha) = {g.max_draft_ratio:.4f}, steady rolling roughly "
                         f"alpha/2 = {0.5 * g.bite_angle:.4f})")
    j = int(np.nonzero((d[:-1] > 0) & (d[1:] <= 0))[0][-1])
    phin = phi[j] + (phi[j + 1] - phi[j]) * d[j] / (d[j] - d[j + 1])
    p = np.minimum(p_ex, p_en)
    sgn = np.where(phi > phin, 1.0, -1.0)
    t = sgn * tau(p)
    # vertical force on one roll: pressure and the vertical component of friction (upward
    # on the roll in the entry zone where the strip's friction on the roll points backwards)
    force_v = R * np.trapz(p * np.cos(phi) + t * np.sin(phi), phi)
    force = R * np.trapz(p, phi)
    torque = R * R * np.trapz(t, phi)
    hn = h1 + 2.0 * R * (1.0 - math.cos(phin))
    return SlabSolution(phi, p, t, h, float(phin), float(force), float(force_v),
                        float(torque), float(hn * math.cos(phin) / h1 - 1.0),
                        float(force / g.contact_length), k)


def sims(R: float, h0: float, h1: float, sigma0: float) -> dict:
    """Sims's roll force for sticking friction (THEORY §14.3).

    Returns ``force`` (per unit width), ``Qp``, ``neutral_angle`` (φn), ``forward_slip``
    (``h_n cos φn / h1 − 1`` with ``h_n = h1 + R φn²``)."""
    R, h0, h1 = _pass(R, h0, h1)
    sigma0 = _positive("flow stress sigma0", sigma0)
    g = bite(R, h0, h1)
    r = g.reduction
    a = math.sqrt((1.0 - r) / r)
    b = math.sqrt(R / h1)
    phin = math.sqrt(h1 / R) * math.tan(math.pi / 8.0 * math.sqrt(h1 / R) * math.log(1.0 - r)
                                        + 0.5 * math.atan(math.sqrt(r / (1.0 - r))))
    hn = h1 + R * phin**2
    Qp = (math.pi / 2.0 * a * math.atan(1.0 / a) - math.pi / 4.0 - a * b * math.log(hn / h1)
          + 0.5 * a * b * math.log(1.0 / (1.0 - r)))
    k = sigma0 / math.sqrt(3.0)
    return dict(force=2.0 * k * g.contact_length * Qp, Qp=Qp, neutral_angle=phin,
                forward_slip=hn * math.cos(phin) / h1 - 1.0)


def ford_alexander(R: float, h0: float, h1: float, sigma0: float) -> float:
    """Ford–Alexander roll force per unit width, ``2kL[π/4 + L/(2(h0 + h1))]``."""
    R, h0, h1 = _pass(R, h0, h1)
    k = _positive("flow stress sigma0", sigma0) / math.sqrt(3.0)
    L = bite(R, h0, h1).contact_length
    return 2.0 * k * L * (math.pi / 4.0 + L / (2.0 * (h0 + h1)))


def hill_spread(R: float, h0: float, h1: float, b0: float) -> float:
    """Hill's spread: exit width ``b1 = b0 (h0/h1)^w``, ``w = ½ exp(−b0 / 2L)`` (``b0``: the
    full strip width)."""
    R, h0, h1 = _pass(R, h0, h1)
    b0 = _positive("strip width b0", b0)
    L = bite(R, h0, h1).contact_length
    return b0 * (h0 / h1) ** (0.5 * math.exp(-b0 / (2.0 * L)))


def theory_band(R: float, h0: float, h1: float, sigma0: float, mu=0.3, mbar=1.0,
                b0=None) -> dict:
    """The classical estimates of one pass: roll force per unit width (slab with the given law,
    Sims, Ford–Alexander, and their min/max: the band), slab torque per unit width and forward
    slip, neutral angle, bite geometry, Hill's exit width (if ``b0`` is given). With too little
    friction for a steady slab solution the slab entries are NaN and ``slab_message`` says why
    (the band is then Sims's and Ford–Alexander's, which assume sticking)."""
    g = bite(R, h0, h1)
    si = sims(R, h0, h1, sigma0)
    fa = ford_alexander(R, h0, h1, sigma0)
    try:
        s = slab(R, h0, h1, sigma0, mu, mbar)
        sl = dict(slab_force=s.force, slab_force_vertical=s.force_vertical,
                  slab_torque=s.torque, slab_forward_slip=s.forward_slip,
                  slab_neutral_angle=s.neutral_angle, slab_message="")
        forces = [s.force, si["force"], fa]
    except ValueError as e:      # too little friction: no steady slab solution
        if "no neutral point" not in str(e):
            raise
        sl = dict(slab_force=math.nan, slab_force_vertical=math.nan, slab_torque=math.nan,
                  slab_forward_slip=math.nan, slab_neutral_angle=math.nan, slab_message=str(e))
        forces = [si["force"], fa]
    out = dict(contact_length=g.contact_length, bite_angle=g.bite_angle,
               tan_bite_angle=g.max_draft_ratio, **sl,
               sims_force=si["force"], sims_forward_slip=si["forward_slip"],
               sims_neutral_angle=si["neutral_angle"], ford_alexander_force=fa,
               force_min=min(forces), force_max=max(forces), sigma0=sigma0)
    if b0 is not None:
        out["hill_width"] = hill_spread(R, h0, h1, b0)
    return out
