# ---
# jupyter:
#   jupytext:
#     text_representation:
#       extension: .py
#       format_name: percent
# ---

# %% [markdown]
# # Flat rolling of a strip to steady state
#
# A strip of thickness $h_0$ passes between two rolls of radius $R$ turning at the peripheral
# speed $v_R$ and leaves them with the thickness $h_1$. The material touches the roll along
# the arc of contact, of projected length $L = \sqrt{R\,\Delta h}$ and bite angle
# $\alpha = \arccos(1 - \Delta h / 2R)$. The strip enters slower than the roll and leaves
# faster (incompressibility): friction drags it into the bite on the entry side and holds it
# back on the exit side, and the two zones meet at the **neutral point**, where the strip
# moves with the roll and the friction stress changes sign. The pressure rises from both ends
# of the arc to a peak there (the friction hill). The strip leaves faster than the roll by
# the **forward slip**, and it widens (spread) where the bite is short against the width.
#
# The classical theories (THEORY §14.3, `fxcontact.theory.flat_rolling`) give the separating force per
# unit width: the slab (von Kármán/Orowan) method with the same Coulomb–Tresca law as the
# model, Sims (sticking friction) and Ford–Alexander; the slab's forward slip and neutral
# angle; Hill's spread formula. A strip bites unaided only if $\mu \ge \tan\alpha$.
#
# The case is the thesis's (THEORY §14.3): 100 mm wide, 25 → 18 mm (28 %), R = 300 mm,
# v_R = 500 mm/s, Norton–Hoff K = 30 MPa·s^m, m = 0.3 (the flow stress σ0 is taken at the
# bite's mean strain rate $(v_R/L)\ln(h_0/h_1)$), Coulomb μ = 0.3 limited by Tresca m̄ = 1.
# Measured results and their discussion: `docs/validation.md`, section "Flat rolling".
#
# Run: `python demos/demo_flat_rolling.py` (the thesis mesh, 45.5k dofs: about half an hour on
# 2 ranks), `--quick` (the reduced size of the tests, under a minute), any field of the case
# (`--R 200 --reduction 0.2 --mu 0.25`, `--roll nagata`, … `--help`); on 2 ranks with
# `mpirun -n 2`. Outputs in `results/flat_rolling`.

# %%
import math

from mpi4py import MPI

from fxcontact.theory import flat_rolling as rolling
from fxcontact.console import case_parser, parse_case
from fxcontact.processes import FlatRollingCase, flat_rolling

parser = case_parser(FlatRollingCase, "Flat rolling of a strip to steady state",
                     "results/flat_rolling")
rank0 = MPI.COMM_WORLD.rank == 0

# %% [markdown]
# ## The case
#
# A `FlatRollingCase` holds the pass (R, h0, reduction, width), the material (K, m), the
# friction (a `Coulomb(mu, mbar)` law; `--mu`, `--mbar` on the command line; the slip velocity
# of the regularised law), the kinematics (roll speed, the
# pusher that starts the strip, the tail's pseudo-inertia) and the numerics (element size,
# dt, the steady-state windows). It checks its fields when it is made; any field is changed
# with `dataclasses.replace` (or on the command line).

# %%
case, args = parse_case(parser, FlatRollingCase)
bite = case.bite
mu = case.friction_coefficients()[0]
if rank0:
    print(f"pass: R = {case.R:g} mm, {case.h0:g} -> {case.h1:.4g} mm ({100 * case.reduction:g} %)"
          f", width {case.width:g} mm; L = {bite.contact_length:.2f} mm, bite angle "
          f"{bite.bite_angle:.4f} rad; mu = {mu} against tan(alpha) = "
          f"{bite.max_draft_ratio:.4f}: {'bites' if bite.bites(mu or 0.0) else 'needs a push'}")

# %% [markdown]
# ## The set-up
#
# `flat_rolling.build(case)` makes the model (one quarter of the strip):
#
# * x is the rolling direction, y across the width, z through the thickness; the width and
#   thickness mid-planes are symmetry planes (`v_y = 0`, `v_z = 0`). The mesh is a
#   structured tetrahedral box, uniform along x (every section of the strip passes the
#   bite in an updated-Lagrangian run, so the bite's element size is the strip's).
# * The upper roll is an analytic `Cylinder` (or a faceted one, `roll="flat"`/`"nagata"`)
#   whose lowest line is at the exit plane x = 0, turning at ω = v_R/R; `NodalContact` with
#   `Coulomb(mu, mbar)` friction. The force and torque of one roll per unit width are the
#   quarter's over the mean half-width.
# * The strip's front is shaped to the roll (a nose) and fills `nose` × L of the bite; a rigid
#   `Plane` pusher on the back face moves it at 0.9 × the ideal entry speed until the roll
#   grips it (no pusher contact for two increments), then stops.
# * Once released, nothing but friction holds the quasi-static strip along x, and Newton
#   may find it thrown out of the bite. The tail face therefore carries a lagged dashpot
#   `c (v − v̄_prev)` (`NodalSprings`, c = `tail_damping` σ0/v_R): a pseudo-inertia that
#   vanishes at steady state and whose power enters the power balance.
#
# `flat_rolling.run(case)` then runs increments under a `SteadyMonitor`
# (`fxcontact.processes.monitor`): it stops when the strip is **refused** (not gripped after
# `grip_travel` × L of push), **lost** (no contact after the release), has **no steady state**
# (the tail reached the bite, or `max_increments`), or is **steady**: the roll force and
# torque means of two consecutive windows of `window` × L of roll travel agree within
# `steady_tol` once the front is `settle` × L past the exit. The steady values are the last
# window's means.

# %% [markdown]
# ## The run

# %%
res = flat_rolling.run(case, output_dir=args.output_dir, pictures=True)
if rank0:
    print(res.report())

# %% [markdown]
# ## Comparison with theory
#
# The FE force per unit width lies below the band of the classical theories at this
# reduction (they assume plane strain and plane sections; the strip spreads), the forward
# slip is above the slab's (its neutral point lies nearer the entry), the spread is close to
# Hill's. The power balance compares the roll's power −Mω (plus the pusher's) with the
# plastic dissipation, the friction power and the dashpot's: without the penalty work it
# closes to 1–2 %, with it to round-off (the discrete virtual-power identity).

# %%
if rank0 and res.steady:
    th = res.theory
    rows = [("roll force P/w [N/mm]", res.force_per_width, th["slab_force"]),
            ("  Sims", res.force_per_width, th["sims_force"]),
            ("  Ford-Alexander", res.force_per_width, th["ford_alexander_force"]),
            ("torque/w [N mm/mm]", res.torque_per_width, th["slab_torque"]),
            ("forward slip [%]", 100 * res.forward_slip, 100 * th["slab_forward_slip"]),
            ("neutral angle [rad]", res.neutral_angle, th["slab_neutral_angle"]),
            ("spread [%] (Hill)", 100 * res.spread, 100 * res.spread_hill)]
    print(f"{'':24s} {'FE':>10s} {'theory':>10s} {'FE/theory':>10s}")
    for name, fe, ref in rows:
        print(f"{name:24s} {fe:10.4g} {ref:10.4g} {fe / ref:10.3f}")
    print(f"power balance {100 * res.power_balance:.2f} % (with the penalty work "
          f"{100 * res.power_balance_penalty:.1e} %)")
elif rank0:
    print(f"not steady: {res.message}")

# %% [markdown]
# ## The picture
#
# `results/flat_rolling/arc_of_contact.png`: the roll pressure and the friction stress along
# the arc of contact at the last increment (every contact node, and their mean across the
# width), against the slab solution with the same friction law. The FE neutral point (where
# the mean friction stress changes sign) lies nearer the entry than the slab's; at the quick
# size (a row of nodes every 7.5 mm) the FE pressure hill is flatter than the slab's, whose
# peak at the neutral point is a cusp. (`strain.png`: the equivalent strain and strain rate
# in a side view.)

# %%
if rank0 and res.pictures:
    print("pictures:", ", ".join(res.pictures))
    slab = rolling.slab(case.R, case.h0, case.h1, res.sigma0, *case.friction_coefficients())
    print(f"peak pressure: FE {max(res.arc['p']):.0f} MPa, slab {max(slab.pressure):.0f} MPa; "
          f"neutral point: FE x = {res.neutral_x:.1f} mm, slab "
          f"{-case.R * math.sin(slab.neutral_angle):.1f} mm")
