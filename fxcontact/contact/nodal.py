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

**Displacement formulation** (THEORY §3.7; ``formulation="displacement"``, for a dolfinx
problem whose unknown is the total displacement u of a P1 field, mesh not moved). The gap is written on the positions
at the end of the load step, X = X_ref + u, against the tools at the step's end time, with the
same schemes. Over a load step t → t + Δt starting from uᵗ (positions xᵗ = X_ref + uᵗ), the
nodal terms are those of the velocity form with v = (u − uᵗ)/Δt — then X = xᵗ + Δt v — and the
penalty ρ = k Δt, k the gap stiffness [stress/length]: the kernels are the same, the residual
entries (nodal forces S k [−gap]₊ n) are unchanged and the Jacobian blocks are divided by Δt
(chain rule). The quasi-implicit predictor is the previous step's displacement rate. Nodal areas
are those of the reference configuration (nominal pressures), so the residual is the exact
gradient of Σ S k [−gap]₊²/2 in u.

Bad states are errors, raised on every rank at once: a node initially buried deeper than
``max_initial_penetration`` (default half the local element size), or a node in contact whose
projection is undefined (exactly on a tool axis: flag 2).
"""

from __future__ import annotations

import logging
import math
import zlib
from collections import deque
from typing import List, Optional

import numpy as np
from mpi4py import MPI

from fxcontact.collective import together
from fxcontact.contact.boundary import ContactBoundary
from fxcontact.contact.friction import (LAW_NONE, friction_kernel, friction_kernel_numpy,
                                        laws_per_tool)
from fxcontact.contact.nodal_io import STICK_FACTOR, NodalContactIO
from fxcontact.contact.penalty import (  # noqa: F401
    DEFAULT_BETA,
    Penalty,
    penalty_from_beta,
    penalty_kernel,
    penalty_kernel_numpy,
)
from fxcontact.contact.view import ContactNodes
from fxcontact.kinematics import CartesianUpdate, gap_derivatives, pad3
from fxcontact.materials import NortonHoff
from fxcontact.newton.problem import ContributorError, NodalTerms
from fxcontact.tools.base import Tool

__all__ = ["NodalContact", "SCHEMES", "FRICTION_MODES", "FORMULATIONS", "penalty_from_beta"]

log = logging.getLogger(__name__)

SCHEMES = ("explicit", "quasi-implicit", "implicit", "implicit-exact")

FRICTION_MODES = ("implicit", "explicit")

#: unknowns the contact is written in: nodal velocities over an increment (updated Lagrangian,
#: fxcontact's Simulation) or total displacements (a dolfinx displacement problem)
FORMULATIONS = ("velocity", "displacement")

#: default slip-speed regularisation v₀ relative to the characteristic speed of the process
#: (THEORY §9: 1e-3 – 1e-2 of the typical sliding speed)
DEFAULT_SLIP_VELOCITY_REL = 1e-3

class _DisplacementBody:
    """Stands for the body of a displacement-form problem (no fxcontact material): penalties
    come from the gap stiffness, friction laws carry their own material data."""

    small_strain = True


class _StepState:
    """What :meth:`NodalContact.begin_increment` reads from a Simulation, for a displacement
    load step: Cartesian positions, the predictor rate v̂ at the contact nodes."""

    kinematics = CartesianUpdate()
    material = _DisplacementBody()

    def __init__(self, v_hat, boundary, u):
        arr = np.zeros(u.x.array.shape)
        arr[boundary.dofs] = v_hat
        box = type("X", (), {"array": arr})()
        self.w_prev = self.w = type("F", (), {"x": box})()


class NodalContact(NodalContactIO):
    """Nodal penalty contact of a :class:`ContactBoundary` against rigid tools.

    Args:
        boundary: the contact nodes.
        tools: one tool or a sequence of tools; a node keeps the tool of smallest signed gap
            (the first on a tie; its friction law applies): the distance to the union of the
            bodies (docs/architecture.md, "Several tools of one contact").
        scheme: one of :data:`SCHEMES`. Default: ``"implicit"`` in velocity form,
            ``"implicit-exact"`` in displacement form (``"implicit"`` if a tool has no gap
            Hessian): a dolfinx problem has no other fxcontact solver settings to tune, and the
            exact tangent takes the neo-Hookean block of ``demos/demo_hyperelastic_contact.py``
            from 114 to 35 Newton iterations (``benchmarks/README.md``).
        penalty: ρ [stress/velocity] or a :class:`Penalty`; or give ``beta`` (§2.5), ``strain_rate``
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
        friction: friction law(s) (:mod:`fxcontact.contact.friction`): one law for every tool,
            or a dict ``{tool or tool name: law}`` (tools left out are frictionless), or a
            sequence aligned with ``tools``. Default: frictionless.
        friction_mode: ``"implicit"`` (p_n and the status of the current iterate, consistent
            non-symmetric Jacobian on the Coulomb branch; default with the implicit schemes)
            or ``"explicit"`` (p_n and the status of the previous converged increment,
            symmetric Jacobian; default with the explicit and quasi-implicit schemes).
        slip_velocity: regularisation v₀ of the slip speed s = √(|Δv_t|² + v₀²) [length/time].
            Default: ``DEFAULT_SLIP_VELOCITY_REL`` (1e-3) × the characteristic speed of the
            process, taken at each increment as the largest of the tools' surface speeds at
            the contact nodes' projections and the contact nodes' speeds of the predictor (a
            roll that starts turning after a pressing stage gets the v₀ of its surface speed).
        friction_tangent: ``"auto"`` (default: the secant friction tangent until the nodes'
            stick/slip state is unchanged and their slip velocities move by less than v₀
            between two Newton iterations, the consistent one from then on — quadratic end of
            the convergence; THEORY §9.5), ``"consistent"`` or ``"secant"``.
        name: label used in history columns.
        backend: "numba" or "numpy" (reference twin of the kernels, for testing).
        formulation: ``"velocity"`` (default: the unknown is the nodal velocity of an increment,
            X = xᵗ + dt·v, for :class:`~fxcontact.simulation.Simulation`) or ``"displacement"``
            (the unknown is the total displacement u of a P1 field, X = X_ref + u, for a
            dolfinx problem; see the module docstring). In displacement form ``penalty`` and
            ``gap_stiffness`` are both the gap stiffness k [stress/length], and ``beta`` gives
            k = β E*/h_e with ``modulus`` = E*; each load step starts with :meth:`begin_step`
            (done by :class:`~fxcontact.newton.problem.ContactProblem`).
        modulus: reference modulus E* [stress] of a displacement-form ``beta``.

    Friction (THEORY §9) acts on the nodes in contact, against the velocity relative to the
    tool's material point at the projection (tools that translate and rotate about their own
    axis). Each law says which shear flow stress k its Tresca limit uses
    (:class:`~fxcontact.contact.friction.ShearLimit`: by default the Norton–Hoff material at
    each node, k = K (√3 ε̄̇)^m with the nodal strain rate of the increment's predictor,
    regularised like the material; or the material at a given strain rate; or a given k); the
    consistency K of viscoplastic friction is the material's. Other materials need
    ``shear_limit``/``K`` in the law. The choice is in the run's summary (:meth:`summary`).

    The penalty is one object, :attr:`penalty` (:class:`~fxcontact.contact.penalty.Penalty`),
    resolved at each increment by ``Penalty.rho``; ``rho`` is its value for the current
    increment.
    """

    def __init__(self, boundary: ContactBoundary, tools, scheme: Optional[str] = None,
                 penalty: Optional[float | Penalty] = None, beta: Optional[float] = None,
                 element_size: Optional[float] = None, strain_rate: Optional[float] = None,
                 sticky_gap: float = 0.0, max_initial_penetration: Optional[float] = None,
                 gap_stiffness: Optional[float] = None, friction=None,
                 friction_mode: Optional[str] = None, slip_velocity: Optional[float] = None,
                 friction_tangent: str = "auto", name: str = "contact", backend: str = "numba",
                 formulation: str = "velocity", modulus: Optional[float] = None):
        # checked on every rank together, raised on every rank (fxcontact.collective)
        with together(getattr(boundary, "comm", MPI.COMM_WORLD), "NodalContact()", name=name,
                      scheme=scheme, formulation=formulation, element_size=element_size,
                      modulus=modulus):
            if formulation not in FORMULATIONS:
                raise ValueError(f"unknown formulation {formulation!r}; choose one of "
                                 f"{FORMULATIONS}")
            self.formulation = formulation
            if formulation == "velocity" and modulus is not None:
                raise ValueError("modulus is for the displacement formulation (k = beta E*/h_e); "
                                 "the velocity form takes beta with the material of the Simulation")
            tools = [tools] if isinstance(tools, Tool) else (
                list(tools) if isinstance(tools, (list, tuple)) else [tools])
            if not tools or not all(isinstance(t, Tool) for t in tools):
                raise ValueError("tools must be a Tool or a non-empty sequence of Tools")
            names = [t.name for t in tools]
            twice = sorted({nm for nm in names if names.count(nm) > 1})
            if twice:
                raise ValueError(f"the tools of a contact need distinct names: several tools are "
                                 f"named {twice} (their history columns '{twice[0]}_force_...' "
                                 f"would overwrite each other); pass a distinct name= to each "
                                 f"tool")
            if scheme is None:
                scheme = ("implicit-exact" if formulation == "displacement" and
                          all(t.has_hessian for t in tools) else "implicit")
            if scheme not in SCHEMES:
                raise ValueError(f"unknown contact scheme {scheme!r}; choose one of {SCHEMES}")
            if scheme == "implicit-exact" and not all(t.has_hessian for t in tools):
                raise ValueError("implicit-exact needs tools that provide the gap Hessian")
            #: the penalty (ρ, β or a gap stiffness), resolved per increment by Penalty.rho
            self.penalty = Penalty.of(penalty, beta, gap_stiffness, strain_rate)
            if not (math.isfinite(sticky_gap) and sticky_gap >= 0):
                raise ValueError("sticky_gap must be >= 0")
            if backend not in ("numba", "numpy"):
                raise ValueError("backend must be 'numba' or 'numpy'")
            self.boundary = boundary
            self.tools: List[Tool] = tools
            self.scheme = scheme
            self.name = name
            self.gdim = boundary.gdim
            self.sticky_gap = float(sticky_gap)
            #: factor on ρ of the current evaluations (< 1 in the softened first stage of a
            #: Newton solve with penalty continuation, SolverOptions.penalty_continuation)
            self.penalty_scale = 1.0
            self.kernel = penalty_kernel if backend == "numba" else penalty_kernel_numpy
            self.friction_kernel = friction_kernel if backend == "numba" else friction_kernel_numpy
            self.friction = laws_per_tool(friction, tools)
            self.has_friction = any(law.code != LAW_NONE for law in self.friction)
            if friction_mode is None:
                friction_mode = ("implicit" if scheme in ("implicit", "implicit-exact")
                                 else "explicit")
            if friction_mode not in FRICTION_MODES:
                raise ValueError(f"unknown friction_mode {friction_mode!r}; choose one of "
                                 f"{FRICTION_MODES}")
            self.friction_mode = friction_mode
            if slip_velocity is not None and not (math.isfinite(slip_velocity)
                                                  and slip_velocity > 0):
                raise ValueError(f"slip_velocity (v0) must be finite and > 0, got "
                                 f"{slip_velocity!r}")
            if friction_tangent not in ("auto", "consistent", "secant"):
                raise ValueError(f"friction_tangent must be 'auto', 'consistent' or 'secant', got "
                                 f"{friction_tangent!r}")
            self.friction_tangent = friction_tangent
            self._fr_state_prev = None
            self._fr_settled = False
            self._slip_velocity_user = None if slip_velocity is None else float(slip_velocity)
            self.slip_velocity = self._slip_velocity_user
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
        self.penalty.bind(formulation, self.element_size, modulus)
        #: ρ of the current increment (None before the first one)
        self.rho = self.penalty.fixed_rho
        if formulation == "displacement":
            self._u_t = None
            self._v_hat = np.zeros((len(boundary), self.gdim))
        self.sim = None
        self.t = 0.0
        self.dt = 1.0
        self._status_prev = None
        self._settled = False
        #: contact state of the last iterates (in contact, tool, feature, projection
        #: fall-back per node), to say what changes over a cycle (:meth:`cycle_hint`)
        self._recent = deque(maxlen=5)   # the longest cycle the solver looks for, 4, + 1
        self._floor = 0.0
        self._force = 0.0
        self._rho_eval = 0.0
        self._fingerprint = ()
        self._placement_checked = False
        self._fallbacks = 0
        self._fallbacks_all = 0
        self._fields = None
        self._k_law = np.full(len(self.tools), np.nan)
        self._reset_nodes(len(boundary))

    def _reset_nodes(self, n: int):
        """The per-node state of ``n`` contact nodes, zero (at the set-up and on a remesh)."""
        self._h = np.zeros(n)
        self._tool = np.zeros(n, dtype=np.int32)
        self._feature = np.zeros(n, dtype=np.int64)
        self._v_last = np.zeros((n, self.gdim))
        self._ever_active = np.zeros(n, dtype=bool)
        self._r = np.zeros((n, self.gdim))
        self._r_all = np.zeros((n, self.gdim))
        # friction state: pressures of the previous converged increment (explicit friction),
        # per-node shear flow stress and consistency, last evaluation's friction terms
        self._p_prev = np.zeros(n)
        self._k_node = np.zeros(n)
        self._K_node = np.zeros(n)
        self._rf = np.zeros((n, self.gdim))
        self._tau = np.zeros((n, self.gdim))
        self._dvt = np.zeros((n, self.gdim))
        self._branch = np.zeros(n, dtype=np.int8)
        self._point = np.zeros((n, 3))
        self._g = self._X = np.zeros((n, self.gdim))
        self._nodes = ContactNodes.of(self, self._X, self._X)

    # ------------------------------------------------------------------ friction set-up
    def _begin_friction(self, sim, t: float, dt: float):
        """Material data at the nodes and the slip regularisation (collective)."""
        mat = sim.material
        for law, tool in zip(self.friction, self.tools):
            if law.needs_shear_limit and law.k_source.kind != "given" and \
                    not isinstance(mat, NortonHoff):
                raise ValueError(f"friction on tool '{tool.name}' needs the shear flow stress k "
                                 f"of the body, which a {type(mat).__name__} material does not "
                                 f"define: give shear_limit= in the friction law")
            if law.needs_consistency and law.K is None and not isinstance(mat, NortonHoff):
                raise ValueError(f"viscoplastic friction on tool '{tool.name}' needs the "
                                 f"consistency K, which a {type(mat).__name__} material does not "
                                 f"define: give K= in the Norton law")
        need_k = any(law.needs_shear_limit and law.k_source.kind == "local rate"
                     for law in self.friction)
        need_K = any(law.needs_consistency and law.K is None for law in self.friction)
        if isinstance(mat, NortonHoff) and (need_K or need_k):   # a law per cell: its own
            self._K_node, self._k_node = self.boundary.material_law(sim.w, sim.space.dx, mat,
                                                                    shear=need_k)
        # k of each law when it is the same at every node (given, or at a given rate); NaN: local
        self._k_law = np.array([law.k_source.k(mat) if law.needs_shear_limit else np.nan
                                for law in self.friction])
        if self._slip_velocity_user is None:
            pr, tool_idx = self._project_all(self.x_t, t, hessian=False)
            speed = 0.0
            for k, tool in enumerate(self.tools):
                sel = tool_idx == k
                if np.any(sel):
                    speed = max(speed, float(np.max(np.linalg.norm(
                        tool.velocity(pr.point[sel], t), axis=1))))
            v = self.boundary.velocities(sim.w)
            if len(v):
                speed = max(speed, float(np.max(np.linalg.norm(v, axis=1))))
            speed = self.boundary.comm.allreduce(speed, op=MPI.MAX)
            if not speed > 0:
                raise ValueError(f"{self.name}: cannot estimate a characteristic speed for the "
                                 f"slip regularisation (static tools and a body at rest): give "
                                 f"slip_velocity=")
            v0 = DEFAULT_SLIP_VELOCITY_REL * speed
            if v0 != self.slip_velocity:
                log.debug("%s: slip regularisation v0 = %.4g", self.name, v0)
            self.slip_velocity = v0

    # ------------------------------------------------------------------ set-up per increment
    # the penalty as given (read-only views of self.penalty)
    beta = property(lambda self: self.penalty.beta)
    gap_stiffness = property(lambda self: self.penalty.gap_stiffness)
    #: the gap stiffness k of the displacement form (or of ``gap_stiffness``), else None
    stiffness = property(lambda self: self.penalty.stiffness)
    #: representative strain rate of a Norton–Hoff β (given or estimated at the first increment)
    strain_rate = property(lambda self: self.penalty.strain_rate)

    def _representative_strain_rate(self, sim) -> float:
        """The strain rate of a Norton–Hoff β: the mean of the first increment's initial guess;
        the start-up solve does not see the tools, so a body driven by velocity conditions
        against static tools (drawing) moves rigidly in it: then the speed of the body relative
        to the tools over the body's size (collective)."""
        rate = sim.mean_strain_rate()
        v = self.boundary.velocities(sim.w)
        speed = max(float(np.max(np.linalg.norm(
            v - tool.velocity(pad3(self.x_t), self.t)[:, : self.gdim], axis=1),
            initial=0.0)) for tool in self.tools)
        speed = self.boundary.comm.allreduce(speed, op=MPI.MAX)
        rate_kin = speed / sim.volume() ** (1.0 / self.gdim)
        if not rate > 1e-6 * rate_kin:
            rate = rate_kin
        if not rate > 0:
            raise ValueError("cannot estimate a representative strain rate for the "
                             "penalty (the body and the tools are at rest): give "
                             "strain_rate= or penalty=")
        return rate

    def _project_all(self, X: np.ndarray, t: float, hessian: bool):
        """Project on every tool; per node keep the tool with the smallest gap."""
        X3 = pad3(X)
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
        self.rho = self.penalty.rho(sim.material, dt,
                                    lambda: self._representative_strain_rate(sim), self.name)
        self._ever_active[:] = False
        self._fallbacks_all = 0
        self._status_prev = None
        self._recent.clear()
        if not self._placement_checked:
            # the whole body (a displacement-form problem: its mesh, or the contact nodes of a
            # boundary without one)
            if self.formulation == "velocity":
                body = x_t_all
            elif hasattr(b, "mesh"):
                body = b.mesh.geometry.x
            else:
                body = b.mesh_positions()
            self._check_placement(np.asarray(body)[:, : self.gdim], t)
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
            self._v_ref = self.tool_velocities(pr0.point, tool0, t)
            self._v_tool_fixed = self._v_ref
        elif self.scheme == "quasi-implicit":
            v_hat = sim.w_prev.x.array[b.dofs]
            x_pred = self.kin.positions(self.x_t, v_hat, dt)
            pr, tool_idx = self._project_all(x_pred, t + dt, hessian=False)
            self._fixed = pr
            self._fixed_tool = tool_idx
            self._v_ref = v_hat.copy()
            self._v_tool_fixed = self.tool_velocities(pr.point, tool_idx, t + dt)
        if self.has_friction:
            self._begin_friction(sim, t, dt)

    def begin_step(self, t: float, dt: float, u):
        """Start a load step t → t + dt of the displacement formulation from the displacement
        Function ``u`` (its current content is the converged uᵗ of the previous step, or the
        initial state). Collective. Called by :class:`~fxcontact.newton.problem.ContactProblem`."""
        if self.formulation != "displacement":
            raise ValueError("begin_step is for formulation='displacement'; the velocity form "
                             "is driven by Simulation (begin_increment)")
        if not (math.isfinite(dt) and dt > 0):
            raise ValueError(f"the load step must advance the time: dt = {dt!r}")
        for law, tool in zip(self.friction, self.tools):
            if (law.needs_shear_limit and law.k_source.kind != "given") or \
                    (law.needs_consistency and law.K is None):
                raise ValueError(f"friction on tool '{tool.name}' in the displacement "
                                 f"formulation: the body's shear flow stress / consistency are "
                                 f"not known to fxcontact, give shear_limit= (and K=) in the law")
        b = self.boundary
        u_nodes = np.array(b.velocities(u), dtype=np.float64).reshape(-1, self.gdim)
        if self._u_t is not None:
            # closure of the previous step: rate for the quasi-implicit predictor
            self._v_hat = (u_nodes - self._u_t) / self.dt
        self._u_t = u_nodes
        x_ref = b.mesh_positions()
        shim = _StepState(self._v_hat, b, u)
        x_all = np.zeros((int(np.max(b.vertices, initial=-1)) + 1, self.gdim))
        x_all[b.vertices] = x_ref + u_nodes
        self.begin_increment(shim, t, dt, x_all)
        self.begin_solve()

    def end_step(self, u):
        """Close a displacement-form load step: true penetration of X_ref + u against the tools
        at the step's end time, pressures for explicit friction (optional; collective)."""
        b = self.boundary
        X = b.mesh_positions() + b.velocities(u)
        pr, _ = self._project_all(X, self.t + self.dt, hessian=False)
        self._true_pen = float(np.max(-pr.gap, initial=-np.inf))
        self._p_prev = self.pressures().copy()

    def tool_velocities(self, points: np.ndarray, tool_idx: np.ndarray, t: float):
        """(N, gdim) material velocity (mm/s) at time ``t`` of each node's tool (``tool_idx``:
        indices in :attr:`tools`) at the points ``points`` (N, 3) (mm), e.g. the projections
        ``nodes.point`` with ``nodes.tool``."""
        vt = np.zeros((len(points), 3))
        for k, tool in enumerate(self.tools):
            sel = tool_idx == k
            if np.any(sel):
                vt[sel] = tool.velocity(points[sel], t)
        return vt[:, : self.gdim]

    def scale_penalty(self, factor: float):
        """Multiply the penalty ρ by ``factor`` in the following evaluations (1 restores it);
        used by the penalty continuation of :class:`~fxcontact.newton.solver.ContactNewtonSolver`."""
        if not (math.isfinite(factor) and factor > 0):
            raise ValueError(f"penalty scale must be finite and > 0, got {factor!r}")
        self.penalty_scale = float(factor)

    def begin_solve(self):
        self._status_prev = None
        self._recent.clear()
        self._settled = False
        self._fr_state_prev = None
        self._fr_settled = False

    # ------------------------------------------------------------------ evaluation
    def _constraint(self, v: np.ndarray, jacobian: bool):
        """h, ∇h, ∇²h (or empty), tool index and feature per node for the current velocity."""
        d, dt = self.gdim, self.dt
        empty = np.zeros((0, d, d))
        if self.scheme in ("explicit", "quasi-implicit"):
            pr = self._fixed
            nrm = pr.normal[:, :d]
            h = -pr.gap / dt - np.einsum("ni,ni->n", v - self._v_ref, nrm)
            self._cur_proj, self._X = pr, self.kin.positions(self.x_t, v, dt)
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
            X, J, d2X = self.kin.derivatives(self.x_t, v, dt)
            pr, tool_idx = self._project_all(X, t1, hessian=True)
            h, g, Hh = gap_derivatives(pr, J, d2X if exact else None, dt)
            if not (exact and jacobian):
                # Gauss–Newton: keep ∇h exact, drop the curvature of d (but J is exact)
                Hh = empty
        self._last_proj = self._cur_proj = pr
        self._X = X
        return h, g, Hh, tool_idx, pr.feature, pr.flag

    def evaluate(self, w, jacobian: bool) -> NodalTerms:
        b = self.boundary
        if self.formulation == "displacement":
            if self._u_t is None:
                raise RuntimeError(f"{self.name}: displacement-form contact evaluated before "
                                   f"begin_step() (ContactProblem.begin_step starts a load step)")
            # v = (u - u^t)/dt: the velocity-form terms, then d/du = (1/dt) d/dv
            v = np.ascontiguousarray((b.velocities(w) - self._u_t) / self.dt)
        else:
            v = np.ascontiguousarray(b.velocities(w))
        self._v_last = v
        h, g, Hh, tool_idx, feature, flag = self._constraint(v, jacobian)
        if flag is not None:
            bad = np.flatnonzero((flag == 2) & (h > 0))
            if len(bad):
                i = bad[0]
                raise ContributorError(
                    f"contact node at {np.array2string(self.x_t[i], precision=4)} is in contact "
                    f"with tool '{self.tools[tool_idx[i]].name}' at a point where its projection "
                    f"is undefined (on the tool axis): the node is deep inside the tool")
        self._flag = flag
        if flag is not None:
            self._fallbacks = int(np.sum(flag == 1))
            self._fallbacks_all += self._fallbacks
        active = h > 0
        if self.sticky_gap > 0:
            self._ever_active |= active
            tangent_active = active | (self._ever_active & (h * self.dt > -self.sticky_gap))
        else:
            tangent_active = active
        g = np.ascontiguousarray(g)
        rho = self.rho * self.penalty_scale
        r, K = self.kernel(b.areas, rho, h, g, np.ascontiguousarray(Hh),
                           tangent_active, jacobian)
        self._h, self._tool, self._feature = h, tool_idx, feature
        self._g = g
        self._tangent_active, self._rho_eval = tangent_active, rho
        self._point = self._cur_proj.point
        self._r = r
        if not isinstance(self.kin, CartesianUpdate) and \
                self.scheme in ("implicit", "implicit-exact"):
            # r = S ρ[h]₊ ∇h is the force conjugate to v: with a non-Cartesian update
            # ∇h = −Jᵀn/dt is n turned back by the increment's rotation; the force on the tool
            # (outputs: tool_force, tool_torque) is the physical one, −S ρ[h]₊ n at X(v)
            self._r = -(b.areas * rho * np.maximum(h, 0.0))[:, None] * \
                self._cur_proj.normal[:, : self.gdim]
        if self.has_friction:
            rf, Kf = self._friction_terms(v, h, g, tool_idx, jacobian)
            self._rf = rf
            r = r + rf
            if jacobian:
                K = K + Kf
        self._r_all = r
        self._nodes = ContactNodes.of(self, self._X, self._cur_proj.normal[:, : self.gdim])
        if jacobian and self.formulation == "displacement":
            K = K / self.dt
        return NodalTerms(b.dofs, r, K if jacobian else None)

    #: gap (× element size) below which a free node may be predicted to enter contact
    PREDICTION_GAP = 0.25

    def active_set_prediction(self, step: np.ndarray):
        """The nodes whose contact status the Newton step ``step`` would change, for the
        active-set prediction of :class:`~fxcontact.newton.prediction.ActiveSetPrediction`.

        The penalty force of a node is piecewise linear in the step δ of its values with the
        gradient ``g`` of the last evaluation: ``S ρ [h + g·δ]₊ g``. The Newton system only
        knows the branch of the current iterate (the tangent ``S ρ A g⊗g`` with ``A`` the
        tangent's active flag, the force ``S ρ [h]₊ g``). For the nodes where the predicted
        status ``h + g·δ > 0`` differs from ``A`` (or where the active branch has an offset
        the residual lacks: a node kept active by ``sticky_gap`` with h ≤ 0), it returns what
        turns the Newton system into the one of the predicted branch: the stiffness change
        ``dc`` along ``g`` (± S ρ) and the residual offset ``o`` along ``g``
        (``S ρ (want·h − [h]₊)``). Nodes of tools with friction are not selected (their
        friction force changes with the status too), nor free nodes whose gap exceeds
        :attr:`PREDICTION_GAP` × the element size.

        In displacement form (u = uᵗ + dt v, THEORY §3.7) the gradient is ``g/dt``; the block
        ``S ρ g⊗g/dt`` and force ``S ρ h g`` are ``S ρ dt (g/dt)⊗(g/dt)`` and ``S ρ dt h (g/dt)``:
        ``dc`` and ``o`` take ``S ρ dt`` (S k dt², k the gap stiffness) for the velocity's ``S ρ``.
        The exact tangent's curvature term ``S ρ [h]₊ ∇²h`` (``implicit-exact``) stays for a node
        predicted to leave: relative to ``S ρ g⊗g`` it is the penetration over the tool's radius.

        Args:
            step: the owned part of the Newton step δ (x_new = x + δ), indexed like the
                boundary's dofs.

        Returns:
            ``(dofs (k, d), g (k, d), dc (k,), o (k,))`` for the k selected owned nodes (the
            gradient with respect to the unknown: ``g/dt`` in displacement form; ``dc`` and
            ``o`` in the units of that gradient).
        """
        d = self.gdim
        dofs = self.boundary.dofs
        scale = 1.0 / self.dt if self.formulation == "displacement" else 1.0
        g = self._g * scale
        dl = np.where(dofs >= 0, step[np.maximum(dofs, 0)], 0.0)
        want = self._h + np.einsum("nd,nd->n", g, dl) > 0.0
        A = self._tangent_active
        c = self.boundary.areas * self._rho_eval
        if self.formulation == "displacement":
            c = c * self.dt    # the weight of the columns g/dt (docstring)
        dc = c * (want.astype(float) - A.astype(float))
        o = c * (np.where(want, self._h, 0.0) - np.maximum(self._h, 0.0))
        change = (dc != 0.0) | (o != 0.0)
        # nodes entering contact: only those already near the tool (end-of-increment gap below
        # PREDICTION_GAP × h_e); further away the gap's linearisation over a whole step means
        # little (a curved tool, a rotating body) and the next iterations' projection will see
        # them
        far = (want & ~A) & (-self._h * self.dt > self.PREDICTION_GAP * self.element_size)
        change &= ~far
        if self.has_friction:
            # the friction force follows p_n = ρ[h]₊ and the status: a frictional node's
            # predicted branch is not the normal part alone (a released sticking node would keep
            # its stick stiffness), so nodes of tools with friction are left to Newton as is
            codes = np.array([law.code for law in self.friction], dtype=np.int64)
            change &= codes[self._tool] == LAW_NONE
        sel = np.flatnonzero(change)
        return (dofs[sel].reshape(-1, d), np.ascontiguousarray(g[sel]), dc[sel], o[sel])

    def _friction_terms(self, v, h, g, tool_idx, jacobian: bool):
        """Friction residual entries and Jacobian blocks at the current iterate (THEORY §9)."""
        pr = self._cur_proj
        if self.scheme in ("explicit", "quasi-implicit"):
            v_tool = self._v_tool_fixed
        else:
            v_tool = self.tool_velocities(pr.point, tool_idx, self.t + self.dt)
        dv = np.ascontiguousarray(v - v_tool)
        a = self.friction_arguments(h, g, tool_idx)
        rf, Kf, tau, branch = self.friction_kernel(
            a["S"], a["law"], a["mu"], a["tau_max"], a["visc"], a["q"], a["pn"], a["dpn"], dv,
            a["nrm"], a["v0"], a["active"], jacobian, a["theta"])
        self._tau, self._branch = tau, branch
        nrm = a["nrm"]
        self._dvt = dv - np.einsum("ni,ni->n", dv, nrm)[:, None] * nrm
        return rf, Kf

    def friction_arguments(self, h, g, tool_idx) -> dict:
        """The per-node arguments of the friction kernel (all but the relative velocity ``dv``
        and ``jacobian``) for the gaps ``h``, gap gradients ``g`` and tools ``tool_idx`` of an
        evaluation at the current projection: ``S, law, mu, tau_max, visc, q, pn, dpn, nrm,
        v0, active, theta`` (also used by :class:`~fxcontact.idle.IdleRotation` to evaluate
        the friction of one tool at another rotation speed)."""
        d = self.gdim
        nrm = np.ascontiguousarray(self._cur_proj.normal[:, :d])
        laws = self.friction
        code = np.array([law.code for law in laws], dtype=np.int64)[tool_idx]
        mu = np.array([getattr(law, "mu", 0.0) for law in laws])[tool_idx]
        mbar = np.array([law.mbar if getattr(law, "mbar", None) is not None else np.nan
                         for law in laws])[tool_idx]
        k_user = self._k_law[tool_idx]
        k = np.where(np.isnan(k_user), self._k_node, k_user)
        tau_max = np.where(np.isnan(mbar), np.inf, mbar * k)
        alpha = np.array([getattr(law, "alpha_f", 0.0) for law in laws])[tool_idx]
        K_user = np.array([law.K if getattr(law, "K", None) is not None else np.nan
                           for law in laws])[tool_idx]
        visc = alpha * np.where(np.isnan(K_user), self._K_node, K_user)
        q = np.array([getattr(law, "q", 1.0) for law in laws])[tool_idx]
        if self.friction_mode == "implicit":
            active = h > 0
            rho = self.rho * self.penalty_scale
            pn = rho * np.maximum(h, 0.0)
            dpn = np.ascontiguousarray(rho * active[:, None] * g)
        else:
            pn = self._p_prev
            active = pn > 0
            dpn = np.zeros((0, d))
        if self.friction_tangent == "auto":
            theta = 1.0 if self._fr_settled else 0.0
        else:
            theta = 1.0 if self.friction_tangent == "consistent" else 0.0
        return dict(S=self.boundary.areas, law=code, mu=mu, tau_max=tau_max, visc=visc, q=q,
                    pn=pn, dpn=dpn, nrm=nrm, v0=float(self.slip_velocity), active=active,
                    theta=theta)

    def stable(self) -> bool:
        """True if the active set (and tools/features for implicit schemes) did not change since
        the previous call (called once per Newton iteration, collective)."""
        status = np.where(self._h > 0, 1 + self._tool, 0).astype(np.int64)
        if self.scheme in ("implicit", "implicit-exact"):
            status = status * (1 << 40) + np.where(self._h > 0, self._feature, 0)
        prev = self._status_prev
        same = prev is not None and np.array_equal(status, prev)
        comm = self.boundary.comm
        active = self._h > 0
        flag = getattr(self, "_flag", None)
        self._recent.append((active, np.where(active, self._tool, -1),
                             np.where(active, self._feature, -1),
                             np.zeros(len(active), bool) if flag is None else flag == 1))
        # round-off of the contact residual: the gap of X = x^t + dt v is known to about
        # eps |X|, h = -gap/dt to eps |X| / dt, each active node's force S ρ h to S ρ eps |X|/dt
        x_t = getattr(self, "x_t", np.zeros((len(active), self.gdim)))
        X = np.abs(x_t).max(axis=1, initial=0.0) + self.dt * np.linalg.norm(self._v_last, axis=1)
        floor = self.boundary.areas * self._rho_eval * np.finfo(float).eps * X / self.dt
        self._floor = math.sqrt(comm.allreduce(float(np.sum(floor[active] ** 2)), op=MPI.SUM))
        self._force = math.sqrt(comm.allreduce(float(np.sum(self._r_all ** 2)), op=MPI.SUM))
        self._fingerprint = tuple(comm.allgather(zlib.crc32(status.tobytes())))
        self._status_prev = status
        self._settled = bool(comm.allreduce(int(same), op=MPI.MIN))
        if self.has_friction:
            # stick (1) / slip (2) state of the friction nodes: the consistent friction tangent
            # is used once it is unchanged between two iterates (friction_tangent="auto")
            slip = np.linalg.norm(self._dvt, axis=1)
            fr = np.where(self._branch > 0,
                          np.where(slip < STICK_FACTOR * self.slip_velocity, 1, 2), 0)
            fr_same = self._fr_state_prev is not None and np.array_equal(fr, self._fr_state_prev)
            # ... and the slip velocities moved by less than v₀ (the law's nonlinearity scale)
            # since the previous iterate: the consistent tangent's basin of convergence
            if fr_same and len(fr):
                fr_same = bool(np.max(np.linalg.norm(self._dvt - self._dvt_prev, axis=1))
                               < self.slip_velocity)
            self._fr_state_prev = fr
            self._dvt_prev = self._dvt.copy()
            self._fr_settled = bool(comm.allreduce(int(fr_same), op=MPI.MIN))
        return self._settled

    def fingerprint(self) -> tuple:
        """Identifier of the contact state at the last :meth:`stable` call (the same on every
        rank): the solver uses it to recognise a Newton iteration that cycles."""
        return self._fingerprint

    def residual_floor(self) -> float:
        """Round-off level of this contact's residual norm at the last iterate (collective
        value of the last :meth:`stable` call): the gap of a node at X is known to about
        ε|X|, so its force S ρ h = −S ρ gap/dt to S ρ ε|X|/dt. Newton cannot reduce the
        residual below it; the solver accepts an iterate there (a tiny dt, where this floor
        exceeds the relative tolerance)."""
        return self._floor

    def force_norm(self) -> float:
        """ℓ² norm of this contact's nodal forces (normal and friction, every rank's owned
        nodes) at the last iterate (collective value of the last :meth:`stable` call): the
        force scale of ``SolverOptions.ftol``."""
        return self._force

    def end_increment(self, sim, dt: float):
        """Measure the true penetration of the updated nodes against the tools at t + dt."""
        b = self.boundary
        x_new = sim.vertex_positions()[b.vertices]
        pr, _ = self._project_all(x_new, self.t + dt, hessian=False)
        self._true_pen = float(np.max(-pr.gap, initial=-np.inf))
        # contact pressures of the converged increment: the explicit friction of the next one
        self._p_prev = self.pressures().copy()
