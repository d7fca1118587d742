"""Processes with a flow stress σ₀(ε̄, ε̄̇, T) and heat (``material=``, ``heat=`` of the cases):
hot upsetting with cold dies — the chilled zone under the die, the hot core, the heat balance of
every increment, the pressure in the theory band with the law's σ₀; bad set-ups refused."""

import numpy as np
import pytest
from mpi4py import MPI

import fxcontact as fx
from fxcontact.processes import UpsettingCase, run_upsetting


def hot_case(**changes):
    """A steel-like billet at 1100 °C (Hansel–Spittel without the strain-softening terms),
    upset 40 % between dies at 200 °C with h_c = 10 N/(mm s K), air with radiation."""
    law = fx.Viscoplastic(fx.HanselSpittel(A=1500.0, m1=-0.0025, m2=0.2, m3=0.12),
                          regularization=1e-3, temperature=1100.0)
    heat = fx.HeatSetup(fx.ThermalMaterial(rho_c=4.5, conductivity=28.0), 1100.0,
                        air=fx.AirExchange(h=0.02, temperature=20.0, emissivity=0.8),
                        tools={"die": fx.ToolHeat(temperature=200.0, h_c=10.0)})
    return UpsettingCase.quick(**{"material": law, "heat": heat, "reduction": 0.4, **changes})


def test_hot_upsetting_with_cold_dies():
    """The billet cools at the die (the coldest cells touch it) and keeps its core hot; every
    increment's heat balance closes to the solver's tolerance; p̄/σ₀ stays in the band with σ₀
    of the law at the homogeneous strain, rate and mean temperature; volume kept."""
    res = run_upsetting(hot_case(), MPI.COMM_WORLD, pictures=False)
    assert res.status == "completed", res.message
    rows = res.history
    for q in rows:
        scale = max(abs(q["heat_stored"]), abs(q["heat_tools"]), abs(q["heat_generated"]))
        assert abs(q["heat_residual"]) < 1e-8 * scale
        assert q["heat_tools"] < 0 and q["heat_generated"] > 0 and q["heat_air"] < 0
    last = rows[-1]
    assert last["heat_T_min"] < last["heat_T_mean"] - 100.0 and last["heat_T_mean"] < 1100.0
    assert last["heat_T_max"] > last["heat_T_mean"] + 50.0
    assert last["heat_T_min"] > 200.0          # the die's temperature bounds the chill
    assert res.band_from is not None
    assert max(abs(q["volume_change"]) for q in rows) < 5e-3
    # the theory's σ₀ follows the law: it grows with the strain at the billet's temperature
    assert rows[-1]["sigma0"] > rows[1]["sigma0"]


def test_hot_upsetting_bad_setups():
    """A heat tool that is not a tool of the process, a material that is not a flow stress."""
    with pytest.raises(ValueError, match="not tools of this process"):
        case = hot_case(heat=fx.HeatSetup(fx.ThermalMaterial(4.5, 28.0), 1100.0,
                                          tools={"roll": fx.ToolHeat(200.0, 10.0)}))
        run_upsetting(case, MPI.COMM_WORLD, pictures=False)
    with pytest.raises(ValueError, match="Viscoplastic"):
        UpsettingCase.quick(material=fx.NortonHoff(K=50.0, m=0.15))
    with pytest.raises(ValueError, match="HeatSetup"):
        UpsettingCase.quick(heat=1100.0)
    with pytest.raises(ValueError, match="initial_temperature"):
        fx.HeatSetup(fx.ThermalMaterial(4.5, 28.0), float("nan"))
    assert np.isfinite(hot_case().flow_stress(1.0, 10.0))


def test_cold_drawing_with_hardening_heats_the_bar():
    """The test-size drawing (43.75 % reduction, frictionless) with power hardening and heat:
    the steady drawing stress against the theory with the law's mean flow stress over the ideal
    strain (ideal ≤ σ_d ≤ 1.1 Avitzur, and within 3 % of the ideal work: no friction), and
    the bar heated by tens of kelvin — at most the adiabatic rise of the upper-bound work
    η_q 1.1 σ_Avitzur/ρc, at least 0.3 × that of the measured work η_q σ_d/ρc (conduction and
    the die at 20 °C take the rest)."""
    from fxcontact.processes import DrawingCase, run_drawing
    law = fx.Viscoplastic(fx.PowerHardening(K0=200.0, m=0.016, n=0.2, eps0=0.02),
                          regularization=1.0)
    heat = fx.HeatSetup(fx.ThermalMaterial(rho_c=2.4, conductivity=150.0), 20.0,
                        air=fx.AirExchange(h=0.01, temperature=20.0),
                        tools={"die": fx.ToolHeat(temperature=20.0, h_c=10.0)})
    res = run_drawing(DrawingCase.quick(material=law, heat=heat), MPI.COMM_WORLD,
                      pictures=False)
    th = res.theory
    assert res.steady_stress is not None
    assert 0.97 * th["ideal"] <= res.steady_stress <= 1.1 * th["avitzur"]
    assert abs(res.steady_stress / th["ideal"] - 1.0) < 0.03
    rise = res.history[-1]["heat_T_max"] - 20.0
    eta, rho_c = heat.thermal.taylor_quinney, heat.thermal.rho_c
    assert 0.3 * eta * res.steady_stress / rho_c < rise < eta * 1.1 * th["avitzur"] / rho_c
    assert 10.0 < rise < 100.0                       # tens of kelvin
    for q in res.history:
        assert abs(q["heat_residual"]) < 1e-8 * max(abs(q["heat_stored"]), q["heat_generated"])
