"""Small dense matrix kernels for numba code (matrices of a few to a few tens of rows).

Inside numba, ``@`` calls BLAS (~1 us per call even for 3x3); these loops avoid that. One home
for the hybrid MPC's ZOH discretisation (:mod:`proxops.control.hybrid_kernels`) and the attitude
MEKF's Van Loan discretisation (:mod:`proxops.navigation.mekf`):

* :func:`expm_pade13`: exp(M) by scaling and squaring with the [13/13] Pade approximant (Higham
  2005, the top branch of ``scipy.linalg.expm``; relative error ~1e-16 on these blocks);
* :func:`matmul` (A B), :func:`matmul_tn` (A^T B), :func:`matvec` (A x), :func:`cross3` (a x b of
  3-vectors; the rigid-body right-hand sides and the hybrid plant);
* :func:`whitened` (L^-1 v, A = L L^T) and :func:`mahalanobis_squared` (v^T A^-1 v): the navigation
  filters' whitened innovations and NEES, by Cholesky; :func:`gated_kalman_update` (their gated
  Joseph-form update of a 3-dimensional measurement) and :func:`symmetrised`.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

_B13 = np.array([64764752532480000.0, 32382376266240000.0, 7771770303897600.0, 1187353796428800.0,
                 129060195264000.0, 10559470521600.0, 670442572800.0, 33522128640.0, 1323241920.0,
                 40840800.0, 960960.0, 16380.0, 182.0, 1.0])
_THETA13 = 5.371920351148152


@njit(cache=True)
def expm_pade13(M):
    """exp(M) (square M): scaling and squaring with the [13/13] Pade approximant (Higham 2005).
    The polynomial sums are element loops into a few work arrays, each element summed in the order
    of the array expressions ``b13 A6 + b11 A4 + b9 A2`` etc. (so the bits of that form)."""
    n = M.shape[0]
    M = np.ascontiguousarray(M)
    norm = 0.0
    for j in range(n):
        s = 0.0
        for i in range(n):
            s += abs(M[i, j])
        norm = max(norm, s)
    sq = 0
    if norm > _THETA13:
        sq = int(math.ceil(math.log2(norm / _THETA13)))
    A = M / (2.0 ** sq)
    b = _B13
    A2 = matmul(A, A)
    A4 = matmul(A2, A2)
    A6 = matmul(A4, A2)
    W = np.empty((n, n))
    T = np.empty((n, n))
    V = np.empty((n, n))
    _pade13_half(b, 1, A2, A4, A6, W, T)
    U = matmul(A, T)
    _pade13_half(b, 0, A2, A4, A6, W, V)
    for i in range(n):
        for j in range(n):
            T[i, j] = V[i, j] - U[i, j]
            W[i, j] = V[i, j] + U[i, j]
    R = np.ascontiguousarray(np.linalg.solve(T, W))
    for _ in range(sq):
        R = matmul(R, R)
    return R


@njit(cache=True)
def _pade13_half(b, k, A2, A4, A6, work, out):
    """One half of the [13/13] Pade approximant into ``out`` (n, n): A6 (b[k+12] A6 + b[k+10] A4 +
    b[k+8] A2) + b[k+6] A6 + b[k+4] A4 + b[k+2] A2 + b[k] I, each element summed in that order
    (k = 1: U / A, k = 0: V of Higham 2005); ``work`` (n, n) is scratch."""
    n = A2.shape[0]
    for i in range(n):
        for j in range(n):
            work[i, j] = b[k + 12] * A6[i, j] + b[k + 10] * A4[i, j] + b[k + 8] * A2[i, j]
    matmul_into(A6, work, out)
    for i in range(n):
        for j in range(n):
            e = 1.0 if i == j else 0.0  # the identity's element (b[k] * 0 = +0 added off the diagonal, as I does)
            out[i, j] = out[i, j] + b[k + 6] * A6[i, j] + b[k + 4] * A4[i, j] + b[k + 2] * A2[i, j] + b[k] * e


@njit(cache=True)
def matmul_into(A, B, out):
    """out = A @ B by loops (the blocks here are at most 12 x 12: numba's @ calls BLAS, ~1 us per call);
    ``out`` may be a view (a block of a larger matrix) and must not alias A or B."""
    n, k = A.shape
    m = B.shape[1]
    for i in range(n):
        for j in range(m):
            out[i, j] = 0.0
        for l in range(k):
            a = A[i, l]
            if a != 0.0:
                for j in range(m):
                    out[i, j] += a * B[l, j]


@njit(cache=True)
def matmul(A, B):
    """A @ B by loops (:func:`matmul_into` into a new array)."""
    out = np.empty((A.shape[0], B.shape[1]))
    matmul_into(A, B, out)
    return out


@njit(cache=True)
def matmul_tn_into(A, B, out):
    """out = A.T @ B by loops; ``out`` must not alias A or B."""
    k, n = A.shape
    m = B.shape[1]
    for i in range(n):
        for j in range(m):
            out[i, j] = 0.0
    for l in range(k):
        for i in range(n):
            a = A[l, i]
            if a != 0.0:
                for j in range(m):
                    out[i, j] += a * B[l, j]


@njit(cache=True)
def matmul_tn(A, B):
    """A.T @ B by loops (:func:`matmul_tn_into` into a new array)."""
    out = np.empty((A.shape[1], B.shape[1]))
    matmul_tn_into(A, B, out)
    return out


@njit(cache=True)
def matvec(A, x):
    """A @ x by loops."""
    n, k = A.shape
    out = np.zeros(n)
    for i in range(n):
        s = 0.0
        for l in range(k):
            s += A[i, l] * x[l]
        out[i] = s
    return out


@njit(cache=True)
def cross3(a, b):
    """a x b of two 3-vectors inside numba code."""
    out = np.empty(3)
    out[0] = a[1] * b[2] - a[2] * b[1]
    out[1] = a[2] * b[0] - a[0] * b[2]
    out[2] = a[0] * b[1] - a[1] * b[0]
    return out


@njit(cache=True)
def _cholesky_lower(A):  # pragma: no cover - compiled
    """Lower Cholesky factor L (A = L L^T) of a symmetric positive definite A (n x n, small); NaN
    where A is not positive definite (as a NaN NEES or whitened innovation: never accepted)."""
    n = A.shape[0]
    L = np.zeros((n, n))
    for j in range(n):
        d = A[j, j]
        for k in range(j):
            d -= L[j, k] * L[j, k]
        d = math.sqrt(d) if d > 0.0 else math.nan
        L[j, j] = d
        for i in range(j + 1, n):
            s = A[i, j]
            for k in range(j):
                s -= L[i, k] * L[j, k]
            L[i, j] = s / d
    return L


@njit(cache=True)
def whitened(A, v):  # pragma: no cover - compiled
    """L^-1 v with L the lower Cholesky factor of A (forward substitution): the whitened innovation
    of an innovation v with covariance A, and |L^-1 v|^2 = v^T A^-1 v."""
    L = _cholesky_lower(A)
    n = v.shape[0]
    w = np.empty(n)
    for i in range(n):
        s = v[i]
        for k in range(i):
            s -= L[i, k] * w[k]
        w[i] = s / L[i, i]
    return w


@njit(cache=True)
def mahalanobis_squared(A, v):  # pragma: no cover - compiled
    """v^T A^-1 v (A symmetric positive definite) by Cholesky: the NEES of an error v with covariance A."""
    w = whitened(A, v)
    s = 0.0
    for i in range(w.shape[0]):
        s += w[i] * w[i]
    return s


@njit(cache=True)
def symmetrised(X):
    """0.5 (X + X^T) of a square X, in place (returned)."""
    n = X.shape[0]
    for i in range(n):
        for j in range(i + 1, n):
            v = 0.5 * (X[i, j] + X[j, i])
            X[i, j] = v
            X[j, i] = v
    return X


@njit(cache=True)
def gated_kalman_update(P, H, R, nu, gate):
    """The linear update of a Kalman filter with a 3-dimensional measurement: S = H P H^T + R (3x3,
    inverted by its adjugate), NIS = nu^T S^-1 nu and, when NIS <= gate (NaN is rejected), the correction
    dx = K nu and the expanded Joseph form P - K H P - (K H P)^T + K S K^T (not symmetrised), K = P H^T S^-1
    (P symmetric). Returns (dx, P after, S, nis, accepted); rejected: (empty, P, S, nis, False)."""
    HP = matmul(H, P)
    S = matmul(HP, np.ascontiguousarray(H.T)) + R
    a00, a01, a02, a10, a11, a12, a20, a21, a22 = (S[0, 0], S[0, 1], S[0, 2], S[1, 0], S[1, 1], S[1, 2],
                                                   S[2, 0], S[2, 1], S[2, 2])
    c00, c01, c02 = a11 * a22 - a12 * a21, a12 * a20 - a10 * a22, a10 * a21 - a11 * a20
    det = a00 * c00 + a01 * c01 + a02 * c02
    Sinv = np.empty((3, 3))  # the adjugate over the determinant
    Sinv[0, 0], Sinv[0, 1], Sinv[0, 2] = c00 / det, (a02 * a21 - a01 * a22) / det, (a01 * a12 - a02 * a11) / det
    Sinv[1, 0], Sinv[1, 1], Sinv[1, 2] = c01 / det, (a00 * a22 - a02 * a20) / det, (a02 * a10 - a00 * a12) / det
    Sinv[2, 0], Sinv[2, 1], Sinv[2, 2] = c02 / det, (a01 * a20 - a00 * a21) / det, (a00 * a11 - a01 * a10) / det
    Sinv_nu = np.zeros(3)
    for i in range(3):
        for j in range(3):
            Sinv_nu[i] += Sinv[i, j] * nu[j]
    nis = nu[0] * Sinv_nu[0] + nu[1] * Sinv_nu[1] + nu[2] * Sinv_nu[2]
    if not nis <= gate:
        return np.empty(0), P, S, nis, False
    K = matmul_tn(HP, Sinv)
    n = P.shape[0]
    dx = np.zeros(n)  # (H P)^T S^-1 nu
    for j in range(3):
        for i in range(n):
            dx[i] += HP[j, i] * Sinv_nu[j]
    KHP = matmul(K, HP)
    KSK = matmul(matmul(K, S), np.ascontiguousarray(K.T))
    P_new = np.empty((n, n))
    for i in range(n):
        for j in range(n):
            P_new[i, j] = P[i, j] - KHP[i, j] - KHP[j, i] + KSK[i, j]
    return dx, P_new, S, nis, True
