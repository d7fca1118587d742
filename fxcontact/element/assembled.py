"""Static condensation of cell-interior dofs (the MINI bubble) inside the linear solve.

The bubble dofs of the MINI element are interior to the cells: in the Newton matrix the
bubble–bubble block is block diagonal by cell (one ``gdim × gdim`` block per cell), and the
contact terms, the Dirichlet rows and the symmetry-plane projection act only on vertex dofs.
Ordering the unknowns as l (vertex velocities and pressures) and b (bubbles),

    [A_ll  A_lb] [x_l]   [r_l]
    [A_bl  A_bb] [x_b] = [r_b],

the b unknowns are eliminated cell by cell: ``S x_l = r_l − A_lb A_bb⁻¹ r_b`` with the condensed
matrix ``S = A_ll − A_lb A_bb⁻¹ A_bl`` (P1/P1; its pressure block carries the stabilisation
``−B_b A_bb⁻¹ B_bᵀ`` that the bubble gives), then ``x_b = A_bb⁻¹ (r_b − A_bl x_l)``. This is an
exact block elimination, so the Newton step is the uncondensed one to round-off when ``S`` is
solved exactly (MUMPS); the global system has about 5× fewer unknowns for tetrahedra.

:class:`CondensedPC` does it as a petsc4py ``python`` preconditioner on the full Jacobian, so the
SNES, the assembly and the line search are unchanged: with ``ksp_type preonly`` it is an exact
solver. The condensed system is solved by an inner KSP under the prefix ``<prefix>condensed_``
(any PETSc options). For the iterative inner solve (field split of ``S``: velocity | pressure)
the preconditioner provides

* the velocity split with its vertex-interlaced ordering, block size ``gdim`` and the rigid-body
  modes as near-null space (attached to the split's IS: PCFieldSplit hands it to GAMG);
* the Schur preconditioner matrix ``S_pp ± M_p/η`` (``pc_fieldsplit_schur_precondition user``):
  the condensed pressure block (condensation stabilisation and any pressure–pressure term of the
  material) plus the lumped pressure mass matrix weighted by the inverse local viscosity, a
  linear form in the pressure test function supplied by the problem (``schur_weight``, e.g.
  ``(1/η(v)) q dx``; the plain mass matrix without it). The sign is that of ``S_pp``'s diagonal
  (the Schur complement of the saddle-point system has the sign of the stabilisation block).

With a direct inner solve (``lu``) and the option ``<prefix>factor_symmetric`` (the
``condensed-mumps`` preset sets it), ``S`` is factorised as L D Lᵀ (``cholesky``: MUMPS's
symmetric indefinite factorisation, about half the work and memory of LU) whenever it is
symmetric, which a random probe tests at every set-up (``‖S x − Sᵀ x‖ ≤ SYMMETRY_RTOL ‖S x‖``):
the primal–dual and consistent Norton–Hoff tangents, elasticity, frictionless contact and
explicit friction give symmetric matrices; implicit Coulomb friction does not, and the set-up
then factorises with LU. The switch costs one new analysis of the matrix.
"""

from __future__ import annotations

import logging
import time
from typing import Optional

import dolfinx.fem.petsc
import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from fxcontact import compat
from fxcontact.la import direct_mumps, factor_solve_many, rigid_body_modes, same_nonzero_pattern

__all__ = ["SYMMETRY_RTOL", "CondensationLayout", "CondensedPC"]

#: relative asymmetry ‖S x − Sᵀ x‖ / ‖S x‖ of the condensed matrix (random x) below which it
#: is factorised as L D Lᵀ (``<prefix>factor_symmetric``); the round-off of a symmetric
#: tangent is ~1e-16, a non-symmetric term (implicit friction) is orders of magnitude above
SYMMETRY_RTOL = 1e-10

log = logging.getLogger(__name__)


class CondensationLayout:
    """Index sets of a mixed space for the condensation of its cell-interior dofs.

    Args:
        W: a dolfinx function space of block size 1 (mixed); the dofs of the cell interiors
            (``dof_layout.entity_dofs(tdim, 0)``, e.g. the MINI bubbles) are condensed.

    Attributes:
        interior: (num_owned_cells, n_int) local dofs of the cell interiors (owned cells).
        vel_nodes: (num_owned_vertices, gdim) local velocity dofs of the owned vertices, or None
            when the retained velocity dofs are not all at vertices (no block ordering).
        retained: the local owned retained dofs in the order of the condensed system (vertex
            velocities interlaced by vertex, then every other retained dof in increasing order).
        n_vel: number of leading entries of ``retained`` that are vertex velocities.
        is_b, is_l: parallel ISs (global W numbering) of the condensed and retained dofs.
    """

    def __init__(self, W):
        msh = W.mesh
        self.comm = msh.comm
        if W.dofmap.index_map_bs != 1:
            raise ValueError("the condensation needs a mixed space (dof block size 1)")
        tdim = msh.topology.dim
        self.gdim = msh.geometry.dim
        lay = W.dofmap.dof_layout
        loc_int = np.asarray(lay.entity_dofs(tdim, 0), dtype=np.int32)
        n_int = self.comm.allreduce(len(loc_int), op=MPI.MAX)
        if n_int == 0:
            raise ValueError("the space has no cell-interior dofs to condense (the condensed "
                             "solvers are for the MINI element)")
        imap = W.dofmap.index_map
        nown = imap.size_local
        self.nown = nown
        self.rstart = imap.local_range[0]
        ncell = msh.topology.index_map(tdim).size_local
        dm = compat.dofmap_array(W)
        interior = dm[:ncell][:, loc_int]
        if np.any(interior >= nown):
            raise RuntimeError("cell-interior dofs of an owned cell are not owned")
        self.interior = np.ascontiguousarray(interior)
        is_int = np.zeros(nown, dtype=bool)
        is_int[interior.ravel()] = True
        # vertex velocities (sub(0) of the mixed space), interlaced by vertex
        self.vel_nodes = None
        self.node_vertices = None
        try:
            V0 = W.sub(0)
            nsub = V0.num_sub_spaces
        except Exception:  # pragma: no cover - not a mixed velocity-pressure space
            nsub = 0
        if nsub == self.gdim:
            c2v = compat.cell_vertices(msh)
            nvc = c2v.shape[1]
            nvert = msh.topology.index_map(0).size_local + msh.topology.index_map(0).num_ghosts
            vd = np.full((nvert, self.gdim), -1, dtype=np.int64)
            vel_mask = np.zeros(dm.max() + 1 if dm.size else 0, dtype=bool)
            for k in range(self.gdim):
                sk = V0.sub(k)
                lk = sk.dofmap.dof_layout
                vpos = [lk.entity_dofs(0, i) for i in range(nvc)]
                cd = compat.dofmap_array(sk)
                vel_mask[cd.ravel()] = True
                if all(len(p) == 1 for p in vpos):
                    cols = [p[0] for p in vpos]
                    vd[c2v.ravel(), k] = cd[:, cols].ravel()
            own_v = np.all((vd >= 0) & (vd < nown), axis=1)
            vel_ret = vel_mask[:nown] & ~is_int
            nodes = vd[own_v].astype(np.int32)
            if np.all(vd[own_v] >= 0) and int(vel_ret.sum()) == nodes.size:
                self.vel_nodes = nodes
                self.node_vertices = np.flatnonzero(own_v).astype(np.int32)
        # PETSc's parallel MatCreateSubMatrix needs sorted index sets: both sets are in the
        # increasing W order. dolfinx numbers the dofs of one entity consecutively, so the
        # velocity dofs of a vertex stay consecutive (x, y, z) in that order: the velocity
        # split of the condensed system is vertex-interlaced (block size gdim) — checked.
        self.retained = np.flatnonzero(~is_int).astype(np.int32)
        if self.vel_nodes is not None:
            order = np.argsort(self.vel_nodes[:, 0], kind="stable")
            self.vel_nodes = self.vel_nodes[order]
            self.node_vertices = self.node_vertices[order]
            pos = np.searchsorted(self.retained, self.vel_nodes)
            if not np.all(np.diff(pos, axis=1) == 1):
                self.vel_nodes = None
            else:
                self.vel_pos = pos.ravel().astype(np.int32)
                mask = np.ones(len(self.retained), dtype=bool)
                mask[self.vel_pos] = False
                self.other_pos = np.flatnonzero(mask).astype(np.int32)
        self.n_vel = 0 if self.vel_nodes is None else self.vel_nodes.size
        b_sorted = np.sort(interior.ravel())
        #: position of each (cell, interior dof) in the b numbering (local)
        self.b_pos = np.searchsorted(b_sorted, interior).astype(np.int32)
        self.is_b = PETSc.IS().createGeneral((self.rstart + b_sorted).astype(PETSc.IntType),
                                             comm=self.comm)
        self.is_l = PETSc.IS().createGeneral(
            (self.rstart + self.retained).astype(PETSc.IntType), comm=self.comm)
        self.n_int = interior.shape[1]
        self.l_start = self.comm.exscan(len(self.retained)) or 0
        self.W = W

    def num_global(self):
        """(full, condensed) global numbers of unknowns."""
        nl = self.comm.allreduce(len(self.retained))
        nb = self.comm.allreduce(self.interior.size)
        return nl + nb, nl

    def split_is(self):
        """(velocity IS, other IS) in the numbering of the condensed system (None, None without
        a vertex-velocity ordering)."""
        if self.vel_nodes is None:
            return None, None
        iu = PETSc.IS().createGeneral((self.l_start + self.vel_pos).astype(PETSc.IntType),
                                      comm=self.comm)
        iu.setBlockSize(self.gdim)
        ip = PETSc.IS().createGeneral((self.l_start + self.other_pos).astype(PETSc.IntType),
                                      comm=self.comm)
        return iu, ip

    def node_coordinates(self) -> np.ndarray:
        """(num_owned_vertices, gdim) current positions of the vertices of ``vel_nodes``."""
        msh = self.W.mesh
        geo = compat.entities_to_geometry(msh, 0, self.node_vertices).ravel()
        return msh.geometry.x[geo, : self.gdim].copy()


def asymmetry(S: PETSc.Mat) -> float:
    """‖S x − Sᵀ x‖ / ‖S x‖ for a random x (PETSc's default generator; collective)."""
    x, y = S.createVecs()
    z = y.duplicate()
    rnd = PETSc.Random().create(S.getComm())
    rnd.setFromOptions()
    x.setRandom(rnd)
    rnd.destroy()
    S.mult(x, y)
    S.multTranspose(x, z)
    ny = y.norm()
    z.axpy(-1.0, y)
    out = z.norm() / ny if ny > 0 else 0.0
    for v in (x, y, z):
        v.destroy()
    return out


class CondensedPC:
    """petsc4py python-type PC: exact block elimination of the cell-interior dofs.

    Args:
        layout: the :class:`CondensationLayout` of the problem's space.
        prefix: options prefix of the inner KSP on the condensed system.
        schur_weight: optional compiled linear form on the mixed space whose pressure rows
            give the lumped, inverse-viscosity-weighted pressure mass (see the module
            docstring); used only when the inner PC is a field split.
        problem: optional :class:`~fxcontact.newton.problem.NonlinearProblem` whose ``augment`` form
            (the volumetric term of the velocity block, compiled on first use) is used with a
            field split: its retained (vertex) block, with the problem's Dirichlet rows and
            columns removed and projected on its constraints, is added to the inner
            *preconditioning* matrix, so that the velocity block the split inverts is not
            singular for a free dilatation; the inner operator stays the exact condensed
            matrix. Option ``<prefix>augment_scale`` (default 0: off; 1 gives the full strain
            rate's velocity block).
    """

    def __init__(self, layout: CondensationLayout, prefix: str, schur_weight=None,
                 problem=None):
        self.lay = layout
        self.prefix = prefix
        self.schur_weight = schur_weight
        self.problem = problem
        self._G = self._Gp = None
        self.comm = layout.comm
        self.ksp = None
        #: the outer KSP whose relative tolerance the inner solve follows (Eisenstat–Walker:
        #: SNES sets the outer KSP's rtol before every Newton step), or None
        self.follow_rtol_of = None
        self._mats = {}
        #: whether S = A_ll and T = A_lb A_bb⁻¹ A_bl have the same nonzero pattern (checked
        #: at the first set-up: both are reused with their pattern afterwards)
        self._same_pattern: Optional[bool] = None
        self._Sp = None
        self._wvec = None
        #: wall times: forming S, the inner set-up, and the whole set-up / application calls
        #: (``setup``, ``apply``: the PC's share of the linear solve, errors included)
        self.times = {"condense": 0.0, "inner_setup": 0.0, "setup": 0.0, "apply": 0.0}
        #: message of the last failed inner solve (None: none since the last reset)
        self.error: Optional[str] = None
        self.setups = 0
        #: set-ups per factorisation kind ("lu", "cholesky") with ``factor_symmetric``, and
        #: the asymmetry measured at the last one
        self.factorisations = {}
        self.last_asymmetry = None
        self.inner_iterations = 0
        self.inner_solves = 0
        #: keep the inner factorisation at the next set-ups (set by the Newton solver,
        #: ``SolverOptions.reuse_factorisation``): the condensed system and its
        #: factorisation stay those of the last set-up that factorised
        self.reuse = False
        #: set-ups that kept the factorisation (``setups`` counts those that made one)
        self.reuses = 0
        #: whether the inner factorisation is that of the current matrix (not a kept one)
        self._fresh = False

    # -- helpers ------------------------------------------------------------------------
    def _sub(self, P, name, isr, isc):
        old = self._mats.get(name)
        M = P.createSubMatrix(isr, isc, submat=old)
        self._mats[name] = M
        return M

    def _block_inverse(self, Abb: PETSc.Mat) -> PETSc.Mat:
        """A_bb⁻¹ as an AIJ matrix of the b layout (per-cell dense inverses)."""
        lay = self.lay
        k = lay.n_int
        ai, aj, av = Abb.getValuesCSR()
        r0, r1 = Abb.getOwnershipRange()
        nrow = len(ai) - 1
        ncell = lay.b_pos.shape[0]
        cell_of = np.empty(nrow, dtype=np.int64)
        comp_of = np.empty(nrow, dtype=np.int64)
        cell_of[lay.b_pos.ravel()] = np.repeat(np.arange(ncell), k)
        comp_of[lay.b_pos.ravel()] = np.tile(np.arange(k), ncell)
        rows = np.repeat(np.arange(nrow), np.diff(ai))
        col = aj.astype(np.int64) - r0
        local = (col >= 0) & (col < nrow)
        colc = np.where(local, col, 0)
        inside = local & (cell_of[colc] == cell_of[rows])
        off = ~inside & (av != 0.0)
        if self.comm.allreduce(int(np.count_nonzero(off))):
            raise RuntimeError("the interior-interior block is not block diagonal by cell: a "
                               "term couples interior dofs of different cells, it cannot be "
                               "condensed element by element")
        blocks = np.zeros((ncell, k, k))
        blocks[cell_of[rows[inside]], comp_of[rows[inside]], comp_of[colc[inside]]] = \
            av[inside]
        try:
            inv = np.linalg.inv(blocks)
        except np.linalg.LinAlgError:
            inv = np.full_like(blocks, np.nan)
        bad = int(np.count_nonzero(~np.isfinite(inv).all(axis=(1, 2))))
        if self.comm.allreduce(bad):
            raise RuntimeError("singular interior (bubble) block in a cell: degenerate element")
        # row r (cell c, component i): columns pos(c, j) (sorted), values inv[c, i, j]
        srt = np.argsort(lay.b_pos, axis=1)
        cpos = np.take_along_axis(lay.b_pos, srt, axis=1)          # (ncell, k) sorted
        vals = np.take_along_axis(inv, srt[:, None, :], axis=2)     # columns sorted
        vrow = np.empty((nrow, k))
        crow = np.empty((nrow, k), dtype=np.int64)
        vrow[lay.b_pos.ravel()] = vals.reshape(-1, k)
        crow[lay.b_pos.ravel()] = np.repeat(cpos, k, axis=0)
        indptr = (np.arange(nrow + 1) * k).astype(PETSc.IntType)
        cols = (r0 + crow).ravel()
        inv = vrow
        D = self._mats.get("Dinv")
        if D is None:
            D = PETSc.Mat().createAIJ(size=((nrow, PETSc.DETERMINE), (nrow, PETSc.DETERMINE)),
                                      csr=(indptr, cols.astype(PETSc.IntType), inv.ravel()),
                                      comm=self.comm)
            D.assemble()
            self._mats["Dinv"] = D
        else:
            D.zeroEntries()
            D.setValuesCSR(indptr, cols.astype(PETSc.IntType), inv.ravel())
            D.assemble()
        return D

    # -- PC interface -------------------------------------------------------------------
    def setUp(self, pc):
        t0 = time.perf_counter()
        try:
            self._setup(pc)
        finally:
            self.times["setup"] += time.perf_counter() - t0

    def apply(self, pc, x, y):
        t0 = time.perf_counter()
        try:
            self._apply(pc, x, y)
        finally:
            self.times["apply"] += time.perf_counter() - t0

    def _setup(self, pc):
        if self.reuse and self.ksp is not None:
            # the inner PC keeps its factorisation even if its matrix changed (the element
            # condensation reassembles it in place)
            self.ksp.getPC().setReusePreconditioner(True)
            self.reuses += 1
            self._fresh = False
            return
        t0 = time.perf_counter()
        self.setups += 1
        _, P = pc.getOperators()
        S = self._condensed_matrix(P)
        self.times["condense"] += time.perf_counter() - t0
        t0 = time.perf_counter()
        first = self.ksp is None
        if first:
            self.ksp = PETSc.KSP().create(self.comm)
            self.ksp.setOptionsPrefix(self.prefix)
            self.ksp.setOperators(S, S)
            self.ksp.setFromOptions()
            if self.ksp.getPC().getType() == PETSc.PC.Type.FIELDSPLIT:
                self._setup_fieldsplit(S, first=True)
        else:
            self.ksp.setOperators(S, S)
            if self.ksp.getPC().getType() == PETSc.PC.Type.FIELDSPLIT:
                self._setup_fieldsplit(S, first=False)
        self.ksp.getPC().setReusePreconditioner(False)
        self._choose_factorisation(S)
        if self.ksp.getPC().getType() == PETSc.PC.Type.FIELDSPLIT:
            Sa = self._augmented(S)
            if Sa is not None:
                self.ksp.setOperators(S, Sa)
        self.ksp.setUp()
        self.times["inner_setup"] += time.perf_counter() - t0
        self._rl = self._rl or S.createVecRight()
        self._yl = self._yl or S.createVecRight()
        self._fresh = True

    _xb = _tb = _rl = _yl = None

    def _condensed_matrix(self, P):
        """The condensed matrix S of the preconditioning matrix P (its work data kept)."""
        lay = self.lay
        Abb = self._sub(P, "bb", lay.is_b, lay.is_b)
        D = self._block_inverse(Abb)
        Alb = self._sub(P, "lb", lay.is_l, lay.is_b)
        Abl = self._sub(P, "bl", lay.is_b, lay.is_l)
        # S = A_ll − A_lb D A_bl (A_ll extracted afresh: it is overwritten by S)
        T = Alb.matMatMult(D, Abl, result=self._mats.get("T"))
        self._mats["T"] = T
        S = self._sub(P, "S", lay.is_l, lay.is_l)
        if self._same_pattern is None:
            self._same_pattern = same_nonzero_pattern(S, T)
        # the same pattern (the usual case: the cell-wise sparsity of a mixed space couples
        # all the vertex dofs of a cell, as T does) makes the update a plain axpy on the
        # values; PETSc's subset-pattern update goes row by row, ~30x slower
        S.axpy(-1.0, T, structure=(PETSc.Mat.Structure.SAME_NONZERO_PATTERN
                                   if self._same_pattern else
                                   PETSc.Mat.Structure.SUBSET_NONZERO_PATTERN))
        self._xb = self._xb or Abb.createVecRight()
        self._tb = self._tb or Abb.createVecRight()
        return S

    def _choose_factorisation(self, S):
        """With ``<prefix>factor_symmetric``: L D Lᵀ when S is symmetric, LU otherwise (only
        for a direct inner solve, ``lu`` or ``cholesky``)."""
        pc = self.ksp.getPC()
        kind = pc.getType()
        if kind not in (PETSc.PC.Type.LU, PETSc.PC.Type.CHOLESKY):
            return
        if not PETSc.Options().getBool(self.prefix + "factor_symmetric", False):
            return
        self.last_asymmetry = asymmetry(S)
        want = (PETSc.PC.Type.CHOLESKY if self.last_asymmetry <= SYMMETRY_RTOL
                else PETSc.PC.Type.LU)
        if want != kind:
            solver = pc.getFactorSolverType()
            pc.setType(want)
            pc.setFactorSolverType(solver)
            log.debug("condensed matrix %s (asymmetry %.1e): %s factorisation",
                      "symmetric" if want == PETSc.PC.Type.CHOLESKY else "not symmetric",
                      self.last_asymmetry, want)
        self.factorisations[want] = self.factorisations.get(want, 0) + 1

    def _setup_fieldsplit(self, S, first: bool):
        lay = self.lay
        pc = self.ksp.getPC()
        if first:
            iu, ip = lay.split_is()
            if iu is None:
                raise ValueError("the condensed field split needs vertex velocities (MINI)")
            self._iu, self._ip = iu, ip
            self._nsp = None
            pc.setFieldSplitIS(("u", iu), ("p", ip))
        # near-null space of the velocity block: rigid-body modes at the current vertices
        nsp = rigid_body_modes(self.comm, lay.node_coordinates())
        self._iu.compose("nearnullspace", nsp)
        if self._nsp is not None:
            self._nsp.destroy()
        self._nsp = nsp
        # the matrix is handed to the field split only when the options ask for it (the
        # preset does): any other choice (selfp, a11, full) is left to PETSc
        pre = PETSc.Options().getString(self.prefix + "pc_fieldsplit_schur_precondition", "")
        if pre != "user":
            return
        # Schur preconditioner: S_pp + sign · (lumped inverse-viscosity pressure mass)
        Spp = S.createSubMatrix(self._ip, self._ip, submat=self._Sp)
        self._Sp = Spp
        m = self._weighted_mass()
        d = Spp.getDiagonal()
        tr = d.sum()
        sign = -1.0 if tr <= 0 else 1.0
        dm = d.duplicate()
        dm.setArray(m)
        scale = PETSc.Options().getReal(self.prefix + "schur_mass_scale", 1.0)
        d.axpy(sign * scale, dm)
        Spp.setDiagonal(d)
        d.destroy()
        dm.destroy()
        pc.setFieldSplitSchurPreType(PETSc.PC.SchurPreType.USER, Spp)

    def _augmented(self, S):
        """S plus the retained block of the augmentation form (Dirichlet rows and columns
        removed, projected on the constraints), or None without one (collective)."""
        scale = PETSc.Options().getReal(self.prefix + "augment_scale", 0.0)
        form = getattr(self.problem, "augment", None) if scale != 0.0 else None
        if form is None:
            return None
        if self._G is None:
            self._G = dolfinx.fem.petsc.create_matrix(form)
        G = self._G
        G.zeroEntries()
        dolfinx.fem.petsc.assemble_matrix(G, form, bcs=self.problem.bcs, diagonal=0.0)
        G.assemble()
        for c in self.problem.constraints:
            if not c.active:
                continue
            self._Gp = c.project_matrix(G, self._Gp)
            G = self._Gp
        Gll = self._sub(G, "Gll", self.lay.is_l, self.lay.is_l)
        Sa = self._mats.get("Saug")
        if Sa is None:
            Sa = self._mats["Saug"] = S.duplicate(copy=True)
        else:
            S.copy(Sa, structure=PETSc.Mat.Structure.SAME_NONZERO_PATTERN)
        Sa.axpy(scale, Gll, structure=PETSc.Mat.Structure.SUBSET_NONZERO_PATTERN)
        return Sa

    def _weighted_mass(self) -> np.ndarray:
        """Lumped pressure mass weighted by the inverse viscosity, in the order of the
        retained non-velocity dofs."""
        lay = self.lay
        return self._weighted_mass_at(lay.retained[lay.other_pos])

    def _weighted_mass_at(self, wdofs: np.ndarray) -> np.ndarray:
        """The lumped inverse-viscosity pressure mass at the local W dofs ``wdofs``."""
        if self.schur_weight is None:
            raise ValueError("the condensed field split needs the problem's schur_weight form")
        if self._wvec is None:
            self._wvec = dolfinx.fem.petsc.create_vector(self.schur_weight)
        b = self._wvec
        with b.localForm() as bl:
            bl.set(0.0)
        dolfinx.fem.petsc.assemble_vector(b, self.schur_weight)
        b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        arr = b.getArray(readonly=True)
        return np.abs(arr[wdofs])

    def _apply(self, pc, x, y):
        lay = self.lay
        self._condensed_rhs(x)
        if self.follow_rtol_of is not None:
            self.ksp.setTolerances(rtol=self.follow_rtol_of.getTolerances()[0])
        self.ksp.solve(self._rl, self._yl)
        self.inner_iterations += self.ksp.getIterationNumber()
        self.inner_solves += 1
        reason = self.ksp.getConvergedReason()
        if reason < 0:
            # the reason is collective: every rank raises, the Newton solve fails with this
            # message (NewtonSolver reads `error`) and is cut back like a failed factorisation
            self.error = (f"the condensed linear solve failed (KSP reason {reason} after "
                          f"{self.ksp.getIterationNumber()} iterations; options under "
                          f"'{self.prefix}')")
            raise RuntimeError(self.error)
        self._write_solution(x, y)

    def apply_many(self, xs, ys) -> bool:
        """``ys[j]`` = the preconditioner applied to ``xs[j]``, all columns in one MUMPS solve
        with several right-hand sides (collective). Only when the inner solve is a direct
        one with the factorisation of the current matrix; returns False (nothing done)
        otherwise."""
        if not self._fresh or not direct_mumps(self.ksp):
            return False
        t0 = time.perf_counter()
        try:
            F = self.ksp.getPC().getFactorMatrix()
            cols = self._condensed_rhs_many(xs)
            for x, yc, y in zip(xs, factor_solve_many(F, self._rl, cols, self.comm), ys):
                self._yl.getArray(readonly=False)[:] = yc
                self._write_solution(x, y)
            self.inner_solves += len(xs)
        finally:
            self.times["apply"] += time.perf_counter() - t0
        return True

    def _condensed_rhs_many(self, xs) -> list:
        """The condensed right-hand sides (owned entries) of the vectors ``xs``."""
        cols = []
        for x in xs:
            self._condensed_rhs(x)
            cols.append(self._rl.getArray(readonly=True).copy())
        return cols

    def _write_solution(self, x, y):
        """The full solution y from the condensed one (``_yl``) and the right-hand side x."""
        yl = y.getSubVector(self.lay.is_l)
        self._yl.copy(yl)
        y.restoreSubVector(self.lay.is_l, yl)
        self._recover(x, y)

    def _condensed_rhs(self, x):
        """``_rl`` = r_l − A_lb A_bb⁻¹ r_b for the full right-hand side x."""
        lay = self.lay
        Alb, D = self._mats["lb"], self._mats["Dinv"]
        xb = x.getSubVector(lay.is_b)
        xl = x.getSubVector(lay.is_l)
        D.mult(xb, self._tb)                  # A_bb⁻¹ r_b
        Alb.mult(self._tb, self._rl)
        self._rl.aypx(-1.0, xl)               # r_l − A_lb A_bb⁻¹ r_b
        x.restoreSubVector(lay.is_b, xb)
        x.restoreSubVector(lay.is_l, xl)

    def _recover(self, x, y):
        """y_b = A_bb⁻¹ (r_b − A_bl y_l), y's l entries holding the condensed solution."""
        lay = self.lay
        Abl, D = self._mats["bl"], self._mats["Dinv"]
        xb = x.getSubVector(lay.is_b)
        Abl.mult(self._yl, self._xb)
        self._xb.aypx(-1.0, xb)               # r_b − A_bl x_l
        x.restoreSubVector(lay.is_b, xb)
        yb = y.getSubVector(lay.is_b)
        D.mult(self._xb, yb)
        y.restoreSubVector(lay.is_b, yb)

    def view(self, pc, viewer=None):
        if self.ksp is not None:
            self.ksp.view(viewer)

    def destroy(self, pc=None):
        for M in self._mats.values():
            M.destroy()
        self._mats = {}
        self._same_pattern = None
        for M in (self._G, self._Gp):
            if M is not None:
                M.destroy()
        self._G = self._Gp = None
        for v in (self._xb, self._tb, self._rl, self._yl, self._wvec):
            if v is not None:
                v.destroy()
        self._xb = self._tb = self._rl = self._yl = self._wvec = None
        if self.ksp is not None:
            self.ksp.destroy()
            self.ksp = None
