# ---
# jupyter:
#   jupytext:
#     text_representation:
#       extension: .py
#       format_name: percent
# ---

# %% [markdown]
# # Radial ring rolling: a driven main roll, an idle mandrel fed towards it, guide rolls
#
# A ring of outer radius $R$, bore $r$ and height $H$ is squeezed between a **main roll**
# (radius $R_1$, driven, fixed axis) on its outer surface and a **mandrel** (radius $R_2$) in
# its bore. The main roll turns the ring; the mandrel is fed towards the main roll at
# $v_f$ and turns freely (**idle**: no torque about its axis). Each revolution of the ring the
# wall passes the bite once and is thinned by the feed per revolution $\Delta h = v_f\,t_{rev}$:
# volume constancy turns that thinning into a growing diameter. Two **guide rolls** on the
# main-roll side keep the growing ring centred on the mill line.
#
# Ring-rolling theory (THEORY §14.4, `fxcontact.theory.forming`) says what to expect:
#
# * the feed per revolution must lie in a **window**: large enough that the plastic zone
#   reaches through the wall (Hawkyard, $\Delta h \ge 6.55\cdot10^{-3}B^2\Sigma$ with
#   $B = R - r$ and the bite's curvature sum $\Sigma = 1/R_1 + 1/R_2 + 1/R - 1/r$), small enough
#   that friction draws the ring into the bite;
# * the bite is short, $L = \sqrt{2\Delta h/\Sigma}$, and the radial roll force is about
#   $2kHLQ$ (k the shear flow stress at the bite's strain rate $(\Delta h/B)\,v_s/L$);
# * the mean diameter follows volume constancy, $D_m = V/(\pi H B)$.
#
# **The material.** The thesis's academic cases (THEORY §12.1) print Norton–Hoff
# K = 1900 MPa·s^m, m = 0.14 for a hot ring: taken literally that is σ₀ ≈ 4070 MPa, the
# strength of a hardened steel cold. Hot 42CrMo4 (1050–1150 °C, 1–10 1/s) flows at roughly
# 80–130 MPa, so the case's default is K = 50 (σ₀ ≈ 107 MPa; the sources are in the docstring of
# `fxcontact.processes.ring_rolling`). K only scales the forces: the thesis's cases stay
# available as `RingRollingCase.case1()` and `case2()`, and the report flags their K.
#
# Run: `python demos/demo_ring_rolling.py` (two revolutions at the default mesh 160 × 4 × 2;
# about an hour on 2 ranks), `--quick` (the reduced size of the tests, a fifth of a
# revolution), any field of the case (`--R 110 --feed_speed 2 --K 1900`, `--cones on
# --cone_speed 0.4`, … `--help`); `--thesis_case 1|2` starts from the thesis's case instead;
# on 2 ranks with `mpirun -n 2`. Outputs in `results/ring_rolling`. Measured results:
# `docs/validation.md`, section "Ring rolling".

# %%
from mpi4py import MPI

from fxcontact.console import case_parser, parse_case
from fxcontact.processes import RingRollingCase, ring_rolling

parser = case_parser(RingRollingCase, "Radial ring rolling", "results/ring_rolling")
parser.add_argument("--thesis_case", type=int, choices=(1, 2),
                    help="start from the thesis's academic case 1 or 2 (its K = 1900)")
parser.add_argument("--checkpoint_every", type=int, default=0,
                    help="write a checkpoint every so many increments")
parser.add_argument("--resume", action="store_true",
                    help="resume from the newest checkpoint in --output-dir")
parser.add_argument("--vtk_every", type=int, default=0, help="VTK series every n increments")
rank0 = MPI.COMM_WORLD.rank == 0

# %% [markdown]
# ## The case
#
# A `RingRollingCase` holds the ring (R, r, H), the mill (R₁, R₂, the guide rolls, the
# initial bite), the material (K, m), the friction of each tool (`friction`: tool name → law,
# `Coulomb(mu, mbar=...)`, `Norton(alpha_f, q)`; on the command line `--main_friction
# coulomb,0.3,0.6`, `--mandrel_friction none`), the kinematics (main roll rpm, mandrel feed,
# how the idle mandrel's speed is found, cone rolls) and the numerics (mesh, increments per revolution,
# revolutions, contact scheme, configuration update). The default is the thesis's case 2 on a
# mill of industrial proportion (THEORY §14.4) with the hot steel: main roll 150 mm at 60
# rpm, mandrel 40 mm fed at 1.5 mm/s, Coulomb μ = 0.3 limited by Tresca m̄ = 0.6 on both rolls.

# %%
case, args = parse_case(parser, RingRollingCase)
if args.thesis_case:   # the options given (a former field's name sets the new field)
    given = {k: v for k, v in vars(args).items()
             if k in RingRollingCase.__dataclass_fields__ and v is not None}
    thesis = getattr(RingRollingCase, f"case{args.thesis_case}")()
    case = (thesis.quick() if args.quick else thesis).with_options(**given)
th = ring_rolling.theory(case)
if rank0:
    w = th["window"]
    print(f"ring {case.R:g}/{case.r:g} x {case.H:g} mm; one revolution {case.t_rev:.3f} s, "
          f"feed {th['feed_per_rev']:.3f} mm/rev in the window {w['min']:.3f} - "
          f"{w['max']:.3f}; bite L = {th['contact_length']:.2f} mm, sigma0 = "
          f"{th['sigma0']:.0f} MPa, 2kHLQ = {th['force_estimate'] / 1e3:.0f} kN")

# %% [markdown]
# ## The set-up
#
# `ring_rolling.build(case)` makes the model:
#
# * the **upper half** of the ring in height (the mid-plane z = 0 is a symmetry plane,
#   `v_z = 0`), the whole plan: a structured tetrahedral ring (`fxcontact.structured_ring`),
#   MINI elements, Norton–Hoff; forces and torques are reported for the whole ring;
# * the tools are analytic `Cylinder`s (`tools="faceted"`: flat facets of the same cylinders)
#   moved by their motions: the main roll turns at `rpm` about a fixed axis at x = R + R₁; the
#   mandrel's axis moves at the feed speed (`ControlledMotion`); one `NodalContact` with the
#   friction of each tool;
# * the **idle mandrel** (`IdleRotation`): its ω is found at each increment from zero torque
#   about its axis, eliminated inside Newton (`idle_method="bordered"`) or by an outer
#   iteration;
# * **centring** (`RingCentring`): the frictionless guide rolls are placed, each increment,
#   where the outer surface of a ring centred on the mill line is; they act only against a
#   drift of the ring off the line;
# * the **configuration update** is cylindrical about the ring's centroid (THEORY §5): a node
#   turning with the ring moves on an arc, so the volume is kept without a correction;
# * the first guess is the ring turning rigidly at the main roll's surface speed.
#
# `ring_rolling.run(case)` then runs the increments for `revolutions` and measures, per
# increment, the diameters (area means of the surface nodes about the centroid), the height,
# the forces and torques, the ring's and the mandrel's speeds, the penetration and the volume.

# %% [markdown]
# ## The run

# %%
res = ring_rolling.run(case, output_dir=args.output_dir, pictures=True,
                       vtk_every=args.vtk_every, checkpoint_every=args.checkpoint_every,
                       resume=args.resume or None)
if rank0:
    print(res.report())

# %% [markdown]
# ## Comparison with theory
#
# * The mean diameter follows volume constancy V/(πHB) of the measured section to a fraction
#   of a per cent at every increment, and the outer diameter grows by the feed turned into
#   length.
# * The main roll's radial force rises through the bite-in (the bite fills over the first
#   revolution) towards the 2kHLQ estimate; over two revolutions of the default mesh it is
#   about 1.2 × 2kHLQ (`docs/validation.md`).
# * The idle mandrel turns at the bore's rolling speed: its surface speed over the bore's is 1
#   to a few 1e-3 (the friction law's regularisation), its torque zero to its tolerance.

# %%
if rank0 and res.history:
    last = res.history[-1]
    rows = [("main roll radial force [kN]", res.main_force_mean / 1e3,
             res.force_estimate / 1e3, "2kHLQ"),
            ("mean diameter [mm]", last["mean_diameter"], last["mean_diameter_volume"],
             "V/(pi H B)"),
            ("mandrel surface speed [mm/s]", last["mandrel_omega"] * case.R2,
             last["bore_speed"], "bore speed")]
    print(f"{'':30s} {'FE':>10s} {'theory':>10s} {'FE/theory':>10s}")
    for name, fe, ref, what in rows:
        print(f"{name:30s} {fe:10.4g} {ref:10.4g} {fe / ref:10.4f}  ({what})")

# %% [markdown]
# ## The picture
#
# `results/ring_rolling/ring_rolling_top.png`: the ring's top face seen from above (outer
# and bore outlines, its centre +) and the tools (grey; the black radius shows each tool's
# angle) at four times: the main roll on the right, the mandrel in the bore, the guide rolls
# following the ring. `ring_rolling_curves.png`: the diameters against volume constancy, the
# roll forces against 2kHLQ and the rotation speeds against time.

# %%
if rank0 and res.pictures:
    print("outputs:", ", ".join(f"{k}: {p}" for k, p in res.pictures.items()))
