# ---
# jupyter:
#   jupytext:
#     text_representation:
#       extension: .py
#       format_name: percent
# ---

# %% [markdown]
# # Hot ring rolling of a superalloy ring: the rolls chill its surfaces, the work heats it
#
# An alloy 718 ring at 1050 °C is rolled on a radial mill: the main roll turns at 8 rpm, the
# mandrel is fed at 0.4 mm/s, both with Coulomb friction μ = 1 capped by Tresca m̄ = 1 — the
# thesis's industrial case 1 (its ring and mill are given only in a figure: the geometry here
# is ours, an aero-engine ring of 500 mm). The ring's temperature is the balance the thesis's
# introduction describes: each pass through the bite the rolls (at 250 °C) draw heat from a thin
# skin of the outer surface and of the bore, the plastic work of the bite heats the wall, the
# free surfaces radiate. The flow stress is a table σ₀(ε̄, ε̄̇, T) read from a CSV
# (`demos/data/alloy718_hot_flow_stress.csv`, values of the order of published hot-compression
# tests, not a fit): about 25 % softer per 50 K, softening after its peak strain.
#
# **The case.** `RingRollingCase` with `material=` a `Viscoplastic` table law and `heat=` a
# `HeatSetup`: ring R = 250, r = 180, H = 70 mm; main roll R₁ = 350, mandrel R₂ = 90, guide rolls
# 90 mm; ρc = 4.9 N/(mm² K), k = 25 N/(s K), η_q = 0.9; rolls `ToolHeat(250 °C, h_c = 10
# N/(mm s K))`; air at 20 °C with h = 0.02 and emissivity 0.7 on the outer, bore and top faces
# (the mid-plane is a symmetry plane); three probes (thermocouples) at the mid-height of the
# outer surface, of the wall and of the bore. Mesh 200 × 4 × 2 (7.9 mm around the outside: the
# bite, L = 18.6 mm, is crossed in about 2.4 increments of 1/200 revolution).
#
# **What we look at.** The top view coloured by the temperature of the top face with the
# tools (`hot_ring_top.png`), the forces, speeds and T(t) of the ring and at the probes
# (`hot_ring_curves.png`), and the report: the second half's mean temperature change against
# an estimate derived in `fxcontact.processes.ring_rolling.heat` (deformation heating Q σ₀
# ε̄_rev V η_q, minus the contact loss of a semi-infinite body at each pass, minus convection
# and radiation of the free surface), term by term. Figures in `docs/validation.md`.
#
# Run: `mpirun -n 2 python demos/demo_hot_ring_rolling.py` (two revolutions, about 13 minutes
# on 2 cores), `--quick` (the coarse mesh of the tests), `--revolutions`, `--T0`,
# `--roll_temperature`, `--h_c`, `--feed_speed`, `--rpm`, `--table` (your alloy's CSV;
# `--help`). Outputs in `results/hot_ring_rolling`.

# %%
import argparse
import os

from mpi4py import MPI

import fxcontact as fx
from fxcontact.contact.friction import Coulomb
from fxcontact.processes.ring_rolling import RingRollingCase, run

TABLE = os.path.join(os.path.dirname(os.path.abspath(__file__)), "data",
                     "alloy718_hot_flow_stress.csv")


def hot_ring(quick=False, revolutions=2.0, T0=1050.0, roll_temperature=250.0, h_c=10.0,
             feed_speed=0.4, rpm=8.0, table=TABLE):
    """The demo's case (the header's values)."""
    law = fx.Viscoplastic(fx.TabulatedFlowStress.from_csv(table), regularization=1e-3,
                          temperature=T0)
    rolls = fx.ToolHeat(temperature=roll_temperature, h_c=h_c)
    R, r = 250.0, 180.0
    heat = fx.HeatSetup(fx.ThermalMaterial(rho_c=4.9, conductivity=25.0), T0,
                        air=fx.AirExchange(h=0.02, temperature=20.0, emissivity=0.7),
                        tools={"main_roll": rolls, "mandrel": rolls},
                        probes={"outer": (R, 0.0, 0.0), "wall": (0.5 * (R + r), 0.0, 0.0),
                                "bore": (r, 0.0, 0.0)})
    friction = Coulomb(1.0, mbar=1.0)
    case = RingRollingCase(R=R, r=r, H=70.0, R1=350.0, R2=90.0, Rg=90.0, rpm=rpm,
                           feed_speed=feed_speed, mu_bite=1.0,
                           friction={"main_roll": friction, "mandrel": friction},
                           material=law, heat=heat, n_theta=200, n_r=4, n_z=2,
                           increments_per_rev=200, revolutions=revolutions)
    return case.quick().replace(revolutions=revolutions) if quick else case


# %% [markdown]
# ## The run
#
# The heat step follows each accepted increment on the configuration it was solved on (before
# the cylindrical update turns the ring): the plastic power η_q s:ε̇ of each cell, the rolls'
# exchange h_c S_n (T − T_roll) at the nodes in contact, the air elsewhere; the next increment's
# flow stress reads the cell temperatures. The probes are material points: they turn with the
# ring, through the bite once per revolution.

# %%
def main(argv=None):
    ap = argparse.ArgumentParser(description="Hot ring rolling of a superalloy ring (see the "
                                 "header).")
    ap.add_argument("--quick", action="store_true", help="the coarse mesh of the tests")
    ap.add_argument("--revolutions", type=float, default=2.0)
    ap.add_argument("--T0", type=float, default=1050.0, help="ring temperature [°C]")
    ap.add_argument("--roll_temperature", type=float, default=250.0, help="[°C]")
    ap.add_argument("--h_c", type=float, default=10.0, help="roll contact [N/(mm s K)]")
    ap.add_argument("--feed_speed", type=float, default=0.4, help="mandrel feed [mm/s]")
    ap.add_argument("--rpm", type=float, default=8.0, help="main roll speed [1/min]")
    ap.add_argument("--table", default=TABLE, help="flow-stress CSV (strain, strain_rate, "
                    "temperature, stress)")
    ap.add_argument("--no-pictures", dest="pictures", action="store_false")
    ap.add_argument("--output-dir", dest="output_dir", default="results/hot_ring_rolling")
    fx.add_verbosity_arguments(ap)
    a = ap.parse_args(argv)
    fx.configure_logging(verbose=a.verbose, quiet=a.quiet)
    case = hot_ring(a.quick, a.revolutions, a.T0, a.roll_temperature, a.h_c, a.feed_speed,
                    a.rpm, a.table)
    if a.pictures and MPI.COMM_WORLD.rank == 0:   # the table as typed: see what the ring gets
        os.makedirs(a.output_dir, exist_ok=True)
        fx.plot_flow_curves(case.material.flow, os.path.join(a.output_dir,
                                                             "hot_ring_flow_curves.png"))
    res = run(case, MPI.COMM_WORLD, output_dir=a.output_dir, pictures=a.pictures,
              name="hot_ring")
    if MPI.COMM_WORLD.rank == 0:
        print(res.report())
    return res


# %% [markdown]
# ## The pictures
#
# `hot_ring_flow_curves.png`: the table as typed (σ₀ against ε̄ at its rates and temperatures).
# `hot_ring_top.png`: the top face coloured by its temperature at four times — a cold band
# just behind each bite on the outer surface and the bore, fading as the skin reheats from the
# wall during the rest of the revolution. `hot_ring_curves.png`: the diameters, the roll forces
# against 2kHLQ (σ₀ of the table over the run's strain), the speeds, and T(t): the outer probe
# dips each time it passes the main roll, the wall probe follows the slow mean.

# %%
if __name__ == "__main__":
    main()
