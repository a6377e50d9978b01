"""The cortex system's campaign-report figure hook draws the closed-loop Figs. 13/14 and 15 from saved
series (plotting.cortex.mc_figures -> plotting.cortex_loop.campaign_figures), apart from the
``cortex references`` figures (plotting.cortex.references_figures, Figs. 11-12). The two once shared
a name in one module, and the hook called the wrong one (a TypeError in every closed-loop report)."""

from __future__ import annotations

from proxops import api
from proxops.plotting import cortex as cortex_figures


def test_closed_loop_campaign_figures_from_saved_series(tmp_path):
    loaded = api.load_scenario("cortex-nominal", ["sim.duration_s=600"])
    assert loaded.scenario.guidance.closed_loop
    result = api.simulate(loaded.system.build(loaded.scenario), seed=0)
    files = cortex_figures.mc_figures(loaded.scenario, [result, result], tmp_path)
    names = sorted(p.name for p in files)
    level = 13 if loaded.scenario.errors.delta_r_m < 0.5 else 14  # Fig. 13 low error, Fig. 14 high (§5.2)
    assert names[0] == f"fig{level}_tracking.png" and names[1].startswith("fig15"), names
    assert all(p.is_file() and p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" for p in files)
