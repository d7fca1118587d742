"""Transfer of fields from an old mesh to a new mesh of the same body, in parallel.

The points where the new fields need values (dof coordinates, quadrature points) are located
in the old mesh by :class:`PointLocation`: every rank sends each of its points only to the
ranks whose bounding box (of their owned old cells, padded) contains it; those ranks find the
owned old cell that contains it (``dolfinx.geometry`` bounding-box trees), or else the nearest
one and its distance; the asking rank keeps, per point, the rank with the smallest distance
(0 inside a cell; the lowest rank on a tie). A point outside every padded box (a new boundary
node a little off the old boundary) is then asked of every rank. The old mesh is never gathered.

A point outside the old mesh takes the value of the nearest old cell's polynomial, extrapolated
(affine cells: exact for a field that is linear in that cell). :attr:`PointLocation.outside`
counts such points and :attr:`PointLocation.max_distance` is the farthest.

* :func:`interpolate_from`: spaces whose dofs are point values (Lagrange P1, P2, vector or not;
  MINI, whose dolfinx 0.5 basis is nodal at the vertices and the cell centroid: its bubble dof is
  the value at the centroid): new dof = old field at the dof's point. A field the old space holds
  exactly and the new one too (a linear field in P1/P2/MINI) is transferred exactly.
* :func:`transfer_cellwise`: DG0 and quadrature ("history") fields. Each old cell carries an
  affine field: its DG0 value, or the least-squares affine fit of its quadrature values (exact
  for a field linear in the cell, needs ≥ 4 non-coplanar points: degree ≥ 2). The new DG0 value
  is the mean over the new cell of the old affine field at its quadrature points (degree 2: exact
  for affine), a new quadrature value the old affine field at the point. With ``conserve``, a
  global correction then gives the new field the old integral ∫ f dV, to round-off: ``"scale"``
  multiplies it by I_old / I_new (keeps the sign and the zeros: strains), ``"shift"`` adds
  (I_old − I_new) / V_new (for fields of both signs, component by component). The correction
  is the error of the sampling: zero for a field affine in each old cell on the same domain, and
  of the order of (jumps of the old field) × (fraction of new cells that straddle an old cell
  face) × (1 / points per cell) otherwise; :func:`transfer_cellwise` returns it.
"""

from __future__ import annotations

import math
from typing import Callable, Optional

import basix
import dolfinx
import dolfinx.fem
import dolfinx.geometry
import numpy as np
from mpi4py import MPI

from fxcontact import compat
from fxcontact.collective import check_together

__all__ = ["PointLocation", "interpolate_from", "transfer_cellwise", "cell_vertex_coordinates",
           "CONSERVE", "physical_points", "quadrature_rule"]

#: the integral corrections of :func:`transfer_cellwise`
CONSERVE = ("scale", "shift", None)


def cell_vertex_coordinates(msh, cells=None) -> np.ndarray:
    """(N, tdim + 1, 3) vertex coordinates of the (owned by default) cells of an affine simplex
    mesh."""
    gd = compat.geometry_dofmap(msh)
    if cells is None:
        cells = np.arange(msh.topology.index_map(msh.topology.dim).size_local)
    return msh.geometry.x[gd[cells][:, : msh.topology.dim + 1]]


class PointLocation:
    """The old-mesh cell (and its rank) of every point of this rank (collective).

    Args:
        msh: the old mesh (distributed over the same communicator as the points).
        points: (N, 3) (or (N, gdim)) points of this rank.
        padding: the ranks' boxes are padded by ``padding`` × the body's diameter in the first
            round (a point a little outside the old body is then found without the second round).
    """

    def __init__(self, msh, points: np.ndarray, padding: float = 1e-3):
        comm = msh.comm
        self.mesh = msh
        self.comm = comm
        pts = np.zeros((len(points), 3))
        pts[:, : np.shape(points)[1] if len(points) else 3] = points
        self.points = pts
        tdim = msh.topology.dim
        self._cells_owned = np.arange(msh.topology.index_map(tdim).size_local, dtype=np.int32)
        X = cell_vertex_coordinates(msh).reshape(-1, 3)
        lo = X.min(axis=0) if len(X) else np.full(3, np.inf)
        hi = X.max(axis=0) if len(X) else np.full(3, -np.inf)
        boxes = np.array(comm.allgather(np.r_[lo, hi])).reshape(comm.size, 2, 3)
        diam = np.linalg.norm(np.max(boxes[:, 1], axis=0) - np.min(boxes[:, 0], axis=0))
        pad = padding * diam
        if len(self._cells_owned):
            self._tree = dolfinx.geometry.BoundingBoxTree(msh, tdim, self._cells_owned)
            self._mid = dolfinx.geometry.create_midpoint_tree(msh, tdim, self._cells_owned)
        # round 1: to the ranks whose padded box holds the point
        inside = np.all((pts[:, None, :] >= boxes[None, :, 0] - pad)
                        & (pts[:, None, :] <= boxes[None, :, 1] + pad), axis=2)   # (N, size)
        sent = [np.flatnonzero(inside[:, r]) for r in range(comm.size)]
        got = comm.alltoall([pts[s] for s in sent])
        found = [self._find(p) for p in got]
        dist = comm.alltoall([d for _, d in found])
        best_d, best_r = self._choose(sent, dist)
        # round 2: the points no padded box holds, to every rank
        lost = np.flatnonzero(~np.isfinite(best_d))
        n_lost = comm.allreduce(len(lost), op=MPI.SUM)
        sent2 = [lost] * comm.size if n_lost else [lost[:0]] * comm.size
        got2 = comm.alltoall([pts[s] for s in sent2]) if n_lost else [np.zeros((0, 3))] * comm.size
        found2 = [self._find(p) for p in got2]
        dist2 = comm.alltoall([d for _, d in found2]) if n_lost else \
            [np.zeros(0)] * comm.size
        sent = [np.r_[a, b] for a, b in zip(sent, sent2)]
        dist = [np.r_[a, b] for a, b in zip(dist, dist2)]
        best_d, best_r = self._choose(sent, dist)
        if np.any(~np.isfinite(best_d)):
            raise RuntimeError("PointLocation: a point was found in no cell of the old mesh on "
                               "any rank (an old mesh without cells?)")
        # tell each rank which of the points it was sent it evaluates
        keep = [best_r[s] == r for r, s in enumerate(sent)]
        kept = comm.alltoall(keep)
        self._eval_points = []
        self._eval_cells = []
        for r in range(comm.size):
            p = np.r_[got[r], got2[r]]
            c = np.r_[found[r][0], found2[r][0]]
            self._eval_points.append(p[kept[r]])
            self._eval_cells.append(c[kept[r]].astype(np.int32))
        self._targets = [s[k] for s, k in zip(sent, keep)]
        d = np.sqrt(best_d)
        #: number of this rank's points outside the old mesh (given the nearest cell's value)
        self.outside = int(np.sum(d > 0.0))
        #: the largest distance of one of this rank's points to its old cell (0: all inside)
        self.max_distance = float(d.max()) if len(d) else 0.0

    def _find(self, pts: np.ndarray):
        """(cells, squared distance) of points in this rank's owned cells: a containing cell
        (distance 0), else the nearest cell; (-1, inf) without owned cells."""
        n = len(pts)
        cells = np.full(n, -1, dtype=np.int32)
        d2 = np.full(n, np.inf)
        if n == 0 or len(self._cells_owned) == 0:
            return cells, d2
        pts = np.ascontiguousarray(pts, dtype=np.float64)
        cand = dolfinx.geometry.compute_collisions(self._tree, pts)
        col = dolfinx.geometry.compute_colliding_cells(self.mesh, cand, pts)
        off = np.asarray(col.offsets)
        hit = np.diff(off) > 0
        cells[hit] = np.asarray(col.array)[off[:-1][hit]]
        d2[hit] = 0.0
        miss = np.flatnonzero(~hit)
        if len(miss):
            pm = np.ascontiguousarray(pts[miss])
            near = np.asarray(dolfinx.geometry.compute_closest_entity(
                self._tree, self._mid, self.mesh, pm), dtype=np.int32)
            cells[miss] = near
            d2[miss] = np.asarray(dolfinx.geometry.squared_distance(self.mesh, self.mesh.topology.dim,
                                                                    near, pm))
        return cells, d2

    def _choose(self, sent, dist):
        """Per point, the smallest distance over the ranks asked and that rank (lowest first)."""
        best_d = np.full(len(self.points), np.inf)
        best_r = np.full(len(self.points), -1)
        for r, (s, d) in enumerate(zip(sent, dist)):
            better = d < best_d[s]
            best_d[s[better]] = d[better]
            best_r[s[better]] = r
        return best_d, best_r

    def evaluate(self, f: Callable[[np.ndarray, np.ndarray], np.ndarray]) -> np.ndarray:
        """``f(points, cells) -> (n, k)`` evaluated where each point was located (on the rank
        that owns its old cell; ``cells`` are that rank's local cell indices); returns the
        (N, k) values at this rank's points, in their order (collective)."""
        vals, err = [], None
        try:
            vals = [np.asarray(f(p, c), dtype=np.float64).reshape(len(p), -1) if len(p) else None
                    for p, c in zip(self._eval_points, self._eval_cells)]
        except Exception as e:   # raised on every rank, not a hang in the exchange
            err = e
        k = max((v.shape[1] for v in vals if v is not None), default=0)
        k = max(check_together(self.comm, "PointLocation.evaluate()", err, share=k))
        back = self.comm.alltoall([np.zeros((0, k)) if v is None else v for v in vals])
        out = np.zeros((len(self.points), k))
        for t, b in zip(self._targets, back):
            if len(t):
                out[t] = b
        return out


def _owned_blocks(V) -> int:
    return V.dofmap.index_map.size_local


def dof_points(V) -> np.ndarray:
    """(owned blocks, 3) coordinates of the owned dofs (one per block) of a collapsed space."""
    return V.tabulate_dof_coordinates()[: _owned_blocks(V)]


def interpolate_from(old, new, location: Optional[PointLocation] = None) -> PointLocation:
    """``new`` (a Function of a collapsed point-value space: Lagrange, MINI) takes the values of
    ``old`` (a Function of any space ``Function.eval`` handles, on the old mesh) at its dof
    points (collective). ``location``: a :class:`PointLocation` of ``dof_points(new's space)``
    already made (several fields of one space); returns the location used."""
    V = new.function_space
    if location is None:
        location = PointLocation(old.function_space.mesh, dof_points(V))
    vals = location.evaluate(old.eval)
    bs = V.dofmap.index_map_bs
    n = _owned_blocks(V)
    new.x.array.reshape(-1, bs)[:n] = vals.reshape(n, bs)
    new.x.scatter_forward()
    return location


# ------------------------------------------------------------------------- cellwise fields
def quadrature_rule(msh, degree: int):
    """(points (q, tdim), weights (q,)) of basix's quadrature of ``degree`` on the
    reference cell of ``msh``."""
    cell = basix.cell.string_to_type(msh.topology.cell_type.name)
    return basix.make_quadrature(cell, int(degree))


def physical_points(P: np.ndarray, ref: np.ndarray) -> np.ndarray:
    """(N, q, 3) physical points of reference points ``ref`` (q, tdim) in simplices P (N, d+1, 3)."""
    J = P[:, 1:] - P[:, :1]                      # (N, tdim, 3)
    return P[:, None, 0] + np.einsum("qi,nij->nqj", ref, J)


def _jacobian_dets(P: np.ndarray) -> np.ndarray:
    J = P[:, 1:] - P[:, :1]
    return np.abs(np.linalg.det(J)) if J.shape[1] == J.shape[2] else \
        np.sqrt(np.abs(np.linalg.det(J @ np.swapaxes(J, 1, 2))))


def _cellwise_kind(V):
    """("dg0", None) or ("quadrature", degree) of a space; ValueError otherwise."""
    e = V.ufl_element()
    fam = e.family()
    if fam == "Quadrature":
        return "quadrature", int(e.degree())
    if fam in ("Discontinuous Lagrange", "DG") and e.degree() == 0:
        return "dg0", None
    raise ValueError(f"transfer_cellwise: a DG0 or quadrature space is needed, got "
                     f"{fam} of degree {e.degree()}; use interpolate_from for Lagrange/MINI")


def _cell_values(f):
    """(owned cells, q, k) values of a DG0 (q = 1) or quadrature function, its (q,) reference
    weights and (q, tdim) reference points."""
    V = f.function_space
    msh = V.mesh
    kind, degree = _cellwise_kind(V)
    nc = msh.topology.index_map(msh.topology.dim).size_local
    bs = V.dofmap.index_map_bs
    dm = compat.dofmap_array(V)[:nc]                       # (nc, q) blocks
    vals = f.x.array.reshape(-1, bs)[dm]                   # (nc, q, bs)
    if kind == "dg0":
        pts = np.full((1, msh.topology.dim), 1.0 / (msh.topology.dim + 1))
        wts = np.array([1.0 / math.factorial(msh.topology.dim)])
    else:
        pts, wts = quadrature_rule(msh, degree)
    return vals, np.asarray(wts), np.asarray(pts)


def _affine_fit(P: np.ndarray, vals: np.ndarray, ref: np.ndarray):
    """Per cell, the least-squares affine field a + B (x − x_c) of values at reference points
    (constant if fewer than tdim + 1 points): returns (a (N, k), B (N, k, 3), x_c (N, 3))."""
    xc = P.mean(axis=1)
    n, q, k = vals.shape
    if q < P.shape[1]:
        return vals.mean(axis=1), np.zeros((n, k, 3)), xc
    Xq = physical_points(P, ref) - xc[:, None]                  # (N, q, 3)
    M = np.concatenate([np.ones((n, q, 1)), Xq], axis=2)  # (N, q, 4)
    coef = np.linalg.pinv(M) @ vals                       # (N, 4, k)
    return coef[:, 0], np.swapaxes(coef[:, 1:], 1, 2), xc


def cellwise_integral(f) -> np.ndarray:
    """(k,) ∫ f dV of a DG0 or quadrature function over the whole mesh (collective)."""
    msh = f.function_space.mesh
    vals, wts, _ = _cell_values(f)
    det = _jacobian_dets(cell_vertex_coordinates(msh))
    loc = np.einsum("n,q,nqk->k", det, wts, vals)
    return msh.comm.allreduce(loc, op=MPI.SUM)


def transfer_cellwise(old, new, conserve: Optional[str] = "scale",
                      quadrature_degree: int = 2) -> dict:
    """Transfer a DG0 or quadrature function ``old`` to ``new`` (DG0 or quadrature, on the new
    mesh) with its integral conserved (module docstring; collective).

    Returns ``{"integral_old", "integral_new", "correction", "outside", "max_distance"}``:
    the old integral (k,), the new one after the correction (equal to round-off), the
    correction (``"scale"``: the factor − 1; ``"shift"``: the added constant × V_new / |I_old|;
    0 without ``conserve``) and the location's outside count (all ranks) and largest distance.
    """
    if conserve not in CONSERVE:
        raise ValueError(f"transfer_cellwise: unknown conserve={conserve!r}; choose one of "
                         f"{CONSERVE}")
    old_msh, new_msh = old.function_space.mesh, new.function_space.mesh
    comm = new_msh.comm
    vals, _, ref = _cell_values(old)
    a, B, xc = _affine_fit(cell_vertex_coordinates(old_msh), vals, ref)
    I_old = cellwise_integral(old)
    kind, degree = _cellwise_kind(new.function_space)
    Pn = cell_vertex_coordinates(new_msh)
    qpts, qw = quadrature_rule(new_msh, quadrature_degree if kind == "dg0" else degree)
    X = physical_points(Pn, qpts)                               # (nc, q, 3)
    loc = PointLocation(old_msh, X.reshape(-1, 3))
    k = a.shape[1]

    def affine(p, c):
        return a[c] + np.einsum("nkj,nj->nk", B[c], p - xc[c])

    v = loc.evaluate(affine).reshape(len(Pn), len(qw), k)
    if kind == "dg0":
        v = np.einsum("q,nqk->nk", qw / qw.sum(), v)[:, None, :]
    bs = new.function_space.dofmap.index_map_bs
    dm = compat.dofmap_array(new.function_space)[: len(Pn)]
    arr = new.x.array.reshape(-1, bs)

    def integral(values):
        if kind == "dg0":
            w = _jacobian_dets(Pn) / math.factorial(new_msh.topology.dim)
            return comm.allreduce(np.einsum("n,nk->k", w, values[:, 0]), op=MPI.SUM)
        return comm.allreduce(np.einsum("n,q,nqk->k", _jacobian_dets(Pn), qw, values), op=MPI.SUM)

    I_s = integral(v)
    corr = np.zeros(k)
    if conserve == "scale":
        ok = np.abs(I_s) > 1e-300
        factor = np.where(ok, I_old / np.where(ok, I_s, 1.0), 1.0)
        v = v * factor
        corr = factor - 1.0
    elif conserve == "shift":
        vol = comm.allreduce(float(np.sum(_jacobian_dets(Pn))), op=MPI.SUM) \
            / math.factorial(new_msh.topology.dim)
        shift = (I_old - I_s) / vol
        v = v + shift
        corr = shift * vol / np.maximum(np.abs(I_old), 1e-300)
    arr[dm] = v.reshape(dm.shape + (bs,))
    new.x.scatter_forward()
    return {"integral_old": I_old, "integral_new": integral(v), "correction": corr,
            "outside": comm.allreduce(loc.outside, op=MPI.SUM),
            "max_distance": comm.allreduce(loc.max_distance, op=MPI.MAX)}
