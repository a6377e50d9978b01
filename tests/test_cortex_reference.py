"""CORTEX reference generation (cortex-convex-guidance.md §3.1): hold logic on synthetic
profiles (closed forms), plume/cone rows (finite differences, sampling), the convex phases
against an independent primer-vector lower bound, plan checks recomputed here, bad input."""

import json
import math

import numpy as np
import pytest
from typer.testing import CliRunner

from proxops.constraints.approach_cone import ApproachCone
from proxops.constraints.plume import PlumeConstraint
from proxops.core.cw import cw_stm, mean_motion
from proxops.errors import ProxopsInputError
from proxops.guidance.cortex import holds
from proxops.guidance.cortex.phases import solve_final_approach, solve_flyaround
from proxops.guidance.cortex.config import PAPER_FIXED_AXIS_HILL, CortexConfig, fibonacci_axes
from proxops.guidance.cortex.reference import plan_reference
from proxops.status import Status

N_CSO = mean_motion(6878.1e3)  # §5.1


def square_profile(period=6000.0, sun=4000.0, dt=10.0, orbits=3):
    """Sunlit for [0, sun) of every period, eclipse for [sun, period); samples every dt."""
    t = np.arange(0.0, orbits * period + dt / 2, dt)
    return t, ((t % period) < sun - 1e-9).astype(np.int8)


# ----------------------------------------------------------------------------- holds (eqs. 13-15)
def test_remaining_sunlight_is_time_to_the_first_eclipse_sample():
    t, eta = square_profile()
    # corrected eq. (14): t_k - t with t_k = 4000 s the first eclipse sample (the printed sum
    # would count interval i twice: 4000 - 1234.5 + (1240 - 1230) )
    assert holds.remaining_sunlight(t, eta, 1234.5) == pytest.approx(4000.0 - 1234.5)
    assert holds.remaining_sunlight(t, eta, 0.0) == pytest.approx(4000.0)


def test_hold_in_eclipse_waits_for_sunrise_eq13():
    t, eta = square_profile()
    assert holds.sunrise_wait(t, eta, 4500.0) == pytest.approx(1500.0)
    assert holds.hold_time(t, eta, 4500.0, 600.0) == pytest.approx(1500.0)


def test_hold_in_sunlight_eq15_both_cases():
    t, eta = square_profile()
    assert holds.hold_time(t, eta, 1000.0, 3000.0) == 0.0  # t_rem = 3000 >= tau
    # t_rem = 2000 < tau = 2500: wait t_rem + eclipse (2000 s) = until the sunrise at 6000 s
    assert holds.hold_time(t, eta, 2000.0, 2500.0) == pytest.approx(6000.0 - 2000.0)


def test_hold_skips_windows_shorter_than_the_transfer():
    t, eta = square_profile(sun=1000.0)  # 1000 s sunlit windows
    assert holds.hold_time(t, eta, 0.0, 1500.0) == math.inf  # never fits: a status, not a loop
    t2 = np.arange(0.0, 20000.0, 10.0)
    eta2 = np.zeros(t2.size, np.int8)
    eta2[(t2 >= 1000) & (t2 < 1500)] = 1  # short window
    eta2[(t2 >= 3000) & (t2 < 9000)] = 1  # long window
    h = holds.hold_time(t2, eta2, 1200.0, 2000.0)
    assert h == pytest.approx(3000.0 - 1200.0)
    assert holds.transfer_in_sunlight(t2, eta2, 1200.0 + h, 2000.0)
    assert not holds.transfer_in_sunlight(t2, eta2, 1200.0, 2000.0)


def test_hold_with_random_profiles_always_lands_in_sunlight():
    rng = np.random.default_rng(3)
    for _ in range(30):
        t = np.arange(0.0, 30000.0, 7.0)
        eta = np.ones(t.size, np.int8)
        for start in rng.uniform(0, 28000, 6):
            eta[(t >= start) & (t < start + rng.uniform(100, 2500))] = 0
        t_start, tau = rng.uniform(0, 8000), rng.uniform(60, 3000)
        h = holds.hold_time(t, eta, t_start, tau)
        if math.isfinite(h):
            assert holds.transfer_in_sunlight(t, eta, t_start + h, tau)
            # no earlier start on a sample boundary would do (the hold is the first window that fits)
            for s in t[(t >= t_start) & (t < t_start + h)][::5]:
                assert not holds.transfer_in_sunlight(t, eta, s, tau) or s == t_start


def test_profile_validation():
    with pytest.raises(ProxopsInputError):
        holds.check_profile([0.0, 1.0, 1.0], [1, 1, 0])
    with pytest.raises(ProxopsInputError):
        holds.check_profile([0.0, 1.0], [1, 2])


# ----------------------------------------------------------------------------- constraints
def test_plume_linearisation_matches_finite_differences_and_is_conservative_in_dv():
    pl = PlumeConstraint(math.radians(24.0))
    rng = np.random.default_rng(0)
    for _ in range(20):
        r, dv = rng.normal(size=3) * 10, rng.normal(size=3) * 0.01
        if pl.h(r, dv) > 0:  # inside the forbidden cone: the row is built at the nearest generatrix
            continue
        a, g, b = pl.linearization(r, dv, 1e-9)
        eps = 1e-7
        fd_r = [(pl.h(r + eps * e, dv) - pl.h(r - eps * e, dv)) / (2 * eps) for e in np.eye(3)]
        fd_v = [(pl.h(r, dv + 1e-9 * e) - pl.h(r, dv - 1e-9 * e)) / 2e-9 for e in np.eye(3)]
        np.testing.assert_allclose(a[0], fd_r, rtol=1e-5, atol=1e-9)
        np.testing.assert_allclose(g[0], fd_v, rtol=1e-5, atol=1e-7)
        assert b[0] == pytest.approx(pl.h(r, dv), abs=1e-12)
        # for r fixed, every dv satisfying the row (a.r is constant) satisfies h <= 0
        samples = rng.normal(size=(4000, 3)) * 0.02
        keep = samples @ g[0] <= 0.0
        assert np.all(pl.h(np.broadcast_to(r, samples.shape), samples)[keep] <= 1e-12)


def test_plume_row_inside_forbidden_cone_admits_the_nearest_generatrix():
    pl = PlumeConstraint(math.radians(24.0))
    r = np.array([0.0, 0.0, 10.0])
    dv = np.array([0.001, 0.0, 0.01])  # 5.7 deg from r: plume on the target
    assert pl.h(r, dv) > 0
    _, g, _ = pl.linearization(r, dv, 1e-9)
    w = np.array([math.sin(math.radians(24.0)), 0.0, math.cos(math.radians(24.0))])
    assert g[0] @ w == pytest.approx(0.0, abs=1e-12)
    assert g[0] @ dv > 0  # the violating reference itself is cut away


def test_approach_cone_soc_equals_the_angle_test():
    cone = ApproachCone([1.0, 1.0, 0.0], math.radians(5.0))
    rng = np.random.default_rng(2)
    pts = rng.normal(size=(3000, 3)) * 5 + 10 * cone.axis
    F, g, c, d = cone.soc(3, 0)
    soc_ok = np.linalg.norm(pts @ F.T + g, axis=1) <= pts @ c + d
    ang = np.degrees(np.arccos(pts @ cone.axis / np.linalg.norm(pts, axis=1)))
    assert np.array_equal(soc_ok, ang <= 5.0)
    assert cone.violation(0.0, np.r_[10 * cone.axis, 0, 0, 0]) < 0


# ----------------------------------------------------------------------------- convex phases
def primer_lower_bound(t, x0, xf, n=N_CSO):
    """Independent lower bound on sum ||dv_k|| (impulses at nodes 0..N, the last one at t_N):
    for every lambda, lambda.(x_f - Phi(t_N) x0) <= max_k ||B' Phi(t_N - t_k)' lambda|| sum ||dv_k||."""
    from scipy.optimize import minimize

    tN = t[-1]
    delta = xf - cw_stm(n, tN) @ x0
    P = np.array([cw_stm(n, tN - tk)[:, 3:6].T for tk in t])  # (N+1, 3, 6)

    cons = {"type": "ineq", "fun": lambda lam: 1.0 - np.sum((P @ lam) ** 2, axis=1),
            "jac": lambda lam: -2.0 * np.einsum("kj,kji->ki", P @ lam, P)}
    res = minimize(lambda lam: -(lam @ delta), np.zeros(6), jac=lambda lam: -delta, constraints=[cons],
                   method="SLSQP", options={"maxiter": 1000, "ftol": 1e-14})
    lam = res.x
    return float(lam @ delta / np.max(np.linalg.norm(P @ lam, axis=1)))  # a valid bound for any lambda


def test_cp1_without_active_constraints_meets_the_primer_vector_bound():
    # ~|e_y| axis: the transfer along the V-bar side stays outside the KOS and the impulse
    # bound is slack for tau = 20 min, so the SOCP optimum equals the dual bound.
    x0 = np.array([0.0, -37.5, 0.0, 0, 0, 0])
    xf = np.array([0.0, -18.0, 3.0, 0, 0, 0])
    res = solve_flyaround(N_CSO, 1200.0, 30.0, x0, xf, 1.92e-3, 18.0)
    assert res.ok
    assert np.linalg.norm(res.dv, axis=1).max() < 0.5 * 1.92e-3 * 30  # bounds inactive
    lb = primer_lower_bound(res.t, x0, xf)
    assert res.dv_total_mps == pytest.approx(lb, rel=1e-6)


def test_cp1_planes_keep_every_node_outside_and_cost_above_bound():
    x0 = np.array([0.0, -37.5, 0.0, 0, 0, 0])
    xf = np.array([0.0, 18.0, 0.0, 0, 0, 0])  # far side: the straight line crosses the KOS
    res = solve_flyaround(N_CSO, 600.0, 30.0, x0, xf, 1.92e-3, 18.0)
    assert res.ok and res.iterations > 1
    assert np.linalg.norm(res.x[:, :3], axis=1).min() >= 18.0 - 1e-6
    assert res.dv_total_mps >= primer_lower_bound(res.t, x0, xf) - 1e-9


def test_cp1_infeasible_is_a_status_with_a_reason():
    x0 = np.array([0.0, -37.5, 0.0, 0, 0, 0])
    xf = np.array([0.0, 18.0, 0.0, 0, 0, 0])
    res = solve_flyaround(N_CSO, 60.0, 30.0, x0, xf, 1e-5, 18.0)
    assert res.status == "infeasible" and "infeasible" in res.reason


def test_cp2_satisfies_cone_and_plume_at_every_node():
    e = np.array(PAPER_FIXED_AXIS_HILL)
    cone, pl = ApproachCone(e, math.radians(5.0)), PlumeConstraint(math.radians(24.0))
    res = solve_final_approach(N_CSO, 300.0, 10.0, np.r_[18 * e, 0, 0, 0], np.r_[e, 0, 0, 0], 1.92e-3, cone, pl)
    assert res.ok
    r = res.x[:, :3]
    ang = np.degrees(np.arccos(r @ e / np.linalg.norm(r, axis=1)))
    assert ang.max() <= 5.0 + 1e-6
    thrust = np.linalg.norm(res.dv, axis=1) > 1e-6
    cosang = np.sum(res.dv * r, axis=1) / (np.linalg.norm(res.dv, axis=1) * np.linalg.norm(r, axis=1))
    assert np.degrees(np.arccos(cosang[thrust])).min() >= 24.0 - 0.01
    # the constraints can only cost fuel: above the unconstrained (primer-vector) bound
    assert res.dv_total_mps >= primer_lower_bound(res.t, np.r_[18 * e, 0, 0, 0], np.r_[e, 0, 0, 0]) - 1e-9


# ----------------------------------------------------------------------------- full plan
@pytest.fixture(scope="module")
def cfg():
    return CortexConfig(mean_motion_rad_s=N_CSO)


def test_fixed_axis_plan_is_checked_and_rechecked(cfg):
    plan = plan_reference(PAPER_FIXED_AXIS_HILL, cfg)
    assert plan.ok, plan.reason
    c = plan.checks
    assert c.passed and c.dynamics_residual < 1e-6 and c.impulse_ratio_max <= 1 + 1e-6
    # recompute from the plan's own arrays with the closed-form STM
    x = plan.cp1.x[0].copy()
    for k in range(len(plan.cp1.t) - 1):
        x[3:] += plan.cp1.dv[k]
        x = cw_stm(N_CSO, plan.cp1.t[k + 1] - plan.cp1.t[k]) @ x
    x[3:] += plan.cp1.dv[-1]
    np.testing.assert_allclose(x, np.r_[18.0 * np.array(PAPER_FIXED_AXIS_HILL), 0, 0, 0], atol=1e-6)
    assert np.linalg.norm(plan.cp1.x[:, :3], axis=1).min() >= 18.0 - 1e-5
    assert plan.tof_s == plan.tau1_s + plan.tau2_s
    assert cfg.tau_lb_s <= plan.tau1_s <= cfg.tau_ub_s


def test_outer_search_returns_the_first_converged_duration(cfg):
    e = np.array([0.0, 1.0, 0.0])  # far side of the V-bar start: tau_lb is too short
    plan = plan_reference(e, cfg)
    assert plan.ok and plan.tau1_s > cfg.tau_lb_s
    shorter = solve_flyaround(N_CSO, plan.tau1_s - cfg.dt_cp1_s, cfg.dt_cp1_s, cfg.start_state,
                              np.r_[cfg.rho_bar * e, 0, 0, 0], cfg.a_bar, cfg.rho_bar)
    assert not shorter.ok
    scan = plan_reference(e, CortexConfig(mean_motion_rad_s=N_CSO, search="scan"))
    assert scan.tau1_s == plan.tau1_s  # linear scan (no monotonicity assumption) agrees


def test_fixed_phase_durations_replace_the_search():
    """planner.tau1_s / tau2_s (the §5.1.2 split: fly-around 14.66 min, final approach 5 min) fix the
    durations: the plan has exactly those, ends on x_f1 / x_f2 (closed-form STM re-propagation in the checks)
    and tries no other duration; a CP1 node grid that does not divide tau_1 ends with a shorter interval."""
    fixed = CortexConfig(mean_motion_rad_s=N_CSO, tau1_s=880.0, tau2_s=300.0)
    plan = plan_reference(PAPER_FIXED_AXIS_HILL, fixed)
    assert plan.ok, plan.reason
    assert plan.tau1_s == 880.0 and plan.tau2_s == 300.0
    assert [tau for _, tau, _ in plan.tried] == [880.0, 300.0]
    assert plan.checks.terminal_miss_m < 1e-6
    assert plan.cp1.t[-1] - plan.cp1.t[-2] == pytest.approx(10.0)  # 880 = 29 x 30 + 10


def test_infeasible_plan_is_a_status(cfg):
    weak = CortexConfig(mean_motion_rad_s=N_CSO, a_max_mps2=1e-5, tau_ub_s=400.0)
    plan = plan_reference([0.0, 1.0, 0.0], weak)
    assert plan.status == "infeasible" and "CP1" in plan.reason


def test_holds_from_a_profile_put_both_transfers_in_sunlight(cfg):
    t, eta = square_profile(period=5700.0, sun=3600.0, dt=5.7)
    plan = plan_reference(PAPER_FIXED_AXIS_HILL, cfg, eclipse=(t, eta), t0_s=3500.0)
    assert plan.ok
    assert plan.hold1_s == pytest.approx(5700.0 - 3500.0)  # t_rem = 100 s < tau_1: next sunrise
    assert plan.checks.sunlit
    assert plan.total_time_s == pytest.approx(plan.tof_s + plan.hold1_s + plan.hold2_s)


@pytest.mark.parametrize("change, field", [
    (dict(plume_half_angle_rad=math.radians(90.0)), "alpha_p"),
    (dict(cone_half_angle_rad=0.0), "alpha_c"),
    (dict(r_kos_m=80.0), "r_kos"),
    (dict(tau_lb_s=4000.0), "tau_lb"),
    (dict(tau1_s=-5.0), "tau1"),
    (dict(start_state=(0.0, -10.0, 0.0, 0.0, 0.0, 0.0)), "start position"),
    (dict(approach_end_position_m=(0.0, 0.0, 1.0)), "approach end position"),
])
def test_bad_input_is_one_clear_error(change, field):
    c = CortexConfig(mean_motion_rad_s=N_CSO, **change)
    with pytest.raises(ProxopsInputError, match=field):
        plan_reference(PAPER_FIXED_AXIS_HILL, c)


def test_zero_axis_is_an_error(cfg):
    with pytest.raises(ProxopsInputError, match="axis"):
        plan_reference([0.0, 0.0, 0.0], cfg)


def test_fibonacci_axes_are_unit_and_balanced():
    a = fibonacci_axes(100)
    np.testing.assert_allclose(np.linalg.norm(a, axis=1), 1.0)
    assert np.linalg.norm(a.mean(axis=0)) < 0.02
    np.testing.assert_allclose(a[:, 2], 1 - (2 * np.arange(100) + 1) / 100)


# ----------------------------------------------------------------------------- system, eclipse, CLI
def test_real_eclipse_profile_hold_is_sunlit_by_an_independent_illumination_call():
    from proxops.environment.eclipse import illumination, kepler_positions
    from proxops.environment.ephemeris import sun_position_eci
    from proxops.scenarios.loader import load_scenario
    from proxops.systems.common import target_elements
    from proxops.systems.cortex_setup import config_from_scenario, eclipse_profile, plan_scenario, scenario_axis

    sc = load_scenario("cortex-reference").scenario
    t, eta = eclipse_profile(sc)
    assert 0 < eta.mean() < 1  # the CSO orbit does see eclipses on 2022-05-01
    sunset = t[np.flatnonzero(np.diff(eta.astype(int)) == -1)[0] + 1]
    plan = plan_reference(scenario_axis(sc), config_from_scenario(sc), eclipse=(t, eta), t0_s=float(sunset) + 60.0)
    assert plan.ok and plan.hold1_s > 0
    el = target_elements(sc.orbit)
    for start, tau in ((sunset + 60.0 + plan.hold1_s, plan.tau1_s),
                       (sunset + 60.0 + plan.hold1_s + plan.tau1_s + plan.hold2_s, plan.tau2_s)):
        ts = np.linspace(start, start + tau, 50)
        il = illumination(kepler_positions(el, ts), sun_position_eci(sc.orbit.epoch_utc, ts), model="conical")
        assert il.min() >= 1.0 - 1e-9
    assert plan_scenario(sc).ok


def test_cli_reference_json_and_bad_axis():
    from proxops.cli import app

    runner = CliRunner()
    res = runner.invoke(app, ["cortex", "reference", "--axis", "-1", "-1", "0", "--json"])
    assert res.exit_code == 0, res.output
    out = json.loads(res.stdout)
    assert out["status"] == "ok" and out["check_passed"] is True
    bad = runner.invoke(app, ["cortex", "reference", "--axis", "0", "0", "0"])
    assert bad.exit_code == 2 and "axis" in bad.output and "Traceback" not in bad.output


def test_cli_references_campaign(tmp_path):
    from proxops.analysis.campaign import load_campaign
    from proxops.cli import app

    res = CliRunner().invoke(app, ["cortex", "references", "--n", "4", "--workers", "1", "--out", str(tmp_path / "c"),
                                   "--json", "--no-figures"])
    assert res.exit_code == 0, res.output
    out = json.loads(res.stdout)
    assert out["n_plans"] == 4 and out["n_ok"] == 4
    table = load_campaign(tmp_path / "c").table
    for col in ("disp.axis.fibonacci_index", "metric.tau1_s", "metric.tau2_s", "metric.hold1_s", "metric.hold2_s",
                "metric.dv1_mps", "metric.dv2_mps", "metric.tof_s", "metric.plan_wall_time_s", "status"):
        assert col in table


@pytest.mark.parametrize("override, key", [
    ("geometry.cone_half_angle_deg=95", "cone_half_angle_deg"),
    ("geometry.plume_half_angle_deg=0", "plume_half_angle_deg"),
    ("geometry.r_kos_m=80", "r_kos_m"),
    ("planner.tau_lb_s=4000", "tau_lb_s"),
])
def test_scenario_rejects_bad_values_at_validation(override, key):
    from proxops.cli import app

    res = CliRunner().invoke(app, ["validate", "cortex-reference", "--set", override])
    assert res.exit_code == 2 and key in res.output and "Traceback" not in res.output


def test_cli_start_inside_kos_is_one_line_error():
    from proxops.cli import app

    res = CliRunner().invoke(app, ["cortex", "reference", "--set", "geometry.start_position_m=[0.0, -10.0, 0.0]"])
    assert res.exit_code == 2 and "start position" in res.output and "Traceback" not in res.output


def test_phase_end_time_is_monotone_so_shortest_durations_minimise_J():
    """The outer-search argument (proxops.guidance.cortex.reference): the end of a phase
    f(t, tau) = t + hold(t, tau) + tau never decreases with its start t or its duration tau."""
    rng = np.random.default_rng(7)
    for _ in range(20):
        t = np.arange(0.0, 40000.0, 11.0)
        eta = np.ones(t.size, np.int8)
        for start in rng.uniform(0, 38000, 8):
            eta[(t >= start) & (t < start + rng.uniform(200, 2000))] = 0

        def f(t0, tau):
            return t0 + holds.hold_time(t, eta, t0, tau) + tau

        starts = np.sort(rng.uniform(0, 15000, 25))
        taus = np.sort(rng.uniform(300, 3600, 15))
        for tau in taus[::3]:
            ends = [f(s, tau) for s in starts]
            assert all(a <= b + 1e-9 for a, b in zip(ends, ends[1:]))
        for s in starts[::5]:
            ends = [f(s, tau) for tau in taus]
            assert all(a <= b + 1e-9 for a, b in zip(ends, ends[1:]))


def test_profile_too_short_is_a_status(cfg):
    t, eta = square_profile(period=5700.0, sun=3600.0, dt=5.7, orbits=1)
    plan = plan_reference(PAPER_FIXED_AXIS_HILL, cfg, eclipse=(t, eta), t0_s=3500.0)
    assert plan.status is Status.FAILED and "eclipse profile short" in plan.reason and "extend" in plan.reason


def test_cli_references_applies_overrides():
    from proxops.cli import app

    runner = CliRunner()
    base = json.loads(runner.invoke(app, ["cortex", "references", "--n", "2", "--workers", "1", "--json"]).stdout)
    slow = runner.invoke(app, ["cortex", "references", "--n", "2", "--workers", "1", "--json",
                               "--set", "planner.tau_lb_s=600"])
    assert slow.exit_code == 0, slow.output
    assert json.loads(slow.stdout)["tof_min"]["median"] >= 20.0 > base["tof_min"]["median"]


def test_arc_planes_reduce_the_coast_penetration():
    from proxops.guidance.cortex.phases import arc_min_distance

    e = np.array([0.0, 1.0, 0.0])
    x0, xf = np.array([0.0, -37.5, 0.0, 0, 0, 0]), np.r_[18.0 * e, 0, 0, 0]
    plain = solve_flyaround(N_CSO, 600.0, 30.0, x0, xf, 1.92e-3, 18.0)
    arc = solve_flyaround(N_CSO, 600.0, 30.0, x0, xf, 1.92e-3, 18.0, arc_planes=True)
    assert plain.ok and arc.ok
    pen_plain = 18.0 - arc_min_distance(N_CSO, plain.t, plain.x, plain.dv)[0]
    pen_arc = 18.0 - arc_min_distance(N_CSO, arc.t, arc.x, arc.dv)[0]
    assert pen_plain > 0.01 and pen_arc < 0.5 * pen_plain
    assert arc.dv_total_mps >= plain.dv_total_mps - 1e-9  # more constraints cannot save fuel
