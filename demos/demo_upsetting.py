# ---
# jupyter:
#   jupytext:
#     text_representation:
#       extension: .py
#       format_name: percent
# ---

# %% [markdown]
# # Upsetting a Norton–Hoff cylinder between two flat dies
#
# A hot billet (radius R, height H) is compressed between two flat dies. The material is
# incompressible Norton–Hoff viscoplastic, ``s = 2K (√3 ε̄̇)^(m-1) ε̇``, discretised with MINI
# (P1+bubble / P1). A quarter of the billet is modelled (symmetry planes x = 0 and y = 0). The
# geometry is updated (updated Lagrangian) after each increment, and the cumulative equivalent
# strain is accumulated per cell. Four kinds of dies:
#
# * ``sticking`` and ``sliding`` (default ``sticking``): the dies are velocity boundary
#   conditions on the end faces; sticking end faces cannot spread and the free surface bulges
#   (barrelling); with sliding dies the deformation stays homogeneous.
# * ``tresca`` and ``coulomb``: the dies are rigid :class:`~fxcontact.tools.analytic.Plane`
#   tools (the upper one moving down, the lower one the static plane z = 0) with nodal penalty
#   contact (implicit scheme) and friction (THEORY §9) on the end faces, frictionless contact
#   on the lateral surface (which can fold over onto a die; in the same contact as the end
#   faces, the lumped area of an edge node would include its share of the lateral surface and
#   inflate its friction force): Tresca ``τ = m̄ k`` (``mbar``) or Coulomb ``τ = μ p_n``
#   (``mu``, not limited by Tresca), with k = σ₀/√3 of the Norton–Hoff law at the node's strain
#   rate. The body is held by the two dies only (no velocity condition in z).
#
# **Mean die pressure** (every kind of die). ``p̄ = F/A_h`` with F the die force and
# ``A_h = V/h`` the end-face area of the homogeneous billet of the same volume V and height
# h (``π R_h²``, R_h = R√(H/h)): ``p̄ v A_h = F v`` is the die power per unit area of
# the upper-bound field, so ``p̄/σ₀`` is the number to put next to the upper bound. It is
# divided by the flow stress ``σ₀ = √3 K (√3 ε̄̇)^m`` at the mean strain rate ε̄̇ = v/h
# (THEORY §14.1) and compared with (THEORY §14.5) the upper bound ``1 + m̄ d/(3√3 h)``
# (d = 2R_h; m̄ = 1 for sticking dies, 0 for sliding ones) and, for Coulomb dies, the slab
# estimate ``2(eˣ − x − 1)/x²``, x = 2μR_h/h. The force, heights and strain rate are taken at
# the start of each increment, the geometry the increment's equilibrium is written on. The
# pressure on the actual end face (``F/(π r_end²)``, r_end the largest radius of the nodes on
# the upper die, which is smaller than R_h when the billet barrels) is reported too.
#
# **Volume.** Updating the geometry with ``x += dt v`` loses volume at second order in dt for an
# incompressible flow, and the loss accumulates: at the default size (``--size 2``, 15
# increments, 30 % reduction) the billet lost 0.52 % of its volume with sticking dies and 0.63 %
# with sliding dies. The simulation's default volume correction (THEORY §1.5: the
# incompressibility equation gives back the volume lost so far) brings this to 0.039 % and
# 0.059 % (one increment's error, no longer accumulating); the die force rises by 0.5–0.6 % and
# the sliding radius goes from 11.917 to 11.951 mm (homogeneous: 11.952 mm). Compare with
# ``--volume-correction none``.
#
# Run: ``python demos/demo_upsetting.py`` (serial) or ``mpirun -n 2 python demos/...``.
# ``--size`` sets the element size, ``--dies`` the kind of dies (``--mbar``, ``--mu``); outputs
# go to ``results/upsetting``: a VTK series (``upsetting.pvd``, open it in ParaView), the CSV
# history and a PNG.

# %%
from __future__ import annotations

import argparse
import os

import numpy as np
from mpi4py import MPI

from fxcontact.console import add_verbosity_arguments, configure_logging
from fxcontact.contact.boundary import ContactBoundary
from fxcontact.contact.friction import Coulomb, Tresca
from fxcontact.contact.nodal import NodalContact
from fxcontact.theory.forming import flow_stress, upsetting_slab_coulomb, upsetting_upper_bound
from fxcontact.materials import NortonHoff
from fxcontact.meshing import BILLET_TAGS, cylinder_billet
from fxcontact.simulation import Simulation
from fxcontact.newton.solver import SolverOptions
from fxcontact.spaces import MixedSpace
from fxcontact.tools.analytic import Plane

#: kinds of dies: velocity boundary conditions, or Plane tools with friction
DIES = ("sticking", "sliding", "tresca", "coulomb")
#: length of the start-up increment of the dies with friction, as a fraction of dt
STARTUP = 0.05


# %%
def run(radius=10.0, height=15.0, h=2.5, K=50.0, m=0.15, die_speed=5.0, reduction=0.3,
        n_steps=15, dies="sticking", mbar=0.3, mu=0.1, output_dir="results/upsetting",
        picture=True, progress=True, comm=MPI.COMM_WORLD, checkpoint_every=0, resume=False,
        volume_correction="global", linear_solver="auto") -> dict:
    """Upset the billet by ``reduction`` of its height in ``n_steps`` increments.

    Args:
        radius, height: billet size [mm]; h: element size [mm].
        K [MPa·s^m], m: Norton–Hoff parameters.
        die_speed: closing speed of the upper die [mm/s] (the lower die is fixed).
        reduction: final height reduction (fraction of the initial height).
        dies: one of :data:`DIES`: ``"sticking"`` (no radial velocity on the end faces),
            ``"sliding"`` (free radial velocity), ``"tresca"`` (Plane dies with Tresca friction
            ``mbar``) or ``"coulomb"`` (Plane dies with Coulomb friction ``mu``).
        mbar: Tresca friction factor m̄ in [0, 1] (``dies="tresca"``).
        mu: Coulomb coefficient μ ≥ 0 (``dies="coulomb"``).
        checkpoint_every: write a checkpoint every n increments (``output_dir/checkpoints``).
        resume: continue from the newest checkpoint (a run that was killed).
        volume_correction: passed to :class:`~fxcontact.simulation.Simulation`.
        linear_solver: ``SolverOptions.linear_solver`` (``"auto"``: by the problem's size).
    Returns:
        dict with the history, the final height, the maximum radius at mid-height and on the
        end faces (barrelling), the final die force (on the body, full billet; < 0), and per
        increment (arrays) ``reduction`` (at the start of the increment), ``p_mean`` (p̄/σ₀ on the
        homogeneous end face, see the notes), ``p_face`` (p̄/σ₀ on the actual end face),
        ``sigma0`` [MPa], ``upper_bound`` (p̄/σ₀ of the Tresca upper bound; NaN for Coulomb
        dies), ``slab`` (Coulomb slab estimate; NaN for the other dies); the paths of the
        outputs.
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
        from fxcontact.io import render_png
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


# %% [markdown]
# ## Results with friction (measured, serial, Debian 12 / dolfinx 0.5.2, 2-core machine)
#
# ``python demos/demo_upsetting.py --dies ...`` (R 10, H 15 mm, h = 2 mm, 30 % in 15
# increments; d/h = 1.33 at the start). p̄/σ₀ of the last increment (28 % reduction, h = 10.8 mm)
# on the homogeneous end face, next to the bound; radius at mid-height / on the end faces
# (homogeneous 11.95 mm); wall time:
#
# | dies | p̄/σ₀ FE | upper bound / slab | FE − bound | r_mid / r_end [mm] | wall |
# |---|---|---|---|---|---|
# | sliding (BC) | 1.0000 | 1 | 0 | 11.92 / 11.92 | 9 s |
# | Tresca m̄ = 0.1 | 1.0387 | 1.0419 | −0.3 % | 11.99 / 11.81 | 11 s |
# | Tresca m̄ = 0.3 | 1.0994 | 1.1256 | −2.3 % | 12.12 / 11.60 | 13 s |
# | Tresca m̄ = 1 | 1.1960 | 1.4189 | −15.7 % | 12.36 / 10.97 | 25 s |
# | sticking (BC) | 1.2049 | 1.4181 (m̄ = 1) | −15.0 % | 12.50 / 10.00 | 16 s |
# | Coulomb μ = 0.1 | 1.0635 | 1.0767 (slab) | −1.2 % | 12.04 / 11.75 | 17 s |
# | Coulomb μ = 0.3 | 1.1647 | 1.2584 (slab) | −7.4 % | 12.23 / 11.38 | 20 s |
#
# * The FE pressure is below the upper bound for every m̄, close to it at low friction (the
#   bound's homogeneous field is nearly right) and 16 % below with sticking friction, where the
#   billet barrels and the end faces spread less (r_end 10.97 mm against 11.95 mm).
# * Tresca m̄ = 1 dies carry 0.7 % less than the no-slip velocity condition (they may slip at
#   the cost of k; the edge nodes do).
# * Coulomb (``Coulomb(mu)``: no Tresca limit, like the slab): below the slab estimate, which
#   ignores barrelling; the gap grows with μ.
# * The radius of the sliding billet is 11.92 mm, not the homogeneous 11.95 mm: the explicit
#   geometry update (r ← r(1 + a/2) per increment of height strain a).
# * The start-up increment (first row of the printed table) has too little friction (k at the
#   rest state's strain rate): p̄/σ₀ = 1.006 for m̄ = 0.1 against 1.024 for the next increment.

# %% [markdown]
# ## Script
# A volume-preserving homogeneous upsetting would give ``R √(H/h)`` everywhere; sticking dies keep
# the end faces near ``R`` and bulge the middle.

# %%
if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--size", type=float, default=2.0, help="element size [mm]")
    ap.add_argument("--dies", default="sticking", choices=DIES)
    ap.add_argument("--mbar", type=float, default=0.3, help="Tresca factor (--dies tresca)")
    ap.add_argument("--mu", type=float, default=0.1, help="Coulomb coefficient (--dies coulomb)")
    ap.add_argument("--output", default="results/upsetting")
    ap.add_argument("--checkpoint-every", type=int, default=5,
                    help="write a checkpoint every n increments (0: never)")
    ap.add_argument("--resume", action="store_true",
                    help="continue a killed run from its newest checkpoint")
    ap.add_argument("--volume-correction", default="global", choices=["global", "none"])
    add_verbosity_arguments(ap)
    a = ap.parse_args()
    configure_logging(a.verbose, a.quiet)
    res = run(h=a.size, dies=a.dies, mbar=a.mbar, mu=a.mu, output_dir=a.output,
              checkpoint_every=a.checkpoint_every, resume=a.resume,
              volume_correction=a.volume_correction)
    if MPI.COMM_WORLD.rank == 0:
        homog = 10.0 * np.sqrt(15.0 / res["height"])
        print(f"final height {res['height']:.3f} mm, die force (full billet) "
              f"{-res['die_force'] / 1e3:.2f} kN, max equivalent strain {res['max_strain']:.3f}")
        print(f"radius at mid-height {res['radius_mid']:.3f} mm, at the end faces "
              f"{res['radius_end']:.3f} mm (homogeneous: {homog:.3f} mm)")
        print(f"volume change {100 * res['volume_change']:.3f} %")
        print("mean die pressure over sigma0 (homogeneous end face / actual end face), "
              "Tresca upper bound, Coulomb slab:")
        for row in zip(res["reduction"], res["p_mean"], res["p_face"], res["upper_bound"],
                       res["slab"]):
            print("  reduction {:5.1%}: p/s0 = {:.4f} / {:.4f}, upper bound {:.4f}, "
                  "slab {:.4f}".format(*row))
        print(f"outputs: {res['vtk']}, {res['png']}")
