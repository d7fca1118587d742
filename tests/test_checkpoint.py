"""Restart after a crash: a run killed with SIGKILL and resumed from its last checkpoint gives the
history and the fields of the uninterrupted run; bad checkpoints are refused with a clear error.

The kill tests start the run of ``checkpoint_driver.py`` as a subprocess and SIGKILL it: serially
while it writes its checkpoint of increment 6, under ``mpirun -n 2`` (the whole process group)
while it sleeps after increment 5. The newest checkpoint is then the one of increment 4 and the
CSV/VTK outputs already hold later increments; the run is resumed in another subprocess and
compared with an uninterrupted run.
"""

import csv
import json
import os
import shutil
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
from mpi4py import MPI

from fxcontact.checkpoint import CheckpointError, latest_checkpoint, list_checkpoints
from fxcontact.io import read_pvd

from checkpoint_driver import build
from helpers import HANG_TIMEOUT, gather_by_position, shared_tmpdir

HERE = os.path.dirname(os.path.abspath(__file__))
DRIVER = os.path.join(HERE, "checkpoint_driver.py")
ROOT = os.path.dirname(HERE)


def _env():
    env = dict(os.environ)
    env["PYTHONPATH"] = ROOT + os.pathsep + env.get("PYTHONPATH", "")
    env.update(OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
               OPENBLAS_NUM_THREADS="1")
    for k in list(env):  # the child is its own MPI job
        if k.startswith(("OMPI_COMM", "PMIX_", "OMPI_MCA_ess", "OMPI_MCA_orte")):
            env.pop(k)
    return env


def _cmd(nranks, *args):
    py = [sys.executable, DRIVER, *args]
    if nranks == 1:
        return py
    return ["mpirun", "-n", str(nranks), "--oversubscribe", *py]


def _run(nranks, *args):
    r = subprocess.run(_cmd(nranks, *args), env=_env(), capture_output=True, text=True,
                       timeout=HANG_TIMEOUT)
    assert r.returncode == 0, r.stderr[-3000:]


def _run_and_kill(nranks, out):
    """Start the run, SIGKILL it (the whole process group: mpirun and its ranks) once it has
    passed increment 5."""
    p = subprocess.Popen(_cmd(nranks, out, "full", "--pause-after", "5"), env=_env(),
                         stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                         start_new_session=True)
    t0 = time.time()
    try:
        while not os.path.exists(os.path.join(out, "paused")):
            assert p.poll() is None, p.stderr.read().decode()[-3000:]
            assert time.time() - t0 < HANG_TIMEOUT, "the run did not reach increment 5"
            time.sleep(0.2)
    finally:
        os.killpg(p.pid, signal.SIGKILL)
        p.wait()
    assert p.returncode == -signal.SIGKILL or nranks > 1


def _csv(path):
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


def _compare(ref_dir, dir_, tol):
    a = np.load(os.path.join(ref_dir, "final.npz"))
    b = np.load(os.path.join(dir_, "final.npz"))
    assert np.array_equal(a["x0"], b["x0"]) and np.array_equal(a["c0"], b["c0"])
    for k in ("vertex", "strain"):
        scale = max(np.max(np.abs(a[k])), 1.0)
        assert np.max(np.abs(a[k] - b[k])) <= tol * scale, (k, np.max(np.abs(a[k] - b[k])))
    # history: every column but the wall times, increment by increment
    keys = list(a["keys"])
    assert keys == list(b["keys"]) and a["history"].shape == b["history"].shape
    for j, k in enumerate(keys):
        if k.startswith("wall_"):
            continue
        x, y = a["history"][:, j], b["history"][:, j]
        assert np.allclose(x, y, rtol=tol, atol=tol * max(np.max(np.abs(x)), 1.0)), (k, x, y)
    # the CSV history continues: same rows, no duplicate, none lost
    ra, rb = _csv(os.path.join(ref_dir, "press_history.csv")), \
        _csv(os.path.join(dir_, "press_history.csv"))
    assert [r["increment"] for r in rb] == [str(i + 1) for i in range(len(ra))]
    for x, y in zip(ra, rb):
        for k in x:
            if not k.startswith("wall_"):
                assert abs(float(x[k]) - float(y[k])) <= tol * max(abs(float(x[k])), 1.0), k
    # the VTK series continues: the same times, each step once, every file present
    pa, pb = read_pvd(os.path.join(ref_dir, "press.pvd")), read_pvd(os.path.join(dir_,
                                                                                 "press.pvd"))
    assert [t for t, _ in pb] == pytest.approx([t for t, _ in pa], rel=1e-12, abs=1e-14)
    assert all(os.path.exists(os.path.join(dir_, f)) for _, f in pb)
    assert any("_r1" in f for _, f in pb)


@pytest.fixture(scope="module")
def serial_runs():
    """An uninterrupted serial run, and a serial run killed while it writes its third
    checkpoint (increment 6; kept aside)."""
    d = shared_tmpdir("fxc_ckpt_")
    if MPI.COMM_WORLD.rank == 0:
        _run(1, os.path.join(d, "full"), "full")
        r = subprocess.run(_cmd(1, os.path.join(d, "killed"), "full", "--die-writing", "3"),
                           env=_env(), capture_output=True, text=True, timeout=HANG_TIMEOUT)
        assert r.returncode == -signal.SIGKILL, r.stderr[-3000:]
    MPI.COMM_WORLD.barrier()
    yield d
    if MPI.COMM_WORLD.rank == 0:
        shutil.rmtree(d, ignore_errors=True)


@pytest.mark.serial
@pytest.mark.slow
def test_killed_serial_run_resumes_to_the_same_result(serial_runs):
    full, killed = os.path.join(serial_runs, "full"), os.path.join(serial_runs, "killed")
    # killed while writing the checkpoint of increment 6: that one is an incomplete temporary
    # directory, the newest checkpoint is the one of increment 4, the outputs hold increment 6
    assert os.path.isdir(os.path.join(killed, "checkpoints", "press_000006.tmp"))
    assert latest_checkpoint(os.path.join(killed, "checkpoints")).endswith("press_000004")
    assert len(_csv(os.path.join(killed, "press_history.csv"))) == 6
    assert len(read_pvd(os.path.join(killed, "press.pvd"))) == 7
    res = os.path.join(serial_runs, "resumed")
    shutil.copytree(killed, res)
    _run(1, res, "resume")
    # the run has a cut-back (increment 3), explicit Coulomb friction on the pressures of the
    # previous increment and a penalty resolved from beta at the first increment: all restored
    _compare(full, res, 1e-10)


@pytest.mark.serial
@pytest.mark.slow
def test_killed_run_on_two_ranks_resumes_to_the_same_result(serial_runs):
    d = serial_runs
    _run(2, os.path.join(d, "full2"), "full")
    _run_and_kill(2, os.path.join(d, "killed2"))
    assert latest_checkpoint(os.path.join(d, "killed2", "checkpoints")).endswith("press_000004")
    _run(2, os.path.join(d, "killed2"), "resume")
    _compare(os.path.join(d, "full2"), os.path.join(d, "killed2"), 1e-10)
    # a serial checkpoint resumed on 2 ranks: another partition, the same result up to the
    # round-off of the distributed solve (measured: 3e-15 relative; 1 vs 2 ranks: 6e-13)
    res = os.path.join(d, "serial_on_two")
    shutil.copytree(os.path.join(d, "killed"), res)
    _run(2, res, "resume")
    _compare(os.path.join(d, "full"), res, 1e-10)


# ----------------------------------------------------------------------------- in process
def test_resume_in_process_matches_and_keeps_outputs():
    """On the current number of ranks: run to t = 0.5 with checkpoints, resume a new
    simulation from the checkpoint of increment 2 and run to the same end."""
    d = shared_tmpdir("fxc_ckpt_ip_")
    sim = build(d)
    sim.run(0.45, 0.1, max_cutbacks=3)
    n = len(sim.history)
    ck = list_checkpoints(os.path.join(d, "checkpoints"), "press")
    assert [os.path.basename(p) for p in ck] == ["press_000002", "press_000004"]
    sim2 = build(d)
    sim2.resume(ck[0])
    assert sim2.increment == 2 and len(sim2.history) == 2
    # the checkpoint of increment 4 (a future the resumed run replaces) is gone
    assert list_checkpoints(os.path.join(d, "checkpoints"), "press") == ck[:1]
    assert sim2.t == sim.history[1]["time"]
    sim2.run(0.45, 0.1, max_cutbacks=3)
    assert len(sim2.history) == n
    for a, b in zip(sim.history, sim2.history):
        for k in a:
            if not k.startswith("wall_"):
                assert abs(a[k] - b[k]) <= 1e-10 * max(abs(a[k]), 1.0), (k, a[k], b[k])
    xa, va = _vertex_state(sim)
    xb, vb = _vertex_state(sim2)
    assert np.array_equal(xa, xb)
    assert np.max(np.abs(va - vb)) <= 1e-10 * max(np.max(np.abs(va)), 1.0)
    c1, c2 = sim.contributors[0], sim2.contributors[0]
    assert c1.rho == c2.rho and c1.strain_rate == c2.strain_rate
    # by position: the two meshes' partitions need not be the same on 2 ranks
    p1, p2 = (gather_by_position(s.comm, s._x_ref[s.space.vertex_geometry][c.boundary.vertices],
                                 c._p_prev)[1] for s, c in ((sim, c1), (sim2, c2)))
    assert np.allclose(p1, p2, rtol=1e-10, atol=1e-12)
    if MPI.COMM_WORLD.rank == 0:
        rows = _csv(os.path.join(d, "press_history.csv"))
        assert [int(r["increment"]) for r in rows] == list(range(1, n + 1))
        shutil.rmtree(d, ignore_errors=True)


def _vertex_state(sim):
    """Velocity, pressure-free vertex state and positions keyed by the initial positions."""
    sp = sim.space
    own = sp.vertex_owned
    x0 = sim._x_ref[sp.vertex_geometry][own]
    vals = np.c_[sim.w.x.array[sp.vertex_dofs[own]], sim.vertex_positions()[own]]
    return gather_by_position(sim.comm, x0, vals)


def _checkpointed(d):
    sim = build(d)
    sim.run(0.2, 0.1)
    return latest_checkpoint(os.path.join(d, "checkpoints"), "press")


def test_bad_checkpoints_are_refused():
    comm = MPI.COMM_WORLD
    d = shared_tmpdir("fxc_ckpt_bad_")
    path = _checkpointed(d)
    # no checkpoint at all
    with pytest.raises(CheckpointError, match="no checkpoint of run 'press'"):
        build(os.path.join(d, "empty")).resume()
    # another package version
    other = os.path.join(d, "other_version")
    if comm.rank == 0:
        shutil.copytree(path, other)
        with open(os.path.join(other, "manifest.json")) as fh:
            man = json.load(fh)
        man["fxcontact"] = "0.0.1"
        with open(os.path.join(other, "manifest.json"), "w") as fh:
            json.dump(man, fh)
    comm.barrier()
    with pytest.raises(CheckpointError, match="another version"):
        build(d).resume(other)
    # a different mesh: the same numbers of cells and vertices, other interior positions
    sim = build(d, perturb=0.12)
    with pytest.raises(CheckpointError, match="different mesh"):
        sim.resume(path)
    # a different set-up: one contributor less
    sim = build(d)
    sim.contributors.pop()
    with pytest.raises(CheckpointError, match="different set-up"):
        sim.resume(path)
    # an incomplete checkpoint (killed while writing) is never taken as the latest
    if comm.rank == 0:
        shutil.copytree(path, path.replace("000002", "000003") + ".tmp")
        os.remove(os.path.join(path.replace("000002", "000003") + ".tmp", "manifest.json"))
    comm.barrier()
    assert latest_checkpoint(os.path.join(d, "checkpoints"), "press") == path
    # a checkpoint directory without its manifest
    with pytest.raises(CheckpointError, match="not a complete checkpoint"):
        build(d).resume(path.replace("000002", "000003") + ".tmp")
    # resume() after the run has started
    sim = build(os.path.join(d, "fresh"))
    sim.step(0.1)
    with pytest.raises(RuntimeError, match="before the first step"):
        sim.resume(path)
    sim.close()
    comm.barrier()
    if comm.rank == 0:
        shutil.rmtree(d, ignore_errors=True)


def test_checkpoint_at_a_failed_increment():
    """An increment that fails for good leaves a checkpoint of the last accepted state."""
    from fxcontact.simulation import IncrementError

    from checkpoint_driver import CutOnce
    d = shared_tmpdir("fxc_ckpt_fail_")
    sim = build(d)
    sim.checkpoint_every = 100
    sim.run(0.2, 0.1)
    with pytest.raises(IncrementError, match="t = 0.2"):
        sim.run(0.4, 0.1, max_cutbacks=0)     # increment 3 needs a cut-back: none allowed
    assert isinstance(sim.contributors[-1], CutOnce)
    path = latest_checkpoint(os.path.join(d, "checkpoints"), "press")
    assert path is not None and path.endswith("press_000002")
    sim2 = build(d)
    sim2.resume()
    assert sim2.t == pytest.approx(0.2, abs=1e-15) and sim2.increment == 2
    sim2.close()
    MPI.COMM_WORLD.barrier()
    if MPI.COMM_WORLD.rank == 0:
        shutil.rmtree(d, ignore_errors=True)
