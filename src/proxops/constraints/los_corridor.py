"""Polyhedral line-of-sight (LOS) docking corridor of a tumbling target.

Iskender 2026 §5, eq. (9): a cone in the target body frame F_B with
axis +y_B and half-angle alpha_c, approximated by ``n_faces`` half-spaces plus a floor::

    face i (i = 0..n_faces-1):  cos(th_i) x_B + sin(th_i) z_B - tan(alpha_c) y_B <= 0,
                                th_i = 2 pi i / n_faces
    floor:                      -y_B <= -y_min

written as ``G p_B <= h`` with ``G`` of shape (n_faces + 1, 3). The rows are the
paper's raw rows (not normalised), so a face residual ``G_i p - h_i`` is in metres but
equals the Euclidean distance to the face plane divided by cos(alpha_c). The 8 faces
circumscribe the circular cone (every point of the circular cone satisfies them).

Public API (also used by the reachability analysis)::

    c = LosCorridor()                      # 30 deg, y_min = 1 m, 8 faces, tol 1e-3 m
    c.G, c.h                               # solver rows, G p_B <= h (body frame)
    c.slack_body(p_B)                      # h - G p_B per row (>= 0 inside), m
    c.violation_body(p_B)                  # max(0, max_i(G p_B - h)_i), m
    c.is_violated_body(p_B)                # violation > tolerance_m (paper eq. 9, §9.3)
    c.violation(t, x_rel)                  # engine constraint hook, see ``frame``
    c.rows_in_frame(R_BF)                  # rows for positions in another frame F
    body_position(p_F, R_BF)               # p_B = R_BF p_F

``frame``: ``"body"`` (default) means the state handed to :meth:`violation` is already
the body-frame relative state ``[r_B, v_B]`` (eqs. 7-8) - this is what the ``los``
system's plant reports. Otherwise pass ``rotation_body_from_frame(t) -> R_BF (3x3)``
and the position ``x_rel[:3]`` (e.g. Hill/LVLH) is rotated into F_B first (eq. 10).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numba import njit

from proxops.errors import input_error

PAPER_TOLERANCE_M = 1e-3  # §9 step 3: a violation counts when it exceeds 1e-3 m


def corridor_rows(half_angle_rad: float, y_min_m: float, n_faces: int = 8) -> tuple[np.ndarray, np.ndarray]:
    """Rows (G, h) of eq. (9): ``n_faces`` cone faces then the floor ``y_B >= y_min``."""
    theta = 2.0 * np.pi * np.arange(n_faces) / n_faces
    G = np.zeros((n_faces + 1, 3))
    G[:n_faces, 0] = np.cos(theta)
    G[:n_faces, 1] = -np.tan(half_angle_rad)
    G[:n_faces, 2] = np.sin(theta)
    G[n_faces] = [0.0, -1.0, 0.0]
    h = np.zeros(n_faces + 1)
    h[n_faces] = -y_min_m
    # round-off of cos/sin(pi/2) etc. to exact zeros keeps the rows tidy for solvers
    G[np.abs(G) < 1e-15] = 0.0
    return G, h


def body_position(p_frame: np.ndarray, rotation_body_from_frame: np.ndarray) -> np.ndarray:
    """p_B = R_BF p_F for one position (3,) or many (n, 3) (eq. 7 without translation)."""
    p = np.asarray(p_frame, dtype=float)
    return p @ np.asarray(rotation_body_from_frame).T


class LosCorridor:
    """Body-frame polyhedral LOS corridor (eq. 9) with solver rows and violation checks.

    Parameters: ``half_angle_rad`` (0, pi/2), ``y_min_m`` >= 0 floor distance (m),
    ``n_faces`` >= 3, ``tolerance_m`` violation tolerance (m), ``frame`` of the state
    passed to :meth:`violation` (see module doc), ``rotation_body_from_frame`` t -> R_BF.
    """

    name = "los_corridor"

    def __init__(
        self,
        half_angle_rad: float = np.radians(30.0),
        y_min_m: float = 1.0,
        n_faces: int = 8,
        tolerance_m: float = PAPER_TOLERANCE_M,
        frame: str = "body",
        rotation_body_from_frame: Callable[[float], np.ndarray] | None = None,
    ):
        if not 0.0 < half_angle_rad < np.pi / 2:
            raise input_error("corridor.half_angle", half_angle_rad, "must be in (0, pi/2)", "rad")
        if not y_min_m >= 0.0:
            raise input_error("corridor.y_min_m", y_min_m, "must be >= 0", "m")
        if int(n_faces) != n_faces or n_faces < 3:
            raise input_error("corridor.n_faces", n_faces, "must be an integer >= 3")
        if not tolerance_m >= 0.0:
            raise input_error("corridor.tolerance_m", tolerance_m, "must be >= 0", "m")
        if frame != "body" and rotation_body_from_frame is None:
            raise input_error(
                "corridor.frame", frame, "a non-body frame needs rotation_body_from_frame(t) -> R_BF"
            )
        self.half_angle_rad = float(half_angle_rad)
        self.y_min_m = float(y_min_m)
        self.n_faces = int(n_faces)
        self.tolerance_m = float(tolerance_m)
        self.frame = frame
        self.rotation_body_from_frame = rotation_body_from_frame
        self.G, self.h = corridor_rows(self.half_angle_rad, self.y_min_m, self.n_faces)

    @property
    def n_rows(self) -> int:
        return self.G.shape[0]

    def slack_body(self, p_body: np.ndarray) -> np.ndarray:
        """Per-row slack ``h - G p_B`` (m); >= 0 inside. Shape (n_rows,) or (n, n_rows)."""
        return self.h - np.asarray(p_body, dtype=float) @ self.G.T

    def violation_body(self, p_body: np.ndarray) -> float | np.ndarray:
        """Largest row excess ``max(0, max_i (G p_B - h)_i)`` (m); array for (n, 3) input."""
        excess = np.max(-self.slack_body(p_body), axis=-1)
        return np.maximum(excess, 0.0)

    def is_violated_body(self, p_body: np.ndarray) -> bool | np.ndarray:
        """True where the violation exceeds ``tolerance_m`` (paper §9 classification)."""
        return self.violation_body(p_body) > self.tolerance_m

    def contains_body(self, p_body: np.ndarray) -> bool | np.ndarray:
        """True where every row holds to ``tolerance_m``."""
        return ~np.asarray(self.is_violated_body(p_body))

    def rows_in_frame(self, rotation_body_from_frame: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Rows for a position in frame F: ``G R_BF p_F <= h`` (eq. 10 with R_BF = R_z(-w t))."""
        return self.G @ np.asarray(rotation_body_from_frame), self.h.copy()

    def violation(self, t: float, x_rel: np.ndarray) -> float:
        """Engine hook: violation (m) of the relative state at time t (s), >0 means outside."""
        p = np.asarray(x_rel, dtype=float)
        if self.frame != "body":
            p = self.rotation_body_from_frame(t) @ p[:3]
        return _max_row_excess(self.G, self.h, p)  # = violation_body(p[:3]), one point, one jitted call

    def __repr__(self) -> str:
        return (
            f"LosCorridor(half_angle_deg={np.degrees(self.half_angle_rad):g}, y_min_m={self.y_min_m:g}, "
            f"n_faces={self.n_faces}, tolerance_m={self.tolerance_m:g}, frame={self.frame!r})"
        )


@njit(cache=True)
def _max_row_excess(G, h, p):  # pragma: no cover - compiled
    """max(0, max_i (G p - h)_i) for the position p[:3] (m); p may be the whole state."""
    worst = 0.0
    for i in range(G.shape[0]):
        e = G[i, 0] * p[0] + G[i, 1] * p[1] + G[i, 2] * p[2] - h[i]
        if e > worst:
            worst = e
    return worst
