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
* :mod:`fxcontact.processes.flat_rolling` — flat rolling of a strip (one quarter);
* :mod:`fxcontact.processes.bar_rolling` — three-roll rolling of a round bar (a third or the
  whole bar);
* :mod:`fxcontact.processes.ring_rolling` — radial ring rolling (driven main roll, idle
  mandrel fed towards it, guide rolls, optional cone rolls; pictures in ``ring_pictures``);
* shared pieces: :mod:`fxcontact.processes.monitor` (the run-until-steady loop and its stop
  rules), :mod:`fxcontact.processes.common` (gathers, power balance, sections and curves),
  :mod:`fxcontact.processes.die` (the bar's nose, the die and its faceted sectors),
  :mod:`fxcontact.processes.contact_laws` (every case's ``penalty`` and ``friction`` fields and
  their former spellings).
"""

from fxcontact.processes import bar_rolling, flat_rolling, ring_rolling
from fxcontact.processes.bar_rolling import BarRollingCase, BarRollingResult, BarRollingSetup
from fxcontact.processes.drawing import DrawingCase, DrawingResult, DrawingSetup
from fxcontact.processes.drawing import build as build_drawing
from fxcontact.processes.drawing import run as run_drawing
from fxcontact.processes.extrusion import ExtrusionCase, ExtrusionResult, ExtrusionSetup
from fxcontact.processes.extrusion import build as build_extrusion
from fxcontact.processes.extrusion import run as run_extrusion
from fxcontact.processes.flat_rolling import FlatRollingCase, FlatRollingResult, FlatRollingSetup
from fxcontact.processes.monitor import (STATUSES, RunNumerics, SteadyMonitor, SteadyRun,
                                         StopRules, window_increments)
from fxcontact.processes.ring_rolling import RingRollingCase, RingRollingResult, RingRollingSetup
from fxcontact.processes.upsetting import UpsettingCase, UpsettingResult, UpsettingSetup
from fxcontact.processes.upsetting import build as build_upsetting
from fxcontact.processes.upsetting import run as run_upsetting

__all__ = ["bar_rolling", "flat_rolling", "ring_rolling",
           "BarRollingCase", "BarRollingResult", "BarRollingSetup",
           "DrawingCase", "DrawingResult", "DrawingSetup", "build_drawing", "run_drawing",
           "ExtrusionCase", "ExtrusionResult", "ExtrusionSetup", "build_extrusion",
           "run_extrusion",
           "FlatRollingCase", "FlatRollingResult", "FlatRollingSetup",
           "RingRollingCase", "RingRollingResult", "RingRollingSetup",
           "UpsettingCase", "UpsettingResult", "UpsettingSetup", "build_upsetting",
           "run_upsetting",
           "STATUSES", "RunNumerics", "SteadyMonitor", "SteadyRun", "StopRules", "window_increments"]
