"""Small numba kernels of one cell shared by the element kernels: the bubble block's inverse,
the Schur complement of an element matrix, the geometry of an affine tetrahedron, and the
condensation of one cell's bubble — of an element system (A, b) for the P1/P1 assembly
(:func:`condense_system`) or of an element matrix with the blocks that recover the bubble
(:func:`condense_matrix`). The condensations have numpy twins (``*_numpy``); the kernels'
results are checked against numpy in ``tests/test_element_condense.py``,
``tests/test_element_jacobian.py`` and ``tests/test_dual.py``."""

import numba
import numpy as np

__all__ = ["SINGULAR_DET", "bubble_inverse", "condense_matrix", "condense_matrix_numpy",
           "condense_system", "condense_system_numpy", "inverse3", "inverse_gauss_jordan", "schur",
           "schur3", "tet_geometry"]

#: a 3 × 3 bubble block whose |det| is below this times its largest entry cubed is singular
#: (round-off of a determinant of O(1) entries: a few 1e-16)
SINGULAR_DET = 1e-13


@numba.njit(cache=True)
def bubble_inverse(A, bpos, Binv):
    """Binv = A_bb⁻¹ of one element matrix (three bubble unknowns, the 3D MINI element: by
    cofactors; otherwise Gauss–Jordan with partial pivoting). Returns False when A_bb is
    singular or the inverse is not finite."""
    if bpos.size == 3:
        return inverse3(A, bpos, Binv)
    return inverse_gauss_jordan(A, bpos, Binv)


@numba.njit(cache=True)
def inverse3(A, bpos, Binv):
    """Binv = A_bb⁻¹ of a 3 × 3 bubble block by cofactors (no allocation: 5× faster than the
    Gauss–Jordan loop in the condensation of a Jacobian). Returns False when |det A_bb| is
    below :data:`SINGULAR_DET` times its largest entry cubed (singular to round-off) or the
    inverse is not finite."""
    b0, b1, b2 = bpos[0], bpos[1], bpos[2]
    a00, a01, a02 = A[b0, b0], A[b0, b1], A[b0, b2]
    a10, a11, a12 = A[b1, b0], A[b1, b1], A[b1, b2]
    a20, a21, a22 = A[b2, b0], A[b2, b1], A[b2, b2]
    c00 = a11 * a22 - a12 * a21
    c10 = a12 * a20 - a10 * a22
    c20 = a10 * a21 - a11 * a20
    det = a00 * c00 + a01 * c10 + a02 * c20
    amax = max(abs(a00), abs(a01), abs(a02), abs(a10), abs(a11), abs(a12), abs(a20),
               abs(a21), abs(a22))
    if not abs(det) > SINGULAR_DET * amax * amax * amax:   # (NaN: not finite)
        return False
    d = 1.0 / det
    Binv[0, 0] = c00 * d
    Binv[0, 1] = (a02 * a21 - a01 * a22) * d
    Binv[0, 2] = (a01 * a12 - a02 * a11) * d
    Binv[1, 0] = c10 * d
    Binv[1, 1] = (a00 * a22 - a02 * a20) * d
    Binv[1, 2] = (a02 * a10 - a00 * a12) * d
    Binv[2, 0] = c20 * d
    Binv[2, 1] = (a01 * a20 - a00 * a21) * d
    Binv[2, 2] = (a00 * a11 - a01 * a10) * d
    for i in range(3):
        for j in range(3):
            if not abs(Binv[i, j]) < np.inf:
                return False
    return True


@numba.njit(cache=True)
def inverse_gauss_jordan(A, bpos, Binv):
    """Binv = A_bb⁻¹ (Gauss–Jordan with partial pivoting). Returns False when A_bb is
    singular or the inverse is not finite."""
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
def schur(A, lpos, bpos, Binv, X, S):
    """X = A_bb⁻¹ A_bl and S = A_ll − A_lb X of one element matrix, given Binv = A_bb⁻¹."""
    if bpos.size == 3:
        schur3(A, lpos, bpos, Binv, X, S)
        return
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


@numba.njit(cache=True)
def schur3(A, lpos, bpos, Binv, X, S):
    """:func:`schur` for three bubble unknowns, unrolled (the same sums in the same order)."""
    b0, b1, b2 = bpos[0], bpos[1], bpos[2]
    nl = lpos.size
    for j in range(nl):
        lj = lpos[j]
        u0, u1, u2 = A[b0, lj], A[b1, lj], A[b2, lj]
        for i in range(3):
            X[i, j] = Binv[i, 0] * u0 + Binv[i, 1] * u1 + Binv[i, 2] * u2
    for i in range(nl):
        li = lpos[i]
        v0, v1, v2 = A[li, b0], A[li, b1], A[li, b2]
        for j in range(nl):
            S[i, j] = A[li, lpos[j]] - v0 * X[0, j] - v1 * X[1, j] - v2 * X[2, j]


@numba.njit(cache=True, error_model="numpy")
def tet_geometry(coords, g1, Ki, G):
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


# -- the condensation of one cell ------------------------------------------------------------------
@numba.njit(cache=True)
def condense_system(A, b, lpos, bpos, S, r, X, y):
    """Condense the ``bpos`` dofs of one element (A, b): S = A_ll − A_lb X, r = b_l − A_lb y
    with X = A_bb⁻¹ A_bl, y = A_bb⁻¹ b_b. Returns False when A_bb is singular or not
    finite."""
    nl = lpos.size
    k = bpos.size
    Binv = np.empty((k, k))
    if not bubble_inverse(A, bpos, Binv):
        return False
    schur(A, lpos, bpos, Binv, X, S)
    for i in range(k):
        acc = 0.0
        for q in range(k):
            acc += Binv[i, q] * b[bpos[q]]
        y[i] = acc
    for i in range(nl):
        acc = b[lpos[i]]
        for q in range(k):
            acc -= A[lpos[i], bpos[q]] * y[q]
        r[i] = acc
    return True


def condense_system_numpy(A: np.ndarray, b: np.ndarray, lpos: np.ndarray, bpos: np.ndarray):
    """numpy twin of :func:`condense_system`: (S, r, X, y) of one element system (A, b)."""
    Abb = A[np.ix_(bpos, bpos)]
    X = np.linalg.solve(Abb, A[np.ix_(bpos, lpos)])
    y = np.linalg.solve(Abb, b[bpos])
    S = A[np.ix_(lpos, lpos)] - A[np.ix_(lpos, bpos)] @ X
    r = b[lpos] - A[np.ix_(lpos, bpos)] @ y
    return S, r, X, y


@numba.njit(cache=True)
def condense_matrix(A, lpos, bpos, S, X, Y, Binv, Abb):
    """S = A_ll − A_lb X, X = A_bb⁻¹ A_bl, Y = A_lb A_bb⁻¹, Binv = A_bb⁻¹, Abb = A_bb. Returns
    False when A_bb is singular or its inverse is not finite."""
    nl = lpos.size
    k = bpos.size
    for i in range(k):
        for j in range(k):
            Abb[i, j] = A[bpos[i], bpos[j]]
    if not bubble_inverse(A, bpos, Binv):
        return False
    schur(A, lpos, bpos, Binv, X, S)
    for i in range(nl):
        li = lpos[i]
        for j in range(k):
            acc = 0.0
            for q in range(k):
                acc += A[li, bpos[q]] * Binv[q, j]
            Y[i, j] = acc
    return True


def condense_matrix_numpy(A: np.ndarray, lpos: np.ndarray, bpos: np.ndarray):
    """numpy twin of :func:`condense_matrix`: (S, X, Y, A_bb⁻¹, A_bb) of one element matrix."""
    Abb = A[np.ix_(bpos, bpos)]
    Binv = np.linalg.inv(Abb)
    X = Binv @ A[np.ix_(bpos, lpos)]
    Y = A[np.ix_(lpos, bpos)] @ Binv
    S = A[np.ix_(lpos, lpos)] - A[np.ix_(lpos, bpos)] @ X
    return S, X, Y, Binv, Abb
