"""Round bar in a turning faceted groove (concave tool, ``fxcontact.processes.groove``) at
reduced size, serially and on 2 ranks: the analytic bore is invariant under the rotation, the
Nagata groove carries the bore's force without the flat facets' oscillation, converges where the
flat fine groove fails (facet switching), and 1 vs 2 ranks agree."""

import math
import os

import numpy as np
import pytest
from mpi4py import MPI

from fxcontact.processes import groove, ironing
from helpers import assert_histories_match, assert_newton_counts_match, shared_tmpdir

NAGATA, FLAT, ANALYTIC = "nagata-coarse-implicit", "flat-coarse-implicit", "analytic-implicit"


@pytest.fixture(scope="module")
def quick():
    d = shared_tmpdir("fxc-groove-")
    res = groove.run(**groove.QUICK, output_dir=d, progress=False, newton_rtol=1e-12)
    return d, res


@pytest.mark.slow
def test_outputs_and_equilibrium(quick):
    d, res = quick
    assert [row["variant"] for row in res["summary"]] == [ANALYTIC, FLAT, NAGATA]
    for row in res["summary"]:
        assert row["status"] == "ok" and row["cutbacks"] == 0, row
        assert row["fallbacks"] == 0
        # penalty penetration negligible against δ = 50 µm
        assert 0.0 < row["penetration_max"] < 1e-3 * 0.05
    # the three grooves share their lowest point (a valley on the true circle)
    for name in (ANALYTIC, FLAT, NAGATA):
        assert abs(res["by_name"][name]["tool_bottom_gap"]) < 1e-12
    # inscribed flat facets stand proud of the circle by R(1 − cos(π/n)) at their middles
    assert abs(res["by_name"][FLAT]["tool_dev_out"] - 6.0 * (1 - math.cos(math.pi / 36))) < 1e-6
    for name in (ANALYTIC, FLAT, NAGATA):
        last = res["results"][name]["history"][-1]
        # the tool pushes the bar up (force on the tool downwards), balanced by the clamp
        assert last["tool_force_z"] < 0
        assert abs(last["tool_force_z"] - last["top_z"]) < 1e-6 * abs(last["tool_force_z"])
        assert abs(last["tool_force_x"]) < 1e-2 * abs(last["tool_force_z"])
    if MPI.COMM_WORLD.rank == 0:
        assert os.path.getsize(res["summary_csv"]) > 0
        for key in ("force", "newton", "contact_nodes"):
            assert os.path.getsize(res["png"][key]) > 10_000
        assert os.path.getsize(os.path.join(d, "groove_coarse.stl")) > 0
        assert os.path.exists(os.path.join(d, NAGATA, f"{NAGATA}.pvd"))


@pytest.mark.slow
def test_bore_rotation_changes_nothing(quick):
    """A turning circular bore is the same surface at every instant: during the rotation the
    force stays at its value at the end of the lift (to 1e-7 relative; the fixture's Newton
    runs to rtol 1e-12, so that this does not depend on where a Newton path stops inside the
    tolerance: at rtol 1e-9 the lift's last force is off by 2.3e-8 with the plain Newton step
    and 1.4e-7 with the active-set prediction) and, once the lift velocity of the initial guess
    has been removed (the ``settle`` increments), every increment converges in one Newton
    iteration (the previous solution is the solution)."""
    _, res = quick
    h = res["results"][ANALYTIC]["history"]
    n_indent, settle = res["parameters"]["n_indent"], res["parameters"]["settle"]
    F0 = h[n_indent - 1]["tool_force_z"]
    for row in h[n_indent:]:
        assert abs(row["tool_force_z"] - F0) <= 1e-7 * abs(F0)
    for row in h[n_indent + settle:]:
        assert row["newton_iterations"] <= 1


@pytest.mark.slow
def test_nagata_groove_force_and_oscillation(quick):
    """The Nagata groove (36 facets, 3–4 in contact) carries the bore's force within 1 %
    (measured −0.07 %) with at least 3× less oscillation than the flat facets (measured
    0.01 % vs 1.0 %), whose proud facets press the bar ~50 % harder."""
    _, res = quick
    s = res["by_name"]
    F_a = s[ANALYTIC]["force_mean"]
    assert F_a < 0
    assert abs(s[NAGATA]["force_mean"] / F_a - 1.0) < 0.01
    assert s[FLAT]["force_mean"] / F_a > 1.2
    assert s[NAGATA]["oscillation"] > 0
    assert 3.0 * s[NAGATA]["oscillation"] <= s[FLAT]["oscillation"]
    assert 3.0 * s[NAGATA]["oscillation_std"] <= s[FLAT]["oscillation_std"]


@pytest.mark.slow
def test_fine_flat_groove_fails_nagata_converges(quick):
    """180 facets (2° apart): under the implicit scheme the flat groove's valleys catch nodes in
    the facet-switching cycle (THEORY §6) and the run fails even after a cut-back; the Nagata
    groove built from the same facets converges without cut-backs and carries the bore's
    force (within 1 %, measured 0.00 %)."""
    _, res = quick
    kw = {**groove.QUICK, "coarse_facets": 180, "n_rotation": 5, "max_cutbacks": 1,
          "variants": (("flat", "coarse", "implicit"), ("nagata", "coarse", "implicit"))}
    out = groove.run(**kw, output_dir=None, progress=False)
    s = out["by_name"]
    assert s[FLAT]["status"].startswith("failed"), s[FLAT]["status"]
    # recognised as a cycle (stopped early) and explained
    err = out["results"][FLAT]["error"]
    assert "cycle with period 2" in err and "facet switching" in err, err
    assert "mode='nagata'" in err
    assert s[NAGATA]["status"] == "ok" and s[NAGATA]["cutbacks"] == 0
    assert s[NAGATA]["newton_max"] <= 5
    F_a = res["by_name"][ANALYTIC]["force_mean"]
    assert abs(s[NAGATA]["force_mean"] / F_a - 1.0) < 0.01


@pytest.mark.slow
def test_groove_parallel_matches_serial(quick):
    """The Nagata run on all ranks gives the force history of a COMM_SELF run."""
    comm = MPI.COMM_WORLD
    if comm.size == 1:
        pytest.skip("needs several ranks (the serial run is the reference)")
    _, res = quick
    kw = {**groove.QUICK, "variants": (("nagata", "coarse", "implicit"),)}
    ref = groove.run(**kw, output_dir=None, progress=False, comm=MPI.COMM_SELF,
                     newton_rtol=1e-12)   # the fixture's Newton tolerance
    h_par = res["results"][NAGATA]["history"]
    h_ser = ref["results"][NAGATA]["history"]
    assert_histories_match(h_par, h_ser, ("tool_force_z", "tool_force_x", "top_z"), 1e-8)
    for a, b in zip(h_par, h_ser):
        assert_newton_counts_match(a["newton_iterations"], b["newton_iterations"])


def test_bad_parameters_and_inward_groove():
    with pytest.raises(ValueError, match="groove wider"):
        groove.run(bar_radius=6.0, groove_radius=5.0, output_dir=None, progress=False)
    with pytest.raises(ValueError, match="bad variant"):
        groove.run(variants=(("flat", None, "implicit"),), output_dir=None, progress=False)
    # a groove whose normals point into the tool material (no flip) is caught
    from fxcontact.tools.faceted import FacetedTool

    center = (0.0, 0.125, 6.0)
    V, T = groove.groove_surface(6.0, 36, 4.25, center)
    wrong = FacetedTool(V, T, mode="flat")
    with pytest.raises(ValueError, match="normals point into the tool"):
        ironing.tool_deviation(wrong, center, 6.0, 0.125, free_point=center)
    right = FacetedTool(V, T, mode="flat", flip=True)
    dev = ironing.tool_deviation(right, center, 6.0, 0.125, free_point=center)
    assert abs(dev["bottom_gap"]) < 1e-12
    assert np.isfinite(dev["dev_out"])
