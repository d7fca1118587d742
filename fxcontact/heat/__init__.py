"""Heat in the workpiece (THEORY §16): conduction, deformation and friction heating, exchange with
the tools and the air, on the moving mesh of an updated-Lagrangian run.

* :mod:`fxcontact.heat.materials` — :class:`ThermalMaterial` (ρc, k, η_q, effusivity),
  :class:`AirExchange` (convection and radiation of the free surface), the units and their
  checks;
* :mod:`fxcontact.heat.problem` — :class:`HeatProblem`: P1 temperature, backward Euler with
  lumped capacity and lumped boundary exchange, one linear solve per step, the step's energy
  balance;
* :mod:`fxcontact.heat.inputs` — the step's arguments read and checked on every rank together.
"""

from fxcontact.heat.materials import SIGMA_SB, AirExchange, ThermalMaterial
from fxcontact.heat.problem import BALANCE_KEYS, HEAT_SOLVERS, HeatProblem

__all__ = ["BALANCE_KEYS", "HEAT_SOLVERS", "SIGMA_SB", "AirExchange", "HeatProblem",
           "ThermalMaterial"]
