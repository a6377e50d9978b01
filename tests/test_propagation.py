"""Truth propagation: two-body + J2 with Encke relative state, fast (numba DOP853) and
reference (scipy DOP853) paths, CW plant, free drift.

Independent references: DOP853 tableau of scipy and Runge-Kutta order conditions,
40-digit decimal arithmetic for differential gravity, invariants (energy, z angular
momentum), the textbook J2 nodal rate, a derived bound on the CW linearisation error,
and the closed-form CW solution."""

import math
from decimal import Decimal, getcontext

import numpy as np
import pytest

from proxops.core.constants import J2_EARTH, MU_EARTH, R_EARTH
from proxops.core.cw import cw_discretize_zoh, cw_stm
from proxops.core.twobody import accel_differential_vec, accel_j2
from proxops.environment.gravity import J2Gravity, j2_raan_rate
from proxops.errors import ProxopsInputError
from proxops.frames.elements import OrbitalElements, circular_orbit, eci_to_elements, elements_to_eci, orbital_period
from proxops.frames.hill import eci_offset_to_hill
from proxops.propagation import kernels
from proxops.propagation.truth import CWPlant, RelativeTruth, propagate_free_drift
from proxops.contracts import Plant

ISS_LIKE = circular_orbit(altitude=500e3, inc=math.radians(51.6), raan=0.3, arg_lat=0.2)
PERIOD = orbital_period(ISS_LIKE.sma)
N = math.sqrt(MU_EARTH / ISS_LIKE.sma**3)


# ----------------------------------------------------------------------------- kernels
def test_dop853_tableau_matches_scipy_and_order_conditions():
    from scipy.integrate._ivp import dop853_coefficients as ref

    assert np.array_equal(kernels.A[: kernels.N_STAGES, :], ref.A[: kernels.N_STAGES, : kernels.N_STAGES])
    assert np.array_equal(kernels.B, ref.B)
    assert np.array_equal(kernels.C, ref.C[: kernels.N_STAGES])
    assert np.array_equal(kernels.E3, ref.E3) and np.array_equal(kernels.E5, ref.E5)
    # row sums give the nodes; quadrature order conditions sum b c^k = 1/(k+1), k <= 7
    assert np.allclose(kernels.A[: kernels.N_STAGES].sum(axis=1), kernels.C, atol=1e-14)
    for k in range(8):
        assert math.isclose(float(kernels.B @ kernels.C**k), 1.0 / (k + 1), rel_tol=1e-13)


def test_dop853_dense_output_tableau_matches_scipy():
    """The continuous extension (three extra stages, the matrix D) is scipy's (Hairer's contd8)."""
    from scipy.integrate._ivp import dop853_coefficients as ref

    assert np.array_equal(kernels.A_EXTRA, ref.A[kernels.N_STAGES + 1:])
    assert np.array_equal(kernels.D, ref.D)
    # Extended stages: row sums are the extra nodes c = 1 (FSAL), 0.1, 0.2, 7/9
    assert np.allclose(kernels.A_EXTRA.sum(axis=1), ref.C[kernels.N_STAGES + 1:], atol=1e-14)


def test_dense_free_drift_matches_a_step_per_sample_and_costs_the_tolerances_steps():
    """integrate_dense (own steps + dense output) against integrate_grid, which lands a step on every
    10 s sample (steps 25x shorter than the tolerance needs, so its samples are the accurate ones):
    a radial 0.3 m/s hop at 2 km under J2 over 3 orbits agrees within 0.2 mm (position) and 1e-7
    m/s (velocity) at all 2 161 samples, with at most 1/15 of the steps; the last sample is the last
    step's end, repeated samples and a sample at the start are exact."""
    p = np.array([MU_EARTH, J2_EARTH, R_EARTH])
    truth = RelativeTruth(ISS_LIKE, np.array([0.0, 2000.0, 0.0, 0.3, 0.0, 0.0]), j2=True)
    y0 = truth.initial_state()
    times = np.linspace(0.0, 3 * PERIOD, 2161)
    fine = np.empty((times.size, 12))
    _, n_fine, _ = kernels.integrate_grid(y0, times, np.zeros(3), p, truth.rtol, truth.atol, fine)
    dense = np.empty((times.size, 12))
    status, n_dense, _ = kernels.integrate_dense(y0, times, np.zeros(3), p, truth.rtol, truth.atol, dense)
    assert status == kernels.STATUS_OK and n_fine == 2160 and n_dense * 15 < n_fine
    a = np.array([kernels.hill_from_y(v, p) for v in fine])
    b = truth.free_drift(y0, times)
    assert np.abs(a[:, :3] - b[:, :3]).max() < 2e-4 and np.abs(a[:, 3:] - b[:, 3:]).max() < 1e-7
    assert np.linalg.norm(a[:, :3] - a[0, :3], axis=1).max() > 1000.0  # it moved (a radial hop: ~2.4 km out)
    # a repeated sample time and the start: the same numbers
    rep = np.array([0.0, 0.0, 100.0, 100.0, 3 * PERIOD])
    out = np.empty((5, 12))
    kernels.integrate_dense(y0, rep, np.zeros(3), p, truth.rtol, truth.atol, out)
    assert np.array_equal(out[0], y0) and np.array_equal(out[1], y0) and np.array_equal(out[2], out[3])
    one = np.empty((2, 12))
    kernels.integrate_dense(y0, np.array([0.0, 3 * PERIOD]), np.zeros(3), p, truth.rtol, truth.atol, one)
    assert np.allclose(out[-1], one[-1], rtol=1e-9, atol=1e-6)


def test_hill_conversion_frame_rate_closed_form_matches_its_definition():
    """kernels.hill_from_y takes the J2 frame rate in closed form, w_x = -3 J2 mu Re^2 z h_z / (r^4 |h|^2);
    its definition is w_x = r (a . h) / |h|^2 with the full two-body + J2 acceleration a (frames.hill, numpy,
    J2Gravity's own acceleration). 300 random targets (i 0-180 deg, r 6 600-42 000 km, eccentric velocities)
    and chasers up to 20 km: the Hill states agree to 1e-12 m and 1e-14 m/s plus 1e-12 relative, and at
    ISS-like inclinations the w_x term moves the Hill velocity by more than 1e-6 m/s (it is exercised)."""
    p = np.array([MU_EARTH, J2_EARTH, R_EARTH])
    grav = J2Gravity()
    rng = np.random.default_rng(7)
    biggest_term = 0.0
    for _ in range(300):
        inc, u, r = rng.uniform(0.0, math.pi), rng.uniform(0.0, 2 * math.pi), rng.uniform(6.6e6, 4.2e7)
        pos = r * np.array([math.cos(u), math.sin(u) * math.cos(inc), math.sin(u) * math.sin(inc)])
        along = np.array([-math.sin(u), math.cos(u) * math.cos(inc), math.cos(u) * math.sin(inc)])
        vel = math.sqrt(MU_EARTH / r) * (along * rng.uniform(0.9, 1.1) + pos / r * rng.uniform(-0.1, 0.1))
        target = np.concatenate([pos, vel])
        offset = np.concatenate([rng.uniform(-2e4, 2e4, 3), rng.uniform(-5.0, 5.0, 3)])
        y = np.concatenate([target, offset])
        got = kernels.hill_from_y(y, p)
        ref = eci_offset_to_hill(target, offset, grav.acceleration(pos))
        assert np.abs(got[:3] - ref[:3]).max() <= 1e-12 + 1e-12 * np.abs(ref[:3]).max()
        assert np.abs(got[3:] - ref[3:]).max() <= 1e-14 + 1e-12 * np.abs(ref[3:]).max()
        kepler_only = eci_offset_to_hill(target, offset)
        biggest_term = max(biggest_term, float(np.abs(kepler_only[3:] - ref[3:]).max()))
    assert biggest_term > 1e-6


def _decimal_gravity(r):
    getcontext().prec = 40
    x, y, z = (c if isinstance(c, Decimal) else Decimal(repr(float(c))) for c in r)
    r2 = x * x + y * y + z * z
    k = -Decimal(repr(MU_EARTH)) / (r2 * r2.sqrt())
    return np.array([k * x, k * y, k * z])


@pytest.mark.parametrize("offset", [[100.0, -50.0, 20.0], [1e-3, 2e-3, -1e-3], [3e3, 8e3, -1e3]])
def test_differential_gravity_has_no_cancellation(offset):
    """Encke/Battin two-body difference vs 40-digit decimal arithmetic."""
    r_t = elements_to_eci(ISS_LIKE)[:3]
    dr = np.array(offset)
    r_c = [Decimal(repr(float(a))) + Decimal(repr(float(b))) for a, b in zip(r_t, dr)]
    ref = (_decimal_gravity(r_c) - _decimal_gravity(r_t)).astype(float)
    got = accel_differential_vec(r_t, dr, MU_EARTH, 0.0, R_EARTH)
    assert np.linalg.norm(got - ref) <= 1e-12 * np.linalg.norm(ref)
    # the J2 part is the plain difference of J2 accelerations
    with_j2 = accel_differential_vec(r_t, dr, MU_EARTH, J2_EARTH, R_EARTH)
    j2_diff = np.array(accel_j2(*(r_t + dr), MU_EARTH, J2_EARTH, R_EARTH)) - np.array(
        accel_j2(*r_t, MU_EARTH, J2_EARTH, R_EARTH)
    )
    assert np.allclose(with_j2 - got, j2_diff, rtol=1e-6, atol=1e-20)


# ----------------------------------------------------------------------------- invariants
def test_energy_and_z_angular_momentum_conserved_under_j2():
    el = OrbitalElements(R_EARTH + 700e3, 0.02, math.radians(63.0), 1.0, 0.5, 0.0)
    truth = RelativeTruth(el, [300.0, -2000.0, 500.0, 0.3, -0.2, 0.4], j2=True)
    grav = J2Gravity()
    y0 = truth.initial_state()
    y1 = truth.propagate(0.0, y0, None, 5 * orbital_period(el.sma))
    tgt0, tgt1, ch0, ch1 = y0[:6], y1[:6], y0[:6] + y0[6:], y1[:6] + y1[6:]
    for a, b in ((tgt0, tgt1), (ch0, ch1)):
        e0, e1 = grav.specific_energy(a), grav.specific_energy(b)
        hz0 = a[0] * a[4] - a[1] * a[3]
        hz1 = b[0] * b[4] - b[1] * b[3]
        assert abs(e1 - e0) < 1e-9 * abs(e0)
        assert abs(hz1 - hz0) < 1e-9 * abs(hz0)
    # and J2 really acts: the total angular momentum direction moved
    h0 = np.cross(tgt0[:3], tgt0[3:])
    h1 = np.cross(tgt1[:3], tgt1[3:])
    assert np.degrees(np.arccos(h0 @ h1 / np.linalg.norm(h0) / np.linalg.norm(h1))) > 0.5


def test_raan_drift_matches_textbook_j2_rate():
    """Secular node regression dRAAN/dt = -3/2 n J2 (Re/p)^2 cos i
    (Vallado 4th ed. eq. 9-41; Curtis eq. 4.52). Linear fit of the osculating RAAN over
    one day (short-period terms average out); agreement to 1 % (the formula uses mean
    elements, we start from osculating ones: O(J2) ~ 0.3 % difference)."""
    el = ISS_LIKE
    truth = RelativeTruth(el, np.zeros(6), j2=True)
    day = 86400.0
    times = np.linspace(0.0, day, 2001)
    ys = np.empty((times.size, 12))
    status, _, _ = kernels.integrate_grid(truth.initial_state(), times, np.zeros(3), truth.params, 1e-10, 1e-12, ys)
    assert status == 0
    raan = np.unwrap([eci_to_elements(y[:6]).raan for y in ys])
    slope = np.polyfit(times, raan, 1)[0]
    n = math.sqrt(MU_EARTH / el.sma**3)
    p = el.sma * (1 - el.ecc**2)
    textbook = -1.5 * n * J2_EARTH * (R_EARTH / p) ** 2 * math.cos(el.inc)
    assert math.isclose(j2_raan_rate(el.sma, el.ecc, el.inc), textbook, rel_tol=1e-14)
    assert abs(slope / textbook - 1.0) < 0.01


# ----------------------------------------------------------------------------- accuracy
def test_fast_path_matches_reference_after_one_orbit_with_control_and_impulse():
    x0 = [50.0, 300.0, -40.0, 0.05, -0.1, 0.02]
    fast = RelativeTruth(ISS_LIKE, x0, j2=True, integrator="fast")
    ref = RelativeTruth(ISS_LIKE, x0, j2=True, integrator="reference")
    u = np.array([2e-5, -1e-5, 5e-6])
    yf, yr = fast.initial_state(), ref.initial_state()
    yf = fast.apply_impulse(0.0, yf, [0.01, 0.0, -0.02])
    yr = ref.apply_impulse(0.0, yr, [0.01, 0.0, -0.02])
    yf = fast.propagate(0.0, yf, u, 0.5 * PERIOD)
    yr = ref.propagate(0.0, yr, u, 0.5 * PERIOD)
    yf = fast.propagate(0.0, yf, None, 0.5 * PERIOD)
    yr = ref.propagate(0.0, yr, None, 0.5 * PERIOD)
    d = fast.relative_state(yf) - ref.relative_state(yr)
    assert np.linalg.norm(d[:3]) < 1e-6  # m (measured ~1e-10)
    assert np.linalg.norm(d[3:]) < 1e-9  # m/s


def test_many_short_steps_match_one_long_step():
    truth = RelativeTruth(ISS_LIKE, [0.0, 200.0, 10.0, 0.0, 0.0, 0.01], j2=True)
    y = truth.initial_state()
    for _ in range(600):
        y = truth.propagate(0.0, y, np.zeros(3), 5.0)
    y_long = truth.propagate(0.0, truth.initial_state(), None, 3000.0)
    assert np.linalg.norm(truth.relative_state(y) - truth.relative_state(y_long)) < 1e-7


def test_initial_relative_state_and_impulse_are_exact():
    x0 = np.array([12.0, -340.0, 7.0, 0.01, 0.2, -0.03])
    truth = RelativeTruth(ISS_LIKE, x0, j2=True)
    y = truth.initial_state()
    assert np.allclose(truth.relative_state(y), x0, atol=1e-12)
    dv = np.array([0.1, -0.2, 0.05])
    y2 = truth.apply_impulse(0.0, y, dv)
    assert np.allclose(truth.relative_state(y2) - truth.relative_state(y), np.r_[0, 0, 0, dv], atol=1e-13)
    assert np.array_equal(y2[:6], y[:6])  # target untouched
    moved = truth.with_relative_state(y, [1.0, 2.0, 3.0, 0.0, 0.0, 0.0])
    assert np.allclose(truth.relative_state(moved), [1, 2, 3, 0, 0, 0], atol=1e-12)
    # the numba Hill extraction agrees with the numpy frames module
    a_t = J2Gravity().acceleration(y[:3])
    assert np.allclose(eci_offset_to_hill(y[:6], y[6:], a_t), truth.relative_state(y), atol=1e-12)


def test_co_located_chaser_stays_co_located():
    truth = RelativeTruth(ISS_LIKE, np.zeros(6), j2=True)
    y = truth.propagate(0.0, truth.initial_state(), None, PERIOD)
    assert np.array_equal(truth.relative_state(y), np.zeros(6))


def test_zoh_hill_acceleration_matches_cw_at_small_range():
    """Constant Hill acceleration from rest at the target: nonlinear truth == CW ZOH
    (range stays < 10 m, CW linearisation error ~ 3 n^2 rho^2 / r t^2 < 1e-9 m)."""
    truth = RelativeTruth(ISS_LIKE, np.zeros(6), j2=False)
    u = np.array([1e-4, -2e-4, 3e-4])
    dt = 200.0
    y = truth.propagate(0.0, truth.initial_state(), u, dt)
    Ad, Bd = cw_discretize_zoh(N, dt)
    assert np.allclose(truth.relative_state(y), Bd @ u, atol=1e-8)


def test_nonlinear_relative_motion_agrees_with_cw_to_derived_order():
    """Two-body, circular target, ~100 m separation, one orbit.

    Derivation: with Hill position rho and target radius r, the exact relative
    acceleration is CW plus d2 + O(rho^3 / r^2) with the quadratic term
    d2 = (n^2 / r) [-3 x^2 + 3/2 (y^2 + z^2), 3 x y, 3 x z], |d2| <= 3 n^2 rho^2 / r.
    The CW error e obeys e' = A e + [0; d2], so |e_pos(T)| <= int_0^T ||Phi_rv(T - s)|| ds
    * 3 n^2 rho_max^2 / r, with Phi_rv the position-from-velocity block of the CW STM.
    Also the error is quadratic in the separation: doubling rho quadruples it."""
    r = ISS_LIKE.sma
    x0 = np.array([30.0, 100.0, -20.0, 0.02, -0.06, 0.03])

    def cw_error(scale):
        truth = RelativeTruth(ISS_LIKE, scale * x0, j2=False)
        y = truth.propagate(0.0, truth.initial_state(), None, PERIOD)
        return truth.relative_state(y) - cw_stm(N, PERIOD) @ (scale * x0)

    err = np.linalg.norm(cw_error(1.0)[:3])
    s = np.linspace(0.0, PERIOD, 2001)
    rho_max = max(np.linalg.norm((cw_stm(N, t) @ x0)[:3]) for t in s)
    gain = np.trapezoid([np.linalg.norm(cw_stm(N, PERIOD - t)[:3, 3:], 2) for t in s], s)
    bound = gain * 3 * N**2 * rho_max**2 / r
    assert 1e-3 < err < bound  # nonlinearity visible, and within the derived bound
    ratio = np.linalg.norm(cw_error(2.0)[:3]) / err
    assert ratio == pytest.approx(4.0, rel=0.02)


# ----------------------------------------------------------------------------- plants
def test_plants_satisfy_protocol_and_cw_plant_is_exact():
    x0 = np.array([10.0, -500.0, 3.0, 0.0, 0.01, 0.0])
    cw = CWPlant(N, x0)
    truth = RelativeTruth(ISS_LIKE, x0)
    assert isinstance(cw, Plant) and isinstance(truth, Plant)
    assert truth.n_x == cw.n_x == 6 and truth.n_u == cw.n_u == 3
    u = np.array([1e-5, 2e-5, -1e-5])
    Ad, Bd = cw_discretize_zoh(N, 10.0)
    assert np.allclose(cw.propagate(0.0, x0, u, 10.0), Ad @ x0 + Bd @ u, rtol=1e-14)
    assert np.allclose(cw.apply_impulse(0.0, x0, [1, 2, 3]), x0 + [0, 0, 0, 1, 2, 3])
    assert CWPlant.from_orbit(ISS_LIKE, x0).mean_motion == pytest.approx(N)


def test_free_drift_sampling():
    x0 = np.array([0.0, 100.0, 0.0, 0.05, 0.0, 0.0])
    truth = RelativeTruth(ISS_LIKE, x0, j2=False)
    cw = CWPlant(N, x0)
    rel = propagate_free_drift(truth, truth.initial_state(), PERIOD, 50)
    rel_cw = propagate_free_drift(cw, x0, PERIOD, 50)
    assert rel.shape == rel_cw.shape == (50, 6)
    assert np.allclose(rel[0], x0, atol=1e-12) and np.allclose(rel_cw[0], x0)
    times = np.linspace(0, PERIOD, 50)
    assert np.allclose(rel_cw, [cw_stm(N, t) @ x0 for t in times])
    assert np.max(np.abs(rel[:, :3] - rel_cw[:, :3])) < 1.0  # within the CW bound above
    # sampled path equals step-by-step propagation of the same plant
    y = truth.initial_state()
    for k in range(1, 50):
        y = truth.propagate(0.0, y, None, times[k] - times[k - 1])
    assert np.allclose(truth.relative_state(y), rel[-1], atol=1e-7)
    # generic fallback (plant without free_drift)

    class Bare:
        n_x, n_u = 6, 3
        relative_state = staticmethod(cw.relative_state)
        propagate = staticmethod(cw.propagate)

    assert np.allclose(propagate_free_drift(Bare(), x0, PERIOD, 50), rel_cw, atol=1e-9)


def test_truth_input_errors():
    with pytest.raises(ProxopsInputError, match="chaser_hill"):
        RelativeTruth(ISS_LIKE, [0, np.nan, 0, 0, 0, 0])
    with pytest.raises(ProxopsInputError, match="perigee"):
        RelativeTruth(OrbitalElements(R_EARTH + 100e3, 0.1, 0, 0, 0, 0), np.zeros(6))
    with pytest.raises(ProxopsInputError, match="integrator"):
        RelativeTruth(ISS_LIKE, np.zeros(6), integrator="rk4")
    truth = RelativeTruth(ISS_LIKE, np.zeros(6))
    with pytest.raises(ProxopsInputError, match="dt"):
        truth.propagate(0.0, truth.initial_state(), None, -1.0)
    with pytest.raises(ProxopsInputError, match="u shape"):
        truth.propagate(0.0, truth.initial_state(), [1.0, 2.0], 1.0)
    with pytest.raises(ProxopsInputError, match="mean_motion"):
        CWPlant(-1.0, np.zeros(6))
    # an ECI target state works as well as elements
    same = RelativeTruth(elements_to_eci(ISS_LIKE), np.zeros(6))
    assert np.allclose(same.initial_state(), truth.initial_state())
