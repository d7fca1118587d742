"""Cylinder ironing (THEORY §12.2): a rigid cylinder, analytic, flat-faceted or Nagata-smoothed,
pressed into an elastic block and translated along it, frictionless nodal penalty contact.

A rigid cylinder (``radius`` R = 5 mm, axis along y) is pressed into an elastic block
(E = 2·10⁵ MPa, ν = 0.3, ``height`` 5 mm) by ``indentation`` δ and then translated along x over
``travel``. The same problem is solved with

* the **analytic** cylinder (:class:`~fxcontact.tools.analytic.Cylinder`, exact distance,
  THEORY §4),
* the **flat**-faceted tool (:class:`~fxcontact.tools.faceted.FacetedTool` in mode ``"flat"``:
  plane of the closest facet, THEORY §6),
* the **Nagata** tool (the same facets smoothed by Nagata patches with NVV normals, §7–8),

with the tool meshed coarsely (``coarse_facet`` = 1.7 mm facets, 18 per turn: the pathological
case of THEORY §6) or finely (``fine_facet`` = 0.2 mm), under any contact scheme of
:class:`~fxcontact.contact.nodal.NodalContact` (``"explicit"``, ``"quasi-implicit"``,
``"implicit"``, ``"implicit-exact"``). A variant is a triple ``(tool, facets, scheme)``, named by
:func:`variant_name` (``"nagata-coarse-implicit"``, ``"analytic-explicit"``).

**Model.** A 3D slab one element thick in y (thickness = ``h_fine``) with ``u_y = 0`` on both y
faces: plane strain with the genuinely 3D tools and projections. The bottom (z = 0) is fixed
(``u_x = u_z = 0``, the block lies on a rigid table), the other faces are free. The mesh is
structured (:func:`slab_mesh`: a box grid split into tetrahedra): uniform ``h_fine`` along the
ironing path (travel + ``margin_fine`` on each side) and in the top ``fine_depth``, growing
geometrically (× ``growth``) to ``h_coarse`` towards the ends and the bottom; ``margin`` of block
before the start and after the end of the travel. Small strain (the material integrates
displacements; the tools move with velocities).

**Motion** (:func:`staged_motion`). ``n_indent`` increments (dt = 1 s) press the tool down by δ,
then increments of ``step`` (default 0.4 ``h_fine``: five positions of the tool per element)
cover the ``travel``. The tool does not rotate. It starts ``start_offset`` = 0.1 ``h_fine`` past
a node (generic position; with 0 a node sits exactly under the bottom vertex row at t = 0, a tie
between two facets).

**Tools** (:func:`faceted_surface`, from :mod:`fxcontact.tools.surfaces`). By default
(``tool_mesh="extruded"``) an open structured cylinder whose cross-sections are all the same
regular polygon *inscribed* in the circle, ``tool_overhang`` longer than the slab on each side;
``"gmsh"`` uses the unstructured closed cylinder instead. With ``phase="vertex"`` (default) a
generator (vertex row) is at the bottom: the three tools have the same lowest point, on the true
circle, and are indented by the same δ and moved identically. Their deviations from the circle
near its bottom are measured by :func:`tool_deviation`. ``phase="facet"`` puts a facet's middle
at the bottom.

**Solver.** Newton with full steps (``line_search="basic"``) for every variant; gap stiffness
k = β E*/h_fine, the same for every variant.

**Statistics** (:mod:`fxcontact.processes.ironing_report`): over the steady phase (translation
increments after ``settle`` of travel) the Newton iterations per increment (mean, max, std),
the mean vertical tool force F_z and its oscillation (max − min over twice the mean, after
removing the least-squares linear trend), contact nodes, true maximum penetration, Nagata
fall-backs, wall time and the shares of the Newton time (contact, UFL assembly, linear solve).

The pieces shared with the grooved tool (:mod:`fxcontact.processes.groove`) are here:
:func:`graded_nodes`, :func:`tool_deviation`, :func:`run_stages`, :func:`check_variants`.

Example::

    from fxcontact.processes import ironing, ironing_report
    res = ironing.run(**ironing.QUICK, output_dir=None)
    print(ironing_report.format_table(res["summary"]))
"""

from __future__ import annotations

import logging
import math
import os
import time

import dolfinx
import dolfinx.mesh
import numpy as np
from mpi4py import MPI

from fxcontact.contact.boundary import ContactBoundary
from fxcontact.contact.nodal import NodalContact
from fxcontact.materials import LinearElastic
from fxcontact.meshing import BLOCK_TAGS
from fxcontact.newton.options import SolverOptions
from fxcontact.processes.ironing_report import collect, plot_all
from fxcontact.simulation import IncrementError, Simulation
from fxcontact.spaces import MixedSpace
from fxcontact.tools import surfaces
from fxcontact.tools.analytic import Cylinder
from fxcontact.tools.base import MovedTool, StagedMotion, Tool
from fxcontact.tools.faceted import FacetedTool

__all__ = ["DEFAULT_VARIANTS", "QUICK", "variant_name", "graded_nodes", "slab_mesh",
           "staged_motion", "faceted_surface", "tool_deviation", "run_variant", "run_stages",
           "run", "check_variants"]

log = logging.getLogger(__name__)

#: Default variants (tool, facets, scheme): the analytic tool and the flat / Nagata tools on
#: the coarse and the fine mesh, each under the explicit and the implicit scheme.
DEFAULT_VARIANTS = tuple(
    [("analytic", None, s) for s in ("explicit", "implicit")]
    + [(m, f, s) for f in ("coarse", "fine") for m in ("flat", "nagata")
       for s in ("explicit", "implicit")])

#: Reduced configuration of the tests: the acceptance variants (coarse tool, implicit scheme)
#: on a shorter block and travel (a few seconds per variant); lengths in mm.
QUICK = dict(travel=1.2, margin=3.0, margin_fine=0.75, fine_depth=0.75, h_coarse=1.5,
             growth=1.5,
             variants=(("analytic", None, "implicit"), ("flat", "coarse", "implicit"),
                       ("nagata", "coarse", "implicit")))


def variant_name(tool: str, facets, scheme: str) -> str:
    """Name of a variant: ``"<tool>-<scheme>"`` (analytic) or ``"<tool>-<facets>-<scheme>"``."""
    return f"{tool}-{scheme}" if facets is None else f"{tool}-{facets}-{scheme}"


# ------------------------------------------------------------------------ structured, graded slab
def graded_nodes(a: float, b: float, fa: float, fb: float, h_fine: float, h_coarse: float,
                 growth: float = 1.3) -> np.ndarray:
    """Node coordinates on [a, b] [mm]: uniform ``h_fine`` from ``fa`` (whole elements, up to
    about ``fb``), element sizes growing by ``growth`` up to ``h_coarse`` towards a and b.

    Raises:
        ValueError: if the fine zone does not fit in [a, b].
    """
    n = max(1, int(round((fb - fa) / h_fine)))
    core = fa + h_fine * np.arange(n + 1)
    if core[0] < a - 1e-12 or core[-1] > b + 1e-12:
        raise ValueError("the fine zone does not fit in the block")

    def side(start: float, stop: float) -> list:
        out, x, h, sgn = [], start, h_fine, math.copysign(1.0, stop - start)
        while abs(stop - x) > 1e-12:
            h = min(h * growth, h_coarse)
            if abs(stop - x) < 1.5 * h:  # last element (0.5 h .. 1.5 h): end exactly
                out.append(stop)
                break
            x += sgn * h
            out.append(x)
        return out

    return np.array(side(core[0], a)[::-1] + list(core) + side(core[-1], b))


def slab_mesh(comm, length: float, thickness: float, height: float, h_fine: float,
              h_coarse: float, fine_x: tuple, fine_depth: float, growth: float = 1.3):
    """Tetrahedral slab [0, length] × [0, thickness] × [0, height] [mm], one element thick in y,
    graded in x (fine on ``fine_x``) and z (fine in the top ``fine_depth``) by
    :func:`graded_nodes`. Collective.

    Returns ``(mesh, facet_tags)`` with the tags :data:`~fxcontact.meshing.BLOCK_TAGS`."""
    xs = graded_nodes(0.0, length, fine_x[0], fine_x[1], h_fine, h_coarse, growth)
    zs = graded_nodes(0.0, height, height - fine_depth, height, h_fine, h_coarse, growth)
    nx, nz = len(xs) - 1, len(zs) - 1
    msh = dolfinx.mesh.create_box(comm, [np.zeros(3), np.array([nx, 1.0, nz])], [nx, 1, nz],
                                  dolfinx.mesh.CellType.tetrahedron)
    g = msh.geometry.x
    g[:, 0] = np.interp(g[:, 0], np.arange(nx + 1), xs)
    g[:, 1] = g[:, 1] * thickness
    g[:, 2] = np.interp(g[:, 2], np.arange(nz + 1), zs)
    fdim = msh.topology.dim - 1
    ext = np.array([length, thickness, height])
    tol = 1e-9 * height
    idx, val = [], []
    for k, c in enumerate("xyz"):
        for side, where in (("min", 0.0), ("max", ext[k])):
            f = dolfinx.mesh.locate_entities_boundary(
                msh, fdim, lambda x, k=k, w=where: np.abs(x[k] - w) < tol)
            idx.append(f)
            val.append(np.full(len(f), BLOCK_TAGS[f"{c}{side}"], dtype=np.int32))
    idx, val = np.concatenate(idx), np.concatenate(val)
    order = np.argsort(idx, kind="stable")
    ft = dolfinx.mesh.meshtags(msh, fdim, idx[order].astype(np.int32), val[order])
    return msh, ft


# ------------------------------------------------------------------------ tools and their motion
def staged_motion(indentation: float, n_indent: int, step: float, dt: float = 1.0):
    """Down by δ = ``indentation`` [mm] over ``n_indent`` increments of ``dt`` [s], then along
    x by ``step`` [mm] per increment.

    A piecewise constant :class:`~fxcontact.tools.base.StagedMotion`: integrated exactly (a
    velocity given as a function of time would be integrated by quadrature at every
    projection); :class:`~fxcontact.tools.base.MovedTool` applies it to any tool built at its
    t = 0 position."""
    t_ind = n_indent * dt
    return StagedMotion(stages=((t_ind, (0.0, 0.0, -indentation / t_ind), 0.0),
                                (1e9, (step / dt, 0.0, 0.0), 0.0)))


def faceted_surface(radius: float, facet_size: float, tool_length: float, center,
                    tool_mesh: str = "extruded", phase: str = "vertex"):
    """Tool surface (axis y) from :mod:`fxcontact.tools.surfaces`, vertices on the true circle.

    Args:
        radius: R [mm]; facet_size: facet width [mm] (``2πR/facet_size`` facets per turn, at
            least 3); tool_length: length along y [mm]; center: a point of the axis [mm].
        tool_mesh: ``"extruded"``, the open structured cylinder with a generator
            (``phase="vertex"``) or a facet middle (``"facet"``) at the bottom; ``"gmsh"``, the
            unstructured closed one.
    Returns:
        ``(vertices, triangles)``, normals outwards.
    """
    if tool_mesh == "gmsh":
        return surfaces.cylinder_surface(radius, tool_length, facet_size, center=center,
                                         axis=(0.0, 1.0, 0.0))
    n = max(3, int(round(2.0 * np.pi * radius / facet_size)))
    # builder frame (axis z): the generator at θ = π/2 maps to −z for the axis y
    theta0 = 0.5 * np.pi + (np.pi / n if phase == "facet" else 0.0)
    return surfaces.extruded_cylinder_surface(radius, tool_length, n_theta=n, theta0=theta0,
                                              center=center, axis=(0.0, 1.0, 0.0))


def tool_deviation(tool: Tool, center, radius: float, y: float, half_angle: float = 0.2,
                   n: int = 4001, free_point=None) -> dict:
    """Deviation of a tool surface from the true circle (``center``, ``radius`` [mm], axis y) in
    the plane ``y`` [mm], over the arc ``|θ| ≤ half_angle`` [rad] around the circle's bottom,
    from the signed gap of ``n`` points of the circle.

    Returns:
        dict [mm]: ``bottom_gap`` (gap of the circle's lowest point: > 0 if the tool's surface
        is recessed from it, into the tool), ``dev_out`` (largest protrusion of the tool
        surface into free space beyond the circle) and ``dev_in`` (largest recess).
    Raises:
        ValueError: if ``free_point`` (default: 1 mm below the circle, for a roll; give the
            axis for a groove) is found inside the tool (normals pointing into it).
    """
    th = np.linspace(-half_angle, half_angle, n)
    c = np.asarray(center, dtype=float)
    P = np.stack([c[0] + radius * np.sin(th), np.full(n, y), c[2] - radius * np.cos(th)], 1)
    gap = tool.project(P, 0.0, hessian=False).gap
    if free_point is None:
        free_point = (c[0], y, c[2] - radius - 1.0)
    free = tool.project(np.array([free_point], dtype=float), 0.0, hessian=False).gap
    if not free[0] > 0.5:
        raise ValueError(f"tool normals point into the tool (gap at a point of free space "
                         f"{free[0]:.3g})")
    return {"bottom_gap": float(gap[n // 2]), "dev_out": float(max(-gap.min(), 0.0)),
            "dev_in": float(max(gap.max(), 0.0))}


# ------------------------------------------------------------------------ one variant
def run_variant(tool_kind: str, facets, scheme: str, *, radius, E, nu, height, indentation,
                n_indent, travel, step, h_fine, h_coarse, growth, margin, margin_fine,
                fine_depth, facet_sizes, tool_mesh, phase, tool_overhang, start_offset, beta,
                line_search, output_dir, progress, comm) -> dict:
    """Run one (tool, facets, scheme) variant of the ironing (the keywords are those of
    :func:`run`, ``facet_sizes`` the facet widths [mm] by ``"coarse"``/``"fine"``). Collective.

    Returns:
        the dict of :func:`run_stages`: history, status, wall time [s], mesh size, tool
        deviation.
    """
    name = variant_name(tool_kind, facets, scheme)
    thickness = h_fine
    length = 2.0 * margin + travel
    msh, ft = slab_mesh(comm, length, thickness, height, h_fine, h_coarse,
                        (margin - margin_fine, margin + travel + margin_fine), fine_depth,
                        growth)
    space = MixedSpace(msh)
    mat = LinearElastic(E, nu)
    vdir = None if output_dir is None else os.path.join(output_dir, name)
    sim = Simulation(space, mat, solver_options=SolverOptions(line_search=line_search),
                     output_dir=vdir, name=name, progress=progress)
    sim.add_velocity_bc(sim.facets(ft, BLOCK_TAGS["ymin"]), 0.0, 1)
    sim.add_velocity_bc(sim.facets(ft, BLOCK_TAGS["ymax"]), 0.0, 1)
    bottom = sim.facets(ft, BLOCK_TAGS["zmin"])
    sim.add_velocity_bc(bottom, 0.0, 0)
    sim.add_velocity_bc(bottom, 0.0, 2)
    sim.add_reaction("bottom", bottom)
    center = (margin + start_offset * h_fine, 0.5 * thickness, height + radius)
    if tool_kind == "analytic":
        tool = Cylinder(point=center, axis=(0.0, 1.0, 0.0), radius=radius, name="tool")
    else:
        V, T = faceted_surface(radius, facet_sizes[facets], thickness + 2.0 * tool_overhang,
                               center, tool_mesh, phase)
        tool = FacetedTool(V, T, mode=tool_kind, name="tool")
    deviation = tool_deviation(tool, center, radius, 0.5 * thickness)
    tool = MovedTool(tool, staged_motion(indentation, n_indent, step))
    # gap stiffness k = β E*/h (ρ = k dt): the same penalty for every variant
    k = beta * mat.plane_strain_modulus / h_fine
    contact = sim.add_contributor(NodalContact(ContactBoundary(space, ft, BLOCK_TAGS["zmax"]),
                                               tool, scheme=scheme, gap_stiffness=k,
                                               element_size=h_fine, name="contact"))
    n_trans = int(round(travel / step))
    return run_stages(sim, contact, (float(n_indent), float(n_indent + n_trans)),
                      name=name, tool_kind=tool_kind, facets=facets, scheme=scheme,
                      deviation=deviation)


def run_stages(sim, contact, stage_ends, *, name, tool_kind, facets, scheme, deviation,
               max_cutbacks: int = 5) -> dict:
    """Run ``sim`` to each time [s] of ``stage_ends`` (dt = 1 s, up to ``max_cutbacks``
    halvings of an increment) and collect the variant's result. Collective.

    A failed increment (:class:`~fxcontact.simulation.IncrementError`) does not raise: the
    variant keeps its history up to there.

    Returns:
        dict with ``name``, ``tool``, ``facets``, ``scheme``, ``status`` (``"ok"`` or
        ``"failed at t = ..."``), ``error`` (the error text of a failed run), ``history``,
        ``wall_time`` [s] (max over ranks), ``deviation`` (of :func:`tool_deviation`),
        ``cells``, ``dofs`` and ``surface_nodes`` (global counts).
    """
    comm = sim.comm
    t0 = time.perf_counter()
    status, error = "ok", ""
    try:
        for i, t_end in enumerate(stage_ends):
            sim.run(t_end, 1.0, max_cutbacks=max_cutbacks, close=i == len(stage_ends) - 1)
    except IncrementError as e:  # collective: raised on every rank; outputs are closed
        status, error = f"failed at t = {e.t:.4g}", str(e)
    wall = comm.allreduce(time.perf_counter() - t0, op=MPI.MAX)
    log.info("%s: %s in %.1f s", name, status, wall)
    return {"name": name, "tool": tool_kind, "facets": facets, "scheme": scheme,
            "status": status, "error": error, "history": sim.history, "wall_time": wall,
            "deviation": deviation,
            "cells": comm.allreduce(sim.mesh.topology.index_map(3).size_local, op=MPI.SUM),
            "dofs": sim.space.global_dofs(),
            "surface_nodes": comm.allreduce(len(contact.boundary), op=MPI.SUM)}


# ------------------------------------------------------------------------ the study
def run(radius=5.0, E=2e5, nu=0.3, height=5.0, indentation=0.04, n_indent=3, travel=5.1,
        step=None, h_fine=0.25, h_coarse=1.0, growth=1.3, margin=6.0, margin_fine=1.0,
        fine_depth=1.0, coarse_facet=1.7, fine_facet=0.2, tool_mesh="extruded",
        phase="vertex", tool_overhang=2.0, start_offset=0.1, beta=1e3, line_search="basic",
        settle=None,
        variants=DEFAULT_VARIANTS, output_dir="results/ironing", picture=True, progress=True,
        comm=MPI.COMM_WORLD) -> dict:
    """Run the ironing variants and compare them. Collective.

    Args:
        radius: tool radius R [mm]; E [MPa], nu: block material; height: block height [mm].
        indentation: δ [mm], reached in ``n_indent`` increments from first touch.
        travel: translation along x after the indentation [mm] (default 3 coarse facets).
        step: tool advance per increment [mm] (default 0.4 ``h_fine``: 5 node positions).
        h_fine: element size on the ironing path and in the top ``fine_depth`` [mm], also the
            slab thickness; h_coarse, growth: far element size [mm] and size growth ratio.
        margin: block length before the start and after the end of the travel [mm];
            margin_fine: fine zone beyond the travel on each side [mm].
        coarse_facet, fine_facet: facet widths of the two tool meshes [mm].
        tool_mesh: ``"extruded"`` (structured, default) or ``"gmsh"`` (unstructured).
        phase: ``"vertex"`` (a generator at the bottom: fair comparison) or ``"facet"``.
        tool_overhang: tool length beyond each y face of the slab [mm].
        start_offset: start of the tool's axis past the node at ``margin``, in ``h_fine``.
        beta: dimensionless penalty; gap stiffness k = β E*/h_fine [MPa/mm] (penetration p/k).
        line_search: Newton line search (``"basic"``: full steps; the backtracking ``"bt"``
            creeps on this sliding contact, whose nodal penalty residual is non-smooth where
            nodes enter or leave contact).
        settle: travel [mm] excluded from the steady-phase statistics (default 2 steps).
        variants: sequence of (tool, facets, scheme): tool ``"analytic"`` (facets None),
            ``"flat"`` or ``"nagata"`` (facets ``"coarse"`` or ``"fine"``); scheme one of
            ``"explicit"``, ``"quasi-implicit"``, ``"implicit"``, ``"implicit-exact"``.
        output_dir: where the outputs go (None: nothing written): per variant ``<variant>/``
            a VTK series and a CSV history, the tool surfaces at t = 0 (``tool_coarse.stl``,
            ``tool_fine.stl``), ``summary.csv`` and, with ``picture``, the PNGs ``force.png``,
            ``newton.png``, ``contact_nodes.png``.
        picture: draw the PNGs (rank 0, matplotlib).
        progress: show the progress bar of each run.
    Returns:
        dict with ``summary`` (one row per variant, see
        :func:`~fxcontact.processes.ironing_report.summarize`: Newton iterations per increment
        mean/max/std over the steady phase, cut-backs, mean F_z [N] and its oscillation, mean
        contact nodes, max true penetration [mm], Nagata fall-backs, wall time [s], Newton time
        per iteration and its shares contact / assembly / linear solve / other, tool deviations
        from the circle [mm]), ``by_name`` (the rows by variant name), ``results`` (per
        variant: history, wall time, mesh size), ``parameters`` and the output paths
        ``summary_csv``, ``png``.
    Raises:
        ValueError: on inconsistent parameters or a bad variant.
    """
    if step is None:
        step = 0.4 * h_fine
    if settle is None:
        settle = 2.0 * step
    if not (0 < indentation < 0.2 * radius and travel > 0 and step > 0 and n_indent >= 1):
        raise ValueError("need 0 < indentation < R/5, travel > 0, step > 0, n_indent >= 1")
    if tool_mesh not in ("extruded", "gmsh") or phase not in ("vertex", "facet"):
        raise ValueError("tool_mesh must be 'extruded' or 'gmsh', phase 'vertex' or 'facet'")
    if not travel > settle + 2 * step:
        raise ValueError("travel too short for the steady-phase statistics")
    check_variants(variants, output_dir, comm)
    facet_sizes = {"coarse": coarse_facet, "fine": fine_facet}
    common = dict(radius=radius, E=E, nu=nu, height=height, indentation=indentation,
                  n_indent=n_indent, travel=travel, step=step, h_fine=h_fine,
                  h_coarse=h_coarse, growth=growth, margin=margin, margin_fine=margin_fine,
                  fine_depth=fine_depth, facet_sizes=facet_sizes, tool_mesh=tool_mesh,
                  phase=phase, tool_overhang=tool_overhang,
                  start_offset=start_offset, beta=beta,
                  line_search=line_search, progress=progress, comm=comm)
    first = n_indent + int(math.ceil(settle / step - 1e-9))
    results = [run_variant(tk, f, s, output_dir=output_dir, **common) for tk, f, s in variants]
    out = collect(results, first, common, settle, variants, output_dir)
    if output_dir is not None and comm.rank == 0:
        for label, fs in facet_sizes.items():
            if any(f == label for _, f, _ in variants):
                V, T = faceted_surface(radius, fs, h_fine + 2.0 * tool_overhang,
                                       (margin, 0.5 * h_fine, height + radius), tool_mesh, phase)
                surfaces.write_surface(os.path.join(output_dir, f"tool_{label}.stl"), V, T)
        if picture:
            out["png"] = plot_all(results, output_dir, n_indent)
    return out


def check_variants(variants, output_dir, comm):
    """Check the (tool, facets, scheme) triples of ``variants`` and make the output directory
    (rank 0; none if ``output_dir`` is None).

    Raises:
        ValueError: naming a bad triple (the tool ``"analytic"`` takes facets None, ``"flat"``
            and ``"nagata"`` take ``"coarse"`` or ``"fine"``).
    """
    for tk, f, s in variants:
        if tk not in ("analytic", "flat", "nagata") or (tk == "analytic") != (f is None) \
                or f not in (None, "coarse", "fine"):
            raise ValueError(f"bad variant {(tk, f, s)!r}")
    if output_dir is not None and comm.rank == 0:
        os.makedirs(output_dir, exist_ok=True)
