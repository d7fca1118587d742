"""Flow-stress laws σ0(ε̄, ε̄̇, T) for the Norton–Hoff form with hardening, rate and temperature.

Units everywhere: σ0 in MPa, ε̄ (cumulated equivalent strain) dimensionless, ε̄̇ (equivalent
strain rate) in 1/s, T in °C. Pure numpy (scipy for the table's reference interpolation); no
dolfinx object.

Each law has its own direct formula, :meth:`FlowStress.sigma0` (the reference), and a
representation for an element kernel, :meth:`FlowStress.pieces`: for a frozen state (ε̄, T) the
rate axis is cut at ``rate_nodes`` into intervals, and on interval j the law is a power law
``σ0 = C[:, j] ε̄̇^m[:, j]``. :func:`norton_hoff_pieces` writes the same pieces as Norton–Hoff
consistencies (THEORY §1.1): with z = √3 ε̄̇ (= √(2 dev ε̇ : dev ε̇) for an incompressible flow),
``σ0 = √3 K z^m`` with ``K = C 3^(−(1+m)/2)``, so the deviatoric stress and its tangent are
those of Norton–Hoff with the piece of the current rate::

    K, m = norton_hoff_pieces(law, strain, temperature)      # (n, nint), once per increment
    j = interval_of(z / sqrt(3), law.rate_nodes)             # at each Newton iterate
    s = 2 K[i, j] z^(m[i, j] − 1) e                          # e = dev ε̇
    ∂s/∂ε̇ = 2 K z^(m − 1) [P_dev + 2 (m − 1)/z² e ⊗ e]

σ0 is continuous across the rate nodes and increasing in the rate, so the dissipation potential
φ(ε̇) = ∫₀^ε̄̇ σ0 dr stays convex; the local rate sensitivity m_loc = ∂ln σ0/∂ln ε̄̇ (> 0 required)
jumps at the nodes, and so does the tangent. Beyond the first interval φ is not the
``K z^(m+1)/(m+1)`` of the current piece (it differs by a constant per interval): a line search on
the energy must integrate σ0 over the rate.
"""

from __future__ import annotations

import abc
import csv
import hashlib
import math
import warnings
from dataclasses import dataclass

import numpy as np
from scipy.interpolate import RegularGridInterpolator

__all__ = ["FlowStress", "HanselSpittel", "PowerHardening", "TabulatedFlowStress",
           "check_temperature", "interval_of", "norton_hoff_pieces"]

SQRT3 = math.sqrt(3.0)
#: °C
ABSOLUTE_ZERO = -273.15
#: °C: a temperature above this was probably given in kelvin
KELVIN_LIKE = 2000.0
#: MPa: a stress above this was probably given in Pa
PA_LIKE = 1.0e5


# -- checks -------------------------------------------------------------------------------------
def _number(name, value, unit):
    """``value`` as a float if it is a finite real number, else a ValueError naming the
    parameter, its value and its unit."""
    if (isinstance(value, (bool, np.bool_))
            or not isinstance(value, (int, float, np.integer, np.floating))
            or not math.isfinite(value)):
        raise ValueError(f"{name} must be a finite number [{unit}], got {value!r}")
    return float(value)


def _positive(name, value, unit):
    v = _number(name, value, unit)
    if v <= 0.0:
        raise ValueError(f"{name} must be > 0 [{unit}], got {value!r}")
    return v


def _non_negative(name, value, unit):
    v = _number(name, value, unit)
    if v < 0.0:
        raise ValueError(f"{name} must be >= 0 [{unit}], got {value!r}")
    return v


def _array(values, what, unit):
    try:
        a = np.asarray(values, dtype=float)
    except (TypeError, ValueError) as err:
        raise ValueError(f"{what} must be numbers [{unit}], got {values!r}") from err
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{what} must be finite [{unit}], got {values!r}")
    return a


def _strain(strain):
    e = _array(strain, "equivalent strain ε̄", "-")
    if np.any(e < 0.0):
        raise ValueError(f"equivalent strain ε̄ must be >= 0 [-], got {e.min():g}")
    return e


def _rate(rate):
    r = _array(rate, "equivalent strain rate ε̄̇", "1/s")
    if np.any(r < 0.0):
        raise ValueError(f"equivalent strain rate ε̄̇ must be >= 0 [1/s], got {r.min():g}")
    return r


def check_temperature(temperature, what="temperature"):
    """``temperature`` [°C] as a float array: finite, not below absolute zero (−273.15 °C: a
    ValueError); a value above 2000 °C gives a UserWarning (kelvin given where °C are
    expected?). ``what`` names the quantity in the messages."""
    if temperature is None:
        raise ValueError(f"{what}: a temperature [°C] is needed (this law depends on it)")
    t = _array(temperature, what, "°C")
    if np.any(t < ABSOLUTE_ZERO):
        raise ValueError(f"{what} {t.min():g} °C is below absolute zero ({ABSOLUTE_ZERO} °C): "
                         "temperatures are expected in °C")
    if np.any(t > KELVIN_LIKE):
        warnings.warn(f"{what} {t.max():g} °C is above {KELVIN_LIKE:g} °C: kelvin given? "
                      "temperatures are expected in °C", UserWarning, stacklevel=3)
    return t


def interval_of(rate, rate_nodes):
    """Index of the rate interval of each equivalent strain rate [1/s] (vectorised): 0 below
    ``rate_nodes[0]``, j for ``rate_nodes[j−1] ≤ rate < rate_nodes[j]``, ``len(rate_nodes)`` from
    the last node on (``np.searchsorted(rate_nodes, rate, side="right")``)."""
    return np.searchsorted(np.asarray(rate_nodes, dtype=float), rate, side="right")


def norton_hoff_pieces(law, strain, temperature=None):
    """The pieces of ``law`` as Norton–Hoff consistencies: ``(K, m)``, arrays of shape
    (n, nint), with ``σ0 = √3 K z^m``, z = √3 ε̄̇, on each rate interval; K [MPa·s^m] =
    C 3^(−(1+m)/2) for the pieces ``(C, m)`` of :meth:`FlowStress.pieces`. The deviatoric stress
    is then ``s = 2 K z^(m−1) dev ε̇`` (THEORY §1.1) with the piece of the current rate
    (:func:`interval_of`). For :class:`PowerHardening` K is computed directly, K0 (ε0 + ε̄)^n:
    with n = 0 it is K0 itself, bit for bit."""
    return law._consistency(strain, temperature)


# -- the base class -----------------------------------------------------------------------------
class FlowStress(abc.ABC):
    """A flow stress σ0(ε̄, ε̄̇, T) [MPa] of the cumulated equivalent strain ε̄ [-], the
    equivalent strain rate ε̄̇ [1/s] and the temperature T [°C].

    Every method accepts scalars or arrays (numpy broadcasting); ``temperature`` may be ``None``
    for a law that does not use it (:attr:`uses_temperature` False), and is then ignored.
    """

    #: whether T enters the law
    uses_temperature = False

    @abc.abstractmethod
    def sigma0(self, strain, rate, temperature=None) -> np.ndarray:
        """σ0 [MPa] by the law's own formula (the reference), broadcast over the arguments."""

    @abc.abstractmethod
    def rate_sensitivity(self, strain, rate, temperature=None) -> np.ndarray:
        """m_loc = ∂ln σ0/∂ln ε̄̇ [-] by the law's own formula, broadcast over the arguments."""

    @abc.abstractmethod
    def pieces(self, strain, temperature=None):
        """``(C, m)``, arrays of shape (n, nint) for the n states (``strain`` 1-D of length n, a
        scalar temperature broadcast): on rate interval j (:func:`interval_of`),
        σ0 = C[:, j] ε̄̇^m[:, j], C in MPa·s^m."""

    @abc.abstractmethod
    def parameters(self) -> dict:
        """The law's parameters, a flat dict name → float or short string (set-up signature)."""

    @property
    def rate_nodes(self) -> np.ndarray:
        """Increasing rate breakpoints [1/s] between the rate intervals (nint − 1 of them);
        empty for a law that is one power law in the rate."""
        return np.empty(0)

    def clamped(self, strain, temperature=None) -> int:
        """How many of the states lie outside the law's data range and were clamped (0 for an
        analytic law)."""
        _strain(strain)
        return 0

    # helpers
    def _states(self, strain, temperature):
        """The states of :meth:`pieces`: 1-D strain, temperature of its length (or None)."""
        e = _strain(strain)
        if e.ndim > 1:
            raise ValueError(f"pieces: strain must be 1-D (n states), got shape {e.shape}")
        e = np.atleast_1d(e)
        if not self.uses_temperature:
            return e, None
        t = check_temperature(temperature)
        try:
            t = np.broadcast_to(t, e.shape)
        except ValueError as err:
            raise ValueError(f"pieces: temperature of shape {t.shape} does not match the "
                             f"{e.size} strain values") from err
        return e, t

    def _consistency(self, strain, temperature):
        C, m = self.pieces(strain, temperature)
        return C * 3.0 ** (-0.5 * (1.0 + m)), m


# -- Norton–Hoff with power hardening -------------------------------------------------------------
@dataclass(frozen=True)
class PowerHardening(FlowStress):
    """Norton–Hoff with power hardening, σ0 = √3 K0 (ε0 + ε̄)^n (√3 ε̄̇)^m [MPa].

    With n = 0 it is :class:`~fxcontact.materials.NortonHoff` of consistency K0 (THEORY §1.1).
    No temperature.

    Args:
        K0: consistency [MPa·s^m], > 0.
        m: strain-rate sensitivity [-], 0 < m ≤ 1.
        n: hardening exponent [-], ≥ 0 (usually < 1).
        eps0: strain offset [-], ≥ 0; > 0 when n > 0 (else σ0 = 0 at ε̄ = 0).
    """

    K0: float
    m: float
    n: float = 0.0
    eps0: float = 0.0

    def __post_init__(self):
        _positive("K0 (consistency)", self.K0, "MPa·s^m")
        m = _number("m (strain-rate sensitivity)", self.m, "-")
        if not 0.0 < m <= 1.0:
            raise ValueError(f"m (strain-rate sensitivity) must be in (0, 1] [-], got {self.m!r}")
        n = _non_negative("n (hardening exponent)", self.n, "-")
        eps0 = _non_negative("eps0 (strain offset)", self.eps0, "-")
        if n > 0.0 and eps0 == 0.0:
            raise ValueError(f"eps0 must be > 0 when n > 0 (n = {self.n!r}): the flow stress "
                             "would be 0 at the start (ε̄ = 0)")

    def _hardening(self, e):
        return (self.eps0 + e) ** self.n

    def sigma0(self, strain, rate, temperature=None):
        e, r = _strain(strain), _rate(rate)
        return SQRT3 * self.K0 * self._hardening(e) * (SQRT3 * r) ** self.m

    def rate_sensitivity(self, strain, rate, temperature=None):
        e, r = _strain(strain), _rate(rate)
        return np.full(np.broadcast(e, r).shape, float(self.m))

    def pieces(self, strain, temperature=None):
        e, _ = self._states(strain, temperature)
        C = SQRT3 * self.K0 * self._hardening(e) * 3.0 ** (0.5 * self.m)
        return C[:, None], np.full((e.size, 1), float(self.m))

    def _consistency(self, strain, temperature):
        e, _ = self._states(strain, temperature)
        return (self.K0 * self._hardening(e))[:, None], np.full((e.size, 1), float(self.m))

    def parameters(self):
        return {"law": type(self).__name__, "K0": float(self.K0), "m": float(self.m),
                "n": float(self.n), "eps0": float(self.eps0)}


# -- Hansel–Spittel -------------------------------------------------------------------------------
_HS_UNITS = {"A": "MPa·s^m_loc", "m1": "1/°C", "m2": "-", "m3": "-", "m4": "-", "m5": "1/°C",
             "m7": "-", "m8": "1/°C", "m9": "-", "strain_floor": "-"}


@dataclass(frozen=True)
class HanselSpittel(FlowStress):
    """Hansel–Spittel flow stress (the nine-parameter form of Forge; it has no m6) [MPa]:

        σ0 = A e^(m1 T) ε̄^m2 ε̄̇^m3 e^(m4/ε̄) (1 + ε̄)^(m5 T) e^(m7 ε̄) ε̄̇^(m8 T) T^m9,

    T in °C, so m_loc = m3 + m8 T, which must be > 0 (convexity of the potential): the methods
    raise a ValueError naming the temperature range where it is not. ε̄ is floored at
    ``strain_floor`` (the ε̄^m2 and e^(m4/ε̄) factors are singular at ε̄ = 0): below it σ0 is
    σ0(strain_floor); such states are not counted by :meth:`clamped`. With m9 ≠ 0 the factor
    T^m9 needs T > 0 °C.

    Args:
        A: [MPa·s^m_loc], > 0.
        m1, m5, m8: [1/°C]. m2, m3, m4, m7, m9: [-]. strain_floor: [-], > 0 (default 1e-3).
    """

    A: float
    m1: float
    m2: float
    m3: float
    m4: float = 0.0
    m5: float = 0.0
    m7: float = 0.0
    m8: float = 0.0
    m9: float = 0.0
    strain_floor: float = 1e-3

    def __post_init__(self):
        for name, unit in _HS_UNITS.items():
            _number(name, getattr(self, name), unit)
        _positive("A", self.A, _HS_UNITS["A"])
        _positive("strain_floor", self.strain_floor, "-")
        if self.m8 == 0 and self.m3 <= 0:
            raise ValueError(f"the rate sensitivity m_loc = m3 + m8·T = m3 = {self.m3!r} must be "
                             "> 0 (convexity of the potential), at every temperature since "
                             "m8 = 0 [1/°C]")
        drop = math.exp(self.m4 / self.strain_floor - self.m4 / 0.1)   # e^(m4/ε̄): floor vs 0.1
        if drop < 0.1:
            warnings.warn(f"HanselSpittel: with m4 = {self.m4!r} the factor e^(m4/ε̄) at the "
                          f"strain floor {self.strain_floor:g} is {drop:.2g} × its value at "
                          f"ε̄ = 0.1: an undeformed body (ε̄ = 0) is then nearly without "
                          f"strength and the first increments may fail — raise strain_floor "
                          f"(e.g. to {max(-self.m4 / 2.3, self.strain_floor):.3g}) or fit m4 "
                          f"on the strains you form at", UserWarning, stacklevel=3)

    @property
    def uses_temperature(self):
        return any(getattr(self, k) != 0 for k in ("m1", "m5", "m8", "m9"))

    def _temperature(self, temperature):
        """T [°C] checked for this law (or 0 if the law does not use it)."""
        if not self.uses_temperature:
            return np.zeros(())
        t = check_temperature(temperature)
        if self.m9 != 0 and np.any(t <= 0.0):
            raise ValueError(f"T^m9 with m9 = {self.m9!r} needs T > 0 °C, got "
                             f"T = {t.min():g} °C")
        mloc = self.m3 + self.m8 * t
        if np.any(mloc <= 0.0):
            tstar = -self.m3 / self.m8
            where = f"T <= {tstar:g} °C" if self.m8 > 0 else f"T >= {tstar:g} °C"
            raise ValueError(f"the rate sensitivity m_loc = m3 + m8·T is <= 0 for {where} "
                             f"(m3 = {self.m3!r}, m8 = {self.m8!r} 1/°C), requested down to "
                             f"m_loc = {mloc.min():g}: it must be > 0 (convexity of the "
                             "potential)")
        return t

    def _state_factor(self, e, t):
        """Every factor but the rate's: A e^(m1 T) ε̄^m2 e^(m4/ε̄) (1+ε̄)^(m5 T) e^(m7 ε̄) T^m9."""
        ef = np.maximum(e, self.strain_floor)
        f = (self.A * np.exp(self.m1 * t) * ef ** self.m2 * np.exp(self.m4 / ef)
             * (1.0 + ef) ** (self.m5 * t) * np.exp(self.m7 * ef))
        return f * t ** self.m9 if self.m9 != 0 else f

    def sigma0(self, strain, rate, temperature=None):
        e, r = _strain(strain), _rate(rate)
        t = self._temperature(temperature)
        ef = np.maximum(e, self.strain_floor)
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            s = (self.A * np.exp(self.m1 * t) * ef ** self.m2 * r ** self.m3
                 * np.exp(self.m4 / ef) * (1.0 + ef) ** (self.m5 * t) * np.exp(self.m7 * ef)
                 * r ** (self.m8 * t))
            if self.m9 != 0:
                s = s * t ** self.m9
        return np.where(r > 0.0, s, 0.0)     # m_loc > 0: σ0 → 0 with the rate

    def rate_sensitivity(self, strain, rate, temperature=None):
        e, r = _strain(strain), _rate(rate)
        t = self._temperature(temperature)
        return np.broadcast_to(self.m3 + self.m8 * t, np.broadcast(e, r, t).shape).copy()

    def pieces(self, strain, temperature=None):
        e, t = self._states(strain, temperature)
        t = self._temperature(t)
        C = np.broadcast_to(self._state_factor(e, t), e.shape)
        m = np.broadcast_to(self.m3 + self.m8 * t, e.shape)
        return C[:, None].copy(), m[:, None].copy()

    def parameters(self):
        return {"law": type(self).__name__,
                **{name: float(getattr(self, name)) for name in _HS_UNITS}}


# -- tabulated ------------------------------------------------------------------------------------
def _axis(values, name, unit):
    a = _array(values, name, unit)
    if a.ndim != 1 or a.size == 0:
        raise ValueError(f"{name} must be a non-empty 1-D array [{unit}], got shape {a.shape}")
    if np.any(np.diff(a) <= 0.0):
        raise ValueError(f"{name} must be strictly increasing [{unit}], got {a.tolist()}")
    return a


def _bracket(axis, x):
    """Lower index and weight of linear interpolation on ``axis`` at ``x`` (inside it)."""
    if axis.size == 1:
        i = np.zeros(x.shape, dtype=int)
        return i, i, np.zeros(x.shape)
    i = np.clip(np.searchsorted(axis, x, side="right") - 1, 0, axis.size - 2)
    return i, i + 1, (x - axis[i]) / (axis[i + 1] - axis[i])


@dataclass(frozen=True, eq=False)
class TabulatedFlowStress(FlowStress):
    """σ0 tabulated point by point on a grid ``stress[i, j, k]`` = σ0(strains[i], rates[j],
    temperatures[k]) [MPa] (ε̄ [-], ε̄̇ [1/s], T [°C]); :meth:`from_csv` reads a long-format CSV.

    Interpolation: linear in ε̄ and in T (bilinear, of σ0 at each tabulated rate), and ln σ0
    linear in ln ε̄̇ between the rates, so m_loc is constant on each of the len(rates) − 1 rate
    intervals (:attr:`rate_nodes` = ``rates[1:-1]``), m_j = ln(σ_{j+1}/σ_j)/ln(r_{j+1}/r_j).

    Outside the table ε̄ and T are clamped to its range (:meth:`clamped` counts the states; an
    axis with a single value — no hardening, or no temperature dependence: ``uses_temperature``
    False — is a constant, not a clamp). In the rate, the first and last power laws are
    extended instead: clamping σ0 in the rate would make m_loc = 0 and the potential not
    strictly convex.

    Requirements (ValueError otherwise): axes strictly increasing, at least 2 rates, all
    > 0; σ0 finite, > 0, in MPa (a value above 1e5 looks like Pa), strictly increasing in the
    rate at every (ε̄, T) of the grid (m_loc > 0); T not below −273.15 °C (above 2000 °C: a
    warning, kelvin?).
    """

    strains: np.ndarray
    rates: np.ndarray
    temperatures: np.ndarray
    stress: np.ndarray

    def __post_init__(self):
        e = _axis(self.strains, "strains", "-")
        if e[0] < 0.0:
            raise ValueError(f"strains must be >= 0 [-], got {e[0]:g}")
        r = _axis(self.rates, "rates", "1/s")
        if r.size < 2:
            raise ValueError(f"at least 2 rates [1/s] are needed (m_loc = ∂ln σ0/∂ln ε̄̇ comes "
                             f"from them), got {r.tolist()}")
        if r[0] <= 0.0:
            raise ValueError(f"rates must be > 0 [1/s] (interpolated in ln ε̄̇), got {r[0]:g}")
        t = _axis(self.temperatures, "temperatures", "°C")
        check_temperature(t, "table temperature")
        s = _array(self.stress, "stress", "MPa")
        shape = (e.size, r.size, t.size)
        if s.shape != shape:
            raise ValueError(f"stress must have the shape (len(strains), len(rates), "
                             f"len(temperatures)) = {shape}, got {s.shape}")
        if s.max() > PA_LIKE:
            raise ValueError(f"stress up to {s.max():g} looks like Pa: flow stresses are "
                             f"expected in MPa (< {PA_LIKE:g})")
        if s.min() <= 0.0:
            i, j, k = np.unravel_index(np.argmin(s), shape)
            raise ValueError(f"stress must be > 0 [MPa]: {s[i, j, k]:g} MPa at ε̄ = {e[i]:g}, "
                             f"ε̄̇ = {r[j]:g} 1/s, T = {t[k]:g} °C")
        bad = np.argwhere(np.diff(s, axis=1) <= 0.0)
        if bad.size:
            i, j, k = bad[0]
            raise ValueError(f"stress must increase strictly with the rate (m_loc > 0): at "
                             f"ε̄ = {e[i]:g}, T = {t[k]:g} °C, σ0 = {s[i, j, k]:g} MPa at "
                             f"ε̄̇ = {r[j]:g} 1/s and {s[i, j + 1, k]:g} MPa at {r[j + 1]:g} 1/s "
                             f"({len(bad)} such pair(s))")
        for name, a in (("strains", e), ("rates", r), ("temperatures", t), ("stress", s)):
            a = a.copy()
            a.setflags(write=False)
            object.__setattr__(self, name, a)
        object.__setattr__(self, "_ln_rates", np.log(r))

    @classmethod
    def from_csv(cls, path) -> TabulatedFlowStress:
        """A table read from a long-format CSV: a header ``strain,strain_rate,temperature,
        stress`` (columns in any order, no other column; ε̄ [-], ε̄̇ [1/s], T [°C], σ0 [MPa]), one
        grid point a line, ``#`` lines are comments. Every (ε̄, ε̄̇, T) combination of the values
        found must be given exactly once."""
        with open(path, newline="", encoding="utf-8") as f:
            lines = [(k, line) for k, line in enumerate(f, 1)
                     if line.strip() and not line.lstrip().startswith("#")]
        if not lines:
            raise ValueError(f"{path}: empty, no header strain,strain_rate,temperature,stress")
        required = ("strain", "strain_rate", "temperature", "stress")
        header = [h.strip() for h in next(csv.reader([lines[0][1]]))]
        extra = [h for h in header if h not in required]
        missing = [h for h in required if h not in header]
        if extra or missing or len(header) != len(set(header)):
            raise ValueError(f"{path}: the header must have the columns {', '.join(required)} "
                             f"once each and no other: extra column(s) {extra}, missing "
                             f"{missing}, got {header}")
        cols = [header.index(name) for name in required]
        rows, where = [], []
        for k, line in lines[1:]:
            fields = next(csv.reader([line]))
            try:
                if len(fields) != len(header):
                    raise ValueError
                vals = [float(fields[c]) for c in cols]
            except ValueError:
                raise ValueError(f"{path}, line {k}: expected {len(header)} numbers, got "
                                 f"{line.strip()!r}") from None
            if not all(math.isfinite(v) for v in vals):
                raise ValueError(f"{path}, line {k}: non-finite value in {line.strip()!r}")
            rows.append(vals)
            where.append(k)
        if not rows:
            raise ValueError(f"{path}: no data line")
        data = np.array(rows)
        axes = [np.unique(data[:, c]) for c in range(3)]
        shape = tuple(a.size for a in axes)
        idx = tuple(np.searchsorted(a, data[:, c]) for c, a in enumerate(axes))
        flat = np.ravel_multi_index(idx, shape)
        counts = np.bincount(flat, minlength=int(np.prod(shape)))

        def point(f):
            i, j, k = np.unravel_index(f, shape)
            return f"(ε̄ = {axes[0][i]:g}, ε̄̇ = {axes[1][j]:g} 1/s, T = {axes[2][k]:g} °C)"

        dup = np.flatnonzero(counts > 1)
        if dup.size:
            lines_dup = [where[q] for q in np.flatnonzero(flat == dup[0])]
            raise ValueError(f"{path}: duplicate point {point(dup[0])} on lines {lines_dup} "
                             f"({dup.size} duplicated point(s))")
        holes = np.flatnonzero(counts == 0)
        if holes.size:
            raise ValueError(f"{path}: the grid has holes, {holes.size} missing point(s) of "
                             f"{counts.size}: {', '.join(point(h) for h in holes[:5])}"
                             + (", ..." if holes.size > 5 else ""))
        stress = np.empty(shape)
        stress.flat[flat] = data[:, 3]
        try:
            return cls(*axes, stress)
        except ValueError as err:
            raise ValueError(f"{path}: {err}") from err

    # -- properties ----------------------------------------------------------------------------
    @property
    def uses_temperature(self):
        return self.temperatures.size > 1

    @property
    def rate_nodes(self):
        return self.rates[1:-1].copy()

    def _clamp(self, e, t):
        e = np.clip(e, self.strains[0], self.strains[-1])
        t = (np.clip(t, self.temperatures[0], self.temperatures[-1]) if self.uses_temperature
             else np.full(e.shape, self.temperatures[0]))
        return e, t

    def clamped(self, strain, temperature=None):
        e, t = self._states(strain, temperature)
        out = np.zeros(e.shape, dtype=bool)
        if self.strains.size > 1:
            out |= (e < self.strains[0]) | (e > self.strains[-1])
        if t is not None:
            out |= (t < self.temperatures[0]) | (t > self.temperatures[-1])
        return int(np.count_nonzero(out))

    # -- pieces (hand-written bilinear interpolation) --------------------------------------------
    def pieces(self, strain, temperature=None):
        e, t = self._clamp(*self._states(strain, temperature))
        i0, i1, we = _bracket(self.strains, e)
        k0, k1, wt = _bracket(self.temperatures, t)
        s = self.stress
        we, wt = we[:, None], wt[:, None]
        S = ((1.0 - we) * (1.0 - wt) * s[i0, :, k0] + we * (1.0 - wt) * s[i1, :, k0]
             + (1.0 - we) * wt * s[i0, :, k1] + we * wt * s[i1, :, k1])       # (n, len(rates))
        m = np.log(S[:, 1:] / S[:, :-1]) / np.diff(self._ln_rates)
        C = S[:, :-1] * self.rates[:-1] ** (-m)
        return C, m

    # -- reference (scipy over (ε̄, T), then log-linear in the rate) --------------------------------
    def _columns(self, strain, rate, temperature):
        """σ0 at every tabulated rate for the broadcast states, (N, len(rates)), and the
        flattened rates and broadcast shape."""
        e, r = _strain(strain), _rate(rate)
        t = check_temperature(temperature) if self.uses_temperature else np.zeros(())
        shape = np.broadcast(e, r, t).shape
        e, r, t = (np.broadcast_to(a, shape).ravel() for a in (e, r, t))
        e, t = self._clamp(e, t)
        grid = [(a, x) for a, x in ((self.strains, e), (self.temperatures, t)) if a.size > 1]
        values = np.moveaxis(self.stress, 1, -1)[
            tuple(slice(None) if a.size > 1 else 0 for a in (self.strains, self.temperatures))]
        if grid:
            interp = RegularGridInterpolator(tuple(a for a, _ in grid), values)
            S = interp(np.stack([x for _, x in grid], axis=-1))
        else:
            S = np.broadcast_to(values, (e.size, self.rates.size))
        return S, r, shape

    def _log_slopes(self, S, r):
        lr = self._ln_rates
        with np.errstate(divide="ignore"):
            x = np.log(r)
        j = np.clip(np.searchsorted(lr, x, side="right") - 1, 0, lr.size - 2)
        rows = np.arange(S.shape[0])
        lo, hi = np.log(S[rows, j]), np.log(S[rows, j + 1])
        return lo, (hi - lo) / (lr[j + 1] - lr[j]), x - lr[j]

    def sigma0(self, strain, rate, temperature=None):
        S, r, shape = self._columns(strain, rate, temperature)
        lo, slope, dx = self._log_slopes(S, r)
        with np.errstate(invalid="ignore"):
            return np.exp(lo + slope * dx).reshape(shape)

    def rate_sensitivity(self, strain, rate, temperature=None):
        S, r, shape = self._columns(strain, rate, temperature)
        return self._log_slopes(S, r)[1].reshape(shape)

    def parameters(self):
        digest = hashlib.sha256()
        for a in (self.strains, self.rates, self.temperatures, self.stress):
            digest.update(np.ascontiguousarray(a, dtype="<f8").tobytes())
        return {"law": type(self).__name__, "shape": "x".join(map(str, self.stress.shape)),
                "strain_min": float(self.strains[0]), "strain_max": float(self.strains[-1]),
                "rate_min": float(self.rates[0]), "rate_max": float(self.rates[-1]),
                "temperature_min": float(self.temperatures[0]),
                "temperature_max": float(self.temperatures[-1]),
                "stress_sha256": digest.hexdigest()[:16]}
