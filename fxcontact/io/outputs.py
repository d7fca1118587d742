"""The outputs of a :class:`~fxcontact.simulation.Simulation`: CSV history, VTK series, run summary.

:class:`Outputs` opens the writers of :mod:`fxcontact.io` at the first increment (after the
checkpoints of :mod:`fxcontact.checkpoint` have claimed the output directory), writes a CSV row
and, every ``output_every`` increments, a VTK step per accepted increment, continues both after
a second ``run()`` or a ``resume()``, and turns a failed write (a full disk) into an
:class:`OutputError` on every rank. :func:`wall_split` and :func:`format_wall_split` give the
wall-time split of a run's summary.
"""

from __future__ import annotations

import logging
import os
from typing import Optional

import numpy as np

from fxcontact import compat
from fxcontact.io.series import HistoryWriter, SeriesWriter
from fxcontact.protocols import HasOutputFields, UpdatesOutputFields

__all__ = ["Outputs", "OutputError", "WALL_PARTS", "wall_split", "format_wall_split",
           "format_iteration_split",
           "output_dir_problem"]

log = logging.getLogger(__name__)


class OutputError(OSError):
    """Writing the outputs (CSV history, VTK series) failed, e.g. on a full disk."""


#: parts of an increment's wall time measured by the solver (``wall_<part>`` in the history)
WALL_PARTS = ("assembly", "linear_solve", "contact")
#: a part of ``linear_solve`` reported beside it: the condensed solver's set-up (with a direct
#: solver, the factorisations; 0 without the condensed solvers)
WALL_SUBPARTS = ("factorisation",)


def wall_split(rows) -> dict:
    """Wall time of a run by part, summed over its increments.

    ``rows``: :attr:`Simulation.history` or a demo's per-increment rows with the keys
    ``wall_assembly``, ``wall_linear_solve``, ``wall_contact`` and the increment's whole wall time
    (``wall_increment_all``, or ``wall``). Returns ``{"assembly", "linear_solve", "contact",
    "other", "total"}`` in seconds; ``other`` is the rest of the increments (geometry update,
    outputs, the failed attempts of cut-backs and fall-backs), and ``"iterations"``: the Newton
    iterations of all attempts (``newton_iterations_all``, or ``newton_iterations``)."""
    rows = list(rows)
    out = {k: float(sum(q.get(f"wall_{k}", 0.0) for q in rows)) for k in WALL_PARTS}
    out["iterations"] = int(sum(q.get("newton_iterations_all", q.get("newton_iterations", 0))
                                for q in rows))
    out["total"] = float(sum(q.get("wall_increment_all", q.get("wall", 0.0)) for q in rows))
    out["other"] = max(out["total"] - sum(out[k] for k in WALL_PARTS), 0.0)
    for k in WALL_SUBPARTS:
        out[k] = float(sum(q.get(f"wall_{k}", 0.0) for q in rows))
    return out


def format_wall_split(split: dict) -> str:
    """``"assembly 120 s (41 %), linear solve ... (factorisation ...), contact ..., other ..."``
    of :func:`wall_split` (the factorisation when there was one)."""
    tot = split["total"] or float("nan")

    def sec(v):   # whole seconds, tenths below 10 s
        return f"{v:.0f}" if v >= 10.0 else f"{v:.1f}"

    def part(k):
        text = f"{k.replace('_', ' ')} {sec(split[k])} s ({100 * split[k] / tot:.1f} %)"
        if k == "linear_solve" and split.get("factorisation", 0.0) > 0.0:
            text = text[:-1] + f"; factorisation {sec(split['factorisation'])} s)"
        return text
    return ", ".join(part(k) for k in WALL_PARTS + ("other",))


def format_iteration_split(split: dict) -> str:
    """``"0.74 s per Newton iteration (562): assembly 0.18, linear solve 0.48 (factorisation
    0.38, solves and the rest 0.10), contact 0.002, other 0.07 s"`` of :func:`wall_split`: the
    run's wall time of the increments and its parts divided by its Newton iterations (all
    attempts; "other" includes the geometry update and the outputs between them). Empty
    without iterations."""
    n = int(split.get("iterations", 0))
    if n <= 0:
        return ""

    def per(k):
        return f"{split[k] / n:.3g}"

    lin = f"linear solve {per('linear_solve')}"
    if split.get("factorisation", 0.0) > 0.0:
        rest = max(split["linear_solve"] - split["factorisation"], 0.0) / n
        lin += f" (factorisation {per('factorisation')}, solves and the rest {rest:.3g})"
    return (f"{split['total'] / n:.3g} s per Newton iteration ({n}): assembly "
            f"{per('assembly')}, {lin}, contact {per('contact')}, other {per('other')} s")


def output_dir_problem(path) -> Optional[str]:
    """Why ``path`` cannot be the output directory (a file is in the way, not writable), or
    None (None also for ``path=None``: no outputs)."""
    if path is None:
        return None
    p = os.path.abspath(str(path))
    if os.path.exists(p) and not os.path.isdir(p):
        return "is a file, not a directory"
    while not os.path.exists(p):
        p = os.path.dirname(p)
    if not os.path.isdir(p):
        return f"cannot be created: {p!r} is a file"
    if not os.access(p, os.W_OK | os.X_OK):
        return f"cannot be written: no write permission in {p!r}"
    return None


class Outputs:
    """The CSV history and the VTK series of a simulation (``output_dir``, ``name``,
    ``output_every`` of :class:`~fxcontact.simulation.Simulation`).

    Args:
        sim: the simulation whose fields (velocity, pressure, strain, strain rate, displacement,
            the contributors' ``output_fields()``) and history are written.
    """

    def __init__(self, sim):
        self.sim = sim
        self._series = None
        self._history = None
        #: whether the writers were opened once (a later opening continues the files)
        self.opened = False
        # the P1 dof of each mesh vertex (the velocity is written at the vertices)
        c2v = compat.cell_vertices(sim.mesh)
        d = compat.dofmap_array(sim.space.P1)
        self._p1_vertex = np.empty(sim.space.vertex_dofs.shape[0], dtype=np.int32)
        self._p1_vertex[c2v.ravel()] = d[:, : c2v.shape[1]].ravel()

    # ------------------------------------------------------------------ fields
    def functions(self) -> list:
        """The functions of each VTK step: velocity, pressure, strain, strain rate, the
        displacement (small strain) and the contributors' and controllers' ``output_fields()``."""
        sim = self.sim
        fields = [sim.velocity, sim.pressure, sim.strain, sim.strain_rate]
        if sim.displacement_out is not None:
            fields.append(sim.displacement_out)
        for c in sim.contributors + sim.controllers:
            if isinstance(c, HasOutputFields):
                fields.extend(c.output_fields())
        return fields

    def _update_fields(self):
        sim = self.sim
        sp = sim.space
        gd = sp.gdim
        varr = sim.velocity.x.array.reshape(-1, gd)
        varr[self._p1_vertex] = sim.w.x.array[sp.vertex_dofs]
        sim.pressure.x.array[:] = sim.w.x.array[sp.Q_to_W]
        if sim.u is not None:
            sim.displacement_out.x.array.reshape(-1, gd)[self._p1_vertex] = \
                sim._vertex_displacement()

    def _write_fields(self):
        self._update_fields()
        for c in self.sim.contributors:
            if isinstance(c, UpdatesOutputFields):
                c.update_output_fields()
        self._series.write(self.functions(), self.sim.t)

    # ------------------------------------------------------------------ files
    def open(self):
        """Open the writers (collective): a first opening claims the output directory
        (:meth:`~fxcontact.checkpoint.Checkpoints.before_first_outputs`) and writes the initial
        state; a resumed run, or a run whose outputs an earlier ``run()`` closed, continues the
        files."""
        sim = self.sim
        if not self.opened:
            sim._checkpoints.before_first_outputs()
        resumed = sim._checkpoints.resumed is not None or self.opened
        self.opened = True
        self._series = SeriesWriter(sim.comm, sim.output_dir, sim.name,
                                    resume_time=sim.t if resumed else None)
        self._history = HistoryWriter(sim.comm, sim.output_dir, sim.name,
                                      rows=sim.history if resumed else None)
        if not resumed:
            self._write_fields()

    def reopen(self):
        """Continue the CSV history and the VTK series that an earlier ``run()`` closed (a
        second ``run()`` to a later ``t_end``)."""
        sim = self.sim
        if self.opened and self._series is None and self._history is None:
            log.info("%s: continuing the outputs in %s from t = %.6g", sim.name,
                     sim.output_dir, sim.t)
            self.open()

    def write(self, row):
        """CSV row and VTK step of an accepted increment; a failed write (full disk…) stops the
        run on every rank with an :class:`OutputError`, the files written so far untouched."""
        sim = self.sim
        err = None
        try:
            if self._history is not None:
                self._history.write(row)
            if self._series is not None and sim.increment % sim.output_every == 0:
                self._write_fields()
        except OSError as e:
            err = f"{type(e).__name__}: {e}"
        errs = [e for e in sim.comm.allgather(err) if e]
        if errs:
            where = os.path.join(sim.output_dir, sim.name) if sim.output_dir else sim.name
            raise OutputError(
                f"writing the outputs of increment {sim.increment} (t = {sim.t:.6g}) failed "
                f"({errs[0]}); what was written before is intact ({where}_history.csv, "
                f"{where}.pvd). Free disk space and resume from the last checkpoint")

    def close(self):
        if self._series is not None:
            self._series.close()
            self._series = None
        if self._history is not None:
            self._history.close()
            self._history = None
