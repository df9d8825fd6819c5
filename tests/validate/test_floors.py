"""Missed targets sorted into OpenSim's floors and o2m's own (o2m.validate.floors)."""

from __future__ import annotations

import math
import re
import shutil

import numpy as np

from o2m.gallery import targets_verdict
from o2m.validate.floors import TargetMiss, target_misses
from o2m.validate.muscles import LEN_PCT, compare_muscles


def test_a_miss_is_at_a_floor_only_when_the_floor_is_beyond_the_target_and_the_value_near_it():
    assert TargetMiss("A", None, 2.4, LEN_PCT, 1.5, "q").at_floor
    above = TargetMiss("A", None, 3.0, LEN_PCT, 1.5, "q")  # 1.5 % beyond the floor: o2m's
    assert above.target_impossible and not above.at_floor
    assert "above OpenSim's floor" in above.describe()
    assert not TargetMiss("A", None, 3.0, LEN_PCT, 0.5, "q").target_impossible
    assert not TargetMiss("A", "q", 4e-3, 2e-3, None).at_floor
    assert TargetMiss("A", "q", 9e-3, 2e-3, 8e-3).at_floor
    assert not TargetMiss("A", "q", 11e-3, 2e-3, 8e-3).at_floor
    assert "OpenSim's floor" in TargetMiss("A", None, 2.4, LEN_PCT, 1.5, "q").describe()
    assert "o2m's" in TargetMiss("A", "q", 4e-3, 2e-3, 1e-4).describe()


def test_the_gallery_verdict_names_o2m_misses():
    assert targets_verdict({}) == ""
    assert targets_verdict({"k1_ok": True}) == "met"
    assert targets_verdict({"k1_ok": True, "misses": [{"at_floor": True}]}) == "OpenSim floors"
    verdict = targets_verdict({"k1_ok": True, "misses": [{"at_floor": True}, {"at_floor": False}]})
    assert verdict.startswith("**missed**") and "1 of 2" in verdict and "floor" not in verdict
    built = targets_verdict({"k1_ok": True, "misses": [{"at_floor": False, "construction": True}, {"at_floor": False}]})
    assert "2 of 2 o2m's, 1 of them its constructions' floor" in built
    assert targets_verdict({"k1_ok": False}) == "**missed**"


def test_arm26_trilong_is_opensim_floor_and_a_moved_point_is_o2m_miss(bundled_conversion, tmp_path):
    """Arm26's TRIlong misses 1 % by OpenSim's own step (a floor); BRA with its ulna point moved by
    2 cm misses lengths and moment arms with no floor behind them, so those misses are o2m's."""
    fetched, conv = bundled_conversion("arm26")
    rep = compare_muscles(fetched.osim, conv.xml, n_poses=30, seed=0)
    # lengths only: the quick wrap fit, measured on poses it did not fit, also misses moment-arm
    # targets of its own (BIClong at OpenSim's kink, tests/integration/test_bundled_muscles.py)
    misses = [m for m in target_misses(fetched.osim, conv.xml, rep, poses=101) if m.coordinate is None]
    assert [m.path for m in misses] == ["TRIlong"] and misses[0].at_floor, [m.describe() for m in misses]
    assert LEN_PCT < misses[0].floor <= misses[0].value

    shutil.copytree(conv.xml.parent, tmp_path / "moved")
    xml = tmp_path / "moved" / conv.xml.name
    text = xml.read_text()
    site = re.search(r'<site name="BRA-P2"[^>]*pos="([^"]+)"', text)
    x, y, z = (float(v) for v in site.group(1).split())
    xml.write_text(text.replace(site.group(0), site.group(0).replace(site.group(1), f"{x + 0.02} {y} {z}")))
    rep = compare_muscles(fetched.osim, xml, n_poses=30, seed=0)
    moved = [m for m in target_misses(fetched.osim, xml, rep, poses=101) if m.path == "BRA"]
    assert moved and moved[0].coordinate is None and not moved[0].at_floor, [m.describe() for m in moved]
    assert any(m.coordinate is not None and not m.at_floor for m in moved), [m.describe() for m in moved]


def test_two_opposite_steps_close_together_are_a_band_not_a_floor():
    from o2m.validate.jumps import BAND_WIDTH, _without_bands

    def step(at, height):
        return {"at": at, "height": height}

    band = [step(0.30, 6e-3), step(0.31, -6.2e-3)]
    assert _without_bands(band, BAND_WIDTH[0]) == []
    lasting = [step(0.30, 6e-3), step(0.30 + 2 * BAND_WIDTH[0], -6e-3)]  # apart: two lasting steps
    assert len(_without_bands(lasting, BAND_WIDTH[0])) == 2
    same_way = [step(0.30, 6e-3), step(0.31, 6e-3)]  # a staircase, not a return
    assert len(_without_bands(same_way, BAND_WIDTH[0])) == 2
    partial = [step(0.30, 6e-3), step(0.31, -2e-3)]  # does not come back
    assert len(_without_bands(partial, BAND_WIDTH[0])) == 2


def _finite_cylinder_pendulum(path) -> None:
    """A pendulum (:func:`tests.helpers.pin_pendulum`, q in [0, 1.5] rad, default 1) whose path
    "m" runs from the ground to the arm over a WrapCylinder (radius 0.06 m, length 0.1 m, axis z,
    no quadrant) on a carrier sliding along z (coordinate "s", [0, 0.2] m, default 0). The path
    cuts the cylinder for small q; once the carrier has slid the cylinder's end past the path's
    plane (s > 0.05 m) OpenSim wraps nothing, so its length steps there, but only at poses where
    q is small: at the defaults the path clears the cylinder and no sweep from them steps."""
    import opensim as osim

    from tests.helpers import arm_path_actuator, pin_pendulum

    m, arm = pin_pendulum("finite_cylinder", (0.0, 1.5))
    m.getCoordinateSet().get("q").setDefaultValue(1.0)
    carrier = osim.Body("carrier", 0.1, osim.Vec3(0), osim.Inertia(1e-3, 1e-3, 1e-3))
    m.addBody(carrier)
    along_z = osim.Vec3(0, -math.pi / 2, 0)  # the slider's x axis along the ground's z
    slide = osim.SliderJoint("slide", m.getGround(), osim.Vec3(0), along_z, carrier, osim.Vec3(0), along_z)
    s = slide.updCoordinate()
    s.setName("s")
    s.setRangeMin(0.0)
    s.setRangeMax(0.2)
    m.addJoint(slide)
    cylinder = osim.WrapCylinder()
    cylinder.setName("roll")
    cylinder.set_radius(0.06)
    cylinder.set_length(0.1)
    cylinder.set_translation(osim.Vec3(0.0, -0.01, 0))
    carrier.addWrapObject(cylinder)
    pa = arm_path_actuator(m, arm, "P3")
    pa.updGeometryPath().addPathWrap(cylinder)
    m.addForce(pa)
    m.finalizeConnections()
    m.initSystem()
    m.printToXML(str(path))


def test_a_step_away_from_the_defaults_is_found_through_the_worst_pose(tmp_path):
    """OpenSim's finite cylinder cuts its wrap off where the carrier slides its end past the path
    (a step of the length); MuJoCo's cylinder has no ends and keeps wrapping, so the tendon misses
    the length target at small q. No sweep from the defaults sees the step; the sweep through the
    tendon's worst pose does, and the miss gets its floor, half the step, there (here about half
    the miss: MuJoCo follows the wrapped side)."""
    from o2m.convert.converter import convert
    from o2m.validate.jumps import opensim_length_steps
    from tests.helpers import convert_options

    osim_path = tmp_path / "finite_cylinder.osim"
    _finite_cylinder_pendulum(osim_path)
    conv = convert(osim_path, tmp_path / "out", convert_options(fit_wraps=False, fit_mechanics=False))
    assert opensim_length_steps(osim_path, conv.xml) == []
    steps = opensim_length_steps(osim_path, conv.xml, through={"q": 0.0})
    assert [s["coordinate"] for s in steps] == ["s"], steps
    assert abs(steps[0]["at"] - 0.05) < 1e-3 and steps[0]["height"] < -5e-3, steps  # the wrap cut off

    rep = compare_muscles(osim_path, conv.xml, n_poses=60, seed=0)
    worst = rep.muscles["m"].worst_pose
    assert worst["s"] > 0.05 and worst["q"] < 0.3, worst  # MuJoCo wraps where OpenSim's cylinder has ended
    # lines from the worst pose meet the step too, where they cross the cylinder's end
    from o2m.osim.pair import ModelPair
    from o2m.validate.jumps import opensim_steps_around

    around = opensim_steps_around(ModelPair(osim_path, conv.xml), "m", worst)
    assert around and all(st["height"] > 5e-3 for st in around), around  # towards smaller s: the wrap comes back
    for st in around:
        a, b = (np.array([st[k][c] for c in ("q", "s")]) for k in ("through", "towards"))
        assert abs((a + st["at"] / np.linalg.norm(b - a) * (b - a))[1] - 0.05) < 1e-6, st
    (miss,) = [m for m in target_misses(osim_path, conv.xml, rep, poses=51) if m.coordinate is None]
    assert miss.floor_through_worst and miss.floor_coordinate == "s", miss
    # MuJoCo's tendon at the worst pose is OpenSim's wrapped path, the step's upper side there
    assert abs(miss.floor - miss.value / 2) < 0.05 * miss.value, miss.describe()
    assert "through its worst pose" in miss.describe()
