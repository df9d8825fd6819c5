"""Forms of .osim documents the corpus does not use, met in public models from elsewhere:
bodies, joints and forces in the model's ``<components>`` list, muscles on a path o2m cannot
convert, and errors about unnamed elements of a 3.x document."""

from __future__ import annotations

import mujoco
import pytest

from o2m.convert.converter import convert
from o2m.errors import UnsupportedElementError
from tests.helpers import convert_options

_MUSCLE_PATH = """<GeometryPath name="path"><PathPointSet><objects>
<PathPoint name="origin"><socket_parent_frame>/ground</socket_parent_frame><location>0 0.3 0</location></PathPoint>
<PathPoint name="insertion"><socket_parent_frame>/body</socket_parent_frame><location>0 0 0</location></PathPoint>
</objects></PathPointSet></GeometryPath>"""


def _components_model(path_xml: str = _MUSCLE_PATH) -> str:
    """A body hanging from a muscle, the body and its slider in the model's <components>."""
    return f"""<?xml version="1.0" encoding="UTF-8" ?>
<OpenSimDocument Version="40600">
<Model name="hanging">
<components>
<Body name="body"><mass>0.5</mass><mass_center>0 0 0</mass_center><inertia>0.01 0.01 0.01 0 0 0</inertia></Body>
<SliderJoint name="joint"><socket_parent_frame>/ground</socket_parent_frame>
<socket_child_frame>/body</socket_child_frame>
<coordinates><Coordinate name="height"><range>-0.1 0.1</range></Coordinate></coordinates></SliderJoint>
<Station name="mark"><socket_parent_frame>/body</socket_parent_frame><location>0 0 0</location></Station>
</components>
<Ground name="ground"/>
<ForceSet name="forceset"><objects>
<Thelen2003Muscle name="muscle">{path_xml}<max_isometric_force>10</max_isometric_force>
<optimal_fiber_length>0.2</optimal_fiber_length><tendon_slack_length>0.1</tendon_slack_length></Thelen2003Muscle>
</objects></ForceSet>
</Model>
</OpenSimDocument>
"""


def test_bodies_and_joints_in_the_components_list_convert(tmp_path):
    src = tmp_path / "hanging.osim"
    src.write_text(_components_model())
    conv = convert(src, tmp_path / "out", convert_options())
    m = mujoco.MjModel.from_xml_path(str(conv.xml))
    assert m.body("body").id > 0 and m.joint("height").type == mujoco.mjtJoint.mjJNT_SLIDE
    assert m.actuator("muscle").id >= 0
    # the station is a generic component: listed as skipped, not silently dropped
    assert any(s.name == "mark" and "generic components" in s.reason for s in conv.report.skipped)


def test_a_muscle_on_another_path_type_names_it(tmp_path):
    src = tmp_path / "fbp.osim"
    src.write_text(_components_model("<FunctionBasedPath name=\"path\"/>"))
    with pytest.raises(UnsupportedElementError, match=r"line 13: <Thelen2003Muscle name=\"muscle\"> has a "
                                                      r"<FunctionBasedPath>, a path o2m cannot convert"):
        convert(src, tmp_path / "out", convert_options())
