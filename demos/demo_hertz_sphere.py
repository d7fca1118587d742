# ---
# jupyter:
#   jupytext:
#     text_representation:
#       extension: .py
#       format_name: percent
# ---

# %% [markdown]
# # Hertz point contact: a rigid sphere indenting an elastic block
#
# A rigid sphere of radius R indents the top face of a linear elastic block (E, ν) by
# ``indentation`` δ, by displacement control: the sphere touches the block at the origin and
# moves down with a constant velocity during ``n_steps`` increments. Frictionless nodal penalty
# contact (THEORY §2), small strain (THEORY §1.4), MINI elements. Quarter model: symmetry
# ``u_x = 0`` on x = 0 and ``u_y = 0`` on y = 0, frictionless roller ``u_z = 0`` on the bottom.
#
# **Comparison with Hertz (THEORY §11.1–11.2).** In 3D the indentation of a half-space is well
# defined, so δ controls the test directly:
#
# $$P = \tfrac43 E^* R^{1/2}\delta^{3/2},\qquad a = \sqrt{R\delta},\qquad
# p_0 = \frac{3P}{2\pi a^2},\qquad p(r) = p_0\sqrt{1-r^2/a^2},\qquad E^* = E/(1-\nu^2).$$
#
# **FEM contact radius.** ``contact_radius`` is the radius of the disc with the active contact
# area, ``sqrt(4 Σ_{p_n>0} S_n / π)`` (S_n: lumped nodal areas of the quarter model). The radii
# of the outermost active and innermost inactive nodes are returned too
# (``contact_radius_bounds``; on an unstructured mesh they may cross).
#
# **Sources of error in the force** (all make the model stiffer than Hertz, measured at
# δ = 13.3 µm, a = 0.258 mm): the finite block on a rigid frictionless base, ≈ +1.5 % for a
# 10 mm block and ∝ 1/H (hence the default 80 mm block, ≈ 300 a, ≈ +0.3 %: the graded mesh
# makes its cost logarithmic); the growth of the element size away from the contact, ∝ growth²
# (≈ +1.3 % at 0.2); the resolution of the contact zone (≈ +2 % at h_fine = 50 µm, +1 % at
# 25 µm). The defaults give +2.2 % on the force, +1.6 % on p_max.
#
# Run: ``python demos/demo_hertz_sphere.py`` (serial) or ``mpirun -n 2 python demos/...``.
# ``--size`` sets ``h_fine`` (the one knob); outputs go to ``results/hertz_sphere``: the VTK
# series, the CSV history, the pressure profile (CSV), a PNG of p(r) against Hertz and a PNG of
# the deformed contact zone (displacements magnified).

# %%
from __future__ import annotations

import argparse
import math
import os
import time

import numpy as np
from mpi4py import MPI

from fxcontact.contact.boundary import ContactBoundary
from fxcontact.contact.nodal import NodalContact, penalty_from_beta
from fxcontact.materials import LinearElastic
from fxcontact import compat
from fxcontact.meshing import BLOCK_TAGS, gmsh_session
from fxcontact.simulation import Simulation
from fxcontact.spaces import MixedSpace
from fxcontact.tools.analytic import Sphere


# %% [markdown]
# ## Mesh: quarter block graded radially from the contact point
#
# The far field of a point load decays like 1/r; linear elements resolve it only if their size
# grows gently with the distance r to the load. :func:`fxcontact.meshing.block` grades over a
# fixed distance (3 × the refinement box), i.e. with a size gradient ``(h - h_fine)/(3 L)``
# that is above 1 for a block large enough for Hertz: measured at δ = 13.3 µm, h_fine = 0.05 mm,
# a 10 mm block meshed with ``block`` (h = 2 mm, gradient 1.6) is 12 % too stiff and a 20 mm
# block (h = 4 mm) 29 %. Here the size is ``h_fine`` within ``refine`` of the origin and grows
# linearly with the distance, with slope ``growth`` (gmsh Distance + Threshold fields), up to
# ``h``.

# %%
def graded_block(comm, width: float, height: float, h_fine: float, refine: float,
                 growth: float, h: float):
    """Quarter block ``[0, width]² × [-height, 0]`` with facet tags :data:`BLOCK_TAGS`."""
    if not (0 < h_fine <= h and refine > 0 and growth > 0):
        raise ValueError("need 0 < h_fine <= h, refine > 0 and growth > 0")
    with gmsh_session("hertz_block") as gmsh:
        if comm.rank == 0:
            occ = gmsh.model.occ
            occ.addBox(0.0, 0.0, -height, width, width, height)
            occ.synchronize()
            gmsh.model.addPhysicalGroup(3, [e[1] for e in gmsh.model.getEntities(3)], 1)
            lower, upper = np.array([0.0, 0.0, -height]), np.array([width, width, 0.0])
            names = ["xmin", "xmax", "ymin", "ymax", "zmin", "zmax"]
            eps = 1e-9 * max(width, height)
            for d_, tag in gmsh.model.getEntities(2):
                c = np.array(occ.getCenterOfMass(d_, tag))
                for k in range(3):
                    for j, ref in enumerate((lower[k], upper[k])):
                        if abs(c[k] - ref) < eps:
                            gmsh.model.addPhysicalGroup(2, [tag], BLOCK_TAGS[names[2 * k + j]])
            origin = [t for _, t in gmsh.model.getEntities(0)
                      if np.allclose(gmsh.model.getValue(0, t, []), 0.0)]
            f = gmsh.model.mesh.field
            dist = f.add("Distance")
            f.setNumbers(dist, "PointsList", origin)
            thr = f.add("Threshold")
            f.setNumber(thr, "InField", dist)
            f.setNumber(thr, "SizeMin", h_fine)
            f.setNumber(thr, "SizeMax", h)
            f.setNumber(thr, "DistMin", refine)
            f.setNumber(thr, "DistMax", refine + (h - h_fine) / growth)
            f.setAsBackgroundMesh(thr)
            for k in ("Mesh.MeshSizeExtendFromBoundary", "Mesh.MeshSizeFromPoints",
                      "Mesh.MeshSizeFromCurvature"):
                gmsh.option.setNumber(k, 0)
            gmsh.model.mesh.generate(3)
        msh, ct, ft = compat.model_to_mesh(gmsh.model, comm, 0, gdim=3)
    return msh, ct, ft


# %% [markdown]
# ## Hertz formulas (rigid sphere on an elastic half-space)

# %%
def hertz_sphere(delta: float, R: float, E_star: float):
    """Load ``P``, contact radius ``a`` and peak pressure ``p0`` for an indentation ``delta``."""
    P = 4.0 / 3.0 * E_star * math.sqrt(R) * delta**1.5
    a = math.sqrt(R * delta)
    return P, a, 3.0 * P / (2.0 * math.pi * a**2)


def gather_profile(contact: NodalContact, x: np.ndarray, comm) -> tuple:
    """Radii, pressures and lumped areas of the contact nodes of all ranks, sorted by radius."""
    b = contact.boundary
    xb = x[b.vertices]
    loc = np.c_[np.hypot(xb[:, 0], xb[:, 1]), contact.pressures(), b.areas]
    allv = np.concatenate(comm.allgather(loc))
    allv = allv[np.argsort(allv[:, 0], kind="stable")]
    return allv[:, 0], allv[:, 1], allv[:, 2]


# %%
def run(radius=5.0, E=2e5, nu=0.3, indentation=0.0133, h_fine=0.025, h=16.0, width=80.0,
        height=80.0, refine=0.4, growth=0.15, scheme="implicit", penalty=None, beta=1e4, n_steps=3,
        output_dir="results/hertz_sphere", picture=True, progress=True,
        comm=MPI.COMM_WORLD) -> dict:
    """Indent the block by ``indentation`` with the sphere in ``n_steps`` increments.

    Args:
        radius: sphere radius R [mm]; E [MPa], nu: block material.
        indentation: final sphere displacement δ [mm] from first touch at the origin.
        h_fine: element size within the distance ``refine`` of the first contact point; it
            grows linearly with slope ``growth`` up to ``h`` far away [mm].
        width, height: quarter block ``[0, width]² × [-height, 0]`` [mm].
        scheme: contact scheme (see :data:`fxcontact.contact.nodal.SCHEMES`).
        penalty: ρ, or None to use ``beta`` (ρ = β dt E*/h_fine, THEORY §2.5).
        n_steps: number of increments.
    Returns:
        dict with ``force`` (4 × quarter), ``contact_radius`` (FEM, equivalent disc),
        ``contact_radius_bounds`` (largest active / smallest inactive nodal radius),
        ``p_max``, Hertz values for the same δ (``hertz_force``,
        ``hertz_contact_radius``, ``hertz_p_max``), the nodal profile ``r``, ``p``, the bottom
        reaction, mesh size, dofs, run time and the history.
    """
    t_start = time.perf_counter()
    if not (0 < indentation < 0.5 * radius):
        raise ValueError("indentation must be in (0, R/2)")
    msh, _, ft = graded_block(comm, width, height, h_fine, refine, growth, h)
    space = MixedSpace(msh)
    mat = LinearElastic(E, nu)
    sim = Simulation(space, mat, output_dir=output_dir, name="hertz_sphere", progress=progress)
    sim.add_velocity_bc(sim.facets(ft, BLOCK_TAGS["xmin"]), 0.0, 0)   # symmetry
    sim.add_velocity_bc(sim.facets(ft, BLOCK_TAGS["ymin"]), 0.0, 1)   # symmetry
    bottom = sim.facets(ft, BLOCK_TAGS["zmin"])
    sim.add_velocity_bc(bottom, 0.0, 2)                                # frictionless roller
    sim.add_reaction("bottom", bottom)
    t_end = 1.0
    speed = indentation / t_end
    tool = Sphere(center=(0.0, 0.0, radius), radius=radius, velocity=(0.0, 0.0, -speed),
                  name="sphere")
    dt = t_end / n_steps
    if penalty is None:
        # ρ = β dt E*/h_e given explicitly: NodalContact(beta=...) leaves ρ unset until the
        # first increment, and writing the initial output fields then fails (see the report)
        penalty = penalty_from_beta(mat, beta, h_fine, dt=dt)
    boundary = ContactBoundary(space, ft, BLOCK_TAGS["zmax"])
    contact = sim.add_contributor(NodalContact(boundary, tool, scheme=scheme, penalty=penalty,
                                               element_size=h_fine))
    sim.run(t_end, dt)
    last = sim.history[-1]
    P = 4.0 * last["sphere_force_z"]               # quarter model → full contact
    E_star = mat.plane_strain_modulus
    P_h, a_h, p0_h = hertz_sphere(indentation, radius, E_star)
    x = sim.vertex_positions()
    rs, ps, Ss = gather_profile(contact, x, comm)
    active = ps > 0
    a_fem = math.sqrt(4.0 * float(np.sum(Ss[active])) / math.pi)
    r_in = float(np.max(rs[active], initial=0.0))
    r_out = float(np.min(rs[~active], initial=np.inf))
    n_cells = comm.allreduce(msh.topology.index_map(3).size_local, op=MPI.SUM)
    out = {"force": P, "contact_radius": a_fem, "contact_radius_bounds": (r_in, r_out),
           "p_max": float(np.max(ps)), "hertz_force": P_h, "hertz_contact_radius": a_h,
           "hertz_p_max": p0_h, "E_star": E_star, "r": rs, "p": ps, "nodal_area": Ss,
           "bottom_reaction": 4.0 * last["bottom_z"], "indentation": indentation,
           "radius": radius, "penetration": last["contact_penetration_true"],
           "active_nodes": int(np.sum(active)), "h_fine": h_fine, "cells": n_cells,
           "dofs": space.global_dofs(), "history": sim.history, "png": None,
           "png_deformed": None}
    if output_dir is not None and picture:
        out["png_deformed"] = render_deformed(
            sim, os.path.join(output_dir, "hertz_sphere_3d.png"), zone=4.0 * a_h)
    if output_dir is not None and comm.rank == 0:
        np.savetxt(os.path.join(output_dir, "profile.csv"), np.c_[rs, ps, Ss], delimiter=",",
                   header="r,p,S", comments="")
        if picture:
            out["png"] = plot_profile(out, os.path.join(output_dir, "hertz_sphere.png"))
    out["wall_time"] = time.perf_counter() - t_start
    return out


# %% [markdown]
# ## Pictures: p(r) against Hertz; the deformed block (collective)

# %%
def plot_profile(res: dict, path: str) -> str:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    a, p0 = res["hertz_contact_radius"], res["hertz_p_max"]
    rr = np.linspace(0.0, a, 400)
    fig, ax = plt.subplots(figsize=(7, 4.5))
    ax.plot(rr / a, np.sqrt(1.0 - (rr / a) ** 2), "k-", label="Hertz, $p_0\\sqrt{1-r^2/a^2}$")
    sel = res["r"] < 2.0 * a
    ax.plot(res["r"][sel] / a, res["p"][sel] / p0, "o", ms=3, alpha=0.7,
            label="FEM nodal $p_n$")
    ax.axvline(res["contact_radius"] / a, color="C1", ls="--", lw=1,
               label="FEM radius $\\sqrt{4\\sum S_n/\\pi}$")
    ax.set_xlabel("$r/a$")
    ax.set_ylabel("$p/p_0$")
    ax.set_xlim(0, 1.5)
    ax.set_title(f"Hertz sphere: δ = {1e3 * res['indentation']:.1f} µm, "
                 f"P = {res['force']:.0f} N (Hertz {res['hertz_force']:.0f} N)")
    ax.legend()
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


def render_deformed(sim: Simulation, path: str, zone: float, scale: float = 20.0):
    """Render the cells within ``zone`` of the contact point, displacements × ``scale``,
    coloured by the equivalent strain (maximum below the surface), seen on the symmetry plane
    y = 0. Collective."""
    import dolfinx.mesh
    from fxcontact.io import render_png

    msh = sim.mesh
    tdim = msh.topology.dim
    ncells = msh.topology.index_map(tdim).size_local
    mid = dolfinx.mesh.compute_midpoints(msh, tdim, np.arange(ncells, dtype=np.int32))
    cells = np.flatnonzero(np.linalg.norm(mid, axis=1) < zone).astype(np.int32)
    sub, cmap, _, gmap = dolfinx.mesh.create_submesh(msh, tdim, cells)
    # displacement of the parent geometry nodes (P1 geometry: one node per vertex)
    vg = sim.space.vertex_geometry
    disp = np.zeros_like(msh.geometry.x)
    disp[vg, :3] = sim.vertex_positions() - msh.geometry.x[vg, :3]
    sub.geometry.x[:, :3] += scale * disp[np.asarray(gmap), :3]
    nsub = sub.topology.index_map(tdim).size_local
    values = sim.strain.x.array[np.asarray(cmap)[:nsub]]
    ok = render_png(sub, path, values, "equivalent strain",
                    title=f"Hertz sphere, r < {zone:.2f} mm seen on the symmetry plane y = 0, "
                          f"displacements x{scale:g}", camera="xz")
    return path if ok else None


# %% [markdown]
# ## Script

# %%
if __name__ == "__main__":
    ap = argparse.ArgumentParser(description="Hertz point contact (rigid sphere)")
    ap.add_argument("--size", type=float, default=0.025, help="fine element size h_fine [mm]")
    ap.add_argument("--scheme", default="implicit")
    ap.add_argument("--output", default="results/hertz_sphere")
    args = ap.parse_args()
    res = run(h_fine=args.size, scheme=args.scheme, output_dir=args.output)
    if MPI.COMM_WORLD.rank == 0:
        lo, hi = res["contact_radius_bounds"]
        print(f"mesh: {res['cells']} tetrahedra, {res['dofs']} dofs, h_fine = {res['h_fine']} "
              f"mm, {res['active_nodes']} active nodes; {res['wall_time']:.1f} s")
        print(f"bottom reaction {res['bottom_reaction']:.2f} N")
        print(f"{'':22s}{'FEM':>12s}{'Hertz':>12s}{'error':>10s}")
        for name, k, kh in (("force P [N]", "force", "hertz_force"),
                            ("radius a [mm]", "contact_radius", "hertz_contact_radius"),
                            ("p_max [MPa]", "p_max", "hertz_p_max")):
            print(f"{name:22s}{res[k]:12.5g}{res[kh]:12.5g}{res[k] / res[kh] - 1:10.2%}")
        print(f"active/inactive node radii {lo:.4f}..{hi:.4f}; a/R = "
              f"{res['hertz_contact_radius'] / res['radius']:.3f}")
        print(f"outputs: {res['png']}, {res['png_deformed']}")
