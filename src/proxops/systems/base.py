"""Base class of every system: the defaults of the optional hooks of
:class:`proxops.contracts.System`.

A system overrides ``build`` and ``summarize`` (and ``Scenario``); everything else has a
default here: ``run`` is one closed loop, ``check`` builds it, ``success`` is "the controller did
not stop the run on a failed step" (read from StopReason and Status) and ``campaign_table`` ``""``. Figures are not a system hook: they are
found by convention in ``proxops.plotting.<system>`` (:mod:`proxops.plotting.systems`), so
systems never import plotting.
"""

from __future__ import annotations

from proxops.status import Status, StopReason


class SystemBase:
    """Defaults for :class:`proxops.contracts.System` (see module doc)."""

    Scenario: type

    def build(self, sc):
        raise NotImplementedError(f"{type(self).__name__}.build")

    def summarize(self, sc, result) -> dict:
        return {}

    def run(self, sc, seed: int = 0, progress: bool = False) -> tuple[dict, dict]:
        """One closed loop: ``(summarize(sc, result), {"run": result})``."""
        from proxops.sim.engine import simulate  # here: a planner's check (cortex) needs no engine (nor numba)

        result = simulate(self.build(sc), seed=seed, progress=progress)
        return self.summarize(sc, result), {"run": result}

    def check(self, sc) -> None:
        """The checks of a run before its first step: by default, build it (and discard it) and
        check its number of steps (:func:`proxops.sim.engine.run_steps`)."""
        setup = self.build(sc)
        from proxops.sim.engine import Setup, run_steps

        if isinstance(setup, Setup):
            run_steps(setup)

    def success(self, sc, summary: dict) -> bool:
        """A campaign run succeeds unless the controller stopped it (``stop_reason``
        :attr:`StopReason.CONTROLLER`) on a failed step (``final_status``, the last controller
        :class:`Status`, is ``failed``) or the plant ended it (:attr:`StopReason.PLANT`, e.g. re-entry):
        runs that reach their duration or a stop condition succeed."""
        if summary.get("stop_reason") == StopReason.PLANT:
            return False
        if summary.get("stop_reason") != StopReason.CONTROLLER:
            return True
        return not Status.parse(summary.get("final_status", Status.NONE)).failed

    def campaign_table(self, sc, table) -> str:
        return ""
