"""Fixed-step Adams-Bashforth-Moulton (PECE) integrator for the composed truth, with the
spherical-harmonic field evaluated once per step.

Why: DOP853 spends 12 right-hand-side evaluations per step, i.e. 24 evaluations of the
100x100 field (target and chaser) per step of ~50 s. A multistep method re-uses the past
derivatives: predictor (Adams-Bashforth, order k), one evaluation, corrector
(Adams-Moulton, order k + 1, on the same history), one evaluation at the corrected state
(PECE; Hairer, Norsett & Wanner, *Solving ODEs I*, sec. III.1; Montenbruck & Gill,
*Satellite Orbits*, sec. 4.2.3-4.2.4, the standard for precise orbit propagation).

Rate split (candidate b): the harmonics n >= 2 are evaluated only at the
predicted state P; the final E re-evaluates the cheap part (point mass, Encke
differential, drag, Sun, Moon, SRP) at the corrected state and re-uses the harmonic
accelerations of P. P and the corrected state differ by the local truncation error
(< 1e-6 m here) and the harmonic part's gradient is < 3e-9 1/s^2 (J2-dominated), so this
changes the stored derivative by < 3e-15 m/s^2: two 100x100 evaluations per step instead
of four (measured effect on the relative state: tests/test_propagation_multistep.py).

Start (without look-ahead; with it, see below): the first k nodes t_0 + j h (j < k)
as one implicit block (collocation: the state at each node is y_0 plus h times the integral
of the degree k - 1 polynomial through the k
derivatives), solved by fixed-point iteration from a DOP853 guess with the field truncated
to 20x20 (replaces k - 1 DOP853 steps of 12). Converged when the last change of the
positions and of (k - 1) h times the velocities is below START_TOL_* (a velocity change
reaches the positions one iteration later: a test on the positions alone stopped after one
iteration for k >= 7, 0.4 mm off at 20 km, 18 mm after two orbits). With the rate split the
harmonics are evaluated twice per node: at the guess (pass 0, iterated to convergence with
the cheap part only), then at pass 0's converged nodes (pass 1, iterated again); the guess
is off by ~5 mm (target) and the harmonic part's gradient is < 3e-9 1/s^2, so pass 1's
harmonics are off by < 1e-13 m/s^2 (2 (2k - 1) field evaluations instead of ~2 (k + 3 (k - 1))).
Sample times between steps: the corrector polynomial (through f_{n+1}, ..., f_{n-k+1})
integrated from t_n to t_n + theta h (same order as the corrector).

Order and step (benchmarks/bench_truth_steps.py; 100x100 + drag with A/m 0.004 / 0.015
m^2/kg + Sun/Moon, 500 km, relative position vs the DOP853 loop at rtol 1e-13, worst of one
and two orbits; 2026-11-23). The error comes from the harmonics: a term of frequency omega
(up to ~0.1 rad/s for degree 100 along the track) is integrated with a relative error that
grows like (omega h)^(k+1) up to omega h ~ 1 and then with the size of the Adams weights
(larger for larger k), and a velocity error of such a term turns into an along-track drift;
the terms' phases depend on the geometry, so the error at 20 km over 15 geometries
(inclination 28.5-97.5 deg, node, argument of latitude, epoch 2020-2025) is:

    k   h (s)  field evaluations / orbit   median    90 %     worst (mm)
    6   20      580                        0.34      4.4      17.5   (the former default)
    6   15      770                        0.15      1.2       2.0
    8   15      774                        0.18      0.52      2.3
    6   12      960                        0.058     0.14      0.32
   10   13       894                       0.050     0.15      0.28
   12   13       898                       0.052     0.31      0.47
   10   12      968                        0.030     0.067     0.22
   12   12      972                        0.030     0.097     0.11   (cheapest < 0.3 mm without look-ahead)
    6   11     1046                        0.024     0.076     0.16
    6   10     1148                        0.014     0.040     0.075

(at the bench's geometry alone order 6 at 20 s gave 0.06 mm at 20 km: one geometry does not
choose a step). Without look-ahead, order 12 at 12 s is the cheapest with < 0.3 mm in every
geometry (worst 0.0054 / 0.013 / 0.016 / 0.11 mm at 1 m / 100 m / 2 km / 20 km; at 20 km with
40x40, 60x60 and 80x80 fields < 0.03 mm). Orders 10-12 at 40-60 s are unstable (order 12 at
60 s stops with a non-finite state).

Look-ahead quadrature of the harmonics (the default, ``lookahead`` = (4, 5)): the harmonic
acceleration g(t) (target; chaser - target) depends on the state only through the gradient
(< 3e-9 1/s^2), so it is treated as a forcing known along the path: g at node n + 5 is
evaluated at positions extrapolated 5 steps ahead from the derivative history (~mm off for
the target, which moves g by < 1e-11 m/s^2 and the differenced g far less), and the velocity
increment over [t_n, t_n+1] integrates g with the 10 nodes n - 4 .. n + 5 (centred on the
step), the rest of the RHS by ABM PECE as above. A centred quadrature's relative error on a
sinusoid is far smaller than the one-sided Adams corrector's (at omega h = 1: 1.2e-4 against
9.3e-3 for order 6; at omega h = 1.5: 4.8e-3 against 0.12). Same 15 geometries, 20 km,
worst of one and two orbits (order 6; measured with the former DOP853 start below):

    h (s)  field evaluations / orbit   median    90 %     worst (mm)
    18      764                        0.032     0.10      0.13   (default, DOP853 start)
    20      700                        0.082     0.15      0.45
    22      650                        0.15      0.25      0.68
    24      606                        0.23      0.58      0.95

Start with look-ahead (:func:`_start_lookahead`): a collocation polynomial through the full
derivatives would alias g as the Adams corrector does, so the block splits them as the march
does: the derivatives without g by the collocation above, g by the same centred quadrature
(the step j -> j + 1 on the nodes j - 4 .. j + 5, so nodes before t_0 too). g is evaluated
(pass 1) at positions from a guess: DOP853 with the field truncated to 20x20 on the nodes
0 .. k - 1 (~1 cm off for the target, ~1 mm in relative position at 20 km), the nodes
outside the block by the guess's velocity polynomial integrated; the block is iterated to
convergence; then (pass 2) g again at the converged nodes 1 .. k - 1 and at the nodes
k .. k + 3 extrapolated from the block as in the march, and the block iterated again.
Pass 2 is needed: with pass 1 alone (g at the guess's cm-off positions) the 20 km errors
below changed by up to 0.03 mm in single geometries (worst 0.088 mm); refreshing the four
nodes before t_0 as well changed nothing at 1e-7 mm (their weights are small and they only
enter the block's steps). Cost: 2 x (14 + 9 + 1) = 48 field evaluations (the first node
ahead of the march included) and 5 DOP853 steps (one per node interval) of the 20x20 field,
against 144 for the former start (DOP853 with the full field on the first k nodes). At the block's nodes (18 s,
100x100, 20 km, against DOP853 at rtol 1e-13 sampled every 0.5 s) it is 4.2e-7 m / 1.4e-9
m/s off in the relative state: the quadrature's error on the degree 40-100 terms, as in any
5 steps of the march (the former start's nodes were exact to 2e-11 m, its dense output
between them aliased: 2.4e-8 m/s); a velocity error of 1e-9 m/s is an along-track drift of
~0.03 mm after two orbits, so the per-geometry errors at 20 km changed by up to 0.06 mm
either way. Default (order 6, 18 s, look-ahead (4, 5)), worst of one and two orbits over the
15 geometries (benchmarks/bench_truth_steps.py ``--default``; 2026-11-23):

    separation   former start (DOP853, 764 field evaluations / orbit)   this start (668)
                 median    90 %     worst (mm)                          median    90 %     worst (mm)
    20 km        0.032     0.10     0.13                                0.022     0.069    0.078
    2 km         0.0046    0.012    0.027                               0.0044    0.010    0.029
    100 m        0.0025    0.0098   0.013                               0.0027    0.010    0.013
    1 m          0.0012    0.0042   0.013                               0.0011    0.0039   0.013

Coefficients: w_j(theta) = int_0^theta L_j(s) ds for the Lagrange basis L_j on the nodes
s_j (units of h from t_n; AB: 0, -1, ..., -(k-1); AM: 1, 0, ..., -(k-1)), computed exactly
in rational arithmetic by :func:`adams_coefficients` (a test checks the classical
AB/AM values, e.g. AB4 = (55, -59, 37, -9)/24).
"""

from __future__ import annotations

import math
from fractions import Fraction
from functools import lru_cache

import numpy as np
from numba import njit

from proxops.propagation import kernels_full as kf
from proxops.propagation.kernels import STATUS_NOT_FINITE, STATUS_OK

DEFAULT_ORDER = 6  # Adams-Bashforth order k (corrector k + 1); chosen by measurement (module doc)
DEFAULT_STEP_S = 18.0  # fixed step (s); chosen by measurement over 15 geometries (module doc)
DEFAULT_LOOKAHEAD = (4, 5)  # look-ahead quadrature of the harmonics: nodes before / after t_n ((0, 0): off)
MIN_STEPS = 3  # spans shorter than MIN_STEPS * k steps use DOP853 (the start-up would dominate)
GUESS_DEGREE = 20.0  # start-up guess: the field truncated to this degree and order
MAX_START_ITERATIONS = 12
START_TOL_TARGET_M = 1e-6  # start-up iteration: last change of the target position (m) ...
START_TOL_RELATIVE_M = 1e-10  # ... and of the chaser offset (m)
STATUS_START_NOT_CONVERGED = 4
START_PASSES_LOOKAHEAD = 2  # evaluations of g at the start-up block's nodes (module doc)


def _lagrange_integrals(nodes: list[int]) -> list[list[Fraction]]:
    """Q[j][p]: int_0^theta L_j(s) ds = sum_p Q[j][p] theta^(p + 1) (exact)."""
    out = []
    for j, sj in enumerate(nodes):
        poly = [Fraction(1)]  # coefficients in s, lowest first
        denom = Fraction(1)
        for i, si in enumerate(nodes):
            if i == j:
                continue
            poly = [Fraction(0)] + poly  # * s
            for q in range(len(poly) - 1):
                poly[q] -= si * poly[q + 1]
            denom *= sj - si
        out.append([c / denom / (q + 1) for q, c in enumerate(poly)])
    return out


@lru_cache(maxsize=None)
def adams_coefficients(order: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(beta_AB (k,), beta_AM (k + 1,), Q (k + 1, k + 1), Q0 (k, k)) for AB order k = ``order``:
    y_p = y_n + h sum_j beta_AB[j] f_{n-j}; y_c = y_n + h (beta_AM[0] f_{n+1} +
    sum_j beta_AM[j + 1] f_{n-j}); dense output y(t_n + theta h) = y_n + h sum_j
    (sum_p Q[j, p] theta^(p + 1)) f_{n+1-j}; start-up block on the nodes t_0 + i h,
    i = 0..k-1: y(t_0 + s h) = y_0 + h sum_i (sum_p Q0[i, p] s^(p + 1)) f_i, and G0 (k, k) its
    weights at the nodes, G0[j, i] = sum_p Q0[i, p] j^(p + 1), summed exactly (in floating
    point the monomial sum loses ~1e-10 relative at j = 9)."""
    k = int(order)
    ab = _lagrange_integrals([-j for j in range(k)])
    am = _lagrange_integrals([1] + [-j for j in range(k)])
    beta_ab = np.array([float(sum(q)) for q in ab])
    beta_am = np.array([float(sum(q)) for q in am])
    Q = np.array([[float(c) for c in q] for q in am])
    q0 = _lagrange_integrals(list(range(k)))
    Q0 = np.array([[float(c) for c in q] for q in q0])
    G0 = np.array([[float(sum(c * Fraction(j) ** (p + 1) for p, c in enumerate(q))) for q in q0] for j in range(k)])
    return beta_ab, beta_am, Q, Q0, G0


@lru_cache(maxsize=None)
def lookahead_coefficients(order: int, before: int, after: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """Look-ahead quadrature of the harmonic forcing (module doc): (Q_ab (k, k), c (m,),
    Q_g (m, m), before) with m = before + after + 1 nodes s = -before .. after (units of h from
    t_n): the velocity increment over [t_n, t_n + theta h] is h sum_i (sum_p Q_g[i, p]
    theta^(p + 1)) g(t_n + s_i h), c = those weights at theta = 1; Q_ab integrates the
    derivative history (nodes 0, -1, .., -(k - 1)) to extrapolate the positions at which g
    is evaluated. ``before`` = 0: no look-ahead (empty arrays)."""
    k = int(order)
    if before == 0:
        return np.zeros((k, k)), np.zeros(0), np.zeros((0, 0)), 0
    if not 0 < before <= k - 1 or after < 1:
        raise ValueError("look-ahead needs 0 < before <= order - 1 and after >= 1")
    ab = _lagrange_integrals([-j for j in range(k)])
    g = _lagrange_integrals(list(range(-before, after + 1)))
    Q_ab = np.array([[float(c) for c in q] for q in ab])
    c = np.array([float(sum(q)) for q in g])
    Q_g = np.array([[float(c_) for c_ in q] for q in g])
    return Q_ab, c, Q_g, int(before)


@njit(cache=True)
def _rhs_split(t, y, u, p, p_cheap, npm, C, S, K, V, W, dens, harm, new_harm, out) -> None:
    """Composed RHS (12,) with the harmonic accelerations (target, chaser; ECI, m/s^2) in
    ``harm[:6]`` and the Sun and Moon (m) in ``harm[6:]`` (12,): evaluated at (t, y) when
    ``new_harm``, else re-used (the Sun and Moon depend on t only: re-used at the same t)."""
    if new_harm:
        harm[0], harm[1], harm[2], harm[3], harm[4], harm[5] = kf._harmonics_eci_pair(
            t, y[0], y[1], y[2], y[0] + y[6], y[1] + y[7], y[2] + y[8], p, npm, C, S, K, V, W
        )
        sun, moon = kf.third_bodies(t, p)
        harm[6], harm[7], harm[8] = sun
        harm[9], harm[10], harm[11] = moon
    sun = (harm[6], harm[7], harm[8])
    moon = (harm[9], harm[10], harm[11])
    kf.rhs_full_sun_moon(t, y, u, p_cheap, npm, C, S, K, V, W, dens, sun, moon, out)
    out[3] += harm[0]
    out[4] += harm[1]
    out[5] += harm[2]
    out[9] += harm[3] - harm[0]
    out[10] += harm[4] - harm[1]
    out[11] += harm[5] - harm[2]


@njit(cache=True)
def _rhs(t, y, u, p, p_cheap, split, npm, C, S, K, V, W, dens, harm, new_harm, out) -> None:
    if split:
        _rhs_split(t, y, u, p, p_cheap, npm, C, S, K, V, W, dens, harm, new_harm, out)
    else:
        kf.rhs_full(t, y, u, p, npm, C, S, K, V, W, dens, out)


@njit(cache=True)
def _poly_weights(Q, s, out) -> None:
    """out[j] = sum_q Q[j, q] s^(q + 1) (Horner)."""
    for j in range(Q.shape[0]):
        w = 0.0
        for q in range(Q.shape[1] - 1, -1, -1):
            w = w * s + Q[j, q]
        out[j] = w * s


@njit(cache=True)
def _block_sweep(y0, h, G, F, ys, dv, add_dv, span) -> tuple:
    """One fixed-point sweep of the start-up block: ys[j] = y0 + h sum_q G[j, q] F[q] for the
    nodes j = 1 .. k - 1 (plus, if ``add_dv``, the look-ahead velocity increments dv[j] (k, 6):
    target velocity in columns 0-2, chaser offset velocity in 3-5). Returns the largest change
    of the target and of the chaser offset, positions in m and velocities times ``span`` (s; a
    velocity change moves the positions by up to span times it in the next sweep)."""
    k = G.shape[0]
    n = y0.size
    change_t = 0.0
    change_r = 0.0
    for j in range(1, k):
        for i in range(n):
            acc = 0.0
            for q in range(k):
                acc += G[j, q] * F[q, i]
            val = y0[i] + h * acc
            if add_dv and i % 6 >= 3:
                val += dv[j, (i // 6) * 3 + i % 6 - 3]
            change = abs(val - ys[j, i]) * (1.0 if (i % 6) < 3 else span)
            if i < 6:
                change_t = max(change_t, change)
            else:
                change_r = max(change_r, change)
            ys[j, i] = val
    return change_t, change_r


@njit(cache=True)
def integrate_multistep(y0, times, u, p, npm, C, S, K, V, W, dens, h, beta_ab, beta_am, Q, Q0, G, Q_ab, c_g, Q_g,
                        before, split, rtol, atol, out) -> tuple:  # fmt: skip
    """Integrate through increasing absolute ``times`` (s after the epoch; times[0] = start)
    with fixed steps ``h`` (s) of ABM PECE (order k = beta_ab.size), storing the state at
    each time in ``out``. ``split``: harmonics once per step (module doc); with ``c_g`` non-empty
    (and ``split``) they are integrated with the look-ahead quadrature (:func:`_march_lookahead`,
    coefficients from :func:`lookahead_coefficients`). The start-up block
    (module doc) takes its guess from :func:`kernels_full.integrate_full` at ``rtol``, ``atol``.
    Returns (status, n_steps, n_rhs, n_field): steps, right-hand-side evaluations and
    evaluations of the full harmonic field (target and chaser counted apart; 0 without
    harmonics; the start-up guess's 20x20 evaluations are not in n_field)."""
    n = y0.size
    m = times.size
    k = beta_ab.size
    for i in range(n):
        out[0, i] = y0[i]
    if m == 1 or times[m - 1] <= times[0]:
        for j in range(1, m):
            for i in range(n):
                out[j, i] = y0[i]
        return STATUS_OK, 0, 0, 0
    if times[m - 1] < times[0] + (k - 1) * h:  # shorter than the start-up: DOP853 only
        status, n_dop, n_rej = kf.integrate_full(y0, times, u, p, npm, C, S, K, V, W, dens, rtol, atol, out)
        n_rhs = 12 * (n_dop + n_rej) + 1
        return status, n_dop, n_rhs, 2 * n_rhs if p[kf.I_GRAV] == 2.0 else 0
    p_cheap = p.copy()
    p_cheap[kf.I_GRAV] = 0.0
    harm = np.zeros(12)
    # history: F[j] = f at t_n - j h (ring buffer: row (head + j) % (k + 1)); Y: state at t_n
    F = np.empty((k + 1, n))
    t0 = times[0]
    grid = np.empty(k)
    for j in range(k):
        grid[j] = t0 + j * h
    # start-up: the implicit block y_j = y_0 + h sum_i G[j, i] f_i on the k nodes (collocation with
    # the degree k - 1 polynomial of f), by fixed-point iteration from a guess with the field
    # truncated to 20x20 (DOP853); contraction ~ n^2 ((k - 1) h)^2 ~ 0.04 per iteration
    p_guess = p.copy()
    if p[kf.I_GRAV] == 2.0:
        p_guess[kf.I_NMAX] = min(p[kf.I_NMAX], GUESS_DEGREE)
        p_guess[kf.I_MMAX] = min(p[kf.I_MMAX], GUESS_DEGREE)
    ys = np.empty((k, n))
    lookahead = split and p[kf.I_GRAV] == 2.0 and c_g.size > 0
    if lookahead:  # the start-up block's collocation polynomial would alias g: start with the quadrature of g too
        return _start_lookahead(y0, times, out, u, p, p_cheap, p_guess, npm, C, S, K, V, W, dens, h, beta_ab, beta_am,
                                Q, Q0, G, Q_ab, c_g, Q_g, before, rtol, atol)  # fmt: skip
    status, n_guess, n_guess_rej = kf.integrate_full(y0, grid, u, p_guess, npm, C, S, K, V, W, dens, rtol, atol, ys)
    if status != STATUS_OK:
        return status, 0, 0, 0
    Fs = np.empty((k, n))
    Hs = np.zeros((k, 12))  # harmonic accelerations, Sun and Moon at each node (split)
    for j in range(k):
        _rhs(grid[j], ys[j], u, p, p_cheap, split, npm, C, S, K, V, W, dens, Hs[j], True, Fs[j])
    n_full = k  # evaluations with the full field (the guess's truncated ones are counted in n_rhs only)
    n_cheap = 0
    span = (k - 1) * h
    # split: pass 0 with the harmonics at the guess, pass 1 with them at pass 0's nodes (module doc)
    for start_pass in range(2 if split else 1):
        if start_pass == 1:
            for j in range(1, k):
                _rhs(grid[j], ys[j], u, p, p_cheap, split, npm, C, S, K, V, W, dens, Hs[j], True, Fs[j])
            n_full += k - 1
        converged = False
        for _ in range(MAX_START_ITERATIONS):
            change_t, change_r = _block_sweep(y0, h, G, Fs, ys, Fs, False, span)
            for j in range(1, k):
                _rhs(grid[j], ys[j], u, p, p_cheap, split, npm, C, S, K, V, W, dens, Hs[j], not split, Fs[j])
            if split:
                n_cheap += k - 1
            else:
                n_full += k - 1
            if change_t < START_TOL_TARGET_M and change_r < START_TOL_RELATIVE_M:
                converged = True
                break
        if not converged:
            return STATUS_START_NOT_CONVERGED, 0, n_full + n_cheap, 0
    wts0 = np.empty(k)
    idx = 1
    while idx < m and times[idx] <= grid[k - 1]:  # samples inside the start-up block
        _poly_weights(Q0, (times[idx] - t0) / h, wts0)
        for i in range(n):
            acc = 0.0
            for q in range(k):
                acc += wts0[q] * Fs[q, i]
            out[idx, i] = y0[i] + h * acc
        idx += 1
    head = 0
    for j in range(k):  # F[j] = f(t_{k-1-j}), the newest first
        for i in range(n):
            F[j, i] = Fs[k - 1 - j, i]
    n_rhs = n_full + n_cheap + 12 * (n_guess + n_guess_rej) + 1
    harmonics = p[kf.I_GRAV] == 2.0
    n_field = 2 * n_full if harmonics else 0
    field_per_step = 0 if not harmonics else (2 if split else 4)
    t_n = grid[k - 1]
    y = ys[k - 1].copy()
    yp = np.empty(n)
    yc = np.empty(n)
    fp = np.empty(n)
    wts = np.empty(k + 1)
    n_steps = k - 1
    while idx < m:
        # P: Adams-Bashforth
        for i in range(n):
            acc = 0.0
            for j in range(k):
                acc += beta_ab[j] * F[(head + j) % (k + 1), i]
            yp[i] = y[i] + h * acc
        t_next = t0 + (n_steps + 1) * h
        _rhs(t_next, yp, u, p, p_cheap, split, npm, C, S, K, V, W, dens, harm, True, fp)
        # C: Adams-Moulton with f_p
        for i in range(n):
            acc = beta_am[0] * fp[i]
            for j in range(k):
                acc += beta_am[j + 1] * F[(head + j) % (k + 1), i]
            yc[i] = y[i] + h * acc
        # E: the new derivative goes in front of the history
        head = (head + k) % (k + 1)
        _rhs(t_next, yc, u, p, p_cheap, split, npm, C, S, K, V, W, dens, harm, False, F[head])
        n_rhs += 2
        n_field += field_per_step
        n_steps += 1
        if not math.isfinite(yc[0] + yc[6]):
            return STATUS_NOT_FINITE, n_steps, n_rhs, n_field
        # samples in (t_n, t_next]: corrector polynomial through f_{n+1} .. f_{n-k+1}
        while idx < m and times[idx] <= t_next:
            _poly_weights(Q, (times[idx] - t_n) / h, wts)
            for i in range(n):
                acc = 0.0
                for j in range(k + 1):
                    acc += wts[j] * F[(head + j) % (k + 1), i]
                out[idx, i] = y[i] + h * acc
            idx += 1
        t_n = t_next
        for i in range(n):
            y[i] = yc[i]
    return STATUS_OK, n_steps, n_rhs, n_field


@njit(cache=True)
def _march_lookahead(times, idx, out, u, p, p_cheap, npm, C, S, K, V, W, dens, h, t0, beta_ab, beta_am, Q, Fc, G_start,
                     y_start, Q_ab, c_g, Q_g, before, n_rhs, n_field) -> tuple:  # fmt: skip
    """Main loop with the harmonic forcing g (target; chaser - target) integrated by the
    look-ahead quadrature on nodes n - before .. n + 1 + ahead (module doc), the rest of the
    RHS by ABM PECE as in :func:`integrate_multistep`; g at node n + 1 + ahead is evaluated
    at positions extrapolated from the derivative history (Q_ab at s = ahead + 1). From the
    start (:func:`_start_lookahead`): ``Fc`` (k, 12) the derivatives without g at the nodes
    0 .. k - 1, ``G_start`` g at the nodes 0 .. k + ahead - 1 (rows: node; [g_t, g_c - g_t])."""
    n = 12
    k = beta_ab.size
    m = c_g.size
    ahead = m - before - 2
    m_last = times.size - 1
    n_nodes = int(math.ceil((times[m_last] - t0) / h)) + ahead + 3
    G = np.zeros((max(n_nodes, G_start.shape[0] + 1), 6))  # g at node j: [g_t, g_c - g_t] (m/s^2)
    F = np.empty((k + 1, n))  # cheap derivatives (velocities, accelerations without g), newest first
    for j in range(G_start.shape[0]):
        for i in range(6):
            G[j, i] = G_start[j, i]
    for j in range(k):
        for i in range(n):
            F[j, i] = Fc[k - 1 - j, i]
    head = 0
    y = y_start.copy()
    wext = np.empty(k)

    for node in range(G_start.shape[0], k + ahead + 1):  # the nodes ahead of the start-up block
        _lookahead_g(node, float(node - (k - 1)), y, F, head, wext, G, node, Q_ab, h, t0, p, npm, C, S, K, V, W)
        n_field += 2
    yp = np.empty(n)
    yc = np.empty(n)
    fp = np.empty(n)
    gsum = np.empty(6)
    wts = np.empty(k + 1)
    wg = np.empty(m)
    nn = k - 1  # index of t_n
    n_steps = k - 1
    while idx < m_last + 1:
        if nn >= k:
            _lookahead_g(nn + 1 + ahead, float(ahead + 1), y, F, head, wext, G, nn + 1 + ahead, Q_ab, h, t0, p, npm, C,
                         S, K, V, W)  # fmt: skip
            n_field += 2
        for i in range(6):
            acc = 0.0
            for q in range(m):
                acc += c_g[q] * G[nn - before + q, i]
            gsum[i] = acc
        t_next = t0 + (nn + 1) * h
        sun, moon = kf.third_bodies(t_next, p)
        # P: Adams-Bashforth on the cheap part + the look-ahead quadrature of g
        for i in range(n):
            acc = 0.0
            for j in range(k):
                acc += beta_ab[j] * F[(head + j) % (k + 1), i]
            yp[i] = y[i] + h * acc
        for i in range(3):
            yp[3 + i] += h * gsum[i]
            yp[9 + i] += h * gsum[3 + i]
        kf.rhs_full_sun_moon(t_next, yp, u, p_cheap, npm, C, S, K, V, W, dens, sun, moon, fp)
        # C: Adams-Moulton with f_p
        for i in range(n):
            acc = beta_am[0] * fp[i]
            for j in range(k):
                acc += beta_am[j + 1] * F[(head + j) % (k + 1), i]
            yc[i] = y[i] + h * acc
        for i in range(3):
            yc[3 + i] += h * gsum[i]
            yc[9 + i] += h * gsum[3 + i]
        head = (head + k) % (k + 1)
        kf.rhs_full_sun_moon(t_next, yc, u, p_cheap, npm, C, S, K, V, W, dens, sun, moon, F[head])
        n_rhs += 2
        n_steps += 1
        if not math.isfinite(yc[0] + yc[6]):
            return STATUS_NOT_FINITE, n_steps, n_rhs, n_field
        t_n = t_next - h
        while idx < m_last + 1 and times[idx] <= t_next:
            theta = (times[idx] - t_n) / h
            _poly_weights(Q, theta, wts)
            _poly_weights(Q_g, theta, wg)
            for i in range(n):
                acc = 0.0
                for j in range(k + 1):
                    acc += wts[j] * F[(head + j) % (k + 1), i]
                out[idx, i] = y[i] + h * acc
            for i in range(3):
                acc_t = 0.0
                acc_r = 0.0
                for q in range(m):
                    acc_t += wg[q] * G[nn - before + q, i]
                    acc_r += wg[q] * G[nn - before + q, 3 + i]
                out[idx, 3 + i] += h * acc_t
                out[idx, 9 + i] += h * acc_r
            idx += 1
        nn += 1
        for i in range(n):
            y[i] = yc[i]
    return STATUS_OK, n_steps, n_rhs, n_field

@njit(cache=True)
def _lookahead_g(node_index, s_ahead, y, F, head, wext, G, row, Q_ab, h, t0, p, npm, C, S, K, V, W) -> None:
    """G[row] = g at node ``node_index`` (t0 + node_index h), at the positions extrapolated
    s_ahead steps from the state y at t_n with the derivative history F (ring, newest at
    ``head``): [g_t, g_c - g_t] (m/s^2)."""
    k = Q_ab.shape[0]
    _poly_weights(Q_ab, s_ahead, wext)
    rx = y[0]
    ry = y[1]
    rz = y[2]
    dx = y[6]
    dy = y[7]
    dz = y[8]
    for j in range(k):
        r = (head + j) % (k + 1)
        rx += h * wext[j] * F[r, 0]
        ry += h * wext[j] * F[r, 1]
        rz += h * wext[j] * F[r, 2]
        dx += h * wext[j] * F[r, 6]
        dy += h * wext[j] * F[r, 7]
        dz += h * wext[j] * F[r, 8]
    _harmonic_forcing(t0 + node_index * h, rx, ry, rz, dx, dy, dz, p, npm, C, S, K, V, W, G, row)


@njit(cache=True)
def _harmonic_forcing(t, rx, ry, rz, dx, dy, dz, p, npm, C, S, K, V, W, G, row) -> None:
    """G[row] = [g_t, g_c - g_t] (m/s^2): the harmonic accelerations at the target position
    (rx, ry, rz) and the chaser at offset (dx, dy, dz) (ECI, m) at t s after the epoch."""
    gtx, gty, gtz, gcx, gcy, gcz = kf._harmonics_eci_pair(t, rx, ry, rz, rx + dx, ry + dy, rz + dz, p, npm, C, S, K, V,
                                                          W)  # fmt: skip
    G[row, 0] = gtx
    G[row, 1] = gty
    G[row, 2] = gtz
    G[row, 3] = gcx - gtx
    G[row, 4] = gcy - gty
    G[row, 5] = gcz - gtz


@njit(cache=True)
def _start_lookahead(y0, times, out, u, p, p_cheap, p_guess, npm, C, S, K, V, W, dens, h, beta_ab, beta_am, Q, Q0, G0,
                     Q_ab, c_g, Q_g, before, rtol, atol) -> tuple:  # fmt: skip
    """Start-up with the look-ahead quadrature (module doc), then :func:`_march_lookahead`.
    The first k nodes as one block: the derivatives without g by collocation (G0, as the
    start without look-ahead), g by the centred quadrature of the march (c_g on nodes
    j - before .. j + after for the step j -> j + 1, nodes before t_0 included). g is
    evaluated at positions from a guess (DOP853 with the field truncated to GUESS_DEGREE on
    the nodes 0 .. k - 1; the nodes -before .. -1 and k .. k - 2 + after by the velocity
    polynomial through the guess's nodes integrated), then (START_PASSES_LOOKAHEAD = 2) again at the block's
    converged nodes 1 .. k - 1 and at the nodes after them extrapolated from the block as in
    the march. Returns as :func:`integrate_multistep`."""
    n = 12
    k = beta_ab.size
    m = c_g.size
    after = m - before - 1
    t0 = times[0]
    last = k - 2 + after  # the last node the block's steps need
    n_g = before + last + 1  # g at the nodes -before .. last: row node + before
    grid = np.empty(last + 1)
    for j in range(last + 1):
        grid[j] = t0 + j * h
    yg = np.empty((k, n))
    status, n_dop, n_rej = kf.integrate_full(y0, grid[:k], u, p_guess, npm, C, S, K, V, W, dens, rtol, atol, yg)
    if status != STATUS_OK:
        return status, 0, 0, 0
    n_rhs = 12 * (n_dop + n_rej) + 1
    Gn = np.empty((n_g, 6))
    w0 = np.empty(k)
    for r in range(n_g):
        node = r - before
        if 0 <= node < k:
            _harmonic_forcing(grid[node], yg[node, 0], yg[node, 1], yg[node, 2], yg[node, 6], yg[node, 7], yg[node, 8],
                              p, npm, C, S, K, V, W, Gn, r)  # fmt: skip
        else:  # outside the block: the velocity polynomial through the guess's nodes 0 .. k - 1 integrated
            _poly_weights(Q0, float(node), w0)
            pos = np.empty(6)
            for i in range(3):
                a_t = y0[i]
                a_r = y0[6 + i]
                for q in range(k):
                    a_t += h * w0[q] * yg[q, 3 + i]
                    a_r += h * w0[q] * yg[q, 9 + i]
                pos[i] = a_t
                pos[3 + i] = a_r
            _harmonic_forcing(t0 + node * h, pos[0], pos[1], pos[2], pos[3], pos[4], pos[5], p, npm, C, S, K, V, W, Gn,
                              r)  # fmt: skip
    n_field = 2 * n_g
    ys = np.empty((k, n))
    Fc = np.empty((k, n))  # derivatives without g at the block's nodes
    sun_moon = np.empty((k, 6))
    for j in range(k):
        for i in range(n):
            ys[j, i] = yg[j, i]
        sun, moon = kf.third_bodies(grid[j], p)
        sun_moon[j, 0], sun_moon[j, 1], sun_moon[j, 2] = sun
        sun_moon[j, 3], sun_moon[j, 4], sun_moon[j, 5] = moon
        kf.rhs_full_sun_moon(grid[j], ys[j], u, p_cheap, npm, C, S, K, V, W, dens, sun, moon, Fc[j])
    n_rhs += k
    dv = np.zeros((k, 6))  # velocity increments from g over [t_0, t_j] (target; chaser - target)
    Fr = np.empty((k + 1, n))
    wext = np.empty(k)
    span = (k - 1) * h
    for start_pass in range(START_PASSES_LOOKAHEAD):
        if start_pass > 0:  # g at the converged nodes and extrapolated from them beyond
            for j in range(1, k):
                _harmonic_forcing(grid[j], ys[j, 0], ys[j, 1], ys[j, 2], ys[j, 6], ys[j, 7], ys[j, 8], p, npm, C, S, K,
                                  V, W, Gn, before + j)  # fmt: skip
            for j in range(k):
                for i in range(n):
                    Fr[j, i] = Fc[k - 1 - j, i]
            for node in range(k, last + 1):
                _lookahead_g(node, float(node - (k - 1)), ys[k - 1], Fr, 0, wext, Gn, before + node, Q_ab, h, t0, p,
                             npm, C, S, K, V, W)  # fmt: skip
            n_field += 2 * (last)
        for j in range(1, k):
            for i in range(6):
                acc = 0.0
                for q in range(m):
                    acc += c_g[q] * Gn[j - 1 + q, i]  # nodes j - 1 - before .. j - 1 + after
                dv[j, i] = dv[j - 1, i] + h * acc
        converged = False
        for _ in range(MAX_START_ITERATIONS):
            change_t, change_r = _block_sweep(y0, h, G0, Fc, ys, dv, True, span)
            for j in range(1, k):
                sun = (sun_moon[j, 0], sun_moon[j, 1], sun_moon[j, 2])
                moon = (sun_moon[j, 3], sun_moon[j, 4], sun_moon[j, 5])
                kf.rhs_full_sun_moon(grid[j], ys[j], u, p_cheap, npm, C, S, K, V, W, dens, sun, moon, Fc[j])
            n_rhs += k - 1
            if change_t < START_TOL_TARGET_M and change_r < START_TOL_RELATIVE_M:
                converged = True
                break
        if not converged:
            return STATUS_START_NOT_CONVERGED, 0, n_rhs, 0
    # samples inside the block: collocation polynomial of the derivatives without g + the quadrature of g
    wg = np.empty(m)
    idx = 1
    while idx < times.size and times[idx] <= grid[k - 1]:
        s_ = (times[idx] - t0) / h
        _poly_weights(Q0, s_, w0)
        step = min(int(s_), k - 2)
        _poly_weights(Q_g, s_ - step, wg)
        for i in range(n):
            acc = 0.0
            for q in range(k):
                acc += w0[q] * Fc[q, i]
            out[idx, i] = y0[i] + h * acc
        for i in range(6):
            acc = 0.0
            for q in range(m):
                acc += wg[q] * Gn[step + q, i]
            out[idx, 3 + (i // 3) * 6 + i % 3] += dv[step, i] + h * acc
        idx += 1
    G_start = Gn[before:, :].copy()  # nodes 0 .. last
    return _march_lookahead(times, idx, out, u, p, p_cheap, npm, C, S, K, V, W, dens, h, t0, beta_ab, beta_am, Q, Fc,
                            G_start, ys[k - 1], Q_ab, c_g, Q_g, before, n_rhs, n_field)  # fmt: skip
