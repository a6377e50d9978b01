"""Run one loaded scenario (``execute``): shared by ``proxops run`` and the campaign workers (the check
without running is :func:`proxops.scenarios.loader.check_scenario`)."""

from __future__ import annotations

from proxops.sim.result import SimResult
from proxops.status import Status


def execute(loaded, seed: int | None = None, progress: bool = False) -> tuple[dict, dict[str, SimResult]]:
    """Run a loaded scenario; returns the summary and the results by label."""
    sc, system = loaded.scenario, loaded.system
    seed = sc.sim.seed if seed is None else seed
    extra, results = system.run(sc, seed=seed, progress=progress)  # default (SystemBase): one simulate(build(sc))
    main = next(iter(results.values()))
    summary = {"scenario": sc.name, "system": sc.system, **main.summary(), **extra}
    summary["seed"] = seed
    # one vocabulary across systems: `success` (the system's own test, as campaigns count it),
    # `outcome` (the system's word for how the run ended: docked, handover, qp_infeasible, ...;
    # the same text as `status`) and `stop_reason` (completed, stop_condition, controller)
    summary["outcome"] = summary.get("outcome", summary.get("status"))
    summary["stop_reason"] = str(main.meta.get("stop_reason", ""))
    # the last controller status (Status.NONE marks samples without a step): SystemBase.success reads it
    summary["final_status"] = str(next((s for s in reversed(main.status) if Status.parse(s) is not Status.NONE),
                                       Status.NONE))
    summary["success"] = bool(system.success(sc, summary))
    return summary, results
