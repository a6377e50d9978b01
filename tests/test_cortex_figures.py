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


def test_fig11_draws_every_plan_in_its_panel_with_the_colour_cycle(tmp_path, monkeypatch):
    # Fig. 11 draws each panel's plans as one line collection: every plan's fly-around nodes (hold 1 + CP1) in
    # panel (a), its approach nodes in panel (b), in plan order with the axes' colour cycle (C0, C1, ... as one
    # line per plan got them), and the panels' limits enclose every node
    from types import SimpleNamespace

    import numpy as np
    from mpl_toolkits.mplot3d.art3d import Line3DCollection

    sc = api.load_scenario("cortex-reference").scenario
    rng = np.random.default_rng(3)
    plans = []
    for k in (4, 7, 5):
        x = rng.uniform(-30.0, 30.0, size=(k + 6, 3))
        plans.append(SimpleNamespace(x_true=x, mode=["hold1"] + ["flyaround"] * (k - 1) + ["approach"] * 6))
    figs = []
    monkeypatch.setattr(cortex_figures, "save", lambda fig, path, tight=True: figs.append(fig) or path)
    cortex_figures.fig11_trajectories(sc, plans, tmp_path / "f.png")
    ax1, ax2 = figs[0].axes
    cycle = cortex_figures.plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for ax, sl in ((ax1, lambda p: p.x_true[: len(p.mode) - 6]), (ax2, lambda p: p.x_true[len(p.mode) - 6 :])):
        cols = [c for c in ax.collections if isinstance(c, Line3DCollection) and len(c._segments3d) == len(plans)]
        assert len(cols) == 1
        for seg, p in zip(cols[0]._segments3d, plans):
            np.testing.assert_array_equal(np.asarray(seg), sl(p))
        from matplotlib.colors import to_rgba_array

        np.testing.assert_array_equal(cols[0].get_colors(), to_rgba_array(cycle[:3]))
        pts = np.concatenate([sl(p) for p in plans])
        for lim, c in zip((ax.get_xlim3d(), ax.get_ylim3d(), ax.get_zlim3d()), pts.T):
            assert lim[0] <= c.min() and c.max() <= lim[1]
    cortex_figures.plt.close(figs[0])


def test_fig12_histograms_hold_the_counts_of_the_successful_plans(tmp_path, monkeypatch):
    # each panel's filled histogram outline rises to numpy's 20-bin counts of the successful plans' values
    import numpy as np
    import pandas as pd
    from matplotlib.path import Path

    rng = np.random.default_rng(5)
    n = 40
    table = pd.DataFrame({"success": [True] * (n - 3) + [False] * 3,
                          "metric.plan_wall_time_s": rng.uniform(0.02, 0.1, n),
                          "metric.tof_s": rng.uniform(600.0, 900.0, n), "metric.dv_total_mps": rng.uniform(0.3, 0.9, n)})
    figs = []
    monkeypatch.setattr(cortex_figures, "save", lambda fig, path, tight=True: figs.append(fig) or path)
    cortex_figures.fig12_histograms(table, tmp_path / "f.png", {"tof_median_min": 12.07, "dv_median_mps": 0.6579,
                                                                "compute_median_s": 30.9})
    ok = table[table["success"]]
    for ax, (col, scale) in zip(figs[0].axes, (("metric.plan_wall_time_s", 1.0), ("metric.tof_s", 1 / 60),
                                               ("metric.dv_total_mps", 1.0))):
        counts, edges = np.histogram(ok[col].to_numpy() * scale, bins=20)
        (poly,) = ax.patches
        outline = Path(poly.get_xy())
        centres = 0.5 * (edges[:-1] + edges[1:])
        for c, k in zip(centres, counts):  # filled up to the count in each bin, empty above it
            assert outline.contains_point((c, k + 0.05)) is False
            assert k == 0 or outline.contains_point((c, k - 0.05))
        assert centres.min() > ax.get_xlim()[0] and centres.max() < ax.get_xlim()[1]
    cortex_figures.plt.close(figs[0])


def test_figs_11_and_12_keep_every_label_inside_the_canvas(tmp_path, monkeypatch):
    # Figs. 11-12 are saved with fixed margins (no tight crop, which draws each figure twice): everything the
    # Agg renderer draws lies inside the figure, for 100 plans
    from types import SimpleNamespace

    import numpy as np
    import pandas as pd

    sc = api.load_scenario("cortex-reference").scenario
    rng = np.random.default_rng(7)
    plans = [SimpleNamespace(x_true=rng.uniform(-40.0, 25.0, size=(12, 3)), mode=["flyaround"] * 6 + ["approach"] * 6)
             for _ in range(100)]
    table = pd.DataFrame({"success": [True] * 100, "metric.plan_wall_time_s": rng.uniform(0.02, 0.12, 100),
                          "metric.tof_s": rng.uniform(600.0, 820.0, 100), "metric.dv_total_mps": rng.uniform(0.3, 1.1, 100)})
    figs = []
    monkeypatch.setattr(cortex_figures, "save", lambda fig, path, tight=True: figs.append((fig, tight)) or path)
    cortex_figures.fig11_trajectories(sc, plans, tmp_path / "a.png")
    cortex_figures.fig12_histograms(table, tmp_path / "b.png", {"tof_median_min": 12.07, "dv_median_mps": 0.6579,
                                                                 "compute_median_s": 30.9})
    for fig, tight in figs:
        assert tight is False
        fig.canvas.draw()
        # what the tight crop would keep: the bounding box of every drawn artist (titles, labels, the tick
        # labels drawn, legends), in inches; inside the canvas means nothing is cut off
        box = fig.get_tightbbox(fig.canvas.get_renderer())
        width, height = fig.get_size_inches()
        assert box.x0 >= -0.01 and box.y0 >= -0.01 and box.x1 <= width + 0.01 and box.y1 <= height + 0.01, box
        # and the margins are not wasteful: the drawn artists span most of the canvas
        assert box.width > 0.85 * width and box.height > 0.8 * height, box
        cortex_figures.plt.close(fig)


def _write_pid(path, fail_in_child_of=None):
    import os

    if fail_in_child_of is not None and os.getpid() != fail_in_child_of:
        raise RuntimeError("child only")
    path.write_text(str(os.getpid()))
    return path


def _always_fails(path):
    raise ValueError("bad figure")


def test_draw_all_draws_the_later_figures_in_a_child_and_redraws_a_failed_one_here(tmp_path):
    # plotting.common.draw_all (Figs. 11 and 12 of `cortex references` at once): paths in job order, the first
    # drawn in this process, the second in a forked child; a job that failed in its child is drawn again here,
    # and an error of this process's own attempt is raised as usual
    import os

    import pytest

    from proxops.plotting.common import Drawing, draw_all

    a, b = tmp_path / "a.txt", tmp_path / "b.txt"
    assert draw_all([Drawing(_write_pid, a), Drawing(_write_pid, b)]) == [a, b]
    assert a.read_text() == str(os.getpid()) and b.read_text() != str(os.getpid())
    c = tmp_path / "c.txt"
    assert draw_all([Drawing(_write_pid, a), Drawing(_write_pid, c, fail_in_child_of=os.getpid())]) == [a, c]
    assert c.read_text() == str(os.getpid())  # the child failed: redrawn here
    with pytest.raises(ValueError, match="bad figure"):
        draw_all([Drawing(_write_pid, a), Drawing(_always_fails, tmp_path / "d.txt")])


_KILLED_PARENT = """
import os, sys, time
sys.path[:0] = [{src!r}]
from pathlib import Path
from proxops.plotting.common import Drawing, draw_all

def held(path):  # this process's figure: held until the test has killed it (60 s at most: no orphan if it fails)
    Path(path).write_text(str(os.getpid()))
    end = time.monotonic() + 60.0
    while time.monotonic() < end:
        time.sleep(0.01)

if __name__ == "__main__":
    draw_all([Drawing(held, Path({tmp!r}) / "parent"), Drawing(held, Path({tmp!r}) / "child")])
"""


def test_draw_all_child_ends_with_its_parent(tmp_path):
    # a process killed while its figures are drawn (a campaign or demo worker stopped by a Ctrl-C) leaves no child
    # drawing on: the child is armed with PR_SET_PDEATHSIG (proxops.exec.forkserver_exit.die_with_parent)
    import os
    import signal
    import subprocess
    import sys
    import time
    from pathlib import Path

    import proxops

    script = tmp_path / "parent.py"
    script.write_text(_KILLED_PARENT.format(src=str(Path(proxops.__file__).parents[1]), tmp=str(tmp_path)))
    proc = subprocess.Popen([sys.executable, str(script)])
    child_file = tmp_path / "child"
    t0 = time.monotonic()
    while not (child_file.is_file() and child_file.read_text()):  # wait on state: the child is drawing
        assert proc.poll() is None and time.monotonic() - t0 < 120, "the child never started"
        time.sleep(0.01)
    child = int(child_file.read_text())
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    t0 = time.monotonic()
    while Path(f"/proc/{child}").exists() and "Z" not in Path(f"/proc/{child}/stat").read_text().rsplit(")", 1)[1][:3]:
        assert time.monotonic() - t0 < 10, f"child {child} still drawing after its parent was killed"
        time.sleep(0.01)
