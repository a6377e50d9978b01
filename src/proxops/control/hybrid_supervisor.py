"""Supervisory logic of Basu et al. §III (Cases 1-4, eq. 17) on the generic
:class:`proxops.control.supervisor.Supervisor`.

Modes: ``"capture"`` (h = 0, capture MPC kappa_0) and ``"post-capture"`` (h = 1, kappa_1).
Eq. 17, ``u = (1 - h) kappa_0(x) + h kappa_1(x)``, is the supervisor applying the active
mode's controller. Transition sets (the paper names them but gives no numbers; ours):

* T_{0->1} (Case 2): the latch sensor reads locked and x is in the capture envelope
  (:class:`proxops.propagation.hybrid_plant.CaptureEnvelope`: |rho|, |rho_dot|, |omega| and
  the attitude error below their thresholds).
* T_{1->0} (Case 4): the latch sensor reads open, or |rho| >= ``release_distance_m``
  (a latch stretched that far no longer holds the pair), with release_distance_m larger
  than the envelope's position threshold: this gap is the hysteresis in rho.

Dwell timer tau (eq. 16): set to T_1 on entry to post-capture; it runs down at rate 1 and
only when it reaches 0 is x tested against |rho| >= release distance of T_{1->0}. A latch
sensor reading open is acted on at once (waiting out tau left the post-capture MPC
pushing +-5 N on a free deputy for up to 8 s after the §VII snap; with navigation noise that
ground the deputy into the chief, 88 contacts and 38 deg/s). (When tau reaches 0, it is reset to T_1, the smallest value eq. 16 allows.) The generic supervisor's minimum dwell is also T_1, so every
mode lasts at least T_1 s and the number of switches in a window of L s is at most
floor(L / T_1) + 1, whatever the state does on the boundary (tests/test_hybrid_system.py).

The sub-controllers see the paper's 32-state: :class:`RelativeStateController` strips the
two sensor entries of the plant's measured state (contact count, latch) and hands the
contact count to a capture MPC that takes it (weights (79) -> (80)).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from proxops.control.supervisor import Supervisor
from proxops.errors import input_error
from proxops.propagation.hybrid_plant import M_CONTACTS, M_LATCHED, CaptureEnvelope
from proxops.contracts import Command

CAPTURE, POST_CAPTURE = "capture", "post-capture"
N_REL = 32


class RelativeStateController:
    """A controller with ``period_s``, ``reset(t0, x_rel)``, ``step(t, x_rel) -> Command`` on the
    paper's 32-state, seen by the engine as a :class:`proxops.contracts.Controller` on the
    plant's measured state (32 + contact count + latch). If the wrapped controller has
    ``set_collision_count(c)``, it receives the contact count before each step."""

    def __init__(self, controller, name: str):
        self.controller = controller
        self.name = name
        self.dt = float(getattr(controller, "period_s", getattr(controller, "dt", None)))
        self._set_c = getattr(controller, "set_collision_count", None)

    def reset(self, t0: float, x0: np.ndarray) -> None:
        self.controller.reset(t0, np.asarray(x0, dtype=float)[:N_REL])

    def step(self, t: float, x_est: np.ndarray) -> Command:
        x = np.asarray(x_est, dtype=float)
        if self._set_c is not None and x.size > M_CONTACTS:
            self._set_c(int(round(x[M_CONTACTS])))
        cmd = self.controller.step(t, x[:N_REL])
        cmd.mode = self.name  # the supervisor's mode names the step (h of eq. 17), whatever the MPC calls itself
        return cmd


@dataclass
class HybridModeRule:
    """Mode rule of Cases 1-4 with the dwell timer tau (module doc). Callable as the generic
    supervisor's ``rule(t, x, mode)``; ``x`` is the plant's measured state (34)."""

    envelope: CaptureEnvelope
    release_distance_m: float = 0.5
    min_dwell_s: float = 10.0  # T_1
    next_check_s: float = field(default=math.inf, init=False)  # t at which tau reaches 0

    def __post_init__(self):
        if not (math.isfinite(self.release_distance_m) and self.release_distance_m > self.envelope.position_m):
            raise input_error("docking.release_distance_m", self.release_distance_m,
                              f"must be finite and > docking.position_m = {self.envelope.position_m:g} (hysteresis)",
                              "m")
        if not (math.isfinite(self.min_dwell_s) and self.min_dwell_s > 0.0):
            raise input_error("docking.min_dwell_s", self.min_dwell_s, "must be a finite number > 0 (T_1)", "s")

    def in_T01(self, x: np.ndarray) -> bool:
        """x in T_{0->1}: latch locked and inside the capture envelope."""
        return bool(x[M_LATCHED] > 0.5 and self.envelope.contains(x))

    def in_T10(self, x: np.ndarray) -> bool:
        """x in T_{1->0}: latch open or |rho| >= release distance."""
        return bool(x[M_LATCHED] < 0.5 or np.linalg.norm(x[0:3]) >= self.release_distance_m)

    def __call__(self, t: float, x: np.ndarray, mode: str | None) -> str:
        x = np.asarray(x, dtype=float)
        if mode is None or mode == CAPTURE:
            if self.in_T01(x):  # Case 2
                self.next_check_s = t + self.min_dwell_s  # tau <- T_1
                return POST_CAPTURE
            return CAPTURE  # Case 1
        if x[M_LATCHED] < 0.5:  # the latch let go (a decoupling jump of the plant): capture at once
            self.next_check_s = t + self.min_dwell_s
            return CAPTURE
        if t + 1e-9 < self.next_check_s:  # tau > 0: flow, no test (eq. 16)
            return POST_CAPTURE
        self.next_check_s = t + self.min_dwell_s  # tau = 0: jump, tau <- T_1
        return CAPTURE if self.in_T10(x) else POST_CAPTURE  # Case 4 / Case 3

    def reset(self) -> None:
        self.next_check_s = math.inf


class HybridSupervisor(Supervisor):
    """The generic supervisor with the §III rule; ``reset`` also resets tau."""

    def __init__(self, capture, post_capture, rule: HybridModeRule):
        controllers = {CAPTURE: RelativeStateController(capture, CAPTURE),
                       POST_CAPTURE: RelativeStateController(post_capture, POST_CAPTURE)}
        super().__init__(controllers, rule, dwell_s=rule.min_dwell_s, reset_on_entry=True)
        self.hybrid_rule = rule

    def reset(self, t0: float, x0: np.ndarray) -> None:
        self.hybrid_rule.reset()
        super().reset(t0, x0)
