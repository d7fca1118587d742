"""The configuration-update maps under their former module name: they live in
:mod:`fxcontact.kinematics` (the kinematics in one module); this alias keeps the old imports
working."""

from fxcontact.kinematics import (AXIS_TOL, _cylindrical_kernel,  # noqa: F401
                                  _cylindrical_numpy, cartesian_update, cylindrical_update,
                                  gap_derivatives)

__all__ = ["AXIS_TOL", "cartesian_update", "cylindrical_update", "gap_derivatives"]
