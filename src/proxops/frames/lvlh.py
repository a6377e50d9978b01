"""Hill/RTN <-> V-bar/R-bar LVLH convention of Silva et al. 2026 (sec. 2).

srf LVLH axes: x = V-bar (along the target velocity), y = -orbit normal (negative
angular momentum), z = R-bar (towards the Earth's centre). In Hill/RTN terms
(x radial out, y along-track, z orbit normal):

    x_lvlh =  y_hill,   y_lvlh = -z_hill,   z_lvlh = -x_hill

Both frames share origin and angular velocity, so positions, velocities,
accelerations and dv all transform with the same constant rotation ``HILL_TO_LVLH``
(right-handed: e_x x e_y = e_z). CW in srf LVLH becomes the textbook form
(as in Fehse, *Automated Rendezvous and Docking of Spacecraft*, ch. 3, unforced):
xdd = 2 n zd, ydd = -n^2 y, zdd = 3 n^2 z - 2 n xd.

Use these functions at the edge (scenario input, srf plots); algorithms work in Hill.
"""

from __future__ import annotations

import numpy as np

from proxops.errors import input_error

HILL_TO_LVLH = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, -1.0], [-1.0, 0.0, 0.0]])
"""Rotation with ``v_lvlh = HILL_TO_LVLH @ v_hill``."""
LVLH_TO_HILL = HILL_TO_LVLH.T.copy()

HILL_TO_LVLH_STATE = np.kron(np.eye(2), HILL_TO_LVLH)
"""6x6 map of states: ``x_lvlh = HILL_TO_LVLH_STATE @ x_hill``; a Hill model
(A, B) becomes (T A T^T, T B R^T) with T this matrix and R = HILL_TO_LVLH."""


def hill_to_lvlh(state_hill: np.ndarray) -> np.ndarray:
    """Relative state(s) ``(..., 6)`` from Hill to srf LVLH (m, m/s)."""
    x = np.asarray(state_hill, dtype=float)
    if x.shape[-1:] != (6,):
        raise input_error("state_hill shape", x.shape, "must end in 6")
    return x @ HILL_TO_LVLH_STATE.T


def lvlh_to_hill(state_lvlh: np.ndarray) -> np.ndarray:
    """Relative state(s) ``(..., 6)`` from srf LVLH to Hill (m, m/s)."""
    x = np.asarray(state_lvlh, dtype=float)
    if x.shape[-1:] != (6,):
        raise input_error("state_lvlh shape", x.shape, "must end in 6")
    return x @ HILL_TO_LVLH_STATE


def hill_vector_to_lvlh(vector_hill: np.ndarray) -> np.ndarray:
    """3-vector(s) ``(..., 3)`` (position, velocity, acceleration, dv) Hill -> srf LVLH."""
    v = np.asarray(vector_hill, dtype=float)
    if v.shape[-1:] != (3,):
        raise input_error("vector_hill shape", v.shape, "must end in 3")
    return v @ HILL_TO_LVLH.T


def lvlh_vector_to_hill(vector_lvlh: np.ndarray) -> np.ndarray:
    """3-vector(s) ``(..., 3)`` srf LVLH -> Hill."""
    v = np.asarray(vector_lvlh, dtype=float)
    if v.shape[-1:] != (3,):
        raise input_error("vector_lvlh shape", v.shape, "must end in 3")
    return v @ HILL_TO_LVLH
