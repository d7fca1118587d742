"""The dual-stress update of the primal–dual Newton (:mod:`fxcontact.element.dual`) as a numba loop over
the cells, for the Norton–Hoff law on the MINI space of affine tetrahedra.

:class:`~fxcontact.element.dual.DualStress` sets the dual stress at the quadrature points from UFL
expressions evaluated by dolfinx (``Expression.eval``: a generated kernel per cell plus the
packing of the coefficients and a copy of the result). On the wire drawing (m = 0.016,
quadrature degree 6) that costs about as much per cell as the element matrix itself. Here the
same formulas are evaluated with the basis split of the hand-written element kernel
(:class:`~fxcontact.element.tensors._KernelTables`: hat functions with constant gradients plus
the bubble), written straight into the dual stress array:

* primal: s = 2K z^(m−1) e, e = dev ε̇(v), z = (2 e:e + 3 ε̇₀²)^(1/2);
* update along a step v_old → v_new: s* ← s_p(ε̇_old) + 2K z_old^(m−1) (e_new − e_old)
  − 2(1−m)/z_old² (e_old : (e_new − e_old)) s*, its norm capped at that of s_p(ε̇_new).

An update starts from the state of the previous call (the last iterate): the coefficient
2K z^(m−1) and z² of that state are kept per quadrature point and read instead of recomputed
when the state, the geometry and the material are the same (the power is the loop's main cost;
the values are bitwise the same).

:func:`dual_update_numpy` is the plain-numpy twin; both are checked against the UFL expressions
in ``tests/test_dual.py``.
"""

from __future__ import annotations

import numba
import numpy as np

from fxcontact.element.cell import _tet_geometry

__all__ = ["DualUpdateKernel", "dual_update_numpy", "kernel_applies"]


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
def _dual_loop(x, xdofs, w_old, w_new, wdofs, s, sdofs, K, m, eps0, g1, gb, share, mode,
               ca, cz2, cached):
    """mode 0: s = primal stress of w_new; 1: the dual update from w_old to w_new (s holds the
    current dual stress, overwritten). ``ca[c, q]``, ``cz2[c, q]`` receive the coefficient
    2K z^(m−1) and z² of w_new; with ``cached`` they hold those of w_old on entry (the same
    geometry), which the update then reads instead of recomputing them (the power is the
    loop's main cost)."""
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
        _tet_geometry(coords, g1, Ki, G)
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
            an = 2.0 * K * np.sqrt(zn2) ** (m - 1.0)
            if cached:
                ao = ca[c, q]
                zo2 = cz2[c, q]
            ca[c, q] = an
            cz2[c, q] = zn2
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
                ao = 2.0 * K * np.sqrt(zo2) ** (m - 1.0)
            cr = 2.0 * (1.0 - m) / zo2 * ed
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


def dual_update_numpy(coords, wv_old, wv_new, s, K, m, eps0, g1, gb, share, mode):
    """numpy twin of the dual update for cells with geometry ``coords`` (n, 4, 3), W values
    ``wv_*`` (n, 19), dual stress ``s`` (n, nq, 3, 3); returns the new (n, nq, 3, 3)."""
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
        return 2.0 * K * z ** (m - 1.0), z

    en = dev(wv_new)
    an, _ = coef(en)
    sp_new = an[..., None, None] * en
    if mode == 0:
        return sp_new
    eo = dev(wv_old)
    ao, zo = coef(eo)
    ed = np.einsum("nqij,nqij->nq", eo, en - eo)
    s_new = ao[..., None, None] * en - (2.0 * (1.0 - m) / zo ** 2 * ed)[..., None, None] * s
    nn = np.sqrt(np.einsum("nqij,nqij->nq", s_new, s_new))
    nc = np.sqrt(np.einsum("nqij,nqij->nq", sp_new, sp_new))
    return np.where((nn > nc)[..., None, None], (nc / np.where(nn > 0, nn, 1.0))[..., None, None]
                    * s_new, s_new)


def kernel_applies(material, space) -> bool:
    """Whether the kernel computes what the material's UFL expressions do: NortonHoff's own
    law (no redefined stress, z, exponent or update), the MINI space on affine tetrahedra."""
    import dolfinx
    from fxcontact import compat
    from fxcontact.materials import NortonHoff
    if not (isinstance(material, NortonHoff) and all(
            getattr(type(material), name) is getattr(NortonHoff, name)
            for name in ("stress_ufl", "z_ufl", "exponent_ufl", "dual_update_ufl"))):
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
        from fxcontact import compat
        from fxcontact.element.tensors import _KernelTables
        self.dual = dual
        t = _KernelTables(space)
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
        self._key = None
        #: calls that read the kept coefficients (for the tests)
        self.cache_hits = 0

    def __call__(self, mode: int, w_old: np.ndarray, w_new: np.ndarray):
        """Set the dual stress array: mode 0 the primal stress of ``w_new``, 1 the update
        (local W arrays with ghosts)."""
        mat = self.dual.material
        prm = (float(mat.K), float(mat.m), float(mat.regularization))
        key = self._key
        cached = (mode != 0 and key is not None and key[2] == prm
                  and np.array_equal(key[0], w_old) and np.array_equal(key[1], self._x))
        _dual_loop(self._x, self._xdofs, w_old, w_new, self._wdofs, self.dual.s.x.array,
                   self._sdofs, *prm, self.g1, self.gb, self.share, int(mode),
                   self._ca, self._cz2, cached)
        self.cache_hits += int(cached)
        if key is None or key[0].shape != w_new.shape:
            self._key = (w_new.copy(), self._x.copy(), prm)
        else:   # no new arrays at each call
            np.copyto(key[0], w_new)
            np.copyto(key[1], self._x)
            self._key = (key[0], key[1], prm)
