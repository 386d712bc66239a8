"""demkit.interactions.special_functions: exp(-x^2) and erfc(x) in plain arithmetic (vectorised in the
screened pair loops of Ewald sums) against the C library (math.exp, math.erfc) and scipy."""
import math

import numpy as np
from numba import njit

from demkit.interactions import special_functions as sf

ULP = 2.0 ** -52


@njit(cache=False)
def _evaluate(x, gauss, scaled, erfc):
    for k in range(x.shape[0]):
        gauss[k] = sf.gaussian(x[k])
        scaled[k] = sf.erfc_scaled(x[k])
        erfc[k] = sf.erfc(x[k])


def _values(x):
    out = [np.empty_like(x) for _ in range(3)]
    _evaluate(x, *out)
    return out


def test_gaussian_is_exp_of_minus_x_squared_to_an_ulp_down_to_the_smallest_normal_number():
    x = np.concatenate([np.linspace(0.0, 6.0, 200001), np.linspace(6.0, 26.6, 20001), [1e-300, 1e-8, 0.5, 1.0]])
    gauss = _values(x)[0]
    truth = np.array([math.exp(-v * v) for v in x])
    # both round -x^2 the same way; the rest is range reduction and a degree-13 Taylor sum (5e-18)
    assert np.max(np.abs(gauss / truth - 1.0)) <= 2 * ULP
    assert gauss[x == 0.0][0] == 1.0
    # below 2^-1022 (x^2 > 708) it is 0, never a subnormal number or garbage bits; infinities and NaN carry
    far = _values(np.array([26.7, 27.0, 40.0, 1e10, np.inf]))[0]
    assert np.all(far == 0.0) and math.exp(-26.7 ** 2) < 2.3e-308
    assert np.isnan(_values(np.array([np.nan]))[0][0])


def test_erfc_matches_the_c_library_to_its_rounding_of_x_squared():
    x = np.concatenate([np.linspace(0.0, 6.0, 200001), np.linspace(6.0, 26.0, 20001)])
    _, scaled, erfc = _values(x)
    truth = np.array([math.erfc(v) for v in x])
    rel = np.abs(erfc / truth - 1.0)
    # the interpolant is good to ~5e-15 (erfcx below); exp(-x^2) adds the rounding of x^2 (x^2 ulp, relative),
    # as any erfc built on exp(-x*x) does: below 1e-14 where screened pairs are (alpha r < 6 for any
    # accuracy demkit tunes to), measured 5.1e-15
    assert rel[x <= 6.0].max() < 1e-14
    assert np.all(rel <= 1e-14 + x * x * ULP)
    from scipy.special import erfcx
    assert np.max(np.abs(scaled / erfcx(x) - 1.0)) < 1e-14
    # erfcx decays as 1/(x sqrt(pi)): far out it is still the interpolant's (t -> 0), not a cancellation
    big = np.array([1e3, 1e6, 1e12])
    assert np.allclose(_values(big)[1], erfcx(big), rtol=1e-12)


def test_the_coefficients_are_the_chebyshev_interpolant_of_the_scaled_erfc():
    np.testing.assert_allclose(sf.fit_erfcx(), sf.ERFCX_CHEBYSHEV, rtol=0, atol=1e-16)
