"""Mesh health of simplex cells: signed measure and shape quality, vectorised.

The quality is the normalised shape ratio

    q = 12 (3|V|)^(2/3) / Σ l²   (tetrahedron),     q = 4√3 |A| / Σ l²   (triangle),

Σ l² the sum of the squared edge lengths: 1 for the regular simplex, → 0 for a flat one. The
:class:`~fxcontact.simulation.Simulation` checks its initial mesh (degenerate or tangled cells)
and records per increment the smallest quality (made negative for a cell whose signed volume
changed sign) and the smallest ratio of a cell's signed volume to its initial one, and rejects a
geometry update that would turn a cell inside out (:class:`MeshHealth`).
"""

from __future__ import annotations

import logging
import math
from typing import Dict, Optional

import numpy as np
from mpi4py import MPI

from fxcontact import compat

__all__ = ["simplex_measures", "degenerate_cells", "overlapping_facets", "DEGENERATE_VOLUME",
           "DEGENERATE_QUALITY", "MeshHealth", "INVERSION"]

log = logging.getLogger(__name__)

#: message prefix of an increment rejected because an element would invert
INVERSION = "element inverted"


def simplex_measures(P: np.ndarray):
    """Signed measure and shape quality of simplices.

    Args:
        P: (N, d + 1, d) vertex coordinates of N triangles (d = 2) or tetrahedra (d = 3).
    Returns:
        ``(measure, quality)``: (N,) signed area/volume det[P1−P0, …]/d! and (N,) q in [0, 1].
    """
    P = np.asarray(P, dtype=np.float64)
    n, nv, d = P.shape
    if nv != d + 1 or d not in (2, 3):
        raise ValueError(f"need (N, d+1, d) simplex vertices with d = 2 or 3, got {P.shape}")
    if n == 0:
        return np.zeros(0), np.zeros(0)
    E = P[:, 1:] - P[:, :1]
    vol = np.linalg.det(E) / math.factorial(d)
    L2 = sum(np.sum((P[:, i] - P[:, j]) ** 2, axis=1) for i in range(nv)
             for j in range(i + 1, nv))
    with np.errstate(divide="ignore", invalid="ignore"):
        if d == 3:
            q = 12.0 * np.cbrt(3.0 * np.abs(vol)) ** 2 / L2
        else:
            q = 4.0 * math.sqrt(3.0) * np.abs(vol) / L2
    return vol, np.where(L2 > 0, q, 0.0)


#: a cell is degenerate if its volume is below this fraction of the mean cell volume …
DEGENERATE_VOLUME = 1e-10
#: … or its shape quality below this (a flat cell of normal size)
DEGENERATE_QUALITY = 1e-6


def degenerate_cells(measure: np.ndarray, quality: np.ndarray, mean_measure: float) -> np.ndarray:
    """(N,) bool: cells of (nearly) zero measure (relative to ``mean_measure``, the mean
    |measure| of the mesh) or of (nearly) zero shape quality."""
    return (np.abs(measure) <= DEGENERATE_VOLUME * mean_measure) | (quality <= DEGENERATE_QUALITY)


def overlapping_facets(X: np.ndarray, cells: np.ndarray, facet_vertices: np.ndarray,
                       facet_cells: np.ndarray) -> np.ndarray:
    """Interior facets whose two cells overlap: a tangled mesh.

    In a valid mesh the two cells that share a facet lie on opposite sides of it, whatever the
    order of their vertices (dolfinx does not orient cells consistently: a mesh may hold cells
    of both signs of the signed volume). A cell turned inside out lies on the same side as its
    neighbour across its facets.

    Args:
        X: (num_vertices, d) vertex positions.
        cells: (num_cells, d + 1) vertices of the cells.
        facet_vertices: (N, d) vertices of N interior facets.
        facet_cells: (N, 2) the two cells of each facet.
    Returns:
        (N,) bool: True where both cells' opposite vertices lie on the same side of the facet.
    """
    F = np.asarray(facet_vertices)
    if len(F) == 0:
        return np.zeros(0, dtype=bool)
    E = X[F[:, 1:]] - X[F[:, :1]]                 # (N, d-1, d) edges of the facet
    side = []
    for j in range(2):
        c = cells[facet_cells[:, j]]              # (N, d+1)
        in_facet = (c[:, :, None] == F[:, None, :]).any(axis=2)
        opp = c[~in_facet]                        # the vertex opposite the facet
        side.append(np.linalg.det(np.concatenate([E, (X[opp] - X[F[:, 0]])[:, None]], axis=1)))
    return side[0] * side[1] > 0.0


def initial_mesh_error(msh, X, c2v_owned, vol0, q0) -> Optional[str]:
    """What is wrong with the initial mesh, or None (collective; the message is local):
    degenerate cells (:func:`degenerate_cells`) or a tangled mesh (cells turned inside out,
    overlapping a neighbour: :func:`overlapping_facets`)."""
    comm = msh.comm
    tdim = msh.topology.dim
    msh.topology.create_connectivity(tdim - 1, tdim)   # collective: before any local return
    msh.topology.create_connectivity(tdim - 1, 0)
    n = comm.allreduce(len(vol0), op=MPI.SUM)
    mean = comm.allreduce(float(np.sum(np.abs(vol0))), op=MPI.SUM) / max(n, 1)
    bad = np.flatnonzero(degenerate_cells(vol0, q0, mean))
    if len(bad):
        c = X[c2v_owned[bad[0]]].mean(axis=0)
        return (f"the mesh has {len(bad)} degenerate (zero-volume) cell(s) (volume below "
                f"{DEGENERATE_VOLUME:g} x the mean cell volume or shape quality below "
                f"{DEGENERATE_QUALITY:g}), e.g. with centroid {np.array2string(c, precision=4)}: "
                f"remesh")
    f2c = msh.topology.connectivity(tdim - 1, tdim)
    nf = msh.topology.index_map(tdim - 1).size_local
    inner = np.flatnonzero(np.diff(f2c.offsets)[:nf] == 2)
    fc = f2c.array[f2c.offsets[inner][:, None] + np.arange(2)]
    fv = msh.topology.connectivity(tdim - 1, 0).array.reshape(-1, tdim)[inner]
    over = overlapping_facets(X, compat.cell_vertices(msh), fv, fc)
    if np.any(over):
        c = X[fv[np.argmax(over)]].mean(axis=0)
        return (f"the mesh is tangled: {int(np.sum(over))} facet(s) have both their cells on "
                f"the same side (cells turned inside out, overlapping their neighbour), e.g. the "
                f"facet with centroid {np.array2string(c, precision=4)}: fix or remesh the mesh "
                f"(check the node order of its cells)")
    return None


class MeshHealth:
    """The mesh health of a :class:`~fxcontact.simulation.Simulation`: the initial mesh checked
    (ValueError on every rank for degenerate or tangled cells), the quality columns of each
    increment, and the check that a converged increment does not invert a cell.

    Args:
        sim: the simulation (its mesh, space, kinematics, solution and time are read).
    """

    def __init__(self, sim):
        self.sim = sim
        msh = sim.mesh
        tdim = msh.topology.dim
        nown = msh.topology.index_map(tdim).size_local
        self._c2v_owned = compat.cell_vertices(msh)[:nown]
        X = sim.space.vertex_positions()
        vol0, q0 = self.measures(X)
        msg = initial_mesh_error(msh, X, self._c2v_owned, vol0, q0)
        msgs = [m for m in sim.comm.allgather(msg) if m]   # raised on every rank
        if msgs:
            raise ValueError(msgs[0])
        self._vol0 = vol0

    def measures(self, X: np.ndarray):
        """Signed measure and shape quality of the owned cells for the vertex positions X
        (:func:`simplex_measures`)."""
        return simplex_measures(X[self._c2v_owned])

    def _worst(self, X: np.ndarray):
        """(min signed quality, min volume ratio, local index of the worst cell) (local)."""
        vol, q = self.measures(X)
        ratio = vol / self._vol0
        qs = np.sign(ratio) * q
        if len(ratio) == 0:
            return math.inf, math.inf, -1
        i = int(np.argmin(ratio))
        return float(np.min(qs)), float(ratio[i]), i

    def columns(self) -> Dict[str, float]:
        """``min_quality`` and ``min_volume_ratio`` of the current configuration (collective):
        see :meth:`Simulation.mesh_health <fxcontact.simulation.Simulation.mesh_health>`."""
        sim = self.sim
        q, r, _ = self._worst(sim.vertex_positions())
        q = sim.comm.allreduce(q, op=MPI.MIN)
        r = sim.comm.allreduce(r, op=MPI.MIN)
        return {"min_quality": q, "min_volume_ratio": r}

    def accept(self, dt: float, info) -> bool:
        """Check the geometry the converged increment would give before accepting it: an
        inverted cell marks the attempt failed (cut-back) with a message saying where and when
        (``info.converged``, ``info.message``). Collective."""
        sim = self.sim
        if not sim.check_inversion or sim.u is not None:
            return True
        sp = sim.space
        sim.w.x.scatter_forward()
        x_t = sim.vertex_positions()
        X = sim.kinematics.positions(x_t, sim.w.x.array[sp.vertex_dofs], dt)
        _, r, i = self._worst(X)
        # the cell is located by its centroid at the start of the increment (the last output)
        worst = sim.comm.allgather((r, None if i < 0 else x_t[self._c2v_owned[i]].mean(axis=0)))
        r_min, c = min(worst, key=lambda a: a[0])
        if r_min > 0.0:
            return True
        info.converged = False
        info.message = (f"{INVERSION}: the cell with centroid {np.array2string(c, precision=4)} "
                        f"would turn inside out (signed volume / initial volume = {r_min:.3g}) at "
                        f"t = {sim.t + dt:.6g} (increment {sim.increment + 1}, dt = {dt:.3g}); "
                        f"the velocity field is too distorted for this step: reduce dt or remesh")
        log.warning("t = %.6g: %s", sim.t, info.message)
        return False
