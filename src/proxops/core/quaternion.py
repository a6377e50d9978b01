"""Quaternion and direction-cosine-matrix (DCM) utilities, one convention for all of proxops.

Convention (the only one used in the package)
----------------------------------------------
* **Scalar-last Hamilton quaternions** ``q = [qx, qy, qz, qw]`` (vector part ``q_eta``,
  scalar ``q_mu`` as in Basu et al. eq. 3), product ``p (x) q`` with
  ``i j = k`` (Hamilton), unit norm.
* ``q`` describes the attitude of a frame B relative to a frame A: B's axes are A's axes
  actively rotated by ``q``. ``quat_to_dcm(q)`` returns the *active* rotation matrix
  ``R = C_{A<-B}``: it maps B-components to A-components, ``v|_A = R v|_B`` and
  ``quat_rotate(q, v) = q (x) [v, 0] (x) q* = R v``.
* Basu et al. eq. 4 writes ``R(q) = (q_mu^2 - q_eta.q_eta) I + 2 q_eta q_eta^T
  - 2 q_mu q_eta^x``: that is ``quat_to_dcm(q).T = C_{B<-A}`` (the passive matrix).
  Note the paper's own eq. 2 (Rodrigues with ``+ sin(theta) n^x``) is the *active*
  matrix, i.e. eq. 2 and eq. 4 are transposes of each other for the same (theta, n);
  we follow eq. 3 + the kinematics eq. 27, which are consistent with the convention here.
* Kinematics with body rates ``w = omega_{B/A}|_B`` (rad/s):
  ``qdot = 0.5 q (x) [w, 0] = 0.5 Omega(w) q`` with
  ``Omega(w) = [[-w^x, w], [-w^T, 0]]`` (Basu et al. eq. 27).

All functions accept a single quaternion/vector or stacks with leading dimensions
(``(..., 4)`` and ``(..., 3)``) and broadcast.
"""

from __future__ import annotations

import math

import numpy as np

from proxops.errors import input_error

IDENTITY = np.array([0.0, 0.0, 0.0, 1.0])


def skew(v: np.ndarray) -> np.ndarray:
    """Cross-product matrix ``v^x`` with ``v^x a = v x a`` (shape (..., 3, 3))."""
    v = np.asarray(v, dtype=float)
    z = np.zeros_like(v[..., 0])
    return np.stack(
        [
            np.stack([z, -v[..., 2], v[..., 1]], axis=-1),
            np.stack([v[..., 2], z, -v[..., 0]], axis=-1),
            np.stack([-v[..., 1], v[..., 0], z], axis=-1),
        ],
        axis=-2,
    )


def quat_multiply(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Hamilton product ``p (x) q`` (scalar last).

    vector = p_w q_v + q_w p_v + p_v x q_v,  scalar = p_w q_w - p_v . q_v."""
    p = np.asarray(p, dtype=float)
    q = np.asarray(q, dtype=float)
    pv, pw = p[..., :3], p[..., 3:4]
    qv, qw = q[..., :3], q[..., 3:4]
    vec = pw * qv + qw * pv + np.cross(pv, qv)
    sca = pw * qw - np.sum(pv * qv, axis=-1, keepdims=True)
    return np.concatenate([vec, sca], axis=-1)


def quat_conjugate(q: np.ndarray) -> np.ndarray:
    """Conjugate ``[-qv, qw]`` (the inverse for a unit quaternion)."""
    q = np.asarray(q, dtype=float)
    return np.concatenate([-q[..., :3], q[..., 3:4]], axis=-1)


def quat_normalize(q: np.ndarray) -> np.ndarray:
    """Unit quaternion ``q / |q|``; raises ProxopsInputError for a zero or non-finite input."""
    q = np.asarray(q, dtype=float)
    norm = np.linalg.norm(q, axis=-1, keepdims=True)
    if not np.all(np.isfinite(norm)) or np.any(norm == 0.0):
        raise input_error("quaternion", q.tolist(), "must be finite and non-zero")
    return q / norm


def quat_rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Active rotation of ``v`` by unit ``q``: ``q (x) [v,0] (x) q* = quat_to_dcm(q) v``.

    Uses v' = v + 2 w (qv x v) + 2 qv x (qv x v)."""
    q = np.asarray(q, dtype=float)
    v = np.asarray(v, dtype=float)
    qv, qw = q[..., :3], q[..., 3:4]
    t = 2.0 * np.cross(qv, v)
    return v + qw * t + np.cross(qv, t)


def quat_rotate_inverse(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Inverse rotation ``q* (x) [v,0] (x) q = quat_to_dcm(q).T v``."""
    return quat_rotate(quat_conjugate(q), v)


def quat_to_dcm(q: np.ndarray) -> np.ndarray:
    """Active rotation matrix ``R = C_{A<-B}`` of unit ``q`` (``v|_A = R v|_B``).

    R = (w^2 - qv.qv) I + 2 qv qv^T + 2 w qv^x  (transpose of Basu et al. eq. 4)."""
    q = np.asarray(q, dtype=float)
    x, y, z, w = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    return np.stack(
        [
            np.stack([w * w + x * x - y * y - z * z, 2 * (x * y - w * z), 2 * (x * z + w * y)], axis=-1),
            np.stack([2 * (x * y + w * z), w * w - x * x + y * y - z * z, 2 * (y * z - w * x)], axis=-1),
            np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), w * w - x * x - y * y + z * z], axis=-1),
        ],
        axis=-2,
    )


def dcm_to_quat(R: np.ndarray) -> np.ndarray:
    """Unit quaternion (``qw >= 0``) of an active rotation matrix; inverse of :func:`quat_to_dcm`.

    Shepperd's method: pick the largest of (w, x, y, z) to avoid dividing by a small number."""
    R = np.asarray(R, dtype=float)
    if R.shape[-2:] != (3, 3):
        raise input_error("dcm shape", R.shape, "must end in (3, 3)")
    flat = R.reshape(-1, 3, 3)
    out = np.empty((flat.shape[0], 4))
    for k, m in enumerate(flat):
        tr = m[0, 0] + m[1, 1] + m[2, 2]
        cand = np.array([m[0, 0], m[1, 1], m[2, 2], tr])
        i = int(np.argmax(cand))
        if i == 3:
            w = 0.5 * np.sqrt(1.0 + tr)
            q = [(m[2, 1] - m[1, 2]) / (4 * w), (m[0, 2] - m[2, 0]) / (4 * w), (m[1, 0] - m[0, 1]) / (4 * w), w]
        elif i == 0:
            x = 0.5 * np.sqrt(1.0 + 2 * m[0, 0] - tr)
            q = [x, (m[0, 1] + m[1, 0]) / (4 * x), (m[0, 2] + m[2, 0]) / (4 * x), (m[2, 1] - m[1, 2]) / (4 * x)]
        elif i == 1:
            y = 0.5 * np.sqrt(1.0 + 2 * m[1, 1] - tr)
            q = [(m[0, 1] + m[1, 0]) / (4 * y), y, (m[1, 2] + m[2, 1]) / (4 * y), (m[0, 2] - m[2, 0]) / (4 * y)]
        else:
            z = 0.5 * np.sqrt(1.0 + 2 * m[2, 2] - tr)
            q = [(m[0, 2] + m[2, 0]) / (4 * z), (m[1, 2] + m[2, 1]) / (4 * z), z, (m[1, 0] - m[0, 1]) / (4 * z)]
        q = np.asarray(q)
        q = q / np.linalg.norm(q)
        out[k] = -q if q[3] < 0 else q
    return out.reshape(R.shape[:-2] + (4,))


def quat_from_axis_angle(axis: np.ndarray, angle: float | np.ndarray) -> np.ndarray:
    """``[sin(angle/2) n, cos(angle/2)]`` for a rotation of ``angle`` (rad) about ``axis``
    (normalised here) -- Basu et al. eq. 3."""
    axis = np.asarray(axis, dtype=float)
    norm = np.linalg.norm(axis, axis=-1, keepdims=True)
    if np.any(norm == 0.0) or not np.all(np.isfinite(norm)):
        raise input_error("rotation axis", axis.tolist(), "must be finite and non-zero")
    half = 0.5 * np.asarray(angle, dtype=float)[..., None]
    return np.concatenate([np.sin(half) * axis / norm, np.cos(half)], axis=-1)


def quat_to_axis_angle(q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(unit axis, angle in [0, pi]) of unit ``q``; the axis is [1, 0, 0] for the identity.

    Uses angle = 2 atan2(|qv|, |qw|) (well conditioned near 0 and pi); q and -q give the
    same result."""
    q = np.asarray(q, dtype=float)
    q = np.where(q[..., 3:4] < 0, -q, q)
    vn = np.linalg.norm(q[..., :3], axis=-1)
    angle = 2.0 * np.arctan2(vn, q[..., 3])
    safe = np.where(vn > 0, vn, 1.0)[..., None]
    axis = np.where(vn[..., None] > 0, q[..., :3] / safe, np.array([1.0, 0.0, 0.0]))
    return axis, angle


def omega_matrix(omega: np.ndarray) -> np.ndarray:
    """4x4 matrix ``Omega(w) = [[-w^x, w], [-w^T, 0]]`` so that ``qdot = 0.5 Omega(w) q``."""
    w = np.asarray(omega, dtype=float)
    if w.shape != (3,):
        raise input_error("omega shape", w.shape, "must be (3,)", "rad/s")
    m = np.zeros((4, 4))
    m[:3, :3] = -skew(w)
    m[:3, 3] = w
    m[3, :3] = -w
    return m


def quat_kinematics(q: np.ndarray, omega: np.ndarray) -> np.ndarray:
    """Quaternion rate ``qdot = 0.5 q (x) [w, 0]`` for body rates ``w`` (rad/s, B-frame
    components); equals ``0.5 Omega(w) q`` and Basu et al. eq. 27."""
    w = np.asarray(omega, dtype=float)
    wq = np.concatenate([w, np.zeros(w.shape[:-1] + (1,))], axis=-1)
    return 0.5 * quat_multiply(q, wq)


def quat_propagate(q: np.ndarray, omega: np.ndarray, dt: float) -> np.ndarray:
    """Exact attitude update for a body rate ``omega`` (rad/s, B-frame) held constant over
    ``dt`` s: ``q(t+dt) = q (x) exp(0.5 omega dt)`` (the solution of :func:`quat_kinematics`)."""
    w = np.asarray(omega, dtype=float)
    rate = np.linalg.norm(w, axis=-1)
    angle = rate * dt
    half = 0.5 * angle
    # sin(half)/rate written so that it stays exact as rate -> 0
    scale = np.where(rate > 1e-300, np.sin(half) / np.where(rate > 1e-300, rate, 1.0), 0.5 * dt)
    dq = np.concatenate([w * scale[..., None], np.cos(half)[..., None]], axis=-1)
    return quat_multiply(q, dq)


def quat_angle_between(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Rotation angle (rad, in [0, pi]) of ``p* (x) q``; insensitive to the sign of either."""
    d = quat_multiply(quat_conjugate(p), q)
    return 2.0 * np.arctan2(np.linalg.norm(d[..., :3], axis=-1), np.abs(d[..., 3]))


# --------------------------------------------------------------------------------------
# numba kernels: the same formulas for one quaternion in hot loops (plant right-hand sides)
# --------------------------------------------------------------------------------------
from numba import njit  # noqa: E402


@njit(cache=True)
def dcm_kernel(q):
    """:func:`quat_to_dcm` for one unit quaternion (float64[4]) inside numba code."""
    x, y, z, w = q[0], q[1], q[2], q[3]
    R = np.empty((3, 3))
    R[0, 0] = w * w + x * x - y * y - z * z
    R[0, 1] = 2 * (x * y - w * z)
    R[0, 2] = 2 * (x * z + w * y)
    R[1, 0] = 2 * (x * y + w * z)
    R[1, 1] = w * w - x * x + y * y - z * z
    R[1, 2] = 2 * (y * z - w * x)
    R[2, 0] = 2 * (x * z - w * y)
    R[2, 1] = 2 * (y * z + w * x)
    R[2, 2] = w * w - x * x - y * y + z * z
    return R


@njit(cache=True)
def kinematics_kernel(q, w):
    """:func:`quat_kinematics` (``0.5 q (x) [w, 0]``) for one quaternion inside numba code."""
    out = np.empty(4)
    out[0] = 0.5 * (q[3] * w[0] + q[1] * w[2] - q[2] * w[1])
    out[1] = 0.5 * (q[3] * w[1] + q[2] * w[0] - q[0] * w[2])
    out[2] = 0.5 * (q[3] * w[2] + q[0] * w[1] - q[1] * w[0])
    out[3] = -0.5 * (q[0] * w[0] + q[1] * w[1] + q[2] * w[2])
    return out


@njit(cache=True)
def multiply_kernel(p, q):
    """:func:`quat_multiply` (Hamilton, scalar last) for two quaternions inside numba code."""
    out = np.empty(4)
    out[0] = p[3] * q[0] + q[3] * p[0] + p[1] * q[2] - p[2] * q[1]
    out[1] = p[3] * q[1] + q[3] * p[1] + p[2] * q[0] - p[0] * q[2]
    out[2] = p[3] * q[2] + q[3] * p[2] + p[0] * q[1] - p[1] * q[0]
    out[3] = p[3] * q[3] - p[0] * q[0] - p[1] * q[1] - p[2] * q[2]
    return out


@njit(cache=True)
def rotation_quaternion_kernel(phi):
    """Unit quaternion (scalar last) of the rotation vector ``phi`` (rad, 3):
    [sin(|phi|/2) phi/|phi|, cos(|phi|/2)] (exp(phi / 2); [0, 0, 0, 1] for phi = 0)."""
    angle = math.sqrt(phi[0] * phi[0] + phi[1] * phi[1] + phi[2] * phi[2])
    out = np.empty(4)
    if angle == 0.0:
        out[0], out[1], out[2], out[3] = 0.0, 0.0, 0.0, 1.0
        return out
    s = math.sin(0.5 * angle) / angle
    out[0], out[1], out[2], out[3] = phi[0] * s, phi[1] * s, phi[2] * s, math.cos(0.5 * angle)
    return out


@njit(cache=True)
def rotation_vector_kernel(q):
    """Rotation vector (rad) of the unit quaternion ``q``: angle * axis, angle in [0, pi] (the shorter
    of +-q); the inverse of :func:`rotation_quaternion_kernel`."""
    s = -1.0 if q[3] < 0.0 else 1.0
    x, y, z, w = s * q[0], s * q[1], s * q[2], s * q[3]
    vn = math.sqrt(x * x + y * y + z * z)
    out = np.empty(3)
    if vn < 1e-12:  # 2 atan2(vn, w) / vn -> 2 / w (first order; w ~ 1 here)
        out[0], out[1], out[2] = 2.0 * x / w, 2.0 * y / w, 2.0 * z / w
        return out
    k = 2.0 * math.atan2(vn, w) / vn
    out[0], out[1], out[2] = k * x, k * y, k * z
    return out


@njit(cache=True)
def propagate_kernel(q, w, dt):
    """:func:`quat_propagate` for one quaternion and rate inside numba code, q (x) exp(0.5 w dt), in the
    numpy form's order of operations (the same bits): its product written as :func:`quat_multiply`
    sums it, (p_w q_v + q_w p_v) + p_v x q_v and p_w q_w - (p_v . q_v)."""
    rate = math.sqrt((w[0] * w[0] + w[1] * w[1]) + w[2] * w[2])
    half = 0.5 * (rate * dt)
    scale = math.sin(half) / rate if rate > 1e-300 else 0.5 * dt
    d0, d1, d2, d3 = w[0] * scale, w[1] * scale, w[2] * scale, math.cos(half)
    p0, p1, p2, p3 = q[0], q[1], q[2], q[3]
    out = np.empty(4)
    out[0] = (p3 * d0 + d3 * p0) + (p1 * d2 - p2 * d1)
    out[1] = (p3 * d1 + d3 * p1) + (p2 * d0 - p0 * d2)
    out[2] = (p3 * d2 + d3 * p2) + (p0 * d1 - p1 * d0)
    out[3] = p3 * d3 - ((p0 * d0 + p1 * d1) + p2 * d2)
    return out
