"""Flat rolling to steady state (fxcontact.processes.flat_rolling) at a reduced size: coarse mesh
(7.5 mm along the strip, 2 elements through the half-thickness, 3 across the half-width), a
short strip, 1.5 mm of roll travel per increment. Checked against the classical theories of
THEORY §14.3 computed by the process (fxcontact.theory.flat_rolling): roll force per unit width in the band of
slab (same Coulomb–Tresca law) / Sims / Ford–Alexander within 15 %, forward slip positive and
within × 1.5 of the slab's, neutral point inside the arc, spread positive and compared with
Hill's, power balance within 3 %, volume and element quality; refusal to enter with μ ≪ tan α;
another pass (radius, reduction, μ); 1 vs 2 ranks; the case's checks; the demo and the
README's example run."""

import math
import re
from dataclasses import replace

import pytest
from mpi4py import MPI

from fxcontact.processes import FlatRollingCase, flat_rolling

from helpers import run_readme_block, shared_tmpdir

#: the reduced size of the tests
QUICK = FlatRollingCase().quick()


def _run(tmp, case=QUICK, **kw):
    out = str(tmp) if MPI.COMM_WORLD.rank == 0 else None
    out = MPI.COMM_WORLD.bcast(out, root=0)
    return flat_rolling.run(replace(case, **kw), output_dir=out, pictures=False)


@pytest.fixture(scope="module")
def default_pass(tmp_path_factory):
    res = _run(tmp_path_factory.mktemp("rolling"))
    if MPI.COMM_WORLD.rank == 0:
        print("\n" + res.report())
    return res


@pytest.fixture(scope="module")
def other_pass(tmp_path_factory):
    res = _run(tmp_path_factory.mktemp("rolling2"),
               FlatRollingCase(R=200.0, reduction=0.2, mu=0.25).quick(), h_x=5.5)
    if MPI.COMM_WORLD.rank == 0:
        print("\n" + res.report())
    return res


def _acceptance(res):
    """The acceptance items that hold at the test size for both passes."""
    assert res.status == "steady", res.message
    th = res.theory
    F = res.force_per_width
    assert 0.85 * th["force_min"] <= F <= 1.15 * th["force_max"], (F, th)
    assert res.forward_slip > 0
    assert 0.0 < res.neutral_angle < res.bite_angle
    assert res.spread > 0
    # Hill's formula is an empirical fit: compared, within a factor 2
    assert res.spread_hill / 2 < res.spread < 2 * res.spread_hill
    # torque x omega against dissipation + friction work (penalty work left out) ...
    assert abs(res.power_balance) < 0.03, res.power_balance
    # ... and with the penalty work the balance is the discrete virtual-power identity
    assert abs(res.power_balance_penalty) < 1e-3, res.power_balance_penalty
    # the tail's pseudo-inertia does no work on average at steady state
    assert abs(res.damper_power) < 0.02 * abs(res.roll_power), res.damper_power
    assert res.max_volume_change < 5e-3
    assert res.min_quality > 0.05
    assert res.gripped_at is not None          # the pusher let go: the roll drives alone
    assert all(q["pusher_nodes"] == 0 for q in res.window())
    assert "steady from increment" in res.report()


def _slip_within_factor(res, factor=1.5):
    fs, fs_slab = res.forward_slip, res.theory["slab_forward_slip"]
    assert fs_slab / factor <= fs <= factor * fs_slab, (fs, fs_slab)


@pytest.mark.serial   # a whole pass to steady state; the MPI path: test_one_and_two_ranks_agree
@pytest.mark.slow
def test_default_pass(default_pass):
    _acceptance(default_pass)
    _slip_within_factor(default_pass)
    assert "k of the material at each node's local strain rate" in default_pass.report()     # which k the Tresca cap uses


@pytest.mark.serial   # a whole pass to steady state; the MPI path: test_one_and_two_ranks_agree
@pytest.mark.slow
def test_other_radius_reduction_friction(other_pass):
    """R = 200 mm, 20 % reduction, μ = 0.25."""
    _acceptance(other_pass)


@pytest.mark.serial   # a whole pass to steady state; the MPI path: test_one_and_two_ranks_agree
@pytest.mark.xfail(strict=True, reason="the forward slip of the R = 200 mm, 20 %, mu = 0.25 pass "
                   "is 5.3 % against the slab's 2.7 % (x 1.9) at the test size, and still 5.3 % "
                   "with 3.5 mm elements and 3 through the half-thickness (not a mesh effect at "
                   "these sizes); the FE neutral angle is 0.062 rad against the slab's 0.054, "
                   "and the slab formula with the FE neutral angle gives 3.7 %: the rest is the "
                   "slab's plane-section assumption (this pass is thicker for its bite, mean "
                   "h / L = 0.71 against 0.47 for the default pass: 6.9 % against 5.1 %, x 1.36)")
@pytest.mark.slow
def test_other_pass_forward_slip(other_pass):
    _slip_within_factor(other_pass)


def test_refuses_to_enter_below_the_bite_condition(tmp_path):
    """μ = 0.05 ≪ tan α = 0.154: the pusher keeps carrying the strip, the run stops after the
    allowed push and says why (no hang)."""
    res = _run(tmp_path, mu=0.05, grip_travel=0.15, max_increments=40)
    assert res.status == "refused"
    assert "refuses to enter" in res.message and "tan(alpha)" in res.message
    assert res.increments < 15
    assert all(q["pusher_nodes"] > 0 for q in res.history[1:])


@pytest.mark.slow
def test_one_and_two_ranks_agree(tmp_path):
    """Three increments on all ranks and on COMM_SELF agree to 1e-8."""
    hs = []
    for comm in (MPI.COMM_WORLD, MPI.COMM_SELF):
        res = flat_rolling.run(replace(QUICK, max_increments=3), comm=comm, output_dir=None,
                               pictures=False)
        hs.append(res.history)
    assert len(hs[0]) == len(hs[1]) == 3
    for a, b in zip(*hs):
        for k in ("force_per_width", "torque_per_width", "dissipation", "friction_power",
                  "pusher_force"):
            assert abs(a[k] - b[k]) <= 1e-8 * abs(b[k]), (k, a[k], b[k])
        # V/V0 - 1 (about 6e-6 here) is a difference of sums over cells: compared to 1e-11 of
        # the volume (measured 1e-13)
        assert abs(a["volume_change"] - b["volume_change"]) <= 1e-11


@pytest.mark.parametrize("field,value,words", [
    ("reduction", 1.2, "reduction must be in (0, 0.8)"),
    ("R", -300.0, "R must be a finite number > 0"),
    ("dt", math.nan, "dt must be a finite number > 0"),
    ("tail_damping", -1.0, "tail_damping must be a finite number >= 0"),
    ("nose", 1.0, "nose (fraction of the bite initially filled) must be in (0, 1)"),
    ("mbar", 1.5, "mbar (Tresca factor) must be in [0, 1]"),
    ("ny", 2.5, "ny must be an integer >= 1"),
    ("roll", "bezier", "roll must be one of"),
    ("newton_ftol", 1.0, "newton_ftol must be in [0, 1)"),
    ("newton_ftol", math.nan, "newton_ftol must be in [0, 1)"),
])
def test_bad_case(field, value, words):
    """The case refuses a bad field when it is made, naming the field and its range."""
    with pytest.raises(ValueError, match=re.escape(words)):
        FlatRollingCase(**{field: value})
    with pytest.raises(ValueError, match=re.escape(words)):
        replace(QUICK, **{field: value})
    with pytest.raises(TypeError, match="radius"):
        FlatRollingCase(radius=3.0)


@pytest.mark.slow
def test_force_tolerance_same_forces_fewer_iterations(tmp_path):
    """``newton_ftol=1e-3`` (the case's field, shared by the process cases: Newton stops at
    ‖R‖ ≤ 1e-3 × the roll's nodal force norm) against the default rtol alone, ten increments
    of the quick pass: the roll force per unit width and the dissipation within 1e-3 at every
    increment, fewer Newton iterations in all. Measured (serial, 30 increments): 415 against
    492 iterations, the force within 5.5e-5, the dissipation within 8.2e-5."""
    assert QUICK.newton_ftol == 0.0
    runs = [_run(tmp_path / f"ftol{f}", newton_ftol=f, max_increments=10).history
            for f in (0.0, 1e-3)]
    assert len(runs[0]) == len(runs[1]) == 10
    for a, b in zip(*runs):
        for k in ("force_per_width", "dissipation"):
            assert abs(b[k] - a[k]) <= 1e-3 * abs(a[k]), (a["increment"], k, a[k], b[k])
    its = [sum(r["newton_iterations"] for r in h) for h in runs]
    assert its[1] < its[0], its


def test_readme_example():
    """The README's flat-rolling example, cut to two increments, runs and reports."""
    ns = run_readme_block("Flat rolling", {
        "case.quick()": "replace(case.quick(), max_increments=2)",
        '"results/flat_rolling"': repr(shared_tmpdir("fxc-flat-readme-"))})
    assert ns["result"].increments == 2 and ns["result"].status == "no steady state"


@pytest.mark.serial   # a dozen increments of a finer mesh; the MPI path: the 1 vs 2 ranks test
@pytest.mark.slow
def test_finer_mesh_not_lost_after_release(tmp_path):
    """A finer mesh and a shorter increment than the test size (5 mm elements, 3 through the
    half-thickness, dt = 1.5 ms): once the pusher has let go the roll alone drives the strip
    (without the tail's pseudo-inertia, Newton has a nearly free x-translation there: 7.5 mm
    elements with dt = 1.9 ms fail at the second increment with dt/32, and 3.5 mm elements were
    thrown out of the bite at t = 15 ms). The strip stays in the bite and moves forward at every
    increment, faster than the pusher pushed it. (This mesh also runs these 9 increments without
    the pseudo-inertia, with a cut-back at t = 6 ms and 69 Newton iterations there: the test
    guards the release on a finer mesh, it does not single out the cure; the runs that need
    the cure are too long for the suite.)"""
    res = _run(tmp_path, h_x=5.0, nz=3, dt=1.5e-3, max_increments=9)
    assert res.status == "no steady state" and "max_increments" in res.message
    h = res.history
    assert res.gripped_at is not None and res.gripped_at <= 4 * 1.5e-3
    after = [q for q in h if q["time"] > res.gripped_at]
    assert len(after) >= 6
    assert all(q["contact_nodes"] > 0 and q["pusher_nodes"] == 0 for q in after)
    v_push = QUICK.push_ratio * QUICK.v_roll * (1 - 0.28)
    fronts = [q["front"] for q in h]
    for a, b in zip(fronts[:-1], fronts[1:]):
        assert b - a > 0
    assert (h[-1]["tail"] - h[-2]["tail"]) / 1.5e-3 > v_push
    # (the pseudo-inertia still works here, 4 % of the roll's power over the last 6
    # increments, while the bite fills; that it does no work at steady state is checked with
    # the whole passes, _acceptance)
