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
from typing import Dict, List, Optional

import numpy as np
from mpi4py import MPI

import dolfinx.fem

from fxcontact import compat
from fxcontact.contact.boundary import ContactBoundary
from fxcontact.contact.friction import (LAW_COULOMB, LAW_NONE, LAW_NORTON, LAW_TRESCA,
                                        FrictionLaw, Frictionless, friction_kernel,
                                        friction_kernel_numpy)
from fxcontact.contact.penalty import penalty_kernel, penalty_kernel_numpy
from fxcontact.kinematics import CartesianUpdate
from fxcontact.materials import LinearElastic, NortonHoff
from fxcontact.collective import together
from fxcontact.petsc import ContributorError, NodalTerms
from fxcontact.tools.base import Tool, unit_vector

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

#: a node sticks if its slip speed |Δv_t| is below this many v₀ (diagnostics only)
STICK_FACTOR = 3.0

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


def _flip_hint(tool) -> str:
    """How to turn a tool's surface the other way (:meth:`NodalContact._check_placement`)."""
    base = getattr(tool, "tool", tool)   # a MovedTool's tool
    if hasattr(base, "normal") and not hasattr(base, "inside"):
        return (f"flip the normal (normal={tuple(0.0 - float(v) for v in base.normal)}: it must "
                f"point out of the tool, towards the body)")
    if hasattr(base, "inside"):
        return f"set inside={not base.inside} (inside=True: the body is inside the surface)"
    return "flip the orientation of its surface (its normals must point towards the body)"


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


class NodalContact:
    """Nodal penalty contact of a :class:`ContactBoundary` against rigid tools.

    Args:
        boundary: the contact nodes.
        tools: one tool or a sequence of tools.
        scheme: one of :data:`SCHEMES`. Default: ``"implicit"`` in velocity form,
            ``"implicit-exact"`` in displacement form (``"implicit"`` if a tool has no gap
            Hessian): a dolfinx problem has no other fxcontact solver settings to tune, and the
            exact tangent takes the neo-Hookean block of ``demos/demo_hyperelastic_contact.py``
            from 114 to 35 Newton iterations (``benchmarks/README.md``).
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
            (done by :class:`~fxcontact.petsc.ContactProblem`).
        modulus: reference modulus E* [stress] of a displacement-form ``beta``.

    Friction (THEORY §9) acts on the nodes in contact, against the velocity relative to the
    tool's material point at the projection (tools that translate and rotate about their own
    axis). The shear flow stress k of Tresca limits and the consistency K of viscoplastic
    friction come from the Norton–Hoff material (k = K (√3 ε̄̇)^m with the nodal strain rate of
    the increment's predictor, regularised like the material); other materials need
    ``shear_limit``/``K`` in the law.
    """

    def __init__(self, boundary: ContactBoundary, tools, scheme: Optional[str] = None,
                 penalty: Optional[float] = None, beta: Optional[float] = None,
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
            self._penalty_given = penalty
            self.strain_rate = strain_rate
            self.sticky_gap = float(sticky_gap)
            #: factor on ρ of the current evaluations (< 1 in the softened first stage of a
            #: Newton solve with penalty continuation, SolverOptions.penalty_continuation)
            self.penalty_scale = 1.0
            self.kernel = penalty_kernel if backend == "numba" else penalty_kernel_numpy
            self.friction_kernel = friction_kernel if backend == "numba" else friction_kernel_numpy
            self.friction = self._friction_per_tool(friction, tools)
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
        self.rho = penalty
        self.stiffness = None
        if formulation == "displacement":
            # gap stiffness k [stress/length]; rho = k dt at each load step
            if gap_stiffness is not None or penalty is not None:
                self.stiffness = float(gap_stiffness if gap_stiffness is not None else penalty)
            else:
                if modulus is None or not (math.isfinite(modulus) and modulus > 0):
                    raise ValueError("the displacement formulation needs the gap stiffness: give "
                                     "penalty= (k, stress/length) or beta= with modulus= (E*, "
                                     f"k = beta E*/h_e); got modulus={modulus!r}")
                self.stiffness = self.beta * float(modulus) / self.element_size
            self.rho = None
            self._u_t = None
            self._v_hat = np.zeros((len(boundary), self.gdim))
        self.sim = None
        self.t = 0.0
        self.dt = 1.0
        n = len(boundary)
        self._h = np.zeros(n)
        self._tool = np.zeros(n, dtype=np.int32)
        self._feature = np.zeros(n, dtype=np.int64)
        self._status_prev = None
        self._settled = False
        #: contact state of the last iterates (in contact, tool, feature, projection
        #: fall-back per node), to say what changes over a cycle (:meth:`cycle_hint`)
        self._recent = deque(maxlen=5)   # the longest cycle the solver looks for, 4, + 1
        self._floor = 0.0
        self._v_last = np.zeros((n, self.gdim))
        self._rho_eval = 0.0
        self._fingerprint = ()
        self._ever_active = np.zeros(n, dtype=bool)
        self._placement_checked = False
        self._fallbacks = 0
        self._fallbacks_all = 0
        self._fields = None
        self._r = np.zeros((n, self.gdim))
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
        self._rate_forms = None

    # ------------------------------------------------------------------ friction set-up
    @staticmethod
    def _friction_per_tool(friction, tools) -> List[FrictionLaw]:
        """One law per tool from a law, a {tool or name: law} dict or a sequence."""
        def check(law, where):
            if not isinstance(law, FrictionLaw):
                raise ValueError(f"friction {where} must be a friction law (Coulomb, Tresca, "
                                 f"Norton, Frictionless), got {law!r}")
            return law
        if friction is None:
            return [Frictionless() for _ in tools]
        if isinstance(friction, FrictionLaw):
            return [friction for _ in tools]
        if isinstance(friction, dict):
            names = [t.name for t in tools]
            out = [Frictionless() for _ in tools]
            for key, law in friction.items():
                if isinstance(key, Tool):
                    idx = [k for k, t in enumerate(tools) if t is key]
                    label = key.name
                elif isinstance(key, str):
                    idx = [k for k, nm in enumerate(names) if nm == key]
                    label = key
                else:
                    raise ValueError(f"friction keys must be tools or tool names, got {key!r}")
                if not idx:
                    raise ValueError(f"friction given for tool '{label}', which is not one of "
                                     f"this contact's tools {names}")
                if len(idx) > 1:
                    raise ValueError(f"friction key '{label}' matches several tools: give the "
                                     f"tools distinct names")
                out[idx[0]] = check(law, f"for tool '{label}'")
            return out
        if isinstance(friction, (list, tuple)):
            if len(friction) != len(tools):
                raise ValueError(f"friction sequence has {len(friction)} laws for "
                                 f"{len(tools)} tools")
            return [check(law, f"[{k}]") for k, law in enumerate(friction)]
        raise ValueError(f"friction must be a friction law, a dict or a sequence, "
                         f"got {friction!r}")

    def _vertex_strain_rate(self, sim) -> np.ndarray:
        """Equivalent strain rate of the current ``sim.w`` at the contact vertices: volume
        average over the adjacent cells (lumped P1 projection; collective)."""
        import ufl
        import dolfinx.fem.petsc
        from petsc4py import PETSc
        if self._rate_forms is None:
            Q1 = compat.function_space(sim.mesh, ("Lagrange", 1))
            q = ufl.TestFunction(Q1)
            v = ufl.split(sim.w)[0]
            e = ufl.sym(ufl.grad(v))
            de = e - ufl.tr(e) / self.gdim * ufl.Identity(self.gdim)
            rate = ufl.sqrt(2.0 / 3.0 * ufl.inner(de, de))
            dx = sim.space.dx
            self._rate_forms = (compat.form(rate * q * dx), compat.form(q * dx),
                                self.boundary.q1_dofs(Q1))
        f_rate, f_vol, q1 = self._rate_forms
        vals = []
        for f in (f_rate, f_vol):
            b = dolfinx.fem.petsc.assemble_vector(f)
            b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
            vals.append(b.getArray(readonly=True)[q1].copy() if len(q1) else np.zeros(0))
            b.destroy()
        return vals[0] / vals[1]

    def _begin_friction(self, sim, t: float, dt: float):
        """Material data at the nodes and the slip regularisation (collective)."""
        mat = sim.material
        for law, tool in zip(self.friction, self.tools):
            if law.needs_shear_limit and law.shear_limit is None and \
                    not isinstance(mat, NortonHoff):
                raise ValueError(f"friction on tool '{tool.name}' needs the shear flow stress k "
                                 f"of the body, which a {type(mat).__name__} material does not "
                                 f"define: give shear_limit= in the friction law")
            if law.needs_consistency and law.K is None and not isinstance(mat, NortonHoff):
                raise ValueError(f"viscoplastic friction on tool '{tool.name}' needs the "
                                 f"consistency K, which a {type(mat).__name__} material does not "
                                 f"define: give K= in the Norton law")
        need_k = any(law.needs_shear_limit and law.shear_limit is None for law in self.friction)
        need_K = any(law.needs_consistency and law.K is None for law in self.friction)
        if isinstance(mat, NortonHoff) and need_K:
            self._K_node = np.full(len(self.boundary), mat.K)
        if isinstance(mat, NortonHoff) and need_k:
            rate = self._vertex_strain_rate(sim)
            z = np.sqrt(3.0 * rate**2 + 3.0 * mat.regularization**2)
            self._k_node = mat.K * z**mat.m
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
    def _resolve_penalty(self, sim, dt):
        if self.formulation == "displacement":
            return self.stiffness * dt
        if self.gap_stiffness is not None:
            return self.gap_stiffness * dt
        if self._penalty is not None:
            return self._penalty
        if isinstance(sim.material, NortonHoff):
            if self.strain_rate is None:
                # representative strain rate: mean of the first increment's initial guess;
                # the start-up solve does not see the tools, so a body driven by velocity
                # conditions against static tools (drawing) moves rigidly in it: then the
                # speed of the body relative to the tools over the body's size
                rate = sim.mean_strain_rate()
                v = self.boundary.velocities(sim.w)
                speed = max(float(np.max(np.linalg.norm(
                    v - tool.velocity(_pad3(self.x_t), self.t)[:, : self.gdim], axis=1),
                    initial=0.0)) for tool in self.tools)
                speed = self.boundary.comm.allreduce(speed, op=MPI.MAX)
                rate_kin = speed / sim.volume() ** (1.0 / self.gdim)
                if not rate > 1e-6 * rate_kin:
                    rate = rate_kin
                if not rate > 0:
                    raise ValueError("cannot estimate a representative strain rate for the "
                                     "penalty (the body and the tools are at rest): give "
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
            self._v_ref = self._tool_velocities(pr0.point, tool0, t)
            self._v_tool_fixed = self._v_ref
        elif self.scheme == "quasi-implicit":
            v_hat = sim.w_prev.x.array[b.dofs]
            x_pred = self.kin.positions(self.x_t, v_hat, dt)
            pr, tool_idx = self._project_all(x_pred, t + dt, hessian=False)
            self._fixed = pr
            self._fixed_tool = tool_idx
            self._v_ref = v_hat.copy()
            self._v_tool_fixed = self._tool_velocities(pr.point, tool_idx, t + dt)
        if self.has_friction:
            self._begin_friction(sim, t, dt)

    def _check_placement(self, x_body: np.ndarray, t: float):
        """ValueError (on every rank) if a tool holds the whole body at the first increment:
        every vertex of the body is on the tool's side of its surface, none further out than
        the burial limit and some deeper in than it (a Plane whose normal points into the body,
        a curved tool with the wrong ``inside``). The contact could never act: no node would
        ever be in contact, the force would stay 0."""
        lim = self.max_initial_penetration
        comm = self.boundary.comm
        for tool in self.tools:
            gap = tool.project(_pad3(x_body), t, hessian=False).gap
            hi = comm.allreduce(float(np.max(gap, initial=-np.inf)), op=MPI.MAX)
            lo = comm.allreduce(float(np.min(gap, initial=np.inf)), op=MPI.MIN)
            if hi <= lim and lo < -lim:
                raise ValueError(
                    f"tool '{tool.name}' of contact '{self.name}' holds the whole body at t = "
                    f"{t:.6g}: every node of the body is on the tool's side of its surface (down "
                    f"to {-lo:.3g} deep), so the contact could never act (no contact node, zero "
                    f"force). The tool's surface is turned the wrong way: "
                    f"{_flip_hint(tool)}")
        self._placement_checked = True

    def begin_step(self, t: float, dt: float, u):
        """Start a load step t → t + dt of the displacement formulation from the displacement
        Function ``u`` (its current content is the converged uᵗ of the previous step, or the
        initial state). Collective. Called by :class:`~fxcontact.petsc.ContactProblem`."""
        if self.formulation != "displacement":
            raise ValueError("begin_step is for formulation='displacement'; the velocity form "
                             "is driven by Simulation (begin_increment)")
        if not (math.isfinite(dt) and dt > 0):
            raise ValueError(f"the load step must advance the time: dt = {dt!r}")
        for law, tool in zip(self.friction, self.tools):
            if (law.needs_shear_limit and law.shear_limit is None) or \
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

    def _tool_velocities(self, points: np.ndarray, tool_idx: np.ndarray, t: float):
        """(N, gdim) material velocity of each node's tool at its projection point."""
        vt = np.zeros((len(points), 3))
        for k, tool in enumerate(self.tools):
            sel = tool_idx == k
            if np.any(sel):
                vt[sel] = tool.velocity(points[sel], t)
        return vt[:, : self.gdim]

    def scale_penalty(self, factor: float):
        """Multiply the penalty ρ by ``factor`` in the following evaluations (1 restores it);
        used by the penalty continuation of :class:`~fxcontact.solver.NewtonSolver`."""
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
            self._cur_proj = pr
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
        self._cur_proj = pr
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
        if jacobian and self.formulation == "displacement":
            K = K / self.dt
        return NodalTerms(b.dofs, r, K if jacobian else None)

    #: gap (× element size) below which a free node may be predicted to enter contact
    PREDICTION_GAP = 0.25

    def active_set_prediction(self, step: np.ndarray):
        """The nodes whose contact status the Newton step ``step`` would change, for the
        active-set prediction of :class:`~fxcontact.prediction.ActiveSetPrediction`.

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

        Args:
            step: the owned part of the Newton step δ (x_new = x + δ), indexed like the
                boundary's dofs.

        Returns:
            ``(dofs (k, d), g (k, d), dc (k,), o (k,))`` for the k selected owned nodes (the
            gradient with respect to the unknown: ``g/dt`` in displacement form).
        """
        d = self.gdim
        dofs = self.boundary.dofs
        scale = 1.0 / self.dt if self.formulation == "displacement" else 1.0
        g = self._g * scale
        dl = np.where(dofs >= 0, step[np.maximum(dofs, 0)], 0.0)
        want = self._h + np.einsum("nd,nd->n", g, dl) > 0.0
        A = self._tangent_active
        c = self.boundary.areas * self._rho_eval
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
            v_tool = self._tool_velocities(pr.point, tool_idx, self.t + self.dt)
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
        v0, active, theta`` (also used by :class:`~fxcontact.mill.IdleRotation` to evaluate
        the friction of one tool at another rotation speed)."""
        d = self.gdim
        nrm = np.ascontiguousarray(self._cur_proj.normal[:, :d])
        laws = self.friction
        code = np.array([law.code for law in laws], dtype=np.int64)[tool_idx]
        mu = np.array([getattr(law, "mu", 0.0) for law in laws])[tool_idx]
        mbar = np.array([law.mbar if getattr(law, "mbar", None) is not None else np.nan
                         for law in laws])[tool_idx]
        k_user = np.array([law.shear_limit if getattr(law, "shear_limit", None) is not None
                           else np.nan for law in laws])[tool_idx]
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

    def cycle_hint(self, period: int = 1) -> str:
        """What changes over a cycle of ``period`` Newton iterations (counted over the whole
        cycle, each node once), and the usual cure: nodes entering and leaving contact,
        switching between tools, between facets/features of one tool, or between the smooth
        projection and its flat fall-back; or nothing (a residual that stagnates)."""
        recent = list(self._recent)[-(period + 1):]
        comm = self.boundary.comm
        n = np.zeros(4, dtype=np.int64)
        if len(recent) > 1:
            act, tool, feat, fb = (np.array([r[k] for r in recent]) for k in range(4))
            enter = np.any(act != act[-1], axis=0)
            both = np.all(act, axis=0)
            tools = both & np.any(tool != tool[-1], axis=0)
            feats = both & ~tools & np.any(feat != feat[-1], axis=0)
            fall = ~enter & ~tools & ~feats & np.any(fb != fb[-1], axis=0)
            n = np.array([np.sum(enter), np.sum(tools), np.sum(feats), np.sum(fall)])
        n_in, n_tool, n_feat, n_fall = (int(k) for k in comm.allreduce(n, op=MPI.SUM))
        who = f"contact '{self.name}'"
        parts = []
        if n_in:
            parts.append(f"{n_in} node(s) enter and leave contact")
        if n_tool:
            names = " and ".join(f"'{t.name}'" for t in self.tools)
            parts.append(f"{n_tool} node(s) switch between the tools {names} (where the tools "
                         f"meet or overlap)")
        if n_feat:
            parts.append(f"{n_feat} node(s) switch between facets/features of their tool "
                         f"(facet switching, THEORY §6)")
        if n_fall:
            parts.append(f"{n_fall} node(s) switch between the smooth projection and its flat "
                         f"fall-back (a hole or a sharp edge of the faceted tool)")
        if not parts:
            return (f"{who}: no node changes its contact status, tool, facet or projection "
                    f"over the cycle: the residual stagnates, not the contact state")
        cures = []
        if n_feat or n_fall:
            cures.append("smooth the faceted tool (mode='nagata') or repair its surface")
        if n_tool:
            cures.append("round or separate the tools where they meet")
        cures.append(self._dt_advice())
        return f"{who}: " + "; ".join(parts) + " over the cycle: " + ", or ".join(cures)

    def _dt_advice(self) -> str:
        """"reduce dt", unless dt is already so small that the gap's round-off ε|X|/dt is
        more than 1e-6 of the nodes' speeds (collective values of the last iterate)."""
        comm = self.boundary.comm
        x_t = getattr(self, "x_t", np.zeros((0, self.gdim)))
        X = comm.allreduce(float(np.max(np.abs(x_t), initial=0.0)), op=MPI.MAX)
        v = comm.allreduce(float(np.max(np.linalg.norm(self._v_last, axis=1), initial=0.0)),
                           op=MPI.MAX)
        eps = np.finfo(float).eps
        if v > 0 and eps * X / self.dt > 1e-6 * v:
            return (f"a larger dt: dt = {self.dt:.3g} is so small that the positions x + dt v "
                    f"(|x| up to {X:.3g}, |v| up to {v:.3g}) keep fewer than 6 digits of the "
                    f"motion; dt >= {1e6 * eps * X / v:.3g} keeps them")
        return "reduce dt (cut-back)"

    # ------------------------------------------------------------------ checkpoint
    def checkpoint_state(self) -> dict:
        """What a resumed run needs (:mod:`fxcontact.checkpoint`): the penalty resolved from β
        at the first increment, the representative strain rate, the slip regularisation and the
        nodal pressures of the last converged increment (explicit friction). The tools are
        immutable and move as functions of time: restoring t restores their positions, except
        for motions whose rates are set during the run (:class:`fxcontact.mill.ControlledMotion`:
        their ``checkpoint_state()`` is saved too, under ``motions``)."""
        from fxcontact.checkpoint import PerVertex
        return {"name": self.name, "scheme": self.scheme,
                "tools": [t.name for t in self.tools],
                "motions": [t.motion.checkpoint_state()
                            if hasattr(getattr(t, "motion", None), "checkpoint_state") else None
                            for t in self.tools],
                "penalty": self._penalty, "strain_rate": self.strain_rate,
                "slip_velocity": self.slip_velocity,
                "p_prev": PerVertex(self.boundary.vertices, self._p_prev)}

    def setup_signature(self) -> dict:
        """The contact's parameters as given (not those resolved during the run): a checkpoint
        is resumed only with the same (:meth:`Simulation.resume
        <fxcontact.simulation.Simulation.resume>` names the one that differs)."""
        from fxcontact.checkpoint import describe
        tools = []
        for t in self.tools:
            base = getattr(t, "tool", t)   # a MovedTool's tool
            geometry = base._repr_fields() if hasattr(base, "_repr_fields") else repr(base)
            tools.append({"type": type(t).__name__, "name": t.name,
                          "geometry": type(base).__name__ if " at 0x" in geometry else geometry,
                          "motion": describe(t.motion)})
        return {"name": self.name, "scheme": self.scheme, "formulation": self.formulation,
                "penalty": self._penalty_given, "beta": self.beta,
                "gap_stiffness": self.gap_stiffness,
                "sticky_gap": self.sticky_gap, "friction": describe(self.friction),
                "friction_mode": self.friction_mode, "slip_velocity": self._slip_velocity_user,
                "tools": tools}

    def restore_state(self, state: dict):
        from fxcontact.checkpoint import CheckpointError
        mine = {"name": self.name, "scheme": self.scheme, "tools": [t.name for t in self.tools]}
        theirs = {k: state.get(k) for k in mine}
        if theirs != mine:
            raise CheckpointError(f"the checkpoint's contact {theirs} is not this contact {mine}")
        if self._penalty is None and self.gap_stiffness is None:  # resolved from beta
            self._penalty = state["penalty"]
            self.rho = self._penalty
        if self.strain_rate is None:
            self.strain_rate = state["strain_rate"]
        if self._slip_velocity_user is None:
            self.slip_velocity = state["slip_velocity"]
        self._p_prev = np.asarray(state["p_prev"].at(self.boundary.vertices), dtype=np.float64)
        for t, m in zip(self.tools, state.get("motions") or [None] * len(self.tools)):
            has = hasattr(getattr(t, "motion", None), "restore_state")
            if (m is None) == has:
                raise CheckpointError(f"the checkpoint's motion of tool '{t.name}' "
                                      f"({'none' if m is None else 'rates set during the run'}) "
                                      f"does not fit this tool's {type(t.motion).__name__}")
            if m is not None:
                t.motion.restore_state(m)

    # ------------------------------------------------------------------ diagnostics / output
    def pressures(self) -> np.ndarray:
        """(N,) nodal contact pressures ρ[h]₊ of the last evaluation."""
        if self.rho is None:  # before the first increment resolves ρ from β
            return np.zeros_like(self._h)
        return self.rho * self.penalty_scale * np.maximum(self._h, 0.0)

    def end_increment(self, sim, dt: float):
        """Measure the true penetration of the updated nodes against the tools at t + dt."""
        b = self.boundary
        x_new = sim.vertex_positions()[b.vertices]
        pr, _ = self._project_all(x_new, self.t + dt, hessian=False)
        self._true_pen = float(np.max(-pr.gap, initial=-np.inf))
        # contact pressures of the converged increment: the explicit friction of the next one
        self._p_prev = self.pressures().copy()

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
            F = self.tool_force(k)
            for j, c in enumerate("xyz"[: self.gdim]):
                out[f"{tool.name}_force_{c}"] = float(F[j])
            if self.has_friction:
                Ff = self.tool_force(k, friction_only=True)
                for j, c in enumerate("xyz"[: self.gdim]):
                    out[f"{tool.name}_friction_{c}"] = float(Ff[j])
                out[f"{tool.name}_torque"] = self.tool_torque(k)
        if self.has_friction:
            on = self._branch > 0
            slip = np.linalg.norm(self._dvt, axis=1)
            stick = on & (slip < STICK_FACTOR * self.slip_velocity)
            out[f"{self.name}_stick"] = comm.allreduce(int(np.sum(stick)), op=MPI.SUM)
            out[f"{self.name}_slip"] = comm.allreduce(int(np.sum(on & ~stick)), op=MPI.SUM)
            # power dissipated by friction Σ S τ·(−Δv_t) = Σ r_f·Δv_t ≥ 0
            out[f"{self.name}_friction_power"] = comm.allreduce(
                float(np.sum(self._rf * self._dvt)), op=MPI.SUM)
            out[f"{self.name}_slip_velocity"] = float(self.slip_velocity)
        return out

    def tool_force(self, k: int = 0, friction_only: bool = False) -> np.ndarray:
        """Force on tool k (gdim,) from the last evaluation, summed over ranks: contact plus
        friction (= −the force on the body), or the friction part only."""
        sel = self._tool == k
        r = self._rf if friction_only else self._r + self._rf
        return self.boundary.comm.allreduce(
            np.sum(r[sel], axis=0) if np.any(sel) else np.zeros(self.gdim), op=MPI.SUM)

    def tool_torque(self, k: int = 0) -> float:
        """Torque on tool k about its own (rotation) axis from the last evaluation, summed over
        ranks: w · Σ (P_n − a) × f_n with f_n the nodal force on the tool (contact + friction)
        at the projection point P_n. For a roll this is the driving torque (sign: the torque
        the body exerts on the tool, right-hand rule about the axis)."""
        tool = self.tools[k]
        sel = self._tool == k
        t = self.t if self.scheme == "explicit" else self.t + self.dt
        w = unit_vector(tool.motion.axis, "tool axis")
        a = tool.motion.axis_point_at(t)
        M = 0.0
        if np.any(sel):
            f = np.zeros((int(np.sum(sel)), 3))
            f[:, : self.gdim] = (self._r + self._rf)[sel]
            arm = self._point[sel] - a
            M = float(np.sum(np.cross(arm, f) @ w))
        return self.boundary.comm.allreduce(M, op=MPI.SUM)

    def output_fields(self):
        if self._fields is None:
            b = self.boundary
            Q1 = compat.function_space(b.mesh, ("Lagrange", 1))
            p = dolfinx.fem.Function(Q1, name=f"{self.name}_pressure")
            s = dolfinx.fem.Function(Q1, name=f"{self.name}_status")
            self._fields = (p, s)
            if self.has_friction:
                V1 = compat.vector_function_space(b.mesh, "Lagrange", 1)
                self._fields += (dolfinx.fem.Function(V1, name=f"{self.name}_friction_stress"),)
        return list(self._fields)

    def update_output_fields(self):
        fields = self.output_fields()
        p, s = fields[:2]
        q = self.boundary.q1_dofs(p.function_space)
        p.x.array[:] = 0.0
        s.x.array[:] = 0.0
        p.x.array[q] = self.pressures()
        s.x.array[q] = (self._h > 0).astype(float)
        if self.has_friction:
            f = fields[2]
            f.x.array[:] = 0.0
            qv = self.boundary.q1_dofs(f.function_space)   # block dofs of the vertices
            f.x.array.reshape(-1, self.gdim)[qv] = self._tau
        for fn in fields:
            fn.x.scatter_forward()
