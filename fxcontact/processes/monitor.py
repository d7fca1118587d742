"""Run a forming process until it is steady, or say why it cannot be (THEORY §14.5).

A process (rolling, drawing, extrusion) is run increment by increment: a per-increment
measure turns the :class:`~fxcontact.Simulation`'s history row into the process's row (forces
per unit width, exit section, power balance, …), and :class:`SteadyMonitor` decides after each
increment whether to go on. Its stop reasons (``status``):

* ``"steady"`` — the means of the monitored quantities over two consecutive windows of
  increments agree (:func:`fxcontact.steady.steady_window`), once the front has passed
  ``settle``; the steady values are the last window's means;
* ``"refused"`` — a pusher drives the workpiece into the tool until it is gripped (no pusher
  contact node for two increments: the pusher is then released); if the front has travelled
  ``grip_travel`` without a grip, the tool refuses the workpiece;
* ``"lost"`` — after the release nothing touches the tool any more (``contact_nodes == 0``);
* ``"no steady state"`` — the tail reached ``tail_limit`` (the workpiece is too short) or
  ``max_increments`` were run;
* ``"failed"`` — an increment failed after its cut-backs (:class:`fxcontact.IncrementError`,
  raised on every rank): the history up to there is kept.

The rows must hold ``front`` and ``tail`` (positions along the process direction, in the unit of
``settle``, ``grip_travel``, ``tail_limit``), ``contact_nodes`` and, with a pusher,
``pusher_nodes``; ``newton_iterations``, ``volume_change``, ``min_quality`` and the wall-time
columns feed the run's summary (:class:`SteadyRun`).
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass, field, fields
from typing import Callable, Dict, List, Mapping, Optional, Sequence, Tuple

import numpy as np

from fxcontact.newton.options import SolverOptions
from fxcontact.processes.contact_laws import ContactLaws
from fxcontact.protocols import HasSummary
from fxcontact.simulation import (IncrementError, format_iteration_split, format_wall_split,
                                  wall_split)
from fxcontact.steady import steady_window

__all__ = ["StopRules", "SteadyMonitor", "SteadyRun", "RunNumerics", "STATUSES", "contact_lines",
           "window_increments", "is_number"]

log = logging.getLogger("fxcontact.processes")

#: the stop reasons of :class:`SteadyMonitor`
STATUSES = ("steady", "refused", "lost", "no steady state", "failed")


def window_increments(travel: float, speed: float, dt: float, minimum: int) -> int:
    """Increments in a window of ``travel`` of the tool at ``speed`` with steps ``dt`` (at least
    ``minimum``): the window should span several element passages into the tool."""
    return max(int(minimum), int(math.ceil(travel / (speed * dt))))


def is_number(x) -> bool:
    """A finite int or float (not a bool)."""
    return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)


def _finite(name, value, low=0.0, strict=True):
    ok = is_number(value) and (
        value > low if strict else value >= low)
    if not ok:
        raise ValueError(f"{name} must be a finite number {'>' if strict else '>='} {low:g}, "
                         f"got {value!r}")


@dataclass(frozen=True)
class RunNumerics(ContactLaws):
    """The numerics every process case shares (the base of the cases): the contact scheme,
    Newton's line search, penalty continuation, active-set prediction and force-scaled
    tolerance (:class:`fxcontact.SolverOptions`), and the increments allowed; the
    ``penalty`` and ``friction`` fields with their former spellings and :meth:`replace`
    (:class:`~fxcontact.processes.contact_laws.ContactLaws`)."""

    scheme: str = "implicit"
    line_search: str = "bt"
    penalty_continuation: Optional[float] = None
    active_set_prediction: object = "auto"
    #: Newton's force-scaled tolerance (``SolverOptions.ftol``: converged when the residual
    #: is below this fraction of the contact's nodal force norm; 0: off, the default; on the
    #: quick bar-rolling pass 1e-3 and 1e-4 both led to a Newton failure at t ≈ 0.24 s that
    #: a dt/2 cut-back recovered, benchmarks/README.md)
    newton_ftol: float = 0.0
    max_increments: int = 2000

    def __post_init__(self):
        if not (isinstance(self.max_increments, (int, np.integer)) and self.max_increments >= 1):
            raise ValueError(f"max_increments must be an integer >= 1, got "
                             f"{self.max_increments!r}")
        if not (is_number(self.newton_ftol) and 0.0 <= self.newton_ftol < 1.0):
            raise ValueError(f"newton_ftol must be in [0, 1), got {self.newton_ftol!r}")

    def solver_options(self):
        """The :class:`fxcontact.SolverOptions` of these numerics."""
        return SolverOptions(line_search=self.line_search,
                             active_set_prediction=self.active_set_prediction,
                             penalty_continuation=self.penalty_continuation,
                             ftol=float(self.newton_ftol))


@dataclass(frozen=True)
class StopRules:
    """When :class:`SteadyMonitor` stops (lengths in the unit of the rows' ``front``/``tail``).

    Attributes:
        steady_keys: the row quantities that must be steady (e.g. roll force and torque).
        window: increments per window (≥ 1; :func:`window_increments`).
        steady_tol: largest relative change of a key's window mean between the two windows.
        settle: the windows count once every row's ``front`` is beyond it.
        max_increments: increments at most.
        grip_travel: with a pusher: the front's travel from ``front_start`` allowed before the
            workpiece is declared refused; ``None``: no pusher phase.
        front_start: the front's position at the start.
        tail_limit: a row whose ``tail`` is beyond it stops the run (the workpiece is too short).
        body, zone: words of the messages ("strip", "bite").
        hints: text appended to the message of a status (the cure, the theory's limit).
    """

    steady_keys: Tuple[str, ...]
    window: int
    steady_tol: float
    settle: float
    max_increments: int
    grip_travel: Optional[float] = None
    front_start: float = 0.0
    tail_limit: float = math.inf
    body: str = "workpiece"
    zone: str = "tool"
    hints: Mapping[str, str] = field(default_factory=dict)

    def __post_init__(self):
        if not self.steady_keys or isinstance(self.steady_keys, str):
            raise ValueError("steady_keys must name at least one row quantity (a tuple of names)")
        if not (isinstance(self.window, (int, np.integer)) and self.window >= 1):
            raise ValueError(f"window must be an integer >= 1 (increments), got {self.window!r}")
        if not (isinstance(self.max_increments, (int, np.integer)) and self.max_increments >= 1):
            raise ValueError(f"max_increments must be an integer >= 1, got "
                             f"{self.max_increments!r}")
        _finite("steady_tol", self.steady_tol)
        if self.grip_travel is not None:
            _finite("grip_travel", self.grip_travel)
        unknown = set(self.hints) - set(STATUSES)
        if unknown:
            raise ValueError(f"hints for unknown status(es) {sorted(unknown)}; the statuses: "
                             f"{STATUSES}")


def contact_lines(sim) -> List[str]:
    """Each contributor's line of the run's summary (a contact: its scheme, the penalty as
    resolved, each friction law and which shear flow stress k it uses), for a process's
    report: the processes step their simulation themselves, so ``Simulation.run``'s summary is
    not printed."""
    return [c.summary() for c in getattr(sim, "contributors", ())   # (a scripted stand-in: none)
            if isinstance(c, HasSummary)]


@dataclass
class SteadyRun:
    """What a :class:`SteadyMonitor` run gives: the stop reason and the history; the base of the
    processes' results (which add the process's steady values and theory)."""

    status: str
    message: str
    history: List[dict]
    gripped_at: Optional[float]
    steady_from: Optional[int]
    wall: float
    # the steady window's means of the power balance (:class:`fxcontact.power.PowerBalance`)
    dissipation: float = math.nan
    friction_power: float = math.nan
    penalty_power: float = math.nan
    power_balance: float = math.nan
    power_balance_penalty: float = math.nan
    #: each contact's line of the run's summary (:func:`contact_lines`)
    contacts: List[str] = field(default_factory=list)

    @property
    def increments(self) -> int:
        return len(self.history)

    @property
    def steady(self) -> bool:
        return self.status == "steady"

    def window(self) -> List[dict]:
        """The rows of the steady window (empty unless steady)."""
        return self.history[self.steady_from:] if self.steady else []

    def means(self, keys: Sequence[str]) -> Dict[str, float]:
        """Means of ``keys`` over the steady window."""
        last = self.window()
        return {k: float(np.mean([q[k] for q in last])) for k in keys}

    def oscillation(self, key: str) -> float:
        """Half the range of ``key`` over the steady window, relative to its mean."""
        a = np.array([q[key] for q in self.window()])
        return float(np.ptp(a) / (2.0 * np.mean(a)))

    @property
    def max_volume_change(self) -> float:
        return max(abs(q["volume_change"]) for q in self.history)

    @property
    def min_quality(self) -> float:
        return min(q["min_quality"] for q in self.history)

    @property
    def newton_mean(self) -> float:
        return float(np.mean([q["newton_iterations"] for q in self.history]))

    @property
    def newton_max(self) -> int:
        return int(max(q["newton_iterations"] for q in self.history))

    @property
    def wall_split(self) -> dict:
        return wall_split(self.history)

    def run_summary(self) -> str:
        """Newton, wall time, volume and quality lines of a report."""
        return (f"Newton its mean {self.newton_mean:.1f} max {self.newton_max}; wall "
                f"{self.wall:.0f} s for {self.increments} increments; max |dV/V| "
                f"{self.max_volume_change:.2e}; min quality {self.min_quality:.3f}\n"
                f"wall by part: {format_wall_split(self.wall_split)}"
                + "".join(f"\n{x}" for x in [format_iteration_split(self.wall_split)] if x)
                + "".join(f"\n{line}" for line in self.contacts))

    def run_fields(self) -> dict:
        """This run's fields (to build a process result from it)."""
        return {**{f.name: getattr(self, f.name) for f in fields(SteadyRun)[:6]},
                "contacts": self.contacts}


class SteadyMonitor:
    """Runs increments of ``sim`` of size ``dt`` until one of the :class:`StopRules` holds.

    Args:
        sim: a set-up :class:`fxcontact.Simulation`.
        dt: the increment.
        measure: ``measure(increment_result) -> row`` (a dict with the keys the rules read).
        rules: :class:`StopRules`.
        release: called with the time at the grip (the pusher stops).
        before_step: called with the increment's index before each increment.
        name: the process's name in the progress log.
    """

    def __init__(self, sim, dt: float, measure: Callable[[object], dict], rules: StopRules,
                 release: Optional[Callable[[float], None]] = None,
                 before_step: Optional[Callable[[int], None]] = None, name: str = "process"):
        self.sim, self.dt, self.measure, self.rules = sim, dt, measure, rules
        self.release, self.before_step, self.name = release, before_step, name

    def _message(self, status, text):
        hint = self.rules.hints.get(status, "")
        return f"{text}{'; ' + hint if hint else ''}"

    def run(self) -> SteadyRun:
        ru, sim = self.rules, self.sim
        rows: List[dict] = []
        status, message = "running", ""
        gripped_at, steady_from = None, None
        gripping = ru.grip_travel is not None
        wall0 = time.perf_counter()
        for it in range(int(ru.max_increments)):
            if self.before_step is not None:
                self.before_step(it)
            try:
                res = sim.step(self.dt)
            except IncrementError as err:      # raised on every rank: no hang
                if not rows:
                    raise
                status, message = "failed", self._message("failed", str(err))
                break
            row = self.measure(res)
            rows.append(row)
            if sim.comm.rank == 0:             # progress of a long run (--quiet hides it)
                log.info("%s: t = %.4g, front %.4g, %s %.4g, %d Newton its, %.1f s", self.name,
                         sim.t, row["front"], ru.steady_keys[0], row[ru.steady_keys[0]],
                         row.get("newton_iterations", -1), row.get("wall", math.nan))
            if gripping and gripped_at is None:
                if len(rows) >= 2 and rows[-1]["pusher_nodes"] == 0 \
                        and rows[-2]["pusher_nodes"] == 0:
                    gripped_at = sim.t
                    if self.release is not None:
                        self.release(sim.t)
                elif row["front"] - ru.front_start > ru.grip_travel:
                    status = "refused"
                    message = self._message("refused", (
                        f"the {ru.body} refuses to enter: not gripped after a push of "
                        f"{row['front'] - ru.front_start:.3g} (grip_travel {ru.grip_travel:.3g})"))
                    break
                continue
            if row["contact_nodes"] == 0:
                status = "lost"
                message = self._message("lost", (
                    f"the {ru.body} lost contact with the tools at t = {sim.t:.4g}"
                    f"{' after the pusher let go' if gripping else ''} (front at "
                    f"{row['front']:.4g})"))
                break
            if row["tail"] > ru.tail_limit:
                status = "no steady state"
                message = self._message("no steady state", (
                    f"the {ru.body}'s tail reached the {ru.zone} at t = {sim.t:.4g} before a "
                    f"steady state: lengthen the {ru.body}"))
                break
            steady_from = steady_window(rows, ru.steady_keys, ru.window, ru.steady_tol,
                                        ready=lambda q: q["front"] > ru.settle)
            if steady_from is not None:
                status = "steady"
                message = (f"the means of {', '.join(ru.steady_keys)} over two windows of "
                           f"{ru.window} increments agree within {ru.steady_tol:g}")
                break
        else:
            status = "no steady state"
            message = f"max_increments = {ru.max_increments} reached before a steady state"
        return SteadyRun(status, message, rows, gripped_at, steady_from,
                         time.perf_counter() - wall0, contacts=contact_lines(sim))
