"""Hot ring rolling (``material=``, ``heat=`` of :class:`RingRollingCase`): a superalloy ring
with a tabulated thermo-softening law, chilled by the rolls and the air, at the coarse size of
the tests; the closed-form contact loss of its heat estimate (:mod:`fxcontact.theory.heat_loss`)
against its limits and a quadrature; bad set-ups refused."""

import math
import os
import shutil
from dataclasses import replace

import numpy as np
import pytest
from mpi4py import MPI
from scipy.integrate import quad
from scipy.special import erfcx

import fxcontact as fx
from fxcontact.contact.friction import Coulomb
from fxcontact.processes.ring_rolling import RingRollingCase, run
from fxcontact.processes.ring_rolling.heat import estimate
from fxcontact.theory.heat_loss import air_flux, contact_heat
from helpers import shared_tmpdir

TABLE = os.path.join(os.path.dirname(__file__), "..", "demos", "data",
                     "alloy718_hot_flow_stress.csv")


def hot_ring(**changes) -> RingRollingCase:
    """An alloy 718 ring (R 250, r 180, H 70 mm) at 1050 °C on an 8 rpm mill, feed 0.4 mm/s,
    Coulomb μ 1 capped by m̄ 1, rolls at 250 °C with h_c = 10 N/(mm s K), air with radiation;
    the coarse quick mesh, 4 increments."""
    law = fx.Viscoplastic(fx.TabulatedFlowStress.from_csv(TABLE), regularization=1e-3,
                          temperature=1050.0)
    heat = fx.HeatSetup(fx.ThermalMaterial(rho_c=4.9, conductivity=25.0), 1050.0,
                        air=fx.AirExchange(h=0.02, temperature=20.0, emissivity=0.7),
                        tools={"main_roll": fx.ToolHeat(250.0, 10.0),
                               "mandrel": fx.ToolHeat(250.0, 10.0)},
                        probes={"outer": (250.0, 0.0, 0.0), "core": (215.0, 0.0, 0.0)})
    fr = Coulomb(1.0, mbar=1.0)
    c = RingRollingCase(R=250.0, r=180.0, H=70.0, R1=350.0, R2=90.0, Rg=90.0, rpm=8.0,
                        feed_speed=0.4, friction={"main_roll": fr, "mandrel": fr},
                        mu_bite=1.0, material=law, heat=heat).quick()
    return replace(c, **{"revolutions": 4.0 / c.increments_per_rev, **changes})


def test_contact_heat_limits_and_quadrature():
    """The heat a semi-infinite body loses through h in a contact of t: the quadrature of the
    surface flux h θ₀ e^{β²} erfc β (Carslaw & Jaeger's surface temperature) to 1e-8, h θ₀ t
    when the surface cannot cool (β → 0) and 2 b θ₀ √(t/π) in perfect contact (β → ∞) to
    1e-3."""
    theta, b = 800.0, 11.0
    for h, t in ((10.0, 0.06), (10.0, 5.0), (0.5, 0.01), (200.0, 2.0), (1e-4, 1.0)):
        Q = contact_heat(theta, h, b, t)
        ref = quad(lambda s: h * theta * erfcx(h * math.sqrt(s) / b), 0.0, t, limit=200)[0]
        assert abs(Q / ref - 1.0) < 1e-8, (h, t, Q, ref)
    assert abs(contact_heat(theta, 1e-3, b, 1.0) / (1e-3 * theta) - 1.0) < 1e-3
    assert abs(contact_heat(theta, 1e5, b, 1.0) / (2 * b * theta / math.sqrt(math.pi))
               - 1.0) < 1e-3
    assert contact_heat(theta, 0.0, b, 1.0) == 0.0
    with pytest.raises(ValueError, match="h"):
        contact_heat(theta, -1.0, b, 1.0)
    air = fx.AirExchange(h=0.02, temperature=20.0, emissivity=0.7)
    sb = 5.670374419e-11 * 0.7 * ((1050 + 273.15) ** 4 - (20 + 273.15) ** 4)
    assert abs(air_flux(air, 1050.0) - (0.02 * 1030.0 + sb)) < 1e-12


def test_hot_ring_is_chilled_by_the_rolls_and_the_air():
    """The coarse hot ring on 1 or 2 ranks: the pass's σ₀ is the table's (hotter is softer),
    the rolls chill the surface (T_min well below T₀) while the core (a probe) cools by less
    than a fifth of the outer surface (another probe) in the time of the test, the mean falls,
    every increment's heat balance closes, volume is kept; the report and the pictures carry
    the heat; the estimate's air loss per revolution is the closed form's over the whole free
    surface."""
    c = hot_ring()
    out = shared_tmpdir("fxc_hot_ring_")
    res = run(c, MPI.COMM_WORLD, output_dir=out)
    assert res.status == "done", res.message
    cooler = run(replace(c, revolutions=1.0 / c.increments_per_rev,
                         heat=replace(c.heat, initial_temperature=1100.0)), MPI.COMM_WORLD,
                 pictures=False)
    assert cooler.sigma0 < res.sigma0          # the table softens with the temperature
    T0 = c.heat.initial_temperature
    last = res.history[-1]
    assert last["heat_T_min"] < T0 - 10.0
    assert last["heat_T_mean"] < T0 and last["heat_T_max"] < T0 + 1.0
    assert T0 - last["heat_T_at_core"] < 0.2 * (T0 - last["heat_T_at_outer"])
    for q in res.history:
        assert abs(q["heat_residual"]) < 1e-8 * abs(q["heat_stored"])
        assert q["heat_tools"] < 0 and q["heat_radiation"] < 0 and q["heat_generated"] >= 0
    assert abs(res.volume_change) < 1e-4
    h = res.heat
    assert h and h["T_min"] == last["heat_T_min"]
    assert "heat (whole ring)" in res.report() and "probe" not in res.report()
    assert os.path.exists(res.pictures["top_view"]) and os.path.exists(res.pictures["curves"])
    MPI.COMM_WORLD.barrier()   # every rank has looked at the files before rank 0 removes them
    if MPI.COMM_WORLD.rank == 0:
        shutil.rmtree(out, ignore_errors=True)
    strain = 2 / math.sqrt(3) * math.log(70.0 / (70.0 - res.feed_per_rev))
    est = estimate(c, {"contact_length": res.contact_length, "Q": res.Q, "sigma0": res.sigma0,
                       "strain_per_rev": strain})
    area = 2 * math.pi * (250.0 + 180.0) * 70.0 + 2 * math.pi * (250.0 ** 2 - 180.0 ** 2)
    assert abs(est["air"] / (air_flux(c.heat.air, T0) * area * c.t_rev) - 1.0) < 1e-12


def test_hot_ring_bad_setups():
    """A material that is not a flow stress, a heat that is not a HeatSetup, a heat tool that
    is not a tool of the mill."""
    with pytest.raises(ValueError, match="Viscoplastic"):
        hot_ring(material=fx.NortonHoff(K=50.0, m=0.14))
    with pytest.raises(ValueError, match="HeatSetup"):
        hot_ring(heat=1050.0)
    c = hot_ring()
    bad = replace(c, heat=replace(c.heat, tools={"die": fx.ToolHeat(200.0, 10.0)}))
    with pytest.raises(ValueError, match="not tools of this process"):
        run(bad, MPI.COMM_WORLD, pictures=False)
    assert np.isfinite(estimate(c, {"contact_length": 18.6, "Q": 1.5, "sigma0": 120.0,
                                    "strain_per_rev": 0.03})["dT_per_rev"])
