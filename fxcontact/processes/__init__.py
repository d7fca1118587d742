"""Forming processes built from fxcontact's pieces: per process a case (a frozen dataclass
with ``.quick()``, the reduced size of the tests), a builder returning a ready
:class:`~fxcontact.Simulation` and its handles, and ``run`` returning a result object with the
steady values, the theory band, the power balance and ``report()``.

* wire drawing: :class:`DrawingCase`, :func:`build_drawing`, :func:`run_drawing`
  (:mod:`fxcontact.processes.drawing`);
* forward extrusion: :class:`ExtrusionCase`, :func:`build_extrusion`, :func:`run_extrusion`
  (:mod:`fxcontact.processes.extrusion`).

Shared pieces: :mod:`fxcontact.processes.common` (gathers, power balance, sections and curves)
and :mod:`fxcontact.processes.die` (the bar's nose, the die and its faceted sectors).
"""

from fxcontact.processes.drawing import DrawingCase, DrawingResult, DrawingSetup
from fxcontact.processes.drawing import build as build_drawing
from fxcontact.processes.drawing import run as run_drawing
from fxcontact.processes.extrusion import ExtrusionCase, ExtrusionResult, ExtrusionSetup
from fxcontact.processes.extrusion import build as build_extrusion
from fxcontact.processes.extrusion import run as run_extrusion

__all__ = ["DrawingCase", "DrawingResult", "DrawingSetup", "build_drawing", "run_drawing",
           "ExtrusionCase", "ExtrusionResult", "ExtrusionSetup", "build_extrusion",
           "run_extrusion"]
