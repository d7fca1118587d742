"""The public per-node view of a :class:`~fxcontact.contact.NodalContact`: its contact nodes
and their state at the contact's last evaluation (:attr:`NodalContact.nodes
<fxcontact.contact.NodalContact.nodes>`), for outputs, controllers and process measures.

Signs. A tool's signed distance ``gap`` is positive in free space and negative inside the tool
(a penetration); its ``normal`` is the tool's outward unit normal at the closest point (from
the tool towards the body). The contact works on ``h = −gap/dt`` (positive: in contact, a
penetration at the end of the increment), the penalty pressure is ``p = ρ[h]₊`` and the normal
nodal force on the tool ``S ρ [h]₊ ∇h`` (``= −S p n`` with the Cartesian update).

Units: lengths in mm, times in s, forces in N, pressures in MPa (any consistent set works: the
view adds no constant).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import Tuple

import numpy as np

__all__ = ["ContactNodes", "read_only"]


def read_only(a: np.ndarray) -> np.ndarray:
    """A read-only view of ``a`` (no copy; ``a`` itself keeps its flags): writing through it
    raises ``ValueError: assignment destination is read-only``."""
    v = np.asarray(a).view()
    v.setflags(write=False)
    return v


@dataclass(frozen=True, eq=False, repr=False)
class ContactNodes:
    """The contact nodes of a :class:`~fxcontact.contact.NodalContact` and their state at the
    contact's last evaluation (``NodalContact.nodes``): a frozen snapshot whose arrays are
    read-only views of the contact's own arrays (no copy; a later evaluation makes new
    arrays and a new view, it does not change this one).

    Rank-local: the nodes are the contact vertices this rank owns (every vertex is in the view
    of exactly one rank), in the order of ``contact.boundary.vertices``; sums over the nodes
    need an ``allreduce``. Before the first evaluation every state array is zero.

    Attributes:
        vertices: (n,) local indices of the owned contact vertices (``boundary.vertices``).
        dofs: (n, gdim) local dofs of their vector components in the unknown's Function.
        area: (n,) lumped nodal areas S_n (mm²) of the evaluation.
        positions: (n, gdim) positions X of the nodes at the end of the increment for the
            current iterate (mm): ``kinematics.positions(xᵗ, v, dt)``, the mesh's positions
            once the increment is accepted (``X_ref + u`` in displacement form).
        point: (n, 3) closest points on each node's tool (mm; 3 columns also in 2D): of X
            (implicit schemes), of xᵗ at t (explicit) or of the predictor xᵗ + dt v̂
            (quasi-implicit) — the projection the contact's forces act at.
        normal: (n, gdim) the tool's outward unit normal at ``point`` (towards the body).
        h: (n,) the contact constraint h = −gap/dt (mm/s; > 0: in contact), linearised in v
            about the fixed projection for the explicit and quasi-implicit schemes.
        grad_h: (n, gdim) ∂h/∂v (dimensionless): −normal with the Cartesian update, −Jᵀn/dt
            with another one (J = ∂X/∂v).
        force: (n, gdim) normal contact force of each node on its tool (N): S ρ [h]₊ ∇h (the
            force on the body is its opposite); zero where ``h <= 0``.
        friction_force: (n, gdim) friction force of each node on its tool (N), tangential
            (zero without friction).
        tool: (n,) index of each node's tool in ``tool_names`` (the tool of smallest gap).
        tool_names: the names of the contact's tools, in the contact's order.
        dt: the increment (load step) of the evaluation (s).
        penalty: ρ of the evaluation (MPa·s/mm, with the penalty scale of a continuation).

    The derived arrays (:attr:`gap`, :attr:`active`, :attr:`pressure`) are computed at their
    first use and kept (read-only too).
    """

    vertices: np.ndarray
    dofs: np.ndarray
    area: np.ndarray
    positions: np.ndarray
    point: np.ndarray
    normal: np.ndarray
    h: np.ndarray
    grad_h: np.ndarray
    force: np.ndarray
    friction_force: np.ndarray
    tool: np.ndarray
    tool_names: Tuple[str, ...]
    dt: float
    penalty: float

    @cached_property
    def gap(self) -> np.ndarray:
        """(n,) end-of-increment gap −dt·h (mm; negative: penetration), the one the penalty
        acts on (``{name}_penetration_predicted`` is the largest −gap over the ranks)."""
        return read_only(-self.dt * self.h)

    @cached_property
    def active(self) -> np.ndarray:
        """(n,) bool: the nodes in contact (h > 0, a nonzero normal force)."""
        return read_only(self.h > 0)

    @cached_property
    def pressure(self) -> np.ndarray:
        """(n,) contact pressure ρ[h]₊ (MPa) of the evaluation (``NodalContact.pressures()``
        at that evaluation)."""
        return read_only(self.penalty * np.maximum(self.h, 0.0))

    def __len__(self) -> int:
        return len(self.vertices)

    def __repr__(self) -> str:
        return (f"ContactNodes({len(self)} owned nodes, {int(np.sum(self.active))} in contact, "
                f"tools {list(self.tool_names)})")

    @classmethod
    def of(cls, contact, positions: np.ndarray, normal: np.ndarray) -> "ContactNodes":
        """The view of ``contact``'s current per-node arrays (built by the contact itself at
        each evaluation; ``positions`` and ``normal`` those of the evaluation)."""
        b = contact.boundary
        return cls(vertices=read_only(b.vertices), dofs=read_only(b.dofs),
                   area=read_only(b.areas), positions=read_only(positions),
                   point=read_only(contact._point), normal=read_only(normal),
                   h=read_only(contact._h), grad_h=read_only(contact._g),
                   force=read_only(contact._r), friction_force=read_only(contact._rf),
                   tool=read_only(contact._tool),
                   tool_names=tuple(t.name for t in contact.tools), dt=float(contact.dt),
                   penalty=float(contact._rho_eval))
