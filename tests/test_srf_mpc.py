"""SRF MPC (problem 29) in closed loop on the linear CW plant (perfect navigation, no J2):
hop timing from the guidance expert, V-bar radial impulses of eq. (8), terminal arrival,
CBF keep-out on the free drift. References: eq. (8) (dv_z = w L / 4), Algorithm 1 hop
durations, the closed-form CW STM, the KOZ geometry."""

import math

import numpy as np
import pytest

from proxops.constraints.keep_out import KeepOutSphere
from proxops.control.srf_mpc import SrfMpc, SrfMpcConfig, build_schedule
from proxops.core.cw import cw_stm, mean_motion
from proxops.errors import ProxopsInputError
from proxops.frames.lvlh import hill_vector_to_lvlh, lvlh_vector_to_hill
from proxops.guidance.hop_times import plan_hops, rbar_phi
from proxops.propagation.truth import CWPlant
from proxops.sim.engine import Setup, simulate

N_ORB = mean_motion(8100e3)
T_ORB = 2 * math.pi / N_ORB
DT = T_ORB / 720


def run_loop(theta_deg, hops, *, vbar_fraction=0.5, koz_radius=50.0, steps_per_hop=6, **cfg_kw):
    theta = math.radians(theta_deg)
    plan = plan_hops(theta, hops, 0.5, 2000.0, 100.0, N_ORB, vbar_period_fraction=vbar_fraction)
    sched = build_schedule(plan.durations_s, steps_per_hop, DT)
    a = lvlh_vector_to_hill([math.cos(theta), 0.0, math.sin(theta)])
    b = lvlh_vector_to_hill([-math.sin(theta), 0.0, math.cos(theta)])
    vbar = abs(math.sin(theta)) < 1e-9
    d = np.array([h.start_m for h in plan.hops] + [plan.hops[-1].end_m])
    defaults = dict(u_max_mps=3.0, vbar_rows=vbar, epsilon_m=50.0 if vbar else 0.0,
                    hop_distance_weight_per_m2=1e-7 if vbar else 0.0,
                    hop_distance_tol_m=None if vbar else list(0.1 * -np.diff(d)),
                    mid_hop_fuel_weight=1.0 if vbar else 2.0, free_drift_nodes=48)
    defaults.update(cfg_kw)
    ctrl = SrfMpc(N_ORB, sched, a, b, 100.0 * a, KeepOutSphere(koz_radius), SrfMpcConfig(**defaults),
                  hop_distances_m=d)
    plant = CWPlant(N_ORB, np.concatenate([2000.0 * a, np.zeros(3)]))
    res = simulate(Setup(plant, ctrl, duration_s=sched.times[-1] + 2 * DT))
    return res, ctrl, plan, sched, a


@pytest.fixture(scope="module")
def vbar_run():
    return run_loop(0.0, 3)


@pytest.fixture(scope="module")
def rbar_run():
    return run_loop(90.0, 4)


def fired(res, tol=1e-3):
    return np.nonzero(np.linalg.norm(res.u_applied, axis=1) > tol)[0]


def test_vbar_hops_every_half_orbit_with_radial_dv(vbar_run):
    res, ctrl, plan, sched, a = vbar_run
    k = fired(res)
    t = res.t[k]
    # impulses above 1 mm/s only at the hop instants: multiples of 0.5 t_orb (eq. 7)
    np.testing.assert_allclose(t / (0.5 * T_ORB), np.round(t / (0.5 * T_ORB)), atol=1e-9)
    assert len(k) == 4  # 3 hops + the final braking impulse
    dv = hill_vector_to_lvlh(res.u_applied)
    share = np.abs(dv[:, 0]).sum() / np.abs(dv).sum()
    assert share < 0.02  # essentially radial (paper §5.1: "all impulses in the radial direction")
    # eq. (8): the first hop's radial impulse is w L1 / 4 with L1 read off the trajectory
    k_half = int(np.argmin(np.abs(res.t - 0.5 * T_ORB)))
    hop1 = 2000.0 - float(a @ res.x_true[k_half, :3])
    assert abs(dv[k[0], 2]) == pytest.approx(N_ORB * hop1 / 4, rel=0.01)
    assert all(s == "optimal" for s, i in zip(res.status, res.info["solved"]) if i == 1)


def test_vbar_arrives_and_hops_decrease(vbar_run):
    res, ctrl, plan, sched, a = vbar_run
    k_end = int(np.argmin(np.abs(res.t - sched.times[-1])))
    assert np.max(np.abs(res.x_true[k_end, :3] - 100.0 * a)) <= 2.0 + 1e-6  # terminal box (29d), inf-norm
    ends = [2000.0] + [float(a @ res.x_true[int(np.argmin(np.abs(res.t - t))), :3])
                       for t in sched.times[sched.hop_nodes]]
    lengths = -np.diff(ends)
    assert np.all(lengths[1:] <= lengths[:-1] - 50.0 + 1.0)  # (29o) with eps = 50 m (1 m tolerances)
    assert np.all(lengths > 0)


def test_vbar_passive_abort_returns_to_hop_start(vbar_run):
    res, ctrl, plan, sched, a = vbar_run
    for k in fired(res)[:-1]:  # every hop impulse (not the final brake)
        x = res.x_true[k].copy()
        x[3:6] += res.u_applied[k]
        back = cw_stm(N_ORB, T_ORB) @ x
        assert np.linalg.norm(back[:3] - x[:3]) < 20.0  # 1 m hop tolerances -> <= 6 pi m of drift
        ranges = [np.linalg.norm((cw_stm(N_ORB, tau) @ x)[:3]) for tau in np.linspace(0.0, T_ORB, 361)]
        assert min(ranges) > 50.0


def test_rbar_hop_intervals_follow_guidance(rbar_run):
    res, ctrl, plan, sched, a = rbar_run
    intervals = np.diff(np.concatenate([[0.0], sched.times[sched.hop_nodes]]))
    np.testing.assert_allclose(intervals, plan.durations_s, atol=DT / 2 + 1e-9)
    assert np.all(intervals < rbar_phi(0.0) / N_ORB)  # every hop within the largest-hop time (0.2030 t_orb)
    k_end = int(np.argmin(np.abs(res.t - sched.times[-1])))
    assert np.max(np.abs(res.x_true[k_end, :3] - 100.0 * a)) <= 2.0 + 1e-6
    # hop ends on the axis at the guidance instants (29l), within r_tol = 1 m
    b = lvlh_vector_to_hill([-1.0, 0.0, 0.0])
    for t in sched.times[sched.hop_nodes]:
        k = int(np.argmin(np.abs(res.t - t)))
        assert abs(b @ res.x_true[k, :3]) <= 1.0 + 1e-6


def test_rbar_costs_more_and_is_faster_than_vbar(vbar_run, rbar_run):
    v, r = vbar_run[0], rbar_run[0]
    assert r.dv_cum[-1] > 4 * v.dv_cum[-1]
    assert rbar_run[3].times[-1] < 0.5 * vbar_run[3].times[-1]


def test_cbf_keeps_free_drift_out_of_koz():
    """§5.4: V-bar with 0.6 t_orb hops; the free drift of the last hop enters the KOZ without the
    CBF, not with it (true nonlinear condition checked on every accepted solution)."""
    koz = KeepOutSphere(50.0)
    out = {}
    for cbf in (False, True):
        res, ctrl, plan, sched, a = run_loop(0.0, 3, vbar_fraction=0.6, cbf=cbf, free_drift_s=2 * T_ORB)
        last_hop = sched.times[sched.hop_nodes[-2]]
        k = int(np.argmin(np.abs(res.t - last_hop)))
        x = res.x_true[k].copy()
        x[3:6] += res.u_applied[k]
        drift = np.array([cw_stm(N_ORB, tau) @ x for tau in np.linspace(0.0, 2 * T_ORB, 1441)])
        out[cbf] = float(np.min(koz.distance_to_surface(drift[:, :3])))
        if cbf:
            solved = np.nan_to_num(res.info["solved"]) > 0
            ok = np.array([s == "optimal" for s in res.status])[solved]
            assert ok.all()
            g_tol = 1e-6 * 0.01 * 50.0**2
            assert np.all(res.info["cbf_min"][solved] >= -g_tol)  # eq. (28) on x_u at every node
            assert np.all(res.info["drift_min_range_m"][solved] >= 50.0 * (1 - 1e-9))
    assert out[False] < 0.0 < out[True]


def test_reference_inside_koz_is_an_error():
    sched = build_schedule([1000.0], 4, 10.0)
    a = np.array([0.0, 1.0, 0.0])
    with pytest.raises(ProxopsInputError, match="keep-out"):
        SrfMpc(N_ORB, sched, a, np.array([-1.0, 0, 0]), 40.0 * a, KeepOutSphere(50.0))


def test_schedule_rounds_hops_to_engine_steps_and_rejects_short_hops():
    sched = build_schedule([1000.0, 505.0], 5, 10.0)
    np.testing.assert_array_equal(sched.times[sched.hop_nodes], [1000.0, 1500.0])  # 505 s -> 50 steps
    assert sched.n == 10
    with pytest.raises(ProxopsInputError, match="dt_s"):
        build_schedule([30.0], 5, 10.0)


@pytest.fixture(scope="module")
def vbar_drift_free_run():
    return run_loop(0.0, 3, drift_free_tol_mps=1e-4)


def test_vbar_drift_free_rows_remove_the_secular_drift(vbar_drift_free_run):
    """CW: y(t) has the secular term -(6 n x0 + 3 vy0) t, so after a hop impulse with
    |vy+ + 2 n x| <= tol the drift returns within 3 t_orb tol per orbit of its start (closed-form STM)."""
    res, ctrl, plan, sched, a = vbar_drift_free_run
    tol = 1e-4
    hop_starts = [0.0] + list(sched.times[sched.hop_nodes][:-1])
    for t in hop_starts:
        k = int(np.argmin(np.abs(res.t - t)))
        x = res.x_true[k].copy()
        x[3:6] += res.u_applied[k]
        assert abs(x[4] + 2 * N_ORB * x[0]) <= tol * (1 + 1e-6) + 1e-9
        for m in (1, 2, 3):
            back = cw_stm(N_ORB, m * T_ORB) @ x
            assert np.linalg.norm(back[:3] - x[:3]) <= m * 3 * T_ORB * tol + 1e-6
    # the hops themselves are unchanged: radial impulses at the half-orbit instants
    k = fired(res)
    np.testing.assert_allclose(res.t[k] / (0.5 * T_ORB), np.round(res.t[k] / (0.5 * T_ORB)), atol=1e-9)


def test_without_drift_rows_the_hop_tolerance_leaves_drift(vbar_run):
    """Regression reference for the test above: (29m)'s 2 mm/s alone leaves more than 3 t_orb tol of drift."""
    res, ctrl, plan, sched, a = vbar_run
    worst = 0.0
    for t in [0.0] + list(sched.times[sched.hop_nodes][:-1]):
        k = int(np.argmin(np.abs(res.t - t)))
        x = res.x_true[k].copy()
        x[3:6] += res.u_applied[k]
        worst = max(worst, abs(x[4] + 2 * N_ORB * x[0]))
    assert worst > 1e-4


@pytest.mark.parametrize("fixture", ["vbar_run", "rbar_run"])
def test_fixed_pattern_qp_matrices_equal_a_fresh_coo_build(fixture, request, monkeypatch):
    """_build gathers the values onto a CSC pattern computed once (a permutation of the COO
    entries); its matrices must be exactly those scipy builds from the same (values, (rows, cols))
    triplets, at first, middle and last nodes, with and without the CBF rows. The matrices are
    refilled in place by the next build of the same pattern, so each build's are copied here."""
    import scipy.sparse as sp

    res, ctrl, plan, sched, a = request.getfixturevalue(fixture)
    x = res.x_true[0]
    fast = {}
    for i in (0, 1, sched.n // 2, sched.n):
        for with_cbf in (True, False):
            qp = ctrl._build(i, x, None, 0, with_cbf=with_cbf)
            fast[i, with_cbf] = (qp.A_eq.copy(), qp.G.copy())

    def direct(key, entries, shape, values):
        rows, cols = entries() if callable(entries) else entries
        return sp.csc_matrix((values, (rows, cols)), shape=shape)

    monkeypatch.setattr(ctrl, "_csc", direct)
    for (i, with_cbf), (A_eq, G) in fast.items():
        ref = ctrl._build(i, x, None, 0, with_cbf=with_cbf)
        for got, want in ((A_eq, ref.A_eq), (G, ref.G)):
            assert got.shape == want.shape
            assert np.array_equal(got.indptr, want.indptr) and np.array_equal(got.indices, want.indices)
            assert np.array_equal(got.data, want.data)  # explicit zeros of the pattern kept, same order
    assert ctrl._n_cbf > 0 and fast[0, True][1].shape[0] > fast[0, False][1].shape[0]  # both patterns exercised
