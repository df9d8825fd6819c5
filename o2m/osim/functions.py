"""OpenSim 1-D functions (TransformAxis / CoordinateCouplerConstraint functions) evaluated in numpy.

Every class here reproduces what OpenSim 4.6 computes for the same XML element, inside and
outside the knot range, without OpenSim.  Behaviours copied from OpenSim (checked against the
opensim 4.6 Python API in ``tests/test_functions.py``):

* ``SimmSpline``: SIMM's cubic spline with Forsythe-Malcolm-Moler end conditions (third
  derivative at each end taken from the cubic through the 4 end points; for 3 points the
  third derivative is continuous at the middle point; 2 points give a line).  Outside
  [x[0], x[-1]] it extrapolates LINEARLY with the end slope.  ``NaturalCubicSpline`` and
  ``natCubicSpline`` elements are read by OpenSim 4.6 as ``SimmSpline`` (``Object::renameType``),
  so they are evaluated the same way (not with natural end conditions).
* ``GCVSpline``: Woltring's GCVSPL as used by Simbody's ``SplineFitter::fitFromErrorVariance``
  (``error_variance`` >= 0) or ``fitFromGCV`` (< 0).  With ``error_variance`` 0 the spline
  interpolates the data only up to the tiny smoothing parameter GCVSPL's search ends on, so
  it is a faithful port of GCVSPL (scipy's exact interpolant differs by up to ~1e-10).  The
  natural spline of degree 2m-1 extrapolates as a polynomial of degree m-1 (constant for
  degree 1, linear for cubic, quadratic for quintic, cubic for heptic).
* ``PiecewiseLinearFunction``: linear extrapolation with the first/last segment slope;
  ``PiecewiseConstantFunction``: y[0] left of the knots, y[-1] right of them, derivative 0.
* ``PolynomialFunction``: coefficients from the HIGHEST power to the lowest.
* ``LinearFunction``: ``<coefficients>slope intercept</coefficients>``.
* ``MultiplierFunction``: ``scale * function(x)``, the wrapped element inside ``<function>``.

Units: x is the independent coordinate value (rad or m), values are in the dependent
coordinate's unit (rad or m); derivatives are value units per x unit.
"""

from __future__ import annotations

import hashlib
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np
from numpy.typing import ArrayLike, NDArray

from o2m.errors import UnsupportedElementError

__all__ = [
    "Function", "Constant", "LinearFunction", "PolynomialFunction", "SimmSpline", "GCVSpline",
    "PiecewiseLinearFunction", "PiecewiseConstantFunction", "MultiplierFunction", "Sine",
    "StepFunction", "PolynomialFit", "parse_function", "function_child", "fit_polynomial",
    "CouplingFit", "fit_coupling", "FUNCTION_TAGS",
]

FloatArray = NDArray[np.float64]

# SimmMacros.h
_TINY_NUMBER = 1e-7
_ROUNDOFF_ERROR = 2e-13


def _as_array(x: ArrayLike) -> FloatArray:
    return np.asarray(x, dtype=np.float64)


def _out(v: FloatArray) -> FloatArray:
    """Return a float64 array (0-d for scalar input)."""
    return np.asarray(v, dtype=np.float64)


# ---------------------------------------------------------------------------------------------
# Base class
# ---------------------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class Function:
    """A function of one variable as OpenSim evaluates it.

    ``kind`` is the OpenSim type name (class attribute); ``name`` the element's name
    attribute; ``tag`` the XML tag it was read from (``NaturalCubicSpline`` for a
    SimmSpline read from such an element), ``line`` its source line.
    """

    kind: ClassVar[str] = "Function"
    name: str | None = field(default=None, kw_only=True)
    tag: str | None = field(default=None, kw_only=True)
    line: int | None = field(default=None, kw_only=True)

    def __call__(self, x: ArrayLike) -> FloatArray:
        """Value at x (float or array of any shape); float64 array of x's shape."""
        raise NotImplementedError

    def derivative(self, x: ArrayLike) -> FloatArray:
        """First derivative d f / d x at x (float or array of any shape); array of x's shape."""
        raise NotImplementedError

    @property
    def knots(self) -> FloatArray:
        """Abscissae where the function's pieces join, shape (k,); empty when smooth."""
        return np.empty(0)

    def _linearity_grid(self, lo: float, hi: float) -> FloatArray:
        """Sample points on [lo, hi] dense enough to expose any non-linearity of a piece."""
        pts = [np.linspace(lo, hi, 201)]
        k = self.knots
        if k.size:
            edges = np.unique(np.clip(np.concatenate([[lo, hi], k]), lo, hi))
            for a, b in zip(edges[:-1], edges[1:], strict=True):
                pts.append(np.linspace(a, b, 11))
        return np.unique(np.concatenate(pts))

    def is_linear(self, lo: float, hi: float, tol: float = 1e-12) -> tuple[float, float] | None:
        """(slope, intercept) if f(x) = slope * x + intercept on [lo, hi] within tol, else None.

        The intercept is the value at x = 0.  tol is relative to max(1, max |f|) on [lo, hi].
        """
        lo, hi = float(min(lo, hi)), float(max(lo, hi))
        if hi == lo:
            slope = float(self.derivative(lo))
            return slope, float(self(lo)) - slope * lo
        xs = self._linearity_grid(lo, hi)
        f = self(xs)
        if not np.all(np.isfinite(f)):
            return None
        slope = (float(f[-1]) - float(f[0])) / (hi - lo)
        intercept = float(f[0]) - slope * lo
        scale = max(1.0, float(np.max(np.abs(f))))
        if np.max(np.abs(f - (slope * xs + intercept))) > tol * scale:
            return None
        return slope, intercept


# ---------------------------------------------------------------------------------------------
# Simple closed-form functions
# ---------------------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class Constant(Function):
    """f(x) = value."""

    kind: ClassVar[str] = "Constant"
    value: float = 0.0

    def __call__(self, x: ArrayLike) -> FloatArray:
        return _out(np.full(np.shape(x), self.value, dtype=np.float64))

    def derivative(self, x: ArrayLike) -> FloatArray:
        return _out(np.zeros(np.shape(x)))

    def is_linear(self, lo: float, hi: float, tol: float = 1e-12) -> tuple[float, float] | None:
        return 0.0, float(self.value)


@dataclass(frozen=True, eq=False)
class LinearFunction(Function):
    """f(x) = slope * x + intercept (OpenSim ``<coefficients>slope intercept</coefficients>``)."""

    kind: ClassVar[str] = "LinearFunction"
    slope: float = 1.0
    intercept: float = 0.0

    def __call__(self, x: ArrayLike) -> FloatArray:
        return _out(self.slope * _as_array(x) + self.intercept)

    def derivative(self, x: ArrayLike) -> FloatArray:
        return _out(np.full(np.shape(x), self.slope, dtype=np.float64))

    def is_linear(self, lo: float, hi: float, tol: float = 1e-12) -> tuple[float, float] | None:
        return float(self.slope), float(self.intercept)


@dataclass(frozen=True, eq=False)
class PolynomialFunction(Function):
    """f(x) = sum_i coefficients[i] * x**(n-1-i): coefficients (n,) from the HIGHEST power down."""

    kind: ClassVar[str] = "PolynomialFunction"
    coefficients: FloatArray = field(default_factory=lambda: np.ones(1))

    def __post_init__(self) -> None:
        c = np.atleast_1d(_as_array(self.coefficients)).copy()
        if c.ndim != 1 or c.size == 0:
            raise ValueError("PolynomialFunction needs at least one coefficient")
        if not np.all(np.isfinite(c)):
            raise ValueError("PolynomialFunction coefficients must be finite")
        object.__setattr__(self, "coefficients", c)

    def __call__(self, x: ArrayLike) -> FloatArray:
        xa = _as_array(x)
        v = np.zeros_like(xa)
        for c in self.coefficients:  # Horner, as SimTK::Function::Polynomial
            v = v * xa + c
        return _out(v)

    def derivative(self, x: ArrayLike) -> FloatArray:
        xa = _as_array(x)
        n = self.coefficients.size
        v = np.zeros_like(xa)
        for i, c in enumerate(self.coefficients[:-1]):
            v = v * xa + c * (n - 1 - i)
        return _out(v)


@dataclass(frozen=True, eq=False)
class Sine(Function):
    """f(x) = amplitude * sin(omega * x + phase) + offset."""

    kind: ClassVar[str] = "Sine"
    amplitude: float = 1.0
    omega: float = 1.0
    phase: float = 0.0
    offset: float = 0.0

    def __call__(self, x: ArrayLike) -> FloatArray:
        return _out(self.amplitude * np.sin(self.omega * _as_array(x) + self.phase) + self.offset)

    def derivative(self, x: ArrayLike) -> FloatArray:
        return _out(self.amplitude * self.omega * np.cos(self.omega * _as_array(x) + self.phase))


@dataclass(frozen=True, eq=False)
class StepFunction(Function):
    """SimTK smooth step: start_value for x <= start_time, end_value for x >= end_time,
    y0 + (y1 - y0) * u^3 (10 - 15 u + 6 u^2) with u = (x - start_time) / (end_time - start_time)."""

    kind: ClassVar[str] = "StepFunction"
    start_time: float = 0.99
    end_time: float = 1.01
    start_value: float = 0.0
    end_value: float = 1.0

    def __post_init__(self) -> None:
        if not self.end_time > self.start_time:
            raise ValueError("StepFunction needs transition_end_time > transition_start_time")

    def _u(self, x: ArrayLike) -> FloatArray:
        return np.clip((_as_array(x) - self.start_time) * (1.0 / (self.end_time - self.start_time)),
                       0.0, 1.0)

    def __call__(self, x: ArrayLike) -> FloatArray:
        u = self._u(x)
        smooth = u * u * u * (10 + u * (6 * u - 15))
        return _out(self.start_value + (self.end_value - self.start_value) * smooth)

    def derivative(self, x: ArrayLike) -> FloatArray:
        u = self._u(x)
        du = 30 * u * u * (1 - u) * (1 - u)
        return _out((self.end_value - self.start_value) * (1.0 / (self.end_time - self.start_time)) * du)

    @property
    def knots(self) -> FloatArray:
        return np.array([self.start_time, self.end_time])


@dataclass(frozen=True, eq=False)
class MultiplierFunction(Function):
    """f(x) = scale * function(x)."""

    kind: ClassVar[str] = "MultiplierFunction"
    function: Function = field(default_factory=Constant)
    scale: float = 1.0

    def __call__(self, x: ArrayLike) -> FloatArray:
        return _out(self.function(x) * self.scale)

    def derivative(self, x: ArrayLike) -> FloatArray:
        return _out(self.function.derivative(x) * self.scale)

    @property
    def knots(self) -> FloatArray:
        return self.function.knots


# ---------------------------------------------------------------------------------------------
# Tabulated functions
# ---------------------------------------------------------------------------------------------
def _check_xy(kind: str, x: ArrayLike, y: ArrayLike, min_points: int) -> tuple[FloatArray, FloatArray]:
    xa = np.atleast_1d(_as_array(x)).copy()
    ya = np.atleast_1d(_as_array(y)).copy()
    if xa.ndim != 1 or ya.ndim != 1:
        raise ValueError(f"{kind} x and y must be 1-D")
    if xa.size != ya.size:
        raise ValueError(f"{kind} has {xa.size} x values but {ya.size} y values")
    if xa.size < min_points:
        raise ValueError(f"{kind} needs at least {min_points} points, got {xa.size}")
    if not (np.all(np.isfinite(xa)) and np.all(np.isfinite(ya))):
        raise ValueError(f"{kind} x and y must be finite")
    if xa.size > 1 and not np.all(np.diff(xa) > 0):
        i = int(np.argmax(~(np.diff(xa) > 0)))
        raise ValueError(f"{kind} x must be strictly increasing "
                         f"(x[{i}]={xa[i]!r} >= x[{i + 1}]={xa[i + 1]!r})")
    return xa, ya


def _opensim_interval(xk: FloatArray, t: FloatArray) -> NDArray[np.intp]:
    """Interval index k (x[k] <= t <= x[k+1]) chosen by OpenSim's binary search (its choice at
    a knot depends on the search path, which matters for piecewise functions).  t: (p,) inside
    [x[0], x[-1]]."""
    n = xk.size
    i = np.zeros(t.shape, dtype=np.intp)
    j = np.full(t.shape, n, dtype=np.intp)
    k = np.zeros(t.shape, dtype=np.intp)
    todo = np.ones(t.shape, dtype=bool)
    for _ in range(4 * n.bit_length() + 8):
        if not todo.any():
            break
        kk = (i + j) // 2
        lt = t < xk[np.minimum(kk, n - 1)]
        gt = ~lt & (t > xk[np.minimum(kk + 1, n - 1)])
        j = np.where(todo & lt, kk, j)
        i = np.where(todo & gt, kk, i)
        done = todo & ~lt & ~gt
        k = np.where(done, kk, k)
        todo &= ~done
    return np.minimum(k, max(n - 2, 0))

def _eval_linear_ends(x: ArrayLike, xk: FloatArray, yk: FloatArray, b: FloatArray, deriv: bool,
                      inner: Callable[[FloatArray], FloatArray]) -> FloatArray:
    """Evaluate a spline as OpenSim does: linear with the end slopes ``b`` outside [xk[0], xk[-1]],
    the end values exactly at (within round-off of) the end knots, and ``inner`` in between."""
    t = _as_array(x)
    shape = t.shape
    t = t.ravel()
    n = xk.size
    out = np.full(t.shape, np.nan)
    left = t < xk[0]
    right = ~left & (t > xk[-1])
    at0 = ~left & ~right & (np.abs(t - xk[0]) <= _ROUNDOFF_ERROR)
    at1 = ~left & ~right & ~at0 & (np.abs(t - xk[-1]) <= _ROUNDOFF_ERROR)
    mid = ~left & ~right & ~at0 & ~at1 & ~np.isnan(t)
    if deriv:
        out[left | at0] = b[0]
        out[right | at1] = b[n - 1]
    else:
        out[left] = yk[0] + (t[left] - xk[0]) * b[0]
        out[right] = yk[n - 1] + (t[right] - xk[n - 1]) * b[n - 1]
        out[at0] = yk[0]
        out[at1] = yk[n - 1]
    if mid.any():
        out[mid] = inner(t[mid])
    return out.reshape(shape)



@dataclass(frozen=True, eq=False)
class SimmSpline(Function):
    """SIMM cubic spline through (x, y), x strictly increasing (n,), n >= 2; linear outside."""

    kind: ClassVar[str] = "SimmSpline"
    x: FloatArray = field(default_factory=lambda: np.zeros(0))
    y: FloatArray = field(default_factory=lambda: np.zeros(0))
    b: FloatArray = field(init=False, repr=False)
    c: FloatArray = field(init=False, repr=False)
    d: FloatArray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        x, y = _check_xy("SimmSpline", self.x, self.y, 2)
        object.__setattr__(self, "x", x)
        object.__setattr__(self, "y", y)
        b, c, d = _simm_coefficients(x.tolist(), y.tolist())
        object.__setattr__(self, "b", np.array(b))
        object.__setattr__(self, "c", np.array(c))
        object.__setattr__(self, "d", np.array(d))

    @property
    def knots(self) -> FloatArray:
        return self.x

    def _eval(self, x: ArrayLike, deriv: bool) -> FloatArray:
        xk, yk, b, c, d = self.x, self.y, self.b, self.c, self.d

        def inner(ti: FloatArray) -> FloatArray:
            k = np.zeros(ti.shape, dtype=np.intp) if xk.size < 3 else _opensim_interval(xk, ti)
            dx = ti - xk[k]
            if deriv:
                return b[k] + dx * (2.0 * c[k] + 3.0 * dx * d[k])
            return yk[k] + dx * (b[k] + dx * (c[k] + dx * d[k]))

        return _eval_linear_ends(x, xk, yk, b, deriv, inner)

    def __call__(self, x: ArrayLike) -> FloatArray:
        return self._eval(x, False)

    def derivative(self, x: ArrayLike) -> FloatArray:
        return self._eval(x, True)


def _simm_coefficients(x: Sequence[float],
                       y: Sequence[float]) -> tuple[list[float], list[float], list[float]]:
    """SimmSpline::calcCoefficients (OpenSim 4.6), operation for operation.

    Returns b, c, d (n,) such that on [x[k], x[k+1]]: y[k] + dx*(b[k] + dx*(c[k] + dx*d[k])).
    """
    n = len(x)
    b = [0.0] * n
    c = [0.0] * n
    d = [0.0] * n
    if n == 2:
        t = max(_TINY_NUMBER, x[1] - x[0])
        b[0] = b[1] = (y[1] - y[0]) / t
        return b, c, d
    nm1, nm2 = n - 1, n - 2
    d[0] = max(_TINY_NUMBER, x[1] - x[0])
    c[1] = (y[1] - y[0]) / d[0]
    for i in range(1, nm1):
        d[i] = max(_TINY_NUMBER, x[i + 1] - x[i])
        b[i] = 2.0 * (d[i - 1] + d[i])
        c[i + 1] = (y[i + 1] - y[i]) / d[i]
        c[i] = c[i + 1] - c[i]
    # End conditions: third derivatives at x[0] and x[n-1] from divided differences.
    b[0] = -d[0]
    b[nm1] = -d[nm2]
    c[0] = 0.0
    c[nm1] = 0.0
    if n > 3:
        d31 = max(_TINY_NUMBER, x[3] - x[1])
        d20 = max(_TINY_NUMBER, x[2] - x[0])
        d1 = max(_TINY_NUMBER, x[nm1] - x[n - 3])
        d2 = max(_TINY_NUMBER, x[nm2] - x[n - 4])
        d30 = max(_TINY_NUMBER, x[3] - x[0])
        d3 = max(_TINY_NUMBER, x[nm1] - x[n - 4])
        c[0] = c[2] / d31 - c[1] / d20
        c[nm1] = c[nm2] / d1 - c[n - 3] / d2
        c[0] = c[0] * d[0] * d[0] / d30
        c[nm1] = -c[nm1] * d[nm2] * d[nm2] / d3
    for i in range(1, n):  # forward elimination
        t = d[i - 1] / b[i - 1]
        b[i] -= t * d[i - 1]
        c[i] -= t * c[i - 1]
    c[nm1] /= b[nm1]  # back substitution
    for j in range(nm1):
        i = nm2 - j
        c[i] = (c[i] - d[i] * c[i + 1]) / b[i]
    b[nm1] = (y[nm1] - y[nm2]) / d[nm2] + d[nm2] * (c[nm2] + 2.0 * c[nm1])
    for i in range(nm1):
        b[i] = (y[i + 1] - y[i]) / d[i] - d[i] * (c[i + 1] + 2.0 * c[i])
        d[i] = (c[i + 1] - c[i]) / d[i]
        c[i] *= 3.0
    c[nm1] *= 3.0
    d[nm1] = d[nm2]
    return b, c, d


@dataclass(frozen=True, eq=False)
class PiecewiseLinearFunction(Function):
    """Linear interpolation through (x, y), x strictly increasing (n,), n >= 2; linear outside."""

    kind: ClassVar[str] = "PiecewiseLinearFunction"
    x: FloatArray = field(default_factory=lambda: np.zeros(0))
    y: FloatArray = field(default_factory=lambda: np.zeros(0))
    b: FloatArray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        x, y = _check_xy("PiecewiseLinearFunction", self.x, self.y, 2)
        object.__setattr__(self, "x", x)
        object.__setattr__(self, "y", y)
        b = np.empty_like(x)
        b[:-1] = (y[1:] - y[:-1]) / np.maximum(_TINY_NUMBER, x[1:] - x[:-1])
        b[-1] = b[-2]
        object.__setattr__(self, "b", b)

    @property
    def knots(self) -> FloatArray:
        return self.x

    def _eval(self, x: ArrayLike, deriv: bool) -> FloatArray:
        xk, yk, b = self.x, self.y, self.b

        def inner(ti: FloatArray) -> FloatArray:
            k = _opensim_interval(xk, ti)
            return b[k] if deriv else yk[k] + (ti - xk[k]) * b[k]

        return _eval_linear_ends(x, xk, yk, b, deriv, inner)

    def __call__(self, x: ArrayLike) -> FloatArray:
        return self._eval(x, False)

    def derivative(self, x: ArrayLike) -> FloatArray:
        return self._eval(x, True)


@dataclass(frozen=True, eq=False)
class PiecewiseConstantFunction(Function):
    """Step function: y[k] on [x[k], x[k+1]], y[0] left of x[0], y[-1] right of x[-1];
    x strictly increasing (n,), n >= 1.  Derivative 0 everywhere (as OpenSim)."""

    kind: ClassVar[str] = "PiecewiseConstantFunction"
    x: FloatArray = field(default_factory=lambda: np.zeros(0))
    y: FloatArray = field(default_factory=lambda: np.zeros(0))

    def __post_init__(self) -> None:
        x, y = _check_xy("PiecewiseConstantFunction", self.x, self.y, 1)
        object.__setattr__(self, "x", x)
        object.__setattr__(self, "y", y)

    @property
    def knots(self) -> FloatArray:
        return self.x

    def __call__(self, x: ArrayLike) -> FloatArray:
        t = _as_array(x)
        shape = t.shape
        t = t.ravel()
        xk, yk = self.x, self.y
        out = np.full(t.shape, np.nan)
        left = (t < xk[0]) | (np.abs(t - xk[0]) <= _ROUNDOFF_ERROR)
        right = ~left & ((t > xk[-1]) | (np.abs(t - xk[-1]) <= _ROUNDOFF_ERROR))
        inner = ~left & ~right & ~np.isnan(t)
        out[left] = yk[0]
        out[right] = yk[-1]
        if inner.any():
            out[inner] = yk[_opensim_interval(xk, t[inner])]
        return out.reshape(shape)

    def derivative(self, x: ArrayLike) -> FloatArray:
        return _out(np.zeros(np.shape(x)))


# ---------------------------------------------------------------------------------------------
# GCVSpline: port of Woltring's GCVSPL (Simbody SimTKmath/src/gcvspl.cpp), K = 1, unit weights.
# Band matrices are stored as lists of columns, column i (1..n) holding rows -w..w at [r + w].
# ---------------------------------------------------------------------------------------------
def _gcv_basis(m: int, n: int, x: list[float]) -> tuple[list[list[float]], float]:
    """BASIS: B(1-m:m-1, n) and its mean absolute row sum bl."""
    mm1 = m - 1
    B = [[0.0] * (2 * m - 1) for _ in range(n + 1)]
    if m == 1:
        for i in range(1, n + 1):
            B[i][0] = 1.0
        return B, 1.0
    mp1, m2 = m + 1, 2 * m
    for l_ in range(1, n + 1):
        q = [0.0] * (2 * m)  # q[j + mm1], j = -mm1..m
        q[mm1 + mm1] = 1.0
        if l_ != 1 and l_ != n:
            q[mm1 + mm1] = 1.0 / (x[l_ + 1] - x[l_ - 1])
        arg = x[l_]
        for i in range(3, m2 + 1):
            ir = mp1 - i
            v = q[ir + mm1]
            if l_ < i:
                for j in range(l_ + 1, i + 1):
                    u = v
                    v = q[ir + 1 + mm1]
                    q[ir + mm1] = u + (x[j] - arg) * v
                    ir += 1
            j1 = max(l_ - i + 1, 1)
            j2 = min(l_ - 1, n - i)
            if j1 <= j2:
                if i < m2:
                    for j in range(j1, j2 + 1):
                        yy = x[i + j]
                        u = v
                        v = q[ir + 1 + mm1]
                        q[ir + mm1] = u + (v - u) * (yy - arg) / (yy - x[j])
                        ir += 1
                else:
                    for j in range(j1, j2 + 1):
                        u = v
                        v = q[ir + 1 + mm1]
                        q[ir + mm1] = (arg - x[j]) * u + (x[i + j] - arg) * v
                        ir += 1
            nmip1 = n - i + 1
            if nmip1 < l_:
                for j in range(nmip1, l_):
                    u = v
                    v = q[ir + 1 + mm1]
                    q[ir + mm1] = (arg - x[j]) * u + v
                    ir += 1
        for j in range(-mm1, mm1 + 1):
            B[l_][j + mm1] = q[j + mm1]
    for i in range(1, mm1 + 1):
        for k in range(i, mm1 + 1):
            B[i][-k + mm1] = 0.0
            B[n + 1 - i][k + mm1] = 0.0
    bl = 0.0
    for i in range(1, n + 1):
        for k in range(-mm1, mm1 + 1):
            bl += abs(B[i][k + mm1])
    return B, bl / n


def _gcv_prep(m: int, n: int, x: list[float], w: list[float]) -> tuple[list[list[float]], float]:
    """PREP: WE(-m:m, n), the weighted divided-difference matrix, and its mean abs sum el."""
    m2, mp1 = 2 * m, m + 1
    m2m1, m2p1 = m2 - 1, m2 + 1
    nm = n - m
    we = [0.0] * (n * m2p1 + 1)  # 1-based flat, WE(k, i) = we[(k + m + 1) + (i - 1) * m2p1]
    f1 = -1.0
    if m != 1:
        for i in range(2, m + 1):
            f1 = -f1 * i
        for i in range(mp1, m2m1 + 1):
            f1 *= i
    i1, i2, jm = 1, m, mp1
    for j in range(1, n + 1):
        inc = m2p1
        if j > nm:
            f1 = -f1
            f = f1
        else:
            if j < mp1:
                inc = 1
                f = f1
            else:
                f = f1 * (x[j + m] - x[j - m])
        if j > mp1:
            i1 += 1
        if i2 < n:
            i2 += 1
        jj = jm
        ff = f
        yy = x[i1]
        i1p1 = i1 + 1
        for i in range(i1p1, i2 + 1):
            ff /= yy - x[i]
        we[jj] = ff
        jj += m2
        i2m1 = i2 - 1
        if i1p1 <= i2m1:
            for l_ in range(i1p1, i2m1 + 1):
                ff = f
                yy = x[l_]
                for i in range(i1, l_):
                    ff /= yy - x[i]
                for i in range(l_ + 1, i2 + 1):
                    ff /= yy - x[i]
                we[jj] = ff
                jj += m2
        ff = f
        yy = x[i2]
        for i in range(i1, i2m1 + 1):
            ff /= yy - x[i]
        we[jj] = ff
        jj += m2
        jm += inc
    kl = 1
    n2m = m2p1 * n + 1
    for i in range(1, m + 1):
        ku = kl + m - i
        for k in range(kl, ku + 1):
            we[k] = 0.0
            we[n2m - k] = 0.0
        kl += m2p1
    jj = 0
    el = 0.0
    for i in range(1, n + 1):
        wi = w[i]
        for _ in range(m2p1):
            jj += 1
            we[jj] /= wi
            el += abs(we[jj])
    WE = [[0.0] * m2p1 for _ in range(n + 1)]
    for i in range(1, n + 1):
        for k in range(-m, m + 1):
            WE[i][k + m] = we[(k + m + 1) + (i - 1) * m2p1]
    return WE, el / n


def _gcv_bandet(E: list[list[float]], m: int, n: int) -> None:
    """BANDET: in-place LU decomposition of the band matrix E(-m:m, n)."""
    if m <= 0:
        return
    for i in range(1, n + 1):
        di = E[i][m]
        mi = min(m, i - 1)
        if mi >= 1:
            for k in range(1, mi + 1):
                di -= E[i][-k + m] * E[i - k][k + m]
            E[i][m] = di
        lm = min(m, n - i)
        if lm >= 1:
            for l_ in range(1, lm + 1):
                dl = E[i + l_][-l_ + m]
                km = min(m - l_, i - 1)
                if km >= 1:
                    du = E[i][l_ + m]
                    for k in range(1, km + 1):
                        du -= E[i][-k + m] * E[i - k][l_ + k + m]
                        dl -= E[l_ + i][-l_ - k + m] * E[i - k][k + m]
                    E[i][l_ + m] = du
                E[i + l_][-l_ + m] = dl / di


def _gcv_bansol(E: list[list[float]], y: list[float], m: int, n: int) -> list[float]:
    """BANSOL: solve with the LU-decomposed band matrix; c (1-based, n)."""
    c = [0.0] * (n + 1)
    if m == 0:
        for i in range(1, n + 1):
            c[i] = y[i] / E[i][m]
        return c
    c[1] = y[1]
    for i in range(2, n + 1):
        mi = min(m, i - 1)
        dd = y[i]
        for l_ in range(1, mi + 1):
            dd -= E[i][-l_ + m] * c[i - l_]
        c[i] = dd
    c[n] /= E[n][m]
    for i in range(n - 1, 0, -1):
        mi = min(m, n - i)
        dd = c[i]
        for l_ in range(1, mi + 1):
            dd -= E[i][l_ + m] * c[i + l_]
        c[i] = dd / E[i][m]
    return c


def _gcv_trinv(Bw: list[list[float]], E: list[list[float]], m: int, n: int) -> float:
    """TRINV: trace of Bw * inverse(E) from the central 2m+1 bands of E^-1 (E overwritten)."""
    E[n][m] = 1.0 / E[n][m]
    for i in range(n - 1, 0, -1):
        mi = min(m, n - i)
        dd = 1.0 / E[i][m]
        for k in range(1, mi + 1):
            E[n][k + m] = E[i][k + m] * dd
            E[1][-k + m] = E[k + i][-k + m]
        dd += dd
        for j in range(mi, 0, -1):
            du = 0.0
            dl = 0.0
            for k in range(1, mi + 1):
                du -= E[n][k + m] * E[i + k][j - k + m]
                dl -= E[1][-k + m] * E[i + j][k - j + m]
            E[i][j + m] = du
            E[j + i][-j + m] = dl
            dd -= E[n][j + m] * dl + E[1][-j + m] * du
        E[i][m] = dd * 0.5
    dd = 0.0
    for i in range(1, n + 1):
        mn = -min(m, i - 1)
        mp = min(m, n - i)
        for k in range(mn, mp + 1):
            dd += Bw[i][k + m] * E[k + i][-k + m]
    for k in range(1, m + 1):
        E[n][k + m] = 0.0
        E[1][-k + m] = 0.0
    return dd


def _gcv_splc(m: int, n: int, y: list[float], wx: list[float], mode: int, val: float, p: float,
              eps: float, B: list[list[float]], WE: list[list[float]], el: float,
              stat: list[float]) -> tuple[float, list[float]]:
    """SPLC: fit for smoothing parameter p; returns (criterion, c 1-based)."""
    dp = p
    stat[4] = p
    pel = p * el
    if pel < eps:
        dp = eps / el
        stat[4] = 0.0
    if pel * eps > 1.0:
        dp = 1.0 / (el * eps)
        stat[4] = dp
    E = [[0.0] * (2 * m + 1) for _ in range(n + 1)]
    for i in range(1, n + 1):
        km = -min(m, i - 1)
        kp = min(m, n - i)
        for l_ in range(km, kp + 1):
            if abs(l_) == m:
                E[i][l_ + m] = dp * WE[i][l_ + m]
            else:
                E[i][l_ + m] = B[i][l_ + m - 1] + dp * WE[i][l_ + m]
    _gcv_bandet(E, m, n)
    c = _gcv_bansol(E, y, m, n)
    stat[3] = _gcv_trinv(WE, E, m, n) * dp
    trn = stat[3] / n
    esn = 0.0
    for i in range(1, n + 1):
        dt = -y[i]
        km = -min(m - 1, i - 1)
        kp = min(m - 1, n - i)
        for l_ in range(km, kp + 1):
            dt += B[i][l_ + m - 1] * c[i + l_]
        esn += dt * dt * wx[i] * 1.0
    esn /= n * 1
    stat[6] = esn / trn
    stat[1] = stat[6] / trn
    stat[2] = esn
    if abs(mode) != 3:
        stat[5] = stat[6] - esn
        ret = 0.0
        if abs(mode) == 2:
            ret = stat[1]
        if abs(mode) == 4:
            ret = abs(stat[3] - val)
    else:
        stat[5] = esn - val * (trn * 2.0 - 1.0)
        ret = stat[5]
    return ret, c


def _gcvspl(x_: Sequence[float], y_: Sequence[float], m: int, md: int, val: float) -> list[float]:
    """GCVSPL with unit weights: natural spline coefficients c (n,) of half order m."""
    n = len(x_)
    x = [0.0, *map(float, x_)]
    y = [0.0, *map(float, y_)]
    wx = [1.0] * (n + 1)
    if m <= 0 or n < 2 * m:
        raise ValueError(f"GCVSpline of half order {m} needs at least {2 * m} points, got {n}")
    eps = 1e-15
    B, r1 = _gcv_basis(m, n, x)
    WE, el = _gcv_prep(m, n, x, wx)
    el /= r1
    stat = [0.0] * 7

    def splc(p: float) -> tuple[float, list[float]]:
        return _gcv_splc(m, n, y, wx, md, val, p, eps, B, WE, el, stat)

    if abs(md) == 1:
        return splc(val)[1][1:]
    budget = 10000  # the Fortran loops have no iteration limit; guard against pathological data
    r1 = 1.0 / el
    r2 = r1 * 2.0
    gf2 = splc(r2)[0]
    while True:  # L40: decrease p while the criterion decreases
        gf1 = splc(r1)[0]
        budget -= 1
        if gf1 > gf2:
            break
        if stat[4] <= 0.0 or budget <= 0:
            return splc(r1)[1][1:]
        r2, gf2 = r1, gf1
        r1 /= 2.0
    r3 = r2 * 2.0  # L50
    while True:  # L60: increase p while the criterion decreases
        gf3 = splc(r3)[0]
        budget -= 1
        if gf3 > gf2:
            break
        if stat[4] >= 999999999999999.88 or budget <= 0:
            return splc(r1)[1][1:]
        r2, gf2 = r3, gf3
        r3 *= 2.0
    r2, gf2 = r3, gf3  # L70: golden section search
    alpha = (r2 - r1) / 1.618033983
    r4 = r1 + alpha
    r3 = r2 - alpha
    gf3 = splc(r3)[0]
    gf4 = splc(r4)[0]
    while budget > 0:  # L80
        budget -= 1
        if gf3 <= gf4:
            r2, gf2 = r4, gf4
            err = (r2 - r1) / (r1 + r2)
            if err * err + 1.0 == 1.0 or err <= 1e-6:
                break
            r4, gf4 = r3, gf3
            alpha /= 1.618033983
            r3 = r2 - alpha
            gf3 = splc(r3)[0]
        else:
            r1, gf1 = r3, gf3
            err = (r2 - r1) / (r1 + r2)
            if err * err + 1.0 == 1.0 or err <= 1e-6:
                break
            r3, gf3 = r4, gf4
            alpha /= 1.618033983
            r4 = r1 + alpha
            gf4 = splc(r4)[0]
    r1 = (r1 + r2) * 0.5  # L90
    return splc(r1)[1][1:]  # L100


def _gcv_splder(ider: int, m: int, t: FloatArray, x: list[float], c: list[float], l_: int) -> FloatArray:
    """SPLDER for all t (p,) lying in the same interval l_ (x[l_] <= t < x[l_+1], 0..n).

    x and c are 1-based lists.  Same operations as the Fortran, element-wise over t.
    """
    n = len(x) - 1
    m2 = 2 * m
    k = m2 - ider
    if k < 1:
        return np.zeros_like(t)
    tt = t
    mp1, npm, m2m1 = m + 1, n + m, m2 - 1
    k1, nk = k - 1, n - k
    lk1 = l_ - k + 1
    jl, ju, ii, ml = l_ + 1, l_ + m2, n - m2, -l_
    q: list = [0.0] * (m2 + 1)
    for j in range(jl, ju + 1):
        q[j + ml] = c[j - m] if mp1 <= j <= npm else 0.0
    if ider > 0:
        jl -= m2
        ml += m2
        for i in range(1, ider + 1):
            jl += 1
            ii += 1
            j1 = max(1, jl)
            j2 = min(l_, ii)
            mi = m2 - i
            j = j2 + 1
            if j1 <= j2:
                for _ in range(j1, j2 + 1):
                    j -= 1
                    jm = ml + j
                    q[jm] = (q[jm] - q[jm - 1]) / (x[j + mi] - x[j])
            if jl >= 1:
                continue
            i1 = i + 1
            j = ml + 1
            if i1 <= ml:
                for _ in range(i1, ml + 1):
                    j -= 1
                    q[j] = -q[j - 1]
        for j in range(1, k + 1):
            q[j] = q[j + ider]
    if k1 >= 1:
        for i in range(1, k1 + 1):
            nki = nk + i
            ir = k
            jj = l_
            ki = k - i
            nki1 = nki + 1
            if l_ >= nki1:
                for _ in range(nki1, l_ + 1):
                    q[ir] = q[ir - 1] + (tt - x[jj]) * q[ir]
                    jj -= 1
                    ir -= 1
            lk1i = lk1 + i
            j1 = max(1, lk1i)
            j2 = min(l_, nki)
            if j1 <= j2:
                for _ in range(j1, j2 + 1):
                    xjki = x[jj + ki]
                    z = q[ir]
                    q[ir] = z + (xjki - tt) * (q[ir - 1] - z) / (xjki - x[jj])
                    ir -= 1
                    jj -= 1
            if lk1i <= 0:
                jj = ki
                for _ in range(1, 1 - lk1i + 1):
                    q[ir] = q[ir] + (x[jj] - tt) * q[ir - 1]
                    jj -= 1
                    ir -= 1
    z = q[k]
    if ider > 0:
        for j in range(k, m2m1 + 1):
            z = z * j
    return np.broadcast_to(np.asarray(z, dtype=np.float64), t.shape).copy()


@dataclass(frozen=True, eq=False)
class GCVSpline(Function):
    """Woltring natural spline of degree 2*half_order-1 through (x, y) (n,), n >= 2*half_order.

    error_variance 0 interpolates (as OpenSim's default), > 0 smooths to that variance,
    < 0 chooses the smoothing by generalized cross-validation.  Outside the knots it is a
    polynomial of degree half_order-1.
    """

    kind: ClassVar[str] = "GCVSpline"
    x: FloatArray = field(default_factory=lambda: np.zeros(0))
    y: FloatArray = field(default_factory=lambda: np.zeros(0))
    half_order: int = 3
    error_variance: float = 0.0
    coefficients: FloatArray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        m = int(self.half_order)
        if not 1 <= m <= 4:
            raise ValueError(f"GCVSpline half_order must be 1..4 (degree 1, 3, 5, 7), got {self.half_order}")
        x, y = _check_xy("GCVSpline", self.x, self.y, 2 * m)
        object.__setattr__(self, "x", x)
        object.__setattr__(self, "y", y)
        object.__setattr__(self, "half_order", m)
        md = 3 if self.error_variance >= 0.0 else 2
        val = float(self.error_variance) if md == 3 else 0.0
        object.__setattr__(self, "coefficients", np.array(_gcvspl(x.tolist(), y.tolist(), m, md, val)))

    @property
    def degree(self) -> int:
        """Polynomial degree of the pieces: 2 * half_order - 1."""
        return 2 * self.half_order - 1

    @property
    def knots(self) -> FloatArray:
        return self.x

    def derivative_n(self, x: ArrayLike, order: int) -> FloatArray:
        """order-th derivative (order >= 0) at x (float or array); array of x's shape."""
        t = _as_array(x)
        shape = t.shape
        t = t.ravel()
        xl = [0.0, *self.x.tolist()]
        cl = [0.0, *self.coefficients.tolist()]
        out = np.empty(t.shape)
        interval = np.searchsorted(self.x, t, side="right")  # SEARCH: x[l] <= t < x[l+1]
        for l_ in np.unique(interval):
            sel = interval == l_
            out[sel] = _gcv_splder(order, self.half_order, t[sel], xl, cl, int(l_))
        return out.reshape(shape)

    def __call__(self, x: ArrayLike) -> FloatArray:
        return self.derivative_n(x, 0)

    def derivative(self, x: ArrayLike) -> FloatArray:
        return self.derivative_n(x, 1)


# ---------------------------------------------------------------------------------------------
# XML parsing
# ---------------------------------------------------------------------------------------------
FUNCTION_TAGS: frozenset[str] = frozenset({
    "Constant", "LinearFunction", "PolynomialFunction", "SimmSpline", "NaturalCubicSpline",
    "natCubicSpline", "GCVSpline", "PiecewiseLinearFunction", "PiecewiseConstantFunction",
    "MultiplierFunction", "Sine", "StepFunction",
})


def _local(tag: object) -> str:
    if not isinstance(tag, str):
        return ""
    return tag.rsplit("}", 1)[-1]


def _children(element) -> list:
    return [ch for ch in element if isinstance(ch.tag, str)]


def function_child(parent) -> object | None:
    """The first child element of ``parent`` whose tag is a function type o2m knows
    (FUNCTION_TAGS), else None.  Use on TransformAxis, <coupled_coordinates_function>, ..."""
    kids = _children(parent)
    for ch in kids:
        if _local(ch.tag) in FUNCTION_TAGS:
            return ch
    return None


def _prop(element, name: str):
    for ch in _children(element):
        if _local(ch.tag) == name:
            return ch
    return None


def _numbers(element, name: str) -> FloatArray | None:
    ch = _prop(element, name)
    if ch is None:
        return None
    text = (ch.text or "").strip()
    if not text:
        return np.zeros(0)
    try:
        return np.array([float(tok) for tok in text.replace(",", " ").split()], dtype=np.float64)
    except ValueError as exc:
        raise ValueError(f"<{name}> holds a value that is not a number: {text!r}") from exc


def _scalar(element, name: str, default: float) -> float:
    v = _numbers(element, name)
    if v is None:
        return default
    if v.size != 1:
        raise ValueError(f"<{name}> must hold one number, got {v.size}")
    if not math.isfinite(v[0]):
        raise ValueError(f"<{name}> must be finite, got {v[0]!r}")
    return float(v[0])


def _xy(element) -> tuple[FloatArray, FloatArray]:
    x = _numbers(element, "x")
    y = _numbers(element, "y")
    return (np.zeros(0) if x is None else x), (np.zeros(0) if y is None else y)


def parse_function(element) -> Function:
    """Build the Function an OpenSim 4.x function element (lxml element; tag = type) describes.

    Raises UnsupportedElementError (naming the element, its name attribute and source line)
    for an unknown type or malformed numbers (x/y lengths differ, too few points,
    non-increasing x, non-numeric text).
    """
    tag = _local(element.tag)
    name = element.get("name")
    line = getattr(element, "sourceline", None)
    meta = {"name": name, "tag": tag, "line": line}

    def fail(message: str) -> UnsupportedElementError:
        return UnsupportedElementError(message, element=tag or str(element.tag), name=name, line=line)

    if tag not in FUNCTION_TAGS:
        raise fail(f"is not a function type o2m supports (supported: {', '.join(sorted(FUNCTION_TAGS))})")
    try:
        if tag == "Constant":
            return Constant(_scalar(element, "value", 0.0), **meta)
        if tag == "LinearFunction":
            c = _numbers(element, "coefficients")
            if c is None:
                c = np.array([1.0, 0.0])
            if c.size != 2 or not np.all(np.isfinite(c)):
                raise ValueError(f"<coefficients> must hold 2 finite numbers (slope intercept), got {c.size}")
            return LinearFunction(float(c[0]), float(c[1]), **meta)
        if tag == "PolynomialFunction":
            c = _numbers(element, "coefficients")
            return PolynomialFunction(np.ones(1) if c is None else c, **meta)
        if tag in ("SimmSpline", "NaturalCubicSpline", "natCubicSpline"):
            return SimmSpline(*_xy(element), **meta)
        if tag == "PiecewiseLinearFunction":
            return PiecewiseLinearFunction(*_xy(element), **meta)
        if tag == "PiecewiseConstantFunction":
            return PiecewiseConstantFunction(*_xy(element), **meta)
        if tag == "GCVSpline":
            if _prop(element, "half_order") is None:
                what = " (OpenSim 4.6 ignores <degree>)" if _prop(element, "degree") is not None else ""
                raise ValueError(f"GCVSpline has no <half_order>{what}")
            h = _scalar(element, "half_order", 0.0)
            if h != int(h):
                raise ValueError(f"<half_order> must be an integer, got {h!r}")
            return GCVSpline(*_xy(element), half_order=int(h),
                             error_variance=_scalar(element, "error_variance", 0.0), **meta)
        if tag == "Sine":
            return Sine(_scalar(element, "amplitude", 1.0), _scalar(element, "omega", 1.0),
                        _scalar(element, "phase", 0.0), _scalar(element, "offset", 0.0), **meta)
        if tag == "StepFunction":
            return StepFunction(_scalar(element, "transition_start_time", 0.99),
                                _scalar(element, "transition_end_time", 1.01),
                                _scalar(element, "start_value", 0.0),
                                _scalar(element, "end_value", 1.0), **meta)
        if tag == "MultiplierFunction":
            wrapper = _prop(element, "function")
            inner = None
            if wrapper is not None:
                kids = _children(wrapper)
                inner = kids[0] if kids else None
            else:
                inner = function_child(element)
            if inner is None:
                raise ValueError("MultiplierFunction has no function to multiply")
            return MultiplierFunction(parse_function(inner), _scalar(element, "scale", 1.0), **meta)
    except UnsupportedElementError:
        raise
    except ValueError as exc:
        raise fail(str(exc)) from None
    raise fail("is not a function type o2m supports")  # pragma: no cover


# ---------------------------------------------------------------------------------------------
# Polynomial approximation
# ---------------------------------------------------------------------------------------------
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
        return _out(np.polynomial.polynomial.polyval(_as_array(x) - self.x0, self.coef))


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
        raise ValueError("function is not finite on [lo, hi]")
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
    return PolynomialFit(coef=best, max_error=best_err[0], rms_error=best_err[1], lo=lo, hi=hi, x0=x0)


# ---------------------------------------------------------------------------------------------
# Coupling fits beyond a quartic: sums of joints along one axis
# ---------------------------------------------------------------------------------------------
#: Starting shapes (c, p) of a new inner polynomial, (t - c)^p, before it is optimised.
COUPLING_STARTS: tuple[tuple[float, int], ...] = tuple((c, p) for p in (3, 4) for c in (-1.0, -0.5, 0.0, 0.5, 1.0))
#: Random starting shapes added to those (seeded, so a conversion is reproducible).
COUPLING_RANDOM_STARTS = 10
#: The terms of each outer joint's correction have amplitudes adding up to at most this times
#: its axis's max |y - y(x0)|: the extra joints then move about as much as the axis itself,
#: never by large amounts that cancel (which a free fit of the same error needs; see
#: fit_couplings).
COUPLING_AMPLITUDE = 2.0
#: An added inner joint is kept only if it brings the error below this fraction of the last.
COUPLING_GAIN = 0.9
#: Each inner joint moves through this many times the largest correction term of the axes it
#: drives (each in its host axis's scale; the choice changes no sum of joints, as the host's main
#: joint makes up for it). An outer joint's force reaches its inner joint times d outer / d inner,
#: and MuJoCo softens the inner joint's equality by its coordinate's inverse weight, so a larger
#: inner joint holds its outer joints stiffer, for an inertia added to the coordinate that grows
#: with its square. Leg6Dof9Musc hanging under gravity, its knee's shared inner slide (which also
#: drives the patella's rotation) sagged 3.8e-5 m off its equality scaled to its host axis's own
#: correction, 2.3e-5 m scaled to the largest of them, 1.2e-5 m at twice that; the extra joints
#: then add 2.3 % to the knee's 0.65 kg m² (the conversion report gives it per axis).
COUPLING_INNER_SCALE = 2.0
#: In the margins beyond [lo, hi] that fit_couplings covers, the error may be this many times
#: the error inside: a degree-16 polynomial fitted on [lo, hi] alone leaves it fast (0.7 mm
#: 0.045 rad beyond a knee's range), which a joint pressing into a soft limit reaches.
COUPLING_MARGIN_SLACK = 5.0
_SEARCH_POINTS = 401
_LAWSON_ROUNDS = 4
_LM_ITERATIONS = 200
_POLISHED = 3
#: Central-difference step of the derivatives fit_couplings bounds, as a fraction of the fitted range.
_SLOPE_STEP = 1e-6
_LP_OPTIONS = {"primal_feasibility_tolerance": 1e-10, "dual_feasibility_tolerance": 1e-10}
_CHEB = np.polynomial.chebyshev
_POLY = np.polynomial.polynomial


@dataclass(frozen=True)
class AxisFit:
    """One axis of a :class:`CouplingFit`: y(x) - y(x0) ≈ main(x) + Σ_{inners l it carries}
    inner_l(x) + Σ_{(l, c) in outers} c(inner_l(x)).

    ``main`` (5,): the axis's main joint, a quartic in (x - x0), lowest power first, ``main[0]``
    being fn(x0); ``outers``: (inner index l, (5,) quartic coefficients in inner l's value,
    constant and linear terms 0), each an outer joint on this axis. ``max_error`` /
    ``rms_error``: realised errors (the function's unit) on a grid 8x denser than the fitting
    grid, over [lo, hi]; ``quartic_error``: the plain quartic's worst error; ``amplitude``: the
    largest range an extra joint on this axis moves through (0 without extra joints);
    ``margin_error``: the worst error in the margins beyond [lo, hi] that the fit also covers.
    ``slope_error`` / ``slope_rms``: the worst and RMS error of the derivative dy/dx over [lo, hi]
    (the function's unit per x unit: for a path point's location against a rotational
    coordinate, m/rad, directly a moment-arm error); ``quartic_slope_error`` /
    ``quartic_slope_rms``: the plain quartic's; ``slope_target``: the derivative's target (inf
    when the fit bounds the value only).
    """

    main: FloatArray
    outers: tuple[tuple[int, FloatArray], ...]
    max_error: float
    rms_error: float
    quartic_error: float
    target: float
    amplitude: float
    margin_error: float = 0.0
    slope_error: float = 0.0
    slope_rms: float = 0.0
    quartic_slope_error: float = 0.0
    quartic_slope_rms: float = 0.0
    slope_target: float = math.inf


@dataclass(frozen=True)
class CouplingFit:
    """Several functions of one variable x (the axes of a coordinate's couplings), each a sum of
    MuJoCo joints following quartic joint equalities; see :func:`fit_couplings`.

    ``inners`` (L, 5): inner joint l, a quartic in (x - x0) with no constant term (driven by x),
    carried by axis ``hosts[l]``; ``shapes`` (L, 4): the inner polynomials' Chebyshev
    coefficients (T_1..T_4) in t = (x - mid) / half, mid and half the centre and half-width of
    [lo - margin, hi + margin]; ``axes``: one :class:`AxisFit` per function; ``condition``: the
    largest 2-norm condition number of an axis's column-scaled linear-program basis;
    ``margin``: how far beyond [lo, hi] the fit reaches on each side (x's unit).
    """

    inners: FloatArray
    hosts: tuple[int, ...]
    shapes: FloatArray
    axes: tuple[AxisFit, ...]
    condition: float
    lo: float
    hi: float
    x0: float
    margin: float = 0.0

    @property
    def n_inner(self) -> int:
        """L, the number of inner joints."""
        return int(self.inners.shape[0])

    def inner_values(self, x: ArrayLike) -> FloatArray:
        """Every inner joint's value at x: (L, *x.shape)."""
        dx = _as_array(x) - self.x0
        return np.array([_POLY.polyval(dx, c) for c in self.inners]).reshape(self.n_inner, *dx.shape)

    def joint_values(self, axis: int, x: ArrayLike) -> tuple[FloatArray, list[FloatArray], list[FloatArray]]:
        """Axis ``axis``'s joints at x, each evaluated as MuJoCo evaluates its equality: (main,
        [inner joints it carries], [its outer joints])."""
        dx = _as_array(x) - self.x0
        inner = self.inner_values(x)
        ax = self.axes[axis]
        hosted = [inner[k] for k in range(self.n_inner) if self.hosts[k] == axis]
        outers = [_out(_POLY.polyval(inner[k], c)) for k, c in ax.outers]
        return _out(_POLY.polyval(dx, ax.main)), hosted, outers

    def axis_value(self, axis: int, x: ArrayLike) -> FloatArray:
        """The sum of axis ``axis``'s joints at x (any shape)."""
        main, hosted, outers = self.joint_values(axis, x)
        return _out(main + sum(hosted, np.zeros_like(main)) + sum(outers, np.zeros_like(main)))

    def axis_slope(self, axis: int, x: ArrayLike) -> FloatArray:
        """d/dx of the sum of axis ``axis``'s joints at x (any shape): the chain rule through
        each outer joint's inner joint."""
        dx = _as_array(x) - self.x0
        inner = self.inner_values(x)
        dinner = [_POLY.polyval(dx, _POLY.polyder(c)) for c in self.inners]
        ax = self.axes[axis]
        s = _POLY.polyval(dx, _POLY.polyder(ax.main)) * np.ones_like(dx)
        for k in range(self.n_inner):
            if self.hosts[k] == axis:
                s = s + dinner[k]
        for k, c in ax.outers:
            s = s + _POLY.polyval(inner[k], _POLY.polyder(c)) * dinner[k]
        return _out(s)

    def __call__(self, x: ArrayLike) -> FloatArray:
        """Every axis's value at x: (n_axes, *x.shape)."""
        return np.array([self.axis_value(a, x) for a in range(len(self.axes))])

    def extra_joints(self, axis: int) -> int:
        """How many joints axis ``axis`` has besides its main joint."""
        return sum(h == axis for h in self.hosts) + len(self.axes[axis].outers)

    def structure(self, axis: int) -> str:
        """A short description of axis ``axis``'s joints, e.g. ``quartic + 1 inner + 1 outer quartic``."""
        ax = self.axes[axis]
        hosted = sum(h == axis for h in self.hosts)
        if not hosted and not ax.outers:
            return "quartic"
        parts = ["quartic"]
        if hosted:
            parts.append(f"{hosted} inner quartic{'s' if hosted > 1 else ''} (a quartic of the coordinate)")
        if ax.outers:
            n = len(ax.outers)
            parts.append(f"{n} outer quartic{'s' if n > 1 else ''} of inner joint{'s' if n > 1 else ''} "
                         + ", ".join(str(k + 1) for k, _ in ax.outers))
        return " + ".join(parts)


def _shape_values(t: FloatArray, t0: float, shape: FloatArray) -> FloatArray:
    """The inner polynomial Σ_i shape[i] T_{i+1}(t), minus its value at t0."""
    c = np.concatenate([[0.0], shape])
    return _CHEB.chebval(t, c) - _CHEB.chebval(t0, c)


def _unit_shape(t: FloatArray, t0: float, shape: FloatArray) -> tuple[FloatArray, float]:
    """The inner polynomial on t scaled to at most 1 in magnitude, and the scale N."""
    h = _shape_values(t, t0, shape)
    nk = max(float(np.max(np.abs(h))), 1e-300)
    return h / nk, nk


def _unit_shape_slope(t: FloatArray, shape: FloatArray, nk: float) -> FloatArray:
    """d/dt of the inner polynomial scaled as :func:`_unit_shape` scales it (by 1 / nk)."""
    return _CHEB.chebval(t, _CHEB.chebder(np.concatenate([[0.0], shape]))) / nk


def _axis_basis_slope(t: FloatArray, t0: float, hs: Sequence[FloatArray], dhs: Sequence[FloatArray]) -> FloatArray:
    """d/dt of the columns of :func:`_axis_basis` (``dhs``: d h_k / dt)."""
    v = t - t0
    cols = [j * v ** (j - 1) for j in range(1, 5)] + [j * h ** (j - 1) * dh for h, dh in zip(hs, dhs, strict=True)
                                                      for j in (2, 3, 4)]
    return np.stack(cols, axis=1)


def numeric_slope(fn: Callable[[FloatArray], FloatArray], x: FloatArray, step: float) -> FloatArray:
    """dfn/dx at x by central differences of step ``step`` (x's unit): for the smooth functions
    fitted here (splines, polynomials) accurate to about step² |f'''| plus round-off."""
    x = np.asarray(x, dtype=np.float64)
    return (np.asarray(fn(x + step), dtype=np.float64) - np.asarray(fn(x - step), dtype=np.float64)) / (2 * step)


def polynomial_slope_errors(fn: Callable[[FloatArray], FloatArray], coef: ArrayLike, lo: float, hi: float,
                            x0: float, n: int = 16001) -> tuple[float, float]:
    """(worst, RMS) error over [lo, hi] of the derivative of sum_j coef[j] (x - x0)^j against
    fn's (uniform samples; fn's by :func:`numeric_slope`)."""
    x = np.linspace(float(lo), float(hi), n)
    e = _POLY.polyval(x - x0, _POLY.polyder(np.asarray(coef, dtype=float))) - numeric_slope(
        fn, x, _SLOPE_STEP * max(float(hi) - float(lo), 1e-12))
    return float(np.max(np.abs(e))), float(np.sqrt(np.mean(e * e)))


def _axis_basis(t: FloatArray, t0: float, hs: Sequence[FloatArray]) -> FloatArray:
    """Columns (m, 4 + 3K) of one axis's fit at t: (t - t0)^j, j = 1..4 (the main quartic), then
    h_k^j, j = 2..4, for each inner shape h_k it has an outer joint of (h_k^1 is a quartic
    vanishing at t0, already in the main quartic's span)."""
    v = t - t0
    cols = [v ** j for j in range(1, 5)] + [h ** j for h in hs for j in (2, 3, 4)]
    return np.stack(cols, axis=1)


class _ShapeSearch:
    """Variable projection for the inner shapes: for shapes θ (L, 4) (Chebyshev coefficients of
    T_1..T_4 in t, each scaled by |θ_l|, which the fit does not depend on), the weighted
    least-squares residuals of every axis's best linear coefficients, stacked, and their
    Jacobian in Kaufman's approximation, for a Levenberg-Marquardt search. ``sw`` (per axis,
    (m,)) turns least squares towards minimax (Lawson's iteration)."""

    def __init__(self, t: FloatArray, t0: float, fs: Sequence[FloatArray], uses: Sequence[Sequence[int]],
                 rows: FloatArray | None = None):
        #: fixed weight of each sample (the range's margin counts less), times ``sw``
        self.rows = np.ones_like(t) if rows is None else np.asarray(rows, dtype=float)
        self.V = np.stack([(t - t0) ** j for j in range(1, 5)], axis=1)
        self.phi = np.stack([_CHEB.chebval(t, np.eye(5)[i]) - _CHEB.chebval(t0, np.eye(5)[i])
                             for i in range(1, 5)], axis=1)
        self.fs = [np.asarray(f, dtype=float) for f in fs]
        self.uses = [list(u) for u in uses]
        self.sw = [np.ones_like(f) for f in self.fs]
        self._key: bytes | None = None

    def _solve(self, flat: FloatArray) -> None:
        key = flat.tobytes() + b"".join(w.tobytes() for w in self.sw)
        if key == self._key:
            return
        th = flat.reshape(-1, 4)
        norms = np.maximum(np.linalg.norm(th, axis=1), 1e-300)
        H = (self.phi @ th.T) / norms  # (m, L)
        self.H, self.th, self.norms = H, th, norms
        self.parts = []
        for f, u, sw in zip(self.fs, self.uses, self.sw, strict=True):
            sw = sw * self.rows
            A = np.hstack([self.V] + [np.stack([H[:, k] ** j for j in (2, 3, 4)], axis=1) for k in u])
            scale = np.maximum(np.linalg.norm(A, axis=0), 1e-300)
            U, S, Vt = np.linalg.svd(A * sw[:, None] / scale, full_matrices=False)
            r = int(np.sum(S > S[0] * 1e-12))
            U, S, Vt = U[:, :r], S[:r], Vt[:r]
            c = (Vt.T @ ((U.T @ (sw * f)) / S)) / scale  # coefficients of the unscaled columns
            self.parts.append((A, U, S, Vt, scale, c, sw * (A @ c - f)))
        self._key = key

    def residual(self, flat: FloatArray) -> FloatArray:
        self._solve(flat)
        return np.concatenate([p[-1] for p in self.parts])  # a new array: the caller may change it

    def errors(self, flat: FloatArray) -> list[FloatArray]:
        """Each axis's residual A c - f, weighted by the samples' fixed weights only."""
        self._solve(flat)
        return [self.rows * (p[0] @ p[5] - f) for p, f in zip(self.parts, self.fs, strict=True)]

    def jac(self, flat: FloatArray) -> FloatArray:
        """d residual / d θ, (Σ m, 4L): Golub and Pereyra's variable-projection derivative,
        P⊥ dA c - A⁺ᵀ dAᵀ r (r = A c - f), for the weighted, column-scaled basis."""
        self._solve(flat)
        L = self.H.shape[1]
        blocks = []
        for (_, U, S, Vt, scale, c, res), u, sw in zip(self.parts, self.uses, self.sw, strict=True):
            sw = sw * self.rows
            J = np.zeros((sw.size, 4 * L))
            for i, k in enumerate(u):
                cols = slice(4 + 3 * i, 7 + 3 * i)
                b = c[cols]
                h = self.H[:, k]
                unit = self.th[k] / self.norms[k]
                dh_dth = (self.phi - h[:, None] * unit[None, :]) / self.norms[k]  # h = φ θ / |θ|, (m, 4)
                dcol = np.stack([sw * j * h ** (j - 1) for j in (2, 3, 4)], axis=1)  # d(weighted column)/dh
                g = (dcol @ b)[:, None] * dh_dth  # dA c, (m, 4)
                first = g - U @ (U.T @ g)
                # A⁺ᵀ dAᵀ r: dA has nonzero columns only at this outer's 3 columns
                dAt_r = (dcol * res[:, None]).T @ dh_dth / scale[cols][:, None]  # (3, 4)
                second = U @ ((Vt[:, cols] @ dAt_r) / S[:, None])
                J[:, 4 * k: 4 * k + 4] += first - second
            blocks.append(J)
        return np.vstack(blocks)


def _levenberg_marquardt(search: _ShapeSearch, x: FloatArray, iterations: int) -> FloatArray:
    """Minimise |search.residual(x)|^2 from x by Levenberg-Marquardt (Marquardt's diagonal
    scaling). Written out rather than scipy's MINPACK, whose steps differ in the last bit from
    run to run, which a search over many local minima turns into different fits of one model."""
    r, J = search.residual(x), search.jac(x)
    cost, lam = float(r @ r), 1e-3
    for _ in range(iterations):
        g, H = J.T @ r, J.T @ J
        d = np.diag(H).copy()
        d = np.maximum(d, 1e-12 * max(float(d.max()), 1e-300))
        try:
            step = np.linalg.solve(H + lam * np.diag(d), -g)
        except np.linalg.LinAlgError:
            lam *= 10.0
            continue
        x_new = x + step
        r_new = search.residual(x_new)
        cost_new = float(r_new @ r_new)
        if cost_new < cost:
            done = cost - cost_new <= 1e-9 * cost
            x, r, cost, lam = x_new, r_new, cost_new, max(lam / 3.0, 1e-12)
            J = search.jac(x)
            if done:
                break
        else:
            lam *= 4.0
            if lam > 1e12:
                break
    return x


def _lp_bounded_minimax(A: FloatArray, f: FloatArray, n_outer: int, bound: float) -> tuple[FloatArray, float] | None:
    """min_a max |A a - f| with Σ_j |a_kj| <= bound for each outer k (the 3 columns of outer k
    after the 4 main ones); A's columns are scaled to at most 1. (a, worst error) or None."""
    from scipy.optimize import linprog

    m, n = A.shape
    nb = 3 * n_outer
    ones = np.ones((m, 1))
    rows = [np.hstack([A, np.zeros((m, nb)), -ones]), np.hstack([-A, np.zeros((m, nb)), -ones])]
    rhs = [f, -f]
    if nb:
        sel = np.zeros((nb, n))
        sel[:, 4:] = np.eye(nb)
        zero = np.zeros((nb, 1))
        rows += [np.hstack([sel, -np.eye(nb), zero]), np.hstack([-sel, -np.eye(nb), zero]),
                 np.hstack([np.zeros((n_outer, n)), np.kron(np.eye(n_outer), np.ones((1, 3))), np.zeros((n_outer, 1))])]
        rhs += [np.zeros(2 * nb), np.full(n_outer, bound)]
    cost = np.zeros(n + nb + 1)
    cost[-1] = 1.0
    # HiGHS's dual simplex sometimes stops on a numerical difficulty (status 4) at these tight
    # tolerances (a Leg6Dof9Musc patella fit did); its interior-point method then solves it
    for method in ("highs", "highs-ipm"):
        res = linprog(cost, A_ub=np.vstack(rows), b_ub=np.concatenate(rhs),
                      bounds=[(None, None)] * n + [(0, None)] * (nb + 1), method=method, options=_LP_OPTIONS)
        if res.status == 0:
            return res.x[:n], float(res.x[-1])
    return None


def _power_shape(c: float, p: int) -> FloatArray:
    """Chebyshev coefficients T_1..T_4 of (t - c)^p (its constant term dropped)."""
    cheb = _CHEB.poly2cheb(_POLY.polypow([-c, 1.0], p))
    return np.concatenate([cheb, np.zeros(5 - cheb.size)])[1:5]


def _shifted_power_series(cheb_shape: FloatArray, t0: float, half: float) -> FloatArray:
    """Power coefficients (5,) in (x - x0) of Σ_i shape[i] T_{i+1}(t) - (its value at t0), with
    t - t0 = (x - x0) / half."""
    p = _CHEB.cheb2poly(np.concatenate([[0.0], cheb_shape]))  # in t, lowest power first
    p = np.concatenate([p, np.zeros(5 - p.size)])
    shifted = np.zeros(5)  # p(t0 + v) = Σ_j shifted[j] v^j
    for i, pi in enumerate(p):
        for j in range(i + 1):
            shifted[j] += pi * math.comb(i, j) * t0 ** (i - j)
    shifted[0] = 0.0
    return shifted / half ** np.arange(5)


#: Fits already made in this process, by a digest of the functions' values and the arguments.
_COUPLING_CACHE: dict[bytes, CouplingFit] = {}


def fit_couplings(fns: Sequence[Callable[[FloatArray], FloatArray]], lo: float, hi: float, x0: float, *,
                  targets: Sequence[float], uses: Sequence[Sequence[int]], hosts: Sequence[int],
                  start_shapes: ArrayLike = (), n: int = 2001, amplitude: float = COUPLING_AMPLITUDE,
                  margin: float = 0.0, seed: int = 0, slope_targets: Sequence[float] | None = None) -> CouplingFit:
    """Approximate functions y_a of one variable x on [lo, hi] (the coupled axes of one
    coordinate) by sums of MuJoCo joints, each joint following a quartic joint equality.

    What: L inner joints D_l(x) = α_l h_l(x), each a quartic in (x - x0) (driven by x) and
    carried by axis ``hosts[l]``; axis a has a main joint C_a, a quartic in (x - x0), and for
    each l in ``uses[a]`` an outer joint E_al, a quartic in D_l (driven by it: a chain). So

        y_a(x) - y_a(x0) ≈ C_a(x) + Σ_{l: hosts[l] = a} D_l(x) + Σ_{l in uses[a]} E_al(D_l(x)).

    Every joint but C_a is 0 at x0 and C_a(x0) = 0 after y_a(x0), so the sums are exact at x0
    and the reference pose satisfies every equality.

    Why: a MuJoCo joint equality (``mjEQ_JOINT``) is a quartic, so one joint cannot follow a
    spline closely (about 0.25 mm on a knee translation). Joints of one body along the same
    axis add up (slides sum their translations, hinges about one axis through one point their
    angles), and a quartic of a quartic reaches degree 16. MuJoCo allows at most 6 degrees of
    freedom per body, so inner joints are shared: one inner joint can drive outer joints on
    several axes, also on other bodies (a knee's inner joint drives the patella's outers).

    How: for fixed inner shapes h_l (scaled to at most 1 in magnitude), each y_a is linear in
    its remaining coefficients (the main quartic's and b_alj of h_l^j, j = 2..4), so its minimax
    fit is one linear program, on column-scaled variables, with each outer's Σ_j |b_alj| held
    to ``amplitude`` times max |y_a - y_a(x0)|. The bound matters: with fixed shapes (x - c)^p a
    free fit reaches its error only with joints moving metres (or turns) in opposite
    directions to sum to millimetres (a degree-16 polynomial written in a poorly conditioned
    basis), which a simulation cannot follow. The shapes are found by a least-squares search
    (variable projection, Levenberg-Marquardt), from ``start_shapes`` (the first inners' shapes,
    e.g. a smaller structure's), for each further inner from (t - c)^p for the shifts and
    degrees of :data:`COUPLING_STARTS` and seeded random shapes, adding one inner at a time;
    the best few are reweighted towards minimax (Lawson's iteration) and scored by their linear
    programs (worst error relative to ``targets``). Then C_a is the main quartic minus the inner
    joints axis a carries, α_l :data:`COUPLING_INNER_SCALE` times the largest correction term
    of the axes using it (scaled to its host axis), and E_al = Σ_j b_alj (D_l / α_l)^j.

    ``margin`` (a fraction of hi - lo) widens the fit by that much on each side, where the error
    may be :data:`COUPLING_MARGIN_SLACK` times larger than inside; the errors reported are the
    ones inside [lo, hi] (the margins' in ``margin_error``).

    ``slope_targets`` (one per function, its unit per x unit) makes the fits derivative-aware:
    the derivative of each sum of joints is linear in the same coefficients, so each linear
    program bounds, on the same samples, max(|error| / target, |d error / dx| / slope target)
    (the derivatives of y_a by :func:`numeric_slope`; the derivative inside [lo, hi] only, not in
    the margins), and the shapes are scored that way too (their search stays on values). A
    path point's location against a rotational coordinate has its derivative error as a
    moment-arm error. Without them only the value is bounded (the derivative errors are still
    reported). The plain quartic (no inner joints) is always the value's minimax quartic.

    Units: x in the driving coordinate's unit (rad or m); y_a and ``targets[a]`` in axis a's.
    """
    lo, hi, x0 = float(lo), float(hi), float(x0)
    n_axes, L = len(fns), len(hosts)
    if not hi > lo:
        raise ValueError(f"fit_couplings needs hi > lo, got [{lo}, {hi}]")
    if not lo <= x0 <= hi:
        raise ValueError(f"fit_couplings needs lo <= x0 <= hi, got x0 = {x0} outside [{lo}, {hi}]")
    if len(targets) != n_axes or len(uses) != n_axes:
        raise ValueError("fit_couplings needs one target and one list of used inners per function")
    if any(not 0 <= h < n_axes for h in hosts) or any(not 0 <= k < L for u in uses for k in u):
        raise ValueError("fit_couplings: hosts must name axes and uses must name inner joints")
    start = np.asarray(start_shapes, dtype=float).reshape(-1, 4)
    if start.shape[0] > L:
        raise ValueError("fit_couplings: more start shapes than inner joints")
    if slope_targets is not None and len(slope_targets) != n_axes:
        raise ValueError("fit_couplings needs one slope target per function")

    knots = [np.asarray(getattr(fn, "knots", np.empty(0)), dtype=float) for fn in fns]
    width = float(margin) * (hi - lo)
    lo_m, hi_m = lo - width, hi + width  # the range with its margins

    def grid(m: int) -> FloatArray:
        xs = np.linspace(lo_m, hi_m, m)
        k = np.concatenate([xs, *knots, [lo, hi]] if width else [xs, *knots])
        return np.unique(k[(k >= lo_m) & (k <= hi_m)])

    def rows(x: FloatArray) -> FloatArray:
        return np.where((x >= lo) & (x <= hi), 1.0, 1.0 / COUPLING_MARGIN_SLACK)

    check = grid(8 * (n - 1) + 1)
    fc = [np.asarray(fn(check), dtype=np.float64) for fn in fns]
    step = _SLOPE_STEP * (hi_m - lo_m)
    dc = [numeric_slope(fn, check, step) for fn in fns]
    slopes = [math.inf] * n_axes if slope_targets is None else [float(v) for v in slope_targets]
    # everything below sees the functions only through their values on this grid (which holds the others)
    key = hashlib.sha256(b"".join([check.tobytes(), *(f.tobytes() for f in fc), *(f.tobytes() for f in dc),
                                   start.tobytes(), np.array([lo, hi, x0, n, amplitude, margin, seed, *targets,
                                                              *hosts, *slopes]).tobytes(),
                                   repr([list(u) for u in uses]).encode()])).digest()
    if key in _COUPLING_CACHE:
        return _COUPLING_CACHE[key]
    if len(_COUPLING_CACHE) > 256:
        _COUPLING_CACHE.clear()

    quartics = [fit_polynomial(fn, lo, hi, x0, degree=4, n=n, exact_at_x0=True) for fn in fns]  # type: ignore[arg-type]
    f0 = [float(np.asarray(fn(np.array([x0])), dtype=np.float64)[0]) for fn in fns]
    mid, half = (lo_m + hi_m) / 2, (hi_m - lo_m) / 2
    t0 = (x0 - mid) / half
    xs = grid(n)
    t, w_fit = (xs - mid) / half, rows(xs)
    fs = [np.asarray(fn(xs), dtype=np.float64) - c for fn, c in zip(fns, f0, strict=True)]
    fscale = [max(float(np.max(np.abs(f))), 1e-300) for f in fs]
    weight = [1.0 / max(float(tg), 1e-9 * q.max_error, 1e-300) for tg, q in zip(targets, quartics, strict=True)]
    ts_x = grid(_SEARCH_POINTS)
    ts, w_search = (ts_x - mid) / half, rows(ts_x)
    f_search = [(np.asarray(fn(ts_x), dtype=np.float64) - c) * w for fn, c, w in zip(fns, f0, weight, strict=True)]
    # derivatives in t (x = mid + half t), each in its function's scale (fs) or its target's (f_search);
    # ratio: the value error a derivative error of its slope target counts as (None: value only)
    ratio = [None if math.isinf(sl) else float(tg) / sl for tg, sl in zip(targets, slopes, strict=True)]
    ds = [numeric_slope(fn, xs, step) * half for fn in fns]
    d_search = [numeric_slope(fn, ts_x, step) * half * w for fn, w in zip(fns, weight, strict=True)]

    def lp(shapes: Sequence[FloatArray], tt: FloatArray, ff: Sequence[FloatArray], dd: Sequence[FloatArray],
           ww: FloatArray, axis_uses, polish=False):
        """Per axis: (worst error weighted by ``ww``, coefficients of the column-scaled basis,
        column scales, cond). With ``polish``, the least-squares coefficients replace the linear
        program's when they respect the amplitude bound and have the smaller worst error (they
        reach round-off for a function the structure represents exactly, where the LP stops at
        its tolerance). ``dd``: each axis's derivative in t (ff's units), bounded (times
        ``ratio``) with the values where the axis has a slope target."""
        units = [_unit_shape(tt, t0, s) for s in shapes]
        hs = [u[0] for u in units]
        dhs = [_unit_shape_slope(tt, s, u[1]) for s, u in zip(shapes, units, strict=True)]
        out = []
        for a, f in enumerate(ff):
            A = _axis_basis(tt, t0, [hs[k] for k in axis_uses[a]])
            scale = np.max(np.abs(A), axis=0)
            As, target = A / scale * ww[:, None], f * ww
            if ratio[a] is not None:  # the derivative's rows, in the value's units
                dA = _axis_basis_slope(tt, t0, [hs[k] for k in axis_uses[a]], [dhs[k] for k in axis_uses[a]])
                sw = (ww >= 1.0) * ratio[a]  # inside [lo, hi] only
                As = np.vstack([As, dA / scale * sw[:, None]])
                target = np.concatenate([target, dd[a] * sw])
            fsa = max(float(np.max(np.abs(f))), 1e-300)
            got = _lp_bounded_minimax(As, target / fsa, len(axis_uses[a]), amplitude)
            if got is None:
                return None
            coef, err = got[0] * fsa, got[1] * fsa
            if polish:
                ls = np.linalg.lstsq(As, target, rcond=None)[0]
                sums = np.abs(ls[4:]).reshape(-1, 3).sum(axis=1) if ls.size > 4 else np.zeros(0)
                ls_err = float(np.max(np.abs(As @ ls - target)))
                if np.all(sums <= amplitude * fsa) and ls_err < float(np.max(np.abs(As @ coef - target))):
                    coef, err = ls, ls_err
            out.append((err, coef, scale, float(np.linalg.cond(A / scale))))
        return out

    def score(shapes, axis_uses) -> float:
        got = lp(shapes, ts, f_search, d_search, w_search, axis_uses)  # f_search is in units of each target already
        return math.inf if got is None else max(g[0] for g in got)

    rng = np.random.default_rng(seed)
    shapes = [s / np.linalg.norm(s) for s in start]
    stages = list(range(len(shapes), L)) or ([L - 1] if L else [])
    for stage in stages:
        k_all = stage + 1
        axis_uses = [[k for k in u if k < k_all] for u in uses]
        search = _ShapeSearch(ts, t0, f_search, axis_uses, w_search)
        if len(shapes) >= k_all:
            starts = [np.zeros(0)]  # polish the given shapes
        else:
            starts = [_power_shape(c, p) for c, p in COUPLING_STARTS]
            starts += list(rng.normal(size=(COUPLING_RANDOM_STARTS, 4)))
        runs = []
        for s0 in starts:
            flat0 = np.concatenate([*shapes[:k_all], s0 / max(float(np.linalg.norm(s0)), 1e-300)] if s0.size
                                   else shapes[:k_all])
            search.sw = [np.ones_like(f) for f in f_search]
            flat = _levenberg_marquardt(search, flat0, _LM_ITERATIONS)
            r = search.residual(flat)
            runs.append((float(r @ r), flat, flat0))
        # every result scored by its linear programs; the best few then reweighted towards
        # minimax (Lawson); the earlier shapes kept as they were with the best new one are a
        # candidate too (its error is no larger than the smaller structure's)
        runs.sort(key=lambda r: r[0])

        def unit_rows(flat: FloatArray) -> list[FloatArray]:
            c = flat.reshape(-1, 4)
            return list(c / np.maximum(np.linalg.norm(c, axis=1), 1e-300)[:, None])

        scored = [(score(unit_rows(f), axis_uses), i, f) for i, f in
                  enumerate([runs[0][2]] + [r[1] for r in runs])]
        scored.sort(key=lambda z: (z[0], z[1]))
        for _, _, flat in list(scored[:_POLISHED]):
            ws = [np.ones_like(f) for f in f_search]
            for j in range(_LAWSON_ROUNDS):
                ws = [w * np.abs(e) for w, e in zip(ws, search.errors(flat), strict=True)]
                top = max(max(float(np.max(w)) for w in ws), 1e-300)
                ws = [w / top for w in ws]
                search.sw = [np.sqrt(w) for w in ws]
                flat = _levenberg_marquardt(search, flat, _LM_ITERATIONS // 4)
                scored.append((score(unit_rows(flat), axis_uses), len(scored) + j, flat))
        best_flat = min(scored, key=lambda z: (z[0], z[1]))[2]
        shapes = unit_rows(best_flat)

    # final fit on the full grid
    got = lp(shapes, t, fs, ds, w_fit, [list(u) for u in uses], polish=True) if L else None
    if L and got is None:
        raise ValueError("fit_couplings: the linear program failed")
    units = [_unit_shape(t, t0, s) for s in shapes]
    inner_poly = [_shifted_power_series(s, t0, half) / nk for s, (_, nk) in zip(shapes, units, strict=True)]
    corrections: dict[tuple[int, int], tuple[FloatArray, float]] = {}  # (axis, inner): (b (3,), max |g|)
    mains = []
    conds = [1.0]
    for a in range(n_axes):
        main = np.zeros(5)
        main[0] = f0[a]
        if L:
            _, coef, scale, cond = got[a]  # type: ignore[index]
            coef = coef / scale
            conds.append(cond)
            main[1:] = coef[:4] / half ** np.arange(1, 5)
            for i, k in enumerate(uses[a]):
                b = coef[4 + 3 * i: 7 + 3 * i]
                g = sum(b[j - 2] * units[k][0] ** j for j in (2, 3, 4))
                corrections[(a, k)] = (b, float(np.max(np.abs(g))))
        else:
            main = np.asarray(quartics[a].coef, dtype=float).copy()
        mains.append(main)
    alphas = []
    for k in range(L):
        host = hosts[k]
        own = corrections.get((host, k), (None, 0.0))[1]
        other = max([corrections[(a, k)][1] * fscale[host] / fscale[a] for a in range(n_axes) if (a, k) in corrections],
                    default=0.0)
        alphas.append(COUPLING_INNER_SCALE * max(own, other, 1e-3 * fscale[host]))
    inners = np.array([p * al for p, al in zip(inner_poly, alphas, strict=True)]).reshape(-1, 5)
    for k in range(L):
        mains[hosts[k]] = mains[hosts[k]] - inners[k]  # the host's main joint makes up for the inner joint
    outers_by_axis: list[list[tuple[int, FloatArray]]] = [[] for _ in range(n_axes)]
    for (a, k), (b, _) in sorted(corrections.items()):
        al = alphas[k]
        outers_by_axis[a].append((k, np.array([0.0, 0.0, b[0] / al ** 2, b[1] / al ** 3, b[2] / al ** 4])))
    draft = CouplingFit(inners=inners, hosts=tuple(int(h) for h in hosts), shapes=np.array(shapes).reshape(-1, 4),
                        axes=tuple(AxisFit(mains[a], tuple(outers_by_axis[a]), 0.0, 0.0, quartics[a].max_error,
                                           float(targets[a]), 0.0) for a in range(n_axes)),
                        condition=float(max(conds)), lo=lo, hi=hi, x0=x0, margin=width)
    inside = (check >= lo) & (check <= hi)
    axes = []
    for a in range(n_axes):
        err = draft.axis_value(a, check) - fc[a]
        slope = (draft.axis_slope(a, check) - dc[a])[inside]
        q_slope = (_POLY.polyval(check - x0, _POLY.polyder(quartics[a].coef)) - dc[a])[inside]
        _, hosted, outers = draft.joint_values(a, check)
        amp = max([float(np.ptp(v)) for v in hosted + outers], default=0.0)
        axes.append(AxisFit(mains[a], tuple(outers_by_axis[a]), float(np.max(np.abs(err[inside]))),
                            float(np.sqrt(np.mean(err[inside] ** 2))), quartics[a].max_error, float(targets[a]), amp,
                            float(np.max(np.abs(err[~inside]), initial=0.0)),
                            float(np.max(np.abs(slope))), float(np.sqrt(np.mean(slope ** 2))),
                            float(np.max(np.abs(q_slope))), float(np.sqrt(np.mean(q_slope ** 2))), slopes[a]))
    fit = CouplingFit(**{**draft.__dict__, "axes": tuple(axes)})
    _COUPLING_CACHE[key] = fit
    return fit


def fit_coupling(fn: Callable[[FloatArray], FloatArray], lo: float, hi: float, x0: float, *,
                 target: float, max_inner: int = 3, n: int = 2001, amplitude: float = COUPLING_AMPLITUDE,
                 margin: float = 0.0, seed: int = 0, slope_target: float | None = None) -> CouplingFit:
    """One function as a sum of joints (:func:`fit_couplings` with one axis carrying all its inner
    joints): the plain quartic when its error is at most ``target``; otherwise K = 1, 2, ...
    ``max_inner`` inner/outer pairs, each K starting from K - 1's shapes, stopping at the first
    K that meets ``target`` (fewest extra joints), and only as long as each pair brings the
    error below :data:`COUPLING_GAIN` times the last; so the error never grows with
    ``max_inner``. With ``slope_target`` the error is max(error / target, slope error / slope
    target) and the fits are derivative-aware (see :func:`fit_couplings`). Units as
    :func:`fit_couplings`."""
    kw = {"n": n, "amplitude": amplitude, "margin": margin, "seed": seed,
          "slope_targets": None if slope_target is None else [slope_target]}

    def ratio(f: CouplingFit) -> float:
        ax = f.axes[0]
        return max(ax.max_error / max(target, 1e-300), ax.slope_error / slope_target if slope_target else 0.0)

    best = fit_couplings([fn], lo, hi, x0, targets=[target], uses=[[]], hosts=[], **kw)
    for k in range(1, max_inner + 1):
        if ratio(best) <= 1:
            break
        fit = fit_couplings([fn], lo, hi, x0, targets=[target], uses=[list(range(k))], hosts=[0] * k,
                            start_shapes=best.shapes, **kw)
        if ratio(fit) > COUPLING_GAIN * ratio(best):
            break
        best = fit
    return best
