"""Power of the current solution (THEORY §14.5): plastic dissipation ∫ s:D dV.

For the power balance of a forming process at steady state: the power delivered by the tools
(force · velocity + torque · ω) equals the plastic dissipation plus the friction work (the
contact's ``{name}_friction_power`` history column) plus the penalty work (small). For the
Norton–Hoff law ``s:D = 2K z^(m−1) dev D : dev D`` (THEORY §1.1; ``= K z^(m+1)`` without the
regularisation). The pressure does no work: the discrete solution satisfies ``∫ q div v = 0``
for every pressure test function, the pressure itself included.
"""

from __future__ import annotations

import math

import dolfinx
import numpy as np
import ufl
from mpi4py import MPI

from fxcontact import compat
from fxcontact.kinematics import CartesianUpdate

__all__ = ["PlasticDissipation", "PressurePower", "PowerBalance", "plastic_dissipation",
           "penalty_power", "delivered_power", "end_velocities", "on_configuration"]


class PlasticDissipation:
    """``∫ s(D(v)) : D(v) dV`` of ``sim.w`` on the current mesh (collective: call on every rank).

    The form is compiled once; each call assembles it for the current velocity and geometry.
    Call it after an increment (``sim.step``/``sim.run`` callback): the velocity of the
    increment on the configuration at its end (updated Lagrangian), like the history columns
    of the tools."""

    def __init__(self, sim):
        mat = sim.material
        if not hasattr(mat, "stress_ufl"):
            raise ValueError(f"plastic dissipation needs a material with a deviatoric stress "
                             f"(stress_ufl), got {type(mat).__name__}")
        v, _ = ufl.split(sim.w)
        eps = ufl.sym(ufl.grad(v))
        self._form = compat.form(ufl.inner(mat.stress_ufl(eps), eps) * sim.space.dx)
        self._comm = sim.comm

    def __call__(self) -> float:
        return self._comm.allreduce(dolfinx.fem.assemble_scalar(self._form), op=MPI.SUM)


class PressurePower:
    """``∫ p div v dV`` of ``sim.w`` on the current mesh (collective). Zero for the plain
    incompressible update (the pressure is one of its own test functions); with the volume
    correction (``div v + ln(V/V⁰)/dt = 0``, THEORY §1.5) it is the power of the pressure on
    the volume given back, which enters the power balance: tool power = ∫ s:D − ∫ p div v
    + friction + penalty work."""

    def __init__(self, sim):
        v, p = ufl.split(sim.w)
        self._form = compat.form(p * ufl.div(v) * sim.space.dx)
        self._comm = sim.comm

    def __call__(self) -> float:
        return self._comm.allreduce(dolfinx.fem.assemble_scalar(self._form), op=MPI.SUM)


def plastic_dissipation(sim) -> float:
    """One-off ``∫ s:D dV`` of the current solution (compiles the form on first use per
    simulation; collective)."""
    pd = getattr(sim, "_fx_plastic_dissipation", None)
    if pd is None:
        pd = PlasticDissipation(sim)
        sim._fx_plastic_dissipation = pd
    return pd()


def on_configuration(sim, X0, fn):
    """Evaluate ``fn()`` with the mesh's vertices moved to ``X0`` (e.g. the start-of-increment
    configuration ``X − dt v`` on which the increment's equations were written), then put them
    back, also if ``fn`` raises."""
    g = sim.mesh.geometry.x
    vg = sim.space.vertex_geometry
    d = sim.space.gdim
    keep = g[vg, :d].copy()
    g[vg, :d] = X0
    try:
        return fn()
    finally:
        g[vg, :d] = keep


def _tool_point_velocities(contact, t):
    """(N, gdim) velocity of each contact node's tool at its projection point at ``t``."""
    nodes = contact.nodes
    return contact.tool_velocities(nodes.point, nodes.tool, t)


def penalty_power(contact, v, t):
    """Work rate of the normal penalty forces of a :class:`~fxcontact.NodalContact`,
    Σ r_n · (v_node − v_tool) over its contact nodes (``r_n``: the nodal force on the tool,
    ``v``: vertex velocities at the nodes' end-of-increment positions, :func:`end_velocities`;
    friction excluded, it is the contact's friction power), summed over ranks. ≈ 0 at steady
    state (the gap does not change); with it the power balance of a process is the discrete
    virtual-power identity."""
    b = contact.boundary
    if len(b.vertices):
        P = float(np.sum(contact.nodes.force * (v[b.vertices]
                                                - _tool_point_velocities(contact, t))))
    else:
        P = 0.0
    return b.comm.allreduce(P, op=MPI.SUM)


def delivered_power(contact, t, k=None) -> float:
    """Power the tools of a :class:`~fxcontact.NodalContact` deliver to the body at its last
    evaluation, −Σ (r_n + r_f,n) · v_tool(P_n) (the nodal forces on the tool times the tool's
    velocity at the projection points, at the increment's end time ``t``), summed over ranks:
    for a tool of rigid motion F·V + M·ω with the force and torque the body exerts on it,
    reversed. ``k``: one tool's (its index in the contact), else every tool's."""
    b = contact.boundary
    P = 0.0
    if len(b.vertices):
        nodes = contact.nodes
        sel = np.ones(len(b.vertices), bool) if k is None else nodes.tool == k
        r = (nodes.force + nodes.friction_force)[sel]
        P = -float(np.sum(r * _tool_point_velocities(contact, t)[sel]))
    return b.comm.allreduce(P, op=MPI.SUM)


def end_velocities(kinematics, x_t, v, dt):
    """The vertex velocities ``v`` turned to the vertices' end-of-increment positions,
    ``J v / dt`` with ``J = ∂X/∂v`` of the configuration update from ``x_t``: ``v`` itself for
    the Cartesian update; for the cylindrical update (rings) ``v`` rotated by the increment's
    angle ``dt v_θ / r`` about the ring axis, its hoop part scaled by ``r'/r``. It is the
    velocity the contact's forces work on (their residual is ``S ρ [h]₊ ∇h`` with
    ``∇h = −Jᵀn/dt``): with ``v`` itself a ring turning at ω would add ``F_n ω r sin(ω dt)``
    to the penalty power."""
    if isinstance(kinematics, CartesianUpdate):
        return v
    _, J, _ = kinematics.derivatives(x_t, v, dt)
    return np.einsum("nia,na->ni", J, v) / dt


class PowerBalance:
    """The power balance of a process, one row per increment (collective; THEORY §14.5).

    ``balance(row, tool_power, absorbed=0.0)``, called after each increment with its history row
    (``sim.step(dt).row``), returns the columns ``dissipation`` (∫ s:D dV − ∫ p div v dV on the
    configuration the increment was solved on, THEORY §1.5), ``friction_power`` (the contacts'
    ``{name}_friction_power``), ``penalty_power`` (:func:`penalty_power` of the contacts),
    ``power_in`` (``tool_power``), ``power_balance = tool_power / (D + P_f + absorbed) − 1``
    and ``power_balance_penalty`` (with the penalty work in the denominator: the discrete
    virtual-power identity, ≈ Newton's tolerance). ``tool_power`` is the power the tools
    deliver (roll torque × ω, pusher force × speed; None: :func:`delivered_power` of the
    contacts), ``absorbed`` any other power taken by a contributor of the process (a dashpot).

    The increment was solved on its start configuration ``x_t``: the balance keeps the vertex
    positions of its previous call (of its construction at first) and checks that the
    simulation's configuration update takes them with the increment's velocity to the current
    positions. Under the Cartesian update ``x_t = X − dt v`` also without them (a balance
    not called at every increment); under another update (the cylindrical one of rings) it
    must be called after every increment (ValueError otherwise). After a remesh its forms
    follow the new mesh; the row of the increment that ended with the remesh is then evaluated
    on the new mesh moved back by ``dt v`` under the Cartesian update (an approximation: a few
    % off) and is NaN under another update (its start configuration on the new mesh is not
    known). Keep one balance over the remeshes: a new one does not know where its first
    increment started."""

    def __init__(self, sim, contacts):
        self.sim = sim
        self.contacts = list(contacts)
        self._bind()
        self._x_start = sim.vertex_positions()

    def _bind(self):
        """The dissipation forms on the simulation's current mesh (again after a remesh)."""
        self._space = self.sim.space
        self._dissipation = PlasticDissipation(self.sim)
        self._pressure = PressurePower(self.sim)

    def _start_configuration(self, X, v, dt, remeshed=False):
        """The increment's start configuration (see the class); None where it is not known
        (an increment ended by a remesh, under another update than the Cartesian one)."""
        sim = self.sim
        if remeshed:
            return X - dt * v if isinstance(sim.kinematics, CartesianUpdate) else None
        x0 = self._x_start
        ok = x0.shape == X.shape
        if ok and len(X):
            err = np.max(np.abs(sim.kinematics.positions(x0, v, dt) - X))
            ok = bool(err <= 1e-9 * (np.max(np.abs(X)) + dt * np.max(np.abs(v))))
        if sim.comm.allreduce(int(ok), op=MPI.MIN):
            return x0
        if isinstance(sim.kinematics, CartesianUpdate):
            return X - dt * v
        raise ValueError(f"PowerBalance: the positions of its last call do not lead to the "
                         f"current ones with the increment's velocity under the "
                         f"{type(sim.kinematics).__name__}: call the balance after every "
                         f"increment (from the first one on) to know where it started")

    def __call__(self, row: dict, tool_power: float = None, absorbed: float = 0.0) -> dict:
        sim = self.sim
        remeshed = sim.space is not self._space
        if remeshed:   # forms on the new mesh
            self._bind()
        X = sim.vertex_positions()
        v = sim.w.x.array[sim.space.vertex_dofs]
        # the configuration the increment's equations live on
        X0 = self._start_configuration(X, v, row["dt"], remeshed)
        self._x_start = X
        if tool_power is None:
            tool_power = sum(delivered_power(c, sim.t) for c in self.contacts)
        Pf = sum(row.get(f"{c.name}_friction_power", 0.0) for c in self.contacts)
        if X0 is None:
            nan = math.nan
            return dict(dissipation=nan, friction_power=Pf, penalty_power=nan,
                        power_in=tool_power, power_balance=nan, power_balance_penalty=nan)
        D = on_configuration(sim, X0, self._dissipation)
        D -= on_configuration(sim, X0, self._pressure)
        V = end_velocities(sim.kinematics, X0, v, row["dt"])
        P_pen = sum(penalty_power(c, V, sim.t) for c in self.contacts)
        out = D + Pf + absorbed
        ok = out > 0
        return dict(dissipation=D, friction_power=Pf, penalty_power=P_pen, power_in=tool_power,
                    power_balance=tool_power / out - 1.0 if ok else math.nan,
                    power_balance_penalty=tool_power / (out + P_pen) - 1.0 if ok else math.nan)
