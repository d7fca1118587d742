"""Ring rolling (fxcontact.processes.ring_rolling, fxcontact.idle): controlled tool motion, the idle
mandrel (zero torque about its axis), centring by guide rolls, the cylindrical update's volume
and the volume-constancy growth, on a short coarse run (two increments of the thesis's case 2);
the ring-rolling theory itself is tested in test_forming.py."""

import math
from dataclasses import replace

import numpy as np
import pytest
from mpi4py import MPI

from fxcontact.contact.friction import Norton
from fxcontact.idle import ControlledMotion
from fxcontact.processes import RingRollingCase, ring_rolling

from helpers import run_readme_block, shared_tmpdir

NI = RingRollingCase().quick().increments_per_rev
#: two increments of the quick (coarse) case 2: Coulomb friction on the main roll and the mandrel
SHORT = replace(RingRollingCase.case2().quick(), revolutions=2.0 / NI)


def test_controlled_motion_is_integrated_exactly():
    """Piecewise-constant rates set per increment: translation and angle are the exact sums,
    a second call at the same time overwrites the stage (a retried increment), the past cannot
    be changed."""
    m = ControlledMotion(velocity=(1.0, 0.0, 0.0), angular_velocity=2.0, axis_point=(0, 0, 0))
    m.set_rates(0.5, velocity=(0.0, 3.0, 0.0), angular_velocity=-1.0)
    m.set_rates(0.5, angular_velocity=4.0)          # the same increment, another trial
    m.set_rates(0.75, velocity=(0.0, 0.0, 1.0))
    assert np.allclose(m.translation(1.0), [0.5, 0.75, 0.25])
    assert m.angle(1.0) == pytest.approx(2.0 * 0.5 + 4.0 * 0.5)
    assert m.angle(0.25) == pytest.approx(0.5)      # earlier stages are kept
    # rates are right-continuous; the axis moved with the tool to (0.5, 0.75, 0)
    v = m.point_velocity(np.array([[1.0, 0.0, 0.0]]), 0.75)[0]
    assert np.allclose(v, np.array([0.0, 0.0, 1.0]) + 4.0 * np.cross([0, 0, 1.0],
                                                                      [0.5, -0.75, 0.0]))
    with pytest.raises(ValueError, match="before the current stage"):
        m.set_rates(0.6, angular_velocity=0.0)
    with pytest.raises(ValueError, match="constant initial rates"):
        ControlledMotion(angular_velocity=lambda t: t)


@pytest.fixture(scope="module")
def short():
    res = ring_rolling.run(SHORT, output_dir=shared_tmpdir("fxc-ring-"))
    if MPI.COMM_WORLD.rank == 0:
        print("\n" + res.report())
    return res


def test_report_rows_and_pictures(short):
    """The result's summary, its rows and pictures: the theory of the pass (feed window,
    contact length, 2kHLQ), the thesis's K flagged, the CSV and the two PNGs."""
    text = short.report()
    for line in ("feed per revolution 1.000 mm", "-> inside", "sigma0 = 4070 MPa",
                 "taken literally", "x 2kHLQ", "mandrel surface / bore speed",
                 "'main_roll' Coulomb(mu=0.3, mbar=0.6), k of the material at each node's local strain rate"):
        assert line in text, text
    # two increments asked; on 2 ranks this run's Newton path follows parallel MUMPS's round-off
    # and one run in six cuts an increment back (measured on the code before the packages by
    # concern too): the end of the run is what is checked, not the number of steps to it
    assert short.increments >= 2 and short.revolutions == pytest.approx(2.0 / NI)
    assert short.main_force_mean > 0 and short.mandrel_force_mean > 0
    assert 0.9 < short.mandrel_speed_ratio < 1.1
    assert short.min_quality > 0.1 and short.max_volume_change < 5e-3
    assert set(short.pictures) == {"csv", "top_view", "curves"}
    if MPI.COMM_WORLD.rank == 0:
        import os
        for path in short.pictures.values():
            assert os.path.getsize(path) > 1000, path


@pytest.mark.serial   # the README's example: a few increments of the hot steel's case
@pytest.mark.slow
def test_readme_example(tmp_path):
    """The README's ring rolling block runs (shortened to two increments)."""
    ns = run_readme_block("Ring rolling", {
        "case.quick()": "replace(case.quick(), revolutions=2.0 / 50)",
        '"results/ring_rolling"': repr(str(tmp_path))})
    res = ns["result"]
    assert res.status == "done" and res.increments == 2
    assert 80.0 < res.sigma0 < 150.0           # hot 42CrMo4, not the thesis's K
    assert 1.0 / 3.0 < res.main_force_mean / res.force_estimate < 3.0


def test_idle_mandrel_zero_torque_and_rolling_speed(short):
    """The idle mandrel's torque is zero to its tolerance (the Newton tolerance × |F| R̄) at
    every increment, and its surface speed is the bore's rolling speed: the slip left is the
    friction's regularisation scale (v₀ = 1e-3 of the roll speed), not a free-wheeling
    mismatch."""
    h = short.history
    assert short.status == "done" and len(h) >= 2    # a cut-back adds a row (see above)
    v0 = 1e-3 * 2 * math.pi * 150.0          # 60 rpm main roll R1 = 150
    for q in h:
        assert q["nodes_mandrel"] > 0
        assert 0 < q["mandrel_idle_tolerance"] < 1e-3 * abs(q["mandrel_force_x"]) * 40.0
        assert abs(q["mandrel_idle_torque"]) <= q["mandrel_idle_tolerance"]
        assert abs(q["mandrel_surface_slip"]) < 5 * v0, q["mandrel_surface_slip"]
        # the mandrel's ω R2 against the bore's speed (ring ω × inner radius)
        assert q["mandrel_omega"] * 40.0 == pytest.approx(q["bore_speed"], rel=0.02)


def test_power_balance(short):
    """What the tools deliver equals the dissipation (on the increment's start configuration),
    the friction power and the penalty work to 1e-5 at every increment: the discrete
    virtual-power identity, whose error is Newton's (relative residual 1e-9, times the ratio of
    the tools' power to the power balanced, a few, and the condition of the sum of powers of
    both signs). The main roll delivers its torque × ω; the idle mandrel's rotation nothing
    (its torque is zero to its tolerance), its feed its force × feed speed. Without the
    penalty work the balance does not close in this coarse run: the ring turns by
    more than the bite's length per increment (``bite_increments`` < 1)."""
    w1 = 2 * math.pi                          # 60 rpm
    for q in short.history:
        assert abs(q["power_balance_penalty"]) < 1e-5, q["power_balance_penalty"]
        assert q["dissipation"] > 0 and q["friction_power"] > 0
        assert q["main_power"] == pytest.approx(q["main_torque"] * w1, rel=1e-10)
        assert q["mandrel_power"] == pytest.approx(-q["mandrel_force_x"] * 1.5, rel=1e-8)
        assert abs(q["mandrel_rotation_power"]) <= q["mandrel_idle_tolerance"] * q["mandrel_omega"]
        assert q["power_in"] == pytest.approx(q["main_power"] + q["mandrel_power"]
                                              + q["guide_power"], rel=1e-10)
    assert abs(short.power_balance_penalty) < 1e-5
    assert short.bite_increments < 1.0
    assert "balance P_in/(D + P_f) - 1" in short.report()


def test_ring_stays_centred_and_keeps_its_volume(short):
    """The centroid stays on the mill line within a fraction of the circumferential spacing;
    the cylindrical update keeps the volume (no volume correction in the demo) to 0.5 %, and
    the mean diameter equals the volume-constancy value V/(πHB) of the measured section within
    2 %."""
    h = short.history
    for q in h:
        assert q["center_offset"] < 0.1 * short.h_theta, q["center_offset"]
        assert abs(q["volume_change"]) < 5e-3
        assert q["mean_diameter"] == pytest.approx(q["mean_diameter_volume"], rel=0.02)


def test_main_roll_force_order_of_2kHLQ(short):
    """The main roll's radial force (whole ring) is of the order of the 2kHLQ estimate with the
    bite's contact length (THEORY §14.4): within a factor 3 either way after the bite-in (the
    estimate uses σ₀ at a nominal strain rate; the first increments are not steady)."""
    F = short.history[-1]["main_force_x"]      # the ring pushes the main roll towards +x
    ratio = F / short.force_estimate
    print(f"main roll force {F / 1e3:.0f} kN, 2kHLQ {short.force_estimate / 1e3:.0f} kN, "
          f"ratio {ratio:.2f}")
    assert 1.0 / 3.0 < ratio < 3.0


def test_one_and_two_ranks_agree(short):
    """The first increment on all ranks (the module's run) and on COMM_SELF agree to 1e-8
    (serially: the same computation twice)."""
    res = ring_rolling.run(replace(SHORT, revolutions=1.0 / NI), comm=MPI.COMM_SELF)
    hs = [short.history[:1], res.history]
    assert len(hs[1]) == 1
    for a, b in zip(*hs):
        for k in ("main_force_x", "main_torque", "mandrel_force_x", "mandrel_omega",
                  "ring_omega", "outer_diameter", "dissipation", "power_in", "penalty_power"):
            assert abs(a[k] - b[k]) <= 1e-8 * abs(b[k]), (k, a[k], b[k])


def test_force_tolerance_same_forces_fewer_iterations(short):
    """``newton_ftol=1e-3`` (Newton stops at ‖R‖ ≤ 1e-3 × the contacts' nodal force norm)
    against the default relative tolerance alone: the roll forces and the idle mandrel's speed
    within 1e-4 (measured 7.5e-6; the tools' input power moves by 3e-3 and the dissipation by
    1.1e-4 on this coarse quick ring, where the tolerance is loose: not held here) and no
    more Newton iterations in the first increment (same start, same iterates: the looser test
    stops no later), on the first increment only: the second starts from states that differ
    by the tolerance and the ring's Newton path is chaotic there (2-rank runs took 29 against
    27 iterations over both, and once a cut-back; at the demo size 9.3 against 11.0 per
    increment)."""
    res = ring_rolling.run(replace(SHORT, revolutions=1.0 / NI, newton_ftol=1e-3))
    assert len(res.history) == 1
    for a, b in zip(short.history[:1], res.history):
        for k in ("main_force_x", "mandrel_force_x", "mandrel_omega"):
            assert abs(a[k] - b[k]) <= 1e-4 * abs(a[k]), (k, a[k], b[k])
    assert res.history[0]["newton_iterations"] <= short.history[0]["newton_iterations"]


def test_bad_parameters():
    """The case checks its fields when it is made, naming the field."""
    with pytest.raises(TypeError, match="radius"):
        RingRollingCase(radius=3.0)
    with pytest.raises(ValueError, match="mandrel R2 < bore r"):
        RingRollingCase(R2=70.0)
    with pytest.raises(ValueError, match="update must be one of"):
        RingRollingCase(update="polar")
    with pytest.raises(ValueError, match="main_friction must be None or"):
        RingRollingCase(main_friction=("tresca", 0.3, 0.6))
    with pytest.raises(ValueError, match="n_theta must be an integer"):
        RingRollingCase(n_theta=0)
    with pytest.raises(ValueError, match="idle_method must be one of"):
        RingRollingCase(idle_method="free")
    # a friction given on the command line (the former spelling of friction["mandrel"])
    assert RingRollingCase(mandrel_friction="norton,0.5,0.15").friction["mandrel"] == \
        Norton(0.5, 0.15)
    assert "mandrel" not in RingRollingCase(mandrel_friction="none").friction


def test_thesis_flow_stress_flagged():
    """The thesis's K = 1900 taken literally gives sigma0 = 4070 MPa for a hot ring: the case
    says so; the default hot-working K gives about 107 MPa (forces scale with K)."""
    thesis, hot = RingRollingCase.case2(), RingRollingCase()
    assert "taken literally" in thesis.thesis_flow_stress_note
    assert hot.thesis_flow_stress_note == ""
    s_thesis = ring_rolling.theory(thesis)["sigma0"]
    s_hot = ring_rolling.theory(hot)["sigma0"]
    assert s_thesis == pytest.approx(4070.0, rel=1e-3)
    assert 80.0 < s_hot < 150.0
    assert s_hot / s_thesis == pytest.approx(hot.K / thesis.K, rel=1e-12)


#: the penetration comparison: case 1 (no idle iteration), a dt-independent gap stiffness
#: k = 5e5 MPa/mm (penalty penetration p/k ≈ 0.013 mm at the ~6.7 GPa of K = 1900 MPa)
PEN = replace(RingRollingCase.case1(gap_stiffness=5e5).quick(), revolutions=2.0 / NI)


@pytest.fixture(scope="module")
def implicit_pen():
    return ring_rolling.run(PEN)


@pytest.mark.serial   # three more short runs; the MPI path is test_one_and_two_ranks_agree
@pytest.mark.slow
def test_implicit_penetration_is_dt_insensitive(implicit_pen):
    """Implicit contact, analytic tools, cylindrical update, gap stiffness k: the largest true
    penetration over the same time at dt and 2 dt differs by less than 25 % (measured over
    0.08 revolution in the benchmark: 0.0202 and 0.0181 mm)."""
    twice = ring_rolling.run(replace(PEN, increments_per_rev=NI // 2))
    p1, p2 = implicit_pen.max_penetration, twice.max_penetration
    print(f"implicit penetration dt {p1:.4f} mm, 2 dt {p2:.4f} mm")
    assert p1 > 0 and abs(p2 / p1 - 1.0) < 0.25


@pytest.mark.serial
@pytest.mark.xfail(strict=True, reason="the thesis's ordering (implicit + analytic 0.014 mm vs "
                   "explicit + faceted 0.33 mm) is not reproduced: on these convex tools the explicit "
                   "(tangent-plane) condition leaves no node inside the facets nor inside the "
                   "exact cylinders (0.0000 mm over 0.08 rev: its nodes end outside, by about "
                   "(v dt)^2/2R), implicit + analytic 0.020 mm (the penalty compliance p/k); "
                   "benchmarks/README.md")
@pytest.mark.slow
def test_implicit_penetration_below_a_tenth_of_explicit_faceted(implicit_pen):
    explicit = ring_rolling.run(replace(PEN, scheme="explicit", tools="faceted",
                                        update="cartesian"))
    p_imp, p_exp = implicit_pen.max_penetration, explicit.max_penetration_exact
    print(f"penetration implicit + analytic {p_imp:.4f} mm, explicit + faceted {p_exp:.4f} mm "
          f"(against the exact tools; {explicit.max_penetration:.4f} mm against its facets)")
    assert implicit_pen.max_penetration_exact == pytest.approx(p_imp, rel=1e-9)
    assert p_imp <= 0.1 * p_exp


def test_command_line_of_the_case():
    """The demo's command line (console.case_parser) types every field of the case: strings
    (idle_method), on/off (cones), a friction "law,a,b" or none, auto|on|off
    (active_set_prediction); a bad on/off value is refused by argparse."""
    from fxcontact.console import case_parser, parse_case
    parser = case_parser(RingRollingCase, "ring rolling", "results")
    case, _ = parse_case(parser, RingRollingCase, [
        "--quick", "--idle_method", "outer", "--cones", "on", "--cone_speed", "0.4",
        "--mandrel_friction", "none", "--main_friction", "norton,0.5,0.15",
        "--active_set_prediction", "off", "--R", "110"])
    assert (case.idle_method, case.cones, case.cone_speed) == ("outer", True, 0.4)
    assert case.friction == {"main_roll": Norton(0.5, 0.15)}
    assert case.active_set_prediction is False
    assert case.R == 110.0 and case.n_theta == RingRollingCase().quick().n_theta
    with pytest.raises(SystemExit):
        parse_case(parser, RingRollingCase, ["--cones", "maybe"])
