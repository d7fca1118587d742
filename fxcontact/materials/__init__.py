"""Constitutive laws (THEORY §1): the materials and the UFL pieces of the increment problem that
depend on them.

* :mod:`fxcontact.materials.laws` — :class:`Material`, :class:`NortonHoff` (incompressible
  viscoplasticity, consistency K in MPa·s^m), :class:`LinearElastic` (E in MPa);
* :mod:`fxcontact.materials.forms` — the equivalent strain rate, the secant shear viscosity and
  the primal–dual Jacobian built from a material.
"""

from fxcontact.materials.laws import LinearElastic, Material, NortonHoff

__all__ = ["LinearElastic", "Material", "NortonHoff"]
