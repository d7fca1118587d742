"""Nodal penalty contact against rigid tools with four time-integration schemes (THEORY §2–§3).

=================  ==================================  =========================  ============
scheme             projection of …                     onto the tool at …         when
=================  ==================================  =========================  ============
explicit           x^t                                 t                          per increment
quasi-implicit     x^t + dt·v̂ (v̂: previous velocity)   t + dt                     per increment
implicit           X(v_k) (current iterate)            t + dt                     every Newton it.
implicit-exact     X(v) with exact ∇h and ∇²h          t + dt                     every evaluation
=================  ==================================  =========================  ============

``implicit`` uses the Gauss–Newton tangent (no curvature term); ``implicit-exact`` adds the gap
Hessian (and, for the cylindrical update, the second derivatives of X). Their residuals are the
same: the exact gradient of the end-of-increment penalty. The curvature term ρS[h]₊∇²h is
negative in the tangential directions of a convex tool and grows with the penetration: on the
first iterates of an increment (predictor penetrations far above the converged ones) it can
exceed the structural stiffness and make the tangent indefinite, and Newton stalls. So
``implicit-exact`` uses the Gauss–Newton tangent until the active set has settled (``stable()``
true at the previous iterate, collective) and the exact tangent from then on, which keeps the
quadratic end of the convergence. Each node is handled against the tool
it penetrates most. Convergence additionally requires an unchanged active set (and, for implicit
schemes, unchanged projected features of faceted tools).

Bad states are errors, raised on every rank at once: a node initially buried deeper than
``max_initial_penetration`` (default half the local element size), or a node in contact whose
projection is undefined (exactly on a tool axis: flag 2).
"""

from __future__ import annotations

import logging
import math
import zlib
from typing import Dict, List, Optional

import numpy as np
from mpi4py import MPI

import dolfinx.fem

from fxcontact import compat
from fxcontact.contact.boundary import ContactBoundary
from fxcontact.contact.penalty import penalty_kernel, penalty_kernel_numpy
from fxcontact.kinematics import CartesianUpdate
from fxcontact.materials import LinearElastic, NortonHoff
from fxcontact.petsc import ContributorError, NodalTerms
from fxcontact.tools.base import Tool

__all__ = ["NodalContact", "SCHEMES", "penalty_from_beta"]

log = logging.getLogger(__name__)

SCHEMES = ("explicit", "quasi-implicit", "implicit", "implicit-exact")

#: β used when neither ``penalty`` nor ``beta`` is given (THEORY §2.5 recommends 1e2–1e4).
DEFAULT_BETA = 1e3


def penalty_from_beta(material, beta: float, element_size: float, strain_rate: float = None,
                      dt: float = None) -> float:
    """Penalty ρ from the dimensionless β of THEORY §2.5.

    Norton–Hoff: ρ = β η / h_e with η = K (√3 ε̄̇)^(m-1) at a representative ``strain_rate``.
    Linear elastic: ρ = β dt E* / h_e (β_el of §2.5), E* = E/(1-ν²).
    """
    if not (beta > 0 and element_size > 0):
        raise ValueError("beta and element_size must be > 0")
    if isinstance(material, NortonHoff):
        if strain_rate is None or not strain_rate > 0:
            raise ValueError("a representative strain_rate > 0 is needed for a Norton-Hoff "
                             "penalty from beta")
        return beta * material.viscosity(strain_rate) / element_size
    if isinstance(material, LinearElastic):
        if dt is None or not dt > 0:
            raise ValueError("dt > 0 is needed for an elastic penalty from beta")
        return beta * dt * material.plane_strain_modulus / element_size
    raise ValueError(f"no beta rule for material {material!r}")


def _pad3(x: np.ndarray) -> np.ndarray:
    if x.shape[1] == 3:
        return np.ascontiguousarray(x)
    out = np.zeros((x.shape[0], 3))
    out[:, : x.shape[1]] = x
    return out


class NodalContact:
    """Nodal penalty contact of a :class:`ContactBoundary` against rigid tools.

    Args:
        boundary: the contact nodes.
        tools: one tool or a sequence of tools.
        scheme: one of :data:`SCHEMES`.
        penalty: ρ [stress/velocity]; or give ``beta`` (THEORY §2.5) with ``strain_rate``
            (Norton–Hoff) — elastic materials take dt from the increment.
        beta: dimensionless penalty, used when ``penalty`` is None.
        element_size: h_e for ``beta`` and the burial limit (default: from the nodal areas).
        strain_rate: representative strain rate for a Norton–Hoff ``beta``.
        sticky_gap: active-set stabilisation (THEORY §3.6): a node active at an earlier
            iteration of the increment keeps its tangent while its gap is below this distance
            (0 disables).
        max_initial_penetration: burial limit at the start of an increment (default half the
            local element size); deeper nodes raise an error.
        gap_stiffness: alternative to ``penalty``/``beta``: a stiffness k [stress/length] on the
            end-of-increment gap, ρ = k·dt at each increment, so that the penalty penetration
            p/k does not depend on the time step.
        name: label used in history columns.
        backend: "numba" or "numpy" (reference twin of the kernel, for testing).
    """

    def __init__(self, boundary: ContactBoundary, tools, scheme: str = "implicit",
                 penalty: Optional[float] = None, beta: Optional[float] = None,
                 element_size: Optional[float] = None, strain_rate: Optional[float] = None,
                 sticky_gap: float = 0.0, max_initial_penetration: Optional[float] = None,
                 gap_stiffness: Optional[float] = None, name: str = "contact",
                 backend: str = "numba"):
        if scheme not in SCHEMES:
            raise ValueError(f"unknown contact scheme {scheme!r}; choose one of {SCHEMES}")
        tools = [tools] if isinstance(tools, Tool) else list(tools)
        if not tools or not all(isinstance(t, Tool) for t in tools):
            raise ValueError("tools must be a Tool or a non-empty sequence of Tools")
        if scheme == "implicit-exact" and not all(t.has_hessian for t in tools):
            raise ValueError("implicit-exact needs tools that provide the gap Hessian")
        if gap_stiffness is not None:
            if penalty is not None or beta is not None:
                raise ValueError("give only one of penalty, beta and gap_stiffness")
            if not (math.isfinite(gap_stiffness) and gap_stiffness > 0):
                raise ValueError(f"gap_stiffness must be finite and > 0, got {gap_stiffness!r}")
        elif penalty is None and beta is None:
            beta = DEFAULT_BETA
        self.gap_stiffness = gap_stiffness
        if penalty is not None and not (math.isfinite(penalty) and penalty > 0):
            raise ValueError(f"penalty must be finite and > 0, got {penalty!r}")
        if beta is not None and not (math.isfinite(beta) and beta > 0):
            raise ValueError(f"beta must be finite and > 0, got {beta!r}")
        if not (math.isfinite(sticky_gap) and sticky_gap >= 0):
            raise ValueError("sticky_gap must be >= 0")
        if backend not in ("numba", "numpy"):
            raise ValueError("backend must be 'numba' or 'numpy'")
        self.boundary = boundary
        self.tools: List[Tool] = tools
        self.scheme = scheme
        self.name = name
        self.gdim = boundary.gdim
        self._penalty, self.beta = penalty, beta
        self.strain_rate = strain_rate
        self.sticky_gap = float(sticky_gap)
        self.kernel = penalty_kernel if backend == "numba" else penalty_kernel_numpy
        comm = boundary.comm
        if element_size is None:
            a = boundary.areas
            loc = np.sqrt(2.0 * a) if self.gdim == 3 else a
            s = comm.allreduce(float(np.sum(loc)), op=MPI.SUM)
            n = comm.allreduce(len(a), op=MPI.SUM)
            element_size = s / max(n, 1)
        if not element_size > 0:
            raise ValueError("element_size must be > 0")
        self.element_size = float(element_size)
        self.max_initial_penetration = (0.5 * self.element_size if max_initial_penetration
                                        is None else float(max_initial_penetration))
        self.rho = penalty
        self.sim = None
        self.t = 0.0
        self.dt = 1.0
        n = len(boundary)
        self._h = np.zeros(n)
        self._tool = np.zeros(n, dtype=np.int32)
        self._feature = np.zeros(n, dtype=np.int64)
        self._status_prev = None
        self._settled = False
        self._changes = (0, 0)
        self._fingerprint = ()
        self._ever_active = np.zeros(n, dtype=bool)
        self._fallbacks = 0
        self._fallbacks_all = 0
        self._fields = None

    # ------------------------------------------------------------------ set-up per increment
    def _resolve_penalty(self, sim, dt):
        if self.gap_stiffness is not None:
            return self.gap_stiffness * dt
        if self._penalty is not None:
            return self._penalty
        if isinstance(sim.material, NortonHoff):
            if self.strain_rate is None:
                # representative strain rate: mean of the first increment's initial guess
                rate = sim.mean_strain_rate()
                if not rate > 1e-12:
                    # rigid initial guess: tool speed over the body's size
                    speed = max(float(np.max(np.linalg.norm(
                        tool.velocity(_pad3(self.x_t), self.t), axis=1), initial=0.0))
                        for tool in self.tools)
                    speed = self.boundary.comm.allreduce(speed, op=MPI.MAX)
                    size = sim.volume() ** (1.0 / self.gdim)
                    rate = speed / size
                if not rate > 0:
                    raise ValueError("cannot estimate a representative strain rate for the "
                                     "penalty (rigid initial velocity and static tools): give "
                                     "strain_rate= or penalty=")
                self.strain_rate = rate
                log.info("%s: representative strain rate %.4g 1/s", self.name, rate)
            self._penalty = penalty_from_beta(sim.material, self.beta, self.element_size,
                                              self.strain_rate)
            log.info("%s: penalty rho = %.4g (beta = %g)", self.name, self._penalty, self.beta)
            return self._penalty
        return penalty_from_beta(sim.material, self.beta, self.element_size, None, dt)

    def _project_all(self, X: np.ndarray, t: float, hessian: bool):
        """Project on every tool; per node keep the tool with the smallest gap."""
        X3 = _pad3(X)
        best = None
        tool_idx = np.zeros(len(X), dtype=np.int32)
        for k, tool in enumerate(self.tools):
            pr = tool.project(X3, t, hessian=hessian)
            if pr.feature is None:
                pr.feature = np.zeros(len(X), dtype=np.int64)
            if pr.flag is None:
                pr.flag = np.zeros(len(X), dtype=np.int32)
            if best is None:
                best = pr
                continue
            sel = pr.gap < best.gap
            if np.any(sel):
                best.gap[sel] = pr.gap[sel]
                best.normal[sel] = pr.normal[sel]
                best.point[sel] = pr.point[sel]
                if hessian and best.hessian is not None and pr.hessian is not None:
                    best.hessian[sel] = pr.hessian[sel]
                best.feature[sel] = pr.feature[sel]
                best.flag[sel] = pr.flag[sel]
                tool_idx[sel] = k
        return best, tool_idx

    def begin_increment(self, sim, t: float, dt: float, x_t_all: np.ndarray):
        b = self.boundary
        self.sim = sim
        self.t, self.dt = t, dt
        self.kin = sim.kinematics
        if not sim.material.small_strain:
            b.update_areas()
        self.x_t = np.ascontiguousarray(x_t_all[b.vertices])
        self.rho = self._resolve_penalty(sim, dt)
        self._ever_active[:] = False
        self._fallbacks_all = 0
        self._status_prev = None
        # burial check at the start of the increment (collective)
        pr0, tool0 = self._project_all(self.x_t, t, hessian=False)
        depth = -pr0.gap
        bad = np.flatnonzero(depth > self.max_initial_penetration)
        msg = None
        if len(bad):
            i = bad[np.argmax(depth[bad])]
            msg = (f"{len(bad)} contact node(s) start the increment at t = {t:.6g} buried in tool "
                   f"'{self.tools[tool0[i]].name}' deeper than the limit "
                   f"{self.max_initial_penetration:.3g} (worst: {depth[i]:.3g} at "
                   f"{np.array2string(self.x_t[i], precision=4)}); move the tool out of the "
                   f"body or raise max_initial_penetration")
        msgs = [m for m in b.comm.allgather(msg) if m]
        if msgs:
            raise ValueError(msgs[0])
        if self.scheme == "explicit":
            self._fixed = pr0
            self._fixed_tool = tool0
            vt = np.zeros((len(self.x_t), 3))
            for k, tool in enumerate(self.tools):
                sel = tool0 == k
                if np.any(sel):
                    vt[sel] = tool.velocity(pr0.point[sel], t)
            self._v_ref = vt[:, : self.gdim]
        elif self.scheme == "quasi-implicit":
            v_hat = sim.w_prev.x.array[b.dofs]
            x_pred = self.kin.positions(self.x_t, v_hat, dt)
            pr, tool_idx = self._project_all(x_pred, t + dt, hessian=False)
            self._fixed = pr
            self._fixed_tool = tool_idx
            self._v_ref = v_hat.copy()

    def begin_solve(self):
        self._status_prev = None
        self._settled = False

    # ------------------------------------------------------------------ evaluation
    def _constraint(self, v: np.ndarray, jacobian: bool):
        """h, ∇h, ∇²h (or empty), tool index and feature per node for the current velocity."""
        d, dt = self.gdim, self.dt
        empty = np.zeros((0, d, d))
        if self.scheme in ("explicit", "quasi-implicit"):
            pr = self._fixed
            nrm = pr.normal[:, :d]
            h = -pr.gap / dt - np.einsum("ni,ni->n", v - self._v_ref, nrm)
            return h, -nrm, empty, self._fixed_tool, pr.feature, pr.flag
        # exact tangent once the active set has settled (see the module docstring)
        exact = self.scheme == "implicit-exact" and self._settled
        t1 = self.t + dt
        if isinstance(self.kin, CartesianUpdate):
            X = self.x_t + dt * v
            pr, tool_idx = self._project_all(X, t1, hessian=exact and jacobian)
            h = -pr.gap / dt
            g = -pr.normal[:, :d]
            Hh = -dt * pr.hessian[:, :d, :d] if (exact and jacobian) else empty
        else:
            from fxcontact.cylindrical import gap_derivatives
            X, J, d2X = self.kin.derivatives(self.x_t, v, dt)
            pr, tool_idx = self._project_all(X, t1, hessian=True)
            h, g, Hh = gap_derivatives(pr, J, d2X if exact else None, dt)
            if not (exact and jacobian):
                # Gauss–Newton: keep ∇h exact, drop the curvature of d (but J is exact)
                Hh = empty
        self._last_proj = pr
        return h, g, Hh, tool_idx, pr.feature, pr.flag

    def evaluate(self, w, jacobian: bool) -> NodalTerms:
        b = self.boundary
        v = np.ascontiguousarray(b.velocities(w))
        h, g, Hh, tool_idx, feature, flag = self._constraint(v, jacobian)
        if flag is not None:
            bad = np.flatnonzero((flag == 2) & (h > 0))
            if len(bad):
                i = bad[0]
                raise ContributorError(
                    f"contact node at {np.array2string(self.x_t[i], precision=4)} is in contact "
                    f"with tool '{self.tools[tool_idx[i]].name}' at a point where its projection "
                    f"is undefined (on the tool axis): the node is deep inside the tool")
        if flag is not None:
            self._fallbacks = int(np.sum(flag == 1))
            self._fallbacks_all += self._fallbacks
        active = h > 0
        if self.sticky_gap > 0:
            self._ever_active |= active
            tangent_active = active | (self._ever_active & (h * self.dt > -self.sticky_gap))
        else:
            tangent_active = active
        r, K = self.kernel(b.areas, self.rho, h, np.ascontiguousarray(g), np.ascontiguousarray(Hh),
                           tangent_active, jacobian)
        self._h, self._tool, self._feature = h, tool_idx, feature
        self._r = r
        return NodalTerms(b.dofs, r, K if jacobian else None)

    def stable(self) -> bool:
        """True if the active set (and tools/features for implicit schemes) did not change since
        the previous call (called once per Newton iteration, collective)."""
        status = np.where(self._h > 0, 1 + self._tool, 0).astype(np.int64)
        if self.scheme in ("implicit", "implicit-exact"):
            status = status * (1 << 40) + np.where(self._h > 0, self._feature, 0)
        prev = self._status_prev
        same = prev is not None and np.array_equal(status, prev)
        comm = self.boundary.comm
        # what changed since the previous iterate: status (in/out of contact), or only the
        # projected feature (facet, patch) of a node in contact — for the cycle diagnosis
        if prev is None:
            n_status = n_feature = 0
        else:
            was, now = prev > 0, status > 0
            n_status = int(np.sum(was != now))
            n_feature = int(np.sum(was & now & (prev != status)))
        self._changes = tuple(comm.allreduce(np.array([n_status, n_feature]), op=MPI.SUM))
        self._fingerprint = tuple(comm.allgather(zlib.crc32(status.tobytes())))
        self._status_prev = status
        self._settled = bool(comm.allreduce(int(same), op=MPI.MIN))
        return self._settled

    def fingerprint(self) -> tuple:
        """Identifier of the contact state at the last :meth:`stable` call (the same on every
        rank): the solver uses it to recognise a Newton iteration that cycles."""
        return self._fingerprint

    def cycle_hint(self) -> str:
        """What changes at each iteration of a cycling Newton iteration, and the usual cure."""
        n_status, n_feature = self._changes
        if n_feature and not n_status:
            return (f"contact '{self.name}': {n_feature} node(s) switch between tool facets at "
                    f"every iteration (facet switching, THEORY §6): smooth the faceted tool "
                    f"(mode='nagata') or reduce dt")
        return (f"contact '{self.name}': {n_status} node(s) enter and leave contact"
                + (f" and {n_feature} switch facets" if n_feature else "")
                + " at every iteration: reduce dt (cut-back)")

    # ------------------------------------------------------------------ diagnostics / output
    def pressures(self) -> np.ndarray:
        """(N,) nodal contact pressures ρ[h]₊ of the last evaluation."""
        if self.rho is None:  # before the first increment resolves ρ from β
            return np.zeros_like(self._h)
        return self.rho * np.maximum(self._h, 0.0)

    def end_increment(self, sim, dt: float):
        """Measure the true penetration of the updated nodes against the tools at t + dt."""
        b = self.boundary
        x_new = sim.vertex_positions()[b.vertices]
        pr, _ = self._project_all(x_new, self.t + dt, hessian=False)
        self._true_pen = float(np.max(-pr.gap, initial=-np.inf))

    def diagnostics(self) -> Dict[str, float]:
        comm = self.boundary.comm
        b = self.boundary
        act = self._h > 0
        pmax = comm.allreduce(float(np.max(self.dt * self._h, initial=-np.inf)), op=MPI.MAX)
        tpen = comm.allreduce(getattr(self, "_true_pen", -np.inf), op=MPI.MAX)
        out = {f"{self.name}_penetration_predicted": max(pmax, 0.0),
               f"{self.name}_penetration_true": max(tpen, 0.0),
               f"{self.name}_nodes": comm.allreduce(int(np.sum(act)), op=MPI.SUM),
               f"{self.name}_area": comm.allreduce(float(np.sum(b.areas[act])), op=MPI.SUM),
               f"{self.name}_pressure_max": comm.allreduce(
                   float(np.max(self.pressures(), initial=0.0)), op=MPI.MAX),
               # projections that fell back to the flat facet (faceted Nagata tools): at the
               # accepted iterate, and summed over every evaluation of the increment
               f"{self.name}_fallbacks": comm.allreduce(self._fallbacks, op=MPI.SUM),
               f"{self.name}_fallbacks_all": comm.allreduce(self._fallbacks_all, op=MPI.SUM)}
        for k, tool in enumerate(self.tools):
            sel = self._tool == k
            # force on the tool = −(force on the body) = Σ r_n
            F = comm.allreduce(np.sum(self._r[sel], axis=0) if np.any(sel)
                               else np.zeros(self.gdim), op=MPI.SUM)
            for j, c in enumerate("xyz"[: self.gdim]):
                out[f"{tool.name}_force_{c}"] = float(F[j])
        return out

    def tool_force(self, k: int = 0) -> np.ndarray:
        """Force on tool k (gdim,) from the last evaluation, summed over ranks."""
        sel = self._tool == k
        return self.boundary.comm.allreduce(
            np.sum(self._r[sel], axis=0) if np.any(sel) else np.zeros(self.gdim), op=MPI.SUM)

    def output_fields(self):
        if self._fields is None:
            b = self.boundary
            Q1 = compat.function_space(b.space.mesh, ("Lagrange", 1))
            p = dolfinx.fem.Function(Q1, name=f"{self.name}_pressure")
            s = dolfinx.fem.Function(Q1, name=f"{self.name}_status")
            self._fields = (p, s)
        return list(self._fields)

    def update_output_fields(self):
        p, s = self.output_fields()
        q = self.boundary.q1_dofs(p.function_space)
        p.x.array[:] = 0.0
        s.x.array[:] = 0.0
        p.x.array[q] = self.pressures()
        s.x.array[q] = (self._h > 0).astype(float)
        p.x.scatter_forward()
        s.x.scatter_forward()
