"""Planar underactuated CubeSat model, NMPC and scenario input checks (issue 7).

Reference values come from closed forms (CW state-transition matrix, constant-torque
attitude motion), from the exact two-body relative acceleration, from the paper's tables
(underactuated-docking-nmpc.md Tables 1-3) or from feasibility checks of the optimiser
output against an independent RK4 re-integration.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from proxops.core.constants import MU_EARTH
from proxops.core.cw import cw_input_matrix_zoh, cw_stm
from proxops.dynamics.planar_cubesat import (
    TABLE2_LIMITS,
    TABLE3_LIMITS,
    DockingSet,
    Interval,
    PlanarCubeSatParams,
    PlanarCubeSatPlant,
    PlanarLimits,
    casadi_step_function,
    planar_rhs,
    rk4_step,
)
from proxops.errors import ProxopsInputError

DEG = math.pi / 180.0
CASE1_S0 = np.array([3.85, -27.2, -11.1 * DEG, 0.254, -2.50, 1.25 * DEG])  # §5


# ----------------------------------------------------------------------------- model
def test_translation_matches_cw_state_transition_matrix():
    """Constant body-axis thrust at fixed attitude = constant Hill acceleration: the plant
    must reproduce Phi(t) x0 + B_zoh(t) a of the closed-form CW solution (Vallado 6-66)."""
    p = PlanarCubeSatParams()
    theta = 0.7
    s0 = np.array([120.0, -80.0, theta, 0.3, -0.5, 0.0])
    u = np.array([0.05, 0.0])  # N, no wheel torque -> theta stays constant
    plant = PlanarCubeSatPlant(p, s0, substeps_per_s=2.0)
    t_end = 600.0
    s = s0.copy()
    for _ in range(int(t_end / 2.0)):
        s = plant.propagate(0.0, s, u, 2.0)
    n = p.mean_motion_rad_s
    x3 = np.array([s0[0], s0[1], 0.0, s0[3], s0[4], 0.0])
    a = np.array([math.cos(theta), math.sin(theta), 0.0]) * u[0] / p.mass_kg
    ref = cw_stm(n, t_end) @ x3 + cw_input_matrix_zoh(n, t_end) @ a
    np.testing.assert_allclose(s[[0, 1]], ref[[0, 1]], atol=1e-6)
    np.testing.assert_allclose(s[[3, 4]], ref[[3, 4]], atol=1e-9)
    assert s[2] == pytest.approx(theta, abs=1e-15)


def test_hcw_signs_match_exact_two_body_relative_acceleration():
    """Eqs. 1-2 signs: the relative acceleration in the rotating Hill frame from exact
    two-body gravity (chief on a circular orbit with eta of Table 1) agrees with the model
    to second order in the separation."""
    p = PlanarCubeSatParams()
    n = p.mean_motion_rad_s
    a_chief = (MU_EARTH / n**2) ** (1.0 / 3.0)
    rho = np.array([15.0, -25.0])
    rho_dot = np.array([0.4, -0.3])
    r_chief = np.array([a_chief, 0.0])
    r_dep = r_chief + rho  # Hill x radial, y along-track at this instant
    grav = -MU_EARTH * r_dep / np.linalg.norm(r_dep) ** 3 + MU_EARTH * r_chief / a_chief**3
    # rotating frame with omega = n about +z: a_rel = a_inertial_rel - 2 w x v - w x (w x r)
    coriolis = -2.0 * n * np.array([-rho_dot[1], rho_dot[0]])
    centrifugal = n**2 * rho
    exact = grav + coriolis + centrifugal
    model = planar_rhs(np.array([rho[0], rho[1], 0.0, rho_dot[0], rho_dot[1], 0.0]), np.zeros(2), p)[3:5]
    np.testing.assert_allclose(model, exact, atol=3.0 * n**2 * np.linalg.norm(rho) ** 2 / a_chief)


def test_attitude_closed_forms_eq4_and_eq5():
    """Constant wheel acceleration: undamped (eq. 4) theta is a parabola; damped (eq. 5)
    omega relaxes exponentially with time constant I_z / c."""
    wheel = 10.0 * DEG
    s0 = np.array([0.0, 0.0, 0.1, 0.0, 0.0, 0.5 * DEG])
    t = 120.0
    p = PlanarCubeSatParams()
    s = rk4_step(s0, np.array([0.0, wheel]), p, t, 240)
    alpha = -p.wheel_inertia_kgm2 * wheel / p.body_inertia_kgm2
    assert s[2] == pytest.approx(0.1 + s0[5] * t + 0.5 * alpha * t * t, rel=1e-12)
    assert s[5] == pytest.approx(s0[5] + alpha * t, rel=1e-12)
    # angular momentum of body + wheel (wheel rate relative to the body = wheel * t)
    assert p.body_inertia_kgm2 * s[5] + p.wheel_inertia_kgm2 * wheel * t == pytest.approx(p.body_inertia_kgm2 * s0[5], rel=1e-12)

    c = 1e-3
    pd = PlanarCubeSatParams(damping_Nms=c)
    s = rk4_step(s0, np.array([0.0, wheel]), pd, t, 240)
    k = c / pd.body_inertia_kgm2
    omega_inf = -pd.wheel_inertia_kgm2 * wheel / c
    omega_ref = omega_inf + (s0[5] - omega_inf) * math.exp(-k * t)
    theta_ref = 0.1 + omega_inf * t + (s0[5] - omega_inf) * (1.0 - math.exp(-k * t)) / k
    assert s[5] == pytest.approx(omega_ref, rel=1e-9)
    assert s[2] == pytest.approx(theta_ref, rel=1e-9)


def test_numpy_and_casadi_evaluate_the_same_model():
    import casadi as ca

    p = PlanarCubeSatParams(damping_Nms=1e-3)
    rng = np.random.default_rng(3)
    F = casadi_step_function(p, 2.0, 2)
    s_sym, u_sym = ca.SX.sym("s", 6), ca.SX.sym("u", 2)
    f_sym = ca.Function("f", [s_sym, u_sym], [planar_rhs(s_sym, u_sym, p)])
    for _ in range(5):
        s = rng.normal(size=6) * np.array([100, 100, 1, 1, 1, 0.02])
        u = rng.normal(size=2) * np.array([1.0, 10.0])
        np.testing.assert_allclose(np.array(f_sym(s, u)).ravel(), planar_rhs(s, u, p), rtol=1e-14, atol=1e-15)
        np.testing.assert_allclose(np.array(F(s, u)).ravel(), rk4_step(s, u, p, 2.0, 2), rtol=1e-14, atol=1e-12)


def test_table_values():
    """Tables 1-3 as implemented (SI)."""
    p = PlanarCubeSatParams()
    assert (p.mass_kg, p.wheel_inertia_kgm2, p.body_inertia_kgm2, p.mean_motion_rad_s) == (12.0, 4.1e-5, 5.6e-2, 1.027e-3)
    assert TABLE2_LIMITS.thrust == Interval(-2.0, 2.0)
    assert TABLE3_LIMITS.thrust == Interval(-0.1, 0.1)
    assert TABLE2_LIMITS.wheel_acc.hi == pytest.approx(1604.0 * DEG)
    assert TABLE3_LIMITS.wheel_acc.hi == pytest.approx(15.0 * DEG)
    assert TABLE3_LIMITS.velocity == Interval(-2.0, 2.0)
    assert TABLE2_LIMITS.rate.hi == pytest.approx(2.0 * DEG) and TABLE2_LIMITS.angular_acc.hi == pytest.approx(DEG)
    dock = DockingSet()
    assert dock.contains([0.09, -0.09, 1.9 * DEG, 0.19, -0.19, 0.9 * DEG])
    for bad in ([0.11, 0, 0, 0, 0, 0], [0, 0, 0, 0, 0.21, 0], [0, 0, 2.1 * DEG, 0, 0, 0], [0, 0, 0, 0, 0, 1.1 * DEG]):
        assert not dock.contains(bad)


# ----------------------------------------------------------------------------- NMPC
def _check_plan(ctrl, s0, variant):
    """Independent feasibility check of the stored optimal plan (re-integrated with RK4)."""
    S, U = ctrl._plan
    lim, p = ctrl.limits, ctrl.params
    np.testing.assert_allclose(S[0], s0, atol=1e-6)
    u_lo, u_hi = lim.control_bounds()
    assert np.all(U >= u_lo - 1e-6) and np.all(U <= u_hi + 1e-6)
    s_lo, s_hi = lim.state_bounds()
    assert np.all(S[1:] >= s_lo - 1e-5) and np.all(S[1:] <= s_hi + 1e-5)
    for k in range(len(U)):
        np.testing.assert_allclose(S[k + 1], rk4_step(S[k], U[k], p, ctrl.dt, 1), atol=1e-4)
        acc = p.angular_acceleration(S[k, 5], U[k, 1])
        assert lim.angular_acc.lo - 1e-7 <= acc <= lim.angular_acc.hi + 1e-7
    if variant == "general":  # terminal box: a fraction of the Table 1 set (0: s_H = 0, eq. 9)
        box = ctrl.config.terminal_box_fraction * np.array([0.1, 0.1, 2.0 * DEG, 0.2, 0.2, 1.0 * DEG])
        assert np.all(np.abs(S[-1]) <= box * (1 + 1e-4) + 1e-6)
    # the reported value is the stage-cost sum of the plan (plus terminal cost)
    q, r = np.array(ctrl.config.q_diag), np.array(ctrl.config.r_diag)
    value = float(np.sum(S[:-1] ** 2 @ q) + np.sum(U**2 @ r))
    if variant == "general":
        value += ctrl.config.terminal_weight * float(S[-1] ** 2 @ q)
    assert ctrl.values[-1] == pytest.approx(value, rel=1e-6, abs=1e-6)


@pytest.mark.parametrize("variant,horizon,box", [("averaged", 20, 0.1), ("general", 80, 0.1), ("general", 80, 0.0)])
def test_single_solve_is_feasible(variant, horizon, box):
    from proxops.control.nmpc_underactuated import NMPCConfig, UnderactuatedNMPC

    p = PlanarCubeSatParams()
    cfg = NMPCConfig(variant=variant, horizon=horizon, terminal_box_fraction=box)
    ctrl = UnderactuatedNMPC(p, TABLE2_LIMITS, cfg)
    ctrl.reset(0.0, CASE1_S0)
    cmd = ctrl.step(0.0, CASE1_S0)
    assert cmd.status == "ok"
    _check_plan(ctrl, CASE1_S0, variant)
    s1 = PlanarCubeSatPlant(p, CASE1_S0).propagate(0.0, CASE1_S0, cmd.u, 2.0)
    cmd = ctrl.step(2.0, s1)  # warm-started solve
    assert cmd.status == "ok" and cmd.info["warm_solver"] == 1.0
    _check_plan(ctrl, s1, variant)


def test_ipopt_warm_solver_takes_shifted_multipliers():
    """solver = "ipopt": the warm solve is warm-started with the shifted multipliers and
    returns a feasible plan (the default fatrop path ignores multipliers)."""
    from proxops.control.nmpc_underactuated import NMPCConfig, UnderactuatedNMPC

    p = PlanarCubeSatParams()
    ctrl = UnderactuatedNMPC(p, TABLE2_LIMITS, NMPCConfig(horizon=20, solver="ipopt"))
    assert ctrl._nlp.warm_uses_multipliers
    cmd = ctrl.step(0.0, CASE1_S0)
    s1 = PlanarCubeSatPlant(p, CASE1_S0).propagate(0.0, CASE1_S0, cmd.u, 2.0)
    cmd = ctrl.step(2.0, s1)
    assert cmd.status == "ok" and cmd.info["warm_solver"] == 1.0
    _check_plan(ctrl, s1, "averaged")


def test_multiplier_shift_moves_every_stage_one_back():
    """Gap and path multipliers of stage k+1 go to stage k; initial-condition and terminal
    rows keep theirs; bound multipliers shift by one stage block (written out per row)."""
    from proxops.control.nmpc_underactuated import NMPCConfig, UnderactuatedNMPC

    ctrl = UnderactuatedNMPC(PlanarCubeSatParams(), TABLE2_LIMITS,
                             NMPCConfig(variant="general", horizon=5, solver="ipopt"))
    nlp = ctrl._nlp
    lam_g = np.arange(len(nlp.lbg), dtype=float) + 1.0
    lam_x = np.arange(nlp.n_w, dtype=float) + 1.0
    g_new, x_new = nlp.shift_multipliers(lam_g, lam_x)
    expected = lam_g.copy()
    for k in range(nlp.horizon - 1):
        for i in range(nlp.gap_rows[k].stop - nlp.gap_rows[k].start):
            expected[nlp.gap_rows[k].start + i] = lam_g[nlp.gap_rows[k + 1].start + i]
        expected[nlp.path_rows[k]] = lam_g[nlp.path_rows[k + 1]]
    np.testing.assert_array_equal(g_new, expected)
    assert g_new[nlp.gap_rows[-1]].tolist() == lam_g[nlp.gap_rows[-1]].tolist()  # last stage kept
    np.testing.assert_array_equal(x_new[: nlp.n_w - nlp.block], lam_x[nlp.block :])
    np.testing.assert_array_equal(x_new[nlp.n_w - nlp.block :], lam_x[nlp.n_w - nlp.block :])


def test_buffered_evaluation_matches_direct_calls():
    """The numpy-buffer evaluation gives what a plain CasADi call gives (closed forms here),
    keeps unset inputs, and solves an NLP to its known minimiser."""
    import casadi as ca

    from proxops.control.nmpc_underactuated import _Buffered

    x, y = ca.SX.sym("x", 3), ca.SX.sym("y")
    f = _Buffered(ca.Function("f", [x, y], [x * y, ca.sumsqr(x)], ["x", "y"], ["xy", "n2"]))
    out = f(np.array([1.0, 2.0, 3.0]), 2.0)
    np.testing.assert_array_equal(out["xy"], [2.0, 4.0, 6.0])
    assert out["n2"][0] == 14.0
    out = f(y=-1.0)  # x keeps its last value
    np.testing.assert_array_equal(out["xy"], [-1.0, -2.0, -3.0])
    # min x0^2 + x1^2 s.t. x0 + x1 = 1  ->  x = [0.5, 0.5], f = 0.5, lam_g = -1
    z = ca.SX.sym("z", 2)
    solver = _Buffered(ca.nlpsol("qp", "ipopt", {"x": z, "f": ca.sumsqr(z), "g": z[0] + z[1]},
                                 {"print_time": False, "ipopt": {"print_level": 0, "sb": "yes"}}))
    out = solver(x0=[3.0, -1.0], lbx=-10.0, ubx=10.0, lbg=1.0, ubg=1.0)
    assert solver.stats()["success"]
    np.testing.assert_allclose(out["x"], [0.5, 0.5], atol=1e-8)
    np.testing.assert_allclose(out["lam_g"], [-1.0], atol=1e-7)
    with pytest.raises(RuntimeError):  # ill-posed bounds: CasADi's input check still applies
        solver(lbx=10.0, ubx=-10.0)


def test_non_finite_measurement_is_a_status_and_solver_time_is_reported():
    """A NaN state gives a failed status (not a hang in the solver), the next valid state is
    solved again; ``solver_time_s`` is part of the step's computation time."""
    from proxops.control.nmpc_underactuated import NMPCConfig, UnderactuatedNMPC

    ctrl = UnderactuatedNMPC(PlanarCubeSatParams(), TABLE2_LIMITS, NMPCConfig(horizon=20))
    cmd = ctrl.step(0.0, CASE1_S0)
    assert cmd.status == "ok" and 0.0 < cmd.info["solver_time_s"] <= cmd.solve_time_s
    bad = CASE1_S0.copy()
    bad[0] = np.nan
    cmd = ctrl.step(2.0, bad)
    assert cmd.status == "invalid_input" and np.all(np.isfinite(cmd.u))
    assert cmd.info["solver_time_s"] == 0.0
    cmd = ctrl.step(4.0, CASE1_S0)
    assert cmd.status == "ok"
    _check_plan(ctrl, CASE1_S0, "averaged")


def test_value_bound_cannot_move_the_minimiser():
    """Eq. 14 with J_H as objective: a bound below the unconstrained optimum is infeasible,
    so the slack formulation returns the same minimiser and the step reports the bound as
    relaxed; the bounded plan is still dynamically feasible."""
    from proxops.control.nmpc_underactuated import NMPCConfig, UnderactuatedNMPC

    p = PlanarCubeSatParams()
    cfg = NMPCConfig(horizon=20, average_window=1)
    free = UnderactuatedNMPC(p, TABLE2_LIMITS, cfg)
    v_free = free.step(0.0, CASE1_S0).info["value_function"]
    bounded = UnderactuatedNMPC(p, TABLE2_LIMITS, cfg)
    bounded.step(0.0, CASE1_S0)
    bounded._values[-1] = 0.5 * v_free  # next step's bound: Vbar = v_free / 2 < min J_H
    s1 = PlanarCubeSatPlant(p, CASE1_S0).propagate(0.0, CASE1_S0, bounded._plan[1][0], 2.0)
    v1_free = free.step(2.0, s1).info["value_function"]
    cmd = bounded.step(2.0, s1)
    assert cmd.info["value_bound"] == pytest.approx(0.5 * v_free)
    assert cmd.info["bound_solve"] == 1.0 and cmd.info["bound_relaxed"] == 1.0
    assert cmd.info["value_function"] == pytest.approx(v1_free, rel=1e-4)
    _check_plan(bounded, s1, "averaged")


def test_averaged_bound_is_enforced_or_reported():
    """After N steps the value is bounded by the mean of the previous N values (eq. 14),
    unless the step reports the bound as relaxed."""
    from proxops.control.nmpc_underactuated import NMPCConfig, UnderactuatedNMPC

    p = PlanarCubeSatParams()
    window = 4
    ctrl = UnderactuatedNMPC(p, TABLE2_LIMITS, NMPCConfig(horizon=20, average_window=window))
    plant = PlanarCubeSatPlant(p, CASE1_S0)
    s = CASE1_S0.copy()
    ctrl.reset(0.0, s)
    values, bounds, relaxed = [], [], []
    for k in range(12):
        cmd = ctrl.step(2.0 * k, s)
        values.append(cmd.info["value_function"])
        bounds.append(cmd.info["value_bound"])
        relaxed.append(cmd.info["bound_relaxed"])
        s = plant.propagate(0.0, s, cmd.u, 2.0)
    for k in range(12):
        if k < window:
            assert math.isnan(bounds[k])
        else:
            start = (k // window) * window
            assert bounds[k] == pytest.approx(np.mean(values[start - window : start]), rel=1e-12)
            if not relaxed[k]:
                assert values[k] <= bounds[k] * (1 + 1e-6)


# ----------------------------------------------------------------------------- input errors
def test_model_input_errors():
    from proxops.control.nmpc_underactuated import NMPCConfig

    with pytest.raises(ProxopsInputError, match="min must be <= max"):
        Interval(2.0, -2.0).check("limits.thrust", "N")
    with pytest.raises(ProxopsInputError, match="limits.thrust"):
        PlanarLimits(Interval(2.0, -2.0), *[getattr(TABLE2_LIMITS, f) for f in
                                            ("wheel_acc", "position", "velocity", "angle", "rate", "angular_acc")])
    with pytest.raises(ProxopsInputError, match="controller.horizon"):
        NMPCConfig(horizon=0)
    with pytest.raises(ProxopsInputError, match="controller.variant"):
        NMPCConfig(variant="terminal")
    with pytest.raises(ProxopsInputError, match="mass_kg"):
        PlanarCubeSatParams(mass_kg=-1.0)
    with pytest.raises(ProxopsInputError, match="theta"):
        TABLE2_LIMITS.check_state([0, 0, 4.0, 0, 0, 0])


def _scenario_data(**changes):
    import tomllib

    from proxops.scenarios.catalog import resolve

    data = tomllib.loads(resolve("underactuated-case1").read_text())
    for dotted, value in changes.items():
        section, key = dotted.split("__")
        data[section][key] = value
    return data


@pytest.mark.parametrize(
    "change,message",
    [
        ({"initial_state__theta_deg": 200.0}, r"initial_state.theta_deg = 200.0 deg: initial angle must lie within \[-180, 180\] deg"),
        ({"controller__horizon": 0}, r"controller.horizon = 0"),
        ({"limits__thrust_N": [2.0, -2.0]}, r"limits.thrust_N = \[2.0, -2.0\] N: must be \[min, max\] with min < max"),
        ({"limits__rate_deg_s": [3.0, 1.0]}, r"limits.rate_deg_s = \[3.0, 1.0\] deg/s: must be \[min, max\] with min < max"),
        ({"initial_state__vy_mps": -12.0}, r"initial_state.vy_mps = -12.0 m/s is outside the limits \[-10.0, 10.0\] m/s"),
    ],
)
def test_scenario_input_errors(change, message):
    from proxops.scenarios.loader import validate_scenario

    with pytest.raises(ProxopsInputError, match=message):
        validate_scenario(_scenario_data(**change))


def test_builtin_scenarios_validate():
    from proxops.scenarios.loader import load_scenario
    from proxops.systems.underactuated import run_configs

    for name in ("underactuated-case1", "underactuated-compare", "underactuated-case2"):
        sc = load_scenario(name).scenario
        assert run_configs(sc)
    assert [r["variant"] for r in run_configs(load_scenario("underactuated-compare").scenario)] == ["averaged", "general"]
    case2 = run_configs(load_scenario("underactuated-case2").scenario)
    assert sorted(r["damping_Nms"] for r in case2) == [0.0, 1e-3]  # §5: c = 1e-3
