"""Transient heat conduction in the workpiece: P1 temperature, backward Euler, lumped capacity and
lumped boundary exchange (THEORY §16.3).

Each step solves, for the increment ΔT = Tⁿ⁺¹ − Tⁿ,

    (M/dt + K + H) ΔT = Q_v + Q_n + H (T_ext − Tⁿ) − K Tⁿ,

the same system as (M/dt + K + H) Tⁿ⁺¹ = M Tⁿ/dt + Q_v + Q_n + H T_ext written so that the linear
solver's tolerance is relative to the step's heat flows (not to M Tⁿ/dt), which keeps the energy
balance of the step at the solver's tolerance. M is the row-sum lumped capacity
M_n = ρc(Tⁿ_n) ∫ N_n dx, K the conduction matrix ∫ k(Tⁿ) ∇N_i·∇N_j dx (k interpolated in P1
from its nodal values), H the diagonal exchange H_nn = h_n S_n with the lumped areas
S_n = ∫ N_n dΓ: air (convection and linearised radiation) on the exchange boundary, replaced at
contact vertices by the tools' coefficients. Q_v = ∫ N_n q dx is the volumetric source (a DG0
field), Q_n nodal heat flows (the friction heat). The forms are compiled once and assembled
on the current coordinates at every step: the mesh may move between steps (updated
Lagrangian).
"""

from __future__ import annotations

import logging
import math

import dolfinx
import dolfinx.fem
import dolfinx.fem.petsc
import dolfinx.mesh
import numpy as np
import ufl
from mpi4py import MPI
from petsc4py import PETSc

from fxcontact import compat
from fxcontact.heat.inputs import (cell_values, checks_together, contact_entries,
                                   nodal_entries, positive_dt)
from fxcontact.heat.materials import AirExchange, ThermalMaterial, check_temperature
from fxcontact.spaces import facets_with_tags

__all__ = ["BALANCE_KEYS", "HEAT_SOLVERS", "HeatProblem"]

log = logging.getLogger(__name__)

#: the linear solvers of :class:`HeatProblem`: CG + BoomerAMG (a MUMPS fallback), MUMPS LU
HEAT_SOLVERS = ("cg", "direct")
#: the scalar entries of the balance a step returns (N mm over the step; flows > 0 into the body)
BALANCE_KEYS = ("stored", "generated", "nodal", "air", "radiation", "fixed", "residual")


class HeatProblem:
    """Transient heat conduction on a (moving) workpiece mesh (THEORY §16).

    Args:
        mesh: a dolfinx simplex mesh (tetrahedra or triangles), lengths in mm. The caller may
            move it between steps (``mesh.geometry.x``): every step assembles on the current
            coordinates.
        thermal: the :class:`~fxcontact.heat.materials.ThermalMaterial`.
        initial_temperature: T⁰ in °C: a number, a callable ``f(x) -> (N,)`` of the points
            (``x`` of shape (3, N), as ``Function.interpolate``), a P1 Function of this mesh, or
            an array of the local dof values (owned and ghost, or owned only).
        air: the free surface's exchange: an :class:`~fxcontact.heat.materials.AirExchange` for
            the whole boundary, a dict {facet tag: AirExchange} (with ``facet_tags``; facets of
            other tags are insulated: ``AirExchange(0.0, T)`` marks a face that exchanges only
            through contact), or None (insulated).
        facet_tags: the facet MeshTags of the mesh (for a dict ``air`` or ``fixed``).
        fixed: {facet tag: temperature °C}: Dirichlet conditions (validation cases; forming
            runs use exchange coefficients instead). The heat they bring in is the balance's
            ``fixed`` entry. A vertex on two fixed tags takes the value of the later one.
        solver: ``"cg"`` (CG + hypre BoomerAMG, relative tolerance ``rtol`` on the true
            residual, with a MUMPS LU fallback if CG fails, logged as a warning) or
            ``"direct"`` (MUMPS LU). PETSc options with the prefix ``heat_`` override the
            Krylov settings (``-heat_ksp_max_it 500``).
        rtol: relative tolerance of CG (the step's balance closes to about rtol × its flows).

    The exchange boundary Γ_x is the union of the ``air`` dict's facets, or the whole exterior
    boundary (``air`` an AirExchange or None). Its lumped areas S_n (:meth:`areas`) weigh the
    air and, at contact vertices, the tools. The unknown is :attr:`T`, a P1 Function named
    ``"temperature"``.

    Coupling (THEORY §16.6): once per increment, after the mechanics has converged and before
    the mesh update, ``step(dt, source=η_q s:ε̇ per cell, contact={tool: (dofs, h_c, T_tool)},
    nodal_heat=(dofs, β_f τ·Δv_t S_n))``, with :meth:`dofs_of_vertices` mapping the contact's
    mesh vertices to dofs and :meth:`ThermalMaterial.heat_share
    <fxcontact.heat.materials.ThermalMaterial.heat_share>` giving β_f. After a remesh: a new
    HeatProblem on the new mesh, then ``fxcontact.remesh.transfer.interpolate_from(old.T,
    new.T)`` (its :meth:`energy` counts from there).

    Attributes:
        T: the temperature (°C), P1, owned and ghost values current after every step.
        V: its function space.
        time: the sum of the steps' dt.
        n_owned: number of owned dofs (the local dofs are owned first, then ghosts).
        vertex_to_dof: (num local vertices,) the P1 dof of each mesh vertex.
    """

    def __init__(self, mesh, thermal: ThermalMaterial, initial_temperature, air=None,
                 facet_tags=None, fixed: dict[int, float] | None = None,
                 solver: str = "cg", rtol: float = 1e-10):
        self.comm = mesh.comm
        with checks_together(self.comm, "HeatProblem()") as agree:
            agree.update(solver=str(solver), rtol=float(rtol))
            if not isinstance(thermal, ThermalMaterial):
                raise ValueError(  # noqa: TRY004
                    f"thermal must be a ThermalMaterial, got {type(thermal).__name__}")
            if solver not in HEAT_SOLVERS:
                raise ValueError(f"solver must be one of {HEAT_SOLVERS}, got {solver!r}")
            if not (0 < float(rtol) < 1):
                raise ValueError(f"rtol must be in (0, 1), got {rtol!r}")
            if mesh.topology.cell_type not in (dolfinx.mesh.CellType.triangle,
                                               dolfinx.mesh.CellType.tetrahedron):
                raise ValueError("HeatProblem needs a simplex mesh (triangles or tetrahedra)")
            air_items = self._air_items(air, facet_tags)
            fixed_items = self._fixed_items(fixed, facet_tags)
            agree.update(air=repr(air_items), fixed=repr(fixed_items))
        self.mesh = mesh
        self.thermal = thermal
        self.solver = solver
        self.rtol = float(rtol)
        self.facet_tags = facet_tags
        self.air = air
        tdim = mesh.topology.dim
        mesh.topology.create_connectivity(tdim - 1, tdim)
        self.V = compat.function_space(mesh, ("Lagrange", 1))
        imap = self.V.dofmap.index_map
        self.n_owned = imap.size_local
        self.n_local = imap.size_local + imap.num_ghosts
        cmap = mesh.topology.index_map(tdim)
        self._n_cells = (cmap.size_local, cmap.size_local + cmap.num_ghosts)
        c2v = compat.cell_vertices(mesh)
        self.vertex_to_dof = np.empty(mesh.topology.index_map(0).size_local
                                      + mesh.topology.index_map(0).num_ghosts, dtype=np.int32)
        self.vertex_to_dof[c2v.ravel()] = compat.dofmap_array(self.V)[:, :c2v.shape[1]].ravel()
        self.T = dolfinx.fem.Function(self.V, name="temperature")
        self._set_initial(initial_temperature)
        self.time = 0.0
        self.steps = 0
        self._stored = 0.0
        self._consistent_mass = False      # private switch: the undershoot of THEORY §16.4
        self._forms(air_items, fixed_items)
        self._solvers()

    # ------------------------------------------------------------------ set-up
    @staticmethod
    def _air_items(air, facet_tags):
        """[(tag or None, AirExchange)] of the ``air`` argument (local checks)."""
        if air is None:
            return []
        if isinstance(air, AirExchange):
            return [(None, air)]
        if isinstance(air, dict):
            if facet_tags is None:
                raise ValueError("air given per facet tag needs facet_tags")
            for tag, a in air.items():
                if not isinstance(a, AirExchange):
                    raise ValueError(f"air[{tag!r}] must be an AirExchange, got "  # noqa: TRY004
                                     f"{type(a).__name__}")
            return [(int(t), a) for t, a in sorted(air.items())]
        raise ValueError(f"air must be an AirExchange, a dict {{facet tag: AirExchange}} or "
                         f"None, got {type(air).__name__}")

    @staticmethod
    def _fixed_items(fixed, facet_tags):
        if not fixed:
            return []
        if not isinstance(fixed, dict):
            msg = f"fixed must be a dict {{facet tag: temperature °C}}, got {type(fixed).__name__}"
            raise ValueError(msg)  # noqa: TRY004
        if facet_tags is None:
            raise ValueError("fixed temperatures need facet_tags")
        return [(int(t), float(check_temperature(f"fixed[{t}]", v))) for t, v in fixed.items()]

    def _set_initial(self, T0):
        """T from the initial temperature (checked on every rank together)."""
        n_own, n_loc = self.n_owned, self.n_local
        arr = self.T.x.array
        owned_only = False
        with checks_together(self.comm, "HeatProblem(initial_temperature)"):
            if callable(T0) or hasattr(T0, "function_space"):   # f(x) or a P1 Function
                self.T.interpolate(T0)
            else:
                a = np.asarray(T0, dtype=float)
                if a.ndim == 0:
                    arr[:] = float(a)
                elif a.shape in ((n_loc,), (n_own,)):
                    arr[:len(a)] = a
                    owned_only = len(a) != n_loc
                else:
                    raise ValueError(f"initial_temperature: a number, a callable, a P1 Function "
                                     f"or one value per local dof ({n_loc}, or {n_own} owned), "
                                     f"got shape {a.shape}")
            check_temperature("initial_temperature", arr[:n_own])
        if owned_only:
            self.T.x.scatter_forward()

    def _forms(self, air_items, fixed_items):
        msh = self.mesh
        V = self.V
        u, v = ufl.TrialFunction(V), ufl.TestFunction(V)
        self._k = dolfinx.fem.Function(V)       # nodal conductivity k(Tⁿ)
        self._rho_c = dolfinx.fem.Function(V)   # nodal ρc(Tⁿ) (consistent mass only)
        self._q = dolfinx.fem.Function(compat.function_space(msh, ("DG", 0)))
        dx = ufl.dx(domain=msh)
        self._a = compat.form(self._k * ufl.inner(ufl.grad(u), ufl.grad(v)) * dx)
        self._flux = compat.form(self._k * ufl.inner(ufl.grad(self.T), ufl.grad(v)) * dx)
        self._volume_form = compat.form(v * dx)
        self._source_form = compat.form(self._q * v * dx)
        self._mass_form = None
        if air_items and air_items[0][0] is not None:
            dsm = ufl.ds(domain=msh, subdomain_data=self.facet_tags)
            for tag, _ in air_items:        # every tag present somewhere (collective)
                facets_with_tags(msh, self.facet_tags, tag, "HeatProblem(air)")
            self._air = [(a, compat.form(v * dsm(tag)), tag) for tag, a in air_items]
            self._exchange_form = compat.form(sum((v * dsm(t) for t, _ in air_items[1:]),
                                                  v * dsm(air_items[0][0])))
        else:
            self._exchange_form = compat.form(v * ufl.ds(domain=msh))
            self._air = [(a, self._exchange_form, None) for _, a in air_items]
        self._boundary_form = compat.form(v * ufl.ds(domain=msh))
        # Dirichlet conditions, imposed on the increment: ΔT = T_fixed − Tⁿ
        self._bcs = []
        self._bc_dofs = np.zeros(0, dtype=np.int32)
        if fixed_items:
            fdim = msh.topology.dim - 1
            values = np.zeros(self.n_local)
            dofs = []
            for tag, value in fixed_items:
                facets = facets_with_tags(msh, self.facet_tags, tag, "HeatProblem(fixed)")
                d = np.asarray(compat.locate_dofs_topological(V, fdim, facets), dtype=np.int32)
                values[d] = value
                dofs.append(d)
            self._bc_dofs = np.unique(np.concatenate(dofs)).astype(np.int32)
            self._bc_values = values
            self._dT_bc = dolfinx.fem.Function(V)
            self._bcs = [dolfinx.fem.dirichletbc(self._dT_bc, self._bc_dofs)]
        self._bc_owned = self._bc_dofs[self._bc_dofs < self.n_owned]

    def _solvers(self):
        self._A = dolfinx.fem.petsc.create_matrix(self._a)
        self._Mc = None
        self._b = dolfinx.fem.petsc.create_vector(self._volume_form)
        self._x = self._b.duplicate()
        self._work = self._b.duplicate()
        self._diag = self._A.createVecLeft()
        self._ksp_cg = None
        if self.solver == "cg":
            ksp = PETSc.KSP().create(self.comm)
            ksp.setOptionsPrefix("heat_")
            ksp.setType(PETSc.KSP.Type.CG)
            ksp.getPC().setType(PETSc.PC.Type.HYPRE)
            ksp.getPC().setHYPREType("boomeramg")
            ksp.setNormType(PETSc.KSP.NormType.UNPRECONDITIONED)
            ksp.setTolerances(rtol=self.rtol, atol=0.0, max_it=1000)
            ksp.setFromOptions()
            self._ksp_cg = ksp
        self._ksp_lu = None     # made at its first use

    def _direct(self):
        if self._ksp_lu is None:
            ksp = PETSc.KSP().create(self.comm)
            ksp.setType(PETSc.KSP.Type.PREONLY)
            pc = ksp.getPC()
            pc.setType(PETSc.PC.Type.LU)
            pc.setFactorSolverType("mumps")
            self._ksp_lu = ksp
        return self._ksp_lu

    def close(self):
        """Destroy the PETSc objects of the problem (collective); the problem is then unusable."""
        for name in ("_A", "_Mc", "_b", "_x", "_work", "_diag", "_ksp_cg", "_ksp_lu"):
            obj = getattr(self, name, None)
            if obj is not None:
                obj.destroy()
                setattr(self, name, None)

    # ------------------------------------------------------------------ assembly helpers
    def _assemble(self, form) -> np.ndarray:
        """The local (owned and ghost) values of an assembled vector form (collective)."""
        w = self._work
        with w.localForm() as loc:
            loc.set(0.0)
        dolfinx.fem.petsc.assemble_vector(w, form)
        w.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        w.ghostUpdate(addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)
        with w.localForm() as loc:
            return loc.array_r.copy()

    def areas(self) -> np.ndarray:
        """(n_local,) lumped areas S_n = ∫ N_n dΓ (mm²) of the exchange boundary Γ_x on the
        current geometry, per local P1 dof (owned and ghost; 0 off Γ_x). The coefficient h of
        a tool at a vertex acts through S_n: H_nn = h S_n. Collective."""
        return self._assemble(self._exchange_form)

    def volumes(self) -> np.ndarray:
        """(n_local,) lumped volumes ∫ N_n dx (mm³) on the current geometry. Collective."""
        return self._assemble(self._volume_form)

    def capacity(self) -> np.ndarray:
        """(n_local,) lumped capacities M_n = ρc(T_n) ∫ N_n dx (N mm/K) on the current geometry
        at the current temperature. Collective."""
        return self.thermal.rho_c_at(self.T.x.array) * self.volumes()

    def dofs_of_vertices(self, vertices) -> np.ndarray:
        """The local P1 dofs of local mesh vertices (e.g. ``NodalContact.nodes``' vertices)."""
        return self.vertex_to_dof[np.asarray(vertices, dtype=np.int64)]

    def dof_coordinates(self) -> np.ndarray:
        """(n_local, 3) current positions of the local dofs (the mesh vertices)."""
        return self.V.tabulate_dof_coordinates()

    # ------------------------------------------------------------------ the step
    def step(self, dt: float, source=None, contact=None, nodal_heat=None) -> dict:
        """One backward-Euler step of length ``dt`` (s) on the current geometry (collective).

        Args:
            dt: the time step (s), > 0, the same on every rank.
            source: volumetric heat source q in N/(mm² s) = W/mm³ (η_q σ:ε̇ for plastic
                work), integrated as ∫ N_n q dx: a number, a DG0 Function of the mesh, or an
                array of the local cells' values (owned and ghost, or owned only).
            contact: exchange with tools at boundary vertices, replacing the air there: one
                tuple ``(vertices, h_c, T_tool)`` or ``(vertices, h_c, T_tool, areas)``; a list
                of such tuples (one per tool: named 0, 1, ... in the balance) or a dict
                {name: tuple}. ``vertices``: local P1 dofs (owned and ghost: a ghost entry is
                ignored, its owner must list it; see :meth:`dofs_of_vertices`), each on the
                exchange boundary; ``h_c`` in N/(mm s K), ``T_tool`` in °C: numbers or one
                value per vertex; ``areas`` (mm², per vertex): the areas through which h_c
                acts, instead of S_n of :meth:`areas` (e.g. the contact's own nodal areas).
                H_nn = Σ h_c S_n over the entries that list n. Every rank passes the same
                entries (names), possibly with no vertex.
            nodal_heat: ``(vertices, Q)``: heat flows into the body at vertices, N mm/s = mW
                (the workpiece's share of the friction power); ghost entries are ignored;
                repeated vertices add up.

        Returns:
            The step's energy balance (THEORY §16.5), the same on every rank, in N mm (= mJ) over the step,
            flows > 0 into the body: ``stored`` Σ M (Tⁿ⁺¹ − Tⁿ), ``generated`` (source),
            ``nodal``, ``air`` (convection), ``radiation``, ``tools`` ({name: exchange}),
            ``fixed`` (through the Dirichlet faces), ``residual`` = stored − the sum of the
            flows (at the linear solver's tolerance); and ``dt``, ``solver`` (``"cg"`` or
            ``"direct"``), ``iterations``, ``fallback`` (CG failed, MUMPS solved).
        """
        n, n_loc = self.n_owned, self.n_local
        with checks_together(self.comm, "HeatProblem.step()") as agree:
            dt = positive_dt(dt)
            src = cell_values(source, *self._n_cells)
            tools = contact_entries(contact, n_loc)
            nodal = nodal_entries(nodal_heat, n_loc)
            agree.update(dt=dt, source=src is not None, nodal=nodal is not None,
                         tools=repr([str(t.name) for t in tools]))
        Tn = self.T.x.array.copy()
        with checks_together(self.comm, "HeatProblem.step(): material at Tⁿ"):
            rho_c = self.thermal.rho_c_at(Tn)
            k = self.thermal.conductivity_at(Tn)
        vol = self.volumes()
        Sx = self.areas()
        self._check_on_boundary(tools, Sx)

        M = rho_c[:n] * vol[:n]
        Tn_own = Tn[:n]
        in_contact = np.zeros(n, dtype=bool)
        tool_terms = []     # per tool: (hS, hS T_tool) on the owned dofs
        for t in tools:
            own = t.dofs < n
            d = t.dofs[own]
            S = Sx[d] if t.areas is None else t.areas[own]
            hS = np.bincount(d, weights=t.h[own] * S, minlength=n)
            tool_terms.append((hS, np.bincount(d, weights=t.h[own] * S * t.temperature[own],
                                               minlength=n)))
            in_contact[d] = True
        air_hS, air_hST = np.zeros(n), np.zeros(n)
        rad_hS, rad_hST = np.zeros(n), np.zeros(n)
        for a, form, _ in self._air:
            S = Sx[:n] if form is self._exchange_form else self._assemble(form)[:n]
            S = np.where(in_contact, 0.0, S)
            air_hS += float(a.h) * S
            air_hST += float(a.h) * float(a.temperature) * S
            if float(a.emissivity) > 0:
                hr = a.radiation_coefficient(Tn_own) * S
                rad_hS += hr
                rad_hST += hr * float(a.temperature)
        hS = air_hS + rad_hS + sum((t[0] for t in tool_terms), np.zeros(n))
        hST = air_hST + rad_hST + sum((t[1] for t in tool_terms), np.zeros(n))
        Qv = np.zeros(n)
        if src is not None:
            values, owned_only = src
            self._q.x.array[:len(values)] = values
            if owned_only:
                self._q.x.scatter_forward()
            Qv = self._assemble(self._source_form)[:n]
        Qn = np.zeros(n)
        if nodal is not None:
            d, Q = nodal
            own = d < n
            Qn = np.bincount(d[own], weights=Q[own], minlength=n)

        # the system for ΔT
        self._k.x.array[:] = k
        KTn = self._assemble(self._flux)[:n]
        rhs = Qv + Qn + hST - hS * Tn_own - KTn
        diag = M / dt + hS
        diag[self._bc_owned] = 0.0      # Dirichlet rows: 1 on the diagonal (assemble_matrix)
        A = self._A
        A.zeroEntries()
        dolfinx.fem.petsc.assemble_matrix(A, self._a, self._bcs)
        A.assemble()
        self._diag.array[:] = diag
        A.setDiagonal(self._diag, addv=PETSc.InsertMode.ADD_VALUES)
        if self._consistent_mass:
            self._add_consistent_mass(A, rho_c, M, dt)
        b = self._b
        with b.localForm() as loc:
            loc.set(0.0)
        b.array[:] = rhs
        if self._bcs:
            self._dT_bc.x.array[:] = 0.0
            self._dT_bc.x.array[self._bc_dofs] = self._bc_values[self._bc_dofs] - Tn[
                self._bc_dofs]
            dolfinx.fem.petsc.apply_lifting(b, [self._a], [self._bcs])
            b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
            dolfinx.fem.petsc.set_bc(b, self._bcs)
        info = self._solve(A, b, self._x)
        dT = self._x.array_r[:n].copy()
        self.T.x.array[:n] = Tn_own + dT
        self.T.x.scatter_forward()

        # the balance (N mm over the step)
        T1 = self.T.x.array[:n]
        if self._consistent_mass:
            Mc_dT = self._mult(self._Mc, dT)
        else:
            Mc_dT = M * dT
        fixed = 0.0
        if self._bcs:
            KT1 = self._assemble(self._flux)[:n]
            r = Mc_dT / dt + KT1 - Qv - Qn - (hST - hS * T1)
            fixed = dt * float(np.sum(r[self._bc_owned]))
        terms = [float(np.sum(Mc_dT)), dt * float(np.sum(Qv)), dt * float(np.sum(Qn)),
                 dt * float(np.sum(air_hST - air_hS * T1)),
                 dt * float(np.sum(rad_hST - rad_hS * T1)), fixed]
        terms += [dt * float(np.sum(hST_t - hS_t * T1)) for hS_t, hST_t in tool_terms]
        total = np.array(terms)
        self.comm.Allreduce(MPI.IN_PLACE, total, op=MPI.SUM)
        out = dict(zip(BALANCE_KEYS[:-1], total[:6].tolist()))
        out["tools"] = {t.name: float(e) for t, e in zip(tools, total[6:])}
        out["residual"] = out["stored"] - (sum(total[1:6]) + sum(total[6:]))
        out.update(dt=dt, **info)
        self.time += dt
        self.steps += 1
        self._stored += out["stored"]
        return out

    def _check_on_boundary(self, tools, Sx):
        """ValueError on every rank if a contact vertex is off the exchange boundary (its S_n is
        0; with given areas: off the exterior boundary). Collective."""
        if not tools:
            return
        need = any(t.areas is not None for t in tools)
        Sb = self._assemble(self._boundary_form) if self.comm.allreduce(need, op=MPI.LOR) \
            else Sx
        bad = np.array([np.count_nonzero((Sx if t.areas is None else Sb)[t.dofs] <= 0)
                        for t in tools], dtype=np.int64)
        total = np.array([len(t.dofs) for t in tools], dtype=np.int64)
        both = np.concatenate([bad, total])
        self.comm.Allreduce(MPI.IN_PLACE, both, op=MPI.SUM)
        bad, total = both[:len(tools)], both[len(tools):]
        for t, nb, nt in zip(tools, bad, total):
            if nb:
                where = ("the exterior boundary" if t.areas is not None else
                         "the exchange boundary (the facets of the air tags, or the exterior "
                         "boundary)")
                raise ValueError(f"contact[{t.name!r}]: {nb} of the {nt} listed vertices (over "
                                 f"the ranks, ghosts included) are not on {where}: their "
                                 f"lumped area S_n is 0. Give local P1 dofs of boundary vertices "
                                 f"(HeatProblem.dofs_of_vertices maps mesh vertices)")

    def _solve(self, A, b, x) -> dict:
        x.set(0.0)
        if self._ksp_cg is not None:
            ksp = self._ksp_cg
            ksp.setOperators(A)
            ksp.solve(b, x)
            reason, its = ksp.getConvergedReason(), ksp.getIterationNumber()
            if reason > 0:
                return {"solver": "cg", "iterations": its, "fallback": False}
            log.warning("heat: CG did not converge (reason %d after %d iterations): solving "
                        "with MUMPS LU instead", reason, its)
            x.set(0.0)
        ksp = self._direct()
        ksp.setOperators(A)
        ksp.solve(b, x)
        reason = ksp.getConvergedReason()
        if reason <= 0:
            raise RuntimeError(f"heat: the direct solve failed (KSP reason {reason})")
        return {"solver": "direct", "iterations": 1, "fallback": self._ksp_cg is not None}

    # ------------------------------------------------------------------ consistent mass
    def _add_consistent_mass(self, A, rho_c, M, dt):
        """Private: A += M_c/dt − M/dt (the consistent capacity instead of the lumped one, to
        show the undershoot the lumping removes; THEORY §16.4)."""
        if self._mass_form is None:
            u, v = ufl.TrialFunction(self.V), ufl.TestFunction(self.V)
            self._mass_form = compat.form(self._rho_c * u * v * ufl.dx(domain=self.mesh))
            self._Mc = dolfinx.fem.petsc.create_matrix(self._mass_form)
        self._rho_c.x.array[:] = rho_c
        Mc = self._Mc
        Mc.zeroEntries()
        dolfinx.fem.petsc.assemble_matrix(Mc, self._mass_form, self._bcs, diagonal=0.0)
        Mc.assemble()
        A.axpy(1.0 / dt, Mc, structure=PETSc.Mat.Structure.SAME_NONZERO_PATTERN)
        d = -M / dt
        d[self._bc_owned] = 0.0
        self._diag.array[:] = d
        A.setDiagonal(self._diag, addv=PETSc.InsertMode.ADD_VALUES)

    def _mult(self, A, values) -> np.ndarray:
        self._diag.array[:] = values
        y = self._diag.duplicate()
        A.mult(self._diag, y)
        out = y.array_r.copy()
        y.destroy()
        return out

    # ------------------------------------------------------------------ results
    def energy(self) -> float:
        """The heat stored since the problem was made, N mm: the sum of the steps' ``stored``
        (Σ M (Tⁿ⁺¹ − Tⁿ) with each step's capacity and geometry). Local (the same on every
        rank)."""
        return self._stored

    def min_temperature(self) -> float:
        """The lowest nodal temperature (°C). Collective."""
        return self.comm.allreduce(float(np.min(self.T.x.array[:self.n_owned], initial=math.inf)),
                                   op=MPI.MIN)

    def max_temperature(self) -> float:
        """The highest nodal temperature (°C). Collective."""
        return self.comm.allreduce(float(np.max(self.T.x.array[:self.n_owned],
                                                initial=-math.inf)), op=MPI.MAX)

    def mean_temperature(self) -> float:
        """The volume mean Σ V_n T_n / Σ V_n with the lumped volumes V_n = ∫ N_n dx (°C).
        Collective."""
        vol = self.volumes()[:self.n_owned]
        s = np.array([float(np.dot(vol, self.T.x.array[:self.n_owned])), float(vol.sum())])
        self.comm.Allreduce(MPI.IN_PLACE, s, op=MPI.SUM)
        return s[0] / s[1]

