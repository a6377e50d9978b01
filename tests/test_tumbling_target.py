"""Tumbling target (tumbling-target-reachability.md eqs. 2, 7-8) and the body-frame
prediction model with its exact Jacobians (§4.4).

Independent references: numerical integration of eq. (2), numerical differentiation of
r_B(t) (transport theorem), the paper's §8.1 apparent velocity, the ECI -> Hill
conversion of proxops.frames.hill, two-body truth, and forward finite differences."""

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from proxops.core.constants import MU_EARTH
from proxops.core.quaternion import quat_kinematics, quat_to_dcm
from proxops.dynamics.tumbling_target import (
    BodyFrameModel,
    NonlinearBodyStep,
    TumblingTarget,
    TumblingTargetTruth,
    body_from_hill_matrix,
    hill_from_body_matrix,
)
from proxops.frames.elements import OrbitalElements, elements_to_eci
from proxops.frames.hill import eci_to_hill

SMA = 6378137.0 + 500e3  # Table 1: 500 km circular
N_MEAN = np.sqrt(MU_EARTH / SMA**3)
W_T = np.radians(3.0)


def test_table_1_mean_motion_is_not_500_km():
    """Paper discrepancy: Table 1 lists n = 1.131e-3 rad/s for 500 km, but sqrt(mu/a^3) at
    500 km is 1.1068e-3 rad/s; 1.131e-3 rad/s is a ~401 km orbit. We use 500 km."""
    assert N_MEAN == pytest.approx(1.1068e-3, rel=1e-4)
    a_paper = (MU_EARTH / 1.131e-3**2) ** (1 / 3)
    assert (a_paper - 6378137.0) / 1e3 == pytest.approx(401.5, abs=1.0)


def test_quaternion_solves_eq_2():
    q0 = np.array([0.1, -0.3, 0.2, 0.9])
    q0 /= np.linalg.norm(q0)
    tgt = TumblingTarget(W_T, q0)
    sol = solve_ivp(lambda t, q: quat_kinematics(q, tgt.omega_body), (0, 200), q0, rtol=1e-12, atol=1e-12,
                    dense_output=True)
    for t in (0.0, 13.0, 77.7, 200.0):
        np.testing.assert_allclose(tgt.quaternion(t), sol.sol(t), atol=1e-9)


def _circular_target(t):
    """Target ECI state on an equatorial circular orbit at time t (analytic)."""
    u = N_MEAN * t
    v = SMA * N_MEAN
    return np.array([SMA * np.cos(u), SMA * np.sin(u), 0.0, -v * np.sin(u), v * np.cos(u), 0.0])


def test_body_velocity_is_time_derivative_of_body_position():
    """Eq. (8) from eq. (7) by differentiation (transport theorem), checked numerically."""
    tgt = TumblingTarget(W_T, np.array([0.0, 0.0, 0.3, 0.95]) / np.linalg.norm([0.0, 0.0, 0.3, 0.95]))
    dr0, dv = np.array([30.0, 120.0, -5.0]), np.array([0.1, -0.2, 0.05])  # inertial straight line

    def r_body(t):
        return tgt.body_state_from_offset(t, np.concatenate([dr0 + dv * t, dv]))

    t, h = 11.0, 1e-4
    numeric = (r_body(t + h)[:3] - r_body(t - h)[:3]) / (2 * h)
    np.testing.assert_allclose(r_body(t)[3:], numeric, atol=1e-7)


def test_inertially_stationary_chaser_has_paper_apparent_velocity():
    """§8.1: v_rot = [w y_B, -w x_B, 0] for an inertially stationary chaser."""
    tgt = TumblingTarget(W_T)
    x = tgt.body_state_from_offset(5.0, np.array([20.0, 80.0, 3.0, 0.0, 0.0, 0.0]))
    xb, yb = x[0], x[1]
    np.testing.assert_allclose(x[3:], [W_T * yb, -W_T * xb, 0.0], atol=1e-12)


def test_body_hill_transform_matches_eqs_7_8_on_a_circular_orbit():
    """x_B = T(theta) x_L with theta = theta0 + (w_t - n) t agrees with eqs. (7)-(8) applied
    to ECI states (Hill from proxops.frames.hill, independent code)."""
    theta0 = 0.4
    tgt = TumblingTarget.aligned_with_hill(W_T, _circular_target(0.0), theta0)
    model = BodyFrameModel(N_MEAN, W_T, 1.0, theta0)
    offset0 = np.array([12.0, -40.0, 7.0, 0.03, 0.01, -0.02])
    for t in (0.0, 50.0, 321.0):
        target = _circular_target(t)
        offset = offset0 + np.concatenate([offset0[3:] * t, np.zeros(3)])
        x_body = tgt.body_state_from_offset(t, offset)
        x_hill = eci_to_hill(target, target + offset)
        np.testing.assert_allclose(model.body_from_hill(t, x_hill), x_body, atol=1e-9)
        np.testing.assert_allclose(model.hill_from_body(t, x_body), x_hill, atol=1e-9)
        T = body_from_hill_matrix(model.theta(t), model.w_rel)
        np.testing.assert_allclose(T @ hill_from_body_matrix(model.theta(t), model.w_rel), np.eye(6), atol=1e-14)


def test_exact_jacobians_match_forward_differences():
    """§4.4 uses forward differences (eps = 1e-6) of the nonlinear pipeline; the CasADi
    Jacobian of the same map and the analytic body-frame CW Jacobian must agree with them."""
    nl = NonlinearBodyStep(SMA, W_T, 1.0, theta0_rad=0.3)
    model = BodyFrameModel(nl.n, W_T, 1.0, theta0_rad=0.3)
    x = np.array([8.0, 140.0, -4.0, 0.2, -0.1, 0.03])
    u = np.array([0.01, -0.02, 0.005])
    for t in (0.0, 17.0, 250.0):
        A_fd, B_fd = nl.finite_difference_jacobian(t, x, u, eps=1e-6)
        A_ad, B_ad = nl.jacobian(t, x, u)
        np.testing.assert_allclose(A_ad, A_fd, atol=1e-6)
        np.testing.assert_allclose(B_ad, B_fd, atol=1e-6)
        A_cw, B_cw = model.step_matrices(t)
        # CW is the first-order expansion of the nonlinear map about the target: the
        # difference scales with range / orbit radius (~2e-5) times n^2 dt^2 (~1e-6).
        np.testing.assert_allclose(A_cw, A_ad, atol=1e-8)
        np.testing.assert_allclose(B_cw @ np.diag([1, 1, 1]), B_ad @ np.diag([1, 1, 1]), atol=1e-8)


def test_body_frame_cw_step_tracks_two_body_truth():
    """One 1 s step of the body-frame CW model vs two-body truth: error << corridor tolerance."""
    from proxops.propagation.truth import RelativeTruth

    el = OrbitalElements(SMA, 0.0, np.radians(51.6), 0.0, 0.0, 0.0)
    tgt = TumblingTarget.aligned_with_hill(W_T, elements_to_eci(el))
    plant = TumblingTargetTruth(RelativeTruth(el, np.zeros(6), j2=False), tgt, np.array([5.0, 120.0, -2.0, 0.1, 0.0, 0.0]))
    model = BodyFrameModel(N_MEAN, W_T, 1.0)
    s = plant.initial_state()
    np.testing.assert_allclose(plant.relative_state(s), [5.0, 120.0, -2.0, 0.1, 0.0, 0.0], atol=1e-9)
    u = np.array([0.02, -0.01, 0.005])
    worst = 0.0
    for k in range(30):
        x = plant.relative_state(s)
        pred = model.step(float(k), x, u)
        s = plant.propagate(float(k), s, u, 1.0)
        worst = max(worst, float(np.max(np.abs(plant.relative_state(s)[:3] - pred[:3]))))
    assert worst < 1e-4  # metres per step, vs the 1e-3 m violation tolerance


def test_plant_quaternion_stays_on_eq_2_solution():
    el = OrbitalElements(SMA, 0.0, 0.2, 0.0, 0.0, 0.0)
    tgt = TumblingTarget.aligned_with_hill(W_T, elements_to_eci(el))
    from proxops.propagation.truth import RelativeTruth

    plant = TumblingTargetTruth(RelativeTruth(el, np.zeros(6), j2=False), tgt, np.array([0, 50.0, 0, 0, 0, 0]))
    s = plant.initial_state()
    for k in range(100):
        s = plant.propagate(float(k), s, np.zeros(3), 1.0)
    np.testing.assert_allclose(quat_to_dcm(s[12:16]), tgt.rotation_inertial_from_body(100.0), atol=1e-12)


def test_initial_rotation_is_the_attitude_at_t0_and_read_only():
    """The cached R_IB(0) (shared by every run of a campaign target) is R_IB(t = 0) bit for bit, equals
    the Hill axes of the target for theta0 = 0 (frames.hill: body = Hill at t = 0), and cannot be
    modified by a caller."""
    from proxops.frames.hill import hill_dcm

    eci = elements_to_eci(OrbitalElements(SMA, 0.001, np.radians(51.6), 0.3, 0.2, 0.1))
    target = TumblingTarget.aligned_with_hill(W_T, eci, 0.0)
    R0 = target.initial_rotation
    assert np.array_equal(R0, target.rotation_inertial_from_body(0.0))
    np.testing.assert_allclose(R0, hill_dcm(eci).T, rtol=0, atol=1e-15)
    with pytest.raises(ValueError):
        R0[0, 0] = 2.0
    body = np.array([3.0, 70.0, -2.0, 0.01, -0.02, 0.0])
    np.testing.assert_allclose(target.body_state_from_offset(0.0, target.offset_from_body_state(0.0, body)), body,
                               rtol=0, atol=1e-12)


@pytest.mark.parametrize("integrator", ["fast", "reference"])
def test_one_call_step_equals_inner_step_plus_quaternion_and_reports_failure(integrator):
    """RelativeTruth.propagate_spinning (the plant's one jitted call with the fast integrator, issue 32 item 2) gives
    the inner truth's own step of state[:12] bit for bit and the exact eq.-(2) quaternion (closed form
    q0 (x) exp(0.5 w t), to 1e-12 after 50 steps); a failed step (a NaN input) raises the inner truth's one-line
    ProxopsError, as RelativeTruth.propagate does (fast integrator)."""
    from proxops.errors import ProxopsError
    from proxops.propagation.truth import RelativeTruth

    el = OrbitalElements(SMA, 0.0, np.radians(51.6), 0.0, 0.0, 0.0)
    tgt = TumblingTarget.aligned_with_hill(W_T, elements_to_eci(el), 0.4)
    inner = RelativeTruth(el, np.zeros(6), j2=True, integrator=integrator)
    plant = TumblingTargetTruth(inner, tgt, np.array([5.0, 60.0, -2.0, 0.1, 0.0, 0.0]))
    s = plant.initial_state()
    u = np.array([0.02, -0.01, 0.005])
    for k in range(50 if integrator == "fast" else 3):
        y12 = inner.propagate(float(k), s[:12], u, 1.0)
        s = plant.propagate(float(k), s, u, 1.0)
        assert np.array_equal(s[:12], y12)
    q = tgt.quaternion(float(k + 1))
    np.testing.assert_allclose(s[12:16] * np.sign(s[15] * q[3]), q, rtol=0, atol=1e-12)
    if integrator == "fast":  # (scipy's solve_ivp does not stop on a NaN input)
        with pytest.raises(ProxopsError, match="truth propagation failed at t = 3.0 s .* non-finite"):
            plant.propagate(3.0, s, np.array([np.nan, 0.0, 0.0]), 1.0)
