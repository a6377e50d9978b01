"""One generic mode-switching controller: named sub-controllers, a mode rule, hysteresis and
dwell time; every switch is an event.

:class:`Supervisor` is itself a :class:`proxops.contracts.Controller`. Each sample it asks
``rule(t, x_est, mode) -> proposed mode`` (``mode`` is None before the first sample), switches
when the proposal differs, the current mode is not absorbing and the current mode has lasted at
least ``dwell_s`` seconds, then returns the active sub-controller's Command with ``mode`` set to
the active mode (unless the sub-controller named its own, e.g. a terminal mode with
``stop``). The engine records every change of ``Command.mode`` as a ``mode`` event
``"old -> new"`` at the sample it happens: that is the switch event (the supervisor also keeps
``switch_log`` = [(t s, old, new)]). Hysteresis belongs to the rule, which sees the current
mode: :class:`Hysteresis` is the two-threshold rule on a scalar signal.

Users: the LOS approach regimes (far / close / hold, :mod:`proxops.control.los_regimes`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable, Mapping, Sequence

import numpy as np

from proxops.errors import input_error
from proxops.contracts import Command, Controller

Rule = Callable[[float, np.ndarray, "str | None"], str]


class Supervisor:
    """Controller switching between named sub-controllers (see module doc).

    controllers: {mode name: Controller}, all with the same ``dt`` (s).
    rule(t, x_est, mode) -> mode name: the proposed mode (``mode`` None before the first sample).
    dwell_s: least time (s) in a mode before the next switch (0: switch at any sample).
    absorbing: modes that are never left once entered (e.g. a latched hold).
    reset_on_entry: reset a sub-controller each time its mode is entered (else once, in reset).
    """

    def __init__(self, controllers: Mapping[str, Controller], rule: Rule, dwell_s: float = 0.0,
                 absorbing: Sequence[str] = (), reset_on_entry: bool = False, dt: float | None = None):
        if not controllers:
            raise input_error("supervisor.controllers", "{}", "needs at least one named sub-controller")
        dts = {float(c.dt) for c in controllers.values()}
        if dt is None and len(dts) != 1:
            raise input_error("supervisor.controllers", sorted(dts), "must share one sample time dt", "s")
        if not (math.isfinite(dwell_s) and dwell_s >= 0.0):
            raise input_error("supervisor.dwell_s", dwell_s, "must be finite and >= 0", "s")
        unknown = set(absorbing) - set(controllers)
        if unknown:
            raise input_error("supervisor.absorbing", sorted(unknown), f"must be among {sorted(controllers)}")
        self.controllers = dict(controllers)
        self.rule = rule
        self.dwell_s = float(dwell_s)
        self.absorbing = frozenset(absorbing)
        self.reset_on_entry = reset_on_entry
        self.dt = float(dt) if dt is not None else dts.pop()
        self.mode: str | None = None
        self.mode_start = 0.0
        self.switch_log: list[tuple[float, str, str]] = []

    def reset(self, t0: float, x0: np.ndarray) -> None:
        self.mode, self.mode_start = None, t0
        self.switch_log = []
        for c in self.controllers.values():
            c.reset(t0, x0)

    def select(self, t: float, x: np.ndarray) -> str:
        """Apply the rule, dwell time and absorbing modes; returns the active mode at ``t``."""
        if self.mode is None:
            self.mode, self.mode_start = self._checked(self.rule(t, x, None)), t
            if self.reset_on_entry:
                self.controllers[self.mode].reset(t, x)
            return self.mode
        if self.mode in self.absorbing or t - self.mode_start < self.dwell_s:
            return self.mode
        proposed = self.rule(t, x, self.mode)
        if proposed != self.mode:
            proposed = self._checked(proposed)
            self.switch_log.append((t, self.mode, proposed))
            self.mode, self.mode_start = proposed, t
            if self.reset_on_entry:
                self.controllers[proposed].reset(t, x)
        return self.mode

    def step(self, t: float, x_est: np.ndarray) -> Command:
        mode = self.select(t, x_est)
        cmd = self.controllers[mode].step(t, x_est)
        if not cmd.mode:
            cmd.mode = mode
        return cmd

    def _checked(self, mode: str) -> str:
        if mode not in self.controllers:
            raise ValueError(f"supervisor rule returned mode {mode!r}, not among {sorted(self.controllers)}")
        return mode


@dataclass
class Hysteresis:
    """Two-threshold mode rule on a scalar ``signal(t, x)``: mode ``high`` is entered when the
    signal exceeds ``upper`` and left (for ``low``) only when it falls below ``lower`` <= upper;
    in between the current mode is kept. The first mode is ``high`` when the signal is above
    ``upper``, else ``low``."""

    signal: Callable[[float, np.ndarray], float]
    lower: float
    upper: float
    low: str = "low"
    high: str = "high"

    def __post_init__(self):
        if not self.lower <= self.upper:
            raise input_error("hysteresis.lower", self.lower, f"must be <= upper = {self.upper}")

    def __call__(self, t: float, x: np.ndarray, mode: str | None) -> str:
        s = self.signal(t, x)
        if mode == self.high:
            return self.low if s < self.lower else self.high
        if mode == self.low:
            return self.high if s > self.upper else self.low
        return self.high if s > self.upper else self.low
