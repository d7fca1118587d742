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
