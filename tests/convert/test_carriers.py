"""Path-point carriers get as few slides as their point's locus needs, on a hand-built pendulum.

ground -> arm (PinJoint q, range [-1, 1.5] rad); PathActuators from ground to the arm through a
MovingPathPoint on the arm whose x, y and z all follow q (polynomials, highest power first; exact
in MuJoCo's quartic joint equalities):

* "line": x and y linear in q, z constant: a straight locus, one slide;
* "twin": the same motion as "line" from another reference location: it rides "line"'s carrier;
* "plane": x quadratic, y linear, z constant: a planar locus, two slides;
* "curve": x, y and z of powers 1, 2 and 3 of q: no plane holds it, three slides.

Each site must stay on its OpenSim location at every q.
"""

from __future__ import annotations

import mujoco
import numpy as np
import opensim as osim
import pytest

from o2m.convert.carriers import CARRIER_AXIS_TOLERANCE
from o2m.convert.converter import convert
from o2m.mj.posing import joint_equality_plan, pose_mujoco
from tests.helpers import add_three_point_paths, convert_options, pin_pendulum, with_moving_point

osim.Logger.setLevelString("error")

#: (x, y, z) PolynomialFunction coefficients of each moving point, highest power first.
MOVING = {
    "line": ("0.03 0.1", "0.01 0.03", "0.02"),
    "twin": ("0.03 0.12", "0.01 0.02", "0.01"),
    "plane": ("0.01 0.03 0.1", "0.01 0.03", "0.02"),
    "curve": ("0.03 0.1", "0.02 0 0.03", "0.01 0 0 0.02"),
}
SLIDES = {"line": 1, "plane": 2, "curve": 3}


def _model(path) -> None:
    m, arm = pin_pendulum("carriers")
    add_three_point_paths(m, arm, MOVING)
    m.finalizeConnections()
    m.initSystem()
    m.printToXML(str(path))
    text = path.read_text()
    for name, coefs in MOVING.items():  # P2 made a MovingPathPoint
        polynomials = tuple(f"<PolynomialFunction><coefficients>{c}</coefficients></PolynomialFunction>"
                            for c in coefs)
        text = with_moving_point(text, f"{name}-P2", "arm", polynomials)
    path.write_text(text)


@pytest.fixture(scope="module")
def converted(tmp_path_factory):
    folder = tmp_path_factory.mktemp("carriers")
    _model(folder / "carriers.osim")
    conv = convert(folder / "carriers.osim", folder / "out",
                   convert_options(path_forces="kinematic", fit_wraps=False, fit_mechanics=False))
    return conv, mujoco.MjModel.from_xml_path(str(conv.xml))


def _carrier_of(model: mujoco.MjModel, name: str) -> int:
    return int(model.site_bodyid[model.site(f"{name}-P2").id])


def test_each_carrier_has_the_slides_its_locus_needs(converted):
    _, m = converted
    for name, n in SLIDES.items():
        body = _carrier_of(m, name)
        assert m.body(body).name.endswith("_carrier"), name
        assert m.body_jntnum[body] == n, (name, m.body_jntnum[body])
    assert _carrier_of(m, "twin") == _carrier_of(m, "line")


def test_sites_follow_their_opensim_location(converted):
    conv, m = converted
    d = mujoco.MjData(m)
    plan = joint_equality_plan(m)
    arm = m.body("arm").id
    for q in np.linspace(-1.0, 1.5, 11):
        pose_mujoco(m, d, {"q": q}, plan=plan)
        rot = d.xmat[arm].reshape(3, 3)
        for name, coefs in MOVING.items():
            want = [np.polyval([float(c) for c in axis.split()], q) for axis in coefs]
            got = rot.T @ (d.site_xpos[m.site(f"{name}-P2").id] - d.xpos[arm])
            np.testing.assert_allclose(got, want, atol=CARRIER_AXIS_TOLERANCE, err_msg=f"{name} at q={q}")
    assert any("rides carrier" in note and "twin" in note for note in conv.report.notes)


def test_a_larger_tolerance_trades_slides_for_a_stated_error(tmp_path):
    """``carrier_tolerance`` 1 cm: "plane" lies within 4.7 mm of a line (one slide), "curve" within
    8.5 mm of a plane (two): fewer slides, every site within 1 cm of its OpenSim location (and
    not exactly on it), and the report's notes name each change."""
    _model(tmp_path / "carriers.osim")
    tol = 0.01
    conv = convert(tmp_path / "carriers.osim", tmp_path / "out",
                   convert_options(path_forces="kinematic", fit_wraps=False, fit_mechanics=False,
                                   carrier_tolerance=tol))
    m = mujoco.MjModel.from_xml_path(str(conv.xml))
    exact = sum(SLIDES.values())
    assert sum(int(m.body_jntnum[_carrier_of(m, n)]) for n in SLIDES) < exact
    d, plan, arm = mujoco.MjData(m), joint_equality_plan(m), m.body("arm").id
    worst = 0.0
    for q in np.linspace(-1.0, 1.5, 26):
        pose_mujoco(m, d, {"q": q}, plan=plan)
        rot = d.xmat[arm].reshape(3, 3)
        for name, coefs in MOVING.items():
            want = [np.polyval([float(c) for c in axis.split()], q) for axis in coefs]
            worst = max(worst, np.linalg.norm(rot.T @ (d.site_xpos[m.site(f"{name}-P2").id] - d.xpos[arm]) - want))
    assert 0.0 < worst <= tol
    assert any("carrier slides instead of 3" in note for note in conv.report.notes)


def test_a_negative_tolerance_is_refused():
    with pytest.raises(ValueError, match="carrier_tolerance"):
        convert_options(carrier_tolerance=-1.0)
