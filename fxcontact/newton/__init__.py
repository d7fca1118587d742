"""The Newton layer: the nonlinear problem with its nodal terms and all PETSc insertion
(:mod:`~fxcontact.newton.problem`), the SNES solver and its settings
(:mod:`~fxcontact.newton.solver`, :mod:`~fxcontact.newton.options`), bordered systems for idle
tools (:mod:`~fxcontact.newton.bordered`), the active-set prediction
(:mod:`~fxcontact.newton.prediction`), linear-algebra helpers (:mod:`~fxcontact.la`:
several right-hand sides per solve, matrix patterns, rigid-body modes) and the retry ladder of an
increment (:mod:`~fxcontact.newton.retry`)."""
