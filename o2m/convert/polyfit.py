"""Minimax polynomial fits of one OpenSim function, for the conversion.

:func:`fit_polynomial` approximates a :class:`~o2m.osim.functions.Function` on a range by a
polynomial in (x - x0) (a MuJoCo joint equality is a quartic of its driving joint): least squares,
then the minimax fit by linear programming. Units: x in the coordinate's unit (rad or m), values
and errors in the function's unit (rad or m).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from o2m.osim.functions import FloatArray, Function

__all__ = ["FitError", "PolynomialFit", "fit_polynomial"]


class FitError(ValueError):
    """A fit gave a non-finite coefficient or error (its function's values are too large for
    double precision, or not finite). ``coordinate``: the coordinate whose couplings were being
    fitted, when the caller knows it."""

    def __init__(self, message: str, coordinate: str | None = None):
        super().__init__(message)
        self.coordinate = coordinate


@dataclass(frozen=True)
class PolynomialFit:
    """p(x) = sum_j coef[j] * (x - x0)**j approximating a function on [lo, hi].

    coef: (degree+1,), lowest power first.  max_error / rms_error: absolute errors (units of
    the function's value) measured on a grid 8x denser than the fitting grid plus the
    function's knots.
    """

    coef: FloatArray
    max_error: float
    rms_error: float
    lo: float
    hi: float
    x0: float

    def __call__(self, x: ArrayLike) -> FloatArray:
        """p(x) for x of any shape."""
        dx = np.asarray(x, dtype=np.float64) - self.x0
        return np.asarray(np.polynomial.polynomial.polyval(dx, self.coef), dtype=np.float64)


def _grid(fn: Function, lo: float, hi: float, n: int) -> FloatArray:
    xs = np.linspace(lo, hi, n)
    k = getattr(fn, "knots", np.empty(0))
    k = np.asarray(k, dtype=np.float64)
    k = k[(k > lo) & (k < hi)]
    return np.unique(np.concatenate([xs, k])) if k.size else xs


def fit_polynomial(fn: Function, lo: float, hi: float, x0: float, degree: int = 4,
                   n: int = 2001, exact_at_x0: bool = False) -> PolynomialFit:
    """Minimax polynomial of ``degree`` in (x - x0) approximating fn on [lo, hi].

    Fits on n uniform points (plus fn's knots inside): least squares first, then the minimax
    (Chebyshev) fit by linear programming; keeps whichever has the smaller maximum error.
    ``exact_at_x0`` fixes the constant term to fn(x0), so the fit is exact at x0 (a MuJoCo
    joint equality then holds exactly at the model's reference pose).
    """
    from scipy.optimize import linprog

    lo, hi, x0 = float(lo), float(hi), float(x0)
    if not hi > lo:
        raise ValueError(f"fit_polynomial needs hi > lo, got [{lo}, {hi}]")
    if degree < 0 or n < degree + 2:
        raise ValueError("fit_polynomial needs degree >= 0 and n >= degree + 2")
    xs = _grid(fn, lo, hi, n)
    f = np.asarray(fn(xs), dtype=np.float64)
    if not np.all(np.isfinite(f)):
        raise FitError(f"the function is not finite on [{lo:g}, {hi:g}]")
    # Scaled variable v = (x - x0) / s keeps the Vandermonde matrix well conditioned.
    s = max(abs(lo - x0), abs(hi - x0), 1e-300)
    V = np.vander((xs - x0) / s, degree + 1, increasing=True)
    unscale = s ** -np.arange(degree + 1, dtype=np.float64)
    f0 = float(np.asarray(fn(np.array([x0])), dtype=np.float64)[0]) if exact_at_x0 else 0.0
    if exact_at_x0:  # fit fn - fn(x0) without a constant term
        V, f, unscale = V[:, 1:], f - f0, unscale[1:]
    head = np.array([f0]) if exact_at_x0 else np.zeros(0)

    check = _grid(fn, lo, hi, 8 * (n - 1) + 1)
    fc = np.asarray(fn(check), dtype=np.float64)

    def errors(coef: FloatArray) -> tuple[float, float]:
        e = np.polynomial.polynomial.polyval(check - x0, coef) - fc
        return float(np.max(np.abs(e))), float(np.sqrt(np.mean(e * e)))

    a_ls = np.linalg.lstsq(V, f, rcond=None)[0]
    best = np.concatenate([head, a_ls * unscale])
    best_err = errors(best)

    fscale = max(float(np.max(np.abs(f))), 1e-300)
    if best_err[0] > 1e-14 * fscale:
        # minimise t subject to |V a - f| <= t, in units of fscale; variables (a, t).
        m = V.shape[0]
        ones = np.ones((m, 1))
        A_ub = np.block([[V, -ones], [-V, -ones]])
        b_ub = np.concatenate([f, -f]) / fscale
        cost = np.zeros(V.shape[1] + 1)
        cost[-1] = 1.0
        try:
            res = linprog(cost, A_ub=A_ub, b_ub=b_ub, bounds=[(None, None)] * V.shape[1] + [(0, None)],
                          method="highs", options={"primal_feasibility_tolerance": 1e-10,
                                                   "dual_feasibility_tolerance": 1e-10})
            if res.status == 0:
                cand = np.concatenate([head, res.x[:-1] * fscale * unscale])
                err = errors(cand)
                if err[0] < best_err[0]:
                    best, best_err = cand, err
        except ValueError:
            pass
    if not (np.all(np.isfinite(best)) and np.isfinite(best_err[0])):
        raise FitError(f"the quartic fitted over [{lo:g}, {hi:g}] is not finite (coefficients {best.tolist()}; "
                       f"the function reaches {float(np.max(np.abs(fc))):g})")
    return PolynomialFit(coef=best, max_error=best_err[0], rms_error=best_err[1], lo=lo, hi=hi, x0=x0)
