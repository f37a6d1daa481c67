"""Natural logarithm and exponential that compile to SIMD inside numba loops.

numba calls libm's ``log`` and ``exp`` one value at a time (this llvmlite has no SVML), so a loop
that takes a logarithm cannot be vectorised, and the Table 8 update spends a third of its time in
them (1/eta_B of Eq. 9 and the pore pressure kappa ln(rho_f/rho_0f): 63 -> 43 ns a point in the
MPM's locked-mixture kernel when they are removed, measured). :func:`log` and :func:`exp` here
are branch-free (selects) double-precision implementations of the classical reductions (Tang
1989; fdlibm's ``e_log.c`` form of the logarithm), so a loop that calls them compiles to SIMD
instructions. Accuracy (tested against numpy on 2e6 values spread over the whole double range):
at most 1 ulp apart from numpy's results; special values as IEEE-754 (log: 0 -> -inf, x < 0 or
NaN -> NaN, inf -> inf, subnormals exact; exp: overflow -> inf, underflow -> 0 through the
subnormals, NaN -> NaN).

Called from Python (scalars or arrays) they are numpy's ``np.log`` / ``np.exp``; compiled by
numba they are the polynomial versions (``numba.extending.overload``), so the same law function
(rheology.laws) serves both.

Method
------
log x: x = 2^e m with m in [sqrt(1/2), sqrt(2)) from the bits of x; with f = m - 1 (exact) and
s = f/(2 + f), ln m = 2 atanh(s) = f - s (f - R(s^2)), R(z) = sum_k 2 z^k/(2k + 1) to k = 11
(|s| <= 0.1716, truncation < 1e-19 relative); ln x = e ln2_hi + (e ln2_lo + ln m).
exp y: n = round(y/ln2) by the 1.5 2^52 shift, r = y - n ln2 (two-part ln2, |r| <= 0.347), the
Taylor series of e^r to degree 13 (truncation < 5e-18), times 2^n built from the exponent bits in
two factors (so subnormal results and overflow to inf come out right).
Both polynomials by Horner's rule in fused multiply-adds (one rounding a step; in a SIMD loop
twice the throughput of a multiply and an add, and half the latency of each step).
"""

from __future__ import annotations

import math

import numpy as np
from llvmlite import ir
from numba import types
from numba.extending import intrinsic, overload, register_jitable

__all__ = ["log", "exp"]


@intrinsic
def _bits(typingctx, x):
    """The IEEE-754 bits of a float64 as an int64 (a bitcast: no conversion)."""
    if x != types.float64:
        return None

    def codegen(context, builder, signature, args):
        return builder.bitcast(args[0], ir.IntType(64))
    return types.int64(types.float64), codegen


@intrinsic
def _from_bits(typingctx, b):
    """The float64 whose IEEE-754 bits are the int64 b (a bitcast)."""
    if b != types.int64:
        return None

    def codegen(context, builder, signature, args):
        return builder.bitcast(args[0], ir.DoubleType())
    return types.float64(types.int64), codegen


@intrinsic
def _fma(typingctx, a, b, c):
    """a b + c rounded once (llvm.fma: one FMA instruction, vectorised in SIMD loops; numba
    does not fuse a multiply and an add by itself)."""
    if not (a == types.float64 and b == types.float64 and c == types.float64):
        return None

    def codegen(context, builder, signature, args):
        d = ir.DoubleType()
        fn = builder.module.declare_intrinsic("llvm.fma", [d], ir.FunctionType(d, [d, d, d]))
        return builder.call(fn, args)
    return types.float64(types.float64, types.float64, types.float64), codegen


_LN2_HI = 6.93147180369123816490e-01       # ln 2 to 32 bits (e ln2_hi exact for |e| < 2^20)
_LN2_LO = 1.90821492927058770002e-10       # ln 2 - _LN2_HI
_SQRT2 = 1.4142135623730951
_MANTISSA = (1 << 52) - 1
_ONE_BITS = 1023 << 52
_SHIFT = 6755399441055744.0                # 1.5 2^52: adding it rounds to an integer
_SHIFT_BITS = 0x4338000000000000
_TWO52_BITS = 0x4330000000000000           # 2^52: its bits | k read k + 2^52 for k < 2^52
_MIN_NORMAL = 2.2250738585072014e-308
_TWO54 = 18014398509481984.0
_INV_LN2 = 1.4426950408889634
#: R(z)/z = sum_k 2 z^(k-1) / (2k + 1), k = 11..1, and e^r = sum_k r^k/k!, k = 13..0: the
#: polynomials' coefficients, highest power first (for :func:`_horner`)
_LOG_R = tuple(2.0 / (2 * k + 1) for k in range(11, 0, -1))
_EXP_P = tuple(1.0 / math.factorial(k) for k in range(13, -1, -1))


@register_jitable(inline="always")
def _horner(x, coeffs):
    """sum_k coeffs[k] x^(n - k) by Horner's rule, one fused multiply-add a step."""
    p = coeffs[0]
    for c in coeffs[1:]:
        p = _fma(p, x, c)
    return p


@register_jitable(inline="always")
def _log_jit(x):
    sub = x < _MIN_NORMAL
    xs = x * _TWO54 if sub else x
    b = _bits(xs)
    eb = (b >> 52) & 0x7FF                                 # biased exponent (a logical shift)
    m = _from_bits((b & _MANTISSA) | _ONE_BITS)           # [1, 2)
    big = m > _SQRT2
    m = 0.5 * m if big else m
    e = (_from_bits(_TWO52_BITS | eb) - 4503599627370496.0) - 1023.0
    e = e + (1.0 if big else 0.0) - (54.0 if sub else 0.0)
    f = m - 1.0
    s = f / (2.0 + f)
    z = s * s
    R = _horner(z, _LOG_R) * z
    r = e * _LN2_HI + (e * _LN2_LO + (f - s * (f - R)))
    r = -np.inf if x == 0.0 else r
    r = x if x == np.inf else r
    return np.nan if not x >= 0.0 else r


@register_jitable(inline="always")
def _exp_jit(y):
    yc = min(max(y, -746.0), 710.0)
    t = yc * _INV_LN2 + _SHIFT
    nf = t - _SHIFT                                        # round(y / ln 2), as a float
    r = (yc - nf * _LN2_HI) - nf * _LN2_LO
    p = _horner(r, _EXP_P)
    # 2^n = 2^n1 2^n2, n1 = floor(n/2): each factor a normal number, so subnormal results and
    # overflow come out right; the integers from the shift trick (float and int64 adds only)
    n1f = np.floor(0.5 * nf)
    n1 = _bits(n1f + _SHIFT) - _SHIFT_BITS
    n2 = _bits((nf - n1f) + _SHIFT) - _SHIFT_BITS
    v = p * _from_bits((n1 + 1023) << 52) * _from_bits((n2 + 1023) << 52)
    return y + y if y != y else v


def log(x):
    """Natural logarithm: ``np.log`` from Python, the SIMD-friendly version under numba.

    Parameters: x, float or array (float). Returns: ln x, same shape; see the module docstring
    for accuracy (<= 1 ulp from numpy) and special values.
    """
    return np.log(x)


def exp(y):
    """Exponential: ``np.exp`` from Python, the SIMD-friendly version under numba (scalars).

    Parameters: y, float or array (float). Returns: e^y, same shape; <= 1 ulp from numpy.
    """
    return np.exp(y)


@overload(log, inline="always")
def _log_overload(x):
    if isinstance(x, types.Float):
        return lambda x: _log_jit(float(x))
    return lambda x: np.log(x)


@overload(exp, inline="always")
def _exp_overload(y):
    if isinstance(y, types.Float):
        return lambda y: _exp_jit(float(y))
    return lambda y: np.exp(y)
