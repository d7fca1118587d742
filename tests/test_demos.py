"""Demos run at small size (serial and on 2 ranks) and give physically sensible results.

The process demos (drawing, extrusion) are run as a user runs them, as scripts in a
subprocess (serially and under ``mpirun -n 2``), at a reduced size: the physics is tested on
``fxcontact.processes`` by the process tests, here only that the story runs and writes its
pictures."""

import os

import numpy as np
import pytest
from mpi4py import MPI

from fxcontact.processes import upsetting_dies
from helpers import run_script, shared_tmpdir

DEMOS = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "demos")

@pytest.fixture
def outdir():
    return shared_tmpdir("fxc-demo-")


@pytest.mark.slow
def test_upsetting_small(outdir):
    res = upsetting_dies.run(h=4.0, n_steps=4, reduction=0.2, output_dir=outdir, progress=False)
    comm = MPI.COMM_WORLD
    H = 15.0 * (1 - 0.2)
    assert abs(res["height"] - H) < 1e-9
    homog = 10.0 * np.sqrt(15.0 / H)
    # barrelling: sticking end faces stay at R, the middle bulges beyond the homogeneous radius
    assert abs(res["radius_end"] - 10.0) < 1e-9
    assert res["radius_mid"] > homog
    hist = res["history"]
    assert len(hist) == 4
    assert abs(hist[-1]["volume"] / hist[0]["volume"] - 1.0) < 2e-2  # faceted lateral surface
    assert res["die_force"] < 0.0
    if comm.rank == 0:
        assert os.path.exists(res["vtk"])
        assert os.path.getsize(os.path.join(outdir, "upsetting_history.csv")) > 0
        assert res["png"] is not None and os.path.getsize(res["png"]) > 10_000


def test_upsetting_sliding_is_homogeneous(outdir):
    res = upsetting_dies.run(h=5.0, n_steps=2, reduction=0.1, dies="sliding", output_dir=None,
                             progress=False)
    # sliding dies: (nearly) uniform radial expansion — the bulge is < 1 % of the expansion
    # (sticking dies give a bulge of the order of the expansion itself)
    expansion = res["radius_end"] - 10.0
    assert expansion > 0.04 * 10.0
    assert abs(res["radius_mid"] - res["radius_end"]) < 1e-2 * expansion
    with pytest.raises(ValueError, match="dies"):
        upsetting_dies.run(dies="glued", output_dir=None)


#: the process demos (fxcontact.processes told as stories) at the reduced size, a few
#: increments: their arguments, a line of their summary, the file of their rows
PROCESS_DEMOS = {
    "demo_flat_rolling": (("--quick", "--max_increments", 3), "max_increments = 3 reached",
                          "theory P/w [N/mm]: slab 6299.6", "flat_rolling_diagnostics.csv"),
    "demo_bar_rolling": (("--quick", "--length_factor", 1.6, "--max_increments", 2),
                         "max_increments = 2 reached", "A_pass = 7579 mm2",
                         "bar_rolling_third_diagnostics.csv"),
    "demo_ring_rolling": (("--quick", "--revolutions", 0.04), "status done",
                          "sigma0 = 107 MPa (K = 50, m = 0.14)", "ring_rolling.csv"),
    "demo_hot_ring_rolling": (("--quick", "--revolutions", 0.06), "status done",
                              "heat (whole ring): T at the end", "hot_ring.csv"),
    "demo_upsetting": (("--quick",), "final height 12.000 mm",
                       "radius at mid-height 11.603 mm, at the end faces 10.000 mm",
                       "upsetting_pressure.csv"),
    "demo_ring_test": (("--quick", "--mbar", 0.3), "20 % height reduction in 2 increments",
                       "20.0 %: ID    0.11    0.64    0.16; UB   -1.73", "ring_test.csv"),
    "demo_ironing": (("--quick", "--travel", 0.5), "slab: 768 tetrahedra, 3528 dofs",
                     "implicit: F_z Nagata / analytic", "summary.csv"),
    "demo_groove": (("--quick", "--rotations", 5), "bar section: 1152 tetrahedra, 5256 dofs",
                    "nagata-coarse-implicit: F_z / bore", "summary.csv"),
    "demo_hertz_sphere": (("--quick",), "Hertz at delta = 13.3 um: P = 1005.1 N, a = 0.2579 mm",
                          "p_max [MPa]", "profile.csv"),
    "demo_hertz_cylinder": (("--quick",), "half-width a [mm]", "a/R = 0.035", "profile.csv"),
    "demo_hyperelastic_contact": (("--quick",), "588 dofs, 3 load steps, indentation 0.3",
                                  "penetration (penalty)", "force.csv"),
    "demo_hot_upsetting": (("--quick", "--reduction", 0.2), "height reduction 20.0 %",
                           "(chilled at the die)", "upsetting_diagnostics.csv"),
}


@pytest.mark.serial   # each demo is its own job, on 1 and 2 ranks
@pytest.mark.parametrize("nranks", [1, 2])
@pytest.mark.parametrize("name", sorted(PROCESS_DEMOS))
@pytest.mark.slow
def test_process_demo_runs_as_a_script(name, nranks, tmp_path):
    """A process demo run as a script (a subprocess) for a few increments of the test size
    prints its summary and writes its rows."""
    args, *lines, rows = PROCESS_DEMOS[name]
    rc, text = run_script(os.path.join(DEMOS, f"{name}.py"), [*args, "--output-dir", tmp_path,
                                                              "--quiet"], nranks=nranks)
    assert rc == 0, text[-3000:]
    for line in lines:
        assert line in text, text
    assert os.path.getsize(tmp_path / rows) > 0


def _process_demo(name, args, pictures, words, tmp_path):
    for n in (1, 2):
        out = tmp_path / f"ranks{n}"
        rc, text = run_script(os.path.join(DEMOS, name), [*args, "--output-dir", out, "--quiet"],
                              nranks=n)
        assert rc == 0, text[-3000:]
        for w in words:
            assert w in text, (w, text[-3000:])
        for pic in pictures:
            assert os.path.getsize(out / pic) > 10_000, pic


@pytest.mark.serial   # each script is its own 1- and 2-rank job
@pytest.mark.slow
def test_wire_drawing_demo(tmp_path):
    _process_demo("demo_wire_drawing.py", ["--quick", "--t_end", "0.01"],
                  ["wire_drawing_strain.png", "wire_drawing_contact.png"],
                  ["drawing stress", "Avitzur"], tmp_path)


@pytest.mark.serial
@pytest.mark.slow
def test_extrusion_demo(tmp_path):
    _process_demo("demo_extrusion.py", ["--quick", "--t_end", "0.05"],
                  ["extrusion_flow.png", "extrusion_pressure.png"],
                  ["punch pressure", "Avitzur"], tmp_path)


@pytest.mark.serial
@pytest.mark.slow
def test_upsetting_folding_demo(tmp_path):
    _process_demo("demo_upsetting_folding.py", ["--quick", "--reduction", "0.15"],
                  ["upsetting_section.png", "upsetting_pressure.png"],
                  ["p/sigma0", "die contact", "free surface"], tmp_path)
