"""Poses to draw: activation colours, tendon paths over wrapping surfaces, OpenSim's kinematics
against MuJoCo's."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from o2m.viz.frames import (
    NO_ACTIVATION_RGB,
    ViewerError,
    activation_colors,
    mujoco_frames,
    opensim_frames,
    tendon_activations,
    tendon_segments,
)
from tests.viz.helpers import arm_motion


def test_activation_colours_and_mapping(arm26):
    _, _, m = arm26
    rgb = activation_colors(np.array([0.0, 1.0, np.nan]))
    np.testing.assert_allclose(rgb[0], [0, 0, 1])
    np.testing.assert_allclose(rgb[1], [1, 0, 0])
    np.testing.assert_allclose(rgb[2], NO_ACTIVATION_RGB)
    per_actuator = np.arange(m.nu) / m.nu
    act = tendon_activations(m, per_actuator, 3)
    assert act.shape == (3, m.ntendon)
    for i in range(m.nu):
        assert act[0, m.actuator_trnid[i, 0]] == pytest.approx(per_actuator[i])
    with pytest.raises(ViewerError):
        tendon_activations(m, np.zeros((3, m.nu + 1)), 3)



def test_tendon_paths_follow_wrapping_surfaces(arm26):
    _, _, m = arm26
    d = mujoco.MjData(m)
    d.qpos[:] = arm_motion(m, 2)[0][-1]
    mujoco.mj_forward(m, d)
    arcs = tendon_segments(m, d, arc_points=8)
    chords = tendon_segments(m, d, arc_points=0)
    assert len(arcs) == m.ntendon
    length = np.array([np.linalg.norm(s[:, 1] - s[:, 0], axis=1).sum() for s in arcs])
    chord = np.array([np.linalg.norm(s[:, 1] - s[:, 0], axis=1).sum() for s in chords])
    np.testing.assert_allclose(length, d.ten_length, atol=5e-4)  # arcs drawn over the wrap surfaces
    assert np.all(chord <= d.ten_length + 1e-9)


def test_opensim_kinematics_matches_mujoco(arm26):
    osim, _, m = arm26
    q, _ = arm_motion(m, 4)
    names = ["r_shoulder_elev", "r_elbow_flex"]
    values = q[:, [m.joint(n).qposadr[0] for n in names]]
    os_frames = opensim_frames(osim, m, names, values)
    mj_frames = mujoco_frames(m, q)
    for a, b in zip(os_frames, mj_frames, strict=True):
        np.testing.assert_allclose(a.body_pos, b.body_pos, atol=1e-6)
        np.testing.assert_allclose(a.body_rot, b.body_rot, atol=1e-6)
        for sa, sb in zip(a.tendon_segments, b.tendon_segments, strict=True):  # same origin and insertion
            np.testing.assert_allclose(sa[0, 0], sb[0, 0], atol=1e-6)
            np.testing.assert_allclose(sa[-1, 1], sb[-1, 1], atol=1e-6)
    with pytest.raises(ViewerError, match="no coordinate"):
        opensim_frames(osim, m, ["nope"], np.zeros((1, 1)))
