"""exp(-x^2) and erfc(x) in plain arithmetic, for the screened real-space pairs of Ewald sums.

numba turns ``math.exp`` into a call of the C library and ``math.erfc`` into a call of a C helper;
neither vectorises, so a block of screened pairs (demkit.interactions.ewald, demkit.engine.generic's blocked
pair loops) ran one pair at a time, ~75 ns each, most of a P3M step. These two functions are only
multiplications, additions and bit operations, which LLVM runs on four pairs at once (AVX2), and
they share their exponential: erfc(x) = erfcx(x) exp(-x^2).

* :func:`gaussian` x -> exp(-x^2). With y = -x^2: k = rint(y / ln 2), r = y - k ln 2 (ln 2 in two
  parts, Cody and Waite, so that k ln2_hi is exact), |r| <= ln(2)/2, e^r by its Taylor series to r^13
  (truncation below 5e-18), 2^k built in the exponent bits. y < -708 (2^k below the smallest normal
  number) gives 0 (the true value is below 3e-308), NaN gives NaN. Relative error: two units in the
  last place against ``math.exp(-x * x)`` (``tests/test_special_functions.py``).
* :func:`erfc_scaled` x -> erfcx(x) = exp(x^2) erfc(x) for x >= 0: t = s/(s + x) (s = 4) maps
  [0, inf) onto (0, 1], where erfcx(x) (s + x)/s is smooth; its Chebyshev interpolant of degree 20
  in 2t - 1 (:data:`ERFCX_CHEBYSHEV`, from :func:`fit_erfcx`) is summed by Clenshaw's recurrence.
  Relative error below 1e-14 for every x >= 0.
* :func:`erfc` = erfc_scaled(x) gaussian(x), x >= 0: relative error below 1e-14 for x < 6 (every
  screened pair of a sum tuned by demkit), growing as x^2 ulp beyond (the rounding of x^2);
  :func:`screened` gives it with the Gaussian term of the screened pairs, from one exponential.
"""
from __future__ import annotations

import numpy as np
from numba import njit, types
from numba.core.extending import intrinsic
from llvmlite import ir

from ..engine.motion import KERNEL_OPTIONS

#: t = ERFCX_SCALE / (ERFCX_SCALE + x)
ERFCX_SCALE = 4.0
#: Chebyshev coefficients (in 2t - 1) of erfcx(x) (s + x)/s, interpolated at the 21 Chebyshev points
#: (fit_erfcx(); tests/test_special_functions.py checks that the fit gives them again)
ERFCX_CHEBYSHEV = np.array((
    0.40802446954913135, 0.3763582356763674, 0.1475803545722234, 0.04957131793002755,
    0.01422710755711737, 0.003443493262717322, 0.0006822541832837137, 0.0001034045197574484,
    9.72854595190127e-06, -1.198871376296041e-07, -2.1747767697037275e-07, -3.0291768048960843e-08,
    9.479919745119963e-10, 8.633410897517493e-10, 6.872143158738528e-11, -1.7035105739937274e-11,
    -3.3922811100214054e-12, 2.6148931173934587e-13, 1.2122832249236643e-13, -2.3940730683682906e-15,
    -4.420897897715865e-15))
_DEGREE = ERFCX_CHEBYSHEV.shape[0] - 1

_LOG2_E = 1.4426950408889634
_LN2_HI = 0.6931471803691238  # ln 2 to 32 bits: k * _LN2_HI is exact for |k| < 2^20
_LN2_LO = 1.9082149292705877e-10  # ln 2 - _LN2_HI
#: 2^52 + 1023: k + this, read as an integer, holds k + 1023 in its lowest bits
_SHIFTER = 4503599627371519.0
_LOWEST = -708.0  # exp of anything lower is below the smallest normal number: 0


@intrinsic
def _float_bits(typingctx, x):
    """The bits of a float64 as an int64."""
    def codegen(context, builder, signature, args):
        return builder.bitcast(args[0], ir.IntType(64))
    return types.int64(types.float64), codegen


@intrinsic
def _bits_float(typingctx, b):
    """The float64 whose bits are the int64 b."""
    def codegen(context, builder, signature, args):
        return builder.bitcast(args[0], ir.DoubleType())
    return types.float64(types.int64), codegen


@njit(**KERNEL_OPTIONS)
def gaussian(x):
    """exp(-x^2) (module docstring)."""
    exponent = -x * x
    y = _LOWEST if exponent < _LOWEST else exponent  # NaN stays NaN (and gives NaN)
    k = np.rint(y * _LOG2_E)
    r = (y - k * _LN2_HI) - k * _LN2_LO
    p = 1.0 / 6227020800.0
    p = p * r + 1.0 / 479001600.0
    p = p * r + 1.0 / 39916800.0
    p = p * r + 1.0 / 3628800.0
    p = p * r + 1.0 / 362880.0
    p = p * r + 1.0 / 40320.0
    p = p * r + 1.0 / 5040.0
    p = p * r + 1.0 / 720.0
    p = p * r + 1.0 / 120.0
    p = p * r + 1.0 / 24.0
    p = p * r + 1.0 / 6.0
    p = p * r + 0.5
    p = p * r + 1.0
    p = p * r + 1.0
    scale = _bits_float(_float_bits(k + _SHIFTER) << 52)  # 2^k
    return 0.0 if exponent < _LOWEST else p * scale


@njit(**KERNEL_OPTIONS)
def erfc_scaled(x):
    """erfcx(x) = exp(x^2) erfc(x) for x >= 0 (module docstring). Clenshaw's recurrence written out
    step by step: straight-line code, which LLVM vectorises over a loop of pairs (a loop over the
    coefficients inside that loop kept it scalar in the large generated pair loops)."""
    t = ERFCX_SCALE / (ERFCX_SCALE + x)
    u2 = 4.0 * t - 2.0  # 2 (2t - 1)
    c = ERFCX_CHEBYSHEV  # a global array: numba freezes it, and each c[k] below is a constant
    b1 = c[20]
    b2 = 0.0
    b1, b2 = u2 * b1 - b2 + c[19], b1
    b1, b2 = u2 * b1 - b2 + c[18], b1
    b1, b2 = u2 * b1 - b2 + c[17], b1
    b1, b2 = u2 * b1 - b2 + c[16], b1
    b1, b2 = u2 * b1 - b2 + c[15], b1
    b1, b2 = u2 * b1 - b2 + c[14], b1
    b1, b2 = u2 * b1 - b2 + c[13], b1
    b1, b2 = u2 * b1 - b2 + c[12], b1
    b1, b2 = u2 * b1 - b2 + c[11], b1
    b1, b2 = u2 * b1 - b2 + c[10], b1
    b1, b2 = u2 * b1 - b2 + c[9], b1
    b1, b2 = u2 * b1 - b2 + c[8], b1
    b1, b2 = u2 * b1 - b2 + c[7], b1
    b1, b2 = u2 * b1 - b2 + c[6], b1
    b1, b2 = u2 * b1 - b2 + c[5], b1
    b1, b2 = u2 * b1 - b2 + c[4], b1
    b1, b2 = u2 * b1 - b2 + c[3], b1
    b1, b2 = u2 * b1 - b2 + c[2], b1
    b1, b2 = u2 * b1 - b2 + c[1], b1
    return t * (0.5 * u2 * b1 - b2 + c[0])


@njit(**KERNEL_OPTIONS)
def erfc(x):
    """erfc(x) for x >= 0."""
    return erfc_scaled(x) * gaussian(x)


@njit(**KERNEL_OPTIONS)
def screened(x):
    """(erfc(x), (2 x / sqrt(pi)) exp(-x^2)) for x = alpha r >= 0: the two radial pieces of every
    Ewald-screened pair term (demkit.interactions.ewald), from one exponential."""
    g = gaussian(x)
    return erfc_scaled(x) * g, 1.1283791670955126 * x * g


def fit_erfcx(degree=_DEGREE, scale=ERFCX_SCALE):
    """The Chebyshev interpolant of erfcx(x) (s + x)/s in 2t - 1, t = s/(s + x), at degree + 1
    Chebyshev points (scipy.special.erfcx as the truth): how ERFCX_CHEBYSHEV was made."""
    from numpy.polynomial import chebyshev
    from scipy.special import erfcx
    k = np.arange(degree + 1)
    u = np.cos(np.pi * (k + 0.5) / (degree + 1))
    t = 0.5 * (u + 1.0)
    x = scale * (1.0 - t) / t
    return chebyshev.chebfit(u, erfcx(x) * (scale + x) / scale, degree)
