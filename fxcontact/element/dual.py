"""Primal–dual Newton for the Norton–Hoff law: the deviatoric stress as a dual variable at the
quadrature points (THEORY §1.1, ``SolverOptions(material_tangent="primal-dual")``).

With m ≪ 1 the consistent tangent of s = 2K z^(m−1) e is 2K z^(m−1) [P_dev − 2(1−m)/z² e⊗e]:
along the current strain-rate direction it is m times the secant one, and a Newton step that
turns the strain-rate direction of a cell overshoots (in one dimension a step from s ≈ ε̇₀
lands on −s). Newton on the dual relation z^(1−m) s − 2K e = 0, with s carried from iteration
to iteration at each quadrature point, replaces the primal stress in the tangent's rank-one term
by the dual one (the primal–dual Newton of total-variation denoising, Chan, Golub & Mulet
1999): where the direction turns, the dual stress still points the old way and the tangent
stays stiff. The residual is the primal one, so the converged solution is the same; at
convergence the dual stress equals the primal one and the tangent is the consistent one.

:class:`DualStress` keeps the dual stress (a quadrature function of the integrals' degree,
set from :meth:`~fxcontact.materials.NortonHoff.dual_update_ufl` with
``dolfinx.fem.Expression.eval``: dolfinx 0.5 cannot interpolate into quadrature spaces), gives
the primal–dual tangent form (or its correction to the consistent Jacobian), and is called by
the Newton solver at the start of each solve (``begin``: the primal stress of the initial
guess) and at each accepted iterate (``accept``).
A Jacobian assembled outside a Newton solve uses the last dual stress (before the first solve
the dual stress is zero, and the tangent is the secant one, 2K z^(m−1) P_dev).

**The numba update** (:class:`DualUpdateKernel`, ``DualStress.use_kernel``): dolfinx's
``Expression.eval`` costs a generated kernel per cell plus the packing of the coefficients and a
copy of the result; on the wire drawing (m = 0.016, quadrature degree 6) about as much per cell
as the element matrix itself. The kernel evaluates the same formulas with the basis split of the
hand-written element kernel (:class:`~fxcontact.element.tensors.KernelTables`: hat functions
with constant gradients plus the bubble), written straight into the dual stress array:

* primal: s = 2K z^(m−1) e, e = dev ε̇(v), z = (2 e:e + 3 ε̇₀²)^(1/2);
* update along a step v_old → v_new: s* ← s_p(ε̇_old) + 2K z_old^(m−1) (e_new − e_old)
  − 2(1−m)/z_old² (e_old : (e_new − e_old)) s*, its norm capped at that of s_p(ε̇_new).

An update starts from the state of the previous call (the last iterate): the coefficient
2K z^(m−1) and z² of that state are kept per quadrature point and read instead of recomputed
when the state, the geometry and the material are the same (the power is the loop's main cost;
the values are bitwise the same). :func:`dual_update_numpy` is the plain-numpy twin; both are
checked against the UFL expressions in ``tests/test_dual.py``.

If a Newton attempt with it fails, :class:`~fxcontact.simulation.Simulation` retries the same
time step with the consistent tangent (``DualStress.active = False``) before its line-search
fallback and the cut-back: the primal–dual direction is not always a descent direction of the
residual norm that the line search backtracks on (measured: the first increment of the ring
rolling with axial cones).
"""

from __future__ import annotations

import basix
import dolfinx
import numba
import numpy as np
import ufl
from petsc4py import PETSc

from fxcontact import compat
from fxcontact.element.cell import tet_geometry
from fxcontact.element.tensors import KernelTables
from fxcontact.materials.laws import NortonHoff, kernel_reads_law

__all__ = ["DualStress", "DualUpdateKernel", "dual_update_numpy", "kernel_applies"]


class DualStress:
    """Dual stress of the primal–dual Newton on a mixed (velocity, pressure) space.

    Args:
        material: a material with ``stress_ufl``, ``dual_tangent_ufl``,
            ``dual_tangent_correction_ufl`` and ``dual_update_ufl``
            (:class:`~fxcontact.materials.NortonHoff`).
        W: the mixed function space (velocity first).
        quadrature_degree: degree of the integrals the dual stress enters (``dx``'s).
    """

    def __init__(self, material, W, quadrature_degree: int):
        for name in ("stress_ufl", "dual_tangent_ufl", "dual_tangent_correction_ufl",
                     "dual_update_ufl"):
            if not hasattr(material, name):
                raise ValueError(f"the primal-dual Newton needs a Norton-Hoff material; "
                                 f"{type(material).__name__} has no {name}")
        self.material = material
        msh = W.mesh
        d = msh.geometry.dim
        Qe = ufl.TensorElement("Quadrature", msh.ufl_cell(), int(quadrature_degree),
                               quad_scheme="default", shape=(d, d))
        self.Q = dolfinx.fem.FunctionSpace(msh, Qe)
        #: the dual stress at the quadrature points
        self.s = dolfinx.fem.Function(self.Q, name="dual_stress")
        self._w_old = dolfinx.fem.Function(W)
        self._w_new = dolfinx.fem.Function(W)
        cell = basix.cell.string_to_type(msh.topology.cell_type.name)
        pts, _ = basix.make_quadrature(cell, int(quadrature_degree))
        eps_old = ufl.sym(ufl.grad(ufl.split(self._w_old)[0]))
        eps_new = ufl.sym(ufl.grad(ufl.split(self._w_new)[0]))
        jit = compat.jit_params()   # -fno-math-errno: the repeated pow calls merged
        self._primal = dolfinx.fem.Expression(material.stress_ufl(eps_new), pts,
                                              jit_params=jit)
        self._update = dolfinx.fem.Expression(
            material.dual_update_ufl(eps_old, eps_new, self.s), pts, jit_params=jit)
        tdim = msh.topology.dim
        imap = msh.topology.index_map(tdim)
        self._cells = np.arange(imap.size_local + imap.num_ghosts, dtype=np.int32)
        dm = np.asarray(self.Q.dofmap.list.array, dtype=np.int64)
        self._blocks = dm.reshape(len(self._cells), -1).ravel()
        self._bs = self.Q.dofmap.index_map_bs
        #: number of dual updates since construction
        self.updates = 0
        #: False: the dual stress follows the primal one (``accept`` sets it to the primal
        #: stress of the iterate), so the Jacobian is the consistent one (to round-off); the
        #: simulation's retry after a failed primal-dual attempt
        self.active = True

    def jacobian_correction(self, v, dv, wt, dx):
        """The UFL bilinear form to add to the consistent Jacobian (``v`` the velocity of the
        iterate, ``dv`` the trial and ``wt`` the test velocity): ``ufl.derivative(F, w, dw) +
        jacobian_correction(...)`` is the primal–dual Jacobian of any residual F holding the
        material's stress term."""
        return self.material.dual_tangent_correction_ufl(
            ufl.sym(ufl.grad(v)), self.s, ufl.sym(ufl.grad(dv)), ufl.sym(ufl.grad(wt))) * dx

    def tangent_form(self, v, dv, wt, dx):
        """The primal–dual tangent of the stress term ∫ s(ε̇(v)) : ε̇(wt) as a UFL bilinear form:
        it replaces that term's ``ufl.derivative`` (the same matrix as the derivative plus
        :meth:`jacobian_correction`, to round-off, at about 60 % of the kernel cost)."""
        return self.material.dual_tangent_ufl(
            ufl.sym(ufl.grad(v)), self.s, ufl.sym(ufl.grad(dv)), ufl.sym(ufl.grad(wt))) * dx

    #: the numba update (:class:`DualUpdateKernel`), or None: the UFL expressions
    kernel = None

    def use_kernel(self, space) -> bool:
        """Update the dual stress by the numba loop of :class:`DualUpdateKernel` (the same
        values, a fraction of the cost) where it applies: NortonHoff's own law on the MINI space
        of affine tetrahedra (``space``: the :class:`~fxcontact.spaces.MixedSpace`). Returns
        whether it is used."""
        if self.kernel is None and kernel_applies(self.material, space):
            self.kernel = DualUpdateKernel(self, space)
        return self.kernel is not None

    def _set(self, expr):
        if self.kernel is not None:
            self.kernel(0 if expr is self._primal else 1, self._w_old.x.array,
                        self._w_new.x.array)
            return
        vals = expr.eval(self._cells)
        arr = self.s.x.array.reshape(-1, self._bs)
        arr[self._blocks] = vals.reshape(-1, self._bs)

    def _load(self, x: PETSc.Vec):
        x.copy(self._w_new.vector)
        self._w_new.x.scatter_forward()

    def begin(self, x: PETSc.Vec):
        """Start of a Newton solve from ``x``: the dual stress is the primal one."""
        self._load(x)
        self._set(self._primal)
        self._w_old.x.array[:] = self._w_new.x.array

    def accept(self, x: PETSc.Vec):
        """A Newton iterate ``x`` was accepted: update the dual stress along the step."""
        self._load(x)
        if self.active:
            self._set(self._update)
            self.updates += 1
        else:
            self._set(self._primal)
        self._w_old.x.array[:] = self._w_new.x.array


# ------------------------------------------------------------------------------ the numba update
@numba.njit(cache=True, error_model="numpy")
def _vertex_part(wv, G, share, Lc, vb):
    """The parts of ∇v constant in a cell: Lc = Σ_n v_n ⊗ ∇λ_n (hat functions) and the
    bubble's coefficient vb = v_B + Σ_n c_n v_n (``wv``: the cell's W values, velocity node n
    component c at 3 n + c)."""
    for i in range(3):
        acc = wv[12 + i]
        for n in range(4):
            acc += share[n] * wv[3 * n + i]
        vb[i] = acc
        for j in range(3):
            acc = 0.0
            for n in range(4):
                acc += wv[3 * n + i] * G[n, j]
            Lc[i, j] = acc


@numba.njit(cache=True, error_model="numpy")
def _deviator_at(Lc, vb, gB, e):
    """e = dev sym ∇v at one quadrature point, ∇v = Lc + vb ⊗ ∇B (``gB``: the bubble's
    physical gradient there)."""
    tr = (Lc[0, 0] + vb[0] * gB[0] + Lc[1, 1] + vb[1] * gB[1] + Lc[2, 2] + vb[2] * gB[2]) / 3.0
    for i in range(3):
        for j in range(3):
            e[i, j] = 0.5 * (Lc[i, j] + Lc[j, i] + vb[i] * gB[j] + vb[j] * gB[i])
        e[i, i] -= tr


@numba.njit(cache=True, error_model="numpy")
def _dual_loop(x, xdofs, w_old, w_new, wdofs, s, sdofs, Kc, mc, zn, eps0, g1, gb, share, mode,
               ca, cz2, cm, cached):
    """mode 0: s = primal stress of w_new; 1: the dual update from w_old to w_new (s holds the
    current dual stress, overwritten). The law of cell c is K = Kc[c, j], m = mc[c, j] on the
    rate interval j of the point's z (bounds ``zn``). ``ca[c, q]``, ``cz2[c, q]``, ``cm[c, q]``
    receive the coefficient 2K z^(m−1), z² and m of w_new; with ``cached`` they hold those of
    w_old on entry (the same geometry and law), which the update then reads instead of
    recomputing them (the power is the loop's main cost)."""
    coords = np.empty((4, 3))
    Ki = np.empty((3, 3))
    G = np.empty((4, 3))
    wo = np.empty(wdofs.shape[1])
    wn = np.empty(wdofs.shape[1])
    eo = np.empty((3, 3))
    en = np.empty((3, 3))
    gB = np.empty(3)
    Lo = np.empty((3, 3))
    Ln = np.empty((3, 3))
    vo = np.empty(3)
    vn = np.empty(3)
    for c in range(xdofs.shape[0]):
        for i in range(4):
            for j in range(3):
                coords[i, j] = x[xdofs[c, i], j]
        tet_geometry(coords, g1, Ki, G)
        for k in range(wdofs.shape[1]):
            wn[k] = w_new[wdofs[c, k]]
            wo[k] = w_old[wdofs[c, k]]
        _vertex_part(wn, G, share, Ln, vn)
        if mode != 0:
            _vertex_part(wo, G, share, Lo, vo)
        for q in range(gb.shape[0]):
            row = sdofs[c, q] * 9
            ao = 0.0
            zo2 = 0.0
            for j in range(3):
                gB[j] = Ki[0, j] * gb[q, 0] + Ki[1, j] * gb[q, 1] + Ki[2, j] * gb[q, 2]
            _deviator_at(Ln, vn, gB, en)
            zn2 = 3.0 * eps0 * eps0
            for i in range(3):
                for j in range(3):
                    zn2 += 2.0 * en[i, j] * en[i, j]
            zq = np.sqrt(zn2)
            j = 0
            while j < zn.size and zq >= zn[j]:
                j += 1
            an = 2.0 * Kc[c, j] * zq ** (mc[c, j] - 1.0)
            mo = 0.0
            if cached:
                ao = ca[c, q]
                zo2 = cz2[c, q]
                mo = cm[c, q]
            ca[c, q] = an
            cz2[c, q] = zn2
            cm[c, q] = mc[c, j]
            if mode == 0:
                for i in range(3):
                    for j in range(3):
                        s[row + 3 * i + j] = an * en[i, j]
                continue
            _deviator_at(Lo, vo, gB, eo)
            ed = 0.0
            for i in range(3):
                for j in range(3):
                    ed += eo[i, j] * (en[i, j] - eo[i, j])
            if not cached:
                zo2 = 3.0 * eps0 * eps0
                for i in range(3):
                    for j in range(3):
                        zo2 += 2.0 * eo[i, j] * eo[i, j]
                zq = np.sqrt(zo2)
                j = 0
                while j < zn.size and zq >= zn[j]:
                    j += 1
                mo = mc[c, j]
                ao = 2.0 * Kc[c, j] * zq ** (mo - 1.0)
            cr = 2.0 * (1.0 - mo) / zo2 * ed
            nn = 0.0
            ncap = 0.0
            for i in range(3):
                for j in range(3):
                    v = ao * en[i, j] - cr * s[row + 3 * i + j]   # s_p(old) + ao (en − eo)
                    s[row + 3 * i + j] = v
                    nn += v * v
                    ncap += (an * en[i, j]) ** 2
            if nn > ncap:
                f = np.sqrt(ncap / nn)
                for k in range(9):
                    s[row + k] *= f


def dual_update_numpy(coords, wv_old, wv_new, s, K, m, eps0, g1, gb, share, mode, z_nodes=()):
    """numpy twin of the dual update for cells with geometry ``coords`` (n, 4, 3), W values
    ``wv_*`` (n, 19), dual stress ``s`` (n, nq, 3, 3), the law's K and m (numbers, or (n, nint)
    per cell and rate interval with the bounds ``z_nodes`` in z); returns the new
    (n, nq, 3, 3)."""
    J = np.transpose(coords[:, 1:] - coords[:, :1], (0, 2, 1))        # (n, 3, 3)
    Ki = np.linalg.inv(J)
    G = np.einsum("nkj,ak->naj", Ki, g1)                               # (n, 4, 3)
    gB = np.einsum("nkj,qk->nqj", Ki, gb)                              # (n, nq, 3)

    def dev(wv):
        vel = wv[:, :15].reshape(-1, 5, 3)
        vb = vel[:, 4] + np.einsum("a,nai->ni", share, vel[:, :4])
        L = np.einsum("nai,naj->nij", vel[:, :4], G)[:, None] + np.einsum(
            "ni,nqj->nqij", vb, gB)
        e = 0.5 * (L + np.swapaxes(L, 2, 3))
        return e - np.trace(e, axis1=2, axis2=3)[..., None, None] / 3.0 * np.eye(3)

    def coef(e):
        z = np.sqrt(2.0 * np.einsum("nqij,nqij->nq", e, e) + 3.0 * eps0 ** 2)
        Kq, mq = K, m
        if np.ndim(K):   # the piece of each point's rate interval
            j = np.searchsorted(np.asarray(z_nodes, dtype=float), z, side="right")
            Kq = np.take_along_axis(np.asarray(K, dtype=float), j, axis=1)
            mq = np.take_along_axis(np.asarray(m, dtype=float), j, axis=1)
        return 2.0 * Kq * z ** (mq - 1.0), z, mq

    en = dev(wv_new)
    an, _, _ = coef(en)
    sp_new = an[..., None, None] * en
    if mode == 0:
        return sp_new
    eo = dev(wv_old)
    ao, zo, mo = coef(eo)
    ed = np.einsum("nqij,nqij->nq", eo, en - eo)
    s_new = ao[..., None, None] * en - (2.0 * (1.0 - mo) / zo ** 2 * ed)[..., None, None] * s
    nn = np.sqrt(np.einsum("nqij,nqij->nq", s_new, s_new))
    nc = np.sqrt(np.einsum("nqij,nqij->nq", sp_new, sp_new))
    return np.where((nn > nc)[..., None, None], (nc / np.where(nn > 0, nn, 1.0))[..., None, None]
                    * s_new, s_new)


def kernel_applies(material, space) -> bool:
    """Whether the kernel computes what the material's UFL expressions do: NortonHoff's own
    law (no redefined stress, z, exponent or update), the MINI space on affine tetrahedra."""
    if not (isinstance(material, NortonHoff) and all(
            getattr(type(material), name) is getattr(NortonHoff, name)
            for name in ("stress_ufl", "z_ufl", "exponent_ufl", "dual_update_ufl"))
            and kernel_reads_law(material)):
        return False
    msh = space.mesh
    return (msh.topology.cell_type == dolfinx.mesh.CellType.tetrahedron
            and space.element == "mini" and compat.geometry_dofmap(msh).shape[1] == 4
            and msh.geometry.dim == 3)


class DualUpdateKernel:
    """The dual stress updates of a :class:`~fxcontact.element.dual.DualStress` by the numba loop.

    Args:
        dual: the DualStress (its material, space W, quadrature space Q).
        space: the :class:`~fxcontact.spaces.MixedSpace` of W (quadrature degree, tables).
    """

    def __init__(self, dual, space):
        self.dual = dual
        t = KernelTables(space)
        self.g1, self.gb, self.share = t.g1, t.gb, t.share
        msh = space.mesh
        self._x = msh.geometry.x
        self._xdofs = compat.geometry_dofmap(msh)
        # the W element order of the hand kernel: velocity node n component c at 3 n + c
        # (node 4 the bubble), the vertex pressures after them
        self._wdofs = np.ascontiguousarray(compat.dofmap_array(space.W))
        sd = compat.dofmap_array(dual.Q)
        if sd.shape[1] != self.gb.shape[0]:
            raise ValueError("the dual stress is not at the quadrature points of the space")
        self._sdofs = np.ascontiguousarray(sd)
        # the coefficient 2K z^(m−1) and z² at each quadrature point for the state, geometry
        # and material of the last call (``_key``): the next update starts from that state
        self._ca = np.zeros(self._sdofs.shape)
        self._cz2 = np.zeros(self._sdofs.shape)
        self._cm = np.zeros(self._sdofs.shape)
        self._key = None
        #: calls that read the kept coefficients (for the tests)
        self.cache_hits = 0

    def __call__(self, mode: int, w_old: np.ndarray, w_new: np.ndarray):
        """Set the dual stress array: mode 0 the primal stress of ``w_new``, 1 the update
        (local W arrays with ghosts)."""
        mat = self.dual.material
        Kc, mc, zn = mat.kernel_law(self._xdofs.shape[0])
        prm = (float(mat.regularization),)
        key = self._key
        cached = (mode != 0 and key is not None and key[2] == prm
                  and np.array_equal(key[0], w_old) and np.array_equal(key[1], self._x)
                  and np.array_equal(key[3], Kc) and np.array_equal(key[4], mc))
        _dual_loop(self._x, self._xdofs, w_old, w_new, self._wdofs, self.dual.s.x.array,
                   self._sdofs, Kc, mc, zn, *prm, self.g1, self.gb, self.share, int(mode),
                   self._ca, self._cz2, self._cm, cached)
        self.cache_hits += int(cached)
        if key is None or key[0].shape != w_new.shape or key[3].shape != Kc.shape:
            self._key = (w_new.copy(), self._x.copy(), prm, Kc.copy(), mc.copy())
        else:   # no new arrays at each call
            for a, b in zip(key, (w_new, self._x, prm, Kc, mc)):
                if isinstance(a, np.ndarray):
                    np.copyto(a, b)
            self._key = key[:2] + (prm,) + key[3:]
