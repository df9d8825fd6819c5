"""Flips between the wrap fit's poses: found in MuJoCo, told from OpenSim's own steps, avoided."""

from __future__ import annotations

from types import SimpleNamespace

import mujoco
import numpy as np

from o2m.convert.wrap_choice import FLIP_TRADE, best_variant
from o2m.convert.wrap_jumps import JUMP_ATOL, opensim_shares, segment_jumps
from tests.helpers import ONE_HINGE_SPHERE_TENDON

#: A site on a body turning about z passes a fixed sphere; the side site on +y sends the path round
#: the +y side, so at q = pi/2 (c at (0, -0.2, 0)) its length jumps from 0.28 to 0.49 m: the long way.
SIDE_SITE_MODEL = """<mujoco><worldbody>
  <site name="a" pos="-0.2 0 0"/>
  <geom name="ball" type="sphere" size="0.05" contype="0" conaffinity="0"/>
  <site name="side" pos="0 0.1 0"/>
  <body name="arm"><joint name="q" axis="0 0 1"/><inertial pos="0 0 0" mass="1" diaginertia="1 1 1"/>
    <site name="c" pos="-0.2 0 0"/></body>
</worldbody><tendon><spatial name="t"><site site="a"/><geom geom="ball" sidesite="{side}"/><site site="c"/>
</spatial></tendon></mujoco>"""


def _lengths(model: mujoco.MjModel, qs: np.ndarray) -> np.ndarray:
    data = mujoco.MjData(model)
    out = []
    for q in qs:
        data.qpos[0] = q
        mujoco.mj_fwdPosition(model, data)
        out.append(data.ten_length[0])
    return np.array(out)


def test_a_side_site_jump_between_two_poses_is_found_and_a_smooth_path_is_not():
    """q sweeps from 1.2 to 2.0 rad: with the side site the length steps by centimetres at one
    sample pair (checked on a fine sweep); without it (the shorter way) it does not, and nothing
    is found where the path is straight."""
    flipping = mujoco.MjModel.from_xml_string(SIDE_SITE_MODEL.format(side="side"))
    smooth = mujoco.MjModel.from_xml_string(SIDE_SITE_MODEL.format(side="").replace(' sidesite=""', ""))
    ends = np.array([[1.2], [2.0]])
    fine = np.abs(np.diff(_lengths(flipping, np.linspace(ends[0, 0], ends[1, 0], 2001))))
    assert fine.max() > 0.01 and np.sort(fine)[-2] < 1e-3  # one step of centimetres, else smooth
    found = segment_jumps(flipping, ends)
    assert len(found) == 1 and found[0]["excess"] > 0.01
    before, after = found[0]["before"][0], found[0]["after"][0]
    step = _lengths(flipping, np.array([before, after]))
    assert abs(step[1] - step[0] - found[0]["explained"]) > 0.01  # the two samples straddle the step
    assert segment_jumps(smooth, ends) == []
    assert segment_jumps(flipping, np.array([[4.5], [5.5]])) == []  # straight


def test_opensim_shares_a_jump_only_where_its_own_length_steps():
    jump = {"explained": 0.002, "excess": 0.03}
    assert opensim_shares(0.400, 0.400 + 0.002 + 0.025, jump)  # OpenSim steps 25 of MuJoCo's 30 mm
    assert not opensim_shares(0.400, 0.400 + 0.002 + 0.001, jump)  # smooth: a flip
    assert opensim_shares(None, 0.4, jump)  # OpenSim could not assemble: no reference, no flip
    assert JUMP_ATOL == 1e-3


def test_a_variant_that_flips_gives_way_to_a_near_one_that_does_not():
    def fit(label, objective, pct, flips):
        errors = {"objective": objective, "len_max_pct": pct, "len_rms_mm": 0.0, "ma_rms_mm": objective**0.5,
                  "poses": 10}
        return SimpleNamespace(variant=label, after=errors, check_after=errors, variants={}, dropped=[], flips=flips)

    assert best_variant([fit("glen", 82.0, 5.4, 7), fit("both", 84.1, 4.9, 0)]).variant == "both"
    far = FLIP_TRADE * 82.0 * 1.01
    assert best_variant([fit("glen", 82.0, 5.4, 7), fit("both", far, 4.9, 0)]).variant == "glen"
    # a variant whose worst length is far above the best's is not kept, flips or not
    assert best_variant([fit("glen", 82.0, 5.4, 7), fit("straight", 83.0, 9.0, 0)]).variant == "glen"
    assert best_variant([fit("a", 10.0, 1.0, 0), fit("b", 12.0, 1.0, 0)]).variant == "a"


def test_a_fit_far_worse_on_its_validation_poses_is_not_kept():
    """Fitting and check targets are the straight path's lengths (the sphere should get out of the
    way); the validation targets are the wrapped path's own, which the start meets exactly. The
    fit is kept without validation poses and refused with them (far worse there than its start)."""
    from o2m.convert.wrap_choice import PathVariant
    from o2m.convert.wrapfit import VALIDATION_GROWTH, _fit_one, _task
    from o2m.convert.wraps import PathGeom

    model = mujoco.MjModel.from_xml_string(ONE_HINGE_SPHERE_TENDON)
    data = mujoco.MjData(model)
    qs = np.linspace(-1.2, 1.2, 24)
    straight, wrapped = [], []
    for q in qs:
        data.qpos[0] = q
        mujoco.mj_fwdPosition(model, data)
        straight.append(np.linalg.norm(data.site("a").xpos - data.site("c").xpos))
        wrapped.append(data.ten_length[0])
    straight, wrapped = np.array(straight), np.array(wrapped)
    assert np.max(wrapped - straight) > 1e-3  # the sphere wraps at some poses
    fitting = {"qpos": qs[:, None], "dv": np.ones((len(qs), 1, 1)), "length": straight,
               "arm": -np.gradient(straight, qs)[:, None], "coordinates": ["q"], "contacts": {}}
    geoms = [PathGeom("m", "g", "s", "WrapSphere", "G")]
    variant = PathVariant("G", frozenset())
    alone = _fit_one(_task("m", ONE_HINGE_SPHERE_TENDON, geoms, fitting, variant, 16, 1, 200, [], 1))
    assert alone.accepted and alone.after["objective"] < 0.1 * alone.before["objective"]

    checked = {**fitting, "qpos": np.concatenate([qs, qs])[:, None], "dv": np.ones((2 * len(qs), 1, 1)),
               "length": np.concatenate([straight, wrapped]),
               "arm": np.concatenate([fitting["arm"], np.full((len(qs), 1), np.nan)]), "n_arms": len(qs)}
    refused = _fit_one(_task("m", ONE_HINGE_SPHERE_TENDON, geoms, checked, variant, 16, 1, 200, [], 1))
    assert not refused.accepted
    assert refused.valid_after["objective"] < 1e-9  # the start, exact on its validation poses
    assert VALIDATION_GROWTH >= 1.0
