"""The single-run progress bar: real progress or nothing, and it counts the steps simulated."""

from __future__ import annotations

import io

import pytest

from proxops.scenarios.loader import load_scenario
from proxops.sim import engine
from proxops.sim.engine import StepBar, simulate


class FakeClock:
    def __init__(self):
        self.t = 0.0

    def __call__(self) -> float:
        return self.t


def _drive(total, first_step_s, step_s, **kw):
    """Feed StepBar ``total`` steps: the first takes ``first_step_s``, the others ``step_s``."""
    clock, made = FakeClock(), []

    def make_bar(total, n, n_first, elapsed_s, since_first_s):
        made.append(dict(total=total, n=n, n_first=n_first, elapsed_s=elapsed_s, since_first_s=since_first_s,
                         at=clock.t))

        class Bar:
            def update(self, k):
                made[-1]["n"] += k

            def close(self):
                made[-1]["closed"] = True

        return Bar()

    bar = StepBar(total, clock=clock, make_bar=make_bar, **kw)
    for k in range(total):
        clock.t += first_step_s if k == 0 else step_s
        bar.update(1)
    bar.close()
    return bar, made


def test_a_jit_warm_up_then_a_fast_run_shows_no_bar():
    # the demo case of issue 10: 2.2 s first step, then 1080 steps in 0.08 s
    bar, made = _drive(1081, 2.2, 0.08 / 1080)
    assert made == [] and bar.n == 1081


def test_a_short_run_shows_no_bar():
    bar, made = _drive(30, 0.01, 0.02)  # 0.6 s in all
    assert made == []


def test_a_long_run_gets_a_bar_whose_rate_excludes_the_warm_up():
    total, step = 2000, 0.01  # 20 s of real work after a 2 s warm-up
    bar, made = _drive(total, 2.0, step)
    assert len(made) == 1
    m = made[0]
    assert m["n_first"] == 1 and m["since_first_s"] == pytest.approx(0.5, abs=step)
    # the bar appeared after 1 s of run and 0.5 s of measured steps, i.e. at step 1 + 50
    appeared_at_n = 1 + round(0.5 / step)
    assert m["at"] == pytest.approx(2.0 + 0.5, abs=step)
    measured_rate = (appeared_at_n - m["n_first"]) / m["since_first_s"]
    assert measured_rate == pytest.approx(1 / step, rel=0.03)  # 100 steps/s, not 1 step per 2 s
    eta = (total - appeared_at_n) / measured_rate
    assert eta == pytest.approx((total - appeared_at_n) * step, rel=0.03)  # the true time left
    assert m["n"] == total and m["closed"]  # every later step reached the bar, no more


def test_the_tqdm_bar_starts_with_the_measured_rate(monkeypatch):
    buf = io.StringIO()
    monkeypatch.setattr(engine.sys, "stderr", buf)
    bar = engine._tqdm_bar(1000, 51, 1, 2.5, 0.5)  # 50 steps in the 0.5 s after the first step
    d = bar.format_dict
    bar.close()
    assert d["n"] == 51 and d["total"] == 1000
    assert d["rate"] == pytest.approx(100.0, rel=0.05)
    assert d["elapsed"] == pytest.approx(2.5, abs=0.1)  # elapsed counts the whole run
    assert "51/1000" in buf.getvalue()


def test_no_bar_when_stderr_is_not_a_terminal(monkeypatch):
    monkeypatch.setattr(engine.sys, "stderr", io.StringIO())
    assert isinstance(engine._progress_bar(100, True), engine._NoBar)
    assert isinstance(engine._progress_bar(100, False), engine._NoBar)


class CountingBar:
    def __init__(self, total, enabled):
        self.total, self.n = total, 0
        CountingBar.last = self

    def update(self, n):
        self.n += n

    def close(self):
        pass


@pytest.mark.parametrize("name, overrides, outcome", [
    ("station-keeping", ["sim.duration_s=600"], "completed"),
    ("srf-rbar", [], "handover"),  # the srf run ends one sample after the braking impulse
])
def test_the_bar_counts_the_steps_simulated(monkeypatch, name, overrides, outcome):
    monkeypatch.setattr(engine, "_progress_bar", CountingBar)
    loaded = load_scenario(name, overrides)
    setup = loaded.system.build(loaded.scenario)
    result = simulate(setup, seed=0, progress=True)
    bar = CountingBar.last
    steps = len(result.t) - 1  # samples 0..K, K steps between them
    assert result.meta["outcome"] == outcome
    assert bar.n == steps == bar.total
    assert result.t[-1] == pytest.approx(setup.duration_s, abs=1e-9 * setup.duration_s)


def test_campaign_bars_count_runs_including_resumed_ones(monkeypatch, tmp_path):
    import copy

    import test_campaign_toy as toy
    from proxops.analysis import campaign

    bars = []

    class Bar:
        def __init__(self, total, initial, desc, enabled):
            self.total, self.n = total, initial
            bars.append(self)

        def update(self, n):
            self.n += n

        def set_postfix(self, **kw):
            pass

        def close(self):
            pass

    from proxops.exec import backends

    monkeypatch.setattr(campaign, "_bar", Bar)
    monkeypatch.setattr(backends, "_bar", Bar)  # map_runs lives in the execution layer
    data = copy.deepcopy(toy.TOY_SCENARIO)
    campaign.run_campaign(data, n_runs=5, workers=1, seed=3, out=tmp_path / "c", progress=True)
    campaign.run_campaign(data, n_runs=9, workers=1, seed=3, out=tmp_path / "c", resume=True, progress=True)
    assert [(b.total, b.n) for b in bars] == [(5, 5), (9, 9)]  # the resumed bar starts at the 5 runs on disk
    assert campaign.map_runs(abs, [-1, 2, -3], workers=1, progress=True) == [1, 2, 3]
    assert (bars[-1].total, bars[-1].n) == (3, 3)
