"""Radial ring rolling (THEORY §12.1, §14.4) as one package: the case and the theory of its
pass (:mod:`~fxcontact.processes.ring_rolling.case`), the build, the run and its result
(:mod:`~fxcontact.processes.ring_rolling.process`), the mill's own controllers — guide rolls
centring the ring, axial cone rolls, bite zones (:mod:`~fxcontact.processes.ring_rolling.mill`)
— and the pictures (:mod:`~fxcontact.processes.ring_rolling.pictures`).

``ring_rolling.run(case)`` rolls a ring; ``ring_rolling.build(case)`` returns the ready
simulation with its handles."""

from fxcontact.processes.ring_rolling.case import (K_HOT, K_THESIS, QUICK, TOOLS, UPDATES,
                                                   RingRollingCase, theory)
from fxcontact.processes.ring_rolling.mill import AxialRolls, RingCentring
from fxcontact.processes.ring_rolling.process import (RingRollingResult, RingRollingSetup, build,
                                                      run)

__all__ = ["AxialRolls", "RingCentring", "K_HOT", "K_THESIS", "QUICK", "TOOLS", "UPDATES",
           "RingRollingCase", "RingRollingResult", "RingRollingSetup", "build", "run", "theory"]
