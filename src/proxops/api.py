"""The curated public surface of proxops: what the README's Python section uses.

    from proxops import api
    loaded = api.load_scenario("srf-vbar", ["sim.duration_s=600"])
    summary, results = api.run(loaded)              # one closed loop (or a system's own runs)
    result = api.simulate(loaded.system.build(loaded.scenario), seed=1)
    campaign = api.run_campaign("srf-vbar-mc", n_runs=8, workers=2)

Results are :class:`SimResult` / :class:`CampaignResult`; components implement the protocols
(:class:`Plant`, :class:`Controller`, :class:`Navigation`, :class:`Actuator`, :class:`Constraint`,
:class:`Periodic`, :class:`System`; base classes with the defaults :class:`PlantBase`,
:class:`SystemBase`; state layouts :class:`StateLayout`; mode switching :class:`Supervisor`);
outcomes are :class:`Status` / :class:`StopReason`; optimisation problems use the solver
forms (:class:`QuadraticProgram`, :class:`ConicProblem`, :class:`LinearProgram`) with any adapter.
"""

from proxops.analysis.campaign import CampaignResult, load_campaign, run_campaign
from proxops.control.supervisor import Hysteresis, Supervisor
from proxops.core.layout import Block, StateLayout
from proxops.dynamics.plant import PlantBase
from proxops.analysis.runs import execute as run
from proxops.errors import ProxopsError, ProxopsInputError
from proxops.report.campaign import write_report
from proxops.scenarios.loader import load_scenario
from proxops.sim.engine import Setup, simulate
from proxops.sim.protocols import Actuator, Command, Constraint, Controller, Navigation, Periodic, Plant, System
from proxops.sim.result import SimResult
from proxops.solvers import (
    ConicProblem,
    LinearProgram,
    QuadraticProgram,
    SolverResult,
    SolveStatus,
    make_solver,
    solve_qp,
    successive_convexification,
)
from proxops.status import Status, StopReason
from proxops.systems.base import SystemBase

__all__ = [
    "Actuator", "Block", "Constraint", "Hysteresis", "Navigation", "Periodic", "PlantBase", "StateLayout", "Status",
    "StopReason", "Supervisor", "System", "SystemBase",
    "CampaignResult", "Command", "ConicProblem", "Controller", "LinearProgram", "Plant", "ProxopsError",
    "ProxopsInputError", "QuadraticProgram", "Setup", "SimResult", "SolveStatus", "SolverResult",
    "load_campaign", "load_scenario", "make_solver", "run", "run_campaign", "simulate", "solve_qp",
    "successive_convexification", "write_report",
]
