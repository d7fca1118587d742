"""Classical forming theory the process demos are compared against (THEORY §14).

Pure numpy/scipy, no FE. The results are approximations (upper bounds, slab estimates) with known
biases: the FE answer is not expected to equal them but to fall in the band they define.

* :func:`flow_stress` — uniaxial flow stress of the Norton–Hoff law at a strain rate (§14.1).
* Upsetting a cylinder between flat dies (§14.5): :func:`upsetting_upper_bound` (Tresca factor
  m̄, homogeneous field) and :func:`upsetting_slab_coulomb` (Coulomb μ, slab method).
* Ring compression (Avitzur's upper bound, §14.5): :func:`ring_power` (closed form),
  :func:`ring_power_quadrature` (the same by quadrature, an independent check),
  :func:`ring_neutral_radius` (minimiser of the power) and :func:`ring_compression_upper_bound`
  (the calibration curve: change of the inner diameter against the height reduction, and the
  mean die pressure).
* Radial ring rolling (§14.4): :func:`ring_rolling_curvature`, :func:`ring_rolling_contact_length`,
  :func:`ring_rolling_feed_window` (Hawkyard's plastic penetration and the bite-in limit),
  :func:`ring_rolling_feed_speed`, :func:`ring_rolling_mean_diameter` (volume constancy) and
  :func:`ring_rolling_force` (2kHLQ).
* Drawing through a conical die (THEORY §14.2): :func:`drawing_ideal_stress` (ideal work, a
  lower bound), :func:`drawing_sachs_stress` (Coulomb μ, slab), :func:`avitzur_f` and
  :func:`drawing_upper_bound` (Avitzur's upper bound with Tresca m̄ and a bearing land),
  :func:`drawing_mean_strain_rate` (the rate at which σ₀ of a power law is taken),
  :func:`drawing_optimal_angle` and :func:`drawing_theory` (the whole band for a Norton–Hoff
  material).
* Forward extrusion through a conical die (THEORY §14.2): :func:`extrusion_container_friction`
  (Tresca friction on the container wall, 2 m̄ k L_c/R₀) and :func:`extrusion_theory` (ideal
  work, Avitzur's die terms — the die part of :func:`drawing_upper_bound` — plus the container
  friction, for a Norton–Hoff material).
* Flat rolling (§14.3): :func:`flat_rolling_theory` (bite, the slab with Coulomb–Tresca friction,
  Sims, Ford–Alexander, Hill's spread: :func:`fxcontact.theory.flat_rolling.theory_band`, whose module holds
  the pieces). Every process's classical theory is thus importable from here (bar rolling is
  compared with its pass's geometry: :func:`fxcontact.processes.bar_rolling.pass_geometry`).

Units are free (consistent); pressures are returned over σ₀ and powers per unit σ₀ and closing
speed unless stated.
"""

from __future__ import annotations

import math
from typing import Dict, Sequence

import numpy as np
from scipy import integrate, optimize

from fxcontact.theory.flat_rolling import theory_band as flat_rolling_theory

__all__ = ["flow_stress", "upsetting_upper_bound", "upsetting_slab_coulomb", "ring_power",
           "ring_power_slope", "ring_power_quadrature", "ring_neutral_radius",
           "ring_compression_upper_bound",
           "ring_rolling_curvature", "ring_rolling_contact_length", "ring_rolling_feed_window",
           "ring_rolling_feed_speed", "ring_rolling_mean_diameter", "ring_rolling_force",
           "drawing_ideal_stress", "drawing_sachs_stress", "avitzur_f", "drawing_upper_bound",
           "drawing_mean_strain_rate", "drawing_optimal_angle", "drawing_theory",
           "extrusion_container_friction", "extrusion_theory", "flat_rolling_theory"]

SQRT3 = math.sqrt(3.0)


def _positive(name: str, value) -> float:
    value = float(value)
    if not (math.isfinite(value) and value > 0):
        raise ValueError(f"{name} must be a finite number > 0, got {value!r}")
    return value


def _friction_factor(mbar) -> float:
    mbar = float(mbar)
    if not (0.0 <= mbar <= 1.0):
        raise ValueError(f"the Tresca friction factor mbar must be in [0, 1], got {mbar!r}")
    return mbar


# ------------------------------------------------------------------------------ flow stress
def flow_stress(K: float, m: float, strain_rate) -> np.ndarray:
    """Uniaxial flow stress σ₀ = √3 K (√3 ε̄̇)^m of the Norton–Hoff law (THEORY §14.1).

    The shear yield stress is k = σ₀/√3.
    """
    _positive("K", K)
    if not (0 < m <= 1):
        raise ValueError(f"the strain-rate sensitivity m must be in (0, 1], got {m!r}")
    rate = np.asarray(strain_rate, dtype=float)
    if np.any(~np.isfinite(rate)) or np.any(rate < 0):
        raise ValueError("strain_rate must be finite and >= 0")
    return SQRT3 * K * (SQRT3 * rate) ** m


# ------------------------------------------------------------------------------ upsetting
def upsetting_upper_bound(mbar: float, diameter: float, height: float) -> float:
    """Upper bound of the mean die pressure, p̄/σ₀ = 1 + m̄ d/(3√3 h) (THEORY §14.5).

    Homogeneous velocity field (no barrelling), Tresca friction τ = m̄ k on both dies; the FE
    answer (which can barrel) is expected below it.
    """
    mbar = _friction_factor(mbar)
    d, h = _positive("diameter", diameter), _positive("height", height)
    return 1.0 + mbar * d / (3.0 * SQRT3 * h)


def upsetting_slab_coulomb(mu: float, radius: float, height: float) -> float:
    """Slab estimate of the mean die pressure with Coulomb friction on both dies,
    p̄/σ₀ = 2(eˣ − x − 1)/x², x = 2μR/h (THEORY §14.5; ≈ 1 + μd/(3h) for small x).

    No Tresca cap (at the centre of a long billet μp can exceed k: the slab then overestimates).
    """
    mu = float(mu)
    if not (math.isfinite(mu) and mu >= 0):
        raise ValueError(f"the Coulomb coefficient mu must be >= 0, got {mu!r}")
    R, h = _positive("radius", radius), _positive("height", height)
    x = 2.0 * mu * R / h
    if x < 1e-4:  # series: 2(eˣ − x − 1)/x² = 1 + x/3 + x²/12 + x³/60 + …
        return 1.0 + x / 3.0 + x * x / 12.0 + x ** 3 / 60.0
    return 2.0 * math.expm1(x) / (x * x) - 2.0 / x


# ------------------------------------------------------------------------------ ring
def _check_ring(inner_radius, outer_radius, height):
    Ri = float(inner_radius)
    Ro = _positive("outer_radius", outer_radius)
    T = _positive("height", height)
    if not (math.isfinite(Ri) and 0 <= Ri < Ro):
        raise ValueError(f"need 0 <= inner_radius < outer_radius, got {Ri!r}, {Ro!r}")
    return Ri, Ro, T


def _plastic_primitive(u: float, b: float) -> float:
    """F(u) with F' = √(3u² + b²)/u (u = r², b = R_n²); for b = 0, F = √3 u."""
    S = math.sqrt(3.0 * u * u + b * b)
    if b == 0.0:
        return S
    return S - b * math.log((b + S) / u)


def _friction_integral(Ri: float, Ro: float, Rn: float) -> float:
    """∫_{Ri}^{Ro} |r² − R_n²| dr (closed form)."""
    b = Rn * Rn

    def G(r):
        return r ** 3 / 3.0 - b * r

    if Rn <= Ri:
        return G(Ro) - G(Ri)
    if Rn >= Ro:
        return G(Ri) - G(Ro)
    return G(Ri) + G(Ro) - 2.0 * G(Rn)


def ring_power(neutral_radius: float, inner_radius: float, outer_radius: float, height: float,
               mbar: float) -> float:
    """Avitzur's upper-bound power J(R_n) of a ring compressed between flat dies, per unit σ₀
    and closing speed v (THEORY §14.5), closed form:

    J/(σ₀v) = (π/√3) [F(R_o²) − F(R_i²)] + (2π m̄/(√3 T)) ∫_{R_i}^{R_o} |r² − R_n²| dr,

    with F(u) = √(3u² + b²) − b ln((b + √(3u² + b²))/u), b = R_n² (a primitive of
    √(3u² + b²)/u, u = r², which turns the plastic term ``(2π/√3)∫ r √(3 + R_n⁴/r⁴) dr`` into
    closed form). Friction on both faces. The die force is J/v: ``σ₀·ring_power``.

    A solid disc (``inner_radius = 0``) has finite power only for R_n = 0 (the strain rate
    ~ R_n²/r² is not integrable at the axis): ``inf`` otherwise.
    """
    Ri, Ro, T = _check_ring(inner_radius, outer_radius, height)
    mbar = _friction_factor(mbar)
    Rn = float(neutral_radius)
    if not (math.isfinite(Rn) and 0 <= Rn <= Ro):
        raise ValueError(f"the neutral radius must be in [0, R_o], got {Rn!r}")
    b = Rn * Rn
    if Ri == 0.0:
        if b > 0.0:
            return math.inf
        plastic = math.pi / SQRT3 * _plastic_primitive(Ro * Ro, 0.0)
    else:
        plastic = math.pi / SQRT3 * (_plastic_primitive(Ro * Ro, b)
                                     - _plastic_primitive(Ri * Ri, b))
    friction = 2.0 * math.pi * mbar / (SQRT3 * T) * _friction_integral(Ri, Ro, Rn)
    return plastic + friction


def ring_power_quadrature(neutral_radius: float, inner_radius: float, outer_radius: float,
                          height: float, mbar: float) -> float:
    """:func:`ring_power` by adaptive quadrature of THEORY §14.5's integrals (reference twin)."""
    Ri, Ro, T = _check_ring(inner_radius, outer_radius, height)
    mbar = _friction_factor(mbar)
    Rn = float(neutral_radius)
    v = 1.0
    plastic = 2.0 * math.pi * v / SQRT3 * integrate.quad(
        lambda r: r * math.sqrt(3.0 + Rn ** 4 / r ** 4), Ri, Ro, epsabs=0.0, epsrel=1e-12,
        limit=200)[0]
    pts = [Rn] if Ri < Rn < Ro else None
    friction = 2.0 * mbar / SQRT3 * v / (2.0 * T) * 2.0 * math.pi * integrate.quad(
        lambda r: abs(r - Rn * Rn / r) * r, Ri, Ro, points=pts, epsabs=0.0, epsrel=1e-12,
        limit=200)[0]
    return plastic + friction


def ring_power_slope(Rn: float, Ri: float, Ro: float, T: float, mbar: float) -> float:
    """dJ/d(R_n²) of :func:`ring_power` (R_i > 0): with g(r) = (b + √(3r⁴ + b²))/r², b = R_n²,
    (π/√3) ln(g(R_i)/g(R_o)) + (2π m̄/(√3 T)) d/db ∫|r² − b| dr (∂F/∂b = −ln((b + S)/u))."""
    b = Rn * Rn

    def lng(r):
        u = r * r
        return math.log((b + math.sqrt(3.0 * u * u + b * b)) / u)

    if Rn <= Ri:
        dI = -(Ro - Ri)
    elif Rn >= Ro:
        dI = Ro - Ri
    else:
        dI = 2.0 * Rn - Ri - Ro
    return math.pi / SQRT3 * (lng(Ri) - lng(Ro)) + 2.0 * math.pi * mbar / (SQRT3 * T) * dI


def ring_neutral_radius(inner_radius: float, outer_radius: float, height: float,
                        mbar: float) -> float:
    """Neutral radius R_n minimising :func:`ring_power` over [0, R_o] (THEORY §14.5).

    ``scipy.optimize.minimize_scalar`` (bounded) on [0, R_o]; the end points, which the bounded
    method never evaluates, are compared with its answer: R_n = 0 (all the material flows
    outwards: the hole grows) is the exact answer for m̄ = 0 and for a solid disc; R_n ≤ R_i
    also means outward flow everywhere, R_i < R_n < R_o that the hole shrinks. An interior
    minimum is then polished to round-off by ``brentq`` on the slope dJ/d(R_n²) (Brent's
    minimiser only locates a flat minimum to ~√ε, which would make the radii's ODE noisy).
    """
    Ri, Ro, T = _check_ring(inner_radius, outer_radius, height)
    mbar = _friction_factor(mbar)
    if Ri == 0.0:  # the power of a disc is finite only for R_n = 0
        return 0.0

    def J(Rn):
        return ring_power(Rn, Ri, Ro, T, mbar)

    if ring_power_slope(0.0, Ri, Ro, T, mbar) >= 0.0:
        # J rises from R_n = 0 (m̄ = 0): 0 is the minimiser; Brent's answer would only be the
        # end of the region where J is flat to round-off (J − J(0) ~ R_n⁴)
        return 0.0

    res = optimize.minimize_scalar(J, bounds=(0.0, Ro), method="bounded",
                                   options={"xatol": 1e-10 * Ro, "maxiter": 500})
    best, Jbest = float(res.x), float(res.fun)
    for x in (0.0, Ro):  # ties go to the end point (J is flat at R_n = 0: dJ/dR_n = 0 there)
        if J(x) <= Jbest:
            best, Jbest = x, J(x)
    if 0.0 < best < Ro:
        def slope(Rn):
            return ring_power_slope(Rn, Ri, Ro, T, mbar)

        d = 1e-6 * Ro
        lo, hi = max(best - d, 0.0), min(best + d, Ro)
        if slope(lo) < 0.0 < slope(hi):
            best = optimize.brentq(slope, lo, hi, xtol=1e-15 * Ro, rtol=4 * np.finfo(float).eps)
    return best


def ring_compression_upper_bound(outer_radius: float, inner_radius: float, height: float,
                                 mbar: float, reductions: Sequence[float]) -> Dict[str, np.ndarray]:
    """Avitzur's ring-compression calibration curve for the Tresca factor ``mbar``.

    The ring (R_o, R_i, height T) is compressed at closing speed v; at each instant R_n minimises
    J on the current geometry and the radii move with the upper-bound field,
    ``dR/dt = u_r(R) = v/(2T) (R − R_n²/R)``, ``dT/dt = −v`` (volume is conserved exactly by
    this field). Integrated over the height reduction ε = 1 − T/T₀ with ``solve_ivp``
    (DOP853, rtol 1e-11).

    Args:
        outer_radius, inner_radius, height: initial ring (a 6:3:2 ring: 30, 15, 20).
        mbar: Tresca friction factor in [0, 1].
        reductions: height reductions ε in [0, 1) where the curve is wanted (increasing).
    Returns:
        dict of arrays over ``reductions``: ``reduction``, ``inner_radius``, ``outer_radius``,
        ``height``, ``neutral_radius``, ``id_change`` (% change of the inner diameter,
        100 (R_i/R_i0 − 1)), ``od_change`` (% for the outer diameter) and ``pressure``
        (mean die pressure over σ₀, J/(v π (R_o² − R_i²))).
    """
    Ri0, Ro0, T0 = _check_ring(inner_radius, outer_radius, height)
    if Ri0 == 0.0:
        raise ValueError("inner_radius must be > 0 for a ring (a disc is upsetting)")
    mbar = _friction_factor(mbar)
    eps = np.asarray(reductions, dtype=float)
    if eps.ndim != 1 or len(eps) == 0 or np.any(~np.isfinite(eps)) or np.any(eps < 0) \
            or np.any(eps >= 1) or np.any(np.diff(eps) < 0):
        raise ValueError("reductions must be a non-empty increasing sequence in [0, 1)")

    def rhs(e, y):
        Ri, Ro = y
        T = T0 * (1.0 - e)
        Rn = ring_neutral_radius(Ri, Ro, T, mbar)
        # d/dε = (T₀/v) d/dt, u_r = v/(2T)(R − R_n²/R)
        k = T0 / (2.0 * T)
        return [k * (Ri - Rn * Rn / Ri), k * (Ro - Rn * Rn / Ro)]

    if eps[-1] > 0:
        sol = integrate.solve_ivp(rhs, (0.0, float(eps[-1])), [Ri0, Ro0], t_eval=eps,
                                  rtol=1e-11, atol=1e-13 * Ro0, method="DOP853")
        if not sol.success:
            raise RuntimeError(f"ring upper bound: integration failed ({sol.message})")
        Ri, Ro = sol.y
    else:
        Ri, Ro = np.full(len(eps), Ri0), np.full(len(eps), Ro0)
    T = T0 * (1.0 - eps)
    Rn = np.array([ring_neutral_radius(a, b, c, mbar) for a, b, c in zip(Ri, Ro, T)])
    J = np.array([ring_power(n, a, b, c, mbar) for n, a, b, c in zip(Rn, Ri, Ro, T)])
    return {"reduction": eps, "inner_radius": Ri, "outer_radius": Ro, "height": T,
            "neutral_radius": Rn, "id_change": 100.0 * (Ri / Ri0 - 1.0),
            "od_change": 100.0 * (Ro / Ro0 - 1.0),
            "pressure": J / (math.pi * (Ro ** 2 - Ri ** 2))}


# ------------------------------------------------------------------------------ ring rolling
def _ring_mill(main_radius, mandrel_radius, outer_radius, inner_radius):
    R1 = _positive("main_radius", main_radius)
    R2 = _positive("mandrel_radius", mandrel_radius)
    R = _positive("outer_radius", outer_radius)
    r = _positive("inner_radius", inner_radius)
    if not r < R:
        raise ValueError(f"need inner_radius < outer_radius, got {r!r} >= {R!r}")
    if not R2 < r:
        raise ValueError(f"the mandrel (radius {R2!r}) must fit in the bore (radius {r!r})")
    return R1, R2, R, r


def ring_rolling_curvature(main_radius: float, mandrel_radius: float, outer_radius: float,
                           inner_radius: float) -> float:
    """Σ = 1/R₁ + 1/R₂ + 1/R − 1/r of the bite of radial ring rolling (THEORY §14.4): main roll
    R₁ on the outer surface R, mandrel R₂ in the bore r."""
    R1, R2, R, r = _ring_mill(main_radius, mandrel_radius, outer_radius, inner_radius)
    return 1.0 / R1 + 1.0 / R2 + 1.0 / R - 1.0 / r


def ring_rolling_contact_length(feed_per_revolution: float, main_radius: float,
                                mandrel_radius: float, outer_radius: float,
                                inner_radius: float) -> float:
    """Projected contact length of the bite L = √(2Δh/Σ) for the wall reduction Δh per
    revolution of the ring (THEORY §14.4)."""
    dh = _positive("feed_per_revolution", feed_per_revolution)
    S = ring_rolling_curvature(main_radius, mandrel_radius, outer_radius, inner_radius)
    if not S > 0:
        raise ValueError(f"the bite curvature sum must be > 0, got {S!r}")
    return math.sqrt(2.0 * dh / S)


def ring_rolling_feed_window(main_radius: float, mandrel_radius: float, outer_radius: float,
                             inner_radius: float, mu: float) -> Dict[str, float]:
    """Window of the feed per revolution Δh of radial ring rolling (THEORY §14.4).

    * plastic penetration through the wall (Hawkyard): Δh ≥ 6.55·10⁻³ B² Σ, B = R − r;
    * bite-in (friction μ = tan β must draw the ring in):
      Δh ≤ 2β²R₁ (1 + R₁/R₂ + R₁/R − R₁/r)/(1 + R₁/R₂)².

    Returns ``{"min": ..., "max": ..., "curvature": Σ, "bite_angle": β}``.
    """
    R1, R2, R, r = _ring_mill(main_radius, mandrel_radius, outer_radius, inner_radius)
    mu = float(mu)
    if not (math.isfinite(mu) and mu > 0):
        raise ValueError(f"the friction coefficient mu must be > 0 for the bite-in limit, "
                         f"got {mu!r}")
    S = ring_rolling_curvature(R1, R2, R, r)
    beta = math.atan(mu)
    lo = 6.55e-3 * (R - r) ** 2 * S
    hi = 2.0 * beta ** 2 * R1 * (1.0 + R1 / R2 + R1 / R - R1 / r) / (1.0 + R1 / R2) ** 2
    return {"min": lo, "max": hi, "curvature": S, "bite_angle": beta}


def ring_rolling_feed_speed(feed_per_revolution: float, main_angular_velocity: float,
                            main_radius: float, outer_radius: float) -> float:
    """Mandrel feed speed v_f = Δh ω₁R₁/(2πR) giving the feed Δh per ring revolution: the ring
    turns once while the main roll's surface covers 2πR (no slip, THEORY §14.4)."""
    dh = _positive("feed_per_revolution", feed_per_revolution)
    w = _positive("main_angular_velocity", main_angular_velocity)
    R1 = _positive("main_radius", main_radius)
    R = _positive("outer_radius", outer_radius)
    return dh * w * R1 / (2.0 * math.pi * R)


def ring_rolling_mean_diameter(volume: float, height, wall):
    """Mean diameter D_m = V/(π H B) of a rectangular ring section of height H and wall B
    (volume constancy, THEORY §14.4); arrays broadcast."""
    V = _positive("volume", volume)
    H = np.asarray(height, dtype=float)
    B = np.asarray(wall, dtype=float)
    if np.any(~np.isfinite(H)) or np.any(H <= 0) or np.any(~np.isfinite(B)) or np.any(B <= 0):
        raise ValueError("height and wall must be finite and > 0")
    return V / (math.pi * H * B)


def ring_rolling_force(shear_yield: float, height: float, contact_length: float,
                       wall: float) -> Dict[str, float]:
    """Radial roll force F ≈ 2kHLQ of ring rolling (THEORY §14.4), with the factor
    Q = 0.8 + 0.2B/L for 1 ≤ B/L < 8.74 and Q = π/4 + L/(4B) for B/L < 1.

    Returns ``{"force": F, "Q": Q, "B_over_L": B/L}``. Raises ValueError for B/L ≥ 8.74 (outside
    the range of the estimate: no plastic penetration of the wall).
    """
    k = _positive("shear_yield", shear_yield)
    H = _positive("height", height)
    L = _positive("contact_length", contact_length)
    B = _positive("wall", wall)
    ratio = B / L
    if ratio >= 8.74:
        raise ValueError(f"B/L = {ratio:.3g} >= 8.74: outside the range of the 2kHLQ estimate "
                         f"(the deformation does not penetrate the wall)")
    Q = 0.8 + 0.2 * ratio if ratio >= 1.0 else math.pi / 4.0 + 1.0 / (4.0 * ratio)
    return {"force": 2.0 * k * H * L * Q, "Q": Q, "B_over_L": ratio}
# ------------------------------------------------------------------------------ drawing
def _drawing_radii(initial_radius, final_radius):
    R0 = _positive("initial_radius", initial_radius)
    Rf = _positive("final_radius", final_radius)
    if not Rf < R0:
        raise ValueError(f"final_radius ({Rf}) must be smaller than initial_radius ({R0})")
    return R0, Rf


def _half_angle(half_angle) -> float:
    a = float(half_angle)
    if not (math.isfinite(a) and 0.0 < a < 0.5 * math.pi):
        raise ValueError(f"the die semi-angle must be in (0, π/2) radians, got {half_angle!r}")
    return a


def drawing_ideal_stress(sigma0: float, initial_radius: float, final_radius: float) -> float:
    """Ideal (homogeneous) work of drawing, σ_d = σ₀ ln(A₀/A_f) = 2σ₀ ln(R₀/R_f) (THEORY
    §14.2): a lower bound of the drawing stress (no friction, no redundant work)."""
    s0 = _positive("sigma0", sigma0)
    R0, Rf = _drawing_radii(initial_radius, final_radius)
    return 2.0 * s0 * math.log(R0 / Rf)


def drawing_sachs_stress(sigma0: float, initial_radius: float, final_radius: float,
                         half_angle: float, mu: float) -> float:
    """Sachs' slab estimate of the drawing stress with Coulomb friction μ on the cone
    (THEORY §14.2): σ_d = σ₀ (1 + B)/B [1 − (A_f/A₀)^B], B = μ cot α; no redundant work, no
    back tension. μ = 0 gives the ideal work (the B → 0 limit, taken by its series)."""
    s0 = _positive("sigma0", sigma0)
    R0, Rf = _drawing_radii(initial_radius, final_radius)
    a = _half_angle(half_angle)
    mu = float(mu)
    if not (math.isfinite(mu) and mu >= 0):
        raise ValueError(f"the Coulomb coefficient mu must be >= 0, got {mu!r}")
    lnr = math.log((R0 / Rf) ** 2)          # ln(A₀/A_f)
    B = mu / math.tan(a)
    if B * lnr < 1e-6:  # (1+B)/B (1 − e^{−B ln r}) = (1 + B)(ln r − B ln²r/2 + B² ln³r/6 …)
        return s0 * (1.0 + B) * lnr * (1.0 - 0.5 * B * lnr + (B * lnr) ** 2 / 6.0)
    return s0 * (1.0 + B) / B * -math.expm1(-B * lnr)


_F_SERIES = 1e-2  # α below which avitzur_f uses its series


def avitzur_f(half_angle):
    """Avitzur's factor f(α) of the internal deformation (THEORY §14.2), α in radians:

    f(α) = 1/sin²α {1 − cos α √(1 − (11/12) sin²α)
           + 1/√132 ln[(1 + √(11/12)) / (√(11/12) cos α + √(1 − (11/12) sin²α))]},

    f → 1 as α → 0. The closed form loses about ε/α² to cancellation; below α = 1e-2 the
    series f = 1 + α²/48 + 23α⁴/3456 + O(α⁶) is used (coefficients from the expansion of the
    braces; the two agree to ~1e-12 at the switch). A scalar gives a float, an array an
    array.
    """
    a = np.asarray(half_angle, dtype=float)
    if np.any(~np.isfinite(a)) or np.any(a < 0) or np.any(a >= 0.5 * math.pi):
        raise ValueError(f"the die semi-angle must be in [0, π/2) radians, got {half_angle!r}")
    c = 11.0 / 12.0
    big = np.maximum(a, _F_SERIES)                  # no 0/0 in the unused branch
    s2b = np.sin(big) ** 2
    rootb = np.sqrt(1.0 - c * s2b)
    closed = (1.0 - np.cos(big) * rootb + np.log((1.0 + math.sqrt(c))
              / (math.sqrt(c) * np.cos(big) + rootb)) / math.sqrt(132.0)) / s2b
    a2 = a * a
    out = np.where(a < _F_SERIES, 1.0 + a2 / 48.0 + 23.0 * a2 * a2 / 3456.0, closed)
    return float(out) if out.ndim == 0 else out


def drawing_upper_bound(sigma0: float, initial_radius: float, final_radius: float,
                        half_angle: float, mbar: float = 0.0, land_length: float = 0.0) -> float:
    """Avitzur's upper bound of the drawing stress through a conical die (THEORY §14.2):

    σ_d/σ₀ = 2 f(α) ln(R₀/R_f) + (2/√3)(α/sin²α − cot α)
             + (2 m̄/√3)(cot α ln(R₀/R_f) + L/R_f),

    internal deformation, the two velocity discontinuities (entry and exit spheres) and
    Tresca friction τ = m̄ k on the cone and on the bearing land of length L. No back tension.
    """
    s0 = _positive("sigma0", sigma0)
    R0, Rf = _drawing_radii(initial_radius, final_radius)
    a = _half_angle(half_angle)
    mbar = _friction_factor(mbar)
    L = float(land_length)
    if not (math.isfinite(L) and L >= 0):
        raise ValueError(f"land_length must be finite and >= 0, got {land_length!r}")
    lnr = math.log(R0 / Rf)
    s2 = math.sin(a) ** 2
    shear = 2.0 / SQRT3 * (a / s2 - 1.0 / math.tan(a))
    friction = 2.0 * mbar / SQRT3 * (lnr / math.tan(a) + L / Rf)
    return s0 * (2.0 * float(avitzur_f(a)) * lnr + shear + friction)


def drawing_mean_strain_rate(initial_radius: float, final_radius: float, half_angle: float,
                             entry_speed: float) -> float:
    """Mean equivalent strain rate in a conical die (homogeneous field, THEORY §14.2):
    ε̄̇ = 6 v₀ tan α / D₀ · ln(A₀/A_f) / (1 − (D_f/D₀)³), with v₀ the entry speed of the bar
    (the exit speed times A_f/A₀). σ₀ of a power law taken at this rate reproduces the ideal
    work of the exact rate field closely."""
    R0, Rf = _drawing_radii(initial_radius, final_radius)
    a = _half_angle(half_angle)
    v0 = _positive("entry_speed", entry_speed)
    return 6.0 * v0 * math.tan(a) / (2.0 * R0) * 2.0 * math.log(R0 / Rf) / (1.0 - (Rf / R0) ** 3)


def drawing_optimal_angle(initial_radius: float, final_radius: float, mbar: float,
                          land_length: float = 0.0, approximate: bool = False) -> float:
    """Die semi-angle (radians) that minimises :func:`drawing_upper_bound` for a Tresca factor
    ``mbar`` > 0 (found by bounded minimisation over (0.1°, 60°)); with ``approximate=True`` the
    classical estimate α_opt ≈ √(1.5 m̄ ln(R₀/R_f)) (THEORY §14.2). Without friction the bound
    decreases to the ideal work as α → 0 and there is no optimum: ``mbar = 0`` is refused."""
    R0, Rf = _drawing_radii(initial_radius, final_radius)
    mbar = _friction_factor(mbar)
    if mbar == 0.0:
        raise ValueError("without friction (mbar = 0) the upper bound has no optimal angle "
                         "(it falls to the ideal work as the angle goes to 0)")
    if approximate:
        return math.sqrt(1.5 * mbar * math.log(R0 / Rf))
    res = optimize.minimize_scalar(
        lambda a: drawing_upper_bound(1.0, R0, Rf, a, mbar, land_length),
        bounds=(math.radians(0.1), math.radians(60.0)), method="bounded",
        options={"xatol": 1e-10})
    return float(res.x)


def drawing_theory(K: float, m: float, initial_radius: float, final_radius: float,
                   half_angle: float, exit_speed: float, mu: float = 0.0, mbar: float = 0.0,
                   land_length: float = 0.0) -> Dict[str, float]:
    """The classical band of the drawing stress for a Norton–Hoff material (THEORY §14.1-2).

    σ₀ = √3 K (√3 ε̄̇)^m at the die's mean strain rate (:func:`drawing_mean_strain_rate`, entry
    speed ``exit_speed`` A_f/A₀). Returns ``sigma0``, ``strain_rate``, ``entry_speed``,
    ``ideal`` (lower bound), ``sachs`` (Coulomb ``mu``; equals ``ideal`` for μ = 0),
    ``avitzur`` (upper bound with ``mbar`` and the land), ``avitzur_f`` and the reduction of
    area ``reduction`` = 1 − A_f/A₀; stresses in the unit of K.
    """
    R0, Rf = _drawing_radii(initial_radius, final_radius)
    v1 = _positive("exit_speed", exit_speed)
    v0 = v1 * (Rf / R0) ** 2
    rate = drawing_mean_strain_rate(R0, Rf, half_angle, v0)
    s0 = float(flow_stress(K, m, rate))
    return {"sigma0": s0, "strain_rate": rate, "entry_speed": v0,
            "reduction": 1.0 - (Rf / R0) ** 2,
            "ideal": drawing_ideal_stress(s0, R0, Rf),
            "sachs": drawing_sachs_stress(s0, R0, Rf, half_angle, mu),
            "avitzur": drawing_upper_bound(s0, R0, Rf, half_angle, mbar, land_length),
            "avitzur_f": float(avitzur_f(half_angle))}


# ------------------------------------------------------------------------------ extrusion
def extrusion_container_friction(shear_yield: float, container_length: float,
                                 initial_radius: float, mbar: float) -> float:
    """Punch pressure spent on Tresca friction τ = m̄ k along the container wall (THEORY
    §14.2): the billet slides over the length L_c still in the container, the friction force
    2π R₀ L_c m̄ k over the punch area π R₀² gives p_c = 2 m̄ k L_c / R₀ (exact for a billet
    that moves rigidly in the container, whatever the die)."""
    k = _positive("shear_yield", shear_yield)
    R0 = _positive("initial_radius", initial_radius)
    L = float(container_length)
    if not (math.isfinite(L) and L >= 0):
        raise ValueError(f"container_length must be finite and >= 0, got {container_length!r}")
    return 2.0 * _friction_factor(mbar) * k * L / R0


def extrusion_theory(K: float, m: float, initial_radius: float, final_radius: float,
                     half_angle: float, punch_speed: float, mbar_die: float = 0.0,
                     mbar_container: float = 0.0, container_length: float = 0.0,
                     land_length: float = 0.0, shear_yield: float = None) -> Dict[str, float]:
    """The classical band of the punch pressure of forward extrusion through a conical die,
    Norton–Hoff material (THEORY §14.2).

    The billet enters the die at the punch speed v₀; the die's work is that of drawing (the
    power p A₀ v₀ = σ_d A_f v_f, so p = σ_d): ``ideal`` = σ₀ ln(R₀²/R_f²) (a lower bound),
    ``avitzur`` = Avitzur's upper bound of the die (:func:`drawing_upper_bound`: internal
    deformation, the two shear surfaces, Tresca ``mbar_die`` on the cone and the land), plus
    ``container`` = 2 m̄_c k L_c / R₀ (:func:`extrusion_container_friction`) with
    ``shear_yield`` k (default σ₀/√3 at the die's mean strain rate); ``upper`` = avitzur +
    container. σ₀ = √3 K (√3 ε̄̇)^m at :func:`drawing_mean_strain_rate` with the entry speed
    v₀. Also ``sigma0``, ``strain_rate``, ``shear_yield``, ``exit_speed``, ``reduction`` (of
    area) and ``extrusion_ratio`` A₀/A_f; stresses in the unit of K.
    """
    R0, Rf = _drawing_radii(initial_radius, final_radius)
    v0 = _positive("punch_speed", punch_speed)
    rate = drawing_mean_strain_rate(R0, Rf, half_angle, v0)
    s0 = float(flow_stress(K, m, rate))
    k = s0 / SQRT3 if shear_yield is None else _positive("shear_yield", shear_yield)
    die = drawing_upper_bound(s0, R0, Rf, half_angle, mbar_die, land_length)
    container = extrusion_container_friction(k, container_length, R0, mbar_container)
    return {"sigma0": s0, "strain_rate": rate, "shear_yield": k,
            "exit_speed": v0 * (R0 / Rf) ** 2, "reduction": 1.0 - (Rf / R0) ** 2,
            "extrusion_ratio": (R0 / Rf) ** 2, "ideal": drawing_ideal_stress(s0, R0, Rf),
            "avitzur": die, "container": container, "upper": die + container}
