"""Hybrid system (hybrid-mpc-capture.md, issue 16 items 4, 6-8): the engine plant with
contacts / latch / latch snap, the §III supervisor (Cases 1-4, tau and T_1, hysteresis),
scenario checks through the CLI. Reference values come from an independent integration
(scipy DOP853 with the truth's own contact event), closed forms (snap impulse) and
invariants (pair momentum across jumps, under the latch)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from typer.testing import CliRunner

from proxops.cli import app
from proxops.control.hybrid_supervisor import CAPTURE, POST_CAPTURE, HybridModeRule, HybridSupervisor
from proxops.control.supervisor import Hysteresis, Supervisor
from proxops.dynamics.hybrid_relative import relative_from_truth
from proxops.dynamics.two_rigid_bodies import (
    SL_RC,
    SL_RD,
    SL_VC,
    SL_VD,
    HybridInitialState,
    HybridParams,
    contact_event,
    contact_guard,
    momenta,
    propagate_truth,
    truth_state_from_initial,
)
from proxops.propagation.hybrid_plant import (
    I_LATCHED,
    M_CONTACTS,
    M_LATCHED,
    N_MEASURED,
    CaptureEnvelope,
    HybridCapturePlant,
    contact_impulses,
    envelope_kernel,
    sat_gap_kernel,
)
from proxops.sim.engine import Setup, simulate
from proxops.contracts import Command

PARAMS = HybridParams()
X78 = truth_state_from_initial(PARAMS, HybridInitialState())


def _docked_truth(params=PARAMS):
    """Truth state of the docked configuration A_0 (rho = 0, q = q_I) with the eq. 78 chief."""
    x = X78.copy()
    x[12:16] = np.array([-0.5, 0.5, 0.5, 0.5])
    x[19:23] = x[12:16]
    from proxops.core.quaternion import quat_to_dcm

    Rc = quat_to_dcm(x[12:16])
    x[SL_RD] = Rc @ (params.P_c - params.P_d)
    x[23:26] = x[16:19]
    w_T = Rc @ (x[16:19]) - params.omega_t  # omega_{C/T} in T
    x[SL_VD] = np.cross(w_T, x[SL_RD])
    return x


# ------------------------------------------------------------------ kernels vs the reference functions
def test_numba_guard_and_envelope_match_the_reference_functions():
    rng = np.random.default_rng(3)
    for _ in range(200):
        x = X78.copy()
        x[SL_RD] = rng.normal(0.0, 0.8, 3)
        for sl in (slice(12, 16), slice(19, 23)):
            q = rng.normal(size=4)
            x[sl] = q / np.linalg.norm(q)
        x[16:19], x[23:26] = rng.normal(0, 0.05, 3), rng.normal(0, 0.05, 3)
        g_ref = contact_guard(x, PARAMS)
        g = sat_gap_kernel(x, PARAMS.half_chief, PARAMS.half_deputy)
        assert np.sign(g) == np.sign(g_ref)
        radii = np.linalg.norm(PARAMS.half_chief) + np.linalg.norm(PARAMS.half_deputy)
        if np.linalg.norm(x[SL_RD] - x[SL_RC]) <= radii:  # spheres overlap: the value is the SAT gap itself
            assert g == pytest.approx(g_ref, abs=1e-12)
        rel = relative_from_truth(x, PARAMS)
        rho, rhod, om, ang = envelope_kernel(x, PARAMS.P_c, PARAMS.P_d, PARAMS.mean_motion_rad_s)
        assert rho == pytest.approx(np.linalg.norm(rel[0:3]), abs=1e-12)
        assert rhod == pytest.approx(np.linalg.norm(rel[3:6]), abs=1e-12)
        assert om == pytest.approx(np.linalg.norm(rel[6:9]), abs=1e-12)
        assert ang == pytest.approx(2 * math.atan2(np.linalg.norm(rel[9:12]), abs(rel[12])), abs=1e-9)


# ------------------------------------------------------------------ contacts
@pytest.fixture(scope="module")
def first_contact_reference():
    """First contact of the free-flying eq. 78 pair: scipy DOP853 (rtol 1e-11) with the truth's
    contact event, an integrator independent of the plant's RK4."""
    sol = propagate_truth(X78, (0.0, 30.0), PARAMS, events=contact_event(PARAMS))
    assert sol.status == 1 and len(sol.t_events[0]) == 1
    return float(sol.t_events[0][0]), sol.y_events[0][0]


@pytest.mark.parametrize("dt", [1.0, 5.0])
def test_contact_located_at_the_reference_instant_for_any_engine_step(first_contact_reference, dt):
    t_ref, x_ref = first_contact_reference
    plant = HybridCapturePlant(PARAMS, X78)
    y, t, events = plant.initial_state(), 0.0, []
    while t < 15.0:
        y_prev = y
        y, ev = plant.propagate_events(t, y, np.zeros(6), dt)
        events += ev
        if ev:
            break
        t += dt
    contacts = [e for e in events if e[1] == "contact"]
    assert contacts, "the contact tunnelled through the step"
    assert contacts[0][0] == pytest.approx(t_ref, abs=2e-5)  # RK4 h = 0.05 s vs DOP853: located to ~1e-6 s
    # the state at the event: momenta conserved across the jump (internal impulse)
    t_c = contacts[0][0]
    y_minus = plant.flow(y_prev, np.zeros(6), t_c - t)
    p0, h0 = momenta(y_minus[:26], PARAMS)
    y_plus = y_minus.copy()
    from proxops.dynamics.two_rigid_bodies import contact_jump

    y_plus[:26], gamma, _, _ = contact_jump(y_minus[:26], PARAMS)
    p1, h1 = momenta(y_plus[:26], PARAMS)
    assert gamma == pytest.approx(contact_impulses(contacts)[0]["impulse_Ns"], rel=1e-4)
    assert np.allclose(p0, p1, atol=1e-12) and np.allclose(h0, h1, atol=1e-9)
    assert abs(contact_guard(y_minus[:26], PARAMS)) < 1e-6


def test_first_contact_of_eq78_free_flight_is_near_the_papers_11_s(first_contact_reference):
    """§VII: first impact at t = 11 s under the capture MPC; with no control it is at 10.84 s."""
    assert 10.0 < first_contact_reference[0] < 11.5


# ------------------------------------------------------------------ latch and snap
def test_latch_conserves_pair_momentum_and_snap_gives_the_closed_form_separation_rate():
    p = HybridParams(snap_time_s=20.0)
    x0 = _docked_truth(p)
    plant = HybridCapturePlant(p, x0, start_latched=True)
    free = HybridCapturePlant(p, x0, snap_enabled=False, envelope=CaptureEnvelope(1e-9, 1e-9, 1e-9, 1e-9))
    y, y_free = plant.initial_state(), free.initial_state()
    m_c, m_d = p.mass_chief_kg, p.mass_deputy_kg

    def com(z):
        return (m_c * z[SL_RC] + m_d * z[SL_RD]) / (m_c + m_d), (m_c * z[SL_VC] + m_d * z[SL_VD]) / (m_c + m_d)

    for k in range(19):
        y, _ = plant.propagate_events(float(k), y, np.zeros(6), 1.0)
        y_free = free.flow(y_free, np.zeros(6), 1.0)
        assert y[I_LATCHED] == 1.0
        # the latch is an internal force pair: the pair's CoM follows the same (linear CW) motion
        assert np.allclose(com(y)[0], com(y_free)[0], atol=1e-10) and np.allclose(com(y)[1], com(y_free)[1], atol=1e-12)
    assert np.linalg.norm(plant.relative_state(y)[0:3]) < 1e-3
    y_before = y.copy()
    y, ev = plant.propagate_events(19.0, y, np.zeros(6), 1.0)
    snap = [e for e in ev if e[1] == "snap"]
    assert snap and snap[0][0] == pytest.approx(20.0) and y[I_LATCHED] == 0.0
    assert ("latch", "latched -> free") in [(k, m) for _, k, m in ev]
    # closed form of the jump: rho_0_dot changes by J (1/m_c + 1/m_d) along rho_0 (outwards)
    y_minus = plant.flow(y_before, np.zeros(6), 1.0)  # latched flow to t = 20 s (flag still set)
    y_minus_jump = y.copy()
    y_back = plant.flow(y_minus_jump, np.zeros(6), 0.0)
    rho0 = y_minus[SL_RD] - y_minus[SL_RC]
    dv = (y_back[SL_VD] - y_back[SL_VC]) - (y_minus[SL_VD] - y_minus[SL_VC])
    expected = p.snap_impulse_Ns * (1 / p.mass_chief_kg + 1 / p.mass_deputy_kg) * rho0 / np.linalg.norm(rho0)
    assert np.allclose(dv, expected, atol=1e-12)


def test_latch_engages_inside_the_capture_envelope_only():
    x0 = _docked_truth()
    x_far = x0.copy()
    x_far[SL_RD] *= 1.1  # ports ~7 cm apart, outside the 2 cm envelope
    for x, expect in ((x0, "free -> latched"), (x_far, None)):
        plant = HybridCapturePlant(PARAMS, x)
        y, ev = plant.propagate_events(0.0, plant.initial_state(), np.zeros(6), 0.1)
        latch = [m for _, k, m in ev if k == "latch"]
        assert (latch[:1] == [expect]) if expect else not latch
        assert plant.mode(y) == ("latched" if expect else "free")


def test_measured_state_layout():
    plant = HybridCapturePlant(PARAMS, X78)
    x = plant.relative_state(plant.initial_state())
    assert x.shape == (N_MEASURED,) and x[M_CONTACTS] == 0 and x[M_LATCHED] == 0
    assert np.allclose(x[:32], relative_from_truth(X78, PARAMS, np.zeros(6)))
    assert plant.delta_v(np.array([1.2, 0, 0, 5, 5, 5]), "acceleration", 2.0) == pytest.approx(1.2 / 120 * 2)


# ------------------------------------------------------------------ supervisor
class _Zero:
    """A scripted controller (no MPC): zero command, counts its resets and collision counts."""

    def __init__(self, period_s=1.0):
        self.period_s = period_s
        self.resets, self.counts = 0, []

    def reset(self, t0, x0):
        assert len(x0) == 32
        self.resets += 1

    def set_collision_count(self, c):
        self.counts.append(c)

    def step(self, t, x):
        assert len(x) == 32
        return Command(u=np.zeros(6), kind="acceleration")


def _measured(rho_m, latched, rate=0.0):
    x = np.zeros(N_MEASURED)
    x[0] = rho_m
    x[12] = 1.0  # q = q_I
    x[6] = rate
    x[M_LATCHED] = 1.0 if latched else 0.0
    return x


def test_cases_1_to_4_with_the_dwell_timer():
    env = CaptureEnvelope()
    rule = HybridModeRule(env, release_distance_m=0.5, min_dwell_s=10.0)
    cap, post = _Zero(), _Zero()
    sup = HybridSupervisor(cap, post, rule)
    sup.reset(0.0, _measured(1.0, False))
    modes = {}
    for t in range(0, 60):
        latched = 12 <= t < 30  # latch closes at 12 s, opens at 30 s
        x = _measured(0.01 if latched else 0.3, latched)
        x[M_CONTACTS] = 2
        modes[t] = sup.step(float(t), x).mode
    assert modes[11] == CAPTURE and modes[12] == POST_CAPTURE  # Case 2 at once (dwell of capture met)
    # latch open at 30 s: the latch sensor is acted on at once (Case 4; the dwell of post-capture,
    # 18 s > T_1, is met), not when tau next reaches 0 at 32 s (issue 29)
    assert all(modes[t] == POST_CAPTURE for t in range(12, 30)) and modes[30] == CAPTURE
    assert [(a, b) for _, a, b in sup.switch_log] == [(CAPTURE, POST_CAPTURE), (POST_CAPTURE, CAPTURE)]
    assert cap.counts and set(cap.counts) == {2}  # the contact count reaches the capture MPC
    assert post.resets >= 2 and cap.resets >= 2  # reset on entry


def test_no_chattering_along_the_boundary():
    """The state is driven along the boundary of T_{0->1}: |rho| dithers across the envelope
    radius and the latch sensor flips at random every sample for 500 s. Every mode lasts at
    least T_1, so at most floor(L / T_1) + 1 switches; a single-threshold rule without dwell
    switches on nearly every crossing."""
    rng = np.random.default_rng(1)
    env = CaptureEnvelope()
    T1, L = 10.0, 500.0
    sup = HybridSupervisor(_Zero(0.5), _Zero(0.5), HybridModeRule(env, 0.5, T1))
    naive = Supervisor({CAPTURE: _AnyDim(), POST_CAPTURE: _AnyDim()},
                       Hysteresis(lambda t, x: -np.linalg.norm(x[0:3]), -env.position_m, -env.position_m,
                                  low=CAPTURE, high=POST_CAPTURE))
    sup.reset(0.0, _measured(0.02, False))
    naive.reset(0.0, _measured(0.02, False))
    times = np.arange(0.0, L, 0.5)
    for t in times:
        x = _measured(env.position_m * (1.0 + 0.2 * rng.uniform(-1, 1)), rng.uniform() < 0.5)
        sup.step(float(t), x)
        naive.step(float(t), x)
    n = len(sup.switch_log)
    assert 2 <= n <= math.floor(L / T1) + 1
    assert len(naive.switch_log) > 5 * n
    gaps = np.diff([0.0] + [t for t, _, _ in sup.switch_log])
    assert gaps.min() >= T1 - 1e-9


class _AnyDim(_Zero):
    dt = 0.5

    def reset(self, t0, x0):
        pass

    def step(self, t, x):
        return Command(u=np.zeros(6))


def test_engine_sequence_with_scripted_controllers():
    """Plant + supervisor in the engine with zero commands (no MPC): start inside the capture
    envelope, latch, post-capture after T_1, snap at 40 s, back to capture at the next tau
    expiry; every mode change and contact is an engine event, in order."""
    p = HybridParams(snap_time_s=40.0)
    x0 = _docked_truth(p)
    x0[SL_RD] *= 1.005  # a few mm apart, inside the envelope, free
    plant = HybridCapturePlant(p, x0)
    sup = HybridSupervisor(_Zero(), _Zero(), HybridModeRule(CaptureEnvelope(), 0.5, 10.0))
    res = simulate(Setup(plant=plant, controller=sup, duration_s=70.0))
    seq = [(round(t, 3), k, m) for t, k, m in res.events]
    kinds = [(k, m) for _, k, m in seq]
    i_latch = kinds.index(("latch", "free -> latched"))
    i_post = kinds.index(("mode", "capture -> post-capture"))
    i_snap = next(i for i, (k, _) in enumerate(kinds) if k == "snap")
    i_back = kinds.index(("mode", "post-capture -> capture"))
    assert i_latch < i_post < i_snap < i_back
    assert seq[i_post][0] == pytest.approx(10.0)  # minimum dwell T_1 in capture from t = 0
    assert seq[i_snap][0] == pytest.approx(40.0)
    # tau expires at 20, 30, 40 s: the snap (end of the step to 40 s) is seen by the 40 s test
    assert seq[i_back][0] == pytest.approx(40.0)
    # the latch re-arms 10 s after the snap; the pair, drifting apart at 0.56 mm/s, is still in the
    # envelope: it latches again at 50 s and the supervisor (dwell T_1 met) re-enters post-capture
    relatch = [t for t, k, m in seq[i_back:] if (k, m) == ("latch", "free -> latched")]
    redock = [t for t, k, m in seq[i_back:] if (k, m) == ("mode", "capture -> post-capture")]
    assert relatch and relatch[0] == pytest.approx(50.0, abs=0.051)
    assert redock and redock[0] == pytest.approx(50.0)
    assert res.plant_mode[0] == "free" and "latched" in res.plant_mode


# ------------------------------------------------------------------ scenario keys through the CLI
BAD = [
    ("chief.mass_kg=-1", "chief.mass_kg"),
    ("deputy.mass_kg=0", "deputy.mass_kg"),
    ("chief.dims_m=[1.0,-1.0,1.0]", "chief.dims_m"),
    ("deputy.inertia_kgm2=[[1,0,0],[0,-1,0],[0,0,1]]", "positive definite"),
    ("deputy.inertia_kgm2=[[1,0,0],[0,1,0],[0,0,3]]", "triangle inequality"),
    ("initial.q=[0.57,0.57,0.57,0]", "unit quaternion"),
    ("initial.p=[1,1,0,0]", "initial.p"),
    ("chief.port_m=[0,1,0]", "chief.port_m"),
    ("deputy.port_m=[0,0,0.5]", "deputy.port_m"),
    ("contact.restitution=1.5", "contact.restitution"),
    ("contact.restitution=-0.1", "contact.restitution"),
    ("initial.rho0_m=[0.5,0,0]", "interpenetrate"),
    ("docking.release_distance_m=0.01", "docking.release_distance_m"),
]


@pytest.mark.parametrize("setting,fragment", BAD)
def test_bad_scenario_keys_one_line_exit_2(setting, fragment):
    res = CliRunner().invoke(app, ["run", "hybrid-capture", "--set", setting, "--json"])
    assert res.exit_code == 2, res.output
    lines = [ln for ln in res.output.strip().splitlines() if ln]
    assert len(lines) == 1 and lines[0].startswith("error: ") and fragment in lines[0], res.output
    assert "Traceback" not in res.output


def test_collision_count_groups_contacts_closer_than_the_gap():
    """A deputy thrust into the chief's face bounces many times a second: every impulse is an
    event, but the collision count (eq. 80's c) only counts contacts more than
    collision_gap_s after the previous one."""
    x0 = _docked_truth()
    x0[SL_RD] *= 1.05  # ~6 cm apart, face to face, outside the latch envelope
    env = CaptureEnvelope(1e-6, 1e-6, 1e-6, 1e-6)  # no latch: keep bouncing
    from proxops.core.quaternion import quat_rotate_inverse

    push = quat_rotate_inverse(x0[19:23], -(x0[SL_RD] - x0[SL_RC]) / np.linalg.norm(x0[SL_RD] - x0[SL_RC]))
    counts = {}
    for gap in (0.0, 1.0):
        plant = HybridCapturePlant(PARAMS, x0, envelope=env, collision_gap_s=gap)
        y, events = plant.initial_state(), []
        for k in range(10):  # 1 N towards the chief for 10 s
            y, ev = plant.propagate_events(float(k), y, np.concatenate([push, np.zeros(3)]), 1.0)
            events += ev
        times = [t for t, kind, _ in events if kind == "contact"]
        assert len(times) > 3
        expected = 1 + int(np.sum(np.diff(times) > gap))
        counts[gap] = plant.relative_state(y)[M_CONTACTS]
        assert counts[gap] == expected
    assert counts[1.0] < counts[0.0]


# ------------------------------------------------------------------ end to end with the MPCs
SHORT = ["sim.duration_s=40", "initial.rho0_m=[-0.94,0,0]", "initial.rho0_dot_mps=[0,-0.002256,-0.002256]",
         "initial.omega_c_rad_s=[-0.0024,0.0024,-0.0024]",
         "latch.snap=true", "latch.snap_time_s=20", "docking.min_dwell_s=5", "latch.rearm_delay_s=5",
         # judged at the end of 40 s: the tumble cannot be damped to the default 0.05 deg/s that soon
         # (success is an end-state verdict, issue 29); exact states keep this sequence test deterministic
         "success.chief_rate_max_deg_s=2.0", "estimation.model=exact"]


def test_short_sequence_end_to_end_with_the_mpcs():
    """hybrid-capture-gentle with the eq. 78 chief tumble, started 1.5 cm from the chief's port
    (aligned, co-moving): latch,
    post-capture MPC, the latch snap at 20 s, decoupling, capture MPC, re-latch, post-capture
    again; the events come in that order and the summary says so. (The contact part of §VII is
    covered by the contact tests above and the slow full run.)"""
    from proxops.analysis.runs import execute
    from proxops.scenarios.loader import load_scenario

    s, results = execute(load_scenario("hybrid-capture-gentle", SHORT))
    res = results["run"]
    kinds = [(k, m) for _, k, m in res.events if k in ("latch", "mode", "snap")]
    order = [("latch", "free -> latched"), ("mode", "capture -> post-capture"), ("snap", None),
             ("mode", "post-capture -> capture"), ("latch", "free -> latched"), ("mode", "capture -> post-capture")]
    i = 0
    for k, m in kinds:
        if i < len(order) and k == order[i][0] and (order[i][1] is None or m == order[i][1]):
            i += 1
    assert i == len(order), kinds
    assert s["docked"] and s["decoupled"] and s["redocked"] and s["status"] == "redocked"
    assert s["dock_time_s"] == pytest.approx(5.0) and s["decouple_time_s"] >= 20.0
    assert [c["to"] for c in s["mode_changes"]] == ["post-capture", "capture", "post-capture"]
    assert s["contacts"] == [] and s["solve_time_ms"]["median"] > 0.0
    # the latched pair holds: |rho| stays within the capture envelope's 2 cm while latched
    latched = np.array(res.plant_mode) == "latched"
    assert np.linalg.norm(res.x_true[latched, 0:3], axis=1).max() < 0.02


@pytest.mark.slow
def test_full_section_vii_sequence():
    """§VII: contact(s) before docking, docking, tumble damped, mm-level tracking, decoupling
    after the snap, re-docking, tracking resumed (800 s). With exact states (hybrid-capture-exact)
    the whole sequence holds, the tumble damped below 10 % of its start. On the estimator
    (hybrid-capture, the default) every step but the damping holds; the tumble ends at ~0.14 deg/s
    (it wanders 0.04-0.14 deg/s between 1100 and 2000 s: not damped), and the status must say so."""
    from proxops.analysis.runs import execute
    from proxops.scenarios.loader import load_scenario

    for name in ("hybrid-capture-exact", "hybrid-capture"):
        s, _ = execute(load_scenario(name))
        assert s["contacts_before_dock"] >= 1 and s["docked"] and s["first_contact_s"] < s["dock_time_s"]
        assert s["decoupled"] and s["decouple_time_s"] >= 593.0 and s["redocked"]
        assert s["tracking_error_last_100s_max_m"] < 5e-3
        if name == "hybrid-capture-exact":
            assert s["chief_rate_final_deg_s"] < 0.1 * s["chief_rate_initial_deg_s"] and s["success"]
        elif s["chief_rate_final_deg_s"] >= 0.05:  # the success threshold of the hybrid status
            assert s["status"].startswith("failed: spinning") and not s["success"]


def test_run_figures_are_written(tmp_path):
    """Figs. 5-9 from a short scripted run (no MPC): five non-empty PNGs."""
    from proxops.plotting.hybrid import run_figures

    p = HybridParams(snap_time_s=20.0)
    x0 = _docked_truth(p)
    plant = HybridCapturePlant(p, x0)
    sup = HybridSupervisor(_Zero(), _Zero(), HybridModeRule(CaptureEnvelope(), 0.5, 5.0))
    res = simulate(Setup(plant=plant, controller=sup, duration_s=40.0))

    class _Sc:
        name = "scripted"

    paths = run_figures(_Sc(), {"run": res}, tmp_path)
    assert len(paths) == 5 and all(p.exists() and p.stat().st_size > 10_000 for p in paths)
