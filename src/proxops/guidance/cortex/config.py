"""CORTEX planner configuration (Wijayatunga et al. Table 2) and docking axes (§5.1.1): the light part of
the reference planner (no solver), so a scenario is checked without importing the planner.

Frame: Hill/RTN (x radial out, y along-track, z orbit normal); see :mod:`proxops.guidance.cortex.reference`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from proxops.errors import input_error

PAPER_FIXED_AXIS_HILL = (-math.sin(math.pi / 4), -math.sin(math.pi / 4), 0.0)  # §5.1.2


@dataclass
class CortexConfig:
    """Table 2 parameters in SI units (angles in rad). Inflated values are derived:
    a_bar = thrust_margin a_max, rho_bar = kos_margin r_KOS, alpha_p_bar = plume_margin alpha_p,
    alpha_c_bar = cone_margin alpha_c (§3.1.1-3.1.2)."""

    mean_motion_rad_s: float
    a_max_mps2: float = 2.4e-3
    r_kos_m: float = 15.0
    r_as_m: float = 75.0
    r_rs_m: float = 10_000.0
    plume_half_angle_rad: float = math.radians(20.0)
    cone_half_angle_rad: float = math.radians(10.0)
    thrust_margin: float = 0.8
    kos_margin: float = 1.2
    plume_margin: float = 1.2
    cone_margin: float = 0.5
    tau_lb_s: float = 300.0
    tau_ub_s: float = 3600.0
    tau1_s: float | None = None  # fixed fly-around duration (no search over tau_1); None: eq. 12 search
    tau2_s: float | None = None  # fixed final-approach duration (no search over tau_2); None: eq. 12 search
    convergence_penalty_s: float = 100.0 * 60.0
    dt_cp1_s: float = 30.0
    dt_cp2_s: float = 10.0
    start_state: tuple = (0.0, -37.5, 0.0, 0.0, 0.0, 0.0)
    flyaround_end_range_m: float | None = None  # default rho_bar (Table 2: x_f1 = [rho_bar e, 0])
    approach_end_range_m: float = 1.0  # Table 2: x_f2 = [e, 0]
    approach_end_position_m: tuple | None = None  # explicit x_f2 position (overrides the range)
    kos_max_iter: int = 50
    kos_arc_planes: bool = False  # also plane the deepest coast point of each interval (not in the paper)
    scp_max_iter: int = 30
    scp_tol_mps: float = 1e-5
    plume_tol_rad: float = 1e-4
    search: str = "auto"  # "auto" (as in the module doc) or "scan" (linear scan for both phases)

    @property
    def a_bar(self) -> float:
        return self.thrust_margin * self.a_max_mps2

    @property
    def rho_bar(self) -> float:
        return self.kos_margin * self.r_kos_m

    @property
    def alpha_p_bar(self) -> float:
        return self.plume_margin * self.plume_half_angle_rad

    @property
    def alpha_c_bar(self) -> float:
        return self.cone_margin * self.cone_half_angle_rad

    def validate(self) -> None:
        """One clear error per bad value (field, value, unit, what is allowed)."""
        def pos(name, v, unit=""):
            if not (math.isfinite(v) and v > 0):
                raise input_error(name, v, "must be finite and > 0", unit)

        pos("mean_motion", self.mean_motion_rad_s, "rad/s")
        pos("a_max", self.a_max_mps2, "m/s^2")
        pos("r_kos", self.r_kos_m, "m")
        pos("r_as", self.r_as_m, "m")
        pos("dt_cp1", self.dt_cp1_s, "s")
        pos("dt_cp2", self.dt_cp2_s, "s")
        pos("tau_lb", self.tau_lb_s, "s")
        for name, v in (("alpha_p", self.plume_half_angle_rad), ("alpha_c", self.cone_half_angle_rad)):
            if not (math.isfinite(v) and 0.0 < v < 0.5 * math.pi):
                raise input_error(name, math.degrees(v), "must satisfy 0 < angle < 90", "deg")
        for name, v in (("thrust_margin", self.thrust_margin), ("cone_margin", self.cone_margin)):
            if not (math.isfinite(v) and 0.0 < v <= 1.0):
                raise input_error(name, v, "must satisfy 0 < margin <= 1 (a reduction)")
        for name, v in (("kos_margin", self.kos_margin), ("plume_margin", self.plume_margin)):
            if not (math.isfinite(v) and v >= 1.0):
                raise input_error(name, v, "must be >= 1 (an inflation)")
        if not (0.0 < self.alpha_p_bar < 0.5 * math.pi):
            raise input_error("plume_margin * alpha_p", math.degrees(self.alpha_p_bar), "must be below 90", "deg")
        if self.r_kos_m >= self.r_as_m:
            raise input_error("r_kos", self.r_kos_m, f"must be smaller than r_AS = {self.r_as_m}", "m")
        if not (math.isfinite(self.tau_ub_s) and self.tau_lb_s <= self.tau_ub_s):
            raise input_error("tau_lb", self.tau_lb_s, f"must not exceed tau_ub = {self.tau_ub_s}", "s")
        for name, v in (("tau1", self.tau1_s), ("tau2", self.tau2_s)):
            if v is not None:
                pos(name, v, "s")
        if self.search not in ("auto", "scan"):
            raise input_error("search", self.search, "allowed: auto, scan")
        x0 = np.asarray(self.start_state, float)
        if x0.shape != (6,) or not np.all(np.isfinite(x0)):
            raise input_error("start state", list(np.ravel(x0)), "must be 6 finite numbers [r (m), v (m/s)]")
        r0 = float(np.linalg.norm(x0[:3]))
        if r0 <= self.rho_bar:
            raise input_error("start position", x0[:3].tolist(),
                              f"range {r0:.3f} m is inside the keep-out sphere used for planning "
                              f"(kos_margin x r_KOS = {self.rho_bar:.3f} m)", "m")
        if self.flyaround_end_range_m is not None:
            pos("flyaround_end_range", self.flyaround_end_range_m, "m")
            if self.flyaround_end_range_m < self.rho_bar:
                raise input_error("flyaround_end_range", self.flyaround_end_range_m,
                                  f"must be >= the inflated KOS radius {self.rho_bar:.3f}", "m")
        pos("approach_end_range", self.approach_end_range_m, "m")


def fibonacci_axes(n: int) -> np.ndarray:
    """N unit axes on a spherical Fibonacci lattice (Keinert et al. 2015, ref. 11), (n, 3) in Hill:
    z_i = 1 - (2i + 1)/n, phi_i = 2 pi i / golden ratio, axis = [sqrt(1-z^2) cos phi, sqrt(1-z^2) sin phi, z]."""
    if isinstance(n, bool) or int(n) != n or n < 1:
        raise input_error("n", n, "must be a whole number >= 1")
    n = int(n)
    i = np.arange(n)
    z = 1.0 - (2.0 * i + 1.0) / n
    phi = 2.0 * math.pi * i / ((1.0 + math.sqrt(5.0)) / 2.0)
    rho = np.sqrt(np.maximum(0.0, 1.0 - z * z))
    return np.column_stack([rho * np.cos(phi), rho * np.sin(phi), z])


def unit_axis(axis) -> np.ndarray:
    e = np.asarray(axis, dtype=float)
    if e.shape != (3,) or not np.all(np.isfinite(e)):
        raise input_error("axis", np.ravel(axis).tolist(), "must be 3 finite numbers (Hill x, y, z)")
    norm = float(np.linalg.norm(e))
    if norm < 1e-9:
        raise input_error("axis", e.tolist(), "must have a non-zero length (it is normalised)")
    return e / norm
