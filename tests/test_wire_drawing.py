"""Wire drawing (``fxcontact.processes.drawing``) and the thesis comparison harness
(benchmarks/bench_thesis_wire_drawing.py) at a reduced size: R₀ 5 → 3.75 mm (the thesis's
reduction), h = 1.5 mm, one third of the bar with an inclined symmetry plane, m = 0.016.

Checked against classical theory computed by the process (THEORY §14.2): the steady drawing stress
F/A₁ lies between the ideal work and 1.1 × Avitzur's upper bound (σ₀ of the Norton–Hoff law at
the die's mean strain rate), for the default die (10°, 43.75 %) and another one (15°, 27.75 %);
volume and element quality; the thesis's contact claims on the harness's own runs (implicit
against explicit penetration, dt × 4, Nagata against flat facets, true penetration measured
against the exact die, with the die sector meshed by gmsh as a CAD die would be; the claim
that does not hold at this size is a strict xfail with the measured figures); 1 vs 2 ranks; the harness's faceted variants on 2 ranks."""

import math
import os

import numpy as np
import pytest
from mpi4py import MPI

from fxcontact.processes import DrawingCase, run_drawing
from fxcontact.processes.die import die_tool

from helpers import load_file

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
bench = load_file("bench_thesis_wire_drawing",
                  os.path.join(ROOT, "benchmarks", "bench_thesis_wire_drawing.py"))


def _run(comm=None, **kw):
    return run_drawing(DrawingCase.quick(**kw), comm=comm)


@pytest.fixture(scope="module")
def default_case():
    res = _run()
    if MPI.COMM_WORLD.rank == 0:
        print("\n" + res.report())
    return res


@pytest.fixture(scope="module")
def other_case():
    res = _run(alpha=15.0, R1=4.25)
    if MPI.COMM_WORLD.rank == 0:
        print("\n" + res.report())
    return res


@pytest.fixture(scope="module")
def harness():
    """The harness at the test size: the thesis's dt (2.5 ms), 4 increments at dt, one at 4 dt."""
    rows = bench.run(quick=True, dt=2.5e-3, t_end=0.01, verbose=False)
    if MPI.COMM_WORLD.rank == 0:
        print("\n" + bench.table(rows))
    return {(r["variant"], r["dt_factor"]): r for r in rows}


def _band(res):
    assert res.status == "completed", res.message
    assert res.steady_stress is not None, "no steady state"
    th = res.theory
    sd = res.steady_stress
    assert th["ideal"] < sd < 1.1 * th["avitzur"], (sd, th["ideal"], th["avitzur"])
    assert res.max_volume_change < 5e-3
    assert res.min_quality > 0.05
    assert all(q["symmetry_violation"] < 1e-9 * res.case.speed for q in res.history)
    # power put in by the pull = plastic dissipation (+ friction), to the discretisation error;
    # with the penalty work, the discrete virtual-power identity
    assert abs(res.power_balance) < 0.05, res.power_balance
    assert abs(res.power_balance_penalty) < 1e-6, res.power_balance_penalty


@pytest.mark.serial   # a run to steady state; the MPI path: test_one_and_two_ranks_agree
@pytest.mark.slow
def test_default_drawing_stress_in_band(default_case):
    _band(default_case)


@pytest.mark.serial
@pytest.mark.slow
def test_other_angle_and_reduction_in_band(other_case):
    _band(other_case)
    assert other_case.theory["reduction"] == pytest.approx(1 - 0.85 ** 2)


@pytest.mark.serial   # ten runs; the MPI path of the demo: test_one_and_two_ranks_agree
@pytest.mark.slow
def test_harness_table_complete(harness):
    """Every variant at dt and 4 dt ran to the end with finite figures; the table has them."""
    assert len(harness) == 2 * len(bench.VARIANTS)
    for (label, k), r in harness.items():
        assert r["status"] == "completed", (label, k, r["message"])
        assert r["time"] == pytest.approx(0.01)
        for key in ("max_penetration", "max_penetration_tool", "steady_force", "newton_mean",
                    "wall"):
            assert math.isfinite(r[key]), (label, k, key)
        assert r["contact_nodes_01"] > 0
        assert r["max_volume_change"] < 5e-3 and r["min_quality"] > 0.05
        th = r["ideal"], 1.1 * r["avitzur"]
        assert th[0] < r["steady_stress"] < th[1], (label, k, r["steady_stress"], th)
        if r["die"] == "exact":   # the true penetration is the library's own for the exact die
            assert r["max_penetration"] == pytest.approx(r["max_penetration_tool"], rel=1e-12)
    text = bench.table(list(harness.values()))
    for label in bench.VARIANTS:
        assert text.count(f"| {label}") == 2


@pytest.mark.serial
@pytest.mark.slow
def test_implicit_penetration_below_a_third_of_explicit(harness):
    """The thesis (Tab. V-4): implicit + facets penetrates 1/3 of explicit + facets (the
    penetration into the faceted die itself: the schemes' error on the same tool; the true
    penetration into the exact die adds the facets' chord error, the same for both)."""
    ex = harness[("explicit + flat (Forge standard)", 1)]["max_penetration_tool"]
    im = harness[("implicit + flat", 1)]["max_penetration_tool"]
    assert im <= ex / 3.0, (im, ex)


@pytest.mark.serial
@pytest.mark.slow
def test_implicit_penetration_independent_of_dt(harness):
    """The thesis (Tab. V-5): with 4 dt the implicit penetration does not change (< 25 %),
    the explicit one grows."""
    for label in ("implicit + Nagata", "implicit + exact die"):
        a, b = (harness[(label, k)]["max_penetration_tool"] for k in (1, 4))
        assert abs(b - a) < 0.25 * a, (label, a, b)
    a, b = (harness[("explicit + flat (Forge standard)", k)]["max_penetration_tool"]
            for k in (1, 4))
    assert b > 1.25 * a, (a, b)


@pytest.mark.serial
@pytest.mark.slow
def test_nagata_penetration_closer_to_exact_than_flat(harness):
    """Nagata's true penetration (into the exact die) is closer to the exact die's than the flat
    facets' (implicit scheme, dt; the same gmsh die mesh)."""
    ex, na, fl = (harness[(v, 1)]["max_penetration"] for v in (
        "implicit + exact die", "implicit + Nagata", "implicit + flat"))
    assert abs(na - ex) < abs(fl - ex), (ex, na, fl)


@pytest.mark.serial
@pytest.mark.xfail(strict=True, reason=(
    "measured at the test size (h = 1.5 mm, 1 mm gmsh facets, implicit, t = 0.01 s): contact "
    "nodes exact 49, Nagata 49, flat 49 - the zones are the same to a node, Nagata is not "
    "closer; at the reduced thesis size see benchmarks/README.md"))
@pytest.mark.slow
def test_nagata_contact_zone_closer_to_exact_than_flat(harness):
    """Nagata's contact zone (contact nodes) is closer to the exact die's than the flat facets'
    (implicit scheme, dt)."""
    ex, na, fl = (harness[(v, 1)]["contact_nodes_01"] for v in (
        "implicit + exact die", "implicit + Nagata", "implicit + flat"))
    assert abs(na - ex) < abs(fl - ex), (ex, na, fl)


def test_one_and_two_ranks_agree():
    """Three increments on all ranks and on COMM_SELF agree to 1e-8 (meaningful under
    ``mpirun -n 2``; serially the two runs are the same computation)."""
    if MPI.COMM_WORLD.size == 1:
        pytest.skip("compares the ranks of COMM_WORLD with one rank: run under mpirun -n 2")
    hs = []
    for comm in (MPI.COMM_WORLD, MPI.COMM_SELF):
        res = _run(comm=comm, t_end=3 * DrawingCase.QUICK["dt"], stop_at_steady=False)
        hs.append(res.history)
    assert len(hs[0]) == len(hs[1]) == 3
    for a, b in zip(*hs):
        for k in ("drawing_force", "penetration_true", "dissipation"):
            assert abs(a[k] - b[k]) <= 1e-8 * abs(b[k]), (k, a[k], b[k])
        assert a["contact_nodes"] == b["contact_nodes"]
        assert abs(a["volume_change"] - b["volume_change"]) <= 1e-11


def test_harness_on_all_ranks():
    """The harness's faceted variants (the tools that MPI could break: flat and Nagata
    projections) for one increment on all ranks (serially the whole table runs above)."""
    if MPI.COMM_WORLD.size == 1:
        pytest.skip("serially the whole harness runs in test_harness_table_complete")
    labels = ["explicit + flat (Forge standard)", "implicit + Nagata"]
    rows = bench.run(quick=True, t_end=DrawingCase.QUICK["dt"], factors=(1,), variants=labels,
                     verbose=False)
    assert [r["variant"] for r in rows] == labels
    for r in rows:
        assert r["status"] == "completed" and r["increments"] == 1, r["message"]
        for key in ("max_penetration", "steady_force", "newton_mean"):
            assert math.isfinite(r[key]), (r["variant"], key)
        assert r["ideal"] < r["steady_stress"] < 1.1 * r["avitzur"]
    assert bench.table(rows).count("|") > 20


def test_gmsh_die_sector_lies_on_the_exact_die():
    """The unstructured (gmsh) die sector: vertices on the exact surface, spanning 0-120°,
    oriented so that the faceted gap has the exact gap's sign (inside the bar's side > 0)."""
    case = DrawingCase.quick(die="flat", die_mesh="gmsh")
    g = case.layout()
    from fxcontact.processes.die import die_profile_tool
    exact = die_profile_tool(g, case.R1, case.alpha, case.land, case.fillet, case.relief_length)
    tool, sag = die_tool(exact, case.die, case.die_mesh, case.sector, g.facet, g.h, case.R0,
                         case.R1, case.fillet, MPI.COMM_WORLD)
    V = tool.vertices
    assert np.max(np.abs(exact.project(V, 0.0, hessian=False).gap)) < 1e-10
    th = np.degrees(np.arctan2(V[:, 1], V[:, 0]))
    assert th.min() == pytest.approx(0.0, abs=1e-9) and th.max() == pytest.approx(120.0)
    rng = np.random.default_rng(1)
    r, t = rng.uniform(1.0, 3.5, 50), np.radians(rng.uniform(5, 115, 50))
    z = rng.uniform(exact.points[0, 0], exact.points[-1, 0], 50)
    x = np.stack([r * np.cos(t), r * np.sin(t), z], 1)
    ge, gt = exact.project(x, 0.0).gap, tool.project(x, 0.0).gap
    assert np.all(np.sign(ge) == np.sign(gt))
    assert np.max(np.abs(ge - gt)) < 2 * sag + 1e-12


def test_bad_parameters():
    """A bad field of the case raises at the case, naming the field."""
    with pytest.raises(TypeError, match="radius"):
        DrawingCase.quick(radius=3.0)
    with pytest.raises(ValueError, match="R1"):
        DrawingCase.quick(R1=12.0)
    with pytest.raises(ValueError, match="die"):
        DrawingCase.quick(die="smooth")
    with pytest.raises(ValueError, match="implicit-exact"):
        DrawingCase.quick(die="flat", scheme="implicit-exact")
    with pytest.raises(ValueError, match="too short"):
        DrawingCase.quick(length=10.0)
    with pytest.raises(ValueError, match="alpha"):
        DrawingCase.quick().replace(alpha=50.0)
    with pytest.raises(ValueError, match="newton_rtol"):
        DrawingCase.quick(newton_rtol=0.0)
    with pytest.raises(ValueError, match="newton_ftol"):
        DrawingCase.quick(newton_ftol=1.0)


@pytest.fixture(scope="module")
def three_increments():
    """Three increments of the quick case at the default Newton tolerances (the reference of
    the looser-tolerance tests)."""
    return _run(t_end=3 * DrawingCase.QUICK["dt"], stop_at_steady=False)


def _looser_same_stress(ref, bound, **tolerance):
    """The run with ``tolerance`` against ``ref``: the drawing stress at every increment
    within ``bound`` (relative) and no more Newton iterations in the first increment (same
    start, same iterates); returns the looser run."""
    b = _run(t_end=3 * DrawingCase.QUICK["dt"], stop_at_steady=False, **tolerance)
    assert len(ref.history) == len(b.history) == 3
    for qa, qb in zip(ref.history, b.history):
        print("drawing stress", qa["drawing_stress"], qb["drawing_stress"],
              "Newton", qa["newton_iterations"], qb["newton_iterations"])
        assert abs(qb["drawing_stress"] - qa["drawing_stress"]) <= bound * abs(qa["drawing_stress"])
    assert b.history[0]["newton_iterations"] <= ref.history[0]["newton_iterations"]
    return b


@pytest.mark.slow
def test_newton_rtol_looser_same_drawing_stress(three_increments):
    """Newton's relative tolerance 1e-6 instead of 1e-9: the same drawing stress at every
    increment within 1e-5, 500x below the 0.5 % accepted for the drawing stress (measured:
    5.4e-6 at this size, 5e-8 at size 0.4); the later increments start from states that differ
    by the tolerance: their counts are not compared."""
    _looser_same_stress(three_increments, 1e-5, newton_rtol=1e-6)


@pytest.mark.slow
def test_force_tolerance_same_drawing_stress(three_increments):
    """Newton stopped at ‖R‖ ≤ 1e-3 × the die's nodal force norm (``newton_ftol=1e-3``)
    against the default relative tolerance 1e-9 alone: the same drawing stress at every
    increment within 1e-3, 5x below the 0.5 % accepted for the drawing stress (measured
    3.9e-4 at this size, 2.4e-7 at size 0.7), and fewer Newton iterations over the run (the
    option's purpose; measured 21 against 28)."""
    assert DrawingCase.quick().newton_ftol == 0.0
    b = _looser_same_stress(three_increments, 1e-3, newton_ftol=1e-3)
    assert (sum(q["newton_iterations"] for q in b.history)
            < sum(q["newton_iterations"] for q in three_increments.history))
