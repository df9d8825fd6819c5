"""Loading OpenSim coordinate motions (.mot/.sto) onto converted MuJoCo models."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from o2m.errors import O2MError
from o2m.osim.storage import write_sto
from o2m.viz.motion import Motion, MotionError, coordinate_of_column, load_motion, resample_motion
from tests.helpers import convert_options, require_models


@pytest.fixture(scope="session")
def arm26(tmp_path_factory) -> mujoco.MjModel:
    """arm26 converted once per session (no muscle fitting: only the kinematics matter here)."""
    require_models()
    from o2m.convert.converter import convert
    from o2m.models import fetch_model_with_geometry

    f = fetch_model_with_geometry("arm26", progress=False)
    res = convert(f.osim, tmp_path_factory.mktemp("motion-arm26"), convert_options(fit_mechanics=False),
                  geometry_dirs=[f.geometry_dir])
    return mujoco.MjModel.from_xml_path(str(res.xml))


def _qadr(model: mujoco.MjModel, name: str) -> int:
    return int(model.jnt_qposadr[model.joint(name).id])


def test_column_labels():
    assert coordinate_of_column("r_elbow_flex") == "r_elbow_flex"
    assert coordinate_of_column("/jointset/r_elbow/r_elbow_flex/value") == "r_elbow_flex"
    assert coordinate_of_column("/jointset/r_elbow/r_elbow_flex/speed") is None
    assert coordinate_of_column("/forceset/BIClong/activation") is None


def test_degrees_to_radians_plain_and_path_labels(arm26, tmp_path):
    t = np.linspace(0.0, 0.5, 6)
    shoulder_deg = np.linspace(-30.0, 60.0, 6)
    elbow_deg = np.linspace(0.0, 120.0, 6)
    columns = ["r_shoulder_elev", "/jointset/r_elbow/r_elbow_flex/value", "/jointset/r_elbow/r_elbow_flex/speed",
               "not_a_coordinate"]
    data = np.column_stack([shoulder_deg, elbow_deg, np.ones(6), np.zeros(6)])
    path = write_sto(tmp_path / "arm.mot", t, columns, data, in_degrees=True)

    with pytest.warns(UserWarning, match="2 column"):
        motion = load_motion(path, arm26)

    assert isinstance(motion, Motion)
    assert motion.qpos.shape == (6, arm26.nq)
    np.testing.assert_allclose(motion.times, t)
    assert motion.coordinates == ("r_shoulder_elev", "r_elbow_flex")
    assert motion.unmatched == ("/jointset/r_elbow/r_elbow_flex/speed", "not_a_coordinate")
    assert motion.in_degrees
    np.testing.assert_allclose(motion.qpos[:, _qadr(arm26, "r_shoulder_elev")], np.deg2rad(shoulder_deg), atol=1e-12)
    np.testing.assert_allclose(motion.qpos[:, _qadr(arm26, "r_elbow_flex")], np.deg2rad(elbow_deg), atol=1e-12)
    np.testing.assert_allclose(motion.values, np.deg2rad(data[:, :2]), atol=1e-12)


def test_radians_file_is_read_as_is(arm26, tmp_path):
    t = np.array([0.0, 0.1])
    path = write_sto(tmp_path / "rad.sto", t, ["r_elbow_flex"], np.array([[0.5], [1.0]]), in_degrees=False)
    motion = load_motion(path, arm26, warn=False)
    np.testing.assert_allclose(motion.qpos[:, _qadr(arm26, "r_elbow_flex")], [0.5, 1.0])
    # Joints not in the file stay at their default pose.
    shoulder = _qadr(arm26, "r_shoulder_elev")
    np.testing.assert_allclose(motion.qpos[:, shoulder], arm26.qpos0[shoulder])


def test_no_matching_column_raises(arm26, tmp_path):
    path = write_sto(tmp_path / "other.mot", np.array([0.0, 1.0]), ["knee_angle_r", "/forceset/BIClong/activation"],
                     np.zeros((2, 2)), in_degrees=True)
    with pytest.raises(MotionError, match="none of its 2 columns") as info:
        load_motion(path, arm26)
    assert isinstance(info.value, O2MError)


SLIDE_AND_COUPLED = """
<mujoco>
  <worldbody>
    <body name="a">
      <joint name="hinge" type="hinge" axis="0 0 1"/>
      <joint name="slide" type="slide" axis="1 0 0"/>
      <geom size="0.1"/>
      <body name="b">
        <joint name="follower" type="hinge" axis="0 1 0"/>
        <geom size="0.1"/>
      </body>
    </body>
  </worldbody>
  <equality>
    <joint joint1="follower" joint2="hinge" polycoef="0 2 0 0 0"/>
  </equality>
</mujoco>
"""


def test_slides_stay_in_metres_and_dependents_follow(tmp_path):
    model = mujoco.MjModel.from_xml_string(SLIDE_AND_COUPLED)
    path = write_sto(tmp_path / "m.mot", np.array([0.0, 1.0]), ["hinge", "slide"],
                     np.array([[10.0, 0.05], [20.0, 0.10]]), in_degrees=True)
    motion = load_motion(path, model)
    np.testing.assert_allclose(motion.qpos[:, 0], np.deg2rad([10.0, 20.0]))
    np.testing.assert_allclose(motion.qpos[:, 1], [0.05, 0.10])
    np.testing.assert_allclose(motion.qpos[:, 2], 2 * np.deg2rad([10.0, 20.0]))  # the equality's follower


def test_resample(tmp_path):
    model = mujoco.MjModel.from_xml_string(SLIDE_AND_COUPLED)
    path = write_sto(tmp_path / "m.mot", np.array([0.0, 1.0]), ["hinge"], np.array([[0.0], [1.0]]))
    motion = resample_motion(load_motion(path, model), model, fps=4)
    np.testing.assert_allclose(motion.times, [0.0, 0.25, 0.5, 0.75, 1.0])
    np.testing.assert_allclose(motion.qpos[:, 0], motion.times)
    np.testing.assert_allclose(motion.qpos[:, 2], 2 * motion.times)


def test_replay_command_writes_a_page(tmp_path):
    """``python -m o2m replay MODEL.xml MOTION.mot``: a .mot in degrees becomes a meshcat page."""
    require_models()
    from o2m.cli import main
    from o2m.convert.converter import convert
    from o2m.models import fetch_model_with_geometry
    from o2m.osim.storage import write_sto

    f = fetch_model_with_geometry("arm26", progress=False)
    res = convert(f.osim, tmp_path / "arm26", convert_options(fit_mechanics=False), geometry_dirs=[f.geometry_dir])
    t = np.linspace(0, 1, 21)
    mot = write_sto(tmp_path / "flex.mot", t, ["r_shoulder_elev", "r_elbow_flex", "pelvis_tx"],
                    np.column_stack([10 * t, 90 * t, 0 * t]), in_degrees=True)
    out = tmp_path / "replay.html"
    assert main(["replay", str(res.xml), str(mot), "-o", str(out), "--fps", "10"]) == 0
    html = out.read_text()
    assert out.stat().st_size > 100_000 and "<script" in html and "http://" not in html.split("<body")[0]
