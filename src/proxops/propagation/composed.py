"""High-fidelity relative truth: the enabled force models composed once per run.

:class:`ForceModels` says what is on (point mass always; ``gravity`` = "point" | "j2" |
"harmonics" with degree/order; drag; Sun; Moon; SRP) and with which spacecraft and
space weather. :class:`ComposedTruth` is a Plant (:mod:`proxops.contracts`) like
:class:`proxops.propagation.truth.RelativeTruth`, with the chaser propagated relative to
the target in Encke form and every perturbation evaluated at both spacecraft and
differenced (:mod:`proxops.propagation.kernels_full`).

Full state (13,): ``[r_t, v_t, dr, dv, t]`` -- the 12-state of RelativeTruth plus the time
since the epoch (s), because the forces depend on absolute time.

Integrators (density from a NRLMSISE-00 table along the target's predicted path on the numba
paths): ``"dop853"`` (numba adaptive DOP853), ``"multistep"`` (numba fixed-step
Adams-Bashforth-Moulton PECE, order 6 / 7, 18 s steps, harmonics once per step with a
look-ahead quadrature; :mod:`proxops.propagation.kernels_multistep`, whose doc has the
order/step measurement), ``"fast"`` (the default: multistep with
spherical harmonics and without SRP on spans of at least MIN_STEPS * order steps (324 s),
DOP853 otherwise: for point mass / J2, which stay bit-identical to RelativeTruth, and with
SRP, whose shadow boundary the fixed step cannot follow) and ``"reference"`` (scipy DOP853
on the same RHS, with pymsis called at both spacecraft on every evaluation). The J2-only and
two-body truths stay in RelativeTruth (the fastest path, unchanged).

With SRP both DOP853 paths restart at every shadow crossing of either spacecraft (penumbra
and umbra boundaries, :func:`proxops.environment.eclipse.shadow_boundaries`): the numba loop
locates them on each step's Hermite interpolant (:mod:`proxops.propagation.kernels_full`),
the reference path with scipy's event search, redoing the step over the crossing. Without
it a step over a crossing made the result depend on where the steps fell (20 km, 20x20 +
Sun/Moon + SRP, one orbit: 0.27-0.82 mm for rtol x 0.8-1.25 and the reference path 0.5-2.8 mm
off the converged solution; now 1-2 um and 4-6 um). Cost with SRP: 877 instead of 553
right-hand sides per orbit (20x20), 1801 instead of 1561 (100x100).

Multistep vs DOP853 (benchmarks/bench_truth.py; 100x100 + drag + Sun/Moon, A/m 0.004 /
0.015 m^2/kg, relative position vs numba DOP853 at rtol 1e-13): the default (order 6, 18 s,
look-ahead) takes 668 evaluations of the 100x100 field per orbit against DOP853's 3122 at the
default rtol, and stays below 0.08 mm at 20 km over two orbits in 15 geometries; the former
default (order 6, 20 s, no look-ahead, 580 evaluations) reached 17.5 mm there (0.06 mm at the bench's
geometry); timings in the README and kernels_multistep's doc.
The field at target and chaser is one call of the two-point kernel (harmonics.py,
accel_harmonics_pair; bit-identical results): measured 2026-11-23 at load 4.6-6.9 on 2 cores
with the former default, one orbit 7.9-13.2 ms against 12.9-24.7 ms with one point per call
(README).

Measured (tests/test_propagation_composed.py, benchmarks/bench_truth.py; 500 km, 51.6 deg,
2022-05-01, one orbit, default rtol 3e-11): fast path vs scipy DOP853 on both absolute
states 0.002 mm at 100 m, 0.006 mm at 2 km, 0.07 mm at 20 km (100x100 + Sun/Moon + SRP,
the absolute integration piecewise between the shadow crossings at rtol 1e-13, whose own
error is part of it: 0.16 mm at 20 km against rtol 3e-14; measured 2026-11-27); fast
(density table) vs reference (direct NRLMSISE-00) with drag + Sun/Moon + SRP and different
A/m: 0.035 mm at 2 km, 0.045 mm at 20 km ahead + 4 km radial + 2 km cross-track (2026-11-27,
both paths restarting at the shadow crossings; 0.03 / 0.10 mm without). pymsis computes in single
precision (float32, ~1e-6..1e-5 relative noise in density), which bounds the latter
comparison. Against Orekit 13 with matching models, two orbits (tests/orekit_reference.py):
<= 0.29 mm at 2 km, <= 3.1 mm at 20 km for every model set, mostly Earth orientation (README, "Validation against Orekit").

Note: ``gravity="j2"`` is RelativeTruth's zonal J2 about the ECI (J2000) z axis; the
pole of date is 0.12 deg away in 2022, which changes the relative motion by ~18 mm over
two orbits at 100 m (measured against Orekit). ``gravity="harmonics"`` with degree 2,
order 0 uses the pole of date.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from proxops.core.constants import J2_EARTH, KARMAN_LINE_KM, MU_EARTH, OMEGA_EARTH, R_EARTH
from proxops.core.memo import memo_get
from proxops.environment.earth import WGS84_A, earth_rotation, geodetic_height
from proxops.environment.eclipse import shadow_boundaries
from proxops.environment.ephemeris import AU, GM_MOON, GM_SUN, N_FIT, R_SUN, cached_third_body_fit, fitted_position
from proxops.environment.epochs import Epoch, check_time_range, parse_epoch
from proxops.environment.forces import Atmosphere, Spacecraft, SpaceWeather
from proxops.environment.harmonics import SphericalHarmonics, check_degree_order
from proxops.errors import PlantEnded, ProxopsError, input_error
from proxops.frames.elements import OrbitalElements, check_perigee_above_surface, eci_to_elements, elements_to_eci
from proxops.propagation import kernels, kernels_full as kf, kernels_multistep as km
from proxops.propagation.full_setup import DENSITY_MARGIN_S, DENSITY_STEP_S, density_table
from proxops.propagation.reference import REFERENCE_ATOL
from proxops.propagation.truth import RelativeTruth
from proxops.dynamics.plant import PlantBase

REENTRY_SCREEN = 1e-3  # relative margin of the re-entry check's screen (1 - cos(0.2 deg) = 6e-6; see _end_if_reentering)
DECAYING_ALTITUDE_KM = 150.0  # km: an integrator failure below this height is the end of a decay (a run ends there)
# Default relative tolerance of the composed truth: 3e-11, a third of a decade below
# RelativeTruth's. Measured (one orbit, 100x100 + Sun/Moon, 20 km separation, relative
# position vs the same loop at rtol 1e-13): 0.06 mm at 3e-11 with the loop's safety factor
# 0.8 (0.09 mm at 1e-11 and 0.8 mm at 1e-10 with the former 0.9).
FULL_RTOL = 3e-11
GRAVITY = ("point", "j2", "harmonics")
_FIELD_CACHE: dict = {}  # (degree, order) -> SphericalHarmonics (its C, S, K are only read)
INTEGRATORS = ("fast", "dop853", "multistep", "reference")
SHADOW = ("conical", "cylindrical")


@dataclass(frozen=True)
class ForceModels:
    """Which perturbations act, for one target/chaser pair (validated on construction)."""

    epoch: str = "2022-05-01T00:00:00Z"
    gravity: str = "harmonics"
    degree: int = 20
    order: int = 20
    drag: bool = False
    sun: bool = False
    moon: bool = False
    srp: bool = False
    shadow: str = "conical"
    target: Spacecraft = field(default_factory=lambda: Spacecraft(name="truth.target"))
    chaser: Spacecraft = field(default_factory=lambda: Spacecraft(name="truth.chaser"))
    weather: SpaceWeather = field(default_factory=SpaceWeather)
    ut1_utc_s: float = 0.0  # UT1 - UTC at the epoch (s), for the Earth rotation angle
    polar_motion_arcsec: tuple[float, float] = (0.0, 0.0)  # pole coordinates x_p, y_p at the epoch (arcsec)

    def __post_init__(self) -> None:
        parse_epoch(self.epoch, "orbit.epoch_utc")
        if self.gravity not in GRAVITY:
            raise input_error("truth.gravity", self.gravity, "must be 'point', 'j2' or 'harmonics'")
        if self.gravity == "harmonics":
            check_degree_order(self.degree, self.order)
        if self.shadow not in SHADOW:
            raise input_error("truth.shadow", self.shadow, "must be 'conical' or 'cylindrical'")

    def label(self) -> str:
        parts = {"point": ["two-body"], "j2": ["J2"], "harmonics": [f"{self.degree}x{self.order}"]}[self.gravity]
        parts += [name for name in ("drag", "sun", "moon", "srp") if getattr(self, name)]
        return " + ".join(parts)

    def without(self, name: str) -> "ForceModels":
        """Copy with one model switched off (``"gravity"`` drops harmonics to point mass)."""
        if name == "gravity":
            return replace(self, gravity="point")
        return replace(self, **{name: False})


class ComposedTruth(PlantBase):
    """Composed force-model truth for one target and one chaser (Plant protocol).

    Parameters
    ----------
    target : OrbitalElements | array (6,) -- target orbit (osculating, at the epoch).
    chaser_hill : array (6,) -- initial chaser Hill state (exact nonlinear map).
    models : ForceModels
    integrator : ``"fast"``, ``"dop853"``, ``"multistep"`` or ``"reference"`` (module doc).
    horizon_s : expected run length, sizes the density table (extended on demand).
    step_s, order : fixed step (s) and Adams-Bashforth order of the multistep path.
    """

    n_x = 6
    n_u = 3

    def __init__(
        self,
        target: OrbitalElements | np.ndarray,
        chaser_hill: np.ndarray,
        models: ForceModels = ForceModels(),
        *,
        integrator: str = "fast",
        horizon_s: float = 6000.0,
        mu: float = MU_EARTH,
        rtol: float = FULL_RTOL,
        atol: float = REFERENCE_ATOL,
        step_s: float = km.DEFAULT_STEP_S,
        order: int = km.DEFAULT_ORDER,
        lookahead: tuple[int, int] = km.DEFAULT_LOOKAHEAD,
    ) -> None:
        if integrator not in INTEGRATORS:
            raise input_error("truth.integrator", integrator, "must be 'fast', 'dop853', 'multistep' or 'reference'")
        if not (math.isfinite(step_s) and 0.0 < step_s <= 120.0):
            raise input_error("step_s", step_s, "must be in (0, 120]", "s")
        if isinstance(order, bool) or not isinstance(order, (int, np.integer)) or not 2 <= order <= 14:
            raise input_error("order", order, "must be an integer in [2, 14]")
        if integrator == "multistep" and models.srp:
            # the shadow boundary (penumbra ~10 s) is a kink the fixed-step polynomial steps over:
            # measured 0.6 / 4 / 7 mm after one orbit at h = 10 / 15 / 20 s (20 km drifting to 57 km,
            # different A/m), against 0.003 mm without SRP
            raise input_error("truth.integrator", integrator, "cannot be used with truth.srp = true (the shadow "
                              "boundary needs the adaptive step); use 'fast' or 'dop853'")
        if isinstance(target, OrbitalElements):
            elements = target
            target_state = elements_to_eci(elements, mu)
        else:
            target_state = np.ascontiguousarray(target, dtype=float)
            elements = eci_to_elements(target_state, mu)
        check_perigee_above_surface(elements, R_EARTH, "target orbit")
        self.models = models
        self.integrator = integrator
        self.step_s = float(step_s)
        self.order = int(order)
        self.adams = km.adams_coefficients(self.order) + km.lookahead_coefficients(self.order, *lookahead)
        self.rtol = float(rtol)
        self.atol = float(atol)
        self.mu = float(mu)
        self.epoch: Epoch = parse_epoch(models.epoch, "orbit.epoch_utc")
        self.target_elements = elements
        self.mean_motion = math.sqrt(mu / elements.sma**3)
        self._target0 = target_state.copy()
        self.rotation = earth_rotation(self.epoch, models.ut1_utc_s, *models.polar_motion_arcsec)
        self.atmosphere = Atmosphere(self.epoch, self.rotation, models.weather) if models.drag else None
        self._build_arrays()
        self._dens = np.zeros((2, 5))
        self._dens_end = -1.0
        if models.drag:
            self._ensure_table(float(horizon_s))
        self._zero_u = np.zeros(3)
        self._time_ok = (math.inf, -math.inf)  # [first, last] time (s) check_time_range passed (without drag)
        self._karman_screen2 = ((WGS84_A + 1e3 * KARMAN_LINE_KM) / (1.0 - REENTRY_SCREEN)) ** 2  # m^2
        self._hill_of = None  # (state, its Hill state) of the last propagate (relative_state hands it out once)
        chaser = np.ascontiguousarray(chaser_hill, dtype=float)
        if chaser.shape != (6,) or not np.all(np.isfinite(chaser)):
            raise input_error("chaser_hill", chaser.tolist(), "must be a finite Hill state of length 6", "m, m/s")
        y = kf.y_from_hill_full(0.0, self._target0, chaser, self.p, *self._arrays(), self._dens)
        self._x0 = np.append(y, 0.0)

    # ------------------------------------------------------------------ model arrays
    def _build_arrays(self) -> None:
        m = self.models
        p = np.zeros(kf.N_P)
        p[kf.I_MU] = self.mu
        p[kf.I_GRAV] = GRAVITY.index(m.gravity)
        p[kf.I_J2] = J2_EARTH
        p[kf.I_RE] = R_EARTH
        if m.gravity == "harmonics":
            # one field per (degree, order) and process: every run of a campaign reads the same C, S, K
            field_ = memo_get(_FIELD_CACHE, (m.degree, m.order), lambda: SphericalHarmonics(m.degree, m.order))
            self._C, self._S, self._K = field_.C, field_.S, field_.K
            p[kf.I_GM_H], p[kf.I_RE_H] = field_.gm, field_.re
            p[kf.I_NMAX], p[kf.I_MMAX] = m.degree, m.order
            n = m.degree
        else:
            self._C = self._S = np.zeros((1, 1))
            self._K = np.zeros((8, 3, 3))
            n = 0
        # V: wide enough for the two-point layout of accel_harmonics_pair (4 values per order)
        self._V = np.zeros((n + 3, 4 * (n + 3)))
        self._W = np.zeros((n + 3, n + 3))
        p[kf.I_DRAG] = float(m.drag)
        p[kf.I_BC_T], p[kf.I_BC_C] = m.target.ballistic, m.chaser.ballistic
        p[kf.I_SUN], p[kf.I_MOON] = float(m.sun), float(m.moon)
        p[kf.I_SRP] = 0.0 if not m.srp else (1.0 if m.shadow == "conical" else 2.0)
        p[kf.I_CR_T], p[kf.I_CR_C] = m.target.srp_factor, m.chaser.srp_factor
        p[kf.I_D0] = self.epoch.days_tt_since_j2000()
        p[kf.I_THETA0], p[kf.I_OMEGA] = self.rotation.theta0, self.rotation.omega
        p[kf.I_PM : kf.I_PM + 9] = (self.rotation.polar - np.eye(3)).ravel()
        if m.sun or m.moon or m.srp:
            p[kf.I_EPH : kf.I_EPH + N_FIT] = cached_third_body_fit(self.epoch)
        p[kf.I_WX : kf.I_WZ + 1] = OMEGA_EARTH * self.rotation.pole_eci
        p[kf.I_GM_SUN], p[kf.I_GM_MOON], p[kf.I_AU] = GM_SUN, GM_MOON, AU
        p[kf.I_R_EARTH], p[kf.I_R_SUN] = R_EARTH, R_SUN
        p[kf.I_DENS_DT] = DENSITY_STEP_S
        p[kf.I_SAFETY] = kf.SAFETY_HARMONICS if m.gravity == "harmonics" else kf.SAFETY
        self.p = p
        self.npm = np.ascontiguousarray(self.rotation.npm)
        self._model_arrays = (self.npm, self._C, self._S, self._K, self._V, self._W)

    def _arrays(self):
        return self._model_arrays

    def _ensure_table(self, t_end: float) -> None:
        """Density table along the target's predicted path (drag off) over [0, t_end + margin]
        (:func:`proxops.propagation.full_setup.density_table`, memoised on its inputs)."""
        if t_end <= self._dens_end:
            return
        span = t_end + DENSITY_MARGIN_S
        check_time_range(self.epoch, span, "duration")
        n = int(math.ceil(span / DENSITY_STEP_S)) + 4
        self._dens = density_table(self, n)
        self.p[kf.I_DENS_T0] = 0.0
        self._dens_end = (n - 3) * DENSITY_STEP_S

    # ------------------------------------------------------------------ Plant protocol
    def initial_state(self) -> np.ndarray:
        """Full 13-state at t = 0."""
        return self._x0.copy()

    def relative_state(self, state: np.ndarray) -> np.ndarray:
        """Exact Hill relative state (6,) (frame rate from the target's total acceleration). Of the state
        :meth:`propagate` returned last, the Hill state that propagation computed with it (the same numbers,
        :func:`proxops.propagation.kernels_full.integrate_full_hill`), handed out once."""
        done = self._hill_of
        if done is not None and done[0] is state:
            self._hill_of = None
            return done[1]
        s = np.ascontiguousarray(state, dtype=float)
        return kf.hill_from_y_full(s[12], s[:12].copy(), self.p, *self._arrays(), self._dens)

    def propagate(self, t: float, state: np.ndarray, u: np.ndarray | None, dt: float) -> np.ndarray:
        """State after ``dt`` s with Hill acceleration ``u`` (m/s^2) held constant. On the DOP853 path
        one kernel call (:func:`proxops.propagation.kernels_full.propagate_full_hill`: the same numbers
        as :meth:`_integrate` on the grid [t, t + dt])."""
        dt = float(dt)
        if not (dt >= 0.0 and math.isfinite(dt)):
            raise input_error("dt", dt, "must be finite and >= 0", "s")
        s = np.ascontiguousarray(state, dtype=float)
        uu = self._zero_u if u is None else np.ascontiguousarray(u, dtype=float)
        t0 = float(s[12])
        self._hill_of = None
        if self.integrator == "reference" or self.uses_multistep(dt):
            out = np.empty(13)  # (np.append's numbers, without its concatenate)
            out[:12] = self._integrate(s[:12].copy(), np.array([t0, t0 + dt]), uu)[-1]
            out[12] = t0 + dt
            return out
        self._check_span(t0 + dt)
        out = np.empty(13)
        hill = np.empty(6)
        status, r_min2 = kf.propagate_full_hill(s, uu, dt, self.p, *self._model_arrays, self._dens, self.rtol,
                                                self.atol, out, hill)  # fmt: skip
        if status != kernels.STATUS_OK:
            self._end_if_reentering(t0, s[:12], DECAYING_ALTITUDE_KM)
            raise ProxopsError(f"truth propagation failed (status {status})")
        if r_min2 <= self._karman_screen2:
            self._end_if_reentering(t0 + dt, out, KARMAN_LINE_KM)
        self._hill_of = (out, hill)
        return out

    def apply_impulse(self, t: float, state: np.ndarray, dv: np.ndarray) -> np.ndarray:
        """Copy of the 13-state with a Hill-axes velocity change ``dv`` (m/s) added to the chaser (the
        kernel reads the target's 6 entries and copies the rest, the time included)."""
        return kernels.apply_hill_impulse(np.ascontiguousarray(state, dtype=float), np.ascontiguousarray(dv, dtype=float))

    def free_drift(self, state: np.ndarray, times: np.ndarray) -> np.ndarray:
        """Uncontrolled Hill states (len(times), 6) at ``times`` (s after now, increasing, >= 0)."""
        s = np.ascontiguousarray(state, dtype=float)
        times = np.ascontiguousarray(times, dtype=float)
        if times.ndim != 1 or times.size == 0 or times[0] < 0.0 or np.any(np.diff(times) < 0.0):
            raise input_error("times", times.tolist(), "must be a non-empty increasing 1-D grid of s >= 0")
        grid = s[12] + (times if times[0] == 0.0 else np.concatenate([[0.0], times]))
        ys = self._integrate(s[:12].copy(), grid, self._zero_u)
        rel = np.array([kf.hill_from_y_full(tk, yk, self.p, *self._arrays(), self._dens) for tk, yk in zip(grid, ys)])
        return rel if times[0] == 0.0 else rel[1:]

    def _check_span(self, t_end: float) -> None:
        """The density table (drag) or the ephemeris' time range (otherwise) covers [0, t_end] (s); the
        range already checked is kept (the check is monotone in t_end)."""
        if self.models.drag:
            self._ensure_table(t_end)
        elif not (self._time_ok[0] <= t_end <= self._time_ok[1]):
            check_time_range(self.epoch, t_end, "duration")
            self._time_ok = (min(self._time_ok[0], t_end), max(self._time_ok[1], t_end))

    def _integrate(self, y0: np.ndarray, grid: np.ndarray, u: np.ndarray) -> np.ndarray:
        """States (len(grid), 12) at the absolute times ``grid``."""
        self._check_span(float(grid[-1]))
        if self.integrator != "reference":
            status, out = self._integrate_numba(y0, grid, u, self.p)
            if status != kernels.STATUS_OK:
                self._end_if_reentering(float(grid[0]), y0, DECAYING_ALTITUDE_KM)
                raise ProxopsError(f"truth propagation failed (status {status})")
        else:
            out = self._integrate_reference(y0, grid, u)
        self._end_if_reentering(float(grid[-1]), out[-1], KARMAN_LINE_KM)
        return out

    def _end_if_reentering(self, t: float, y: np.ndarray, floor_km: float) -> None:
        """Raise :class:`PlantEnded` when the target or the chaser is below ``floor_km`` of geodetic
        height at ``t`` (s): below the Karman line after a step, or below DECAYING_ALTITUDE_KM where the
        integrator gave up (drag at the end of a decay, not a numerical fault). Screened first: the
        geodetic height is at least |r| cos(lat - lat_geocentric) - a >= |r| (1 - REENTRY_SCREEN) - a
        (the two latitudes differ by < 0.2 deg), so positions beyond (a + floor) / (1 - REENTRY_SCREEN)
        from the centre are above the floor without the iteration (the check runs after every step)."""
        tx, ty, tz, _, _, _, dx, dy, dz = y[:9].tolist()
        cx, cy, cz = tx + dx, ty + dy, tz + dz
        r_min2 = min(tx * tx + ty * ty + tz * tz, cx * cx + cy * cy + cz * cz)
        r_screen = (WGS84_A + 1e3 * floor_km) / (1.0 - REENTRY_SCREEN)
        if r_min2 > r_screen * r_screen:
            return
        for name, r in (("target", y[:3]), ("chaser", y[:3] + y[6:9])):
            h_km = geodetic_height(float(r[0]), float(r[1]), float(r[2])) / 1e3
            if h_km < floor_km:
                what = "re-entered" if floor_km == KARMAN_LINE_KM else "decayed (the truth integrator stopped)"
                raise PlantEnded(f"{name} {what}: geodetic altitude {h_km:.1f} km < {floor_km:g} km at t = {t:.0f} s")

    def uses_multistep(self, span_s: float) -> bool:
        """Whether a propagation over ``span_s`` s takes the multistep path (module doc)."""
        if self.integrator == "multistep":
            return True
        return (self.integrator == "fast" and self.models.gravity == "harmonics" and not self.models.srp
                and span_s >= km.MIN_STEPS * self.order * self.step_s)  # fmt: skip

    def _integrate_numba(self, y0: np.ndarray, grid: np.ndarray, u: np.ndarray, p: np.ndarray):
        """(status, states (len(grid), 12)) from the numba DOP853 or multistep kernel."""
        out = np.empty((grid.size, 12))
        if self.uses_multistep(float(grid[-1] - grid[0])):
            split = p[kf.I_GRAV] == 2.0
            status, *_ = km.integrate_multistep(y0, grid, u, p, *self._arrays(), self._dens, self.step_s,
                                                  *self.adams, split, self.rtol, self.atol, out)  # fmt: skip
        else:
            status, _, _ = kf.integrate_full(y0, grid, u, p, *self._arrays(), self._dens, self.rtol, self.atol, out)
        return status, out

    def _integrate_reference(self, y0: np.ndarray, grid: np.ndarray, u: np.ndarray) -> np.ndarray:
        """scipy DOP853 on the same RHS with NRLMSISE-00 called directly at both spacecraft;
        with SRP restarted at every shadow crossing, located by scipy's own event search
        (its dense output and root finder) on the event functions of
        :func:`proxops.environment.eclipse.shadow_boundaries`."""
        arrays = self._arrays()
        p = self.p

        def fun(t, y):
            out = np.empty(12)
            if self.models.drag:
                rho = self.atmosphere.density(np.array([t, t]), np.stack([y[:3], y[:3] + y[6:9]]))
                rho_t, rho_c = float(rho[0]), float(rho[1])
            else:
                rho_t = rho_c = 0.0
            kf.rhs_full_rho(t, y, u, p, *arrays, rho_t, rho_c, out)
            return out

        if grid[-1] == grid[0]:
            return np.tile(y0, (grid.size, 1))
        from scipy.integrate import solve_ivp  # heavy (0.5 s): only on the reference path

        events = self._shadow_events() if self.models.srp else []
        side = [math.copysign(1.0, g(grid[0], y0)) for g in events]  # the side of each boundary now
        out = np.empty((grid.size, 12))
        out[0] = y0
        t, y, idx = float(grid[0]), y0, 1

        def run(t_a, t_b, y_a, samples, **kw):
            sol = solve_ivp(fun, (t_a, t_b), y_a, method="DOP853", t_eval=samples, rtol=self.rtol, atol=self.atol,
                            **kw)  # fmt: skip
            if not sol.success:
                raise ProxopsError(f"reference propagation failed: {sol.message}")
            return sol, np.asarray(sol.y).reshape(12, -1).T  # (no sample: scipy gives empty lists)

        while idx < grid.size:
            for g, sgn in zip(events, side):
                g.terminal, g.direction = True, -sgn  # the next crossing leaves the current side
            sol, ys = run(t, float(grid[-1]), y, grid[idx:], events=events or None, dense_output=bool(events))
            if sol.status != 1:
                out[idx:] = ys
                break
            hit = [k for k, te in enumerate(sol.t_events) if te.size]
            t_event = float(sol.t_events[hit[0]][0])
            # scipy locates the crossing on the dense output of the step over it, whose stages
            # straddle the kink: the samples after that step's start and the state at the
            # crossing are redone from the step's start
            ts = sol.sol.ts
            t_a = float(ts[max(0, int(np.searchsorted(ts, t_event, side="left")) - 1)])
            keep = int(np.count_nonzero(grid[idx:] <= t_a))
            out[idx : idx + keep] = ys[:keep]
            idx += keep
            n_redo = int(np.count_nonzero(grid[idx:] <= t_event))
            _, redo = run(t_a, t_event, sol.sol(t_a), np.append(grid[idx : idx + n_redo], t_event))
            out[idx : idx + n_redo] = redo[:n_redo]
            idx += n_redo
            t, y = t_event, redo[-1]
            for k in hit:  # (the cylindrical model's two functions of one spacecraft cross together)
                if sol.t_events[k][0] == t_event:
                    side[k] = -side[k]
        return out

    def _shadow_events(self) -> list:
        """Event functions g(t, y) of the shadow boundaries (target and chaser; penumbra and
        umbra, one for the cylindrical model) for scipy's solve_ivp."""
        p = self.p
        conical = self.models.shadow == "conical"

        def make(body: int, which: int):
            def g(t, y):
                sx, sy, sz = fitted_position(0, p[kf.I_D0] + t / 86400.0, t / 86400.0, p, kf.I_EPH)
                r = y[:3] + y[6:9] if body else y[:3]
                return shadow_boundaries(r[0], r[1], r[2], sx, sy, sz, p[kf.I_R_EARTH], p[kf.I_R_SUN], conical)[which]

            return g

        return [make(body, which) for body in (0, 1) for which in ((0, 1) if conical else (0,))]

    # ------------------------------------------------------------------ helpers
    def with_relative_state(self, state: np.ndarray, hill_state: np.ndarray) -> np.ndarray:
        s = np.ascontiguousarray(state, dtype=float)
        y = kf.y_from_hill_full(s[12], s[:6].copy(), np.ascontiguousarray(hill_state, dtype=float), self.p,
                                *self._arrays(), self._dens)  # fmt: skip
        return np.append(y, s[12])

    # the first 12 entries are laid out as RelativeTruth's state: the same accessors
    target_state = staticmethod(RelativeTruth.target_state)
    chaser_state = staticmethod(RelativeTruth.chaser_state)


# ---------------------------------------------------------------------- what each model changes
CONTRIBUTIONS = (
    ("harmonics above J2", "gravity_j2"),
    ("gravity n >= 2 (all)", "gravity"),
    ("drag", "drag"),
    ("Sun", "sun"),
    ("Moon", "moon"),
    ("SRP", "srp"),
)


def final_hill(target: OrbitalElements, chaser_hill: np.ndarray, models: ForceModels, duration_s: float,
               integrator: str = "fast") -> np.ndarray:  # fmt: skip
    """Hill state (6,) after ``duration_s`` s of free drift under ``models``."""
    truth = ComposedTruth(target, chaser_hill, models, integrator=integrator, horizon_s=duration_s)
    return truth.relative_state(truth.propagate(0.0, truth.initial_state(), None, duration_s))


def force_contributions(
    target: OrbitalElements, chaser_hill: np.ndarray, models: ForceModels, duration_s: float, integrator: str = "fast"
) -> tuple[np.ndarray, list[dict]]:
    """Final Hill state under ``models`` and, for each enabled model, the difference it
    makes at the end: final(models) - final(models without it) (m, m/s)."""
    full = final_hill(target, chaser_hill, models, duration_s, integrator)
    rows = []
    for label, key in CONTRIBUTIONS:
        if key == "gravity_j2":
            if models.gravity != "harmonics":
                continue
            other = replace(models, gravity="j2")
        elif key == "gravity":
            if models.gravity == "point":
                continue
            other = models.without("gravity")
        else:
            if not getattr(models, key):
                continue
            other = models.without(key)
        d = full - final_hill(target, chaser_hill, other, duration_s, integrator)
        rows.append(
            {
                "model": label,
                "delta_hill": d,
                "delta_position_m": float(np.linalg.norm(d[:3])),
                "delta_velocity_mps": float(np.linalg.norm(d[3:])),
            }
        )
    return full, rows
