"""Remeshing of the deformed body, in building blocks: the boundary of the current geometry
gathered on rank 0 (:mod:`~fxcontact.remesh.surface`), a new graded volume mesh made by gmsh
from it (:mod:`~fxcontact.remesh.volume`), the transfer of fields by parallel point location
(:mod:`~fxcontact.remesh.transfer`) and the criteria that say when to remesh
(:mod:`~fxcontact.remesh.criteria`)."""
