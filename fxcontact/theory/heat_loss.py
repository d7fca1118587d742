"""Heat a hot body loses, in closed form (THEORY §16): the tool contacts and the free surfaces of
a forming process, for the estimates the thermal process runs are compared with.

* :func:`contact_heat` — the heat per unit area a semi-infinite body at uniform temperature
  loses to a tool through a contact coefficient h during a contact of duration t (the tool's
  surface kept at its temperature): with θ₀ = T − T_tool, b = √(kρc) the body's effusivity and
  β = h√t/b, Q/A = θ₀ (b²/h) [e^{β²} erfc β − 1 + 2β/√π] (the integral of the surface flux
  h θ_s(t) of the semi-infinite body with a film, Carslaw & Jaeger, section 2.7). Small β:
  h θ₀ t (the surface does not cool: a lumped estimate); large β: 2 b θ₀ √(t/π) (perfect
  contact).
* :func:`air_flux` — the flux a surface at T loses to air, h (T − T_a) + ε σ (T_K⁴ − T_a,K⁴).

Units: N, mm, s, °C: h in N/(mm s K), b in N/(mm s^½ K), heat per area in N/mm (= mJ/mm²).
"""

from __future__ import annotations

import math

import numpy as np
from scipy.special import erfcx

from fxcontact.heat.materials import KELVIN, SIGMA_SB

__all__ = ["contact_heat", "air_flux"]


def contact_heat(theta0: float, h: float, effusivity: float, time: float) -> float:
    """Heat per unit area [N/mm] a semi-infinite body at θ₀ = ``theta0`` [K] above the tool
    loses through ``h`` [N/(mm s K)] in a contact of ``time`` [s] (module docstring); b =
    ``effusivity`` [N/(mm s^½ K)] of the body."""
    for name, v in (("h", h), ("effusivity", effusivity), ("time", time)):
        if not (math.isfinite(v) and v >= 0):
            raise ValueError(f"{name} must be finite and >= 0, got {v!r}")
    if h == 0.0 or time == 0.0:
        return 0.0
    if effusivity == 0.0:
        raise ValueError("the body's effusivity must be > 0 N/(mm s^½ K)")
    beta = h * math.sqrt(time) / effusivity
    if beta < 1e-3:   # the series: h t θ₀ (1 − 4β/(3√π) + β²/2 ...), no cancellation
        return float(theta0 * h * time * (1.0 - 4.0 * beta / (3.0 * math.sqrt(math.pi))
                                          + 0.5 * beta * beta))
    return float(theta0 * effusivity ** 2 / h
                 * (erfcx(beta) - 1.0 + 2.0 * beta / math.sqrt(math.pi)))


def air_flux(air, T) -> np.ndarray:
    """The flux [N/(mm s)] a surface at ``T`` [°C] loses to ``air`` (an
    :class:`~fxcontact.heat.AirExchange`): convection and radiation (not linearised)."""
    T = np.asarray(T, dtype=float)
    Ta = float(air.temperature)
    rad = float(air.emissivity) * SIGMA_SB * ((T + KELVIN) ** 4 - (Ta + KELVIN) ** 4)
    return float(air.h) * (T - Ta) + rad
