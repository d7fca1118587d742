"""The run-until-steady monitor of the processes (fxcontact.processes.monitor) on scripted
histories: each stop reason (steady, refused, lost, no steady state: tail or max_increments,
failed), the grip and the release of the pusher, the steady window's means, the rules'
checks. No finite elements: a stand-in simulation returns the scripted rows (the same on every
rank)."""

import math

import pytest
from mpi4py import MPI

from fxcontact import IncrementError
from fxcontact.processes.common import gather
from fxcontact.processes.monitor import SteadyMonitor, StopRules, window_increments


class ScriptedSim:
    """``step(dt)`` advances t and returns the next scripted row (``fail_at``: raise there)."""

    comm = MPI.COMM_WORLD

    def __init__(self, rows, fail_at=None):
        self.rows, self.fail_at, self.t, self.k = rows, fail_at, 0.0, 0

    def step(self, dt):
        if self.k == self.fail_at:
            raise IncrementError(self.t, dt, "scripted failure")
        self.t += dt
        self.k += 1

        class Result:
            row = dict(self.rows(self.k), time=self.t, newton_iterations=3,
                       volume_change=1e-6 * self.k, min_quality=0.5, wall=0.1,
                       wall_assembly=0.05, wall_linear_solve=0.03, wall_contact=0.01)
        return Result()


def _rules(**kw):
    base = dict(steady_keys=("force",), window=4, steady_tol=0.01, settle=1.0,
                max_increments=100, grip_travel=5.0, front_start=0.0, tail_limit=50.0,
                body="strip", zone="bite", hints={"refused": "mu against tan(alpha)"})
    return StopRules(**{**base, **kw})


def _run(rows, rules, fail_at=None):
    released = []
    sim = ScriptedSim(rows, fail_at)
    out = SteadyMonitor(sim, 0.5, lambda res: res.row, rules,
                        release=released.append).run()
    return out, released


def rolling(k, grip=3, lose=None, force=lambda k: 100.0):
    """The front advances 1 per increment; the pusher touches up to increment ``grip``."""
    return dict(front=float(k), tail=float(k) - 20.0, force=force(k),
                pusher_nodes=5 if k <= grip else 0,
                contact_nodes=0 if lose is not None and k >= lose else 10)


def test_steady_after_the_grip():
    """Constant force after a transient: steady once both windows are past ``settle`` and
    agree; the pusher is released at the second increment without pusher contact."""
    out, released = _run(lambda k: rolling(k, force=lambda k: 100.0 + 50.0 * (k < 8)),
                         _rules())
    assert out.status == "steady" and out.steady
    assert "force" in out.message and "4 increments" in out.message
    assert out.gripped_at == pytest.approx(2.5) and released == [pytest.approx(2.5)]
    assert out.steady_from == out.increments - 4
    assert all(q["force"] == 100.0 for q in out.window())
    assert out.means(["force"]) == {"force": 100.0}
    assert out.oscillation("force") == 0.0
    assert out.max_volume_change == pytest.approx(1e-6 * out.increments)
    assert out.newton_mean == 3.0 and out.newton_max == 3 and out.min_quality == 0.5
    assert "Newton its mean 3.0" in out.run_summary()


def test_refused():
    out, released = _run(lambda k: rolling(k, grip=1000), _rules(grip_travel=5.0))
    assert out.status == "refused" and not released and out.gripped_at is None
    assert out.increments == 6     # the front travelled 6 > 5
    assert "the strip refuses to enter" in out.message and "mu against tan(alpha)" in out.message
    assert out.window() == []


def test_lost_after_the_release():
    out, _ = _run(lambda k: rolling(k, lose=7), _rules())
    assert out.status == "lost" and out.increments == 7
    assert "the strip lost contact" in out.message and "after the pusher let go" in out.message


def test_tail_reaches_the_bite():
    out, _ = _run(lambda k: rolling(k, force=lambda k: float(k)), _rules(tail_limit=-10.0))
    assert out.status == "no steady state" and out.increments == 11
    assert "tail reached the bite" in out.message and "lengthen the strip" in out.message


def test_max_increments():
    out, _ = _run(lambda k: rolling(k, force=lambda k: float(k)), _rules(max_increments=9))
    assert out.status == "no steady state" and out.increments == 9
    assert out.message == "max_increments = 9 reached before a steady state"


def test_failed_increment_keeps_the_history():
    """An increment that fails after its cut-backs ends the run with "failed" and its message;
    the rows before are kept. Failing at the first increment raises the error itself."""
    out, _ = _run(lambda k: rolling(k), _rules(), fail_at=5)
    assert out.status == "failed" and out.increments == 5
    assert "scripted failure" in out.message
    with pytest.raises(IncrementError, match="scripted failure"):
        _run(lambda k: rolling(k), _rules(), fail_at=0)


def test_no_pusher_phase():
    """``grip_travel=None``: no pusher (drawing, extrusion): steady without a grip."""
    out, released = _run(lambda k: dict(front=float(k), tail=-100.0, force=1.0,
                                         contact_nodes=4), _rules(grip_travel=None))
    assert out.status == "steady" and out.gripped_at is None and not released


@pytest.mark.parametrize("kw,words", [
    (dict(steady_keys=()), "steady_keys must name at least one"),
    (dict(steady_keys="force"), "steady_keys must name at least one"),
    (dict(window=0), "window must be an integer >= 1"),
    (dict(max_increments=0), "max_increments must be an integer >= 1"),
    (dict(steady_tol=-1.0), "steady_tol must be a finite number > 0"),
    (dict(grip_travel=math.inf), "grip_travel must be a finite number > 0"),
    (dict(hints={"stuck": "?"}), "hints for unknown status"),
])
def test_bad_rules(kw, words):
    with pytest.raises(ValueError, match=words):
        _rules(**kw)


def test_window_increments_and_gather():
    assert window_increments(10.0, 100.0, 0.01, 3) == 10
    assert window_increments(1.0, 100.0, 0.01, 3) == 3
    comm = MPI.COMM_WORLD
    g = gather(comm, [[comm.rank, 1.0]])
    assert g.shape == (comm.size, 2) and list(g[:, 0]) == list(range(comm.size))
