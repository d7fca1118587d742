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
# **Tool.** ``tool="analytic"`` (default) is the exact sphere. ``tool="nagata"`` and
# ``tool="flat"`` replace it by a coarse triangulated sphere (:class:`FacetedTool`, THEORY §6–8),
# see the section on the faceted tool below; ``--compare`` runs the three on the same block mesh.
#
# Run: ``python demos/demo_hertz_sphere.py`` (serial) or ``mpirun -n 2 python demos/...``.
# ``--size`` sets ``h_fine`` (the one knob); outputs go to ``results/hertz_sphere``: the VTK
# series, the CSV history, the pressure profile (CSV), a PNG of p(r) against Hertz and a PNG of
# the deformed contact zone (displacements magnified). ``--tool nagata|flat`` and
# ``--tool-facet-size`` select a faceted tool; ``--compare`` prints the analytic / Nagata / flat
# table and writes ``hertz_sphere_tools.png`` (the three profiles against Hertz).

# %%
from __future__ import annotations

import argparse
import math
import os
import time

import numpy as np
from dolfinx.io import gmshio
from mpi4py import MPI

from fxcontact.console import add_verbosity_arguments, configure_logging
from fxcontact.contact.boundary import ContactBoundary
from fxcontact.contact.nodal import NodalContact, penalty_from_beta
from fxcontact.io import figure, plot_pressure_profile
from fxcontact.materials import LinearElastic
from fxcontact.meshing import BLOCK_TAGS, gmsh_session
from fxcontact.simulation import Simulation
from fxcontact.newton.solver import SolverOptions
from fxcontact.spaces import MixedSpace
from fxcontact.tools.analytic import Sphere
from fxcontact.tools.faceted import FacetedTool


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
        msh, ct, ft = gmshio.model_to_mesh(gmsh.model, comm, 0, gdim=3)
    return msh, ct, ft


# %% [markdown]
# ## The faceted sphere tool (``tool="nagata"`` / ``"flat"``)
#
# **Mesh.** The quarter model is valid only if the tool is symmetric about the planes x = 0 and
# y = 0, which a generic sphere triangulation (gmsh, icosphere) is not. The tool is therefore an
# *octahedral sphere*: each of the 8 octant faces of an octahedron is split into n² triangles
# (barycentric grid, mapped to the sphere with equal angles along the octahedron edges). The
# mesh is exactly mirror-symmetric about the three coordinate planes, and one octahedron vertex
# (valence 4) is the lowest point of the sphere. n is chosen so that the edges at that vertex
# are ``tool_facet_size`` long (chord 2R sin(π/4n)); the facets elsewhere are up to 1.45× longer.
# The default 1 mm (n = 8, 512 triangles on the full sphere) is about 4× the Hertz contact radius
# a = 0.258 mm: the whole contact zone lies on the 4 facets around the lowest vertex.
#
# **Positioning (fair comparison).** The vertices lie on the true sphere; the facets lie inside
# it (a chord sags by h²/8R = 25 µm at h = 1 mm, twice the indentation). The lowest vertex is
# placed at the first-touch point, the origin, exactly where the analytic sphere touches. First
# touch therefore happens at the same place and time for the three tools, and δ is the same
# rigid displacement from first touch. The Nagata patches interpolate that vertex and its normal
# (vertical by symmetry), so they are tangent to the block there like the true sphere.
#
# **What to expect.** Around the lowest vertex the flat facets form a shallow square pyramid
# (slopes tan(α/2) ≈ 0.10 along the axes and 0.14 along the diagonals, α the edge angle), not a
# flat punch: a punch would need a facet centred at the lowest point, which breaks the quarter
# symmetry. Flat contact is then conical: a smaller contact radius, a far smaller load, and a
# pressure peak at the tip that grows as the block mesh is refined (the cone pressure is
# log-singular). The Nagata patches restore the curvature: their gap error over the contact zone
# is below 0.05 µm against the 6.6 µm sphere gap r²/2R at r = a (n = 8, NVV normals).
#
# **Measured** (``--compare``, default block mesh h_fine = 25 µm, 1 mm tool edges; errors
# against Hertz): analytic P = 1027.6 N (+2.2 %), p_max = 7328 MPa (+1.6 %), a = 0.261 mm;
# Nagata P = 1030.5 N (+2.5 %), p_max = 7309 MPa (+1.3 %, −0.26 % against the analytic tool),
# a = 0.262 mm, no fallbacks, the same 4 Newton iterations per increment; flat P = 221 N
# (−78 %), p_max = 5.7 p0 (4.7 p0 at h_fine = 50 µm: the tip peak is mesh dependent),
# a = 0.065 mm. On the 50 µm test mesh the Nagata p_max stays within 1 % of the analytic one for
# tool edges of 0.5, 1, 2 and 2.6 mm.
#
# **Fallbacks.** ``fallbacks`` is the largest number of nodes whose Nagata projection fell back
# to the flat facet in any increment (``contact_fallbacks`` of the last evaluation); the tool's
# own running count over all projections is ``tool_projection_fallbacks``.

# %%
def octahedral_sphere(n: int, radius: float = 1.0, center=(0.0, 0.0, 0.0)):
    """Sphere triangulated from an octahedron, n² triangles per octant, mirror-symmetric about
    the coordinate planes through ``center``; vertices on the sphere, outward orientation.

    Returns ``(vertices (N, 3), triangles (8 n², 3))``; N = 4 n² + 2.
    """
    n = int(n)
    if n < 1:
        raise ValueError("n must be >= 1")
    index, verts, tris = {}, [], []
    # barycentric grid (i, j, k = n - i - j) on one octant face, equal angles along its edges
    grid = [(i, j) for i in range(n + 1) for j in range(n + 1 - i)]
    lam = np.array([(i, j, n - i - j) for i, j in grid], dtype=np.float64) / n
    w = np.sin(0.5 * np.pi * lam)
    local = []
    for i in range(n):
        for j in range(n - i):
            local.append(((i, j), (i + 1, j), (i, j + 1)))
            if i + j < n - 1:
                local.append(((i + 1, j), (i + 1, j + 1), (i, j + 1)))
    for sx in (1.0, -1.0):
        for sy in (1.0, -1.0):
            for sz in (1.0, -1.0):
                p = w * np.array([sx, sy, sz])
                p /= np.linalg.norm(p, axis=1, keepdims=True)
                ids = {}
                for (ij, q) in zip(grid, p):
                    key = tuple(np.round(q, 12) + 0.0)
                    if key not in index:
                        index[key] = len(verts)
                        verts.append(q)
                    ids[ij] = index[key]
                T = np.array([[ids[a], ids[b], ids[c]] for a, b, c in local], dtype=np.int64)
                if sx * sy * sz < 0:  # mirrored octant: reverse to keep the outward orientation
                    T = T[:, [0, 2, 1]]
                tris.append(T)
    V = np.array(verts) * radius + np.asarray(center, dtype=np.float64)
    return V, np.vstack(tris)


def octahedral_divisions(radius: float, facet_size: float) -> int:
    """n such that the edges at an octahedron vertex, 2R sin(π/4n), are closest to
    ``facet_size`` (at least 1)."""
    if not 0 < facet_size < 2 * radius:
        raise ValueError("tool_facet_size must be in (0, 2R)")
    return max(1, int(round(0.5 * math.pi / (2.0 * math.asin(0.5 * facet_size / radius)))))


def make_tool(kind: str, radius: float, speed: float, facet_size: float = 1.0,
              normals="nvv"):
    """The indenter touching the origin at t = 0 and moving down at ``speed``: the analytic
    sphere, or the octahedral faceted sphere (lowest vertex at the origin) in Nagata or flat
    mode. Returns ``(tool, info)`` with the facet count and the edge length at the lowest
    vertex."""
    center = (0.0, 0.0, radius)
    velocity = (0.0, 0.0, -speed)
    if kind == "analytic":
        return Sphere(center=center, radius=radius, velocity=velocity, name="sphere"), {}
    if kind not in ("nagata", "flat"):
        raise ValueError(f"tool must be 'analytic', 'nagata' or 'flat', got {kind!r}")
    n = octahedral_divisions(radius, facet_size)
    V, T = octahedral_sphere(n, radius, center)
    if isinstance(normals, str) and normals == "exact":
        normals = (V - np.asarray(center)) / radius
    tool = FacetedTool(V, T, mode=kind, normals=normals, velocity=velocity, name="sphere")
    info = {"tool_divisions": n, "tool_triangles": int(T.shape[0]),
            "tool_facet_size": 2.0 * radius * math.sin(0.25 * math.pi / n)}
    return tool, info


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
        height=80.0, refine=0.4, growth=0.15, scheme=None, penalty=None, beta=1e4, n_steps=3,
        tool="analytic", tool_facet_size=1.0, tool_normals="nvv",
        output_dir="results/hertz_sphere", picture=True, progress=True,
        comm=MPI.COMM_WORLD, formulation="mixed", linear_solver="auto") -> dict:
    """Indent the block by ``indentation`` with the sphere in ``n_steps`` increments.

    ``formulation="mixed"`` (default) is fxcontact's MINI velocity–pressure Simulation;
    ``formulation="p1"`` is a plain P1-displacement dolfinx problem with the same contact
    (:func:`run_p1`, displacement form, same penalty, same mesh).

    Args:
        radius: sphere radius R [mm]; E [MPa], nu: block material.
        indentation: final sphere displacement δ [mm] from first touch at the origin.
        h_fine: element size within the distance ``refine`` of the first contact point; it
            grows linearly with slope ``growth`` up to ``h`` far away [mm].
        width, height: quarter block ``[0, width]² × [-height, 0]`` [mm].
        scheme: contact scheme (see :data:`fxcontact.contact.nodal.SCHEMES`); None: the
            contact's default (``implicit``, and ``implicit-exact`` in P1 displacement).
        penalty: ρ, or None to use ``beta`` (ρ = β dt E*/h_fine, THEORY §2.5).
        n_steps: number of increments.
        tool: ``"analytic"`` (exact sphere), ``"nagata"`` or ``"flat"`` (octahedral faceted
            sphere, lowest vertex at the first-touch point; see :func:`make_tool`).
        tool_facet_size: edge length of the faceted tool at its lowest vertex [mm].
        tool_normals: nodal normals of the Nagata patches: ``"nvv"`` (estimated from the
            facets, default), ``"exact"`` (the sphere's radial normals) or any value
            :class:`FacetedTool` accepts.
        linear_solver: ``SolverOptions.linear_solver`` of the mixed formulation, or the kind of
            :meth:`fxcontact.ContactProblem.use_linear_solver` in P1 (``"auto"``: by the
            problem's size; P1: ``"direct"`` or ``"iterative"``, or ``"mumps"``: the demo's
            own plain MUMPS LU at every Newton iteration, without the helper).
    Returns:
        dict with ``force`` (4 × quarter), ``contact_radius`` (FEM, equivalent disc),
        ``contact_radius_bounds`` (largest active / smallest inactive nodal radius),
        ``p_max``, Hertz values for the same δ (``hertz_force``,
        ``hertz_contact_radius``, ``hertz_p_max``), the nodal profile ``r``, ``p``, the bottom
        reaction, mesh size, dofs, run time and the history; ``tool``, the Newton iterations
        summed over the increments (``newton_iterations``), Nagata fallbacks (``fallbacks``,
        ``tool_projection_fallbacks``) and, for faceted tools, ``tool_triangles``,
        ``tool_divisions``, ``tool_facet_size``.
    """
    if formulation == "p1":
        return run_p1(radius=radius, E=E, nu=nu, indentation=indentation, h_fine=h_fine, h=h,
                      width=width, height=height, refine=refine, growth=growth, scheme=scheme,
                      beta=beta, n_steps=n_steps, tool=tool, tool_facet_size=tool_facet_size,
                      tool_normals=tool_normals, output_dir=output_dir, picture=picture,
                      comm=comm, linear_solver=linear_solver)
    if formulation != "mixed":
        raise ValueError(f"formulation must be 'mixed' or 'p1', got {formulation!r}")
    t_start = time.perf_counter()
    if not (0 < indentation < 0.5 * radius):
        raise ValueError("indentation must be in (0, R/2)")
    msh, _, ft = graded_block(comm, width, height, h_fine, refine, growth, h)
    space = MixedSpace(msh)
    mat = LinearElastic(E, nu)
    sim = Simulation(space, mat, output_dir=output_dir, name="hertz_sphere", progress=progress,
                     solver_options=SolverOptions(linear_solver=linear_solver))
    sim.add_velocity_bc(sim.facets(ft, BLOCK_TAGS["xmin"]), 0.0, 0)   # symmetry
    sim.add_velocity_bc(sim.facets(ft, BLOCK_TAGS["ymin"]), 0.0, 1)   # symmetry
    bottom = sim.facets(ft, BLOCK_TAGS["zmin"])
    sim.add_velocity_bc(bottom, 0.0, 2)                                # frictionless roller
    sim.add_reaction("bottom", bottom)
    t_end = 1.0
    speed = indentation / t_end
    indenter, tool_info = make_tool(tool, radius, speed, tool_facet_size, tool_normals)
    dt = t_end / n_steps
    if penalty is None:
        # ρ = β dt E*/h_e given explicitly: NodalContact(beta=...) leaves ρ unset until the
        # first increment, and writing the initial output fields then fails (see the report)
        penalty = penalty_from_beta(mat, beta, h_fine, dt=dt)
    boundary = ContactBoundary(space, ft, BLOCK_TAGS["zmax"])
    contact = sim.add_contributor(NodalContact(boundary, indenter, scheme=scheme,
                                               penalty=penalty,
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
           "png_deformed": None, "tool": tool,
           "newton_iterations": int(sum(r["newton_iterations"] for r in sim.history)),
           "fallbacks": int(max(r["contact_fallbacks"] for r in sim.history)),
           "tool_projection_fallbacks": comm.allreduce(
               int(getattr(indenter, "total_fallbacks", 0)), op=MPI.SUM), **tool_info}
    if output_dir is not None and picture:
        out["png_deformed"] = render_deformed(
            sim, os.path.join(output_dir, "hertz_sphere_3d.png"), zone=4.0 * a_h)
    if output_dir is not None and comm.rank == 0:
        np.savetxt(os.path.join(output_dir, "profile.csv"), np.c_[rs, ps, Ss], delimiter=",",
                   header="r,p,S", comments="")
        if picture:
            out["png"] = plot_profile(out, os.path.join(output_dir, "hertz_sphere.png"))
    out["wall_time"] = time.perf_counter() - t_start
    out["formulation"] = "mixed"
    return out


# %% [markdown]
# ## The same test in P1 displacement (a plain dolfinx problem plus fxcontact's contact)
#
# For compressible elasticity the mixed velocity–pressure machinery is not needed: the
# displacement u of a ``VectorFunctionSpace(msh, ("Lagrange", 1))`` and the linear elastic
# residual ∫ σ(u):ε(v) dx, written the dolfinx way, solved by dolfinx's own ``NewtonSolver``.
# fxcontact adds the nodal contact in displacement form (:class:`fxcontact.ContactProblem`,
# ``NodalContact(..., formulation="displacement")``): the gap is written on X = X_ref + u with
# the sphere at the end of each load step, with the gap stiffness k = β E*/h_fine — the
# same penalty as the mixed run (ρ = β dt E*/h_fine on the velocity). Same mesh, same nodes,
# same areas: the two differ only by the volume discretisation (P1 against MINI with a mixed
# pressure). ``--formulation both`` prints them side by side.

# %%
def run_p1(radius=5.0, E=2e5, nu=0.3, indentation=0.0133, h_fine=0.025, h=16.0, width=80.0,
           height=80.0, refine=0.4, growth=0.15, scheme=None, beta=1e4, n_steps=3,
           tool="analytic", tool_facet_size=1.0, tool_normals="nvv",
           output_dir="results/hertz_sphere", picture=True, comm=MPI.COMM_WORLD,
           linear_solver="auto") -> dict:
    """:func:`run` in P1 displacement; returns the same keys (no deformed-mesh picture) plus
    the wall-time split ``times`` (``assembly``, ``contact``, ``linear_solve``, ``newton``: the
    whole solves) and the ``linear_solver`` used."""
    import ufl
    import dolfinx.fem
    import dolfinx.fem.petsc
    import dolfinx.mesh
    import dolfinx.nls.petsc
    from petsc4py import PETSc
    import fxcontact as fx

    t_start = time.perf_counter()
    if not (0 < indentation < 0.5 * radius):
        raise ValueError("indentation must be in (0, R/2)")
    msh, _, ft = graded_block(comm, width, height, h_fine, refine, growth, h)
    # --- the dolfinx problem: linear elasticity in P1 displacement -----------------------
    V = dolfinx.fem.VectorFunctionSpace(msh, ("Lagrange", 1))
    u, v = dolfinx.fem.Function(V, name="displacement"), ufl.TestFunction(V)
    mu, lmbda = E / (2 * (1 + nu)), E * nu / ((1 + nu) * (1 - 2 * nu))
    eps = lambda w: ufl.sym(ufl.grad(w))  # noqa: E731
    sigma = 2 * mu * eps(u) + lmbda * ufl.tr(eps(u)) * ufl.Identity(3)
    F = ufl.inner(sigma, eps(v)) * ufl.dx
    fdim = 2
    bcs = []
    for name, comp in (("xmin", 0), ("ymin", 1), ("zmin", 2)):
        facets = ft.indices[ft.values == BLOCK_TAGS[name]]
        dofs = dolfinx.fem.locate_dofs_topological(V.sub(comp), fdim, facets)
        bcs.append(dolfinx.fem.dirichletbc(PETSc.ScalarType(0.0), dofs, V.sub(comp)))
    # --- the fxcontact lines --------------------------------------------------------------
    mat = LinearElastic(E, nu)
    indenter, tool_info = make_tool(tool, radius, indentation, tool_facet_size, tool_normals)
    contact = fx.NodalContact(fx.ContactBoundary(V, ft, BLOCK_TAGS["zmax"]), indenter,
                              scheme=scheme, formulation="displacement", beta=beta,
                              modulus=mat.plane_strain_modulus, element_size=h_fine)
    problem = fx.ContactProblem(F, u, bcs, contributors=[contact])
    solver = dolfinx.nls.petsc.NewtonSolver(comm, problem)
    # dolfinx's "residual" test is relative to the first Newton step's norm (0.5.2): on a
    # stiff elastic problem it stalls at the round-off floor; test the Newton step instead
    solver.convergence_criterion = "incremental"
    solver.rtol, solver.atol = 1e-9, 1e-14
    problem.set_solver(solver)
    if linear_solver == "mumps":
        # the user's own KSP: MUMPS LU at every Newton iteration
        ksp = solver.krylov_solver
        opts, pfx = PETSc.Options(), ksp.getOptionsPrefix()
        for key, val in {"ksp_type": "preonly", "pc_type": "lu",
                         "pc_factor_mat_solver_type": "mumps"}.items():
            opts[pfx + key] = val
        ksp.setFromOptions()
        kind = "mumps"
    else:
        # MUMPS reused while the active set holds, or CG + GAMG with the rigid-body modes
        # from 30k unknowns (fxcontact's opt-in helper)
        kind = problem.use_linear_solver(solver, linear_solver)
    newton = 0
    t_newton = time.perf_counter()
    for k in range(1, n_steps + 1):
        problem.begin_step(k / n_steps)       # the sphere at t = k/n: indentation k δ/n
        its, converged = solver.solve(u)
        newton += its
    problem.end_step()
    times = {**problem.timers.times, "newton": time.perf_counter() - t_newton,
             "krylov_iterations": problem.krylov_iterations,
             "factorisations": problem.factorisations[0]}
    # --- outputs (as run) -----------------------------------------------------------------
    E_star = mat.plane_strain_modulus
    P = 4.0 * float(contact.tool_force(0)[2])
    P_h, a_h, p0_h = hertz_sphere(indentation, radius, E_star)
    b = contact.boundary
    xb = b.mesh_positions()
    loc = np.c_[np.hypot(xb[:, 0], xb[:, 1]), contact.pressures(), b.areas]
    allv = np.concatenate(comm.allgather(loc))
    allv = allv[np.argsort(allv[:, 0], kind="stable")]
    rs, ps, Ss = allv[:, 0], allv[:, 1], allv[:, 2]
    active = ps > 0
    a_fem = math.sqrt(4.0 * float(np.sum(Ss[active])) / math.pi)
    # bottom reaction: the internal forces at the bottom's u_z dofs (owned), summed
    r = dolfinx.fem.petsc.assemble_vector(problem.L)
    r.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
    bdofs = dolfinx.fem.locate_dofs_topological(
        V.sub(2), fdim, ft.indices[ft.values == BLOCK_TAGS["zmin"]])
    bdofs = bdofs[bdofs < V.dofmap.index_map.size_local * 3]
    Rz = comm.allreduce(float(np.sum(r.getArray(readonly=True)[bdofs])), op=MPI.SUM)
    r.destroy()
    diag = contact.diagnostics()
    n_cells = comm.allreduce(msh.topology.index_map(3).size_local, op=MPI.SUM)
    out = {"force": P, "contact_radius": a_fem,
           "contact_radius_bounds": (float(np.max(rs[active], initial=0.0)),
                                     float(np.min(rs[~active], initial=np.inf))),
           "p_max": float(np.max(ps)), "hertz_force": P_h, "hertz_contact_radius": a_h,
           "hertz_p_max": p0_h, "E_star": E_star, "r": rs, "p": ps, "nodal_area": Ss,
           "bottom_reaction": 4.0 * Rz, "indentation": indentation, "radius": radius,
           "penetration": diag["contact_penetration_true"], "active_nodes": int(np.sum(active)),
           "h_fine": h_fine, "cells": n_cells,
           "dofs": V.dofmap.index_map.size_global * V.dofmap.index_map_bs, "history": [],
           "png": None, "png_deformed": None, "tool": tool, "newton_iterations": newton,
           "fallbacks": int(diag["contact_fallbacks"]),
           "tool_projection_fallbacks": comm.allreduce(
               int(getattr(indenter, "total_fallbacks", 0)), op=MPI.SUM),
           "formulation": "p1", "times": times, "linear_solver": kind, **tool_info}
    if output_dir is not None and comm.rank == 0:
        os.makedirs(output_dir, exist_ok=True)
        np.savetxt(os.path.join(output_dir, "profile_p1.csv"), np.c_[rs, ps, Ss],
                   delimiter=",", header="r,p,S", comments="")
        if picture:
            out["png"] = plot_profile(out, os.path.join(output_dir, "hertz_sphere_p1.png"))
    out["wall_time"] = time.perf_counter() - t_start
    return out


def compare_formulations(**params) -> dict:
    """The mixed (MINI velocity–pressure) and the P1-displacement runs on the same mesh, one
    after the other in the same process; returns ``{"mixed": …, "p1": …, "table": str}``."""
    out = {f: run(formulation=f, **params) for f in ("mixed", "p1")}
    first = out["mixed"]
    lines = [f"Hertz (δ = {1e3 * first['indentation']:.1f} µm): P = {first['hertz_force']:.1f} "
             f"N, p0 = {first['hertz_p_max']:.0f} MPa, a = {first['hertz_contact_radius']:.4f} "
             f"mm; {first['cells']} tetrahedra, h_fine = {first['h_fine']} mm",
             f"{'formulation':12s}{'dofs':>9s}{'force [N]':>11s}{'vs H':>8s}{'p_max':>8s}"
             f"{'vs H':>8s}{'a [mm]':>8s}{'vs H':>8s}{'Newton':>7s}{'time [s]':>9s}"]
    for f in ("mixed", "p1"):
        r = out[f]
        lines.append(f"{f:12s}{r['dofs']:9d}{r['force']:11.2f}"
                     f"{r['force'] / r['hertz_force'] - 1:8.2%}{r['p_max']:8.0f}"
                     f"{r['p_max'] / r['hertz_p_max'] - 1:8.2%}{r['contact_radius']:8.4f}"
                     f"{r['contact_radius'] / r['hertz_contact_radius'] - 1:8.2%}"
                     f"{r['newton_iterations']:7d}{r['wall_time']:9.1f}")
    out["table"] = "\n".join(lines)
    return out


# %% [markdown]
# ## Comparison of the three tools on the same block mesh
#
# :func:`compare_tools` runs the analytic, Nagata and flat tools with the same parameters (each
# run writes into its own subdirectory of ``output_dir``), prints a table and draws the three
# nodal pressure profiles against Hertz. Acceptance (issue 4): the Nagata p_max within 5 % of
# the analytic-tool p_max on the same mesh; flat facets are reported for comparison.

# %%
TOOLS = ("analytic", "nagata", "flat")


def compare_tools(tools=TOOLS, output_dir="results/hertz_sphere", picture=True, **params) -> dict:
    """Run :func:`run` once per tool kind with the same ``params``; returns ``{tool: result}``
    plus ``"table"`` (text) and ``"png"`` (the profiles, rank 0; None without output)."""
    comm = params.get("comm", MPI.COMM_WORLD)
    out = {}
    for kind in tools:
        sub = None if output_dir is None else os.path.join(output_dir, kind)
        out[kind] = run(tool=kind, output_dir=sub, picture=False, **params)
    out["table"] = format_table(out, tools)
    out["png"] = None
    if output_dir is not None and picture and comm.rank == 0:
        out["png"] = plot_tools(out, tools, os.path.join(output_dir, "hertz_sphere_tools.png"))
    return out


def format_table(results: dict, tools=TOOLS) -> str:
    """Force, p_max, contact radius (with the error against Hertz and, for p_max, against the
    analytic tool), Nagata fallbacks, Newton iterations and wall time, one line per tool."""
    first = results[tools[0]]
    ref = results.get("analytic")
    lines = [f"Hertz (δ = {1e3 * first['indentation']:.1f} µm, R = {first['radius']:g} mm): "
             f"P = {first['hertz_force']:.1f} N, p0 = {first['hertz_p_max']:.0f} MPa, "
             f"a = {first['hertz_contact_radius']:.4f} mm; block mesh {first['cells']} "
             f"tetrahedra, h_fine = {first['h_fine']} mm",
             f"{'tool':9s}{'facets':>7s}{'force [N]':>11s}{'vs H':>8s}{'p_max [MPa]':>12s}"
             f"{'vs H':>8s}{'vs an.':>8s}{'a [mm]':>8s}{'vs H':>8s}{'fallb.':>7s}"
             f"{'Newton':>7s}{'time [s]':>9s}"]
    for kind in tools:
        r = results[kind]
        vs_an = f"{r['p_max'] / ref['p_max'] - 1:8.2%}" if ref is not None else f"{'':8s}"
        facets = str(r.get("tool_triangles", "-"))
        lines.append(
            f"{kind:9s}{facets:>7s}{r['force']:11.2f}{r['force'] / r['hertz_force'] - 1:8.2%}"
            f"{r['p_max']:12.0f}{r['p_max'] / r['hertz_p_max'] - 1:8.2%}{vs_an}"
            f"{r['contact_radius']:8.4f}"
            f"{r['contact_radius'] / r['hertz_contact_radius'] - 1:8.2%}{r['fallbacks']:7d}"
            f"{r['newton_iterations']:7d}{r['wall_time']:9.1f}")
    facet = next((results[k] for k in tools if "tool_facet_size" in results[k]), None)
    if facet is not None:
        lines.append(f"faceted tool: octahedral sphere, n = {facet['tool_divisions']}, "
                     f"{facet['tool_triangles']} triangles, edge {facet['tool_facet_size']:.3f} "
                     f"mm at the lowest vertex (a/edge = "
                     f"{facet['hertz_contact_radius'] / facet['tool_facet_size']:.2f})")
    return "\n".join(lines)


def plot_tools(results: dict, tools, path: str) -> str:
    """p/p0 against r/a for each tool, with the Hertz ellipse."""
    first = results[tools[0]]
    a, p0 = first["hertz_contact_radius"], first["hertz_p_max"]
    style = {"analytic": ("o", "C0"), "nagata": ("s", "C2"), "flat": ("^", "C3")}
    label = {"analytic": "analytic sphere", "nagata": "faceted, Nagata patches",
             "flat": "faceted, flat facets"}
    nodes = []
    for kind in tools:
        r = results[kind]
        mk, col = style.get(kind, ("x", None))
        nodes.append((r["r"], r["p"], dict(
            marker=mk, color=col, ms=3.5, alpha=0.7, mfc="none" if kind == "nagata" else col,
            label=f"{label.get(kind, kind)}: $p_{{max}}/p_0$ = {r['p_max'] / p0:.3f}, "
                  f"P = {r['force']:.0f} N")))
    edge = next((results[k]["tool_facet_size"] for k in tools
                 if "tool_facet_size" in results[k]), None)
    extra = f", tool edge {edge:.2f} mm = {edge / a:.1f} a" if edge else ""
    with figure(path, figsize=(7.5, 4.8)) as (fig, ax):
        plot_pressure_profile(ax, a, p0, nodes)
        ax.set_ylim(0, None)
        ax.set_title(f"Hertz sphere, δ = {1e3 * first['indentation']:.1f} µm (Hertz P = "
                     f"{first['hertz_force']:.0f} N){extra}", fontsize=10)
        ax.legend(fontsize=8)
    return path


# %% [markdown]
# ## Pictures: p(r) against Hertz; the deformed block (collective)

# %%
def plot_profile(res: dict, path: str) -> str:
    a, p0 = res["hertz_contact_radius"], res["hertz_p_max"]
    with figure(path) as (fig, ax):
        nodes = [(res["r"], res["p"], dict(ms=3, alpha=0.7, label="FEM nodal $p_n$"))]
        plot_pressure_profile(ax, a, p0, nodes, extent=(
            res["contact_radius"], "FEM radius $\\sqrt{4\\sum S_n/\\pi}$"))
        ax.set_title(f"Hertz sphere: δ = {1e3 * res['indentation']:.1f} µm, "
                     f"P = {res['force']:.0f} N (Hertz {res['hertz_force']:.0f} N)")
        ax.legend()
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
    ap.add_argument("--scheme", default=None,
                    help="contact scheme (default: implicit; implicit-exact in P1)")
    ap.add_argument("--tool", default="analytic", choices=TOOLS,
                    help="indenter: exact sphere or faceted sphere (Nagata / flat)")
    ap.add_argument("--tool-facet-size", type=float, default=1.0,
                    help="faceted tool: edge length at the lowest vertex [mm]")
    ap.add_argument("--tool-normals", default="nvv", choices=("nvv", "exact", "angle", "area"),
                    help="nodal normals of the Nagata patches")
    ap.add_argument("--compare", action="store_true",
                    help="run the analytic, Nagata and flat tools and compare them")
    ap.add_argument("--formulation", default="mixed", choices=("mixed", "p1", "both"),
                    help="MINI velocity-pressure (fxcontact Simulation), P1 displacement (a "
                         "dolfinx problem + ContactProblem), or both side by side")
    ap.add_argument("--output", default="results/hertz_sphere")
    add_verbosity_arguments(ap)
    args = ap.parse_args()
    configure_logging(args.verbose, args.quiet)
    if args.compare:
        res = compare_tools(h_fine=args.size, scheme=args.scheme,
                            tool_facet_size=args.tool_facet_size, tool_normals=args.tool_normals,
                            output_dir=args.output)
        if MPI.COMM_WORLD.rank == 0:
            print(res["table"])
            print(f"output: {res['png']}")
        raise SystemExit(0)
    if args.formulation == "both":
        res = compare_formulations(h_fine=args.size, scheme=args.scheme, tool=args.tool,
                                   tool_facet_size=args.tool_facet_size,
                                   tool_normals=args.tool_normals, output_dir=args.output)
        if MPI.COMM_WORLD.rank == 0:
            print(res["table"])
        raise SystemExit(0)
    res = run(h_fine=args.size, scheme=args.scheme, tool=args.tool,
              tool_facet_size=args.tool_facet_size, tool_normals=args.tool_normals,
              output_dir=args.output, formulation=args.formulation)
    if MPI.COMM_WORLD.rank == 0:
        lo, hi = res["contact_radius_bounds"]
        print(f"mesh: {res['cells']} tetrahedra, {res['dofs']} dofs, h_fine = {res['h_fine']} "
              f"mm, {res['active_nodes']} active nodes; {res['wall_time']:.1f} s")
        if res["tool"] != "analytic":
            print(f"tool: {res['tool']}, {res['tool_triangles']} triangles, edge "
                  f"{res['tool_facet_size']:.3f} mm at the lowest vertex; Nagata fallbacks "
                  f"{res['fallbacks']}")
        print(f"bottom reaction {res['bottom_reaction']:.2f} N")
        print(f"{'':22s}{'FEM':>12s}{'Hertz':>12s}{'error':>10s}")
        for name, k, kh in (("force P [N]", "force", "hertz_force"),
                            ("radius a [mm]", "contact_radius", "hertz_contact_radius"),
                            ("p_max [MPa]", "p_max", "hertz_p_max")):
            print(f"{name:22s}{res[k]:12.5g}{res[kh]:12.5g}{res[k] / res[kh] - 1:10.2%}")
        print(f"active/inactive node radii {lo:.4f}..{hi:.4f}; a/R = "
              f"{res['hertz_contact_radius'] / res['radius']:.3f}")
        print(f"outputs: {res['png']}, {res['png_deformed']}")
        print(f"formulation: {res['formulation']}")
