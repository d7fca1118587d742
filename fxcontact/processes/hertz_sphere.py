"""Hertz point contact: a rigid sphere indenting an elastic block (THEORY §11.1–11.2).

A rigid sphere of radius R indents the top face of a linear elastic block (E, ν) by the
``indentation`` δ, under displacement control: the sphere touches the block at the origin at
t = 0 and moves down at a constant speed during ``n_steps`` increments. Frictionless nodal
penalty contact (THEORY §2), small strain (THEORY §1.4). Quarter model: symmetry ``u_x = 0``
on x = 0 and ``u_y = 0`` on y = 0, frictionless roller ``u_z = 0`` on the bottom. The block is
:func:`~fxcontact.processes.hertz.graded_block`, the tool
:func:`~fxcontact.processes.hertz.make_tool`, the reference
:func:`~fxcontact.processes.hertz.hertz_sphere` (δ controls the test directly: in 3D the
indentation of a half-space is well defined).

* :func:`run` — fxcontact's MINI velocity–pressure :class:`~fxcontact.simulation.Simulation`
  (``formulation="mixed"``), or :func:`run_p1` (``formulation="p1"``): a plain P1-displacement
  dolfinx problem with the same contact (:class:`~fxcontact.newton.problem.ContactProblem`);
* :func:`compare_formulations` (mixed against P1) and :func:`compare_tools` (analytic, Nagata
  and flat tools on the same block mesh) with their tables (:func:`format_table`);
* pictures: :func:`plot_profile` (p(r) against Hertz), :func:`plot_tools`,
  :func:`render_deformed` (the deformed contact zone).

**FEM contact radius.** ``contact_radius`` is the radius of the disc with the active contact
area, ``sqrt(4 Σ_{p_n>0} S_n / π)`` (S_n: lumped nodal areas of the quarter model). The radii
of the outermost active and innermost inactive nodes are returned too
(``contact_radius_bounds``; on an unstructured mesh they may cross).

**Sources of error in the force** (all make the model stiffer than Hertz, measured at
δ = 13.3 µm, a = 0.258 mm): the finite block on a rigid frictionless base, ≈ +1.5 % for a
10 mm block and ∝ 1/H (hence the default 80 mm block, ≈ 300 a, ≈ +0.3 %: the graded mesh
makes its cost logarithmic); the growth of the element size away from the contact, ∝ growth²
(≈ +1.3 % at 0.2); the resolution of the contact zone (≈ +2 % at h_fine = 50 µm, +1 % at
25 µm). The defaults give +2.2 % on the force, +1.6 % on p_max.

**Fallbacks** (faceted Nagata tool). ``fallbacks`` is the largest number of nodes whose Nagata
projection fell back to the flat facet in any increment (``contact_fallbacks`` of the last
evaluation); the tool's own running count over all projections is
``tool_projection_fallbacks``.

Units: mm, N, MPa, s (the runs last 1 s). Every function that runs or gathers is collective;
the CSV files and matplotlib pictures are written on rank 0.
"""

from __future__ import annotations

import math
import os
import time

import dolfinx
import dolfinx.fem
import dolfinx.fem.petsc
import dolfinx.mesh
import dolfinx.nls.petsc
import numpy as np
import ufl
from mpi4py import MPI
from petsc4py import PETSc

from fxcontact.contact.boundary import ContactBoundary
from fxcontact.contact.nodal import NodalContact, penalty_from_beta
from fxcontact.io import figure, plot_pressure_profile, render_png
from fxcontact.materials import LinearElastic
from fxcontact.meshing import BLOCK_TAGS
from fxcontact.newton.problem import ContactProblem
from fxcontact.newton.solver import SolverOptions
from fxcontact.processes.hertz import TOOLS, graded_block, hertz_sphere, make_tool
from fxcontact.simulation import Simulation
from fxcontact.spaces import MixedSpace

__all__ = ["run", "run_p1", "compare_formulations", "compare_tools", "format_table",
           "gather_profile", "plot_profile", "plot_tools", "render_deformed"]


def gather_profile(contact: NodalContact, x: np.ndarray, comm) -> tuple:
    """Radii [mm], pressures [MPa] and lumped areas [mm²] of the contact nodes of all ranks,
    sorted by radius (``x``: the vertex positions [mm]). Collective."""
    b = contact.boundary
    xb = x[b.vertices]
    loc = np.c_[np.hypot(xb[:, 0], xb[:, 1]), contact.pressures(), b.areas]
    allv = np.concatenate(comm.allgather(loc))
    allv = allv[np.argsort(allv[:, 0], kind="stable")]
    return allv[:, 0], allv[:, 1], allv[:, 2]


# ------------------------------------------------------------------ the runs

def run(radius=5.0, E=2e5, nu=0.3, indentation=0.0133, h_fine=0.025, h=16.0, width=80.0,
        height=80.0, refine=0.4, growth=0.15, scheme=None, penalty=None, beta=1e4, n_steps=3,
        tool="analytic", tool_facet_size=1.0, tool_normals="nvv",
        output_dir="results/hertz_sphere", picture=True, progress=True,
        comm=MPI.COMM_WORLD, formulation="mixed", linear_solver="auto") -> dict:
    """Indent the block by ``indentation`` with the sphere in ``n_steps`` increments (the run
    lasts 1 s: the tool's speed is ``indentation`` per second).

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
        penalty: ρ [MPa·s/mm], or None to use ``beta`` (ρ = β dt E*/h_fine, THEORY §2.5).
        beta: dimensionless penalty factor β.
        n_steps: number of increments.
        tool: ``"analytic"`` (exact sphere), ``"nagata"`` or ``"flat"`` (octahedral faceted
            sphere, lowest vertex at the first-touch point; see
            :func:`~fxcontact.processes.hertz.make_tool`).
        tool_facet_size: edge length of the faceted tool at its lowest vertex [mm].
        tool_normals: nodal normals of the Nagata patches: ``"nvv"`` (estimated from the
            facets, default), ``"exact"`` (the sphere's radial normals) or any value
            :class:`~fxcontact.tools.faceted.FacetedTool` accepts.
        linear_solver: ``SolverOptions.linear_solver`` of the mixed formulation, or the kind of
            :meth:`fxcontact.ContactProblem.use_linear_solver` in P1 (``"auto"``: by the
            problem's size; P1: ``"direct"`` or ``"iterative"``, or ``"mumps"``: a plain
            MUMPS LU at every Newton iteration, without the helper).
        output_dir: where the VTK series, the CSV history (``hertz_sphere_history.csv``), the
            nodal profile (``profile.csv``: r, p, S) and the pictures go; None: no output.
        picture: draw ``hertz_sphere.png`` (p(r) against Hertz, :func:`plot_profile`) and
            ``hertz_sphere_3d.png`` (the deformed contact zone, :func:`render_deformed`).
        progress: show the progress bar of the increments.
        comm: the communicator of the run.
        formulation: ``"mixed"`` or ``"p1"``.
    Returns:
        dict with ``force`` [N] (4 × quarter), ``contact_radius`` [mm] (FEM, equivalent disc),
        ``contact_radius_bounds`` (largest active / smallest inactive nodal radius),
        ``p_max`` [MPa], Hertz values for the same δ (``hertz_force``,
        ``hertz_contact_radius``, ``hertz_p_max``), the nodal profile ``r``, ``p``, the bottom
        reaction [N], mesh size, dofs, run time [s] and the history; ``tool``, the Newton
        iterations summed over the increments (``newton_iterations``), Nagata fallbacks
        (``fallbacks``, ``tool_projection_fallbacks``) and, for faceted tools,
        ``tool_triangles``, ``tool_divisions``, ``tool_facet_size`` [mm].
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
        # first increment, and writing the initial output fields then fails
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


def run_p1(radius=5.0, E=2e5, nu=0.3, indentation=0.0133, h_fine=0.025, h=16.0, width=80.0,
           height=80.0, refine=0.4, growth=0.15, scheme=None, beta=1e4, n_steps=3,
           tool="analytic", tool_facet_size=1.0, tool_normals="nvv",
           output_dir="results/hertz_sphere", picture=True, comm=MPI.COMM_WORLD,
           linear_solver="auto") -> dict:
    """:func:`run` in P1 displacement: a plain dolfinx problem plus fxcontact's contact.

    For compressible elasticity the mixed velocity–pressure machinery is not needed: the
    displacement u of a ``VectorFunctionSpace(msh, ("Lagrange", 1))`` and the linear elastic
    residual ∫ σ(u):ε(v) dx, written the dolfinx way, solved by dolfinx's own
    ``NewtonSolver``. The nodal contact is added in displacement form
    (:class:`~fxcontact.newton.problem.ContactProblem`,
    ``NodalContact(..., formulation="displacement")``): the gap is written on X = X_ref + u
    with the sphere at the end of each load step, with the gap stiffness k = β E*/h_fine
    [MPa/mm] — the same penalty as the mixed run (ρ = β dt E*/h_fine on the velocity). Same
    mesh, same nodes, same areas: the two differ only by the volume discretisation (P1
    against MINI with a mixed pressure).

    The arguments are those of :func:`run` (``penalty`` and ``progress`` excepted). Returns the
    keys of :func:`run` (no deformed-mesh picture, empty ``history``) plus the wall-time split
    ``times`` [s] (``assembly``, ``contact``, ``linear_solve``, ``newton``: the whole solves)
    and the ``linear_solver`` used. Writes ``profile_p1.csv`` and ``hertz_sphere_p1.png``.
    """
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
    contact = NodalContact(ContactBoundary(V, ft, BLOCK_TAGS["zmax"]), indenter,
                           scheme=scheme, formulation="displacement", beta=beta,
                           modulus=mat.plane_strain_modulus, element_size=h_fine)
    problem = ContactProblem(F, u, bcs, contributors=[contact])
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


# ------------------------------------------------------------------ comparisons and tables

def compare_formulations(**params) -> dict:
    """The mixed (MINI velocity–pressure) and the P1-displacement runs on the same mesh, one
    after the other in the same process (``params``: those of :func:`run`); returns
    ``{"mixed": …, "p1": …, "table": str}`` (force, p_max, contact radius against Hertz,
    dofs, Newton iterations, wall time)."""
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


def compare_tools(tools=TOOLS, output_dir="results/hertz_sphere", picture=True, **params) -> dict:
    """Run :func:`run` once per tool kind of ``tools`` with the same ``params`` (each run
    writes into its own subdirectory of ``output_dir``, without its own pictures); returns
    ``{tool: result}`` plus ``"table"`` (:func:`format_table`) and ``"png"``
    (``hertz_sphere_tools.png``, the profiles of :func:`plot_tools`, rank 0; None without
    output).

    Measured (default block mesh h_fine = 25 µm, 1 mm tool edges): the Nagata p_max within
    0.3 % of the analytic tool's with the same Newton iterations; flat facets make a conical
    indenter (P ≈ −78 %, a pressure peak at the tip that grows as the mesh is refined)."""
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


# ------------------------------------------------------------------ pictures

def plot_tools(results: dict, tools, path: str) -> str:
    """p/p0 against r/a for each tool of ``results`` (:func:`compare_tools`), with the Hertz
    ellipse; writes the PNG ``path`` and returns it (matplotlib: call on one rank)."""
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


def plot_profile(res: dict, path: str) -> str:
    """The nodal pressures of a run (:func:`run`) against Hertz's ellipse, p/p0 against r/a,
    with the FEM contact radius; writes the PNG ``path`` and returns it (matplotlib: call on
    one rank)."""
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
    y = 0. Collective. ``zone`` [mm]; returns ``path``, or None without a renderer."""
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

