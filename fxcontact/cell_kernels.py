"""Small numba kernels of one cell shared by the element kernels: the bubble block's inverse,
the Schur complement of an element matrix and the geometry of an affine tetrahedron (their
results are checked against numpy in ``tests/test_element_condense.py``,
``tests/test_element_jacobian.py`` and ``tests/test_dual.py``)."""

import numba
import numpy as np


@numba.njit(cache=True)
def _bubble_inverse(A, bpos, Binv):
    """Binv = A_bb⁻¹ of one element matrix (Gauss–Jordan with partial pivoting). Returns False
    when A_bb is singular or the inverse is not finite."""
    k = bpos.size
    M = np.empty((k, k))
    for i in range(k):
        for j in range(k):
            M[i, j] = A[bpos[i], bpos[j]]
            Binv[i, j] = 1.0 if i == j else 0.0
    for col in range(k):
        piv = col
        for i in range(col + 1, k):
            if abs(M[i, col]) > abs(M[piv, col]):
                piv = i
        if not abs(M[piv, col]) > 0.0:
            return False
        if piv != col:
            for j in range(k):
                M[col, j], M[piv, j] = M[piv, j], M[col, j]
                Binv[col, j], Binv[piv, j] = Binv[piv, j], Binv[col, j]
        d = M[col, col]
        for j in range(k):
            M[col, j] /= d
            Binv[col, j] /= d
        for i in range(k):
            if i != col:
                f = M[i, col]
                if f != 0.0:
                    for j in range(k):
                        M[i, j] -= f * M[col, j]
                        Binv[i, j] -= f * Binv[col, j]
    return np.all(np.isfinite(Binv))


@numba.njit(cache=True)
def _schur(A, lpos, bpos, Binv, X, S):
    """X = A_bb⁻¹ A_bl and S = A_ll − A_lb X of one element matrix, given Binv = A_bb⁻¹."""
    nl = lpos.size
    k = bpos.size
    for i in range(k):
        for j in range(nl):
            acc = 0.0
            for q in range(k):
                acc += Binv[i, q] * A[bpos[q], lpos[j]]
            X[i, j] = acc
    for i in range(nl):
        for j in range(nl):
            acc = A[lpos[i], lpos[j]]
            for q in range(k):
                acc -= A[lpos[i], bpos[q]] * X[q, j]
            S[i, j] = acc


@numba.njit(cache=True, error_model="numpy")
def _tet_geometry(coords, g1, Ki, G):
    """J⁻¹ (Ki) and the physical gradients G (4, 3) of the hat functions of an affine
    tetrahedron (vertex coordinates ``coords`` (4, 3), reference gradients ``g1`` (4, 3));
    returns det J (not finite results on a degenerate cell)."""
    J = np.empty((3, 3))
    for i in range(3):
        for k in range(3):
            J[i, k] = coords[k + 1, i] - coords[0, i]
    det = (J[0, 0] * (J[1, 1] * J[2, 2] - J[1, 2] * J[2, 1])
           - J[0, 1] * (J[1, 0] * J[2, 2] - J[1, 2] * J[2, 0])
           + J[0, 2] * (J[1, 0] * J[2, 1] - J[1, 1] * J[2, 0]))
    Ki[0, 0] = (J[1, 1] * J[2, 2] - J[1, 2] * J[2, 1]) / det
    Ki[0, 1] = (J[0, 2] * J[2, 1] - J[0, 1] * J[2, 2]) / det
    Ki[0, 2] = (J[0, 1] * J[1, 2] - J[0, 2] * J[1, 1]) / det
    Ki[1, 0] = (J[1, 2] * J[2, 0] - J[1, 0] * J[2, 2]) / det
    Ki[1, 1] = (J[0, 0] * J[2, 2] - J[0, 2] * J[2, 0]) / det
    Ki[1, 2] = (J[0, 2] * J[1, 0] - J[0, 0] * J[1, 2]) / det
    Ki[2, 0] = (J[1, 0] * J[2, 1] - J[1, 1] * J[2, 0]) / det
    Ki[2, 1] = (J[0, 1] * J[2, 0] - J[0, 0] * J[2, 1]) / det
    Ki[2, 2] = (J[0, 0] * J[1, 1] - J[0, 1] * J[1, 0]) / det
    for n in range(4):
        for j in range(3):
            acc = 0.0
            for k in range(3):
                acc += Ki[k, j] * g1[n, k]
            G[n, j] = acc
    return det
