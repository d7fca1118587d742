# ---
# jupyter:
#   jupytext:
#     text_representation:
#       extension: .py
#       format_name: percent
# ---

# %% [markdown]
# # Hot upsetting with cold dies: the chilled zone under the die, the hot core
#
# A steel billet at 1100 °C is upset between dies at 200 °C. Where the billet touches a die it
# loses heat fast (h_c = 10 N/(mm s K), i.e. 10 kW/(m² K)): a cold, hard layer forms under the
# die, while the core is heated by the plastic work. The flow stress depends on the temperature
# (a Hansel–Spittel law, THEORY §15: σ₀ = A e^(m₁T) ε̄^m₂ ε̄̇^m₃), so the chilled zone deforms
# less and the dead zone under the die grows — the classic picture of hot forging.
#
# **The case.** `UpsettingCase` (R₀ = 10 mm, H₀/D₀ = 1.5, sticking dies closing at 10 mm/s, a
# 45° sector and half the height, remeshing) with `material=` a `Viscoplastic` Hansel–Spittel
# law (A = 1500 MPa, m₁ = −0.0025 1/°C, m₂ = 0.2, m₃ = 0.12: about 70 MPa at 1100 °C, ε̄ = 0.2,
# 1/s; no published steel is claimed) and `heat=` a `HeatSetup`: ρc = 4.5 N/(mm² K),
# k = 28 N/(s K), η_q = 0.9, air at 20 °C with h = 0.02 N/(mm s K) and emissivity 0.8, the die
# `ToolHeat(200 °C, h_c = 10)` (the mid-plane and the sector's planes are insulated symmetry
# planes).
#
# **What we look at.** The temperature on the θ = 0 section (`upsetting_temperature.png`),
# the strain (`upsetting_section.png`), p̄/σ₀ against the band with σ₀ of the law at the
# homogeneous strain ln(H₀/h), the rate v/h and the billet's mean temperature
# (`upsetting_pressure.png`), and the heat balance of the run in the report: plastic work +
# friction + tools + air = heat stored, every increment to the linear solver's tolerance.
# Figures in `docs/validation.md`.
#
# Run: `mpirun -n 2 python demos/demo_hot_upsetting.py` (a few minutes), `--quick` (the tests'
# billet, R₀ = 5 mm), `--T0`, `--die_temperature`, `--h_c`, `--reduction` (`--help`). Outputs in
# `results/hot_upsetting`.

# %%
import argparse

from mpi4py import MPI

import fxcontact as fx
from fxcontact.processes import UpsettingCase, run_upsetting


def hot_case(quick=False, T0=1100.0, die_temperature=200.0, h_c=10.0, reduction=0.6):
    """The demo's case (the header's values)."""
    law = fx.Viscoplastic(fx.HanselSpittel(A=1500.0, m1=-0.0025, m2=0.2, m3=0.12),
                          regularization=1e-3, temperature=T0)
    heat = fx.HeatSetup(fx.ThermalMaterial(rho_c=4.5, conductivity=28.0), T0,
                        air=fx.AirExchange(h=0.02, temperature=20.0, emissivity=0.8),
                        tools={"die": fx.ToolHeat(temperature=die_temperature, h_c=h_c)})
    base = UpsettingCase.quick() if quick else UpsettingCase(sector=45.0, h=1.5)
    return base.replace(material=law, heat=heat, reduction=reduction)


# %% [markdown]
# ## The run
#
# The heat step follows each accepted increment on the configuration it was solved on: the
# plastic power η_q s:ε̇ of each cell, the die's exchange h_c S_n (T − T_die) at the nodes in
# contact, the air elsewhere on the free surface; the next increment's flow stress reads the
# cell temperatures.

# %%
def main(argv=None):
    ap = argparse.ArgumentParser(description="Hot upsetting with cold dies (see the header).")
    ap.add_argument("--quick", action="store_true", help="the reduced size of the tests")
    ap.add_argument("--T0", type=float, default=1100.0, help="billet temperature [°C]")
    ap.add_argument("--die_temperature", type=float, default=200.0, help="[°C]")
    ap.add_argument("--h_c", type=float, default=10.0, help="die contact [N/(mm s K)]")
    ap.add_argument("--reduction", type=float, default=0.6, help="height reduction 1 - h/H0")
    ap.add_argument("--no-pictures", dest="pictures", action="store_false")
    ap.add_argument("--output-dir", dest="output_dir", default="results/hot_upsetting")
    fx.add_verbosity_arguments(ap)
    a = ap.parse_args(argv)
    fx.configure_logging(verbose=a.verbose, quiet=a.quiet)
    case = hot_case(a.quick, a.T0, a.die_temperature, a.h_c, a.reduction)
    res = run_upsetting(case, MPI.COMM_WORLD, output_dir=a.output_dir, pictures=a.pictures)
    if MPI.COMM_WORLD.rank == 0:
        print(res.report())
    return res


# %% [markdown]
# ## The pictures
#
# `upsetting_temperature.png`: the section coloured by temperature — the dark layer under the
# die (a few hundred kelvin below the core after the first increments of contact), the hot
# core and mid-plane, the side cooling slowly in air. `upsetting_section.png`: the strain, with
# the dead zone under the die. `upsetting_pressure.png`: p̄/σ₀ against the band.

# %%
if __name__ == "__main__":
    main()
