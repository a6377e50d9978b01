"""Set-up of the ``cortex`` system shared by the planner (:mod:`proxops.systems.cortex`) and the closed
loop (:mod:`proxops.systems.cortex_loop`): the planner configuration of a scenario, its docking axis, the
eclipse profile of the holds, the plan, and the checks of the loop's keys. Light at import (no solver, no
numba): ``proxops validate`` checks a cortex scenario with it.
"""

from __future__ import annotations

import math

import numpy as np

from proxops.core.cw import mean_motion
from proxops.environment.disk_memo import digest, disk_get  # hashlib and numpy only
from proxops.errors import input_error
from proxops.guidance.cortex.config import CortexConfig, fibonacci_axes, unit_axis
from proxops.guidance.cortex.holds import sunlit_flags
from proxops.guidance.cortex.timeline import substeps


def config_from_scenario(sc):
    """The planner configuration (SI) of a scenario; the checks of CortexConfig.validate apply."""
    g, m, p = sc.geometry, sc.margins, sc.planner
    start = g.start_position_m if g.start_position_m is not None else [0.0, -g.r_as_m / 2.0, 0.0]
    return CortexConfig(
        mean_motion_rad_s=mean_motion(sc.orbit.sma_m), a_max_mps2=sc.servicer.a_max_mps2,
        r_kos_m=g.r_kos_m, r_as_m=g.r_as_m, r_rs_m=g.r_rs_m,
        plume_half_angle_rad=math.radians(g.plume_half_angle_deg), cone_half_angle_rad=math.radians(g.cone_half_angle_deg),
        thrust_margin=m.thrust, kos_margin=m.kos, plume_margin=m.plume, cone_margin=m.cone,
        tau_lb_s=p.tau_lb_s, tau_ub_s=p.tau_ub_s, tau1_s=p.tau1_s, tau2_s=p.tau2_s, convergence_penalty_s=p.convergence_penalty_s,
        dt_cp1_s=p.dt_cp1_s, dt_cp2_s=p.dt_cp2_s, start_state=tuple(list(start) + list(g.start_velocity_mps)),
        flyaround_end_range_m=g.flyaround_end_range_m, approach_end_range_m=g.approach_end_range_m,
        approach_end_position_m=None if g.approach_end_position_m is None else tuple(g.approach_end_position_m),
        kos_max_iter=p.kos_max_iter, kos_arc_planes=p.kos_arc_planes, scp_max_iter=p.scp_max_iter, scp_tol_mps=p.scp_tol_mps,
        plume_tol_rad=math.radians(p.plume_tol_deg), search=p.search,
    )


def scenario_axis(sc) -> np.ndarray:
    if sc.axis.fibonacci_index is not None:
        return fibonacci_axes(sc.axis.fibonacci_n)[sc.axis.fibonacci_index]
    return unit_axis(sc.axis.docking_axis)


_PROFILES: dict = {}


def eclipse_profile(sc):
    """(t_s, eta) sunlight flags along the CSO orbit from orbit.epoch_utc, or None (model "none").
    Cached per process (every axis of a campaign shares it) and the illumination on disk
    (:func:`illumination_profile`)."""
    e = sc.eclipse
    if e.model == "none":
        return None
    o = sc.orbit
    key = (o.sma_m, o.ecc, o.inc_deg, o.raan_deg, o.argp_deg, o.nu_deg, o.epoch_utc, e.model, e.samples_per_orbit,
           e.orbits, e.sunlit_threshold)
    got = _PROFILES.get(key)
    if got is None:
        t, illum = illumination_profile(o, e)
        got = (t, sunlit_flags(illum, e.sunlit_threshold))
        _PROFILES[key] = got
    return got


_LIBRARIES = ("numba", "llvmlite", "erfa")  # compute the profile (kernels, the Sun's series) with numpy


def _library_stamp() -> tuple:
    """Where and which build of the libraries that compute the profile are installed ((path, mtime, size) of
    their ``__init__.py``, found without importing them, and numpy's version): part of the disk key."""
    import importlib.util
    import os

    out: list = [np.__version__]
    for name in _LIBRARIES:
        spec = importlib.util.find_spec(name)
        origin = getattr(spec, "origin", None) if spec is not None else None
        try:
            st = os.stat(origin) if origin else None
        except OSError:
            st = None
        out.append((name, origin, st.st_mtime_ns if st else None, st.st_size if st else None))
    return tuple(out)


def illumination_profile(orbit, eclipse) -> tuple[np.ndarray, np.ndarray]:
    """(t_s, illum) of :func:`proxops.environment.eclipse.eclipse_profile` for the [orbit] and [eclipse]
    sections, memoised on disk (:mod:`proxops.environment.disk_memo`: keyed by the inputs and the libraries'
    installs, in a folder of the current sources), so a process that finds it stored imports neither numba
    nor the ephemeris (~1 s of CPU before a campaign's first plan, measured). The same bits either way."""
    o, e = orbit, eclipse
    n = int(round(e.samples_per_orbit * e.orbits)) + 1  # eclipse_profile's sample count (both ends)

    def compute() -> np.ndarray:
        from proxops.environment.eclipse import eclipse_profile as profile  # numba: only when not stored
        from proxops.systems.schema._build_free import target_elements

        t, illum = profile(target_elements(o), o.epoch_utc, n_per_orbit=e.samples_per_orbit, n_orbits=e.orbits,
                           model=e.model)
        return np.stack([t, illum])

    key = digest("cortex_eclipse_profile", o.sma_m, o.ecc, o.inc_deg, o.raan_deg, o.argp_deg, o.nu_deg, o.epoch_utc,
                 e.model, e.samples_per_orbit, e.orbits, _library_stamp())
    got = disk_get("eclipse", key, (2, n), compute)
    return got[0], got[1]


def plan_scenario(sc, axis=None):
    """Plan the reference of a scenario (its axis, or ``axis`` when given)."""
    from proxops.guidance.cortex.reference import plan_reference  # the solvers: not at check time

    cfg = config_from_scenario(sc)
    e = scenario_axis(sc) if axis is None else axis
    return plan_reference(e, cfg, eclipse=eclipse_profile(sc), t0_s=sc.planner.start_delay_s)


def eps_r(g) -> dict:
    return {"hold1": g.recompute_hold1_m, "flyaround": g.recompute_flyaround_m, "hold2": g.recompute_hold2_m,
            "approach": g.recompute_approach_m}


def check_loop(sc) -> None:
    """Input checks of the loop (one clear error each): eps_r > 0, delta_t_g divides Delta_t_g."""
    g = sc.guidance
    substeps(g.dt_g_s, g.substep_s)
    check_navigation(sc)
    for phase, v in eps_r(g).items():
        if not (math.isfinite(v) and v > 0):
            raise input_error(f"guidance.recompute_{phase}_m", v, "must be > 0 (recompute threshold eps_r of Table 1)", "m")
    if sc.actuator.min_on_time_s > g.substep_s:
        raise input_error("actuator.min_on_time_s", sc.actuator.min_on_time_s,
                          f"must not exceed the PWM period guidance.substep_s = {g.substep_s:g} s", "s")
    if not g.terminal_penalty > 0:
        raise input_error("guidance.terminal_penalty", g.terminal_penalty, "must be > 0 (eps_P of eq. 27a)")


def check_navigation(sc) -> None:
    """The navigation keys of the closed loop (see :func:`proxops.systems.cortex_loop.navigation_of`)."""
    e, nav = sc.errors, sc.navigation
    if nav.model == "ekf":
        if e.delta_r_m != 0.0:
            raise input_error("errors.delta_r_m", e.delta_r_m, "must be 0 with navigation.model = ekf (the injection "
                              "errors of Algorithm 3 are the noise option; the filter's sensor sets the errors)", "m")
        from proxops.systems.common import ekf_navigation  # the filter's own checks (numba: ekf scenarios only)

        ekf_navigation(nav, sc.orbit, sc.guidance.substep_s, system="cortex")
        return
    for key in ("position_sigma_m", "velocity_sigma_mps"):
        if getattr(nav, key) != 0.0:
            raise input_error(f"navigation.{key}", getattr(nav, key), "is not used by cortex: give the injection "
                              "errors as errors.delta_r_m (Algorithm 3), or navigation.model = ekf")
