"""The retry ladder of one increment: fall-backs at the same dt, then cut-backs (THEORY §1.5).

:meth:`Simulation.step <fxcontact.simulation.Simulation.step>` hands one increment to
:class:`RetryLadder`, which tries it at ``dt`` and, when Newton fails, climbs these levels:

1. **fall-backs at the same dt**, each taken once and in this order:

   * the linear solver that ``linear_solver="auto"`` chose iteratively (condensed-amg) failed:
     the direct condensed solver from now on (``ContactNewtonSolver.fall_back_to_direct``);
   * the primal–dual Norton–Hoff tangent failed (:mod:`fxcontact.element.dual`): the consistent tangent
     for the attempts at this dt;
   * the line search failed: ``SolverOptions.line_search_fallback`` for one attempt;

2. **cut-back**: dt halved, at most ``max_cutbacks`` times and never below ``min_dt``; an
   increment whose geometry update would invert a cell counts as failed
   (:meth:`~fxcontact.mesh_health.MeshHealth.accept`);
3. **remesh** (:meth:`Simulation.set_remeshing <fxcontact.simulation.Simulation.
   set_remeshing>` with ``rescue``): when the last attempt inverted a cell, the body is
   remeshed once and the increment taken again from ``dt``;
4. **stop**: an :class:`IncrementError` (:class:`MeshInversionError` for an inverted cell) naming
   the time, the last dt and the reason of every attempt; a checkpoint of the last accepted
   state is written first when checkpoints are on.
"""

from __future__ import annotations

import logging
import time
from typing import List

from fxcontact.mesh_health import INVERSION

__all__ = ["RetryLadder", "IncrementError", "MeshInversionError"]

log = logging.getLogger(__name__)


class IncrementError(RuntimeError):
    """Newton failed at some time even after the allowed cut-backs."""

    def __init__(self, t: float, dt: float, message: str):
        super().__init__(f"increment starting at t = {t:.6g} failed (last dt = {dt:.3g}): "
                         f"{message}. Results up to t = {t:.6g} are written.")
        self.t = t
        self.dt = dt


class MeshInversionError(IncrementError):
    """An element would invert (signed volume ≤ 0) even after the allowed cut-backs."""


def _attempts(msgs) -> str:
    """The reasons of the failed attempts at one dt (fall-backs, then the last), each once."""
    msgs = list(dict.fromkeys(msgs))
    if len(msgs) == 1:
        return msgs[0]
    return f"{len(msgs)} attempts: " + " | ".join(msgs)


class RetryLadder:
    """Cut-backs and fall-backs of the increments of one :class:`~fxcontact.simulation.
    Simulation` (see the module docstring). It drives the simulation's ``_try_increment``
    (one Newton attempt), its mesh health (``accept``) and ``_commit``/``_record``."""

    def __init__(self, sim):
        self.sim = sim

    def step(self, dt: float, max_cutbacks: int, min_dt: float):
        """The increment at ``dt`` or less: ``(row, info)`` of the accepted attempt (the row
        recorded in the history), or an :class:`IncrementError`."""
        sim = self.sim
        trial = float(dt)
        msg = ""
        msgs: List[str] = []
        failed_its = 0
        t_first = time.perf_counter()
        for k in range(max_cutbacks + 1):
            if k > 0 and trial < min_dt * (1.0 - 1e-12):
                msg += f"; dt would fall below the smallest allowed {min_dt:.3g}"
                break
            t0 = time.perf_counter()
            first = len(msgs)   # the attempts at this dt, for the cut-back warning
            info, its = self._attempt_with_fallbacks(trial, msgs)
            failed_its += its
            if info.converged and sim._mesh_health.accept(trial, info):
                row = sim._commit(trial, info)
                row["cutbacks"] = k
                # Newton iterations of the accepted attempt plus those of the failed attempts
                row["newton_iterations_all"] = info.iterations + failed_its
                row["wall_increment"] = time.perf_counter() - t0
                row["wall_increment_all"] = time.perf_counter() - t_first
                sim._record(row)
                return row, info
            msg = info.message
            msgs.append(msg)
            failed_its += info.iterations
            log.warning("t = %.6g: Newton failed with dt = %.3g (%s); retrying with dt/2",
                        sim.t, trial, _attempts(msgs[first:]))
            trial *= 0.5
        if msg.startswith(INVERSION) and sim._remeshing is not None \
                and sim._remeshing.rescue(sim):   # a new mesh, then the increment again
            return self.step(dt, max_cutbacks, min_dt)
        earlier = [m for m in dict.fromkeys(msgs[:-1]) if m != msgs[-1]] if msgs else []
        if earlier:
            msg += f" (earlier attempts: {' | '.join(earlier)})"
        raise self.failure(trial * 2, msg)

    def _attempt_with_fallbacks(self, trial: float, msgs: List[str]):
        """One attempt at ``trial`` and the fall-backs at the same dt (level 1 of the ladder):
        the last attempt's info and the Newton iterations of the failed ones (their messages
        appended to ``msgs``)."""
        sim = self.sim
        failed_its = 0
        info = sim._try_increment(trial)
        if not info.converged and "condensed linear solve failed" in info.message \
                and sim.solver.fall_back_to_direct():
            # "auto" chose the iterative solver and it failed: the direct one from now on,
            # the same dt again
            log.warning("t = %.6g: %s; the linear solver chosen by 'auto' is switched from "
                        "condensed-amg to condensed-mumps", sim.t, info.message)
            if sim._startup is not None:
                sim._startup.fall_back_to_direct()
            failed_its += info.iterations
            msgs.append(info.message)
            info = sim._try_increment(trial)
        dual_off = False
        if not info.converged and sim.dual is not None and sim.dual.active \
                and not sim.problem.error:
            # second attempt at the same dt with the consistent tangent (the primal-dual
            # direction is not always a descent direction of the residual norm), and the
            # line-search fallback below with it too
            log.info("t = %.6g: Newton failed with the primal-dual tangent (%s); retrying "
                     "dt = %.3g with the consistent tangent", sim.t, info.message, trial)
            failed_its += info.iterations
            msgs.append(info.message)
            sim.dual.active, dual_off = False, True
        try:
            if dual_off:
                info = sim._try_increment(trial)
            opts = sim.solver_options
            fb = opts.line_search_fallback
            if not info.converged and fb and fb != opts.line_search and not sim.problem.error:
                # another attempt at the same dt with the fallback line search
                log.info("t = %.6g: Newton failed with the %s line search (%s); retrying "
                         "dt = %.3g with the %s line search", sim.t, opts.line_search,
                         info.message, trial, fb)
                failed_its += info.iterations
                msgs.append(info.message)
                sim.solver.set_line_search(fb)
                try:
                    info = sim._try_increment(trial)
                finally:
                    sim.solver.set_line_search(opts.line_search)
        finally:
            if dual_off:
                sim.dual.active = True
        return info, failed_its

    def failure(self, dt: float, msg: str) -> IncrementError:
        """The error of an increment that failed for good; a checkpoint of the last accepted
        state is written first (when checkpoints are on) so the run can be resumed from it."""
        sim = self.sim
        if sim.checkpoint_every:
            try:
                sim._checkpoints.write_unless_there()
            except OSError as e:
                log.warning("checkpoint at the failed increment not written: %s", e)
        cls = MeshInversionError if msg.startswith(INVERSION) else IncrementError
        return cls(sim.t, dt, msg)
