"""Interfaces shared by every plant, controller, navigation, actuator, constraint and system.

The ground floor of proxops (the layer just above ``core``; it imports numpy, the state layout
record of :mod:`proxops.core.layout` and :mod:`proxops.status` only), so every layer implements
these contracts without an upward import. The closed-loop engine
(:mod:`proxops.sim.engine`) only talks to these protocols, so a new paper's system is a new
controller (and maybe a plant) plus scenarios.

Optional capabilities are declared protocols too (``ObservesTruth``, ``ObservesCoast``,
``MeasuresMany``, ``ReceivesCommand``, ``EmitsEvents``, ``ReportsConsistency``, ``LimitsCommand``,
``PassesZero``, ``ViolationsMany``, ``Coasts``): the engine checks each component against them
once, at set-up (``isinstance``), and never looks a hook up by name.

Conventions: SI units; relative states in Hill/RTN ``[x, y, z, vx, vy, vz]``
(x radial out, y along-track, z orbit normal); time in seconds from scenario start.
Every optional hook has a default in a base class: plants subclass
:class:`proxops.dynamics.plant.PlantBase`, navigation models
:class:`proxops.navigation.NavigationBase`, actuators :class:`proxops.actuators.ActuatorBase`,
systems :class:`proxops.systems.base.SystemBase`. Outcomes use :class:`proxops.status.Status`
(controller and solver) and :class:`proxops.status.StopReason` (why a run ended).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Protocol, runtime_checkable

import numpy as np

from proxops.core.layout import StateLayout
from proxops.status import Status


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
    status: Status = Status.OK  # solver/controller outcome; Status.OK for laws that do not optimise
    solve_time_s: float = 0.0
    mode: str = ""  # guidance regime / controller mode, recorded as an event on change
    events: list[tuple[str, str]] = field(default_factory=list)  # (kind, message)
    info: dict = field(default_factory=dict)  # scalars recorded per step (e.g. value function)
    stop: bool = False  # controller declares the run finished (e.g. docked)
    status_detail: str = ""  # the solver's own words for a failed status (message of the "solver" event)
    next_decision_s: float | None = None  # the controller's next decision is due at this time (s); None: next tick
    idle: "Command | None" = None  # what every tick before next_decision_s would return (zero u)


@runtime_checkable
class Controller(Protocol):
    """Every controller: ``reset`` once, then ``step(t, x_est) -> Command`` each sample.

    Optional hooks: ``observe_truth(t, x_true)`` (shown the truth before each step: safety
    monitors), ``observe_coast(t (n,), x_est (n, n_x))`` (the estimates of the ticks the engine
    skipped after a command with ``next_decision_s``, in time order, before the next step: what
    those ``step`` calls would have seen).

    ``dt`` is also the controller's period in the multi-rate schedule. Before ``reset`` the
    engine sets ``rng`` (numpy Generator): the controller's own random stream (e.g. for a
    randomised planner); it must draw from nothing else."""

    dt: float  # sample time, s

    def reset(self, t0: float, x0: np.ndarray) -> None: ...

    def step(self, t: float, x_est: np.ndarray) -> Command: ...


@runtime_checkable
class Plant(Protocol):
    """Truth model. Its full state may hold more than the relative state (e.g. the
    target's inertial state); ``relative_state`` extracts what navigation measures.

    Defaults for everything below ``apply_impulse`` are in
    :class:`proxops.dynamics.plant.PlantBase` (Hill layout, translational delta-v, no events), and
    of the idle-step hook ``coast(times, state, u, dt) -> (states, relative states)``: the numbers
    of ``len(times)`` ``propagate`` calls (the truth plants give them in one jitted call)."""

    n_x: int  # length of the measured state returned by relative_state
    n_u: int  # length of the control vector
    layout: StateLayout  # named blocks (units) of the measured state, stored with the result
    control_layout: StateLayout  # names, units and frame of the control vector u (result columns)
    has_events: bool  # True: the engine calls propagate_events (guards, jump maps) instead of propagate
    rng: np.random.Generator | None  # the plant's own stream (process noise), set by the engine

    def initial_state(self) -> np.ndarray: ...

    def relative_state(self, state: np.ndarray) -> np.ndarray: ...

    def propagate(self, t: float, state: np.ndarray, u: np.ndarray, dt: float) -> np.ndarray:
        """Advance by ``dt`` seconds under the ZOH control ``u`` (acceleration)."""
        ...

    def apply_impulse(self, t: float, state: np.ndarray, dv: np.ndarray) -> np.ndarray:
        """Instantaneous velocity change ``dv`` (m/s) in the control frame."""
        ...

    def propagate_events(self, t: float, state: np.ndarray, u: np.ndarray, dt: float
                         ) -> tuple[np.ndarray, list[tuple[float, str, str]]]:
        """Like ``propagate``, plus the events ``(t s, kind, message)`` located inside the step
        (guard crossings, after which the plant applied its jump map and continued)."""
        ...

    def delta_v(self, u: np.ndarray, kind: str, dt: float) -> float:
        """Delta-v (m/s) of the applied command ``u`` of ``kind`` held for ``dt`` s."""
        ...

    def mode(self, state: np.ndarray) -> str:
        """The plant's discrete mode (recorded per step as ``SimResult.plant_mode``)."""
        ...


@runtime_checkable
class Navigation(Protocol):
    """What the controller sees: ``measure(t, x_true, rng) -> x_est`` (same layout and units
    as the plant's measured state). ``period_s``: measurement period (s), None = the
    controller's; the estimate is held between measurements. Idle-step hook (default in
    :class:`proxops.navigation.NavigationBase`): ``measure_many(t (n,), x_true (n, n_x), rng)``, the
    numbers and draws of ``measure`` on each sample in turn (a filter with ``command``/``events``
    hooks is called sample by sample instead)."""

    period_s: float | None

    def measure(self, t: float, x_true: np.ndarray, rng: np.random.Generator) -> np.ndarray: ...


@runtime_checkable
class Actuator(Protocol):
    """Between command and truth: ``apply(t, u, kind, rng) -> u_applied`` (limits, errors),
    in the command's unit (m/s^2 for ``acceleration``, m/s for ``impulse``, or the plant's own
    control units). ``period_s``: None = applied once per controller sample; a shorter period
    re-applies a held acceleration command (fresh errors) on each of its ticks.
    ``zero_passthrough`` (:class:`proxops.actuators.ActuatorBase`: False): ``apply`` of a zero
    command returns zero and draws nothing, so the engine may coast idle ticks."""

    period_s: float | None

    def apply(self, t: float, u: np.ndarray, kind: str, rng: np.random.Generator) -> np.ndarray: ...


@runtime_checkable
class Periodic(Protocol):
    """A further component on its own period (``Setup.periodic``), run on its ticks after
    navigation and before the controller: e.g. a guidance planner every 30 s that re-plans the
    reference a faster tracking controller (sharing the reference object) follows.
    ``update(t, x_est)`` returns events ``(kind, message)``."""

    period_s: float

    def reset(self, t0: float) -> None: ...

    def update(self, t: float, x_est: np.ndarray) -> list[tuple[str, str]]: ...


@runtime_checkable
class Constraint(Protocol):
    """A path constraint checked by the engine on the true measured state: ``violation(t, x)``
    >= 0 in the constraint's unit (m for keep-out and corridors), 0 when satisfied. Each
    constraint also gives its solver rows to the controllers that enforce it. Optional
    ``violations(t (n,), x (n, n_x)) -> (n,)``: the same vectorised up to rounding (the engine
    screens a coast with it and calls ``violation`` wherever it is above -1e-6)."""

    name: str

    def violation(self, t: float, x: np.ndarray) -> float: ...


@runtime_checkable
class System(Protocol):
    """One paper's system: its scenario model and how a scenario becomes a run.

    Defaults for every hook below ``summarize`` are in :class:`proxops.systems.base.SystemBase`:
    ``run`` = one ``simulate(build(sc))``; ``check`` = build; ``success`` = the run did not end
    in a failed status; ``campaign_table`` = ``""``. Figures are found by convention in
    ``proxops.plotting.<system>`` (``run_figures``, ``mc_figures``; :mod:`proxops.plotting.systems`)."""

    Scenario: type  # pydantic model (subclass of proxops.scenarios.schema.ScenarioBase)

    def build(self, sc) -> object:
        """The :class:`proxops.sim.engine.Setup` of one closed loop."""
        ...

    def summarize(self, sc, result) -> dict:
        """System-specific summary keys of one run (SI units, key suffixes name the unit)."""
        ...

    def run(self, sc, seed: int = 0, progress: bool = False) -> tuple[dict, dict]:
        """``(extra summary, {label: SimResult})``; the first result is the main one."""
        ...

    def check(self, sc) -> None:
        """Every check a run makes before its first step; raises ProxopsInputError (one line)."""
        ...

    def success(self, sc, summary: dict) -> bool:
        """Whether a campaign run counts as a success."""
        ...

    def campaign_table(self, sc, table) -> str: ...


# --- optional capabilities (checked once by the engine at set-up) ------------------------------


@runtime_checkable
class ObservesTruth(Protocol):
    """Controller hook: shown the true measured state ``x_true`` (plant units, e.g. m, m/s) at
    ``t`` (s) before each of its steps (a safety monitor, e.g. the cortex triggers of Table 1);
    a controller with it is never coasted."""

    def observe_truth(self, t: float, x_true: np.ndarray) -> None: ...


@runtime_checkable
class ObservesCoast(Protocol):
    """Controller hook: the estimates ``x_est`` (n, n_x) at the times ``t`` (n,) s of the ticks the
    engine coasted over (in time order, before the next ``step``): what those steps would have seen."""

    def observe_coast(self, t: np.ndarray, x_est: np.ndarray) -> None: ...


@runtime_checkable
class MeasuresMany(Protocol):
    """Navigation hook: estimates (n, n_x) of the samples ``x_true`` (n, n_x) at times ``t`` (n,) s:
    the numbers and random draws of ``measure`` called on each in turn (the idle-step coast)."""

    def measure_many(self, t: np.ndarray, x_true: np.ndarray, rng: np.random.Generator) -> np.ndarray: ...


@runtime_checkable
class ReceivesCommand(Protocol):
    """Navigation (filter) hook: each controller command ``u`` of ``kind`` at ``t`` (s) after the
    actuator's known saturations (m/s^2 or m/s), e.g. for the filter's propagation."""

    def command(self, t: float, u: np.ndarray, kind: str) -> None: ...


@runtime_checkable
class EmitsEvents(Protocol):
    """Navigation (filter) hook: a list of ``(kind, message)`` (e.g. rejected measurements) that the
    engine drains into the run's events after each measurement (stamped with its time, s)."""

    events: list


@runtime_checkable
class ReportsConsistency(Protocol):
    """Navigation (filter) hook: ``(series, meta)`` at the end of a run, series ``{key: (t s, values)}``
    (e.g. ``nav_nees``, ``nav_nis``, dimensionless) stored as ``info`` columns on their ticks."""

    def consistency_record(self) -> tuple[dict, dict]: ...


@runtime_checkable
class LimitsCommand(Protocol):
    """Actuator hook: the deterministic part of ``apply`` (saturations, minimum impulse bit) of a
    command ``u`` (its unit, m/s^2 or m/s): what the vehicle knows it commanded."""

    def limited(self, u: np.ndarray) -> np.ndarray: ...


@runtime_checkable
class PassesZero(Protocol):
    """Actuator flag: ``zero_passthrough`` True when ``apply`` of a zero command returns zero and
    draws nothing, so the engine may coast idle ticks (False: unknown, never coast)."""

    zero_passthrough: bool


@runtime_checkable
class ViolationsMany(Protocol):
    """Constraint hook: ``violation`` vectorised, (n,) in the constraint's unit (m) for states
    (n, n_x) at times ``t`` (n,) s, equal up to rounding (the engine screens a coast with it)."""

    def violations(self, t: np.ndarray, x: np.ndarray) -> np.ndarray: ...


@runtime_checkable
class Coasts(Protocol):
    """Plant hook (default :class:`proxops.dynamics.plant.PlantBase`): ``coast(times (n,) s, state,
    u, dt s) -> (states (n + 1), relative states (n + 1, n_x))``, each piece exactly ``propagate``."""

    def coast(self, times: np.ndarray, state, u: np.ndarray, dt: float): ...
