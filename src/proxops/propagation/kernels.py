"""Numba kernels of the truth propagator: Encke relative right-hand side, Hill-state
extraction, and an adaptive Dormand-Prince 8(5,3) integrator (the fast path).

State ``y`` (12,): target ECI position and velocity ``[r_t, v_t]`` followed by the
chaser ECI offset ``[dr, dv] = chaser - target`` (m, m/s). Parameters ``p`` (3,):
``[mu, j2, re]`` (``j2 = 0`` for two-body only). Control ``u`` (3,): chaser
acceleration in Hill axes (m/s^2), rotated to ECI with the current target state.

    r_t'' = g(r_t)
    dr''  = g(r_t + dr) - g(r_t) + C(r_t, v_t)^T u          (Encke, see core.twobody)

DOP853: coefficients of Hairer, Norsett & Wanner, *Solving Ordinary Differential
Equations I*, sec. II.10 (dop853.f; identical to scipy's ``dop853_coefficients``, which a
test checks), with scipy's error norm and step-size control (safety 0.9, factor in
[0.2, 10], exponent -1/8), i.e. the same accept/reject logic as
``scipy.integrate.solve_ivp(method="DOP853")``; only the first trial step differs
(see :func:`initial_step_orbit`).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from proxops.core.twobody import accel_differential, accel_gravity, potential

# ---------------------------------------------------------------- DOP853 tableau
N_STAGES = 12
C = np.array(
    [
        0.0,
        0.526001519587677318785587544488e-01,
        0.789002279381515978178381316732e-01,
        0.118350341907227396726757197510,
        0.281649658092772603273242802490,
        0.333333333333333333333333333333,
        0.25,
        0.307692307692307692307692307692,
        0.651282051282051282051282051282,
        0.6,
        0.857142857142857142857142857142,
        1.0,
    ]
)

A = np.zeros((N_STAGES + 1, N_STAGES))
A[1, 0] = 5.26001519587677318785587544488e-2
A[2, 0] = 1.97250569845378994544595329183e-2
A[2, 1] = 5.91751709536136983633785987549e-2
A[3, 0] = 2.95875854768068491816892993775e-2
A[3, 2] = 8.87627564304205475450678981324e-2
A[4, 0] = 2.41365134159266685502369798665e-1
A[4, 2] = -8.84549479328286085344864962717e-1
A[4, 3] = 9.24834003261792003115737966543e-1
A[5, 0] = 3.7037037037037037037037037037e-2
A[5, 3] = 1.70828608729473871279604482173e-1
A[5, 4] = 1.25467687566822425016691814123e-1
A[6, 0] = 3.7109375e-2
A[6, 3] = 1.70252211019544039314978060272e-1
A[6, 4] = 6.02165389804559606850219397283e-2
A[6, 5] = -1.7578125e-2
A[7, 0] = 3.70920001185047927108779319836e-2
A[7, 3] = 1.70383925712239993810214054705e-1
A[7, 4] = 1.07262030446373284651809199168e-1
A[7, 5] = -1.53194377486244017527936158236e-2
A[7, 6] = 8.27378916381402288758473766002e-3
A[8, 0] = 6.24110958716075717114429577812e-1
A[8, 3] = -3.36089262944694129406857109825
A[8, 4] = -8.68219346841726006818189891453e-1
A[8, 5] = 2.75920996994467083049415600797e1
A[8, 6] = 2.01540675504778934086186788979e1
A[8, 7] = -4.34898841810699588477366255144e1
A[9, 0] = 4.77662536438264365890433908527e-1
A[9, 3] = -2.48811461997166764192642586468
A[9, 4] = -5.90290826836842996371446475743e-1
A[9, 5] = 2.12300514481811942347288949897e1
A[9, 6] = 1.52792336328824235832596922938e1
A[9, 7] = -3.32882109689848629194453265587e1
A[9, 8] = -2.03312017085086261358222928593e-2
A[10, 0] = -9.3714243008598732571704021658e-1
A[10, 3] = 5.18637242884406370830023853209
A[10, 4] = 1.09143734899672957818500254654
A[10, 5] = -8.14978701074692612513997267357
A[10, 6] = -1.85200656599969598641566180701e1
A[10, 7] = 2.27394870993505042818970056734e1
A[10, 8] = 2.49360555267965238987089396762
A[10, 9] = -3.0467644718982195003823669022
A[11, 0] = 2.27331014751653820792359768449
A[11, 3] = -1.05344954667372501984066689879e1
A[11, 4] = -2.00087205822486249909675718444
A[11, 5] = -1.79589318631187989172765950534e1
A[11, 6] = 2.79488845294199600508499808837e1
A[11, 7] = -2.85899827713502369474065508674
A[11, 8] = -8.87285693353062954433549289258
A[11, 9] = 1.23605671757943030647266201528e1
A[11, 10] = 6.43392746015763530355970484046e-1
# row 12 holds the 8th-order weights B
A[12, 0] = 5.42937341165687622380535766363e-2
A[12, 5] = 4.45031289275240888144113950566
A[12, 6] = 1.89151789931450038304281599044
A[12, 7] = -5.8012039600105847814672114227
A[12, 8] = 3.1116436695781989440891606237e-1
A[12, 9] = -1.52160949662516078556178806805e-1
A[12, 10] = 2.01365400804030348374776537501e-1
A[12, 11] = 4.47106157277725905176885569043e-2
B = A[N_STAGES].copy()

# error estimators over the 13 stages (12 + the FSAL derivative at the new point)
E3 = np.zeros(N_STAGES + 1)
E3[:-1] = B
E3[0] -= 0.244094488188976377952755905512
E3[8] -= 0.733846688281611857341361741547
E3[11] -= 0.220588235294117647058823529412e-1

E5 = np.zeros(N_STAGES + 1)
E5[0] = 0.1312004499419488073250102996e-1
E5[5] = -0.1225156446376204440720569753e1
E5[6] = -0.4957589496572501915214079952
E5[7] = 0.1664377182454986536961530415e1
E5[8] = -0.3503288487499736816886487290
E5[9] = 0.3341791187130174790297318841
E5[10] = 0.8192320648511571246570742613e-1
E5[11] = -0.2235530786388629525884427845e-1

# Dense output (Hairer's dop853.f ``contd8``; scipy's ``Dop853DenseOutput``): three extra stages
# (rows 13-15 of the extended tableau, after the FSAL derivative K[12]) and the 4 x 16 matrix D of
# the 7th-order continuous extension's upper coefficients.
N_STAGES_EXTENDED = 16
A_EXTRA = np.zeros((N_STAGES_EXTENDED - N_STAGES - 1, N_STAGES_EXTENDED))
A_EXTRA[0, 0] = 5.61675022830479523392909219681e-2
A_EXTRA[0, 6] = 2.53500210216624811088794765333e-1
A_EXTRA[0, 7] = -2.46239037470802489917441475441e-1
A_EXTRA[0, 8] = -1.24191423263816360469010140626e-1
A_EXTRA[0, 9] = 1.5329179827876569731206322685e-1
A_EXTRA[0, 10] = 8.20105229563468988491666602057e-3
A_EXTRA[0, 11] = 7.56789766054569976138603589584e-3
A_EXTRA[0, 12] = -8.298e-3
A_EXTRA[1, 0] = 3.18346481635021405060768473261e-2
A_EXTRA[1, 5] = 2.83009096723667755288322961402e-2
A_EXTRA[1, 6] = 5.35419883074385676223797384372e-2
A_EXTRA[1, 7] = -5.49237485713909884646569340306e-2
A_EXTRA[1, 10] = -1.08347328697249322858509316994e-4
A_EXTRA[1, 11] = 3.82571090835658412954920192323e-4
A_EXTRA[1, 12] = -3.40465008687404560802977114492e-4
A_EXTRA[1, 13] = 1.41312443674632500278074618366e-1
A_EXTRA[2, 0] = -4.28896301583791923408573538692e-1
A_EXTRA[2, 5] = -4.69762141536116384314449447206
A_EXTRA[2, 6] = 7.68342119606259904184240953878
A_EXTRA[2, 7] = 4.06898981839711007970213554331
A_EXTRA[2, 8] = 3.56727187455281109270669543021e-1
A_EXTRA[2, 12] = -1.39902416515901462129418009734e-3
A_EXTRA[2, 13] = 2.9475147891527723389556272149
A_EXTRA[2, 14] = -9.15095847217987001081870187138
D = np.zeros((4, N_STAGES_EXTENDED))
D[0, 0] = -0.84289382761090128651353491142e+1
D[0, 5] = 0.56671495351937776962531783590
D[0, 6] = -0.30689499459498916912797304727e+1
D[0, 7] = 0.23846676565120698287728149680e+1
D[0, 8] = 0.21170345824450282767155149946e+1
D[0, 9] = -0.87139158377797299206789907490
D[0, 10] = 0.22404374302607882758541771650e+1
D[0, 11] = 0.63157877876946881815570249290
D[0, 12] = -0.88990336451333310820698117400e-1
D[0, 13] = 0.18148505520854727256656404962e+2
D[0, 14] = -0.91946323924783554000451984436e+1
D[0, 15] = -0.44360363875948939664310572000e+1
D[1, 0] = 0.10427508642579134603413151009e+2
D[1, 5] = 0.24228349177525818288430175319e+3
D[1, 6] = 0.16520045171727028198505394887e+3
D[1, 7] = -0.37454675472269020279518312152e+3
D[1, 8] = -0.22113666853125306036270938578e+2
D[1, 9] = 0.77334326684722638389603898808e+1
D[1, 10] = -0.30674084731089398182061213626e+2
D[1, 11] = -0.93321305264302278729567221706e+1
D[1, 12] = 0.15697238121770843886131091075e+2
D[1, 13] = -0.31139403219565177677282850411e+2
D[1, 14] = -0.93529243588444783865713862664e+1
D[1, 15] = 0.35816841486394083752465898540e+2
D[2, 0] = 0.19985053242002433820987653617e+2
D[2, 5] = -0.38703730874935176555105901742e+3
D[2, 6] = -0.18917813819516756882830838328e+3
D[2, 7] = 0.52780815920542364900561016686e+3
D[2, 8] = -0.11573902539959630126141871134e+2
D[2, 9] = 0.68812326946963000169666922661e+1
D[2, 10] = -0.10006050966910838403183860980e+1
D[2, 11] = 0.77771377980534432092869265740
D[2, 12] = -0.27782057523535084065932004339e+1
D[2, 13] = -0.60196695231264120758267380846e+2
D[2, 14] = 0.84320405506677161018159903784e+2
D[2, 15] = 0.11992291136182789328035130030e+2
D[3, 0] = -0.25693933462703749003312586129e+2
D[3, 5] = -0.15418974869023643374053993627e+3
D[3, 6] = -0.23152937917604549567536039109e+3
D[3, 7] = 0.35763911791061412378285349910e+3
D[3, 8] = 0.93405324183624310003907691704e+2
D[3, 9] = -0.37458323136451633156875139351e+2
D[3, 10] = 0.10409964950896230045147246184e+3
D[3, 11] = 0.29840293426660503123344363579e+2
D[3, 12] = -0.43533456590011143754432175058e+2
D[3, 13] = 0.96324553959188282948394950600e+2
D[3, 14] = -0.39177261675615439165231486172e+2
D[3, 15] = -0.14972683625798562581422125276e+3

SAFETY = 0.9
MIN_FACTOR = 0.2
MAX_FACTOR = 10.0
ERROR_EXPONENT = -1.0 / 8.0
MAX_STEPS = 1_000_000

STATUS_OK = 0
STATUS_STEP_TOO_SMALL = 1
STATUS_TOO_MANY_STEPS = 2
STATUS_NOT_FINITE = 3


# ---------------------------------------------------------------- right-hand side
@njit(cache=True)
def hill_axes(y: np.ndarray):
    """Hill unit vectors (x_hat, y_hat, z_hat) as 9 floats from the target part of y."""
    rx, ry, rz, vx, vy, vz = y[0], y[1], y[2], y[3], y[4], y[5]
    rn = math.sqrt(rx * rx + ry * ry + rz * rz)
    hx = ry * vz - rz * vy
    hy = rz * vx - rx * vz
    hz = rx * vy - ry * vx
    hn = math.sqrt(hx * hx + hy * hy + hz * hz)
    xx, xy, xz = rx / rn, ry / rn, rz / rn
    zx, zy, zz = hx / hn, hy / hn, hz / hn
    yx = zy * xz - zz * xy
    yy = zz * xx - zx * xz
    yz = zx * xy - zy * xx
    return xx, xy, xz, yx, yy, yz, zx, zy, zz


@njit(cache=True)
def rhs_relative(y: np.ndarray, u: np.ndarray, p: np.ndarray, out: np.ndarray) -> None:
    """Encke relative RHS written into ``out`` (12,) (autonomous: no time argument)."""
    mu, j2, re = p[0], p[1], p[2]
    ax, ay, az = accel_gravity(y[0], y[1], y[2], mu, j2, re)
    dax, day, daz = accel_differential(y[0], y[1], y[2], y[6], y[7], y[8], mu, j2, re)
    if u[0] != 0.0 or u[1] != 0.0 or u[2] != 0.0:
        xx, xy, xz, yx, yy, yz, zx, zy, zz = hill_axes(y)
        dax += xx * u[0] + yx * u[1] + zx * u[2]
        day += xy * u[0] + yy * u[1] + zy * u[2]
        daz += xz * u[0] + yz * u[1] + zz * u[2]
    out[0] = y[3]
    out[1] = y[4]
    out[2] = y[5]
    out[3] = ax
    out[4] = ay
    out[5] = az
    out[6] = y[9]
    out[7] = y[10]
    out[8] = y[11]
    out[9] = dax
    out[10] = day
    out[11] = daz


@njit(cache=True)
def rhs_relative_alloc(y: np.ndarray, u: np.ndarray, p: np.ndarray) -> np.ndarray:
    """Allocating version of :func:`rhs_relative` (for scipy's solve_ivp)."""
    out = np.empty(12)
    rhs_relative(y, u, p, out)
    return out


# ---------------------------------------------------------------- Hill extraction
@njit(cache=True, inline="always")  # inlined at numba IR level (array arguments): a Hill conversion 47 -> 43 ns
def hill_frame_rate(y: np.ndarray, p: np.ndarray):
    """(w_x, w_z) of the Hill frame of the target state y[0:6] (rad/s), w_y = 0: w_z = |h| / r^2 and
    w_x = r (a . h) / |h|^2, non-zero only through J2 (two-body a is along r, and r . h = 0). With the
    J2 acceleration a_J2 = k (x (1 - s), y (1 - s), z (3 - s)), k = -3/2 J2 mu Re^2 / r^5, s = 5 z^2 / r^2,
    and x h_x + y h_y = -z h_z: a . h = 2 k z h_z, so w_x = -3 J2 mu Re^2 z h_z / (r^4 |h|^2)
    (= -3 J2 mu Re^2 sin 2i sin u / (2 h r^3), Schweighart-Sedwick). The closed form drops the
    two-body part that cancels in exact arithmetic (before 2026-11-28 it was summed and cancelled:
    the same w_x to ~1e-15 relative, 1.6x the time of a Hill conversion)."""
    rx, ry, rz, vx, vy, vz = y[0], y[1], y[2], y[3], y[4], y[5]
    rn2 = rx * rx + ry * ry + rz * rz
    hx = ry * vz - rz * vy
    hy = rz * vx - rx * vz
    hz = rx * vy - ry * vx
    h2 = hx * hx + hy * hy + hz * hz
    wx = 0.0
    if p[1] != 0.0:
        wx = -3.0 * p[1] * p[0] * p[2] * p[2] * rz * hz / (rn2 * rn2 * h2)
    return wx, math.sqrt(h2) / rn2


@njit(cache=True)
def hill_from_y(y: np.ndarray, p: np.ndarray) -> np.ndarray:
    """Exact Hill relative state (6,) of the chaser: rho = C dr, rho' = C dv - w x rho
    (frame rate w incl. the J2 x part; see proxops.frames.hill)."""
    out = np.empty(6)
    hill_into(y, p, out)
    return out


@njit(cache=True)
def hill_into(y: np.ndarray, p: np.ndarray, out: np.ndarray) -> None:
    """:func:`hill_from_y` written into ``out`` (6,), e.g. a row of a preallocated array (no allocation)."""
    wx, wz = hill_frame_rate(y, p)
    hill_from_rates(y, wx, wz, out)


@njit(cache=True, inline="always")  # inlined at numba IR level: a call here cost ~8 % of a Hill conversion
def hill_from_rates(y: np.ndarray, wx: float, wz: float, out: np.ndarray) -> None:
    """Hill state (6,) of the chaser into ``out`` for the Hill frame rate w = (wx, 0, wz) (rad/s) of the
    target y[0:6]: rho = C dr, rho' = C dv - w x rho. The one Hill map of both truths (the J2 truth's w
    from :func:`hill_frame_rate`, the composed one's from its total acceleration)."""
    xx, xy, xz, yx, yy, yz, zx, zy, zz = hill_axes(y)
    px = xx * y[6] + xy * y[7] + xz * y[8]
    py = yx * y[6] + yy * y[7] + yz * y[8]
    pz = zx * y[6] + zy * y[7] + zz * y[8]
    out[0] = px
    out[1] = py
    out[2] = pz
    # w x rho with w = (wx, 0, wz): (-wz py, wz px - wx pz, wx py)
    out[3] = xx * y[9] + xy * y[10] + xz * y[11] + wz * py
    out[4] = yx * y[9] + yy * y[10] + yz * y[11] - (wz * px - wx * pz)
    out[5] = zx * y[9] + zy * y[10] + zz * y[11] - wx * py


@njit(cache=True)
def y_from_hill(target: np.ndarray, hill: np.ndarray, p: np.ndarray) -> np.ndarray:
    """12-state from target ECI state (6,) and chaser Hill state (6,); inverse of hill_from_y."""
    y = np.zeros(12)
    for i in range(6):
        y[i] = target[i]
    wx, wz = hill_frame_rate(y, p)
    offset_from_rates(y, hill, wx, wz)
    return y


@njit(cache=True, inline="always")
def offset_from_rates(y: np.ndarray, hill: np.ndarray, wx: float, wz: float) -> None:
    """Inverse of :func:`hill_from_rates`: the chaser's ECI offset y[6:12] (m, m/s) written from its Hill
    state ``hill`` (6,) and the frame rate w = (wx, 0, wz) (rad/s) of the target y[0:6]."""
    xx, xy, xz, yx, yy, yz, zx, zy, zz = hill_axes(y)
    px, py, pz = hill[0], hill[1], hill[2]
    # rho' + w x rho
    qx = hill[3] - wz * py
    qy = hill[4] + wz * px - wx * pz
    qz = hill[5] + wx * py
    y[6] = xx * px + yx * py + zx * pz
    y[7] = xy * px + yy * py + zy * pz
    y[8] = xz * px + yz * py + zz * pz
    y[9] = xx * qx + yx * qy + zx * qz
    y[10] = xy * qx + yy * qy + zy * qz
    y[11] = xz * qx + yz * qy + zz * qz


@njit(cache=True)
def energy_invariants(targets: np.ndarray, hill: np.ndarray, p: np.ndarray) -> np.ndarray:
    """Chaser-minus-target specific orbital energy over |v_t| (m/s) for target ECI states (n, 6) and
    chaser Hill states (n, 6): ``(v_t . dv + |dv|^2 / 2 + V(r_t + dr) - V(r_t)) / |v_t|`` with the
    exact offset (dr, dv) of :func:`y_from_hill` and V the two-body + J2 potential (J2 = p[1]).
    Conserved on the free motion of both (axisymmetric J2); zero difference means equal semi-major
    axes, i.e. no secular along-track drift (the srf MPC's drift invariant)."""
    n = targets.shape[0]
    out = np.empty(n)
    mu, j2, re = p[0], p[1], p[2]
    for k in range(n):
        y = y_from_hill(targets[k], hill[k], p)
        rtx, rty, rtz, vtx, vty, vtz = y[0], y[1], y[2], y[3], y[4], y[5]
        dx, dy, dz, dvx, dvy, dvz = y[6], y[7], y[8], y[9], y[10], y[11]
        d_kin = vtx * dvx + vty * dvy + vtz * dvz + 0.5 * (dvx * dvx + dvy * dvy + dvz * dvz)
        d_pot = potential(rtx + dx, rty + dy, rtz + dz, mu, j2, re) - potential(rtx, rty, rtz, mu, j2, re)
        out[k] = (d_kin + d_pot) / math.sqrt(vtx * vtx + vty * vty + vtz * vtz)
    return out


@njit(cache=True)
def energy_gains(targets: np.ndarray, hill: np.ndarray, p: np.ndarray) -> np.ndarray:
    """Gradient of :func:`energy_invariants` with respect to an impulse in Hill axes (n, 3) (1/1,
    m/s per m/s): the chaser's inertial velocity in Hill components over |v_t|,
    ``(C v_t + rho' + w x rho) / |v_t|`` (w: Hill frame rate incl. the J2 x part)."""
    n = targets.shape[0]
    out = np.empty((n, 3))
    y = np.zeros(12)
    for k in range(n):
        for i in range(6):
            y[i] = targets[k, i]
        xx, xy, xz, yx, yy, yz, zx, zy, zz = hill_axes(y)
        wx, wz = hill_frame_rate(y, p)
        vx, vy, vz = y[3], y[4], y[5]
        px, py, pz = hill[k, 0], hill[k, 1], hill[k, 2]
        vn = math.sqrt(vx * vx + vy * vy + vz * vz)
        # w x rho with w = (wx, 0, wz): (-wz py, wz px - wx pz, wx py)
        out[k, 0] = (xx * vx + xy * vy + xz * vz + hill[k, 3] - wz * py) / vn
        out[k, 1] = (yx * vx + yy * vy + yz * vz + hill[k, 4] + wz * px - wx * pz) / vn
        out[k, 2] = (zx * vx + zy * vy + zz * vz + hill[k, 5] + wx * py) / vn
    return out


@njit(cache=True)
def apply_hill_impulse(y: np.ndarray, dv: np.ndarray) -> np.ndarray:
    """Copy of y with a Hill-axes velocity change ``dv`` (m/s) added to the chaser."""
    out = y.copy()
    xx, xy, xz, yx, yy, yz, zx, zy, zz = hill_axes(y)
    out[9] += xx * dv[0] + yx * dv[1] + zx * dv[2]
    out[10] += xy * dv[0] + yy * dv[1] + zy * dv[2]
    out[11] += xz * dv[0] + yz * dv[1] + zz * dv[2]
    return out


# ---------------------------------------------------------------- DOP853 integrator
@njit(cache=True)
def initial_step_orbit(y, p, rtol) -> float:
    """First trial step rtol^(1/8) / n_local (s), n_local = sqrt(mu / r_t^3): ~50 s in LEO at
    rtol = 1e-10, about a third of the accepted step size there. Used instead of Hairer's
    heuristic (scipy's select_initial_step), which the tiny atol-scaled chaser components
    drive down to ~0.05 s and which costs an extra RHS call on every short control step."""
    r2 = y[0] * y[0] + y[1] * y[1] + y[2] * y[2]
    n_local = math.sqrt(p[0] / (r2 * math.sqrt(r2)))
    return rtol ** (1.0 / 8.0) / n_local


@njit(cache=True)
def dop853_step(y, f0, h, u, p, K, work, y_new) -> None:
    """One DOP853 step of size h from (y, f0): y_new and all 13 stage derivatives in K
    (K[12] = f(y_new), the FSAL derivative)."""
    n = y.size
    for i in range(n):
        K[0, i] = f0[i]
    for s in range(1, N_STAGES):
        for i in range(n):
            acc = 0.0
            for j in range(s):
                acc += A[s, j] * K[j, i]
            work[i] = y[i] + h * acc
        rhs_relative(work, u, p, K[s])
    for i in range(n):
        acc = 0.0
        for j in range(N_STAGES):
            acc += B[j] * K[j, i]
        y_new[i] = y[i] + h * acc
    rhs_relative(y_new, u, p, K[N_STAGES])


@njit(cache=True)
def dop853_error_norm(y, y_new, K, h, rtol, atol) -> float:
    """scipy's DOP853 error norm (blend of the 5th- and 3rd-order estimators)."""
    n = y.size
    err5 = 0.0
    err3 = 0.0
    for i in range(n):
        e5 = 0.0
        e3 = 0.0
        for j in range(N_STAGES + 1):
            e5 += E5[j] * K[j, i]
            e3 += E3[j] * K[j, i]
        sc = atol + max(abs(y[i]), abs(y_new[i])) * rtol
        err5 += (e5 / sc) ** 2
        err3 += (e3 / sc) ** 2
    if err5 == 0.0 and err3 == 0.0:
        return 0.0
    denom = err5 + 0.01 * err3
    return abs(h) * err5 / math.sqrt(denom * n)


@njit(cache=True)
def _accepted_step(y, f0, t, h_abs, t_end, u, p, rtol, atol, K, work, y_new, n_done, keep_proposal) -> tuple:
    """One accepted DOP853 step from ``t`` (s) starting with the proposal ``h_abs`` (s), shortened
    to end on ``t_end`` if it would pass it; the step is left in ``y_new`` and ``K``. ``n_done``:
    steps and rejections so far (against MAX_STEPS). ``keep_proposal``: after a shortened step the
    next proposal is the larger of the controller's and the current one (sample landing of
    :func:`integrate_grid`). Returns (status, h, clipped, next proposal, rejections in this call)."""
    rejected = False
    n_rej = 0
    while True:
        if n_done + n_rej >= MAX_STEPS:
            return STATUS_TOO_MANY_STEPS, 0.0, False, h_abs, n_rej
        min_step = 10.0 * (np.nextafter(abs(t), np.inf) - abs(t))
        if h_abs < min_step:
            return STATUS_STEP_TOO_SMALL, 0.0, False, h_abs, n_rej
        clipped = t + h_abs >= t_end
        h = t_end - t if clipped else h_abs
        dop853_step(y, f0, h, u, p, K, work, y_new)
        err = dop853_error_norm(y, y_new, K, h, rtol, atol)
        if not math.isfinite(err):
            return STATUS_NOT_FINITE, h, clipped, h_abs, n_rej
        if err < 1.0:
            if err == 0.0:
                factor = MAX_FACTOR
            else:
                factor = min(MAX_FACTOR, SAFETY * err**ERROR_EXPONENT)
            if rejected:
                factor = min(1.0, factor)
            h_next = max(h * factor, h_abs) if clipped and keep_proposal else h * factor
            return STATUS_OK, h, clipped, h_next, n_rej
        h_abs = h * max(MIN_FACTOR, SAFETY * err**ERROR_EXPONENT)
        rejected = True
        n_rej += 1


@njit(cache=True)
def integrate_grid(y0, times, u, p, rtol, atol, out) -> tuple:
    """Integrate the relative problem through increasing ``times`` (times[0] is the
    start), storing the state at each time in ``out`` (len(times), 12).

    Steps are shortened to land on each sample time; after such a shortened step the
    controller's unshortened proposal is kept. Returns (status, n_steps, n_rejected)."""
    n = y0.size
    m = times.size
    K = np.empty((N_STAGES + 1, n))
    work = np.empty(n)
    y = y0.copy()
    y_new = np.empty(n)
    f0 = np.empty(n)
    for i in range(n):
        out[0, i] = y0[i]
    if m == 1:
        return STATUS_OK, 0, 0
    rhs_relative(y, u, p, f0)
    span = times[m - 1] - times[0]
    if span <= 0.0:
        for k in range(1, m):
            for i in range(n):
                out[k, i] = y0[i]
        return STATUS_OK, 0, 0
    h_abs = min(span, initial_step_orbit(y, p, rtol))
    t = times[0]
    n_steps = 0
    n_rej = 0
    for k in range(1, m):
        t_end = times[k]
        while t < t_end:
            # a step shortened to hit a sample time keeps the current proposal
            status, h, clipped, h_abs, rej = _accepted_step(y, f0, t, h_abs, t_end, u, p, rtol, atol, K, work, y_new,
                                                            n_steps + n_rej, True)  # fmt: skip
            n_rej += rej
            if status != STATUS_OK:
                return status, n_steps, n_rej
            n_steps += 1
            t = t_end if clipped else t + h
            for i in range(n):
                y[i] = y_new[i]
                f0[i] = K[N_STAGES, i]
        for i in range(n):
            out[k, i] = y[i]
    return STATUS_OK, n_steps, n_rej


@njit(cache=True)
def propagate_dop853(y0, dt, u, p, rtol, atol) -> tuple:
    """State after ``dt`` s (>= 0) under constant Hill acceleration ``u``: (y, status, n_steps)."""
    times = np.empty(2)
    times[0] = 0.0
    times[1] = dt
    out = np.empty((2, y0.size))
    status, n_steps, _ = integrate_grid(y0, times, u, p, rtol, atol, out)
    y = np.empty(y0.size)
    for i in range(y0.size):
        y[i] = out[1, i]
    return y, status, n_steps


@njit(cache=True)
def coast_dop853(y0, n, dt, u, p, rtol, atol) -> tuple:
    """``n`` consecutive :func:`propagate_dop853` calls of ``dt`` s each (the same numbers, one
    call): full states (n + 1, 12), their Hill states (n + 1, 6), the status and the index of the
    piece that failed (-1 if none)."""
    ys = np.empty((n + 1, y0.size))
    rel = np.empty((n + 1, 6))
    times = np.empty(2)
    times[0] = 0.0
    times[1] = dt
    out = np.empty((2, y0.size))
    for i in range(y0.size):
        ys[0, i] = y0[i]
    for k in range(n + 1):
        h = hill_from_y(ys[k], p)
        for i in range(6):
            rel[k, i] = h[i]
        if k == n:
            break
        status, _, _ = integrate_grid(ys[k], times, u, p, rtol, atol, out)
        if status != STATUS_OK:
            return ys, rel, status, k
        for i in range(y0.size):
            ys[k + 1, i] = out[1, i]
    return ys, rel, STATUS_OK, -1


@njit(cache=True)
def _dense_coefficients(y, y_new, h, u, p, K, work, F) -> None:
    """The continuous extension of the step y -> y_new of size h (K: its 13 stages; rows 13-15
    are filled here): F (7, n) as scipy's ``DOP853._dense_output_impl``."""
    n = y.size
    for s in range(3):
        row = N_STAGES + 1 + s
        for i in range(n):
            acc = 0.0
            for j in range(row):
                acc += A_EXTRA[s, j] * K[j, i]
            work[i] = y[i] + h * acc
        rhs_relative(work, u, p, K[row])
    for i in range(n):
        dy = y_new[i] - y[i]
        F[0, i] = dy
        F[1, i] = h * K[0, i] - dy
        F[2, i] = 2.0 * dy - h * (K[N_STAGES, i] + K[0, i])
        for r in range(4):
            acc = 0.0
            for j in range(N_STAGES_EXTENDED):
                acc += D[r, j] * K[j, i]
            F[3 + r, i] = h * acc


@njit(cache=True)
def integrate_dense(y0, times, u, p, rtol, atol, out) -> tuple:
    """Like :func:`integrate_grid`, but with the integrator's own steps (only the last one is
    shortened, to end on times[-1]) and each sample from DOP853's 7th-order dense output of the
    step that covers it: the cost is that of the steps the tolerance needs (~80 over three LEO
    orbits at rtol 1e-10), not of one step per sample (2 160 for 720 samples per orbit). The
    samples agree with :func:`integrate_grid`'s to the integration tolerance, not bit for bit.
    Returns (status, n_steps, n_rejected)."""
    n = y0.size
    m = times.size
    K = np.empty((N_STAGES_EXTENDED, n))
    work = np.empty(n)
    F = np.empty((7, n))
    y = y0.copy()
    y_new = np.empty(n)
    f0 = np.empty(n)
    for i in range(n):
        out[0, i] = y0[i]
    if m == 1:
        return STATUS_OK, 0, 0
    t_final = times[m - 1]
    span = t_final - times[0]
    k = 1
    while k < m and times[k] <= times[0]:  # samples at the start time
        for i in range(n):
            out[k, i] = y0[i]
        k += 1
    if span <= 0.0:
        return STATUS_OK, 0, 0
    rhs_relative(y, u, p, f0)
    h_abs = min(span, initial_step_orbit(y, p, rtol))
    t = times[0]
    n_steps = 0
    n_rej = 0
    while k < m:
        status, h, clipped, h_abs, rej = _accepted_step(y, f0, t, h_abs, t_final, u, p, rtol, atol, K, work, y_new,
                                                        n_steps + n_rej, False)  # fmt: skip
        n_rej += rej
        if status != STATUS_OK:
            return status, n_steps, n_rej
        n_steps += 1
        t_new = t_final if clipped else t + h
        if k < m and (times[k] <= t_new or clipped):
            _dense_coefficients(y, y_new, h, u, p, K, work, F)
            while k < m and (times[k] <= t_new or clipped):
                if times[k] >= t_new:  # the step's end (and the last sample): the step's own state
                    for i in range(n):
                        out[k, i] = y_new[i]
                else:
                    x = (times[k] - t) / h
                    for i in range(n):
                        acc = F[6, i] * x
                        acc = (acc + F[5, i]) * (1.0 - x)
                        acc = (acc + F[4, i]) * x
                        acc = (acc + F[3, i]) * (1.0 - x)
                        acc = (acc + F[2, i]) * x
                        acc = (acc + F[1, i]) * (1.0 - x)
                        acc = (acc + F[0, i]) * x
                        out[k, i] = y[i] + acc
                k += 1
        t = t_new
        for i in range(n):
            y[i] = y_new[i]
            f0[i] = K[N_STAGES, i]
    return STATUS_OK, n_steps, n_rej


@njit(cache=True)
def free_drift_hill(y0, times, p, rtol, atol) -> tuple:
    """Uncontrolled Hill relative states (len(times), 6) at ``times`` (increasing, from
    times[0] = start) and the integrator status: the integrator's own steps, samples from its
    dense output (:func:`integrate_dense`)."""
    u = np.zeros(3)
    ys = np.empty((times.size, y0.size))
    status, _, _ = integrate_dense(y0, times, u, p, rtol, atol, ys)
    out = np.empty((times.size, 6))
    for k in range(times.size):
        hill_into(ys[k], p, out[k])
    return out, status
