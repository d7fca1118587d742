"""Checkpoints of a ring-rolling run (fxcontact.processes.ring_rolling): the mill's controllers
(guide rolls placed by :class:`~fxcontact.processes.ring_rolling.mill.RingCentring`, the idle
mandrel's ω, the cones of :class:`~fxcontact.processes.ring_rolling.mill.AxialRolls`, the controlled
tool motions, the ring's centre of the cylindrical update) are saved and restored,
so a resumed run equals the uninterrupted one; a checkpoint is refused, with a clear
ValueError, by a simulation with other controllers."""

import json
import os
import shutil
from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest
from mpi4py import MPI

import fxcontact as fx
from fxcontact.checkpoint import CheckpointError, list_checkpoints, plain_state
from fxcontact.idle import ControlledMotion, IdleRotation
from fxcontact.kinematics import RingAxisUpdate
from fxcontact.processes import ring_rolling

from checkpoint_driver import build
from helpers import shared_tmpdir

from ring_runs import CONES as SHORT, cone_runs


def _json_round_trip(state):
    return json.loads(json.dumps(state))


def test_controlled_motion_state_round_trip():
    """A motion rebuilt from the JSON of its state is the same motion at every time (past
    stages included), and a malformed state is refused."""
    m = ControlledMotion(velocity=(1.0, 0.0, 0.0), angular_velocity=2.0, axis_point=(1, 2, 3))
    m.set_rates(0.3, velocity=(0.0, -2.0, 0.5), angular_velocity=-1.0)
    m.set_rates(0.7, angular_velocity=4.0)
    n = ControlledMotion(velocity=(0.0, 0.0, 0.0), angular_velocity=0.0, axis_point=(1, 2, 3))
    n.restore_state(_json_round_trip(m.checkpoint_state()))
    for t in (0.0, 0.1, 0.3, 0.5, 0.7, 0.9, 1.5):
        assert np.array_equal(m.translation(t), n.translation(t))
        assert m.angle(t) == n.angle(t)
        assert np.array_equal(m.velocity(t), n.velocity(t))
        assert m.angular_velocity(t) == n.angular_velocity(t)
    n.set_rates(1.0, angular_velocity=0.5)          # the restored motion goes on
    assert n.angle(1.2) == pytest.approx(m.angle(1.0) + 0.1)
    bad = m.checkpoint_state()
    bad["w"] = bad["w"][:-1]
    with pytest.raises(ValueError, match="ControlledMotion state"):
        n.restore_state(bad)


def test_idle_rotation_and_axis_update_state_round_trip():
    """The idle tool's ω and motion, the update's centre come back; another tool or axis is
    refused."""
    def idle(name, omega):
        tool = fx.MovedTool(fx.Cylinder((0, 0, 0), (0, 0, 1), 1.0, name=name),
                            ControlledMotion(angular_velocity=omega), name=name)
        contact = SimpleNamespace(tools=[tool], friction=[fx.Frictionless()], scheme="implicit")
        return IdleRotation(contact, tool)
    a = idle("mandrel", 3.0)
    a.motion.set_rates(0.5, angular_velocity=5.0)
    a.omega = 5.0
    b = idle("mandrel", 0.0)
    b.restore_state(_json_round_trip(a.checkpoint_state()))
    assert b.omega == 5.0 and b.motion.angle(1.0) == a.motion.angle(1.0) == 4.0
    with pytest.raises(ValueError, match=r"tools \['mandrel'\]"):
        idle("guide", 0.0).restore_state(a.checkpoint_state())
    u = RingAxisUpdate((1.0, 2.0, 0.0))
    v = RingAxisUpdate()
    v.restore_state(_json_round_trip(plain_state(u.checkpoint_state())))
    assert np.array_equal(v.center, u.center)
    with pytest.raises(ValueError, match="ring axis"):
        RingAxisUpdate(axis=(1, 0, 0)).restore_state(u.checkpoint_state())


def _scale(row, key):
    """Scale of a history value: forces and torques are compared with the largest force or
    torque of the row (the frictionless tools' torques, the friction components normal to the
    rolling direction are round-off of it), the powers with the largest power of the row (the
    idle mandrel's rotation power is round-off of it), the volume rate ∫div v with the volume
    per increment, the rest with their own size (at least 1)."""
    if key.endswith("_power") or key == "power_in":
        return max(max(abs(v) for k, v in row.items()
                       if k.endswith("_power") or k == "power_in"), 1.0)
    for word, family in (("torque", ("torque",)), ("force", ("force", "friction")),
                         ("friction", ("force", "friction"))):
        if word in key:
            return max(max(abs(v) for k, v in row.items() if any(f in k for f in family)), 1.0)
    if key in ("div_v", "volume_restore_rate"):
        return row["volume"] / row["dt"]
    return max(abs(row[key]), 1.0)


@pytest.fixture(scope="module")
def runs():
    """The uninterrupted run (a checkpoint at each increment) and the run resumed from its
    checkpoint of increment 1, on the current number of ranks (tests/ring_runs.py)."""
    return cone_runs()


@pytest.mark.slow
def test_resumed_ring_rolling_equals_uninterrupted(runs):
    """Every history column (tool forces and torques, the mandrel's ω, the ring centre and
    radius, the guide rolls' forces, Newton iterations…) of the resumed increments equals
    that of the uninterrupted run to 1e-10. Without the motions' state the mandrel's angle
    (integrated from the ω set at each increment) is wrong after the resume (measured: by
    9e-4 rad two increments after a resume at increment 2; with faceted tools the facets would
    then be elsewhere); the
    guide rolls are placed by a velocity (target − position)/dt that corrects a wrong
    position within one increment, the frictionless mandrel's ω does not change the field."""
    full, resumed, ck, _ = runs
    assert [os.path.basename(p)[-6:] for p in ck] == ["000001", "000002"]
    assert full.status == resumed.status == "done"
    ha, hb = full.sim_history, resumed.sim_history
    assert len(ha) == len(hb) == 2 and len(resumed.history) == 1
    bad = []
    for a, b in zip(ha, hb):
        assert set(a) == set(b)
        for k in a:
            # the final Newton residual norm (below the solver's tolerance) is not compared:
            # on 2 ranks the round-off of the distributed solve changes it by ~1e-4 of itself
            if not (k.startswith("wall_") or k == "residual"):
                if not abs(a[k] - b[k]) <= 1e-10 * _scale(a, k):
                    bad.append((a["increment"], k, a[k], b[k]))
    # the demo's own rows (diameters, height, forces, exact penetration) of increment 2
    for a, b in zip(full.history[1:], resumed.history):
        for k in a:
            if not k.startswith("wall") and not abs(a[k] - b[k]) <= 1e-10 * _scale(a, k):
                bad.append((a["increment"], k, a[k], b[k]))
    assert not bad, bad
    man = json.load(open(os.path.join(ck[0], "manifest.json")))
    types = [c["type"] for c in man["controllers"]]
    assert types == ["RingCentring", "IdleRotation", "AxialRolls"]
    assert man["controllers"][1]["state"]["omegas"] == pytest.approx(
        [ha[0]["mandrel_omega"]], rel=1e-14)
    assert man["controllers"][2]["state"]["omega"] == pytest.approx(
        [ha[0]["cone_omega"]], rel=1e-14)
    # the update's centre: measured at the start of increment 1, the initial centroid of the
    # upper half ring (0, 0, H/4)
    assert man["kinematics"]["center"] == pytest.approx([0.0, 0.0, SHORT.H / 4],
                                                        abs=1e-9)


@pytest.mark.slow
def test_ring_checkpoint_without_cones_refused(runs):
    """The checkpoint of the run with cones, resumed by the same mill without them: refused."""
    _, _, ck, d = runs
    with pytest.raises(ValueError, match=r"\['RingCentring', 'IdleRotation', 'AxialRolls'\]; "
                                         r"this simulation has \['RingCentring', 'IdleRotation'\]"):
        ring_rolling.run(replace(SHORT, cones=False), output_dir=os.path.join(d, "other"),
                         resume=ck[0])


class _Counter:
    """A stateful controller: counts the increments."""

    def __init__(self):
        self.n = 0

    def begin_increment(self, sim, t, dt, x_t):
        pass

    def end_increment(self, sim, dt):
        self.n += 1

    def checkpoint_state(self):
        return {"n": self.n}

    def restore_state(self, state):
        self.n = int(state["n"])


def test_controllers_must_match():
    """A checkpoint written without controllers, resumed by a simulation with one, and the
    reverse, are refused (ValueError naming the controllers); with the same controller its
    state comes back."""
    d = shared_tmpdir("fxc_ring_ckpt_ctl_")
    sim = build(d)
    sim.add_controller(_Counter())
    sim.run(0.2, 0.1)
    path = list_checkpoints(os.path.join(d, "checkpoints"), "press")[-1]
    sim2 = build(d)
    with pytest.raises(ValueError, match=r"controllers \['_Counter'\]; this simulation has \[\]"):
        sim2.resume(path)
    sim3 = build(d)
    sim3.add_controller(_Counter())
    sim3.add_controller(_Counter())
    with pytest.raises(CheckpointError, match="register the same controllers"):
        sim3.resume(path)
    sim4 = build(d)
    c = sim4.add_controller(_Counter())
    sim4.resume(path)
    assert c.n == 2
    MPI.COMM_WORLD.barrier()
    if MPI.COMM_WORLD.rank == 0:
        shutil.rmtree(d, ignore_errors=True)
