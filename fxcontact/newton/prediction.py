"""Active-set prediction of the Newton step for nodal penalty contact (THEORY §3.6 of
docs/theory.md, "Active-set prediction").

The nodal penalty force ``S ρ [h]₊ ∇h`` is piecewise linear in the nodal velocity, and the Newton
system only knows the branch of the current iterate. A node that is free at the iterate but
that the Newton step drives into the tool does not resist in the linearisation: on a nearly
rigid-plastic material (the tangent along the flow is m times the secant one) the step pushes
it deep into the tool, the penalty residual of the full step is huge, and the line search
creeps with 1–10 % steps for tens of iterations (``benchmarks/README.md``, "Newton at
m = 0.016"). The prediction solves the Newton system *of the predicted branch* instead:

1. ``y₀ = J⁻¹F`` (the ordinary Newton step, x_new = x − y);
2. the contributors list the nodes whose status the step changes (``h + ∇h·δ > 0`` differs from
   the tangent's active flag, δ = −y): their stiffness changes ``dc ∇h⊗∇h`` and residual offsets
   ``o ∇h``;
3. ``y = (J + U C Uᵀ)⁻¹ (F + U o)`` by the Woodbury identity, with one solve ``Z = J⁻¹U`` per
   selected node, C = diag(dc) (with a MUMPS factorisation, the columns of a round in one
   solve with several right-hand sides, :mod:`fxcontact.la`):
   ``w = y₀ + Z o``, ``y = w − Z (I + C UᵀZ)⁻¹ C Uᵀ w``;
4. repeat from 2 with the new step until the predicted set is unchanged (at most ``rounds``
   times; the solves of nodes already selected are reused).

Each column ``U`` is the node's ``∇h`` at its dofs, zero at the Dirichlet dofs and projected on
the symmetry planes like the Jacobian. If the predicted set still changes after ``rounds``
rounds, the plain step is kept. The contributors leave out the nodes of tools with friction
and free nodes far from the tool (:meth:`NodalContact.active_set_prediction
<fxcontact.contact.nodal.NodalContact.active_set_prediction>`). The line search then checks the
corrected step on the true residual as usual. The converged solution is unchanged (the
prediction only changes the search direction); the cost is one linear solve per selected node
(a back-substitution with a direct solver: :class:`~fxcontact.newton.solver.SolverOptions` turns it on
by default only then).
"""

from __future__ import annotations

import logging
import time
from typing import Dict, List

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from fxcontact.la import pc_apply_many

__all__ = ["ActiveSetPrediction", "woodbury_step_numpy"]

log = logging.getLogger(__name__)


def woodbury_step_numpy(J: np.ndarray, F: np.ndarray, U: np.ndarray, dc: np.ndarray,
                        o: np.ndarray) -> np.ndarray:
    """Reference for the corrected step: ``(J + U diag(dc) Uᵀ)⁻¹ (F + U o)`` by a dense solve
    (for testing only)."""
    return np.linalg.solve(J + (U * dc) @ U.T, F + U @ o)


class ActiveSetPrediction:
    """Corrects a Newton step for the contact status changes it predicts (module docstring).

    Args:
        problem: the :class:`~fxcontact.newton.problem.NodalNonlinearProblem` (its contributors with
            ``active_set_prediction``, Dirichlet marker and constraints).
        comm: the communicator.
        rounds: maximum number of prediction rounds per Newton step.
        max_nodes: largest number of selected nodes (over all ranks) for which the step is
            corrected; above it the step is left as it is for that iteration (the cost is one
            linear solve per node).
    """

    def __init__(self, problem, comm, rounds: int = 5, max_nodes: int = 200):
        self.problem = problem
        self.comm = comm
        self.rounds = int(rounds)
        self.max_nodes = int(max_nodes)
        #: totals since construction: corrected steps, rounds, column solves, wall time,
        #: steps left uncorrected because of max_nodes or a singular small system
        #: ("skipped") or because the predicted set did not settle ("unsettled")
        self.stats: Dict[str, float] = {"steps": 0, "corrected": 0, "rounds": 0, "solves": 0,
                                        "time": 0.0, "skipped": 0, "unsettled": 0,
                                        "batched": 0}

    def _contributors(self) -> List:
        return [c for c in self.problem.contributors if hasattr(c, "active_set_prediction")
                and getattr(c, "_h", None) is not None]

    def _column(self, template: PETSc.Vec, dofs: np.ndarray, g: np.ndarray):
        """The vector with ``g`` at ``dofs`` (owned rows), zero at the Dirichlet dofs, projected
        on the symmetry planes (collective: every rank calls it, the owner fills it), and its
        nonzero entries on this rank ``(indices, values)``."""
        u = template.duplicate()
        u.set(0.0)
        idx = np.zeros(0, dtype=np.int64)
        vals = np.zeros(0)
        # every rank takes the array for writing, also where it stays zero: a write changes
        # the vector's state on this rank only, and PETSc keeps a norm computed earlier (here
        # the 0 of ``set``) while the state is unchanged, so a rank that did not write would
        # skip the reduction of the next norm (a Krylov solve) and the ranks would hang
        arr = u.getArray(readonly=False)
        if dofs is not None:
            keep = dofs >= 0
            ii = dofs[keep]
            ok = ~self.problem.bc_marker[ii]
            arr[ii[ok]] = g[keep][ok]
            for c in self.problem.constraints:
                c.project_entries(arr)
            idx = np.flatnonzero(arr)
            vals = arr[idx].copy()
        del arr
        return u, idx, vals

    def _solve_columns(self, ksp: PETSc.KSP, us: List[PETSc.Vec]) -> List[PETSc.Vec]:
        """``J⁻¹ u`` for the columns ``us`` (collective). With a direct solver, all in one
        solve with several right-hand sides (:func:`~fxcontact.la.pc_apply_many`).
        Under a Krylov method the sum of the columns is checked against ``ksp``'s tolerances
        (one product with J: the columns sit at different nodes, their sum does not cancel);
        if it fails (e.g. a kept factorisation), every column is solved by ``ksp`` as
        without the batch."""
        zs = [u.duplicate() for u in us]
        redo = not pc_apply_many(ksp.getPC(), us, zs)
        if not redo and ksp.getType() != PETSc.KSP.Type.PREONLY:
            su, sz, r = us[0].duplicate(), us[0].duplicate(), us[0].duplicate()
            su.set(0.0)
            sz.set(0.0)
            for u, z in zip(us, zs):
                su.axpy(1.0, u)
                sz.axpy(1.0, z)
            ksp.getOperators()[0].mult(sz, r)
            r.aypx(-1.0, su)
            rtol, atol = ksp.getTolerances()[:2]
            redo = r.norm() > max(rtol * su.norm(), atol)
            for v in (su, sz, r):
                v.destroy()
        if redo:
            for u, z in zip(us, zs):
                ksp.solve(u, z)
        else:
            self.stats["batched"] += len(us)
        self.stats["solves"] += len(us)
        return zs

    def correct(self, ksp: PETSc.KSP, y: PETSc.Vec) -> bool:
        """Replace the Newton step ``y`` (x_new = x − y, ``ksp`` holding the factorisation or
        preconditioner of J) by the step of the predicted branch; returns whether it changed
        (collective)."""
        t0 = time.perf_counter()
        try:
            return self._correct(ksp, y)
        finally:
            self.stats["time"] += time.perf_counter() - t0

    def _correct(self, ksp, y) -> bool:
        contribs = self._contributors()
        comm = self.comm
        self.stats["steps"] += 1
        if not comm.allreduce(len(contribs), op=MPI.MAX):
            return False
        # the copies of the step are made once a node changes status (most Newton steps
        # change none): until then the current step is y itself
        y0 = cur = None
        cache: Dict[tuple, tuple] = {}     # (rank, contributor, node dofs) -> (U, Z)
        prev = None
        changed = False
        settled = False
        try:
            for rnd in range(self.rounds + 1):
                step = -(y if cur is None else cur).getArray(readonly=True)
                sel = []
                for ci, c in enumerate(contribs):
                    dofs, g, dc, o = c.active_set_prediction(step)
                    for j in range(len(dc)):
                        sel.append((ci, tuple(int(v) for v in dofs[j]), g[j], dc[j], o[j]))
                key = [(ci, d, float(dc_), float(o_)) for ci, d, _, dc_, o_ in sel]
                keys = comm.allgather(key)
                if prev is not None and keys == prev:
                    settled = True
                    break
                prev = keys
                k = sum(len(kk) for kk in keys)
                if k == 0:
                    settled = True
                    break
                if rnd == self.rounds:
                    break            # ``rounds`` corrections, and the set still changes
                if k > self.max_nodes:
                    log.debug("active-set prediction: %d nodes change status (> max_nodes = "
                              "%d): step not corrected", k, self.max_nodes)
                    self.stats["skipped"] += 1
                    changed = False
                    break
                self.stats["rounds"] += 1
                if cur is None:
                    y0, cur = y.copy(), y.copy()
                new = {}
                for r, kk in enumerate(keys):
                    for m, (ci, d, _, _) in enumerate(kk):
                        ck = (r, ci, d)
                        if ck not in cache and ck not in new:
                            mine = r == comm.rank
                            new[ck] = self._column(y, np.array(d) if mine else None,
                                                   sel[m][2] if mine else None)
                if new:
                    us = [v[0] for v in new.values()]
                    zs = self._solve_columns(ksp, us)
                    for (ck, (u, idx, vals)), z in zip(new.items(), zs):
                        cache[ck] = (u, z, idx, vals)
                Us, Zs, dcs, os_ = [], [], np.zeros(k), np.zeros(k)
                j = 0
                for r, kk in enumerate(keys):
                    for m, (ci, d, dc_, o_) in enumerate(kk):
                        ck = (r, ci, d)
                        Us.append(cache[ck][2:])
                        Zs.append(cache[ck][1])
                        dcs[j], os_[j] = dc_, o_
                        j += 1
                # w = y0 + Z o;  y = w − Z (I + C UᵀZ)⁻¹ C Uᵀ w  (U sparse: a few entries per
                # column, on its owner; one reduction for UᵀZ and Uᵀw)
                w = y0.copy()
                for j in range(k):
                    if os_[j] != 0.0:
                        w.axpy(os_[j], Zs[j])
                za = [z.getArray(readonly=True) for z in Zs]
                wa = w.getArray(readonly=True)
                local = np.zeros((k, k + 1))
                for a, (idx, vals) in enumerate(Us):
                    if len(idx):
                        local[a, :k] = [float(vals @ zb[idx]) for zb in za]
                        local[a, k] = float(vals @ wa[idx])
                del za, wa
                tot = comm.allreduce(local, op=MPI.SUM)
                UZ, Uw = tot[:, :k], tot[:, k]
                M = np.eye(k) + dcs[:, None] * UZ
                try:
                    coef = np.linalg.solve(M, dcs * Uw)
                except np.linalg.LinAlgError:
                    coef = None
                if coef is None or not np.all(np.isfinite(coef)):
                    self.stats["skipped"] += 1
                    w.destroy()
                    changed = False
                    break
                for j in range(k):
                    w.axpy(-coef[j], Zs[j])
                w.copy(cur)
                w.destroy()
                changed = True
            if changed and not settled:   # (a skipped step has changed = False)
                # the predicted set still changes after ``rounds`` rounds (it cycles, or the
                # linearised gaps mislead): the plain Newton step is kept
                log.debug("active-set prediction: the predicted set did not settle in %d "
                          "rounds: step not corrected", self.rounds)
                self.stats["unsettled"] += 1
                changed = False
            if changed:
                cur.copy(y)
                self.stats["corrected"] += 1
        finally:
            for u, z, _, _ in cache.values():
                u.destroy()
                z.destroy()
            if cur is not None:
                y0.destroy()
                cur.destroy()
        return changed
