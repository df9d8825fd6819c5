"""A clamped coordinate in forward dynamics: OpenSim does not hold it in its range, nor does o2m."""

from __future__ import annotations

import mujoco
import opensim as osim
import pytest

from o2m.convert.converter import convert
from tests.helpers import convert_options

START, RANGE, SECONDS = 0.94, (-1.0, 2.0), 1.0


def _falling_slider(path) -> float:
    """Write a 10-kg body on a vertical slider clamped to RANGE, starting at START (m); return its
    height after SECONDS of OpenSim forward dynamics under gravity."""
    model = osim.Model()
    model.setGravity(osim.Vec3(0, -9.81, 0))
    body = osim.Body("b", 10, osim.Vec3(0), osim.Inertia(1, 1, 1))
    model.addBody(body)
    turn = osim.Vec3(0, 0, 1.5707963267948966)  # the slider's x axis along ground's y (up)
    joint = osim.SliderJoint("j", model.getGround(), osim.Vec3(0), turn, body, osim.Vec3(0), turn)
    coord = joint.upd_coordinates(0)
    coord.setName("ty")
    coord.setRangeMin(RANGE[0])
    coord.setRangeMax(RANGE[1])
    coord.setDefaultClamped(True)
    coord.setDefaultValue(START)
    model.addJoint(joint)
    state = model.initSystem()
    model.printToXML(str(path))
    manager = osim.Manager(model)
    manager.initialize(state)
    state = manager.integrate(SECONDS)
    return model.getCoordinateSet().get("ty").getValue(state)


def _mujoco_height(xml) -> float:
    model = mujoco.MjModel.from_xml_path(str(xml))
    model.opt.integrator = mujoco.mjtIntegrator.mjINT_RK4
    model.opt.timestep = 1e-3
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, model.key("default-pose").id)
    while data.time < SECONDS - 1e-9:
        mujoco.mj_step(model, data)
    return float(data.qpos[model.joint("ty").id])


@pytest.fixture(scope="module")
def falling(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("clamped")
    path = tmp / "clamped_fall.osim"
    return path, _falling_slider(path), tmp


def test_clamped_coordinate_falls_through_its_range_as_in_opensim(falling):
    """OpenSim falls 0.5 g t^2 past the range's lower end (-3.965 m); so does the converted joint."""
    path, opensim_end, tmp = falling
    assert opensim_end == pytest.approx(START - 0.5 * 9.81 * SECONDS**2, abs=1e-6)
    conv = convert(path, tmp / "out", convert_options(fit_mechanics=False, fit_wraps=False))
    assert _mujoco_height(conv.xml) == pytest.approx(opensim_end, abs=1e-6)
    assert any("(ty) have unlimited MuJoCo joints" in n for n in conv.report.notes)


def test_clamped_limits_option_stops_it_at_the_range(falling):
    """With ``clamped_limits`` the joint gets MuJoCo's hard limit: it stops near the lower end."""
    path, _, tmp = falling
    conv = convert(path, tmp / "hard", convert_options(fit_mechanics=False, fit_wraps=False, clamped_limits=True))
    assert _mujoco_height(conv.xml) == pytest.approx(RANGE[0], abs=0.01)
    assert not any("unlimited MuJoCo joints" in n for n in conv.report.notes)
