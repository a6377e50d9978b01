"""The cortex planner's eclipse profile memoised on disk (issue 32, `cortex references` start-up): the stored
profile is the computed one bit for bit, is keyed by its inputs, is read without computing (no numba, no
ephemeris), and its eclipse intervals agree with a direct geometric shadow check of an independently
integrated orbit and erfa's Sun."""

import math

import erfa
import numpy as np
import pytest
from scipy.integrate import solve_ivp

from proxops.core.constants import MU_EARTH, R_EARTH
from proxops.environment import disk_memo
from proxops.environment.epochs import parse_epoch
from proxops.frames.elements import elements_to_eci, orbital_period
from proxops.scenarios.loader import load_scenario
from proxops.systems import cortex_setup
from proxops.systems.schema._build_free import target_elements


@pytest.fixture
def memo(tmp_path, monkeypatch):
    monkeypatch.setattr(disk_memo, "memo_dir", lambda: str(tmp_path))
    monkeypatch.setenv("PROXOPS_SETUP_CACHE", "1")
    monkeypatch.setattr(cortex_setup, "_PROFILES", {})
    return tmp_path


def _direct(sc):
    from proxops.environment.eclipse import eclipse_profile

    e = sc.eclipse
    return eclipse_profile(target_elements(sc.orbit), sc.orbit.epoch_utc, n_per_orbit=e.samples_per_orbit,
                           n_orbits=e.orbits, model=e.model)


def test_stored_profile_is_the_computed_one_and_is_read_without_computing(memo, monkeypatch):
    sc = load_scenario("cortex-reference").scenario
    t_ref, ill_ref = _direct(sc)
    t1, eta1 = cortex_setup.eclipse_profile(sc)
    assert len(list(memo.glob("eclipse-*.npy"))) == 1
    np.testing.assert_array_equal(t1, t_ref)
    np.testing.assert_array_equal(eta1, (ill_ref >= sc.eclipse.sunlit_threshold).astype(eta1.dtype))
    # a new process (empty per-process cache) reads the file: the computation must not run
    import proxops.environment.eclipse as eclipse_module

    def forbidden(*_a, **_k):
        raise AssertionError("the stored profile was recomputed")

    monkeypatch.setattr(eclipse_module, "eclipse_profile", forbidden)
    monkeypatch.setattr(cortex_setup, "_PROFILES", {})
    t2, ill2 = cortex_setup.illumination_profile(sc.orbit, sc.eclipse)
    np.testing.assert_array_equal(t2, t_ref)
    np.testing.assert_array_equal(ill2, ill_ref)


def test_another_epoch_or_model_is_another_entry(memo):
    sc = load_scenario("cortex-reference").scenario
    cortex_setup.illumination_profile(sc.orbit, sc.eclipse)
    for over in (['orbit.epoch_utc="2022-11-01T00:00:00"'], ["eclipse.model=cylindrical"], ["eclipse.orbits=2.0"]):
        other = load_scenario("cortex-reference", over).scenario
        t, ill = cortex_setup.illumination_profile(other.orbit, other.eclipse)
        t_ref, ill_ref = _direct(other)
        np.testing.assert_array_equal(t, t_ref)
        np.testing.assert_array_equal(ill, ill_ref)
    assert len(list(memo.glob("eclipse-*.npy"))) == 4


def test_profile_eclipses_agree_with_a_direct_shadow_geometry_check(memo):
    # Independent: the orbit integrated as a two-body ODE from the osculating state, the Sun from erfa's epv00
    # (not the fitted series), and the shadow as geometry: at the CSO's radius the umbra/penumbra boundaries lie
    # within R_E tan(0.27 deg) * (r/R_E) ~ 33 km of the shadow cylinder's wall, so a sample more than 40 km inside
    # the cylinder (behind the Earth) must be eclipsed and one more than 40 km outside it (or sunward) sunlit.
    sc = load_scenario("cortex-reference").scenario
    t, eta = cortex_setup.eclipse_profile(sc)
    el = target_elements(sc.orbit)
    sol = solve_ivp(lambda _t, y: np.concatenate([y[3:], -MU_EARTH * y[:3] / np.linalg.norm(y[:3]) ** 3]),
                    (0.0, float(t[-1])), elements_to_eci(el), t_eval=t, rtol=1e-11, atol=1e-6, method="DOP853")
    r = sol.y[:3].T
    ep = parse_epoch(sc.orbit.epoch_utc)
    s_hat = np.empty((len(t), 3))
    for k, tk in enumerate(t):
        pvh, _ = erfa.epv00(2451545.0, ep.days_tt_since_j2000(float(tk)))
        s_hat[k] = -pvh[0] / np.linalg.norm(pvh[0])
    along = np.sum(r * s_hat, axis=1)
    perp = np.linalg.norm(r - along[:, None] * s_hat, axis=1)
    margin = 40e3
    deep = (along < 0) & (perp < R_EARTH - margin)
    clear = (along >= 0) | (perp > R_EARTH + margin)
    assert deep.sum() > 0.25 * len(t)  # the CSO on 2022-05-01 spends about a third of each orbit in shadow
    assert np.all(eta[deep] == 0)
    assert np.all(eta[clear] == 1)
    # the samples left undecided are the boundary crossings only: two per orbit, each a few samples wide
    n_orbits = float(t[-1]) / orbital_period(el.sma)
    assert (~deep & ~clear).sum() <= 2 * math.ceil(n_orbits) * 10
