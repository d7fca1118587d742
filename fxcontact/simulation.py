"""The increment loop: updated-Lagrangian (or small-strain) time stepping with cut-back.

One increment ``t → t + dt`` (THEORY §1.5): boundary values and tools are taken at ``t + dt``,
contributors prepare (explicit projections…), Newton starts from the previous increment's velocity
(predictor), and on success the geometry (or the displacement), the cumulative equivalent strain,
the history and the outputs are updated. A failed Newton solve is retried with ``dt`` halved, at
most ``max_cutbacks`` times, then :class:`IncrementError` names the time; everything written so far
stays on disk.
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass
from typing import Callable, Dict, List, Optional

import numpy as np
import ufl
from mpi4py import MPI
from petsc4py import PETSc

import dolfinx
import dolfinx.fem
import dolfinx.fem.petsc

from fxcontact import compat, console
from fxcontact.kinematics import CartesianUpdate
from fxcontact.materials import Material
from fxcontact.petsc import NonlinearProblem
from fxcontact.solver import NewtonSolver, SolveInfo, SolverOptions
from fxcontact.spaces import MixedSpace, facets_with_tags, set_function_value, velocity_bc

__all__ = ["Simulation", "IncrementError", "IncrementResult"]

log = logging.getLogger(__name__)


class IncrementError(RuntimeError):
    """Newton failed at some time even after the allowed cut-backs."""

    def __init__(self, t: float, dt: float, message: str):
        super().__init__(f"increment starting at t = {t:.6g} failed (last dt = {dt:.3g}): "
                         f"{message}. Results up to t = {t:.6g} are written.")
        self.t = t
        self.dt = dt


@dataclass
class IncrementResult:
    """Outcome of one accepted increment (also one row of the history)."""

    row: Dict[str, float]
    info: SolveInfo


@dataclass
class _BC:
    bc: object
    g: object
    value: object
    gdim: Optional[int]


def _time_value(value, t):
    """A BC value at time t: constants pass through, f(t) is called, f(x) (vectorised) too."""
    if callable(value):
        try:
            import inspect
            params = inspect.signature(value).parameters
        except (TypeError, ValueError):
            params = {}
        if "t" in params and len(params) == 1:
            return value(t)
        if "t" in params:
            return lambda x: value(x, t)
        return value
    return value


class Simulation:
    """Time stepping of a forming problem with nodal contributors (contact, springs…).

    Args:
        space: the :class:`MixedSpace`.
        material: a :class:`~fxcontact.materials.Material`.
        solver_options: Newton settings.
        kinematics: configuration update (Cartesian by default; cylindrical for rings).
        extra_residual: optional ``f(v, p, w, q) -> ufl.Form`` added to the residual
            (tractions, body forces).
        output_dir: where the VTK series, the CSV history and pictures go (None: no files).
        name: basename of the outputs.
        output_every: write the VTK series every n increments.
        progress: show a tqdm progress bar (rank 0 only), unless the console was set up quiet
            (:func:`fxcontact.console.configure_logging`).
    """

    def __init__(self, space: MixedSpace, material: Material,
                 solver_options: Optional[SolverOptions] = None, kinematics=None,
                 extra_residual: Optional[Callable] = None, output_dir: Optional[str] = None,
                 name: str = "result", output_every: int = 1, progress: bool = True):
        if not isinstance(material, Material):
            raise ValueError(f"material must be a fxcontact material, got {material!r}")
        if output_every < 1:
            raise ValueError("output_every must be >= 1")
        self.space = space
        self.mesh = space.mesh
        self.comm = space.mesh.comm
        self.material = material
        self.solver_options = solver_options or SolverOptions()
        self.kinematics = kinematics or CartesianUpdate()
        self.extra_residual = extra_residual
        self.output_dir = output_dir
        self.name = name
        self.output_every = int(output_every)
        self.progress = progress
        self.t = 0.0
        self.increment = 0
        self._bcs: List[_BC] = []
        self.contributors: List = []
        self.history: List[Dict[str, float]] = []
        self._built = False
        W = space.W
        self.w = dolfinx.fem.Function(W, name="solution")
        self.w_prev = dolfinx.fem.Function(W)
        self.dt_c = dolfinx.fem.Constant(self.mesh, PETSc.ScalarType(1.0))
        self.u = dolfinx.fem.Function(space.V, name="displacement") if material.small_strain \
            else None
        # output fields
        self.velocity = dolfinx.fem.Function(space.P1, name="velocity")
        self.pressure = dolfinx.fem.Function(space.Q, name="pressure")
        self.strain = dolfinx.fem.Function(space.DG0, name="equivalent_strain")
        self.strain_rate = dolfinx.fem.Function(space.DG0, name="equivalent_strain_rate")
        self.displacement_out = dolfinx.fem.Function(space.P1, name="displacement") \
            if material.small_strain else None
        self._p1_vertex = self._p1_vertex_dofs()
        self._x_ref = self.mesh.geometry.x.copy()
        self._writer = None
        self._history_writer = None
        self._reactions: Dict[str, np.ndarray] = {}

    # ------------------------------------------------------------------------ set-up
    def _p1_vertex_dofs(self) -> np.ndarray:
        c2v = compat.cell_vertices(self.mesh)
        d = compat.dofmap_array(self.space.P1)
        out = np.empty(self.space.vertex_dofs.shape[0], dtype=np.int32)
        out[c2v.ravel()] = d[:, : c2v.shape[1]].ravel()
        return out

    def facets(self, facet_tags, tags) -> np.ndarray:
        return facets_with_tags(self.mesh, facet_tags, tags)

    def add_velocity_bc(self, facets: np.ndarray, value, component: Optional[int] = None):
        """Prescribe the velocity (or one component) on facets.

        ``value`` is a constant (scalar for a component, gdim-vector otherwise), a function of
        time ``f(t)``, a function of space ``f(x)`` (dolfinx interpolation signature) or of both
        ``f(x, t)``; it is evaluated at the end of each increment (t + dt).
        """
        self._check_not_built()
        v0 = _time_value(value, 0.0)
        bc, g = velocity_bc(self.space, facets, v0, component)
        self._bcs.append(_BC(bc, g, value, self.space.gdim if component is None else None))
        return bc

    def add_reaction(self, name: str, facets: np.ndarray):
        """Record, each increment, the force exerted on the body through the Dirichlet dofs of
        ``facets`` (history columns ``{name}_x``, ``{name}_y``, ``{name}_z``), computed on the
        configuration of the increment (before the geometry update)."""
        self._reactions[name] = np.asarray(facets, dtype=np.int32)

    def add_contributor(self, contributor):
        """Register a nodal contributor (``evaluate``, ``stable``; optional ``begin_increment``,
        ``end_increment``, ``diagnostics``, ``output_fields``)."""
        self._check_not_built()
        self.contributors.append(contributor)
        return contributor

    def _check_not_built(self):
        if self._built:
            raise RuntimeError("the simulation is already set up: add conditions before run()")

    def _build(self):
        if self._built:
            return
        sp = self.space
        v, p = ufl.split(self.w)
        wt, q = ufl.TestFunctions(sp.W)
        F = self.material.residual(v, p, wt, q, sp.dx, self.dt_c, self.u)
        if self.extra_residual is not None:
            F = F + self.extra_residual(v, p, wt, q)
        self.F_ufl = F
        self.problem = NonlinearProblem(F, self.w, [b.bc for b in self._bcs],
                                        contributors=self.contributors)
        fs_is = self.fieldsplit_is() if self.solver_options.uses_fieldsplit else None
        self.solver = NewtonSolver(self.problem, self.solver_options, fs_is)
        # start-up problem: the linearised material without contributors gives the first guess
        # when there is no previous velocity (a power law from v = 0 converges badly)
        lin_mat = self.material.linearized()
        self._startup = None
        if lin_mat is not self.material:
            F0 = lin_mat.residual(v, p, wt, q, sp.dx, self.dt_c, self.u)
            if self.extra_residual is not None:
                F0 = F0 + self.extra_residual(v, p, wt, q)
            opts = SolverOptions(**{**self.solver_options.__dict__, "prefix":
                                    self.solver_options.prefix + "startup_"})
            self._startup = NewtonSolver(NonlinearProblem(F0, self.w, [b.bc for b in self._bcs]),
                                         opts, fs_is)
        # cell averages of the strain rate, volume
        q0 = ufl.TestFunction(sp.DG0)
        epsd = self._strain_rate_expr(v)
        self._rate_form = compat.form(epsd * q0 * sp.dx)
        self._cellvol_form = compat.form(q0 * sp.dx)
        self._volume_form = compat.form(dolfinx.fem.Constant(self.mesh, 1.0) * sp.dx)
        self._div_form = compat.form(ufl.div(v) * sp.dx)
        self._mean_rate_form = compat.form(epsd * sp.dx)
        self._built = True
        if self.output_dir is not None:
            from fxcontact.io import HistoryWriter, SeriesWriter
            self._writer = SeriesWriter(self.comm, self.output_dir, self.name)
            self._history_writer = HistoryWriter(self.comm, self.output_dir, self.name)
            self._write_fields()

    def _strain_rate_expr(self, v):
        e = ufl.sym(ufl.grad(v))
        d = self.space.gdim
        de = e - ufl.tr(e) / d * ufl.Identity(d)
        return ufl.sqrt(2.0 / 3.0 * ufl.inner(de, de))

    def fieldsplit_is(self):
        sp = self.space
        nown = sp.num_owned_dofs
        imap = sp.W.dofmap.index_map
        def to_is(dofs):
            dofs = dofs[dofs < nown]
            return PETSc.IS().createGeneral(
                (imap.local_range[0] + np.sort(dofs)).astype(np.int32), comm=self.comm)
        return to_is(sp.V_to_W), to_is(sp.Q_to_W)

    # ------------------------------------------------------------------------ state
    def vertex_positions(self) -> np.ndarray:
        """(num_local_vertices, gdim) vertex positions at the start of the increment."""
        sp = self.space
        x = self.mesh.geometry.x[sp.vertex_geometry, : sp.gdim].copy()
        if self.u is not None:
            x += self._vertex_displacement()
        return x

    def _vertex_displacement(self) -> np.ndarray:
        sp = self.space
        vd = sp.vertex_dofs
        # u lives on the collapsed velocity space: map W dofs -> V dofs
        W_to_V = self._W_to_V()
        return self.u.x.array[W_to_V[vd]]

    def _W_to_V(self) -> np.ndarray:
        if not hasattr(self, "_w2v"):
            sp = self.space
            n = sp.W.dofmap.index_map.size_local + sp.W.dofmap.index_map.num_ghosts
            m = np.full(n, -1, dtype=np.int64)
            m[sp.V_to_W] = np.arange(len(sp.V_to_W))
            self._w2v = m
        return self._w2v

    def volume(self) -> float:
        self._build()
        return self.comm.allreduce(dolfinx.fem.assemble_scalar(self._volume_form), op=MPI.SUM)

    def mean_strain_rate(self) -> float:
        """Volume average of the (un-regularised) equivalent strain rate of the current w."""
        self._build()
        num = self.comm.allreduce(dolfinx.fem.assemble_scalar(self._mean_rate_form), op=MPI.SUM)
        return num / self.volume()

    def divergence_integral(self) -> float:
        """∫ div v dx of the current solution (discrete incompressibility check)."""
        self._build()
        return self.comm.allreduce(dolfinx.fem.assemble_scalar(self._div_form), op=MPI.SUM)

    def reaction_force(self, facets: np.ndarray) -> np.ndarray:
        """Force exerted *on the body* through the Dirichlet dofs of ``facets`` (gdim,).

        Computed as the sum of the (bc-free) UFL residual entries (internal forces) at the
        velocity dofs of the facets, owned dofs only, summed over ranks, on the *current*
        geometry (use :meth:`add_reaction` for the value on the increment's configuration).
        """
        self._build()
        sp = self.space
        b = dolfinx.fem.petsc.assemble_vector(self.problem.L)
        b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        arr = b.getArray(readonly=True)
        fdim = self.mesh.topology.dim - 1
        out = np.zeros(sp.gdim)
        nown = sp.num_owned_dofs
        for k in range(sp.gdim):
            Wk = sp.W.sub(0).sub(k)
            Vk, _ = compat.collapse(Wk)
            dofs = compat.locate_dofs_topological((Wk, Vk), fdim, facets)[0]
            dofs = dofs[dofs < nown]
            out[k] = np.sum(arr[dofs])
        b.destroy()
        return self.comm.allreduce(out, op=MPI.SUM)

    # ------------------------------------------------------------------------ stepping
    def _set_bc_values(self, t: float):
        for b in self._bcs:
            set_function_value(b.g, _time_value(b.value, t), b.gdim)

    def _try_increment(self, dt: float) -> SolveInfo:
        t_new = self.t + dt
        self.dt_c.value = dt
        self._set_bc_values(t_new)
        # predictor: previous increment's velocity, with the new boundary values
        self.w.x.array[:] = self.w_prev.x.array
        dolfinx.fem.petsc.set_bc(self.w.vector, self.problem.bcs)
        self.w.x.scatter_forward()
        if self._startup is not None and not np.any(self.w_prev.x.array):
            self.comm.barrier()
            info0 = self._startup.solve()
            log.log(logging.DEBUG if info0.converged else logging.INFO,
                    "start-up (linearised material) solve: %d iterations, converged=%s",
                    info0.iterations, info0.converged)
            if not info0.converged:  # keep the zero guess
                self.w.x.array[:] = 0.0
                dolfinx.fem.petsc.set_bc(self.w.vector, self.problem.bcs)
                self.w.x.scatter_forward()
        x_t = self.vertex_positions()
        for c in self.contributors:
            if hasattr(c, "begin_increment"):
                c.begin_increment(self, self.t, dt, x_t)
        return self.solver.solve()

    def _commit(self, dt: float, info: SolveInfo) -> Dict[str, float]:
        sp = self.space
        w = self.w
        w.x.scatter_forward()
        x_t = self.vertex_positions()
        v_vert = w.x.array[sp.vertex_dofs]
        # cumulative strain and strain rate (cell averages, before the geometry moves)
        rate = self._cell_average(self._rate_form)
        self.strain_rate.x.array[:] = rate
        self.strain.x.array[:] += dt * rate
        reactions = {name: self.reaction_force(f) for name, f in self._reactions.items()}
        div_v = self.divergence_integral()
        # geometry / displacement update with the same map as the contact condition
        X = self.kinematics.positions(x_t, v_vert, dt)
        if self.u is None:
            g = self.mesh.geometry.x
            g[sp.vertex_geometry, : sp.gdim] = X
        else:
            self.u.x.array[:] += dt * w.x.array[sp.V_to_W]
            self.u.x.scatter_forward()
        self.t += dt
        self.increment += 1
        self.w_prev.x.array[:] = w.x.array
        row = {"increment": self.increment, "time": self.t, "dt": dt,
               "newton_iterations": info.iterations,
               "residual": info.residual_norms[-1] if info.residual_norms else float("nan")}
        for k in ("assembly", "linear_solve", "contact", "other", "total"):
            row[f"wall_{k}"] = info.times.get(k, 0.0)
        row["volume"] = self.volume()
        row["div_v"] = div_v
        for name, F in reactions.items():
            for k, c in enumerate("xyz"[: sp.gdim]):
                row[f"{name}_{c}"] = F[k]
        for c in self.contributors:
            if hasattr(c, "end_increment"):
                c.end_increment(self, dt)
            if hasattr(c, "diagnostics"):
                row.update(c.diagnostics())
        return row

    def _cell_average(self, frm) -> np.ndarray:
        b1 = dolfinx.fem.petsc.assemble_vector(frm)
        b2 = dolfinx.fem.petsc.assemble_vector(self._cellvol_form)
        for b in (b1, b2):
            b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
            b.ghostUpdate(addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)
        with b1.localForm() as l1, b2.localForm() as l2:
            out = l1.array / l2.array
        b1.destroy()
        b2.destroy()
        return out

    def step(self, dt: float, max_cutbacks: int = 5, min_dt: float = 0.0) -> IncrementResult:
        """Advance by one increment of (at most) ``dt``, halving it on Newton failure (at most
        ``max_cutbacks`` times, and never below ``min_dt``)."""
        if not (isinstance(dt, (int, float, np.floating)) and math.isfinite(dt) and dt > 0):
            raise ValueError(f"dt must be a finite number > 0, got {dt!r}")
        if max_cutbacks < 0:
            raise ValueError("max_cutbacks must be >= 0")
        self._build()
        trial = float(dt)
        msg = ""
        msgs: List[str] = []
        failed_its = 0
        t_first = time.perf_counter()
        for k in range(max_cutbacks + 1):
            if k > 0 and trial < min_dt * (1.0 - 1e-12):
                msg += f"; dt would fall below the smallest allowed {min_dt:.3g}"
                break
            t0 = time.perf_counter()
            info = self._try_increment(trial)
            fb = self.solver_options.line_search_fallback
            if not info.converged and fb and fb != self.solver_options.line_search \
                    and not self.problem.error:
                # second attempt at the same dt with the fallback line search
                log.info("t = %.6g: Newton failed with the %s line search (%s); retrying dt = "
                         "%.3g with the %s line search", self.t, self.solver_options.line_search,
                         info.message, trial, fb)
                failed_its += info.iterations
                msgs.append(info.message)
                self.solver.set_line_search(fb)
                try:
                    info = self._try_increment(trial)
                finally:
                    self.solver.set_line_search(self.solver_options.line_search)
            if info.converged:
                row = self._commit(trial, info)
                row["cutbacks"] = k
                # Newton iterations of the accepted attempt plus those of the failed attempts
                row["newton_iterations_all"] = info.iterations + failed_its
                row["wall_increment"] = time.perf_counter() - t0
                row["wall_increment_all"] = time.perf_counter() - t_first
                self._record(row)
                return IncrementResult(row, info)
            msg = info.message
            msgs.append(msg)
            failed_its += info.iterations
            log.warning("t = %.6g: Newton failed with dt = %.3g (%s); retrying with dt/2",
                        self.t, trial, msg)
            trial *= 0.5
        earlier = [m for m in dict.fromkeys(msgs[:-1]) if m != msgs[-1]] if msgs else []
        if earlier:
            msg += f" (earlier attempts: {' | '.join(earlier)})"
        raise IncrementError(self.t, trial * 2, msg)

    def _record(self, row):
        self.history.append(row)
        if self._history_writer is not None:
            self._history_writer.write(row)
        if self._writer is not None and self.increment % self.output_every == 0:
            self._write_fields()

    def _update_output_fields(self):
        sp = self.space
        gd = sp.gdim
        varr = self.velocity.x.array.reshape(-1, gd)
        varr[self._p1_vertex] = self.w.x.array[sp.vertex_dofs]
        self.pressure.x.array[:] = self.w.x.array[sp.Q_to_W]
        if self.u is not None:
            self.displacement_out.x.array.reshape(-1, gd)[self._p1_vertex] = \
                self._vertex_displacement()

    def output_functions(self) -> list:
        fields = [self.velocity, self.pressure, self.strain, self.strain_rate]
        if self.displacement_out is not None:
            fields.append(self.displacement_out)
        for c in self.contributors:
            if hasattr(c, "output_fields"):
                fields.extend(c.output_fields())
        return fields

    def _write_fields(self):
        self._update_output_fields()
        for c in self.contributors:
            if hasattr(c, "update_output_fields"):
                c.update_output_fields()
        self._writer.write(self.output_functions(), self.t)

    def run(self, t_end: float, dt: float, max_cutbacks: int = 5,
            callback: Optional[Callable] = None, close: bool = True) -> List[Dict[str, float]]:
        """Advance to ``t_end`` with increments ``dt`` (cut back on failure, then grown back).

        An increment that fails is retried with dt halved, at most ``max_cutbacks`` times and
        never below ``dt / 2**max_cutbacks``: a run whose sub-increments keep failing stops with
        an :class:`IncrementError` instead of creeping on with ever smaller steps.

        Returns the history (one dict per increment). Outputs are flushed after each increment
        and closed on error, and at the end unless ``close=False`` (to continue with another
        ``run``).
        """
        if not (math.isfinite(t_end) and t_end > self.t):
            raise ValueError(f"t_end must be > current time {self.t}, got {t_end!r}")
        if not (isinstance(dt, (int, float, np.floating)) and math.isfinite(dt) and dt > 0):
            raise ValueError(f"dt must be a finite number > 0, got {dt!r}")
        self._build()
        bar = None
        if self.progress and console.progress_enabled() and self.comm.rank == 0:
            from tqdm import tqdm
            bar = tqdm(total=t_end - self.t, desc=self.name, unit="s", leave=False,
                       bar_format="{l_bar}{bar}| {n:.4g}/{total:.4g} s "
                                  "[{elapsed}<{remaining}{postfix}]")
        n0, t0, wall0 = len(self.history), self.t, time.perf_counter()
        cur = dt
        eps = 1e-9 * dt
        try:
            while self.t < t_end - eps:
                step = min(cur, t_end - self.t)
                res = self.step(step, max_cutbacks, min_dt=dt * 0.5 ** max_cutbacks)
                if bar is not None:  # one refresh per increment (set_postfix would add one)
                    bar.set_postfix(newton=res.info.iterations, refresh=False)
                    bar.update(res.row["dt"])
                # after a cut-back, grow back towards the nominal dt
                cur = min(dt, 2.0 * res.row["dt"]) if res.row["cutbacks"] else dt
                if callback is not None:
                    callback(self, res)
        except BaseException:
            self.close()
            raise
        finally:
            if bar is not None:
                bar.close()
        rows = self.history[n0:]
        log.info("%s: t = %.4g -> %.4g in %d increments (%d cut-backs), %d Newton iterations, "
                 "%.1f s", self.name, t0, self.t, len(rows), sum(r["cutbacks"] for r in rows),
                 sum(r["newton_iterations_all"] for r in rows), time.perf_counter() - wall0)
        if close:
            self.close()
        return self.history

    def close(self):
        if self._writer is not None:
            self._writer.close()
            self._writer = None
        if self._history_writer is not None:
            self._history_writer.close()
            self._history_writer = None
