"""Base class of truth plants (the defaults of :class:`proxops.contracts.Plant`) and guard
location for plants with events and jump maps (hybrid contacts, latch, decoupling).

A plant subclasses :class:`PlantBase` and overrides what differs from a translational Hill
plant: ``layout`` (the named blocks of the measured state), ``delta_v`` (when the control is
not a translational acceleration / impulse), ``mode`` (its discrete mode, recorded per step) and,
for a hybrid plant, ``has_events = True`` with ``propagate_events`` returning the events met
inside the step. :func:`locate_guard` finds a guard crossing inside one step by bisection.
"""

from __future__ import annotations

import math
from typing import Callable

import numpy as np

from proxops.core.layout import HILL_CONTROL, HILL_LAYOUT, StateLayout


def translational_delta_v(u: np.ndarray, kind: str, dt: float) -> float:
    """Delta-v (m/s) of one applied command: |dv| for an impulse, |a| dt for a held
    acceleration (m/s^2 held over ``dt`` s)."""
    if len(u) == 3:  # float arithmetic: the same sum order and bits as u @ u (checked), ~4x cheaper
        x, y, z = u.tolist()
        norm_u = math.sqrt(x * x + y * y + z * z)
    else:
        norm_u = math.sqrt(u @ u)  # = np.linalg.norm(u), without its overhead
    return norm_u if kind == "impulse" else norm_u * dt


class PlantBase:
    """Defaults for every plant: Hill layout, translational delta-v, no events, one mode.

    Attributes set by the engine before a run: ``rng`` (the plant's own random stream,
    :class:`numpy.random.Generator`; process noise must draw from it and nothing else).
    """

    layout: StateLayout = HILL_LAYOUT
    control_layout: StateLayout = HILL_CONTROL  # what u is: names, units, frame (result columns)
    has_events: bool = False  # True: the engine calls propagate_events instead of propagate
    rng: np.random.Generator | None = None

    @property
    def position_slice(self) -> tuple[int, int]:
        return self.layout.span("position") or (0, 3)

    @property
    def velocity_slice(self) -> tuple[int, int]:
        return self.layout.span("velocity") or (3, 6)

    def delta_v(self, u: np.ndarray, kind: str, dt: float) -> float:
        """Delta-v (m/s) of the applied command ``u`` of ``kind`` held for ``dt`` s."""
        return translational_delta_v(u, kind, dt)

    def mode(self, state: np.ndarray) -> str:
        """Discrete mode of the full state (e.g. ``"free"``, ``"contact"``); ``""`` for none."""
        return ""

    def coast(self, times: np.ndarray, state, u: np.ndarray, dt: float):
        """Pieces of ``dt`` s starting at ``times`` (s), each exactly ``propagate(t, state, u, dt)``:
        returns ``(states, relative)`` -- the full state before every piece and after the last
        (len(times) + 1 of them) and their relative states (len(times) + 1, n_x). The engine's
        idle-step coast; plants override it with one jitted call giving the same numbers."""
        states = [state]
        for t in times:
            state = self.propagate(float(t), state, u, dt)
            states.append(state)
        return states, np.array([self.relative_state(s) for s in states], dtype=float)

    def propagate_events(self, t: float, state: np.ndarray, u: np.ndarray, dt: float):
        """Advance by ``dt`` s like ``propagate``; returns ``(state, events)`` with events
        ``(t_event s, kind, message)`` located inside the step (jump maps already applied)."""
        return self.propagate(t, state, u, dt), []


def locate_guard(flow: Callable[[np.ndarray, float], np.ndarray], guard: Callable[[np.ndarray], float],
                 x0: np.ndarray, dt: float, tol_s: float = 1e-9, n_scan: int = 8):
    """First time ``tau`` in (0, dt] where ``guard(flow(x0, tau))`` crosses zero from above.

    ``flow(x0, tau)`` is the plant's flow from ``x0`` over ``tau`` s (exact or its integrator);
    ``guard`` is positive in the flow set and ``x0`` is in it or on its boundary (e.g. just
    after a jump, where the guard is 0 and the flow leaves it). The step is scanned at ``n_scan`` points (so a guard
    that dips below zero and back inside one scan interval can be missed: choose ``n_scan``
    for the fastest guard), then the bracketing interval is bisected until it is shorter than
    ``tol_s`` s. Returns ``(tau, x_at_tau)`` with ``x_at_tau`` on the non-positive side of the
    guard (at most ``tol_s`` after the crossing), or ``None`` when the guard stays positive.
    """
    lo, x_lo = 0.0, x0
    for i in range(1, n_scan + 1):
        hi = dt * i / n_scan
        x_hi = flow(x0, hi)
        if guard(x_hi) <= 0.0:
            while hi - lo > tol_s:
                mid = 0.5 * (lo + hi)
                x_mid = flow(x0, mid)
                if guard(x_mid) <= 0.0:
                    hi, x_hi = mid, x_mid
                else:
                    lo, x_lo = mid, x_mid
            return hi, x_hi
        lo, x_lo = hi, x_hi
    return None
