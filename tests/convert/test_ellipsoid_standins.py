"""An ellipsoid's stand-in, sphere or cylinder, is chosen per path by measured error
(:mod:`o2m.convert.ellipsoid_standins`), on a pendulum whose path runs over the end of an
elongated ellipsoid.

Ground -> arm (PinJoint q in [0, 1] rad); a PathActuator "m" from P1 (-0.2, 0, 0) on ground to P3
(0.3, 0, 0) on the arm, over a WrapEllipsoid on ground at (0, -0.08, 0.03) of semi-axes (0.06,
0.12, 0.06) m (quadrant all): its long axis points at the path, whose straight line cuts its end
near q = 0 and clears it as q grows. The converter starts from the cylinder along the long axis
(ratio 2 > 1.5), which the path, 0.03 m off that axis, cuts at every angle: the infinite cylinder
wraps it where OpenSim's ellipsoid has ended.
"""

from __future__ import annotations

import numpy as np
import opensim as osim

from o2m.convert.converter import convert
from o2m.convert.ellipsoid_standins import first_kind, standins
from tests.helpers import arm_path_actuator, convert_options, pendulum_lengths, pin_pendulum

osim.Logger.setLevelString("error")


def _pendulum_over_an_ellipsoid_end(path) -> None:
    m, arm = pin_pendulum("ellipsoid_end", (0.0, 1.0))
    pa = arm_path_actuator(m, arm, "P3")
    m.addForce(pa)
    w = osim.WrapEllipsoid()
    w.setName("obstacle")
    w.set_dimensions(osim.Vec3(0.06, 0.12, 0.06))
    w.set_translation(osim.Vec3(0.0, -0.08, 0.03))
    w.set_quadrant("all")
    m.updGround().addWrapObject(w)
    pa.updGeometryPath().addPathWrap(w)
    m.finalizeConnections()
    m.initSystem()
    m.printToXML(str(path))


def test_standins_and_their_gaps():
    """Both stand-ins of an ellipsoid, with the largest gap between the surfaces along any of its
    axes: a cylinder's is its radius (the ellipsoid's section shrinks to a point at its ends)."""
    s = standins([0.03, 0.06, 0.03])
    size, rot, gap, _ = s["cylinder"]
    assert size[:2] == [0.03, 0.06] and np.allclose(rot[:, 2], [0, 1, 0]) and gap == 0.03
    size, _, gap, _ = s["sphere"]
    assert np.isclose(size[0], 0.04) and np.isclose(gap, 0.02)
    assert first_kind([0.03, 0.06, 0.03]) == "cylinder" and first_kind([0.03, 0.04, 0.03]) == "sphere"


def test_the_cylinder_wraps_where_the_ellipsoid_is_not(tmp_path):
    """Without the wrap fit the tendon wraps the converter's cylinder at every angle, 3-4 mm
    longer than OpenSim's path, which touches the ellipsoid's end only near q = 0 (0.74 mm)."""
    osim_path = tmp_path / "ellipsoid_end.osim"
    _pendulum_over_an_ellipsoid_end(osim_path)
    conv = convert(osim_path, tmp_path / "out", convert_options(fit_wraps=False, fit_mechanics=False))
    l_os, l_mj = pendulum_lengths(osim_path, conv.xml, np.linspace(0.0, 1.0, 21))
    assert np.all(l_mj - l_os > 3e-3), l_mj - l_os


def test_a_path_over_an_ellipsoids_end_keeps_the_sphere(tmp_path):
    """The wrap fit fits the path with both stand-ins and keeps the sphere, nearer OpenSim on its
    fitting and check poses (measured: 1 micrometre at worst, the fitted cylinder 0.63 mm, as far
    as the straight path); the report's error of the ellipsoid is the path's worst length error
    against OpenSim at the fit's poses (%), no longer a size."""
    osim_path = tmp_path / "ellipsoid_end.osim"
    _pendulum_over_an_ellipsoid_end(osim_path)
    conv = convert(osim_path, tmp_path / "out", convert_options(fit_mechanics=False, workers=1))
    (fit,) = conv.report.path_fits
    assert fit["variant"] == "obstacle (obstacle sphere)", fit["variants"]
    assert fit["swapped"]["wrap_obstacle"]["kind"] == "sphere"
    kept, cylinder = fit["variants"][fit["variant"]], fit["variants"]["obstacle"]
    assert kept["len_max_pct"] < 0.1 * cylinder["len_max_pct"], fit["variants"]
    (approx,) = [a for a in conv.report.approximations if a.element == "WrapEllipsoid"]
    worst = max(fit["after"]["len_max_pct"], fit["check_after"]["len_max_pct"])
    assert approx.units == "%" and np.isclose(approx.max_error, worst) and "sphere: m" in approx.what
    l_os, l_mj = pendulum_lengths(osim_path, conv.xml, np.linspace(0.0, 1.0, 101))
    assert np.max(np.abs(l_mj - l_os)) < 1e-5, np.max(np.abs(l_mj - l_os))
