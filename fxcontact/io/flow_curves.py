"""A picture of a flow-stress law (:mod:`fxcontact.materials.flow`): σ0 against ε̄ for several
strain rates and temperatures."""

from __future__ import annotations

import math

import numpy as np

from fxcontact.io.series import figure
from fxcontact.materials.flow import FlowStress, HanselSpittel, TabulatedFlowStress

__all__ = ["plot_flow_curves"]

#: the rates drawn for an analytic law [1/s]
DEFAULT_RATES = (0.01, 0.1, 1.0, 10.0)
_STYLES = ("-", "--", "-.", ":", (0, (6, 1.5)), (0, (3, 1, 1, 1, 1, 1)))


def _colours(n):
    from matplotlib import colormaps
    cmap = colormaps["viridis"]
    return [cmap(0.85 * i / max(n - 1, 1)) for i in range(n)]


def plot_flow_curves(law: FlowStress, path: str, strain_max: float = 1.0, rates=None,
                     temperatures=None):
    """Draw σ0 [MPa] against ε̄ ∈ [0, ``strain_max``] to the PNG ``path``: one colour per rate
    ``rates`` [1/s], one line style per temperature ``temperatures`` [°C] (at most 6).

    Defaults: a table's own rates and temperatures; 0.01, 0.1, 1, 10 1/s for an analytic law.
    A law that uses the temperature and is not a table needs ``temperatures`` (ValueError
    otherwise). The strain ranges where a table is clamped are shaded, the rates where its end
    power laws are extended and the temperatures where it is clamped are marked in the legend;
    the strains below a Hansel–Spittel floor are shaded when the floor shows. Not collective:
    draw on the rank that writes (rank 0)."""
    if not isinstance(law, FlowStress):
        raise TypeError(f"law must be a FlowStress, got {type(law).__name__}")
    if not (isinstance(strain_max, (int, float)) and math.isfinite(strain_max)
            and strain_max > 0):
        raise ValueError(f"strain_max must be a finite number > 0 [-], got {strain_max!r}")
    table = law if isinstance(law, TabulatedFlowStress) else None
    if rates is None:
        rates = table.rates if table is not None else DEFAULT_RATES
    rates = np.atleast_1d(np.asarray(rates, dtype=float))
    if rates.size == 0 or not np.all(np.isfinite(rates) & (rates > 0)):
        raise ValueError(f"rates must be finite numbers > 0 [1/s], got {rates.tolist()}")
    if not law.uses_temperature:
        temps = [table.temperatures[0] if table is not None else None]
    elif temperatures is not None:
        temps = list(np.atleast_1d(np.asarray(temperatures, dtype=float)))
    elif table is not None:
        temps = list(table.temperatures)
    else:
        raise ValueError(f"{type(law).__name__} depends on the temperature: give the "
                         "temperatures [°C] of the curves (temperatures=[...])")
    if len(temps) > len(_STYLES):
        raise ValueError(f"at most {len(_STYLES)} temperatures in one picture, got {len(temps)}")

    strains = np.linspace(0.0, strain_max, 301)
    if table is not None:
        strains = np.union1d(strains, table.strains[table.strains <= strain_max])
    colours = _colours(rates.size)
    with figure(path, figsize=(8.5, 4.8)) as (_fig, ax):
        shaded = _shade(ax, law, strain_max)
        for k, t in enumerate(temps):
            for c, r in zip(colours, rates):
                ax.plot(strains, law.sigma0(strains, r, t), color=c, ls=_STYLES[k], lw=1.6)
        ax.set_xlim(0.0, strain_max)
        ax.set_ylim(bottom=0.0)
        ax.grid(alpha=0.3)
        ax.set_xlabel("equivalent strain ε̄ [-]")
        ax.set_ylabel("flow stress σ₀ [MPa]")
        title = f"{type(law).__name__}: flow curves"
        if table is not None and not law.uses_temperature:
            title += f" (table at T = {temps[0]:g} °C only)"
        ax.set_title(title)
        _legends(ax, law, table, rates, temps, colours, shaded)


def _shade(ax, law, strain_max):
    """Shade the strains where the law is clamped or floored; the patches, for the legend."""
    spans, label = [], ""
    if isinstance(law, TabulatedFlowStress) and law.strains.size > 1:
        lo, hi = law.strains[0], law.strains[-1]
        if lo > 0.0:
            spans.append((0.0, min(lo, strain_max)))
        if hi < strain_max:
            spans.append((hi, strain_max))
        label = "ε̄ outside the\ntable: σ₀ clamped"
    elif isinstance(law, HanselSpittel) and law.strain_floor > 0.005 * strain_max:
        spans.append((0.0, min(law.strain_floor, strain_max)))
        label = "ε̄ below the floor:\nσ₀ floored"
    patches = [ax.axvspan(a, b, color="0.6", alpha=0.25, lw=0,
                          label=label if i == 0 else None) for i, (a, b) in enumerate(spans)]
    return patches[:1]


def _legends(ax, law, table, rates, temps, colours, shaded):
    from matplotlib.lines import Line2D
    out = []
    if table is not None:
        out = [r < table.rates[0] or r > table.rates[-1] for r in rates]
    handles = [Line2D([], [], color=c, lw=2,
                      label=f"{r:g}" + (" (extended)" if out and out[i] else ""))
               for i, (c, r) in enumerate(zip(colours, rates))]
    first = ax.legend(handles=handles + shaded, title=r"$\dot{\bar\varepsilon}$ [1/s]",
                      loc="upper left", bbox_to_anchor=(1.02, 1.0),
                      ncol=2 if len(handles) > 10 else 1, fontsize="small", borderaxespad=0.0)
    if law.uses_temperature:
        ax.add_artist(first)
        first.set_clip_on(False)    # else left out of the figure's tight layout
        lo, hi = (table.temperatures[0], table.temperatures[-1]) if table is not None else (
            -math.inf, math.inf)
        styles = [Line2D([], [], color="k", ls=_STYLES[k], lw=1.6,
                         label=f"{t:g}" + (" (clamped)" if t < lo or t > hi else ""))
                  for k, t in enumerate(temps)]
        ax.legend(handles=styles, title="T [°C]", loc="lower left", bbox_to_anchor=(1.02, 0.0),
                  fontsize="small", borderaxespad=0.0)
