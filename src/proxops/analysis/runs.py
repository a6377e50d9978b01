"""Run one loaded scenario (``execute``) and check it without running (``check_scenario``):
shared by ``proxops run``, ``validate`` and the campaign workers."""

from __future__ import annotations

from proxops.sim.engine import simulate
from proxops.sim.result import SimResult


def execute(loaded, seed: int | None = None, progress: bool = False) -> tuple[dict, dict[str, SimResult]]:
    """Run a loaded scenario; returns the summary and the results by label."""
    sc, system = loaded.scenario, loaded.system
    seed = sc.sim.seed if seed is None else seed
    if hasattr(system, "run"):
        extra, results = system.run(sc, seed=seed, progress=progress)
        main = next(iter(results.values()))
        summary = {"scenario": sc.name, "system": sc.system, **main.summary(), **extra}
    else:
        result = simulate(system.build(sc), seed=seed, progress=progress)
        results = {"run": result}
        summary = {"scenario": sc.name, "system": sc.system, **result.summary(), **system.summarize(sc, result)}
    summary["seed"] = seed
    return summary, results


def check_scenario(loaded) -> None:
    """Every check a run makes before its first step: the schema (done when loading), the
    system's build (geometry, feasibility of the hop ladder, KOZ vs start...) and the
    dispersions table. Raises ProxopsInputError with one line; ``validate`` and ``mc`` call it."""
    from proxops.scenarios.dispersions import parse_dispersions

    check = getattr(loaded.system, "check", None)  # planners without a closed loop check without building
    check(loaded.scenario) if check is not None else loaded.system.build(loaded.scenario)
    parse_dispersions(loaded.scenario, loaded.scenario.dispersions)
