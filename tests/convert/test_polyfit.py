"""o2m.convert.polyfit.fit_polynomial: a function's minimax polynomial in (x - x0) on a range
(recovers a quartic exactly, beats least squares on a knee-like spline, exact at x0 on request)."""

from __future__ import annotations

import numpy as np
import pytest

from o2m.convert.polyfit import FitError, fit_polynomial
from o2m.osim.functions import Constant, PolynomialFunction, SimmSpline


def test_fit_polynomial_recovers_quartic():
    coefs_high_first = [0.3, -1.0, 0.25, 2.0, -0.5]
    fn = PolynomialFunction(coefs_high_first)
    x0 = 0.4
    fit = fit_polynomial(fn, -1.0, 2.0, x0)
    p = np.polynomial.Polynomial(coefs_high_first[::-1])
    expected = p(np.polynomial.Polynomial([x0, 1.0])).coef  # coefficients in (x - x0), low first
    np.testing.assert_allclose(fit.coef, expected, rtol=0, atol=1e-12)
    assert fit.max_error <= 1e-12 and fit.rms_error <= fit.max_error
    assert (fit.lo, fit.hi, fit.x0) == (-1.0, 2.0, x0)


def test_fit_polynomial_minimax_on_curved_spline():
    # shaped like a knee translation spline: a typical non-polynomial SimmSpline
    x = np.array([-2.0944, -1.74533, -1.39626, -1.0472, -0.698132, -0.349066, -0.174533,
                  0.197344, 0.337395, 0.490178, 1.52146, 2.0944])
    y = np.array([-0.0032, 0.00179, 0.00411, 0.0041, 0.00212, -0.001, -0.0031, -0.005227,
                  -0.005435, -0.005574, -0.005435, -0.00525])
    fn = SimmSpline(x, y)
    lo, hi, x0 = -2.0944, 0.17, 0.0
    fit = fit_polynomial(fn, lo, hi, x0, degree=4)
    grid = np.linspace(lo, hi, 2001)
    ls = np.polynomial.polynomial.polyfit(grid - x0, fn(grid), 4)
    dense = np.unique(np.concatenate([np.linspace(lo, hi, 200001), x[(x > lo) & (x < hi)]]))
    ls_max = np.max(np.abs(np.polynomial.polynomial.polyval(dense - x0, ls) - fn(dense)))
    err = fit(dense) - fn(dense)
    dense_max = np.max(np.abs(err))
    assert fit.max_error <= ls_max
    assert fit.max_error < 0.9 * ls_max  # the minimax fit really improves on least squares
    assert fit.max_error == pytest.approx(dense_max, rel=1e-3)
    assert fit.rms_error == pytest.approx(np.sqrt(np.mean(err**2)), rel=2e-2)
    assert fit.coef.shape == (5,)


def test_fit_polynomial_rejects_empty_range():
    with pytest.raises(ValueError):
        fit_polynomial(Constant(1.0), 1.0, 1.0, 1.0)


def test_fit_polynomial_exact_at_x0_keeps_the_reference_point():
    """A fit pinned at x0 is exact there and still close elsewhere (never better than the free fit)."""
    x = np.array([-2.0, -1.2, -0.5, 0.0, 0.3, 0.9, 1.5])
    y = np.array([0.004, -0.002, 0.003, 0.0, -0.001, 0.0025, -0.003])
    spline = SimmSpline(x, y)
    free = fit_polynomial(spline, -2.0, 1.5, 0.3)
    pinned = fit_polynomial(spline, -2.0, 1.5, 0.3, exact_at_x0=True)
    assert pinned.coef[0] == pytest.approx(float(spline(0.3)), abs=1e-15)
    assert pinned(np.array([0.3]))[0] == pytest.approx(float(spline(0.3)), abs=1e-15)
    assert pinned.max_error >= free.max_error - 1e-15
    assert pinned.max_error < 0.01


def test_fit_polynomial_refuses_a_fit_that_is_not_finite():
    """Values near the largest double overflow the fit (its coefficients once reached MJCF as
    polycoef="nan inf -inf ..."): FitError, as for a function that is not finite on the range."""
    with np.errstate(all="ignore"), pytest.raises(FitError, match="quartic .* is not finite"):
        fit_polynomial(lambda x: 1.5e308 * np.sin(3 * x), -2.0, 0.5, 0.0)
    with np.errstate(all="ignore"), pytest.raises(FitError, match="function is not finite"):
        fit_polynomial(lambda x: 1.0 / x, -1.0, 1.0, 0.5)
