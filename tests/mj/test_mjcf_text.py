"""o2m.mj.mjcf_text: numbers written in full, and the check that none of an MJCF's numbers is NaN or inf."""

from __future__ import annotations

import numpy as np

from o2m.mj import mjcf_text


def test_number_text_round_trips():
    x = np.array([0.1, 1 / 3, -2.5e-17])
    assert np.array_equal(np.array(mjcf_text.number_text(x).split(), dtype=float), x)


def test_non_finite_finds_nan_and_inf_numbers_only():
    xml = """<mujoco model="inf">
      <worldbody><body name="nan" pos="0 0 1"><joint name="inf" range="-1 1"/>
        <geom size="0.1" rgba="1 inf 1 1"/></body></worldbody>
      <equality><joint joint1="nan" joint2="inf" polycoef="0 NaN 0 0 0"/></equality>
      <compiler angle="radian" autolimits="true"/>
    </mujoco>"""
    bad = mjcf_text.non_finite(xml)
    assert bad == [("geom", None, "rgba", "1 inf 1 1"), ("joint", None, "polycoef", "0 NaN 0 0 0")]
    assert mjcf_text.non_finite(xml.replace("1 inf 1 1", "1 1 1 1").replace("0 NaN", "0 1")) == []
