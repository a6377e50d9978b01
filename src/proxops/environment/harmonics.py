"""Spherical-harmonic gravity to degree/order N: EGM96 coefficients shipped offline, and a
stable normalised Cunningham recursion on plain floats.

Data: ``environment/data/egm96_120.npz`` -- EGM96 (Lemoine et al., NASA/TP-1998-206861;
a US-government work in the public domain) fully normalised C_nm, S_nm to degree and
order 120, tide-free, GM = 3.986004415e14 m^3/s^2, R = 6378136.3 m. It is a verbatim
truncation of ``EGM96.gfc`` (ICGEM format) as shipped by the PyPI package
``satkit-data`` 0.9.0; :func:`read_gfc` reads that file, and a test compares the shipped
arrays with it when ``satkit-data`` is installed. 120 covers the 100 x 100 field of
Wijayatunga et al. eq. 4 (which uses GGM03S, not on PyPI: EGM96 and GGM03S
differ by ~1e-9 in normalised coefficients below degree 50).

Recursion (Montenbruck & Gill, *Satellite Orbits*, sec. 3.2.4-3.2.5, eqs. 3.29-3.33,
written here for normalised V, W; the normalisation N_nm = sqrt((2 - d_m0)(2n + 1)
(n - m)! / (n + m)!) is moved into the recursion coefficients so nothing overflows):

    V_mm = f_m [x' V_{m-1,m-1} - y' W_{m-1,m-1}],  W_mm = f_m [x' W_{m-1,m-1} + y' V_{m-1,m-1}]
    V_nm = a_nm z' V_{n-1,m} - b_nm rho'^2 V_{n-2,m}           (same for W)
    x' = x R / r^2 (etc.), rho'^2 = R^2 / r^2, V_00 = R / r
    f_1 = sqrt(3), f_m = sqrt((2m + 1) / (2m)),
    a_nm = sqrt((2n + 1)(2n - 1) / ((n - m)(n + m))),
    b_nm = sqrt((2n + 1)(n + m - 1)(n - m - 1) / ((2n - 3)(n + m)(n - m)))

and the acceleration (GM / R^2 times, Earth-fixed axes; M&G eq. 3.33 with the ratios
of normalisation factors):

    x: m = 0: -C_n0 c0 V_{n+1,1};  m > 0: 1/2 [c1 (-C V_{n+1,m+1} - S W_{n+1,m+1})
                                            + c2 (C V_{n+1,m-1} + S W_{n+1,m-1})]
    y: m = 0: -C_n0 c0 W_{n+1,1};  m > 0: 1/2 [c1 (-C W_{n+1,m+1} + S V_{n+1,m+1})
                                            + c2 (-C W_{n+1,m-1} + S V_{n+1,m-1})]
    z: c3 (-C V_{n+1,m} - S W_{n+1,m})
    c0 = sqrt((2n+1)(n+1)(n+2) / (2(2n+3))),  c1 = sqrt((2n+1)(n+m+1)(n+m+2) / (2n+3)),
    c2 = sqrt(k (2n+1)(n-m+1)(n-m+2) / (2n+3)) with k = 2 for m = 1 else 1,
    c3 = sqrt((2n+1)(n+m+1)(n-m+1) / (2n+3)).

The recursion in Cartesian coordinates has no singularity at the poles. Tests check
it against finite differences of an independent potential (scipy Legendre functions)
and the closed-form J2, J3 accelerations.

Two kernels, both strict IEEE: :func:`accel_harmonics` (one point; also fills V, W for
:func:`potential_harmonics`) and :func:`accel_harmonics_pair` (two points in one pass, the
points in SIMD lanes, each lane bit-identical to a single-point call; the truth integrators
evaluate target and chaser with it). Measured (benchmarks/bench_truth.py, 100x100, 2 shared
cores of an AMD EPYC with AVX2/AVX-512): see the README's truth section.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import lru_cache
from importlib import resources

import numpy as np
from llvmlite import ir
from numba import njit, types
from numba.core import cgutils
from numba.core.errors import TypingError
from numba.extending import intrinsic

from proxops.core.constants import EGM96_SHIPPED_DEGREE as SHIPPED_DEGREE
from proxops.errors import input_error

DATA_FILE = "egm96_120.npz"


def read_gfc(path, degree: int) -> tuple[np.ndarray, np.ndarray, dict]:
    """Normalised (C, S) arrays (degree+1, degree+1) and header of an ICGEM ``.gfc`` file,
    truncated to ``degree``."""
    C = np.zeros((degree + 1, degree + 1))
    S = np.zeros((degree + 1, degree + 1))
    header: dict[str, str] = {}
    in_head = True
    with open(path) as fh:
        for line in fh:
            parts = line.split()
            if in_head:
                if parts and parts[0] == "end_of_head":
                    in_head = False
                elif len(parts) == 2:
                    header[parts[0]] = parts[1]
                continue
            if not parts or parts[0] != "gfc":
                continue
            n, m = int(parts[1]), int(parts[2])
            if n <= degree and m <= degree:
                C[n, m] = float(parts[3].replace("D", "e"))
                S[n, m] = float(parts[4].replace("D", "e"))
    return C, S, header


@lru_cache(maxsize=1)
def _shipped() -> tuple[np.ndarray, np.ndarray, float, float]:
    with resources.files("proxops.environment").joinpath("data", DATA_FILE).open("rb") as fh:
        data = np.load(fh)
        return data["C"].copy(), data["S"].copy(), float(data["gm"]), float(data["radius"])


def recursion_coefficients(nmax: int, C: np.ndarray, S: np.ndarray) -> np.ndarray:
    """Precomputed factors K (16, nmax + 3, nmax + 3) so that the kernel takes no square root
    and does one fused multiply-add per term: K[0] = a_nm, K[1] = b_nm (recursion), and the
    products with the coefficients K[2] = c1 C (c0 C at m = 0), K[3] = c1 S, K[4] = c2 C,
    K[5] = c2 S, K[6] = c3 C, K[7] = c3 S (module doc; C, S to degree ``nmax``). K[8:16],
    read as (nmax + 3, nmax + 3, 8), holds for each (n, m) the signed pairs (K4, K5), (K5, -K4),
    (-K2, K3), (-K3, -K2) of :func:`accel_harmonics_pair` (adjacent in memory: one load each)."""
    K = np.zeros((16, nmax + 3, nmax + 3))
    # whole-array form of the loop over 0 <= m <= n <= nmax + 2 (the same IEEE operations per entry,
    # bit-identical; 100x100: 2.8 ms instead of 16 ms)
    n, m = np.meshgrid(np.arange(nmax + 3), np.arange(nmax + 3), indexing="ij")
    nf, mf = n.astype(float), m.astype(float)
    low = m <= n
    with np.errstate(divide="ignore", invalid="ignore"):
        a = low & (n >= m + 1)
        K[0][a] = np.sqrt(((2.0 * nf + 1.0) * (2.0 * nf - 1.0) / ((n - m) * (n + m)))[a])
        b = low & (n >= m + 2)
        K[1][b] = np.sqrt(((2.0 * nf + 1.0) * (nf + mf - 1.0) * (nf - mf - 1.0)
                           / ((2.0 * nf - 3.0) * (nf + mf) * (nf - mf)))[b])  # fmt: skip
        tn, tn3 = 2.0 * nf + 1.0, 2.0 * nf + 3.0
        c1 = np.where(m == 0, np.sqrt(tn * (nf + 1.0) * (nf + 2.0) / (2.0 * tn3)),
                      np.sqrt(tn * (nf + mf + 1.0) * (nf + mf + 2.0) / tn3))  # fmt: skip
        c2 = np.where(m == 0, 0.0, np.sqrt(np.where(m == 1, 2.0, 1.0) * tn * (nf - mf + 1.0) * (nf - mf + 2.0) / tn3))
        c3 = np.sqrt(tn * (nf + mf + 1.0) * (nf - mf + 1.0) / tn3)
    cs = np.zeros((2, nmax + 3, nmax + 3))
    cs[0, : nmax + 1, : nmax + 1] = C[: nmax + 1, : nmax + 1]
    cs[1, : nmax + 1, : nmax + 1] = S[: nmax + 1, : nmax + 1]
    inner = low & (n <= nmax)
    for plane, value in zip(range(2, 8), (c1 * cs[0], c1 * cs[1], c2 * cs[0], c2 * cs[1], c3 * cs[0], c3 * cs[1])):
        K[plane][inner] = value[inner]
    # planes 8..15 read as (nmax + 3, nmax + 3, 8): per (n, m) the signed coefficient pairs of
    # the two-point kernel's sums (see _pair_order_sums)
    pairs = K[8:].reshape(nmax + 3, nmax + 3, 8)
    for k, (plane, sign) in enumerate(((4, 1), (5, 1), (5, 1), (4, -1), (2, -1), (3, 1), (3, -1), (2, -1))):
        pairs[:, :, k] = sign * K[plane]
    return K


@njit(inline="always", fastmath=False)
def _scaled_position(x, y, z, re):
    """(r^2, (re/r)^2, x re/r^2, y re/r^2, z re/r^2) of an Earth-fixed position (m): the start of the
    V/W recursion, shared by the single-point and the two-point kernels (the same IEEE operations)."""
    r2 = x * x + y * y + z * z
    return r2, re * re / r2, x * re / r2, y * re / r2, z * re / r2


@njit(cache=True, fastmath=False)  # IEEE on purpose (determinism), see the docstring
def accel_harmonics(
    x: float, y: float, z: float, gm: float, re: float, C: np.ndarray, S: np.ndarray, nmax: int, mmax: int,
    nmin: int, K: np.ndarray, V: np.ndarray, W: np.ndarray,
):  # fmt: skip
    """Acceleration (m/s^2, Earth-fixed axes) of the degree ``nmin..nmax``, order ``<= mmax``
    terms at Earth-fixed position (m). ``nmin = 0`` includes the central term, ``nmin = 2``
    gives the perturbation only. ``K`` from :func:`recursion_coefficients` (it carries the
    coefficients C, S multiplied in; ``C``, ``S`` are kept in the signature for
    :func:`potential_harmonics`); ``V``, ``W``: work arrays (>= nmax + 2, >= nmax + 2),
    filled with V_nm, W_nm on return.

    Loop order (for speed, same recursion): degree-outer, order-inner, so that the
    inner loops run over contiguous rows with no dependency between orders (SIMD), and
    the terms of degree n are summed as soon as row n + 1 of V, W exists (in cache).
    Strict IEEE arithmetic (``fastmath=False``), on purpose: with fastmath LLVM reassociated
    and fused (FMA) the sums differently in each compiled copy of this kernel (standalone, and
    inlined into every caller's object: _harmonics_eci, the truth integrators), so the same
    input gave results differing by ~1e-15 relative between a freshly compiled and a
    disk-cached caller, and within one process by which copy was loaded first. That made
    campaign runs depend on the worker's history (cortex-high-mc seed 2 run 9 recomputed in
    some executions only). Measured cost (load ~2): 1.09x (degree 100) to 1.17x (degree 20)
    the fastmath time per standalone call, ~1.36x on one orbit of the default "fast" truth
    (100x100, best of 7: 12.3 ms against 9.0 ms; the inlined fastmath sums vectorised).
    tests/test_determinism.py checks the bits."""
    r2, rho, x0, y0, z0 = _scaled_position(x, y, z, re)
    mtop = min(mmax + 1, nmax + 1)
    V[0, 0] = re / math.sqrt(r2)
    W[0, 0] = 0.0
    ax = 0.0
    ay = 0.0
    az = 0.0
    for n in range(1, nmax + 2):
        # row n of V, W: orders m <= n - 2 by the two-term recursion in n, then the
        # sub-diagonal (m = n - 1) and the diagonal (m = n)
        a_row = K[0, n]
        b_row = K[1, n]
        vn1 = V[n - 1]
        wn1 = W[n - 1]
        vn2 = V[n - 2] if n >= 2 else V[0]
        wn2 = W[n - 2] if n >= 2 else W[0]
        vr = V[n]
        wr = W[n]
        for m in range(0, min(n - 1, mtop + 1)):
            a = a_row[m] * z0
            b = b_row[m] * rho
            vr[m] = a * vn1[m] - b * vn2[m]
            wr[m] = a * wn1[m] - b * wn2[m]
        if n - 1 <= mtop:
            a = a_row[n - 1] * z0
            vr[n - 1] = a * vn1[n - 1]
            wr[n - 1] = a * wn1[n - 1]
        if n <= mtop:
            f = 1.7320508075688772 if n == 1 else math.sqrt((2.0 * n + 1.0) / (2.0 * n))
            vp = vn1[n - 1]
            wp = wn1[n - 1]
            vr[n] = f * (x0 * vp - y0 * wp)
            wr[n] = f * (x0 * wp + y0 * vp)
        d = n - 1  # the terms of degree d need row d + 1 = n only
        if d < nmin:
            continue
        c1c = K[2, d]
        c1s = K[3, d]
        c2c = K[4, d]
        c2s = K[5, d]
        c3c = K[6, d]
        c3s = K[7, d]
        az -= c3c[0] * vr[0]
        ax -= c1c[0] * vr[1]
        ay -= c1c[0] * wr[1]
        sx = 0.0
        sy = 0.0
        sz = 0.0
        for m in range(1, min(d, mmax) + 1):
            sz -= c3c[m] * vr[m] + c3s[m] * wr[m]
            sx += c2c[m] * vr[m - 1] + c2s[m] * wr[m - 1] - c1c[m] * vr[m + 1] - c1s[m] * wr[m + 1]
            sy += c2s[m] * vr[m - 1] - c2c[m] * wr[m - 1] + c1s[m] * vr[m + 1] - c1c[m] * wr[m + 1]
        ax += 0.5 * sx
        ay += 0.5 * sy
        az += sz
    k = gm / (re * re)
    return k * ax, k * ay, k * az


# ----------------------------------------------------------------------------- two points per pass
# The truth integrators always need the field at the target and the chaser together.
# accel_harmonics_pair runs the recursion and the sums of accel_harmonics once for both
# points, the two points in the lanes of SIMD registers: per lane, exactly the scalar
# kernel's IEEE operations in its order (no fusion, no reassociation), so each point's
# result equals a single-point call bit for bit (tests/test_harmonics.py). LLVM does not
# vectorise the strict-IEEE sums by itself (the serial sums over m are loop-carried
# reductions), so the two inner loops are written as LLVM vector IR (numba intrinsics).
#
# Work array ``VW`` (>= 3 rows, >= 4 (nmax + 2) columns, C order): a ring of three rows (the
# recursion needs rows n - 1 and n - 2, the sums of degree n - 1 row n only, and no caller
# reads V, W afterwards), row n of V, W in VW[n % 3], holding for each order m
# (V_nm at a, W_nm at a, V_nm at b, W_nm at b) at columns 4 m .. 4 m + 3: ~10 kB at degree
# 100, in L1 (the full triangle of the single-point kernel is ~170 kB).
_F64 = ir.DoubleType()
_I32 = ir.IntType(32)
_I64 = ir.IntType(64)
_VEC2 = ir.VectorType(_F64, 2)
_VEC4 = ir.VectorType(_F64, 4)


def _item_ptr(context, builder, ary_type, ary_value, indices):
    """double* to ary[indices] (C-contiguous array, no bounds check)."""
    ary = context.make_array(ary_type)(context, builder, ary_value)
    shape = cgutils.unpack_tuple(builder, ary.shape, ary_type.ndim)
    strides = cgutils.unpack_tuple(builder, ary.strides, ary_type.ndim)
    return cgutils.get_item_pointer2(context, builder, ary.data, shape, strides, ary_type.layout, indices)


def _load_vec(builder, base, index, vec_type):
    """vec_type (<k x double>) at base[index .. index + k - 1] (align 8: rows are not 16-byte aligned)."""
    return builder.load(builder.bitcast(builder.gep(base, [index]), vec_type.as_pointer()), align=8)


def _splat(builder, value, vec_type):
    lanes = vec_type.count
    vec = builder.insert_element(ir.Constant(vec_type, ir.Undefined), value, ir.Constant(_I32, 0))
    return builder.shuffle_vector(vec, ir.Constant(vec_type, ir.Undefined), ir.Constant(ir.VectorType(_I32, lanes), [0] * lanes))


def _i64(builder, value):
    return value if value.type == _I64 else builder.sext(value, _I64)


def _check_c_arrays(*arrays):
    for a in arrays:
        if not (isinstance(a, types.Array) and a.dtype == types.float64 and a.layout == "C"):
            raise TypingError(f"C-contiguous float64 array expected, got {a}")


@intrinsic
def _pair_row(typingctx, VW, K, n, rows, m_end, sub, diag, za, zb, rhoa, rhob, xa, xb, ya, yb, f):
    """Row n of ``VW`` (both lanes, V and W; n >= 1), as in :func:`accel_harmonics`, one
    <4 x double> per order: orders m = 0 .. m_end - 1 by (a_nm z') X_{n-1,m} - (b_nm rho'^2)
    X_{n-2,m}; if ``sub`` the sub-diagonal (a_{n,n-1} z') X_{n-1,n-1}; if ``diag`` the diagonal
    V_nn = f (x' V - y' W)_{n-1,n-1}, W_nn = f (x' W + y' V)_{n-1,n-1}. All stored as vectors,
    so the next row's vector loads are forwarded from these stores."""
    _check_c_arrays(VW, K)
    sig = types.void(VW, K, n, rows, m_end, sub, diag, za, zb, rhoa, rhob, xa, xb, ya, yb, f)

    def codegen(context, builder, signature, args):
        vw_t, k_t = signature.args[0], signature.args[1]
        n_ = _i64(builder, args[2])
        one = ir.Constant(_I64, 1)
        zero = ir.Constant(_I64, 0)
        four = ir.Constant(_I64, 4)
        rows_ = cgutils.unpack_tuple(builder, args[3], 3)
        out = _item_ptr(context, builder, vw_t, args[0], [_i64(builder, rows_[0]), zero])
        row1 = _item_ptr(context, builder, vw_t, args[0], [_i64(builder, rows_[1]), zero])
        row2 = _item_ptr(context, builder, vw_t, args[0], [_i64(builder, rows_[2]), zero])
        ka = _item_ptr(context, builder, k_t, args[1], [zero, n_, zero])
        kb = _item_ptr(context, builder, k_t, args[1], [one, n_, zero])

        def lanes(a, b):  # (a, a, b, b): the (V a, W a, V b, W b) lanes of one order
            vec = ir.Constant(_VEC4, ir.Undefined)
            for lane, value in enumerate((a, a, b, b)):
                vec = builder.insert_element(vec, value, ir.Constant(_I32, lane))
            return vec

        def store(index, value):
            builder.store(value, builder.bitcast(builder.gep(out, [index]), _VEC4.as_pointer()), align=8)

        zz = lanes(args[7], args[8])
        rr = lanes(args[9], args[10])
        with cgutils.for_range(builder, _i64(builder, args[4])) as loop:
            m = loop.index
            j = builder.mul(m, four)
            a = builder.fmul(_splat(builder, builder.load(builder.gep(ka, [m])), _VEC4), zz)
            b = builder.fmul(_splat(builder, builder.load(builder.gep(kb, [m])), _VEC4), rr)
            store(j, builder.fsub(builder.fmul(a, _load_vec(builder, row1, j, _VEC4)),
                                  builder.fmul(b, _load_vec(builder, row2, j, _VEC4))))  # fmt: skip
        j = builder.mul(builder.sub(n_, one), four)  # order n - 1
        with builder.if_then(args[5]):
            a = builder.fmul(_splat(builder, builder.load(builder.gep(ka, [builder.sub(n_, one)])), _VEC4), zz)
            store(j, builder.fmul(a, _load_vec(builder, row1, j, _VEC4)))
        with builder.if_then(args[6]):
            p = _load_vec(builder, row1, j, _VEC4)  # (V a, W a, V b, W b) at (n - 1, n - 1)
            q = builder.shuffle_vector(p, ir.Constant(_VEC4, ir.Undefined),
                                       ir.Constant(ir.VectorType(_I32, 4), [1, 0, 3, 2]))  # (W a, V a, W b, V b)  # fmt: skip
            t1 = builder.fmul(lanes(args[11], args[12]), p)  # x' V, x' W
            t2 = builder.fmul(lanes(args[13], args[14]), q)  # y' W, y' V
            value = builder.shuffle_vector(builder.fsub(t1, t2), builder.fadd(t1, t2),
                                           ir.Constant(ir.VectorType(_I32, 4), [0, 5, 2, 7]))  # fmt: skip
            store(builder.add(j, four), builder.fmul(_splat(builder, args[15], _VEC4), value))
        return context.get_dummy_value()

    return sig, codegen


@intrinsic
def _pair_order_sums(typingctx, VW, K, d, row, m_last):
    """(sx_a, sx_b, sy_a, sy_b, sz_a, sz_b): the sums over m = 1 .. m_last of degree d in
    :func:`accel_harmonics` (from row d + 1, ``VW[row]``), per lane in the scalar order.

    sx and sy of both points share one <4 x double> (lanes sx_a, sy_a, sx_b, sy_b): the
    scalar kernel's sx term c2c V + c2s W - c1c V' - c1s W' and sy term c2s V - c2c W + c1s V'
    - c1c W' (V, W at m - 1, V', W' at m + 1) are the same chain of products and sums once
    the subtractions are written as additions of the negated coefficient, which IEEE
    arithmetic makes exact (a - b = a + (-b), (-c) x = -(c x)): four products of the
    coefficient pairs (c2c, c2s), (c2s, -c2c), (-c1c, c1s), (-c1s, -c1c) (K planes 8..15,
    :func:`recursion_coefficients`) with (V, V), (W, W), (V', V'), (W', W') of each point.
    sz (lanes sz_a, sz_a, sz_b, sz_b) as in the scalar kernel."""
    _check_c_arrays(VW, K)
    sig = types.UniTuple(types.float64, 6)(VW, K, d, row, m_last)

    def codegen(context, builder, signature, args):
        vw_t, k_t = signature.args[0], signature.args[1]
        d_ = _i64(builder, args[2])
        zero = ir.Constant(_I64, 0)
        four = ir.Constant(_I64, 4)
        row = _item_ptr(context, builder, vw_t, args[0], [_i64(builder, args[3]), zero])
        k3c, k3s = (_item_ptr(context, builder, k_t, args[1], [ir.Constant(_I64, i), d_, zero]) for i in (6, 7))
        width = cgutils.unpack_tuple(builder, context.make_array(k_t)(context, builder, args[1]).shape, 3)[2]
        pairs = builder.gep(_item_ptr(context, builder, k_t, args[1], [ir.Constant(_I64, 8), zero, zero]),
                            [builder.mul(d_, builder.mul(width, ir.Constant(_I64, 8)))])  # fmt: skip
        undef4 = ir.Constant(_VEC4, ir.Undefined)

        def spread(vec, lo, hi):  # (vec[lo], vec[lo], vec[hi], vec[hi]), in-lane
            return builder.shuffle_vector(vec, undef4, ir.Constant(ir.VectorType(_I32, 4), [lo, lo, hi, hi]))

        def pair(index):  # (p0, p1, p0, p1) from pairs[index], pairs[index + 1]
            vec = _load_vec(builder, pairs, index, _VEC2)
            return builder.shuffle_vector(vec, ir.Constant(_VEC2, ir.Undefined),
                                          ir.Constant(ir.VectorType(_I32, 4), [0, 1, 0, 1]))  # fmt: skip

        vzero = ir.Constant(_VEC4, [0.0] * 4)
        sxy, sz = (cgutils.alloca_once_value(builder, vzero) for _ in range(2))
        first = _load_vec(builder, row, zero, _VEC4)
        second = _load_vec(builder, row, four, _VEC4)
        carried = [cgutils.alloca_once_value(builder, v) for v in
                   (spread(first, 0, 2), spread(first, 1, 3), spread(second, 0, 2), spread(second, 1, 3))]  # fmt: skip
        with cgutils.for_range(builder, _i64(builder, args[4])) as loop:
            m = builder.add(loop.index, ir.Constant(_I64, 1))
            nxt = _load_vec(builder, row, builder.mul(builder.add(m, ir.Constant(_I64, 1)), four), _VEC4)
            vm1, wm1, v0, w0 = (builder.load(c) for c in carried)  # (V a, V a, V b, V b) etc.
            vp1 = spread(nxt, 0, 2)
            wp1 = spread(nxt, 1, 3)
            base = builder.mul(m, ir.Constant(_I64, 8))
            q1, q2, q3, q4 = (pair(builder.add(base, ir.Constant(_I64, 2 * k))) for k in range(4))
            a3c = _splat(builder, builder.load(builder.gep(k3c, [m])), _VEC4)
            a3s = _splat(builder, builder.load(builder.gep(k3s, [m])), _VEC4)
            fmul, fadd, fsub = builder.fmul, builder.fadd, builder.fsub
            # sz -= c3c V_m + c3s W_m
            builder.store(fsub(builder.load(sz), fadd(fmul(a3c, v0), fmul(a3s, w0))), sz)
            # (sx, sy) += ((q1 V_{m-1} + q2 W_{m-1}) + q3 V_{m+1}) + q4 W_{m+1}
            t = fadd(fadd(fadd(fmul(q1, vm1), fmul(q2, wm1)), fmul(q3, vp1)), fmul(q4, wp1))
            builder.store(fadd(builder.load(sxy), t), sxy)
            for slot, value in zip(carried, (v0, w0, vp1, wp1)):
                builder.store(value, slot)
        a = builder.load(sxy)
        z = builder.load(sz)
        out = [builder.extract_element(vec, ir.Constant(_I32, lane)) for vec, lane in
               ((a, 0), (a, 2), (a, 1), (a, 3), (z, 0), (z, 2))]  # fmt: skip
        return context.make_tuple(builder, signature.return_type, out)

    return sig, codegen


@njit(cache=True)
def pair_arrays_fit(K: np.ndarray, VW: np.ndarray, nmax: int) -> bool:
    """True if ``K`` has the pair planes (16 planes, :func:`recursion_coefficients`) and ``VW`` can
    hold the pair layout to degree ``nmax`` (see :func:`accel_harmonics_pair`)."""
    return K.shape[0] >= 16 and K.shape[1] >= nmax + 3 and VW.shape[0] >= 3 and VW.shape[1] >= 4 * (nmax + 2)


@njit(cache=True, fastmath=False)  # IEEE on purpose (determinism), see accel_harmonics
def accel_harmonics_pair(
    xa: float, ya: float, za: float, xb: float, yb: float, zb: float, gm: float, re: float, nmax: int, mmax: int,
    nmin: int, K: np.ndarray, VW: np.ndarray,
):  # fmt: skip
    """(ax_a, ay_a, az_a, ax_b, ay_b, az_b): :func:`accel_harmonics` (m/s^2, Earth-fixed) at
    the two Earth-fixed points a and b (m) in one pass, bit-identical to two single-point
    calls (same recursion and sums, per lane the same IEEE operations in the same order; see
    the section comment). ``VW``: work array in the pair layout (:func:`pair_arrays_fit`;
    not checked here: the caller checks, an undersized array is written out of bounds)."""
    r2a, rhoa, xa0, ya0, za0 = _scaled_position(xa, ya, za, re)
    r2b, rhob, xb0, yb0, zb0 = _scaled_position(xb, yb, zb, re)
    mtop = min(mmax + 1, nmax + 1)
    VW[0, 0] = re / math.sqrt(r2a)
    VW[0, 1] = 0.0
    VW[0, 2] = re / math.sqrt(r2b)
    VW[0, 3] = 0.0
    axa = 0.0
    axb = 0.0
    aya = 0.0
    ayb = 0.0
    aza = 0.0
    azb = 0.0
    for n in range(1, nmax + 2):
        diag = n <= mtop
        f = (1.7320508075688772 if n == 1 else math.sqrt((2.0 * n + 1.0) / (2.0 * n))) if diag else 0.0
        rows = (n % 3, (n + 2) % 3, (n + 1) % 3)  # rows n, n - 1, n - 2 of the three-row ring
        _pair_row(VW, K, n, rows, min(n - 1, mtop + 1), n - 1 <= mtop, diag, za0, zb0, rhoa, rhob, xa0, xb0, ya0, yb0,
                  f)  # fmt: skip
        d = n - 1  # the terms of degree d need row d + 1 = n only
        if d < nmin:
            continue
        c1c0 = K[2, d, 0]
        c3c0 = K[6, d, 0]
        row = rows[0]
        aza -= c3c0 * VW[row, 0]
        azb -= c3c0 * VW[row, 2]
        axa -= c1c0 * VW[row, 4]
        axb -= c1c0 * VW[row, 6]
        aya -= c1c0 * VW[row, 5]
        ayb -= c1c0 * VW[row, 7]
        sxa, sxb, sya, syb, sza, szb = _pair_order_sums(VW, K, d, row, min(d, mmax))
        axa += 0.5 * sxa
        axb += 0.5 * sxb
        aya += 0.5 * sya
        ayb += 0.5 * syb
        aza += sza
        azb += szb
    k = gm / (re * re)
    return k * axa, k * aya, k * aza, k * axb, k * ayb, k * azb


@njit(cache=True, fastmath=False)
def potential_harmonics(x, y, z, gm, re, C, S, nmax, mmax, nmin, K, V, W) -> float:
    """Gravitational potential U (J/kg, a = +grad U) of the same terms, from V, W."""
    accel_harmonics(x, y, z, gm, re, C, S, nmax, mmax, nmin, K, V, W)  # fills V, W
    u = 0.0
    for n in range(nmax, nmin - 1, -1):
        for m in range(min(n, mmax), -1, -1):
            u += C[n, m] * V[n, m] + S[n, m] * W[n, m]
    return gm / re * u


@dataclass
class SphericalHarmonics:
    """EGM96 gravity field to ``degree`` x ``order`` (<= 120, shipped). ``include_central``
    adds the point-mass term (n = 0); otherwise degrees 2..degree only. Positions and
    accelerations in Earth-fixed axes (SI); see :mod:`proxops.environment.earth` for the
    rotation from ECI."""

    degree: int
    order: int
    include_central: bool = False
    gm: float = field(init=False)
    re: float = field(init=False)

    def __post_init__(self) -> None:
        check_degree_order(self.degree, self.order)
        C, S, self.gm, self.re = _shipped()
        n = self.degree
        self.C = np.ascontiguousarray(C[: n + 1, : n + 1])
        self.S = np.ascontiguousarray(S[: n + 1, : n + 1])
        if self.include_central:
            self.C[0, 0] = 1.0
        self.K = recursion_coefficients(n, self.C, self.S)
        self._V = np.zeros((n + 3, n + 3))
        self._W = np.zeros((n + 3, n + 3))

    @property
    def nmin(self) -> int:
        return 0 if self.include_central else 2

    def acceleration(self, r_ecef: np.ndarray) -> np.ndarray:
        """Acceleration (..., 3) m/s^2 at Earth-fixed position(s) (..., 3) m."""
        r = np.asarray(r_ecef, dtype=float)
        flat = r.reshape(-1, 3)
        out = np.array(
            [
                accel_harmonics(p[0], p[1], p[2], self.gm, self.re, self.C, self.S, self.degree, self.order,
                                self.nmin, self.K, self._V, self._W)
                for p in flat
            ]
        )  # fmt: skip
        return out.reshape(r.shape)

    def potential(self, r_ecef: np.ndarray) -> np.ndarray:
        """Potential U (...,) J/kg with a = +grad U."""
        r = np.asarray(r_ecef, dtype=float)
        flat = r.reshape(-1, 3)
        out = np.array(
            [
                potential_harmonics(p[0], p[1], p[2], self.gm, self.re, self.C, self.S, self.degree, self.order,
                                    self.nmin, self.K, self._V, self._W)
                for p in flat
            ]
        )  # fmt: skip
        return out.reshape(r.shape[:-1])


def check_degree_order(degree, order, prefix: str = "truth.") -> None:
    """Raise ProxopsInputError unless 2 <= degree <= shipped degree and 0 <= order <= degree."""
    if isinstance(degree, bool) or not isinstance(degree, (int, np.integer)) or not 2 <= degree <= SHIPPED_DEGREE:
        raise input_error(
            f"{prefix}gravity_degree", degree, f"must be an integer in [2, {SHIPPED_DEGREE}] (shipped EGM96 truncation)"
        )
    if isinstance(order, bool) or not isinstance(order, (int, np.integer)) or not 0 <= order <= degree:
        raise input_error(f"{prefix}gravity_order", order, f"must be an integer in [0, gravity_degree = {degree}]")
