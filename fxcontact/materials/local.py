"""Viscoplasticity with a flow stress that depends on the state (THEORY §15): the material a user
gives (:class:`Viscoplastic`, a flow-stress law of :mod:`fxcontact.materials.flow` and a
regularisation) and the Norton–Hoff law it becomes on a mesh (:class:`LocalNortonHoff`).

On interval j of the equivalent strain rate, every law of :mod:`fxcontact.materials.flow` is a
power law σ₀ = C_j ε̄̇^(m_j) whose C_j and m_j depend on the state (ε̄, T) only; written as a
Norton–Hoff consistency K_j = C_j 3^(−(1+m_j)/2), the deviatoric stress is the Norton–Hoff one,
s = 2 K_j z^(m_j − 1) dev ε̇ with the regularised z = √3 ε̄̇_r (THEORY §1.1), and its consistent
tangent too, with m_j the local rate sensitivity. The state is taken at the start of the
increment (explicit in the state, implicit in the rate: THEORY §15), so K_j and m_j are per-cell
fields fixed during the Newton solve, and the interval is chosen at each quadrature point by the
current rate:

* the UFL forms read them as DG0 functions (``conditional`` on z between intervals): compiled
  once, updated in place each increment (:meth:`LocalNortonHoff.update`);
* the hand-written element kernel and the numba dual update read the same values per cell
  (:meth:`LocalNortonHoff.kernel_law`), plain :class:`~fxcontact.materials.NortonHoff` giving
  one interval with its own K and m (the same arithmetic: bit-identical results).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import logging

import dolfinx
import numpy as np
import ufl
from mpi4py import MPI

from fxcontact.materials.flow import FlowStress, norton_hoff_pieces
from fxcontact.materials.laws import Material, NortonHoff, _check_positive

__all__ = ["LocalNortonHoff", "Viscoplastic"]

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class Viscoplastic(Material):
    """Incompressible viscoplasticity in Norton–Hoff form with a flow stress σ₀(ε̄, ε̄̇, T)
    (THEORY §15): ``s = (2/3) σ₀/ε̄̇ ε̇``, the consistent tangent with the local rate
    sensitivity m_loc = ∂ln σ₀/∂ln ε̄̇.

    Args:
        flow: the flow-stress law (:class:`~fxcontact.materials.flow.PowerHardening`,
            :class:`~fxcontact.materials.flow.HanselSpittel`,
            :class:`~fxcontact.materials.flow.TabulatedFlowStress`), σ₀ in MPa, ε̄̇ in 1/s, T in
            °C.
        regularization: ε̇₀ [1/s] of the regularised rate ε̄̇_r² = ε̄̇² + ε̇₀² (THEORY §1.1),
            > 0; 1e-3–1e-4 × the process strain rate.
        temperature: the workpiece's uniform temperature [°C] for a law that depends on T (no
            heat equation yet: T stays at this value); None for a law without T.

    The cumulated strain ε̄ is the simulation's ``strain`` field (cell averages). ``K`` and
    ``m`` (of :meth:`reference`) are the law's Norton–Hoff values at ε̄ = 0 and ε̄̇ = 1/s: they
    size the contact penalty and a Norton friction law as a plain Norton–Hoff's do.
    """

    flow: FlowStress
    regularization: float = 1e-6
    temperature: float = None

    small_strain = False

    def __post_init__(self):
        if not isinstance(self.flow, FlowStress):
            raise ValueError(f"flow must be a flow-stress law of fxcontact.materials.flow "
                             f"(PowerHardening, HanselSpittel, TabulatedFlowStress), got "
                             f"{self.flow!r}")
        _check_positive("regularization (reference strain rate, 1/s)", self.regularization)
        if self.flow.uses_temperature and self.temperature is None:
            raise ValueError(f"{type(self.flow).__name__} depends on the temperature: give "
                             f"Viscoplastic(temperature=...) in °C")
        if self.temperature is not None:
            if not (isinstance(self.temperature, (int, float, np.floating, np.integer))
                    and math.isfinite(self.temperature)):
                raise ValueError(f"temperature must be a finite number in °C, got "
                                 f"{self.temperature!r}")
            self.flow.sigma0(0.0, 1.0, float(self.temperature))   # the law's own checks of T

    def _temperature(self) -> float:
        return 20.0 if self.temperature is None else float(self.temperature)

    def reference(self) -> NortonHoff:
        """The Norton–Hoff law of the flow stress at ε̄ = 0, ε̄̇ = 1/s (and the temperature):
        what scales a contact penalty or a Norton friction law."""
        K, m = norton_hoff_pieces(self.flow, np.zeros(1), self._temperature())
        j = int(np.searchsorted(self.flow.rate_nodes, 1.0, side="right"))
        return NortonHoff(float(K[0, j]), float(min(m[0, j], 1.0)), self.regularization)

    @property
    def K(self) -> float:
        return self.reference().K

    @property
    def m(self) -> float:
        return self.reference().m

    def flow_stress(self, strain_rate: float, strain: float = 0.0) -> float:
        """σ₀(ε̄, ε̄̇, T) [MPa] at the material's temperature."""
        return float(self.flow.sigma0(strain, strain_rate, self._temperature()))

    def linearized(self) -> NortonHoff:
        """The Newtonian fluid of the reference consistency: the start-up guess."""
        return self.reference().linearized()

    def on(self, space) -> "LocalNortonHoff":
        """The Norton–Hoff law of this material on ``space``'s mesh (its DG0 fields)."""
        ref = self.reference()
        return LocalNortonHoff(ref.K, ref.m, self.regularization, law=self,
                               fields=CellLaw(space, self.flow))

    def residual(self, v, p, w, q, dx, dt, u_prev=None):
        raise ValueError("a Viscoplastic material is assembled on a mesh: give it to "
                         "fxcontact.Simulation, or use material.on(space).residual(...)")


class CellLaw:
    """The per-cell Norton–Hoff pieces (K_j, m_j) of a flow-stress law on a mesh: DG0 functions
    for the UFL forms and arrays by cell index for the kernels (THEORY §15).

    Args:
        space: the :class:`~fxcontact.spaces.MixedSpace` (its DG0 space).
        flow: the flow-stress law.
    """

    def __init__(self, space, flow: FlowStress):
        self.flow = flow
        self.rate_nodes = np.asarray(flow.rate_nodes, dtype=float)
        #: the interval bounds in the regularised z = √3 ε̄̇_r of the kernels and the forms
        self.z_nodes = np.sqrt(3.0) * self.rate_nodes
        nint = self.rate_nodes.size + 1
        DG0 = space.DG0
        # (rank-local data in private attributes, read through properties: a set-up compared
        # between ranks, fxcontact.collective.digest, sees the law only)
        self._K = [dolfinx.fem.Function(DG0, name=f"consistency_{j}") for j in range(nint)]
        self._m = [dolfinx.fem.Function(DG0, name=f"rate_sensitivity_{j}") for j in range(nint)]
        msh = space.mesh
        tdim = msh.topology.dim
        imap = msh.topology.index_map(tdim)
        ncells = imap.size_local + imap.num_ghosts
        dm = np.asarray(DG0.dofmap.list.array, dtype=np.int64)
        self._cell_dofs = dm.reshape(ncells, -1)[:, 0]
        self._K_cells = np.zeros((ncells, nint))
        self._m_cells = np.zeros((ncells, nint))
        self._comm = msh.comm
        self._owned = DG0.dofmap.index_map.size_local
        #: cells whose state lay outside the law's data at the last update (clamped, all ranks)
        self.clamped = 0

    @property
    def K(self) -> list:
        """The DG0 functions K_j [MPa·s^m], one per rate interval."""
        return self._K

    @property
    def m(self) -> list:
        """The DG0 functions m_j, one per rate interval."""
        return self._m

    @property
    def cell_dofs(self) -> np.ndarray:
        """The DG0 dof of each local cell (owned and ghost)."""
        return self._cell_dofs

    @property
    def K_cells(self) -> np.ndarray:
        """(ncells, nint) K_j by cell index: the kernels' array."""
        return self._K_cells

    @property
    def m_cells(self) -> np.ndarray:
        """(ncells, nint) m_j by cell index."""
        return self._m_cells

    def update(self, strain: np.ndarray, temperature):
        """Set the pieces from the state: ``strain`` the DG0 array of ε̄ (owned and ghost
        dofs), ``temperature`` [°C] a number or a DG0 array. Collective (the clamped states
        are counted over the ranks and reported once, on the first update that has some)."""
        T = np.broadcast_to(np.asarray(temperature, dtype=float), strain.shape)
        K, m = norton_hoff_pieces(self.flow, np.asarray(strain, dtype=float), T)
        for j in range(K.shape[1]):
            self._K[j].x.array[:] = K[:, j]
            self._m[j].x.array[:] = m[:, j]
        self._K_cells[:] = K[self._cell_dofs]
        self._m_cells[:] = m[self._cell_dofs]
        n = self._owned
        clamped = self._comm.allreduce(
            int(self.flow.clamped(np.asarray(strain[:n], dtype=float), T[:n])), op=MPI.SUM)
        if clamped and not self.clamped:
            log.warning("the state (strain, temperature) of %d cells is outside the flow-stress "
                        "table: its edge values are used (reported once)", clamped)
        self.clamped = max(self.clamped, clamped)

    def ufl(self, z):
        """(K, m) at the regularised ``z`` (UFL): the DG0 fields of z's rate interval."""
        K, m = self.K[-1], self.m[-1]
        for j in range(len(self.z_nodes) - 1, -1, -1):
            below = ufl.lt(z, float(self.z_nodes[j]))
            K = ufl.conditional(below, self.K[j], K)
            m = ufl.conditional(below, self.m[j], m)
        return K, m


@dataclass(frozen=True)
class LocalNortonHoff(NortonHoff):
    """The Norton–Hoff law of a :class:`Viscoplastic` material on one mesh: K and m per cell
    and per rate interval (:class:`CellLaw`), set from the state by :meth:`update` before each
    increment. ``K`` and ``m`` are the reference values (:meth:`Viscoplastic.reference`)."""

    law: Viscoplastic = field(default=None, compare=False)
    fields: CellLaw = field(default=None, compare=False, repr=False)

    def law_ufl(self, z):
        return self.fields.ufl(z)

    def secant_law_ufl(self, z):
        return self.fields.ufl(z)

    def update(self, strain: np.ndarray, temperature=None):
        """The pieces from the cumulated strain (DG0 array) and the temperature (°C; the
        material's own when None)."""
        self.fields.update(strain, self.law._temperature() if temperature is None
                           else temperature)

    def kernel_law(self, ncells: int):
        """(K (ncells, nint), m (ncells, nint), z_nodes (nint − 1,)) for the kernels."""
        f = self.fields
        return f.K_cells, f.m_cells, f.z_nodes

    def linearized(self) -> NortonHoff:
        return self.law.linearized()
