"""rheology.vecmath: the SIMD-friendly log and exp against numpy (libm), special values, and the
law functions that use them (numba and numpy paths agree)."""

import numba as nb
import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from rheology import laws, vecmath


@nb.njit(error_model="numpy")
def _log_loop(x, out):
    for k in range(x.shape[0]):
        out[k] = vecmath.log(x[k])


@nb.njit(error_model="numpy")
def _exp_loop(y, out):
    for k in range(y.shape[0]):
        out[k] = vecmath.exp(y[k])


@nb.njit(error_model="numpy")
def _inv_eta_B_loop(phi, phi_j, v1, a1, v2, a2, out):
    for k in range(phi.shape[0]):
        out[k] = laws.inv_eta_B(phi[k], phi_j, v1, a1, v2, a2)


def _ulps(a, b):
    """|a - b| in units of the last place of b (finite, nonzero b)."""
    return np.abs(a - b) / np.spacing(np.abs(b))


def test_log_within_one_ulp_over_the_double_range():
    rng = np.random.default_rng(1)
    x = np.concatenate([10.0 ** rng.uniform(-307, 308, 400_000),       # whole normal range
                        rng.uniform(0.5, 2.0, 400_000),               # around 1 (reduction edge)
                        1.0 + rng.normal(0.0, 1e-3, 100_000),          # pore-pressure arguments
                        np.array([np.sqrt(2.0), np.nextafter(np.sqrt(2.0), 2.0), 2.0, 0.5])])
    out = np.empty_like(x)
    _log_loop(x, out)
    ref = np.log(x)
    nz = ref != 0.0
    assert _ulps(out[nz], ref[nz]).max() <= 1.0
    assert np.all(out[~nz] == 0.0)


def test_exp_within_one_ulp_and_its_range_ends():
    rng = np.random.default_rng(2)
    y = np.concatenate([rng.uniform(-708.0, 709.7, 400_000), rng.uniform(-1.0, 1.0, 400_000),
                        rng.normal(0.0, 1e-8, 10_000)])
    out = np.empty_like(y)
    _exp_loop(y, out)
    assert _ulps(out, np.exp(y)).max() <= 1.0
    # subnormal results, underflow to 0, overflow to inf
    y = np.array([-710.0, -740.0, -745.1, -745.2, -1e300, 709.78, 709.79, 1e300])
    out = np.empty_like(y)
    _exp_loop(y, out)
    with np.errstate(over="ignore"):
        ref = np.exp(y)
    fin = np.isfinite(ref)
    assert np.all(np.abs(out[fin] - ref[fin]) <= np.spacing(ref[fin]) + 5e-324)
    assert out[-1] == np.inf and out[-2] == np.inf and out[4] == 0.0 and out[3] == 0.0


def test_special_values_follow_ieee():
    x = np.array([0.0, -0.0, -1.0, -np.inf, np.nan, np.inf, 5e-324, 1e-310, 1.0])
    out = np.empty_like(x)
    _log_loop(x, out)
    with np.errstate(divide="ignore", invalid="ignore"):
        np.testing.assert_array_equal(out, np.log(x))      # -inf, nan, inf, subnormals exact
    y = np.array([np.nan, np.inf, -np.inf, 0.0])
    out = np.empty_like(y)
    _exp_loop(y, out)
    np.testing.assert_array_equal(out, np.exp(y))


def test_python_calls_are_numpy():
    x = np.array([0.3, 2.0, 7.5])
    np.testing.assert_array_equal(vecmath.log(x), np.log(x))
    np.testing.assert_array_equal(vecmath.exp(x), np.exp(x))
    assert vecmath.log(2.0) == np.log(2.0)


@settings(max_examples=60, deadline=None)
@given(st.floats(0.0, 0.7), st.floats(0.2, 3.0), st.floats(0.0, 3.0))
def test_inv_eta_B_compiled_equals_numpy_path(phi_j, a1, a2):
    """Eq. (9) under numba (vecmath) and from numpy (libm): the same to the conditioning of
    x^alpha = exp(alpha ln x) (a 1-ulp difference in ln x is alpha |ln x| ulp in the power),
    exactly 0 at phi >= phi_j."""
    phi = np.linspace(0.0, 0.75, 301)
    out = np.empty_like(phi)
    _inv_eta_B_loop(phi, phi_j, 1e3, a1, 2e2, a2, out)
    ref = laws.inv_eta_B(phi, phi_j, 1e3, a1, 2e2, a2)
    x = np.maximum(phi_j - phi, 1e-300)
    cond = 4.0 + 2.0 * max(a1, a2) * np.abs(np.log(x))
    assert np.all(np.abs(out - ref) <= cond * np.finfo(float).eps * np.abs(ref) + 1e-300)
    at_or_above = phi >= phi_j
    np.testing.assert_array_equal(out[at_or_above], ref[at_or_above])
