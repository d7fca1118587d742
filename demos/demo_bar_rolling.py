# ---
# jupyter:
#   jupytext:
#     text_representation:
#       extension: .py
#       format_name: percent
# ---

# %% [markdown]
# # Three-roll rolling of a round bar
#
# In long-product rolling a round bar is reduced in a stand of three grooved rolls at 120°.
# Each roll carries a circular groove; in the exit plane the three grooves and the barrel
# shoulders beside them enclose the **pass**. The bar is squeezed radially under the grooves
# and spreads sideways into the **roll gaps** between two rolls, where the shoulders leave
# open "ears": how far the bar fills them (the fill of the pass, its complement the
# underfill) is what a pass designer wants to know, with the roll force and torque.
#
# The thesis's case (THEORY §12.2): a bar R0 = 58 mm rolled to the inscribed radius
# R1 = 48 mm; grooves of radius R1 spanning ±50° about each roll's direction, roll radius
# 180 mm at the groove bottom, groove edges rounded 5 mm; Norton–Hoff K = 50 MPa·s^m,
# m = 0.03 (nearly rigid-plastic); viscoplastic (Norton) friction α_f = 0.3, q = 0.15;
# 100 mm/s. Measured results and their discussion: `docs/validation.md`, "Bar rolling".
#
# Run: `python demos/demo_bar_rolling.py --quick` (the reduced size of the tests: 16 mm
# elements, dt = 20 ms, about 85 increments to steady state), the thesis size without
# `--quick` (9 mm elements, dt = 1 ms: 15 min on 2 ranks to steady state), any field of the
# case (`--groove_angle 45`, `--roll_radius 250`, `--model full` …, `--help`), `--compare N`
# (the third against the whole bar over N increments); on 2 ranks with `mpirun -n 2`.
# Outputs in `results/bar_rolling`.

# %%
import math

import numpy as np
from mpi4py import MPI

from fxcontact.console import case_parser, parse_case
from fxcontact.processes import BarRollingCase, bar_rolling

parser = case_parser(BarRollingCase, "Three-roll rolling of a round bar to steady state",
                     "results/bar_rolling")
parser.add_argument("--compare", type=int, default=0, metavar="N",
                    help="the third against the whole model over N increments")
rank0 = MPI.COMM_WORLD.rank == 0

# %% [markdown]
# ## The case and the pass
#
# A `BarRollingCase` holds the pass (R0, R1, the groove's half-angle, the roll radius, the
# edge radius), the material, the friction, the kinematics and the numerics; it checks its
# fields when it is made. `bar_rolling.stand_pass(case)` designs the pass: each groove's
# centre lies on the bar axis, so the three grooves are arcs of the circle of radius R1 (the
# inscribed radius); beside the grooves the shoulders of two rolls meet at the corner radius
# r_c = 2 R1 cos β, beyond the incoming bar's radius, so the ears stay open.

# %%
case, args = parse_case(parser, BarRollingCase)
geo = bar_rolling.stand_pass(case)
if rank0:
    print(f"pass: groove depth {geo['h_g']:.2f} mm, corner radius r_c = {geo['r_c']:.2f} mm "
          f"(bar R0 = {case.R0:g}); area {geo['A_pass']:.0f} mm2 against the incoming "
          f"{math.pi * case.R0**2:.0f} and the inscribed circle's {geo['A_inscribed']:.0f};"
          f" bite length {case.bite_length:.1f} mm")

# %% [markdown]
# ## The set-up
#
# `bar_rolling.build(case)` makes the model:
#
# * the bar axis is z, rolling towards +z; the roll axes lie in the exit plane, each roll a
#   `RevolvedProfile.grooved_roll` turning so that its surface nearest the bar moves with it;
# * `model="third"` (default): the sector 0–120° with one roll at 60° between two inclined
#   symmetry planes (`Simulation.add_symmetry_plane`, exact; the third holds one whole roll,
#   so per-roll values are the third's and the stand's torque and power are 3 ×);
#   `model="full"`: the whole bar and three rolls. The default mesh of the third is
#   mirror-symmetric, and the whole bar is made of three turned copies of it: both models
#   then have the same discrete solution (`--compare`);
# * one `NodalContact` for the rolls with `Norton` friction, the penalty from β = 10;
# * the bar's front is shaped to the pass and fills 30 % of the bite; a `Plane` pusher moves
#   it until the rolls grip it;
# * Newton from rest with m = 0.03 stalls, so the first increment is solved with
#   m_start = 0.1 and the next ones with m (the exponent is a `Constant` of the residual).
#
# `bar_rolling.run(case)` runs it under the `SteadyMonitor` (stop reasons: refused, lost,
# no steady state, failed, steady: the roll force and torque window means agree within 2 %).

# %% [markdown]
# ## The run

# %%
if args.compare:
    cmp = bar_rolling.compare(case, args.compare)
    if rank0:
        for key, d in cmp["max_rel_diff"].items():
            print(f"third vs full: max relative difference of the per-roll {key}: {d:.2e}")
        for qa, qb in zip(cmp["third"].history, cmp["full"].history):
            print(f"t = {qa['time']:.4g}: radial force third {qa['roll_force']:.6g} full "
                  f"{qb['roll_force']:.6g} N; torque third {qa['roll_torque']:.6g} full "
                  f"{qb['roll_torque']:.6g} N mm")
res = None if args.compare else bar_rolling.run(case, output_dir=args.output_dir)
if rank0 and res is not None:
    print(res.report())

# %% [markdown]
# ## Comparison with the pass
#
# Volume is conserved (the exit section times the exit speed is the entry's flow), so the
# exit area must lie between the inscribed circle (the bar touches every groove bottom) and
# the whole pass (the ears filled), plus the sliver of the penalty penetration along the
# perimeter. The power balance compares the rolls' power Mω (and the pusher's) with the
# plastic dissipation and the friction power: without the penalty work it closes to about
# 1 %, with it to round-off.

# %%
if rank0 and res is not None and res.steady:
    outline = geo["outline"] if "outline" in geo else bar_rolling.pass_outline(geo)
    per = float(np.sum(np.linalg.norm(np.diff(outline, axis=0), axis=1)))
    upper = 1.0 + per * res.max_penetration / geo["A_pass"]
    print(f"fill of the pass {100 * res.fill:.2f} %: between the inscribed circle's "
          f"{100 * geo['A_inscribed'] / geo['A_pass']:.2f} % and "
          f"{100 * upper:.2f} % (with the penetration)")
    print(f"the bar reaches {res.radius_gap:.1f} mm at the roll gaps, of the "
          f"{geo['r_c']:.1f} mm corner radius; power balance {100 * res.power_balance:.2f} %")
    print(f"a third of the stand: per roll {res.roll_force / 1e3:.1f} kN radial, "
          f"{res.roll_torque / 1e6:.2f} kN m; the stand {res.stand_power / 1e6:.1f} kW")
elif rank0 and res is not None:
    print(f"not steady: {res.message}")

# %% [markdown]
# ## The picture
#
# `results/bar_rolling/exit_section_third.png`: the exit section half a bite length past the
# roll axes (the modelled third in red, its turned copies in salmon) in the pass (grey), with
# the incoming bar and the inscribed circle. The bar fills the grooves and spreads into the
# ears beside them, short of the corners at the roll gaps.

# %%
if rank0 and res is not None and res.pictures:
    print("picture:", res.pictures[0])
