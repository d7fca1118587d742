"""The Jacobian of the MINI element (P1+bubble / P1) with its bubble condensed, and the
primal–dual stress update:

* :mod:`~fxcontact.element.cell` — per-cell numba kernels (bubble inverse, Schur complement,
  tetrahedron geometry, condensation of one cell) and their numpy twins;
* :mod:`~fxcontact.element.tensors` — element tensors: FFCx kernels of any form, the hand-written
  Norton–Hoff kernel, the P1/P1 layout;
* :mod:`~fxcontact.element.jacobian` — the condensed Newton matrix assembled element by element
  and its preconditioner (the default of the condensed presets);
* :mod:`~fxcontact.element.assembled` — the bubble eliminated from the assembled MINI matrix
  inside the linear solve;
* :mod:`~fxcontact.element.dual` — the dual stress of the primal–dual Newton and its kernel.
"""
