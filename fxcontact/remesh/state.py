"""The state a :class:`~fxcontact.simulation.Simulation` keeps between increments, carried to a
new mesh of the body.

What an increment reads from the previous ones (``simulation.py``):

* ``w_prev``: the last converged (velocity, pressure), the predictor of the next Newton solve
  and the switch that skips the start-up solve — transferred by point values
  (:func:`~fxcontact.remesh.transfer.interpolate_from`: MINI velocity at the vertices and the
  cell centroids, P1 pressure at the vertices);
* ``strain`` (the accumulated equivalent strain, DG0) — transferred with its integral conserved
  (:func:`~fxcontact.remesh.transfer.transfer_cellwise`, ``"scale"``); ``strain_rate`` (DG0, an
  output) the same way;
* the volume correction's reference ``_volume_initial`` (the body's volume at t = 0): a number,
  kept as it is, so that ``ln(V/V⁰)`` goes on from the new mesh's volume;
* the dual stress (:class:`~fxcontact.element.dual.DualStress`) is not state: ``begin()`` sets it to
  the primal stress of the predictor at the start of every Newton solve, so the new simulation
  rebuilds it from the transferred velocity;
* ``t``, ``increment``, ``history``, tools and controllers: unchanged numbers and objects.
"""

from __future__ import annotations

from typing import Dict

import dolfinx
import dolfinx.fem

from fxcontact.remesh.transfer import interpolate_from, transfer_cellwise

__all__ = ["transfer_simulation_state"]


def transfer_simulation_state(sim, space) -> Dict[str, object]:
    """The fields of ``sim`` (its current mesh) on the new :class:`~fxcontact.spaces.
    MixedSpace` ``space`` (collective).

    Returns ``{"w_prev": Function(space.W), "strain": Function(space.DG0), "strain_rate":
    Function(space.DG0), "volume_initial": float, "transfer": {name: transfer_cellwise info}}``.
    """
    old = sim.space
    w_old = sim.w_prev
    w_old.x.scatter_forward()
    w_new = dolfinx.fem.Function(space.W, name="solution")
    for Vo, o2W, Vn, n2W in ((old.V, old.V_to_W, space.V, space.V_to_W),
                             (old.Q, old.Q_to_W, space.Q, space.Q_to_W)):
        fo = dolfinx.fem.Function(Vo)
        fo.x.array[:] = w_old.x.array[o2W]
        fn = dolfinx.fem.Function(Vn)
        interpolate_from(fo, fn)
        w_new.x.array[n2W] = fn.x.array
    w_new.x.scatter_forward()
    out = {"w_prev": w_new, "volume_initial": sim.initial_volume, "transfer": {}}
    for name in ("strain", "strain_rate"):
        f = dolfinx.fem.Function(space.DG0, name=getattr(sim, name).name)
        out["transfer"][name] = transfer_cellwise(getattr(sim, name), f, conserve="scale")
        out[name] = f
    return out
