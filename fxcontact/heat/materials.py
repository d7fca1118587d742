"""Thermal data of the workpiece and of its free surface, in the units of fxcontact (N, mm, s,
°C; THEORY §16.2).

=====================  ======================  ============================  ==================
quantity               unit                    equals                        steel
=====================  ======================  ============================  ==================
ρc (capacity)          N/(mm² K)               MJ/(m³ K)                     3.9
k (conductivity)       N/(s K)                 W/(m K)                       30
h (film coefficient)   N/(mm s K)              kW/(m² K)                     air 0.01, die 5–20
σ_SB                   N/(mm s K⁴)             10⁻³ W/(m² K⁴)                5.670e-11
heat flow              N mm/s                  mW
source q               N/(mm² s)               W/mm³
=====================  ======================  ============================  ==================

The unit checks catch values given in SI units (J/(m³ K) for ρc, W/(m² K) for h): a value far
outside what any workpiece or surface has raises a ValueError, a value outside the usual range
of forming gives a UserWarning naming the expected unit. The thresholds are the module
constants below.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from typing import Callable, Union

import numpy as np

__all__ = ["AIR_H_WARN", "CONDUCTIVITY_MAX", "CONDUCTIVITY_RANGE", "CONTACT_H_WARN",
           "HOT_CELSIUS", "H_MAX", "KELVIN", "RHO_C_MAX", "RHO_C_RANGE", "SIGMA_SB", "AirExchange",
           "ThermalMaterial", "check_temperature", "film_coefficient"]

#: Stefan–Boltzmann constant in N/(mm s K⁴): 5.670374419e-8 W/(m² K⁴) × 10⁻³
SIGMA_SB = 5.670374419e-11
#: 0 °C in kelvin
KELVIN = 273.15
#: ρc outside this range (N/(mm² K)) gives a warning: solid metals are 2–4, polymers about 1.5–2
RHO_C_RANGE = (0.1, 20.0)
#: ρc above this is refused: it is in J/(m³ K) or kJ/(m³ K) (steel 3.9e6 J/(m³ K))
RHO_C_MAX = 1000.0
#: k outside this range (N/(s K) = W/(m K)) gives a warning: insulators 0.04, copper 400
CONDUCTIVITY_RANGE = (0.01, 1000.0)
#: k above this is refused (no material conducts more than about 2000 W/(m K))
CONDUCTIVITY_MAX = 1.0e4
#: an air film coefficient above this (N/(mm s K) = kW/(m² K)) gives a warning: natural and
#: forced convection in air are 0.005–0.2; more is a spray or a quench, or W/(m² K) given
AIR_H_WARN = 1.0
#: a contact coefficient above this gives a warning: a die in good contact is 5–20
CONTACT_H_WARN = 1000.0
#: any film coefficient above this is refused: it is in W/(m² K)
H_MAX = 1.0e5
#: a temperature above this (°C) gives a warning: a temperature in kelvin?
HOT_CELSIUS = 2000.0

_RHO_C_UNIT = "ρc is in N/(mm² K) = MJ/(m³ K): steel ≈ 3.9, aluminium ≈ 2.4"
_K_UNIT = "k is in N/(s K) = W/(m K): steel ≈ 30, aluminium ≈ 200"
_H_UNIT = ("h is in N/(mm s K) = kW/(m² K): still air ≈ 0.01, a die in good contact 5–20 "
           "(a value in W/(m² K) is 1000 times too large)")

Value = Union[float, Callable[[np.ndarray], np.ndarray]]


def _finite_positive(name: str, value, unit: str) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a number or a callable of the temperature, got "
                         f"{value!r}") from None
    if not math.isfinite(v) or v <= 0:
        raise ValueError(f"{name} must be finite and > 0, got {v!r} ({unit})")
    return v


def _check_magnitude(name: str, values: np.ndarray, lo: float, hi: float, top: float,
                     unit: str):
    """ValueError above ``top``; warning outside [lo, hi]."""
    vmin, vmax = float(np.min(values)), float(np.max(values))
    if vmax > top:
        raise ValueError(f"{name} = {vmax:g} is far too large for mm-N-s units (above {top:g}): "
                         f"{unit}")
    if vmin < lo or vmax > hi:
        bad = vmin if vmin < lo else vmax
        warnings.warn(f"{name} = {bad:g} is outside the usual range [{lo:g}, {hi:g}] of "
                      f"forming: {unit}", UserWarning, stacklevel=4)


def _values(name: str, value: Value, T: np.ndarray, unit: str) -> np.ndarray:
    """``value`` at the temperatures ``T`` (°C): an array of T's shape, checked finite and > 0."""
    T = np.asarray(T, dtype=float)
    if callable(value):
        out = np.asarray(value(T), dtype=float)
        if out.shape != T.shape:
            out = np.broadcast_to(out, T.shape) if out.ndim == 0 else out
        if out.shape != T.shape:
            raise ValueError(f"{name}(T) must return one value per temperature: got shape "
                             f"{out.shape} for {T.shape}")
        bad = ~np.isfinite(out) | (out <= 0)
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            raise ValueError(f"{name}(T) must be finite and > 0: {name}({T[i]:g} °C) = "
                             f"{out[i]!r} ({int(bad.sum())} bad value(s); {unit})")
        return out
    return np.full(T.shape, float(value))


def check_temperature(name: str, T) -> np.ndarray:
    """``T`` (°C) as a float array: ValueError if NaN or below absolute zero, UserWarning (which
    names the largest value) above :data:`HOT_CELSIUS` (kelvin given?). Local."""
    a = np.asarray(T, dtype=float)
    if a.size == 0:
        return a
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{name} must be finite (°C), got {int((~np.isfinite(a)).sum())} NaN or "
                         f"infinite value(s)")
    if a.min() < -KELVIN:
        raise ValueError(f"{name} = {a.min():g} °C is below absolute zero (−273.15 °C): "
                         f"temperatures are in °C")
    if a.max() > HOT_CELSIUS:
        warnings.warn(f"{name} = {a.max():g} °C is above {HOT_CELSIUS:g} °C: temperatures are in "
                      f"°C (given in kelvin? subtract 273.15)", UserWarning, stacklevel=3)
    return a


def film_coefficient(name: str, h, warn_above: float) -> np.ndarray:
    """A film coefficient (scalar or array, N/(mm s K)) checked: finite and ≥ 0, refused above
    :data:`H_MAX`, a warning above ``warn_above``. Local."""
    a = np.asarray(h, dtype=float)
    if a.size == 0:
        return a
    if not np.all(np.isfinite(a)) or a.min() < 0:
        raise ValueError(f"{name} must be finite and ≥ 0 (N/(mm s K)), got "
                         f"{a.min() if np.all(np.isfinite(a)) else 'NaN'}")
    if a.max() > H_MAX:
        raise ValueError(f"{name} = {a.max():g} is far too large for mm-N-s units: {_H_UNIT}")
    if a.max() > warn_above:
        warnings.warn(f"{name} = {a.max():g} N/(mm s K) = {a.max():g} kW/(m² K) is large: "
                      f"{_H_UNIT}", UserWarning, stacklevel=3)
    return a


@dataclass(frozen=True)
class ThermalMaterial:
    """Heat capacity and conductivity of the workpiece (THEORY §16.1).

    Args:
        rho_c: volumetric heat capacity ρc in N/(mm² K) = MJ/(m³ K) (steel 3.9): a number or a
            callable ``f(T) -> array`` of the temperature in °C (an array of the nodal
            temperatures).
        conductivity: k in N/(s K) = W/(m K) (steel 30): a number or a callable of T.
        taylor_quinney: η_q in [0, 1], the fraction of the plastic power turned into heat (the
            caller multiplies σ:ε̇ by it to make the source of :meth:`HeatProblem.step`).

    A temperature-dependent ρc or k is evaluated at the nodal temperatures at the start of each
    step (Tⁿ), so a step stays one linear solve; halve dt to check the lag.

    Unit checks (values in SI units are the usual mistake): ρc above :data:`RHO_C_MAX` or k
    above :data:`CONDUCTIVITY_MAX` raise a ValueError, ρc outside :data:`RHO_C_RANGE` and k
    outside :data:`CONDUCTIVITY_RANGE` give a UserWarning, both naming the expected unit. The
    values of a callable are checked (finite, > 0, magnitude) where it is evaluated.
    """

    rho_c: Value
    conductivity: Value
    taylor_quinney: float = 0.9

    def __post_init__(self):
        if not callable(self.rho_c):
            v = _finite_positive("rho_c", self.rho_c, _RHO_C_UNIT)
            _check_magnitude("rho_c", np.array([v]), *RHO_C_RANGE, RHO_C_MAX, _RHO_C_UNIT)
        if not callable(self.conductivity):
            v = _finite_positive("conductivity", self.conductivity, _K_UNIT)
            _check_magnitude("conductivity", np.array([v]), *CONDUCTIVITY_RANGE,
                             CONDUCTIVITY_MAX, _K_UNIT)
        eta = self.taylor_quinney
        try:
            eta = float(eta)
        except (TypeError, ValueError):
            raise ValueError(f"taylor_quinney must be a number in [0, 1], got {eta!r}") from None
        if not (0.0 <= eta <= 1.0):
            raise ValueError(f"taylor_quinney (η_q, the fraction of the plastic power turned "
                             f"into heat) must be in [0, 1], got {eta!r}")

    @property
    def temperature_dependent(self) -> bool:
        """True if ρc or k is a callable of the temperature."""
        return callable(self.rho_c) or callable(self.conductivity)

    def rho_c_at(self, T) -> np.ndarray:
        """ρc at the temperatures ``T`` (°C), checked (finite, > 0, magnitude)."""
        out = _values("rho_c", self.rho_c, T, _RHO_C_UNIT)
        if callable(self.rho_c) and out.size:
            _check_magnitude("rho_c(T)", out, *RHO_C_RANGE, RHO_C_MAX, _RHO_C_UNIT)
        return out

    def conductivity_at(self, T) -> np.ndarray:
        """k at the temperatures ``T`` (°C), checked (finite, > 0, magnitude)."""
        out = _values("conductivity", self.conductivity, T, _K_UNIT)
        if callable(self.conductivity) and out.size:
            _check_magnitude("conductivity(T)", out, *CONDUCTIVITY_RANGE, CONDUCTIVITY_MAX,
                             _K_UNIT)
        return out

    def _constant(self, what: str):
        if self.temperature_dependent:
            raise ValueError(f"{what} of a temperature-dependent material: use "
                             f"{what}_at(T) with the temperature in °C")

    @property
    def effusivity(self) -> float:
        """b = √(k ρc) in N/(mm s^½ K) (constant properties; else :meth:`effusivity_at`)."""
        self._constant("effusivity")
        return math.sqrt(float(self.conductivity) * float(self.rho_c))

    def effusivity_at(self, T) -> np.ndarray:
        """b = √(k ρc) at the temperatures ``T`` (°C)."""
        return np.sqrt(self.conductivity_at(T) * self.rho_c_at(T))

    @property
    def diffusivity(self) -> float:
        """a = k/ρc in mm²/s (constant properties; else :meth:`diffusivity_at`)."""
        self._constant("diffusivity")
        return float(self.conductivity) / float(self.rho_c)

    def diffusivity_at(self, T) -> np.ndarray:
        """a = k/ρc at the temperatures ``T`` (°C), mm²/s."""
        return self.conductivity_at(T) / self.rho_c_at(T)

    def heat_share(self, tool) -> float:
        """The workpiece's share β_f = b_w/(b_w + b_t) of the friction power (THEORY §16.1):
        ``tool`` is the tool's :class:`ThermalMaterial` or its effusivity b_t (constant
        properties)."""
        bt = tool.effusivity if isinstance(tool, ThermalMaterial) else float(tool)
        if not math.isfinite(bt) or bt < 0:
            raise ValueError(f"the tool's effusivity must be finite and ≥ 0, got {bt!r}")
        bw = self.effusivity
        return bw / (bw + bt)


@dataclass(frozen=True)
class AirExchange:
    """Heat exchange of a free surface with its surroundings (THEORY §16.1, §16.3):
    q = h (T − T_a) + ε σ_SB (T_K⁴ − T_a,K⁴) leaving the body.

    Args:
        h: film coefficient in N/(mm s K) = kW/(m² K) (still air ≈ 0.01; ≥ 0). Above
            :data:`AIR_H_WARN` a UserWarning (W/(m² K) given?), above :data:`H_MAX` a
            ValueError.
        temperature: T_a, the ambient (and radiation sink) temperature in °C.
        emissivity: ε_r in [0, 1] (0: no radiation). The radiation is linearised about the
            start-of-step temperature Tⁿ in kelvin: h_r = ε σ_SB (T_K² + T_a,K²)(T_K + T_a,K).
    """

    h: float
    temperature: float
    emissivity: float = 0.0

    def __post_init__(self):
        for name in ("h", "temperature", "emissivity"):
            v = getattr(self, name)
            if callable(v) or np.ndim(v) != 0:
                raise ValueError(f"AirExchange.{name} must be a number, got {v!r}")
        film_coefficient("AirExchange h", self.h, AIR_H_WARN)
        check_temperature("AirExchange temperature", self.temperature)
        e = float(self.emissivity)
        if not (0.0 <= e <= 1.0):
            raise ValueError(f"AirExchange emissivity must be in [0, 1], got {self.emissivity!r}")

    def radiation_coefficient(self, T) -> np.ndarray:
        """h_r (N/(mm s K)) at the surface temperatures ``T`` (°C), linearised about them."""
        TK = np.asarray(T, dtype=float) + KELVIN
        TaK = float(self.temperature) + KELVIN
        return float(self.emissivity) * SIGMA_SB * (TK * TK + TaK * TaK) * (TK + TaK)
