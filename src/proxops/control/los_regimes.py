"""Guidance regimes for the approach to a tumbling target (Iskender 2026 §7)
with the eq.-(11) MPC as safety filter; one Controller for the closed-loop engine, built on the
generic :class:`proxops.control.supervisor.Supervisor` (sub-controllers far / close / hold, the
§7 switching rule, hold absorbing; every regime change is a ``mode`` event).

Regimes, by range r = |r_B| against r_sync = 2 a_max / w_t^2 (eq. 14):

1. far approach (r > r_sync): LVLH-frame PD on a spiral reference - the docking-axis
   point p_ref = r_ref y_B seen from LVLH, which spirals in as r_ref shrinks - with the
   reference velocity limited to v_achv = min(a_max t_far / 2, v_max) (t_far: time
   since the regime began).
2. close approach (r <= r_sync): body-frame PD on the same axis point; the command adds
   the body-frame fictitious accelerations (2 W x v_B + W x (W x r_B), W = (w_t - n) z)
   so that the loop co-rotates, then the CW feed-forward of eq. (12).
3. hold (|r - r_h| <= eps_h and |v_B| < v_switch, then latched): body-frame PD on the hold
   point r_h y_B with the same compensation and eq. (12).

The reference range r_ref moves toward r_h at min(v_achv, sqrt(a_max (r_ref - r_h)))
(a braking profile at a_max / 2). The MPC (11) tracks the regime's body-frame
reference (a trajectory over the horizon along the axis in close approach / hold, the
constant velocity-limited state in far approach, as the paper's single x_ref) subject
to the corridor and input box; only u_0 is applied. The PD command is the nominal law:
it is what is applied with ``use_mpc=False``, and the fallback (clipped) when the QP
fails in soft mode. With hard constraints an infeasible QP is reported as status
``"infeasible"`` and, with ``stop_on_infeasible``, ends the run (paper §9.3: a failed
run).

Chaser inputs are body-axes accelerations at the sample instant (the box +-a_max is on
those axes), converted to LVLH components for the plant and held over the step.
Documented defaults (the paper gives no values): r_h = min(10, max(2, a_max / (2 w_t^2))) m
(:func:`auto_hold_range`), eps_h = 1 m,
v_switch = 0.05 m/s, v_max = 1 m/s, PD natural frequency 0.05 rad/s, damping 1.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np
from numba import njit

from proxops.constraints.los_corridor import LosCorridor
from proxops.control.los_mpc import LosMpc, LosMpcConfig, _qp_data
from proxops.control.supervisor import Supervisor
from proxops.dynamics.tumbling_target import BodyFrameModel, cross3, rot_z, sync_range
from proxops.errors import input_error
from proxops.contracts import Command
from proxops.status import Status


_NO_EVENTS = ()  # a step without events (a step with events makes its own list)
_F64 = np.dtype(np.float64)
_MODE_CODE = {"far": 0, "close": 1, "hold": 2}  # the regimes as :func:`_guidance` numbers them
_perf_counter = time.perf_counter


def _six(x) -> list:
    """The first six components of a state as Python floats (cheaper than numpy on 3-vectors)."""
    return (x.tolist() if x.__class__ is np.ndarray and x.ndim == 1 else np.asarray(x, float).reshape(-1).tolist())[:6]


def auto_hold_range(a_max: float, tumble_rate_rad_s: float) -> float:
    """Default hold range (m): min(10, max(2, 0.5 a_max / w_t^2)).

    Holding at r on the docking axis needs the centripetal acceleration w_t^2 r; the
    default keeps that at or below a_max / 2 (never closer than 2 m, never beyond 10 m)."""
    if tumble_rate_rad_s == 0.0:
        return 10.0
    return float(min(10.0, max(2.0, 0.5 * a_max / tumble_rate_rad_s**2)))


def cw_feedforward(n: float, x_hill: np.ndarray) -> np.ndarray:
    """Eq. (12): a_ff = -[3 n^2 x + 2 n yd, -2 n xd, -n^2 z] (m/s^2, LVLH)."""
    x = x_hill
    return -np.array([3 * n * n * x[0] + 2 * n * x[4], -2 * n * x[3], -n * n * x[2]])


@dataclass
class LosGuidanceConfig:
    """Guidance parameters (SI). See module doc for the defaults' provenance."""

    hold_range_m: float | None = None  # None: auto_hold_range(a_max, w_t)
    hold_band_m: float = 1.0
    v_switch_mps: float = 0.05
    v_max_mps: float = 1.0
    pd_natural_frequency_rad_s: float = 0.05
    pd_damping: float = 1.0
    use_mpc: bool = True
    stop_on_infeasible: bool = True
    stop_at_hold: bool = False  # end the run when hold is reached (faster campaigns)

    def check(self) -> None:
        if self.hold_range_m is not None and not (np.isfinite(self.hold_range_m) and self.hold_range_m > 0):
            raise input_error("guidance.hold_range_m", self.hold_range_m, "must be finite and > 0 (or None for auto)", "m")
        for name in ("hold_band_m", "v_switch_mps", "v_max_mps", "pd_natural_frequency_rad_s", "pd_damping"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0):
                raise input_error(f"guidance.{name}", v, "must be finite and > 0")


class _Regime:
    """One §7 regime as a sub-controller of the supervisor; the state it shares with the other
    regimes (reference range, previous input, MPC) lives in the LosGuidanceController."""

    def __init__(self, owner: "LosGuidanceController", name: str):
        self.owner, self.name, self.dt = owner, name, owner.dt

    def reset(self, t0: float, x0: np.ndarray) -> None:
        pass

    def step(self, t: float, x_est: np.ndarray) -> Command:
        return self.owner._regime_step(self.name, t, x_est)


class LosGuidanceController(Supervisor):
    """Controller (proxops.contracts): §7 regimes + eq.-(11) MPC safety filter, on the
    generic :class:`proxops.control.supervisor.Supervisor`: sub-controllers ``far``, ``close``
    and ``hold`` (absorbing: the hold is latched), mode rule :meth:`regime_rule`, no dwell.

    Works on the body-frame relative state [r_B, v_B] (what
    :class:`proxops.dynamics.tumbling_target.TumblingTargetTruth` reports) and returns an
    LVLH acceleration. ``info`` per step: range_m, r_ref_m, mpc_iterations,
    mpc_build_ms, u_body_0..2, slack_m.

    ``attitude_source`` (None: the target attitude is known): a navigation that estimates the target
    attitude (:class:`proxops.navigation.target_attitude.TargetAttitudeNavigation`); before each step
    the model's frame angle becomes theta(t) + ``attitude_source.frame_angle_error()`` (the body frame
    as estimated), so commands are rotated to LVLH and the corridor is predicted from the estimate.
    """

    def __init__(self, model: BodyFrameModel, a_max: float, corridor: LosCorridor | None = None,
                 mpc_config: LosMpcConfig | None = None, guidance: LosGuidanceConfig | None = None):
        if not a_max > 0:
            raise input_error("chaser.a_max_mps2", a_max, "must be > 0", "m/s^2")
        self.model = model
        self._theta0_rad = model.theta0_rad
        self.attitude_source = None  # estimated target attitude (frame_angle_error(), rad): see _regime_step
        self.dt = model.dt
        self.a_max = float(a_max)
        self.corridor = corridor or LosCorridor()
        self.g = guidance or LosGuidanceConfig()
        self.g.check()
        self.mpc = LosMpc(model, self.corridor, a_max, mpc_config) if self.g.use_mpc else None
        self.r_sync = sync_range(a_max, model.tumble_rate_rad_s)
        self.hold_range = (self.g.hold_range_m if self.g.hold_range_m is not None
                           else auto_hold_range(a_max, model.tumble_rate_rad_s))
        self.kp = self.g.pd_natural_frequency_rad_s**2
        self.kd = 2.0 * self.g.pd_damping * self.g.pd_natural_frequency_rad_s
        self.W = np.array([0.0, 0.0, model.w_rel])
        # the MPC's reference x_1..x_N (m, m/s), rewritten every step by _guidance (no MPC: no rows)
        self._ref_buffer = np.zeros((0 if self.mpc is None else self.mpc.N, 6))
        self._gparams = np.array([self.a_max, self.dt, self.g.v_max_mps, self.hold_range, model.w_rel])  # _guidance's
        super().__init__({name: _Regime(self, name) for name in ("far", "close", "hold")}, self.regime_rule,
                         absorbing=("hold",), dt=self.dt)
        self.reset(0.0, np.zeros(6))

    # ------------------------------------------------------------------ protocol
    def reset(self, t0: float, x0: np.ndarray) -> None:
        self.r_ref = max(float(np.linalg.norm(np.asarray(x0, float)[:3])), self.hold_range)
        self.hold_reached = False
        self.u_prev = np.zeros(3)  # body axes
        if self.mpc is not None:
            self.mpc.reset()
        super().reset(t0, x0)  # mode undetermined until the first sample

    def step(self, t: float, x_est: np.ndarray) -> Command:
        """:meth:`Supervisor.step` with the regime's command computed here (each sub-controller only forwards
        to :meth:`_regime_step`, which always names the mode). Once in ``hold`` (absorbing, no dwell time)
        :meth:`Supervisor.select` returns it without asking the rule: that shortcut is taken here."""
        mode = self.mode
        if mode != "hold":
            mode = self.select(t, x_est)
        return self._regime_step(mode, t, x_est)

    def regime_rule(self, t: float, x: np.ndarray, mode: str | None) -> str:
        """§7: hold when |r - r_h| <= eps_h and |v_B| < v_switch (latched: ``hold`` is absorbing),
        else far approach beyond r_sync and close approach inside."""
        p0, p1, p2, v0, v1, v2 = _six(x)
        r = math.sqrt(p0 * p0 + p1 * p1 + p2 * p2)
        if abs(r - self.hold_range) <= self.g.hold_band_m and math.sqrt(v0 * v0 + v1 * v1 + v2 * v2) < self.g.v_switch_mps:
            return "hold"
        return "far" if r > self.r_sync else "close"

    def _regime_step(self, mode: str, t: float, x_est: np.ndarray) -> Command:
        """The command of regime ``mode`` (reference, PD law, MPC safety filter). The reference range and
        the MPC's reference are one jitted call (:func:`_guidance`); with DAQP in hard mode (the staged path,
        :meth:`LosMpc.lean_inputs`) that call also writes the QP data (:func:`_guided_qp_data`), so a step makes
        one kernel call and one solver call (per-step cost: issue 32 item 2)."""
        if self.attitude_source is not None:  # the body frame as estimated: theta^ = theta(t) + psi
            self.model.theta0_rad = self._theta0_rad + self.attitude_source.frame_angle_error()
        x = x_est if x_est.__class__ is np.ndarray and x_est.dtype == _F64 else np.asarray(x_est, float)
        model = self.model
        theta = model.theta0_rad + model.w_rel * t
        code, ref, mpc = _MODE_CODE[mode], self._ref_buffer, self.mpc
        lean = None if mpc is None else mpc.lean_inputs()
        if lean is not None:  # guidance + QP data in one call, then DAQP (LosMpc.solve_staged)
            t_build = _perf_counter()
            r, self.r_ref, finite = _guided_qp_data(code, t - self.mode_start, theta, x, self.r_ref, self._gparams, ref,
                                                    self.u_prev, *lean)
            out = mpc.solve_staged(theta, t_build) if finite else mpc.solve_raw(t, x, ref, self.u_prev)
        else:
            r, self.r_ref, v_ref, v_achv = _guidance(code, t - self.mode_start, x, self.r_ref, self._gparams, ref)
            out = None if mpc is None else mpc.solve_raw(t, x, ref, self.u_prev)
        stop = False
        if mpc is None:
            u_body, status, solve_time = self._nominal_body(mode, t, x, theta, v_ref, v_achv), Status.OK, 0.0
            b0, b1, b2 = u_body.tolist()
            info = {"range_m": r, "r_ref_m": self.r_ref, "u_body_0": b0, "u_body_1": b1, "u_body_2": b2}
        else:
            # MpcSolution's fields without building it (LosMpc.solve_raw)
            status, u_body, _, _, solve_time, build_time, iterations, slack, _ = out
            if not status.ok:
                if mpc.soft:  # (soft mode never takes the staged path: v_ref, v_achv are set)
                    u_body = self._nominal_body(mode, t, x, theta, v_ref, v_achv)
                elif self.g.stop_on_infeasible:  # u_body: the shifted previous plan
                    stop = True
                    mode = "qp_infeasible"
            b0, b1, b2 = u_body.tolist()
            info = {"range_m": r, "r_ref_m": self.r_ref, "mpc_iterations": iterations,
                    "mpc_build_ms": build_time * 1e3, "slack_m": slack, "u_body_0": b0, "u_body_1": b1,
                    "u_body_2": b2}
        self.u_prev = u_body
        events = _NO_EVENTS
        if mode == "hold" and not self.hold_reached:
            self.hold_reached = True
            events = [("hold", f"hold reached at range {r:.2f} m")]
        if self.hold_reached and self.g.stop_at_hold:
            stop, mode = True, "hold_reached"
        c, s = math.cos(theta), math.sin(theta)  # u_L = R_z(theta) u_B (proxops.dynamics.tumbling_target.rotate_z)
        return Command(np.array([c * b0 - s * b1, s * b0 + c * b1, b2]), "acceleration", status, solve_time, mode,
                       events, info, stop)

    def _nominal_body(self, mode: str, t: float, x: np.ndarray, theta: float, v_ref: float, v_achv: float) -> np.ndarray:
        """The §7 PD law of regime ``mode`` (body axes, clipped to the box): what is applied without the MPC
        and the fallback after a failed soft-mode solve."""
        p, v = x[:3], x[3:6]
        p_ref, R_LB = np.array([0.0, self.r_ref, 0.0]), rot_z(theta)
        x_hill = self.model.hill_from_body(t, x)
        if mode == "far":
            v_ref_L = self._spiral_velocity(p_ref, v_ref, v_achv, R_LB)
            u_hill = (self.kp * (R_LB @ p_ref - x_hill[:3]) + self.kd * (v_ref_L - x_hill[3:6])
                      + cw_feedforward(self.model.n, x_hill))
        else:
            a_des = self.kp * (p_ref - p) + self.kd * (np.array([0.0, -v_ref, 0.0]) - v)
            a_body = a_des + 2.0 * cross3(self.W, v) + cross3(self.W, cross3(self.W, p))
            u_hill = R_LB @ a_body + cw_feedforward(self.model.n, x_hill)
        return np.minimum(np.maximum(R_LB.T @ u_hill, -self.a_max), self.a_max)

    # ------------------------------------------------------------------ pieces
    def _spiral_velocity(self, p_ref_B, v_ref, v_achv, R_LB) -> np.ndarray:
        """LVLH velocity of the spiral reference (axis point moving in at v_ref and
        co-rotating), limited in magnitude to v_achv (§7 far approach)."""
        v_ref_L = R_LB @ (np.array([0.0, -v_ref, 0.0]) + cross3(self.W, p_ref_B))
        speed = float(np.sqrt(v_ref_L @ v_ref_L))
        if speed > v_achv:
            v_ref_L *= v_achv / speed
        return v_ref_L


@njit(cache=True)
def _guidance(mode, elapsed, x, r_ref, g, ref):  # pragma: no cover - compiled
    """§7 reference of regime ``mode`` (0 far, 1 close, 2 hold; module doc) ``elapsed`` s after the regime began,
    from the body-frame state ``x`` (m, m/s) and the reference range ``r_ref`` (m); g = [a_max (m/s^2), dt (s),
    v_max (m/s), r_h (m), w_rel (rad/s): the body frame's rate in LVLH].
    Returns (r, r_ref', v_ref, v_achv) (m, m, m/s, m/s) and writes the MPC's reference x_1..x_N into ``ref``
    (N, 6): in far approach the axis point [0, r_ref', 0] with the spiral velocity seen from the body frame,
    v_B = [(1 - k) w r_ref', -k v_ref, 0], k = min(1, v_achv / |[w r_ref', v_ref]|) (the LVLH spiral velocity
    limited to v_achv; a rotation keeps its norm), one state over the horizon; in close approach and hold the
    axis trajectory [0, max(r_ref' - v_ref dt j, r_h), 0, 0, -v_ref (0 once at r_h), 0], j = 1..N.
    min/max written as Python's (the first argument unless the second is smaller/larger)."""
    a_max, dt, v_max, r_h, w_rel = g[0], g[1], g[2], g[3], g[4]
    r = math.sqrt(x[0] * x[0] + x[1] * x[1] + x[2] * x[2])
    v_achv = a_max * (elapsed + dt) / 2.0  # v_achv = min(a_max t_far / 2, v_max), t_far = elapsed + dt
    if v_max < v_achv:
        v_achv = v_max
    if mode == 2:
        r_ref, v_ref = r_h, 0.0
    else:
        gap = r_ref - r_h
        if 0.0 > gap:
            gap = 0.0
        v_ref = math.sqrt(a_max * gap)
        if not v_ref < v_achv:
            v_ref = v_achv
        r_ref = r_ref - v_ref * dt
        if r_h > r_ref:
            r_ref = r_h
    if mode == 0:
        a0, a1 = -w_rel * r_ref, -v_ref
        speed = math.sqrt(a0 * a0 + a1 * a1)
        k = v_achv / speed if speed > v_achv else 1.0
        v0, v1 = k * a0 + w_rel * r_ref, k * a1
        for j in range(ref.shape[0]):
            ref[j, 0], ref[j, 1], ref[j, 2], ref[j, 3], ref[j, 4], ref[j, 5] = 0.0, r_ref, 0.0, v0, v1, 0.0
    else:
        step_m = v_ref * dt
        for j in range(ref.shape[0]):
            rj = r_ref - step_m * (j + 1.0)
            if r_h > rj:
                rj = r_h
            ref[j, 0], ref[j, 1], ref[j, 2], ref[j, 3], ref[j, 5] = 0.0, rj, 0.0, 0.0, 0.0
            ref[j, 4] = -v_ref if rj > r_h else 0.0
    return r, r_ref, v_ref, v_achv


@njit(cache=True)
def _guided_qp_data(mode, elapsed, theta_k, x, r_ref, g, ref, u_prev, plan, consts, mats, basis, work, upper,
                    lower):  # pragma: no cover - compiled
    """:func:`_guidance` then :func:`proxops.control.los_mpc._qp_data` on the plan shifted by one step (the staged
    path of :meth:`LosGuidanceController._regime_step`): returns (r (m), r_ref' (m), True when the QP data are
    finite)."""
    r, r_ref, _, _ = _guidance(mode, elapsed, x, r_ref, g, ref)
    return r, r_ref, _qp_data(theta_k, 1, x, u_prev, ref, plan, consts, mats, basis, work, upper, lower)
