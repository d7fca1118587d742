"""Constitutive laws (THEORY §1): the materials and the UFL pieces of the increment problem that
depend on them.

* :mod:`fxcontact.materials.laws` — :class:`Material`, :class:`NortonHoff` (incompressible
  viscoplasticity, consistency K in MPa·s^m), :class:`LinearElastic` (E in MPa);
* :mod:`fxcontact.materials.forms` — the equivalent strain rate, the secant shear viscosity and
  the primal–dual Jacobian built from a material;
* :mod:`fxcontact.materials.flow` — flow-stress laws σ0(ε̄, ε̄̇, T) in MPa (:class:`FlowStress`,
  :class:`PowerHardening`, :class:`HanselSpittel`, :class:`TabulatedFlowStress`) and their
  Norton–Hoff pieces for an element kernel (pure numpy);
* :mod:`fxcontact.materials.local` — :class:`Viscoplastic` (a flow-stress law as a material) and
  :class:`LocalNortonHoff`, its Norton–Hoff law on a mesh with per-cell pieces.
"""

from fxcontact.materials.flow import (FlowStress, HanselSpittel, PowerHardening,
                                     TabulatedFlowStress, interval_of, norton_hoff_pieces)
from fxcontact.materials.laws import LinearElastic, Material, NortonHoff
from fxcontact.materials.local import LocalNortonHoff, Viscoplastic

__all__ = ["FlowStress", "HanselSpittel", "LinearElastic", "LocalNortonHoff", "Material",
           "NortonHoff", "PowerHardening", "TabulatedFlowStress", "Viscoplastic", "interval_of",
           "norton_hoff_pieces"]
