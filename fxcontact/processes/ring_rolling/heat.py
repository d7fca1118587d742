"""The heat of a hot ring rolled (THEORY §16, §14.4): the run's heat balance and the estimate of
the ring's mean temperature change it is compared with.

**The estimate** (per revolution of the whole ring, its initial geometry, at the initial
temperature T₀): the wall thins by Δh (the feed per revolution) in plane strain, so the plastic
work is W = Q σ₀ ε̄_rev V with ε̄_rev = (2/√3) ln(B/(B − Δh)), σ₀ the flow stress at the bite
and Q the 2kHLQ factor (the mean pressure over 2k: the work of a bite that deforms the wall
unevenly, THEORY §14.4); η_q W of it is heat. Each point of the outer surface meets the main
roll once per revolution for L/v (v the main roll's surface speed), each point of the bore the
mandrel for L/(v r/R); between two contacts its surface temperature recovers (the ring turns
in t_rev ≫ L/v), so each contact takes the heat of a semi-infinite body at T₀ through the
tool's h_c (:func:`fxcontact.theory.heat_loss.contact_heat`). The free surface (outer, bore,
both faces) loses h (T₀ − T_a) + ε σ (T₀⁴ − T_a⁴) for t_rev. ΔT per revolution = (η_q W −
Q_main − Q_mandrel − Q_air)/(ρc V). Left out: friction heat (the simulation reports it), the
guide rolls (a clearance, light contact) and the change of geometry and temperature over the
run (first order in the number of revolutions).
"""

from __future__ import annotations

import math
from typing import List

import numpy as np

from fxcontact.theory.heat_loss import air_flux, contact_heat

__all__ = ["estimate", "summary", "report_lines"]

#: the history's heat terms summed by :func:`summary` (N mm per increment, half model)
TERMS = ("stored", "generated", "friction", "tools", "air", "radiation", "residual")


def estimate(case, th: dict) -> dict:
    """The heat of one revolution of the whole ring [N mm] (module docstring) and the mean
    temperature change per revolution ``dT_per_rev`` [K]; ``th`` is the pass's theory
    (:func:`~fxcontact.processes.ring_rolling.case.theory`)."""
    c, heat = case, case.heat
    thermal, T0 = heat.thermal, float(heat.initial_temperature)
    R, r, H = float(c.R), float(c.r), float(c.H)
    V = math.pi * (R * R - r * r) * H
    v = c.omega_main * c.R1
    L = th["contact_length"]
    rho_c = float(np.ravel(thermal.rho_c_at(np.array([T0])))[0])
    b = float(np.ravel(thermal.effusivity_at(np.array([T0])))[0])
    W = th["Q"] * th["sigma0"] * th["strain_per_rev"] * V
    tools = dict(heat.tools or {})
    out = dict(volume=V, generated=thermal.taylor_quinney * W, plastic_work=W)
    for name, area, t_c in (("main_roll", 2 * math.pi * R * H, L / v),
                            ("mandrel", 2 * math.pi * r * H, L * R / (v * r))):
        spec = tools.get(name)
        out[f"contact_time_{name}"] = t_c
        out[f"tool_{name}"] = (0.0 if spec is None else
                               area * contact_heat(T0 - spec.temperature, spec.h_c, b, t_c))
    area = 2 * math.pi * (R + r) * H + 2 * math.pi * (R * R - r * r)
    out["air"] = (0.0 if heat.air is None else
                  float(air_flux(heat.air, T0)) * area * c.t_rev)
    out["tools"] = out["tool_main_roll"] + out["tool_mandrel"]
    out["dT_per_rev"] = (out["generated"] - out["tools"] - out["air"]) / (rho_c * V)
    return out


def summary(res, th: dict) -> dict:
    """The run's heat, whole ring: the temperatures at the end [°C], and over the second half
    of the run (the bite-in left out: the rolls reach the feed per revolution after about one
    revolution) the sums of the history's heat terms [N mm] (``heat_*``, doubled: the model is
    the upper half) and the mean temperature change, against :func:`estimate` over the same
    revolutions (``th`` the pass's theory); {} without heat."""
    rows, c = res.history, res.case
    if c.heat is None or not rows or "heat_T_mean" not in rows[-1]:
        return {}
    second = res.second_half()
    first = rows[rows.index(second[0]) - 1] if rows.index(second[0]) > 0 else None
    T_start = first["heat_T_mean"] if first else float(c.heat.initial_temperature)
    n = second[-1]["revolutions"] - (first["revolutions"] if first else 0.0)
    out = {k: 2.0 * float(sum(q[f"heat_{k}"] for q in second)) for k in TERMS}
    last = rows[-1]
    out.update(T_min=last["heat_T_min"], T_mean=last["heat_T_mean"], T_max=last["heat_T_max"],
               dT_total=last["heat_T_mean"] - float(c.heat.initial_temperature),
               dT_mean=last["heat_T_mean"] - T_start, revolutions=n)
    est = estimate(c, th)
    out["estimate"] = {k: v * n if k in ("generated", "plastic_work", "tools", "air",
                                         "tool_main_roll", "tool_mandrel", "dT_per_rev")
                       else v for k, v in est.items()}
    out["estimate"]["dT"] = out["estimate"].pop("dT_per_rev")
    return out


def report_lines(res) -> List[str]:
    """The heat lines of the ring-rolling report (none without heat)."""
    h = getattr(res, "heat", None)
    if not h:
        return []
    e = h["estimate"]
    kj = 1e-6   # N mm -> kJ
    return [
        f"heat (whole ring): T at the end min {h['T_min']:.0f} / mean {h['T_mean']:.1f} / max "
        f"{h['T_max']:.0f} °C (mean {h['dT_total']:+.2f} K since the start); over the second "
        f"half ({h['revolutions']:.2f} rev) the mean changed by {h['dT_mean']:+.2f} K (estimate "
        f"{e['dT']:+.2f} K: deformation heating minus tool and air losses)",
        f"heat of the second half [kJ]: generated {h['generated'] * kj:.4g} (estimate "
        f"{e['generated'] * kj:.4g}), friction {h['friction'] * kj:.4g}, to the tools "
        f"{-h['tools'] * kj:.4g} (estimate {e['tools'] * kj:.4g}), to the air "
        f"{-(h['air'] + h['radiation']) * kj:.4g} (estimate {e['air'] * kj:.4g}); stored "
        f"{h['stored'] * kj:.4g}, balance residual {h['residual'] * kj:.2g}"]
