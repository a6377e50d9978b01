"""CORTEX planner speed paths (issue 32): the coast-arc minimum by Newton's method against a closed form
and an independent ODE integration, and the per-process reuse of the phase set-ups (a reused problem
solves exactly as a new set-up, in any order of axes)."""

import math

import numpy as np
import pytest
import scipy.sparse as sp
from scipy.integrate import solve_ivp
from scipy.optimize import minimize_scalar

from proxops.core.cw import mean_motion
from proxops.guidance.cortex import phases
from proxops.guidance.cortex.config import CortexConfig, fibonacci_axes
from proxops.guidance.cortex.phases import arc_min_distance, coast_min_range
from proxops.guidance.cortex.reference import plan_reference
from proxops.solvers import ClarabelSOCP, ConicProblem

N_CSO = mean_motion(6878.1e3)


def test_coast_minimum_of_an_out_of_plane_oscillation_is_the_closed_form():
    # V-bar rest position y0 plus an out-of-plane oscillation z(t) = z0 cos nt + (vz/n) sin nt: the range
    # sqrt(y0^2 + z^2) is smallest, = |y0|, where z crosses zero, at t* = atan2(-z0 n, vz) / n (mod pi/n)
    y0, z0, vz = -20.0, 3.0, -0.01
    x0 = np.array([0.0, y0, z0, 0.0, 0.0, vz])
    t_star = math.atan2(z0 * N_CSO, -vz) / N_CSO
    s, r = coast_min_range(N_CSO, x0, t_star - 20.0, 0.0, t_star + 100.0)
    assert r == pytest.approx(abs(y0), abs=1e-9)
    assert s == pytest.approx(t_star, abs=1e-6)


def _cw_rhs(n):
    def f(_t, y):
        x, yy, z, vx, vy, vz = y
        return [vx, vy, vz, 3 * n * n * x + 2 * n * vy, -2 * n * vx, -n * n * z]
    return f


def test_arc_minimum_matches_an_independent_integration_over_random_coasts():
    # coasts through the keep-out region: the minimum by sampling + Newton vs the CW ODE integrated by
    # scipy (DOP853, rtol 1e-12) and minimised by a bounded scalar search on a fine bracket
    rng = np.random.default_rng(7)
    for _ in range(12):
        r0 = rng.normal(size=3) * 30.0
        v0 = -r0 / 200.0 + rng.normal(size=3) * 0.02  # heading roughly towards the target
        t = np.arange(0.0, 301.0, 30.0)
        x = np.empty((len(t), 6))
        x[0] = np.r_[r0, v0]
        sol = solve_ivp(_cw_rhs(N_CSO), (0.0, t[-1]), x[0], method="DOP853", rtol=1e-12, atol=1e-12, dense_output=True)
        x = sol.sol(t).T
        dv = np.zeros((len(t), 3))
        val, at = arc_min_distance(N_CSO, t, x, dv)
        grid = np.linspace(0.0, t[-1], 30001)
        rr = np.linalg.norm(sol.sol(grid)[:3], axis=0)
        j = int(np.argmin(rr))
        ref = minimize_scalar(lambda s: float(np.linalg.norm(sol.sol(s)[:3])),
                              bounds=(grid[max(j - 1, 0)], grid[min(j + 1, len(grid) - 1)]), method="bounded",
                              options={"xatol": 1e-9})
        assert val == pytest.approx(ref.fun, abs=1e-7)
        assert val <= rr.min() + 1e-9  # never above a dense sample of the true coast
        if ref.x > 1e-3 and ref.x < t[-1] - 1e-3:
            assert at == pytest.approx(float(ref.x), abs=1e-3)


def _same(a, b):
    assert a.status == b.status and a.tau1_s == b.tau1_s and a.tau2_s == b.tau2_s
    assert a.kos_iterations == b.kos_iterations and a.scp_iterations == b.scp_iterations
    for pa, pb in ((a.cp1, b.cp1), (a.cp2, b.cp2)):
        np.testing.assert_array_equal(pa.x, pb.x)
        np.testing.assert_array_equal(pa.dv, pb.dv)


def test_reused_phase_set_ups_solve_exactly_as_new_ones():
    cfg = CortexConfig(mean_motion_rad_s=N_CSO)
    axes = fibonacci_axes(100)[[3, 41, 77]]  # CP1 with and without KOS planes, different cone axes
    phases._SET_UPS.clear()
    fresh = []
    for e in axes:
        phases._SET_UPS.clear()  # every plan on new set-ups
        fresh.append(plan_reference(e, cfg))
    assert any(p.kos_iterations > 1 for p in fresh)  # a plan that added planes: its set-up is reused after
    phases._SET_UPS.clear()
    for e, ref in list(zip(axes, fresh))[::-1] + list(zip(axes, fresh)):  # reused, in both orders
        _same(plan_reference(e, cfg), ref)
    assert 0 < len(phases._SET_UPS) <= phases.SET_UPS_KEPT


def test_set_up_cache_is_bounded():
    cfg = CortexConfig(mean_motion_rad_s=N_CSO)
    phases._SET_UPS.clear()
    x0 = np.array([0.0, -37.5, 0.0, 0.0, 0.0, 0.0])
    for k in range(phases.SET_UPS_KEPT + 5):  # durations on distinct node grids
        phases.solve_flyaround(cfg.mean_motion_rad_s, 300.0 + 30.0 * k, 30.0, x0, np.r_[0.0, 18.0, 0.0, 0, 0, 0],
                               cfg.a_bar, cfg.rho_bar, kos_max_iter=1)
    assert len(phases._SET_UPS) == phases.SET_UPS_KEPT


def test_clarabel_rebuild_equals_a_new_set_up():
    # min x1 + x2 s.t. ||(x1, x2)|| <= 2 + b-shift, x1 + x2 >= -1: a small SOCP; new data by rebuild() give the
    # bit-identical solve of a new set-up (fresh equilibration); the optimum is the closed form -r sqrt(2)
    A = sp.csc_matrix(np.array([[0.0, 0.0], [-1.0, 0.0], [0.0, -1.0], [-1.0, -1.0]]))
    cones = [("soc", 3), ("nonneg", 1)]
    q = np.array([1.0, 1.0])

    def new(b, a_vals):
        s = ClarabelSOCP()
        AA = A.copy()
        AA.data[:] = a_vals
        s.setup(ConicProblem(None, q, AA, b, cones))
        return s.solve()

    b1, b2 = np.array([2.0, 0.0, 0.0, 10.0]), np.array([3.0, 0.0, 0.0, 10.0])
    a2 = A.data * 1.5  # scales the position rows: ||1.5 x|| <= 3
    s = ClarabelSOCP()
    s.setup(ConicProblem(None, q, A, b1, cones))
    assert s.solve().objective == pytest.approx(-2.0 * math.sqrt(2.0), abs=1e-7)
    s.rebuild(b=b2, A_values=a2)
    got, ref = s.solve(), new(b2, a2)
    np.testing.assert_array_equal(got.x, ref.x)
    assert got.objective == pytest.approx(-2.0 * math.sqrt(2.0), abs=1e-7)


def test_fork_server_warm_up_plans_once_and_fills_the_caches():
    # what the pool's fork server does for `cortex references` (exec.worker_warmup): the planner's set-ups
    # and the eclipse profile end up cached, so the forked workers plan their first axis at the warm speed
    from proxops.exec.worker_warmup import warm_up
    from proxops.systems import cortex_setup

    phases._SET_UPS.clear()
    cortex_setup._PROFILES.clear()
    assert warm_up("cortex-reference")
    assert len(cortex_setup._PROFILES) == 1
    assert len(phases._SET_UPS) >= 2  # CP1 and CP2 of the first converged durations
    assert not warm_up("cortex-reference", ["planner.dt_cp1_s=-1"])  # bad input: no warm-up, no error raised


def test_references_out_draws_fig11_from_the_rows_without_series(tmp_path):
    # the rows keep each plan's node positions (metric.trace.*): Fig. 11 without a saved series; the trace
    # matches the plan's own trajectory to the 0.1 mm rounding and splits at the first approach node
    from typer.testing import CliRunner

    from proxops.analysis.campaign import load_campaign
    from proxops.cli import app
    from proxops.plotting.cortex import plan_traces
    from proxops.scenarios.loader import load_scenario
    from proxops.systems.cortex_setup import plan_scenario

    out = tmp_path / "c"
    res = CliRunner().invoke(app, ["cortex", "references", "--n", "3", "--workers", "1", "--out", str(out), "--json"])
    assert res.exit_code == 0, res.output
    assert (out / "fig11_trajectories.png").is_file() and not (out / "series").exists()
    table = load_campaign(out).table
    traces = plan_traces(table)
    assert len(traces) == 3
    for i, tr in enumerate(traces):
        sc = load_scenario("cortex-reference", ["axis.fibonacci_n=3", f"axis.fibonacci_index={i}"]).scenario
        traj = plan_scenario(sc).trajectory()
        np.testing.assert_allclose(tr.x_true, traj["x"][:, :3], rtol=0, atol=0.5e-4 + 1e-12)
        assert [m == "approach" for m in tr.mode] == [p == "approach" for p in traj["phase"]]
