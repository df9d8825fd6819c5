"""OpenSim 1-D functions (TransformAxis / CoordinateCouplerConstraint functions) evaluated in numpy.

Every class here reproduces what OpenSim 4.6 computes for the same XML element, inside and
outside the knot range, without OpenSim.  Behaviours copied from OpenSim (checked against the
opensim 4.6 Python API in ``tests/osim/test_functions.py``):

* ``SimmSpline``: SIMM's cubic spline with Forsythe-Malcolm-Moler end conditions (third
  derivative at each end taken from the cubic through the 4 end points; for 3 points the
  third derivative is continuous at the middle point; 2 points give a line).  Outside
  [x[0], x[-1]] it extrapolates LINEARLY with the end slope.  ``NaturalCubicSpline`` and
  ``natCubicSpline`` elements are read by OpenSim 4.6 as ``SimmSpline`` (``Object::renameType``),
  so they are evaluated the same way (not with natural end conditions).
* ``GCVSpline``: Woltring's GCVSPL as used by Simbody's ``SplineFitter::fitFromErrorVariance``
  (``error_variance`` >= 0) or ``fitFromGCV`` (< 0).  With ``error_variance`` 0 the spline
  interpolates the data only up to the tiny smoothing parameter GCVSPL's search ends on, so
  it is a faithful port of GCVSPL (:mod:`o2m.osim.gcvspl`; scipy's exact interpolant differs
  by up to ~1e-10).  The natural spline of degree 2m-1 extrapolates as a polynomial of degree
  m-1 (constant for degree 1, linear for cubic, quadratic for quintic, cubic for heptic).
* ``PiecewiseLinearFunction``: linear extrapolation with the first/last segment slope;
  ``PiecewiseConstantFunction``: y[0] left of the knots, y[-1] right of them, derivative 0.
* ``PolynomialFunction``: coefficients from the HIGHEST power to the lowest;
  ``MultivariatePolynomialFunction`` of one dimension: from the LOWEST power up, read as a
  PolynomialFunction (more dimensions are refused: a coupler or axis has one input).
* ``LinearFunction``: ``<coefficients>slope intercept</coefficients>``.
* ``MultiplierFunction``: ``scale * function(x)``, the wrapped element inside ``<function>``.

Units: x is the independent coordinate value (rad or m), values are in the dependent
coordinate's unit (rad or m); derivatives are value units per x unit. Fits of these functions
for the conversion are in :mod:`o2m.convert.polyfit` and :mod:`o2m.convert.couplings`.

The XML reader that builds them is :mod:`o2m.osim.function_reader`; GCVSPL is in
:mod:`o2m.osim.gcvspl`.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np
from numpy.typing import ArrayLike, NDArray

from o2m.osim.gcvspl import gcv_splder, gcvspl

__all__ = [
    "Function", "Constant", "LinearFunction", "PolynomialFunction", "SimmSpline", "GCVSpline",
    "PiecewiseLinearFunction", "PiecewiseConstantFunction", "MultiplierFunction", "Sine",
    "StepFunction",
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
# GCVSpline: Woltring's GCVSPL (o2m.osim.gcvspl), K = 1, unit weights.
# ---------------------------------------------------------------------------------------------
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
        object.__setattr__(self, "coefficients", np.array(gcvspl(x.tolist(), y.tolist(), m, md, val)))

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
            out[sel] = gcv_splder(order, self.half_order, t[sel], xl, cl, int(l_))
        return out.reshape(shape)

    def __call__(self, x: ArrayLike) -> FloatArray:
        return self.derivative_n(x, 0)

    def derivative(self, x: ArrayLike) -> FloatArray:
        return self.derivative_n(x, 1)


# ---------------------------------------------------------------------------------------------
# XML parsing
