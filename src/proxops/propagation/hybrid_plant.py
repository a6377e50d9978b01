"""The two-rigid-body truth of hybrid-mpc-capture.md as an engine plant with events: free
flight with cuboid contacts (jump map with restitution, eqs. 33-39 on the direct state),
a spring-damper latch (eq. 81) while docked, and the scripted latch snap of §VII.

Modes (``plant.mode``): ``"free"`` (two bodies, contacts active) and ``"latched"`` (the
eq. 81 latch acts between the docking ports; contacts are not checked, as in the paper's
h = 1 flow). Events returned by :meth:`HybridCapturePlant.propagate_events`:

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

Plant state (internal, 37): truth (26, :mod:`proxops.dynamics.two_rigid_bodies`), x_ref
(6, natural CW motion, the paper's f_T), latched flag, collision count, snap done flag,
time from which the latch is armed, time of the last contact.

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
from proxops.core.quaternion import dcm_kernel
from proxops.dynamics.hybrid_relative import N_REL, relative_from_truth
from proxops.dynamics.plant import PlantBase, locate_guard
from proxops.dynamics.two_rigid_bodies import (
    N_TRUTH,
    HybridParams,
    _latch_kernel,
    contact_jump,
    contact_normal_velocity,
    latch_snap_jump,
    port_kinematics_kernel,
    truth_rhs_kernel,
)
from proxops.errors import input_error

# internal plant-state indices
I_REF = slice(N_TRUTH, N_TRUTH + 6)
I_LATCHED, I_CONTACTS, I_SNAPPED, I_ARMED_FROM, I_LAST_CONTACT = (N_TRUTH + 6, N_TRUTH + 7, N_TRUTH + 8, N_TRUTH + 9,
                                                              N_TRUTH + 10)
N_PLANT = N_TRUTH + 11
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


@njit(cache=True)
def _rhs(y, u, latched, m_c, m_d, J_c, J_c_inv, J_d, J_d_inv, n, P_c, P_d, KT, DT, KR, DR):
    """d/dt of truth (26) + x_ref (6); the latch pair of two_rigid_bodies.latch_wrench when latched."""
    dy = np.zeros(32)
    x = y[0:26]
    dy[0:26] = truth_rhs_kernel(x, u, m_c, m_d, J_c, J_c_inv, J_d, J_d_inv, n)
    if latched:
        F, tau_d, tau_c = _latch_kernel(x, P_c, P_d, KT, DT, KR, DR, n)
        dy[9:12] += F / m_d
        dy[3:6] -= F / m_c
        dy[23:26] += J_d_inv @ tau_d
        dy[16:19] += J_c_inv @ tau_c
    # x_ref: natural CW motion (corrected G2 of eq. 21), hybrid_relative.reference_rhs
    dy[26:29] = y[29:32]
    dy[29] = 3.0 * n * n * y[26] + 2.0 * n * y[30]
    dy[30] = -2.0 * n * y[29]
    dy[31] = -n * n * y[28]
    return dy


@njit(cache=True)
def _rk4(y, u, latched, h, n_steps, m_c, m_d, J_c, J_c_inv, J_d, J_d_inv, n, P_c, P_d, KT, DT, KR, DR):
    """``n_steps`` classical RK4 steps of length h (s); quaternions renormalised after each."""
    y = y.copy()
    for _ in range(n_steps):
        k1 = _rhs(y, u, latched, m_c, m_d, J_c, J_c_inv, J_d, J_d_inv, n, P_c, P_d, KT, DT, KR, DR)
        k2 = _rhs(y + 0.5 * h * k1, u, latched, m_c, m_d, J_c, J_c_inv, J_d, J_d_inv, n, P_c, P_d, KT, DT, KR, DR)
        k3 = _rhs(y + 0.5 * h * k2, u, latched, m_c, m_d, J_c, J_c_inv, J_d, J_d_inv, n, P_c, P_d, KT, DT, KR, DR)
        k4 = _rhs(y + h * k3, u, latched, m_c, m_d, J_c, J_c_inv, J_d, J_d_inv, n, P_c, P_d, KT, DT, KR, DR)
        y = y + h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
        y[12:16] /= np.sqrt(np.sum(y[12:16] ** 2))
        y[19:23] /= np.sqrt(np.sum(y[19:23] ** 2))
    return y


@njit(cache=True)
def sat_gap_kernel(x, hc, hd):
    """numba form of :func:`proxops.dynamics.two_rigid_bodies.contact_guard` (the
    separating-axis gap of the two cuboids, m; same 15 axes), with a bounding-sphere early out
    (returns the positive sphere gap when the spheres are apart: same sign, cheaper)."""
    d = x[6:9] - x[0:3]
    dist = math.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2])
    sphere_gap = dist - math.sqrt(hc[0] ** 2 + hc[1] ** 2 + hc[2] ** 2) - math.sqrt(hd[0] ** 2 + hd[1] ** 2 + hd[2] ** 2)
    if sphere_gap > 0.0:
        return sphere_gap
    Rc = dcm_kernel(x[12:16])
    Rd = dcm_kernel(x[19:23])
    best = -np.inf
    axes = np.empty((15, 3))
    valid = np.ones(15, dtype=np.bool_)
    for i in range(3):
        axes[i] = Rc[:, i]
        axes[3 + i] = Rd[:, i]
    for i in range(3):
        for j in range(3):
            a = np.array([Rc[1, i] * Rd[2, j] - Rc[2, i] * Rd[1, j], Rc[2, i] * Rd[0, j] - Rc[0, i] * Rd[2, j],
                          Rc[0, i] * Rd[1, j] - Rc[1, i] * Rd[0, j]])
            na = math.sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2])
            k = 6 + 3 * i + j
            if na > 1e-9:
                axes[k] = a / na
            else:
                valid[k] = False
    for k in range(15):
        if not valid[k]:
            continue
        a = axes[k]
        gap = abs(d @ a) - np.sum(np.abs(Rc.T @ a) * hc) - np.sum(np.abs(Rd.T @ a) * hd)
        if gap > best:
            best = gap
    return best


@njit(cache=True)
def envelope_kernel(x, P_c, P_d, n):
    """(|rho| m, |rho_dot| m/s, |omega| rad/s, attitude error rad) of the truth state x (26)."""
    _, _, _, q, om, rho, rhod = port_kinematics_kernel(x, P_c, P_d, n)
    s = math.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2])
    angle = 2.0 * math.atan2(s, abs(q[3]))
    return (math.sqrt(rho @ rho), math.sqrt(rhod @ rhod), math.sqrt(om @ om), angle)


class HybridCapturePlant(PlantBase):
    """Plant (:class:`proxops.sim.protocols.Plant`) of the chief-deputy pair with contacts,
    latch and latch snap (module doc)."""

    n_x, n_u = N_MEASURED, 6
    layout = HYBRID_LAYOUT
    control_layout = make_control_layout(("F_x", "F_y", "F_z", "M_x", "M_y", "M_z"), ("N",) * 3 + ("N m",) * 3, "deputy")
    has_events = True

    def __init__(self, params: HybridParams, x0_truth, envelope: CaptureEnvelope = CaptureEnvelope(),
                 x_ref0=None, snap_enabled: bool = True, rearm_delay_s: float = 10.0,
                 max_substep_s: float = 0.05, tol_s: float = 1e-7, start_latched: bool = False,
                 collision_gap_s: float = 1.0):
        self.params = params
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
        self._args = (p.mass_chief_kg, p.mass_deputy_kg, p.J_c, p.J_c_inv, p.J_d, p.J_d_inv, p.mean_motion_rad_s,
                      p.P_c, p.P_d, float(p.latch_KT), float(p.latch_DT), float(p.latch_KR), float(p.latch_DR))

    # --- protocol -------------------------------------------------------------------
    def initial_state(self) -> np.ndarray:
        return self.y0.copy()

    def relative_state(self, state: np.ndarray) -> np.ndarray:
        y = np.asarray(state, dtype=float)
        out = np.empty(N_MEASURED)
        out[:N_REL] = relative_from_truth(y[:N_TRUTH], self.params, y[I_REF])
        out[M_CONTACTS] = y[I_CONTACTS]
        out[M_LATCHED] = y[I_LATCHED]
        return out

    def mode(self, state: np.ndarray) -> str:
        return "latched" if state[I_LATCHED] > 0.5 else "free"

    def delta_v(self, u: np.ndarray, kind: str, dt: float) -> float:
        """|F_d| / m_d dt (m/s): the deputy's translational delta-v of the held thrust."""
        return float(np.linalg.norm(np.asarray(u, float)[0:3])) / self.params.mass_deputy_kg * dt

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
        out[:32] = _rk4(y[:32], u, y[I_LATCHED] > 0.5, tau / n_sub, n_sub, *self._args)
        return out

    def _guard(self, y: np.ndarray) -> float:
        """Contact guard (m): :func:`contact_guard` of the truth (numba form, same sign)."""
        return sat_gap_kernel(y[:N_TRUTH], self._hc, self._hd)

    def propagate_events(self, t: float, state: np.ndarray, u: np.ndarray, dt: float):
        y = np.asarray(state, dtype=float).copy()
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
            if y[I_LATCHED] > 0.5:
                y = self.flow(y, u, step)
                done += step
                continue
            # free flight: contacts (a contact already on, approaching: jump at once)
            if self._guard(y) <= 0.0 and contact_normal_velocity(y[:N_TRUTH], self.params) < 0.0:
                self._contact(y, t_now, events)
            g0 = self._guard(y)
            y_next = self.flow(y, u, step)
            if g0 > 0.0 and self._guard(y_next) <= 0.0:
                tau, y_hit = locate_guard(lambda y0, s: self.flow(y0, u, s), self._guard, y, step, self.tol_s, n_scan=1)
                y = y_hit
                done += tau
                self._contact(y, t + done, events)
            else:
                y = y_next
                done += step
            self._latch_check(y, t + done, events)
        return y, events

    def _contact(self, y: np.ndarray, t_event: float, events: list) -> None:
        """Apply the contact jump in place (if approaching) and record the event."""
        x_plus, gamma, r, n = contact_jump(y[:N_TRUTH], self.params)
        if gamma > 0.0:
            y[:N_TRUTH] = x_plus
            if t_event - y[I_LAST_CONTACT] > self.collision_gap_s:
                y[I_CONTACTS] += 1.0  # a new collision; contacts closer than collision_gap_s belong to it
            y[I_LAST_CONTACT] = t_event
            events.append((t_event, "contact", f"impulse {gamma:.6g} N s, normal [{n[0]:.3f}, {n[1]:.3f}, {n[2]:.3f}], "
                           f"e = {self.params.restitution:g}"))
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


def contact_impulses(events) -> list[dict]:
    """[{t_s, impulse_Ns}] of the ``contact`` events of a run (message format above)."""
    out = []
    for t, kind, msg in events:
        if kind == "contact" and msg.startswith("impulse "):
            out.append({"t_s": float(t), "impulse_Ns": float(msg.split()[1].rstrip(","))})
    return out

