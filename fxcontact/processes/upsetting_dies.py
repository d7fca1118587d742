"""Upsetting a Norton–Hoff cylinder between two flat dies, four kinds of dies (THEORY §14.1,
§14.5): the billet of ``demos/demo_upsetting.py``, on one mesh (no remeshing).

A billet of radius R and height H (mm) is compressed by the upper die closing at ``die_speed``
(mm/s) onto the fixed lower one. The material is incompressible Norton–Hoff viscoplastic,
``s = 2K (√3 ε̄̇)^(m-1) ε̇`` (K in MPa·s^m), discretised with MINI (P1+bubble / P1); a quarter of
the billet is modelled (symmetry planes x = 0 and y = 0, the whole height,
:func:`fxcontact.meshing.cylinder_billet`), the geometry is updated after each increment
(updated Lagrangian) and the cumulative equivalent strain is accumulated per cell. The dies
(:data:`DIES`):

* ``sticking`` and ``sliding``: velocity boundary conditions on the end faces; sticking end
  faces cannot spread and the free surface bulges (barrelling); sliding dies keep the
  deformation homogeneous;
* ``tresca`` and ``coulomb``: rigid :class:`~fxcontact.tools.analytic.Plane` tools (the upper
  one moving down, the lower one the static plane z = 0) with nodal penalty contact (implicit
  scheme) and friction (THEORY §9) on the end faces, and frictionless contact with the same
  planes on the lateral surface (which can fold over onto a die; in the same contact as the end
  faces, the lumped area of an edge node would include its share of the lateral surface and
  inflate its friction force): Tresca ``τ = m̄ k`` (``mbar``) or Coulomb ``τ = μ p_n`` (``mu``,
  not limited by Tresca), k = σ₀/√3 of the Norton–Hoff law at the node's strain rate. The body
  is held by the two dies only. A start-up increment of :data:`STARTUP` × dt comes first: the
  nodal Tresca limits k come from the increment's predictor, the rest state in the first one.

**Mean die pressure.** ``p̄ = F/A_h`` with F the die force (whole billet) and ``A_h = V/h`` the
end face of the homogeneous billet of the same volume V at height h, over the flow stress
``σ₀ = √3 K (√3 ε̄̇)^m`` at the mean strain rate ε̄̇ = v/h, next to the upper bound
``1 + m̄ d/(3√3 h)`` (d = 2R_h; m̄ = 1 for sticking dies, 0 for sliding ones;
:func:`fxcontact.theory.forming.upsetting_upper_bound`) and, for Coulomb dies, the slab
estimate ``2(eˣ − x − 1)/x²``, x = 2μR_h/h
(:func:`fxcontact.theory.forming.upsetting_slab_coulomb`). Force, height and strain rate are
those at the start of each increment (the geometry its equilibrium is written on). The
pressure on the actual end face, ``F/(π r_end²)``, is reported too.

This is not :mod:`fxcontact.processes.upsetting` (a sector and half the height of a taller
billet, both dies moving, remeshing, the fold onto the die): a different mesh and different
numerics, so different numbers for the same billet.

Example::

    from fxcontact.processes import upsetting_dies
    res = upsetting_dies.run(h=4.0, n_steps=4, reduction=0.2, dies="tresca", mbar=0.3,
                             output_dir=None)
    print(res["p_mean"][-1], res["upper_bound"][-1])
"""

from __future__ import annotations

import os

import numpy as np
from mpi4py import MPI

from fxcontact.contact.boundary import ContactBoundary
from fxcontact.contact.friction import Coulomb, Tresca
from fxcontact.contact.nodal import NodalContact
from fxcontact.io.series import render_png
from fxcontact.materials import NortonHoff
from fxcontact.meshing import BILLET_TAGS, cylinder_billet
from fxcontact.newton.solver import SolverOptions
from fxcontact.simulation import Simulation
from fxcontact.spaces import MixedSpace
from fxcontact.theory.forming import flow_stress, upsetting_slab_coulomb, upsetting_upper_bound
from fxcontact.tools.analytic import Plane

__all__ = ["DIES", "STARTUP", "run"]

#: kinds of dies: velocity boundary conditions, or Plane tools with friction
DIES = ("sticking", "sliding", "tresca", "coulomb")
#: length of the start-up increment of the dies with friction, as a fraction of dt
STARTUP = 0.05


def run(radius=10.0, height=15.0, h=2.5, K=50.0, m=0.15, die_speed=5.0, reduction=0.3,
        n_steps=15, dies="sticking", mbar=0.3, mu=0.1, output_dir="results/upsetting",
        picture=True, progress=True, comm=MPI.COMM_WORLD, checkpoint_every=0, resume=False,
        volume_correction="global", linear_solver="auto") -> dict:
    """Upset the quarter billet by ``reduction`` of its height in ``n_steps`` increments (and
    a start-up increment of :data:`STARTUP` × dt first with Plane dies).

    Args:
        radius, height: billet size [mm]; h: element size [mm].
        K [MPa·s^m], m: Norton–Hoff parameters.
        die_speed: closing speed of the upper die [mm/s] (the lower die is fixed).
        reduction: final height reduction (fraction of the initial height).
        n_steps: increments (dt = reduction × height / die_speed / n_steps [s]).
        dies: one of :data:`DIES`: ``"sticking"`` (no radial velocity on the end faces),
            ``"sliding"`` (free radial velocity), ``"tresca"`` (Plane dies with Tresca friction
            ``mbar``) or ``"coulomb"`` (Plane dies with Coulomb friction ``mu``).
        mbar: Tresca friction factor m̄ in [0, 1] (``dies="tresca"``).
        mu: Coulomb coefficient μ ≥ 0 (``dies="coulomb"``).
        output_dir: the VTK series ``upsetting.pvd``, the CSV history ``upsetting_history.csv``
            and the picture ``upsetting.png`` go there (None: nothing written).
        picture: draw ``upsetting.png`` (the equivalent strain on the deformed billet).
        progress: log the increments.
        comm: the MPI communicator.
        checkpoint_every: write a checkpoint every n increments (``output_dir/checkpoints``).
        resume: continue from the newest checkpoint (a run that was killed).
        volume_correction: passed to :class:`~fxcontact.simulation.Simulation`.
        linear_solver: ``SolverOptions.linear_solver`` (``"auto"``: by the problem's size).
    Returns:
        dict with ``history`` (the Simulation's rows), ``height`` (final) [mm], ``radius_mid``
        and ``radius_end`` (largest radius at mid-height and on the end faces: barrelling)
        [mm], ``die_force`` (final, on the body, full billet; < 0) [N], ``volume_change``,
        ``max_strain`` (largest equivalent strain), ``dies``, and per increment (arrays)
        ``reduction`` (at the start of the increment), ``p_mean`` (p̄/σ₀ on the homogeneous
        end face, module docstring), ``p_face`` (p̄/σ₀ on the actual end face), ``sigma0``
        [MPa], ``upper_bound`` (p̄/σ₀ of the Tresca upper bound; NaN for Coulomb dies),
        ``slab`` (Coulomb slab estimate; NaN for the other dies); the paths ``vtk`` and ``png``
        (None without ``output_dir``).
    """
    if dies not in DIES:
        raise ValueError(f"dies must be one of {DIES}, got {dies!r}")
    if not (0 < reduction < 1 and n_steps >= 1 and die_speed > 0):
        raise ValueError("need 0 < reduction < 1, n_steps >= 1 and die_speed > 0")
    msh, _, ft = cylinder_billet(comm, radius, height, h, quarter=True)
    space = MixedSpace(msh)
    sim = Simulation(space, NortonHoff(K=K, m=m, regularization=1e-4 * die_speed / height),
                     output_dir=output_dir, name="upsetting", progress=progress,
                     checkpoint_every=checkpoint_every, overwrite=not resume,
                     volume_correction=volume_correction,
                     solver_options=SolverOptions(linear_solver=linear_solver))
    f = {k: sim.facets(ft, v) for k, v in BILLET_TAGS.items()}
    sim.add_velocity_bc(f["symmetry_x"], 0.0, 0)
    sim.add_velocity_bc(f["symmetry_y"], 0.0, 1)
    contact = None
    if dies == "sticking":
        sim.add_velocity_bc(f["bottom"], np.zeros(3))
        sim.add_velocity_bc(f["top"], np.array([0.0, 0.0, -die_speed]))
    elif dies == "sliding":
        sim.add_velocity_bc(f["bottom"], 0.0, 2)
        sim.add_velocity_bc(f["top"], -die_speed, 2)
    else:
        law = Tresca(mbar) if dies == "tresca" else Coulomb(mu)
        die = Plane(point=(0.0, 0.0, height), normal=(0.0, 0.0, -1.0),
                    velocity=(0.0, 0.0, -die_speed), name="die")
        base = Plane(point=(0.0, 0.0, 0.0), normal=(0.0, 0.0, 1.0), name="base")
        contact = sim.add_contributor(NodalContact(
            ContactBoundary(space, ft, [BILLET_TAGS["top"], BILLET_TAGS["bottom"]]),
            [die, base], scheme="implicit", friction=law, name="contact"))
        # the lateral surface may fold over onto the dies: frictionless contact with the same
        # planes (a node's lumped area sums its facets: in one contact with the end faces, an
        # edge node would carry friction on its lateral area share too)
        sim.add_contributor(NodalContact(
            ContactBoundary(space, ft, BILLET_TAGS["lateral"]),
            [Plane(die.point, die.normal, velocity=(0.0, 0.0, -die_speed), name="die_fold"),
             Plane(base.point, base.normal, name="base_fold")], scheme="implicit",
            name="fold"))
    if contact is None:
        sim.add_reaction("die", f["top"])
    t_end = reduction * height / die_speed
    dt = t_end / n_steps
    if resume:
        sim.resume()
    # end-face radii recorded per increment (NaN for increments restored from a
    # checkpoint: their geometry is gone)
    n_restored = len(sim.history)
    volume0 = sim.volume() if not n_restored else np.nan
    r_face = [np.nan] * n_restored

    def end_face_radius(sim_, res):
        # largest radius of the nodes on the upper die at the end of the increment
        x = sim_.vertex_positions()
        top = comm.allreduce(np.max(x[:, 2], initial=-np.inf), op=MPI.MAX)
        on = x[:, 2] > top - 1e-3 * h
        r_face.append(comm.allreduce(np.max(np.hypot(x[on, 0], x[on, 1]), initial=0.0),
                                     op=MPI.MAX))

    if contact is not None and not n_restored:
        # start-up increment: the nodal Tresca limits k come from the increment's predictor,
        # which is the rest state in the first increment (k at the regularisation's strain
        # rate); a short first increment (5 % of dt) gives the next ones a real predictor
        sim.run(STARTUP * dt, STARTUP * dt, close=False, callback=end_face_radius)
    if sim.t < t_end * (1.0 - 1e-9):
        sim.run(t_end, dt, callback=end_face_radius)
    else:  # resumed from the checkpoint of the last increment: nothing left to do
        sim.close()
    hist = sim.history
    # die force on the body (full billet), per increment
    if contact is None:
        Fz = np.array([4.0 * row["die_z"] for row in hist])
    else:
        Fz = np.array([-4.0 * (row["die_force_z"] + row["die_fold_force_z"]) for row in hist])
    # the increment's equilibrium is written on its initial geometry (updated Lagrangian)
    t0 = np.array([row["time"] - row["dt"] for row in hist])
    # volume at the start of each increment (the explicit geometry update of an increment
    # changes it by O(dt²): 0.2 % per increment of 5 % height reduction)
    vol = 4.0 * np.r_[volume0, [row["volume"] for row in hist[:-1]]]
    h0 = height - die_speed * t0
    area_h = vol / h0                        # homogeneous end face (volume is conserved)
    R_h = np.sqrt(area_h / np.pi)
    sigma0 = flow_stress(K, m, die_speed / h0)
    p_mean = -Fz / area_h / sigma0
    r0 = np.r_[radius, r_face[:-1]]          # end face at the start of each increment
    p_face = -Fz / (np.pi * r0 ** 2) / sigma0
    mb = {"sticking": 1.0, "sliding": 0.0, "tresca": mbar}.get(dies)
    ub = np.array([upsetting_upper_bound(mb, 2 * r, hh) if mb is not None else np.nan
                   for r, hh in zip(R_h, h0)])
    slab = np.array([upsetting_slab_coulomb(mu, r, hh) if dies == "coulomb" else np.nan
                     for r, hh in zip(R_h, h0)])
    # barrelling: radius of the lateral surface at mid-height vs at the end faces
    x = space.vertex_positions()
    r = np.hypot(x[:, 0], x[:, 1])
    hcur = comm.allreduce(np.max(x[:, 2]), op=MPI.MAX)
    zmin = comm.allreduce(np.min(x[:, 2]), op=MPI.MIN)
    mid = np.abs(x[:, 2] - 0.5 * (hcur + zmin)) < 0.51 * h
    ends = (x[:, 2] < zmin + 1e-3 * h) | (x[:, 2] > hcur - 1e-3 * h)
    r_mid = comm.allreduce(np.max(r[mid], initial=0.0), op=MPI.MAX)
    r_end = comm.allreduce(np.max(r[ends], initial=0.0), op=MPI.MAX)
    png = None
    if picture and output_dir is not None:
        png = os.path.join(output_dir, "upsetting.png")
        label = {"tresca": f"Tresca m̄ = {mbar:g}", "coulomb": f"Coulomb μ = {mu:g}"}.get(
            dies, dies)
        render_png(msh, png, sim.strain.x.array, "equivalent strain",
                   title=f"Upsetting, {label} dies, {100 * reduction:.0f}% reduction")
    return {"history": hist, "height": hcur - zmin, "radius_mid": r_mid, "radius_end": r_end,
            "die_force": float(Fz[-1]), "png": png,
            "volume_change": sim.history[-1]["volume_change"],
            "vtk": os.path.join(output_dir, "upsetting.pvd") if output_dir else None,
            "max_strain": comm.allreduce(np.max(sim.strain.x.array), op=MPI.MAX),
            "reduction": 1.0 - h0 / height, "p_mean": p_mean, "p_face": p_face,
            "sigma0": sigma0, "upper_bound": ub, "slab": slab, "dies": dies}
