"""SRF guidance expert (srf-hopping-mpc.md §4.1-4.3, Algorithm 1).

Independent references: the Hill-frame CW STM of proxops.core.cw (Vallado eq. 6-66)
rotated to the paper's LVLH with proxops.frames.lvlh; the closed form eq. (14) derived
by hand (see module docstring); the R-bar root 3 phi = 4 sin phi by Newton iteration here;
the paper's §4.2/§5.3 statements (phi ~ 1.27, V-bar 0.5 t_orb, band beyond ~110 deg).
"""

import json
import math

import numpy as np
import pytest

from proxops.core.cw import cw_stm, mean_motion
from proxops.errors import ProxopsInputError
from proxops.frames.lvlh import HILL_TO_LVLH_STATE
from proxops.guidance import hop_times as ht

N = mean_motion(8100e3)  # Table 2 orbit
T_ORB = 2 * math.pi / N


def lvlh_stm(tau):
    """6x6 CW STM in the paper's LVLH from the Hill STM."""
    T = HILL_TO_LVLH_STATE
    return T @ cw_stm(N, tau) @ T.T


def propagate_lvlh(x0, tau):
    return lvlh_stm(tau) @ x0


def initial_state(theta, d0, v_xz):
    """LVLH state on the approach axis at d0 with in-plane velocity v_xz (m/s)."""
    return np.array([d0 * math.cos(theta), 0.0, d0 * math.sin(theta), v_xz[0], 0.0, v_xz[1]])


def test_eq19_blocks_match_hill_stm():
    for phi in (0.3, 1.2757, 2.0, 3.5):
        pp, pv, vp, vv = ht.cw_blocks(phi)
        P = lvlh_stm(phi / N)
        ix, iv = [0, 2], [3, 5]
        np.testing.assert_allclose(pp, P[np.ix_(ix, ix)], atol=1e-12)
        np.testing.assert_allclose(pv / N, P[np.ix_(ix, iv)], rtol=1e-10, atol=1e-6)
        np.testing.assert_allclose(vp * N, P[np.ix_(iv, ix)], atol=1e-15)
        np.testing.assert_allclose(vv, P[np.ix_(iv, iv)], atol=1e-12)


def test_rbar_largest_hop_phi_four_significant_digits():
    # Newton on 3 phi - 4 sin phi = 0, independent of the module's brentq.
    phi = 1.3
    for _ in range(50):
        phi -= (3 * phi - 4 * math.sin(phi)) / (3 - 4 * math.cos(phi))
    got = ht.rbar_phi(0.0)
    assert got == pytest.approx(phi, abs=1e-12)
    assert round(got, 2) == pytest.approx(1.28, abs=0.011)  # paper §4.2: "phi ~ 1.27" (truncated)
    assert f"{got:.4g}" == "1.276"
    assert got / (2 * math.pi) < 0.21  # paper: maximum hop "approximately 0.21 t_orb"


def test_general_solution_reduces_to_eq14_on_rbar():
    phi = np.linspace(0.05, 1.25, 30)
    np.testing.assert_allclose(ht.hop_rho(phi, math.pi / 2), ht.rbar_rho(phi), rtol=1e-9, atol=1e-12)
    for rho in (0.0, 0.3, 0.7, 0.95):
        p = ht.rbar_phi(rho)
        sol = ht.solve_hop(math.pi / 2, rho)
        assert sol.phi_rad == pytest.approx(p, rel=1e-9)


@pytest.mark.parametrize("theta_deg", [10.0, 40.0, 90.0, 110.0, 200.0, 250.0])
@pytest.mark.parametrize("rho", [0.3, 0.7])
def test_hop_arrives_on_axis_with_perpendicular_velocity(theta_deg, rho):
    theta, d0 = math.radians(theta_deg), 2000.0
    sol = ht.solve_hop(theta, rho)
    x0 = initial_state(theta, d0, sol.velocity_lvlh * N * d0)
    xt = propagate_lvlh(x0, sol.phi_rad / N)
    axis = np.array([math.cos(theta), 0.0, math.sin(theta)])
    np.testing.assert_allclose(xt[:3], rho * d0 * axis, atol=1e-6 * d0)  # eq. (23): r_t = [rho d0, 0]
    assert abs(xt[3:6] @ axis) < 1e-9 * N * d0  # eq. (17): p_t . v_t = 0


@pytest.mark.parametrize("rho", [0.2, 0.5, 0.9])
def test_vbar_hop_half_orbit_and_closed_return(rho):
    d0 = 2000.0
    sol = ht.solve_hop(0.0, rho)
    assert sol.period_fraction == 0.5  # eq. (7)
    x0 = initial_state(0.0, d0, sol.velocity_lvlh * N * d0)
    assert x0[3] == 0.0  # purely radial impulse
    half = propagate_lvlh(x0, T_ORB / 2)
    np.testing.assert_allclose(half[[0, 2, 3]], [rho * d0, 0.0, 0.0], atol=1e-6)  # eq. (8)
    assert half[5] == pytest.approx(-x0[5], rel=1e-9)  # v_zt = -v_z0
    full = propagate_lvlh(x0, T_ORB)
    np.testing.assert_allclose(full[:3], x0[:3], atol=1e-6)  # passive abort: back to the start


def test_fig8a_vbar_half_period_and_minimum_near_rbar():
    rho = 0.7
    for r in (0.1, 0.4, 0.7, 0.95):
        assert ht.solve_hop(0.0, r).period_fraction == 0.5
        assert ht.solve_hop(math.pi, r).period_fraction == 0.5
    # continuity towards the V-bar (Fig. 8a starts at 0.5)
    assert ht.solve_hop(math.radians(0.01), rho).period_fraction > 0.49
    angles = np.arange(2.0, 110.0, 4.0)
    fractions = np.array([ht.solve_hop(math.radians(a), rho).period_fraction for a in angles])
    assert np.all(np.diff(fractions[:10]) < 0)  # "rapidly decreasing" from the V-bar
    assert 78.0 <= angles[np.argmin(fractions)] <= 98.0  # "minimum close to the R-bar"
    assert fractions.min() < 0.21
    # period pi (§5.3): the third quadrant repeats the first
    for a in (20.0, 60.0, 100.0):
        f1 = ht.solve_hop(math.radians(a), rho).period_fraction
        f3 = ht.solve_hop(math.radians(a + 180.0), rho).period_fraction
        assert f3 == pytest.approx(f1, rel=1e-6)


def test_fig8a_no_solution_in_infeasible_band():
    rho = 0.7
    for a in (112.0, 120.0, 135.0, 150.0, 170.0, 179.0, 295.0, 330.0, 359.0):
        assert ht.try_solve_hop(math.radians(a), rho) is None, a
    edge = math.degrees(ht.feasible_angle_limit(rho))
    assert 105.0 < edge < 115.0  # §5.3: "beyond approximately 110 deg"


def test_first_quadrant_hops_are_passively_safe():
    # §5.3 / Fig. 8b: after a first/third-quadrant hop the free drift does not come closer
    # to the target than the hop end (the crossing point).
    d0 = 2000.0
    for a in (10.0, 40.0, 70.0, 90.0, 200.0):
        theta = math.radians(a)
        sol = ht.solve_hop(theta, 0.7)
        x0 = initial_state(theta, d0, sol.velocity_lvlh * N * d0)
        ranges = [np.linalg.norm(propagate_lvlh(x0, t)[:3]) for t in np.linspace(0, T_ORB, 721)]
        assert min(ranges) >= 0.7 * d0 * (1 - 1e-6)


def test_infeasible_angle_message():
    with pytest.raises(ProxopsInputError, match=r"approach angle = 130\.000 deg.*allowed for this rho"):
        ht.solve_hop(math.radians(130.0), 0.7)
    with pytest.raises(ProxopsInputError, match="approach angle"):
        ht.plan_hops(math.radians(150.0), 3, 0.5, 2000.0, 100.0, N)


def test_hop_distances_algorithm1():
    d = ht.hop_distances(2000.0, 100.0, 5, 0.5)
    lengths = -np.diff(d)
    assert d[0] == 2000.0 and d[-1] == 100.0
    assert lengths.sum() == pytest.approx(1900.0)
    np.testing.assert_allclose(lengths[1:] / lengths[:-1], 0.5)


@pytest.mark.parametrize("gamma", [0.0, 1.0, 1.5, -0.2, float("nan")])
def test_gamma_outside_unit_interval(gamma):
    with pytest.raises(ProxopsInputError, match="gamma"):
        ht.hop_distances(2000.0, 100.0, 3, gamma)


def test_bad_distances_and_hops():
    with pytest.raises(ProxopsInputError, match="end_m"):
        ht.hop_distances(100.0, 2000.0, 3, 0.5)
    with pytest.raises(ProxopsInputError, match="hops"):
        ht.hop_distances(2000.0, 100.0, 0, 0.5)
    with pytest.raises(ProxopsInputError, match="rho"):
        ht.solve_hop(0.5, 1.2)


def test_plan_hops_rbar_every_hop_within_largest_hop_time():
    plan = ht.plan_hops(math.pi / 2, 5, 0.5, 2000.0, 100.0, N)
    assert len(plan.hops) == 5
    limit = ht.rbar_phi(0.0) / N
    assert all(0 < h.duration_s < limit for h in plan.hops)
    for h in plan.hops:  # each hop time solves eq. (14) for its rho
        assert ht.rbar_rho(h.phi_rad) == pytest.approx(h.rho, abs=1e-9)


def test_cli_hop_times_json():
    from typer.testing import CliRunner

    from proxops.cli import app

    res = CliRunner().invoke(app, ["hop-times", "--approach-deg", "90", "--hops", "5", "--gamma", "0.5",
                                   "--start-m", "2000", "--end-m", "100", "--json"])
    assert res.exit_code == 0, res.output
    out = json.loads(res.stdout)
    assert out["period_s"] == pytest.approx(T_ORB, rel=1e-12)
    assert len(out["hops"]) == 5
    assert set(out["hops"][0]) == {"start_m", "end_m", "rho", "phi_rad", "duration_s", "period_fraction"}
    res = CliRunner().invoke(app, ["hop-times", "--approach-deg", "140", "--hops", "3", "--gamma", "0.5",
                                   "--start-m", "2000", "--end-m", "100", "--json"])
    assert res.exit_code == 2
    res = CliRunner().invoke(app, ["hop-times", "--approach-deg", "0", "--hops", "3", "--gamma", "1.2",
                                   "--start-m", "2000", "--end-m", "100", "--altitude-km", "500"])
    assert res.exit_code == 2 and "gamma" in res.output
