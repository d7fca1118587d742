"""A round bar pressed into a turning grooved tool: a concave faceted tool, flat versus Nagata,
against the analytic bore (the concave counterpart of :mod:`fxcontact.processes.ironing`).

A round bar (radius ``bar_radius`` = 5 mm, elastic E = 2·10⁵ MPa, ν = 0.3, plane strain) lies in
a circular groove of radius ``groove_radius`` = 6 mm: the shape of roll grooves in long-product
rolling and of drawing dies. The groove is lifted by ``clearance`` + δ in ``n_indent`` increments
(δ = ``indentation`` past the first touch of the true circle), then **turns about its own
axis** by ``rotation_step`` per increment. A turning circular groove is the same surface at
every instant: with the analytic bore the solution does not change during the rotation; a
faceted groove brings its valleys (the concave vertex rows, where the facet normal jumps,
THEORY §6) past the contact zone one after the other.

**Tools.** The analytic bore (:class:`~fxcontact.tools.analytic.Cylinder` with
``inside=True``) and the groove of :func:`groove_surface` (a regular polygon inscribed in the
circle, extruded along the axis by
:func:`~fxcontact.tools.surfaces.extruded_cylinder_surface`, used with ``flip=True`` so that
its normals point towards the axis, out of the tool material), ``coarse_facets`` = 36 or
``fine_facets`` = 180 around, **flat** (plane of the closest facet) or **Nagata**-smoothed
(NVV normals). A valley is at the bottom at t = 0, so the three grooves share their lowest
point; between the valleys the inscribed flat facets stand proud of the circle by up to
R(1 − cos(π/n)).

**Model** (:func:`bar_section_mesh`). The lower part of the bar's section: |x| ≤
``half_width``, from the circular bottom up to ``height`` above it, clamped on its top face
(held by the other roll), one element thick in y with u_y = 0 on both faces (plane strain).
Structured tetrahedra of size ``h`` near the contact (bottom ``fine_depth``), growing upwards.
Frictionless nodal penalty, gap stiffness k = β E*/h, the same for every tool; Newton with full
steps.

Variants, statistics (over the rotation increments after ``settle``), tables and pictures are
those of the ironing study (:mod:`fxcontact.processes.ironing_report`).

Example::

    from fxcontact.processes import groove, ironing_report
    res = groove.run(**groove.QUICK, output_dir=None)
    print(ironing_report.format_table(res["summary"]))
"""

from __future__ import annotations

import math
import os

import dolfinx
import dolfinx.mesh
import numpy as np
from mpi4py import MPI

from fxcontact.contact.boundary import ContactBoundary
from fxcontact.contact.nodal import NodalContact
from fxcontact.materials import LinearElastic
from fxcontact.meshing import BLOCK_TAGS
from fxcontact.newton.options import SolverOptions
from fxcontact.processes.ironing import (check_variants, graded_nodes, run_stages, tool_deviation,
                                         variant_name)
from fxcontact.processes.ironing_report import collect, plot_all
from fxcontact.simulation import Simulation
from fxcontact.spaces import MixedSpace
from fxcontact.tools import surfaces
from fxcontact.tools.analytic import Cylinder
from fxcontact.tools.base import MovedTool, StagedMotion
from fxcontact.tools.faceted import FacetedTool

__all__ = ["DEFAULT_VARIANTS", "QUICK", "bar_section_mesh", "run_variant", "groove_surface",
           "run"]

#: analytic bore, then flat and Nagata grooves, coarse and fine, under both schemes
DEFAULT_VARIANTS = tuple(
    [("analytic", None, s) for s in ("explicit", "implicit")]
    + [(m, f, s) for f in ("coarse", "fine") for m in ("flat", "nagata")
       for s in ("explicit", "implicit")])

#: Reduced configuration of the tests: the coarse groove and the bore, implicit scheme;
#: lengths in mm.
QUICK = dict(half_width=3.0, height=3.0, h_coarse=0.75, n_rotation=10,
             variants=(("analytic", None, "implicit"), ("flat", "coarse", "implicit"),
                       ("nagata", "coarse", "implicit")))


def bar_section_mesh(comm, bar_radius: float, half_width: float, height: float,
                     thickness: float, h: float, h_coarse: float, fine_depth: float,
                     growth: float):
    """Lower part of a round bar's section [mm]: |x| ≤ ``half_width``, from the circular bottom
    f(x) = R_b − √(R_b² − x²) up to ``height`` above the lowest point, ``thickness`` in y (one
    element). Structured tetrahedra: uniform ``h`` across, graded upwards by
    :func:`~fxcontact.processes.ironing.graded_nodes` (``h`` in the bottom ``fine_depth``,
    growing by ``growth`` to ``h_coarse``). A box, tagged on its faces, then mapped onto the
    section. Collective.

    Returns:
        ``(mesh, facet_tags)`` with the tags :data:`~fxcontact.meshing.BLOCK_TAGS`: ``zmin`` is
        the bar's surface, ``zmax`` the flat top.
    Raises:
        ValueError: unless 0 < half_width < bar_radius and height > 0.
    """
    if not (0 < half_width < bar_radius and height > 0):
        raise ValueError("need 0 < half_width < bar_radius and height > 0")
    xs = np.linspace(-half_width, half_width, 2 * max(1, int(round(half_width / h))) + 1)
    zs = graded_nodes(0.0, height, 0.0, min(fine_depth, height), h, h_coarse, growth)
    nx, nz = len(xs) - 1, len(zs) - 1
    msh = dolfinx.mesh.create_box(comm, [np.zeros(3), np.array([nx, 1.0, nz])], [nx, 1, nz],
                                  dolfinx.mesh.CellType.tetrahedron)
    fdim = msh.topology.dim - 1
    ext = np.array([nx, 1.0, nz])
    idx, val = [], []
    for k, c in enumerate("xyz"):
        for side, where in (("min", 0.0), ("max", ext[k])):
            f = dolfinx.mesh.locate_entities_boundary(
                msh, fdim, lambda x, k=k, w=where: np.abs(x[k] - w) < 1e-9)
            idx.append(f)
            val.append(np.full(len(f), BLOCK_TAGS[f"{c}{side}"], dtype=np.int32))
    idx, val = np.concatenate(idx), np.concatenate(val)
    order = np.argsort(idx, kind="stable")
    ft = dolfinx.mesh.meshtags(msh, fdim, idx[order].astype(np.int32), val[order])
    g = msh.geometry.x
    x = np.interp(g[:, 0], np.arange(nx + 1), xs)
    z = np.interp(g[:, 2], np.arange(nz + 1), zs)
    bottom = bar_radius - np.sqrt(bar_radius**2 - x**2)
    g[:, 0] = x
    g[:, 1] = g[:, 1] * thickness
    g[:, 2] = bottom + z * (height - bottom) / height
    return msh, ft


def run_variant(tool_kind: str, facets, scheme: str, *, bar_radius, groove_radius, E, nu,
                height, half_width, h, h_coarse, fine_depth, growth, clearance, indentation,
                n_indent, rotation_step, n_rotation, facet_counts, beta, max_cutbacks,
                output_dir, progress, comm, newton_rtol=1e-9) -> dict:
    """Run one (tool, facets, scheme) variant of the groove (the keywords are those of
    :func:`run`, ``facet_counts`` the facets around by ``"coarse"``/``"fine"``). Collective.

    Returns:
        the dict of :func:`~fxcontact.processes.ironing.run_stages`.
    """
    name = variant_name(tool_kind, facets, scheme)
    msh, ft = bar_section_mesh(comm, bar_radius, half_width, height, h, h, h_coarse,
                               fine_depth, growth)
    space = MixedSpace(msh)
    mat = LinearElastic(E, nu)
    vdir = None if output_dir is None else os.path.join(output_dir, name)
    sim = Simulation(space, mat, solver_options=SolverOptions(line_search="basic",
                                                              rtol=newton_rtol),
                     output_dir=vdir, name=name, progress=progress)
    sim.add_velocity_bc(sim.facets(ft, BLOCK_TAGS["ymin"]), 0.0, 1)
    sim.add_velocity_bc(sim.facets(ft, BLOCK_TAGS["ymax"]), 0.0, 1)
    top = sim.facets(ft, BLOCK_TAGS["zmax"])
    sim.add_velocity_bc(top, np.zeros(3))
    sim.add_reaction("top", top)
    # the groove's axis, with its lowest point `clearance` below the bar's
    center = (0.0, 0.5 * h, groove_radius - clearance)
    if tool_kind == "analytic":
        tool = Cylinder(point=center, axis=(0.0, 1.0, 0.0), radius=groove_radius, inside=True,
                        name="tool")
    else:
        V, T = groove_surface(groove_radius, facet_counts[facets], h + 4.0, center)
        tool = FacetedTool(V, T, mode=tool_kind, flip=True, name="tool")
    deviation = tool_deviation(tool, center, groove_radius, 0.5 * h,
                               half_angle=math.asin(min(1.0, half_width / groove_radius)),
                               free_point=center)
    t_ind = float(n_indent)
    motion = StagedMotion(stages=((t_ind, (0.0, 0.0, (clearance + indentation) / t_ind), 0.0),
                                  (1e9, (0.0, 0.0, 0.0), rotation_step)),
                          axis_point=center, axis=(0.0, 1.0, 0.0))
    tool = MovedTool(tool, motion)
    k = beta * mat.plane_strain_modulus / h
    contact = sim.add_contributor(NodalContact(ContactBoundary(space, ft, BLOCK_TAGS["zmin"]),
                                               tool, scheme=scheme, gap_stiffness=k,
                                               element_size=h, name="contact"))
    return run_stages(sim, contact, (t_ind, t_ind + n_rotation), name=name,
                      tool_kind=tool_kind, facets=facets, scheme=scheme,
                      deviation=deviation, max_cutbacks=max_cutbacks)


def groove_surface(radius: float, n_facets: int, length: float, center):
    """Groove polygon of ``n_facets`` around, inscribed in the circle of ``radius`` [mm] (axis
    y through ``center``, ``length`` [mm] along it, a vertex row at the bottom), normals
    radially outward: build the tool with ``flip=True``. Returns ``(vertices, triangles)``."""
    return surfaces.extruded_cylinder_surface(radius, length, n_theta=n_facets,
                                              theta0=0.5 * np.pi, center=center,
                                              axis=(0.0, 1.0, 0.0))


def run(bar_radius=5.0, groove_radius=6.0, E=2e5, nu=0.3, height=4.0, half_width=4.0, h=0.25,
        h_coarse=1.0, fine_depth=1.0, growth=1.3, clearance=0.05, indentation=0.05, n_indent=3,
        rotation_step=math.radians(3.7), n_rotation=14, coarse_facets=36, fine_facets=180,
        beta=1e3, settle=2, max_cutbacks=5, variants=DEFAULT_VARIANTS, newton_rtol=1e-9,
        output_dir="results/groove",
        picture=True, progress=True, comm=MPI.COMM_WORLD) -> dict:
    """Run the groove variants and compare them. Collective.

    Args:
        bar_radius, groove_radius: R_b < R_g [mm]; E [MPa], nu: the bar's material.
        height: section height above the bar's lowest point [mm]; half_width: |x| ≤
            half_width [mm].
        h: element size near the contact, also the slab thickness [mm]; h_coarse [mm], growth,
            fine_depth [mm]: grading upwards.
        clearance: initial gap between the bar and the true groove [mm]; indentation: δ past the
            first touch [mm], reached after ``n_indent`` increments (dt = 1 s).
        rotation_step: groove rotation per increment [rad] (default 0.37 coarse facet);
            n_rotation: number of rotation increments.
        coarse_facets, fine_facets: facets around the faceted grooves.
        beta: dimensionless penalty, gap stiffness k = β E*/h [MPa/mm].
        settle: rotation increments excluded from the statistics.
        max_cutbacks: halvings of dt allowed for an increment whose Newton fails.
        variants: (tool, facets, scheme) as in :func:`fxcontact.processes.ironing.run`.
        newton_rtol: Newton's relative residual tolerance (``SolverOptions.rtol``).
        output_dir: outputs (None: nothing written): per variant a VTK series and a CSV
            history, ``summary.csv``, the groove surfaces ``groove_coarse.stl`` and
            ``groove_fine.stl`` and, with ``picture``, the PNGs ``force.png``, ``newton.png``,
            ``contact_nodes.png``.
        picture: draw the PNGs (rank 0, matplotlib).
        progress: show the progress bar of each run.
    Returns:
        dict with ``summary`` (rows of
        :func:`~fxcontact.processes.ironing_report.summarize`; F_z [N] is the force on the
        groove, negative: downwards), ``by_name``, ``results``, ``parameters``,
        ``summary_csv``, ``png``.
    Raises:
        ValueError: on inconsistent parameters or a bad variant.
    """
    if not (0 < bar_radius < groove_radius):
        raise ValueError("need 0 < bar_radius < groove_radius (a groove wider than the bar)")
    if not (clearance >= 0 and indentation > 0 and n_indent >= 1 and n_rotation >= settle + 3
            and rotation_step != 0):
        raise ValueError("need clearance >= 0, indentation > 0, n_indent >= 1, a non-zero "
                         "rotation_step and n_rotation >= settle + 3")
    check_variants(variants, output_dir, comm)
    facet_counts = {"coarse": int(coarse_facets), "fine": int(fine_facets)}
    common = dict(bar_radius=bar_radius, groove_radius=groove_radius, E=E, nu=nu,
                  height=height, half_width=half_width, h=h, h_coarse=h_coarse,
                  fine_depth=fine_depth, growth=growth, clearance=clearance,
                  indentation=indentation, n_indent=n_indent, rotation_step=rotation_step,
                  n_rotation=n_rotation, facet_counts=facet_counts, beta=beta,
                  max_cutbacks=max_cutbacks, progress=progress, comm=comm,
                  newton_rtol=newton_rtol)
    results = [run_variant(tk, f, s, output_dir=output_dir, **common) for tk, f, s in variants]
    out = collect(results, n_indent + settle, common, settle, variants, output_dir)
    if output_dir is not None and comm.rank == 0:
        for label, n in facet_counts.items():
            if any(f == label for _, f, _ in variants):
                V, T = groove_surface(groove_radius, n, h + 4.0,
                                      (0.0, 0.5 * h, groove_radius - clearance))
                surfaces.write_surface(os.path.join(output_dir, f"groove_{label}.stl"), V, T)
        if picture:
            out["png"] = plot_all(results, output_dir, n_indent,
                                  xlabel="time [s] (lift, then rotation)")
    return out
