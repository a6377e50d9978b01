"""The paper's relative model against the direct two-rigid-body truth (Basu et al.
§IV): the agreement numbers behind ``proxops reproduce hybrid`` and
benchmarks/bench_hybrid_physics.py.

The truth (dynamics/two_rigid_bodies.py: CW translation of both bodies, eq. 21 with the
corrected G2, Euler eqs. 23-24) is integrated over a tumbling arc, mapped to the paper's
32-state (``relative_from_truth``), and compared with the state obtained by integrating the
relative model f_0 (eq. 32) directly, once with our corrections and once with eq. 21's printed
G2 (``corrected=False``).
"""

from __future__ import annotations

import numpy as np

from proxops.dynamics.hybrid_relative import (
    S_OM,
    S_OMC,
    S_P,
    S_Q,
    S_RHO,
    S_RHOD,
    S_RN,
    S_RND,
    relative_from_truth,
    relative_rhs,
)
from proxops.dynamics.two_rigid_bodies import HybridInitialState, HybridParams, propagate_truth, truth_state_from_initial

#: the blocks compared, with their units
AGREEMENT_BLOCKS = (("rho [m]", S_RHO), ("rho_dot [m/s]", S_RHOD), ("omega [rad/s]", S_OM), ("q [-]", S_Q),
                    ("p [-]", S_P), ("omega_c [rad/s]", S_OMC), ("rho_n [m]", S_RN),
                    ("rho_n_dot [m/s]", S_RND))  # fmt: skip

#: a tumbling test arc: 3.9 deg/s chief tumble, eq. 78 deputy rates
TUMBLE = HybridInitialState(omega_c_rad_s=(0.05, -0.03, 0.04))


def test_input(t, x=None) -> np.ndarray:
    """A smooth time-varying (F_d|_D [N], M_d|_D [N m]) so the input terms are exercised."""
    return np.array([0.3 * np.sin(0.1 * t), 0.2, -0.1 * np.cos(0.05 * t), 0.05, -0.02 * np.sin(0.2 * t), 0.01])


test_input.__test__ = False  # not a pytest test


def relative_model_agreement(duration_s: float = 100.0, samples: int = 201, params: HybridParams | None = None,
                             initial: HybridInitialState = TUMBLE):
    """(t [s], truth relative states (samples, 32), {True: |error| corrected, False: |error| printed G2}).

    Both integrations use scipy's DOP853 at rtol 1e-11, atol 1e-12; quaternion blocks are
    compared up to sign (q and -q are one attitude)."""
    from scipy.integrate import solve_ivp

    P = params or HybridParams()
    ts = np.linspace(0.0, duration_s, samples)
    truth = propagate_truth(truth_state_from_initial(P, initial), (ts[0], ts[-1]), P, u_of_t=test_input, t_eval=ts)
    X = np.array([relative_from_truth(truth.y[:, k], P) for k in range(ts.size)])
    errors = {}
    for corrected in (True, False):
        rel = solve_ivp(lambda t, y: relative_rhs(y, test_input(t), P, corrected), (ts[0], ts[-1]), X[0],
                        method="DOP853", rtol=1e-11, atol=1e-12, t_eval=ts)  # fmt: skip
        Y = rel.y.T.copy()
        for sl in (S_Q, S_P):
            Y[:, sl] *= np.sign(np.sum(X[:, sl] * Y[:, sl], axis=1))[:, None]
        errors[corrected] = np.abs(X - Y)
    return ts, X, errors


def block_maxima(errors: np.ndarray) -> dict[str, float]:
    """Largest |error| over the arc per block of :data:`AGREEMENT_BLOCKS`."""
    return {name: float(errors[:, sl].max()) for name, sl in AGREEMENT_BLOCKS}
