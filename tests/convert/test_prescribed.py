"""A prescribed coordinate: OpenSim moves it as a function of time whatever value is set. A
constant one is folded into fixed transforms at its value, like a locked coordinate; any other
keeps a free MuJoCo joint that starts at the function's value at time 0, with a warning."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
from lxml import etree

from o2m.convert import ConvertOptions, convert
from o2m.validate.kinematics import compare_kinematics
from tests.helpers import model_file


def _prescribed(tmp_path, function: str):
    """The corpus's double pendulum with q1 prescribed by the OpenSim ``function`` element."""
    tree = etree.parse(str(model_file("opensim-models/Models/DoublePendulum/double_pendulum.osim")))
    q1 = next(c for c in tree.iter("Coordinate") if c.get("name") == "q1")
    for tag in ("prescribed_function", "prescribed"):
        for old in q1.findall(tag):
            q1.remove(old)
    holder = etree.SubElement(q1, "prescribed_function")
    holder.append(etree.fromstring(function))
    etree.SubElement(q1, "prescribed").text = "true"
    path = tmp_path / "pendulum.osim"
    tree.write(str(path))
    return path


def test_a_constant_prescription_is_a_fixed_joint_at_its_value(tmp_path):
    osim = _prescribed(tmp_path, "<Constant><value>0.7</value></Constant>")
    out = convert(osim, tmp_path / "out", ConvertOptions(quick=True))
    m = mujoco.MjModel.from_xml_path(str(out.xml))
    assert mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, "q1") < 0
    assert any("prescribed constant coordinate 'q1'" in n and "0.7" in n for n in out.report.notes)
    rep = compare_kinematics(osim, out.xml, n_poses=20, seed=0)
    assert rep.max_pos_error < 1e-9 and rep.max_ang_error < 1e-9


def test_a_prescribed_motion_keeps_a_free_joint_starting_where_opensim_does(tmp_path):
    osim = _prescribed(tmp_path, "<Sine><amplitude>0.5</amplitude><omega>3</omega><phase>0.4</phase>"
                                 "<offset>0.1</offset></Sine>")
    out = convert(osim, tmp_path / "out", ConvertOptions(quick=True))
    m = mujoco.MjModel.from_xml_path(str(out.xml))
    start = 0.5 * np.sin(0.4) + 0.1
    assert m.qpos0[m.jnt_qposadr[m.joint("q1").id]] == pytest.approx(start, abs=1e-12)
    assert any("Coordinate q1: prescribed motion" in w for w in out.report.warnings)
    # OpenSim holds q1 at its time-0 value whatever a pose sets, so the comparison does not sample it
    rep = compare_kinematics(osim, out.xml, n_poses=20, seed=0)
    assert "q1" in rep.locked_coordinates
    assert rep.max_pos_error < 1e-9 and rep.max_ang_error < 1e-9
