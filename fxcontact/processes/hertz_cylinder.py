"""Hertz line contact: a rigid cylinder pressed on an elastic block in plane strain
(THEORY §11.2).

A rigid cylinder of radius R is pressed on the top face of a linear elastic block (E, ν, plane
strain) under displacement control: the tool touches the block at x = 0 at t = 0 and moves
down at a constant speed, so that after ``n_steps`` increments (1 s) it has indented the block
by ``indentation``. Frictionless nodal penalty contact (THEORY §2), small strain
(THEORY §1.4). Half model: symmetry ``u_x = 0`` on x = 0, frictionless roller ``u_y = 0`` on
the bottom face.

**Comparison with Hertz.** In 2D the indentation of a half-space under a line load is not
defined (it depends logarithmically on the block size), so the load ``P`` per unit length is
taken from the FEM (twice the force on the tool of the half model) and the Hertz half-width
and peak pressure are computed *for that load* (:func:`~fxcontact.processes.hertz.hertz_line`):
a = √(4PR/(πE*)), p0 = 2P/(πa), p(x) = p0 √(1 − x²/a²), E* = E/(1 − ν²).

**FEM contact half-width** (:func:`contact_edge`). The nodal pressure ``p_n = ρ[h_n]₊`` is
known at the contact nodes only; the edge of the contact lies between the last active node
``x_k`` and the first inactive one (``contact_half_width_bounds``). Near the edge of a smooth
frictionless contact the pressure behaves like ``sqrt(a - x)``, so ``p²`` is linear in x:
``contact_half_width`` is where the straight line through ``(x_{k-1}, p²_{k-1})`` and
``(x_k, p²_k)`` vanishes, clipped to the bracketing interval. ``contact_half_width_area`` is
the simpler ``Σ_{p_n>0} S_n`` (S_n: lumped nodal length), the midpoint of the bracket on a
uniform mesh (error ≤ h/2).

**Mesh.** :func:`fxcontact.meshing.block`, graded (gmsh box field) from ``h_fine`` in a square
of side ``refine`` under the tool to ``h`` far away; the block is large compared with ``a``
(THEORY §11.2: ≥ 10–20 a; here 10 mm ≈ 60 a). That grading is steep (size gradient ≈ 0.8):
it stiffens the far field, which changes the load for a given indentation but not the
comparison, made for the FEM load (the sphere, compared at a given δ, needs the gentler
:func:`~fxcontact.processes.hertz.graded_block`).

Units: mm, N (N/mm per unit length), MPa, s. :func:`run` is collective; its CSV and picture
are written on rank 0.
"""

from __future__ import annotations

import os
import time

import numpy as np
from mpi4py import MPI

from fxcontact.contact.boundary import ContactBoundary
from fxcontact.contact.nodal import NodalContact, penalty_from_beta
from fxcontact.io import figure, plot_pressure_profile
from fxcontact.materials import LinearElastic
from fxcontact.meshing import BLOCK_TAGS, block
from fxcontact.processes.hertz import hertz_line
from fxcontact.simulation import Simulation
from fxcontact.spaces import MixedSpace
from fxcontact.tools.analytic import Cylinder

__all__ = ["run", "contact_edge", "gather_profile", "plot_profile"]


def gather_profile(contact: NodalContact, x: np.ndarray, comm) -> tuple:
    """Contact-node abscissae [mm], pressures [MPa] and lumped lengths [mm] of all ranks,
    sorted by x (``x``: the vertex positions [mm]). Collective."""
    b = contact.boundary
    loc = np.c_[x[b.vertices, 0], contact.pressures(), b.areas]
    allv = np.concatenate(comm.allgather(loc))
    allv = allv[np.argsort(allv[:, 0])]
    return allv[:, 0], allv[:, 1], allv[:, 2]


def contact_edge(xs: np.ndarray, ps: np.ndarray) -> tuple:
    """Edge of the contact from sorted nodal (x [mm], p [MPa]): p² extrapolated linearly to
    zero from the last two active nodes, clipped to [last active, first inactive] (the midpoint
    of that bracket with fewer than two active nodes or a non-decreasing edge). Returns
    ``(a, (last active x, first inactive x))`` [mm]."""
    act = np.flatnonzero(ps > 0)
    if len(act) == 0:
        return 0.0, (0.0, float(xs[0]))
    k = act[-1]
    hi = float(xs[k + 1]) if k + 1 < len(xs) else float("inf")
    bounds = (float(xs[k]), hi)
    if k == 0 or ps[k - 1] <= ps[k] or not np.isfinite(hi):
        # too few active nodes (or a non-decreasing edge): midpoint of the bracket
        return (0.5 * (bounds[0] + hi) if np.isfinite(hi) else bounds[0]), bounds
    x1, x2, q1, q2 = xs[k - 1], xs[k], ps[k - 1] ** 2, ps[k] ** 2
    a = x2 + q2 * (x2 - x1) / (q1 - q2)
    return float(min(max(a, bounds[0]), hi)), bounds


def run(radius=5.0, E=2e5, nu=0.3, indentation=0.0145, h_fine=0.008, h=1.0, width=10.0,
        height=10.0, refine=0.4, scheme="implicit", penalty=None, beta=1e4, n_steps=4,
        output_dir="results/hertz_cylinder", picture=True, progress=True,
        comm=MPI.COMM_WORLD) -> dict:
    """Press the cylinder into the block by ``indentation`` in ``n_steps`` increments (the run
    lasts 1 s).

    Args:
        radius: cylinder radius R [mm]; E [MPa], nu: block material (plane strain).
        indentation: final tool displacement [mm] from first touch (x = 0, y = 0).
        h_fine: element size in the refined square ``[0, refine] × [-refine, 0]`` under the
            tool; h: element size far away [mm].
        width, height: size of the half block ``[0, width] × [-height, 0]`` [mm].
        scheme: contact scheme (see :data:`fxcontact.contact.nodal.SCHEMES`).
        penalty: ρ [MPa·s/mm], or None to use ``beta`` (ρ = β dt E*/h_fine, THEORY §2.5).
        beta: dimensionless penalty factor β.
        n_steps: number of increments.
        output_dir: where the VTK series, the CSV history (``hertz_cylinder_history.csv``),
            the nodal profile (``profile.csv``: x, p, S) and the picture go; None: no output.
        picture: draw ``hertz_cylinder.png`` (:func:`plot_profile`).
        progress: show the progress bar of the increments.
        comm: the communicator of the run.
    Returns:
        dict with ``force`` (P per unit length [N/mm], full contact), ``contact_half_width``
        [mm] (FEM, p² extrapolated to zero), ``contact_half_width_bounds`` (last active /
        first inactive node), ``contact_half_width_area`` (Σ S_n over the active nodes),
        ``p_max`` [MPa],
        ``hertz_half_width`` and ``hertz_p_max`` for the FEM load, the nodal profile ``x``,
        ``p``, the bottom reaction [N/mm] (equilibrium check), mesh size, dofs, run time [s]
        and the history.
    """
    t_start = time.perf_counter()
    if not (0 < indentation < 0.5 * radius):
        raise ValueError("indentation must be in (0, R/2)")
    msh, _, ft = block(comm, (0.0, -height), (width, 0.0), h,
                       refine_box=((0.0, -refine), (refine, 0.0)), h_fine=h_fine, dim=2)
    space = MixedSpace(msh)
    mat = LinearElastic(E, nu)
    sim = Simulation(space, mat, output_dir=output_dir, name="hertz_cylinder",
                     progress=progress)
    sim.add_velocity_bc(sim.facets(ft, BLOCK_TAGS["xmin"]), 0.0, 0)   # symmetry
    bottom = sim.facets(ft, BLOCK_TAGS["ymin"])
    sim.add_velocity_bc(bottom, 0.0, 1)                                # frictionless roller
    sim.add_reaction("bottom", bottom)
    t_end = 1.0
    speed = indentation / t_end
    tool = Cylinder(point=(0.0, radius, 0.0), axis=(0.0, 0.0, 1.0), radius=radius,
                    velocity=(0.0, -speed, 0.0), name="cylinder")
    dt = t_end / n_steps
    if penalty is None:
        # ρ = β dt E*/h_e given explicitly: NodalContact(beta=...) leaves ρ unset until the
        # first increment, and writing the initial output fields then fails
        penalty = penalty_from_beta(mat, beta, h_fine, dt=dt)
    boundary = ContactBoundary(space, ft, BLOCK_TAGS["ymax"])
    contact = sim.add_contributor(NodalContact(boundary, tool, scheme=scheme, penalty=penalty,
                                               element_size=h_fine))
    sim.run(t_end, dt)
    last = sim.history[-1]
    P = 2.0 * last["cylinder_force_y"]            # half model → full contact
    E_star = mat.plane_strain_modulus
    a_h, p0_h = hertz_line(P, radius, E_star)
    xs, ps, Ss = gather_profile(contact, sim.vertex_positions(), comm)
    a_area = float(np.sum(Ss[ps > 0]))
    a_fem, bounds = contact_edge(xs, ps)
    n_cells = comm.allreduce(msh.topology.index_map(2).size_local, op=MPI.SUM)
    out = {"force": P, "contact_half_width": a_fem, "contact_half_width_bounds": bounds,
           "contact_half_width_area": a_area,
           "p_max": float(np.max(ps)), "hertz_half_width": a_h, "hertz_p_max": p0_h,
           "E_star": E_star, "x": xs, "p": ps, "nodal_length": Ss,
           "bottom_reaction": 2.0 * last["bottom_y"], "indentation": indentation, "radius": radius,
           "penetration": last["contact_penetration_true"],
           "nodes_on_half_width": int(np.sum(ps > 0)), "h_fine": h_fine, "cells": n_cells,
           "dofs": space.global_dofs(), "history": sim.history, "png": None,
           "wall_time": time.perf_counter() - t_start}
    if output_dir is not None and comm.rank == 0:
        np.savetxt(os.path.join(output_dir, "profile.csv"), np.c_[xs, ps, Ss], delimiter=",",
                   header="x,p,S", comments="")
        if picture:
            out["png"] = plot_profile(out, os.path.join(output_dir, "hertz_cylinder.png"))
    return out


def plot_profile(res: dict, path: str) -> str:
    """The nodal pressures of a run (:func:`run`) against Hertz's ellipse for the FEM load,
    p/p0 against x/a, with the FEM half-width; writes the PNG ``path`` and returns it
    (matplotlib: call on one rank)."""
    a, p0 = res["hertz_half_width"], res["hertz_p_max"]
    with figure(path) as (fig, ax):
        nodes = [(res["x"], res["p"], dict(ms=4, label="FEM nodal $p_n$"))]
        plot_pressure_profile(ax, a, p0, nodes, variable="x", extent=(
            res["contact_half_width"], "FEM half-width ($p^2$ extrapolated)"))
        ax.set_title(f"Hertz line contact: P = {res['force']:.1f} N/mm, a = {a:.4f} mm, "
                     f"$p_0$ = {p0:.0f} MPa")
        ax.legend()
    return path

