"""The two-rigid-body truth of Basu et al. as an engine plant with events: free
flight with cuboid contacts (jump map with restitution, eqs. 33-39 on the direct state),
a spring-damper latch (eq. 81) while docked, and the scripted latch snap of §VII.

Modes (``plant.mode``): ``"free"`` (two bodies, contacts active) and ``"latched"`` (the
eq. 81 latch acts between the docking ports, and the docking faces' physical stop,
:func:`latch_stop_kernel`, keeps them from passing through each other: a stiff unilateral
spring-damper at every deputy corner that crosses the chief's docking-face plane, 62 um
under the 5 N post-capture bound; measured 10 mm overlaps without it).

Translational truth (``gravity``): ``"j2"`` (default of the scenarios) or
``"twobody"``: each CoM and x_ref move under exact inertial point-mass (+ J2) gravity seen
from T (:func:`gravity_correction_kernel`; T = the frame of the chief's initial circular
orbit, uniformly turning at n0); ``"cw"``: the linear model itself (eq. 21). x_ref is then
the natural motion of a point mass under the same gravity (the desired parking orbit is a
natural orbit of the truth). The MPCs keep their CW models, so the mismatch is real. Events returned by :meth:`HybridCapturePlant.propagate_events`:

* ``contact`` -- the cuboids touch while approaching (guard :func:`contact_guard` crosses 0,
  located by :func:`proxops.dynamics.plant.locate_guard` to ``tol_s``), the frictionless
  impulse of :func:`contact_jump` is applied; message ``impulse <gamma> N s ...``.
* ``latch`` -- the state enters the capture envelope (the docking set T_{0->1} of the
  supervisor: |rho| <= r, |rho_dot| <= v, attitude error <= angle, |omega| <= rate): the
  latch engages (free -> latched), checked at the end of every integration substep.
* ``snap`` -- at ``snap_time_s`` while latched: the internal impulse of
  :func:`latch_snap_jump` (``snap_impulse_Ns`` along rho_0) and the latch lets go
  (latched -> free). Applied at the scheduled instant inside the step. A snap time met while
  free is recorded (``snap`` event "skipped: not latched") and does nothing.

After a snap the latch re-arms ``rearm_delay_s`` later (default 10 s; a latch that has just
released cannot grab again on the spot: without the delay the snapped pair, still inside the
envelope at 0.56 mm/s, would re-latch within one substep); from then on the capture envelope
is checked again (re-docking).

Plant state (internal, 38): truth (26, :mod:`proxops.dynamics.two_rigid_bodies`), x_ref
(6, natural motion, the paper's f_T), latched flag, collision count, snap done flag,
time from which the latch is armed, time of the last contact, the plant's clock (s).

Contact location: the guard is tested at each substep end against 0 (apart) or, when the
bodies already touch after a bounce, against the current gap less ``DEPTH_TOL_M`` (10 um),
so a second crossing during a touch is located too (measured contacts found only
after 1.6 mm overlap); the event message gives the overlap at location.

Measured state (``relative_state``, 34): the paper's relative state (32,
:func:`relative_from_truth`, with x_ref) followed by the collision count (a contact sensor:
the capture MPC's weights depend on it, eq. 80) and the latch sensor (1 locked, 0 open).
The collision count c counts collisions, not impulses: a contact less than
``collision_gap_s`` (default 1 s, one control period) after the previous one belongs to the
same collision (a deputy pushed against the chief bounces many times per second; every
impulse is still an event).

Integration: fixed-step RK4 (numba) on substeps of at most ``max_substep_s`` (default
0.05 s: ~5e-3 rad per step at the fastest rates of §VII; the built-in scenarios' latch,
sqrt(K_R/J) ~ 7.4 rad/s, at 17 steps per period, h lambda < 0.8 for its damping: well inside
RK4's stability region). The contact guard is checked
at each substep end: a graze that enters and leaves the other cuboid within one substep
(depth below ~|v_rel| h / 2, i.e. < 2.5 mm at 0.1 m/s) is not seen.

Control: ``u = (F_d|_D, M_d|_D)`` (N, N m), ZOH over the step (``kind="acceleration"`` in
the engine's words: a held command). ``delta_v`` is |F_d| / m_d dt (m/s).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from proxops.core.layout import Block, StateLayout, make_control_layout
from proxops.core.constants import J2_EARTH, MU_EARTH, R_EARTH
from proxops.core.quaternion import dcm_kernel
from proxops.core.twobody import accel_differential, accel_j2
from proxops.dynamics.hybrid_relative import N_REL, relative_from_truth_kernel
from proxops.dynamics.plant import PlantBase, locate_guard
from proxops.dynamics.two_rigid_bodies import (
    N_TRUTH,
    HybridParams,
    cross9,
    dcm9,
    mtv9,
    mv9,
    contact_jump,
    contact_normal_velocity,
    latch_scalars,
    latch_snap_jump,
    port_kinematics_kernel,
    truth_rhs_into,
)
from proxops.errors import input_error

# internal plant-state indices
I_REF = slice(N_TRUTH, N_TRUTH + 6)
I_LATCHED, I_CONTACTS, I_SNAPPED, I_ARMED_FROM, I_LAST_CONTACT = (N_TRUTH + 6, N_TRUTH + 7, N_TRUTH + 8, N_TRUTH + 9,
                                                              N_TRUTH + 10)
I_TIME = N_TRUTH + 11  # the plant's clock (s): the gravity model needs the frame's inertial orientation
N_PLANT = N_TRUTH + 12
DEPTH_TOL_M = 1e-5  # a further overlap than this below the current (touching) gap is located as a new contact
# measured-state indices beyond the paper's 32
M_CONTACTS, M_LATCHED = N_REL, N_REL + 1
N_MEASURED = N_REL + 2

HYBRID_LAYOUT = StateLayout(N_MEASURED, (
    Block("rho", "position", 0, 3, ("rho_x", "rho_y", "rho_z")),
    Block("rho_dot", "velocity", 3, 6, ("rho_dot_x", "rho_dot_y", "rho_dot_z")),
    Block("omega", "rate", 6, 9, ("omega_x", "omega_y", "omega_z")),
    Block("q", "quaternion", 9, 13, ("q_x", "q_y", "q_z", "q_w")),
    Block("p", "quaternion", 13, 17, ("p_x", "p_y", "p_z", "p_w")),
    Block("omega_c", "rate", 17, 20, ("omega_c_x", "omega_c_y", "omega_c_z")),
    Block("rho_n", "other", 20, 23, ("rho_n_x", "rho_n_y", "rho_n_z"), "m"),
    Block("rho_n_dot", "other", 23, 26, ("rho_n_dot_x", "rho_n_dot_y", "rho_n_dot_z"), "m/s"),
    Block("r_des", "other", 26, 29, ("r_des_x", "r_des_y", "r_des_z"), "m"),
    Block("r_des_dot", "other", 29, 32, ("r_des_dot_x", "r_des_dot_y", "r_des_dot_z"), "m/s"),
    Block("contacts", "other", 32, 33, ("contacts",), "count"),
    Block("latched", "other", 33, 34, ("latched",), "flag"),
))  # fmt: skip


@dataclass(frozen=True)
class CaptureEnvelope:
    """The docking set T_{0->1} (around A_0 of eq. 13; the paper gives no size, our choice):
    |rho| <= position_m, |rho_dot| <= velocity_mps, attitude error angle(q, q_I) <= angle_rad,
    |omega| <= rate_rad_s. The latch engages inside it; the supervisor enters post-capture."""

    position_m: float = 0.02
    velocity_mps: float = 0.01
    angle_rad: float = math.radians(2.0)
    rate_rad_s: float = math.radians(0.5)

    def __post_init__(self):
        for name, unit in (("position_m", "m"), ("velocity_mps", "m/s"), ("angle_rad", "rad"), ("rate_rad_s", "rad/s")):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0.0):
                raise input_error(f"docking.{name}", v, "must be a finite number > 0", unit)

    def contains(self, x_rel: np.ndarray) -> bool:
        """x_rel (the paper's 32-state, or the 34 measured) is inside the envelope."""
        x = np.asarray(x_rel, dtype=float)
        return bool(
            np.linalg.norm(x[0:3]) <= self.position_m
            and np.linalg.norm(x[3:6]) <= self.velocity_mps
            and np.linalg.norm(x[6:9]) <= self.rate_rad_s
            and attitude_error_rad(x[9:13]) <= self.angle_rad
        )


def attitude_error_rad(q) -> float:
    """Rotation angle (rad) of the relative attitude q from q_I (q and -q alike)."""
    q = np.asarray(q, dtype=float)
    return float(2.0 * math.atan2(math.sqrt(q[0] ** 2 + q[1] ** 2 + q[2] ** 2), abs(q[3])))


GRAVITY_MODELS = ("cw", "twobody", "j2")  # truth translational gravity (module doc)


@njit(cache=True)
def gravity_correction_kernel(r, t, grav):
    """a_true - a_CW (m/s^2, T components) for a point mass at T-position ``r`` (m) at time
    ``t`` (s), without the Coriolis term (the same in both: T turns at the constant n0).

    ``grav = (mode, n0, a0, cos i, sin i, j2, Re, mu)``; mode 0: CW (returns 0), 1: two-body,
    2: two-body + J2 (:func:`proxops.core.twobody.accel_differential`, Encke/Battin form).
    T is the frame of a circular orbit of radius a0 (n0^2 a0^3 = mu), inclination i, RAAN 0,
    argument of latitude u = n0 t. Exact inertial motion seen from T:
    r'' = [g(R0 + r) - g(R0)] + a_J2(R0) + n0^2 (x, y, 0) - 2 omega_t x r'  (R0 = a0 e_x),
    and CW is r'' = (3 n0^2 x, 0, -n0^2 z) - 2 omega_t x r'."""
    out = np.zeros(3)
    if int(grav[0]) == 0:
        return out
    out[0], out[1], out[2] = gravity_point(r[0], r[1], r[2], gravity_frame(t, grav))
    return out


@njit(cache=True)
def gravity_frame(t, grav):
    """The part of :func:`gravity_correction_kernel` that depends on the time only (one evaluation
    serves every point at t; mode 0, CW, is the caller's to skip): (n0, a0, j2, Re, mu, the columns
    e_x, e_y, e_z of C_{I<-T} (9 floats), a_J2(R0) (3; 0 for two-body))."""
    n, a0, ci, si, j2, re, mu = grav[1], grav[2], grav[3], grav[4], grav[5], grav[6], grav[7]
    if int(grav[0]) == 1:
        j2 = 0.0
    u = n * t
    cu, su = math.cos(u), math.sin(u)
    # columns of C_{I<-T}: e_x (radial), e_y (along-track), e_z (orbit normal)
    ex0, ex1, ex2 = cu, ci * su, si * su
    ey0, ey1, ey2 = -su, ci * cu, si * cu
    ez0, ez1, ez2 = 0.0, -si, ci
    bx = by = bz = 0.0
    if j2 != 0.0:
        bx, by, bz = accel_j2(a0 * ex0, a0 * ex1, a0 * ex2, mu, j2, re)
    return (n, a0, j2, re, mu, ex0, ex1, ex2, ey0, ey1, ey2, ez0, ez1, ez2, bx, by, bz)


@njit(cache=True, inline="always")
def gravity_point(r0, r1, r2, fr):
    """:func:`gravity_correction_kernel` at the T-position (r0, r1, r2) (m) with the time's
    :func:`gravity_frame` ``fr``, as a tuple (m/s^2)."""
    n, a0, j2, re, mu, ex0, ex1, ex2, ey0, ey1, ey2, ez0, ez1, ez2, bx, by, bz = fr
    dx = ex0 * r0 + ey0 * r1 + ez0 * r2
    dy = ex1 * r0 + ey1 * r1 + ez1 * r2
    dz = ex2 * r0 + ey2 * r1 + ez2 * r2
    rx, ry, rz = a0 * ex0, a0 * ex1, a0 * ex2
    ax, ay, az = accel_differential(rx, ry, rz, dx, dy, dz, mu, 0.0, re)
    if j2 != 0.0:  # accel_differential's J2 difference, with a_J2(R0) = (bx, by, bz) of the frame (computed once per t)
        cx, cy, cz = accel_j2(rx + dx, ry + dy, rz + dz, mu, j2, re)
        ax += cx - bx
        ay += cy - by
        az += cz - bz
        ax += bx
        ay += by
        az += bz
    return (ex0 * ax + ex1 * ay + ex2 * az - 2.0 * n * n * r0,
            ey0 * ax + ey1 * ay + ey2 * az + n * n * r1,
            ez0 * ax + ez1 * ay + ez2 * az + n * n * r2)


STOP_K_N_PER_M = 2.0e4  # latch stop: stiffness per deputy corner (4 on the docking face: 8e4 N/m, 62 um under 5 N)
STOP_C_NS_PER_M = 400.0  # and damping per corner (~0.3 of critical for the 90 kg reduced mass)


@njit(cache=True)
def latch_stop_kernel(x, corners_d, v_c, plane_c, k, c, omega_t):
    """Physical stop of the docking faces while latched: every deputy cuboid corner that passes
    the plane of the chief's docking face (normal v in C through P_c) is pushed back by a
    unilateral spring-damper (k depth + c depth', never pulling) acting at that corner on the
    deputy and its opposite on the chief (momentum conserving). Returns (F_T on the deputy's
    CoM sum (N, T), tau_d (N m, D), tau_c (N m, C), deepest penetration m)."""
    F0, F1, F2, d0, d1, d2, c0, c1, c2, deepest = latch_stop_scalars(x, corners_d, v_c, plane_c, k, c, omega_t[0],
                                                                     omega_t[1], omega_t[2])
    return np.array([F0, F1, F2]), np.array([d0, d1, d2]), np.array([c0, c1, c2]), deepest


@njit(cache=True)
def latch_stop_scalars(x, corners_d, v_c, plane_c, k, c, w0, w1, w2):
    """:func:`latch_stop_kernel` with omega_t = (w0, w1, w2), as ten floats (F_T, tau_d, tau_c,
    deepest; no heap array)."""
    Rc = dcm9(x[12:16])
    Rd = dcm9(x[19:23])
    r0, r1, r2 = x[6] - x[0], x[7] - x[1], x[8] - x[2]
    c0, c1, c2 = cross9(w0, w1, w2, r0, r1, r2)
    vr0, vr1, vr2 = x[9] - x[3] + c0, x[10] - x[4] + c1, x[11] - x[5] + c2
    Wc0, Wc1, Wc2 = mv9(Rc, x[16], x[17], x[18])
    Wd0, Wd1, Wd2 = mv9(Rd, x[23], x[24], x[25])
    n0, n1, n2 = mv9(Rc, v_c[0], v_c[1], v_c[2])
    Fs0 = Fs1 = Fs2 = 0.0
    td0 = td1 = td2 = 0.0
    tc0 = tc1 = tc2 = 0.0
    deepest = 0.0
    for i in range(corners_d.shape[0]):
        a0, a1, a2 = mv9(Rd, corners_d[i, 0], corners_d[i, 1], corners_d[i, 2])
        p0, p1, p2 = r0 + a0, r1 + a1, r2 + a2
        depth = plane_c - (n0 * p0 + n1 * p1 + n2 * p2)
        if depth <= 0.0:
            continue
        deepest = max(deepest, depth)
        b0, b1, b2 = cross9(Wd0, Wd1, Wd2, a0, a1, a2)
        c0, c1, c2 = cross9(Wc0, Wc1, Wc2, p0, p1, p2)
        rate = -(n0 * (vr0 + b0 - c0) + n1 * (vr1 + b1 - c1) + n2 * (vr2 + b2 - c2))
        f = k * depth + c * rate
        if f <= 0.0:
            continue
        F0, F1, F2 = f * n0, f * n1, f * n2
        Fs0 += F0
        Fs1 += F1
        Fs2 += F2
        b0, b1, b2 = cross9(a0, a1, a2, F0, F1, F2)
        b0, b1, b2 = mtv9(Rd, b0, b1, b2)
        td0 += b0
        td1 += b1
        td2 += b2
        c0, c1, c2 = cross9(p0, p1, p2, -F0, -F1, -F2)
        c0, c1, c2 = mtv9(Rc, c0, c1, c2)
        tc0 += c0
        tc1 += c1
        tc2 += c2
    return Fs0, Fs1, Fs2, td0, td1, td2, tc0, tc1, tc2, deepest


@njit(cache=True, inline="always")
def _add_pair(dy, m_c, m_d, J_c_inv, J_d_inv, F0, F1, F2, d0, d1, d2, c0, c1, c2):
    """An internal force/torque pair into dy: the deputy's acceleration + F/m_d, the chief's - F/m_c,
    J^-1 tau into both body rates (element by element the array expressions of the former form)."""
    dy[9] += F0 / m_d
    dy[10] += F1 / m_d
    dy[11] += F2 / m_d
    dy[3] -= F0 / m_c
    dy[4] -= F1 / m_c
    dy[5] -= F2 / m_c
    for i in range(3):
        dy[23 + i] += J_d_inv[i, 0] * d0 + J_d_inv[i, 1] * d1 + J_d_inv[i, 2] * d2
    for i in range(3):
        dy[16 + i] += J_c_inv[i, 0] * c0 + J_c_inv[i, 1] * c1 + J_c_inv[i, 2] * c2


@njit(cache=True)
def _rhs(y, u, latched, t, grav, stop, corners_d, m_c, m_d, J_c, J_c_inv, J_d, J_d_inv, n, P_c, P_d, KT, DT, KR, DR):
    """d/dt of truth (26) + x_ref (6) at time t (s); the latch pair of
    two_rigid_bodies.latch_wrench when latched; the CW translation of truth_rhs_kernel
    corrected to the ``grav`` model (:func:`gravity_correction_kernel`) for both CoMs and x_ref."""
    dy = np.empty(32)
    _rhs_into(y, u, latched, t, grav, stop, corners_d, m_c, m_d, J_c, J_c_inv, J_d, J_d_inv, n, P_c, P_d, KT, DT,
              KR, DR, dy)
    return dy


@njit(cache=True)
def _rhs_into(y, u, latched, t, grav, stop, corners_d, m_c, m_d, J_c, J_c_inv, J_d, J_d_inv, n, P_c, P_d, KT, DT,
              KR, DR, dy):
    """:func:`_rhs` written into ``dy`` (32) without a heap array (the RK4 calls it 4 times a substep)."""
    truth_rhs_into(y, u, m_c, m_d, J_c, J_c_inv, J_d, J_d_inv, n, dy)
    if latched:
        F0, F1, F2, d0, d1, d2, c0, c1, c2 = latch_scalars(y, P_c, P_d, KT, DT, KR, DR, n)
        _add_pair(dy, m_c, m_d, J_c_inv, J_d_inv, F0, F1, F2, d0, d1, d2, c0, c1, c2)
        if stop[0] > 0.0:
            F0, F1, F2, d0, d1, d2, c0, c1, c2, _ = latch_stop_scalars(y, corners_d, stop[1:4], stop[4], stop[5],
                                                                       stop[6], 0.0, 0.0, n)
            _add_pair(dy, m_c, m_d, J_c_inv, J_d_inv, F0, F1, F2, d0, d1, d2, c0, c1, c2)
    # x_ref: natural motion of a point mass (CW: corrected G2 of eq. 21, hybrid_relative.reference_rhs)
    dy[26] = y[29]
    dy[27] = y[30]
    dy[28] = y[31]
    dy[29] = 3.0 * n * n * y[26] + 2.0 * n * y[30]
    dy[30] = -2.0 * n * y[29]
    dy[31] = -n * n * y[28]
    if grav[0] > 0.5:  # both CoMs and x_ref, with one gravity_frame for the three
        fr = gravity_frame(t, grav)
        for i in (3, 9, 29):
            g0, g1, g2 = gravity_point(y[i - 3], y[i - 2], y[i - 1], fr)
            dy[i] += g0
            dy[i + 1] += g1
            dy[i + 2] += g2


@njit(cache=True)
def _rk4(y, u, latched, t0, grav, stop, corners_d, h, n_steps, m_c, m_d, J_c, J_c_inv, J_d, J_d_inv, n, P_c, P_d, KT, DT, KR, DR):
    """``n_steps`` classical RK4 steps of length h (s) from time t0 (s); quaternions
    renormalised after each."""
    out = y[0:32].copy()
    _rk4_inplace(out, u, latched, t0, grav, stop, corners_d, h, n_steps, m_c, m_d, J_c, J_c_inv, J_d, J_d_inv, n,
                 P_c, P_d, KT, DT, KR, DR, np.empty((5, 32)))
    return out


@njit(cache=True)
def _rk4_inplace(y, u, latched, t0, grav, stop, corners_d, h, n_steps, m_c, m_d, J_c, J_c_inv, J_d, J_d_inv, n, P_c,
                 P_d, KT, DT, KR, DR, work):
    """:func:`_rk4` on ``y`` (32) in place, with a (5, 32) ``work`` array (k1..k4 and the stage
    state): element by element the operations of the array form y + h/6 (k1 + 2 k2 + 2 k3 + k4)
    in the same order, so the same bits (tests/test_hybrid_truth.py)."""
    k1, k2, k3, k4, z = work[0], work[1], work[2], work[3], work[4]
    a = (m_c, m_d, J_c, J_c_inv, J_d, J_d_inv, n, P_c, P_d, KT, DT, KR, DR)
    hh = 0.5 * h
    h6 = h / 6.0
    for i in range(n_steps):
        t = t0 + i * h
        _rhs_into(y, u, latched, t, grav, stop, corners_d, *a, k1)
        for j in range(32):
            z[j] = y[j] + hh * k1[j]
        _rhs_into(z, u, latched, t + 0.5 * h, grav, stop, corners_d, *a, k2)
        for j in range(32):
            z[j] = y[j] + hh * k2[j]
        _rhs_into(z, u, latched, t + 0.5 * h, grav, stop, corners_d, *a, k3)
        for j in range(32):
            z[j] = y[j] + h * k3[j]
        _rhs_into(z, u, latched, t + h, grav, stop, corners_d, *a, k4)
        for j in range(32):
            y[j] = y[j] + h6 * (k1[j] + 2.0 * k2[j] + 2.0 * k3[j] + k4[j])
        for q0 in (12, 19):  # renormalise: q / sqrt(sum of squares, summed in order)
            r = math.sqrt(y[q0] * y[q0] + y[q0 + 1] * y[q0 + 1] + y[q0 + 2] * y[q0 + 2] + y[q0 + 3] * y[q0 + 3])
            for j in range(q0, q0 + 4):
                y[j] = y[j] / r


@njit(cache=True)
def sat_gap_kernel(x, hc, hd):
    """numba form of :func:`proxops.dynamics.two_rigid_bodies.contact_guard` (the
    separating-axis gap of the two cuboids, m; same 15 axes), with a bounding-sphere early out
    (returns the positive sphere gap when the spheres are apart: same sign, cheaper)."""
    d0, d1, d2 = x[6] - x[0], x[7] - x[1], x[8] - x[2]
    dist = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
    sphere_gap = dist - math.sqrt(hc[0] ** 2 + hc[1] ** 2 + hc[2] ** 2) - math.sqrt(hd[0] ** 2 + hd[1] ** 2 + hd[2] ** 2)
    if sphere_gap > 0.0:
        return sphere_gap
    Rc = dcm9(x[12:16])  # row major: R[i, j] = R9[3 i + j] (no heap array: ~40 calls a free-flight step)
    Rd = dcm9(x[19:23])
    best = -np.inf
    for k in range(15):  # face normals of the chief (columns of Rc), of the deputy, then their cross products
        if k < 3:
            a0, a1, a2 = Rc[k], Rc[3 + k], Rc[6 + k]
        elif k < 6:
            a0, a1, a2 = Rd[k - 3], Rd[k], Rd[k + 3]
        else:
            i, j = (k - 6) // 3, (k - 6) % 3
            a0 = Rc[3 + i] * Rd[6 + j] - Rc[6 + i] * Rd[3 + j]
            a1 = Rc[6 + i] * Rd[j] - Rc[i] * Rd[6 + j]
            a2 = Rc[i] * Rd[3 + j] - Rc[3 + i] * Rd[j]
            na = math.sqrt(a0 * a0 + a1 * a1 + a2 * a2)
            if not na > 1e-9:
                continue
            a0, a1, a2 = a0 / na, a1 / na, a2 / na
        gap = abs(d0 * a0 + d1 * a1 + d2 * a2)
        for m in range(3):
            gap -= (abs(Rc[m] * a0 + Rc[3 + m] * a1 + Rc[6 + m] * a2) * hc[m]
                    + abs(Rd[m] * a0 + Rd[3 + m] * a1 + Rd[6 + m] * a2) * hd[m])
        if gap > best:
            best = gap
    return best


@njit(cache=True)
def envelope_kernel(x, P_c, P_d, n):
    """(|rho| m, |rho_dot| m/s, |omega| rad/s, attitude error rad) of the truth state x (26)."""
    _, _, _, q, om, rho, rhod = port_kinematics_kernel(x, P_c, P_d, n)
    s = math.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2])
    angle = 2.0 * math.atan2(s, abs(q[3]))
    return (math.sqrt(rho[0] * rho[0] + rho[1] * rho[1] + rho[2] * rho[2]),
            math.sqrt(rhod[0] * rhod[0] + rhod[1] * rhod[1] + rhod[2] * rhod[2]),
            math.sqrt(om[0] * om[0] + om[1] * om[1] + om[2] * om[2]), angle)


@njit(cache=True)
def advance_kernel(y, u, t, done, dt, h, n_max, latched, armed_from, env, grav, stop, corners_d, hc, hd,
                   m_c, m_d, J_c, J_c_inv, J_d, J_d_inv, n, P_c, P_d, KT, DT, KR, DR):
    """Up to ``n_max`` plain substeps of :meth:`HybridCapturePlant.propagate_events` in one call
    (the same arithmetic as its Python loop: step = min(h, dt - done), one RK4 step each, the
    plant clock y[I_TIME] advanced by step). Free flight stops *before* a substep whose start
    touches (guard <= 0) or whose end crosses the guard (the Python path locates the contact),
    and *after* a substep that ends inside the capture envelope once armed (code 2: latch).
    ``y`` (38) is updated in place; returns (done, code): 0 = n_max substeps or dt reached,
    1 = stopped before a contact substep, 2 = latched."""
    y32 = y[0:32].copy()
    nxt = np.empty(32)
    work = np.empty((5, 32))  # RK4 stages, reused by every substep
    ytime = y[37]
    for _ in range(n_max):
        if not done < dt - 1e-12:
            break
        step = min(h, dt - done)
        if not latched:
            if sat_gap_kernel(y32[0:26], hc, hd) <= 0.0:
                break
        nxt[:] = y32
        _rk4_inplace(nxt, u, latched, ytime, grav, stop, corners_d, step, 1, m_c, m_d, J_c, J_c_inv, J_d, J_d_inv,
                     n, P_c, P_d, KT, DT, KR, DR, work)
        if not latched and sat_gap_kernel(nxt[0:26], hc, hd) <= 0.0:
            break
        y32, nxt = nxt, y32
        ytime = ytime + step
        done += step
        if not latched and t + done >= armed_from:
            rho, rhod, om, angle = envelope_kernel(y32[0:26], P_c, P_d, n)
            if rho <= env[0] and rhod <= env[1] and om <= env[2] and angle <= env[3]:
                y[0:32] = y32
                y[37] = ytime
                return done, 2
    y[0:32] = y32
    y[37] = ytime
    return done, 0 if not done < dt - 1e-12 else 1


class HybridCapturePlant(PlantBase):
    """Plant (:class:`proxops.contracts.Plant`) of the chief-deputy pair with contacts,
    latch and latch snap (module doc)."""

    n_x, n_u = N_MEASURED, 6
    layout = HYBRID_LAYOUT
    control_layout = make_control_layout(("F_x", "F_y", "F_z", "M_x", "M_y", "M_z"), ("N",) * 3 + ("N m",) * 3, "deputy")
    has_events = True

    def __init__(self, params: HybridParams, x0_truth, envelope: CaptureEnvelope = CaptureEnvelope(),
                 x_ref0=None, snap_enabled: bool = True, rearm_delay_s: float = 10.0,
                 max_substep_s: float = 0.05, tol_s: float = 1e-7, start_latched: bool = False,
                 collision_gap_s: float = 1.0, gravity: str = "cw", inclination_deg: float = 51.6,
                 latch_stop: bool = True):
        self.params = params
        if gravity not in GRAVITY_MODELS:
            raise input_error("truth.gravity", gravity, "allowed: " + ", ".join(GRAVITY_MODELS))
        if not (math.isfinite(inclination_deg) and 0.0 <= inclination_deg <= 180.0):
            raise input_error("inclination_deg", inclination_deg, "must lie in [0, 180]", "deg")
        self.gravity, self.latch_stop = gravity, bool(latch_stop)
        n0 = params.mean_motion_rad_s
        inc = math.radians(inclination_deg)
        self._grav = np.array([float(GRAVITY_MODELS.index(gravity)), n0, (MU_EARTH / n0 ** 2) ** (1.0 / 3.0),
                               math.cos(inc), math.sin(inc), J2_EARTH, R_EARTH, MU_EARTH])
        self.envelope = envelope
        self.snap_enabled = bool(snap_enabled)
        if not (math.isfinite(rearm_delay_s) and rearm_delay_s >= 0.0):
            raise input_error("latch.rearm_delay_s", rearm_delay_s, "must be a finite number >= 0", "s")
        self.rearm_delay_s = float(rearm_delay_s)
        if not (math.isfinite(max_substep_s) and max_substep_s > 0.0):
            raise input_error("max_substep_s", max_substep_s, "must be a finite number > 0", "s")
        self.max_substep_s, self.tol_s = float(max_substep_s), float(tol_s)
        if not (math.isfinite(collision_gap_s) and collision_gap_s >= 0.0):
            raise input_error("contact.collision_gap_s", collision_gap_s, "must be a finite number >= 0", "s")
        self.collision_gap_s = float(collision_gap_s)
        y0 = np.zeros(N_PLANT)
        y0[:N_TRUTH] = np.asarray(x0_truth, dtype=float)
        y0[I_REF] = np.zeros(6) if x_ref0 is None else np.asarray(x_ref0, dtype=float)
        y0[I_LATCHED] = 1.0 if start_latched else 0.0
        y0[I_ARMED_FROM] = 0.0
        y0[I_LAST_CONTACT] = -math.inf
        self.y0 = y0
        p = params
        self._hc, self._hd = params.half_chief, params.half_deputy
        v = params.P_c / np.linalg.norm(params.P_c)
        self._corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], float) * self._hd
        self._stop = np.array([1.0 if self.latch_stop else 0.0, *v, float(v @ params.P_c), STOP_K_N_PER_M,
                               STOP_C_NS_PER_M])
        env = self.envelope
        self._env = np.array([env.position_m, env.velocity_mps, env.rate_rad_s, env.angle_rad])
        self._rel_args = (p.P_c, p.P_d, float(p.mass_chief_kg), float(p.mass_deputy_kg), float(p.mean_motion_rad_s))
        self._args = (p.mass_chief_kg, p.mass_deputy_kg, p.J_c, p.J_c_inv, p.J_d, p.J_d_inv, p.mean_motion_rad_s,
                      p.P_c, p.P_d, float(p.latch_KT), float(p.latch_DT), float(p.latch_KR), float(p.latch_DR))

    # --- protocol -------------------------------------------------------------------
    def initial_state(self) -> np.ndarray:
        return self.y0.copy()

    def relative_state(self, state: np.ndarray) -> np.ndarray:
        y = np.asarray(state, dtype=float)
        out = np.empty(N_MEASURED)
        relative_from_truth_kernel(y, y[I_REF], out, *self._rel_args)  # relative_from_truth into out[:N_REL]
        out[M_CONTACTS] = y[I_CONTACTS]
        out[M_LATCHED] = y[I_LATCHED]
        return out

    def mode(self, state: np.ndarray) -> str:
        return "latched" if state[I_LATCHED] > 0.5 else "free"

    def delta_v(self, u: np.ndarray, kind: str, dt: float) -> float:
        """|F_d| / m_d dt (m/s): the deputy's translational delta-v of the held thrust."""
        f = np.asarray(u, float)[0:3]
        return math.sqrt(f.dot(f)) / self.params.mass_deputy_kg * dt  # np.linalg.norm's sqrt(f.dot(f))

    def apply_impulse(self, t: float, state: np.ndarray, dv: np.ndarray) -> np.ndarray:
        raise NotImplementedError("HybridCapturePlant takes held thrust/torque commands (kind='acceleration')")

    def propagate(self, t: float, state: np.ndarray, u: np.ndarray, dt: float) -> np.ndarray:
        return self.propagate_events(t, state, u, dt)[0]

    # --- flow and jumps -------------------------------------------------------------
    def flow(self, y: np.ndarray, u: np.ndarray, tau: float) -> np.ndarray:
        """Flow of the current mode over ``tau`` s (RK4 substeps of at most max_substep_s)."""
        if tau <= 0.0:
            return y.copy()
        n_sub = max(1, int(math.ceil(tau / self.max_substep_s - 1e-9)))
        out = y.copy()
        out[:32] = _rk4(y[:32], u, y[I_LATCHED] > 0.5, y[I_TIME], self._grav, self._stop, self._corners, tau / n_sub, n_sub, *self._args)
        out[I_TIME] = y[I_TIME] + tau
        return out

    def _guard(self, y: np.ndarray) -> float:
        """Contact guard (m): :func:`contact_guard` of the truth (numba form, same sign)."""
        return sat_gap_kernel(y[:N_TRUTH], self._hc, self._hd)

    def propagate_events(self, t: float, state: np.ndarray, u: np.ndarray, dt: float):
        y = np.asarray(state, dtype=float).copy()
        y[I_TIME] = t
        u = np.asarray(u, dtype=float)
        events: list[tuple[float, str, str]] = []
        t_snap = self.params.snap_time_s
        done = 0.0
        n_sub = max(1, int(math.ceil(dt / self.max_substep_s - 1e-9)))
        h = dt / n_sub
        while done < dt - 1e-12:
            step = min(h, dt - done)
            t_now = t + done
            # the scheduled snap inside this substep: flow to it, jump, continue
            if self.snap_enabled and y[I_SNAPPED] < 0.5 and t_now - 1e-12 < t_snap <= t_now + step + 1e-12:
                y = self.flow(y, u, max(t_snap - t_now, 0.0))
                done += max(t_snap - t_now, 0.0)
                y[I_SNAPPED] = 1.0
                if y[I_LATCHED] > 0.5:
                    y[:N_TRUTH] = latch_snap_jump(y[:N_TRUTH], self.params)
                    y[I_LATCHED], y[I_ARMED_FROM] = 0.0, t_snap + self.rearm_delay_s
                    events.append((t_snap, "snap", f"latch snap {self.params.snap_impulse_Ns:g} N s along rho_0, "
                                   "latch released"))
                    events.append((t_snap, "latch", "latched -> free"))
                else:
                    events.append((t_snap, "snap", "skipped: not latched"))
                continue
            n_fast = n_sub + 1
            if self.snap_enabled and y[I_SNAPPED] < 0.5 and t_snap > t_now - 1e-12:  # stop before the snap substep
                n_fast = int((t_snap - t_now) / h) - 1  # (the Python path checks the last ones)
            if n_fast > 0:  # plain substeps in one numba call (advance_kernel); only events come back here
                done, code = advance_kernel(y, u, t, done, dt, h, n_fast, bool(y[I_LATCHED] > 0.5),
                                            float(y[I_ARMED_FROM]), self._env, self._grav, self._stop, self._corners,
                                            self._hc, self._hd, *self._args)
                if code == 2:
                    y[I_LATCHED] = 1.0
                    events.append((t + done, "latch", "free -> latched"))
                    continue
                if not done < dt - 1e-12:
                    break
                step = min(h, dt - done)
                t_now = t + done
                if self.snap_enabled and y[I_SNAPPED] < 0.5 and t_now - 1e-12 < t_snap <= t_now + step + 1e-12:
                    continue  # the snap branch above
            latched = y[I_LATCHED] > 0.5
            if latched:  # the latch and its face stop (latch_stop_kernel) are in the flow
                y = self.flow(y, u, step)
                done += step
                continue
            # free-flight contacts. A contact already on and approaching jumps at once; otherwise
            # the step's end is tested against the current gap (0 when apart, the gap less
            # DEPTH_TOL_M when touching) and the crossing located by bisection.
            if self._guard(y) <= 0.0 and contact_normal_velocity(y[:N_TRUTH], self.params) < 0.0:
                self._contact(y, t_now, events)
            g0 = self._guard(y)
            level = 0.0 if g0 > 0.0 else g0 - DEPTH_TOL_M
            y_next = self.flow(y, u, step)
            if self._guard(y_next) <= level:
                tau, y_hit = locate_guard(lambda y0, s: self.flow(y0, u, s), lambda yy: self._guard(yy) - level,
                                          y, step, self.tol_s, n_scan=1)
                y = y_hit
                done += tau
                self._contact(y, t + done, events)
            else:
                y = y_next
                done += step
            self._latch_check(y, t + done, events)
        return y, events

    def _contact(self, y: np.ndarray, t_event: float, events: list) -> None:
        """Apply the contact jump in place (if approaching) and record the event with the
        overlap at which it was located (m)."""
        depth = -self._guard(y)
        x_plus, gamma, r, n = contact_jump(y[:N_TRUTH], self.params)
        if gamma > 0.0:
            y[:N_TRUTH] = x_plus
            if t_event - y[I_LAST_CONTACT] > self.collision_gap_s:
                y[I_CONTACTS] += 1.0  # a new collision; contacts closer than collision_gap_s belong to it
            y[I_LAST_CONTACT] = t_event
            events.append((t_event, "contact", f"impulse {gamma:.6g} N s, normal [{n[0]:.3f}, {n[1]:.3f}, {n[2]:.3f}], "
                           f"e = {self.params.restitution:g}, overlap {max(depth, 0.0):.3g} m"))
        return None

    def _latch_check(self, y: np.ndarray, t_event: float, events: list) -> None:
        if t_event < y[I_ARMED_FROM]:
            return
        rho, rhod, om, angle = envelope_kernel(y[:N_TRUTH], self.params.P_c, self.params.P_d,
                                               self.params.mean_motion_rad_s)
        env = self.envelope
        if rho <= env.position_m and rhod <= env.velocity_mps and om <= env.rate_rad_s and angle <= env.angle_rad:
            y[I_LATCHED] = 1.0
            events.append((t_event, "latch", "free -> latched"))


def overlap_from_relative(x_rel, params: HybridParams) -> float:
    """Separating-axis gap (m) of the two cuboids from the relative pose of ``x_rel`` (rho in C,
    q = D rel. C): positive apart, negative = overlap depth. The chief is placed at the origin
    of C, the deputy CoM at rho + P_c - C_{C<-D} P_d."""
    x = np.asarray(x_rel, float)
    q = x[9:13] / np.linalg.norm(x[9:13])
    Q_T = dcm_kernel(q)  # C_{C<-D}
    xt = np.zeros(N_TRUTH)
    xt[15] = 1.0
    xt[6:9] = x[0:3] + params.P_c - Q_T @ params.P_d
    xt[19:23] = q
    return float(sat_gap_kernel(xt, params.half_chief, params.half_deputy))


def contact_impulses(events) -> list[dict]:
    """[{t_s, impulse_Ns}] of the ``contact`` events of a run (message format above)."""
    out = []
    for t, kind, msg in events:
        if kind == "contact" and msg.startswith("impulse "):
            out.append({"t_s": float(t), "impulse_Ns": float(msg.split()[1].rstrip(","))})
    return out

