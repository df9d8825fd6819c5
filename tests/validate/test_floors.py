"""Missed targets sorted into OpenSim's floors and o2m's own (o2m.validate.floors)."""

from __future__ import annotations

import re
import shutil

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
