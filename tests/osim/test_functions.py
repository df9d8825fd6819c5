"""o2m.functions against OpenSim 4.6 itself: values and first derivatives, inside and outside
the knot range, of functions built with the opensim API, serialised by OpenSim and parsed back."""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

import numpy as np
import pytest
from lxml import etree

from o2m.errors import UnsupportedElementError
from o2m.osim.function_reader import function_child, parse_function
from o2m.osim.functions import (
    Constant,
    GCVSpline,
    LinearFunction,
    MultiplierFunction,
    PiecewiseLinearFunction,
    PolynomialFunction,
    SimmSpline,
)
from tests.helpers import model_file

osim = pytest.importorskip("opensim")

TOL = 1e-10  # max |o2m - OpenSim| relative to max(1, |OpenSim|) over the sample points


# ----------------------------------------------------------------------------------------------
# helpers
# ----------------------------------------------------------------------------------------------
def _osim_eval(f, xs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """OpenSim's value and first derivative at xs (p,)."""
    d1 = osim.StdVectorInt([0])
    v = np.array([f.calcValue(osim.Vector(1, float(t))) for t in xs])
    d = np.array([f.calcDerivative(d1, osim.Vector(1, float(t))) for t in xs])
    return v, d


def _sample(lo: float, hi: float, knots=()) -> np.ndarray:
    """300 points inside [lo, hi], the knots themselves, and 20% beyond each end."""
    w = hi - lo if hi > lo else 1.0
    return np.unique(np.concatenate([
        np.linspace(lo, hi, 301), np.asarray(knots, dtype=float),
        np.linspace(lo - 0.2 * w, lo, 21), np.linspace(hi, hi + 0.2 * w, 21),
    ]))


def _assert_matches(osim_f, mine, xs: np.ndarray) -> None:
    v, d = _osim_eval(osim_f, xs)
    mv, md = mine(xs), mine.derivative(xs)
    assert mv.shape == xs.shape and md.shape == xs.shape
    assert mv.dtype == np.float64
    err_v = np.max(np.abs(mv - v)) / max(1.0, np.max(np.abs(v)))
    err_d = np.max(np.abs(md - d)) / max(1.0, np.max(np.abs(d)))
    assert err_v <= TOL, f"{mine.kind}: value error {err_v:.3e}"
    assert err_d <= TOL, f"{mine.kind}: derivative error {err_d:.3e}"


def _roundtrip(osim_f):
    """OpenSim's own XML for the object, parsed by o2m."""
    return parse_function(etree.fromstring(osim_f.dump().encode()))


def _dataset(seed: int, n: int, lo: float = -2.0, hi: float = 2.5) -> tuple[np.ndarray, np.ndarray]:
    """Random knots with 4 decimals, so OpenSim's 6-digit printing of <x>/<y> is lossless."""
    rng = np.random.default_rng(seed)
    while True:
        x = np.array([float(f"{v:.4f}") for v in np.sort(rng.uniform(lo, hi, n))])
        if np.all(np.diff(x) > 0):
            break
    y = np.array([float(f"{v:.4f}") for v in rng.normal(0.0, 1.5, n)])
    return x, y


def _add_points(f, x, y):
    for a, b in zip(x, y, strict=True):
        f.addPoint(float(a), float(b))
    return f


def _owned_clone(f):
    """A copy whose ownership passes to the OpenSim object it is given to."""
    c = f.clone()
    c.thisown = False
    return c


def _load_xml_object(xml: str):
    """Let OpenSim read a function element from an XML document (as it reads model files)."""
    fd, path = tempfile.mkstemp(suffix=".xml")
    os.close(fd)
    try:
        Path(path).write_text('<?xml version="1.0" encoding="UTF-8" ?>\n'
                              f'<OpenSimDocument Version="40600">\n{xml}\n</OpenSimDocument>\n')
        obj = osim.OpenSimObject.makeObjectFromFile(path)
    finally:
        os.remove(path)
    return obj, osim.Function.safeDownCast(obj)


def _xy_xml(tag: str, x, y, extra: str = "") -> str:
    xs = " ".join(repr(v) for v in np.asarray(x).tolist())
    ys = " ".join(repr(v) for v in np.asarray(y).tolist())
    return f'<{tag} name="function">{extra}<x>{xs}</x><y>{ys}</y></{tag}>'


# ----------------------------------------------------------------------------------------------
# every function type, built with the opensim API and serialised by OpenSim
# ----------------------------------------------------------------------------------------------
SPLINE_CASES = [(seed, n) for n in (2, 3, 4, 5, 9, 25) for seed in (0, 1)]


@pytest.mark.parametrize(("seed", "n"), SPLINE_CASES)
def test_simm_spline_matches_opensim(seed, n):
    x, y = _dataset(seed, n)
    f = _add_points(osim.SimmSpline(), x, y)
    mine = _roundtrip(f)
    assert isinstance(mine, SimmSpline) and mine.kind == "SimmSpline"
    np.testing.assert_array_equal(mine.x, x)
    np.testing.assert_array_equal(mine.y, y)
    _assert_matches(f, mine, _sample(x[0], x[-1], x))


@pytest.mark.parametrize("tag", ["NaturalCubicSpline", "natCubicSpline"])
def test_natural_cubic_spline_is_read_as_simm_spline(tag):
    """OpenSim 4.6 renames NaturalCubicSpline / natCubicSpline to SimmSpline when reading."""
    x, y = _dataset(7, 8)
    xml = _xy_xml(tag, x, y)
    keep, f = _load_xml_object(xml)
    assert f.getConcreteClassName() == "SimmSpline"
    mine = parse_function(etree.fromstring(xml))
    assert mine.kind == "SimmSpline" and mine.tag == tag
    _assert_matches(f, mine, _sample(x[0], x[-1], x))
    del keep


GCV_CASES = [(degree, n, seed) for degree in (1, 3, 5, 7)
             for n in sorted({degree + 1, degree + 2, 12}) for seed in (0, 1, 2)]


@pytest.mark.parametrize(("degree", "n", "seed"), GCV_CASES)
def test_gcv_spline_matches_opensim(degree, n, seed):
    x, y = _dataset(100 + seed, n, 0.0, 3.0)
    f = osim.GCVSpline()
    f.setDegree(degree)
    _add_points(f, x, y)
    mine = _roundtrip(f)
    assert isinstance(mine, GCVSpline)
    assert mine.half_order == (degree + 1) // 2 and mine.degree == degree
    _assert_matches(f, mine, _sample(x[0], x[-1], x))


def test_gcv_spline_property_names_as_opensim_prints_them():
    f = osim.GCVSpline()
    f.setDegree(5)
    _add_points(f, *_dataset(3, 6))
    names = [ch.tag for ch in etree.fromstring(f.dump().encode())]
    assert names == ["half_order", "error_variance", "x", "y", "weights", "coefficients"]


@pytest.mark.parametrize(("half_order", "error_variance"), [(2, 0.01), (3, 0.001), (2, -1.0), (3, -1.0)])
def test_gcv_spline_smoothing_matches_opensim(half_order, error_variance):
    """error_variance > 0 smooths (fitFromErrorVariance), < 0 uses GCV (fitFromGCV)."""
    x, y = _dataset(11, 15, 0.0, 3.0)
    xml = _xy_xml("GCVSpline", x, y,
                  f"<half_order>{half_order}</half_order><error_variance>{error_variance!r}</error_variance>")
    keep, f = _load_xml_object(xml)
    mine = parse_function(etree.fromstring(xml))
    _assert_matches(f, mine, _sample(x[0], x[-1], x))
    del keep


@pytest.mark.parametrize(("seed", "n"), [(s, n) for n in (2, 3, 6, 20) for s in (0, 1)])
def test_piecewise_linear_matches_opensim(seed, n):
    x, y = _dataset(200 + seed, n)
    f = _add_points(osim.PiecewiseLinearFunction(), x, y)
    mine = _roundtrip(f)
    assert isinstance(mine, PiecewiseLinearFunction)
    _assert_matches(f, mine, _sample(x[0], x[-1], x))


@pytest.mark.parametrize(("seed", "n"), [(s, n) for n in (1, 2, 3, 6, 20) for s in (0, 1)])
def test_piecewise_constant_matches_opensim(seed, n):
    x, y = _dataset(300 + seed, n)
    f = _add_points(osim.PiecewiseConstantFunction(), x, y)
    mine = _roundtrip(f)
    assert mine.kind == "PiecewiseConstantFunction"
    _assert_matches(f, mine, _sample(x[0], x[-1], x))


@pytest.mark.parametrize("coefs", [[2.5], [1.0, -0.5], [1.0, 2.0, 3.0], [0.3, -1.2, 0.0, 2.0, -0.7]])
def test_polynomial_matches_opensim_highest_power_first(coefs):
    f = osim.PolynomialFunction(osim.Vector(coefs))
    mine = _roundtrip(f)
    assert isinstance(mine, PolynomialFunction)
    np.testing.assert_array_equal(mine.coefficients, coefs)
    _assert_matches(f, mine, _sample(-2.0, 2.0))
    assert float(mine(2.0)) == pytest.approx(float(np.polyval(coefs, 2.0)))


def test_linear_and_constant_match_opensim():
    lin = osim.LinearFunction(2.0, 3.0)
    mine = _roundtrip(lin)
    assert isinstance(mine, LinearFunction) and (mine.slope, mine.intercept) == (2.0, 3.0)
    _assert_matches(lin, mine, _sample(-3.0, 3.0))
    const = osim.Constant(2.5)
    mine = _roundtrip(const)
    assert isinstance(mine, Constant) and mine.value == 2.5
    _assert_matches(const, mine, _sample(-3.0, 3.0))


def test_sine_and_step_match_opensim():
    sine = osim.Sine(2.0, 3.0, 0.5, 1.0)
    _assert_matches(sine, _roundtrip(sine), _sample(-2.0, 2.0))
    step = osim.StepFunction(0.5, 1.5, 2.0, 5.0)
    _assert_matches(step, _roundtrip(step), _sample(0.0, 2.0, [0.5, 1.5]))


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_multiplier_function_matches_opensim(seed):
    x, y = _dataset(400 + seed, 5 + seed)
    inner = _add_points(osim.SimmSpline(), x, y)
    f = osim.MultiplierFunction(_owned_clone(inner), 0.9 + seed)
    nested = osim.MultiplierFunction(_owned_clone(f), -1.7)
    for g in (f, nested):
        mine = _roundtrip(g)
        assert isinstance(mine, MultiplierFunction)
        assert isinstance(mine.function, (SimmSpline, MultiplierFunction))
        _assert_matches(g, mine, _sample(x[0], x[-1], x))


def test_multiplier_without_function_wrapper():
    el = etree.fromstring('<MultiplierFunction name="function"><SimmSpline><x>0 1 2</x><y>0 1 4</y>'
                          '</SimmSpline><scale>2</scale></MultiplierFunction>')
    f = parse_function(el)
    assert isinstance(f, MultiplierFunction) and float(f(1.0)) == 2.0


# ----------------------------------------------------------------------------------------------
# functions inside a model printed by OpenSim
# ----------------------------------------------------------------------------------------------
def _coupler_functions():
    x, y = _dataset(500, 6)
    gcv = osim.GCVSpline()
    gcv.setDegree(5)
    _add_points(gcv, x, y)
    simm = _add_points(osim.SimmSpline(), x, y)
    return {
        "SimmSpline": simm,
        "GCVSpline": gcv,
        "MultiplierFunction": osim.MultiplierFunction(_owned_clone(simm), 0.5),
        "PiecewiseLinearFunction": _add_points(osim.PiecewiseLinearFunction(), x, y),
        "PolynomialFunction": osim.PolynomialFunction(osim.Vector([0.1, -0.2, 1.0, 0.3])),
        "LinearFunction": osim.LinearFunction(-0.5, 0.25),
        "Constant": osim.Constant(0.125),
    }


@pytest.mark.parametrize("kind", list(_coupler_functions()))
def test_coordinate_coupler_function_printed_in_model(kind, tmp_path):
    """Function in a CoordinateCouplerConstraint: printed with the model, reloaded by OpenSim."""
    f = _coupler_functions()[kind]
    model = osim.Model()
    model.setName("coupler")
    b1 = osim.Body("b1", 1.0, osim.Vec3(0), osim.Inertia(0.1))
    b2 = osim.Body("b2", 1.0, osim.Vec3(0), osim.Inertia(0.1))
    j1 = osim.PinJoint("j1", model.getGround(), b1)
    j2 = osim.SliderJoint("j2", b1, b2)
    cc = osim.CoordinateCouplerConstraint()
    cc.setName("cc")
    cc.setIndependentCoordinateNames(osim.ArrayStr("j1_coord_0", 1))
    cc.setDependentCoordinateName("j2_coord_0")
    cc.setFunction(_owned_clone(f))
    for obj in (b1, b2, j1, j2, cc):
        obj.thisown = False
    model.addBody(b1)
    model.addBody(b2)
    model.addJoint(j1)
    model.addJoint(j2)
    model.addConstraint(cc)
    model.finalizeConnections()
    path = tmp_path / "coupler.osim"
    model.printToXML(str(path))

    tree = etree.parse(str(path))
    (wrapper,) = tree.iter("coupled_coordinates_function")
    el = function_child(wrapper)
    assert el is not None and el.tag == kind
    mine = parse_function(el)
    assert mine.kind == kind and mine.line == el.sourceline

    loaded = osim.Model(str(path))
    ref = osim.CoordinateCouplerConstraint.safeDownCast(loaded.getConstraintSet().get("cc")).getFunction()
    knots = getattr(mine, "knots", np.empty(0))
    lo, hi = (float(knots[0]), float(knots[-1])) if len(knots) else (-1.0, 1.0)
    _assert_matches(ref, mine, _sample(lo, hi, knots))


# ----------------------------------------------------------------------------------------------
# real models
# ----------------------------------------------------------------------------------------------
REAL_MODELS = [
    "opensim-models/Models/Gait2354_Simbody/gait2354_simbody.osim",
    "opensim-models/Models/Leg6Dof9Musc/leg6dof9musc.osim",
    "opensim-models/Models/Gait2354_Simbody/subject01_simbody.osim",  # scaled: MultiplierFunction(SimmSpline)
]


@pytest.mark.parametrize("registry_path", REAL_MODELS, ids=lambda p: p.rsplit("/", 1)[-1])
def test_real_model_functions_match_opensim(registry_path):
    path = model_file(registry_path)
    tree = etree.parse(str(path))
    model = osim.Model(str(path))
    joints = model.getJointSet()
    kinds = set()
    n_checked = 0
    for joint_el in tree.iter("CustomJoint"):
        joint = osim.CustomJoint.safeDownCast(joints.get(joint_el.get("name")))
        st = joint.getSpatialTransform()
        for axis_el in joint_el.iter("TransformAxis"):
            el = function_child(axis_el)
            assert el is not None, f"no function in {joint_el.get('name')}/{axis_el.get('name')}"
            mine = parse_function(el)
            inner = mine.function.kind if isinstance(mine, MultiplierFunction) else ""
            kinds.add(f"{mine.kind}({inner})" if inner else mine.kind)
            index = ["rotation1", "rotation2", "rotation3",
                     "translation1", "translation2", "translation3"].index(axis_el.get("name"))
            ref = st.getTransformAxis(index).getFunction()
            knots = mine.knots
            lo, hi = (float(knots[0]), float(knots[-1])) if len(knots) else (-2.0, 2.0)
            _assert_matches(ref, mine, _sample(lo, hi, knots))
            n_checked += 1
    constraints = model.getConstraintSet()
    for cc_el in tree.iter("CoordinateCouplerConstraint"):
        el = function_child(next(cc_el.iter("coupled_coordinates_function")))
        mine = parse_function(el)
        ref = osim.CoordinateCouplerConstraint.safeDownCast(constraints.get(cc_el.get("name"))).getFunction()
        knots = mine.knots
        lo, hi = (float(knots[0]), float(knots[-1])) if len(knots) else (-2.0, 2.0)
        _assert_matches(ref, mine, _sample(lo, hi, knots))
        n_checked += 1
    assert n_checked > 0
    assert any("SimmSpline" in k for k in kinds)


# ----------------------------------------------------------------------------------------------
# is_linear
# ----------------------------------------------------------------------------------------------
def test_is_linear():
    ident = SimmSpline(np.linspace(-2.0944, 2.0944, 7), np.linspace(-2.0944, 2.0944, 7))
    slope, intercept = ident.is_linear(-2.0944, 2.0944)
    assert slope == pytest.approx(1.0, abs=1e-12) and intercept == pytest.approx(0.0, abs=1e-12)
    # collinear points with unequal spacing, evaluated partly outside the knots
    xs = np.array([-1.0, -0.3, 0.2, 1.5, 2.0])
    line = SimmSpline(xs, 2.0 * xs - 1.0)
    slope, intercept = line.is_linear(-1.5, 2.5)
    assert slope == pytest.approx(2.0, abs=1e-12) and intercept == pytest.approx(-1.0, abs=1e-12)
    curved = SimmSpline([0.0, 1.0, 2.0, 3.0], [0.0, 0.5, 0.1, 1.0])
    assert curved.is_linear(0.0, 3.0) is None
    assert Constant(0.3).is_linear(-1, 1) == (0.0, 0.3)
    assert LinearFunction(2.0, -1.0).is_linear(-1, 1) == (2.0, -1.0)
    assert MultiplierFunction(ident, 0.5).is_linear(-1, 1) == pytest.approx((0.5, 0.0), abs=1e-12)
    pwl = PiecewiseLinearFunction([0.0, 1.0, 2.0], [0.0, 1.0, 0.0])
    assert pwl.is_linear(0.0, 2.0) is None
    assert pwl.is_linear(0.1, 0.9) == pytest.approx((1.0, 0.0))
    assert PolynomialFunction([0.0, 0.0, 3.0, 1.0]).is_linear(-5, 5) == pytest.approx((3.0, 1.0))
    assert PolynomialFunction([1e-3, 0.0, 1.0]).is_linear(-1, 1) is None


def test_vectorized_shapes():
    f = SimmSpline([0.0, 1.0, 2.0, 3.0], [0.0, 0.5, 0.1, 1.0])
    assert f(1.5).shape == () and f.derivative(1.5).shape == ()
    grid = np.linspace(-1, 4, 12).reshape(3, 4)
    assert f(grid).shape == (3, 4) and f.derivative(grid).shape == (3, 4)
    np.testing.assert_array_equal(f(grid).ravel(), f(grid.ravel()))


# ----------------------------------------------------------------------------------------------
# errors
# ----------------------------------------------------------------------------------------------
def _parse_doc(text: str):
    root = etree.fromstring(text.encode())
    return parse_function(function_child(root) if root.tag == "TransformAxis" else root)


def test_unknown_function_raises_with_element_and_line():
    doc = '<TransformAxis name="rotation1">\n  <axis>1 0 0</axis>\n  <FancySpline name="function">\n' \
          '    <x>0 1</x>\n  </FancySpline>\n</TransformAxis>'
    el = etree.fromstring(doc.encode())[1]
    with pytest.raises(UnsupportedElementError) as info:
        parse_function(el)
    e = info.value
    assert (e.element, e.name, e.line) == ("FancySpline", "function", 3)
    assert "FancySpline" in str(e) and "line 3" in str(e)


@pytest.mark.parametrize(("body", "words"), [
    ('<SimmSpline name="f">\n<x>0 1 2</x>\n<y>0 1</y>\n</SimmSpline>', "3 x values but 2 y values"),
    ('<SimmSpline name="f">\n<x>0</x>\n<y>1</y>\n</SimmSpline>', "at least 2 points"),
    ('<SimmSpline name="f">\n<x>0 2 1</x>\n<y>0 1 2</y>\n</SimmSpline>', "strictly increasing"),
    ('<PiecewiseLinearFunction name="f">\n<x>0 1 1</x>\n<y>0 1 2</y>\n</PiecewiseLinearFunction>',
     "strictly increasing"),
    ('<GCVSpline name="f">\n<half_order>3</half_order>\n<x>0 1 2 3 4</x>\n<y>0 1 2 3 4</y>\n</GCVSpline>',
     "at least 6 points"),
    ('<GCVSpline name="f">\n<degree>5</degree>\n<x>0 1 2 3 4 5</x>\n<y>0 1 2 3 4 5</y>\n</GCVSpline>',
     "half_order"),
    ('<SimmSpline name="f">\n<x>0 1 two</x>\n<y>0 1 2</y>\n</SimmSpline>', "not a number"),
    ('<LinearFunction name="f">\n<coefficients>1 2 3</coefficients>\n</LinearFunction>', "2 finite numbers"),
    ('<MultiplierFunction name="f">\n<function />\n<scale>2</scale>\n</MultiplierFunction>', "no function"),
])
def test_malformed_numbers_raise(body, words):
    with pytest.raises(UnsupportedElementError) as info:
        _parse_doc(body)
    e = info.value
    assert e.name == "f" and e.line == 1 and e.element == body[1:body.index(" ")]
    assert words in str(e)


def test_error_inside_multiplier_names_inner_element():
    doc = '<MultiplierFunction name="outer">\n<function>\n<SimmSpline name="inner">\n' \
          '<x>0 1</x>\n<y>0</y>\n</SimmSpline>\n</function>\n</MultiplierFunction>'
    with pytest.raises(UnsupportedElementError) as info:
        _parse_doc(doc)
    assert (info.value.element, info.value.name, info.value.line) == ("SimmSpline", "inner", 3)
