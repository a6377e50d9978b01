"""Hybrid capture physics (issue 16 items 1-3 and the bad-input list): two-rigid-body truth,
the paper's relative model verified against it, contact and decoupling jump maps.

Reference values: closed-form CW state-transition matrix (Vallado 6-66), rigid-body
invariants (inertial angular momentum and energy of a torque-free body), the cuboid
inertia formula, conservation laws of an internal impulse, Newton's restitution law,
finite differences of the contact gap, and a fine-step brute-force contact search.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from proxops.core.cw import cw_stm
from proxops.core.quaternion import quat_multiply, quat_rotate, quat_to_dcm
from proxops.dynamics.hybrid_relative import (
    S_OM,
    S_OMC,
    S_P,
    S_Q,
    S_RHO,
    S_RHOD,
    S_RN,
    S_RND,
    composite_inertia,
    impact_velocity,
    relative_contact_jump,
    relative_decoupling_jump,
    relative_from_truth,
    relative_rhs,
    steady_inputs,
)
from proxops.dynamics.two_rigid_bodies import (
    SL_QC,
    SL_QD,
    SL_RC,
    SL_RD,
    SL_VC,
    SL_VD,
    SL_WC,
    SL_WD,
    HybridInitialState,
    HybridParams,
    contact_frame,
    contact_event,
    contact_guard,
    contact_jump,
    contact_normal_velocity,
    in_jump_set,
    kinetic_energy,
    latch_snap_jump,
    latch_wrench,
    momenta,
    propagate_truth,
    truth_rhs,
    truth_state_from_initial,
)
from proxops.errors import ProxopsInputError

P = HybridParams()
TUMBLE = HybridInitialState(omega_c_rad_s=(0.05, -0.03, 0.04))  # ~3.9 deg/s chief tumble


def _u(t, x=None):
    """A smooth, time-varying deputy input in D (N, N m), well inside the capture box."""
    return np.array([0.3 * np.sin(0.1 * t), 0.2, -0.1 * np.cos(0.05 * t), 0.05, -0.02 * np.sin(0.2 * t), 0.01])


def _first_contact(x0, t_end=60.0, u_of_t=None):
    sol = propagate_truth(x0, (0.0, t_end), P, u_of_t=u_of_t, events=contact_event(P))
    assert sol.status == 1, "no contact found"
    return sol.t_events[0][0], sol.y_events[0][0]


# ----------------------------------------------------------------------------- parameters
def test_section7_cuboids_and_ports():
    """§VII: m/12 (b^2 + c^2, a^2 + c^2, a^2 + b^2); ports at face centres on +-y."""
    np.testing.assert_allclose(np.diag(P.J_d), [120 / 12 * (0.7**2 + 0.8**2), 120 / 12 * (0.6**2 + 0.8**2), 120 / 12 * (0.6**2 + 0.7**2)])
    np.testing.assert_allclose(np.diag(P.J_c), [30 * (1.15**2 + 1.57**2), 30 * (1.04**2 + 1.57**2), 30 * (1.04**2 + 1.15**2)])
    np.testing.assert_allclose(P.P_c, [0, 0.575, 0])
    np.testing.assert_allclose(P.P_d, [0, -0.35, 0])
    assert P.mass_total_kg == 480.0


# ----------------------------------------------------------------------------- truth
def test_truth_translation_is_standard_cw():
    """Both CoMs follow the closed-form CW solution (x'' = 3n^2 x + 2n y', not the printed
    eq. 21 G2 sign)."""
    n = P.mean_motion_rad_s
    x = truth_state_from_initial(P, HybridInitialState(rho0_m=(3.0, -2.0, 1.0), rho0_dot_m_s=(0.01, -0.02, 0.005)))
    x[SL_VC] = [0.002, -0.001, 0.0005]
    t = 1500.0
    sol = propagate_truth(x, (0.0, t), P)
    for sl_r, sl_v in ((SL_RC, SL_VC), (SL_RD, SL_VD)):
        ref = cw_stm(n, t) @ np.concatenate([x[sl_r], x[sl_v]])
        np.testing.assert_allclose(sol.y[sl_r, -1], ref[:3], atol=1e-8)
        np.testing.assert_allclose(sol.y[sl_v, -1], ref[3:], atol=1e-11)


def test_truth_attitude_conserves_inertial_momentum_and_energy():
    """Torque-free Euler + kinematics relative to the rotating T: each body's angular
    momentum is fixed in inertial space (T turns by n t about z) and its energy constant."""
    x0 = truth_state_from_initial(P, TUMBLE)
    t = 300.0
    sol = propagate_truth(x0, (0.0, t), P)
    x1 = sol.y[:, -1]
    c, s = math.cos(P.mean_motion_rad_s * t), math.sin(P.mean_motion_rad_s * t)
    Rz = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])  # C_{I<-T}(t) with T(0) = I(0)
    for sq, sw, J in ((SL_QC, SL_WC, P.J_c), (SL_QD, SL_WD, P.J_d)):
        h0 = quat_rotate(x0[sq], J @ x0[sw])
        h1 = Rz @ quat_rotate(x1[sq], J @ x1[sw])
        np.testing.assert_allclose(h1, h0, atol=1e-9 * np.linalg.norm(h0))
        assert x1[sw] @ J @ x1[sw] == pytest.approx(x0[sw] @ J @ x0[sw], rel=1e-10)


# ----------------------------------------------------------------------------- relative model
def _compare_relative_vs_truth(corrected: bool):
    """(truth relative states, |f_0 - truth|) at every second of the 100 s arc (the comparison
    behind ``proxops reproduce hybrid``; same tumble and input as this file's TUMBLE and _u)."""
    from proxops.analysis.hybrid_model_check import TUMBLE as ARC_TUMBLE
    from proxops.analysis.hybrid_model_check import relative_model_agreement, test_input

    assert ARC_TUMBLE == TUMBLE and np.array_equal(test_input(7.0), _u(7.0))
    _, X, errors = relative_model_agreement(100.0, 101, P)
    return X, errors[corrected]


def test_relative_model_matches_two_body_truth_over_tumbling_100s_arc():
    """f_0 (eqs. 22, 25-29, 32; corrected G2) integrated on its own agrees with the relative
    state computed from the direct two-body truth at every second of a 100 s arc with a
    3.9 deg/s chief tumble, the eq. 78 deputy rates and a time-varying input."""
    X, err = _compare_relative_vs_truth(corrected=True)
    assert err[:, S_RHO].max() < 1e-8  # m
    assert err[:, S_RHOD].max() < 1e-9  # m/s
    assert err[:, S_OM].max() < 1e-10  # rad/s
    assert err[:, S_Q].max() < 1e-9 and err[:, S_P].max() < 1e-9
    assert err[:, S_OMC].max() < 1e-12
    assert err[:, S_RN].max() < 1e-8 and err[:, S_RND].max() < 1e-10
    assert np.ptp(X[:, S_RHO], axis=0).max() > 1.0  # the arc does move (not a trivial match)


def test_printed_g2_disagrees_with_truth():
    """The printed eq. 21 G2 sign makes rho drift from the truth by metres in 100 s."""
    _, err = _compare_relative_vs_truth(corrected=False)
    assert err[:, S_RHO].max() > 0.1


def test_casadi_and_numpy_evaluate_the_same_model():
    import casadi as ca  # a core dependency
    x = relative_from_truth(truth_state_from_initial(P, TUMBLE), P)
    u = _u(3.0)
    X, U = ca.SX.sym("x", 32), ca.SX.sym("u", 6)
    f = ca.Function("f", [X, U], [relative_rhs(X, U, P)])
    np.testing.assert_allclose(np.array(f(x, u)).ravel(), relative_rhs(x, u, P), rtol=0, atol=1e-15)
    p, w = ca.SX.sym("p", 4), ca.SX.sym("w", 3)
    g = ca.Function("k0", [p, w], [ca.vertcat(*steady_inputs(p, w, P))])
    np.testing.assert_allclose(np.array(g(x[S_P], x[S_OMC])).ravel(), np.concatenate(steady_inputs(x[S_P], x[S_OMC], P)), atol=1e-15)


def test_steady_inputs_hold_the_docked_configuration_in_the_truth():
    """kappa^0 (eqs. 41, 43) evaluated along the way keeps rho = 0, omega = 0 in the
    direct truth (docked configuration of eq. 13, chief tumbling at 3.9 deg/s)."""
    ic = HybridInitialState(omega_c_rad_s=(0.05, -0.03, 0.04), omega_rad_s=(0, 0, 0), q=(0, 0, 0, 1))
    # docked: rho_0 = R^T (P_c - P_d), rho_0_dot from eq. 20 with rho = 0, omega = 0
    p = np.asarray(ic.p)
    R = quat_to_dcm(p).T
    d = P.P_c - P.P_d
    omc = np.asarray(ic.omega_c_rad_s)
    ic = HybridInitialState(
        rho0_m=tuple(R.T @ d), rho0_dot_m_s=tuple(R.T @ np.cross(omc, d)), omega_rad_s=(0, 0, 0), q=(0, 0, 0, 1),
        omega_c_rad_s=tuple(omc), p=tuple(p),
    )  # fmt: skip
    xt0 = truth_state_from_initial(P, ic)
    x_rel0 = relative_from_truth(xt0, P)
    np.testing.assert_allclose(x_rel0[S_RHO], 0, atol=1e-15)
    np.testing.assert_allclose(x_rel0[S_RHOD], 0, atol=1e-15)

    def u(t, xt):
        xr = relative_from_truth(xt, P)
        u1, u2 = steady_inputs(xr[S_P], xr[S_OMC], P)
        return np.concatenate([u1, u2])

    sol = propagate_truth(xt0, (0.0, 30.0), P, u_of_t=u)
    xr = relative_from_truth(sol.y[:, -1], P)
    assert np.abs(xr[S_RHO]).max() < 1e-7
    assert np.abs(xr[S_OM]).max() < 1e-9
    # and the paper's f_0 has rho'' = 0, omega' = 0 there
    du = np.concatenate(steady_inputs(x_rel0[S_P], x_rel0[S_OMC], P))
    f = relative_rhs(x_rel0, du, P)
    np.testing.assert_allclose(f[S_RHOD], 0, atol=1e-14)
    np.testing.assert_allclose(f[S_OM], 0, atol=1e-14)


# ----------------------------------------------------------------------------- contacts
def test_guard_root_agrees_with_brute_force_search():
    """First contact of the free-flying eq. 78 approach: root finding on g(x) (solve_ivp
    event) lands inside the bracket of a 1 ms brute-force scan of g along the same flow."""
    x0 = truth_state_from_initial(P, HybridInitialState())
    t_root, x_root = _first_contact(x0)
    assert abs(contact_guard(x_root, P)) < 1e-9
    from scipy.integrate import solve_ivp

    dense = solve_ivp(
        lambda t, y: truth_rhs(t, y, np.zeros(6), P), (0.0, t_root + 1.0), x0, method="DOP853", rtol=1e-11,
        atol=1e-12, dense_output=True,
    )  # fmt: skip
    ts = np.arange(0.0, t_root + 1.0, 1e-3)
    g = np.array([contact_guard(dense.sol(t), P) for t in ts])
    k = int(np.argmax(g <= 0.0))
    assert k > 0 and g[k - 1] > 0.0
    assert ts[k - 1] <= t_root <= ts[k]
    assert 5.0 < t_root < 20.0  # closing at ~0.08 m/s from 2 m (paper's controlled run: 11 s)


def test_impact_velocity_is_the_gap_rate():
    """v_rel of eq. 33 (truth form and the corrected relative-state form) equals the
    finite-difference rate of the contact gap just before impact; the printed eq. 33
    (with + omega_t x rho_0) does not."""
    x0 = truth_state_from_initial(P, HybridInitialState())
    t_c, x_c = _first_contact(x0)
    h = 1e-4
    sol = propagate_truth(x0, (0.0, t_c - h), P)
    rate = (contact_guard(x_c, P) - contact_guard(sol.y[:, -1], P)) / h
    v = contact_normal_velocity(x_c, P)
    assert v == pytest.approx(rate, rel=1e-3)
    r, n = contact_frame(x_c, P)
    xr = relative_from_truth(x_c, P)
    assert impact_velocity(xr, r, n, P) == pytest.approx(v, rel=1e-10)
    assert abs(impact_velocity(xr, r, n, P, corrected=False) - v) > 1e-5


def _contacts():
    """Contact states from several free-flying approaches (different tumbles and offsets)."""
    out = []
    rng = np.random.default_rng(16)
    for k in range(4):
        ic = HybridInitialState(
            rho0_m=(2.0, 0.2 * rng.standard_normal(), 0.2 * rng.standard_normal()),
            omega_c_rad_s=tuple(0.05 * rng.standard_normal(3)),
            omega_rad_s=tuple(0.1 * rng.standard_normal(3)),
        )
        out.append(_first_contact(truth_state_from_initial(P, ic))[1])
    return out


@pytest.mark.parametrize("e", [0.0, 0.5, 1.0])
def test_contact_jump_conserves_momentum_and_does_not_add_energy(e):
    for x in _contacts():
        xp, gamma, r, n = contact_jump(x, P, e)
        assert gamma > 0.0
        p0, h0 = momenta(x, P)
        p1, h1 = momenta(xp, P)
        np.testing.assert_allclose(p1, p0, atol=1e-12 * P.mass_total_kg)
        np.testing.assert_allclose(h1, h0, atol=1e-12 * max(1.0, np.linalg.norm(h0)))
        k0, k1 = kinetic_energy(x, P), kinetic_energy(xp, P)
        assert k1 <= k0 * (1 + 1e-10)  # round-off of ~1e-12 J on ~1 J
        if e == 1.0:
            assert k1 == pytest.approx(k0, rel=1e-10)
        else:  # loss = (1 - e^2) v_rel^2 / (2 k_eff) > 0
            assert k1 < k0 - 1e-6
        # Newton's law: normal relative velocity reversed and scaled by e
        assert contact_normal_velocity(xp, P, r, n) == pytest.approx(-e * contact_normal_velocity(x, P, r, n), abs=1e-10)
        np.testing.assert_array_equal(xp[SL_RC], x[SL_RC])
        np.testing.assert_array_equal(xp[SL_QD], x[SL_QD])


def test_jump_set_is_contact_and_approach():
    """D_0 (eq. 15 with eq. 33): in contact and approaching before the jump; after it the
    bodies separate (v_rel > 0 for e > 0), so the state is no longer in D_0."""
    x = _contacts()[0]
    assert in_jump_set(x, P)
    xp, _, _, _ = contact_jump(x, P, 0.5)
    assert not in_jump_set(xp, P)
    apart = truth_state_from_initial(P, HybridInitialState())
    assert not in_jump_set(apart, P)


def test_relative_jump_map_matches_truth_impulse():
    """g_0 (eqs. 34, 37, corrected 38) applied to the relative state equals the relative
    state of the truth after the same impulse; the printed eq. 38 moves the pair's CoM."""
    for x in _contacts():
        xp, gamma, r, n = contact_jump(x, P)
        xr, xr_plus = relative_from_truth(x, P), relative_from_truth(xp, P)
        np.testing.assert_allclose(relative_contact_jump(xr, gamma, r, n, P), xr_plus, atol=1e-11)
        printed = relative_contact_jump(xr, gamma, r, n, P, corrected=False)
        assert np.abs(printed[S_RND] - xr_plus[S_RND]).max() > 1e-3


def test_decoupling_jump_matches_truth_and_separates():
    """Latch snap (§VII, 0.05 N s along rho_0): g_1 (eqs. 53-61) equals the truth's jump;
    rates and the pair CoM are unchanged and the bodies separate."""
    ic = HybridInitialState(omega_rad_s=(0, 0, 0), q=(0, 0, 0, 1), rho0_m=(0.0, 0.925, 0.0), p=(0, 0, 0, 1))
    x = truth_state_from_initial(P, ic)
    xs = latch_snap_jump(x, P)
    rho0 = x[SL_RD] - x[SL_RC]
    T_pi = -0.05 * rho0 / np.linalg.norm(rho0)  # impulse on the chief, eq. 57
    xr = relative_from_truth(x, P)
    np.testing.assert_allclose(relative_decoupling_jump(xr, T_pi, P), relative_from_truth(xs, P), atol=1e-15)
    np.testing.assert_array_equal(xs[SL_WC], x[SL_WC])
    np.testing.assert_array_equal(xs[SL_WD], x[SL_WD])
    np.testing.assert_allclose(momenta(xs, P)[0], momenta(x, P)[0], atol=1e-15)
    sep_rate = (xs[SL_VD] - xs[SL_VC] - x[SL_VD] + x[SL_VC]) @ rho0 / np.linalg.norm(rho0)
    assert sep_rate == pytest.approx(0.05 * (1 / 360 + 1 / 120), rel=1e-12)


def test_composite_inertia_gives_the_pair_kinetic_energy():
    """Rigidly co-rotating docked pair: (1/2) m |v_n|^2 + (1/2) W.J_n W with the corrected
    composite inertia (parallel-axis) equals the sum of the two bodies' kinetic energies."""
    p = np.array([-0.5, 0.5, 0.5, 0.5])
    Rtc = quat_to_dcm(p)  # C_{T<-C}
    W_C = np.array([0.02, -0.01, 0.03])  # omega_{C/I}|_C
    d_T = Rtc @ (P.P_c - P.P_d)
    x = np.zeros(26)
    x[SL_QC], x[SL_QD], x[SL_WC], x[SL_WD] = p, p, W_C, W_C
    x[SL_RD] = d_T
    W_T = Rtc @ W_C
    m, mc, md = P.mass_total_kg, P.mass_chief_kg, P.mass_deputy_kg
    rn = md / m * d_T
    vn_in = np.array([0.01, 0.0, -0.02])  # inertial CoM velocity
    wt = P.omega_t
    for sl_r, sl_v, r in ((SL_RC, SL_VC, np.zeros(3)), (SL_RD, SL_VD, d_T)):
        x[sl_v] = vn_in + np.cross(W_T, r - rn) - np.cross(wt, r)  # T-frame derivative
    J_n = composite_inertia(relative_from_truth(x, P), P)
    k_comp = 0.5 * m * vn_in @ vn_in + 0.5 * W_C @ J_n @ W_C
    assert k_comp == pytest.approx(kinetic_energy(x, P), rel=1e-12)
    k_printed = 0.5 * m * vn_in @ vn_in + 0.5 * W_C @ (P.J_c + P.J_d) @ W_C  # eq. 49's J_c + J_d
    assert abs(k_printed - kinetic_energy(x, P)) > 1e-6


# ----------------------------------------------------------------------------- bad input
@pytest.mark.parametrize(
    "make, field",
    [
        (lambda: HybridParams(mass_chief_kg=0.0), "mass_chief_kg"),
        (lambda: HybridParams(mass_deputy_kg=-120.0), "mass_deputy_kg"),
        (lambda: HybridParams(dims_deputy_m=(0.6, 0.0, 0.8)), "dims_deputy_m"),
        (lambda: HybridParams(inertia_chief_kgm2=np.diag([100.0, 100.0, -1.0])), "inertia_chief_kgm2"),
        (lambda: HybridParams(inertia_deputy_kgm2=np.diag([1.0, 1.0, 0.0])), "inertia_deputy_kgm2"),
        (lambda: HybridParams(inertia_deputy_kgm2=np.diag([1.0, 1.0, 2.5])), "triangle inequality"),
        (lambda: HybridParams(inertia_deputy_kgm2=[[10, 1, 0], [0, 10, 0], [0, 0, 10]]), "symmetric"),
        (lambda: HybridParams(port_chief_m=(0.0, 0.6, 0.0)), "port_chief_m"),
        (lambda: HybridParams(port_deputy_m=(0.0, 0.0, -0.41)), "port_deputy_m"),
        (lambda: HybridParams(restitution=1.2), "restitution"),
        (lambda: HybridParams(restitution=-0.1), "restitution"),
        (lambda: HybridParams(latch_KT=0.0), "latch_KT"),
        (lambda: HybridParams(force_max_capture_N=-1.0), "force_max_capture_N"),
        (lambda: HybridInitialState(q=(0.57, 0.57, 0.57, 0.0)), "q = "),  # eq. 78 as printed
        (lambda: HybridInitialState(p=(0.5, 0.5, 0.5, 0.6)), "p = "),
        (lambda: truth_state_from_initial(P, HybridInitialState(rho0_m=(1.0, 0.0, 0.0))), "interpenetrate"),
    ],
)
def test_bad_input_is_one_clear_line(make, field):
    with pytest.raises(ProxopsInputError) as err:
        make()
    msg = str(err.value)
    assert field in msg and "\n" not in msg


def test_docked_start_is_not_interpenetration():
    """Faces flush (the docked configuration, rho = 0) is allowed; 1 cm deeper is not."""
    ok = HybridInitialState(rho0_m=(0.0, 0.925, 0.0), p=(0, 0, 0, 1), q=(0, 0, 0, 1))
    truth_state_from_initial(P, ok)
    with pytest.raises(ProxopsInputError):
        truth_state_from_initial(P, HybridInitialState(rho0_m=(0.0, 0.915, 0.0), p=(0, 0, 0, 1), q=(0, 0, 0, 1)))


def test_q_d_composition():
    """Sanity of the eq. 78 -> truth mapping: q_d = p (x) q and the relative map inverts it."""
    x = truth_state_from_initial(P, HybridInitialState())
    np.testing.assert_allclose(x[SL_QD], quat_multiply(np.asarray(HybridInitialState().p), np.asarray(HybridInitialState().q)))
    xr = relative_from_truth(x, P)
    np.testing.assert_allclose(xr[S_OM], HybridInitialState().omega_rad_s, atol=1e-15)
    np.testing.assert_allclose(xr[S_OMC], HybridInitialState().omega_c_rad_s, atol=1e-15)
    np.testing.assert_allclose(xr[S_RN], 120 / 480 * np.array([2.0, 0, 0]), atol=1e-15)


# ----------------------------------------------------------------------------- latch (eq. 81)
def _near_docked(params=P):
    p = np.array([-0.5, 0.5, 0.5, 0.5])
    R = quat_to_dcm(p).T
    d = params.P_c - params.P_d
    omc = np.array([-0.0024, 0.0024, -0.0024])
    ic = HybridInitialState(
        rho0_m=tuple(R.T @ (d + np.array([0.003, 0.01, 0.002]))), rho0_dot_m_s=tuple(R.T @ np.cross(omc, d) + 0.002),
        omega_rad_s=(0.01, 0.0, 0.005), q=(0.0, 0.0, 0.0, 1.0), omega_c_rad_s=tuple(omc), p=tuple(p),
    )  # fmt: skip
    return truth_state_from_initial(params, ic)


def test_latch_is_an_internal_pair():
    """The latch forces sum to zero and their moments plus torques about T's origin too."""
    x = _near_docked()
    F, tau_d, tau_c = latch_wrench(x, P)
    assert np.linalg.norm(F) > 1e-3
    moment = (
        np.cross(x[SL_RD], F) + quat_rotate(x[SL_QD], tau_d) + np.cross(x[SL_RC], -F) + quat_rotate(x[SL_QC], tau_c)
    )
    np.testing.assert_allclose(moment, 0.0, atol=1e-15)


def test_latched_pair_com_follows_cw():
    """Internal latch loads leave the pair's CoM on its CW trajectory (closed form)."""
    x0 = _near_docked()
    t = 30.0
    sol = propagate_truth(x0, (0.0, t), P, latched=True, rtol=1e-10, atol=1e-12)
    m = P.mass_total_kg

    def com(x):
        return np.concatenate([(P.mass_chief_kg * x[SL_RC] + P.mass_deputy_kg * x[SL_RD]) / m,
                               (P.mass_chief_kg * x[SL_VC] + P.mass_deputy_kg * x[SL_VD]) / m])  # fmt: skip

    np.testing.assert_allclose(com(sol.y[:, -1]), cw_stm(P.mean_motion_rad_s, t) @ com(x0), atol=1e-10)


def test_latch_dissipates_energy():
    """Near-inertial frame (n = 1e-12 rad/s): kinetic energy + latch spring energy
    (1/2 K_T |rho|^2 + 1/2 K_R theta^2) never increases."""
    params = HybridParams(mean_motion_rad_s=1e-12)
    x0 = _near_docked(params)
    ts = np.linspace(0.0, 20.0, 41)
    sol = propagate_truth(x0, (0.0, 20.0), params, t_eval=ts, latched=True)

    def energy(x):
        xr = relative_from_truth(x, params)
        theta = 2.0 * math.atan2(np.linalg.norm(xr[S_Q][:3]), xr[S_Q][3])
        return kinetic_energy(x, params) + 0.5 * params.latch_KT * xr[S_RHO] @ xr[S_RHO] + 0.5 * params.latch_KR * theta**2

    E = np.array([energy(sol.y[:, k]) for k in range(ts.size)])
    assert np.all(np.diff(E) <= 1e-12 * E[0])
    assert E[-1] < E[0]


def _edge_points(R, c, h, n_per_edge=400):
    """Points (T) sampled along the 12 edges of a box."""
    pts = []
    s = np.linspace(-1.0, 1.0, n_per_edge)
    for k in range(3):
        o = [i for i in range(3) if i != k]
        for a in (-1.0, 1.0):
            for b in (-1.0, 1.0):
                local = np.zeros((n_per_edge, 3))
                local[:, k] = s * h[k]
                local[:, o[0]] = a * h[o[0]]
                local[:, o[1]] = b * h[o[1]]
                pts.append(c + local @ R.T)
    return np.vstack(pts)


def _deepest_edge_penetration(x):
    """Most negative signed distance (m) of either box's sampled edge points inside the
    other box (independent of the separating-axis guard)."""
    Rc, Rd = quat_to_dcm(x[SL_QC]), quat_to_dcm(x[SL_QD])
    from proxops.dynamics.two_rigid_bodies import box_sdf

    pd = _edge_points(Rd, x[SL_RD], P.half_deputy)
    pc = _edge_points(Rc, x[SL_RC], P.half_chief)
    return min(box_sdf((pd - x[SL_RC]) @ Rc, P.half_chief).min(), box_sdf((pc - x[SL_RD]) @ Rd, P.half_deputy).min())


def test_guard_catches_edge_edge_contacts():
    """Random tumbling approaches: before the located contact no edge point of either cuboid
    is inside the other, 0.1 s later (no jump) one is -- whether the first touch is
    vertex-face or edge-edge."""
    from scipy.integrate import solve_ivp

    rng = np.random.default_rng(5)
    for _ in range(5):
        ic = HybridInitialState(
            rho0_m=(2.0, 0.3 * rng.standard_normal(), 0.3 * rng.standard_normal()),
            omega_c_rad_s=tuple(0.05 * rng.standard_normal(3)), omega_rad_s=tuple(0.1 * rng.standard_normal(3)),
        )  # fmt: skip
        x0 = truth_state_from_initial(P, ic)
        t_c, _ = _first_contact(x0)
        dense = solve_ivp(lambda t, y: truth_rhs(t, y, np.zeros(6), P), (0.0, t_c + 0.1), x0, method="DOP853",
                          rtol=1e-11, atol=1e-12, dense_output=True)  # fmt: skip
        for t in np.linspace(max(0.0, t_c - 3.0), t_c - 1e-3, 60):
            assert _deepest_edge_penetration(dense.sol(t)) > -1e-6
        assert _deepest_edge_penetration(dense.sol(t_c + 0.1)) < -1e-3
