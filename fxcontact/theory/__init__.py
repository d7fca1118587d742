"""Classical forming theory the processes are compared with (THEORY §14), pure numpy/scipy:
:mod:`~fxcontact.theory.forming` (flow stress, upsetting, ring compression, ring rolling,
drawing, extrusion) and :mod:`~fxcontact.theory.flat_rolling` (bite, slab, Sims, Ford–Alexander,
spread)."""
