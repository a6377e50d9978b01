"""Verified insertion on the safe circumnavigation orbit after a CORTEX abort (Wijayatunga et al. §3.4).

§3.4 asks for a passively safe orbit; the safe circumnavigation orbit is a CLOSED CW ellipse, so its drift
2 x + y_dot / n must vanish, not only its position error. After the retreat transfer the thrusters coast
``insertion_coast_s`` while the estimates are collected; their CW-mapped mean x_bar predicts the thrust-free
motion. The thrusters stay off only when (1) the predicted drift |6 pi (2 x + y_dot / n)| per orbit is within
``insertion_drift_tol_m`` and (2) the predicted motion stays outside r_KOS + ``passive_margin_m`` for
``passive_orbits`` orbits. Otherwise: (1) fails -> a drift trim (the along-track impulse -(y_dot + 2 n x) e_y
that nulls the drift, in impulses of at most a_max delta_t_g, then the coast check again, so its execution
errors are measured and trimmed in turn); (2) fails -> one CP_g interval (from x_bar) onto the safe orbit's own
CW motion and the coast check again; at most ``insertion_max_intervals`` of both together. Two drift trims in a
row that remove < 10 % of a drift well above its estimate's noise (4 tol) stop the trims (thrusters dead).
Measured before: open-loop insertion with 20 % magnitude errors left 1-7 mm/s, and 1 mm/s drifts ~17 m
along-track per orbit against a 3.75 m margin; a position-only check over one orbit passed states drifting up
to 12 m/orbit (12 of 21 high-error aborts re-entered r_KOS within 5 orbits).
"""

from __future__ import annotations

import math

import numpy as np

from proxops.core.cw import cw_stm
from proxops.guidance.cortex.timeline import Timeline, extend_on_safe_orbit


class SafeOrbitInsertion:
    """State and decisions of the insertion check (``settings``: the supervisor's; ``dv_max`` m/s per impulse)."""

    def __init__(self, n_rad_s: float, settings, r_kos_m: float, dt_s: float, dv_max_mps: float):
        self.n, self.s, self.r_kos_m, self.dt, self.dv_max = n_rad_s, settings, r_kos_m, dt_s, dv_max_mps
        self._drift_stms = None
        self.reset()

    def reset(self) -> None:
        self.verifying = False  # coasting to verify the insertion
        self.trim_queue: list[np.ndarray] = []
        self.verify_samples: list = []
        self.extensions = 0
        self.drift_trims = 0
        self._trim_drift = None  # predicted drift (m/orbit) that the last drift trim acted on
        self._ineffective_trims = 0  # consecutive drift trims that left > 0.9 of the drift (dead thrusters)
        self.predicted_passive_min_m = None
        self.predicted_drift_m = None  # m/orbit, CW prediction from the coast estimates at the stop
        self.verified = None  # the onboard check passed (False: stopped at the cap)
        self.stop_reason = ""

    def predicted_min_range(self, x) -> float:
        """Smallest range of the thrust-free CW motion from x over ``passive_orbits`` orbits (m), sampled
        200 times per orbit (the STMs are built once)."""
        if self._drift_stms is None:
            period = 2.0 * math.pi / self.n
            ts = np.linspace(0.0, self.s.passive_orbits * period, int(200 * self.s.passive_orbits) + 1)
            self._drift_stms = np.array([cw_stm(self.n, float(tt))[:3] for tt in ts])  # (k, 3, 6)
        return float(np.linalg.norm(self._drift_stms @ np.asarray(x, float), axis=1).min())

    def predicted_drift_m_per_orbit(self, x, t: float = 0.0) -> float:
        """Along-track drift per orbit of the thrust-free motion from x at time t (m, signed, Hill y): the CW
        secular term of y(t) is -3 (y_dot0 + 2 n x0) t, so -6 pi (2 x0 + y_dot0 / n) per orbit; plus, on a J2
        (or full) truth, -``j2_drift_gain`` sin(2 u) y: an along-track offset y samples the J2 short-period
        term of the semi-major axis, a_sp = (3 J2 Re^2 / 2 a) sin^2 i cos 2u (circular orbit), at u + y / a,
        so the same osculating CW motion has a mean-a offset of (d a_sp / du) y / a and a drift of -3 pi times
        it per orbit: -(9 pi J2 (Re / a)^2 sin^2 i) sin(2u) y (0.95 m/orbit at y = 37.5 m for the CSO of §5.1).
        Measured on J2 truth (cortex-abort, no errors, centre drift dy of the 3-orbit thrust-free truth, Hill
        +y): ground abort at 150 s, CW 0.13 - 0.95 = -0.82 against -1.02 m/orbit; at 450 s -0.10 - 0.81 = -0.90
        against -0.99 m/orbit (CW alone: 0.13 / -0.10)."""
        x = np.asarray(x, float)
        cw = -6.0 * math.pi * (2.0 * x[0] + x[4] / self.n)
        j2 = -self.s.j2_drift_gain * math.sin(2.0 * (self.s.u0_rad + self.n * t)) * x[1] if self.s.j2_drift_gain else 0.0
        return float(cw + j2)

    def mean_estimate(self, t: float) -> np.ndarray:
        """The coast's estimates mapped to time t by the CW STM and averaged (thrusters off in between):
        the white navigation noise of one sample shrinks by sqrt(samples)."""
        return np.mean([cw_stm(self.n, t - ti) @ xi for ti, xi in self.verify_samples], axis=0)

    def coast_s(self) -> float:
        return self.s.insertion_coast_s if self.s.insertion_coast_s is not None else self.s.dt_g_s

    def start_coast(self, timeline: Timeline, t, x_est, trims) -> Timeline:
        """Start a check: fire ``trims`` (one per step), then coast collecting the estimates (``x_est``: the
        first sample, already after every impulse). Returns the timeline extended along the safe orbit."""
        self.verifying = True
        self.trim_queue = list(trims)
        self.verify_samples = [] if x_est is None else [(t, np.asarray(x_est, float).copy())]
        return extend_on_safe_orbit(timeline, self.n, self.coast_s() + len(trims) * self.dt)

    def decide(self, timeline: Timeline, t, x_est, events):
        """At the end of the retreat time line: ("coast", timeline) start a check; ("trim", timeline, dv) a
        drift trim (its first impulse); ("extend", timeline, x_bar) one more CP_g interval from x_bar;
        ("stop",) thrusters off (``verified``, ``stop_reason`` set)."""
        if not self.verifying:
            return ("coast", self.start_coast(timeline, t, x_est, []))
        self.verify_samples.append((t, np.asarray(x_est, float).copy()))
        x_bar = self.mean_estimate(t)
        self.verifying = False
        rmin = self.predicted_min_range(x_bar)
        drift = self.predicted_drift_m_per_orbit(x_bar, t)
        tol = self.s.insertion_drift_tol_m
        range_ok = rmin >= self.r_kos_m + self.s.passive_margin_m
        drift_ok = tol is None or abs(drift) <= tol
        if self._trim_drift is not None:  # the last check was after a drift trim: did it act?
            big = abs(self._trim_drift) > 4.0 * (tol if tol is not None else 0.0)
            self._ineffective_trims = self._ineffective_trims + 1 if (big and abs(drift) > 0.9 * abs(self._trim_drift)) else 0
            self._trim_drift = None
        dead = self._ineffective_trims >= 2  # two drift trims in a row removed < 10 %: the thrusters do not act
        if not (range_ok and drift_ok) and self.extensions < self.s.insertion_max_intervals and not dead:
            self.extensions += 1
            if not drift_ok:
                dvy = self.n * drift / (6.0 * math.pi)  # m/s along y: the predicted drift -> 0 (CW: -(y_dot + 2 n x))
                k = max(1, int(math.ceil(abs(dvy) / self.dv_max - 1e-12)))
                self.drift_trims += 1
                self._trim_drift = drift
                events.append(("drift_trim", f"predicted drift {drift:+.2f} m/orbit: along-track trim "
                               f"{dvy * 1e3:+.3f} mm/s in {k} impulse(s)"))
                timeline = self.start_coast(timeline, t, None, [np.array([0.0, dvy / k, 0.0]) for _ in range(k)])
                return ("trim", timeline, self.trim_queue.pop(0))
            return ("extend", extend_on_safe_orbit(timeline, self.n, self.s.dt_g_s), x_bar)
        self.predicted_passive_min_m = rmin
        self.predicted_drift_m = drift
        self.verified = bool(range_ok and drift_ok)
        tol_txt = "" if tol is None else f" (tol {tol:g})"
        why = "two drift trims without effect (thrusters?)" if dead else "trim cap reached"
        self.stop_reason = (f"{'verified' if self.verified else f'NOT verified ({why})'}: "
                            f"predicted thrust-free min range {rmin:.2f} m over {self.s.passive_orbits:g} orbit(s) "
                            f"(need {self.r_kos_m + self.s.passive_margin_m:g}), drift {drift:+.2f} m/orbit{tol_txt}")
        events.append(("safe_orbit", f"on the safe circumnavigation orbit after {self.extensions} trim "
                       f"interval(s) ({self.drift_trims} drift trim(s)), {self.stop_reason}; thrusters off"))
        return ("stop",)
