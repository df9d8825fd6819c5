"""The ``default-pose`` keyframe is OpenSim's assembled default state: a body constraint the
coordinates' default values leave open starts closed in MuJoCo, as in OpenSim."""

from __future__ import annotations

import re

import mujoco
import numpy as np
import opensim as osim
import pytest

from o2m.convert import convert
from o2m.transforms import OSIM_TO_MJ
from tests.helpers import arm_and_block, convert_options

osim.Logger.setLevelString("off")

ARM_POINT = np.array([0.0, -0.5, 0.0])  # the arm's constrained point (m, arm frame)
GAP = np.array([0.08, 0.05, -0.03])  # where the block's default position leaves it (m)


def _open_pendulum(path, kind: str, gap: np.ndarray) -> str:
    """An arm pinned to the ground (0.4 rad) and a free block whose centre a ``kind`` constraint
    holds at the arm's end; the block's default position is ``gap`` away from it."""
    end = np.array([[np.cos(0.4), -np.sin(0.4), 0], [np.sin(0.4), np.cos(0.4), 0], [0, 0, 1]]) @ ARM_POINT
    m, arm, block = arm_and_block(f"open_{kind}", 0.4, (0.0, 0.0, 0.0, *(end + gap)))
    if kind == "PointConstraint":
        c = osim.PointConstraint(arm, osim.Vec3(*ARM_POINT), block, osim.Vec3(0))
    else:
        c = osim.PointOnLineConstraint(arm, osim.Vec3(1, 0, 0), osim.Vec3(*ARM_POINT), block, osim.Vec3(0))
    c.setName("held")
    m.addConstraint(c)
    m.finalizeConnections()
    m.printToXML(str(path))
    return str(path)


def _opensim_block(path: str) -> np.ndarray:
    """The block's centre (MuJoCo world frame, m) in OpenSim's initSystem state."""
    m = osim.Model(path)
    s = m.initSystem()
    return OSIM_TO_MJ @ m.getBodySet().get("block").getPositionInGround(s).to_numpy()


def _residual(m: mujoco.MjModel, d: mujoco.MjData) -> float:
    """The largest equality row's violation (m) at ``d.qpos``."""
    mujoco.mj_forward(m, d)
    rows = d.efc_type[:d.nefc] == mujoco.mjtConstraint.mjCNSTR_EQUALITY
    return float(np.abs(d.efc_pos[:d.nefc][rows]).max(initial=0.0))


@pytest.mark.parametrize("kind", ["PointConstraint", "PointOnLineConstraint"])
def test_keyframe_is_opensims_assembled_state(tmp_path, kind):
    path = _open_pendulum(tmp_path / f"{kind}.osim", kind, GAP)
    conv = convert(path, tmp_path / "out", convert_options(fit_wraps=False, fit_mechanics=False))
    m = mujoco.MjModel.from_xml_path(str(conv.xml))
    d = mujoco.MjData(m)
    assert _residual(m, d) > 0.02  # qpos0 keeps the default values: open
    mujoco.mj_resetDataKeyframe(m, d, m.key("default-pose").id)
    assert _residual(m, d) < 1e-8
    assert np.linalg.norm(d.body("block").xpos - _opensim_block(path)) < 1e-8
    note = next(n for n in conv.report.notes if n.startswith("the 'default-pose' keyframe is OpenSim's assembled"))
    assert "pin_coord_0" in note and "free_coord_5 +0.03" in note, note
    after, before = (float(x) for x in re.search(r"residual there (\S+) \(at qpos0, the default values, (\S+);",
                                                 note).groups())
    assert after < 1e-8 and before > 0.02, note


def test_keyframe_is_qpos0_where_the_defaults_are_assembled(tmp_path):
    path = _open_pendulum(tmp_path / "closed.osim", "PointConstraint", np.zeros(3))
    conv = convert(path, tmp_path / "out", convert_options(fit_wraps=False, fit_mechanics=False))
    m = mujoco.MjModel.from_xml_path(str(conv.xml))
    assert np.array_equal(m.key("default-pose").qpos, m.qpos0)
    assert not any("assembled default state" in n for n in conv.report.notes)
