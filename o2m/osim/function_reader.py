"""Reading OpenSim function elements (lxml) into :mod:`o2m.osim.functions` objects.

:func:`parse_function` dispatches on the element's tag (one branch per OpenSim Function type o2m
evaluates); :func:`function_child` finds the function element inside a property such as a
TransformAxis or a ``<coupled_coordinates_function>``. Malformed numbers or an unknown type raise
:class:`~o2m.errors.UnsupportedElementError` naming the element and its line.
"""

from __future__ import annotations

import math

import numpy as np

from o2m.errors import UnsupportedElementError
from o2m.osim.document import MAX_MAGNITUDE
from o2m.osim.functions import (
    Constant,
    FloatArray,
    Function,
    GCVSpline,
    LinearFunction,
    MultiplierFunction,
    PiecewiseConstantFunction,
    PiecewiseLinearFunction,
    PolynomialFunction,
    SimmSpline,
    Sine,
    StepFunction,
)

FUNCTION_TAGS: frozenset[str] = frozenset({
    "Constant", "LinearFunction", "PolynomialFunction", "SimmSpline", "NaturalCubicSpline",
    "natCubicSpline", "GCVSpline", "PiecewiseLinearFunction", "PiecewiseConstantFunction",
    "MultiplierFunction", "Sine", "StepFunction", "MultivariatePolynomialFunction",
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
        v = np.array([float(tok) for tok in text.replace(",", " ").split()], dtype=np.float64)
    except ValueError as exc:
        raise ValueError(f"<{name}> holds a value that is not a number: {text!r}") from exc
    big = np.isfinite(v) & (np.abs(v) > MAX_MAGNITUDE)
    if big.any():
        raise ValueError(f"<{name}> holds {v[big][0]:g}, beyond {MAX_MAGNITUDE:g}, MuJoCo's largest value")
    return v


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


def _univariate_polynomial(element, meta: dict) -> PolynomialFunction:
    """A MultivariatePolynomialFunction of one dimension (coefficients c0 + c1 x + ... + cn x^n)."""
    dim = _scalar(element, "dimension", 0.0)
    if dim != 1:
        raise ValueError(f"has <dimension> {dim:g}; o2m reads a MultivariatePolynomialFunction of one "
                         "dimension only (its input here is one coordinate)")
    c = _numbers(element, "coefficients")
    if c is None or c.size == 0:
        raise ValueError("MultivariatePolynomialFunction has no <coefficients>")
    order = _scalar(element, "order", float(c.size - 1))
    if order != c.size - 1:
        raise ValueError(f"has <order> {order:g} but {c.size} coefficients (one dimension needs order + 1)")
    return PolynomialFunction(c[::-1].copy(), **meta)


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
        if tag == "MultivariatePolynomialFunction":
            return _univariate_polynomial(element, meta)
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
