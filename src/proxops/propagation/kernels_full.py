"""Numba kernels of the composed (high-fidelity) truth: the enabled force models summed
in one right-hand side, Encke relative form, and its DOP853 loop.

State ``y`` (12,) as in :mod:`proxops.propagation.kernels`: target ECI ``[r_t, v_t]`` and
chaser offset ``[dr, dv]``. Time ``t`` is seconds after the scenario epoch (the models
depend on it through the Earth's rotation and the Sun and Moon).

    r_t''  = -mu r_t / r_t^3 + a_p(t, r_t, v_t, target)
    dr''   = [g(r_t + dr) - g(r_t)]_point mass (Battin, exact) + a_p(t, r_c, v_c, chaser)
             - a_p(t, r_t, v_t, target) + C^T u

where ``a_p`` sums the enabled perturbations (J2 or spherical harmonics n >= 2, drag,
Sun, Moon, SRP), evaluated at both spacecraft and differenced. The DOP853 loop is the
one of :mod:`proxops.propagation.kernels` (same tableau, error norm and step control;
only the right-hand side differs, which now takes ``t`` and the model arrays), kept as a
separate copy so that the J2-only fast path is untouched (bit-identical, same speed).

Model arrays (built by :mod:`proxops.propagation.forces`): ``p`` (float parameters, indices
below), ``C``, ``S``, ``K`` (harmonic coefficients and recursion factors), ``V``, ``W``
(work arrays; ``V`` at least (3, 4 (nmax + 2)) wide is also the work array of the two-point
kernel that evaluates the field at target and chaser in one pass, otherwise two single-point
calls are made, with the same bits), ``dens`` (n, 5) density table along the target's path [ln rho, h, d ln rho/dh,
d^2 ln rho/dh^2, d ln rho/dc] (c: cross-track, at constant height) on a uniform time grid, ``npm`` (3, 3) frozen precession-nutation.

Density between the table nodes: Catmull-Rom cubic in time of the columns, then
rho = exp(ln rho_tab + dh d ln rho/dh + dh^2/2 d^2 ln rho/dh^2 + c d ln rho/dc),
dh = h - h_tab at the spacecraft's own geodetic height h, c = its offset along the
target's orbit normal; the chaser reads the table at t + (dr . v_t)/|v_t|^2 (its
along-track lead). The curvature and cross-track terms matter from km offsets: without
them the density at 4 km radial (2 km cross-track) offset was off by 5e-4 (6e-5) on
average, and the relative position after two orbits at 20 km by 57 mm against Orekit. The table error against direct NRLMSISE-00 calls is measured in
tests (the reference path calls pymsis at every evaluation).

Shadow crossings (SRP on): the shadow factor is not smooth where a spacecraft enters or
leaves the penumbra or the umbra (:func:`proxops.environment.eclipse.shadow_boundaries`),
and a DOP853 step over such a point is not of order 8: its error estimate does not see it,
and the result depends on where the steps happen to fall (measured, 20x20 + Sun/Moon + SRP,
20 km, one orbit: 0.27-0.82 mm for rtol 3e-11 x 0.8 .. 1.25, while without SRP the paths
agree to 3-5 um; one 85 s step held all four crossings of both spacecraft). The loop
therefore checks the four event functions (target and chaser, penumbra and umbra) on the
quintic Hermite interpolant of each accepted step (positions, velocities and accelerations
at both ends: ~1e-4 m at 85 s steps) at SHADOW_SCAN interior points and its end; at a sign
change it bisects the earliest crossing to SHADOW_TOL_S, discards the step and steps to the
crossing instead (the integrator restarts there; a passage through the penumbra shorter
than a quarter of a step, only in grazing geometries, can be missed).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from proxops.core.twobody import accel_differential, accel_j2, accel_twobody
from proxops.environment.earth import geodetic, geodetic_height
from proxops.environment.eclipse import shadow_boundaries, shadow_factor
from proxops.environment.ephemeris import fitted_position
from proxops.environment.forces import accel_drag, accel_srp, accel_third_body
from proxops.environment.harmonics import accel_harmonics, accel_harmonics_pair, pair_arrays_fit
from proxops.propagation.kernels import (
    SAFETY,
    A,
    B,
    C as C_NODES,
    ERROR_EXPONENT,
    MAX_FACTOR,
    MAX_STEPS,
    MIN_FACTOR,
    N_STAGES,
    STATUS_NOT_FINITE,
    STATUS_OK,
    STATUS_STEP_TOO_SMALL,
    STATUS_TOO_MANY_STEPS,
    dop853_error_norm,
    hill_axes,
    hill_from_rates,
    initial_step_orbit,
    offset_from_rates,
)

# ------------------------------------------------------------------ parameter layout of p
I_MU = 0  # central GM (m^3/s^2)
I_GRAV = 1  # 0 point mass only, 1 zonal J2, 2 spherical harmonics
I_J2 = 2
I_RE = 3  # J2 reference radius (m)
I_GM_H = 4  # harmonics GM and radius
I_RE_H = 5
I_NMAX = 6
I_MMAX = 7
I_DRAG = 8  # 0/1
I_BC_T = 9  # C_D A / m target, chaser (m^2/kg)
I_BC_C = 10
I_SUN = 11  # 0/1 Sun third body
I_MOON = 12  # 0/1 Moon third body
I_SRP = 13  # 0 off, 1 conical shadow, 2 cylindrical shadow
I_CR_T = 14  # C_R A / m target, chaser (m^2/kg)
I_CR_C = 15
I_D0 = 16  # TT days from J2000 at t = 0
I_THETA0 = 17  # Earth rotation angle at t = 0 (rad) and rate (rad/s)
I_OMEGA = 18
I_WX = 19  # Earth rotation vector in ECI (rad/s) for the co-rotating atmosphere
I_WY = 20
I_WZ = 21
I_GM_SUN = 22
I_GM_MOON = 23
I_AU = 24
I_R_EARTH = 25  # shadow: Earth and Sun radii (m)
I_R_SUN = 26
I_DENS_T0 = 27  # density table start time (s) and spacing (s)
I_DENS_DT = 28
I_SAFETY = 29  # step-size safety factor of the DOP853 loop (see SAFETY_HARMONICS)
I_PM = 30  # polar motion W - I (9 values, row-major; all 0: none): r_itrf = W r_pef
I_EPH = 39  # Sun and Moon correction to erfa (ephemeris.third_body_fit, N_FIT = 24 values; 0: series alone)
N_P = 63

# Step-size safety factor with spherical harmonics: 0.8 instead of the J2 loop's 0.9 (kept
# for point mass and J2, whose results stay bit-identical to RelativeTruth). The 100x100
# field varies on ~57 s (degree 100 along the track), the accepted steps are ~50 s, and at
# 0.9 a quarter of the steps were rejected; at 0.8 about a tenth (one orbit, 100x100 +
# Sun/Moon: 1596 RHS evaluations at rtol 1e-11 and 0.9 -> 1368 at rtol 3e-11 and 0.8,
# relative error vs rtol 1e-13 0.09 -> 0.06 mm at 20 km).
SAFETY_HARMONICS = 0.8


@njit(cache=True)
def _catmull_rom(dens: np.ndarray, i: int, j: int, f: float, f2: float, f3: float) -> float:
    """Column j of the table between rows i and i + 1 at fraction f (f2 = f^2, f3 = f^3)."""
    n = dens.shape[0]
    p1 = dens[i, j]
    p2 = dens[i + 1, j]
    # end segments: quadratic-extrapolated ghost nodes (needs n >= 3)
    p0 = dens[i - 1, j] if i > 0 else 3.0 * p1 - 3.0 * p2 + dens[i + 2, j]
    p3 = dens[i + 2, j] if i + 2 < n else 3.0 * p2 - 3.0 * p1 + dens[i - 1, j]
    return 0.5 * (2.0 * p1 + (-p0 + p2) * f + (2.0 * p0 - 5.0 * p1 + 4.0 * p2 - p3) * f2 + (-p0 + 3.0 * p1 - 3.0 * p2 + p3) * f3)


@njit(cache=True)
def _interp_row(dens: np.ndarray, p: np.ndarray, t: float):
    """Catmull-Rom cubic interpolation of the 5 table columns at time t (held constant
    outside), as a 5-tuple (no allocation: called twice per right-hand side)."""
    n = dens.shape[0]
    s = (t - p[I_DENS_T0]) / p[I_DENS_DT]
    if s <= 0.0:
        return dens[0, 0], dens[0, 1], dens[0, 2], dens[0, 3], dens[0, 4]
    if s >= n - 1:
        return dens[n - 1, 0], dens[n - 1, 1], dens[n - 1, 2], dens[n - 1, 3], dens[n - 1, 4]
    i = int(s)
    f = s - i
    f2 = f * f
    f3 = f2 * f
    return (_catmull_rom(dens, i, 0, f, f2, f3), _catmull_rom(dens, i, 1, f, f2, f3), _catmull_rom(dens, i, 2, f, f2, f3),
            _catmull_rom(dens, i, 3, f, f2, f3), _catmull_rom(dens, i, 4, f, f2, f3))  # fmt: skip


@njit(cache=True)
def geodetic_rows(ecef: np.ndarray) -> np.ndarray:
    """(n, 3) WGS-84 [lat rad, lon rad, h m] of Earth-fixed positions (n, 3) m
    (:func:`proxops.environment.earth.geodetic` on every row, one jitted loop)."""
    out = np.empty((ecef.shape[0], 3))
    for k in range(ecef.shape[0]):
        out[k, 0], out[k, 1], out[k, 2] = geodetic(ecef[k, 0], ecef[k, 1], ecef[k, 2])
    return out


@njit(cache=True)
def density_at(t: float, rx: float, ry: float, rz: float, cross: float, p: np.ndarray, npm: np.ndarray,
               dens: np.ndarray) -> float:  # fmt: skip
    """Tabulated NRLMSISE-00 density (kg/m^3) at ECI position r (m), time t (s), ``cross`` m
    off the target's orbit plane (along its normal)."""
    ln_rho, h_tab, d1, d2, dc = _interp_row(dens, p, t)
    ex, ey, ez = _to_ecef(t, rx, ry, rz, p, npm)
    dh = geodetic_height(ex, ey, ez) - h_tab
    return math.exp(ln_rho + dh * d1 + 0.5 * dh * dh * d2 + cross * dc)


@njit(cache=True)
def _to_ecef(t, x, y, z, p, npm):
    qx = npm[0, 0] * x + npm[0, 1] * y + npm[0, 2] * z
    qy = npm[1, 0] * x + npm[1, 1] * y + npm[1, 2] * z
    qz = npm[2, 0] * x + npm[2, 1] * y + npm[2, 2] * z
    th = p[I_THETA0] + p[I_OMEGA] * t
    c = math.cos(th)
    s = math.sin(th)
    return _polar(c * qx + s * qy, -s * qx + c * qy, qz, p, 1)


@njit(cache=True)
def _polar(x, y, z, p, forward):
    """r_itrf = W r_pef (``forward`` = 1) or r_pef = W^T r_itrf (0); W = I + p[I_PM:I_PM + 9]."""
    if forward:
        return (x + p[I_PM] * x + p[I_PM + 1] * y + p[I_PM + 2] * z, y + p[I_PM + 3] * x + p[I_PM + 4] * y
                + p[I_PM + 5] * z, z + p[I_PM + 6] * x + p[I_PM + 7] * y + p[I_PM + 8] * z)  # fmt: skip
    return (x + p[I_PM] * x + p[I_PM + 3] * y + p[I_PM + 6] * z, y + p[I_PM + 1] * x + p[I_PM + 4] * y
            + p[I_PM + 7] * z, z + p[I_PM + 2] * x + p[I_PM + 5] * y + p[I_PM + 8] * z)  # fmt: skip


@njit(cache=True)
def _harmonics_eci(t, x, y, z, p, npm, C, S, K, V, W):
    ex, ey, ez = _to_ecef(t, x, y, z, p, npm)
    bx, by, bz = accel_harmonics(ex, ey, ez, p[I_GM_H], p[I_RE_H], C, S, int(p[I_NMAX]), int(p[I_MMAX]), 2, K, V, W)
    bx, by, bz = _polar(bx, by, bz, p, 0)
    th = p[I_THETA0] + p[I_OMEGA] * t
    c = math.cos(th)
    s = math.sin(th)
    qx = c * bx - s * by
    qy = s * bx + c * by
    qz = bz
    # npm^T q
    return (
        npm[0, 0] * qx + npm[1, 0] * qy + npm[2, 0] * qz,
        npm[0, 1] * qx + npm[1, 1] * qy + npm[2, 1] * qz,
        npm[0, 2] * qx + npm[1, 2] * qy + npm[2, 2] * qz,
    )


@njit(cache=True)
def _harmonics_eci_pair(t, xa, ya, za, xb, yb, zb, p, npm, C, S, K, V, W):
    """:func:`_harmonics_eci` at two ECI positions (m) in one pass of
    :func:`accel_harmonics_pair` (bit-identical to two calls; ``V`` is its lane-interleaved
    work array when wide enough, else two single-point calls are made)."""
    nmax = int(p[I_NMAX])
    if not pair_arrays_fit(K, V, nmax):
        ta = _harmonics_eci(t, xa, ya, za, p, npm, C, S, K, V, W)
        tb = _harmonics_eci(t, xb, yb, zb, p, npm, C, S, K, V, W)
        return ta[0], ta[1], ta[2], tb[0], tb[1], tb[2]
    exa, eya, eza = _to_ecef(t, xa, ya, za, p, npm)
    exb, eyb, ezb = _to_ecef(t, xb, yb, zb, p, npm)
    bxa, bya, bza, bxb, byb, bzb = accel_harmonics_pair(exa, eya, eza, exb, eyb, ezb, p[I_GM_H], p[I_RE_H], nmax,
                                                        int(p[I_MMAX]), 2, K, V)  # fmt: skip
    bxa, bya, bza = _polar(bxa, bya, bza, p, 0)
    bxb, byb, bzb = _polar(bxb, byb, bzb, p, 0)
    th = p[I_THETA0] + p[I_OMEGA] * t
    c = math.cos(th)
    s = math.sin(th)
    qxa = c * bxa - s * bya
    qya = s * bxa + c * bya
    qxb = c * bxb - s * byb
    qyb = s * bxb + c * byb
    # npm^T q, as _harmonics_eci
    return (
        npm[0, 0] * qxa + npm[1, 0] * qya + npm[2, 0] * bza,
        npm[0, 1] * qxa + npm[1, 1] * qya + npm[2, 1] * bza,
        npm[0, 2] * qxa + npm[1, 2] * qya + npm[2, 2] * bza,
        npm[0, 0] * qxb + npm[1, 0] * qyb + npm[2, 0] * bzb,
        npm[0, 1] * qxb + npm[1, 1] * qyb + npm[2, 1] * bzb,
        npm[0, 2] * qxb + npm[1, 2] * qyb + npm[2, 2] * bzb,
    )


@njit(cache=True)
def accel_perturbations(t, rx, ry, rz, vx, vy, vz, chaser, rho, sun, moon, p, npm, C, S, K, V, W):
    """Sum of the enabled perturbations (m/s^2, ECI) on one spacecraft; ``rho`` its density
    (kg/m^3), ``sun``/``moon`` geocentric positions (m, 3-tuples)."""
    ax = 0.0
    ay = 0.0
    az = 0.0
    grav = p[I_GRAV]
    if grav == 1.0:
        ax, ay, az = accel_j2(rx, ry, rz, p[I_MU], p[I_J2], p[I_RE])
    elif grav == 2.0:
        ax, ay, az = _harmonics_eci(t, rx, ry, rz, p, npm, C, S, K, V, W)
    return _add_non_gravity(ax, ay, az, rx, ry, rz, vx, vy, vz, chaser, rho, sun, moon, p)


@njit(cache=True)
def _add_non_gravity(ax, ay, az, rx, ry, rz, vx, vy, vz, chaser, rho, sun, moon, p):
    """(ax, ay, az) (the gravity perturbation, m/s^2) plus drag, Sun, Moon and SRP, in that order."""
    if p[I_DRAG] != 0.0:
        bc = p[I_BC_C] if chaser else p[I_BC_T]
        dx, dy, dz = accel_drag(rx, ry, rz, vx, vy, vz, rho, bc, p[I_WX], p[I_WY], p[I_WZ])
        ax += dx
        ay += dy
        az += dz
    if p[I_SUN] != 0.0:
        dx, dy, dz = accel_third_body(rx, ry, rz, sun[0], sun[1], sun[2], p[I_GM_SUN])
        ax += dx
        ay += dy
        az += dz
    if p[I_MOON] != 0.0:
        dx, dy, dz = accel_third_body(rx, ry, rz, moon[0], moon[1], moon[2], p[I_GM_MOON])
        ax += dx
        ay += dy
        az += dz
    if p[I_SRP] != 0.0:
        nu = shadow_factor(rx, ry, rz, sun[0], sun[1], sun[2], p[I_R_EARTH], p[I_R_SUN], p[I_SRP] == 1.0)
        if nu > 0.0:
            cr = p[I_CR_C] if chaser else p[I_CR_T]
            dx, dy, dz = accel_srp(rx, ry, rz, sun[0], sun[1], sun[2], cr, nu, p[I_AU])
            ax += dx
            ay += dy
            az += dz
    return ax, ay, az


@njit(cache=True)
def third_bodies(t: float, p: np.ndarray):
    """Geocentric Sun and Moon (m, 3-tuples; zeros when no enabled model needs them) at t s
    after the epoch: one evaluation per time, shared by target and chaser."""
    d = p[I_D0] + t / 86400.0
    sun = (0.0, 0.0, 0.0)
    moon = (0.0, 0.0, 0.0)
    if p[I_SUN] != 0.0 or p[I_SRP] != 0.0:
        sun = fitted_position(0, d, t / 86400.0, p, I_EPH)
    if p[I_MOON] != 0.0:
        moon = fitted_position(1, d, t / 86400.0, p, I_EPH)
    return sun, moon


@njit(cache=True)
def rhs_full_rho(t, y, u, p, npm, C, S, K, V, W, rho_t, rho_c, out) -> None:
    """Composed Encke RHS (12,) with given densities at target and chaser (kg/m^3)."""
    sun, moon = third_bodies(t, p)
    rhs_full_env(t, y, u, p, npm, C, S, K, V, W, rho_t, rho_c, sun, moon, out)


@njit(cache=True)
def rhs_full_env(t, y, u, p, npm, C, S, K, V, W, rho_t, rho_c, sun, moon, out) -> None:
    """Composed Encke RHS (12,) with given densities (kg/m^3) and Sun and Moon positions
    (m, from :func:`third_bodies` at the same t)."""
    rtx, rty, rtz = y[0], y[1], y[2]
    rcx, rcy, rcz = rtx + y[6], rty + y[7], rtz + y[8]
    ax, ay, az = accel_twobody(rtx, rty, rtz, p[I_MU])
    if p[I_GRAV] == 2.0:  # the field at both spacecraft in one pass (same bits as two calls)
        gtx, gty, gtz, gcx, gcy, gcz = _harmonics_eci_pair(t, rtx, rty, rtz, rcx, rcy, rcz, p, npm, C, S, K, V, W)
        ptx, pty, ptz = _add_non_gravity(gtx, gty, gtz, rtx, rty, rtz, y[3], y[4], y[5], False, rho_t, sun, moon, p)
        pcx, pcy, pcz = _add_non_gravity(
            gcx, gcy, gcz, rcx, rcy, rcz, y[3] + y[9], y[4] + y[10], y[5] + y[11], True, rho_c, sun, moon, p
        )
    else:
        ptx, pty, ptz = accel_perturbations(
            t, rtx, rty, rtz, y[3], y[4], y[5], False, rho_t, sun, moon, p, npm, C, S, K, V, W
        )
        pcx, pcy, pcz = accel_perturbations(
            t, rcx, rcy, rcz, y[3] + y[9], y[4] + y[10], y[5] + y[11], True, rho_c, sun, moon, p, npm, C, S, K, V, W
        )
    dax, day, daz = accel_differential(rtx, rty, rtz, y[6], y[7], y[8], p[I_MU], 0.0, 1.0)
    dax += pcx - ptx
    day += pcy - pty
    daz += pcz - ptz
    if u[0] != 0.0 or u[1] != 0.0 or u[2] != 0.0:
        xx, xy, xz, yx, yy, yz, zx, zy, zz = hill_axes(y)
        dax += xx * u[0] + yx * u[1] + zx * u[2]
        day += xy * u[0] + yy * u[1] + zy * u[2]
        daz += xz * u[0] + yz * u[1] + zz * u[2]
    out[0] = y[3]
    out[1] = y[4]
    out[2] = y[5]
    out[3] = ax + ptx
    out[4] = ay + pty
    out[5] = az + ptz
    out[6] = y[9]
    out[7] = y[10]
    out[8] = y[11]
    out[9] = dax
    out[10] = day
    out[11] = daz




@njit(cache=True)
def densities(t, y, p, npm, dens):
    """Tabulated densities (kg/m^3) at target and chaser (0 without drag; module doc)."""
    rho_t = 0.0
    rho_c = 0.0
    if p[I_DRAG] != 0.0:
        rho_t = density_at(t, y[0], y[1], y[2], 0.0, p, npm, dens)
        v2 = y[3] * y[3] + y[4] * y[4] + y[5] * y[5]
        lead = (y[6] * y[3] + y[7] * y[4] + y[8] * y[5]) / v2
        hx = y[1] * y[5] - y[2] * y[4]
        hy = y[2] * y[3] - y[0] * y[5]
        hz = y[0] * y[4] - y[1] * y[3]
        cross = (y[6] * hx + y[7] * hy + y[8] * hz) / math.sqrt(hx * hx + hy * hy + hz * hz)
        rho_c = density_at(t + lead, y[0] + y[6], y[1] + y[7], y[2] + y[8], cross, p, npm, dens)
    return rho_t, rho_c


@njit(cache=True)
def rhs_full(t, y, u, p, npm, C, S, K, V, W, dens, out) -> None:
    """Composed Encke RHS (12,) with the density from the table (see module doc)."""
    rho_t, rho_c = densities(t, y, p, npm, dens)
    rhs_full_rho(t, y, u, p, npm, C, S, K, V, W, rho_t, rho_c, out)


@njit(cache=True)
def rhs_full_sun_moon(t, y, u, p, npm, C, S, K, V, W, dens, sun, moon, out) -> None:
    """:func:`rhs_full` with the Sun and Moon given (from :func:`third_bodies` at the same t)."""
    rho_t, rho_c = densities(t, y, p, npm, dens)
    rhs_full_env(t, y, u, p, npm, C, S, K, V, W, rho_t, rho_c, sun, moon, out)


@njit(cache=True)
def target_accel(t, y, p, npm, C, S, K, V, W, dens):
    """Total acceleration (3-tuple, m/s^2) of the target (for the Hill frame rate)."""
    out = np.empty(12)
    u = np.zeros(3)
    rhs_full(t, y, u, p, npm, C, S, K, V, W, dens, out)
    return out[3], out[4], out[5]


@njit(cache=True)
def hill_from_y_full(t, y, p, npm, C, S, K, V, W, dens) -> np.ndarray:
    """Exact Hill relative state (6,) with the frame rate x part r (a_t . h_hat)/|h| from
    the target's total acceleration (see proxops.frames.hill)."""
    ax, ay, az = target_accel(t, y, p, npm, C, S, K, V, W, dens)
    return hill_from_accel(y, ax, ay, az)


@njit(cache=True)
def frame_rates_from_accel(y, ax, ay, az):
    """(w_x, w_z) (rad/s) of the Hill frame of the target y[0:6] with its total acceleration (ax, ay, az)
    (m/s^2): w_z = |h| / r^2, w_x = r (a . h) / |h|^2 (w_y = 0)."""
    rn2 = y[0] * y[0] + y[1] * y[1] + y[2] * y[2]
    hx = y[1] * y[5] - y[2] * y[4]
    hy = y[2] * y[3] - y[0] * y[5]
    hz = y[0] * y[4] - y[1] * y[3]
    h2 = hx * hx + hy * hy + hz * hz
    return math.sqrt(rn2) * (ax * hx + ay * hy + az * hz) / h2, math.sqrt(h2) / rn2


@njit(cache=True)
def hill_from_accel(y, ax, ay, az) -> np.ndarray:
    """:func:`hill_from_y_full` with the target's total acceleration (ax, ay, az) (m/s^2) given."""
    wx, wz = frame_rates_from_accel(y, ax, ay, az)
    out = np.empty(6)
    hill_from_rates(y, wx, wz, out)
    return out


@njit(cache=True)
def y_from_hill_full(t, target, hill, p, npm, C, S, K, V, W, dens) -> np.ndarray:
    """12-state from the target ECI state (6,) and chaser Hill state (6,); inverse of
    :func:`hill_from_y_full`."""
    y = np.zeros(12)
    for i in range(6):
        y[i] = target[i]
    ax, ay, az = target_accel(t, y, p, npm, C, S, K, V, W, dens)
    wx, wz = frame_rates_from_accel(y, ax, ay, az)
    offset_from_rates(y, hill, wx, wz)
    return y


# ---------------------------------------------------------------- shadow crossings (module doc)
SHADOW_SCAN = 3  # interior points of each accepted step where the shadow event functions are checked
SHADOW_TOL_S = 1e-7  # a located crossing is at most this far (s) before the end of the step to it


@njit(cache=True)
def _hermite5(s, h, p0, v0, a0, p1, v1, a1) -> float:
    """Quintic Hermite interpolant at fraction ``s`` of a step of ``h`` s through the values,
    first and second derivatives at both ends."""
    s2 = s * s
    s3 = s2 * s
    s4 = s3 * s
    s5 = s4 * s
    return ((1.0 - 10.0 * s3 + 15.0 * s4 - 6.0 * s5) * p0 + (10.0 * s3 - 15.0 * s4 + 6.0 * s5) * p1
            + h * ((s - 6.0 * s3 + 8.0 * s4 - 3.0 * s5) * v0 + (-4.0 * s3 + 7.0 * s4 - 3.0 * s5) * v1)
            + 0.5 * h * h * ((s2 - 3.0 * s3 + 3.0 * s4 - s5) * a0 + (s3 - 2.0 * s4 + s5) * a1))  # fmt: skip


@njit(cache=True)
def _body_position(s, h, i, body, y0, f0, y1, f1) -> float:
    """ECI position component ``i`` (m) of the target (``body`` 0) or the chaser (1) at
    fraction ``s`` of the step from (y0, f0) to (y1, f1) (:func:`_hermite5`)."""
    if body == 0:
        return _hermite5(s, h, y0[i], y0[3 + i], f0[3 + i], y1[i], y1[3 + i], f1[3 + i])
    return _hermite5(s, h, y0[i] + y0[6 + i], y0[3 + i] + y0[9 + i], f0[3 + i] + f0[9 + i], y1[i] + y1[6 + i],
                     y1[3 + i] + y1[9 + i], f1[3 + i] + f1[9 + i])  # fmt: skip


@njit(cache=True)
def _shadow_side(t, h, s, y0, f0, y1, f1, p) -> int:
    """Bit mask of the shadow event functions that are > 0 (bits: target penumbra, target
    umbra, chaser penumbra, chaser umbra) at t + s h on the step's Hermite interpolant
    (s = 0 and 1: the step's end states themselves)."""
    sx, sy, sz = fitted_position(0, p[I_D0] + (t + s * h) / 86400.0, (t + s * h) / 86400.0, p, I_EPH)
    conical = p[I_SRP] == 1.0
    mask = 0
    for body in range(2):
        rx = _body_position(s, h, 0, body, y0, f0, y1, f1)
        ry = _body_position(s, h, 1, body, y0, f0, y1, f1)
        rz = _body_position(s, h, 2, body, y0, f0, y1, f1)
        g_pen, g_umb = shadow_boundaries(rx, ry, rz, sx, sy, sz, p[I_R_EARTH], p[I_R_SUN], conical)
        if g_pen > 0.0:
            mask |= 1 << (2 * body)
        if g_umb > 0.0:
            mask |= 1 << (2 * body + 1)
    return mask


@njit(cache=True)
def _first_shadow_crossing(t, h, y0, f0, y1, f1, p, mask0) -> float:
    """Offset (s, in (0, h]) just after the earliest shadow crossing inside the step
    [t, t + h] (bisected to SHADOW_TOL_S), or -1.0 when every event function keeps the
    sign it had at the start (``mask0``) at the SHADOW_SCAN interior points and the end."""
    lo = 0.0
    n = SHADOW_SCAN + 1
    for j in range(1, n + 1):
        hi = h * j / n
        if _shadow_side(t, h, hi / h if j < n else 1.0, y0, f0, y1, f1, p) != mask0:
            while hi - lo > SHADOW_TOL_S:
                mid = 0.5 * (lo + hi)
                if _shadow_side(t, h, mid / h, y0, f0, y1, f1, p) != mask0:
                    hi = mid
                else:
                    lo = mid
            return hi
        lo = hi
    return -1.0


# ---------------------------------------------------------------- DOP853 loop (time-dependent RHS)
@njit(cache=True)
def _step(t, y, f0, h, u, p, npm, C, S, K, V, W, dens, Kst, work, y_new) -> None:
    n = y.size
    for i in range(n):
        Kst[0, i] = f0[i]
    for s in range(1, N_STAGES):
        for i in range(n):
            acc = 0.0
            for j in range(s):
                acc += A[s, j] * Kst[j, i]
            work[i] = y[i] + h * acc
        rhs_full(t + C_NODES[s] * h, work, u, p, npm, C, S, K, V, W, dens, Kst[s])
    for i in range(n):
        acc = 0.0
        for j in range(N_STAGES):
            acc += B[j] * Kst[j, i]
        y_new[i] = y[i] + h * acc
    rhs_full(t + h, y_new, u, p, npm, C, S, K, V, W, dens, Kst[N_STAGES])


@njit(cache=True)
def integrate_full(y0, times, u, p, npm, C, S, K, V, W, dens, rtol, atol, out) -> tuple:
    """Integrate through increasing absolute ``times`` (s after the epoch; times[0] = start),
    storing the state at each time in ``out``. Same step control as
    :func:`proxops.propagation.kernels.integrate_grid`; with SRP the integrator restarts at
    every shadow crossing (module doc). Returns (status, n_steps, n_rejected), the rejected
    count including the steps discarded at a crossing."""
    status, n_steps, n_rej, _ = integrate_full_crossings(y0, times, u, p, npm, C, S, K, V, W, dens, rtol, atol, out,
                                                         np.empty(0), np.empty(0))  # fmt: skip
    return status, n_steps, n_rej


@njit(cache=True)
def integrate_full_hill(y0, times, u, p, npm, C, S, K, V, W, dens, rtol, atol, out, hill) -> int:
    """:func:`integrate_full` that also writes the Hill state of the final state into ``hill`` (6,):
    :func:`hill_from_y_full` at ``times[-1]``, whose target acceleration is the last step's FSAL
    derivative when that was evaluated at ``times[-1]`` exactly (the same right-hand side at the same
    t and state: the same bits, one evaluation fewer). Returns the status."""
    f_end = np.empty(13)
    status, _, _, _ = integrate_full_crossings(y0, times, u, p, npm, C, S, K, V, W, dens, rtol, atol, out,
                                               np.empty(0), f_end)  # fmt: skip
    if status != STATUS_OK:
        return status
    m = times.size
    y_end = out[m - 1]
    if f_end[12] == times[m - 1]:
        h = hill_from_accel(y_end, f_end[3], f_end[4], f_end[5])
    else:
        h = hill_from_y_full(times[m - 1], y_end, p, npm, C, S, K, V, W, dens)
    for i in range(6):
        hill[i] = h[i]
    return status


@njit(cache=True)
def propagate_full_hill(s, u, dt, p, npm, C, S, K, V, W, dens, rtol, atol, out, hill) -> tuple:
    """One propagation of the full 13-state ``s`` = [y (12,), t (s)] over ``dt`` s in one call:
    :func:`integrate_full_hill` on the grid [t, t + dt], the state after it into ``out`` (13,) with
    its time t + dt, its Hill state into ``hill`` (6,). Returns (status, the smaller squared distance
    of target and chaser from the Earth's centre at the end (m^2), for the re-entry screen)."""
    t0 = s[12]
    times = np.empty(2)
    times[0] = t0
    times[1] = t0 + dt
    ys = np.empty((2, 12))
    status = integrate_full_hill(s[:12].copy(), times, u, p, npm, C, S, K, V, W, dens, rtol, atol, ys, hill)
    for i in range(12):
        out[i] = ys[1, i]
    out[12] = times[1]
    tx, ty, tz = out[0], out[1], out[2]
    cx, cy, cz = tx + out[6], ty + out[7], tz + out[8]
    return status, min(tx * tx + ty * ty + tz * tz, cx * cx + cy * cy + cz * cz)


@njit(cache=True)
def integrate_full_crossings(y0, times, u, p, npm, C, S, K, V, W, dens, rtol, atol, out, crossings, f_end) -> tuple:
    """:func:`integrate_full` that also stores the times (s) of the first ``crossings.size``
    shadow crossings it restarted at; returns (status, n_steps, n_rejected, n_crossings). With
    ``f_end.size >= 13``: f_end[:12] = the derivative at the final state from the last step (FSAL)
    and f_end[12] = the time it was evaluated at (NaN when no step was taken)."""
    n = y0.size
    m = times.size
    keep_f = f_end.size >= 13
    if keep_f:
        f_end[12] = math.nan
    t_f = math.nan  # time of the last accepted step's FSAL evaluation (t + h)
    Kst = np.empty((N_STAGES + 1, n))
    work = np.empty(n)
    y = y0.copy()
    y_new = np.empty(n)
    f0 = np.empty(n)
    for i in range(n):
        out[0, i] = y0[i]
    if m == 1:
        return STATUS_OK, 0, 0, 0
    t = times[0]
    rhs_full(t, y, u, p, npm, C, S, K, V, W, dens, f0)
    span = times[m - 1] - times[0]
    if span <= 0.0:
        for k in range(1, m):
            for i in range(n):
                out[k, i] = y0[i]
        return STATUS_OK, 0, 0, 0
    pp = np.empty(1)
    pp[0] = p[I_MU]
    h_abs = min(span, initial_step_orbit(y, pp, rtol))
    n_steps = 0
    n_rej = 0
    n_cross = 0
    shadow = p[I_SRP] != 0.0
    side = _shadow_side(t, 0.0, 0.0, y, f0, y, f0, p) if shadow else 0
    t_event = math.inf  # a located crossing the next step ends at
    for k in range(1, m):
        t_end = times[k]
        while t < t_end:
            t_stop = min(t_end, t_event)
            rejected = False
            while True:
                if n_steps + n_rej >= MAX_STEPS:
                    return STATUS_TOO_MANY_STEPS, n_steps, n_rej, n_cross
                min_step = 10.0 * (np.nextafter(abs(t), np.inf) - abs(t))
                if h_abs < min_step:
                    return STATUS_STEP_TOO_SMALL, n_steps, n_rej, n_cross
                clipped = t + h_abs >= t_stop
                h = t_stop - t if clipped else h_abs
                _step(t, y, f0, h, u, p, npm, C, S, K, V, W, dens, Kst, work, y_new)
                err = dop853_error_norm(y, y_new, Kst, h, rtol, atol)
                if not math.isfinite(err):
                    return STATUS_NOT_FINITE, n_steps, n_rej, n_cross
                if err < 1.0:
                    if err == 0.0:
                        factor = MAX_FACTOR
                    else:
                        factor = min(MAX_FACTOR, p[I_SAFETY] * err**ERROR_EXPONENT)
                    if rejected:
                        factor = min(1.0, factor)
                    h_abs = max(h * factor, h_abs) if clipped else h * factor
                    break
                h_abs = h * max(MIN_FACTOR, p[I_SAFETY] * err**ERROR_EXPONENT)
                rejected = True
                n_rej += 1
            if shadow:
                tau = _first_shadow_crossing(t, h, y, f0, y_new, Kst[N_STAGES], p, side)
                if tau > 0.0 and h - tau > SHADOW_TOL_S:  # a crossing inside: step to it instead
                    t_event = t + tau
                    n_rej += 1
                    continue
                side = _shadow_side(t, h, 1.0, y, f0, y_new, Kst[N_STAGES], p)
                if tau > 0.0:
                    if n_cross < crossings.size:
                        crossings[n_cross] = t + h
                    n_cross += 1
            n_steps += 1
            t_f = t + h
            t = t_stop if clipped else t + h
            if t >= t_event:
                t_event = math.inf
            for i in range(n):
                y[i] = y_new[i]
                f0[i] = Kst[N_STAGES, i]
        for i in range(n):
            out[k, i] = y[i]
    if keep_f and n_steps > 0:
        for i in range(n):
            f_end[i] = f0[i]
        f_end[12] = t_f
    return STATUS_OK, n_steps, n_rej, n_cross
