"""Interfaces shared by every plant, controller, navigation and actuator model.

The closed-loop engine (:mod:`proxops.sim.engine`) only talks to these protocols, so
a new paper's system is a new controller (and maybe a plant) plus scenarios.

Conventions: SI units; relative states in Hill/RTN ``[x, y, z, vx, vy, vz]``
(x radial out, y along-track, z orbit normal); time in seconds from scenario start.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Protocol, runtime_checkable

import numpy as np


@dataclass
class Command:
    """What a controller asks for at one sample.

    ``u`` is either a zero-order-hold acceleration held over the step (m/s^2,
    ``kind="acceleration"``) or an impulsive velocity change applied at the start of
    the step (m/s, ``kind="impulse"``), expressed in the plant's control frame
    (Hill for translational plants).
    """

    u: np.ndarray
    kind: str = "acceleration"  # "acceleration" | "impulse"
    status: str = "ok"  # solver status as a string, "ok" for non-optimising laws
    solve_time_s: float = 0.0
    mode: str = ""  # guidance regime / controller mode, recorded as an event on change
    events: list[tuple[str, str]] = field(default_factory=list)  # (kind, message)
    info: dict = field(default_factory=dict)  # scalars recorded per step (e.g. value function)
    stop: bool = False  # controller declares the run finished (e.g. docked)


@runtime_checkable
class Controller(Protocol):
    """Every controller: ``reset`` once, then ``step(t, x_est) -> Command`` each sample."""

    dt: float  # sample time, s

    def reset(self, t0: float, x0: np.ndarray) -> None: ...

    def step(self, t: float, x_est: np.ndarray) -> Command: ...


@runtime_checkable
class Plant(Protocol):
    """Truth model. Its full state may hold more than the relative state (e.g. the
    target's inertial state); ``relative_state`` extracts what navigation measures."""

    n_x: int  # length of the measured state returned by relative_state
    n_u: int  # length of the control vector

    def initial_state(self) -> np.ndarray: ...

    def relative_state(self, state: np.ndarray) -> np.ndarray: ...

    def propagate(self, t: float, state: np.ndarray, u: np.ndarray, dt: float) -> np.ndarray:
        """Advance by ``dt`` seconds under the ZOH control ``u`` (acceleration)."""
        ...

    def apply_impulse(self, t: float, state: np.ndarray, dv: np.ndarray) -> np.ndarray:
        """Instantaneous velocity change ``dv`` (m/s) in the control frame."""
        ...

    # Optional: ``delta_v(u, kind, dt) -> float`` (m/s) when the control is not a
    # translational acceleration or impulse (the engine's default is |u| or |u| dt);
    # ``position_slice`` / ``velocity_slice`` when the state is not [r(3), v(3)].
