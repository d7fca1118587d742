"""Forming processes as a library: per process a case (a frozen dataclass: geometry, material,
friction, kinematics, numerics; ``.quick()`` is the reduced size of the tests), a builder that
returns the ready :class:`fxcontact.Simulation` with its handles, and ``run(case)`` returning a
result (steady values over the detected steady window, the theory band, power balance,
pictures, ``report()``).

* :mod:`fxcontact.processes.drawing` — wire drawing through a die: :class:`DrawingCase`,
  :func:`build_drawing`, :func:`run_drawing`;
* :mod:`fxcontact.processes.extrusion` — forward extrusion: :class:`ExtrusionCase`,
  :func:`build_extrusion`, :func:`run_extrusion`;
* :mod:`fxcontact.processes.upsetting` — upsetting a cylinder between flat dies, remeshed:
  :class:`UpsettingCase`, :func:`build_upsetting`, :func:`run_upsetting`;
* :mod:`fxcontact.processes.upsetting_dies` — upsetting a quarter billet on one mesh between
  sticking, sliding, Tresca or Coulomb dies against the upper bound and the slab estimate:
  :func:`run_upsetting_dies`;
* :mod:`fxcontact.processes.ring_test` — the ring-compression friction test against Avitzur's
  calibration curves: :func:`run_ring_test`;
* :mod:`fxcontact.processes.flat_rolling` — flat rolling of a strip (one quarter);
* :mod:`fxcontact.processes.bar_rolling` — three-roll rolling of a round bar (a third or the
  whole bar);
* :mod:`fxcontact.processes.ring_rolling` — radial ring rolling (driven main roll, idle
  mandrel fed towards it, guide rolls, optional cone rolls; pictures in ``ring_pictures``);
* :mod:`fxcontact.processes.ironing` — a rigid cylinder (analytic, flat-faceted or
  Nagata-smoothed) ironing an elastic slab: ``ironing.run``, the tool comparison per
  (tool, facets, scheme) variant; :mod:`fxcontact.processes.groove` — the concave counterpart, a
  round bar in a turning faceted groove: ``groove.run``; their statistics, tables and pictures
  in :mod:`fxcontact.processes.ironing_report`;
* :mod:`fxcontact.processes.hertz_sphere`, :mod:`fxcontact.processes.hertz_cylinder` — Hertz
  validation: a rigid sphere indenting an elastic quarter block (MINI mixed or P1
  displacement, analytic or faceted tool: :func:`run_hertz_sphere`) and a rigid cylinder
  pressed on a half block in plane strain (:func:`run_hertz_cylinder`); Hertz's formulas, the
  graded block and the octahedral sphere tool in :mod:`fxcontact.processes.hertz`;
* :mod:`fxcontact.processes.hyperelastic` — contact in a user's own dolfinx problem: a
  neo-Hookean block pressed by a ball with dolfinx's NewtonSolver, a SNES or fxcontact's
  solver (:func:`run_hyperelastic`);
* shared pieces: :mod:`fxcontact.processes.monitor` (the run-until-steady loop and its stop
  rules), :mod:`fxcontact.processes.common` (gathers, power balance, sections and curves),
  :mod:`fxcontact.processes.die` (the bar's nose, the die and its faceted sectors),
  :mod:`fxcontact.processes.contact_laws` (every case's ``penalty`` and ``friction`` fields and
  their former spellings).
"""

from fxcontact.processes import (bar_rolling, flat_rolling, groove, hertz, hertz_cylinder,
                                 hertz_sphere, hyperelastic, ironing, ironing_report, ring_rolling,
                                 ring_test, upsetting_dies)
from fxcontact.processes.bar_rolling import BarRollingCase, BarRollingResult, BarRollingSetup
from fxcontact.processes.drawing import DrawingCase, DrawingResult, DrawingSetup
from fxcontact.processes.drawing import build as build_drawing, run as run_drawing
from fxcontact.processes.extrusion import ExtrusionCase, ExtrusionResult, ExtrusionSetup
from fxcontact.processes.extrusion import build as build_extrusion, run as run_extrusion
from fxcontact.processes.flat_rolling import FlatRollingCase, FlatRollingResult, FlatRollingSetup
from fxcontact.processes.hertz_cylinder import run as run_hertz_cylinder
from fxcontact.processes.hertz_sphere import run as run_hertz_sphere
from fxcontact.processes.hyperelastic import run as run_hyperelastic
from fxcontact.processes.monitor import (STATUSES, RunNumerics, SteadyMonitor, SteadyRun, StopRules,
                                         window_increments)
from fxcontact.processes.ring_rolling import RingRollingCase, RingRollingResult, RingRollingSetup
from fxcontact.processes.ring_test import run as run_ring_test
from fxcontact.processes.upsetting import UpsettingCase, UpsettingResult, UpsettingSetup
from fxcontact.processes.upsetting import build as build_upsetting, run as run_upsetting
from fxcontact.processes.upsetting_dies import run as run_upsetting_dies

__all__ = ["bar_rolling", "flat_rolling", "groove", "hertz", "hertz_cylinder", "hertz_sphere",
           "hyperelastic", "ironing", "ironing_report", "ring_rolling", "ring_test", "upsetting_dies",
           "BarRollingCase", "BarRollingResult", "BarRollingSetup",
           "DrawingCase", "DrawingResult", "DrawingSetup", "build_drawing", "run_drawing",
           "ExtrusionCase", "ExtrusionResult", "ExtrusionSetup", "build_extrusion",
           "run_extrusion",
           "FlatRollingCase", "FlatRollingResult", "FlatRollingSetup",
           "run_hertz_cylinder", "run_hertz_sphere", "run_hyperelastic",
           "RingRollingCase", "RingRollingResult", "RingRollingSetup", "run_ring_test",
           "UpsettingCase", "UpsettingResult", "UpsettingSetup", "build_upsetting",
           "run_upsetting", "run_upsetting_dies",
           "STATUSES", "RunNumerics", "SteadyMonitor", "SteadyRun", "StopRules", "window_increments"]
