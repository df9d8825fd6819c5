"""Consecutive ConditionalPathPoints and a range end at the default pose, on small hand-built models.

A pendulum (tests.helpers.pin_pendulum: ground -> arm on PinJoint q, range [-1, 1.5] rad) with one
PathActuator "m" from P1 on ground (-0.2, 0, 0) to P4 on the arm (0.3, 0, 0), and between them
ConditionalPathPoints on the arm, all switched by q (written as text: OpenSim's API crashes
inserting them).

Expected of the converter: a run of consecutive conditional points gets the sphere / always-on /
left-out roles whose path is nearest OpenSim's (here exact wherever OpenSim has the long-lived
point on, which keeping one sphere is not), and a pose at a range end has the point on, as in
OpenSim, on both sides of a finite-difference step.
"""

from __future__ import annotations

import mujoco
import numpy as np
import opensim as osim
import pytest

from o2m.convert.converter import convert
from o2m.mj.tendons import mujoco_moment_arms
from tests.helpers import arm_path_actuator, convert_options, pendulum_lengths, pin_pendulum

osim.Logger.setLevelString("error")


def _pendulum(path, points: list[tuple[str, tuple[float, float, float], tuple[float, float]]]) -> None:
    """Write the pendulum with the ConditionalPathPoints ``points`` (name, location on the arm
    (m), range of q (rad)), in order, between P1 and P4."""
    m, arm = pin_pendulum("pendulum_conditional")
    pa = arm_path_actuator(m, arm, "P4")
    m.addForce(pa)
    m.finalizeConnections()
    m.initSystem()
    m.printToXML(str(path))
    text = path.read_text()
    cond = "".join(f'<ConditionalPathPoint name="{name}"><socket_parent_frame>/bodyset/arm</socket_parent_frame>'
                   f'<location>{x!r} {y!r} {z!r}</location><range>{lo!r} {hi!r}</range>'
                   f'<socket_coordinate>/jointset/pin/q</socket_coordinate></ConditionalPathPoint>'
                   for name, (x, y, z), (lo, hi) in points)
    i = text.index('<PathPoint name="P4">')
    path.write_text(text[:i] + cond + text[i:])


@pytest.mark.parametrize("between", [False, True])
def test_a_run_of_two_keeps_the_long_lived_point_always_on(tmp_path, between):
    """P2 is on over q's whole range [-1, 1.5], P3 (after it) for q in [-1, 0.2], both bending
    the path. Keeping one sphere (o2m's rule before) misses the other point's detour; P2 always on
    and P3 a sphere is OpenSim's path. ``between``: a point active at q = 0 only (left out)
    between them, which must not hide the run (two spheres with no site between: one was lost)."""
    path = tmp_path / "run.osim"
    zero = [("P2b", (0.05, 0.05, 0.0), (0.0, 0.0))] if between else []
    _pendulum(path, [("P2", (0.0, 0.03, 0.0), (-1.0, 1.5))] + zero + [("P3", (0.15, 0.04, 0.0), (-1.0, 0.2))])
    conv = convert(path, tmp_path / "out", convert_options(fit_wraps=False, fit_mechanics=False))
    assert any("'P2' kept always on the path" in n for n in conv.report.notes), conv.report.notes
    xml = conv.xml.read_text()
    assert "P3_cond" in xml and "P2_cond" not in xml
    qs = np.arange(-1.0, 1.5, np.deg2rad(1.0))
    l_os, l_mj = pendulum_lengths(path, conv.xml, qs)
    # within the conditional sphere's rounding of the bend at P3
    assert np.abs(l_mj - l_os).max() < 2e-4, np.abs(l_mj - l_os).max()
    # keeping one sphere would miss a detour that is real: P2's where P3 is off, and P3's
    assert l_os[np.argmin(np.abs(qs - 1.0))] - _straight(1.0) > 1e-3
    assert l_os[np.argmin(np.abs(qs))] - _without_p3(0.0) > 1e-3


def _straight(q: float) -> float:
    """Length (m) of the straight line P1-P4 at angle ``q`` (rad)."""
    return float(np.hypot(0.3 * np.cos(q) + 0.2, 0.3 * np.sin(q)))


def _without_p3(q: float) -> float:
    """Length (m) of P1-P2-P4 at angle ``q`` (rad), P2 at (0, 0.03) on the arm."""
    p2 = np.array([-0.03 * np.sin(q), 0.03 * np.cos(q)])
    p4 = 0.3 * np.array([np.cos(q), np.sin(q)])
    return float(np.linalg.norm(p2 - [-0.2, 0.0]) + np.linalg.norm(p4 - p2))


def test_a_range_end_at_the_default_pose_is_on_both_sides_of_a_step(tmp_path):
    """P2, bending the path, is on for q in [-1, 0], the default angle: OpenSim has it on at q = 0.
    MuJoCo's side site sat on its sphere's surface there, so rounding decided, and a central
    difference of 1e-6 rad crossed the step (WristModel's FDPM: moment arms of 0.4 m)."""
    path = tmp_path / "end.osim"
    _pendulum(path, [("P2", (0.1, 0.03, 0.0), (-1.0, 0.0))])
    conv = convert(path, tmp_path / "out", convert_options(fit_wraps=False, fit_mechanics=False))
    l_os, l_mj = pendulum_lengths(path, conv.xml, [0.0, 0.01])
    assert abs(l_mj[0] - l_os[0]) < 2e-4  # on at the range end, as OpenSim
    assert l_os[0] - l_os[1] > 1e-3 and abs(l_mj[1] - l_os[1]) < 1e-9  # a real step, off past it
    m = mujoco.MjModel.from_xml_path(str(conv.xml))
    d = mujoco.MjData(m)
    fd = mujoco_moment_arms(m, d, {"q": 0.0}, ["q"], method="fd")
    jac = mujoco_moment_arms(m, d, {"q": 0.0}, ["q"], method="jacobian")
    assert np.abs(fd - jac).max() < 1e-6, (fd, jac)


@pytest.mark.parametrize("radius", [1e-3, None])
def test_a_bend_that_turns_over_still_passes_through_the_point(tmp_path, monkeypatch, radius):
    """P2, 5 mm off the line P1-P4 at q = 0, is on for q in [-1, 1]: the path bends towards +y
    (arm frame) at q = 0 but towards -y beyond q ~ 0.02, where the tendon touches the sphere on
    its far side, two radii from the point. With the 1 mm sphere o2m used before that cut the
    corner by millimetres; CONDITIONAL_RADIUS (None: the converter's) keeps it a tenth of that."""
    import o2m.convert.conditional as conditional

    if radius is not None:
        monkeypatch.setattr(conditional, "CONDITIONAL_RADIUS", radius)
    r = conditional.CONDITIONAL_RADIUS
    path = tmp_path / "turn.osim"
    _pendulum(path, [("P2", (0.02, 0.005, 0.0), (-1.0, 1.0))])
    conv = convert(path, tmp_path / "out", convert_options(fit_wraps=False, fit_mechanics=False))
    qs = np.arange(-1.0, 1.0, np.deg2rad(2.0))
    l_os, l_mj = pendulum_lengths(path, conv.xml, qs)
    err = np.abs(l_mj - l_os)
    assert err.max() <= 4 * r, (r, err.max())  # at most two radii on either side of the point
    if radius is not None:  # the old radius: a corner cut of over a millimetre where the bend turned
        assert err[qs > 0.5].max() > 1e-3, err.max()
    else:
        assert err.max() < 4e-4, err.max()


def _arm_polyline(q: float, points: list[tuple[float, float]]) -> float:
    """Length (m) at angle ``q`` (rad) of P1 (ground, (-0.2, 0)) through ``points`` (arm frame,
    x and y, m) to P4 (arm, (0.3, 0))."""
    c, s = np.cos(q), np.sin(q)
    xy = [np.array([-0.2, 0.0])] + [np.array([c * x - s * y, s * x + c * y]) for x, y in points + [(0.3, 0.0)]]
    return float(sum(np.linalg.norm(b - a) for a, b in zip(xy[:-1], xy[1:], strict=True)))


def test_two_points_of_one_body_on_in_disjoint_ranges_share_a_sphere(tmp_path):
    """P2 bends the path for q in [0.9, 1.5], P3 (after it, on the same arm) for q in [-1, -0.4];
    between, neither. With a sphere per point and a site between any two, one point must be
    kept always on or left out: a detour of millimetres somewhere. One sphere that a carrier
    moves from P3 to P2 while both are off (a quartic of q, its worst offset in the report),
    its side site out of it only in the gap, is exact in the gap and within that offset of
    OpenSim where a point is on."""
    p2, p3 = (0.1, 0.02), (0.12, -0.015)
    path = tmp_path / "shared.osim"
    _pendulum(path, [("P2", (*p2, 0.0), (0.9, 1.5)), ("P3", (*p3, 0.0), (-1.0, -0.4))])
    conv = convert(path, tmp_path / "out", convert_options(fit_wraps=False, fit_mechanics=False))
    note = next((n for n in conv.report.notes if "share a wrap sphere" in n), None)
    assert note is not None and "'P2' and 'P3'" in note, conv.report.notes
    offset = float(note.split("within ")[1].split(" mm")[0]) * 1e-3
    m = mujoco.MjModel.from_xml_path(str(conv.xml))
    spheres = [m.geom(i).name for i in range(m.ngeom) if m.geom(i).name.endswith("_cond")]
    assert spheres == ["m-P2_P3_cond"], spheres
    qs = np.arange(-1.0, 1.5, np.deg2rad(1.0))
    l_os, l_mj = pendulum_lengths(path, conv.xml, qs)
    err = np.abs(l_mj - l_os)
    gap = (qs > -0.4 + 1e-3) & (qs < 0.9 - 1e-3)
    assert err[gap].max() < 1e-9, err[gap].max()
    assert err.max() <= offset + 4 * 1e-4, (err.max(), offset)
    # every role with a sphere per point (C), always on (S) or left out (D) errs more
    on2, on3 = (qs >= 0.9), (qs <= -0.4)
    worst = {}
    for r2, r3 in [("C", "S"), ("S", "C"), ("C", "D"), ("D", "C"), ("S", "S"), ("S", "D"), ("D", "S"), ("D", "D")]:
        keep2 = on2 if r2 == "C" else np.full(len(qs), r2 == "S")
        keep3 = on3 if r3 == "C" else np.full(len(qs), r3 == "S")
        lengths = [_arm_polyline(q, [p for p, k in ((p2, k2), (p3, k3)) if k])
                   for q, k2, k3 in zip(qs, keep2, keep3, strict=True)]
        worst[r2 + r3] = float(np.abs(np.array(lengths) - l_os).max())
    assert min(worst.values()) > 2 * err.max(), (worst, err.max())
